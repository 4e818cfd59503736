// Tests for structural_instance.h and allocator.h on the host: the seed's SPGrid, run-time capacities.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "MnBase/Memory/allocator.h"
#include "MnBase/Memory/structural_instance.h"
#include "spgrid_example.h"

namespace fbar {
namespace {

using namespace placeholder;
using test::grid_block_;
using test::grid_buffer_;
using test::spgrid_byte_offset;

/// HostAllocator that records every call, so tests see exactly what an instance asks for.
struct CountingAllocator {
  struct Call {
    void* ptr;
    std::size_t bytes;
  };
  std::vector<Call> allocations, deallocations;
  std::size_t outstanding_bytes = 0;

  void* allocate(std::size_t bytes) {
    void* p = HostAllocator{}.allocate(bytes);
    allocations.push_back({p, bytes});
    outstanding_bytes += bytes;
    return p;
  }
  void deallocate(void* p, std::size_t bytes) {
    deallocations.push_back({p, bytes});
    outstanding_bytes -= bytes;
    HostAllocator{}.deallocate(p, bytes);
  }
};

template <typename F, std::size_t... Cs>
void for_each_index(F& f, std::index_sequence<Cs...>) {
  (f(placeholder::index_t<static_cast<attrib_index>(Cs)>{}), ...);
}
/// Calls f(index_t<0>{}), ..., f(index_t<N-1>{}): a loop over compile-time channel indices.
template <std::size_t N, typename F>
void for_each_index(F&& f) {
  for_each_index(f, std::make_index_sequence<N>{});
}

std::size_t byte_offset(const void* p, const std::byte* base) { return static_cast<const std::byte*>(p) - base; }

static_assert(std::is_trivially_copyable_v<structural_instance<grid_buffer_>>);
static_assert(std::is_trivially_copyable_v<structural_instance<grid_block_>>);
static_assert(sizeof(structural_instance<grid_buffer_>) == sizeof(void*) + sizeof(std::size_t));

TEST(StructuralInstance, SpgridAllocatesCapacityTimesBlockBytes) {
  CountingAllocator counter;
  // 37 blocks: not a power of two, not a compile-time constant of the structure.
  auto grid = spawn<grid_buffer_>(counter, 37);
  ASSERT_EQ(counter.allocations.size(), 1u);
  EXPECT_EQ(counter.allocations[0].bytes, 37u * 1024);
  EXPECT_EQ(grid.capacity(), 37u);
  EXPECT_EQ(grid.size_bytes(), 37u * 1024);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(grid.data()) % HostAllocator::alignment, 0u);

