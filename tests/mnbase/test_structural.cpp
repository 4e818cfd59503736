// Tests for Library/MnBase/Memory/structural.h: element sizes, padding, AoS/SoA attribute offsets.
//
// Expected offsets are derived by hand in the comments from the rules in structural.h:
//   AoS: attribute I of element e at  e * element_storage_size + offset_I (C-struct placement).
//   SoA: attribute I of element e at  base_I + e * size_I, base_I = end of the previous array rounded up
//        to alignof(attribute I).
//   align padding: element_storage_size = next power of two of element_size.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <utility>
#include <vector>

#include "MnBase/Memory/structural.h"

namespace fbar {
namespace {

using aos_align =
    decorator<structural_allocation_policy::full_allocation, structural_padding_policy::align, attrib_layout::aos>;
using soa_align =
    decorator<structural_allocation_policy::full_allocation, structural_padding_policy::align, attrib_layout::soa>;
using aos_compact =
    decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact, attrib_layout::aos>;
using soa_compact =
    decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact, attrib_layout::soa>;

// The seed's Figure 8 pair: a 4x4 domain of {float, double}, AoS and SoA, align padding.
using Attrib0 = structural_entity<float>;
using Attrib1 = structural_entity<double>;
using StructuralA = structural<structural_type::dense, domain<int, 4, 4>, aos_align, Attrib0, Attrib1>;
using StructuralB = structural<structural_type::dense, domain<int, 4, 4>, soa_align, Attrib0, Attrib1>;

// AoS element: float at 0 (4 B), double at round_up(4, 8) = 8 (8 B); end 16, alignment 8 -> 16 B.
// align: next_pow2(16) = 16. Node: 16 elements * 16 B = 256 B.
static_assert(StructuralA::alignment == 8);
static_assert(StructuralA::element_size == 16 && StructuralA::element_storage_size == 16);
static_assert(StructuralA::extent == 16 && StructuralA::size == 256);
static_assert(StructuralA::accessor<0>::element_stride == 16 && StructuralA::accessor<1>::element_stride == 16);
static_assert(StructuralA::accessor<0>{}.base_offset() == 0 && StructuralA::accessor<1>{}.base_offset() == 8);
// SoA: float[16] at [0, 64), double[16] at [64, 192) (64 is already a multiple of 8); strides 4 and 8.
// Element storage is still 16 B, so the node reserves the same 256 B (the last 64 B are tail padding).
static_assert(StructuralB::element_storage_size == 16 && StructuralB::size == 256);
static_assert(StructuralB::accessor<0>::element_stride == 4 && StructuralB::accessor<1>::element_stride == 8);
static_assert(StructuralB::accessor<0>{}.base_offset() == 0 && StructuralB::accessor<1>{}.base_offset() == 64);

TEST(Structural, SeedStructuralAAoSOffsetsByHand) {
  // Element (2, 3) is linear element 4*2 + 3 = 11: float at 11*16 = 176, double at 176 + 8 = 184.
  EXPECT_EQ(StructuralA::accessor<0>{}.coord_offset(2, 3), 176u);
  EXPECT_EQ(StructuralA::accessor<1>{}.coord_offset(2, 3), 184u);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const std::size_t e = 4 * i + j;
      EXPECT_EQ(StructuralA::accessor<0>{}.coord_offset(i, j), e * 16);
      EXPECT_EQ(StructuralA::accessor<1>{}.coord_offset(i, j), e * 16 + 8);
      EXPECT_EQ(StructuralA::accessor<1>{}.linear_offset(e), StructuralA::accessor<1>{}.coord_offset(i, j));
    }
}

TEST(Structural, SeedStructuralBSoAOffsetsByHand) {
  // Element 11: float at 11*4 = 44, double at 64 + 11*8 = 152.
  EXPECT_EQ(StructuralB::accessor<0>{}.coord_offset(2, 3), 44u);
  EXPECT_EQ(StructuralB::accessor<1>{}.coord_offset(2, 3), 152u);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const std::size_t e = 4 * i + j;
      EXPECT_EQ(StructuralB::accessor<0>{}.coord_offset(i, j), e * 4);
      EXPECT_EQ(StructuralB::accessor<1>{}.coord_offset(i, j), 64 + e * 8);
    }
}

