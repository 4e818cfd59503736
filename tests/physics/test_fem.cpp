// Linear tetrahedra (physics/fem.cuh): the element forces against closed forms, the patch test on a box mesh, and the
// F-bar element's volume ratio.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "geometry/tet_mesh.h"
#include "physics/constitutive_models.cuh"
#include "physics/fem.cuh"
#include "physics/material_spec.h"

namespace fbar {
namespace {

TetElement<double> make_element(const Vec3d& X0, const Vec3d& X1, const Vec3d& X2, const Vec3d& X3) {
  TetElement<double> e{};
  const Mat3d Dm = tet_edges(X0, X1, X2, X3);
  e.Dm_inv = inverse(Dm);
  e.volume = determinant(Dm) / 6.0;
  return e;
}

MaterialSpec elastic(double E, double nu) {
  MaterialSpec m;
  m.law = Constitutive::FixedCorotated;
  m.rho = 1000.0;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  return m;
}

// The unit right tetrahedron stretched by s along x: F = diag(s, 1, 1), sigma11 = (lambda + 2 mu)(s - 1) (the
// uniaxial check of fixed_corotated.cuh) with P = sigma J F^-T: P11 = sigma11 (J = s). f = -V0 P Dm^-T with V0 = 1/6
// and Dm = I: vertex 1 is pulled back by -P11 / 6 along x (a third of the traction P11 on the face x = 0 of area 1/2),
// vertex 2 by -P22 / 6 along y; nothing else.
TEST(FemElement, UniaxialStretchGivesTheFaceTraction) {
  const TetElement<double> e = make_element(Vec3d::zero(), Vec3d{{1, 0, 0}}, Vec3d{{0, 1, 0}}, Vec3d{{0, 0, 1}});
  EXPECT_DOUBLE_EQ(e.volume, 1.0 / 6.0);
  const double s = 1.01, E = 1e6, nu = 0.3;
  const auto params = FixedCorotated::make_params<double>(elastic(E, nu));
  const Mat3d F = tet_deformation_gradient(e, Vec3d::zero(), Vec3d{{s, 0, 0}}, Vec3d{{0, 1, 0}}, Vec3d{{0, 0, 1}});
  EXPECT_NEAR(F(0, 0), s, 1e-15);
  EXPECT_NEAR(F(1, 1), 1.0, 1e-15);
  const Mat3d tau = FixedCorotated::kirchhoff_stress(params, FixedCorotatedState<double>{F}, Mat3d::zero()).kirchhoff;
  const Mat3d H = tet_nodal_forces(e, tau, F);
  const double P11 = (params.lambda + 2 * params.mu) * (s - 1);  // sigma11 J / s with J = s
  EXPECT_NEAR(H(0, 0), -P11 / 6.0, 1e-9 * P11);
  EXPECT_NEAR(H(1, 0), 0.0, 1e-9 * P11);
  EXPECT_NEAR(H(2, 0), 0.0, 1e-9 * P11);
  // Vertex 2's force along y: -V0 P22 (Dm^-T)_22 with P22 = sigma22 J / F22 = lambda (s - 1) s.
  EXPECT_NEAR(H(1, 1), -params.lambda * (s - 1) * s / 6.0, 1e-9 * P11);
  // Vertex 0 balances the three others: f0 = -(f1 + f2 + f3); along x only vertex 1 is loaded (P is diagonal).
  EXPECT_NEAR(H(0, 1), 0.0, 1e-9 * P11);
  EXPECT_NEAR(H(0, 2), 0.0, 1e-9 * P11);
}

// A rigid rotation gives no force; the four forces of any deformation sum to zero and their moment about the origin
// vanishes (f_i x x_i summed: the stress is symmetric in the current configuration).
TEST(FemElement, RigidRotationIsForceFreeAndForcesBalance) {
  const Vec3d X[4] = {Vec3d{{0.1, 0.2, 0.0}}, Vec3d{{1.1, 0.3, 0.1}}, Vec3d{{0.2, 1.0, 0.2}}, Vec3d{{0.3, 0.1, 0.9}}};
  const TetElement<double> e = make_element(X[0], X[1], X[2], X[3]);
  ASSERT_GT(e.volume, 0.0);
  const auto params = FixedCorotated::make_params<double>(elastic(1e6, 0.3));
  const double c = std::cos(0.7), s = std::sin(0.7);
  Mat3d R = Mat3d::identity();
  R(0, 0) = c;
  R(0, 1) = -s;
  R(1, 0) = s;
  R(1, 1) = c;
  Vec3d x[4];
  for (int i = 0; i < 4; ++i) x[i] = R * X[i];
  Mat3d F = tet_deformation_gradient(e, x[0], x[1], x[2], x[3]);
  Mat3d H = tet_nodal_forces(e, FixedCorotated::kirchhoff_stress(params, FixedCorotatedState<double>{F}, Mat3d::zero()).kirchhoff, F);
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) EXPECT_NEAR(H(a, b), 0.0, 1e-9) << a << b;
  // A general deformation.
  x[1] = x[1] + Vec3d{{0.05, -0.02, 0.01}};
  x[3] = x[3] + Vec3d{{-0.03, 0.04, 0.02}};
  F = tet_deformation_gradient(e, x[0], x[1], x[2], x[3]);
  H = tet_nodal_forces(e, FixedCorotated::kirchhoff_stress(params, FixedCorotatedState<double>{F}, Mat3d::zero()).kirchhoff, F);
  Vec3d f[4];
  for (int a = 0; a < 3; ++a) {
    f[1][a] = H(a, 0);
    f[2][a] = H(a, 1);
    f[3][a] = H(a, 2);
    f[0][a] = -(H(a, 0) + H(a, 1) + H(a, 2));
  }
  Vec3d moment = Vec3d::zero();
  double scale = 0;
  for (int i = 0; i < 4; ++i) {
    moment += cross(x[i], f[i]);
    scale = std::max(scale, norm(f[i]));
  }
  ASSERT_GT(scale, 1e3);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(moment[a], 0.0, 1e-12 * scale) << a;
}

// Patch test, for both element laws: a box mesh of Kuhn tetrahedra under a homogeneous deformation x = A X has no net
// force at its inner vertices (the elements around each cancel), and the nodal forces do the virtual work of the
// first Piola-Kirchhoff stress (below).
template <typename M>
void expect_patch_test() {
  const TetMesh mesh = box_tet_mesh(Vec3d::zero(), Vec3d{{1.0, 0.5, 0.5}}, Vec3i{{4, 2, 2}});
  MaterialSpec spec = elastic(1e6, 0.25);
  spec.law = M::kLaw;
  const auto params = M::template make_params<double>(spec);
  Mat3d A = Mat3d::identity();
  A(0, 0) = 1.02;
  A(0, 1) = 0.01;
  A(1, 1) = 0.99;
  A(2, 2) = 1.005;
  std::vector<Vec3d> x;
  for (const Vec3d& X : mesh.vertices) x.push_back(A * X);
  std::vector<Vec3d> f(x.size(), Vec3d::zero());
  Mat3d tau{};
  for (const auto& el : mesh.elements) {
    const TetElement<double> e = make_element(mesh.vertices[el[0]], mesh.vertices[el[1]], mesh.vertices[el[2]], mesh.vertices[el[3]]);
    const Mat3d F = tet_deformation_gradient(e, x[el[0]], x[el[1]], x[el[2]], x[el[3]]);
    tau = M::kirchhoff_stress(params, FixedCorotatedState<double>{F}, Mat3d::zero()).kirchhoff;
    const Mat3d H = tet_nodal_forces(e, tau, F);
    for (int a = 0; a < 3; ++a) {
      f[el[1]][a] += H(a, 0);
      f[el[2]][a] += H(a, 1);
      f[el[3]][a] += H(a, 2);
      f[el[0]][a] -= H(a, 0) + H(a, 1) + H(a, 2);
    }
  }
  const double scale = 1e6 * 0.02 * 0.25 * 0.25;
  Mat3d virtual_work = Mat3d::zero();  // sum_v f_v X_v^T
  for (std::size_t v = 0; v < x.size(); ++v) {
    const Vec3d& X = mesh.vertices[v];
    const bool inner = X[0] > 1e-9 && X[0] < 1 - 1e-9 && X[1] > 1e-9 && X[1] < 0.5 - 1e-9 && X[2] > 1e-9 && X[2] < 0.5 - 1e-9;
    if (inner) {
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(f[v][a], 0.0, 1e-9 * scale) << "vertex " << v;
    }
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) virtual_work(a, b) += f[v][a] * X[b];
  }
  // Virtual work: moving the vertices by dx_v = dA X_v changes every element's F by dA, so the stored energy by
  // V P : dA; the nodal forces are -dPsi/dx, hence sum_v f_v X_v^T = -V P with P = tau F^-T (V = 0.25 m^3).
  const Mat3d P = tau * transpose(inverse(A));
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) EXPECT_NEAR(virtual_work(a, b), -0.25 * P(a, b), 1e-9 * scale) << a << b;
}

