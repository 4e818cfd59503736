// Homogeneous patch tests of the materials against closed forms: stresses, invariance, energy, wave speeds, fp32.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "physics/constitutive_models.cuh"
#include "physics/frame_attributes.h"
#include "physics_test_support.h"

namespace fbar {
namespace {

using test::kEps;

MaterialSpec solid_spec(double E, double nu, double rho) {
  MaterialSpec m;
  m.law = Constitutive::FixedCorotated;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  m.rho = rho;
  return m;
}

MaterialSpec fluid_spec(double K, double gamma, double viscosity, double rho) {
  MaterialSpec m;
  m.law = Constitutive::JFluid;
  m.bulk_modulus = K;
  m.gamma = gamma;
  m.viscosity = viscosity;
  m.rho = rho;
  return m;
}

double max_abs_diff(const Mat3d& a, const Mat3d& b) { return max_abs(a - b); }

// ------------------------------------------------------------------------------------------------ material list

TEST(MaterialList, MapsLawsAndJsonNamesToTypes) {
  EXPECT_EQ(supported_material_names(),
            "JFluid, FixedCorotated, NeoHookean, DruckerPrager, NACC, Hencky, VonMises, CoupledUP");
  EXPECT_EQ(material_index(Constitutive::CoupledUP), 7);
  EXPECT_EQ(material_index(Constitutive::Hencky), 5);
  EXPECT_EQ(material_index(Constitutive::NeoHookean), 2);
  EXPECT_EQ(material_index(Constitutive::JFluid), 0);
  EXPECT_EQ(material_index(Constitutive::FixedCorotated), 1);
  EXPECT_EQ(material_index(Constitutive::DruckerPrager), 3);
  EXPECT_EQ(material_index(Constitutive::NACC), 4);
  EXPECT_EQ(material_index("FixedCorotated"), 1);
  EXPECT_EQ(material_index("Water"), -1);  // aliases are the parser's business (kAliases)
  bool called = false;
  EXPECT_TRUE(visit_material(Constitutive::JFluid, [&](auto m) {
    called = true;
    EXPECT_STREQ(decltype(m)::kJsonName, "JFluid");
  }));
  EXPECT_TRUE(called);
  called = false;
  EXPECT_FALSE(visit_material(static_cast<Constitutive>(99), [&](auto) { called = true; }));
  EXPECT_FALSE(called);
}

TEST(MaterialList, LameParametersFollowValidationFormulas) {
  const auto p = FixedCorotated::make_params<double>(solid_spec(1e7, 0.2, 1000.0));
  EXPECT_NEAR(p.mu, 1e7 / 2.4, 1e-9 * p.mu);
  EXPECT_NEAR(p.lambda, 1e7 * 0.2 / (1.2 * 0.6), 1e-9 * p.lambda);
  EXPECT_EQ(p.rho0, 1000.0);
}

// ------------------------------------------------------------------------------------------------ FixedCorotated

// F = diag(s, 1, 1) gives sigma11 = (lambda + 2 mu)(s - 1), sigma22 = sigma33 = lambda (s - 1).
// (Cauchy stress; what kirchhoff_stress returns is tau = J sigma = s sigma, cauchy_stress() divides by J.)
// The SVD of a diagonal matrix is exact (no rotation is needed), so the only error is the rounding of a few products:
// tolerance 16 eps (lambda + 2 mu) max(1, s)^2.
TEST(FixedCorotated, UniaxialStretchMatchesClosedForm) {
  const auto p = FixedCorotated::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  for (double s : {0.5, 0.8, 0.99, 0.999999, 1.0, 1.000001, 1.01, 1.5, 2.0}) {
    SCOPED_TRACE(s);
    const FixedCorotatedState<double> st{Mat3d::diagonal(Vec3d{{s, 1.0, 1.0}})};
    const StressResult<double> r = FixedCorotated::kirchhoff_stress(p, st, Mat3d::zero());
    EXPECT_NEAR(r.J, s, 4 * kEps * s);
    const Mat3d sigma = cauchy_stress(r);
    const double tol = 16 * kEps * (p.lambda + 2 * p.mu) * std::max(1.0, s * s);
    EXPECT_NEAR(sigma(0, 0), (p.lambda + 2 * p.mu) * (s - 1), tol);
    EXPECT_NEAR(sigma(1, 1), p.lambda * (s - 1), tol);
    EXPECT_NEAR(sigma(2, 2), p.lambda * (s - 1), tol);
    EXPECT_EQ(sigma(0, 1), 0.0);
    EXPECT_EQ(sigma(0, 2), 0.0);
    EXPECT_EQ(sigma(1, 2), 0.0);
  }
}

// tau = P F^T with P = 2 mu (F - R) + lambda (J - 1) J F^-T evaluated literally (polar decomposition, inverse): the
// SVD form in the material must agree for general F, also inverted ones. Both paths are backward stable with
// condition number ~ |F| |F^-1| (< 10 here), so 1e-13 (lambda + 2 mu) is a few hundred eps of the stress scale.
TEST(FixedCorotated, KirchhoffStressEqualsLiteralPiolaFormula) {
  const auto p = FixedCorotated::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  std::mt19937_64 rng(7);
  std::vector<Mat3d> Fs;
  for (int n = 0; n < 200; ++n) Fs.push_back(test::random_deformation(rng, 0.3));
  Fs.push_back(Mat3d::diagonal(Vec3d{{-0.5, 1.0, 1.0}}));  // inverted
  Fs.push_back(test::rotation(Vec3d{{1, 2, 3}}, 0.7) * Mat3d::diagonal(Vec3d{{1.2, 0.9, -0.3}}));
  for (const Mat3d& F : Fs) {
    const Polar3<double> pd = polar_decomposition(F);
    const double J = determinant(F);
    const Mat3d P = (F - pd.R) * (2 * p.mu) + transpose(inverse(F)) * (p.lambda * (J - 1) * J);
    const Mat3d tau_ref = P * transpose(F);
    const StressResult<double> r = FixedCorotated::kirchhoff_stress(p, FixedCorotatedState<double>{F}, Mat3d::zero());
    EXPECT_LE(max_abs_diff(r.kirchhoff, tau_ref), 1e-13 * (p.lambda + 2 * p.mu));
    EXPECT_NEAR(r.J, J, 1e-14);
    EXPECT_EQ(max_abs(r.kirchhoff - transpose(r.kirchhoff)), 0.0);  // exactly symmetric
  }
}

// Single precision, where the GPU runs: the stress of a float F (Newton's polar rotation for J > 0, the SVD for an
// inverted F) against the literal formula in double on the same F. Both float paths are backward stable: the
// error is a few float eps of the stress scale (lambda + 2 mu) max(1, |F|^2); tolerance 64 eps_float of it.
// Random deformations of amplitude 0.05 and 0.3 and the two inverted F of the test above.
TEST(FixedCorotated, SinglePrecisionStressMatchesLiteralFormula) {
  const auto pd = FixedCorotated::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  const auto pf = FixedCorotated::make_params<float>(solid_spec(1e7, 0.3, 1000.0));
  std::mt19937_64 rng(17);
  std::vector<Mat3d> Fs;
  for (int n = 0; n < 300; ++n) Fs.push_back(test::random_deformation(rng, n < 150 ? 0.05 : 0.3));
  Fs.push_back(Mat3d::diagonal(Vec3d{{-0.5, 1.0, 1.0}}));
  Fs.push_back(test::rotation(Vec3d{{1, 2, 3}}, 0.7) * Mat3d::diagonal(Vec3d{{1.2, 0.9, -0.3}}));
  double worst = 0;
  for (const Mat3d& F0 : Fs) {
    const Mat3f Ff = F0.cast<float>();
    const Mat3d F = Ff.cast<double>();  // the float-rounded F, in double
    const Polar3<double> polar = polar_decomposition(F);
    const double J = determinant(F);
    const Mat3d tau_ref =
        ((F - polar.R) * (2 * pd.mu) + transpose(inverse(F)) * (pd.lambda * (J - 1) * J)) * transpose(F);
    const StressResult<float> r = FixedCorotated::kirchhoff_stress(pf, FixedCorotatedState<float>{Ff}, Mat3f::zero());
    const double scale = (pd.lambda + 2 * pd.mu) * std::max(1.0, max_abs(F) * max_abs(F));
    const double err = max_abs_diff(r.kirchhoff.cast<double>(), tau_ref) / scale;
    EXPECT_LE(err, 64 * std::numeric_limits<float>::epsilon());
    EXPECT_NEAR(r.J, J, 8 * std::numeric_limits<float>::epsilon() * std::max(1.0, std::abs(J)));
    EXPECT_EQ(max_abs(r.kirchhoff - transpose(r.kirchhoff)), 0.0f);
    worst = std::max(worst, err);
  }
  std::printf("[measured] FixedCorotated float stress against the double formula: %.2e (lambda + 2 mu)\n", worst);
}

// Objectivity: tau(R F) = R tau(F) R^T for every rotation R. SVD error O(eps |F|) -> 1e-13 (lambda + 2 mu).
TEST(FixedCorotated, RotationInvariance) {
  const auto p = FixedCorotated::make_params<double>(solid_spec(5e6, 0.25, 2000.0));
  std::mt19937_64 rng(11);
  for (int n = 0; n < 200; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.3);
    const Mat3d R = test::random_rotation(rng);
    const Mat3d tau = FixedCorotated::kirchhoff_stress(p, {F}, Mat3d::zero()).kirchhoff;
    const Mat3d tau_rot = FixedCorotated::kirchhoff_stress(p, {R * F}, Mat3d::zero()).kirchhoff;
    EXPECT_LE(max_abs_diff(tau_rot, R * tau * transpose(R)), 1e-13 * (p.lambda + 2 * p.mu));
  }
  // A pure rotation carries no stress.
  const Mat3d R = test::rotation(Vec3d{{0.3, -1, 2}}, 2.1);
  EXPECT_LE(max_abs(FixedCorotated::kirchhoff_stress(p, {R}, Mat3d::zero()).kirchhoff), 16 * kEps * p.lambda);
}

// The stress is the derivative of the energy: P = dpsi/dF (central differences, h = 1e-6: truncation
// ~ psi''' h^2 ~ 1e-12 E, rounding ~ eps psi / h ~ 1e-11 E; tolerance 1e-8 E).
TEST(FixedCorotated, StressIsEnergyDerivative) {
  const auto p = FixedCorotated::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  std::mt19937_64 rng(3);
  for (int n = 0; n < 20; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.2);
    const Mat3d tau = FixedCorotated::kirchhoff_stress(p, {F}, Mat3d::zero()).kirchhoff;
    const Mat3d P = tau * transpose(inverse(F));  // P = tau F^-T
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Mat3d Fp = F, Fm = F;
        Fp(i, j) += h;
        Fm(i, j) -= h;
        const double dpsi =
            (FixedCorotated::energy_density(p, {Fp}) - FixedCorotated::energy_density(p, {Fm})) / (2 * h);
        EXPECT_NEAR(P(i, j), dpsi, 1e-8 * 1e7);
      }
  }
  EXPECT_EQ(FixedCorotated::energy_density(p, FixedCorotated::reference_state<double>()), 0.0);
}

