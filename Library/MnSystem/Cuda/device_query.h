// CUDA device discovery and checked calls for host code (links against the CUDA runtime).
#pragma once

#include <cuda_runtime_api.h>

#include <sstream>
#include <stdexcept>
#include <string>

namespace fbar::cuda {

/// Number of usable CUDA devices; 0 when there is no driver, no device, or the runtime fails.
inline int device_count() {
  int n = 0;
  if (cudaGetDeviceCount(&n) != cudaSuccess) {
    cudaGetLastError();  // clear the sticky "no device" error
    return 0;
  }
  return n;
}

/// Why device_count() is 0, for skip messages and logs.
inline std::string no_device_reason() {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  cudaGetLastError();
  if (e != cudaSuccess) return std::string("no CUDA device: ") + cudaGetErrorString(e);
  if (n == 0) return "no CUDA device: the driver reports 0 devices";
  return {};
}

/// Throws std::runtime_error with the call site when a CUDA runtime call fails.
inline void check(cudaError_t e, const char* what, const char* file, int line) {
  if (e != cudaSuccess) {
    std::ostringstream os;
    os << "CUDA error " << cudaGetErrorName(e) << " (" << cudaGetErrorString(e) << ") in " << what << " at "
       << file << ":" << line;
    throw std::runtime_error(os.str());
  }
}

}  // namespace fbar::cuda

#define FBAR_CUDA_CHECK(call) ::fbar::cuda::check((call), #call, __FILE__, __LINE__)
