// gpu_engine_fit(): can the visible GPU run this build's kernels? The compiled architectures and one kernel loaded.
#include <cuda_runtime.h>

#include <string>

#include "MnSystem/Cuda/device_query.h"
#include "engine/gpu/gpu_engine.h"

#ifndef FBAR_CUDA_ARCHITECTURES
#define FBAR_CUDA_ARCHITECTURES ""  // unknown: the loaded kernel decides
#endif

namespace fbar {
namespace {

/// Compiled with the same architectures as every kernel of fbar_gpu: if it loads, they do.
__global__ void probe_kernel() {}

}  // namespace

GpuCodeFit gpu_engine_fit(int device) {
  cuda::DeviceInfo info;
  std::string prefix = "GPU " + std::to_string(device);
  if (!cuda::device_info(device, info)) {
    GpuCodeFit fit;
    fit.message = prefix + ": the CUDA runtime cannot read its properties";
    return fit;
  }
  prefix += " (" + info.name + ", compute capability " + std::to_string(info.major) + "." +
            std::to_string(info.minor) + ")";
  GpuCodeFit fit = gpu_code_fit(FBAR_CUDA_ARCHITECTURES, info.major, info.minor);

  // The driver's answer: load the probe kernel on the device (creates its context, which the run needs anyway).
  int current = 0;
  const bool had_current = cudaGetDevice(&current) == cudaSuccess;
  cudaFuncAttributes attributes{};
  cudaError_t e = cudaSetDevice(device);
  if (e == cudaSuccess) e = cudaFuncGetAttributes(&attributes, probe_kernel);
  cudaGetLastError();  // a missing kernel image is not sticky: clear it
  if (had_current) cudaSetDevice(current);

  if (e == cudaSuccess) {
    // Loaded: it runs (should the rules have said otherwise, or not known, the driver is right).
    fit.runs = true;
    if (!fit.jit) fit.message.clear();
  } else if (!fit.runs) {
    // The rules and the driver agree: no code for this device (the message says how to rebuild).
  } else {
    fit.runs = false;
    fit.jit = false;
    fit.message = std::string("the CUDA driver cannot load this build's kernels on it: ") + cudaGetErrorName(e) +
                  " (" + cudaGetErrorString(e) + ")" +
                  (e == cudaErrorUnsupportedPtxVersion
                       ? "; the driver is older than the CUDA toolkit that built fbar: update the driver, or rebuild "
                         "with -DCMAKE_CUDA_ARCHITECTURES=" + std::to_string(info.major * 10 + info.minor)
                       : std::string());
  }
  if (!fit.message.empty()) fit.message = prefix + ": " + fit.message;
  return fit;
}

}  // namespace fbar
