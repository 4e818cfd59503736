// NACC: non-associative Cam-Clay of Wolper et al. 2019 (CD-MPM), state = F, logJp (hardening).
//
// Elasticity: psi = mu/2 (tr b^ - 3) + kappa/2 ((J^2 - 1)/2 - ln J), b^ = J^(-2/3) F F^T, so
//     tau = mu dev(b^) + kappa/2 (J^2 - 1) I           (Kirchhoff; Kirchhoff pressure p = -kappa/2 (J^2 - 1))
// kappa = E / (3 (1 - 2 nu)) the bulk modulus, mu = E / (2 (1 + nu)).
// Uniaxial check (elastic, F = diag(s, 1, 1), J = s): tau11 = (2/3) mu s^(-2/3) (s^2 - 1) + kappa/2 (s^2 - 1),
// tau22 = -(1/3) mu s^(-2/3) (s^2 - 1) + kappa/2 (s^2 - 1), sigma = tau / s.
//
// Yield surface (an ellipse in p-q, q = sqrt(3/2) |dev tau|):
//     y(p, q) = (1 + 2 beta) q^2 + M^2 (p + beta p0)(p - p0) <= 0,     p0 = kappa (1e-5 + sinh(xi max(-logJp, 0)))
// spanning p in [-beta p0, p0] (tension tip, compression cap) with its top at p_c = (1 - beta) p0 / 2. For beta = 0
// the top lies on the critical-state line q = M p. M comes from friction_angle (triaxial compression, Mohr-Coulomb
// match): M = 6 sin(phi) / (3 - sin(phi)) (ClaymoreUW fixes M at phi = 45 deg and ignores the key).
// Return mapping of the trial state (F_trial = (I + dt C) F, singular values s_i, J = s0 s1 s2), as in Wolper et al.:
//   p > p0: to the cap, p = p0 (isotropic: F_new = U J_new^(1/3) V^T with -kappa/2 (J_new^2 - 1) = p0);
//   p < -beta p0: to the tension tip, the same with p = -beta p0;
//   y <= 0: elastic;
//   otherwise: q is scaled onto the ellipse at constant p (non-associative: no plastic volume change in F), b^'s
//   deviator scaled by the same factor.
// Hardening (hardeningOn): in the three plastic cases logJp += ln(J_trial / J_x), where p_x is the pressure the
// ellipse would need to pass through the trial state along the ray from its centre (p_c, 0) (the tips: p_x = the
// tip pressure). Trial states on the dense side (p > p_c) harden (p0 grows), on the loose side soften, and p = p_c
// is stationary: a shear path at constant J saturates at the ellipse's top (q = M p for beta = 0). The surface
// moves after the projection (explicit hardening, Wolper et al.).
// P-wave speed c_p = sqrt((kappa + 4 mu / 3) / rho0).
#pragma once

#include <cmath>

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/drucker_prager.cuh"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

template <typename T>
struct NaccParams {
  T rho0;       ///< [kg/m^3]
  T mu;         ///< [Pa] shear modulus
  T kappa;      ///< [Pa] bulk modulus
  T M2;         ///< [-] M^2, M = 6 sin(phi) / (3 - sin(phi))
  T beta;       ///< [-] tension tip at -beta p0
  T xi;         ///< [-] hardening rate
  int hardening;  ///< 1: logJp evolves (hardeningOn)
};

/// p-q position of a state with respect to the NACC ellipse.
template <typename T>
struct NaccYield {
  T p0;  ///< [Pa] compression cap
  T p;   ///< [Pa] Kirchhoff pressure
  T q;   ///< [Pa] sqrt(3/2) |dev tau|
  T y;   ///< [Pa^2] yield function (<= 0 admissible)
};

struct NACC {
  static constexpr const char* kJsonName = "NACC";
  static constexpr Constitutive kLaw = Constitutive::NACC;
  static constexpr const char* kAliases[] = {"CamClay", "Cam-Clay"};
  static constexpr MaterialParameter kParameters[] = {
      kYoungsModulusParameter,
      kPoissonRatioParameter,
      number_parameter("friction_angle", "deg", &MaterialSpec::friction_angle, ValidRange{0.0, 90.0, true, true}, 0.0,
                       "friction angle phi, sets M = 6 sin(phi) / (3 - sin(phi)), 0 < phi < 90"),
      number_parameter("xi", "-", &MaterialSpec::xi, kNonNegativeValue, 0.0, "hardening rate of p0"),
      number_parameter("beta", "-", &MaterialSpec::beta, kNonNegativeValue, 0.0,
                       "tension tip at -beta p0 (cohesion)"),
      number_parameter("logJp0", "-", &MaterialSpec::logJp0, kAnyValue, 0.0,
                       "initial log plastic volume ratio (negative: consolidated, p0 = kappa sinh(-xi logJp0))"),
      flag_parameter("hardeningOn", &MaterialSpec::hardening, "logJp evolves (hardening and softening)"),
  };
  template <typename T>
  using Params = NaccParams<T>;
  template <typename T>
  using State = PlasticState<T>;
  static constexpr int kStoredScalars = 13;  ///< position (3) + F (9) + logJp
  static constexpr MaterialOutputs kOutputs{true, true};

