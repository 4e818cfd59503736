// APIC / MLS-MPM particle-grid transfers with quadratic B-splines (host and device formulas, no storage).
//
// Hu et al. 2018, "A moving least squares material point method with displacement discontinuity and two-way rigid
// body coupling" (MLS-MPM), with the APIC affine matrix C_p (Jiang et al. 2015). Per step (symplectic Euler):
//   P2G   m_i   += w_ip m_p
//         p_i   += w_ip [ m_p v_p + (m_p C_p - dt V_p^0 D_p^-1 tau_p) (x_i - x_p) ]
//                    (the second term inside the bracket is the MLS internal force impulse -dt f_i)
//   grid  v_i    = p_i / m_i + dt g, then boundary projections   (grid_update.cuh, boundary.cuh)
//   G2P   v_p    = sum_i w_ip v_i
//         C_p    = D_p^-1 sum_i w_ip v_i (x_i - x_p)^T
//         x_p   += dt v_p;   F_p <- (I + dt C_p) F_p  or  J_p <- (1 + dt tr C_p) J_p   (material advance())
// with D_p^-1 = 4 / dx^2 (bspline.h: apic_inertia_inverse), V_p^0 the reference particle volume and tau_p the
// Kirchhoff stress (materials). Units: m [kg], v [m/s], C [1/s], x [m], tau [Pa], V [m^3], dt [s].
//
// Conservation (exact in exact arithmetic, the tests check round-off): quadratic B-splines satisfy
// sum_i w_ip = 1 and sum_i w_ip (x_i - x_p) = 0, so P2G conserves mass and momentum and the internal force sums to
// zero; G2P conserves momentum (sum_p m_p v_p = sum_i m_i v_i).
#pragma once

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// What one particle deposits on its 27 nodes: node momentum = w (momentum + affine (x_i - x_p)), node mass = w mass.
template <typename T>
struct P2GParticle {
  T mass;            ///< [kg] m_p
  Vec3<T> momentum;  ///< [kg m/s] m_p v_p
  Mat3<T> affine;    ///< [kg/s] m_p C_p - dt V_p^0 D_p^-1 tau_p
};

/// The P2G payload of a particle (MLS-MPM: the stress enters as an affine term, no weight gradients needed).
/// d_inv = D_p^-1 = 4 / dx^2 [1/m^2].
template <typename T>
FBAR_HOST_DEVICE constexpr P2GParticle<T> mls_p2g_particle(T mass, T volume0, const Vec3<T>& velocity, const Mat3<T>& C,
                                                           const Mat3<T>& kirchhoff, T dt, T d_inv) {
  return P2GParticle<T>{mass, velocity * mass, C * mass - kirchhoff * (dt * volume0 * d_inv)};
}

/// Momentum a particle gives node i: w_ip (m v + A (x_i - x_p)) [kg m/s]; xixp = x_i - x_p [m].
template <typename T>
FBAR_HOST_DEVICE constexpr Vec3<T> p2g_node_momentum(const P2GParticle<T>& p, T w, const Vec3<T>& xixp) {
  return (p.momentum + p.affine * xixp) * w;
}

/// Bound b on every component of what a particle gives any of its 27 nodes, per unit weight:
/// |p2g_node_momentum(p, w, x_i - x_p)_k| <= w b for every k and node, since |x_i - x_p|_inf <= 1.5 dx on a
/// quadratic stencil: b = max_k (|momentum_k| + 1.5 dx sum_j |affine_kj|) [kg m/s]. The fixed-point P2G of the
/// GPU engine sizes its quantum from it (kernels/g2p2g_kernel.cuh).
template <typename T>
FBAR_HOST_DEVICE T p2g_momentum_bound(const P2GParticle<T>& p, T dx) {
  auto abs_of = [](T x) { return x < T(0) ? -x : x; };
  T b = T(0);
  for (int k = 0; k < 3; ++k) {
    const T row = abs_of(p.affine(k, 0)) + abs_of(p.affine(k, 1)) + abs_of(p.affine(k, 2));
    const T component = abs_of(p.momentum[k]) + T(1.5) * dx * row;
    b = b > component ? b : component;
  }
  return b;
}

/// Calls f(i, j, k, w, xixp) for the 27 nodes base + (i, j, k) of a stencil: w the 3D weight, xixp = x_i - x_p [m].
template <typename T, typename F>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void for_each_stencil_node(const QuadraticBspline<T>& s, T dx, F&& f) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const T wij = s.w[0][i] * s.w[1][j];
      for (int k = 0; k < 3; ++k) f(i, j, k, wij * s.w[2][k], s.node_offset(i, j, k, dx));
    }
}