TEST(FemElement, HomogeneousDeformationOfAMeshLeavesInnerVerticesFree) {
  expect_patch_test<FixedCorotated>();
  expect_patch_test<NeoHookean>();
}

// The F-bar element's gradient keeps F's shape and takes the blended volume ratio.
TEST(FemElement, FbarGradientTakesTheBlendedVolumeRatio) {
  Mat3d F = Mat3d::identity();
  F(0, 0) = 1.1;
  F(0, 1) = 0.05;
  F(2, 2) = 0.95;
  const double J = determinant(F), Jbar = 0.98;
  for (double psi : {0.0, 0.5, 1.0}) {
    const Mat3d Fb = tet_fbar_gradient(F, J, Jbar, psi);
    EXPECT_NEAR(determinant(Fb), (1 - psi) * J + psi * Jbar, 1e-14) << psi;
    EXPECT_NEAR(Fb(0, 1) / Fb(0, 0), F(0, 1) / F(0, 0), 1e-14);
  }
}

// The smallest height of the unit right tetrahedron: 3 V / largest face = 3 (1/6) / (sqrt(3)/2) = 1 / sqrt(3).
TEST(FemElement, MinHeightOfTheRightTetrahedron) {
  EXPECT_NEAR(tet_min_height(Vec3d::zero(), Vec3d{{1, 0, 0}}, Vec3d{{0, 1, 0}}, Vec3d{{0, 0, 1}}), 1 / std::sqrt(3.0), 1e-15);
}

}  // namespace
}  // namespace fbar