// Three floats (a velocity) per node of a 4x4x4 block: the case where the two padding policies differ.
using vel_compact = structural<structural_type::dense, domain<char, 4, 4, 4>, aos_compact, f32_, f32_, f32_>;
using vel_align = structural<structural_type::dense, domain<char, 4, 4, 4>, aos_align, f32_, f32_, f32_>;
// compact: 12 B elements, 64 * 12 = 768 B. align: next_pow2(12) = 16 B elements, 1024 B.
static_assert(vel_compact::element_size == 12 && vel_compact::element_storage_size == 12 && vel_compact::size == 768);
static_assert(vel_align::element_size == 12 && vel_align::element_storage_size == 16 && vel_align::size == 1024);
// Five floats: 20 B -> 32 B under align.
static_assert(
    structural<structural_type::dense, domain<int, 1>, aos_align, f32_, f32_, f32_, f32_, f32_>::element_storage_size ==
    32);
// A power of two already is left alone: 4 floats stay 16 B.
static_assert(
    structural<structural_type::dense, domain<int, 1>, aos_align, f32_, f32_, f32_, f32_>::element_storage_size == 16);
// C-struct tail rounding (both policies): {double, float} ends at 12, alignment 8 -> 16 B.
static_assert(structural<structural_type::dense, domain<int, 1>, aos_compact, f64_, f32_>::element_size == 16);
// An empty attribute takes no bytes.
static_assert(structural<structural_type::dense, domain<int, 1>, aos_compact, f32_, empty_, f32_>::element_size == 8);

TEST(Structural, AlignPaddingChangesTheAoSStrideOnly) {
  // Node (1, 2, 3) = element 27; third float at +8 inside the element.
  EXPECT_EQ(vel_compact::accessor<2>{}.coord_offset(1, 2, 3), 27u * 12 + 8);  // 332
  EXPECT_EQ(vel_align::accessor<2>{}.coord_offset(1, 2, 3), 27u * 16 + 8);    // 440
  EXPECT_EQ(vel_compact::accessor<2>::element_stride, 12u);
  EXPECT_EQ(vel_align::accessor<2>::element_stride, 16u);
}

TEST(Structural, AlignPaddingLeavesSoAArraysPackedAndPadsTheNode) {
  using soa_c = structural<structural_type::dense, domain<char, 4, 4, 4>, soa_compact, f32_, f32_, f32_>;
  using soa_a = structural<structural_type::dense, domain<char, 4, 4, 4>, soa_align, f32_, f32_, f32_>;
  // Arrays of 64 floats: bases 0, 256, 512 under both policies; node 768 B compact, 1024 B align.
  EXPECT_EQ(soa_c::accessor<2>{}.base_offset(), 512u);
  EXPECT_EQ(soa_a::accessor<2>{}.base_offset(), 512u);
  EXPECT_EQ(soa_c::size, 768u);
  EXPECT_EQ(soa_a::size, 1024u);
}

// A structural child contributes its whole size: {grid block (1024 B), float} per element.
using block_ = structural<structural_type::dense, domain<char, 4, 4, 4>, soa_compact, f32_, f32_, f32_, f32_>;
using pair_ = structural<structural_type::dense, domain<int, 2>, aos_compact, block_, f32_>;
static_assert(block_::size == 1024 && block_::alignment == 4);
static_assert(pair_::element_size == 1028 && pair_::size == 2056);
static_assert(structural<structural_type::dense, domain<int, 2>, aos_align, block_, f32_>::element_storage_size ==
              2048);
static_assert(pair_::accessor<0>{}.coord_offset(1) == 1028 && pair_::accessor<1>{}.coord_offset(1) == 1028 + 1024);

// A dynamic node's SoA bases follow its run-time capacity; AoS offsets do not depend on it.
using dyn_soa = structural<structural_type::dynamic, dynamic_domain<int>, soa_compact, f32_, f64_>;
using dyn_aos = structural<structural_type::dynamic, dynamic_domain<int>, aos_compact, f32_, f64_>;
static_assert(dyn_soa::is_run_time_sized && dyn_soa::element_storage_size == 16 && dyn_soa::bytes(5) == 80);

