// Tests for MnBase/Math/svd.h: rotation-variant SVD, symmetric eigen and polar decomposition against Eigen.
//
// Reference: Eigen::JacobiSVD<Matrix3d> (ComputeFullU | ComputeFullV) and SelfAdjointEigenSolver<Matrix3d> in double
// on the same input; the float code is compared with Eigen in double on the float-rounded matrix, so the float
// tolerances measure only the float algorithm.
//
// Tolerances (all relative to ||A||_F, eps = machine epsilon of the precision under test):
//   kBackward = 4 eps (3 S + 2), S = Jacobi sweeps. One-sided Jacobi is backward stable: each of the 3 S plane
//     rotations (plus the 2 Gram-Schmidt / cross-product steps that build U) perturbs the two 3-vectors it touches by
//     at most ~4 eps relative (a product and a sum per entry, plus the rounding of c and s), and the perturbations
//     add at worst linearly. Double (S = 5): 68 eps = 1.5e-14; float (S = 4): 56 eps = 6.7e-6. This bounds the
//     reconstruction error ||U diag(sigma) V^T - A|| and the orthogonality ||U^T U - I||, ||V^T V - I||.
//   Singular values: Weyl's theorem, |sigma_i(A + E) - sigma_i(A)| <= ||E||_2. The computed factors are the exact
//     SVD of A + E with ||E|| <= reconstruction + orthogonality of U and V, so 3 kBackward; Eigen adds its own
//     backward error (16 eps_double, generous for its 2x2 Jacobi sweeps).
//   Singular vectors: Wedin's theorem, sin(angle) <= ||E|| / gap, checked with a factor 2 where the gap is resolved.
//   Polar factor R: R.-C. Li, SIAM J. Matrix Anal. Appl. 16 (1995) for real matrices (see also Higham, "Functions
//     of Matrices", 2008, ch. 8): ||dR||_F <= 2 ||dA||_F / (sigma_2 + sigma_3).
#include "MnBase/Math/svd.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <type_traits>

#include "math_test_support.h"

namespace fbar::test {
namespace {

constexpr double kEpsDouble = std::numeric_limits<double>::epsilon();

template <typename T>
constexpr double eps() {
  return std::numeric_limits<T>::epsilon();
}

/// Backward-error bound of the Jacobi routines for T (see the file comment).
template <typename T>
constexpr double backward_tol() {
  return 4.0 * eps<T>() * (3 * JacobiSweeps<T>::value + 2);
}

template <typename T>
constexpr double sigma_tol() {
  return 3.0 * backward_tol<T>() + 16.0 * kEpsDouble;
}

const char* type_name(float) { return "float"; }
const char* type_name(double) { return "double"; }

/// Worst errors seen by one test, printed at its end (these are the numbers quoted in svd.h and the report).
struct Worst {
  // vectors: largest sin(angle) to Eigen's singular vectors among those the gap resolves (polar: ||R - R_ref||_F).
  double reconstruction = 0, orthogonality = 0, determinant = 0, sigma = 0, vectors = 0;
  void print(const char* what) const {
    std::printf("[ worst    ] %s: reconstruction %.3g  orthogonality %.3g  |det-1| %.3g  sigma %.3g  vectors %.3g\n",
                what, reconstruction, orthogonality, determinant, sigma, vectors);
  }
};

template <typename T>
bool all_finite(const Svd3<T>& s) {
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(s.sigma[i])) return false;
    for (int j = 0; j < 3; ++j)
      if (!std::isfinite(s.U(i, j)) || !std::isfinite(s.V(i, j))) return false;
  }
  return true;
}

