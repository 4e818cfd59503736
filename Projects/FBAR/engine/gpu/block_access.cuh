// Leaf access into a run-time sized buffer of fixed-size elements with every byte offset folded at compile time.
//
// A structural instance computes a child's offset with the Library's general rule (a loop over the children, a
// modulo per alignment round-up, valid for any run-time extent). Inside kernels that runs per access, in 64-bit
// integer arithmetic with a local-memory table (seen in the PTX: 240 bytes of stack and rem.u64 per particle).
// The engine's buffers are all "one dynamic node holding one dense child" (grid blocks, particle bins), so the
// outer offset is element * Node::size and the inner offsets are compile-time constants: this helper evaluates
// them through the same Library accessors in a constant expression, so the layout stays defined in one place.
#pragma once

#include <cstddef>

#include "MnBase/Memory/structural_instance.h"
#include "MnBase/Meta/config.h"
#include "MnBase/Meta/placeholder.h"

namespace fbar {

/// Leaf C of element `inner` (linear index in the dense child) of element `outer` of a dynamic buffer.
template <typename Outer, placeholder::placeholder_type C>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE auto& block_val(const structural_instance<Outer>& buf, placeholder::index_t<C>,
                                                   int outer, int inner) {
  static_assert(Outer::child_count == 1, "block_val: the outer node holds one dense child per element");
  using Node = typename Outer::template child<0>;
  using V = typename Node::template child<C>::value_type;
  constexpr std::size_t base = typename Node::template accessor<C>{}.base_offset();
  constexpr std::size_t stride = Node::template accessor<C>::element_stride;
  constexpr std::size_t element = Node::size;
  static_assert(typename Outer::template accessor<0>{1}.base_offset() == 0, "block_val: the child starts at 0");
  return *reinterpret_cast<V*>(buf.data() + static_cast<std::size_t>(outer) * element + base +
                               static_cast<std::size_t>(inner) * stride);
}

}  // namespace fbar
