// Tests for Library/MnBase/Meta: type_seq indexing, value_seq reductions, attribute placeholders.
#include <gtest/gtest.h>

#include <cstdint>
#include <tuple>
#include <type_traits>

#include "MnBase/Meta/placeholder.h"
#include "MnBase/Meta/type_seq.h"

namespace fbar {
namespace {

using three = type_seq<int, float, double>;
static_assert(three::count == 3);
static_assert(std::is_same_v<three::type<0>, int>);
static_assert(std::is_same_v<three::type<1>, float>);
static_assert(std::is_same_v<three::type<2>, double>);
static_assert(std::is_same_v<three::apply<std::tuple>, std::tuple<int, float, double>>);
static_assert(type_seq<>::count == 0);

// A repeated type must not confuse the index lookup: each position is its own base.
static_assert(std::is_same_v<type_at_t<2, int, int, char, int>, char>);
static_assert(std::is_same_v<type_at_t<3, int, int, char, int>, int>);

// Long list: the lookup is by overload resolution, not recursion; element 17 of 20.
template <int N>
struct tag {};
static_assert(
    std::is_same_v<type_at_t<17, tag<0>, tag<1>, tag<2>, tag<3>, tag<4>, tag<5>, tag<6>, tag<7>, tag<8>, tag<9>,
                             tag<10>, tag<11>, tag<12>, tag<13>, tag<14>, tag<15>, tag<16>, tag<17>, tag<18>, tag<19>>,
                   tag<17>>);

static_assert(std::is_same_v<type_seq_cat_t<type_seq<int>, type_seq<>, type_seq<float, char>, type_seq<double>>,
                             type_seq<int, float, char, double>>);
static_assert(std::is_same_v<type_seq_cat_t<>, type_seq<>>);

using sizes = value_seq<std::size_t, 4, 8, 1>;
static_assert(sizes::count == 3 && sizes::sum == 13 && sizes::max == 8);
static_assert(sizes::at(1) == 8);
static_assert(sizes::exclusive_sum(0) == 0 && sizes::exclusive_sum(1) == 4 && sizes::exclusive_sum(2) == 12 &&
              sizes::exclusive_sum(3) == 13);
static_assert(value_seq<int>::sum == 0 && value_seq<int>::max == 0);
static_assert(value_seq<int, -3, 5>::sum == 2);

static_assert(std::is_same_v<decltype(placeholder::_0), const std::integral_constant<attrib_index, 0>>);
static_assert(placeholder::_7 == 7 && placeholder::_15 == 15);

// The same reductions evaluated at run time (the functions are also called from device code).
TEST(ValueSeq, RunTimeReductionsMatchHandSums) {
  volatile std::size_t i = 2;  // defeats constant folding so the run-time path is exercised
  EXPECT_EQ(sizes::exclusive_sum(i), 12u);
  EXPECT_EQ(sizes::at(i), 1u);
  using decades = value_seq<std::uint64_t, 10, 20, 30, 40>;
  EXPECT_EQ(decades::exclusive_sum(i + 1), 60u);
}

}  // namespace
}  // namespace fbar
