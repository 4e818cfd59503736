// Host allocator for structural instances: aligned operator new, same interface as cuda::DeviceAllocator.
#pragma once

#include <cstddef>
#include <new>

namespace fbar {

/// Allocates host memory aligned to `Alignment` bytes (default 256, cudaMalloc's guarantee, so host
/// mirrors of device structures see the same alignment). Stateless: copies are interchangeable.
template <std::size_t Alignment = 256>
struct BasicHostAllocator {
  static_assert(Alignment != 0 && (Alignment & (Alignment - 1)) == 0,
                "HostAllocator: alignment must be a power of two");
  static constexpr std::size_t alignment = Alignment;

  /// `bytes` of uninitialised storage; throws std::bad_alloc on failure. 0 bytes gives nullptr.
  void* allocate(std::size_t bytes) const {
    return bytes == 0 ? nullptr : ::operator new (bytes, std::align_val_t{Alignment});
  }
  /// Frees storage that allocate(bytes) returned; nullptr is ignored.
  void deallocate(void* ptr, std::size_t bytes) const noexcept {
    if (ptr != nullptr) ::operator delete (ptr, bytes, std::align_val_t{Alignment});
  }
};

using HostAllocator = BasicHostAllocator<>;

}  // namespace fbar
