// 3x3 singular value, symmetric eigen and polar decompositions for host and device (rotation-variant SVD).
//
// API (T = float or double; every function is FBAR_HOST_DEVICE, allocation-free, exception-free, recursion-free):
//
//   Svd3<T>    svd(const Mat3<T>& a);                  // a = U diag(sigma) V^T
//   SymEig3<T> symmetric_eigen(const Mat3<T>& s);      // s = Q diag(lambda) Q^T
//   Polar3<T>  polar_decomposition(const Mat3<T>& f);  // f = R S
//   PolarRotation<T> polar_rotation(const Mat3<T>& f);  // R of f = R S for det f > 0 (Newton; faster, may decline)
//   Mat3<T>    u_diag_vt(U, d, V);                     // U diag(d) V^T, the usual way back from principal space
//
// Conventions
// -----------
// * svd() returns the rotation-variant SVD used for inverted elements in MPM/FEM (Irving, Teran & Fedkiw,
//   "Invertible finite elements for robust simulation of large deformation", SCA 2004): U and V are proper
//   rotations (det = +1) and the sign of det(a) is carried by the last singular value, so
//       sigma[0] >= sigma[1] >= |sigma[2]| >= 0 ... with only sigma[2] allowed to be negative.
//   The ordering holds exactly (not only to round-off). |sigma| are the classical singular values.
// * symmetric_eigen() sorts eigenvalues in descending order (lambda[0] >= lambda[1] >= lambda[2], so principal
//   stresses come out tension-first) and returns Q with det(Q) = +1. Only the symmetric part of s is used.
// * polar_decomposition() returns R = U V^T (a proper rotation) and S = V diag(sigma) V^T (symmetric). For
//   det(f) > 0 this is the classical polar decomposition (S positive definite); for an inverted f (det < 0) S has
//   one negative eigenvalue, which is what corotated models need to push an inverted element back.
//
// Algorithm and why
// -----------------
// svd(): one-sided (Hestenes) Jacobi on the columns of a, then a Gram-Schmidt construction of U.
//   1. a is scaled by a power of two so that max|a_ij| lies in [0.5, 1). The scaling is exact (svd(2^k a) gives
//      bit-identical U, V and 2^k sigma), keeps the Gram entries (squares of entries) away from overflow and
//      underflow at any input scale (float squares overflow at 2e19), and is undone exactly on sigma.
//   2. Plane rotations J applied on the right, B <- B J, V <- V J (B starts as a, V as I), each chosen from the
//      freshly computed 2x2 Gram block of the two columns so that they become orthogonal. Recomputing the dot
//      products from B at every rotation (rather than updating a^T a) is what makes one-sided Jacobi accurate:
//      its error is O(eps ||a||) for all singular values and O(eps) relative for the large ones, while any method
//      that diagonalises a^T a (a Jacobi eigen-solve of a^T a, then U from a V) squares the condition number: the
//      columns of a V are then only orthogonal to eps ||a||^2, and a Gram-Schmidt U reconstructs near-rank-1
//      matrices (sigma_2 ~ sqrt(eps) ||a||) with an error of up to sqrt(eps) ||a|| = 1e-8 in double (the McAdams et
//      al. 2011 QR step has the same floor, it drops the off-diagonal of R). A fixed number of cyclic sweeps
//      (JacobiSweeps<T>) is used so that every GPU lane runs the same instruction stream: cyclic Jacobi converges
//      quadratically, also for repeated singular values.
//   3. Columns of B are sorted by length with compare-and-swap steps that negate one of the swapped columns
//      (in B and V together), so B = a V and det(V) = +1 survive the sort.
//   4. u0 = b0/|b0|, u1 = Gram-Schmidt of b1 against u0, u2 = u0 x u1 (so det U = +1 by construction), and
//      sigma = (|b0|, |b1 - (u0.b1) u0|, u2.b2). The signed sigma[2] is where det(a) < 0 shows up. A zero or
//      negligible b0 / b1 (rank 0 or 1) is replaced by a unit vector orthogonal to u0 from the branch-free basis of
//      Duff et al., "Building an orthonormal basis, revisited", JCGT 6(1) 2017: any choice is exact because the
//      singular value it multiplies is (negligibly close to) zero.
//   Cost: JacobiSweeps<T> x 3 rotations of ~60 flops and one sqrt, one division and one rsqrt each; no
//   data-dependent loop exit, no dynamic indexing, no local memory (sm_90: float svd 40 registers, double 66, no
//   spills), a handful of selects.
//   Measured (tests/math, 10^4 random + 10^4 deformation gradients + ~1900 adversarial matrices incl. 1e-20..1e20
//   scaling): reconstruction ||U S V^T - a||_F / ||a||_F <= 1.7e-15 (double), 7.5e-7 (float); U, V orthonormal to
//   2.8e-15 / 1.3e-6; |sigma - sigma_Eigen| / ||a|| <= 1.8e-15 / 3.8e-7. On an H100 (tests/math/math_device_test.cu)
//   the device path (hardware rsqrt, FMA contraction) gives 1.0e-15 / 1.3e-6, and svd + U diag(f) V^T runs at
//   ~23e9 matrices/s in float, ~9e9 in double (one matrix per thread, coalesced loads and stores).
//   Accuracy is relative to ||a|| as long as ||a|| and the outputs are normal numbers of T; NaN or Inf in a give
//   non-finite sigma (never a silently finite result), so callers' NaN checks keep working.
//
// symmetric_eigen(): cyclic two-sided Jacobi (Rutishauser's update: a_pp -= t a_pq, a_qq += t a_pq), same
//   exact power-of-two scaling and fixed sweeps. Jacobi is chosen over the closed-form cubic because the cubic
//   loses eigenvector accuracy for clustered eigenvalues (exactly the hydrostatic states of a material).
#pragma once

