// The explicit time-step bounds (docs/user_guide.md, "What --check prints"): dt = min(default_dt, every viscous body's viscous bound,
// min_b min(CFL_b dx / (c_b + |v|max), kAcousticCourant dx / c_b)).
//
// The acoustic cap. A particle alone in its grid cells (a splash droplet, the tip of a jet) is the stiffest
// oscillator MLS-MPM has: its nodes carry only its own mass, so a step moves its velocity gradient by
// dC = (4 / dx^2)(tau / rho) dt, and its volume mode oscillates at omega = 2 sqrt(3) c / dx (the elasticity's largest
// eigenvalue, 3 lambda + 2 mu <= 3 rho c^2, over rho; c the p-wave or sound speed). Explicit steps are stable only
// for omega dt < 2, that is c dt / dx < 1 / sqrt(3) = 0.577 in 3D, whatever the flow does elsewhere. A body's CFL
// number may be up to 1 (ClaymoreUW's range), and the bulk of a flow is stable there, but lone particles are not: the
// stability map (docs/validation.md) measured silent blow-ups of lone particles from CFL 0.75 on (their
// energy grew by 1e5 over a thousand steps before J <= 0 stopped the run). So the acoustic part of every step stays
// at c dt / dx <= 0.5, below the lone particle's limit, and a CFL above 0.5 only lengthens steps that advection,
// not sound, limits.
#pragma once

#include <limits>

#include "MnBase/Meta/config.h"

namespace fbar {

/// The largest acoustic Courant number c dt / dx of any step (see the file comment: a lone particle's limit is
/// 1 / sqrt(3)).
inline constexpr double kAcousticCourant = 0.5;

/// One body's CFL bound min(CFL dx / (c + |v|max), kAcousticCourant dx / c) [s]: cfl (0, 1], dx [m], wave_speed c
/// [m/s] (solid p-wave speed sqrt((lambda + 2 mu)/rho), fluid sound speed), max_speed [m/s] the largest grid
/// velocity magnitude.
template <typename T>
FBAR_HOST_DEVICE constexpr T cfl_time_step(T cfl, T dx, T wave_speed, T max_speed) {
  const T flow = cfl * dx / (wave_speed + max_speed);
  const T acoustic = T(kAcousticCourant) * dx / wave_speed;  // +inf for c = 0
  return acoustic < flow ? acoustic : flow;
}

/// Divisor k of the explicit viscous bound dt <= CFL rho dx^2 / (k mu). Measured on the CPU engine (a JFluid cube
/// thrown into Separable walls, dx 0.02 m, K 2e5 Pa, mu 1e4 Pa s, APIC, 8 ppc): stable at dt = 0.40 dx^2 / nu,
/// unstable (velocities grow and the CFL step collapses) at 0.45 dx^2 / nu; k = 3 puts CFL 1 at 0.33 dx^2 / nu and
/// the usual CFL 0.5 at 0.17 dx^2 / nu. A finite-difference Laplacian would allow dx^2 / (6 nu) in 3D.
inline constexpr double kViscousBoundDivisor = 3.0;

/// One body's explicit viscous bound CFL rho dx^2 / (k mu) [s]; +infinity for an inviscid body (mu = 0).
inline double viscous_time_step(double cfl, double dx, double rho, double viscosity) {
  return viscosity > 0.0 ? cfl * rho * dx * dx / (kViscousBoundDivisor * viscosity)
                         : std::numeric_limits<double>::infinity();
}

/// Divisor k of the explicit seepage bound dt <= CFL dx^2 / (k kappa M) (saturated bodies, seepage.cuh). The grid's
/// seepage operator (the Galerkin Laplacian with MLS-MPM's gradient on the particles, lumped by the node volumes)
/// has its largest eigenvalue at 2.4 / dx^2 per axis (computed for 2, 3 and 4 particles per cell in 1D: 2.40, 2.39,
/// 2.37), 7.2 / dx^2 in 3D; its flux reaches the particles one step late, which is stable for dt kappa M lambda < 1
/// (half forward Euler's 2). k = 8 keeps CFL 1 inside that and CFL 0.5 at half of it.
inline constexpr double kSeepageBoundDivisor = 8.0;

/// One saturated body's explicit seepage bound CFL dx^2 / (k kappa M) [s] (kappa M the seepage diffusivity,
/// CoupledUP::seepage_diffusivity); +infinity for an undrained body (Kperm = 0).
inline double seepage_time_step(double cfl, double dx, double diffusivity) {
  return diffusivity > 0.0 ? cfl * dx * dx / (kSeepageBoundDivisor * diffusivity)
                           : std::numeric_limits<double>::infinity();
}

/// min(a, b) for step bounds (a NaN bound never wins).
template <typename T>
FBAR_HOST_DEVICE constexpr T min_time_step(T a, T b) {
  return b < a ? b : a;
}

}  // namespace fbar
