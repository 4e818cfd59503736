// DruckerPrager: granular elastoplasticity of Klar et al. 2016 (Hencky strain, Drucker-Prager cone), state = F, logJp.
//
// Elasticity (St. Venant-Kirchhoff in Hencky strain): with F = U diag(s) V^T and eps = ln s (principal),
//     tau = U diag(2 mu eps_i + lambda tr eps) U^T                              (Kirchhoff stress)
//     psi = mu |eps|^2 + lambda/2 (tr eps)^2                                     (per reference volume)
// Uniaxial check (the constitutive patch test, inside the cone): F = diag(s, 1, 1) gives sigma = tau / s with
// sigma11 = (lambda + 2 mu) ln(s) / s, sigma22 = lambda ln(s) / s.
//
// Plasticity (Klar et al. 2016, sec. 4.3.2 and 6.3; every case defined, including friction_angle = 0):
//   e = eps - c 1 (c = cohesion, ClaymoreUW's meaning: the cone apex sits at log strain c, so tension up to c is
//   elastic); with volume correction e_c = e + (logJp / 3) 1, else e_c = e. Yield test on the strain,
//       dgamma = |dev e| + (3 lambda + 2 mu) / (2 mu) tr(e_c) alpha,   alpha = sqrt(2/3) 2 sin(phi) / (3 - sin(phi))
//   (this is |dev tau| + alpha tr tau <= 0 divided by 2 mu, with tau the stress of e_c):
//   case II  tr e_c >= 0 (tension): return to the apex, eps_new = c 1 (stress-free for c = 0); with volume
//            correction logJp += beta tr e (Tampubolon et al. 2017: the dilation removed is remembered, scaled
//            by beta, and must be compressed away before the grain carries stress again);
//   case I   dgamma <= 0 (inside the cone, also |dev e| = 0 at phi = 0): eps_new = e_c + c 1;
//   case III otherwise: eps_new = e_c - dgamma dev(e) / |dev e| + c 1 (radial return onto the cone at constant
//            tr e_c; at phi = 0 the shear strain is removed entirely: a frictionless, cohesionless grain carries
//            pressure only).
//   In cases I and III the remembered dilation is folded into the elastic strain (e_c) and logJp returns to 0,
//   so the stress is continuous when a dilated grain closes up again. ClaymoreUW resets logJp without folding it
//   in, and leaves the new singular values undefined for a trial state that is in compression with
//   friction_angle = 0 (the branch the issue names): here that state takes case I or III as above.
// Singular values below 1e-4 (in magnitude) are clamped before the logarithm, so inverted or collapsed particles
// get a finite strain, and F_new = U diag(exp(eps_new)) V^T is never inverted.
// P-wave speed c_p = sqrt((lambda + 2 mu) / rho0) (elastic, small strain).
#pragma once

#include <cmath>

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/fixed_corotated.cuh"
#include "physics/materials/hencky.cuh"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

template <typename T>
struct DruckerPragerParams {
  T rho0;            ///< [kg/m^3]
  T mu;              ///< [Pa] shear modulus
  T lambda;          ///< [Pa] Lame's first parameter
  T alpha;           ///< [-] cone coefficient sqrt(2/3) 2 sin(phi) / (3 - sin(phi))
  T cohesion;        ///< [-] log strain of the cone apex
  T beta;            ///< [-] fraction of the dilation remembered by the volume correction
  int vol_correction;  ///< 1: volume correction on (SandVolCorrection)
};

/// Per-particle state besides the position: elastic F and the volume-correction memory logJp.
template <typename T>
struct PlasticState {
  Mat3<T> F;  ///< [-] elastic deformation gradient
  T logJp;    ///< [-] DruckerPrager: remembered dilation; NACC: log plastic volume ratio (hardening state)
};