#include <cmath>
#include <limits>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// Rotation-variant SVD: a = U diag(sigma) V^T, det U = det V = +1, sigma[0] >= sigma[1] >= |sigma[2]|.
template <typename T>
struct Svd3 {
  Mat3<T> U;
  Vec3<T> sigma;
  Mat3<T> V;
};

/// Symmetric eigen-decomposition: s = Q diag(lambda) Q^T, lambda descending, det Q = +1 (columns = eigenvectors).
template <typename T>
struct SymEig3 {
  Vec3<T> lambda;
  Mat3<T> Q;
};

/// Polar decomposition f = R S: R proper rotation, S symmetric (indefinite when det f < 0).
template <typename T>
struct Polar3 {
  Mat3<T> R;
  Mat3<T> S;
};

/// Cyclic Jacobi sweeps used by svd() and symmetric_eigen() (3 plane rotations each). Measured worst relative
/// reconstruction error over 4e6 random matrices after 2 / 3 / 4 sweeps: ~1e-1 / 1.7e-5 / 1.7e-15 (double; float
/// bottoms out at 4 sweeps, ~8e-7). The convergence is quadratic, so after the 4th sweep the residual is ~(residual
/// after 3)^2: float (floor 1e-7) keeps 4 sweeps, which would need a 3rd-sweep residual 20x worse than any seen to
/// miss its floor; double keeps 5, a full sweep of margin for its 1e-15 floor.
/// tests/math/svd_test.cpp (JacobiSweepCountIsNeededAndSufficient) checks the count reaches round-off and that
/// two sweeps fewer do not.
template <typename T>
struct JacobiSweeps;
template <>
struct JacobiSweeps<float> {
  static constexpr int value = 4;
};
template <>
struct JacobiSweeps<double> {
  static constexpr int value = 5;
};

