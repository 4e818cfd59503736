// Single-particle tests of the plastic laws (DruckerPrager, NACC): elastic closed forms, energy derivatives, and
// the return mappings against the yield surfaces they must land on.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "physics/constitutive_models.cuh"
#include "physics_test_support.h"

namespace fbar {
namespace {

using test::kEps;

MaterialSpec plastic_spec(Constitutive law, double E, double nu, double phi_deg) {
  MaterialSpec m;
  m.law = law;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  m.rho = 2000.0;
  m.friction_angle = phi_deg;
  m.cohesion = 0.0;
  m.beta = 0.5;
  m.xi = 0.8;
  m.logJp0 = 0.0;
  m.vol_correction = false;
  m.hardening = true;
  return m;
}

/// Mean pressure p = -tr(tau)/3 and q = sqrt(3/2) |dev tau| of a Kirchhoff stress [Pa].
struct PQ {
  double p, q;
};
PQ pq(const Mat3d& tau) {
  const Mat3d s = deviatoric_part(tau);
  return PQ{-trace(tau) / 3.0, std::sqrt(1.5 * ddot(s, s))};
}

/// Simple shear increment F <- (I + g e0 x e1) F (isochoric).
Mat3d shear(const Mat3d& F, double g) {
  Mat3d S = Mat3d::identity();
  S(0, 1) = g;
  return S * F;
}

// ------------------------------------------------------------------------------------------------ DruckerPrager

// Inside the cone the law is Hencky elasticity: F = diag(s, 1, 1) gives tau11 = (lambda + 2 mu) ln s,
// tau22 = lambda ln s, sigma = tau / s (the uniaxial closed form in Hencky strain). Uniaxial compression stays inside
// the phi = 30 deg cone for nu = 0.3: |dev e| = sqrt(2/3) |ln s| < (3 lambda + 2 mu)/(2 mu) alpha |ln s|
// (0.816 < 1.061). Tolerance: the SVD and log of a diagonal F, 64 eps of (lambda + 2 mu).
TEST(DruckerPrager, UniaxialCompressionInsideConeIsHenckyElastic) {
  const auto p = DruckerPrager::make_params<double>(plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 30.0));
  for (double s : {0.999, 0.99, 0.95, 0.9}) {
    SCOPED_TRACE(s);
    Mat3d F = Mat3d::identity();
    F(0, 0) = s;
    const auto r = DruckerPrager::return_map(p, F, 0.0);
    EXPECT_LE(max_abs(r.F - F), 64 * kEps);
    const StressResult<double> st = DruckerPrager::kirchhoff_stress(p, r, Mat3d::zero());
    const Mat3d sigma = cauchy_stress(st);
    const double tol = 64 * kEps * (p.lambda + 2 * p.mu);
    EXPECT_NEAR(sigma(0, 0), (p.lambda + 2 * p.mu) * std::log(s) / s, tol);
    EXPECT_NEAR(sigma(1, 1), p.lambda * std::log(s) / s, tol);
    EXPECT_NEAR(sigma(2, 2), p.lambda * std::log(s) / s, tol);
    EXPECT_NEAR(sigma(0, 1), 0.0, tol);
  }
}

// The cone of Klar et al.: |dev tau| + alpha tr tau <= 0 with alpha = sqrt(2/3) 2 sin(phi)/(3 - sin(phi)). In p-q
// that is q <= M p with M = 6 sin(phi)/(3 - sin(phi)), the triaxial-compression Mohr-Coulomb slope (the same M
// NACC uses). Trial states with compression and large shear must return onto the cone at constant tr(tau) (radial
// return in the deviatoric plane): direction of dev tau kept, q/p = M. Tolerances: 1e-10 relative (SVD, log, exp
// of O(1) strains in double).
TEST(DruckerPrager, ShearReturnsOntoTheConeAtConstantPressure) {
  const MaterialSpec spec = plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 30.0);
  const auto p = DruckerPrager::make_params<double>(spec);
  const double M = NACC::critical_state_slope(30.0);
  EXPECT_NEAR(M, 1.2, 1e-15);
  std::mt19937_64 rng(11);
  int returned = 0;
  for (int n = 0; n < 200; ++n) {
    const Mat3d R = test::random_rotation(rng);
    Mat3d F = test::random_deformation(rng, 0.15) * 0.97;  // compression plus random shear
    F = R * F;
    const StressResult<double> trial = DruckerPrager::kirchhoff_stress(p, {F, 0.0}, Mat3d::zero());
    const PQ t = pq(trial.kirchhoff);
    const auto r = DruckerPrager::return_map(p, F, 0.0);
    const StressResult<double> out = DruckerPrager::kirchhoff_stress(p, r, Mat3d::zero());
    const PQ o = pq(out.kirchhoff);
    const double scale = std::abs(t.p) + t.q;
    if (t.p > 0 && t.q > M * t.p) {
      ++returned;
      EXPECT_NEAR(o.p, t.p, 1e-10 * scale);
      EXPECT_NEAR(o.q, M * o.p, 1e-10 * scale);
      // dev tau keeps its direction: dev_out = k dev_trial with 0 <= k < 1.
      const Mat3d dt = deviatoric_part(trial.kirchhoff), dout = deviatoric_part(out.kirchhoff);
      const double k = ddot(dout, dt) / ddot(dt, dt);
      EXPECT_GE(k, 0.0);
      EXPECT_LT(k, 1.0);
      EXPECT_LE(max_abs(dout - dt * k), 1e-10 * scale);
    } else if (t.p > 0) {
      EXPECT_LE(max_abs(r.F - F), 1e-13);  // inside: untouched
    } else {
      EXPECT_LE(max_abs(out.kirchhoff), 1e-9 * scale + 64 * kEps * p.lambda);  // tension: apex, stress-free
    }
  }
  EXPECT_GT(returned, 50);  // the sample exercises the return
}