/// Checks every property of the rotation-variant SVD of `a` against Eigen; returns the errors seen.
template <typename T>
void check_svd(const Mat3<T>& a, const std::string& name, Worst& worst) {
  SCOPED_TRACE(name + " (" + type_name(T{}) + ")");
  const Svd3<T> s = svd(a);
  ASSERT_TRUE(all_finite(s));

  const Mat3d ad = a.template cast<double>();
  const double norm_a = norm_or_one(a);
  const Mat3d ud = s.U.template cast<double>(), vd = s.V.template cast<double>();
  const Vec3d sd = s.sigma.template cast<double>();
  const double tol = backward_tol<T>();

  // Reconstruction, orthogonality, proper rotations.
  const double recon = frobenius_norm(u_diag_vt(ud, sd, vd) - ad) / norm_a;
  const double orth = std::max(orthogonality_error(s.U), orthogonality_error(s.V));
  const double det = std::max(std::abs(determinant(ud) - 1.0), std::abs(determinant(vd) - 1.0));
  EXPECT_LE(recon, tol);
  EXPECT_LE(orth, tol);
  EXPECT_LE(det, tol);

  // Ordering holds exactly: sigma0 >= sigma1 >= |sigma2|, only sigma2 may be negative.
  EXPECT_GE(s.sigma[0], s.sigma[1]);
  EXPECT_GE(s.sigma[1], std::abs(s.sigma[2]));
  EXPECT_GE(s.sigma[1], T(0));

  // Magnitudes against Eigen (Weyl).
  const Eigen::JacobiSVD<Eigen::Matrix3d> ref(to_eigen(ad), Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d ref_sigma = ref.singularValues();
  double sigma_err = 0;
  for (int i = 0; i < 3; ++i) sigma_err = std::max(sigma_err, std::abs(std::abs(sd[i]) - ref_sigma(i)) / norm_a);
  EXPECT_LE(sigma_err, sigma_tol<T>());

  // Sign convention: sign(sigma2) = sign(det A) whenever sigma2 is resolved. sign(det A) = det(U_eig) det(V_eig)
  // because Eigen's singular values are non-negative (this avoids the round-off of det(A) itself).
  const double det_sign = ref.matrixU().determinant() * ref.matrixV().determinant();
  if (ref_sigma(2) > 10.0 * sigma_tol<T>() * norm_a) {
    EXPECT_EQ(s.sigma[2] > T(0), det_sign > 0) << "sigma = " << s.sigma[0] << ", " << s.sigma[1] << ", " << s.sigma[2];
  }

  // Singular vectors where the gap resolves them (Wedin), with consistent signs: u_i sigma_i v_i^T must equal
  // u_ref sigma_ref v_ref^T, so sign(u . u_ref) sign(v . v_ref) = sign(sigma_i) (checked where sigma_i is resolved).
  double vec_err = 0;
  for (int i = 0; i < 3; ++i) {
    double gap = std::numeric_limits<double>::infinity();
    for (int j = 0; j < 3; ++j)
      if (j != i) gap = std::min(gap, std::abs(ref_sigma(i) - ref_sigma(j)));
    const double bound = 2.0 * sigma_tol<T>() * norm_a / gap;
    if (!(bound < 1e-2)) continue;
    Vec3d u{}, v{}, ur{}, vr{};
    for (int k = 0; k < 3; ++k) {
      u[k] = ud(k, i);
      v[k] = vd(k, i);
      ur[k] = ref.matrixU()(k, i);
      vr[k] = ref.matrixV()(k, i);
    }
    const double sin_u = norm(cross(u, ur)), sin_v = norm(cross(v, vr));
    EXPECT_LE(sin_u, bound) << "left singular vector " << i;
    EXPECT_LE(sin_v, bound) << "right singular vector " << i;
    if (ref_sigma(i) > 10.0 * sigma_tol<T>() * norm_a) {
      const double expected_sign = (i < 2 || s.sigma[2] > T(0)) ? 1.0 : -1.0;
      EXPECT_GT(dot(u, ur) * dot(v, vr) * expected_sign, 0.0) << "singular vector pair " << i << " sign mismatch";
    }
    vec_err = std::max({vec_err, sin_u, sin_v});
  }

  worst.reconstruction = std::max(worst.reconstruction, recon);
  worst.orthogonality = std::max(worst.orthogonality, orth);
  worst.determinant = std::max(worst.determinant, det);
  worst.sigma = std::max(worst.sigma, sigma_err);
  worst.vectors = std::max(worst.vectors, vec_err);
}

template <typename T>
class SvdTyped : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(SvdTyped, Scalars);

TYPED_TEST(SvdTyped, RandomMatricesMatchEigen) {
  using T = TypeParam;
  std::mt19937_64 rng(12345);
  Worst worst;
  for (int n = 0; n < 10000; ++n) {
    const Mat3<T> a = from_eigen(random_uniform_matrix(rng)).template cast<T>();
    check_svd(a, "random #" + std::to_string(n), worst);
    if (::testing::Test::HasFailure()) break;  // one failing matrix is enough to diagnose
  }
  worst.print((std::string("random uniform [-1,1], 10^4, ") + type_name(T{})).c_str());
}

TYPED_TEST(SvdTyped, DeformationGradientsMatchEigen) {
  // What MPM feeds the SVD: rotations times stretches of a few percent up to a factor 3, some inverted.
  using T = TypeParam;
  std::mt19937_64 rng(777);
  std::normal_distribution<double> stretch(0.0, 0.4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Worst worst;
  for (int n = 0; n < 10000; ++n) {
    Eigen::Vector3d s(std::exp(stretch(rng)), std::exp(stretch(rng)), std::exp(stretch(rng)));
    if (u(rng) < 0.1) s(2) = -s(2);
    const Eigen::Matrix3d f = random_rotation(rng) * s.asDiagonal() * random_rotation(rng);
    check_svd(from_eigen(f).template cast<T>(), "deformation gradient #" + std::to_string(n), worst);
    if (::testing::Test::HasFailure()) break;
  }
  worst.print((std::string("deformation gradients, 10^4, ") + type_name(T{})).c_str());
}

TYPED_TEST(SvdTyped, AdversarialMatricesMatchEigen) {
  using T = TypeParam;
  Worst worst;
  for (const MatrixCase& c : adversarial_cases()) check_svd(from_eigen(c.a).template cast<T>(), c.name, worst);
  worst.print((std::string("adversarial list, ") + type_name(T{})).c_str());
}

TYPED_TEST(SvdTyped, KnownDecompositions) {
  using T = TypeParam;
  const double tol = sigma_tol<T>();
  // -I: det = -1, so sigma = (1, 1, -1) with U, V rotations.
  const Svd3<T> m = svd(Mat3<T>::identity() * T(-1));
  EXPECT_NEAR(m.sigma[0], 1.0, tol);
  EXPECT_NEAR(m.sigma[1], 1.0, tol);
  EXPECT_NEAR(m.sigma[2], -1.0, tol);
  // Zero matrix: sigma = 0 exactly, U and V still rotations.
  const Svd3<T> z = svd(Mat3<T>::zero());
  EXPECT_EQ(z.sigma, Vec3<T>::zero());
  EXPECT_NEAR(determinant(z.U), 1.0, tol);
  EXPECT_NEAR(determinant(z.V), 1.0, tol);
  // R1 diag(3, 2, -1) R2: the negative value stays on the smallest singular value; a rotation has U V^T = R.
  std::mt19937_64 rng(99);
  for (int k = 0; k < 100; ++k) {
    const Eigen::Matrix3d r1 = random_rotation(rng), r2 = random_rotation(rng);
    const Svd3<T> s = svd(from_eigen(r1 * Eigen::Vector3d(3, -2, 1).asDiagonal() * r2).template cast<T>());
    EXPECT_NEAR(s.sigma[0], 3.0, 3 * tol);
    EXPECT_NEAR(s.sigma[1], 2.0, 3 * tol);
    EXPECT_NEAR(s.sigma[2], -1.0, 3 * tol);
    const Svd3<T> r = svd(from_eigen(r1).template cast<T>());
    const Mat3d uvt = (r.U * transpose(r.V)).template cast<double>();
    EXPECT_LE(frobenius_norm(uvt - from_eigen(r1)), 3 * tol);
    EXPECT_NEAR(r.sigma[2], 1.0, tol);
  }
}

TYPED_TEST(SvdTyped, PowerOfTwoScalingIsExact) {
  // The algorithm works on a * 2^-e: scaling the input by a power of two must scale sigma by exactly that power and
  // leave U, V bit-identical (this is the guarantee behind the 1e-20 .. 1e20 robustness).
  using T = TypeParam;
  std::mt19937_64 rng(5);
  const int max_shift = std::is_same_v<T, float> ? 60 : 600;
  for (int n = 0; n < 200; ++n) {
    const Mat3<T> a = from_eigen(random_uniform_matrix(rng)).template cast<T>();
    const Svd3<T> s = svd(a);
    for (int shift = -max_shift; shift <= max_shift; shift += max_shift / 3) {
      Mat3<T> b = a;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) b(i, j) = std::ldexp(a(i, j), shift);
      const Svd3<T> t = svd(b);
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(t.sigma[i], std::ldexp(s.sigma[i], shift));
        for (int j = 0; j < 3; ++j) {
          EXPECT_EQ(t.U(i, j), s.U(i, j));
          EXPECT_EQ(t.V(i, j), s.V(i, j));
        }
      }
    }
  }
}