namespace svd_detail {

/// 1/sqrt(x): the hardware reciprocal square root on the device (float: 2 ulp, double: 1 ulp), IEEE sqrt and
/// division on the host. Either error is far inside the 4 eps per rotation that the accuracy bound assumes.
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE T rsqrt_of(T x) {
#if FBAR_IN_DEVICE_CODE
  return ::rsqrt(x);
#else
  using std::sqrt;
  return T(1) / sqrt(x);
#endif
}

/// Power-of-two exponent e with max|a_ij| * 2^-e in [0.5, 1); e = 0 for the zero matrix (frexp(0) gives 0).
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE int scale_exponent(const Mat3<T>& a) {
  using std::frexp;
  int e = 0;
  frexp(max_abs(a), &e);
  return e;
}

template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE Mat3<T> ldexp_all(Mat3<T> a, int e) {
  using std::ldexp;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a.m[i][j] = ldexp(a.m[i][j], e);
  return a;
}

/// Jacobi plane rotation J = [[c, s], [-s, c]] that diagonalises the symmetric 2x2 block [[app, apq], [apq, aqq]]
/// (J^T A J has a zero off-diagonal). t = s/c is the smaller root of t^2 + 2 zeta t - 1 = 0 with
/// zeta = (aqq - app) / (2 apq), written without the division by apq:
///     t = 2 apq sign(d) / (|d| + sqrt(d^2 + 4 apq^2)),  d = aqq - app,   |t| <= 1 (inner rotation).
/// The max() keeps 0/0 (apq = 0, d = 0) from producing NaN and the clamp keeps |t| <= 1 when the squares
/// underflow; both cases give a harmless orthogonal rotation.
template <typename T>
struct JacobiRotation {
  T c, s, t;
};
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE JacobiRotation<T> jacobi_rotation(T app, T aqq, T apq) {
  using std::fabs;
  using std::fmax;
  using std::fmin;
  using std::sqrt;
  const T d = aqq - app;
  const T num = (d >= T(0) ? T(2) : T(-2)) * apq;
  const T den = fabs(d) + sqrt(d * d + T(4) * apq * apq);
  T t = num / fmax(den, std::numeric_limits<T>::min());
  t = fmin(fmax(t, T(-1)), T(1));
  const T c = rsqrt_of(T(1) + t * t);
  return {c, c * t, t};
}

/// (p, q) <- (c p - s q, s p + c q): the columns p, q of a matrix multiplied on the right by J.
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void rotate_pair(Vec3<T>& p, Vec3<T>& q, T c, T s) {
  for (int i = 0; i < 3; ++i) {
    const T x = p[i];
    const T y = q[i];
    p[i] = c * x - s * y;
    q[i] = s * x + c * y;
  }
}

/// One Hestenes step: orthogonalise columns bp, bq of B = a V and apply the same rotation to V's columns.
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void orthogonalize_columns(Vec3<T>& bp, Vec3<T>& bq, Vec3<T>& vp, Vec3<T>& vq) {
  const JacobiRotation<T> r = jacobi_rotation(dot(bp, bp), dot(bq, bq), dot(bp, bq));
  rotate_pair(bp, bq, r.c, r.s);
  rotate_pair(vp, vq, r.c, r.s);
}

/// Two-sided Jacobi step on the symmetric matrix (entries app, aqq, apq and the third row r: arp, arq): zeroes
/// apq and accumulates the rotation into the eigenvector columns qp, qq.
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void symmetric_rotation(T& app, T& aqq, T& apq, T& arp, T& arq, Vec3<T>& qp,
                                                           Vec3<T>& qq) {
  const JacobiRotation<T> r = jacobi_rotation(app, aqq, apq);
  app -= r.t * apq;
  aqq += r.t * apq;
  apq = T(0);
  const T rp = arp;
  arp = r.c * rp - r.s * arq;
  arq = r.s * rp + r.c * arq;
  rotate_pair(qp, qq, r.c, r.s);
}

/// Orders two keys descending in place; returns whether they were swapped.
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE bool order_descending(T& key_a, T& key_b) {
  const bool swap = key_a < key_b;
  const T ka = swap ? key_b : key_a;
  const T kb = swap ? key_a : key_b;
  key_a = ka;
  key_b = kb;
  return swap;
}

/// If `swap`: (a, b) <- (b, -a). Swapping two columns of a rotation flips its determinant; negating one flips it
/// back, and applying the same step to B keeps B = a V. Straight-line selects, no branch.
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void swap_negate_if(bool swap, Vec3<T>& a, Vec3<T>& b) {
  for (int i = 0; i < 3; ++i) {
    const T ai = a[i];
    const T bi = b[i];
    a[i] = swap ? bi : ai;
    b[i] = swap ? -ai : bi;
  }
}

/// A unit vector orthogonal to the unit vector n, without branches (Duff et al., JCGT 2017, listing 3).
template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE Vec3<T> any_orthonormal(const Vec3<T>& n) {
  using std::copysign;
  const T sign = copysign(T(1), n[2]);
  const T a = T(-1) / (sign + n[2]);
  const T b = n[0] * n[1] * a;
  return Vec3<T>{{T(1) + sign * n[0] * n[0] * a, sign * b, -sign * n[0]}};
}

template <typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE Mat3<T> from_columns(const Vec3<T>& c0, const Vec3<T>& c1, const Vec3<T>& c2) {
  Mat3<T> m{};
  for (int i = 0; i < 3; ++i) {
    m.m[i][0] = c0[i];
    m.m[i][1] = c1[i];
    m.m[i][2] = c2[i];
  }
  return m;
}

}  // namespace svd_detail

