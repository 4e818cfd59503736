// NeoHookean: the compressible Neo-Hookean hyperelastic solid (ClaymoreUW's law), state = F (material header).
//
// Energy per reference volume psi = mu/2 (tr(F^T F) - 3) - mu ln J + lambda/2 (ln J)^2, J = det F, so
//     P   = mu (F - F^-T) + lambda ln J F^-T        (the constitutive patch test)
//     tau = P F^T = mu (F F^T - I) + lambda ln J I  (symmetric, no inverse needed).
// Uniaxial check: F = diag(s, 1, 1), sigma = tau / J: sigma11 = mu (s - 1/s) + lambda ln(s) / s,
// sigma22 = sigma33 = lambda ln(s) / s. ln J is undefined for an inverted element (J <= 0): the stress is then
// NaN, which both engines report as a non-finite particle (body, step, time) instead of running on.
// P-wave speed c_p = sqrt((lambda + 2 mu) / rho0) (the small-strain value, as for FixedCorotated).
#pragma once

#include <cmath>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/fixed_corotated.cuh"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

struct NeoHookean {
  static constexpr const char* kJsonName = "NeoHookean";
  static constexpr Constitutive kLaw = Constitutive::NeoHookean;
  static constexpr MaterialParameter kParameters[] = {kYoungsModulusParameter, kPoissonRatioParameter};
  /// Same parameters (rho0, mu, lambda from E and nu) and the same state (F) as FixedCorotated.
  template <typename T>
  using Params = FixedCorotatedParams<T>;
  template <typename T>
  using State = FixedCorotatedState<T>;
  static constexpr int kStoredScalars = 12;  ///< position (3) + F (9)
  static constexpr MaterialOutputs kOutputs{true, false};
  /// Nodal F-bar (physics/fbar_nodal.cuh): the particle keeps its own volume; only the stress sees JBar.
  static constexpr bool kFbarKeepsOwnVolume = true;

  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    return FixedCorotated::make_params<T>(m);
  }

  // Reference state, J, the F update and the p-wave speed are FixedCorotated's (same state, same parameters).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> reference_state() {
    return FixedCorotated::reference_state<T>();
  }
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T volume_ratio(const State<T>& s) {
    return FixedCorotated::volume_ratio(s);
  }

  /// Kirchhoff stress tau = mu (F F^T - I) + lambda ln J I [Pa]; C is unused (no rate dependence).
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& /*C*/) {
    using std::log;
    const T J = determinant(s.F);
    const T volumetric = p.lambda * log(J);  // NaN for J <= 0: reported by the engines' finiteness checks
    Mat3<T> tau = s.F * transpose(s.F);
    for (int i = 0; i < 3; ++i)
      for (int j = i; j < 3; ++j) tau.m[i][j] = p.mu * (tau.m[i][j] - (i == j ? T(1) : T(0)));
    for (int i = 0; i < 3; ++i) tau.m[i][i] += volumetric;
    tau.m[1][0] = tau.m[0][1];
    tau.m[2][0] = tau.m[0][2];
    tau.m[2][1] = tau.m[1][2];
    return StressResult<T>{tau, J};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> advance(const Params<T>& p, const State<T>& s, const Mat3<T>& C,
                                                     T dt) {
    return FixedCorotated::advance(p, s, C, dt);
  }
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& s) {
    return FixedCorotated::wave_speed(p, s);
  }

  /// psi = mu/2 (tr(F^T F) - 3) - mu ln J + lambda/2 (ln J)^2 [J/m^3].
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    using std::log;
    T trace = T(0);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) trace += s.F.m[i][j] * s.F.m[i][j];
    const T lnJ = log(determinant(s.F));
    return T(0.5) * p.mu * (trace - T(3)) - p.mu * lnJ + T(0.5) * p.lambda * lnJ * lnJ;
  }
};

}  // namespace fbar
