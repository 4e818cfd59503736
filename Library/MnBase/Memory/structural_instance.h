// Structural instances: trivially-copyable handles (pointer + capacity) that address a structural node.
//
// An instance does not own its memory and does not hold its allocator (Claymore's rule, kept): the
// allocator chosen at run time decides whether the bytes live on the host or the device, and the
// program allocates and frees explicitly. Being a plain {pointer, capacity} pair, an instance is passed
// by value to CUDA kernels, and a child instance (ch) is just the parent pointer plus a byte offset.
//
//   auto grid = spawn<grid_buffer_>(allocator, block_capacity);   // run-time capacity
//   auto block = grid.ch(_0, blockno);                             // child 0 of element `blockno`
//   block.val(_1, x, y, z) = vx;                                   // leaf 1 at coordinates (x, y, z)
//   block.val_1d(_0, cell) += m;                                   // leaf 0 of linear element `cell`
//   grid.deallocate(allocator);
//
// Access is shallow-const, like a pointer or std::span: a const instance still yields writable values,
// so a kernel taking `const Instance` by value can write through it.
//
// Allocator interface: void* allocate(std::size_t bytes); void deallocate(void* p, std::size_t bytes);
// the returned storage must be aligned to at least Structural::alignment (HostAllocator and
// cuda::DeviceAllocator give 256 bytes).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "MnBase/Memory/structural.h"
#include "MnBase/Meta/config.h"
#include "MnBase/Meta/placeholder.h"

namespace fbar {

template <typename Structural>
class structural_instance {
 public:
  using structural = Structural;
  template <attrib_index I>
  using child = typename Structural::template child<I>;
  template <attrib_index I>
  using accessor = typename Structural::template accessor<I>;

  static_assert(Structural::type != structural_type::entity, "structural_instance: instantiate a structural node");

  structural_instance() = default;

  /// A view of existing storage of a compile-time sized node (`data` aligned to Structural::alignment).
  FBAR_HOST_DEVICE constexpr explicit structural_instance(std::byte* data) noexcept
      : data_{data}, capacity_{compile_time_extent()} {}

  /// A view of existing storage of a dynamic or hash node holding `capacity` elements (slots).
  FBAR_HOST_DEVICE constexpr structural_instance(std::byte* data, std::size_t capacity) noexcept
      : data_{data}, capacity_{capacity} {
    static_assert(Structural::is_run_time_sized, "structural_instance: a compile-time sized node takes no capacity");
  }

  /// Start of the node's storage (nullptr when unallocated).
  FBAR_HOST_DEVICE constexpr std::byte* data() const noexcept { return data_; }
  /// Number of elements: the run-time capacity of a dynamic or hash node, Domain::extent otherwise.
  FBAR_HOST_DEVICE constexpr std::size_t capacity() const noexcept { return extent(); }
  /// Bytes of storage the instance addresses.
  FBAR_HOST_DEVICE constexpr std::size_t size_bytes() const noexcept { return Structural::bytes(extent()); }
  FBAR_HOST_DEVICE constexpr explicit operator bool() const noexcept { return data_ != nullptr; }

  /// Instance of child I (a structural node) of the element at `is...` (one index for dynamic/hash).
  template <attrib_index I, typename... Is>
  FBAR_HOST_DEVICE constexpr auto ch(std::integral_constant<attrib_index, I>, Is... is) const {
    using C = child<I>;
    static_assert(C::type != structural_type::entity, "ch() descends into a structural child; read a leaf with val()");
    return structural_instance<C>{data_ + accessor<I>{extent()}.coord_offset(is...)};
  }

  /// Leaf I of the element at coordinates `is...` (one index for dynamic/hash).
  template <attrib_index I, typename... Is>
  FBAR_HOST_DEVICE constexpr auto& val(std::integral_constant<attrib_index, I>, Is... is) const {
    return leaf<I>(accessor<I>{extent()}.coord_offset(is...));
  }

  /// Leaf I of linear element i (row-major order of the domain).
  template <attrib_index I>
  FBAR_HOST_DEVICE constexpr auto& val_1d(std::integral_constant<attrib_index, I>, std::size_t i) const {
    return leaf<I>(accessor<I>{extent()}.linear_offset(i));
  }

  /// Allocates the storage of a compile-time sized node.
  template <typename Allocator>
  void allocate_handle(Allocator&& allocator) {
    static_assert(!Structural::is_run_time_sized, "allocate_handle: a dynamic or hash node needs a capacity");
    if constexpr (!Structural::is_run_time_sized) allocate_bytes(allocator, Structural::extent);
  }

  /// Allocates the storage of a dynamic or hash node for `capacity` elements (slots).
  template <typename Allocator>
  void allocate_handle(Allocator&& allocator, std::size_t capacity) {
    static_assert(Structural::is_run_time_sized,
                  "allocate_handle: this node's extent is fixed at compile time; call it without a capacity");
    allocate_bytes(allocator, capacity);
  }

  /// Returns the storage to the allocator it came from; the instance becomes empty.
  template <typename Allocator>
  void deallocate(Allocator&& allocator) {
    if (data_ != nullptr) allocator.deallocate(data_, size_bytes());
    data_ = nullptr;
    capacity_ = 0;
  }

 private:
  // Compile-time sized nodes use their constant extent, so their offsets fold to constants.
  FBAR_HOST_DEVICE constexpr std::size_t extent() const noexcept {
    if constexpr (Structural::is_run_time_sized) {
      return capacity_;
    } else {
      return Structural::extent;
    }
  }
  FBAR_HOST_DEVICE static constexpr std::size_t compile_time_extent() noexcept {
    static_assert(!Structural::is_run_time_sized, "structural_instance: a dynamic or hash node needs its capacity");
    if constexpr (Structural::is_run_time_sized) {
      return 0;
    } else {
      return Structural::extent;
    }
  }

  template <attrib_index I>
  FBAR_HOST_DEVICE constexpr auto& leaf(std::size_t byte_offset) const {
    using C = child<I>;
    constexpr bool is_leaf = C::type == structural_type::entity;
    static_assert(is_leaf, "val() reads a leaf; descend into a structural child with ch()");
    using T = typename std::conditional_t<is_leaf, C, structural_entity<std::byte>>::value_type;
    static_assert(!std::is_void_v<T>, "val(): an empty_ attribute holds no value");
    // The two static_asserts above report misuse; the fallbacks only keep the compiler from adding noise.
    return *reinterpret_cast<std::conditional_t<std::is_void_v<T>, std::byte, T>*>(data_ + byte_offset);
  }

  template <typename Allocator>
  void allocate_bytes(Allocator& allocator, std::size_t capacity) {
    if (data_ != nullptr) throw std::logic_error("structural_instance: already allocated; deallocate first");
    const std::size_t n = Structural::bytes(capacity);
    data_ = n != 0 ? static_cast<std::byte*>(allocator.allocate(n)) : nullptr;
    capacity_ = capacity;
  }

  std::byte* data_ = nullptr;
  std::size_t capacity_ = 0;
};

/// Allocates a compile-time sized structural node.
template <typename Structural, typename Allocator>
structural_instance<Structural> spawn(Allocator&& allocator) {
  structural_instance<Structural> instance;
  instance.allocate_handle(allocator);
  return instance;
}

/// Allocates a dynamic or hash node with `capacity` elements (slots).
template <typename Structural, typename Allocator>
structural_instance<Structural> spawn(Allocator&& allocator, std::size_t capacity) {
  structural_instance<Structural> instance;
  instance.allocate_handle(allocator, capacity);
  return instance;
}

}  // namespace fbar