  /// M = 6 sin(phi) / (3 - sin(phi)) [-], phi in degrees.
  static double critical_state_slope(double friction_angle_deg) {
    const double s = std::sin(friction_angle_deg * 3.14159265358979323846 / 180.0);
    return 6.0 * s / (3.0 - s);
  }

  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    const LameParameters l = lame_parameters(m.youngs_modulus, m.poisson_ratio);
    const double M = critical_state_slope(m.friction_angle);
    const double kappa = m.youngs_modulus / (3.0 * (1.0 - 2.0 * m.poisson_ratio));  // bulk modulus
    return Params<T>{static_cast<T>(m.rho),       static_cast<T>(l.mu),
                     static_cast<T>(kappa),       static_cast<T>(M * M),
                     static_cast<T>(m.beta),      static_cast<T>(m.xi),
                     m.hardening ? 1 : 0};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> reference_state() {
    return State<T>{Mat3<T>::identity(), T(0)};
  }
  template <typename T>
  static State<T> initial_state(const MaterialSpec& m) {
    return State<T>{Mat3<T>::identity(), static_cast<T>(m.logJp0)};
  }
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T volume_ratio(const State<T>& s) {
    return determinant(s.F);
  }

  /// Compression cap p0 = kappa (1e-5 + sinh(xi max(-logJp, 0))) [Pa] (the 1e-5 keeps the ellipse non-empty).
  template <typename T>
  FBAR_HOST_DEVICE static inline T cap_pressure(const Params<T>& p, T logJp) {
    using std::sinh;
    return p.kappa * (T(1e-5) + sinh(p.xi * (logJp < T(0) ? -logJp : T(0))));
  }
  /// Kirchhoff pressure of volume ratio J: -kappa/2 (J^2 - 1) [Pa].
  template <typename T>
  FBAR_HOST_DEVICE static inline T pressure_of_J(const Params<T>& p, T J) {
    return -T(0.5) * p.kappa * (J * J - T(1));
  }
  /// Volume ratio with Kirchhoff pressure `pressure` (inverse of pressure_of_J; clamped at 1e-4 beyond kappa/2).
  template <typename T>
  FBAR_HOST_DEVICE static inline T J_of_pressure(const Params<T>& p, T pressure) {
    using std::sqrt;
    const T J2 = T(1) - T(2) * pressure / p.kappa;
    return sqrt(J2 > T(1e-8) ? J2 : T(1e-8));
  }

  /// Where a state lies with respect to the ellipse of hardening state logJp.
  template <typename T>
  FBAR_HOST_DEVICE static inline NaccYield<T> yield(const Params<T>& p, const Mat3<T>& F, T logJp) {
    using std::sqrt;
    const StressResult<T> s = kirchhoff_stress(p, State<T>{F, logJp}, Mat3<T>::zero());
    const T pressure = -trace(s.kirchhoff) / T(3);
    const Mat3<T> dev = deviatoric_part(s.kirchhoff);
    const T q = sqrt(T(1.5) * ddot(dev, dev));
    const T p0 = cap_pressure(p, logJp);
    return NaccYield<T>{p0, pressure, q,
                        (T(1) + T(2) * p.beta) * q * q + p.M2 * (pressure + p.beta * p0) * (pressure - p0)};
  }

  /// Return mapping and hardening (file comment) of the trial F.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> return_map(const Params<T>& p, const Mat3<T>& F_trial, T logJp) {
    using std::cbrt;
    using std::fabs;
    using std::log;
    using std::sqrt;
    const Svd3<T> d = svd(F_trial);
    const T J = d.sigma[0] * d.sigma[1] * d.sigma[2];
    const T p0 = cap_pressure(p, logJp);
    const T p_min = -p.beta * p0;
    const T cbrtJ = cbrt(J);
    const T scale = T(1) / (cbrtJ * cbrtJ);  // J^(-2/3)
    Vec3<T> b{{d.sigma[0] * d.sigma[0] * scale, d.sigma[1] * d.sigma[1] * scale, d.sigma[2] * d.sigma[2] * scale}};
    const T b_mean = (b[0] + b[1] + b[2]) / T(3);
    const Vec3<T> s_dev{{p.mu * (b[0] - b_mean), p.mu * (b[1] - b_mean), p.mu * (b[2] - b_mean)}};
    const T s_norm = sqrt(dot(s_dev, s_dev));
    const T q = sqrt(T(1.5)) * s_norm;
    const T pressure = pressure_of_J(p, J);
    const T y_s = (T(1) + T(2) * p.beta) * q * q;
    const T y_p = p.M2 * (pressure - p_min) * (pressure - p0);