TEST(Structural, DynamicSoABasesUseTheRunTimeCapacity) {
  // capacity 5: float[5] ends at 20, doubles start at round_up(20, 8) = 24. capacity 8: 32, already aligned.
  EXPECT_EQ(dyn_soa::accessor<1>{5}.base_offset(), 24u);
  EXPECT_EQ(dyn_soa::accessor<1>{8}.base_offset(), 32u);
  EXPECT_EQ(dyn_soa::accessor<1>{5}.linear_offset(4), 24u + 4 * 8);
  EXPECT_EQ(dyn_soa::accessor<1>{1000}.coord_offset(999), 4000u + 999 * 8);
  EXPECT_EQ(dyn_aos::accessor<1>{5}.linear_offset(3), 3u * 16 + 8);
  EXPECT_EQ(dyn_aos::accessor<1>{8}.linear_offset(3), 3u * 16 + 8);
}

// A hash node stores a run-time number of slots; its domain is the key space the table maps from.
using hashed_blocks_ = structural<structural_type::hash, domain<int, 64, 64, 64>, soa_compact, block_>;
static_assert(hashed_blocks_::is_run_time_sized && hashed_blocks_::domain::extent == 262144);

TEST(Structural, HashNodeIsAddressedBySlot) {
  EXPECT_EQ(hashed_blocks_::accessor<0>{100}.coord_offset(7), 7u * 1024);
  EXPECT_EQ(hashed_blocks_::bytes(100), 102400u);
}

// A particle bin composed from attribute lists (material's + scheme's), as the project builds them:
// 32 particles, SoA, {x, y, z, J} + {vx, vy, vz}: 7 arrays of 32 floats, 7 * 128 = 896 B.
template <typename... Attribs>
using bin_of = structural<structural_type::dense, domain<int, 32>, soa_compact, Attribs...>;
using fluid_attribs = type_seq<f32_, f32_, f32_, f32_>;
using flip_attribs = type_seq<f32_, f32_, f32_>;
using fluid_flip_bin_ = type_seq_cat_t<fluid_attribs, flip_attribs>::apply<bin_of>;
static_assert(fluid_flip_bin_::child_count == 7 && fluid_flip_bin_::size == 896);
static_assert(fluid_flip_bin_::accessor<4>{}.coord_offset(5) == 4 * 128 + 5 * 4);

// Invariants every layout must satisfy, checked over every (attribute, element) of a node:
// each leaf is naturally aligned, lies inside bytes(extent), and no two leaves overlap.
template <typename S, std::size_t... Is>
void check_layout_invariants(std::size_t extent, std::index_sequence<Is...>) {
  std::vector<std::pair<std::size_t, std::size_t>> spans;  // [begin, end) in bytes
  auto add = [&](auto i) {
    constexpr attrib_index I = decltype(i)::value;
    using C = typename S::template child<I>;
    const typename S::template accessor<I> acc{extent};
    for (std::size_t e = 0; e < extent; ++e) {
      const std::size_t off = acc.linear_offset(e);
      EXPECT_EQ(off % C::alignment, 0u) << "attribute " << I << " element " << e;
      if (C::size != 0) spans.emplace_back(off, off + C::size);
    }
  };
  (add(std::integral_constant<attrib_index, static_cast<attrib_index>(Is)>{}), ...);
  std::sort(spans.begin(), spans.end());
  for (std::size_t k = 1; k < spans.size(); ++k) EXPECT_LE(spans[k - 1].second, spans[k].first) << "overlap";
  if (!spans.empty()) {
    EXPECT_LE(spans.back().second, S::bytes(extent));
  }
}

template <typename S>
void check_layout_invariants(std::size_t extent) {
  check_layout_invariants<S>(extent, std::make_index_sequence<S::child_count>{});
}

TEST(Structural, LeavesAreAlignedDisjointAndInsideTheNode) {
  check_layout_invariants<StructuralA>(StructuralA::extent);
  check_layout_invariants<StructuralB>(StructuralB::extent);
  check_layout_invariants<vel_compact>(vel_compact::extent);
  check_layout_invariants<pair_>(pair_::extent);
  using mixed = structural<structural_type::dense, domain<int, 3>, soa_compact, f32_, f64_, i32_, u64_, empty_>;
  check_layout_invariants<mixed>(mixed::extent);
  for (std::size_t capacity : {1, 3, 5, 8, 33}) {
    check_layout_invariants<dyn_soa>(capacity);
    check_layout_invariants<dyn_aos>(capacity);
  }
}

}  // namespace
}  // namespace fbar
