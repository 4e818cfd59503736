// Validation: axial vibration of a clamped-free elastic bar (VALIDATION.md item 3, Bardenhagen 2002).
//
// Problem: L = 25 m, E = 100 Pa, rho = 1 kg/m^3, nu = 0, clamped at x = 0, free at x = L, initial velocity
// v(x, 0) = v0 sin(pi x / (2 L)), v0 = 0.1 m/s (the first mode). Exact (linear elasticity):
//   c = sqrt(E / rho) = 10 m/s, omega = pi c / (2 L), T1 = 4 L / c = 10 s,
//   u(x, t) = (v0 / omega) sin(pi x / (2 L)) sin(omega t): tip amplitude v0 / omega = 0.15915 m,
//   centre-of-mass velocity v_cm(t) = (2 / pi) v0 cos(omega t): amplitude 0.063662 m/s.
// With nu = 0 the bar and the laterally confined p-wave speeds agree (lambda = 0: c_p = sqrt((lambda+2mu)/rho) =
// sqrt(E/rho)), so a thin 3D bar between lateral slip walls (1 x 1 cell cross-section, 2 x 2 particles) is exactly
// the 1D bar. FixedCorotated (its small-strain limit is linear elasticity; the peak strain v0/c = 1 % adds a
// geometric nonlinearity of the same order on the stress and far less on the period).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace {

using validation::kPi;
using validation::r3;

constexpr double kL = 25.0;                      // [m]
constexpr double kE = 100.0;                     // [Pa]
constexpr double kRho = 1.0;                     // [kg/m^3]
constexpr double kV0 = 0.1;                      // [m/s]
constexpr double kC = 10.0;                      // [m/s] sqrt(E / rho)
constexpr double kPeriod = 4 * kL / kC;          // [s] 10
constexpr double kOmega = 2 * kPi / kPeriod;     // [1/s]
constexpr double kVcmAmplitude = 2 / kPi * kV0;  // [m/s] 0.063662
constexpr double kTipAmplitude = kV0 / kOmega;   // [m] 0.15915

struct BarResult {
  bool ok = false;
  double period = 0;  // [s] from the centre-of-mass velocity zero crossings
  int crossings = 0;
  std::vector<double> peaks;                  // [m/s] |v_cm| extremum in each half period (t = 0, T/2, T, ...)
  double tip_amplitude = 0;                   // [m] largest |mean tip-row displacement| in the first half period
  double energy0 = 0, energy_end = 0;         // [J] kinetic + elastic
  double energy_max = 0, energy_min = 1e300;  // [J] over the run
  double dt = 0;                              // [s] last step size
  long long steps = 0;
  std::size_t particles = 0;
  double seconds = 0;
};

/// Transfer scheme of a run: APIC (alpha = beta = 0), PIC-FLIP blend (alpha), ASFLIP (alpha, beta_min, beta_max).
struct Scheme {
  const char* name;
  double alpha, beta_min, beta_max;
};
constexpr Scheme kApic{"APIC", 0, 0, 0};

