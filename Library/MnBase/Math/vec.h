// Small fixed-size vectors and matrices for host and device code (row-major, value semantics).
//
// Vec<T, N> and Mat<T, R, C> are aggregates: brace-initialise them, pass them by value to kernels.
// Index conventions: v[i] is component i (x = 0, y = 1, z = 2); m(i, j) is row i, column j.
// Everything is constexpr and FBAR_HOST_DEVICE so the CPU reference engine and the GPU kernels
// share one implementation of the algebra.
#pragma once

#include <cmath>
#include <cstddef>

#include "MnBase/Meta/config.h"

namespace fbar {

template <typename T, int N>
struct Vec {
  static_assert(N > 0, "Vec needs at least one component");
  using value_type = T;
  static constexpr int size = N;
  T v[N];

  FBAR_HOST_DEVICE constexpr T& operator[](int i) { return v[i]; }
  FBAR_HOST_DEVICE constexpr const T& operator[](int i) const { return v[i]; }

  FBAR_HOST_DEVICE static constexpr Vec zero() {
    Vec r{};
    for (int i = 0; i < N; ++i) r.v[i] = T(0);
    return r;
  }
  FBAR_HOST_DEVICE static constexpr Vec filled(T s) {
    Vec r{};
    for (int i = 0; i < N; ++i) r.v[i] = s;
    return r;
  }
  /// Converts component-wise to another scalar type (float <-> double).
  template <typename U>
  FBAR_HOST_DEVICE constexpr Vec<U, N> cast() const {
    Vec<U, N> r{};
    for (int i = 0; i < N; ++i) r.v[i] = static_cast<U>(v[i]);
    return r;
  }

  FBAR_HOST_DEVICE constexpr Vec& operator+=(const Vec& o) {
    for (int i = 0; i < N; ++i) v[i] += o.v[i];
    return *this;
  }
  FBAR_HOST_DEVICE constexpr Vec& operator-=(const Vec& o) {
    for (int i = 0; i < N; ++i) v[i] -= o.v[i];
    return *this;
  }
  FBAR_HOST_DEVICE constexpr Vec& operator*=(T s) {
    for (int i = 0; i < N; ++i) v[i] *= s;
    return *this;
  }
  FBAR_HOST_DEVICE constexpr Vec& operator/=(T s) {
    for (int i = 0; i < N; ++i) v[i] /= s;
    return *this;
  }
};

template <typename T> using Vec2 = Vec<T, 2>;
template <typename T> using Vec3 = Vec<T, 3>;
using Vec3f = Vec<float, 3>;
using Vec3d = Vec<double, 3>;
using Vec3i = Vec<int, 3>;

template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> operator+(Vec<T, N> a, const Vec<T, N>& b) { return a += b; }
template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> operator-(Vec<T, N> a, const Vec<T, N>& b) { return a -= b; }
template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> operator-(const Vec<T, N>& a) {
  Vec<T, N> r{};
  for (int i = 0; i < N; ++i) r.v[i] = -a.v[i];
  return r;
}
template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> operator*(Vec<T, N> a, T s) { return a *= s; }
template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> operator*(T s, Vec<T, N> a) { return a *= s; }
template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> operator/(Vec<T, N> a, T s) { return a /= s; }
template <typename T, int N>
FBAR_HOST_DEVICE constexpr bool operator==(const Vec<T, N>& a, const Vec<T, N>& b) {
  for (int i = 0; i < N; ++i)
    if (!(a.v[i] == b.v[i])) return false;
  return true;
}

template <typename T, int N>
FBAR_HOST_DEVICE constexpr T dot(const Vec<T, N>& a, const Vec<T, N>& b) {
  T s = T(0);
  for (int i = 0; i < N; ++i) s += a.v[i] * b.v[i];
  return s;
}
template <typename T, int N>
FBAR_HOST_DEVICE constexpr T norm_squared(const Vec<T, N>& a) { return dot(a, a); }
template <typename T, int N>
FBAR_HOST_DEVICE inline T norm(const Vec<T, N>& a) { using std::sqrt; return sqrt(dot(a, a)); }
template <typename T, int N>
FBAR_HOST_DEVICE constexpr T max_abs(const Vec<T, N>& a) {
  T m = T(0);
  for (int i = 0; i < N; ++i) {
    const T x = a.v[i] < T(0) ? -a.v[i] : a.v[i];
    m = x > m ? x : m;
  }
  return m;
}
/// Component-wise product (Hadamard).
template <typename T, int N>
FBAR_HOST_DEVICE constexpr Vec<T, N> cwise_mul(const Vec<T, N>& a, const Vec<T, N>& b) {
  Vec<T, N> r{};
  for (int i = 0; i < N; ++i) r.v[i] = a.v[i] * b.v[i];
  return r;
}
template <typename T>
FBAR_HOST_DEVICE constexpr Vec<T, 3> cross(const Vec<T, 3>& a, const Vec<T, 3>& b) {
  return Vec<T, 3>{{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}};
}

// ---------------------------------------------------------------------------------------------
// Matrices

template <typename T, int R, int C = R>
struct Mat {
  static_assert(R > 0 && C > 0, "Mat needs positive extents");
  using value_type = T;
  static constexpr int rows = R;
  static constexpr int cols = C;
  T m[R][C];