/// Rotation-variant SVD of a 3x3 matrix (see the file comment for conventions, algorithm and accuracy).
/// Sweeps: cyclic Jacobi sweeps; the default is the measured minimum plus margin for T (see JacobiSweeps: two
/// fewer sweeps leave errors of 1e-2 .. 1e-6), so kernels should not lower it.
template <typename T, int Sweeps = JacobiSweeps<T>::value>
FBAR_HOST_DEVICE inline Svd3<T> svd(const Mat3<T>& a) {
  using std::copysign;
  using std::fabs;
  using std::fmin;
  using std::ldexp;
  using std::sqrt;
  namespace d = svd_detail;
  static_assert(std::numeric_limits<T>::is_iec559, "svd needs IEEE float or double");

  const int e = d::scale_exponent(a);
  const Mat3<T> as = d::ldexp_all(a, -e);
  Vec3<T> b0 = as.col(0), b1 = as.col(1), b2 = as.col(2);
  Vec3<T> v0{{T(1), T(0), T(0)}}, v1{{T(0), T(1), T(0)}}, v2{{T(0), T(0), T(1)}};

  for (int sweep = 0; sweep < Sweeps; ++sweep) {
    d::orthogonalize_columns(b0, b1, v0, v1);
    d::orthogonalize_columns(b0, b2, v0, v2);
    d::orthogonalize_columns(b1, b2, v1, v2);
  }

  // Sort the columns by length, descending (three compare-and-swaps sort three keys).
  T n0 = dot(b0, b0), n1 = dot(b1, b1), n2 = dot(b2, b2);
  bool swap = d::order_descending(n0, n1);
  d::swap_negate_if(swap, b0, b1);
  d::swap_negate_if(swap, v0, v1);
  swap = d::order_descending(n1, n2);
  d::swap_negate_if(swap, b1, b2);
  d::swap_negate_if(swap, v1, v2);
  swap = d::order_descending(n0, n1);
  d::swap_negate_if(swap, b0, b1);
  d::swap_negate_if(swap, v0, v1);

  // After scaling a nonzero matrix has |b0| >= 0.5. A squared length below `tiny` (~1e-31 in float, 1e-292 in
  // double) means a singular value below sqrt(tiny) relative to ||a||: its direction is noise and its squares are
  // (nearly) subnormal, so the column is replaced by an exact orthonormal direction.
  constexpr T tiny = std::numeric_limits<T>::min() / std::numeric_limits<T>::epsilon();
  const bool rank0 = !(n0 > tiny);
  const T s0 = sqrt(n0);
  Vec3<T> u0 = b0 * (rank0 ? T(0) : T(1) / s0);
  u0[0] += rank0 ? T(1) : T(0);

  const Vec3<T> b1p = b1 - dot(u0, b1) * u0;
  const T n1p = dot(b1p, b1p);
  const bool rank1 = !(n1p > tiny);
  T s1 = sqrt(n1p);
  const Vec3<T> u1_gs = b1p * (rank1 ? T(0) : T(1) / s1);
  const Vec3<T> u1_any = d::any_orthonormal(u0);
  Vec3<T> u1{};
  for (int i = 0; i < 3; ++i) u1[i] = rank1 ? u1_any[i] : u1_gs[i];

  const Vec3<T> u2 = cross(u0, u1);
  T s2 = dot(u2, b2);

  // Enforce sigma0 >= sigma1 >= |sigma2| exactly; the clamps move values by round-off only (the column lengths
  // are already sorted, Gram-Schmidt and projection can only add an ulp).
  s1 = fmin(s1, s0);
  s2 = copysign(fmin(fabs(s2), s1), s2);

  Svd3<T> r;
  r.U = d::from_columns(u0, u1, u2);
  r.V = d::from_columns(v0, v1, v2);
  r.sigma = Vec3<T>{{ldexp(s0, e), ldexp(s1, e), ldexp(s2, e)}};
  return r;
}

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi (uses 0.5 (s + s^T)).
template <typename T, int Sweeps = JacobiSweeps<T>::value>
FBAR_HOST_DEVICE inline SymEig3<T> symmetric_eigen(const Mat3<T>& s) {
  using std::ldexp;
  namespace d = svd_detail;
  static_assert(std::numeric_limits<T>::is_iec559, "symmetric_eigen needs IEEE float or double");

  const int e = d::scale_exponent(s);
  const Mat3<T> as = d::ldexp_all(s, -e);
  T a00 = as(0, 0), a11 = as(1, 1), a22 = as(2, 2);
  T a01 = T(0.5) * (as(0, 1) + as(1, 0));
  T a02 = T(0.5) * (as(0, 2) + as(2, 0));
  T a12 = T(0.5) * (as(1, 2) + as(2, 1));
  Vec3<T> q0{{T(1), T(0), T(0)}}, q1{{T(0), T(1), T(0)}}, q2{{T(0), T(0), T(1)}};

  for (int sweep = 0; sweep < Sweeps; ++sweep) {
    d::symmetric_rotation(a00, a11, a01, a02, a12, q0, q1);  // (p, q, r) = (0, 1, 2)
    d::symmetric_rotation(a00, a22, a02, a01, a12, q0, q2);  // (0, 2, 1): a_rp = a10, a_rq = a12
    d::symmetric_rotation(a11, a22, a12, a01, a02, q1, q2);  // (1, 2, 0): a_rp = a01, a_rq = a02
  }

  d::swap_negate_if(d::order_descending(a00, a11), q0, q1);
  d::swap_negate_if(d::order_descending(a11, a22), q1, q2);
  d::swap_negate_if(d::order_descending(a00, a11), q0, q1);

  SymEig3<T> r;
  r.lambda = Vec3<T>{{ldexp(a00, e), ldexp(a11, e), ldexp(a22, e)}};
  r.Q = d::from_columns(q0, q1, q2);
  return r;
}

