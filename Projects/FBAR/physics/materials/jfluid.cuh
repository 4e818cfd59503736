// JFluid: a weakly compressible Tait-Murnaghan fluid with Newtonian viscosity, state = 1 - J (material header).
//
// Equation of state (docs/user_guide.md §2.4): p = (K / gamma) (J^-gamma - 1), K = bulk modulus at rest, J = V / V0.
// Cauchy stress sigma = -p I + 2 mu_visc dev(sym(grad v)), grad v = C (APIC affine matrix, see material_common).
// Sound speed c^2 = dp/drho = (K / rho0) J^(1 - gamma)  (= (K + gamma p) / rho, rho = rho0 / J).
//
// Tension cutoff (tension_cutoff = p_t >= 0, fbar's; absent: none, ClaymoreUW's law): the fluid carries at most p_t
// of tension, p >= -p_t. J stops growing at J_t, p(J_t) = -p_t: a fluid pulled further separates (cavitates) instead
// of storing the expansion, so that it carries no tension when it closes again. The law's pressure and energy are
// unchanged below J_t. J_t = (1 - gamma p_t / K)^(-1/gamma); when gamma p_t >= K there is no J_t (the law's tension
// never exceeds K / gamma) and nothing is cut.
//
// Hydrostatic initial state (bodies[].initial_state "hydrostatic"): hydrostatic_state() gives the J whose Kirchhoff
// pressure J p(J) equals rho0 g depth. MPM's momentum balance integrates the Kirchhoff stress over reference volumes
// (a particle's force is V0 tau grad w), so this profile is the discrete equilibrium of a column of particles of mass
// rho0 V0, where the Cauchy profile p = rho0 g depth would leave a residual force of relative size p / K.
//
// Precision: a particle stores 1 - J, never J. Near rest 1 - J ~ p / K is tiny (water at 1 m depth: 5e-5), and
// every formula below is written with log1p / expm1 on 1 - J so that the pressure keeps the relative accuracy of
// the stored value in float: p = (K/gamma) expm1(-gamma log1p(-(1 - J))).
#pragma once

#include <cmath>
#include <limits>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/material_spec.h"

namespace fbar {

/// JFluid parameters (trivially copyable; pass to kernels by value).
template <typename T>
struct JFluidParams {
  T rho0;          ///< [kg/m^3] density at rest (J = 1)
  T bulk_modulus;  ///< [Pa] K > 0
  T gamma;         ///< [-] Tait-Murnaghan exponent, >= 1 (water: ~7)
  T viscosity;     ///< [Pa s] dynamic viscosity mu_visc >= 0
  T one_minus_J_min = -std::numeric_limits<T>::infinity();  ///< [-] 1 - J_t of the tension cutoff (-inf: none)
  /// Terms of the pressure's Taylor series in u = 1 - J that single precision evaluates near rest (pressure()).
  static constexpr int kSeriesTerms = 12;
  T series[kSeriesTerms] = {};  ///< [Pa] a_k, p = sum_k a_k u^(k+1) (make_params; float only)
  T series_limit = T(-1);      ///< [-] |u| up to which that sum is within 2^-26 of p (-1: never used)
};

/// Per-particle state of a JFluid particle besides its position.
template <typename T>
struct JFluidState {
  T one_minus_J;  ///< [-] 1 - J (positive in compression)
};

struct JFluid {
  /// Name of the law in scene files (material.constitutive) and its enumerator.
  static constexpr const char* kJsonName = "JFluid";
  static constexpr Constitutive kLaw = Constitutive::JFluid;
  /// Other names scene files use for it (ClaymoreUW's).
  static constexpr const char* kAliases[] = {"Water", "Fluid", "Liquid"};
  /// Scene parameters (bodies[].material), besides rho, ppc and CFL which every material reads.
  static constexpr MaterialParameter kParameters[] = {
      number_parameter("bulk_modulus", "Pa", &MaterialSpec::bulk_modulus, kPositiveValue, 1.0,
                       "bulk modulus K at rest"),
      number_parameter("gamma", "-", &MaterialSpec::gamma, kPositiveValue, 0.0, "Tait-Murnaghan exponent"),
      number_parameter("viscosity", "Pa s", &MaterialSpec::viscosity, kNonNegativeValue, 1.5, "dynamic viscosity"),
      number_parameter("tension_cutoff", "Pa", &MaterialSpec::tension_cutoff, kNonNegativeValue, 1.0,
                       "most tension the fluid carries, p >= -tension_cutoff (absent: no cutoff)"),
  };
  template <typename T>
  using Params = JFluidParams<T>;
  template <typename T>
  using State = JFluidState<T>;
  /// Scalars a particle stores: position (3) + 1 - J (1). Mass and volume are per body.
  static constexpr int kStoredScalars = 4;
  static constexpr MaterialOutputs kOutputs{false, false};
  /// Nodal F-bar (physics/fbar_nodal.cuh): the particle keeps its own volume; only the stress sees JBar.
  static constexpr bool kFbarKeepsOwnVolume = true;

