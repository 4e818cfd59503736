// Shared helpers for the Math tests: seeded matrix generators, the adversarial SVD case list, Eigen conversions.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"

namespace fbar::test {

inline Eigen::Matrix3d to_eigen(const Mat3d& a) {
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = a(i, j);
  return m;
}

inline Mat3d from_eigen(const Eigen::Matrix3d& m) {
  Mat3d a{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a(i, j) = m(i, j);
  return a;
}

/// Uniformly distributed rotation (normalised Gaussian quaternion).
inline Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

inline Eigen::Matrix3d random_uniform_matrix(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3d m;
  for (int i = 0; i < 9; ++i) m.data()[i] = u(rng);
  return m;
}

struct MatrixCase {
  std::string name;
  Eigen::Matrix3d a;
};

/// The adversarial SVD inputs, each structured case also wrapped in random rotations (so nothing relies on
/// axis alignment) and scaled by 10^s for s in {-20, -10, 0, 10, 20} (very large and very small scales).
inline std::vector<MatrixCase> adversarial_cases(std::uint64_t seed = 2024) {
  std::mt19937_64 rng(seed);
  std::vector<MatrixCase> base;
  auto add = [&](const std::string& name, const Eigen::Matrix3d& a) { base.push_back({name, a}); };
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();

  add("zero", Eigen::Matrix3d::Zero());
  add("identity", I);
  add("minus_identity", -I);
  add("diag_123", Eigen::Vector3d(1, 2, 3).asDiagonal());
  add("diag_inverted_1m23", Eigen::Vector3d(1, -2, 3).asDiagonal());
  add("diag_one_negative_11m1", Eigen::Vector3d(1, 1, -1).asDiagonal());
  add("diag_two_negative", Eigen::Vector3d(-1, -2, 3).asDiagonal());
  add("diag_001", Eigen::Vector3d(0, 0, 1).asDiagonal());
  add("diag_rank2_110", Eigen::Vector3d(1, 1, 0).asDiagonal());
  Eigen::Matrix3d cyclic;
  cyclic << 0, 1, 0, 0, 0, 1, 1, 0, 0;
  add("permutation_cyclic", cyclic);
  Eigen::Matrix3d swap;
  swap << 0, 1, 0, 1, 0, 0, 0, 0, 1;
  add("permutation_swap_det_m1", swap);
  Eigen::Matrix3d nilpotent;
  nilpotent << 0, 1, 0, 0, 0, 1, 0, 0, 0;
  add("nilpotent_shift", nilpotent);
  Eigen::Matrix3d jordan;
  jordan << 1, 1, 0, 0, 1, 1, 0, 0, 1;
  add("jordan_block", jordan);
  Eigen::Matrix3d shear;
  shear << 1, 1e8, 0, 0, 1, 0, 0, 0, 1;
  add("shear_1e8_cond_1e16", shear);
  Eigen::Matrix3d zero_col = random_uniform_matrix(rng);
  zero_col.col(1).setZero();
  add("zero_column", zero_col);
  Eigen::Matrix3d zero_row = random_uniform_matrix(rng);
  zero_row.row(2).setZero();
  add("zero_row", zero_row);
  Eigen::Matrix3d equal_cols = random_uniform_matrix(rng);
  equal_cols.col(2) = equal_cols.col(0);
  add("two_equal_columns", equal_cols);
  add("graded_rows", Eigen::Vector3d(1, 1e-8, 1e-16).asDiagonal() * random_uniform_matrix(rng));
  add("graded_columns", random_uniform_matrix(rng) * Eigen::Vector3d(1e-16, 1, 1e-8).asDiagonal());
  for (int k = 0; k < 8; ++k) {
    const Eigen::Matrix3d r = random_rotation(rng);
    add("rotation", r);
    add("reflection", r * Eigen::Vector3d(1, 1, -1).asDiagonal());
    const Eigen::Vector3d a = random_uniform_matrix(rng).col(0), b = random_uniform_matrix(rng).col(1);
    const Eigen::Vector3d c = random_uniform_matrix(rng).col(2), d = random_uniform_matrix(rng).col(0);
    add("rank1", a * b.transpose());
    add("rank2", a * b.transpose() + c * d.transpose());
    add("near_identity_1e-6", I + 1e-6 * random_uniform_matrix(rng));
    add("rotated_near_identity", r * (I + 1e-3 * random_uniform_matrix(rng)));
  }
  // Prescribed singular values between two random rotations: repeated, clustered, rank-deficient, near-singular,
  // inverted (negative entry = det < 0).
  const double sets[][3] = {{1, 1, 1},         {2, 2, 1},         {1, 1, 0},
                            {1, 0, 0},         {1, 1e-8, 1e-16},  {1, 1 + 1e-9, 1 - 1e-9},
                            {1, 1e-10, 1e-10}, {3, 2, -1},        {1, 1, -1},
                            {1e-8, 1e-8, 1},   {1, 1e-4, 1e-8},   {2, 2, 1e-15},
                            {1, 1e-20, 0},     {1, 1, -1e-14},    {1, 1e-12, -1e-12},
                            {5, 1, 1},         {1, 1, 1 + 1e-15}, {1, -1e-300, 0}};
  for (const auto& s : sets) {
    char name[96];
    std::snprintf(name, sizeof(name), "svals_%g_%g_%g", s[0], s[1], s[2]);
    for (int k = 0; k < 6; ++k)
      add(name, random_rotation(rng) * Eigen::Vector3d(s[0], s[1], s[2]).asDiagonal() * random_rotation(rng));
  }

  std::vector<MatrixCase> out;
  for (const MatrixCase& c : base)
    for (int s = -20; s <= 20; s += 10) out.push_back({c.name + "_x1e" + std::to_string(s), c.a * std::pow(10.0, s)});
  return out;
}

/// ||a||_F, or 1 for the zero matrix (so relative errors of the zero matrix are absolute errors).
template <typename T>
double norm_or_one(const Mat3<T>& a) {
  const double n = frobenius_norm(a.template cast<double>());
  return n > 0 ? n : 1.0;
}

/// ||Q^T Q - I||_F in double.
template <typename T>
double orthogonality_error(const Mat3<T>& q) {
  const Mat3d qd = q.template cast<double>();
  return frobenius_norm(transpose(qd) * qd - Mat3d::identity());
}

}  // namespace fbar::test