/// U diag(d) V^T without forming diag(d) (27 multiply-adds): maps principal-space quantities back.
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> u_diag_vt(const Mat3<T>& U, const Vec3<T>& d, const Mat3<T>& V) {
  Mat3<T> r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      r.m[i][j] = U.m[i][0] * d[0] * V.m[j][0] + U.m[i][1] * d[1] * V.m[j][1] + U.m[i][2] * d[2] * V.m[j][2];
  return r;
}

/// Polar decomposition f = R S from the rotation-variant SVD: R = U V^T, S = V diag(sigma) V^T.
/// S is returned exactly symmetric (upper triangle computed, mirrored).
template <typename T>
FBAR_HOST_DEVICE inline Polar3<T> polar_decomposition(const Mat3<T>& f) {
  const Svd3<T> d = svd(f);
  Polar3<T> r;
  r.R = d.U * transpose(d.V);
  r.S = u_diag_vt(d.V, d.sigma, d.V);
  r.S.m[1][0] = r.S.m[0][1];
  r.S.m[2][0] = r.S.m[0][2];
  r.S.m[2][1] = r.S.m[1][2];
  return r;
}

/// Newton's polar iteration (polar_rotation): it stops after the first step that changes no entry by more than
/// sqrt(eps) (quadratic convergence leaves about half the square of that, eps / 2, in R) or after kMaxIterations
/// steps. Measured most steps (tests/math/svd_test.cpp, PolarRotationMatchesPolarDecomposition), float / double:
/// singular values in [0.9, 1.1] 3 / 4, [0.5, 2] 4 / 6, [0.2, 5] 6 / 7, [0.01, 100] 10 / 11; ||R - R_ref|| 2.2e-7 /
/// 2.3e-15 up to [0.5, 2] (svd(): 7.1e-7 / 7.1e-7 on random matrices of its own test).
template <typename T>
struct NewtonPolar;
template <>
struct NewtonPolar<float> {
  static constexpr float kTolerance = 3.4526698e-4f;  // sqrt(2^-23)
  static constexpr int kMaxIterations = 16;
};
template <>
struct NewtonPolar<double> {
  static constexpr double kTolerance = 1.4901161193847656e-8;  // sqrt(2^-52)
  static constexpr int kMaxIterations = 16;
};