  /// Parameters from the resolved scene (host only).
  template <typename T>
  static Params<T> make_params(const MaterialSpec& m) {
    Params<T> p{static_cast<T>(m.rho), static_cast<T>(m.bulk_modulus), static_cast<T>(m.gamma),
                static_cast<T>(m.viscosity)};
    const double ratio = m.gamma * m.tension_cutoff / m.bulk_modulus;  // gamma p_t / K
    if (std::isfinite(m.tension_cutoff) && ratio < 1.0)
      p.one_minus_J_min = static_cast<T>(-std::expm1(-std::log1p(-ratio) / m.gamma));  // 1 - J_t
    if constexpr (sizeof(T) == sizeof(float)) set_pressure_series(p, m.bulk_modulus, m.gamma);
    return p;
  }
  /// The float pressure's series: (K / gamma)((1 - u)^-gamma - 1) = sum_k a_k u^(k+1), a_k = (K / gamma)
  /// gamma (gamma + 1) ... (gamma + k) / (k + 1)!, and the largest |u| (searched in steps of 1e-4) at which the
  /// truncated sum stays within 2^-26 (a quarter of a float ulp) of the law on both sides of rest: with 12 terms
  /// 0.108 for gamma = 7.15, 0.16 for gamma = 3 (tests/physics/test_materials.cpp). Host only.
  template <typename T>
  static void set_pressure_series(Params<T>& p, double K, double gamma) {
    constexpr int n = Params<T>::kSeriesTerms;
    double a[n];
    double c = 1.0;
    for (int k = 0; k < n; ++k) {
      c *= (gamma + k) / (k + 1);
      a[k] = K / gamma * c;
      p.series[k] = static_cast<T>(a[k]);
    }
    const auto within = [&](double u) {
      for (const double x : {u, -u}) {
        double sum = 0.0;
        for (int k = n - 1; k >= 0; --k) sum = (sum + a[k]) * x;
        const double law = K / gamma * std::expm1(-gamma * std::log1p(-x));
        if (!(std::fabs(sum - law) <= 0x1p-26 * std::fabs(law))) return false;
      }
      return true;
    };
    double limit = 0.0;
    while (limit < 0.5 && within(limit + 1e-4)) limit += 1e-4;
    p.series_limit = limit > 0.0 ? static_cast<T>(limit) : T(-1);
  }

