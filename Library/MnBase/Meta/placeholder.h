// Compile-time attribute indices _0.._15 that select a child of a structural node.
//
// A child index must be a compile-time value because each child may have a different type; passing
// it as std::integral_constant lets `node.val(_1, x, y)` deduce the index from an ordinary argument.
// Projects give these positional indices names at their own level, either as aliases
//   inline constexpr auto grid_mass = fbar::placeholder::_0;
// or as tag types deriving from index_t<I> that carry more (output name, unit); a derived tag binds to
// the std::integral_constant parameter of ch/val/val_1d. Kernels then read `block.val(grid_mass, x, y, z)`.
#pragma once

#include <type_traits>

namespace fbar {

namespace placeholder {

using placeholder_type = unsigned;

/// The type of the index constant for child I.
template <placeholder_type I>
using index_t = std::integral_constant<placeholder_type, I>;

inline constexpr index_t<0> _0{};
inline constexpr index_t<1> _1{};
inline constexpr index_t<2> _2{};
inline constexpr index_t<3> _3{};
inline constexpr index_t<4> _4{};
inline constexpr index_t<5> _5{};
inline constexpr index_t<6> _6{};
inline constexpr index_t<7> _7{};
inline constexpr index_t<8> _8{};
inline constexpr index_t<9> _9{};
inline constexpr index_t<10> _10{};
inline constexpr index_t<11> _11{};
inline constexpr index_t<12> _12{};
inline constexpr index_t<13> _13{};
inline constexpr index_t<14> _14{};
inline constexpr index_t<15> _15{};

}  // namespace placeholder

/// Index of a child (attribute) of a structural node.
using attrib_index = placeholder::placeholder_type;

}  // namespace fbar
