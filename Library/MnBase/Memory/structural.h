// Structural nodes: compile-time description of a hierarchical data structure and its byte layout.
//
// A structural node is  structural<Type, Domain, Decorator, Children...>:
//   Type       entity (a leaf value), dense (a compile-time box of elements), dynamic (a 1-D buffer whose
//              capacity is chosen at run time), hash (a run-time number of slots, each addressed by the
//              slot index a hash table hands out; the table itself lives in the project).
//   Domain     the index space of the elements: domain<Tn, Ns...> (compile time) or dynamic_domain<Tn>.
//              For a hash node it is the KEY domain the table maps from; storage is addressed by slot.
//   Decorator  allocation, padding and attribute layout (decorator.h).
//   Children   the attributes of one element: leaves structural_entity<T> or other structural nodes.
//
// Byte layout (all offsets in bytes from the start of the node's storage):
//   - Attributes of an element are placed like the members of a C struct: each at the next multiple of
//     its own alignment, the element rounded up to the largest alignment (element_size). Claymore packed
//     attributes byte-tight, which puts an f64 after an f32 at offset 4: a misaligned-address fault on
//     the GPU. Natural alignment keeps every access aligned while adding no bytes to all-f32 structures.
//   - align padding rounds element_size up to the next power of two (element_storage_size).
//   - AoS: attribute I of element e sits at  e * element_storage_size + offset_I.
//     SoA: attribute I of element e sits at  base_I(extent) + e * size(child I), where the arrays follow
//          each other in child order, each starting at its child's alignment:
//          base_0 = 0, base_I = round_up(base_{I-1} + extent * size(child I-1), align(child I)).
//     SoA bases depend on the extent, so for a dynamic or hash node they use the run-time capacity.
//   - A node occupies extent * element_storage_size bytes (the SoA arrays always fit inside).
//
// Only the outermost node of a structure may be run-time sized (dynamic or hash): one instance carries one
// capacity. Everything below it has compile-time extents, as in every fbar structure (grid buffer of
// blocks, particle buffer of bins, hash slots of blocks).
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "MnBase/Memory/decorator.h"
#include "MnBase/Memory/domain.h"
#include "MnBase/Meta/config.h"
#include "MnBase/Meta/placeholder.h"
#include "MnBase/Meta/type_seq.h"

namespace fbar {

enum class structural_type : unsigned { entity = 0, hash = 1, dense = 2, dynamic = 3 };

/// Leaf node: one value of type T (T = void: an empty attribute taking no bytes).
template <typename T>
struct structural_entity {
  static_assert(std::is_trivially_copyable_v<T>, "structural_entity: values are copied as raw bytes");
  static constexpr structural_type type = structural_type::entity;
  static constexpr bool is_run_time_sized = false;
  using value_type = T;
  static constexpr std::size_t size = sizeof(T);
  static constexpr std::size_t alignment = alignof(T);
};

template <>
struct structural_entity<void> {
  static constexpr structural_type type = structural_type::entity;
  static constexpr bool is_run_time_sized = false;
  using value_type = void;
  static constexpr std::size_t size = 0;
  static constexpr std::size_t alignment = 1;
};

using empty_ = structural_entity<void>;
using i32_ = structural_entity<std::int32_t>;
using u32_ = structural_entity<std::uint32_t>;
using i64_ = structural_entity<std::int64_t>;
using u64_ = structural_entity<std::uint64_t>;
using f32_ = structural_entity<float>;
using f64_ = structural_entity<double>;

namespace detail {

/// Placement of the children of one element (struct-like for AoS, array-after-array for SoA).
template <typename... Children>
struct element_layout {
  // Checked here, the first place a structural instantiates, so these messages come before any other.
  static_assert(sizeof...(Children) > 0, "structural: give at least one child (attribute)");
  static_assert((!Children::is_run_time_sized && ...),
                "structural: only the outermost node may be dynamic or hash (an instance carries one capacity)");

  using sizes = value_seq<std::size_t, Children::size...>;
  using alignments = value_seq<std::size_t, Children::alignment...>;

  static constexpr std::size_t alignment = alignments::max > 1 ? alignments::max : 1;

  /// Byte offset of child i inside an element when `extent` elements are stored: AoS uses extent 1
  /// (one element), SoA the node's extent (whole arrays precede child i).
  FBAR_HOST_DEVICE static constexpr std::size_t offset(std::size_t i, std::size_t extent) {
    std::size_t off = 0;
    for (std::size_t k = 0; k < i; ++k) off = round_up(off, alignments::at(k)) + extent * sizes::at(k);
    return round_up(off, alignments::at(i));
  }