// ------------------------------------------------------------------------------------------------ NeoHookean

// P = mu (F - F^-T) + lambda ln J F^-T; F = diag(s, 1, 1) gives the Cauchy stress
// sigma11 = mu (s - 1/s) + lambda ln(s) / s, sigma22 = sigma33 = lambda ln(s) / s. The material evaluates
// tau = mu (F F^T - I) + lambda ln J I: a few roundings of products of size (lambda + 2 mu) max(1, s^2), so
// 16 eps of that, divided by J = s for sigma.
TEST(NeoHookean, UniaxialStretchMatchesClosedForm) {
  const auto p = NeoHookean::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  for (double s : {0.5, 0.8, 0.99, 0.999999, 1.0, 1.000001, 1.01, 1.5, 2.0}) {
    SCOPED_TRACE(s);
    const StressResult<double> r =
        NeoHookean::kirchhoff_stress(p, {Mat3d::diagonal(Vec3d{{s, 1.0, 1.0}})}, Mat3d::zero());
    EXPECT_NEAR(r.J, s, 4 * kEps * s);
    const Mat3d sigma = cauchy_stress(r);
    const double tol = 16 * kEps * (p.lambda + 2 * p.mu) * std::max(1.0, s * s) / s;
    EXPECT_NEAR(sigma(0, 0), p.mu * (s - 1 / s) + p.lambda * std::log(s) / s, tol);
    EXPECT_NEAR(sigma(1, 1), p.lambda * std::log(s) / s, tol);
    EXPECT_NEAR(sigma(2, 2), p.lambda * std::log(s) / s, tol);
    EXPECT_EQ(sigma(0, 1), 0.0);
    EXPECT_EQ(sigma(1, 2), 0.0);
  }
}