  FBAR_HOST_DEVICE constexpr T& operator()(int i, int j) { return m[i][j]; }
  FBAR_HOST_DEVICE constexpr const T& operator()(int i, int j) const { return m[i][j]; }

  FBAR_HOST_DEVICE static constexpr Mat zero() {
    Mat r{};
    for (int i = 0; i < R; ++i)
      for (int j = 0; j < C; ++j) r.m[i][j] = T(0);
    return r;
  }
  FBAR_HOST_DEVICE static constexpr Mat identity() {
    static_assert(R == C, "identity needs a square matrix");
    Mat r = zero();
    for (int i = 0; i < R; ++i) r.m[i][i] = T(1);
    return r;
  }
  FBAR_HOST_DEVICE static constexpr Mat diagonal(const Vec<T, R>& d) {
    static_assert(R == C, "diagonal needs a square matrix");
    Mat r = zero();
    for (int i = 0; i < R; ++i) r.m[i][i] = d[i];
    return r;
  }
  template <typename U>
  FBAR_HOST_DEVICE constexpr Mat<U, R, C> cast() const {
    Mat<U, R, C> r{};
    for (int i = 0; i < R; ++i)
      for (int j = 0; j < C; ++j) r.m[i][j] = static_cast<U>(m[i][j]);
    return r;
  }
  FBAR_HOST_DEVICE constexpr Vec<T, C> row(int i) const {
    Vec<T, C> r{};
    for (int j = 0; j < C; ++j) r[j] = m[i][j];
    return r;
  }
  FBAR_HOST_DEVICE constexpr Vec<T, R> col(int j) const {
    Vec<T, R> r{};
    for (int i = 0; i < R; ++i) r[i] = m[i][j];
    return r;
  }
  FBAR_HOST_DEVICE constexpr void set_col(int j, const Vec<T, R>& c) {
    for (int i = 0; i < R; ++i) m[i][j] = c[i];
  }

  FBAR_HOST_DEVICE constexpr Mat& operator+=(const Mat& o) {
    for (int i = 0; i < R; ++i)
      for (int j = 0; j < C; ++j) m[i][j] += o.m[i][j];
    return *this;
  }
  FBAR_HOST_DEVICE constexpr Mat& operator-=(const Mat& o) {
    for (int i = 0; i < R; ++i)
      for (int j = 0; j < C; ++j) m[i][j] -= o.m[i][j];
    return *this;
  }
  FBAR_HOST_DEVICE constexpr Mat& operator*=(T s) {
    for (int i = 0; i < R; ++i)
      for (int j = 0; j < C; ++j) m[i][j] *= s;
    return *this;
  }
  FBAR_HOST_DEVICE constexpr Mat& operator/=(T s) {
    for (int i = 0; i < R; ++i)
      for (int j = 0; j < C; ++j) m[i][j] /= s;
    return *this;
  }
};

template <typename T> using Mat3 = Mat<T, 3, 3>;
using Mat3f = Mat<float, 3, 3>;
using Mat3d = Mat<double, 3, 3>;

template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator+(Mat<T, R, C> a, const Mat<T, R, C>& b) { return a += b; }
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator-(Mat<T, R, C> a, const Mat<T, R, C>& b) { return a -= b; }
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator-(Mat<T, R, C> a) { return a *= T(-1); }
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator*(Mat<T, R, C> a, T s) { return a *= s; }
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator*(T s, Mat<T, R, C> a) { return a *= s; }
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator/(Mat<T, R, C> a, T s) { return a /= s; }

template <typename T, int R, int K, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> operator*(const Mat<T, R, K>& a, const Mat<T, K, C>& b) {
  Mat<T, R, C> r = Mat<T, R, C>::zero();
  for (int i = 0; i < R; ++i)
    for (int k = 0; k < K; ++k)
      for (int j = 0; j < C; ++j) r.m[i][j] += a.m[i][k] * b.m[k][j];
  return r;
}
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Vec<T, R> operator*(const Mat<T, R, C>& a, const Vec<T, C>& x) {
  Vec<T, R> r = Vec<T, R>::zero();
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) r[i] += a.m[i][j] * x[j];
  return r;
}