// Pure tension returns to the apex: sigma = 0 (c = 0), the remaining F a rotation; with the volume correction the
// dilation removed, tr(ln s), is remembered scaled by beta (Tampubolon et al. 2017).
TEST(DruckerPrager, TensionReturnsToTheStressFreeApexAndIsRemembered) {
  MaterialSpec spec = plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 30.0);
  spec.vol_correction = true;
  spec.beta = 0.5;
  const auto p = DruckerPrager::make_params<double>(spec);
  const Mat3d R = test::rotation(Vec3d{{1, 2, 3}}, 0.7);
  Mat3d D = Mat3d::identity();
  D(0, 0) = 1.01;
  D(1, 1) = 1.02;
  D(2, 2) = 0.995;
  const Mat3d F = R * D;
  const auto r = DruckerPrager::return_map(p, F, 0.0);
  const StressResult<double> out = DruckerPrager::kirchhoff_stress(p, r, Mat3d::zero());
  EXPECT_LE(max_abs(out.kirchhoff), 64 * kEps * (3 * p.lambda + 2 * p.mu));
  EXPECT_NEAR(r.logJp, 0.5 * (std::log(1.01) + std::log(1.02) + std::log(0.995)), 1e-15);
  EXPECT_NEAR(determinant(r.F), 1.0, 1e-14);
}

// ClaymoreUW leaves the state undefined for a trial in compression with friction_angle = 0. Here: with shear the
// return removes the whole deviator (a frictionless grain carries pressure only) at constant volume; an isotropic
// compression is elastic. Both finite.
TEST(DruckerPrager, ZeroFrictionInCompressionIsDefined) {
  const auto p = DruckerPrager::make_params<double>(plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 0.0));
  EXPECT_EQ(p.alpha, 0.0);
  const Mat3d F = test::rotation(Vec3d{{0, 0, 1}}, 0.3) * shear(Mat3d::identity() * 0.98, 0.05);
  const auto r = DruckerPrager::return_map(p, F, 0.0);
  ASSERT_TRUE(all_finite(r.F));
  const StressResult<double> out = DruckerPrager::kirchhoff_stress(p, r, Mat3d::zero());
  EXPECT_LE(max_abs(deviatoric_part(out.kirchhoff)), 1e-9 * p.lambda);
  EXPECT_NEAR(determinant(r.F), determinant(F), 1e-14);
  EXPECT_LT(trace(out.kirchhoff), 0.0);

  const Mat3d iso = Mat3d::identity() * 0.99;
  const auto r2 = DruckerPrager::return_map(p, iso, 0.0);
  ASSERT_TRUE(all_finite(r2.F));
  EXPECT_LE(max_abs(r2.F - iso), 16 * kEps);
}