TYPED_TEST(SvdTyped, NonFiniteInputGivesNonFiniteSigma) {
  // A NaN or Inf anywhere in F must surface in sigma (the simulator's NaN checks read stresses built from it);
  // the clamps inside the rotation must not turn it into a finite, plausible-looking result.
  using T = TypeParam;
  std::mt19937_64 rng(404);
  for (T bad :
       {std::numeric_limits<T>::quiet_NaN(), std::numeric_limits<T>::infinity(), -std::numeric_limits<T>::infinity()})
    for (int k = 0; k < 9; ++k) {
      Mat3<T> a = from_eigen(random_uniform_matrix(rng)).template cast<T>();
      a(k / 3, k % 3) = bad;
      const Svd3<T> s = svd(a);
      EXPECT_FALSE(std::isfinite(s.sigma[0]) && std::isfinite(s.sigma[1]) && std::isfinite(s.sigma[2]))
          << "entry " << k << " = " << bad;
      const Polar3<T> p = polar_decomposition(a);
      EXPECT_FALSE(std::isfinite(ddot(p.S, p.S))) << "entry " << k << " = " << bad;
      const SymEig3<T> e = symmetric_eigen(T(0.5) * (a + transpose(a)));
      EXPECT_FALSE(std::isfinite(e.lambda[0]) && std::isfinite(e.lambda[1]) && std::isfinite(e.lambda[2]))
          << "entry " << k << " = " << bad;
    }
}