// tau = P F^T with P evaluated literally from the formula above (inverse, transpose) for general F; both
// are backward stable with condition ~ |F| |F^-1| < 10: 1e-13 (lambda + 2 mu). Objectivity tau(R F) = R tau R^T to
// the same bound, a rotation carries no stress, and an inverted F gives a NaN stress (the engines report it).
TEST(NeoHookean, KirchhoffStressEqualsLiteralPiolaFormulaAndIsObjective) {
  const auto p = NeoHookean::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  std::mt19937_64 rng(5);
  for (int n = 0; n < 200; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.3);
    const double J = determinant(F);
    if (J < 0.1) continue;  // ln J needs a well-conditioned, uninverted F
    const Mat3d Finv_T = transpose(inverse(F));
    const Mat3d P = (F - Finv_T) * p.mu + Finv_T * (p.lambda * std::log(J));
    const StressResult<double> r = NeoHookean::kirchhoff_stress(p, {F}, Mat3d::zero());
    EXPECT_LE(max_abs_diff(r.kirchhoff, P * transpose(F)), 1e-13 * (p.lambda + 2 * p.mu));
    EXPECT_EQ(max_abs(r.kirchhoff - transpose(r.kirchhoff)), 0.0);
    const Mat3d R = test::random_rotation(rng);
    const Mat3d tau_rot = NeoHookean::kirchhoff_stress(p, {R * F}, Mat3d::zero()).kirchhoff;
    EXPECT_LE(max_abs_diff(tau_rot, R * r.kirchhoff * transpose(R)), 1e-13 * (p.lambda + 2 * p.mu));
  }
  const Mat3d R = test::rotation(Vec3d{{0.3, -1, 2}}, 2.1);
  EXPECT_LE(max_abs(NeoHookean::kirchhoff_stress(p, {R}, Mat3d::zero()).kirchhoff), 16 * kEps * p.lambda);
  const Mat3d inverted = Mat3d::diagonal(Vec3d{{-0.5, 1.0, 1.0}});
  EXPECT_TRUE(std::isnan(NeoHookean::kirchhoff_stress(p, {inverted}, Mat3d::zero()).kirchhoff(0, 0)));
}

