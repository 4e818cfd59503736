// CUDA device discovery and checked calls for host code (links against the CUDA runtime).
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
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

/// A device allocation the device could not satisfy (std::runtime_error; message: bytes asked, free and total).
struct OutOfMemory : std::runtime_error {
  using std::runtime_error::runtime_error;
  std::size_t requested = 0;
};

/// Bytes of device memory free and in total on the current device (0, 0 without one).
inline void memory_info(std::size_t& free_bytes, std::size_t& total_bytes) {
  free_bytes = total_bytes = 0;
  if (cudaMemGetInfo(&free_bytes, &total_bytes) != cudaSuccess) {
    cudaGetLastError();
    free_bytes = total_bytes = 0;
  }
}

/// cudaMalloc that turns an out-of-memory failure into OutOfMemory (naming `what`, the bytes and what is free),
/// and any other failure into the usual std::runtime_error. 0 bytes gives nullptr.
inline void* device_malloc(std::size_t bytes, const char* what = "device buffer") {
  void* ptr = nullptr;
  if (bytes == 0) return nullptr;
  const cudaError_t e = cudaMalloc(&ptr, bytes);
  if (e == cudaErrorMemoryAllocation) {
    cudaGetLastError();  // not sticky: clear it so the caller can report and shut down cleanly
    std::size_t free_bytes = 0, total_bytes = 0;
    memory_info(free_bytes, total_bytes);
    std::ostringstream os;
    os.precision(3);
    os << "out of device memory: " << what << " needs " << static_cast<double>(bytes) / (1u << 30) << " GiB, "
       << static_cast<double>(free_bytes) / (1u << 30) << " GiB of " << static_cast<double>(total_bytes) / (1u << 30)
       << " GiB are free";
    OutOfMemory error(os.str());
    error.requested = bytes;
    throw error;
  }
  check(e, "cudaMalloc", __FILE__, __LINE__);
  return ptr;
}

}  // namespace fbar::cuda

#define FBAR_CUDA_CHECK(call) ::fbar::cuda::check((call), #call, __FILE__, __LINE__)
