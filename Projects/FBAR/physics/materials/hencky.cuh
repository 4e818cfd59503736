// Hencky: isotropic hyperelasticity in logarithmic (Hencky) strain, state = F (material header). The worked example
// of docs/developer_guide.md, "Adding a material": tests/physics/test_material_guide.cpp checks that every code block
// the guide shows is this file's text, so the guide and the code cannot drift apart.
//
// With the SVD F = U diag(s) V^T and the principal Hencky strains e_i = log s_i, the Kirchhoff stress is
//     tau = U diag(2 mu e_i + lambda (e_0 + e_1 + e_2)) U^T,
// Hooke's law in logarithmic strain: the same constants as linear elasticity, exact for small strains, objective
// for large rotations, and tau -> -inf as s_i -> 0 (a particle resists being crushed to zero volume, unlike
// St Venant-Kirchhoff). Energy psi = mu sum_i e_i^2 + lambda/2 (sum_i e_i)^2 per reference volume.
// Uniaxial check: F = diag(s, 1, 1) gives tau_11 = (lambda + 2 mu) log s, tau_22 = tau_33 = lambda log s.
// An inverted F (s_i <= 0: the SVD is rotation-variant, svd.h) has no logarithm; e_i uses max(s_i, 1e-4), the
// floor DruckerPrager uses, so the stress stays finite and strongly restoring.
#pragma once

#include <cmath>

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

/// Hencky parameters (trivially copyable; pass to kernels by value).
template <typename T>
struct HenckyParams {
  T rho0;    ///< [kg/m^3] reference density
  T mu;      ///< [Pa] shear modulus E / (2 (1 + nu))
  T lambda;  ///< [Pa] Lame's first parameter E nu / ((1 + nu)(1 - 2 nu))
};

/// Per-particle state of a Hencky particle besides its position.
template <typename T>
struct HenckyState {
  Mat3<T> F;  ///< [-] deformation gradient
};

struct Hencky {
  static constexpr const char* kJsonName = "Hencky";
  static constexpr const char* kAliases[] = {"HenckyElastic"};
  static constexpr Constitutive kLaw = Constitutive::Hencky;
  static constexpr MaterialParameter kParameters[] = {kYoungsModulusParameter, kPoissonRatioParameter};
  template <typename T>
  using Params = HenckyParams<T>;
  template <typename T>
  using State = HenckyState<T>;
  /// Scalars a particle stores: position (3) + F (9).
  static constexpr int kStoredScalars = 12;
  /// Outputs besides the common ones (J, stress, pressure): DefGrad_*, no logJp.
  static constexpr MaterialOutputs kOutputs{true, false};
  /// Nodal F-bar (physics/fbar_nodal.cuh): the particle keeps its own volume; only the stress sees JBar.
  static constexpr bool kFbarKeepsOwnVolume = true;

  /// Lame parameters from Young's modulus and Poisson's ratio (material_common.cuh), host only.
  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    const LameParameters l = lame_parameters(m.youngs_modulus, m.poisson_ratio);
    return Params<T>{static_cast<T>(m.rho), static_cast<T>(l.mu), static_cast<T>(l.lambda)};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> reference_state() {
    return State<T>{Mat3<T>::identity()};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr T volume_ratio(const State<T>& s) {
    return determinant(s.F);
  }

  /// Principal Hencky strains e_i = log max(s_i, 1e-4) of F = U diag(s) V^T.
  template <typename T>
  FBAR_HOST_DEVICE static inline Vec3<T> principal_strains(const Svd3<T>& d) {
    using std::log;
    const T floor = T(1e-4);
    return Vec3<T>{{log(d.sigma[0] > floor ? d.sigma[0] : floor), log(d.sigma[1] > floor ? d.sigma[1] : floor),
                    log(d.sigma[2] > floor ? d.sigma[2] : floor)}};
  }

  /// Kirchhoff stress tau = U diag(2 mu e_i + lambda tr e) U^T [Pa]; C is unused (no rate dependence).
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& /*C*/) {
    const Svd3<T> d = svd(s.F);
    const Vec3<T> e = principal_strains(d);
    const T volumetric = p.lambda * (e[0] + e[1] + e[2]);
    const T shear = T(2) * p.mu;
    const Vec3<T> principal{{shear * e[0] + volumetric, shear * e[1] + volumetric, shear * e[2] + volumetric}};
    Mat3<T> tau = u_diag_vt(d.U, principal, d.U);
    tau.m[1][0] = tau.m[0][1];  // symmetric bit for bit
    tau.m[2][0] = tau.m[0][2];
    tau.m[2][1] = tau.m[1][2];
    return StressResult<T>{tau, d.sigma[0] * d.sigma[1] * d.sigma[2]};
  }

  /// State after one step: F <- (I + dt C) F (elastic: no return mapping).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> advance(const Params<T>& /*p*/, const State<T>& s, const Mat3<T>& C,
                                                     T dt) {
    return State<T>{advance_deformation_gradient(s.F, C, dt)};
  }

  /// P-wave speed c_p = sqrt((lambda + 2 mu) / rho0) [m/s] at small strain.
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& /*s*/) {
    using std::sqrt;
    return sqrt((p.lambda + T(2) * p.mu) / p.rho0);
  }

  /// Stored energy per reference volume psi = mu sum e_i^2 + lambda/2 (sum e_i)^2 [J/m^3].
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    const Vec3<T> e = principal_strains(svd(s.F));
    const T tr = e[0] + e[1] + e[2];
    return p.mu * dot(e, e) + T(0.5) * p.lambda * tr * tr;
  }
};

}  // namespace fbar
