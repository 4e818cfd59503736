// Validation: VonMises in a structure, Hill's elastic-perfectly-plastic thick-walled sphere under internal pressure
// (the problem, its closed form and the run: thick_sphere_case.h). CPU engine, double precision.
#include <gtest/gtest.h>

#include "thick_sphere_case.h"

namespace fbar {
namespace {

using namespace thick_sphere_case;

// a / dx = 10, p = 1.2 sigma_y (c = 0.1505 m, half the wall yields). Measured (2026-11-25): c 0.1479 m, 0.4 % of the
// particles inside c - dx unyielded, none outside c + dx yielded, u(b) 0.899 of Hill's, sigma_r RMS 0.044 sigma_y,
// sigma_theta - sigma_r = 0.997 sigma_y in the plastic zone.
TEST(ThickSphere, PlasticZoneAndDisplacementFollowHill) {
  const double dx = 0.01;
  const SphereResult r = run_sphere(dx, 1.2 * kSy);
  ASSERT_TRUE(r.ok);
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
  // u(b) grows with c^3: 15 % holds the pressure layer's offset (the load acts at about a + dx / 4, which moves c
  // by -1.7 %, u(b) by -5 %) and the symmetry planes' stiffer first particle layers. The elastic law would give 0.60.
  EXPECT_NEAR(r.ub_measured / r.ub_exact, 1.0, 0.15);
  EXPECT_LE(r.u_rms, 0.2);
}

}  // namespace
}  // namespace fbar
