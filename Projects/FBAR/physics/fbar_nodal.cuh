// ClaymoreUW's F-bar (bodies[].algorithm.FBAR_scheme "nodal"): a second volume ratio JBar per particle, averaged
// through the grid nodes with the B-spline weights, host and device formulas (no storage). fbar's other scheme,
// averaging J per cell, is in transfer.cuh (FBAR_scheme "cell").
//
// ClaymoreUW (mgmpm_kernels.cuh, "Simple FBar") stores s = 1 - JBar per particle next to the law's own state and
// carries two grid channels, V = sum_p w_ip V_p and S = sum_p w_ip V_p s_p (V_p = V0 J_p the particle's current
// volume). Per step, with dJ = the particle's own volume increment over the step (1 + dt tr C for a law that stores
// J, det(I + dt C) for one that stores F) and s_own = 1 - J^n dJ its own new 1 - J:
//   fused (FBAR_fused_kernel true, ClaymoreUW's g2p2g_FBar): the nodes hold the previous step's sums; a node's value
//     is s_i = clamp(S_i / V_i, -0.9, 0.9) (0 without volume, mgmpm_kernels.cuh:1903-1905); the particle gathers
//     sbar = sum_i w_ip s_i, advances it by its own increment, sbar* = 1 - (1 - sbar) dJ, and blends:
//         s = (1 - psi) s_own + psi sbar*
//   split (false, ClaymoreUW's g2p_FBar then p2g_FBar): a first pass sums V_i = sum w V^n and S_i = sum w V^n
//     (1 - JBar_p dJ_p) (each particle's JBar advanced by its own increment); the second gathers
//     sbar = sum_i w_ip S_i / V_i (no clamp) and blends s = (1 - psi) s_own + psi sbar.
// The stress sees JBar = 1 - s: a law that keeps its own volume (M::kFbarKeepsOwnVolume: JFluid, FixedCorotated,
// NeoHookean, Hencky; ClaymoreUW's fluids and elastic solids) stores its own state and is stressed at the state
// dilated to JBar (fbar_stress_state: F (JBar / J)^(1/3), or 1 - J = s); any other law (the plastic ones: ClaymoreUW's
// Sand and NACC) stores the state advanced with the velocity gradient whose trial state has the volume JBar
// (nodal_fbar's C_state, I + dt C' = lambda (I + dt C), lambda = (JBar / J_trial)^(1/3)), so its return mapping sees
// the averaged volume. psi = 0 leaves every law as without F-bar.
#pragma once

#include <cmath>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/material_common.cuh"

