// Pieces every material shares: the stress result, small tensor helpers and the deformation kinematics.
//
// Conventions (all materials, host and device):
//  * Stress functions return the Kirchhoff stress tau = J sigma [Pa] because the MLS-MPM force term needs
//    V_p^0 tau_p (Hu et al. 2018, eq. 17): V^0 tau = V^n sigma, and V^0 is constant per particle.
//  * C is the APIC affine matrix of the particle, C_p = D_p^-1 sum_i w_ip v_i (x_i - x_p)^T [1/s]; in MLS-MPM it is
//    the particle's velocity gradient, grad v ~ C (so the same C updates F and enters viscous stresses).
//  * State updates are symplectic Euler with the new C: F <- (I + dt C) F and J <- (1 + dt tr C) J.
#pragma once

#include <cmath>
#include <type_traits>
#include <utility>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// What a material's stress function returns.
template <typename T>
struct StressResult {
  Mat3<T> kirchhoff;  ///< [Pa] tau = J sigma (symmetric)
  T J;                ///< [-] det F (volume ratio current / reference)
};

/// Cauchy stress sigma = tau / J [Pa].
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> cauchy_stress(const StressResult<T>& s) {
  return s.kirchhoff / s.J;
}

/// Symmetric part (A + A^T) / 2.
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> symmetric_part(const Mat3<T>& a) {
  return (a + transpose(a)) * T(0.5);
}

/// Deviatoric part A - tr(A)/3 I.
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> deviatoric_part(const Mat3<T>& a) {
  Mat3<T> d = a;
  const T mean = trace(a) / T(3);
  for (int i = 0; i < 3; ++i) d.m[i][i] -= mean;
  return d;
}

/// Mean pressure p = -tr(sigma) / 3 [Pa] (positive in compression).
template <typename T>
FBAR_HOST_DEVICE constexpr T mean_pressure(const Mat3<T>& sigma) {
  return -trace(sigma) / T(3);
}

/// Von Mises equivalent stress sqrt(3/2 s:s), s = dev(sigma) [Pa].
template <typename T>
FBAR_HOST_DEVICE inline T von_mises_stress(const Mat3<T>& sigma) {
  using std::sqrt;
  const Mat3<T> s = deviatoric_part(sigma);
  return sqrt(T(1.5) * ddot(s, s));
}

/// (1 + a)(1 + b)(1 + c) - 1 without forming the products near 1: keeps det - 1 accurate when the factors are
/// close to 1 (the cancellation in sigma0 sigma1 sigma2 - 1 would cost float its last 7 digits of J - 1).
template <typename T>
FBAR_HOST_DEVICE constexpr T product_minus_one(T a, T b, T c) {
  return a + b + c + a * b + b * c + c * a + a * b * c;
}

/// det(F) - 1 without the cancellation of det(F) - 1 near the identity: with H = F - I (exact in floating point
/// for diagonal entries in [0.5, 2]), det(I + H) - 1 = tr H + the principal 2x2 minors of H + det H.
template <typename T>
FBAR_HOST_DEVICE constexpr T determinant_minus_one(const Mat3<T>& F) {
  const T h00 = F.m[0][0] - T(1), h11 = F.m[1][1] - T(1), h22 = F.m[2][2] - T(1);
  const T m01 = h00 * h11 - F.m[0][1] * F.m[1][0];
  const T m02 = h00 * h22 - F.m[0][2] * F.m[2][0];
  const T m12 = h11 * h22 - F.m[1][2] * F.m[2][1];
  const T det_h = h00 * m12 - F.m[0][1] * (F.m[1][0] * h22 - F.m[1][2] * F.m[2][0]) +
                  F.m[0][2] * (F.m[1][0] * F.m[2][1] - h11 * F.m[2][0]);
  return (h00 + h11 + h22) + (m01 + m02 + m12) + det_h;
}

/// F <- (I + dt C) F (MLS-MPM deformation update, Hu et al. 2018 eq. 16 with grad v = C).
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> advance_deformation_gradient(const Mat3<T>& F, const Mat3<T>& C, T dt) {
  return F + (C * dt) * F;
}

/// One minus the volume ratio, advanced by J <- (1 + dt tr C) J written on 1 - J:
///   1 - J' = (1 - J) - J dt tr C,  with J = 1 - (1 - J).
/// Storing 1 - J keeps small volume changes in float: J = 1 - 1e-6 is 0.999999 (quantum 6e-8, i.e. 6 % of 1 - J)
/// while 1 - J = 1e-6 carries 24 bits.
template <typename T>
FBAR_HOST_DEVICE constexpr T advance_one_minus_J(T one_minus_J, const Mat3<T>& C, T dt) {
  return one_minus_J - (T(1) - one_minus_J) * dt * trace(C);
}

/// True when a law's state stores 1 - J itself (a member `one_minus_J`, as JFluid's does).
template <class S, class = void>
struct StoresOneMinusJ : std::false_type {};
template <class S>
struct StoresOneMinusJ<S, std::void_t<decltype(std::declval<const S&>().one_minus_J)>> : std::true_type {};

/// 1 - J of a state of law M: the stored value where the law keeps it (exact in float), else 1 - M::volume_ratio.
template <class M, class S>
FBAR_HOST_DEVICE constexpr auto one_minus_volume_ratio(const S& s) {
  if constexpr (StoresOneMinusJ<S>::value) {
    return s.one_minus_J;
  } else {
    using T = decltype(M::volume_ratio(s));
    return T(1) - M::volume_ratio(s);
  }
}

/// Lame parameters [Pa] of an isotropic elastic solid from Young's modulus E [Pa] and Poisson's ratio nu [-] (host; the
/// elastic laws' make_params and the plastic laws' elasticity).
struct LameParameters {
  double mu;      ///< shear modulus E / (2 (1 + nu))
  double lambda;  ///< Lame's first parameter E nu / ((1 + nu)(1 - 2 nu))
};
inline LameParameters lame_parameters(double E, double nu) {
  return LameParameters{E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))};
}

/// True when every entry is finite (no NaN, no infinity).
template <typename T>
FBAR_HOST_DEVICE inline bool all_finite(T x) {
  using std::isfinite;
  return isfinite(x);
}
template <typename T, int N>
FBAR_HOST_DEVICE inline bool all_finite(const Vec<T, N>& v) {
  using std::isfinite;
  bool ok = true;
  for (int i = 0; i < N; ++i) ok = ok && isfinite(v[i]);
  return ok;
}
template <typename T, int R, int C>
FBAR_HOST_DEVICE inline bool all_finite(const Mat<T, R, C>& a) {
  using std::isfinite;
  bool ok = true;
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) ok = ok && isfinite(a.m[i][j]);
  return ok;
}

/// True for a law whose particles carry pore water (M::kPoreFluid, materials/coupled_up.cuh): the engines run the
/// seepage channels (physics/seepage.cuh) for its bodies.
template <class M, class = void>
struct IsPoreFluid : std::false_type {};
template <class M>
struct IsPoreFluid<M, std::void_t<decltype(M::kPoreFluid)>> : std::bool_constant<M::kPoreFluid> {};

/// Which particle outputs a material can produce beyond the common ones (ID, Mass, Volume, Position, Velocity,
/// J, Pressure, StressCauchy, VonMisesStress).
struct MaterialOutputs {
  bool deformation_gradient;  ///< DefGrad_XX..ZZ (a material that stores F in State::F)
  bool log_jp;                ///< logJp (a plastic material that stores State::logJp)
  bool pore_pressure = false;  ///< PorePressure (a saturated material that stores State::pore_pressure)
};

}  // namespace fbar