// The remembered dilation is consumed by compression (case II, stress-free, logJp += beta tr e) and, once the
// corrected trace is negative, folded into the elastic strain (logJp -> 0): the stress is continuous. beta = 1.
TEST(DruckerPrager, VolumeCorrectionIsConsumedAndFoldedContinuously) {
  MaterialSpec spec = plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 30.0);
  spec.vol_correction = true;
  spec.beta = 1.0;
  const auto p = DruckerPrager::make_params<double>(spec);
  const double memory = 0.03;  // tr(ln s) of dilation remembered
  auto iso = [](double tr_log) { return Mat3d::identity() * std::exp(tr_log / 3.0); };
  // Compressed less than the memory: stress-free, memory reduced by the compression.
  const auto a = DruckerPrager::return_map(p, iso(-0.01), memory);
  EXPECT_NEAR(a.logJp, memory - 0.01, 1e-15);
  EXPECT_LE(max_abs(DruckerPrager::kirchhoff_stress(p, a, Mat3d::zero()).kirchhoff), 1e-9);
  // Compressed more: the excess is the elastic strain, memory cleared.
  const auto b = DruckerPrager::return_map(p, iso(-0.05), memory);
  EXPECT_EQ(b.logJp, 0.0);
  const double tr_elastic = -0.05 + memory;
  const Mat3d tau = DruckerPrager::kirchhoff_stress(p, b, Mat3d::zero()).kirchhoff;
  EXPECT_NEAR(tau(0, 0), (2 * p.mu / 3 + p.lambda) * tr_elastic, 1e-9 * p.lambda);
  // At the crossing the stress is zero from both sides.
  const auto c = DruckerPrager::return_map(p, iso(-memory - 1e-9), memory);
  EXPECT_LE(max_abs(DruckerPrager::kirchhoff_stress(p, c, Mat3d::zero()).kirchhoff), 1e-9 * (3 * p.lambda + 2 * p.mu));
}

// Cohesion c moves the apex to log strain c: pure tension returns to tau = (3 lambda + 2 mu) c I.
TEST(DruckerPrager, CohesionGivesTensileStrengthAtTheApex) {
  MaterialSpec spec = plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 30.0);
  spec.cohesion = 0.002;
  const auto p = DruckerPrager::make_params<double>(spec);
  const auto r = DruckerPrager::return_map(p, Mat3d::identity() * 1.05, 0.0);
  const Mat3d tau = DruckerPrager::kirchhoff_stress(p, r, Mat3d::zero()).kirchhoff;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(tau(i, i), (3 * p.lambda + 2 * p.mu) * 0.002, 1e-9 * p.lambda);
  // Small tension below the cohesion is elastic.
  const Mat3d small = Mat3d::identity() * std::exp(0.001 / 3);
  EXPECT_LE(max_abs(DruckerPrager::return_map(p, small, 0.0).F - small), 16 * kEps);
}