TYPED_TEST(SvdTyped, JacobiSweepCountIsNeededAndSufficient) {
  // The fixed sweep count must reach round-off on this set, and the set must be hard enough that two sweeps fewer
  // does not (otherwise the accuracy tests above could not detect a too-small count).
  using T = TypeParam;
  constexpr int S = JacobiSweeps<T>::value;
  std::mt19937_64 rng(31337);
  double worst_default = 0, worst_fewer = 0;
  for (int n = 0; n < 10000; ++n) {
    const Mat3<T> a = from_eigen(random_uniform_matrix(rng)).template cast<T>();
    const Mat3d ad = a.template cast<double>();
    const Svd3<T> s = svd<T, S>(a);
    const Svd3<T> f = svd<T, S - 2>(a);
    auto recon = [&](const Svd3<T>& x) {
      return frobenius_norm(
                 u_diag_vt(x.U.template cast<double>(), x.sigma.template cast<double>(), x.V.template cast<double>()) -
                 ad) /
             frobenius_norm(ad);
    };
    worst_default = std::max(worst_default, recon(s));
    worst_fewer = std::max(worst_fewer, recon(f));
  }
  std::printf("[ sweeps   ] %s: %d sweeps -> %.3g, %d sweeps -> %.3g\n", type_name(T{}), S, worst_default, S - 2,
              worst_fewer);
  EXPECT_LE(worst_default, backward_tol<T>());
  EXPECT_GT(worst_fewer, backward_tol<T>());
}

// ---------------------------------------------------------------------------------------------------------------
// Symmetric eigen-decomposition

