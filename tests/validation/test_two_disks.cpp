// Validation: two elastic disks colliding head-on (VALIDATION.md item 6, Sulsky, Chen & Schreyer 1994).
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
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace {

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

Vec3d body_velocity(const CpuEngine<double>& engine, int body) {
  Vec3d p = Vec3d::zero();
  double m = 0;
  for (std::size_t i = 0; i < engine.particle_count(body); ++i) {
    p += engine.velocities(body)[i] * engine.masses(body)[i];
    m += engine.masses(body)[i];
  }
  return p / m;
}

struct Scheme {
  const char* name;
  double alpha, beta_min, beta_max;
};
constexpr Scheme kApic{"APIC", 0, 0, 0};

DisksResult run_disks(double dx, double t_end, const Scheme& scheme = kApic) {
  validation::Stopwatch clock;
  // The slab [z0, z0 + dx] between slip walls; with one cell of thickness every node is a wall node along z, so
  // both WallFit placements give the same plane-strain constraint.
  const double z0 = 2 * dx;
  Scene scene = validation::make_scene(r3(1.5, 1.5, z0 + 3 * dx), dx, r3(0, 0, 0));
  for (int d = 0; d < 2; ++d) {
    const double c = kShift + (d == 0 ? -0.3 : 0.3);
    BodySpec disk = validation::fixed_corotated_body(kRho, kE, kNu);
    disk.algorithm.use_asflip = true;
    disk.algorithm.asflip_alpha = scheme.alpha;
    disk.algorithm.asflip_beta_min = scheme.beta_min;
    disk.algorithm.asflip_beta_max = scheme.beta_max;
    validation::add_disk(disk, c, c, kR, z0, dx);
    disk.velocity = d == 0 ? r3(kSpeed, kSpeed, 0) : r3(-kSpeed, -kSpeed, 0);
    scene.bodies.push_back(disk);
  }
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(-validation::kFar, -validation::kFar, z0),
                                                  r3(validation::kFar, validation::kFar, z0 + dx), dx,
                                                  validation::WallFit::LastWallNodePlane));

  CpuEngine<double> engine(scene);
  DisksResult r;
  r.particles = engine.particle_count();
  r.thickness = dx;
  // Lattice area: each particle stands for (dx/2)^2 of the plane (8 ppc = 2 per axis).
  r.area_ratio = static_cast<double>(engine.particle_count(0)) / 2.0 * (0.25 * dx * dx) / (kPi * kR * kR);
  r.energy0 = engine.kinetic_energy() + engine.elastic_energy();
  r.ke0_per_thickness = engine.kinetic_energy() / r.thickness;
  r.energy_max = r.energy0;
  r.ke_min = r.energy0;
  double p_scale = 0;
  for (int b = 0; b < 2; ++b)
    for (std::size_t i = 0; i < engine.particle_count(b); ++i)
      p_scale += engine.masses(b)[i] * norm(engine.velocities(b)[i]);
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