    T logJp_new = logJp;
    if (pressure > p0 || pressure < p_min) {  // beyond a tip: isotropic state at the tip pressure
      const T J_new = J_of_pressure(p, pressure > p0 ? p0 : p_min);
      if (p.hardening) logJp_new = logJp + log(J / J_new);
      const T s_new = cbrt(J_new);
      return State<T>{u_diag_vt(d.U, Vec3<T>{{s_new, s_new, s_new}}, d.V), logJp_new};
    }
    if (y_s + y_p <= T(0)) return State<T>{F_trial, logJp};  // elastic
    if (p.hardening && p0 > T(0)) {
      // p_x: where the ray from the ellipse centre (p_c, 0) towards the trial point meets the current ellipse.
      const T p_c = (T(1) - p.beta) * p0 / T(2);
      T dir_p = p_c - pressure, dir_q = -q;  // from the trial point towards the centre
      const T len = sqrt(dir_p * dir_p + dir_q * dir_q);
      if (len > T(0)) {
        dir_p /= len;
        dir_q /= len;
        // Points p_c + l dir on the ellipse: A l^2 + Cc = 0 (no linear term: p_c is the midpoint of the tips).
        const T A = p.M2 * dir_p * dir_p + (T(1) + T(2) * p.beta) * dir_q * dir_q;
        const T Cc = p.M2 * (p_c - p_min) * (p_c - p0);  // < 0: the centre is inside
        const T l = sqrt(-Cc / A);
        // The intersection on the trial point's side of the centre (dir points from the trial point to p_c).
        const T p_x = p_c - l * dir_p;
        logJp_new = logJp + log(J / J_of_pressure(p, p_x));
      }
    }
    // Scale q onto the ellipse at constant p: b^'s deviator by the same factor, J unchanged.
    const T q_new = sqrt(fabs(y_p) / (T(1) + T(2) * p.beta));
    const T factor = q > T(0) ? q_new / q : T(0);
    // b^_new = m 1 + factor dev(b^) with m chosen so that det b^_new = 1, i.e. J is kept exactly (Simo's return keeps
    // the mean m = tr(b^)/3 instead, which changes J and hence p by O(q^2 / mu^2)): Newton on
    // sum_i ln(m + factor d_i) = 0 from m = tr(b^)/3 (an upper bound by AM-GM; the function is concave and
    // increasing, so Newton decreases m monotonically to the root: 4 fixed iterations reach double round-off for
    // |dev b^| < 0.5).
    Vec3<T> dev_b{{factor * (b[0] - b_mean), factor * (b[1] - b_mean), factor * (b[2] - b_mean)}};
    T m = b_mean;
    for (int it = 0; it < 4; ++it) {
      const T x0 = m + dev_b[0], x1 = m + dev_b[1], x2 = m + dev_b[2];
      m -= log(x0 * x1 * x2) / (T(1) / x0 + T(1) / x1 + T(1) / x2);
    }
    Vec3<T> s_new;
    for (int i = 0; i < 3; ++i) s_new[i] = sqrt(m + dev_b[i]) * cbrtJ;
    s_new[2] = d.sigma[2] < T(0) ? -s_new[2] : s_new[2];  // keep det = J (rotation-variant SVD)
    return State<T>{u_diag_vt(d.U, s_new, d.V), logJp_new};
  }

  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> advance(const Params<T>& p, const State<T>& s, const Mat3<T>& C, T dt) {
    return return_map(p, advance_deformation_gradient(s.F, C, dt), s.logJp);
  }

  /// tau = mu J^(-2/3) dev(F F^T) + kappa/2 (J^2 - 1) I [Pa]; C unused.
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& /*C*/) {
    using std::cbrt;
    const T J = determinant(s.F);
    const T c = cbrt(J);
    const Mat3<T> b = s.F * transpose(s.F);
    Mat3<T> tau = deviatoric_part(b) * (p.mu / (c * c));
    const T volumetric = T(0.5) * p.kappa * (J * J - T(1));
    for (int i = 0; i < 3; ++i) tau.m[i][i] += volumetric;
    tau.m[1][0] = tau.m[0][1];
    tau.m[2][0] = tau.m[0][2];
    tau.m[2][1] = tau.m[1][2];
    return StressResult<T>{tau, J};
  }

  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& /*s*/) {
    using std::sqrt;
    return sqrt((p.kappa + T(4) / T(3) * p.mu) / p.rho0);
  }

  /// psi = mu/2 (tr b^ - 3) + kappa/2 ((J^2 - 1)/2 - ln J) [J/m^3].
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    using std::cbrt;
    using std::log;
    const T J = determinant(s.F);
    const T c = cbrt(J);
    const T tr_b = ddot(s.F, s.F) / (c * c);
    return T(0.5) * p.mu * (tr_b - T(3)) + T(0.5) * p.kappa * (T(0.5) * (J * J - T(1)) - log(J));
  }
};

}  // namespace fbar
