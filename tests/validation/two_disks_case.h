// Validation case: two elastic disks colliding head-on (docs/validation.md; Sulsky, Chen & Schreyer 1994).
//
// Problem (2D, per unit thickness): domain [-0.5, 0.5]^2, disks of radius R = 0.2 m centred at (-0.3, -0.3) and
// (0.3, 0.3), E = 1000 Pa, nu = 0.3, rho = 1000 kg/m^3, velocities +(0.1, 0.1) and -(0.1, 0.1) m/s. No gravity, no
// walls. Total momentum is zero; kinetic energy 2 x (1/2) rho pi R^2 |v|^2 = 2.513 J per metre of thickness. The
// disks meet at t = (0.6 sqrt(2) - 2R) / (2 |v|) = 1.586 s, convert kinetic into strain energy, and rebound.
// Sulsky et al. (single velocity field, no contact algorithm) show the rebound with a modest energy loss.
//
// Here: a slab one cell thick between slip walls along z (plane strain), the 2D domain shifted by +0.75 m into
// [0.25, 1.25]^2 of a 1.5 m square domain (no wall in x, y acts), FixedCorotated, APIC, 8 ppc (2 x 2 per cell in
// the plane, Sulsky used 4 per cell), CFL 0.5, double precision.
// Shared by the CPU validation test (test_two_disks.cpp) and the study runner's fbar_study_cases: the run is
// templated on the engine (CpuEngine, or test::GpuValidationEngine with the same queries).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace disks_case {

using validation::kPi;
using validation::r3;

constexpr double kR = 0.2;       // [m]
constexpr double kE = 1000.0;    // [Pa]
constexpr double kNu = 0.3;      // [-]
constexpr double kRho = 1000.0;  // [kg/m^3]
constexpr double kSpeed = 0.1;   // [m/s] each velocity component
constexpr double kShift = 0.75;  // [m] the 2D domain [-0.5, 0.5]^2 moved into [0.25, 1.25]^2
constexpr double kKineticPerThickness = kRho * kPi * kR * kR * 2 * kSpeed * kSpeed;  // [J/m] 2.513

struct DisksResult {
  bool ok = false;
  double thickness = 0;          // [m] slab thickness (one cell)
  double area_ratio = 0;         // [-] sampled disk area / (pi R^2)
  double ke0_per_thickness = 0;  // [J/m]
  double energy0 = 0;            // [J] kinetic + elastic at t = 0 (= kinetic)
  double energy_max = 0;         // [J] largest total energy over the run
  double energy_end = 0;         // [J] total energy at the end
  double elastic_max = 0;        // [J] largest strain energy (during contact)
  double ke_min = 0;             // [J] smallest kinetic energy (during contact)
  double momentum_drift = 0;     // [-] max |P(t)| / sum m |v| (0 at start)
  Vec3d v_end[2];                // [m/s] centre-of-mass velocity of each disk at the end
  double t_contact = 0;          // [s] strain energy first above 1 % of E0 (grid supports overlap)
  long long steps = 0;
  std::size_t particles = 0;
  double seconds = 0;
};

template <class Engine>
Vec3d body_velocity(Engine& engine, int body) {
  Vec3d p = Vec3d::zero();
  double m = 0;
  const auto masses = engine.masses(body);
  const auto& v = engine.velocities(body);
  for (std::size_t i = 0; i < masses.size(); ++i) {
    p += v[i].template cast<double>() * static_cast<double>(masses[i]);
    m += static_cast<double>(masses[i]);
  }
  return p / m;
}

using validation::kApic;
using validation::Scheme;

template <class Engine = CpuEngine<double>>
DisksResult run_disks(double dx, double t_end, const Scheme& scheme = kApic) {
  validation::Stopwatch clock;
  // The slab [z0, z0 + dx] between slip walls; with one cell of thickness every node is a wall node along z, so
  // both WallFit placements give the same plane-strain constraint.
  const double z0 = 2 * dx;
  Scene scene = validation::make_scene(r3(1.5, 1.5, z0 + 3 * dx), dx, r3(0, 0, 0));
  for (int d = 0; d < 2; ++d) {
    const double c = kShift + (d == 0 ? -0.3 : 0.3);
    BodySpec disk = validation::fixed_corotated_body(kRho, kE, kNu);
    validation::set_scheme(disk, scheme);
    validation::add_disk(disk, c, c, kR, z0, dx);
    disk.velocity = d == 0 ? r3(kSpeed, kSpeed, 0) : r3(-kSpeed, -kSpeed, 0);
    scene.bodies.push_back(disk);
  }
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(-validation::kFar, -validation::kFar, z0),
                                                  r3(validation::kFar, validation::kFar, z0 + dx), dx,
                                                  validation::WallFit::LastWallNodePlane));

  Engine engine(scene);
  DisksResult r;
  r.particles = engine.particle_count(0) + engine.particle_count(1);
  r.thickness = dx;
  // Lattice area: each particle stands for (dx/2)^2 of the plane (8 ppc = 2 per axis).
  r.area_ratio = static_cast<double>(engine.particle_count(0)) / 2.0 * (0.25 * dx * dx) / (kPi * kR * kR);
  r.energy0 = engine.kinetic_energy() + engine.elastic_energy();
  r.ke0_per_thickness = engine.kinetic_energy() / r.thickness;
  r.energy_max = r.energy0;
  r.ke_min = r.energy0;
  double p_scale = 0;
  for (int b = 0; b < 2; ++b) {
    const auto masses = engine.masses(b);
    const auto& v = engine.velocities(b);
    for (std::size_t i = 0; i < masses.size(); ++i)
      p_scale += static_cast<double>(masses[i]) * norm(v[i].template cast<double>());
  }
  while (engine.time() < t_end) {
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return r;
    }
    const double ke = engine.kinetic_energy(), pe = engine.elastic_energy(), e = ke + pe;
    r.energy_max = std::max(r.energy_max, e);
    r.elastic_max = std::max(r.elastic_max, pe);
    r.ke_min = std::min(r.ke_min, ke);
    if (pe > 0.01 * r.energy0 && r.t_contact == 0) r.t_contact = engine.time();
    r.momentum_drift = std::max(r.momentum_drift, max_abs(engine.total_momentum()) / p_scale);
  }
  r.energy_end = engine.kinetic_energy() + engine.elastic_energy();
  for (int b = 0; b < 2; ++b) r.v_end[b] = body_velocity(engine, b);
  r.steps = engine.steps();
  r.seconds = clock.seconds();
  r.ok = true;
  std::printf("two disks (%s), dx = %g m (R/dx = %g): %zu particles, %lld steps, %.2f s wall\n", scheme.name, dx,
              kR / dx, r.particles, r.steps, r.seconds);
  std::printf("  KE0 %.4f J/m (reference %.4f; sampled area / pi R^2 = %.4f); energy max %.5f, end %.5f of E0\n",
              r.ke0_per_thickness, kKineticPerThickness, r.area_ratio, r.energy_max / r.energy0,
              r.energy_end / r.energy0);
  std::printf("  strain energy max %.4f of E0, kinetic min %.4f of E0; contact from %.3f s; momentum drift %.3g\n",
              r.elastic_max / r.energy0, r.ke_min / r.energy0, r.t_contact, r.momentum_drift);
  std::printf("  final disk velocities (%+.5f, %+.5f), (%+.5f, %+.5f) m/s\n", r.v_end[0][0], r.v_end[0][1],
              r.v_end[1][0], r.v_end[1][1]);
  return r;
}

}  // namespace disks_case
}  // namespace fbar
