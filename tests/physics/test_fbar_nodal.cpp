// Nodal F-bar (physics/fbar_nodal.cuh) against ClaymoreUW's formulas, transcribed from mgmpm_kernels.cuh: the fused
// fluid kernel (g2p2g_FBar, JFluid_FBAR: K:10027-10042), the split solid kernel (p2g_FBar, FixedCorotated_FBAR:
// K:13909-13947), and the grid update's node value (K:1903-1905); and what fbar adds: a plastic law's trial state
// at JBar, and psi = 0 as plain MPM.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "physics/constitutive_models.cuh"
#include "physics/fbar_nodal.cuh"
#include "physics_test_support.h"

namespace fbar {
namespace {

MaterialSpec jfluid_spec() {
  MaterialSpec m;
  m.law = Constitutive::JFluid;
  m.rho = 1000.0;
  m.bulk_modulus = 2e7;
  m.gamma = 7.1;
  m.viscosity = 1e-3;
  return m;
}

bool same(const Mat3d& a, const Mat3d& b) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (a(i, j) != b(i, j)) return false;
  return true;
}

Mat3d random_gradient(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Mat3d C;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C(i, j) = u(rng);
  return C;
}

// Fused JFluid: sJInc = tr(C) dt; sJ <- sJ + sJ sJInc - sJInc; sJBar* = sJBar + sJBar sJInc - sJInc (the gathered
// nodal value advanced); stored and stressed: (1 - psi) sJ + psi sJBar*. The law keeps its own 1 - J, and its
// stress state's 1 - J is the blend. Tolerance: 4 ulp of the unit (the same products in another order).
TEST(FbarNodal, FusedFluidFollowsClaymoresKernel) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> small(-0.01, 0.01), psi_of(0.0, 1.0);
  const auto params = JFluid::make_params<double>(jfluid_spec());
  for (int trial = 0; trial < 200; ++trial) {
    const double dt = 1e-4, sJ = small(rng), sbar = small(rng), psi = psi_of(rng);
    const Mat3d C = random_gradient(rng, 50.0);
    const double sJInc = (C(0, 0) + C(1, 1) + C(2, 2)) * dt;
    const double sJ_new = sJ + sJ * sJInc - sJInc;
    const double sbar_new = sbar + sbar * sJInc - sJInc;
    const double want = (1.0 - psi) * sJ_new + psi * sbar_new;
    const JFluid::State<double> state{sJ};
    const NodalFbar<double> f = nodal_fbar<JFluid>(state, C, sbar, true, psi, dt);
    EXPECT_NEAR(f.s, want, 4 * std::numeric_limits<double>::epsilon());
    EXPECT_TRUE(same(f.C_state, C));  // the fluid keeps its own J
    const JFluid::State<double> own = JFluid::advance(params, state, f.C_state, dt);
    EXPECT_NEAR(own.one_minus_J, sJ_new, 4 * std::numeric_limits<double>::epsilon());
    EXPECT_EQ(fbar_stress_state<JFluid>(params, own, f.s).one_minus_J, f.s);
  }
}

// Split FixedCorotated: F <- (I + dt C) F, J = det F; sJBar = (1 - psi)(1 - J) + psi sJBar_gathered; the stress is
// at J_Scale F, J_Scale = cbrt((1 - sJBar) / J), and the stored F is the unscaled one. Tolerance: 1e-13 on F's
// entries (determinant and cube root in another order).
TEST(FbarNodal, SplitSolidFollowsClaymoresJScale) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> small(-0.02, 0.02), psi_of(0.0, 1.0);
  const FixedCorotated::Params<double> params{1000.0, 1e6, 1e7};
  for (int trial = 0; trial < 200; ++trial) {
    const double dt = 1e-4, sbar = small(rng), psi = psi_of(rng);
    const FixedCorotated::State<double> state{Mat3d::identity() + random_gradient(rng, 0.03)};
    const Mat3d C = random_gradient(rng, 50.0);
    const Mat3d F_new = (Mat3d::identity() + C * dt) * state.F;
    const double J = determinant(F_new);
    const double want = (1.0 - psi) * (1.0 - J) + psi * sbar;
    const Mat3d F_bar = F_new * std::cbrt((1.0 - want) / J);
    const NodalFbar<double> f = nodal_fbar<FixedCorotated>(state, C, sbar, false, psi, dt);
    EXPECT_NEAR(f.s, want, 1e-14);
    EXPECT_TRUE(same(f.C_state, C));
    const FixedCorotated::State<double> own = FixedCorotated::advance(params, state, f.C_state, dt);
    const Mat3d stressed = fbar_stress_state<FixedCorotated>(params, own, f.s).F;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        EXPECT_NEAR(own.F(i, j), F_new(i, j), 1e-15);
        EXPECT_NEAR(stressed(i, j), F_bar(i, j), 1e-13);
      }
  }
}