// tau = (dpsi/dF) F^T for psi = mu |ln s|^2 + lambda/2 (tr ln s)^2 (central differences, h = 1e-6; tolerance
// A plane-strain Mohr-Coulomb angle converts to the compression cone's friction_angle by equal sqrt(J2) / p:
// 2 sqrt(3) sin(phi) / (3 - sin(phi)) = 3 tan(phi_mc) / sqrt(9 + 12 tan^2(phi_mc)) to round-off; 33 deg -> 23.04 deg,
// always below phi_mc (the compression cone is the stronger fit); 0 stays 0.
TEST(DruckerPrager, PlaneStrainFrictionAngleMatchesMohrCoulomb) {
  const double deg = 3.14159265358979323846 / 180.0;
  for (const double phi_mc : {10.0, 20.0, 33.0, 40.0, 45.0}) {
    const double phi = DruckerPrager::plane_strain_friction_angle(phi_mc);
    const double s = std::sin(phi * deg), t = std::tan(phi_mc * deg);
    EXPECT_NEAR(2 * std::sqrt(3.0) * s / (3 - s), 3 * t / std::sqrt(9 + 12 * t * t), 1e-14) << phi_mc;
    EXPECT_LT(phi, phi_mc);
  }
  EXPECT_NEAR(DruckerPrager::plane_strain_friction_angle(33.0), 23.04, 0.01);
  EXPECT_EQ(DruckerPrager::plane_strain_friction_angle(0.0), 0.0);
}

// 1e-8 E as for the elastic laws).
TEST(DruckerPrager, HenckyStressIsEnergyDerivative) {
  const auto p = DruckerPrager::make_params<double>(plastic_spec(Constitutive::DruckerPrager, 1e7, 0.3, 30.0));
  std::mt19937_64 rng(5);
  for (int n = 0; n < 20; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.2);
    const Mat3d P = DruckerPrager::kirchhoff_stress(p, {F, 0.0}, Mat3d::zero()).kirchhoff * transpose(inverse(F));
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Mat3d Fp = F, Fm = F;
        Fp(i, j) += h;
        Fm(i, j) -= h;
        const double d = (DruckerPrager::energy_density(p, {Fp, 0.0}) - DruckerPrager::energy_density(p, {Fm, 0.0})) /
                         (2 * h);
        EXPECT_NEAR(P(i, j), d, 1e-8 * 1e7);
      }
  }
  EXPECT_NEAR(DruckerPrager::wave_speed(p, DruckerPrager::reference_state<double>()),
              std::sqrt((p.lambda + 2 * p.mu) / 2000.0), 1e-12);
}

// ------------------------------------------------------------------------------------------------ NACC

// M must come from friction_angle (ClaymoreUW fixes 45 deg): M = 6 sin(phi) / (3 - sin(phi)); kappa = E/(3(1-2nu)).
TEST(NACC, ParametersFollowTheFrictionAngle) {
  const auto p30 = NACC::make_params<double>(plastic_spec(Constitutive::NACC, 1e7, 0.3, 30.0));
  EXPECT_NEAR(p30.M2, 1.44, 1e-14);
  const auto p45 = NACC::make_params<double>(plastic_spec(Constitutive::NACC, 1e7, 0.3, 45.0));
  const double s45 = std::sqrt(0.5);
  EXPECT_NEAR(p45.M2, std::pow(6 * s45 / (3 - s45), 2), 1e-14);
  EXPECT_NEAR(p30.kappa, 1e7 / (3 * 0.4), 1e-6);
  EXPECT_NEAR(p30.mu, 1e7 / 2.6, 1e-6);
  EXPECT_NEAR(NACC::wave_speed(p30, NACC::reference_state<double>()),
              std::sqrt((p30.kappa + 4 * p30.mu / 3) / 2000.0), 1e-12);
}

// Elastic inside the ellipse: F = diag(s, 1, 1), J = s, tau11 = (2/3) mu s^(-2/3) (s^2 - 1) + kappa/2 (s^2 - 1),
// tau22 = -(1/3) mu s^(-2/3) (s^2 - 1) + kappa/2 (s^2 - 1). A consolidated state (logJp = -1, p0 = 0.89 kappa)
// keeps these small strains elastic. Tolerance 64 eps of (kappa + mu).
TEST(NACC, UniaxialElasticMatchesClosedForm) {
  const auto p = NACC::make_params<double>(plastic_spec(Constitutive::NACC, 1e7, 0.3, 30.0));
  for (double s : {0.99, 0.999, 1.0, 1.001}) {
    SCOPED_TRACE(s);
    Mat3d F = Mat3d::identity();
    F(0, 0) = s;
    const auto r = NACC::return_map(p, F, -1.0);
    EXPECT_LE(max_abs(r.F - F), 16 * kEps);
    EXPECT_EQ(r.logJp, -1.0);
    const Mat3d tau = NACC::kirchhoff_stress(p, r, Mat3d::zero()).kirchhoff;
    const double c = std::pow(s, -2.0 / 3.0) * (s * s - 1);
    const double tol = 64 * kEps * (p.kappa + p.mu);
    EXPECT_NEAR(tau(0, 0), 2.0 / 3.0 * p.mu * c + 0.5 * p.kappa * (s * s - 1), tol);
    EXPECT_NEAR(tau(1, 1), -1.0 / 3.0 * p.mu * c + 0.5 * p.kappa * (s * s - 1), tol);
    EXPECT_NEAR(tau(2, 2), tau(1, 1), tol);
  }
}