  grid.deallocate(counter);
  ASSERT_EQ(counter.deallocations.size(), 1u);
  EXPECT_EQ(counter.deallocations[0].ptr, counter.allocations[0].ptr);
  EXPECT_EQ(counter.deallocations[0].bytes, 37u * 1024);
  EXPECT_EQ(counter.outstanding_bytes, 0u);
  EXPECT_FALSE(grid);
  EXPECT_EQ(grid.capacity(), 0u);
}

TEST(StructuralInstance, SpgridValSitsAtTheDocumentedByteOffset) {
  HostAllocator host;
  auto grid = spawn<grid_buffer_>(host, 37);
  for (std::size_t b : {0, 1, 17, 36}) {
    const auto block = grid.ch(_0, b);
    EXPECT_EQ(byte_offset(block.data(), grid.data()), b * 1024);
    for_each_index<4>([&](auto c) {
      for (int x = 0; x < 4; ++x)
        for (int y = 0; y < 4; ++y)
          for (int z = 0; z < 4; ++z)
            EXPECT_EQ(byte_offset(&block.val(c, x, y, z), grid.data()), spgrid_byte_offset(b, c, x, y, z))
                << "block " << b << " channel " << c << " node " << x << y << z;
    });
  }
  grid.deallocate(host);
}

TEST(StructuralInstance, ValVal1dAndChAgree) {
  HostAllocator host;
  auto grid = spawn<grid_buffer_>(host, 5);
  for (std::size_t b = 0; b < grid.capacity(); ++b) {
    const auto block = grid.ch(_0, b);
    for_each_index<4>([&](auto c) {
      for (std::size_t cell = 0; cell < 64; ++cell) {
        const auto xyz = grid_block_::domain::coord(cell);
        EXPECT_EQ(&block.val_1d(c, cell), &block.val(c, xyz[0], xyz[1], xyz[2]));
      }
    });
  }
  grid.deallocate(host);
}

// Values written through the instance are found in the raw bytes at the documented offsets, and read
// back through val_1d; a copy of the handle aliases the same storage.
TEST(StructuralInstance, HostWritesLandInTheRawBytes) {
  HostAllocator host;
  const std::size_t capacity = 6;
  auto grid = spawn<grid_buffer_>(host, capacity);
  const auto value = [](std::size_t b, std::size_t c, std::size_t cell) { return float((b * 4 + c) * 64 + cell); };
  const auto writer = grid;  // the handle is a value: both copies address the same blocks
  for (std::size_t b = 0; b < capacity; ++b)
    for_each_index<4>([&](auto c) {
      for (int x = 0; x < 4; ++x)
        for (int y = 0; y < 4; ++y)
          for (int z = 0; z < 4; ++z) writer.ch(_0, b).val(c, x, y, z) = value(b, c, x * 16 + y * 4 + z);
    });

  for (std::size_t b = 0; b < capacity; ++b)
    for (std::size_t c = 0; c < 4; ++c)
      for (std::size_t cell = 0; cell < 64; ++cell) {
        float raw = 0.f;
        std::memcpy(&raw, grid.data() + spgrid_byte_offset(b, c, cell / 16, cell / 4 % 4, cell % 4), sizeof raw);
        EXPECT_EQ(raw, value(b, c, cell));  // exact: small integers are exact in float
      }
  for (std::size_t b = 0; b < capacity; ++b)
    for_each_index<4>([&](auto c) {
      for (std::size_t cell = 0; cell < 64; ++cell) EXPECT_EQ(grid.ch(_0, b).val_1d(c, cell), value(b, c, cell));
    });
  grid.deallocate(host);
}

// Two attributes of different types in SoA under a dynamic node: the double array starts after
// capacity floats (rounded to 8), so the offsets must follow the capacity the instance carries.
TEST(StructuralInstance, DynamicSoAFollowsTheRunTimeCapacity) {
  using soa =
      decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact, attrib_layout::soa>;
  using particles_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, f32_, f64_>;
  CountingAllocator counter;
  for (std::size_t capacity : {5, 8, 1000}) {
    auto p = spawn<particles_>(counter, capacity);
    EXPECT_EQ(counter.allocations.back().bytes, capacity * 16);
    const std::size_t double_base = (capacity * 4 + 7) / 8 * 8;
    EXPECT_EQ(byte_offset(&p.val(_1, 0), p.data()), double_base);
    EXPECT_EQ(byte_offset(&p.val_1d(_0, capacity - 1), p.data()), (capacity - 1) * 4);
    for (std::size_t i = 0; i < capacity; ++i) {
      p.val(_0, i) = float(i);
      p.val(_1, i) = -double(i) - 0.5;
    }
    // Any overlap between the two arrays would have overwritten earlier writes.
    for (std::size_t i = 0; i < capacity; ++i) {
      EXPECT_EQ(p.val_1d(_0, i), float(i));
      EXPECT_EQ(p.val_1d(_1, i), -double(i) - 0.5);
    }
    p.deallocate(counter);
  }
  EXPECT_EQ(counter.outstanding_bytes, 0u);
}

TEST(StructuralInstance, CompileTimeNodeAndHashSlots) {
  CountingAllocator counter;
  auto block = spawn<grid_block_>(counter);
  EXPECT_EQ(counter.allocations.back().bytes, 1024u);
  EXPECT_EQ(block.capacity(), 64u);
  block.val(_3, 3, 3, 3) = 2.5f;
  EXPECT_EQ(block.val_1d(_3, 63), 2.5f);
  block.deallocate(counter);

  using soa = test::spgrid_decorator;
  using hashed_ = structural<structural_type::hash, domain<int, 32, 32, 32>, soa, grid_block_>;
  auto slots = spawn<hashed_>(counter, 10);
  EXPECT_EQ(counter.allocations.back().bytes, 10u * 1024);
  EXPECT_EQ(byte_offset(&slots.ch(_0, 9).val(_2, 1, 0, 0), slots.data()), 9u * 1024 + 2 * 256 + 16 * 4);
  slots.deallocate(counter);
  EXPECT_EQ(counter.outstanding_bytes, 0u);
}

// Projects name attributes with tag types that derive from index_t<I> and carry metadata; such a tag
// must select the same leaf as the bare placeholder.
struct MomentumX : placeholder::index_t<1> {
  static constexpr const char* name = "momentum_x";
};

TEST(StructuralInstance, NamedTagSelectsTheSameLeafAsItsIndex) {
  HostAllocator host;
  auto grid = spawn<grid_buffer_>(host, 3);
  EXPECT_EQ(&grid.ch(_0, 2).val(MomentumX{}, 1, 2, 3), &grid.ch(_0, 2).val(_1, 1, 2, 3));
  EXPECT_EQ(&grid.ch(_0, 2).val_1d(MomentumX{}, 27), &grid.ch(_0, 2).val(_1, 1, 2, 3));
  grid.deallocate(host);
}

TEST(StructuralInstance, EmptyAndDoubleAllocation) {
  CountingAllocator counter;
  auto none = spawn<grid_buffer_>(counter, 0);
  EXPECT_TRUE(counter.allocations.empty());  // nothing to allocate
  EXPECT_FALSE(none);
  none.deallocate(counter);
  EXPECT_TRUE(counter.deallocations.empty());

  auto grid = spawn<grid_buffer_>(counter, 2);
  EXPECT_THROW(grid.allocate_handle(counter, 4), std::logic_error);  // would leak the first allocation
  grid.deallocate(counter);
  EXPECT_EQ(counter.outstanding_bytes, 0u);
}

}  // namespace
}  // namespace fbar
