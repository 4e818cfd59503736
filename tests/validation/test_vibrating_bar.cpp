// Validation: axial vibration of a clamped-free elastic bar (docs/validation.md; Bardenhagen 2002).
// The problem, its reference and the run are in vibrating_bar_case.h; the tests here run it on the CPU engine.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "scene/scene_parse.h"
#include "vibrating_bar_case.h"

namespace fbar {
namespace {

using namespace bar_case;

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

// Cauchy similitude (simulation.use_cauchy_scaling true, cauchy_bulk_ratio r, no Froude scaling): E x r at equal
// density makes the wave speed sqrt(r) c, so the first period is T1 / sqrt(r). r = 4 must give 5 s within the same
// 2 % as the unscaled bar (the clamp's error is relative to L, which does not change); a ratio applied twice (E x 16,
// 2.5 s) or not at all (10 s) fails.
TEST(VibratingBar, CauchyScalingShortensThePeriodBySqrtOfTheRatio) {
  double scaled_modulus = 0;
  const BarResult r = run_bar(0.5, 1.6, validation::WallFit::LastWallNodePlane, kApic, [&](Scene& scene) {
    scene.simulation.cauchy_scaling = CauchyScaling::On;
    scene.simulation.cauchy_bulk_ratio = 4.0;
    apply_froude_scaling(scene);
    scaled_modulus = scene.bodies[0].material.youngs_modulus;
  });
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(scaled_modulus, 4.0 * kE);
  EXPECT_NEAR(r.period, kPeriod / 2, 0.02 * kPeriod / 2);
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
  for (const Scheme& s : validation::kTransferSchemes) {
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
