// Seepage through the grid: the pore water of saturated bodies (CoupledUP, physics/materials/coupled_up.cuh) between
// particles, host and device (both engines call these functions).
//
// The storage equation (1/M) dp/dt = -alpha div v - div q is split: the law's advance() takes -alpha M tr C on the
// particle; the grid carries the flux part in its weak form, the Galerkin form on the particles' quadrature. What
// travels is the piezometric pressure h = p - rhow g . x (p plus the weight of water above a datum; constant in water
// at rest, so that hydrostatic pore water, whose p grows by rhow |g| per metre, stays exactly at rest), with Darcy
// q = -kappa grad h:
//   P2G      V_i = sum_p w_ip V_p,  H_i = sum_p w_ip V_p (h_p + grad h_p . (x_i - x_p)),  R_i = sum_p V_p q_p . grad w_ip,
//            W_i = sum_p w_ip m_w,p,  D_i = sum_p w_ip V_p rhow_p
//            (V_p = V0_p J_p the particle's volume, q_p its Darcy flux, grad h_p = -q_p / kappa, m_w,p = n rhow V0_p
//            its water; grad w_ip is MLS-MPM's w_ip D^-1 (x_i - x_p), D^-1 = 4 / dx^2, the gradient the stress
//            force uses)
//   grid     h_i = H_i / V_i,  r_i = R_i / V_i  (the node's -div q [1/s], the rate its water comes in per volume)
//   G2P      p_p = sum_i w_ip h_i + rhow g . x_p + dt M sum_i w_ip r_i (+ advance()'s undrained change);
//            grad h_p = sum_i w_ip D^-1 (x_i - x_p) h_i;  q_p = -kappa grad h_p, deposited by the next P2G.
// The pressure goes to the grid and back whole, with its gradient, as APIC carries velocity: a linear h crosses
// unchanged, and pressure differences the grid cannot see (two particle rows of one cell) do not survive. Carried as
// increments instead (FLIP), such differences, which a drained surface and the walls' velocity gradients create,
// never decay: on Terzaghi's column at dx = H / 32 they held the pore pressure 2-3 cells under the surface at 4 times
// the series solution (docs/validation.md). The weak form's natural boundary is impermeable: walls, floors and beds
// hold the water with nothing to do. A free surface drains: a node that holds less than kDrainedFraction of a full
// node's volume (dx^3) and that no boundary holds is drained, p_i = 0 there (h_i = -rhow_i g . x_i, rhow_i =
// D_i / V_i). A soil surface on a node plane has half a node's volume on that plane (a drained plane) and 98 % one
// plane below (solved): the surface is drained where the soil ends. The flux of step n reads h_i of step n and reaches
// the particles one step later (the fused G2P2G kernel's order; both engines): explicit, stable while
// dt M kappa lambda_max < 1 (seepage_time_step, physics/time_step.cuh). An undrained body (Kperm = 0) exchanges
// nothing.
#pragma once

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// A node holding less than this fraction of dx^3 of saturated volume, and held by no boundary, is drained (p = 0).
inline constexpr double kDrainedFraction = 0.75;

/// What one saturated particle adds to a node's five seepage channels (`head` given with its gradient term).
template <typename T>
struct SeepageDeposit {
  T volume;   ///< [m^3] w V
  T head;     ///< [Pa m^3] w V h
  T inflow;   ///< [m^3/s] V q . grad w
  T water;    ///< [kg] w m_w
  T density;  ///< [kg] w V rhow
};
/// `head` h = p - rhow g . x [Pa], `flux` q [m/s], `water_mass` n rhow V0 [kg], `rhow` [kg/m^3].
template <typename T>
FBAR_HOST_DEVICE constexpr SeepageDeposit<T> seepage_deposit(T w, const Vec3<T>& xixp, T d_inv, T volume, T head,
                                                             const Vec3<T>& flux, T water_mass, T rhow) {
  return SeepageDeposit<T>{w * volume, w * volume * head, volume * w * d_inv * dot(flux, xixp), w * water_mass,
                           w * volume * rhow};
}

/// A node's seepage values after the grid update: h_i (-rhow_i g . x_i when drained), r_i (0 when drained) and its
/// pore pressure p_i = h_i + rhow_i g . x_i (0 when drained).
template <typename T>
struct SeepageNode {
  T head;      ///< [Pa]
  T inflow;    ///< [1/s]
  T pressure;  ///< [Pa]
};
/// The sums of one node (V_i, H_i, R_i, D_i) at x_node, gravity g; `held()`: whether some boundary acts on the node
/// (its walls hold the water: never drained), asked only of a node short of soil; `full_volume` = dx^3.
template <typename T, typename Held>
FBAR_HOST_DEVICE inline SeepageNode<T> seepage_node(T volume, T head_volume, T inflow_volume, T density_volume,
                                                    const Vec3<T>& x_node, const Vec3<T>& gravity, Held&& held,
                                                    T full_volume) {
  if (!(volume > T(0))) return SeepageNode<T>{T(0), T(0), T(0)};
  const T weight = density_volume / volume * dot(gravity, x_node);  // rhow_i g . x_i = h - p at the node
  if (volume < T(kDrainedFraction) * full_volume && !held()) return SeepageNode<T>{-weight, T(0), T(0)};
  const T h = head_volume / volume;
  return SeepageNode<T>{h, inflow_volume / volume, h + weight};
}

/// G2P accumulator of a saturated particle: add() every stencil node (weight w, x_i - x_p, the node's h_i and r_i).
template <typename T>
struct SeepageSum {
  T inflow = T(0);                     ///< [1/s] sum w r_i
  T head = T(0);                       ///< [Pa] sum w h_i
  Vec3<T> gradient = Vec3<T>::zero();  ///< [Pa m] sum w (x_i - x_p) h_i (head_gradient() applies D^-1)
  FBAR_HOST_DEVICE constexpr void add(T w, const Vec3<T>& xixp, T node_head, T inflow_rate) {
    inflow += w * inflow_rate;
    head += w * node_head;
    gradient += xixp * (w * node_head);
  }
  /// grad h = D^-1 sum w (x_i - x_p) h_i [Pa/m].
  FBAR_HOST_DEVICE constexpr Vec3<T> head_gradient(T d_inv) const { return gradient * d_inv; }
};

}  // namespace fbar