BarResult run_bar(double dx, double periods, validation::WallFit fit = validation::WallFit::LastWallNodePlane,
                  const Scheme& scheme = kApic) {
  validation::Stopwatch clock;
  const double x0 = dx + validation::wall_inset(fit, dx), y0 = x0, z0 = x0;  // material faces (validation_support.h)
  Scene scene = validation::make_scene(r3(x0 + kL + 4 * dx, y0 + 2.5 * dx, z0 + 2.5 * dx), dx, r3(0, 0, 0));
  BodySpec bar = validation::fixed_corotated_body(kRho, kE, 0.0);
  bar.algorithm.use_asflip = true;
  bar.algorithm.asflip_alpha = scheme.alpha;
  bar.algorithm.asflip_beta_min = scheme.beta_min;
  bar.algorithm.asflip_beta_max = scheme.beta_max;
  validation::add_box(bar, r3(x0, y0, z0), r3(kL, dx, dx));
  scene.bodies.push_back(bar);
  // Clamp: sticky wall against the bar's end x = x0; lateral: slip walls against the bar's faces.
  scene.boundaries.push_back(validation::wall_box(Contact::Sticky, r3(x0, -validation::kFar, -validation::kFar),
                                                  r3(validation::kFar, validation::kFar, validation::kFar), dx, fit));
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(-validation::kFar, y0, z0),
                                                  r3(validation::kFar, y0 + dx, z0 + dx), dx, fit));

  CpuEngine<double> engine(scene);
  engine.set_velocities(0, [&](const Vec3d& x) { return Vec3d{{kV0 * std::sin(kPi * (x[0] - x0) / (2 * kL)), 0, 0}}; });
  const std::vector<Vec3d> x_ref = engine.positions(0);
  double tip_ref = 0;
  for (const Vec3d& x : x_ref) tip_ref = std::max(tip_ref, x[0]);
  std::vector<std::size_t> tip;  // the last particle row (largest x)
  for (std::size_t i = 0; i < x_ref.size(); ++i)
    if (x_ref[i][0] > tip_ref - 1e-9) tip.push_back(i);

  BarResult r;
  r.particles = x_ref.size();
  const double mass = engine.total_mass();
  r.energy0 = engine.kinetic_energy() + engine.elastic_energy();
  std::vector<double> times{0.0}, vcm{engine.total_momentum()[0] / mass};
  const double t_end = periods * kPeriod;
  while (engine.time() < t_end) {
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return r;
    }
    const double e = engine.kinetic_energy() + engine.elastic_energy();
    r.energy_max = std::max(r.energy_max, e);
    r.energy_min = std::min(r.energy_min, e);
    times.push_back(engine.time());
    vcm.push_back(engine.total_momentum()[0] / mass);
    if (engine.time() < 0.5 * kPeriod) {
      double u = 0;
      for (std::size_t i : tip) u += engine.positions(0)[i][0] - x_ref[i][0];
      r.tip_amplitude = std::max(r.tip_amplitude, std::fabs(u / tip.size()));
    }
  }
  r.steps = engine.steps();
  r.dt = engine.last_dt();
  r.energy_end = engine.kinetic_energy() + engine.elastic_energy();
  const std::vector<double> zeros = validation::zero_crossings(times, vcm);
  r.crossings = static_cast<int>(zeros.size());
  if (zeros.size() < 5) {
    ADD_FAILURE() << "only " << zeros.size() << " zero crossings of v_cm in " << t_end << " s";
    return r;
  }
  // Crossings k and k + 4 are two periods apart; average over all such pairs.
  double sum = 0;
  int pairs = 0;
  for (std::size_t k = 0; k + 4 < zeros.size(); ++k, ++pairs) sum += 0.5 * (zeros[k + 4] - zeros[k]);
  r.period = sum / pairs;
  // Extrema of v_cm: at t = 0, then one between consecutive zero crossings.
  r.peaks.push_back(std::fabs(vcm[0]));
  for (std::size_t k = 0; k + 1 < zeros.size(); ++k) {
    double peak = 0;
    for (std::size_t i = 0; i < times.size(); ++i)
      if (times[i] > zeros[k] && times[i] < zeros[k + 1]) peak = std::max(peak, std::fabs(vcm[i]));
    r.peaks.push_back(peak);
  }
  r.seconds = clock.seconds();
  r.ok = true;
  std::printf("vibrating bar, dx = %g m (L/dx = %g): %zu particles, %lld steps, %.2f s wall\n", dx, kL / dx,
              r.particles, r.steps, r.seconds);
  std::printf("  period %.5f s (exact %.1f, error %+.3f %%) from %d zero crossings\n", r.period, kPeriod,
              100 * (r.period / kPeriod - 1), r.crossings);
  std::printf("  |v_cm| extrema:");
  for (double p : r.peaks) std::printf(" %.6f", p);
  std::printf(" (exact %.6f)\n  tip amplitude %.5f m (exact %.5f, error %+.3f %%); energy %.6g -> %.6g J (%+.3f %%)\n",
              kVcmAmplitude, r.tip_amplitude, kTipAmplitude, 100 * (r.tip_amplitude / kTipAmplitude - 1), r.energy0,
              r.energy_end, 100 * (r.energy_end / r.energy0 - 1));
  std::printf("  energy range over the run %+.3f %% .. %+.3f %%, dt %.4g, omega dt %.4g\n",
              100 * (r.energy_min / r.energy0 - 1), 100 * (r.energy_max / r.energy0 - 1), r.dt, kOmega * r.dt);
  return r;
}