TEST(NACC, StressIsEnergyDerivative) {
  const auto p = NACC::make_params<double>(plastic_spec(Constitutive::NACC, 1e7, 0.3, 30.0));
  std::mt19937_64 rng(9);
  for (int n = 0; n < 20; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.2);
    const Mat3d P = NACC::kirchhoff_stress(p, {F, 0.0}, Mat3d::zero()).kirchhoff * transpose(inverse(F));
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Mat3d Fp = F, Fm = F;
        Fp(i, j) += h;
        Fm(i, j) -= h;
        const double d = (NACC::energy_density(p, {Fp, 0.0}) - NACC::energy_density(p, {Fm, 0.0})) / (2 * h);
        EXPECT_NEAR(P(i, j), d, 1e-8 * 1e7);
      }
  }
}

// Without hardening the ellipse is fixed: every trial state between the tips returns onto it at constant J (p
// kept, q scaled, deviator direction kept), states inside stay. Tolerance: y relative to M^2 p0^2, 1e-10.
TEST(NACC, ReturnLandsOnTheEllipseAtConstantPressure) {
  MaterialSpec spec = plastic_spec(Constitutive::NACC, 1e7, 0.3, 30.0);
  spec.hardening = false;
  const auto p = NACC::make_params<double>(spec);
  const double logJp = -0.05;
  std::mt19937_64 rng(21);
  int returned = 0;
  for (int n = 0; n < 300; ++n) {
    const Mat3d F = test::random_rotation(rng) * test::random_deformation(rng, 0.08) * 0.995;
    const NaccYield<double> t = NACC::yield(p, F, logJp);
    if (t.p > t.p0 || t.p < -p.beta * t.p0) continue;  // the tips: tested below
    const auto r = NACC::return_map(p, F, logJp);
    EXPECT_EQ(r.logJp, logJp);
    const NaccYield<double> o = NACC::yield(p, r.F, logJp);
    const double scale = p.M2 * t.p0 * t.p0;
    EXPECT_NEAR(o.p, t.p, 1e-10 * t.p0);
    EXPECT_NEAR(determinant(r.F), determinant(F), 1e-13);
    if (t.y > 0) {
      ++returned;
      EXPECT_NEAR(o.y, 0.0, 1e-10 * scale);
      EXPECT_LT(o.q, t.q);
    } else {
      EXPECT_LE(max_abs(r.F - F), 16 * kEps);
    }
  }
  EXPECT_GT(returned, 50);
}