  /// C-struct size of one element: end of the last child, rounded up to the element's alignment.
  FBAR_HOST_DEVICE static constexpr std::size_t struct_size() {
    constexpr std::size_t n = sizeof...(Children);
    if constexpr (n == 0) {
      return 0;
    } else {
      return round_up(offset(n - 1, 1) + sizes::at(n - 1), alignment);
    }
  }
  static constexpr std::size_t size = struct_size();
};

/// `extent` and `size` exist only for nodes whose extent is known at compile time.
template <bool RunTimeSized, typename Domain, std::size_t ElementStorageSize>
struct static_extent_traits {
  static constexpr std::size_t extent = Domain::extent;
  /// Bytes the node occupies (what a parent reserves for it).
  static constexpr std::size_t size = extent * ElementStorageSize;
};

template <typename Domain, std::size_t ElementStorageSize>
struct static_extent_traits<true, Domain, ElementStorageSize> {};

}  // namespace detail

template <structural_type Type, typename Domain, typename Decorator, typename... Children>
struct structural
    : detail::static_extent_traits<Type == structural_type::dynamic || Type == structural_type::hash, Domain,
                                   Decorator::storage_size(detail::element_layout<Children...>::size)> {
  static_assert(Type != structural_type::entity, "structural: a leaf is structural_entity<T>, not structural");
  static_assert(Decorator::alloc_policy == structural_allocation_policy::full_allocation,
                "structural: only full_allocation is supported (see decorator.h)");
  static_assert(Type != structural_type::dense || !Domain::is_dynamic,
                "structural: a dense node needs a compile-time domain<Tn, Ns...>");
  static_assert(Type != structural_type::dynamic || Domain::is_dynamic,
                "structural: a dynamic node takes dynamic_domain<Tn>; its capacity is chosen at allocation");

 private:
  using layout = detail::element_layout<Children...>;

 public:
  using domain = Domain;  ///< for a hash node: the key domain of its table
  using decoration = Decorator;
  using children = type_seq<Children...>;
  template <attrib_index I>
  using child = typename children::template type<I>;

  static constexpr structural_type type = Type;
  static constexpr bool is_run_time_sized = Type == structural_type::dynamic || Type == structural_type::hash;
  static constexpr std::size_t child_count = sizeof...(Children);
  /// Alignment every element (and so the whole node) needs: the largest child alignment.
  static constexpr std::size_t alignment = layout::alignment;
  /// Bytes of one element's attributes, C-struct rules (natural alignment, rounded to `alignment`).
  static constexpr std::size_t element_size = layout::size;
  /// Bytes one element occupies: element_size, or its next power of two under the align policy.
  static constexpr std::size_t element_storage_size = Decorator::storage_size(element_size);

  /// Bytes of storage for `extent` elements (the run-time capacity of a dynamic or hash node).
  FBAR_HOST_DEVICE static constexpr std::size_t bytes(std::size_t extent) { return extent * element_storage_size; }

  /// Element index of a coordinate tuple: the domain's row-major offset, or the element / slot index
  /// itself for a dynamic or hash node.
  template <typename... Is>
  FBAR_HOST_DEVICE static constexpr std::size_t element_index(Is... is) {
    if constexpr (is_run_time_sized) {
      static_assert(sizeof...(Is) == 1, "a dynamic or hash node is addressed by one index (element or slot)");
      return (static_cast<std::size_t>(is), ...);
    } else {
      return Domain::offset(is...);
    }
  }

  /// Byte offsets of child I. Construct with the node's extent (its capacity for dynamic/hash nodes;
  /// the default constructor is for compile-time extents only).
  template <attrib_index I>
  class accessor {
    static_assert(I < sizeof...(Children), "accessor: child index out of range");

   public:
    using child_type = type_at_t<I, Children...>;

    /// Bytes between element e and element e+1 of child I.
    static constexpr std::size_t element_stride =
        Decorator::layout == attrib_layout::aos ? element_storage_size : child_type::size;

    FBAR_HOST_DEVICE constexpr accessor() : extent_{compile_time_extent()} {}
    FBAR_HOST_DEVICE explicit constexpr accessor(std::size_t extent) : extent_{extent} {}

    /// Offset of child I of element 0.
    FBAR_HOST_DEVICE constexpr std::size_t base_offset() const {
      return layout::offset(I, Decorator::layout == attrib_layout::aos ? 1 : extent_);
    }
    /// Offset of child I of the element at these coordinates.
    template <typename... Is>
    FBAR_HOST_DEVICE constexpr std::size_t coord_offset(Is... is) const {
      return base_offset() + element_index(is...) * element_stride;
    }
    /// Offset of child I of linear element i.
    FBAR_HOST_DEVICE constexpr std::size_t linear_offset(std::size_t i) const {
      return base_offset() + i * element_stride;
    }

   private:
    FBAR_HOST_DEVICE static constexpr std::size_t compile_time_extent() {
      static_assert(!is_run_time_sized, "accessor of a dynamic or hash node: construct it with the capacity");
      if constexpr (is_run_time_sized) {
        return 0;
      } else {
        return Domain::extent;
      }
    }

    std::size_t extent_;
  };
};

}  // namespace fbar
