// CUDA device discovery and checked calls for host code (the CUDA runtime; a build without it sees no device).
#pragma once

#include <cstddef>
#include <sstream>
#include <stdexcept>
#include <string>

#if defined(FBAR_HAS_CUDA)
#include <cuda_runtime_api.h>
#endif

namespace fbar::cuda {

/// A device allocation the device could not satisfy (std::runtime_error; message: bytes asked, free and total).
struct OutOfMemory : std::runtime_error {
  using std::runtime_error::runtime_error;
  std::size_t requested = 0;
};

/// What a CUDA device is, for messages and the start-up check: its name and compute capability (major.minor).
struct DeviceInfo {
  std::string name;
  int major = 0;
  int minor = 0;
};

#if !defined(FBAR_HAS_CUDA)
// Configured without the CUDA toolkit (FBAR_ENABLE_CUDA=OFF): the host code that asks for devices sees none, and
// says why.

inline int device_count() { return 0; }
inline std::string no_device_reason() {
  return "no CUDA device: this build has no GPU engine (configured without the CUDA toolkit)";
}
inline bool device_info(int /*device*/, DeviceInfo& /*info*/) { return false; }
inline void memory_info(std::size_t& free_bytes, std::size_t& total_bytes) { free_bytes = total_bytes = 0; }
inline bool device_memory(int /*device*/, std::size_t& free_bytes, std::size_t& total_bytes) {
  free_bytes = total_bytes = 0;
  return false;
}

#else

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

/// Bytes of device memory free and in total on the current device (0, 0 without one).
inline void memory_info(std::size_t& free_bytes, std::size_t& total_bytes) {
  free_bytes = total_bytes = 0;
  if (cudaMemGetInfo(&free_bytes, &total_bytes) != cudaSuccess) {
    cudaGetLastError();
    free_bytes = total_bytes = 0;
  }
}

/// Makes `device` current and gives its free and total memory; false (0, 0) when it cannot be made current.
inline bool device_memory(int device, std::size_t& free_bytes, std::size_t& total_bytes) {
  free_bytes = total_bytes = 0;
  if (cudaSetDevice(device) != cudaSuccess) {
    cudaGetLastError();
    return false;
  }
  memory_info(free_bytes, total_bytes);
  return true;
}

/// The name and compute capability of `device`; false when the runtime cannot tell.
inline bool device_info(int device, DeviceInfo& info) {
  cudaDeviceProp prop{};
  if (cudaGetDeviceProperties(&prop, device) != cudaSuccess) {
    cudaGetLastError();
    return false;
  }
  info.name = prop.name;
  info.major = prop.major;
  info.minor = prop.minor;
  return true;
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

#endif  // FBAR_HAS_CUDA

}  // namespace fbar::cuda

#if defined(FBAR_HAS_CUDA)
#define FBAR_CUDA_CHECK(call) ::fbar::cuda::check((call), #call, __FILE__, __LINE__)
#endif