// Beyond the tips the state goes to the tip pressure with q = 0; hardening moves logJp by ln(J_trial / J_tip):
// compaction past the cap hardens (logJp decreases), stretching past the tension tip softens.
TEST(NACC, TipsReturnIsotropicallyAndHarden) {
  const auto p = NACC::make_params<double>(plastic_spec(Constitutive::NACC, 1e7, 0.3, 30.0));
  const double logJp = -0.05;
  const double p0 = NACC::cap_pressure(p, logJp);
  EXPECT_NEAR(p0, p.kappa * (1e-5 + std::sinh(0.8 * 0.05)), 1e-9);
  for (double J : {0.9, 1.05}) {
    SCOPED_TRACE(J);
    const Mat3d F = test::rotation(Vec3d{{1, 1, 0}}, 0.4) * shear(Mat3d::identity() * std::cbrt(J), 0.01);
    const auto r = NACC::return_map(p, F, logJp);
    const NaccYield<double> o = NACC::yield(p, r.F, logJp);
    const double tip = J < 1 ? p0 : -p.beta * p0;
    EXPECT_NEAR(o.p, tip, 1e-9 * p.kappa);
    EXPECT_NEAR(o.q, 0.0, 1e-9 * p.kappa);
    const double J_tip = std::sqrt(1 - 2 * tip / p.kappa);
    EXPECT_NEAR(r.logJp, logJp + std::log(J / J_tip), 1e-13);
    if (J < 1) {
      EXPECT_LT(r.logJp, logJp);
    } else {
      EXPECT_GT(r.logJp, logJp);
    }
  }
}

// A shear path at constant pressure saturates on the critical-state line q = M p (beta = 0:
// the ellipse's top lies on it). Hardening drives p_c = (1 - beta) p0 / 2 to the particle's pressure from either
// side (loose: p < p_c softens, dense: p > p_c hardens). Simple shear keeps J, hence p, exactly. The approach is
// geometric: measured |q/p - M| / M = 1e-5 after 500 increments of 1e-3 and 3e-13 after 4000 (the slowest case,
// beta 0.5 from the dense side: 2e-2, 1.6e-6, 6e-12 after 500, 2000, 4000); tolerance 1e-9 after 4000.
// With beta = 0.5 the saturated state is the ellipse's top: p = p_c, q^2 = -M^2 (p_c + beta p0)(p_c - p0)/(1 + 2 beta).
TEST(NACC, ShearAtConstantPressureSaturatesAtTheCriticalState) {
  for (double beta : {0.0, 0.5}) {
    for (double start_ratio : {4.0, 1.3}) {  // p0 / p at the start: loose (p < p_c) and dense (p > p_c for beta 0)
      SCOPED_TRACE(testing::Message() << "beta " << beta << ", p0/p " << start_ratio);
      MaterialSpec spec = plastic_spec(Constitutive::NACC, 1e7, 0.3, 30.0);
      spec.beta = beta;
      const auto p = NACC::make_params<double>(spec);
      const double J = 0.99;
      const double pressure = NACC::pressure_of_J(p, J);
      // logJp with p0 = start_ratio * p: kappa (1e-5 + sinh(-xi logJp)) = p0.
      const double logJp0 = -std::asinh(start_ratio * pressure / p.kappa - 1e-5) / p.xi;
      PlasticState<double> s{Mat3d::identity() * std::cbrt(J), logJp0};
      for (int n = 0; n < 4000; ++n) s = NACC::return_map(p, shear(s.F, 1e-3), s.logJp);
      const NaccYield<double> o = NACC::yield(p, s.F, s.logJp);
      EXPECT_NEAR(o.p, pressure, 1e-9 * pressure);
      const double p_c = (1 - beta) * o.p0 / 2;
      EXPECT_NEAR(p_c, o.p, 1e-9 * o.p);
      const double q_top = std::sqrt(-p.M2 * (p_c + beta * o.p0) * (p_c - o.p0) / (1 + 2 * beta));
      EXPECT_NEAR(o.q, q_top, 1e-9 * q_top);
      if (beta == 0.0) {
        EXPECT_NEAR(o.q / o.p, 1.2, 1e-9 * 1.2);
      }
    }
  }
}

// ------------------------------------------------------------------------------------------------ VonMises

MaterialSpec von_mises_spec(double E, double nu, double sigma_y, double H) {
  MaterialSpec m;
  m.law = Constitutive::VonMises;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  m.rho = 7800.0;
  m.tensile_yield_strength = sigma_y;
  m.hardening_modulus = H;
  return m;
}

Mat3d diag3(double a, double b, double c) {
  Mat3d D = Mat3d::zero();
  D(0, 0) = a;
  D(1, 1) = b;
  D(2, 2) = c;
  return D;
}

