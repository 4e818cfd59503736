// The saturated soil law (CoupledUP, physics/materials/coupled_up.cuh) on one particle, and the grid's seepage node
// (physics/seepage.cuh): Skempton's B in undrained loading against Biot's closed form, the skeleton equal to the
// DruckerPrager law (the drained limit: p stays 0 when the pore water can leave), the stress decomposition, and the
// drained / held / solved nodes.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "physics/constitutive_models.cuh"
#include "MnBase/Math/bspline.h"
#include "physics/seepage.cuh"
#include "physics/transfer.cuh"

namespace fbar {
namespace {

MaterialSpec saturated_spec() {
  MaterialSpec m;
  m.law = Constitutive::CoupledUP;
  m.youngs_modulus = 3e7;
  m.poisson_ratio = 0.25;
  m.rho = 2000.0;
  m.friction_angle = 35.0;
  m.cohesion = 0.0;
  m.vol_correction = false;
  m.rhow = 1000.0;
  m.poro = 0.4;
  m.Kf = 2.2e9;
  m.Ks = 3.6e10;                                                           // quartz grains
  m.alpha1 = 1.0 - m.youngs_modulus / (3.0 * (1.0 - 2.0 * m.poisson_ratio)) / m.Ks;  // 1 - K / Ks
  m.Kperm = 1e-4;
  return m;
}

// Undrained isotropic compression by a volume strain e (tr C dt = -e): the pore pressure rises by alpha M e and the
// mean total stress by (K + alpha^2 M) e. Their ratio is Skempton's B, whose classic form (Skempton 1954, with
// alpha = 1 - K / Ks) is B = (1/K - 1/Ks) / ((1/K - 1/Ks) + n (1/Kf - 1/Ks)), K = lambda + 2 mu / 3 the skeleton's
// bulk modulus.
TEST(CoupledUP, UndrainedIsotropicCompressionGivesSkemptonsB) {
  const MaterialSpec m = saturated_spec();
  const auto p = CoupledUP::make_params<double>(m);
  const double e = 1e-6;
  const double dt = 1e-3;
  const Mat3d C = Mat3d::identity() * (-e / (3.0 * dt));
  const auto s = CoupledUP::advance(p, CoupledUP::reference_state<double>(), C, dt);
  const StressResult<double> r = CoupledUP::kirchhoff_stress(p, s, Mat3d::zero());
  const double mean_total = -trace(r.kirchhoff) / 3.0 / r.J;
  const double M = 1.0 / (m.poro / m.Kf + (m.alpha1 - m.poro) / m.Ks);
  const double K = m.youngs_modulus / (3.0 * (1.0 - 2.0 * m.poisson_ratio));
  const double skempton = (1.0 / K - 1.0 / m.Ks) / ((1.0 / K - 1.0 / m.Ks) + m.poro * (1.0 / m.Kf - 1.0 / m.Ks));
  EXPECT_NEAR(s.pore_pressure, m.alpha1 * M * e, 1e-9 * m.alpha1 * M * e);
  EXPECT_NEAR(s.pore_pressure / mean_total, skempton, 1e-5) << "B = " << skempton;  // O(e) from the log strain
  EXPECT_NEAR(skempton, 0.9966, 1e-4);  // a stiff, saturated sand: B close to 1
}

// The skeleton is the DruckerPrager law: the same F and logJp after any history, and the total stress is its
// effective stress minus alpha J p I. With p = 0 (drained, the water gone) the stress is DruckerPrager's, bit for bit.
TEST(CoupledUP, SkeletonIsDruckerPragerAndStressIsEffectiveMinusPore) {
  MaterialSpec m = saturated_spec();
  const auto p = CoupledUP::make_params<double>(m);
  m.law = Constitutive::DruckerPrager;
  const auto dp = DruckerPrager::make_params<double>(m);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-40.0, 40.0);
  auto s = CoupledUP::reference_state<double>();
  auto d = DruckerPrager::reference_state<double>();
  for (int step = 0; step < 200; ++step) {
    Mat3d C;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) C(i, j) = u(rng);
    s = CoupledUP::advance(p, s, C, 1e-4);
    d = DruckerPrager::advance(dp, d, C, 1e-4);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_EQ(s.F(i, j), d.F(i, j));
  EXPECT_EQ(s.logJp, d.logJp);
  const StressResult<double> total = CoupledUP::kirchhoff_stress(p, s, Mat3d::zero());
  const StressResult<double> effective = DruckerPrager::kirchhoff_stress(dp, d, Mat3d::zero());
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      EXPECT_NEAR(total.kirchhoff(i, j), effective.kirchhoff(i, j) - (i == j ? m.alpha1 * total.J * s.pore_pressure : 0.0),
                  1e-9 * std::fabs(effective.kirchhoff(i, j)) + 1e-6);
  s.pore_pressure = 0.0;
  const StressResult<double> drained = CoupledUP::kirchhoff_stress(p, s, Mat3d::zero());
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_EQ(drained.kirchhoff(i, j), effective.kirchhoff(i, j));
}

// Undrained (Kperm = 0) pore water exchanges nothing with the grid; drained pore water takes the grid's pressure and
// sets its flux from the head gradient, q = -Kperm / (rhow g0) grad h.
TEST(CoupledUP, SeepTakesTheGridOnlyWhenWaterCanMove) {
  MaterialSpec m = saturated_spec();
  auto p = CoupledUP::make_params<double>(m);
  auto s = CoupledUP::reference_state<double>();
  s.pore_pressure = 5e4;
  const Vec3d grad{{0.0, -2e4, 0.0}};
  const auto drained = CoupledUP::seep(p, s, 0.01, grad, 4e4, -100.0, 1e-4);
  EXPECT_NEAR(drained.pore_pressure, 4e4 + 1e-4 * (1.0 / CoupledUP::storage(m)) * 0.01 - 100.0, 1e-6);
  EXPECT_NEAR(CoupledUP::seepage(p, drained)[1], 2e4 * m.Kperm / (m.rhow * kStandardGravity), 1e-15);
  m.Kperm = 0.0;
  p = CoupledUP::make_params<double>(m);
  const auto undrained = CoupledUP::seep(p, s, 0.01, grad, 4e4, -100.0, 1e-4);
  EXPECT_EQ(undrained.pore_pressure, s.pore_pressure);
  EXPECT_EQ(CoupledUP::seepage(p, undrained)[1], 0.0);
}

// The seepage node: a node in the soil solves the storage equation (h_i = H / V, r_i = R / V, p_i = h_i + rhow g . x);
// a node at the free surface (less than 3/4 of dx^3) is drained to p = 0 unless a boundary holds it; hydrostatic
// water has the same head at every node.
TEST(Seepage, NodesAreSolvedDrainedOrHeld) {
  const double dx = 0.1, full = dx * dx * dx;
  const Vec3d g{{0.0, -9.81, 0.0}};
  const Vec3d x{{0.3, 0.7, 0.2}};
  const double rhow = 1000.0;
  // Hydrostatic water under a surface at y = 1: p = rhow 9.81 (1 - y), h = p + rhow 9.81 y = rhow 9.81.
  const double V = 0.98 * full, h = rhow * 9.81;
  const auto free = [] { return false; };
  const auto wall = [] { return true; };
  int asked = 0;  // a node with its soil around it is solved without probing the boundaries
  const SeepageNode<double> solved = seepage_node(V, V * h, V * 0.5, V * rhow, x, g, [&] { return ++asked > 0; }, full);
  EXPECT_EQ(asked, 0);
  EXPECT_DOUBLE_EQ(solved.head, h);
  EXPECT_DOUBLE_EQ(solved.inflow, 0.5);
  EXPECT_NEAR(solved.pressure, rhow * 9.81 * (1.0 - x[1]), 1e-9);
  const double Vs = 0.5 * full;
  const SeepageNode<double> drained = seepage_node(Vs, Vs * h, Vs * 0.5, Vs * rhow, x, g, free, full);
  EXPECT_DOUBLE_EQ(drained.pressure, 0.0);
  EXPECT_DOUBLE_EQ(drained.inflow, 0.0);
  EXPECT_NEAR(drained.head, rhow * 9.81 * x[1], 1e-9);  // p = 0: h = -rhow g . x
  const SeepageNode<double> held = seepage_node(Vs, Vs * h, Vs * 0.5, Vs * rhow, x, g, wall, full);
  EXPECT_DOUBLE_EQ(held.head, h);
  EXPECT_DOUBLE_EQ(held.inflow, 0.5);
  const SeepageNode<double> empty = seepage_node(0.0, 0.0, 0.0, 0.0, x, g, free, full);
  EXPECT_EQ(empty.head, 0.0);
}

// The G2P sums reproduce a linear head exactly: grad h = D^-1 sum w (x_i - x_p) h_i and sum w h_i = h(x_p) for the
// quadratic B-spline at any position (the transfer carries hydrostatic and linear excess pressures unchanged).
TEST(Seepage, LinearHeadCrossesTheGridExactly) {
  const double dx = 0.05;
  const Vec3d a{{120.0, -3000.0, 45.0}};
  const double h0 = 777.0;
  for (const Vec3d xp : {Vec3d{{0.1234, 0.5678, 0.9012}}, Vec3d{{0.2, 0.3, 0.4}}, Vec3d{{0.0251, 1.0, 0.333}}}) {
    const QuadraticBspline<double> s = quadratic_bspline_inv(xp, 1.0 / dx);
    SeepageSum<double> sum;
    for_each_stencil_node(s, dx, [&](int, int, int, double w, const Vec3d& xixp) {
      const Vec3d xi = xp + xixp;
      sum.add(w, xixp, h0 + dot(a, xi), 0.0);
    });
    EXPECT_NEAR(sum.head, h0 + dot(a, xp), 1e-9);
    const Vec3d grad = sum.head_gradient(apic_inertia_inverse(dx));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(grad[k], a[k], 1e-9 * std::fabs(a[1]));
  }
}

}  // namespace
}  // namespace fbar