// A plastic law (DruckerPrager) stores the state at JBar, as ClaymoreUW's Sand_FBAR does: its trial F is
// lambda (I + dt C) F, det = 1 - s. Inside the cone (compression) the return mapping keeps the trial, so the stored
// F is lambda F_trial and its determinant 1 - s. Tolerance 1e-13.
TEST(FbarNodal, PlasticLawTakesTheAveragedVolume) {
  MaterialSpec m = jfluid_spec();
  m.law = Constitutive::DruckerPrager;
  m.youngs_modulus = 1e7;
  m.poisson_ratio = 0.3;
  m.rho = 2000.0;
  m.friction_angle = 30.0;
  m.cohesion = 0.0;
  m.beta = 0.5;
  m.logJp0 = 0.0;
  const auto params = DruckerPrager::make_params<double>(m);
  const DruckerPrager::State<double> state = DruckerPrager::reference_state<double>();
  Mat3d C = Mat3d::zero();
  C(0, 0) = -20.0;
  C(1, 1) = -10.0;
  C(2, 2) = -15.0;  // compression, well inside the cone
  const double dt = 1e-4;
  for (const bool fused : {true, false})
    for (const double psi : {0.3, 0.9, 1.0}) {
      const double sbar = 0.004;
      const NodalFbar<double> f = nodal_fbar<DruckerPrager>(state, C, sbar, fused, psi, dt);
      const DruckerPrager::State<double> stored = DruckerPrager::advance(params, state, f.C_state, dt);
      EXPECT_NEAR(determinant(stored.F), 1.0 - f.s, 1e-13);
      const Mat3d trial = Mat3d::identity() + C * dt;
      const double lambda = std::cbrt((1.0 - f.s) / determinant(trial));
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) EXPECT_NEAR(stored.F(i, j), lambda * trial(i, j), 1e-13);
      EXPECT_TRUE(same(fbar_stress_state<DruckerPrager>(params, stored, f.s).F, stored.F));  // stressed as stored
    }
}

// psi = 0: the gradient is C itself for every law (bit for bit), and the stress state's J is the particle's own
// (within rounding): plain MPM.
TEST(FbarNodal, PsiZeroIsPlainMpm) {
  std::mt19937 rng(3);
  const Mat3d C = random_gradient(rng, 50.0);
  const double dt = 1e-4;
  const DruckerPrager::State<double> sand = DruckerPrager::reference_state<double>();
  EXPECT_TRUE(same(nodal_fbar<DruckerPrager>(sand, C, 0.3, true, 0.0, dt).C_state, C));
  const FixedCorotated::Params<double> params{1000.0, 1e6, 1e7};
  const FixedCorotated::State<double> solid{Mat3d::identity() + random_gradient(rng, 0.03)};
  const NodalFbar<double> f = nodal_fbar<FixedCorotated>(solid, C, 0.3, false, 0.0, dt);
  const FixedCorotated::State<double> own = FixedCorotated::advance(params, solid, f.C_state, dt);
  EXPECT_NEAR(f.s, 1.0 - determinant(own.F), 1e-15);
  const Mat3d stressed = fbar_stress_state<FixedCorotated>(params, own, f.s).F;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(stressed(i, j), own.F(i, j), 1e-15);
}

// A node's value: S / V, clamped to +-0.9 for the fused kernel only (ClaymoreUW clamps in the grid update the fused
// kernel reads; the split kernel divides without), 0 where no volume reached the node.
TEST(FbarNodal, NodeValueClampsOnlyTheFusedKernel) {
  EXPECT_DOUBLE_EQ(fbar_node_value(0.2, 0.5, true), 0.4);
  EXPECT_DOUBLE_EQ(fbar_node_value(0.5, 0.5, true), 0.9);
  EXPECT_DOUBLE_EQ(fbar_node_value(-0.5, 0.5, true), -0.9);
  EXPECT_DOUBLE_EQ(fbar_node_value(0.5, 0.5, false), 1.0);
  EXPECT_DOUBLE_EQ(fbar_node_value(0.5, 0.0, true), 0.0);
  EXPECT_DOUBLE_EQ(fbar_node_value(0.5, 0.0, false), 0.0);
}

}  // namespace
}  // namespace fbar