/// The rotation of f = R S for det f > 0, and whether it converged.
template <typename T>
struct PolarRotation {
  Mat3<T> R;
  bool converged;
  int steps;  ///< Newton steps taken
};

/// R of the polar decomposition f = R S (S positive definite) for det f > 0, by Newton's iteration
/// X <- (X + X^-T) / 2 from X = f (Higham, SIAM J. Sci. Stat. Comput. 7(4), 1986), X^-T = cof(X) / det(X). Each
/// step maps every singular value s of X to (s + 1/s) / 2 and keeps the singular vectors, so the iterates converge
/// quadratically to U V^T, the rotation svd() gives, at a fraction of its cost: a step is a cofactor matrix, one
/// division and 18 multiply-adds, against svd()'s 12 Jacobi rotations. It is backward stable like svd(): the error
/// in R is O(eps) times the condition number of f. converged = false (R then means nothing) when det f <= 0 (the
/// iteration would converge to the reflection U V^T with det -1, not the rotation-variant factor), a step's
/// determinant is not a positive finite number, or kMaxIterations pass; callers then use svd().
template <typename T>
FBAR_HOST_DEVICE inline PolarRotation<T> polar_rotation(const Mat3<T>& f) {
  Mat3<T> x = f;
#if FBAR_IN_DEVICE_CODE
#pragma unroll 1
#endif
  for (int it = 0; it < NewtonPolar<T>::kMaxIterations; ++it) {
    const Mat3<T> c = cofactor(x);
    const T det = x.m[0][0] * c.m[0][0] + x.m[0][1] * c.m[0][1] + x.m[0][2] * c.m[0][2];
    if (!(det > T(0)) || !(det <= std::numeric_limits<T>::max())) return PolarRotation<T>{x, false, it};
    const T half_inv_det = T(0.5) / det;
    T change = T(0);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const T next = T(0.5) * x.m[i][j] + half_inv_det * c.m[i][j];
        const T d = next - x.m[i][j];
        change = (d < T(0) ? -d : d) > change ? (d < T(0) ? -d : d) : change;
        x.m[i][j] = next;
      }
    if (change <= NewtonPolar<T>::kTolerance) return PolarRotation<T>{x, true, it + 1};
  }
  return PolarRotation<T>{x, false, NewtonPolar<T>::kMaxIterations};
}

}  // namespace fbar