template <typename T>
void check_symmetric_eigen(const Mat3<T>& a, const std::string& name, Worst& worst) {
  SCOPED_TRACE(name + " (" + type_name(T{}) + ")");
  const SymEig3<T> e = symmetric_eigen(a);
  const Mat3d ad = a.template cast<double>(), q = e.Q.template cast<double>();
  const Vec3d lambda = e.lambda.template cast<double>();
  const double norm_a = norm_or_one(a);
  const double tol = backward_tol<T>();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(std::isfinite(lambda[i]));

  const double residual = frobenius_norm(ad * q - q * Mat3d::diagonal(lambda)) / norm_a;
  const double orth = orthogonality_error(e.Q);
  const double det = std::abs(determinant(q) - 1.0);
  EXPECT_LE(residual, tol);
  EXPECT_LE(orth, tol);
  EXPECT_LE(det, tol);
  EXPECT_GE(e.lambda[0], e.lambda[1]);
  EXPECT_GE(e.lambda[1], e.lambda[2]);

  // Weyl for symmetric perturbations; Eigen sorts ascending.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> ref(to_eigen(ad));
  double lambda_err = 0;
  for (int i = 0; i < 3; ++i)
    lambda_err = std::max(lambda_err, std::abs(lambda[i] - ref.eigenvalues()(2 - i)) / norm_a);
  EXPECT_LE(lambda_err, sigma_tol<T>());

  worst.reconstruction = std::max(worst.reconstruction, residual);
  worst.orthogonality = std::max(worst.orthogonality, orth);
  worst.determinant = std::max(worst.determinant, det);
  worst.sigma = std::max(worst.sigma, lambda_err);
}

template <typename T>
Mat3<T> symmetric_float_rounded(const Eigen::Matrix3d& s) {
  // Round, then mirror the upper triangle, so the matrix under test is exactly symmetric in T.
  Mat3<T> a = from_eigen(s).template cast<T>();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < i; ++j) a(i, j) = a(j, i);
  return a;
}

TYPED_TEST(SvdTyped, SymmetricEigenMatchesEigen) {
  using T = TypeParam;
  std::mt19937_64 rng(4242);
  Worst worst;
  for (int n = 0; n < 10000; ++n) {
    const Eigen::Matrix3d m = random_uniform_matrix(rng);
    check_symmetric_eigen(symmetric_float_rounded<T>(m + m.transpose()), "random #" + std::to_string(n), worst);
    if (::testing::Test::HasFailure()) break;
  }
  // Adversarial: the symmetric parts A + A^T and the Gram matrices A^T A of the SVD list (repeated, clustered,
  // zero and rank-deficient spectra at all scales), plus a pressure state with a tiny deviator.
  for (const MatrixCase& c : adversarial_cases()) {
    check_symmetric_eigen(symmetric_float_rounded<T>(c.a + c.a.transpose()), c.name + " A+A^T", worst);
    // A^T A squares the scale: keep it where T represents it to full precision (1e-20^2 is subnormal in float,
    // where the eigenvalues themselves could only be stored to ~1e-5; 1e20^2 overflows).
    const double gram = c.a.squaredNorm();
    if (gram > std::numeric_limits<T>::min() / std::numeric_limits<T>::epsilon() &&
        gram < 1e-3 * std::numeric_limits<T>::max())
      check_symmetric_eigen(symmetric_float_rounded<T>(c.a.transpose() * c.a), c.name + " A^TA", worst);
  }
  const Eigen::Matrix3d r = random_rotation(rng);
  const Eigen::Matrix3d pressure = r * Eigen::Vector3d(-1e5, -1e5 * (1 + 1e-12), -1e5).asDiagonal() * r.transpose();
  check_symmetric_eigen(symmetric_float_rounded<T>(pressure), "pressure + tiny deviator", worst);
  worst.print((std::string("symmetric eigen, ") + type_name(T{})).c_str());

  // Known spectrum: eigenvalues come out sorted descending.
  const SymEig3<T> e =
      symmetric_eigen(symmetric_float_rounded<T>(r * Eigen::Vector3d(3, -1, 2).asDiagonal() * r.transpose()));
  EXPECT_NEAR(e.lambda[0], 3.0, 3 * sigma_tol<T>());
  EXPECT_NEAR(e.lambda[1], 2.0, 3 * sigma_tol<T>());
  EXPECT_NEAR(e.lambda[2], -1.0, 3 * sigma_tol<T>());
}

// ---------------------------------------------------------------------------------------------------------------
// Polar decomposition

