// Validation: Martin & Moyce (1952) dam break on a dry bed (VALIDATION.md validation item 1).
//
// Experiment: a water column of width a = 2.25 in = 0.05715 m and height 2a against the back wall of a flat dry
// channel is released at t = 0. Martin & Moyce report the surge front Z = z / a (z from the back wall) against
// T = t sqrt(2 g / a), and the residual height at the back wall H = h / (2 a) against tau = t sqrt(g / a). In
// these variables an inviscid flow is scale-free, so the experiment's own a is used.
// Simulation: a slab one cell thick (slip walls along z: 2D flow), slip back wall and bed (the Walls box one cell
// outside the column's faces: the engine's convention, validation_support.h), JFluid rho = 1000 kg/m^3, gamma = 7,
// viscosity 1e-3 Pa s (water; Re ~ 1e5, negligible), bulk modulus from c0 = 10 x Ritter's front speed
// 2 sqrt(g 2a) = 2.12 m/s: Mach <= 0.1 keeps density variations at the 1 % level (weakly compressible practice,
// Monaghan 1994). 8 ppc, CFL 0.5, double precision. Front: the largest particle x (the 99.9th percentile is
// printed alongside and agrees within 0.025 in T: no stray particle runs ahead).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace {

using validation::r3;

constexpr double kA = 0.05715;   // [m] column width a (height 2a)
constexpr double kG = 9.81;      // [m/s^2]
constexpr double kRho = 1000.0;  // [kg/m^3]
constexpr double kGamma = 7.0;
constexpr double kViscosity = 1e-3;  // [Pa s] water

// Martin & Moyce (1952), a = 2.25 in: surge front Z = z / a against T = t sqrt(2 g / a).
const std::vector<double> kFrontT{0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20,
                                  2.32, 2.51, 2.65, 2.83, 2.98, 3.11, 3.33};
const std::vector<double> kFrontZ{1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56,
                                  2.78, 3.00, 3.22, 3.44, 3.67, 3.89, 4.11};
// Residual column height H = h / (2 a) at the back wall against tau = t sqrt(g / a).
const std::vector<double> kHeightTau{0.56, 0.77, 0.93, 1.08, 1.28, 1.46, 1.66, 1.84, 2.00,
                                     2.21, 2.45, 2.70, 3.06, 3.44, 4.20, 5.25, 7.40};
const std::vector<double> kHeightH{0.94, 0.89, 0.83, 0.78, 0.72, 0.67, 0.61, 0.56, 0.50,
                                   0.44, 0.39, 0.33, 0.28, 0.22, 0.17, 0.11, 0.06};

struct DamResult {
  bool ok = false;
  std::vector<double> T, Z, Z999;  // front history (max particle x; 99.9th percentile)
  std::vector<double> tau, H;      // back-wall height history
  long long steps = 0;
  std::size_t particles = 0;
  double seconds = 0;
  double mach = 0;
};

DamResult run_dam(int cells_per_a, double T_end, validation::WallFit fit = validation::WallFit::LastWallNodePlane) {
  validation::Stopwatch clock;
  const double dx = kA / cells_per_a;
  const double x0 = dx + validation::wall_inset(fit, dx), y0 = x0, z0 = x0;
  const double c0 = 10 * 2 * std::sqrt(kG * 2 * kA);  // 10x Ritter's front speed 2 sqrt(g h0), h0 = 2a
  Scene scene = validation::make_scene(r3(x0 + 6 * kA + 2 * dx, y0 + 2 * kA + 4 * dx, z0 + 3 * dx), dx, r3(0, -kG, 0));
  BodySpec water = validation::jfluid_body(kRho, kRho * c0 * c0, kGamma, kViscosity);
  validation::add_box(water, r3(x0, y0, z0), r3(kA, 2 * kA, dx));
  scene.bodies.push_back(water);
  scene.boundaries.push_back(
      validation::wall_box(Contact::Slip, r3(x0, y0, z0), r3(x0 + 6 * kA, validation::kFar, z0 + dx), dx, fit));
  CpuEngine<double> engine(scene);
  DamResult r;
  r.particles = engine.particle_count(0);
  const double t_scale = std::sqrt(2 * kG / kA), tau_scale = std::sqrt(kG / kA);
  const double t_end = T_end / t_scale;
  std::vector<double> xs(r.particles);
  auto record = [&]() {
    const auto& x = engine.positions(0);
    double front = 0, height = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      xs[i] = x[i][0];
      front = std::max(front, x[i][0]);
      if (x[i][0] < x0 + dx) height = std::max(height, x[i][1]);
    }
    const std::size_t k = static_cast<std::size_t>(0.999 * (xs.size() - 1));
    std::nth_element(xs.begin(), xs.begin() + k, xs.end());
    r.T.push_back(engine.time() * t_scale);
    r.Z.push_back((front - x0) / kA);
    r.Z999.push_back((xs[k] - x0) / kA);
    r.tau.push_back(engine.time() * tau_scale);
    r.H.push_back((height - y0) / (2 * kA));
  };
  record();
  double vmax = 0;
  while (engine.time() < t_end) {
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return r;
    }
    vmax = std::max(vmax, engine.max_grid_speed());
    record();
  }
  r.mach = vmax / c0;
  r.steps = engine.steps();
  r.seconds = clock.seconds();
  r.ok = true;
  std::printf("dam break a/dx = %d: %zu particles, %lld steps, %.2f s wall, max speed %.3f m/s (Mach %.3f)\n",
              cells_per_a, r.particles, r.steps, r.seconds, vmax, r.mach);
  for (std::size_t i = 0; i < kFrontZ.size(); ++i) {
    const double Ts = validation::first_reach(r.T, r.Z, kFrontZ[i]);
    const double Ts999 = validation::first_reach(r.T, r.Z999, kFrontZ[i]);
    std::printf("  Z %.2f: T data %.2f, fbar %.3f (99.9%% front %.3f), Ritter %.3f\n", kFrontZ[i], kFrontT[i], Ts,
                Ts999, (kFrontZ[i] - 1) / 2);
  }
  std::printf("  front speed dZ/dT between Z = 2.11 and 4.11: %.3f (data %.3f, Ritter 2)\n",
              (kFrontZ.back() - 2.11) /
                  (validation::first_reach(r.T, r.Z, kFrontZ.back()) - validation::first_reach(r.T, r.Z, 2.11)),
              (kFrontZ.back() - 2.11) / (kFrontT.back() - 1.83));
  for (std::size_t i = 0; i < kHeightTau.size(); ++i) {
    if (kHeightTau[i] > r.tau.back()) break;
    std::printf("  tau %.2f: H data %.2f, fbar %.3f\n", kHeightTau[i], kHeightH[i],
                validation::interpolate(r.tau, r.H, kHeightTau[i]));
  }
  return r;
}

