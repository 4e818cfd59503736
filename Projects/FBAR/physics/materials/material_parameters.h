// What a material declares about its scene parameters: JSON key, unit, valid range, Froude scaling and meaning.
//
// A material type lists its parameters once (M::kParameters, an array of MaterialParameter); the scene parser
// (type and range checks, the error for a key the law does not read), --check's printout, the scene writer, Froude
// scaling and the user guide's parameter table (tested in tests/scene) all walk that list, so a parameter is
// described in exactly one place. Values live in MaterialSpec (scene.h); the entry points at its field.
#pragma once

#include <limits>

#include "physics/material_spec.h"

namespace fbar {

/// Closed or open interval of valid values of a numeric parameter.
struct ValidRange {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;

  constexpr bool contains(double x) const {
    return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
  }
};

inline constexpr ValidRange kAnyValue{};
inline constexpr ValidRange kPositiveValue{0.0, std::numeric_limits<double>::infinity(), true, false};
inline constexpr ValidRange kNonNegativeValue{0.0, std::numeric_limits<double>::infinity(), false, false};

/// Where a parameter's value lives in MaterialSpec.
using NumberField = double MaterialSpec::*;
using FlagField = bool MaterialSpec::*;

/// One scene parameter of a material (bodies[].material.<key>).
struct MaterialParameter {
  const char* key;                          ///< JSON key, e.g. "youngs_modulus"
  const char* unit;                         ///< "Pa", "Pa s", "deg", "-" (dimensionless)
  const char* meaning;                      ///< one line for --check and the user guide
  ValidRange range;                         ///< numbers only
  NumberField number = nullptr;             ///< the field of a numeric parameter
  FlagField flag = nullptr;                 ///< the field of a boolean parameter
  /// Froude scaling by a length factor s multiplies the value by s^froude_power (stress 1, viscosity 1.5, 0 for
  /// dimensionless values and angles).
  double froude_power = 0.0;

  constexpr bool is_flag() const { return flag != nullptr; }
};

/// A numeric parameter.
constexpr MaterialParameter number_parameter(const char* key, const char* unit, NumberField field,
                                             ValidRange range, double froude_power, const char* meaning) {
  return MaterialParameter{key, unit, meaning, range, field, nullptr, froude_power};
}
/// A true/false parameter.
constexpr MaterialParameter flag_parameter(const char* key, FlagField field, const char* meaning) {
  return MaterialParameter{key, "-", meaning, kAnyValue, nullptr, field, 0.0};
}

/// The elastic pair every solid reads (E, nu): Lame parameters mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)).
inline constexpr MaterialParameter kYoungsModulusParameter =
    number_parameter("youngs_modulus", "Pa", &MaterialSpec::youngs_modulus, kPositiveValue, 1.0, "Young's modulus E");
inline constexpr MaterialParameter kPoissonRatioParameter =
    number_parameter("poisson_ratio", "-", &MaterialSpec::poisson_ratio, ValidRange{-1.0, 0.5, true, true}, 0.0,
                     "Poisson's ratio nu, -1 < nu < 0.5");

/// What a material's check of a combination of parameters found wrong (empty key: nothing).
struct ParameterProblem {
  const char* key = nullptr;  ///< the parameter to name in the error
  const char* expected = "";  ///< what was expected instead
};

}  // namespace fbar
