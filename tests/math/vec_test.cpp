// Tests for MnBase/Math/vec.h: algebraic identities of the small vector/matrix types on seeded random data.
//
// Tolerances: each identity compares two evaluations of a polynomial of degree <= 6 in entries of size ~1 built from
// at most a few dozen roundings, so both sides agree to ~1e2 eps_double; 1e-12 leaves a wide margin without hiding
// a wrong formula (a sign or index error shows up at O(1)).
#include "MnBase/Math/vec.h"

#include <gtest/gtest.h>

#include <random>

namespace fbar {
namespace {

constexpr double kTol = 1e-12;

Mat3d random_matrix(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Mat3d m{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = u(rng);
  return m;
}

Vec3d random_vector(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Vec3d{{u(rng), u(rng), u(rng)}};
}

TEST(VecMat, ProductDeterminantTransposeIdentities) {
  std::mt19937_64 rng(1);
  for (int n = 0; n < 1000; ++n) {
    const Mat3d a = random_matrix(rng), b = random_matrix(rng);
    // det(AB) = det(A) det(B); (AB)^T = B^T A^T; det(A^T) = det(A); tr(AB) = A^T : B.
    EXPECT_NEAR(determinant(a * b), determinant(a) * determinant(b), kTol);
    EXPECT_LE(max_abs(transpose(a * b) - transpose(b) * transpose(a)), kTol);
    EXPECT_NEAR(determinant(transpose(a)), determinant(a), kTol);
    EXPECT_NEAR(trace(a * b), ddot(transpose(a), b), kTol);
  }
}

TEST(VecMat, InverseAndCofactor) {
  std::mt19937_64 rng(2);
  int checked = 0;
  for (int n = 0; n < 1000; ++n) {
    const Mat3d a = random_matrix(rng);
    const double det = determinant(a);
    // cof(A) = det(A) A^-T holds for every A; A A^-1 = I is checked where A is comfortably invertible.
    EXPECT_LE(max_abs(cofactor(a) * transpose(a) - Mat3d::identity() * det), kTol);
    if (std::abs(det) < 1e-2) continue;
    ++checked;
    EXPECT_LE(max_abs(a * inverse(a) - Mat3d::identity()), 1e2 * kTol);  // relative error grows like cond(A)
    EXPECT_LE(max_abs(inverse(a) * a - Mat3d::identity()), 1e2 * kTol);
  }
  EXPECT_GT(checked, 900);
}

TEST(VecMat, CrossDotOuterIdentities) {
  std::mt19937_64 rng(3);
  for (int n = 0; n < 1000; ++n) {
    const Vec3d a = random_vector(rng), b = random_vector(rng), c = random_vector(rng);
    // a x b is orthogonal to a and b; a . (b x c) = det[a b c]; |a x b|^2 = |a|^2 |b|^2 - (a.b)^2;
    // tr(a b^T) = a . b; (a b^T) c = a (b . c).
    const Vec3d axb = cross(a, b);
    EXPECT_NEAR(dot(axb, a), 0.0, kTol);
    EXPECT_NEAR(dot(axb, b), 0.0, kTol);
    Mat3d abc{};
    abc.set_col(0, a);
    abc.set_col(1, b);
    abc.set_col(2, c);
    EXPECT_NEAR(dot(a, cross(b, c)), determinant(abc), kTol);
    EXPECT_NEAR(norm_squared(axb), norm_squared(a) * norm_squared(b) - dot(a, b) * dot(a, b), kTol);
    EXPECT_NEAR(trace(outer(a, b)), dot(a, b), kTol);
    EXPECT_LE(max_abs(outer(a, b) * c - a * dot(b, c)), kTol);
    EXPECT_NEAR(frobenius_norm(outer(a, b)), norm(a) * norm(b), kTol);
  }
}

TEST(VecMat, DiagonalIdentityAndCasts) {
  const Mat3d d = Mat3d::diagonal(Vec3d{{2.0, -3.0, 0.5}});
  EXPECT_EQ(determinant(d), -3.0);
  EXPECT_EQ(trace(Mat3d::identity()), 3.0);
  const Mat3f f = d.cast<float>();
  EXPECT_EQ(f(1, 1), -3.0f);
  EXPECT_EQ(f(0, 1), 0.0f);
  EXPECT_EQ(d.col(1), (Vec3d{{0.0, -3.0, 0.0}}));
  EXPECT_EQ(d.row(2), (Vec3d{{0.0, 0.0, 0.5}}));
}

}  // namespace
}  // namespace fbar
