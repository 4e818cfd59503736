// FixedCorotated: the fixed corotated hyperelastic solid (Stomakhin et al. 2012), state = F (material header).
//
// First Piola-Kirchhoff stress P = 2 mu (F - R) + lambda (J - 1) J F^-T, with F = R S the polar decomposition
// (Library/MnBase/Math/svd.h, rotation-variant: inverted F gives J < 0 and a restoring stress). The Kirchhoff
// stress tau = P F^T is
//     tau = 2 mu (F - R) F^T + lambda (J - 1) J I,
// free of F^-T; (F - R) F^T = F F^T - R S R^T is symmetric, so the upper triangle is computed and mirrored.
// For J > 0 (every particle of a committed step: G2P2G fails a step whose J <= 0) R comes from Newton's polar
// iteration (polar_rotation: 3-4 cofactor steps for everyday strains, a third of svd()'s instructions), J - 1 from
// F - I without cancellation (determinant_minus_one). An inverted F, or one the iteration declines, takes the SVD
// F = U diag(s) V^T (R = U V^T): tau = U diag(2 mu (s_i - 1) s_i) U^T + lambda (J - 1) J I, J = s0 s1 s2.
// Uniaxial check (the constitutive patch test): F = diag(s, 1, 1) gives sigma = tau / J with
//     sigma11 = (lambda + 2 mu)(s - 1),  sigma22 = sigma33 = lambda (s - 1).
// Energy psi = mu sum_i (s_i - 1)^2 + lambda/2 (J - 1)^2 per reference volume.
// P-wave speed c_p = sqrt((lambda + 2 mu) / rho0) (not ClaymoreUW's sqrt(K/rho): docs/user_guide.md §7 item 1).
#pragma once

#include <cmath>

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

/// FixedCorotated parameters (trivially copyable; pass to kernels by value).
template <typename T>
struct FixedCorotatedParams {
  T rho0;    ///< [kg/m^3] reference density
  T mu;      ///< [Pa] shear modulus E / (2 (1 + nu))
  T lambda;  ///< [Pa] Lame's first parameter E nu / ((1 + nu)(1 - 2 nu))
};

/// Per-particle state of a FixedCorotated particle besides its position.
template <typename T>
struct FixedCorotatedState {
  Mat3<T> F;  ///< [-] deformation gradient
};

struct FixedCorotated {
  static constexpr const char* kJsonName = "FixedCorotated";
  static constexpr Constitutive kLaw = Constitutive::FixedCorotated;
  static constexpr MaterialParameter kParameters[] = {kYoungsModulusParameter, kPoissonRatioParameter};
  template <typename T>
  using Params = FixedCorotatedParams<T>;
  template <typename T>
  using State = FixedCorotatedState<T>;
  /// Scalars a particle stores: position (3) + F (9). Mass and volume are per body.
  static constexpr int kStoredScalars = 12;
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

  /// Kirchhoff stress tau = P F^T [Pa] (see the file comment); C is unused (no rate dependence).
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& /*C*/) {
    const T det_minus_1 = determinant_minus_one(s.F);
    if (det_minus_1 > T(-1)) {
      const PolarRotation<T> polar = polar_rotation(s.F);
      if (polar.converged) {
        const Mat3<T> D = s.F - polar.R;
        const T shear = T(2) * p.mu;
        const T volumetric = p.lambda * det_minus_1 * (T(1) + det_minus_1);
        Mat3<T> tau;
        for (int i = 0; i < 3; ++i)
          for (int j = i; j < 3; ++j)
            tau.m[i][j] = shear * (D.m[i][0] * s.F.m[j][0] + D.m[i][1] * s.F.m[j][1] + D.m[i][2] * s.F.m[j][2]) +
                          (i == j ? volumetric : T(0));
        tau.m[1][0] = tau.m[0][1];
        tau.m[2][0] = tau.m[0][2];
        tau.m[2][1] = tau.m[1][2];
        return StressResult<T>{tau, T(1) + det_minus_1};
      }
    }
    const Svd3<T> d = svd(s.F);
    const Vec3<T> sm1{{d.sigma[0] - T(1), d.sigma[1] - T(1), d.sigma[2] - T(1)}};
    const T J_minus_1 = product_minus_one(sm1[0], sm1[1], sm1[2]);
    const T J = T(1) + J_minus_1;
    const T shear = T(2) * p.mu;
    const Vec3<T> principal{{shear * sm1[0] * d.sigma[0], shear * sm1[1] * d.sigma[1], shear * sm1[2] * d.sigma[2]}};
    Mat3<T> tau = u_diag_vt(d.U, principal, d.U);
    const T volumetric = p.lambda * J_minus_1 * J;
    for (int i = 0; i < 3; ++i) tau.m[i][i] += volumetric;
    // Mirror the upper triangle: tau is symmetric in exact arithmetic, keep it so bit for bit.
    tau.m[1][0] = tau.m[0][1];
    tau.m[2][0] = tau.m[0][2];
    tau.m[2][1] = tau.m[1][2];
    return StressResult<T>{tau, J};
  }

  /// State after one step: F <- (I + dt C) F.
  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> advance(const Params<T>& /*p*/, const State<T>& s, const Mat3<T>& C,
                                                     T dt) {
    return State<T>{advance_deformation_gradient(s.F, C, dt)};
  }

  /// P-wave speed c_p = sqrt((lambda + 2 mu) / rho0) [m/s] (small-strain value, independent of the state).
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& /*s*/) {
    using std::sqrt;
    return sqrt((p.lambda + T(2) * p.mu) / p.rho0);
  }

  /// Stored energy per reference volume psi = mu sum (s_i - 1)^2 + lambda/2 (J - 1)^2 [J/m^3].
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    const Svd3<T> d = svd(s.F);
    const Vec3<T> sm1{{d.sigma[0] - T(1), d.sigma[1] - T(1), d.sigma[2] - T(1)}};
    const T J_minus_1 = product_minus_one(sm1[0], sm1[1], sm1[2]);
    return p.mu * dot(sm1, sm1) + T(0.5) * p.lambda * J_minus_1 * J_minus_1;
  }
};

}  // namespace fbar