template <typename T>
void check_polar(const Mat3<T>& f, const std::string& name, Worst& worst) {
  SCOPED_TRACE(name + " (" + type_name(T{}) + ")");
  const Polar3<T> p = polar_decomposition(f);
  const Mat3d fd = f.template cast<double>(), rd = p.R.template cast<double>(), sd = p.S.template cast<double>();
  const double norm_f = norm_or_one(f);
  // R S multiplies the SVD factors once more: one more backward-error budget.
  const double tol = 2.0 * backward_tol<T>();

  const double recon = frobenius_norm(rd * sd - fd) / norm_f;
  EXPECT_LE(recon, tol);
  EXPECT_LE(orthogonality_error(p.R), tol);
  EXPECT_NEAR(determinant(rd), 1.0, tol);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_EQ(p.S(i, j), p.S(j, i));

  // Against the Eigen-built rotation-variant polar factor U diag(1, 1, sign det) V^T where it is well conditioned:
  // ||dR|| <= 2 ||dF|| / (sigma_2 + sigma_3) with the signed sigma_3 (Li 1995, see the file comment).
  const Eigen::JacobiSVD<Eigen::Matrix3d> ref(to_eigen(fd), Eigen::ComputeFullU | Eigen::ComputeFullV);
  const double det_sign = ref.matrixU().determinant() * ref.matrixV().determinant();
  const Eigen::Vector3d sv = ref.singularValues();
  const double denom = sv(1) + det_sign * sv(2);
  const double bound = 2.0 * sigma_tol<T>() * norm_f / denom;
  double r_err = 0;
  if (denom > 0 && bound < 1e-2) {
    const Eigen::Matrix3d r_ref =
        ref.matrixU() * Eigen::Vector3d(1, 1, ref.matrixU().determinant()).asDiagonal() *
        (ref.matrixV() * Eigen::Vector3d(1, 1, ref.matrixV().determinant()).asDiagonal()).transpose();
    r_err = frobenius_norm(rd - from_eigen(r_ref));
    EXPECT_LE(r_err, bound);
  }
  worst.reconstruction = std::max(worst.reconstruction, recon);
  worst.orthogonality = std::max(worst.orthogonality, orthogonality_error(p.R));
  worst.determinant = std::max(worst.determinant, std::abs(determinant(rd) - 1.0));
  worst.vectors = std::max(worst.vectors, r_err);
}

TYPED_TEST(SvdTyped, PolarDecomposition) {
  using T = TypeParam;
  std::mt19937_64 rng(2718);
  Worst worst;
  for (int n = 0; n < 10000; ++n) {
    check_polar(from_eigen(random_uniform_matrix(rng)).template cast<T>(), "random #" + std::to_string(n), worst);
    if (::testing::Test::HasFailure()) break;
  }
  for (const MatrixCase& c : adversarial_cases()) check_polar(from_eigen(c.a).template cast<T>(), c.name, worst);
  worst.print((std::string("polar (vectors column = ||R - R_ref||), ") + type_name(T{})).c_str());
}

TYPED_TEST(SvdTyped, PolarOfStretchAndInversionIsAnalytic) {
  // F = R0 D with D diagonal: for D = diag(2, 1, 1), R = R0, S = D; for the inverted D = diag(-0.5, 1, 1) the
  // negative value is on the smallest |sigma|, so again R = R0, S = D. For D = diag(0.5, 1.2, -0.8) the sign moves
  // to the smallest |sigma| (0.5): R = R0 diag(-1, 1, -1), S = diag(-0.5, 1.2, 0.8).
  using T = TypeParam;
  const double tol = 4.0 * sigma_tol<T>();
  std::mt19937_64 rng(161);
  struct Expect {
    Eigen::Vector3d d, flip, s;
  };
  const Expect cases[] = {{{2, 1, 1}, {1, 1, 1}, {2, 1, 1}},
                          {{-0.5, 1, 1}, {1, 1, 1}, {-0.5, 1, 1}},
                          {{0.5, 1.2, -0.8}, {-1, 1, -1}, {-0.5, 1.2, 0.8}}};
  for (const Expect& c : cases)
    for (int k = 0; k < 50; ++k) {
      const Eigen::Matrix3d r0 = random_rotation(rng);
      const Polar3<T> p = polar_decomposition(from_eigen(r0 * c.d.asDiagonal()).template cast<T>());
      EXPECT_LE(frobenius_norm(p.R.template cast<double>() - from_eigen(r0 * c.flip.asDiagonal())), tol);
      EXPECT_LE(frobenius_norm(p.S.template cast<double>() - from_eigen(Eigen::Matrix3d(c.s.asDiagonal()))), tol);
    }
}