// P = dpsi/dF by central differences (h = 1e-6; truncation and rounding as for FixedCorotated: 1e-8 E), the
// reference state stores no energy, and the wave speed is the p-wave speed of the same Lame parameters.
TEST(NeoHookean, StressIsEnergyDerivativeAndWaveSpeedIsPWaveSpeed) {
  const auto p = NeoHookean::make_params<double>(solid_spec(1e7, 0.3, 1000.0));
  std::mt19937_64 rng(9);
  for (int n = 0; n < 20; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.2);
    const Mat3d P = NeoHookean::kirchhoff_stress(p, {F}, Mat3d::zero()).kirchhoff * transpose(inverse(F));
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Mat3d Fp = F, Fm = F;
        Fp(i, j) += h;
        Fm(i, j) -= h;
        const double dpsi = (NeoHookean::energy_density(p, {Fp}) - NeoHookean::energy_density(p, {Fm})) / (2 * h);
        EXPECT_NEAR(P(i, j), dpsi, 1e-8 * 1e7);
      }
  }
  EXPECT_EQ(NeoHookean::energy_density(p, NeoHookean::reference_state<double>()), 0.0);
  EXPECT_EQ(NeoHookean::wave_speed(p, NeoHookean::reference_state<double>()),
            FixedCorotated::wave_speed(p, FixedCorotated::reference_state<double>()));
}

