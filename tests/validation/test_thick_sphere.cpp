// Validation: VonMises in a structure, Hill's elastic-perfectly-plastic thick-walled sphere under internal pressure
// (the problem, its closed form and the run: thick_sphere_case.h). CPU engine, double precision.
#include <gtest/gtest.h>

#include "thick_sphere_case.h"

namespace fbar {
namespace {

using namespace thick_sphere_case;

// a / dx = 10, p = 1.2 sigma_y (c = 0.1505 m, half the wall yields), with a / dx = 5 for the trend. Measured
// (2026-11-25 and again on this revision, dx 0.01 / 0.02): c 0.1479 / 0.1438 m, 0.4 / 0.9 % of the particles inside
// c - dx unyielded, none outside c + dx yielded, u(b) 0.899 / 0.830 of Hill's, elastic-zone u RMS 0.124 / 0.204,
// sigma_r RMS 0.044 / 0.073 sigma_y, sigma_theta - sigma_r = 0.997 / 0.993 sigma_y in the plastic zone.
TEST(ThickSphere, PlasticZoneAndDisplacementFollowHill) {
  const double dx = 0.01;
  const SphereResult coarse = run_sphere(2 * dx, 1.2 * kSy);
  const SphereResult r = run_sphere(dx, 1.2 * kSy);
  ASSERT_TRUE(r.ok && coarse.ok);
  EXPECT_LT(r.ke_end, 1e-6 * r.pressure * kA * kA * kA) << "the hold must end at rest (quasi-static)";
  // The yield front: resolved to half a cell (the particle spacing).
  EXPECT_NEAR(r.c_measured, r.c_exact, 0.5 * dx);
  EXPECT_LE(r.inner_unyielded, 0.02);
  EXPECT_LE(r.outer_yielded, 0.02);
  // On the yield surface, the plastic zone's stresses differ by sigma_y (the return mapping in the structure).
  EXPECT_NEAR(r.diff_plastic, 1.0, 0.02);
  // The radial stress profile, loaded layer and free-surface bin left out: 8 % of sigma_y (the profile spans
  // 1.2 sigma_y; the particles' stresses at a / dx = 10 scatter by a few %).
  EXPECT_LE(r.sr_rms, 0.08);
  // u(b) and the elastic zone's displacement are not converged at a / dx = 10: their errors are O(dx), one-cell
  // effects (the pressure acts on the inner particle layer, at about a + dx / 4, which moves c by -1.7 % and u(b) by
  // -5 %; the symmetry planes' first particle layers are stiffer). So the trend under refinement is asserted, not a
  // band at one dx (the old +-15 % on u(b) and u RMS <= 0.2 had no budget):
  //  * halving dx must cut the u(b) error and the u RMS to at most 0.7 of the coarse run's (first order predicts
  //    0.5; 0.7 leaves room for the second-order part; measured 0.59 and 0.61);
  //  * Richardson's first-order extrapolation 2 u(b)_dx - u(b)_2dx removes the O(dx) error; what is left is O(dx^2):
  //    budget 5 % of Hill's u(b) (measured 0.968: -3.2 %). The elastic law alone would give 0.60.
  const double e_ub = std::fabs(r.ub_measured / r.ub_exact - 1), e_ub_coarse = std::fabs(coarse.ub_measured / coarse.ub_exact - 1);
  const double richardson = (2 * r.ub_measured - coarse.ub_measured) / r.ub_exact;
  std::printf("[measured] u(b) error %.4f (dx %g), %.4f (dx %g): ratio %.3f; Richardson u(b) / Hill %.4f; u RMS ratio %.3f\n",
              e_ub, dx, e_ub_coarse, 2 * dx, e_ub / e_ub_coarse, richardson, r.u_rms / coarse.u_rms);
  EXPECT_LE(e_ub, 0.7 * e_ub_coarse);
  EXPECT_NEAR(richardson, 1.0, 0.05);
  EXPECT_LE(r.u_rms, 0.7 * coarse.u_rms);
}

}  // namespace
}  // namespace fbar