/// Hencky strain and its stress in principal space, shared by the plastic laws.
template <typename T>
struct HenckyPrincipal {
  Svd3<T> d;
  Vec3<T> eps;  ///< ln |s_i| (|s_i| clamped at 1e-4)
};
template <typename T>
FBAR_HOST_DEVICE inline HenckyPrincipal<T> hencky_principal(const Mat3<T>& F) {
  using std::fabs;
  using std::log;
  HenckyPrincipal<T> h{svd(F), Vec3<T>::zero()};
  for (int i = 0; i < 3; ++i) {
    const T s = fabs(h.d.sigma[i]);
    h.eps[i] = log(s > T(1e-4) ? s : T(1e-4));
  }
  return h;
}

/// The elasticity of a plastic law whose State<T> holds the elastic F (State::F) and whose Params<T> hold rho0, mu
/// and lambda (DruckerPrager, VonMises): the Hencky law (materials/hencky.cuh) of F_e. Such a law derives from
/// HenckyElastoplastic<its Params, its State> for kirchhoff_stress, wave_speed and energy_density, and supplies its
/// own return mapping.
template <template <typename> class Params, template <typename> class State>
struct HenckyElastoplastic {
  /// The Hencky parameters with the law's mu and lambda.
  template <typename T>
  FBAR_HOST_DEVICE static constexpr Hencky::Params<T> elastic(const Params<T>& p) {
    return Hencky::Params<T>{p.rho0, p.mu, p.lambda};
  }

  /// tau = U diag(2 mu eps + lambda tr eps) U^T [Pa] of the stored (returned, never inverted) F_e; C unused.
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& C) {
    return Hencky::kirchhoff_stress(elastic(p), Hencky::State<T>{s.F}, C);
  }

  /// P-wave speed sqrt((lambda + 2 mu) / rho0) [m/s] (elastic, small strain: the fastest wave).
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& /*s*/) {
    return Hencky::wave_speed(elastic(p), Hencky::State<T>{Mat3<T>::identity()});
  }

  /// Stored elastic energy psi = mu |eps|^2 + lambda/2 (tr eps)^2 of F_e per reference volume [J/m^3] (the plastic
  /// work is dissipated).
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    return Hencky::energy_density(elastic(p), Hencky::State<T>{s.F});
  }
};

struct DruckerPrager : HenckyElastoplastic<DruckerPragerParams, PlasticState> {
  static constexpr const char* kJsonName = "DruckerPrager";
  static constexpr Constitutive kLaw = Constitutive::DruckerPrager;
  static constexpr const char* kAliases[] = {"Sand", "Drucker-Prager", "Drucker_Prager"};
  static constexpr MaterialParameter kParameters[] = {
      kYoungsModulusParameter,
      kPoissonRatioParameter,
      number_parameter("friction_angle", "deg", &MaterialSpec::friction_angle, ValidRange{0.0, 90.0, false, true}, 0.0,
                       "internal friction angle phi, 0 <= phi < 90"),
      number_parameter("cohesion", "-", &MaterialSpec::cohesion, kNonNegativeValue, 0.0,
                       "log strain of the cone apex (tensile strength (3 lambda + 2 mu) c)"),
      number_parameter("logJp0", "-", &MaterialSpec::logJp0, kNonNegativeValue, 0.0,
                       "initial remembered dilation (volume correction)"),
      number_parameter("beta", "-", &MaterialSpec::beta, ValidRange{0.0, 1.0, false, false}, 0.0,
                       "fraction of the dilation the volume correction remembers, 0..1"),
      flag_parameter("SandVolCorrection", &MaterialSpec::vol_correction, "volume correction on"),
  };
  template <typename T>
  using Params = DruckerPragerParams<T>;
  template <typename T>
  using State = PlasticState<T>;
  static constexpr int kStoredScalars = 13;  ///< position (3) + F (9) + logJp
  static constexpr MaterialOutputs kOutputs{true, true};

  /// logJp0 is the volume correction's starting memory: without the correction it would be silently unused.
  static ParameterProblem check(const MaterialSpec& m) {
    if (!m.vol_correction && m.logJp0 != 0.0) return {"logJp0", "0 when SandVolCorrection is false"};
    return {};
  }

  /// Cone coefficient alpha = sqrt(2/3) 2 sin(phi) / (3 - sin(phi)) [-], phi in degrees (Klar et al. 2016).
  static double cone_coefficient(double friction_angle_deg) {
    const double s = std::sin(friction_angle_deg * 3.14159265358979323846 / 180.0);
    return std::sqrt(2.0 / 3.0) * 2.0 * s / (3.0 - s);
  }