// c_p = sqrt((lambda + 2 mu) / rho) = sqrt(E (1 - nu) / ((1 + nu)(1 - 2 nu) rho)); ClaymoreUW's
// sqrt(K / rho) under-estimates it by sqrt(3 (1 - nu) / (1 + nu)) (sqrt(3) at nu = 0).
TEST(FixedCorotated, WaveSpeedIsPWaveSpeed) {
  for (double nu : {0.0, 0.2, 0.3, 0.45}) {
    const double E = 1e7, rho = 1000.0;
    const auto p = FixedCorotated::make_params<double>(solid_spec(E, nu, rho));
    const double c = FixedCorotated::wave_speed(p, FixedCorotated::reference_state<double>());
    EXPECT_NEAR(c, std::sqrt(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu) * rho)), 1e-12 * c);
    const double K = E / (3 * (1 - 2 * nu));
    EXPECT_NEAR(c / std::sqrt(K / rho), std::sqrt(3 * (1 - nu) / (1 + nu)), 1e-12);
  }
}

TEST(FixedCorotated, AdvanceUpdatesF) {
  const Mat3d F = test::rotation(Vec3d{{1, 0, 0}}, 0.2) * Mat3d::diagonal(Vec3d{{1.1, 1.0, 0.9}});
  Mat3d C = Mat3d::zero();
  C(0, 1) = 3.0;
  C(2, 2) = -1.0;
  const double dt = 1e-3;
  const Mat3d expected = (Mat3d::identity() + C * dt) * F;
  EXPECT_LE(max_abs_diff(FixedCorotated::advance(FixedCorotatedParams<double>{}, FixedCorotatedState<double>{F}, C, dt).F, expected), 4 * kEps);
}

// ------------------------------------------------------------------------------------------------ JFluid

double tait_pressure_reference(double K, double gamma, double one_minus_J) {
  // long double J = 1 - (1 - J) and pow: 11 more bits than the double function under test.
  const long double J = 1.0L - static_cast<long double>(one_minus_J);
  return static_cast<double>(static_cast<long double>(K) / gamma *
                             (std::pow(J, -static_cast<long double>(gamma)) - 1.0L));
}

// JFluid sigma = -p I (no viscosity, any C), p = (K/gamma)(J^-gamma - 1). Reference from a
// long-double pow: its own error ~1e-19 / (gamma (1 - J)) relative stays below 1e-11 for |1 - J| >= 1e-8;
// tolerance 1e-12 relative (+ that) for the double log1p/expm1 form.
TEST(JFluid, StressIsMinusPressureIdentity) {
  const double K = 2.2e9, gamma = 7.15;
  const auto p = JFluid::make_params<double>(fluid_spec(K, gamma, 0.0, 998.0));
  Mat3d C = Mat3d::zero();
  C(0, 1) = 5.0;
  C(1, 1) = -2.0;
  for (double omj : {-0.1, -1e-2, -1e-4, -1e-6, 1e-8, 1e-6, 1e-4, 1e-2, 0.1, 0.3}) {
    SCOPED_TRACE(omj);
    const double J = 1.0 - omj;
    const double p_ref = tait_pressure_reference(K, gamma, omj);
    const JFluidState<double> st{omj};
    const double tol = 1e-12 * std::fabs(p_ref) + 1e-19 / (gamma * std::fabs(omj)) * std::fabs(p_ref);
    EXPECT_NEAR(JFluid::pressure(p, st), p_ref, tol);
    const StressResult<double> r = JFluid::kirchhoff_stress(p, st, C);
    EXPECT_EQ(r.J, J);
    const Mat3d sigma = cauchy_stress(r);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(sigma(i, j), i == j ? -p_ref : 0.0, tol + 4 * kEps * std::fabs(p_ref));
  }
}

