// CoupledUP: saturated soil, Biot's u-p mixture with a DruckerPrager skeleton. State = F, logJp, the pore pressure p
// and the head gradient whose Darcy flux the engines' seepage channels carry.
//
// Mixture (Zienkiewicz's u-p form, the pore water's acceleration relative to the skeleton neglected):
//   total stress        sigma = sigma'(F_e) - alpha p I          (sigma' the DruckerPrager law of drucker_prager.cuh,
//                                                                 Kirchhoff tau = tau' - alpha J p I)
//   momentum            rho dv/dt = div sigma + rho g            (rho = the body's rho: the saturated density)
//   pore water storage  (1/M) dp/dt = -alpha div v - div q,      1/M = n / Kf + (alpha - n) / Ks (Biot modulus M)
//   Darcy               q = -kappa grad (p - rhow g . x),        kappa = Kperm / (rhow g0), g0 = 9.80665 m/s^2
// with n = poro, alpha = alpha1 (Biot coefficient), Kf and Ks the bulk moduli of the water and of the grains, Kperm
// the hydraulic conductivity [m/s] (the unit soil tests give; kappa is the permeability over the water's
// viscosity). p is the pore water's whole pressure (compression positive): at rest it is hydrostatic, rhow g depth
// below the water table, and q = 0.
//
// Split of the storage equation between the law and the engines:
//   * advance() (here, per particle): the undrained part, p <- p - dt alpha M tr C, and the skeleton's return
//     mapping (DruckerPrager::advance). Kperm = 0 is the undrained limit: Skempton's B follows from Kf, Ks, n.
//   * seep() (called by the engines after advance): the seepage part. The engines' grid carries each node's
//     volume-weighted piezometric pressure h_i (h = p - rhow g . x) and the inflow rate r_i = sum_p V_p q_p .
//     grad w_ip / sum_p w_ip V_p (the weak form of -div q, whose natural boundary is impermeable); the particle adds
//     dt M sum_i w_ip r_i to the grid's pressure at its place (drained nodes, at the free surface, hold p = 0) and
//     reads grad h = sum_i h_i grad w_ip for its next flux (physics/seepage.cuh, docs/user_guide.md §2.4 "Saturated
//     soil").
// The particle keeps grad h of its last step (the flux q = -kappa grad h follows from it: seepage()).
// The time step is bounded by the seepage's explicit limit too (seepage_time_step, physics/time_step.cuh).
#pragma once

#include <cmath>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/drucker_prager.cuh"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

/// Standard gravity [m/s^2]: hydraulic conductivities are measured under it (Kperm = kappa rhow g0).
inline constexpr double kStandardGravity = 9.80665;


template <typename T>
struct CoupledUPParams {
  DruckerPragerParams<T> skeleton;  ///< the effective-stress law (rho0 is the mixture's density)
  T biot;                           ///< [-] Biot coefficient alpha
  T biot_modulus;                   ///< [Pa] M, 1/M = n/Kf + (alpha - n)/Ks
  T conductivity;                   ///< [m^2/(Pa s)] kappa = Kperm / (rhow g0)
  T rhow;                           ///< [kg/m^3] pore water density
  T porosity;                       ///< [-] n
};

/// What a saturated particle stores besides its position.
template <typename T>
struct PoroPlasticState {
  Mat3<T> F;          ///< [-] the skeleton's elastic deformation gradient
  T logJp;            ///< [-] DruckerPrager's remembered dilation
  T pore_pressure;    ///< [Pa] p, compression positive
  Vec3<T> head_gradient;  ///< [Pa/m] grad h = grad (p - rhow g . x) of the last step (the next P2G deposits it)
};

