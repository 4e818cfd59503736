// Device allocator for structural instances: cudaMalloc / cudaFree, same interface as HostAllocator.
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>

#include "MnSystem/Cuda/device_query.h"

namespace fbar::cuda {

/// Allocates global memory on the current device; cudaMalloc aligns to at least 256 bytes.
/// Stateless: the device is the one current at the call, as for cudaMalloc itself.
struct DeviceAllocator {
  static constexpr std::size_t alignment = 256;

  /// `bytes` of uninitialised device memory; throws cuda::OutOfMemory when the device is full, std::runtime_error
  /// on any other failure. 0 bytes gives nullptr.
  void* allocate(std::size_t bytes) const { return device_malloc(bytes); }
  /// Frees memory from allocate(); nullptr is ignored. Throws std::runtime_error if cudaFree fails.
  void deallocate(void* ptr, std::size_t /*bytes*/) const {
    if (ptr != nullptr) FBAR_CUDA_CHECK(cudaFree(ptr));
  }
};

}  // namespace fbar::cuda