template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, C, R> transpose(const Mat<T, R, C>& a) {
  Mat<T, C, R> r{};
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) r.m[j][i] = a.m[i][j];
  return r;
}
/// Outer product a b^T.
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr Mat<T, R, C> outer(const Vec<T, R>& a, const Vec<T, C>& b) {
  Mat<T, R, C> r{};
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) r.m[i][j] = a[i] * b[j];
  return r;
}
template <typename T, int N>
FBAR_HOST_DEVICE constexpr T trace(const Mat<T, N, N>& a) {
  T s = T(0);
  for (int i = 0; i < N; ++i) s += a.m[i][i];
  return s;
}
/// Frobenius inner product A : B.
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr T ddot(const Mat<T, R, C>& a, const Mat<T, R, C>& b) {
  T s = T(0);
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) s += a.m[i][j] * b.m[i][j];
  return s;
}
template <typename T, int R, int C>
FBAR_HOST_DEVICE inline T frobenius_norm(const Mat<T, R, C>& a) { using std::sqrt; return sqrt(ddot(a, a)); }
template <typename T, int R, int C>
FBAR_HOST_DEVICE constexpr T max_abs(const Mat<T, R, C>& a) {
  T mx = T(0);
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) {
      const T x = a.m[i][j] < T(0) ? -a.m[i][j] : a.m[i][j];
      mx = x > mx ? x : mx;
    }
  return mx;
}

template <typename T>
FBAR_HOST_DEVICE constexpr T determinant(const Mat<T, 3, 3>& a) {
  return a.m[0][0] * (a.m[1][1] * a.m[2][2] - a.m[1][2] * a.m[2][1]) -
         a.m[0][1] * (a.m[1][0] * a.m[2][2] - a.m[1][2] * a.m[2][0]) +
         a.m[0][2] * (a.m[1][0] * a.m[2][1] - a.m[1][1] * a.m[2][0]);
}
template <typename T>
FBAR_HOST_DEVICE constexpr T determinant(const Mat<T, 2, 2>& a) {
  return a.m[0][0] * a.m[1][1] - a.m[0][1] * a.m[1][0];
}
/// Cofactor matrix: cof(A) = det(A) A^-T, defined (and smooth) also for singular A.
template <typename T>
FBAR_HOST_DEVICE constexpr Mat<T, 3, 3> cofactor(const Mat<T, 3, 3>& a) {
  Mat<T, 3, 3> c{};
  c.m[0][0] = a.m[1][1] * a.m[2][2] - a.m[1][2] * a.m[2][1];
  c.m[0][1] = a.m[1][2] * a.m[2][0] - a.m[1][0] * a.m[2][2];
  c.m[0][2] = a.m[1][0] * a.m[2][1] - a.m[1][1] * a.m[2][0];
  c.m[1][0] = a.m[0][2] * a.m[2][1] - a.m[0][1] * a.m[2][2];
  c.m[1][1] = a.m[0][0] * a.m[2][2] - a.m[0][2] * a.m[2][0];
  c.m[1][2] = a.m[0][1] * a.m[2][0] - a.m[0][0] * a.m[2][1];
  c.m[2][0] = a.m[0][1] * a.m[1][2] - a.m[0][2] * a.m[1][1];
  c.m[2][1] = a.m[0][2] * a.m[1][0] - a.m[0][0] * a.m[1][2];
  c.m[2][2] = a.m[0][0] * a.m[1][1] - a.m[0][1] * a.m[1][0];
  return c;
}
/// Inverse of a 3x3 matrix (caller guarantees det != 0).
template <typename T>
FBAR_HOST_DEVICE constexpr Mat<T, 3, 3> inverse(const Mat<T, 3, 3>& a) {
  return transpose(cofactor(a)) / determinant(a);
}

}  // namespace fbar