struct CoupledUP {
  static constexpr const char* kJsonName = "CoupledUP";
  static constexpr Constitutive kLaw = Constitutive::CoupledUP;
  // ClaymoreUW's spellings; folded matching makes "UP" and "up" one.
  static constexpr const char* kAliases[] = {"coupled", "up", "coupledup", "undrained"};
  static constexpr MaterialParameter kParameters[] = {
      kYoungsModulusParameter,
      kPoissonRatioParameter,
      DruckerPrager::kParameters[2],  // friction_angle
      DruckerPrager::kParameters[3],  // cohesion
      DruckerPrager::kParameters[4],  // logJp0
      DruckerPrager::kParameters[5],  // beta
      DruckerPrager::kParameters[6],  // SandVolCorrection
      number_parameter("rhow", "kg/m^3", &MaterialSpec::rhow, kPositiveValue, 0.0, "density of the pore water"),
      number_parameter("alpha1", "-", &MaterialSpec::alpha1, ValidRange{0.0, 1.0, true, false}, 0.0,
                       "Biot coefficient alpha, poro <= alpha1 <= 1"),
      number_parameter("poro", "-", &MaterialSpec::poro, ValidRange{0.0, 1.0, true, true}, 0.0, "porosity n, 0 < n < 1"),
      number_parameter("Kf", "Pa", &MaterialSpec::Kf, kPositiveValue, 1.0, "bulk modulus of the pore water"),
      number_parameter("Ks", "Pa", &MaterialSpec::Ks, kPositiveValue, 1.0, "bulk modulus of the solid grains"),
      number_parameter("Kperm", "m/s", &MaterialSpec::Kperm, kNonNegativeValue, 0.5,
                       "hydraulic conductivity (Darcy q = -Kperm / (rhow g0) (grad p - rhow g)); 0: undrained"),
  };
  template <typename T>
  using Params = CoupledUPParams<T>;
  template <typename T>
  using State = PoroPlasticState<T>;
  static constexpr int kStoredScalars = 17;  ///< position (3) + F (9) + logJp + p + q (3)
  static constexpr MaterialOutputs kOutputs{true, true, true};
  /// The engines run the seepage channels for this law (IsPoreFluid, material_common.cuh).
  static constexpr bool kPoreFluid = true;

  static ParameterProblem check(const MaterialSpec& m) {
    if (m.alpha1 < m.poro) return {"alpha1", "at least poro (alpha = 1 - K_skeleton / Ks >= n)"};
    return DruckerPrager::check(m);
  }

  /// 1 / M = n / Kf + (alpha - n) / Ks [1/Pa] (the storage of the pore space per unit pressure).
  static double storage(const MaterialSpec& m) { return m.poro / m.Kf + (m.alpha1 - m.poro) / m.Ks; }
  /// Seepage diffusivity kappa M [m^2/s]: the pore pressure's diffusion coefficient at a rigid skeleton (an upper
  /// bound of the consolidation coefficient c_v = kappa / (1/M + alpha^2 / K_oedometric)).
  static double seepage_diffusivity(const MaterialSpec& m) {
    return m.Kperm / (m.rhow * kStandardGravity) / storage(m);
  }

  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    return Params<T>{DruckerPrager::make_params<T>(m),
                     static_cast<T>(m.alpha1),
                     static_cast<T>(1.0 / storage(m)),
                     static_cast<T>(m.Kperm / (m.rhow * kStandardGravity)),
                     static_cast<T>(m.rhow),
                     static_cast<T>(m.poro)};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> reference_state() {
    return State<T>{Mat3<T>::identity(), T(0), T(0), Vec3<T>::zero()};
  }
  template <typename T>
  static State<T> initial_state(const MaterialSpec& m) {
    return State<T>{Mat3<T>::identity(), static_cast<T>(m.logJp0), T(0), Vec3<T>::zero()};
  }
  /// bodies[].initial_state "hydrostatic": the pore water carries the whole overburden (Kirchhoff pressure rho g d of
  /// the mixture), the skeleton none: the state right after the body's weight came on undrained (B = 1). It then
  /// consolidates toward the effective stress the skeleton can carry (Terzaghi, docs/validation.md).
  template <typename T>
  static State<T> hydrostatic_state(const Params<T>& p, double kirchhoff_pressure) {
    return State<T>{Mat3<T>::identity(), T(0), static_cast<T>(kirchhoff_pressure / static_cast<double>(p.biot)),
                    Vec3<T>::zero()};
  }
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T volume_ratio(const State<T>& s) {
    return determinant(s.F);
  }