// Bounds on the front, at a/dx = 16 and 24 (gauges Z >= 1.22):
//  * Upper speed bound (Ritter 1892): an ideal frictionless shallow-water dam break fronts at 2 sqrt(g h0), dZ/dT = 2
//    from Z = 1 at T = 0, so no front reaches Z before T = (Z - 1) / 2.
//  * Lower speed bound: the data. Bed friction, viscosity, surface tension and the finite gate release only delay
//    the experimental surge; the simulation has none of them (slip bed, negligible viscosity), so its front must
//    reach every gauge no later than the experiment: T_sim <= T_data. A numerical front lags its converged
//    position (the grid smooths the corner and the front's pressure gradient; measured T(Z = 3) = 2.60, 2.45, 2.37,
//    2.31 at a/dx = 8, 12, 16, 24): at a/dx >= 16 the lag is below the physical lead of the inviscid flow (the margin
//    is >= 0.08 in T), at a/dx = 8 it is not (T(Z = 2.33) = 2.10 > 1.98); docs/validation.md lists all four.
//  * Refinement moves the front forward: T_sim(a/dx = 24) <= T_sim(a/dx = 16) at every gauge.
//  * Late front speed: dZ/dT between the Z = 2.11 and Z = 4.11 gauges within [1.3, 2]: no slower than the
//    experiment over the same gauges (1.33) and no faster than Ritter.
// The first gauge (Z = 1.11 at T = 0.41) is not asserted: it implies a mean acceleration above 2.5 g over the first
// 0.11 a, the corner's singular pressure gradient, which the grid spreads over a cell (fbar reaches it at T = 0.55
// and 0.51 at a/dx = 16 and 24).
// Residual height at the back wall, tau <= 2.21 (the run's end is tau = 2.4): within 0.1 of the data. The height is
// the top of the particles within one cell of the wall (one cell = 0.03 in H at a/dx = 16; the data carry two
// digits); 0.1 is ~3 cells. Measured: fbar is 0 to 0.07 above the data. The bound fails a fluid layer that clings
// to the wall (with the column's faces on the zero-velocity plane the wall film stands at H = 0.96).
TEST(DamBreak, FrontAndResidualHeightAgainstMartinMoyce) {
  const DamResult medium = run_dam(16, 3.4), fine = run_dam(24, 3.4);
  ASSERT_TRUE(medium.ok && fine.ok);
  for (const DamResult* r : {&medium, &fine}) {
    EXPECT_LE(r->mach, 0.15);  // weakly compressible regime (max grid speed includes the splash at the front)
    for (std::size_t i = 1; i < kFrontZ.size(); ++i) {
      const double T = validation::first_reach(r->T, r->Z, kFrontZ[i]);
      ASSERT_FALSE(std::isnan(T)) << "front never reached Z = " << kFrontZ[i];
      EXPECT_GE(T, (kFrontZ[i] - 1) / 2) << "faster than Ritter at Z = " << kFrontZ[i];
      EXPECT_LE(T, kFrontT[i]) << "slower than the experiment at Z = " << kFrontZ[i];
    }
    const double slope = (kFrontZ.back() - 2.11) / (validation::first_reach(r->T, r->Z, kFrontZ.back()) -
                                                    validation::first_reach(r->T, r->Z, 2.11));
    EXPECT_GE(slope, 1.3);
    EXPECT_LE(slope, 2.0);
    for (std::size_t i = 0; i < kHeightTau.size() && kHeightTau[i] <= 2.21; ++i)
      EXPECT_NEAR(validation::interpolate(r->tau, r->H, kHeightTau[i]), kHeightH[i], 0.1) << "tau = " << kHeightTau[i];
  }
  for (std::size_t i = 1; i < kFrontZ.size(); ++i)
    EXPECT_LE(validation::first_reach(fine.T, fine.Z, kFrontZ[i]),
              validation::first_reach(medium.T, medium.Z, kFrontZ[i]))
        << "Z = " << kFrontZ[i];
}

}  // namespace
}  // namespace fbar
