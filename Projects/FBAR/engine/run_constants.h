// Per-run constants both engines derive from the scene (SI units): grid spacing, gravity, domain, default dt, boundaries.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "physics/boundary.cuh"
#include "scene/scene.h"
#include "physics/time_step.cuh"

namespace fbar {

template <typename T>
struct RunConstants {
  T dx{};                 ///< [m] grid spacing
  T inv_dx{};             ///< [1/m]
  T d_inv{};              ///< [1/m^2] APIC D_p^-1 = 4 / dx^2 (follows dx)
  Vec3<T> gravity{};      ///< [m/s^2]
  Vec3<T> domain{};       ///< [m] extent from the origin
  double default_dt = 0;  ///< [s] simulation.default_dt, resolved (dx / 100 when absent)
  std::vector<BoundaryParams<T>> boundaries;  ///< every boundary of the scene, in scene order

  RunConstants() = default;
  /// Throws std::invalid_argument naming the key when dx is not positive or a boundary cannot be applied by
  /// `engine` (named in the message, e.g. "CPU engine").
  RunConstants(const Scene& scene, const std::string& engine) {
    const SimulationSpec& sim = scene.simulation;
    if (!(sim.dx > 0.0)) throw std::invalid_argument("simulation.default_dx: must be positive");
    dx = static_cast<T>(sim.dx);
    inv_dx = T(1) / dx;
    d_inv = apic_inertia_inverse(dx);
    for (int a = 0; a < 3; ++a) {
      gravity[a] = static_cast<T>(sim.gravity[a]);
      domain[a] = static_cast<T>(sim.domain[a]);
    }
    default_dt = resolved_default_dt(sim);
    for (std::size_t i = 0; i < scene.boundaries.size(); ++i) {
      BoundaryParams<T> p{};
      std::string error;
      if (!make_boundary_params(scene.boundaries[i], sim, p, error))
        throw std::invalid_argument("boundaries[" + std::to_string(i) + "]: " + error + " in the " + engine);
      boundaries.push_back(p);
    }
  }
};

}  // namespace fbar
