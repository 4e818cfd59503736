// Frame attributes derived from F and the Cauchy stress (physics/frame_columns.h, io/particle_frame.h): PK1, PK2, small
// strain, invariants, principal values and the von Mises strain, against closed forms; names and units resolve.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "io/particle_frame.h"
#include "scene/attributes.h"

namespace fbar {
namespace {

double value(const std::string& name, const FrameInputs<double>& in) {
  FrameAttributeSpec a;
  EXPECT_TRUE(resolve_frame_attribute(canonical_attribute(name), a)) << name;
  return frame_value(a.column, in);
}

/// F = diag(2, 1, 1/2) (J = 1), sigma = diag(3, 2, 1) Pa: every derived quantity is diagonal and known by hand.
FrameInputs<double> stretched() {
  FrameInputs<double> in{};
  in.F = Mat3d::diagonal(Vec3d{{2.0, 1.0, 0.5}});
  in.sigma = Mat3d::diagonal(Vec3d{{3.0, 2.0, 1.0}});
  in.J = 1.0;
  return in;
}

TEST(FrameAttributes, TensorsOfADiagonalState) {
  const FrameInputs<double> in = stretched();
  // P = J sigma F^-T = diag(1.5, 2, 2); S = F^-1 P = diag(0.75, 2, 4); eps = sym(F) - I = diag(1, 0, -0.5).
  EXPECT_DOUBLE_EQ(value("StressPK1_XX", in), 1.5);
  EXPECT_DOUBLE_EQ(value("StressPK1_ZZ", in), 2.0);
  EXPECT_DOUBLE_EQ(value("StressPK1_XY", in), 0.0);
  EXPECT_DOUBLE_EQ(value("StressPK2_XX", in), 0.75);
  EXPECT_DOUBLE_EQ(value("StressPK2_ZZ", in), 4.0);
  EXPECT_DOUBLE_EQ(value("StrainSmall_XX", in), 1.0);
  EXPECT_DOUBLE_EQ(value("StrainSmall_ZZ", in), -0.5);
  // Invariants of F: I1 = 3.5, I2 = 2 + 0.5 + 1 = 3.5, I3 = 1; of sigma: 6, 11, 6.
  EXPECT_DOUBLE_EQ(value("DefGrad_Invariant1", in), 3.5);
  EXPECT_DOUBLE_EQ(value("DefGrad_Invariant2", in), 3.5);
  EXPECT_DOUBLE_EQ(value("DefGrad_Invariant3", in), 1.0);
  EXPECT_DOUBLE_EQ(value("StressCauchy_Invariant1", in), 6.0);
  EXPECT_DOUBLE_EQ(value("StressCauchy_Invariant2", in), 11.0);
  EXPECT_DOUBLE_EQ(value("StressCauchy_Invariant3", in), 6.0);
  // Aliases: Dilation = tr eps = 0.5, StrainSmall_Determinant = det eps = 0.
  EXPECT_DOUBLE_EQ(value("Dilation", in), 0.5);
  EXPECT_DOUBLE_EQ(value("StrainSmall_Determinant", in), 0.0);
  // e = dev(eps) = (5/6, -1/6, -2/3): sqrt(2/3 e:e) = sqrt(28/36).
  EXPECT_NEAR(value("VonMisesStrain", in), std::sqrt(28.0 / 36.0), 1e-15);
}

TEST(FrameAttributes, PrincipalValuesOfARotatedState) {
  // Rotating the state by R (45 degrees about z): F' = R F R^T, sigma' = R sigma R^T. Principal values, largest
  // first, are the diagonal values again: singular values of F, eigenvalues of sigma, PK2 and eps.
  const double c = std::sqrt(0.5);
  Mat3d R = Mat3d::identity();
  R(0, 0) = c;
  R(0, 1) = -c;
  R(1, 0) = c;
  R(1, 1) = c;
  FrameInputs<double> in = stretched();
  in.F = R * in.F * transpose(R);
  in.sigma = R * in.sigma * transpose(R);
  EXPECT_NEAR(value("DefGrad_1", in), 2.0, 1e-14);
  EXPECT_NEAR(value("DefGrad_2", in), 1.0, 1e-14);
  EXPECT_NEAR(value("DefGrad_3", in), 0.5, 1e-14);
  EXPECT_NEAR(value("StressCauchy_1", in), 3.0, 1e-14);
  EXPECT_NEAR(value("StressCauchy_3", in), 1.0, 1e-14);
  EXPECT_NEAR(value("StressPK2_1", in), 4.0, 1e-13);  // S rotates like sigma here: diag(0.75, 2, 4) rotated
  EXPECT_NEAR(value("StressPK2_3", in), 0.75, 1e-13);
  EXPECT_NEAR(value("StressPK1_1", in), 2.0, 1e-13);  // singular values of P = R diag(1.5, 2, 2) R^T
  EXPECT_NEAR(value("StrainSmall_1", in), 1.0, 1e-14);
  EXPECT_NEAR(value("StrainSmall_3", in), -0.5, 1e-14);
  // Invariants do not change under rotation.
  EXPECT_NEAR(value("StressCauchy_Invariant2", in), 11.0, 1e-13);
  EXPECT_NEAR(value("VonMisesStrain", in), std::sqrt(28.0 / 36.0), 1e-14);
}

// JBar and J of one JFluid particle (1 - J = 0.01): without nodal F-bar JBar is J; with it, JBar is the particle's
// 1 - JBar (0.02 here) and the stress is the one at JBar: p = (K / gamma)(JBar^-gamma - 1), ClaymoreUW's JBarFluid.
TEST(FrameAttributes, JBarIsTheVolumeRatioTheStressSees) {
  MaterialSpec m;
  m.law = Constitutive::JFluid;
  m.rho = 1000.0;
  m.bulk_modulus = 2e7;
  m.gamma = 7.0;
  const auto params = JFluid::make_params<double>(m);
  const JFluid::State<double> state{0.01};
  const Vec3d x{{0.0, 0.0, 0.0}};
  const FrameInputs<double> plain =
      particle_frame_inputs<JFluid, double>(x, x, Mat3d::zero(), state, params, 1.0, 1.0, true);
  EXPECT_DOUBLE_EQ(value("J", plain), 0.99);
  EXPECT_DOUBLE_EQ(value("JBar", plain), 0.99);
  const FrameInputs<double> nodal =
      particle_frame_inputs<JFluid, double>(x, x, Mat3d::zero(), state, params, 1.0, 1.0, true, true, 0.02);
  EXPECT_DOUBLE_EQ(value("J", nodal), 0.99);
  EXPECT_DOUBLE_EQ(value("JBar", nodal), 0.98);
  EXPECT_DOUBLE_EQ(value("DefGrad_Determinant_FBAR", nodal), 0.98);
  EXPECT_NEAR(value("Pressure", nodal), 2e7 / 7.0 * (std::pow(0.98, -7.0) - 1.0), 1e-6);
  EXPECT_NEAR(value("Pressure", plain), 2e7 / 7.0 * (std::pow(0.99, -7.0) - 1.0), 1e-6);
}

TEST(FrameAttributes, NamesUnitsAndWhatIsNotKept) {
  FrameAttributeSpec a;
  ASSERT_TRUE(resolve_frame_attribute("StressPK1_Invariant3", a));
  EXPECT_EQ(a.unit, "Pa");
  EXPECT_EQ(a.column.row, kTensorInvariant);
  EXPECT_EQ(a.column.col, 2);
  ASSERT_TRUE(resolve_frame_attribute("StrainSmall_2", a));
  EXPECT_EQ(a.unit, "");
  EXPECT_EQ(a.column.row, kTensorPrincipal);
  // JBar is the volume ratio the stress sees (nodal F-bar's JBar, else J: frame_columns.h); PorePressure is the
  // saturated laws' pore pressure.
  ASSERT_TRUE(resolve_frame_attribute("JBar", a));
  EXPECT_EQ(a.column.quantity, FrameQuantity::JBar);
  EXPECT_EQ(a.name, "JBar");
  ASSERT_TRUE(resolve_frame_attribute("PorePressure", a));
  EXPECT_EQ(a.column.quantity, FrameQuantity::PorePressure);
  EXPECT_EQ(a.unit, "Pa");
  EXPECT_TRUE(material_has(Constitutive::CoupledUP, FrameQuantity::PorePressure));
  EXPECT_FALSE(material_has(Constitutive::DruckerPrager, FrameQuantity::PorePressure));
  // Every canonical name of attributes.h resolves.
  for (std::string_view n : kParticleAttributeNames) {
    const std::string name(n);
    EXPECT_TRUE(resolve_frame_attribute(canonical_attribute(name), a)) << name;
  }
}

}  // namespace
}  // namespace fbar