/// A uniaxial stress test driven in log strain: each increment stretches axis 0 by de11 and solves the lateral
/// increment (axes 1 and 2) for tau22 = 0 by the secant method, as a testing machine does.
struct UniaxialDriver {
  VonMises::Params<double> p;
  VonMises::State<double> s{Mat3d::identity(), 0.0};
  double e11 = 0.0, e22 = 0.0;  ///< total log strains
  double tau11 = 0.0, tau22 = 0.0;

  VonMises::State<double> trial(double d11, double d22) const {
    return VonMises::return_map(p, diag3(std::exp(d11), std::exp(d22), std::exp(d22)) * s.F, s.eps_p);
  }
  double lateral_stress(double d11, double d22) const {
    return VonMises::kirchhoff_stress(p, trial(d11, d22), Mat3d::zero()).kirchhoff(1, 1);
  }
  void step(double d11) {
    double a = -0.5 * d11, b = -0.3 * d11;  // between plastic (-1/2) and elastic (-nu) contraction
    double fa = lateral_stress(d11, a), fb = lateral_stress(d11, b);
    for (int it = 0; it < 60 && std::fabs(fb) > 1e-12 * p.yield_stress && fb != fa; ++it) {
      const double c = b - fb * (b - a) / (fb - fa);
      a = b;
      fa = fb;
      b = c;
      fb = lateral_stress(d11, b);
    }
    s = trial(d11, b);
    e11 += d11;
    e22 += b;
    const Mat3d tau = VonMises::kirchhoff_stress(p, s, Mat3d::zero()).kirchhoff;
    tau11 = tau(0, 0);
    tau22 = tau(1, 1);
  }
};

// Uniaxial stress (the tensile test that defines sigma_y): Hencky elasticity tau11 = E e11 up to the yield stress,
// then tau11 = (sigma_y + H e11) / (1 + H / E) (linear hardening; H = 0: a plateau at sigma_y), plastic flow at
// constant volume (lateral strain -nu tau11 / E - eps_p / 2), and the hardening variable eps_p = e11 - tau11 / E.
// The radial return is exact on this proportional path: tolerance 1e-9 of sigma_y (the secant solve's 1e-12 and
// the SVD's round-off accumulated over 300 increments), in tension and compression.
TEST(VonMises, UniaxialStressFollowsTheClosedForm) {
  const double E = 2e8, nu = 0.3, sy = 4e5;
  for (double H : {0.0, 0.1 * E}) {
    for (double sign : {1.0, -1.0}) {
      UniaxialDriver d;
      d.p = VonMises::make_params<double>(von_mises_spec(E, nu, sy, H));
      const double de = sign * 1e-4;  // yield at e11 = sigma_y / E = 2e-3: 20 elastic increments, 280 plastic
      for (int i = 0; i < 300; ++i) {
        d.step(de);
        const double e = std::fabs(d.e11);
        const double expected = e <= sy / E ? E * e : (sy + H * e) / (1.0 + H / E);
        ASSERT_NEAR(sign * d.tau11, expected, 1e-9 * sy) << "H " << H << " step " << i;
        ASSERT_NEAR(d.tau22, 0.0, 1e-9 * sy);
        const double eps_p = std::max(0.0, e - expected / E);
        ASSERT_NEAR(d.s.eps_p, eps_p, 1e-9) << "H " << H << " step " << i;
        ASSERT_NEAR(sign * d.e22, -nu * expected / E - 0.5 * eps_p, 1e-9) << "H " << H << " step " << i;
      }
      EXPECT_GT(d.s.eps_p, 0.02);  // well into the plastic range
    }
  }
}

