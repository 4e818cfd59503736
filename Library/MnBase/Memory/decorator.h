// Decorators: how a structural node allocates, pads and lays out the attributes of its elements.
//
//   alloc_policy    full_allocation: every element's storage is part of the node's one allocation.
//                   on_demand:       (Claymore) children allocated later and reached through pointers.
//   padding_policy  compact: an element takes the C-struct size of its attributes.
//                   align:   an element is padded to the next power of two, so elements never straddle
//                            more cache lines / memory transactions than needed.
//   layout          aos: element 0 {a0, a1, ...}, element 1 {a0, a1, ...}, ...
//                   soa: a0 of every element, then a1 of every element, ...
//
// fbar supports full_allocation only: an on_demand child's pointer would have to be written into
// device memory by the host, which the handle-only instance cannot do, and every fbar structure is
// sized from the scene at run time instead (see structural.h, dynamic nodes).
#pragma once

#include <cstddef>

#include "MnBase/Meta/config.h"

namespace fbar {

enum class structural_allocation_policy : unsigned { full_allocation = 0, on_demand = 1 };
enum class structural_padding_policy : unsigned { compact = 0, align = 1 };
enum class attrib_layout : unsigned { aos = 0, soa = 1 };

/// Smallest power of two >= n (1 for n == 0).
FBAR_HOST_DEVICE constexpr std::size_t next_power_of_two(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

/// Smallest multiple of `alignment` >= n (alignment > 0).
FBAR_HOST_DEVICE constexpr std::size_t round_up(std::size_t n, std::size_t alignment) {
  return (n + alignment - 1) / alignment * alignment;
}

template <structural_allocation_policy AllocPolicy = structural_allocation_policy::full_allocation,
          structural_padding_policy PaddingPolicy = structural_padding_policy::compact,
          attrib_layout Layout = attrib_layout::aos>
struct decorator {
  static constexpr structural_allocation_policy alloc_policy = AllocPolicy;
  static constexpr structural_padding_policy padding_policy = PaddingPolicy;
  static constexpr attrib_layout layout = Layout;

  /// Bytes one element occupies in storage, given its unpadded size.
  FBAR_HOST_DEVICE static constexpr std::size_t storage_size(std::size_t element_size) {
    const bool pad = padding_policy == structural_padding_policy::align && element_size != 0;
    return pad ? next_power_of_two(element_size) : element_size;
  }
};

}  // namespace fbar