// sigma = -p I + 2 mu dev(sym(grad v)): trace carries only the pressure, the deviator only the viscous part.
TEST(JFluid, ViscousStressIsDeviatoricStrainRate) {
  const double mu = 0.5;
  const auto p = JFluid::make_params<double>(fluid_spec(1e6, 7.0, mu, 1000.0));
  Mat3d C{{{1.0, 2.0, -3.0}, {0.5, -4.0, 1.5}, {2.5, 0.25, 6.0}}};
  const JFluidState<double> st{1e-3};
  const Mat3d sigma = cauchy_stress(JFluid::kirchhoff_stress(p, st, C));
  const double pr = JFluid::pressure(p, st);
  EXPECT_NEAR(mean_pressure(sigma), pr, 1e-13 * pr);
  const Mat3d D = (C + transpose(C)) * 0.5;
  const double trD = trace(D) / 3.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double expected = 2 * mu * (D(i, j) - (i == j ? trD : 0.0)) - (i == j ? pr : 0.0);
      EXPECT_NEAR(sigma(i, j), expected, 1e-13 * pr);
    }
  // Objectivity of the viscous term: rotating the velocity gradient rotates the stress.
  const Mat3d R = test::rotation(Vec3d{{1, 1, 0}}, 0.4);
  const Mat3d sigma_rot = cauchy_stress(JFluid::kirchhoff_stress(p, st, R * C * transpose(R)));
  EXPECT_LE(max_abs_diff(sigma_rot, R * sigma * transpose(R)), 1e-12 * pr);
}

// c^2 = (K/rho0) J^(1 - gamma) = (K + gamma p) / rho with rho = rho0 / J; c0 = sqrt(K / rho0).
TEST(JFluid, SoundSpeed) {
  const double K = 2e7, gamma = 7.1, rho0 = 1000.0;
  const auto p = JFluid::make_params<double>(fluid_spec(K, gamma, 0.0, rho0));
  EXPECT_NEAR(JFluid::wave_speed(p, JFluid::reference_state<double>()), std::sqrt(K / rho0),
              1e-14 * std::sqrt(K / rho0));
  for (double omj : {-0.05, -1e-4, 1e-4, 0.05}) {
    const JFluidState<double> st{omj};
    const double J = 1 - omj;
    const double c = JFluid::wave_speed(p, st);
    EXPECT_NEAR(c * c, K / rho0 * std::pow(J, 1 - gamma), 1e-13 * c * c);
    EXPECT_NEAR(c * c, (K + gamma * JFluid::pressure(p, st)) / (rho0 / J), 1e-12 * c * c);
  }
}

// -dpsi/dJ = p (central differences in J, h = 1e-7: error ~ K h^2 + eps psi / h, tolerance 1e-6 K), psi(1) = 0,
// and the gamma -> 1 limit is finite.
TEST(JFluid, EnergyIsPressurePotential) {
  for (double gamma : {7.0, 1.0 + 1e-12, 1.0, 2.5}) {
    const double K = 1e6;
    const auto p = JFluid::make_params<double>(fluid_spec(K, gamma, 0.0, 1000.0));
    EXPECT_EQ(JFluid::energy_density(p, JFluid::reference_state<double>()), 0.0);
    for (double omj : {-0.1, -1e-3, 1e-3, 0.1}) {
      const double h = 1e-7;
      const double dpsi = (JFluid::energy_density(p, JFluidState<double>{omj - h}) -
                           JFluid::energy_density(p, JFluidState<double>{omj + h})) /
                          (2 * h);  // d/dJ = -d/d(1-J)
      EXPECT_NEAR(-dpsi, JFluid::pressure(p, JFluidState<double>{omj}), 1e-6 * K) << "gamma " << gamma;
    }
  }
}

// J <- (1 + dt tr C) J written on 1 - J.
TEST(JFluid, AdvanceUpdatesOneMinusJ) {
  Mat3d C = Mat3d::zero();
  C(0, 0) = -2.0;
  C(1, 1) = 0.5;
  C(0, 2) = 9.0;  // off-diagonal: no volume change
  const double dt = 1e-3, omj = 2e-3;
  const double J_new = (1 - omj) * (1 + dt * trace(C));
  EXPECT_NEAR(JFluid::advance(JFluidParams<double>{}, JFluidState<double>{omj}, C, dt).one_minus_J, 1 - J_new, 4 * kEps);
}