  /// Undeformed state (J = 1).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> reference_state() {
    return State<T>{T(0)};
  }
  /// State with a prescribed volume ratio J (e.g. hydrostatic initial conditions).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> state_with_J(T J) {
    return State<T>{T(1) - J};
  }

  template <typename T>
  FBAR_HOST_DEVICE static constexpr T volume_ratio(const State<T>& s) {
    return T(1) - s.one_minus_J;
  }

  /// Equation-of-state pressure p = (K/gamma)(J^-gamma - 1) [Pa], accurate in float near J = 1. Float takes the
  /// law's Taylor series in 1 - J where it is within a quarter ulp of the law (set_pressure_series: 12 multiply-adds
  /// instead of log1p, expm1 and a division, about 60 instructions fewer per particle in G2P2G), else log1p / expm1.
  template <typename T>
  FBAR_HOST_DEVICE static inline T pressure(const Params<T>& p, const State<T>& s) {
    using std::expm1;
    using std::log1p;
    const T u = s.one_minus_J;
    if constexpr (sizeof(T) == sizeof(float)) {
      if (u <= p.series_limit && u >= -p.series_limit) {
        T sum = p.series[Params<T>::kSeriesTerms - 1];
        for (int k = Params<T>::kSeriesTerms - 2; k >= 0; --k) sum = sum * u + p.series[k];
        return sum * u;
      }
    }
    return p.bulk_modulus / p.gamma * expm1(-p.gamma * log1p(-u));
  }

  /// Kirchhoff stress tau = J (-p I + 2 mu_visc dev(sym C)) [Pa]; C [1/s] is the particle's velocity gradient.
  template <typename T>
  FBAR_HOST_DEVICE static inline StressResult<T> kirchhoff_stress(const Params<T>& p, const State<T>& s,
                                                                  const Mat3<T>& C) {
    const T J = volume_ratio(s);
    Mat3<T> sigma = deviatoric_part(symmetric_part(C)) * (T(2) * p.viscosity);
    const T pr = pressure(p, s);
    for (int i = 0; i < 3; ++i) sigma.m[i][i] -= pr;
    return StressResult<T>{sigma * J, J};
  }

  /// State after one step: J <- (1 + dt tr C) J on 1 - J, then J <- min(J, J_t) (the tension cutoff).
  template <typename T>
  FBAR_HOST_DEVICE static constexpr State<T> advance(const Params<T>& p, const State<T>& s, const Mat3<T>& C,
                                                     T dt) {
    const T one_minus_J = advance_one_minus_J(s.one_minus_J, C, dt);
    return State<T>{one_minus_J < p.one_minus_J_min ? p.one_minus_J_min : one_minus_J};
  }

  /// The state whose Kirchhoff pressure J p(J) is `kirchhoff_pressure` [Pa] (>= 0; host): the hydrostatic initial
  /// state at depth d has kirchhoff_pressure = rho0 g d. Newton's method on 1 - J, in double.
  template <typename T>
  static State<T> hydrostatic_state(const Params<T>& p, double kirchhoff_pressure) {
    const double K = static_cast<double>(p.bulk_modulus), gamma = static_cast<double>(p.gamma);
    double u = kirchhoff_pressure / K;  // 1 - J, first guess from the linear law
    for (int it = 0; it < 60; ++it) {
      const double J = 1.0 - u;
      const double pressure = K / gamma * std::expm1(-gamma * std::log1p(-u));
      const double dpressure = K * std::exp(-(gamma + 1.0) * std::log1p(-u));  // dp/du
      const double f = J * pressure - kirchhoff_pressure;
      const double df = J * dpressure - pressure;  // d(J p)/du > 0 for J <= 1
      const double step = f / df;
      u -= step;
      if (!(std::fabs(step) > 1e-16 * std::fabs(u))) break;
    }
    return State<T>{static_cast<T>(u)};
  }

  /// Sound speed c = sqrt((K/rho0) J^(1-gamma)) [m/s] of the current state.
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed(const Params<T>& p, const State<T>& s) {
    using std::exp;
    using std::log1p;
    using std::sqrt;
    return sqrt(p.bulk_modulus / p.rho0 * exp((T(1) - p.gamma) * log1p(-s.one_minus_J)));
  }

  /// A key that orders states by wave speed (constitutive_models.cuh): c^2 is proportional to J^(1 - gamma), which
  /// grows with compression (1 - J) for gamma > 1 and shrinks for gamma < 1.
  template <typename T>
  FBAR_HOST_DEVICE static constexpr T wave_speed_order(const Params<T>& p, const State<T>& s) {
    return p.gamma >= T(1) ? s.one_minus_J : -s.one_minus_J;
  }
  /// The wave speed of the state whose wave_speed_order is `key`.
  template <typename T>
  FBAR_HOST_DEVICE static inline T wave_speed_at_order(const Params<T>& p, T key) {
    return wave_speed(p, State<T>{p.gamma >= T(1) ? key : -key});
  }

  /// Stored energy per reference volume psi(J) = (K/gamma) [(J^(1-gamma) - 1)/(gamma - 1) + (J - 1)] [J/m^3],
  /// the potential with -dpsi/dJ = p and psi(1) = 0 (gamma = 1: K (J - 1 - ln J)).
  template <typename T>
  FBAR_HOST_DEVICE static inline T energy_density(const Params<T>& p, const State<T>& s) {
    using std::expm1;
    using std::fabs;
    using std::log1p;
    const T log_J = log1p(-s.one_minus_J);
    const T t = (T(1) - p.gamma) * log_J;
    // (J^(1-gamma) - 1) / (gamma - 1) = -ln J * expm1(t) / t, finite as gamma -> 1.
    const T expm1_over_t = fabs(t) > T(0) ? expm1(t) / t : T(1);
    return p.bulk_modulus / p.gamma * (-log_J * expm1_over_t - s.one_minus_J);
  }
};

}  // namespace fbar
