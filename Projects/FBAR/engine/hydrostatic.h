// The hydrostatic initial state of a fluid body (bodies[].initial_state "hydrostatic"; host, both engines: it reads
// the body and the simulation of the scene, so it lives with what both engines share).
//
// ClaymoreUW starts every body stress-free (J = 1). A fluid column released stress-free under gravity first falls
// into its own compression: a pressure wave runs down and rings between the bed and the free surface at the
// sound speed, and the particle pressures swing around the hydrostatic profile (with tension) until the bulk
// viscosity of the scheme damps them. A hydrostatic start removes that transient: each particle starts with the
// pressure of the water above it.
//
// The free surface is a plane normal to gravity through the highest point of the body's geometry (its bounding
// box, before the partition clip, geometry/geometry.h BodySampler::geometry_bounds): depth = surface + down . x,
// with down the unit vector along gravity, and the surface where -down . x is largest over the box's corners. A
// body of one connected pool at rest is in equilibrium only with a level surface, so this is the surface of every
// fluid body that starts at rest; two pools at different levels need two bodies.
//
// A particle at depth d gets the material's state whose Kirchhoff pressure is rho0 |g| d (M::hydrostatic_state,
// physics/materials/jfluid.cuh says why Kirchhoff). Particles keep their mass rho0 V0 (the body's mass is unchanged);
// a body with a velocity starts with it as well.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "MnBase/Math/vec.h"
#include "scene/scene.h"

namespace fbar {

struct HydrostaticProfile {
  bool active = false;
  Vec3d down{};          ///< unit vector along gravity (zero without gravity)
  double rho_g = 0.0;    ///< [Pa/m] rho0 |g|
  double surface = 0.0;  ///< [m] height of the free surface along -down

  /// [m] depth of x below the free surface (0 above it).
  double depth(const Vec3d& x) const {
    const double d = surface + down[0] * x[0] + down[1] * x[1] + down[2] * x[2];
    return d > 0.0 ? d : 0.0;
  }
  /// [Pa] the Kirchhoff pressure J p of the hydrostatic state at x.
  double kirchhoff_pressure(const Vec3d& x) const { return rho_g * depth(x); }
};

/// The profile of a body whose geometry spans [lo, hi] (inactive unless bodies[].initial_state is hydrostatic).
inline HydrostaticProfile hydrostatic_profile(const BodySpec& body, const SimulationSpec& sim, const Vec3d& lo,
                                              const Vec3d& hi) {
  HydrostaticProfile h;
  if (body.initial_state != InitialState::Hydrostatic) return h;
  h.active = true;
  const double g = std::sqrt(sim.gravity[0] * sim.gravity[0] + sim.gravity[1] * sim.gravity[1] +
                             sim.gravity[2] * sim.gravity[2]);
  if (!(g > 0.0)) return h;  // no gravity: the rest state
  for (int d = 0; d < 3; ++d) h.down[d] = sim.gravity[d] / g;
  h.rho_g = body.material.rho * g;
  h.surface = -std::numeric_limits<double>::infinity();
  for (int c = 0; c < 8; ++c) {
    double s = 0.0;  // -down . corner
    for (int d = 0; d < 3; ++d) s -= h.down[d] * ((c >> d) & 1 ? hi[d] : lo[d]);
    h.surface = std::max(h.surface, s);
  }
  return h;
}

}  // namespace fbar
