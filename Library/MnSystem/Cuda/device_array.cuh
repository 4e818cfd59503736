// Device and pinned host arrays for engines (RAII, no copies), and the checks of a kernel launch.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "MnSystem/Cuda/device_query.h"

namespace fbar::cuda {

/// CUDA blocks of `threads` threads that cover n items.
inline int grid_for(long long n, int threads) { return static_cast<int>((n + threads - 1) / threads); }

/// Throws the error of the last launch (launch configuration, not the kernel's run), naming the kernel.
inline void check_launch(const char* what) {
  const cudaError_t e = cudaGetLastError();
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA launch of ") + what + " failed: " + cudaGetErrorString(e));
}

/// Pinned host memory owned by a unique_ptr (frames hand it to the writer thread).
struct PinnedDeleter {
  void operator()(void* p) const { cudaFreeHost(p); }
};
using PinnedBytes = std::unique_ptr<void, PinnedDeleter>;
inline PinnedBytes pinned(std::size_t bytes) {
  void* p = nullptr;
  FBAR_CUDA_CHECK(cudaMallocHost(&p, bytes));
  return PinnedBytes(p);
}

/// A device array of trivially copyable T (RAII, no copy).
template <typename V>
class DeviceArray {
 public:
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  ~DeviceArray() {
    if (ptr_) cudaFree(ptr_);
  }
  void allocate(std::size_t n) {
    if (ptr_) FBAR_CUDA_CHECK(cudaFree(ptr_));
    ptr_ = nullptr;
    size_ = n;
    if (n) ptr_ = static_cast<V*>(cuda::device_malloc(sizeof(V) * n, "GPU engine buffer"));
    // Zeroed: allocations are rare, and growth copies whole arrays whose unused slots were never written. The
    // memset runs on the legacy stream, which the engine's non-blocking streams do not wait for: finish it here.
    if (n) {
      FBAR_CUDA_CHECK(cudaMemset(ptr_, 0, sizeof(V) * n));
      FBAR_CUDA_CHECK(cudaDeviceSynchronize());
    }
  }
  V* get() const { return ptr_; }
  void swap(DeviceArray& o) noexcept {
    std::swap(ptr_, o.ptr_);
    std::swap(size_, o.size_);
  }
  std::size_t size() const { return size_; }
  std::size_t bytes() const { return size_ * sizeof(V); }

 private:
  V* ptr_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace fbar::cuda
