// Index domains: map multi-dimensional coordinates of a structural node to a linear element index.
//
// domain<Tn, N0, N1, ..., Nd-1> is a box of N0 x N1 x ... x Nd-1 elements known at compile time,
// laid out row-major: the LAST coordinate varies fastest, so
//   offset(i0, ..., id-1) = ((i0 * N1 + i1) * N2 + i2) ... (Horner form)
// and for a 4x4x4 grid block offset(x, y, z) = 16 x + 4 y + z.
// Coordinates must lie in [0, Nk); nothing is checked (this sits on the hottest path of every kernel).
//
// dynamic_domain<Tn> is the 1-D domain of a run-time sized node (a dynamic buffer or the slots of a
// hash node): its extent is the capacity the instance carries, chosen when it is allocated.
#pragma once

#include <cstddef>
#include <type_traits>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

template <typename Tn, Tn... Ns>
struct domain {
  static_assert(std::is_integral_v<Tn>, "domain: the index type must be an integer type");
  static_assert(sizeof...(Ns) > 0, "domain: give at least one extent");
  static_assert(((Ns > 0) && ...), "domain: every extent must be positive");

  using index_type = Tn;
  /// Coordinates of one element, (i0, ..., id-1).
  using coord_type = Vec<Tn, static_cast<int>(sizeof...(Ns))>;

  static constexpr bool is_dynamic = false;
  static constexpr int dim = static_cast<int>(sizeof...(Ns));
  /// Number of elements, N0 * N1 * ... * Nd-1.
  static constexpr std::size_t extent = (std::size_t{1} * ... * static_cast<std::size_t>(Ns));

  /// Extent along axis d (0 <= d < dim).
  FBAR_HOST_DEVICE static constexpr std::size_t range(int d) {
    const std::size_t ns[] = {static_cast<std::size_t>(Ns)...};
    return ns[d];
  }

  /// Linear element index of coordinates (i0, ..., id-1), row-major (last fastest).
  template <typename... Is>
  FBAR_HOST_DEVICE static constexpr std::size_t offset(Is... is) {
    static_assert(sizeof...(Is) == sizeof...(Ns), "domain::offset: give one coordinate per dimension");
    std::size_t r = 0;
    // Two packs of equal length expand in lockstep: r = (r * N_k + i_k) for k = 0 .. dim-1.
    ((r = r * static_cast<std::size_t>(Ns) + static_cast<std::size_t>(is)), ...);
    return r;
  }

  /// Inverse of offset(): the coordinates of linear index l (0 <= l < extent).
  FBAR_HOST_DEVICE static constexpr coord_type coord(std::size_t l) {
    coord_type c{};
    for (int d = dim - 1; d >= 0; --d) {
      c[d] = static_cast<Tn>(l % range(d));
      l /= range(d);
    }
    return c;
  }
};

template <typename Tn>
struct dynamic_domain {
  static_assert(std::is_integral_v<Tn>, "dynamic_domain: the index type must be an integer type");

  using index_type = Tn;
  using coord_type = Vec<Tn, 1>;

  static constexpr bool is_dynamic = true;
  static constexpr int dim = 1;
  // No `extent`: it is a run-time value carried by the instance (structural_instance::capacity()).

  template <typename I>
  FBAR_HOST_DEVICE static constexpr std::size_t offset(I i) {
    return static_cast<std::size_t>(i);
  }
  FBAR_HOST_DEVICE static constexpr coord_type coord(std::size_t l) { return coord_type{{static_cast<Tn>(l)}}; }
};

}  // namespace fbar