  /// The friction_angle [deg] to give this law for a granular material whose Mohr-Coulomb angle phi_mc [deg] was
  /// measured in plane strain (a planar flume, a slab between walls). The cone above matches Mohr-Coulomb in
  /// triaxial compression (Klar et al. 2016, as ClaymoreUW): sqrt(J2) = k p with k = 2 sqrt(3) sin(phi) / (3 -
  /// sin(phi)); in plane strain Mohr-Coulomb is sqrt(J2) = k p with k = 3 tan(phi_mc) / sqrt(9 + 12 tan^2(phi_mc))
  /// (the inscribed match). Equal k: sin(phi) = 3 k / (2 sqrt(3) + k). 33 deg in plane strain is 23.04 deg here:
  /// the compression cone at 33 deg is 48 % stronger than the plane-strain material.
  static double plane_strain_friction_angle(double phi_mc_deg) {
    const double t = std::tan(phi_mc_deg * 3.14159265358979323846 / 180.0);
    const double k = 3.0 * t / std::sqrt(9.0 + 12.0 * t * t);
    return std::asin(3.0 * k / (2.0 * std::sqrt(3.0) + k)) * 180.0 / 3.14159265358979323846;
  }

  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    const auto e = FixedCorotated::make_params<T>(m);
    return Params<T>{e.rho0,
                     e.mu,
                     e.lambda,
                     static_cast<T>(cone_coefficient(m.friction_angle)),
                     static_cast<T>(m.cohesion),
                     static_cast<T>(m.beta),
                     m.vol_correction ? 1 : 0};
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

  /// The return mapping (file comment) of a trial state; F_trial is the elastic predictor.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> return_map(const Params<T>& p, const Mat3<T>& F_trial, T logJp) {
    using std::exp;
    using std::sqrt;
    const HenckyPrincipal<T> h = hencky_principal(F_trial);
    Vec3<T> e{{h.eps[0] - p.cohesion, h.eps[1] - p.cohesion, h.eps[2] - p.cohesion}};
    const T tr_e = e[0] + e[1] + e[2];
    const T memory = p.vol_correction ? logJp : T(0);
    const T tr_c = tr_e + memory;
    const T mean = tr_e / T(3);
    const Vec3<T> dev{{e[0] - mean, e[1] - mean, e[2] - mean}};
    const T dev_norm = sqrt(dot(dev, dev));
    Vec3<T> eps_new;
    T logJp_new = logJp;
    if (tr_c >= T(0)) {  // case II: apex
      eps_new = Vec3<T>{{p.cohesion, p.cohesion, p.cohesion}};
      if (p.vol_correction) logJp_new = logJp + p.beta * tr_e;
    } else {
      const T dgamma = dev_norm + (T(3) * p.lambda + T(2) * p.mu) / (T(2) * p.mu) * tr_c * p.alpha;
      // dgamma > 0 implies dev_norm > 0 (tr_c < 0, alpha >= 0): the division below is safe.
      const T shrink = dgamma > T(0) ? dgamma / dev_norm : T(0);  // case III, or 0 for case I
      for (int i = 0; i < 3; ++i) eps_new[i] = e[i] + memory / T(3) - shrink * dev[i] + p.cohesion;
      if (p.vol_correction) logJp_new = T(0);
    }
    const Vec3<T> s_new{{exp(eps_new[0]), exp(eps_new[1]), exp(eps_new[2])}};
    return State<T>{u_diag_vt(h.d.U, s_new, h.d.V), logJp_new};
  }

  /// F <- (I + dt C) F, then the return mapping.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> advance(const Params<T>& p, const State<T>& s, const Mat3<T>& C, T dt) {
    return return_map(p, advance_deformation_gradient(s.F, C, dt), s.logJp);
  }

  // kirchhoff_stress, wave_speed, energy_density: HenckyElastoplastic (the Hencky law of the elastic F).
};

}  // namespace fbar
