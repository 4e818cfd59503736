// Tests for Library/MnBase/Memory/domain.h: row-major offsets (last index fastest) and their inverse.
#include <gtest/gtest.h>

#include <cstddef>

#include "MnBase/Memory/domain.h"

namespace fbar {
namespace {

using block = domain<char, 4, 4, 4>;
using plane = domain<int, 4, 4>;
using box = domain<int, 2, 3, 5>;  // unequal extents catch a transposed Horner scheme

static_assert(block::dim == 3 && block::extent == 64 && !block::is_dynamic);
static_assert(plane::dim == 2 && plane::extent == 16);
static_assert(box::extent == 30 && box::range(0) == 2 && box::range(1) == 3 && box::range(2) == 5);
// Hand values: (x * 3 + y) * 5 + z.
static_assert(box::offset(0, 0, 1) == 1 && box::offset(0, 1, 0) == 5 && box::offset(1, 0, 0) == 15);
static_assert(box::offset(1, 2, 4) == 29);
static_assert(block::offset(1, 2, 3) == 16 + 8 + 3);

TEST(Domain, BlockOffsetIs16xPlus4yPlusZ) {
  for (int x = 0; x < 4; ++x)
    for (int y = 0; y < 4; ++y)
      for (int z = 0; z < 4; ++z) EXPECT_EQ(block::offset(x, y, z), std::size_t(x * 16 + y * 4 + z));
}

TEST(Domain, PlaneOffsetIs4iPlusJ) {
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) EXPECT_EQ(plane::offset(i, j), std::size_t(4 * i + j));
}

// Visiting coordinates with the last index innermost must produce 0, 1, 2, ... exactly: this is the
// definition of "row-major, last index fastest", independent of any closed formula.
TEST(Domain, LastIndexVariesFastest) {
  std::size_t expected = 0;
  for (int x = 0; x < 2; ++x)
    for (int y = 0; y < 3; ++y)
      for (int z = 0; z < 5; ++z) EXPECT_EQ(box::offset(x, y, z), expected++);
  EXPECT_EQ(expected, box::extent);
}

TEST(Domain, CoordInvertsOffset) {
  for (std::size_t l = 0; l < box::extent; ++l) {
    const auto c = box::coord(l);
    EXPECT_EQ(box::offset(c[0], c[1], c[2]), l);
  }
  const auto c = block::coord(27);  // 27 = 1*16 + 2*4 + 3
  EXPECT_EQ(c[0], 1);
  EXPECT_EQ(c[1], 2);
  EXPECT_EQ(c[2], 3);
}

TEST(Domain, DynamicDomainIsTheIdentity) {
  using d = dynamic_domain<int>;
  static_assert(d::is_dynamic && d::dim == 1);
  EXPECT_EQ(d::offset(12345), 12345u);
  EXPECT_EQ(d::coord(77)[0], 77);
}

}  // namespace
}  // namespace fbar