/// Interpolated previous grid velocity sum_i w v_i^n (ASFLIP's v_old).
template <typename T>
struct G2POldSum {
  Vec3<T> v = Vec3<T>::zero();  ///< [m/s]
  FBAR_HOST_DEVICE constexpr void add(T w, const Vec3<T>& v_node_old) { v += v_node_old * w; }
};

/// G2P accumulator: add() every stencil node, then velocity() and affine().
template <typename T>
struct G2PSum {
  Vec3<T> v = Vec3<T>::zero();  ///< [m/s] sum_i w v_i
  Mat3<T> B = Mat3<T>::zero();  ///< [m^2/s] sum_i w v_i (x_i - x_p)^T

  FBAR_HOST_DEVICE constexpr void add(T w, const Vec3<T>& v_node, const Vec3<T>& xixp) {
    const Vec3<T> wv = v_node * w;
    v += wv;
    B += outer(wv, xixp);
  }
  FBAR_HOST_DEVICE constexpr Vec3<T> velocity() const { return v; }
  /// C_p = D_p^-1 B [1/s].
  FBAR_HOST_DEVICE constexpr Mat3<T> affine(T d_inv) const { return B * d_inv; }
};

/// PIC-FLIP blend and ASFLIP (Fei et al. 2021, "Revisiting integration in the material point method: a scheme for
/// easier separation and less dissipation"). With v_pic = sum_i w v_i^{n+1} (the APIC/PIC velocity, as above) and
/// v_old = sum_i w v_i^n, where v_i^n is the grid velocity the particles transported, before any force: in MLS-MPM the
/// P2G momentum p_i already holds the stress impulse, so v_i^n = sum_p w m_p (v_p + C_p (x_i - x_p)) / m_i is
/// accumulated apart (p_i / m_i would hide the elastic force from the FLIP increment v^{n+1} - v^n),
///   v_p^{n+1} = v_pic + alpha (v_p^n - v_old)                      (alpha = 1: FLIP, 0: APIC)
///   x_p^{n+1} = x_p^n + dt (v_pic + beta (v_p^n - v_old))           (beta = 0: the APIC position update)
/// beta = beta_max for a particle whose volume ratio J >= 1 (dilated: separating, splashing) and beta_min otherwise
/// (in contact), the switch of Fei et al. ClaymoreUW's keys: ASFLIP_alpha, ASFLIP_beta_min, ASFLIP_beta_max. The
/// affine C stays APIC's (from v^{n+1}), so alpha = beta = 0 is exactly APIC. Uniform motion is exact for every
/// alpha, beta: then v_p^n = v_old.
template <typename T>
struct AsflipParams {
  T alpha;     ///< [-] FLIP fraction of the velocity update, 0..1
  T beta_min;  ///< [-] position correction of compressed particles (J < 1), 0..1
  T beta_max;  ///< [-] position correction of dilated particles (J >= 1), 0..1
};

/// What ASFLIP gives a particle: its new velocity and its displacement this step.
template <typename T>
struct AsflipUpdate {
  Vec3<T> v;     ///< [m/s] v_p^{n+1}
  Vec3<T> move;  ///< [m] x_p^{n+1} - x_p^n
};

/// The ASFLIP particle update (above); J is the particle's volume ratio after the step.
template <typename T>
FBAR_HOST_DEVICE constexpr AsflipUpdate<T> asflip_update(const AsflipParams<T>& a, const Vec3<T>& v_particle,
                                                        const Vec3<T>& v_pic, const Vec3<T>& v_old, T J, T dt) {
  const Vec3<T> flip = v_particle - v_old;
  const T beta = J >= T(1) ? a.beta_max : a.beta_min;
  return AsflipUpdate<T>{v_pic + flip * a.alpha, (v_pic + flip * beta) * dt};
}