// Tension cutoff: J stops at J_t with p(J_t) = -tension_cutoff, so the pressure never falls below -tension_cutoff
// however far the fluid is pulled; compression is untouched; without the key (the default, ClaymoreUW's law) nothing
// is cut, and a cutoff beyond the law's own limit K / gamma cuts nothing either.
TEST(JFluid, TensionCutoffBoundsThePressure) {
  const double K = 2e6, gamma = 7.0;
  MaterialSpec spec = fluid_spec(K, gamma, 0.0, 1000.0);
  Mat3d expand = Mat3d::identity() * 10.0;  // tr C = 30 /s
  const double dt = 1e-3;
  for (double cutoff : {0.0, 1e4}) {
    spec.tension_cutoff = cutoff;
    const auto p = JFluid::make_params<double>(spec);
    JFluidState<double> s = JFluid::reference_state<double>();
    for (int i = 0; i < 50; ++i) s = JFluid::advance(p, s, expand, dt);  // J would reach 1.03^50 = 4.4
    EXPECT_NEAR(JFluid::pressure(p, s), -cutoff, 1e-9 * K) << "cutoff " << cutoff;
    EXPECT_LE(JFluid::volume_ratio(s), 1.0 + 2 * cutoff / K);
    // compression is not cut
    const JFluidState<double> c = JFluid::advance(p, JFluidState<double>{2e-3}, Mat3d::identity() * -1.0, dt);
    EXPECT_NEAR(c.one_minus_J, 1 - (1 - 2e-3) * (1 - 3 * dt), 4 * kEps);
  }
  spec.tension_cutoff = std::numeric_limits<double>::infinity();  // the key absent
  JFluidState<double> s = JFluid::reference_state<double>();
  const auto none = JFluid::make_params<double>(spec);
  for (int i = 0; i < 50; ++i) s = JFluid::advance(none, s, expand, dt);
  EXPECT_NEAR(JFluid::volume_ratio(s), std::pow(1.03, 50), 1e-9);
  spec.tension_cutoff = K;  // gamma p_t / K = 7 >= 1: beyond the law's tension K / gamma
  EXPECT_EQ(JFluid::make_params<double>(spec).one_minus_J_min, -std::numeric_limits<double>::infinity());
}

// The hydrostatic initial state: J p(J) equals the requested Kirchhoff pressure (Newton in double) for the range of
// depths a scene meets (tau / K from 1e-9 to 0.3), and zero depth is the rest state.
TEST(JFluid, HydrostaticStateHasTheKirchhoffPressure) {
  for (double gamma : {1.0, 7.0}) {
    const double K = 2e6;
    const auto p = JFluid::make_params<double>(fluid_spec(K, gamma, 0.0, 1000.0));
    EXPECT_EQ(JFluid::hydrostatic_state<double>(p, 0.0).one_minus_J, 0.0);
    for (double tau : {2e-3, 1.0, 1e3, 5e4, 6e5}) {
      const JFluidState<double> s = JFluid::hydrostatic_state<double>(p, tau);
      EXPECT_GT(s.one_minus_J, 0.0);
      EXPECT_NEAR(JFluid::volume_ratio(s) * JFluid::pressure(p, s), tau, 1e-12 * tau + 1e-15 * K)
          << "gamma " << gamma << ", tau " << tau;
    }
  }
}