  /// tau = tau'(F_e) - alpha J p I [Pa].
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& C) {
    StressResult<T> r = DruckerPrager::kirchhoff_stress(p.skeleton, PlasticState<T>{s.F, s.logJp}, C);
    const T pore = p.biot * r.J * s.pore_pressure;
    for (int i = 0; i < 3; ++i) r.kirchhoff.m[i][i] -= pore;
    return r;
  }

  /// The skeleton's step (DruckerPrager::advance) and the undrained part of the storage equation,
  /// p <- p - dt alpha M tr C. The seepage part is seep()'s.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> advance(const Params<T>& p, const State<T>& s, const Mat3<T>& C, T dt) {
    const PlasticState<T> skeleton = DruckerPrager::advance(p.skeleton, PlasticState<T>{s.F, s.logJp}, C, dt);
    return State<T>{skeleton.F, skeleton.logJp, s.pore_pressure - dt * p.biot * p.biot_modulus * trace(C),
                    s.head_gradient};
  }

  /// The seepage part of a step (physics/seepage.cuh): the particle takes the grid's pore pressure at its place,
  /// `grid_pressure` = sum_i w_ip h_i + rhow g . x_p [Pa] (h_i = p_i - rhow g . x_i, drained nodes at p = 0), plus the
  /// seepage of the step, dt M sum_i w_ip r_i (`inflow` [1/s]), plus the undrained change advance() made
  /// (`undrained_change` [Pa]); it keeps `grad_head` [Pa/m] for its next flux, -kappa grad h. An undrained body
  /// (Kperm = 0) keeps its own pressure: no water moves, so nothing is exchanged.
  template <typename T>
  FBAR_HOST_DEVICE static inline State<T> seep(const Params<T>& p, State<T> s, T inflow, const Vec3<T>& grad_head,
                                               T grid_pressure, T undrained_change, T dt) {
    if (!(p.conductivity > T(0))) return s;
    s.pore_pressure = grid_pressure + dt * p.biot_modulus * inflow + undrained_change;
    s.head_gradient = grad_head;
    return s;
  }
  /// Pore water density [kg/m^3] (the piezometric pressure p - rhow g . x the grid carries).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T water_density(const Params<T>& p) {
    return p.rhow;
  }
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T pore_pressure(const State<T>& s) {
    return s.pore_pressure;
  }
  /// Darcy flux q = -kappa grad h [m/s] of the last step (zero when undrained).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr Vec3<T> seepage(const Params<T>& p, const State<T>& s) {
    return s.head_gradient * (-p.conductivity);
  }
  template <typename T>
  FBAR_HOST_DEVICE static constexpr Vec3<T> head_gradient(const State<T>& s) {
    return s.head_gradient;
  }
  /// Pore water mass of a particle of reference volume V0 [kg]: n rhow V0.
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T water_mass(const Params<T>& p, T volume0) {
    return p.porosity * p.rhow * volume0;
  }

  /// Undrained p-wave speed sqrt((lambda + 2 mu + alpha^2 M) / rho) [m/s]: the pore water stiffens the mixture.
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& /*s*/) {
    using std::sqrt;
    return sqrt((p.skeleton.lambda + T(2) * p.skeleton.mu + p.biot * p.biot * p.biot_modulus) / p.skeleton.rho0);
  }

  /// The skeleton's stored elastic energy plus the pore water's, p^2 / (2 M) [J/m^3].
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    return DruckerPrager::energy_density(p.skeleton, PlasticState<T>{s.F, s.logJp}) +
           s.pore_pressure * s.pore_pressure / (T(2) * p.biot_modulus);
  }
};

}  // namespace fbar