// Pure shear F = diag(e^a, e^-a, 1) (isochoric, proportional): q = 2 sqrt(3) mu a up to yield, then
// q = (sigma_y + H e_eq) / (1 + H / (3 mu)) with e_eq = 2 a / sqrt(3) the equivalent total strain; the shear stress
// (tau11 - tau22) / 2 = q / sqrt(3) reaches the shear yield stress sigma_y / sqrt(3) for H = 0 (von Mises, not
// Tresca's sigma_y / 2). Each increment is one return mapping; tolerance 1e-9 of sigma_y.
TEST(VonMises, PureShearYieldsAtTheShearYieldStress) {
  const double E = 2e8, nu = 0.25, sy = 4e5;
  for (double H : {0.0, 0.2 * E}) {
    const auto p = VonMises::make_params<double>(von_mises_spec(E, nu, sy, H));
    VonMises::State<double> s = VonMises::reference_state<double>();
    const double da = 2e-5;
    for (int i = 1; i <= 400; ++i) {
      s = VonMises::return_map(p, diag3(std::exp(da), std::exp(-da), 1.0) * s.F, s.eps_p);
      const Mat3d tau = VonMises::kirchhoff_stress(p, s, Mat3d::zero()).kirchhoff;
      const double a = i * da, e_eq = 2.0 * a / std::sqrt(3.0);
      const double q_elastic = 2.0 * std::sqrt(3.0) * p.mu * a;
      const double q = q_elastic <= sy ? q_elastic : (sy + H * e_eq) / (1.0 + H / (3.0 * p.mu));
      ASSERT_NEAR(0.5 * (tau(0, 0) - tau(1, 1)), q / std::sqrt(3.0), 1e-9 * sy) << "H " << H << " step " << i;
      ASSERT_NEAR(trace(tau), 0.0, 1e-9 * sy);                   // isochoric: no pressure
      ASSERT_NEAR(determinant(s.F), 1.0, 1e-12);                 // plastic flow keeps the volume
    }
    if (H == 0.0) {  // the plateau is the shear yield stress
      const Mat3d tau = VonMises::kirchhoff_stress(p, s, Mat3d::zero()).kirchhoff;
      EXPECT_NEAR(0.5 * (tau(0, 0) - tau(1, 1)), sy / std::sqrt(3.0), 1e-9 * sy);
    }
  }
}

// Simple shear (rotating principal axes) to gamma = 1 in 2000 increments: the state never leaves the yield surface
// (q <= sigma_y (1 + 1e-12)), ends on it, and the return is objective: rotating the trial F rotates the stress.
TEST(VonMises, SimpleShearStaysOnTheSurfaceAndIsObjective) {
  const auto p = VonMises::make_params<double>(von_mises_spec(1e8, 0.3, 2e5, 0.0));
  VonMises::State<double> s = VonMises::reference_state<double>();
  double q_max = 0.0;
  for (int i = 0; i < 2000; ++i) {
    s = VonMises::return_map(p, shear(s.F, 5e-4), s.eps_p);
    q_max = std::max(q_max, pq(VonMises::kirchhoff_stress(p, s, Mat3d::zero()).kirchhoff).q);
  }
  EXPECT_LE(q_max, 2e5 * (1.0 + 1e-12));
  EXPECT_NEAR(pq(VonMises::kirchhoff_stress(p, s, Mat3d::zero()).kirchhoff).q, 2e5, 1e-9 * 2e5);
  EXPECT_GT(s.eps_p, 0.5);
  // Objectivity: R F_trial returns to R F_e (same eps_p), whose stress is R tau R^T.
  const Mat3d F_trial = shear(s.F, 0.01);
  const double c = std::cos(0.7), sn = std::sin(0.7);
  Mat3d R = Mat3d::identity();
  R(0, 0) = c;
  R(0, 1) = -sn;
  R(1, 0) = sn;
  R(1, 1) = c;
  const auto a = VonMises::return_map(p, F_trial, s.eps_p);
  const auto b = VonMises::return_map(p, R * F_trial, s.eps_p);
  EXPECT_NEAR(b.eps_p, a.eps_p, 1e-14);
  const Mat3d ta = R * VonMises::kirchhoff_stress(p, a, Mat3d::zero()).kirchhoff * transpose(R);
  const Mat3d tb = VonMises::kirchhoff_stress(p, b, Mat3d::zero()).kirchhoff;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(tb(i, j), ta(i, j), 1e-9 * 2e5);
}

}  // namespace
}  // namespace fbar