// polar_rotation (Newton): for det f > 0 the rotation of polar_decomposition within the same perturbation bound
// (Li 1995: ||dR|| <= 2 ||dF|| / (sigma_2 + sigma_3), the SVD's backward error as ||dF||), orthonormal to the same
// tolerance, in the number of steps svd.h states for each range of singular values; it declines (converged false)
// an inverted or singular f and a non-finite one, where callers take svd().
TYPED_TEST(SvdTyped, PolarRotationMatchesPolarDecomposition) {
  using T = TypeParam;
  std::mt19937_64 rng(4242);
  struct Range {
    double lo, hi;
    int max_steps;  // the counts svd.h states (NewtonPolar)
  };
  const bool is_float = std::is_same_v<T, float>;
  const Range ranges[] = {{0.9, 1.1, is_float ? 3 : 4},
                          {0.5, 2.0, is_float ? 4 : 6},
                          {0.2, 5.0, is_float ? 6 : 7},
                          {0.01, 100.0, is_float ? 10 : 11}};
  for (const Range& r : ranges) {
    std::uniform_real_distribution<double> log_s(std::log(r.lo), std::log(r.hi));
    double worst_r = 0, worst_orth = 0;
    int worst_steps = 0;
    for (int n = 0; n < 5000; ++n) {
      const Eigen::Vector3d s(std::exp(log_s(rng)), std::exp(log_s(rng)), std::exp(log_s(rng)));
      const Mat3<T> f = from_eigen(random_rotation(rng) * s.asDiagonal() * random_rotation(rng)).template cast<T>();
      const PolarRotation<T> p = polar_rotation(f);
      ASSERT_TRUE(p.converged) << "singular values in [" << r.lo << ", " << r.hi << "], #" << n;
      const Mat3d fd = f.template cast<double>(), rd = p.R.template cast<double>();
      const Eigen::JacobiSVD<Eigen::Matrix3d> ref(to_eigen(fd), Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Eigen::Vector3d sv = ref.singularValues();
      const Eigen::Matrix3d r_ref = ref.matrixU() * ref.matrixV().transpose();  // det f > 0: a rotation
      const double bound = 2.0 * sigma_tol<T>() * norm_or_one(f) / (sv(1) + sv(2));
      const double err = frobenius_norm(rd - from_eigen(r_ref));
      EXPECT_LE(err, bound) << "#" << n;
      EXPECT_LE(orthogonality_error(p.R), 2.0 * backward_tol<T>()) << "#" << n;
      worst_r = std::max(worst_r, err);
      worst_orth = std::max(worst_orth, orthogonality_error(p.R));
      worst_steps = std::max(worst_steps, p.steps);
    }
    EXPECT_LE(worst_steps, r.max_steps) << "singular values in [" << r.lo << ", " << r.hi << "]";
    std::printf("[measured] polar_rotation (%s), singular values in [%g, %g]: ||R - R_ref|| <= %.2e, "
                "orthogonality %.2e, at most %d steps\n",
                type_name(T{}), r.lo, r.hi, worst_r, worst_orth, worst_steps);
  }
  // Declines: inverted (det < 0), singular, non-finite.
  const Mat3<T> inverted = from_eigen(random_rotation(rng) * Eigen::Vector3d(1.2, 0.9, -0.3).asDiagonal()).template cast<T>();
  EXPECT_FALSE(polar_rotation(inverted).converged);
  EXPECT_FALSE(polar_rotation(Mat3<T>::diagonal(Vec3<T>{{T(1), T(1), T(0)}})).converged);
  Mat3<T> nan = Mat3<T>::identity();
  nan(1, 2) = std::numeric_limits<T>::quiet_NaN();
  EXPECT_FALSE(polar_rotation(nan).converged);
  // A rotation is its own polar factor (one step).
  const Mat3<T> rot = from_eigen(random_rotation(rng)).template cast<T>();
  const PolarRotation<T> pr = polar_rotation(rot);
  EXPECT_TRUE(pr.converged);
  EXPECT_LE(frobenius_norm((pr.R - rot).template cast<double>()), 16.0 * eps<T>());
}

}  // namespace
}  // namespace fbar::test
