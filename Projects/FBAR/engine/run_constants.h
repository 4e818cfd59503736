// Per-run constants both engines derive from the scene (SI units): grid spacing, gravity, domain, default dt, boundaries.
#pragma once

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "physics/boundary.cuh"
#include "scene/facilities.h"
#include "physics/constitutive_models.cuh"
#include "physics/motion_path.h"
#include "scene/scene.h"
#include "physics/time_step.cuh"

namespace fbar {

/// The scene's default_dt, resolved: the given value, or dx / 100 (numerically, dx in metres -> seconds, ClaymoreUW's
/// default and docs/user_guide.md's) when the scene left it out (<= 0).
inline double resolved_default_dt(const SimulationSpec& sim) {
  return sim.default_dt > 0.0 ? sim.default_dt : sim.dx / 100.0;
}

/// The smallest explicit diffusive bound of a scene (time_step.cuh): viscosity (a law that reads the "viscosity" key,
/// JFluid, with a positive value) or seepage (a saturated law, CoupledUP); its body (-1: none) and which it is.
struct DiffusiveBound {
  double dt = std::numeric_limits<double>::infinity();  ///< [s]
  int body = -1;
  bool seepage = false;  ///< the seepage bound (else the viscous one)
  /// How it is computed, for the run's note.
  const char* formula() const {
    return seepage ? "CFL x dx^2 / (8 x kappa x M), explicit seepage" : "CFL x rho x dx^2 / (3 x viscosity)";
  }
};
inline double body_viscous_step_bound(const BodySpec& body, double dx) {
  double bound = std::numeric_limits<double>::infinity();
  for_each_material_parameter(body.material.law, [&](const MaterialParameter& p) {
    if (std::string_view(p.key) == "viscosity")
      bound = viscous_time_step(body.material.cfl, dx, body.material.rho, body.material.viscosity);
  });
  return bound;
}
/// A saturated body's explicit seepage bound (time_step.cuh seepage_time_step); +infinity for other laws.
inline double body_seepage_step_bound(const BodySpec& body, double dx) {
  double bound = std::numeric_limits<double>::infinity();
  visit_material(body.material.law, [&](auto m) {
    using M = decltype(m);
    if constexpr (IsPoreFluid<M>::value)
      bound = seepage_time_step(body.material.cfl, dx, M::seepage_diffusivity(body.material));
  });
  return bound;
}
inline DiffusiveBound diffusive_step_bound(const Scene& scene) {
  DiffusiveBound v;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const double viscous = body_viscous_step_bound(scene.bodies[b], scene.simulation.dx);
    const double seepage = body_seepage_step_bound(scene.bodies[b], scene.simulation.dx);
    if (viscous < v.dt) v = {viscous, static_cast<int>(b), false};
    if (seepage < v.dt) v = {seepage, static_cast<int>(b), true};
  }
  return v;
}

/// A mesh body's explicit element bound (physics/fem.cuh): CFL x its smallest element height (at rest,
/// MeshEntrySpec::stats) / the law's p-wave speed (cfl_time_step with no flow speed; constant for the element laws,
/// whose wave speed does not depend on the state); +infinity for particle bodies and meshes without element forces.
inline double body_element_step_bound(const Scene& scene, const BodySpec& body) {
  double bound = std::numeric_limits<double>::infinity();
  if (body.mesh < 0 || !body.algorithm.use_fem) return bound;
  const double h = scene.meshes.at(static_cast<std::size_t>(body.mesh)).stats.min_height;
  visit_material(body.material.law, [&](auto mt) {
    using M = decltype(mt);
    const double c = M::wave_speed(M::template make_params<double>(body.material), M::template reference_state<double>());
    bound = cfl_time_step(body.material.cfl, h, c, 0.0);
  });
  return bound;
}

template <typename T>
struct RunConstants {
  T dx{};                 ///< [m] grid spacing
  T inv_dx{};             ///< [1/m]
  T d_inv{};              ///< [1/m^2] APIC D_p^-1 = 4 / dx^2 (follows dx)
  Vec3<T> gravity{};      ///< [m/s^2]
  Vec3<T> domain{};       ///< [m] extent from the origin
  double default_dt = 0;  ///< [s] largest step: simulation.default_dt, resolved (dx / 100 when absent), or the
                          ///< smallest diffusive bound (diffusive_step_bound) or element bound
                          ///< (body_element_step_bound) when that is smaller
  std::vector<BoundaryParams<T>> boundaries;  ///< every boundary of the scene, in scene order, arrays expanded
  std::vector<MotionPath> motions;            ///< (boundary) its motion file, or empty
  BoundaryProfiles<T> profiles;               ///< the points of every Bathymetry boundary

  /// Boundary i at time t [s]: moved by its motion file (displacement along x at t - time[0], the file's velocity)
  /// or by its constant velocity (boundary_at).
  BoundaryParams<T> boundary_at_time(std::size_t i, double t) const {
    const MotionPath& m = motions[i];
    if (m.empty()) return boundary_at(boundaries[i], t);
    BoundaryParams<T> b = boundaries[i];
    double d = 0, v = 0;
    m.at(t - b.t_begin, d, v);
    b.lo[0] += static_cast<T>(d);
    b.hi[0] += static_cast<T>(d);
    b.pivot[0] += static_cast<T>(d);
    b.velocity = Vec3<T>{{static_cast<T>(v), T(0), T(0)}};
    if (b.rotates) b.rotation = rotation_of(b.omega, t - b.t_begin);
    return b;
  }

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
    default_dt = std::min(resolved_default_dt(sim), diffusive_step_bound(scene).dt);
    for (const BodySpec& b : scene.bodies) default_dt = std::min(default_dt, body_element_step_bound(scene, b));
    for (std::size_t i = 0; i < scene.boundaries.size(); ++i) {
      MotionPath motion;
      if (!scene.boundaries[i].file.empty())
        motion = MotionPath::load(scene.boundaries[i].file, sim.froude_scaling, scene.boundaries[i].output_frequency,
                                  "boundaries[" + std::to_string(i) + "].file");
      // A facility object is several generic pieces (scene/facilities.h), each with the entry's array and motion.
      for (const BoundarySpec& spec : expand_boundary(scene.boundaries[i], sim)) {
        BoundaryParams<T> p{};
        std::string error;
        if (!make_boundary_params(spec, sim.dx, sim.domain, p, error))
          throw std::invalid_argument("boundaries[" + std::to_string(i) + "]: " + error + " in the " + engine);
        if (p.shape == BoundaryShape::Bathymetry) {
          const std::vector<std::array<double, 2>>& bed = spec.bathymetry;
          if (profiles.count + static_cast<int>(bed.size()) > BoundaryProfiles<T>::kMax)
            throw std::invalid_argument("boundaries[" + std::to_string(i) + "].bathymetry: more than " +
                                        std::to_string(BoundaryProfiles<T>::kMax) +
                                        " bathymetry points in all boundaries of the scene");
          p.profile_first = profiles.count;
          p.profile_count = static_cast<int>(bed.size());
          for (const auto& point : bed) {
            profiles.x[profiles.count] = static_cast<T>(point[0]);
            profiles.y[profiles.count] = static_cast<T>(point[1]);
            ++profiles.count;
          }
        }
        for (const BoundaryParams<T>& copy : boundary_array(p, spec)) {
          boundaries.push_back(copy);
          motions.push_back(motion);
        }
      }
    }
  }
};

}  // namespace fbar
