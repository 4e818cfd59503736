// VonMises: J2 (von Mises) elastoplasticity in Hencky strain with linear isotropic hardening, state = elastic F and
// the accumulated equivalent plastic strain (metals, ice, clay in undrained loading; ClaymoreUW's "VonMises", whose
// header calls it "not validated, quick hack": this is a radial return, validated against closed forms in
// tests/physics/test_plasticity.cpp).
//
// Elasticity is the Hencky law's (materials/hencky.cuh): with F_e = U diag(s) V^T and eps_i = ln s_i,
//     tau = U diag(2 mu eps_i + lambda tr eps) U^T                                         (Kirchhoff stress)
// Yield on the Kirchhoff stress (Simo 1992; = Cauchy x J, and J = det F_e stays near 1 because plastic flow is
// isochoric), with q = sqrt(3/2) |dev tau| = 2 mu sqrt(3/2) |dev eps|:
//     f = q - (sigma_y + H eps_p) <= 0,   sigma_y = tensile_yield_strength, H = hardening_modulus.
// Return mapping (exact in principal log strain, Simo 1992 / de Souza Neto et al. 2008 sec. 14.5): when the trial
// state has f > 0,
//     dgamma = f / (3 mu + H),   dev eps <- (1 - 3 mu dgamma / q) dev eps,   tr eps unchanged,   eps_p += dgamma,
// which lands on the hardened surface q = sigma_y + H eps_p exactly, along the trial deviator (radial return).
// Closed forms it meets (H = 0 is perfect plasticity): uniaxial stress tau11 = (sigma_y + H e11) / (1 + H / E) after
// yield (e11 the total log strain), pure shear tau12 = sigma_y / sqrt(3) (the shear yield stress).
// Singular values below 1e-4 are clamped before the logarithm (as DruckerPrager), so an inverted or collapsed
// particle has a finite strain, and the returned F_e = U diag(exp eps) V^T is never inverted.
#pragma once

#include <cmath>

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/drucker_prager.cuh"
#include "physics/materials/fixed_corotated.cuh"
#include "physics/materials/hencky.cuh"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

template <typename T>
struct VonMisesParams {
  T rho0;          ///< [kg/m^3]
  T mu;            ///< [Pa] shear modulus
  T lambda;        ///< [Pa] Lame's first parameter
  T yield_stress;  ///< [Pa] initial yield stress in uniaxial tension sigma_y
  T hardening;     ///< [Pa] linear isotropic hardening modulus H (0: perfectly plastic)
};

/// Per-particle state besides the position.
template <typename T>
struct VonMisesState {
  Mat3<T> F;  ///< [-] elastic deformation gradient
  T eps_p;    ///< [-] accumulated equivalent plastic strain (the hardening variable)
};

struct VonMises : HenckyElastoplastic<VonMisesParams, VonMisesState> {
  static constexpr const char* kJsonName = "VonMises";
  static constexpr Constitutive kLaw = Constitutive::VonMises;
  static constexpr const char* kAliases[] = {"Von_Mises", "Von-Mises", "Von Mises"};
  static constexpr MaterialParameter kParameters[] = {
      kYoungsModulusParameter,
      kPoissonRatioParameter,
      number_parameter("tensile_yield_strength", "Pa", &MaterialSpec::tensile_yield_strength, kPositiveValue, 1.0,
                       "initial yield stress in uniaxial tension sigma_y (von Mises: shear yield sigma_y / sqrt 3)"),
      number_parameter("hardening_modulus", "Pa", &MaterialSpec::hardening_modulus, kNonNegativeValue, 1.0,
                       "linear isotropic hardening H: the yield stress is sigma_y + H eps_p (0: perfectly plastic)"),
  };
  template <typename T>
  using Params = VonMisesParams<T>;
  template <typename T>
  using State = VonMisesState<T>;
  static constexpr int kStoredScalars = 13;  ///< position (3) + F (9) + eps_p
  /// DefGrad_* (the elastic F) besides the common outputs; no logJp.
  static constexpr MaterialOutputs kOutputs{true, false};

  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    const auto e = FixedCorotated::make_params<T>(m);
    return Params<T>{e.rho0, e.mu, e.lambda, static_cast<T>(m.tensile_yield_strength),
                     static_cast<T>(m.hardening_modulus)};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> reference_state() {
    return State<T>{Mat3<T>::identity(), T(0)};
  }
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T volume_ratio(const State<T>& s) {
    return determinant(s.F);
  }

  /// The radial return (file comment) of the elastic trial F_trial from the hardening state eps_p.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> return_map(const Params<T>& p, const Mat3<T>& F_trial, T eps_p) {
    using std::exp;
    using std::sqrt;
    const HenckyPrincipal<T> h = hencky_principal(F_trial);
    const T mean = (h.eps[0] + h.eps[1] + h.eps[2]) / T(3);
    const Vec3<T> dev{{h.eps[0] - mean, h.eps[1] - mean, h.eps[2] - mean}};
    const T q = T(2) * p.mu * sqrt(T(1.5) * dot(dev, dev));
    const T f = q - (p.yield_stress + p.hardening * eps_p);
    if (!(f > T(0))) return State<T>{F_trial, eps_p};  // elastic (also q = 0)
    const T dgamma = f / (T(3) * p.mu + p.hardening);
    const T keep = T(1) - T(3) * p.mu * dgamma / q;  // in (0, 1): f < q
    const Vec3<T> s_new{{exp(mean + keep * dev[0]), exp(mean + keep * dev[1]), exp(mean + keep * dev[2])}};
    return State<T>{u_diag_vt(h.d.U, s_new, h.d.V), eps_p + dgamma};
  }

  /// F <- (I + dt C) F, then the return mapping.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> advance(const Params<T>& p, const State<T>& s, const Mat3<T>& C, T dt) {
    return return_map(p, advance_deformation_gradient(s.F, C, dt), s.eps_p);
  }

  // kirchhoff_stress, wave_speed, energy_density: HenckyElastoplastic (the Hencky law of the elastic F).
};

}  // namespace fbar