// L/dx = 50 (dx = 0.5 m, 400 particles, ~1050 steps over 2.6 periods), the bar's end on the last wall node plane of
// the sticky wall (validation_support.h: the engine's convention).
// Period: within 2 % of T1 = 10 s. Error budget: the clamp. The grid velocity vanishes identically up to half a cell
// before the bar's end and, quadratic B-splines being C1, has zero slope there: the clamp's position is known to a
// fraction of a cell. The measured period error is +0.18 dx / L at three resolutions (the bar vibrates as if 0.18 dx
// longer: +0.36 % here; with the end on the zero-velocity plane instead, -0.34 dx / L). B-spline/lumped-mass
// dispersion of the first mode is O((k dx)^2) = 1e-3, symplectic Euler's phase error O((omega dt)^2) = 2e-4.
// 2 % is 5x the budget and still fails a modulus 5 % off (period -2.4 %).
// Amplitude: APIC transfers affine velocity fields exactly, so the first mode loses only O((k dx)^4) per step
// (measured 0.02 % per period; 0.14 % with the end on the zero-velocity plane, whose frozen first layer adds
// friction). PIC, or APIC with a broken affine term, damps the mode by the B-spline round trip 1 - (k dx)^2 / 4 per
// step (k = pi / 2L): 2.5e-4 x 400 steps = 10 % per period (amplitude 0.906 after one period; an estimate, the CPU
// engine has no PIC mode). The bound 0.99 per period allows 1 % loss: 50x APIC's measured loss, 10x less than PIC's
// (the suggested 0.9 would let PIC pass).
// Tip amplitude: within 2 % (same clamp budget). Energy (kinetic + elastic at the particles): symplectic Euler's
// measured energy oscillates by +-(omega dt / 2) E about its conserved shadow energy; max over the run <= E0 (1 +
// omega dt) means no secular growth.
TEST(VibratingBar, PeriodAmplitudeAndEnergy) {
  const BarResult r = run_bar(0.5, 2.6);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.period, kPeriod, 0.02 * kPeriod);
  ASSERT_GE(r.peaks.size(), 5u);
  EXPECT_NEAR(r.peaks[0], kVcmAmplitude, 1e-3 * kVcmAmplitude);  // the sampled initial field (lattice quadrature)
  EXPECT_GE(r.peaks[2], 0.99 * kVcmAmplitude);                   // after one period
  EXPECT_GE(r.peaks[4], 0.99 * r.peaks[2]);                      // over the second period
  EXPECT_LE(r.peaks[2], kVcmAmplitude * (1 + 1e-3));             // and no growth
  EXPECT_NEAR(r.tip_amplitude, kTipAmplitude, 0.02 * kTipAmplitude);
  EXPECT_LE(r.energy_max, r.energy0 * (1 + kOmega * r.dt));
}

// The period error converges at first order (the clamp, above): L/dx = 25, 50, 100 must give decreasing errors, each
// within 2 %, halving with dx (ratio > 1.5; first order gives 2).
TEST(VibratingBar, PeriodErrorConvergesWithRefinement) {
  const BarResult coarse = run_bar(1.0, 2.6), medium = run_bar(0.5, 2.6), fine = run_bar(0.25, 2.6);
  ASSERT_TRUE(coarse.ok && medium.ok && fine.ok);
  const double e1 = std::fabs(coarse.period / kPeriod - 1), e2 = std::fabs(medium.period / kPeriod - 1),
               e3 = std::fabs(fine.period / kPeriod - 1);
  EXPECT_LE(e1, 0.02);
  EXPECT_GT(e1 / e2, 1.5);
  EXPECT_GT(e2 / e3, 1.5);
  std::printf("period error |T - T1| / T1: %.4f %% (L/dx 25), %.4f %% (50), %.4f %% (100); ratios %.2f, %.2f\n",
              100 * e1, 100 * e2, 100 * e3, e1 / e2, e2 / e3);
}

// Every transfer scheme on the same bar (L/dx 50, 2.6 periods): the period and the amplitude criteria above hold
// for each (2 % period; at most 1 % amplitude loss per period, which still fails PIC's ~10 %). FLIP (alpha = 1)
// carries the particle velocity over and so damps even less than APIC's O((k dx)^4); the ASFLIP position
// correction (beta) moves particles by the FLIP velocity difference, which in this smooth mode is O((k dx)^2) v:
// no change of period or amplitude at this tolerance. Measured (CPU, double): period +0.357 % for all four;
// v_cm amplitude change per period -0.018 % (APIC), +0.0007 % (PIC-FLIP 0.95, ASFLIP 0.95/0/0.2), +0.0025 % (FLIP).
TEST(VibratingBar, PeriodAndDecayPerTransferScheme) {
  const Scheme schemes[] = {kApic, {"PIC-FLIP 0.95", 0.95, 0, 0}, {"FLIP", 1.0, 0, 0}, {"ASFLIP", 0.95, 0.0, 0.2}};
  for (const Scheme& s : schemes) {
    SCOPED_TRACE(s.name);
    const BarResult r = run_bar(0.5, 2.6, validation::WallFit::LastWallNodePlane, s);
    ASSERT_TRUE(r.ok);
    ASSERT_GE(r.peaks.size(), 5u);
    const double decay = 1 - std::sqrt(r.peaks[4] / r.peaks[0]);  // per period, over two periods
    std::printf("%-14s period %.4f s (%+.3f %%), v_cm amplitude loss per period %.4f %%, energy max/E0 %.5f, "
                "end/E0 %.5f, %.1f s wall\n",
                s.name, r.period, 100 * (r.period / kPeriod - 1), 100 * decay, r.energy_max / r.energy0,
                r.energy_end / r.energy0, r.seconds);
    EXPECT_NEAR(r.period, kPeriod, 0.02 * kPeriod);
    EXPECT_GE(r.peaks[2], 0.99 * kVcmAmplitude);
    EXPECT_GE(r.peaks[4], 0.99 * r.peaks[2]);
    EXPECT_LE(r.peaks[2], kVcmAmplitude * (1 + 1e-3));
  }
}

}  // namespace
}  // namespace fbar
