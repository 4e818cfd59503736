// Validation: Martin & Moyce (1952) dam break on a dry bed (docs/validation.md).
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

// Two-sided bands around Martin & Moyce's data, at a/dx = 16 and 24, from this error budget:
//  * Data resolution. The front was read at gauges half an inch apart (Z steps of 0.222 = 0.5 in / a): the front is
//    located to +-0.11 in Z, +-0.08 in T at the data's late speed dZ/dT = 1.33. The residual height was read at
//    quarter-inch marks (H steps of 0.0556 = 0.25 in / 2a): +-0.028 in H. Both carry two digits (+-0.005).
//  * Discretisation: first order in dx at the front and at the free surface (measured T(Z = 3) = 2.60, 2.45, 2.37,
//    2.31 at a/dx = 8, 12, 16, 24, docs/validation.md). Refinement must move the front forward and the height towards
//    the data (trend); the height's band adds two cells, 2 dx / (2a) in H (the height is the top particle within a
//    cell of the wall, where the node-layer wall's 1.5-cell layer acts).
//  * Unmodelled physics, front only: the simulation is inviscid on a slip bed with an instantaneous release; the
//    experiment's gate release, bed friction and surface tension only delay its surge, so the simulated front must
//    reach every gauge no later than the data (upper bound T_data). The lower bound is T_data - 0.40: the gauge
//    reading (0.08) plus a release lag of 0.32 in T (17 ms): the converged inviscid front (first-order Richardson
//    from a/dx 16 and 24) leads the data by a nearly constant 0.23 to 0.37 from Z = 1.44 on, a shift of the time
//    origin, not a speed difference (the late speeds agree, below). Ritter's shallow-water front, (Z - 1) / 2, is
//    printed for comparison; it is up to 2x below the data and bounds nothing here.
//    Measured lead of fbar over the data, Z >= 1.22: 0.08 to 0.18 (a/dx 16), 0.13 to 0.24 (24).
//  * Late front speed dZ/dT between the Z = 2.11 and 4.11 gauges: the data's 1.333 +- 0.15 (the +-0.11 gauge reading
//    at both ends over Z 2.11 to 4.11, T 1.83 to 3.33) +- 0.02 (first order: 2 x the 16-to-24 change of 0.011):
//    [1.16, 1.50]. Measured 1.399 (16), 1.388 (24).
//  * Residual height at the back wall, tau <= 2.21 (the run's end is tau = 2.4): |H - H_data| <= 0.028 + 0.005 +
//    2 dx / (2a), 0.096 at a/dx = 16 and 0.075 at 24. Measured: fbar is -0.01 to +0.071 (16) and -0.007 to +0.058 (24)
//    off the data; refinement brings it closer (a/dx 24 no farther from the data than 16, to the data's 0.005). The
//    band fails a fluid layer that clings to the wall (with the column's faces on the zero-velocity plane the wall
//    film stands at H = 0.96).
// The first gauge (Z = 1.11 at T = 0.41) is not asserted: it implies a mean acceleration above 2.5 g over the first
// 0.11 a, the corner's singular pressure gradient, which the grid spreads over a cell (fbar reaches it at T = 0.55
// and 0.51 at a/dx = 16 and 24).
TEST(DamBreak, FrontAndResidualHeightAgainstMartinMoyce) {
  const DamResult medium = run_dam(16, 3.4), fine = run_dam(24, 3.4);
  ASSERT_TRUE(medium.ok && fine.ok);
  constexpr double kReleaseLag = 0.32, kGaugeReadT = 0.08;  // [-] in T, see above
  constexpr double kMarkH = 0.028, kDigits = 0.005;         // [-] in H
  for (const DamResult* r : {&medium, &fine}) {
    const int cells_per_a = r == &medium ? 16 : 24;
    EXPECT_LE(r->mach, 0.15);  // weakly compressible regime (max grid speed includes the splash at the front)
    for (std::size_t i = 1; i < kFrontZ.size(); ++i) {
      const double T = validation::first_reach(r->T, r->Z, kFrontZ[i]);
      ASSERT_FALSE(std::isnan(T)) << "front never reached Z = " << kFrontZ[i];
      EXPECT_GE(T, kFrontT[i] - kGaugeReadT - kReleaseLag) << "too far ahead of the experiment at Z = " << kFrontZ[i];
      EXPECT_LE(T, kFrontT[i]) << "slower than the experiment at Z = " << kFrontZ[i];
    }
    const double slope = (kFrontZ.back() - 2.11) / (validation::first_reach(r->T, r->Z, kFrontZ.back()) -
                                                    validation::first_reach(r->T, r->Z, 2.11));
    EXPECT_GE(slope, 1.16);
    EXPECT_LE(slope, 1.50);
    const double band_H = kMarkH + kDigits + 2.0 / (2 * cells_per_a);
    for (std::size_t i = 0; i < kHeightTau.size() && kHeightTau[i] <= 2.21; ++i)
      EXPECT_NEAR(validation::interpolate(r->tau, r->H, kHeightTau[i]), kHeightH[i], band_H)
          << "tau = " << kHeightTau[i] << ", a/dx = " << cells_per_a;
  }
  for (std::size_t i = 1; i < kFrontZ.size(); ++i)
    EXPECT_LE(validation::first_reach(fine.T, fine.Z, kFrontZ[i]),
              validation::first_reach(medium.T, medium.Z, kFrontZ[i]))
        << "Z = " << kFrontZ[i];
  for (std::size_t i = 0; i < kHeightTau.size() && kHeightTau[i] <= 2.21; ++i)
    EXPECT_LE(std::fabs(validation::interpolate(fine.tau, fine.H, kHeightTau[i]) - kHeightH[i]),
              std::fabs(validation::interpolate(medium.tau, medium.H, kHeightTau[i]) - kHeightH[i]) + kDigits)
        << "refinement moved the height away from the data at tau = " << kHeightTau[i];
}

}  // namespace
}  // namespace fbar