/// F-bar anti-locking by volume averaging over background cells (de Souza Neto et al. 1996's F-bar, with the cell as
/// the element, as Coombs et al. 2018, "Overcoming volumetric locking in material point methods", do). A nearly
/// incompressible material locks when every particle must keep its own volume: more volume constraints than the grid
/// has velocity degrees of freedom, and the pressure checkerboards. F-bar gives the particles of a grid cell one
/// volume ratio, the cell's current over its reference volume:
///   Jbar_c = sum_{q in c} V0_q J_q / sum_{q in c} V0_q           (cell c = floor(x_q / dx), at the start of the step)
/// and each step pulls every particle's J toward it by the fraction psi before its own volume rate acts:
///   J_p <- ((1 - psi) J_p + psi Jbar_c) (1 + dt tr C_p)           (psi = FBAR_psi: 0 off, 1 full F-bar)
/// The material takes this as the velocity gradient C'_p = C_p + kappa I (fbar_velocity_gradient below), so the state
/// update stays one code path for every law: JFluid's J <- (1 + dt tr C') J gives the line above exactly, F <-
/// (I + dt C') F to first order in dt, and the return mapping of a plastic law sees the averaged volume. The deviatoric
/// part of the motion is untouched, and the transfers keep C_p: mass, momentum and angular momentum are conserved as
/// without F-bar. A uniform J is left unchanged, and the cell's total volume sum V0 J changes as without F-bar.
/// Why the volume, not its rate: averaging the rate (J <- (1 + dt d_c) J, d_c the cell's mean tr C) locks as well,
/// but a particle's J then integrates other particles' rates along its path and stops measuring the space it fills:
/// in a 5 s piston-driven flume (FBAR_psi 0.96, 8 particles per cell at rest) the water's particles spread to 6.97 per
/// interior cell with J = 1 everywhere, against 7.97 with this form and 7.93 without F-bar (docs/validation.md,
/// "F-bar and the volume of a long free-surface flow"). Why cells, not nodes: averaging through the B-spline weights
/// leaves a two-cell pressure wave in a nearly incompressible block (tests/validation/test_fbar_locking.cpp measured
/// checkerboard 0.066 rho g H against 0.0008 per cell).
/// The cell sums ride in two grid channels (cell c at node c, the node at its lower corner), filled by a pass over the
/// particles between the grid update and G2P (CPU: fbar_cell_sums; GPU: the fbar_cell_sums kernel).

/// Offset of the cell holding x from the stencil base (each component 0 or 1: cell node = base + offset).
template <typename T>
FBAR_HOST_DEVICE inline Vec3i fbar_cell_offset(const Vec3<T>& x, T inv_dx, const Vec3i& base) {
  using std::floor;
  return Vec3i{{static_cast<int>(floor(x[0] * inv_dx)) - base[0], static_cast<int>(floor(x[1] * inv_dx)) - base[1],
                static_cast<int>(floor(x[2] * inv_dx)) - base[2]}};
}

/// The cell's mean of 1 - J, (sum V0 (1 - J)) / (sum V0) [-] (1 - Jbar_c, stored like JFluid's state for float
/// accuracy near J = 1); 0 for a cell without particles.
template <typename T>
FBAR_HOST_DEVICE constexpr T fbar_cell_compression(T compression_sum, T volume_sum) {
  return volume_sum > T(0) ? compression_sum / volume_sum : T(0);
}

/// C'_p = C_p + kappa I [1/s] with 1 + dt tr C'_p = ((1 - psi) J_p + psi Jbar_c)(1 + dt tr C_p) / J_p (above):
///   kappa = psi (Jbar_c - J_p) (1 + dt tr C_p) / (3 dt J_p),   Jbar_c - J_p = (1 - J_p) - (1 - Jbar_c).
/// one_minus_J: the particle's 1 - J at the start of the step; cell_compression: fbar_cell_compression of its cell.
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> fbar_velocity_gradient(const Mat3<T>& C, T one_minus_J, T cell_compression, T psi,
                                                          T dt) {
  const T trace_C = C(0, 0) + C(1, 1) + C(2, 2);
  const T kappa = psi * (one_minus_J - cell_compression) * (T(1) + dt * trace_C) / (T(3) * dt * (T(1) - one_minus_J));
  Mat3<T> out = C;
  out(0, 0) += kappa;
  out(1, 1) += kappa;
  out(2, 2) += kappa;
  return out;
}

/// x_p <- x_p + dt v_p (symplectic Euler: the new velocity moves the particle).
template <typename T>
FBAR_HOST_DEVICE constexpr Vec3<T> advect(const Vec3<T>& x, const Vec3<T>& v, T dt) {
  return x + v * dt;
}

/// Angular momentum of an APIC particle about the origin [kg m^2/s]: m x × v plus the affine spin
/// m (dx^2/4) eps_abc C_cb, what its P2G deposits as sum_i x_i × m_i v_i (Jiang et al. 2015).
template <typename T>
FBAR_HOST_DEVICE constexpr Vec3<T> apic_angular_momentum(T mass, const Vec3<T>& x, const Vec3<T>& v, const Mat3<T>& C,
                                                         T dx) {
  const T inertia = dx * dx / T(4);
  const Vec3<T> spin{{C(2, 1) - C(1, 2), C(0, 2) - C(2, 0), C(1, 0) - C(0, 1)}};
  return (cross(x, v) + spin * inertia) * mass;
}

}  // namespace fbar