// Assertions at R/dx = 4 (Sulsky's grid, dx = 0.05), 8 and 16, 4.5 s (the collision and the rebound):
//  * Thickness scaling: the initial kinetic energy per metre of slab is 2.513 J x (sampled area / pi R^2) to
//    round-off (the lattice area differs from pi R^2 by the point count in a disk of R / h = 8..32 lattice spacings:
//    +3.5 %, +1.0 %, +0.3 %, reported).
//  * Momentum: no wall acts in the plane and P2G / G2P conserve momentum exactly, so |P(t)| stays at round-off:
//    <= 1e-12 of sum m |v| (each step sums ~1e4 terms in a fixed order, ~1e3 steps: a few thousand eps at most).
//  * Energy never grows: before contact the disks translate rigidly (energy constant to round-off); during contact
//    APIC with a single velocity field dissipates, and the measured energy of symplectic Euler oscillates by only
//    +-(omega dt / 2) about a decreasing shadow energy. Bound E(t) <= E0 (1 + 1e-3) (measured: never above E0).
//  * Conversion: strain energy peaks above E0 / 2 (impact speed / c_p = 0.14 / 1.16: a quasi-static impact converts
//    nearly all the kinetic energy; measured 0.89 .. 0.95 E0), kinetic energy falls below E0 / 2.
//  * Rebound: each disk's centre-of-mass velocity has reversed (both components) by the end.
//  * Dissipation converges: the energy lost by the end falls by more than 1.5x per halving of dx (first order
//    gives 2: the contact zone, where the single-field MPM sticks the disks, spans a fixed number of cells).
TEST(TwoDisks, MomentumEnergyAndRebound) {
  const double t_end = 4.5;
  std::vector<DisksResult> runs;
  for (double dx : {0.05, 0.025, 0.0125}) runs.push_back(run_disks(dx, t_end));
  for (const DisksResult& r : runs) {
    ASSERT_TRUE(r.ok);
    EXPECT_NEAR(r.ke0_per_thickness, kKineticPerThickness * r.area_ratio, 1e-12 * kKineticPerThickness);
    EXPECT_LE(r.momentum_drift, 1e-12);
    EXPECT_LE(r.energy_max, r.energy0 * (1 + 1e-3));
    EXPECT_GE(r.elastic_max, 0.5 * r.energy0);
    EXPECT_LE(r.ke_min, 0.5 * r.energy0);
    EXPECT_LT(r.v_end[0][0], 0.0);
    EXPECT_LT(r.v_end[0][1], 0.0);
    EXPECT_GT(r.v_end[1][0], 0.0);
    EXPECT_GT(r.v_end[1][1], 0.0);
  }
  const double loss[3] = {1 - runs[0].energy_end / runs[0].energy0, 1 - runs[1].energy_end / runs[1].energy0,
                          1 - runs[2].energy_end / runs[2].energy0};
  EXPECT_GT(loss[0] / loss[1], 1.5);
  EXPECT_GT(loss[1] / loss[2], 1.5);
  std::printf(
      "energy lost by t = %.1f s: %.2f %% (R/dx 4), %.2f %% (8), %.2f %% (16); restitution |v_end| / |v0|: "
      "%.4f, %.4f, %.4f\n",
      t_end, 100 * loss[0], 100 * loss[1], 100 * loss[2], -runs[0].v_end[0][0] / kSpeed, -runs[1].v_end[0][0] / kSpeed,
      -runs[2].v_end[0][0] / kSpeed);
}

// Energy history per transfer scheme (VALIDATION.md item 6: "report energy loss per scheme"), R/dx = 8. Each scheme
// must conserve momentum to round-off (P2G/G2P conserve it for any alpha, beta: the FLIP increment is a grid
// difference) and rebound; FLIP keeps the particle velocity through the contact and dissipates less than APIC: the
// loss must not exceed APIC's. Energy growth: the blends (alpha 0.95) must stay within the symplectic oscillation
// (1e-3) like APIC; pure FLIP (alpha = 1) keeps the particle velocity modes the grid cannot see (the FLIP noise of
// VALIDATION.md "where methods fail"), nothing damps them and the contact pumps some energy into them: measured
// +0.26 % at the peak, bounded here at +1 % (a growing instability would exceed it; engineering use keeps
// alpha < 1).
// Measured (CPU, double): energy lost APIC 12.04 %, PIC-FLIP 0.95 4.58 %, FLIP 4.44 %, ASFLIP (0.95, 0, 0.2) 4.56 %;
// restitution 0.919, 0.952, 0.952, 0.952.
TEST(TwoDisks, EnergyPerTransferScheme) {
  const Scheme schemes[] = {kApic, {"PIC-FLIP 0.95", 0.95, 0, 0}, {"FLIP", 1.0, 0, 0}, {"ASFLIP", 0.95, 0.0, 0.2}};
  double apic_loss = 0;
  for (const Scheme& s : schemes) {
    SCOPED_TRACE(s.name);
    const DisksResult r = run_disks(0.025, 4.5, s);
    ASSERT_TRUE(r.ok);
    const double loss = 1 - r.energy_end / r.energy0;
    std::printf("%-14s energy lost %.2f %%, energy max/E0 %.5f, restitution %.4f, momentum drift %.2g\n", s.name,
                100 * loss, r.energy_max / r.energy0, -r.v_end[0][0] / kSpeed, r.momentum_drift);
    EXPECT_LE(r.momentum_drift, 1e-12);
    EXPECT_LE(r.energy_max, r.energy0 * (1 + (s.alpha < 1 ? 1e-3 : 1e-2)));
    EXPECT_LT(r.v_end[0][0], 0.0);
    EXPECT_GT(r.v_end[1][0], 0.0);
    if (s.alpha == 0) apic_loss = loss;
    else EXPECT_LE(loss, apic_loss);
  }
}

}  // namespace
}  // namespace fbar