// fp32: with 1 - J stored, float keeps the pressure of tiny compressions (water, K = 2e8, the OSU flume scene) to a few
// ulps: log1p, a product, expm1 and a product, each within 1-2 ulp -> tolerance 16 ulp = 1e-6 relative. Storing J
// itself would round 1 - J to multiples of 6e-8 (1.3 % of 1 - J = 1e-6): the "naive" check documents why.
TEST(JFluid, SinglePrecisionPressureNearRestViaOneMinusJ) {
  const double K = 2e8, gamma = 7.125;
  const auto pf = JFluid::make_params<float>(fluid_spec(K, gamma, 1e-3, 998.0));
  const auto pd = JFluid::make_params<double>(fluid_spec(K, gamma, 1e-3, 998.0));
  for (float omj : {1e-7f, 3e-7f, 1e-6f, 1e-5f, 1e-4f, 1e-3f, -1e-6f, -1e-4f}) {
    SCOPED_TRACE(omj);
    const double p_ref = JFluid::pressure(pd, JFluidState<double>{static_cast<double>(omj)});
    const float p32 = JFluid::pressure(pf, JFluidState<float>{omj});
    EXPECT_NEAR(p32, p_ref, 16 * test::kEpsF * std::fabs(p_ref));
    const float p_stress =
        mean_pressure(cauchy_stress(JFluid::kirchhoff_stress(pf, JFluidState<float>{omj}, Mat3f::zero())));
    EXPECT_NEAR(p_stress, p_ref, 16 * test::kEpsF * std::fabs(p_ref));
  }
  // Naive float: J = 1 - 1e-6 stored as a float loses 1.3 % of the compression.
  const float J_naive = 1.0f - 1e-6f;
  const float p_naive = static_cast<float>(K / gamma) * (std::pow(J_naive, -static_cast<float>(gamma)) - 1.0f);
  const double p_ref = JFluid::pressure(pd, JFluidState<double>{static_cast<double>(1e-6f)});
  EXPECT_GT(std::fabs(p_naive - p_ref), 1e-3 * p_ref);
}

// Single precision evaluates the pressure by its Taylor series in 1 - J where that is within a quarter ulp of the law
// (JFluid::set_pressure_series): against the double law over |1 - J| up to 1.2 times that limit (log1p / expm1 past
// it), for gamma 1 to 20. The series' truncation (2^-26) plus 12 roundings of a multiply-add and the coefficients'
// own: tolerance 8 float ulps. The limit for gamma = 7.15 is the one jfluid.cuh quotes.
TEST(JFluid, SinglePrecisionPressureSeriesMatchesTheLaw) {
  for (const double gamma : {1.0, 3.0, 7.15, 20.0}) {
    SCOPED_TRACE(gamma);
    const double K = 2e6;
    const auto pf = JFluid::make_params<float>(fluid_spec(K, gamma, 0.0, 1000.0));
    const auto pd = JFluid::make_params<double>(fluid_spec(K, gamma, 0.0, 1000.0));
    ASSERT_GT(pf.series_limit, 0.0f);
    EXPECT_LT(pd.series_limit, 0.0);  // double keeps log1p / expm1
    if (gamma == 7.15) {
      EXPECT_NEAR(pf.series_limit, 0.108, 1e-3);
    }
    double worst = 0;
    for (int i = 0; i <= 4000; ++i) {
      const float omj = static_cast<float>(pf.series_limit * (-1.2 + 2.4 * i / 4000.0));
      const double ref = JFluid::pressure(pd, JFluidState<double>{static_cast<double>(omj)});
      const float got = JFluid::pressure(pf, JFluidState<float>{omj});
      EXPECT_NEAR(got, ref, 8 * test::kEpsF * std::fabs(ref)) << "1 - J = " << omj;
      if (ref != 0) worst = std::max(worst, std::fabs(got - ref) / std::fabs(ref));
    }
    std::printf("[measured] JFluid float pressure, gamma %g: series up to |1 - J| = %g, worst %.2e relative\n", gamma,
                static_cast<double>(pf.series_limit), worst);
  }
}

// physics/frame_attributes.h: an output attribute is available where the material's state has its quantity.
TEST(MaterialSupportsAttribute, FollowsTheMaterialsState) {
  EXPECT_TRUE(material_supports_attribute(Constitutive::JFluid, "Pressure"));
  EXPECT_TRUE(material_supports_attribute(Constitutive::NACC, "logJp"));
  EXPECT_FALSE(material_supports_attribute(Constitutive::JFluid, "logJp"));  // a fluid keeps no plastic volume
  EXPECT_FALSE(material_supports_attribute(Constitutive::JFluid, "NoSuchAttribute"));
}

}  // namespace
}  // namespace fbar
