// The explicit time-step bound (VALIDATION.md): dt = min(default_dt, min_b CFL_b dx / (c_b + |v|max)).
#pragma once

#include "MnBase/Meta/config.h"
#include "scene/scene.h"

namespace fbar {

/// One body's CFL bound CFL dx / (c + |v|max) [s]: cfl (0, 1], dx [m], wave_speed c [m/s] (solid p-wave speed
/// sqrt((lambda + 2 mu)/rho), fluid sound speed), max_speed [m/s] the largest grid velocity magnitude.
template <typename T>
FBAR_HOST_DEVICE constexpr T cfl_time_step(T cfl, T dx, T wave_speed, T max_speed) {
  return cfl * dx / (wave_speed + max_speed);
}

/// min(a, b) for step bounds (a NaN bound never wins).
template <typename T>
FBAR_HOST_DEVICE constexpr T min_time_step(T a, T b) {
  return b < a ? b : a;
}

/// The scene's default_dt, resolved: the given value, or dx / 100 (numerically, dx in metres -> seconds, ClaymoreUW's
/// default and SCHEMA.md's) when the scene left it out (<= 0).
inline double resolved_default_dt(const SimulationSpec& sim) {
  return sim.default_dt > 0.0 ? sim.default_dt : sim.dx / 100.0;
}

}  // namespace fbar