namespace fbar {

/// ClaymoreUW's clamp of a node's 1 - JBar (mgmpm_kernels.cuh:1904: "standard limit for volumetric deformation").
inline constexpr double kFbarNodalLimit = 0.9;

template <class M, typename T>
using fbar_state_t = typename M::template State<T>;

/// True when law M keeps its own state under nodal F-bar (M::kFbarKeepsOwnVolume) and is only stressed at JBar.
template <class M, class = void>
struct FbarKeepsOwnVolume : std::false_type {};
template <class M>
struct FbarKeepsOwnVolume<M, std::void_t<decltype(M::kFbarKeepsOwnVolume)>>
    : std::bool_constant<M::kFbarKeepsOwnVolume> {};

/// det(I + H) - 1 for a small H (H = dt C) without forming I + H: tr H + the principal 2x2 minors + det H.
template <typename T>
FBAR_HOST_DEVICE constexpr T det_identity_plus_minus_one(const Mat3<T>& H) {
  const T m01 = H.m[0][0] * H.m[1][1] - H.m[0][1] * H.m[1][0];
  const T m02 = H.m[0][0] * H.m[2][2] - H.m[0][2] * H.m[2][0];
  const T m12 = H.m[1][1] * H.m[2][2] - H.m[1][2] * H.m[2][1];
  const T det_h = H.m[0][0] * m12 - H.m[0][1] * (H.m[1][0] * H.m[2][2] - H.m[1][2] * H.m[2][0]) +
                  H.m[0][2] * (H.m[1][0] * H.m[2][1] - H.m[1][1] * H.m[2][0]);
  return (H.m[0][0] + H.m[1][1] + H.m[2][2]) + (m01 + m02 + m12) + det_h;
}

/// dJ - 1 of law M over a step with velocity gradient C: dt tr C where the state stores J (J <- (1 + dt tr C) J),
/// det(I + dt C) - 1 where it stores F (F <- (I + dt C) F).
template <class M, typename T>
FBAR_HOST_DEVICE constexpr T fbar_volume_increment(const Mat3<T>& C, T dt) {
  if constexpr (StoresOneMinusJ<fbar_state_t<M, T>>::value)
    return dt * (C(0, 0) + C(1, 1) + C(2, 2));
  else
    return det_identity_plus_minus_one(C * dt);
}

/// 1 - (1 - s) dJ written on s and dJ - 1 (exact near s = 0, dJ = 1): s - (1 - s)(dJ - 1).
template <typename T>
FBAR_HOST_DEVICE constexpr T fbar_advance_one_minus_J(T s, T dJ_minus_one) {
  return s - (T(1) - s) * dJ_minus_one;
}

/// A node's 1 - JBar from its sums S = sum w V s and V = sum w V (0 without volume); fused: clamped to +-0.9.
template <typename T>
FBAR_HOST_DEVICE constexpr T fbar_node_value(T volume_jbar_sum, T volume_sum, bool fused) {
  if (!(volume_sum > T(0))) return T(0);
  const T s = volume_jbar_sum / volume_sum;
  if (!fused) return s;
  const T limit = static_cast<T>(kFbarNodalLimit);
  return s > limit ? limit : (s < -limit ? -limit : s);
}

/// One particle's nodal F-bar for the step: its new s = 1 - JBar (stored) and the velocity gradient its state is
/// advanced with (C itself for a law that keeps its own volume).
template <typename T>
struct NodalFbar {
  T s;              ///< [-] 1 - JBar after the step
  Mat3<T> C_state;  ///< [1/s] the gradient M::advance takes
};

/// The step of nodal F-bar for a particle of law M in state `state` (at the start of the step) with velocity gradient
/// C: gathered = sum_i w_ip s_i (fused: the nodes' clamped values, advanced here by the particle's own increment) or
/// sum_i w_ip S_i / V_i (split: already advanced); psi the blend (FBAR_psi).
template <class M, typename T>
FBAR_HOST_DEVICE inline NodalFbar<T> nodal_fbar(const fbar_state_t<M, T>& state, const Mat3<T>& C, T gathered,
                                                bool fused, T psi, T dt) {
  using std::cbrt;
  const T dJ1 = fbar_volume_increment<M>(C, dt);
  const T s_n = one_minus_volume_ratio<M>(state);
  const T s_own = fbar_advance_one_minus_J(s_n, dJ1);
  const T s_avg = fused ? fbar_advance_one_minus_J(gathered, dJ1) : gathered;
  const T s = (T(1) - psi) * s_own + psi * s_avg;
  NodalFbar<T> out{s, C};
  if constexpr (!FbarKeepsOwnVolume<M>::value) {
    if constexpr (StoresOneMinusJ<fbar_state_t<M, T>>::value) {
      // J' = J^n (1 + dt tr C') = 1 - s: C' = C + kappa I, kappa = (s_own - s) / (3 dt J^n).
      const T kappa = (s_own - s) / (T(3) * dt * (T(1) - s_n));
      for (int a = 0; a < 3; ++a) out.C_state(a, a) += kappa;
    } else {
      // I + dt C' = lambda (I + dt C): the trial F is lambda F_trial, det = JBar.
      const T lambda = cbrt((T(1) - s) / (T(1) - s_own));
      out.C_state = C * lambda;
      const T shift = (lambda - T(1)) / dt;
      for (int a = 0; a < 3; ++a) out.C_state(a, a) += shift;
    }
  }
  return out;
}

/// The state law M is stressed at under nodal F-bar: a law that keeps its own volume, dilated to JBar = 1 - s
/// (1 - J set to s, within the law's own limits: JFluid's tension cutoff; F scaled by (JBar / J)^(1/3), as
/// ClaymoreUW's J_Scale); any other law, its stored state.
template <class M, typename T>
FBAR_HOST_DEVICE inline fbar_state_t<M, T> fbar_stress_state(const typename M::template Params<T>& params,
                                                            const fbar_state_t<M, T>& state, T s) {
  using std::cbrt;
  fbar_state_t<M, T> out = state;
  if constexpr (FbarKeepsOwnVolume<M>::value) {
    if constexpr (StoresOneMinusJ<fbar_state_t<M, T>>::value) {
      out.one_minus_J = s;
      out = M::advance(params, out, Mat3<T>::zero(), T(1));  // no motion: only the law's limits act
    } else {
      const T scale = cbrt((T(1) - s) / M::volume_ratio(state));
      out.F = state.F * scale;
    }
  }
  return out;
}

}  // namespace fbar
