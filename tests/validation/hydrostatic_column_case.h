// Validation: hydrostatic JFluid column (docs/validation.md; the cb-geo benchmark) at two resolutions.
//
// Problem: fluid column of height H = 0.1 m, rho0 = 1800 kg/m^3, g = 9.81 m/s^2, K = 1e6 Pa, walls on the sides and
// base; base pressure rho0 g H = 1765.8 Pa. cb-geo (linear basis, 25 ppc, elastic E = 1e6, nu = 0) reports base
// pressure errors of -4.85 % at dx = 0.01 and -2.33 % at dx = 0.005 (first order). Here: JFluid with gamma = 7 (Tait
// water exponent; p / K <= 1.8e-3, so gamma moves the pressure by < 0.1 %), inviscid, a thin 3D column (2 x 2 cells
// in x, z between slip walls: a 1D problem by symmetry), 8 ppc, CFL 0.5, double precision unless stated.
//
// Two starts:
//  * Equilibrium: J(y) = (1 + gamma p(y)/K)^(-1/gamma) with the exact compressible p(y) (set_volume_ratios with mass
//    rescaling, so the density is rho0 / J). Checks that the engine's discrete equilibrium IS the hydrostatic field.
//  * Stress-free (the cb-geo procedure): J = 1, gravity switched on at t = 0; the column falls, rebounds and
//    oscillates acoustically (period 4 H / c0 = 17 ms) with little damping (inviscid, APIC). The pressure field is
//    averaged over whole oscillation periods (between the first and the last upward zero crossing of the
//    centre-of-mass velocity), which removes the oscillation from the mean.
//  * Hydrostatic: the scene's bodies[].initial_state "hydrostatic" (engine/hydrostatic.h), which both engines
//    apply: particles of mass rho0 V0 with the Kirchhoff pressure J p = rho0 g (surface - y). Its exact discrete
//    field is that Kirchhoff profile (the node forces integrate tau over V0; Cauchy p = tau / J).
// Wall placement (validation_support.h, WallFit): the equilibrium test puts the bed on the zero-velocity plane, where
// a resting fluid is an exact discrete equilibrium; the stress-free test uses the engine's convention (bed on the
// last wall node plane, one cell inside the Walls face), the placement whose first particle layer takes its load.
// Shared by the CPU validation test and the GPU engine's (tests/engine/gpu/test_validation_gpu.cu): the run is
// templated on the engine (CpuEngine, or test::GpuValidationEngine with the same queries).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <type_traits>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "scene/scene_parse.h"
#include "validation_support.h"

namespace fbar {
namespace hydrostatic_case {

using validation::r3;

constexpr double kRho = 1800.0;                   // [kg/m^3]
constexpr double kG = 9.81;                       // [m/s^2]
constexpr double kK = 1e6;                        // [Pa]
constexpr double kGamma = 7.0;                    // [-]
constexpr double kH = 0.1;                        // [m]
constexpr double kBasePressure = kRho * kG * kH;  // [Pa] 1765.8, the benchmark's reference

/// Exact hydrostatic pressure [Pa] at depth d [m] below the free surface of a Tait fluid whose density follows its
/// state, rho = rho0 / J = rho0 (1 + gamma p / K)^(1/gamma). Integrating dp/dd = rho g:
///   p(d) = (K / gamma) [(1 + (gamma - 1) rho0 g d / K)^(gamma / (gamma - 1)) - 1]   (-> rho0 g d as K -> inf);
/// p(H) = 1767.35 Pa, 0.09 % above rho0 g H because the compressed fluid column holds more mass.
double hydrostatic_pressure(double depth) {
  const double u = std::pow(1.0 + (kGamma - 1.0) * kRho * kG * depth / kK, kGamma / (kGamma - 1.0));
  return kK / kGamma * (u - 1.0);
}

/// Volume ratio of the Tait law at pressure p [Pa]: J = (1 + gamma p / K)^(-1/gamma).
double volume_ratio(double p) { return std::pow(1.0 + kGamma * p / kK, -1.0 / kGamma); }

enum class Start { Equilibrium, StressFree, Hydrostatic };

struct ColumnResult {
  bool ok = false;
  std::vector<double> row_pressure;  // [Pa] (time-averaged) row-mean pressure, bottom row first
  std::vector<double> row_error;   // [-] (time-averaged) row-mean pressure error relative to the row's exact value
  std::vector<double> cell_error;  // [-] the same for cell means (the 2 particle rows of a cell together)
  double profile_rms = 0;          // [-] RMS over rows of (p - p_exact) / (rho0 g H)
  double checkerboard = 0;         // [-] RMS over cells above the bottom one of (row - cell mean) / (rho0 g H)
  double base_fit = 0;             // [Pa] middle-half cell-mean profile, least-squares line, extrapolated to the bed
  double base_exact = 0;           // [Pa] the same fit of the exact field (rho0 g H for the stress-free start)
  double ke_max = 0;               // [J] largest kinetic energy of the run
  double ke_first = 0;             // [J] largest kinetic energy in the first fifth of the run
  double ke_last = 0;              // [J] largest kinetic energy in the last fifth of the run
  double weight_energy = 0;        // [J] m g H, the energy scale of the problem
  int periods = 0;                 // oscillation periods averaged over (StressFree)
  long long steps = 0;
  std::size_t particles = 0;
  double seconds = 0;
  double base_row_error() const { return row_error.front(); }
  double base_fit_error() const { return (base_fit - base_exact) / base_exact; }
};

// The profile's figures from the time-averaged row pressures: row and cell errors against the exact rows, the RMS,
// the checkerboard, and the middle-half line's base pressure with the same line through the exact cells.
inline void fit_profile(ColumnResult& result, const std::vector<double>& average, const std::vector<double>& row_exact,
                        double dx) {
  const int rows = static_cast<int>(average.size());
  result.row_pressure = average;
  double rms = 0;
  for (int r = 0; r < rows; ++r) {
    result.row_error.push_back((average[r] - row_exact[r]) / row_exact[r]);
    rms += (average[r] - row_exact[r]) * (average[r] - row_exact[r]);
  }
  result.profile_rms = std::sqrt(rms / rows) / kBasePressure;
  // Cell means, and the least-squares line through the cells of the middle half of the column (reference height),
  // extrapolated to the bed: the base pressure one reads off the profile away from the bed and surface layers.
  // The same line through the exact cell means is the reference (the compressible exact profile is slightly curved).
  double sy = 0, syy = 0, sp = 0, syp = 0, se = 0, sye = 0;
  int fitted = 0;
  for (int c = 0; c < rows / 2; ++c) {
    const double pm = 0.5 * (average[2 * c] + average[2 * c + 1]);
    const double pe = 0.5 * (row_exact[2 * c] + row_exact[2 * c + 1]);
    result.cell_error.push_back((pm - pe) / pe);
    if (c > 0) result.checkerboard += 0.25 * (average[2 * c] - average[2 * c + 1]) * (average[2 * c] - average[2 * c + 1]);
    const double yc = (c + 0.5) * dx;  // cell centre above the bed
    if (yc >= 0.25 * kH && yc <= 0.75 * kH) {
      sy += yc, syy += yc * yc, sp += pm, syp += yc * pm, se += pe, sye += yc * pe;
      ++fitted;
    }
  }
  auto intercept = [&](double s_p, double s_yp) {
    const double slope = (fitted * s_yp - sy * s_p) / (fitted * syy - sy * sy);
    return (s_p - slope * sy) / fitted;
  };
  result.checkerboard = std::sqrt(result.checkerboard / (rows / 2 - 1)) / kBasePressure;
  result.base_fit = intercept(sp, syp);
  result.base_exact = intercept(se, sye);
}

// One run's figures, printed.
inline void print_column(const ColumnResult& result, Start start, validation::WallFit fit, const char* precision,
                         double dx, double fbar_psi) {
  std::printf("hydrostatic column, %s, %s start, %s, dx = %g m: %zu particles, %lld steps, %.2f s wall\n",
              fit == validation::WallFit::ZeroVelocityPlane ? "bed on the zero-velocity plane"
                                                            : "bed on the last wall node plane",
              start == Start::Equilibrium ? "equilibrium" : start == Start::Hydrostatic ? "hydrostatic" : "stress-free",
              precision, dx, result.particles, result.steps, result.seconds);
  std::printf(
      "  bottom rows error %+.4f %% %+.4f %% %+.4f %% %+.4f %%; bottom cells %+.4f %% %+.4f %% %+.4f %%; top row %+.3f "
      "%%\n",
      100 * result.row_error[0], 100 * result.row_error[1], 100 * result.row_error[2], 100 * result.row_error[3],
      100 * result.cell_error[0], 100 * result.cell_error[1], 100 * result.cell_error[2],
      100 * result.row_error.back());
  std::printf("  base from the middle-half profile %.3f Pa (exact %.3f, error %+.4f %%); profile RMS %.3g rho0 g H; "
              "checkerboard %.3g rho0 g H (FBAR_psi %g)\n",
              result.base_fit, result.base_exact, 100 * result.base_fit_error(), result.profile_rms,
              result.checkerboard, fbar_psi);
  std::printf("  KE max %.3g J (%.3g m g H); max in first / last fifth %.3g / %.3g J; %d periods averaged\n",
              result.ke_max, result.ke_max / result.weight_energy, result.ke_first, result.ke_last, result.periods);
}

// The column, its bed and side faces placed against the Walls box as `fit` says. T, TG: particle and grid scalar
// types (<float, float> single, <double, double> double, <double, float> mixed).
template <typename T, typename TG = T, class Engine = CpuEngine<T, TG>>
ColumnResult run_column(double dx, Start start, double t_end, validation::WallFit fit, double fbar_psi = 0.0,
                        FbarScheme scheme = FbarScheme::Cell, bool fused = false) {
  validation::Stopwatch clock;
  const double w = 2 * dx;
  const double x0 = dx + validation::wall_inset(fit, dx), y0 = x0, z0 = x0;
  Scene scene = validation::make_scene(r3(x0 + w + 2 * dx, y0 + kH + 3 * dx, z0 + w + 2 * dx), dx, r3(0, -kG, 0));
  scene.simulation.precision = !std::is_same_v<T, TG>     ? Precision::Mixed
                               : std::is_same_v<T, float> ? Precision::Single
                                                          : Precision::Double;
  BodySpec column = validation::jfluid_body(kRho, kK, kGamma, 0.0);
  column.algorithm.use_fbar = fbar_psi != 0.0;
  column.algorithm.fbar_psi = fbar_psi;
  column.algorithm.fbar_scheme = scheme;
  column.algorithm.fbar_fused_kernel = fused;
  if (start == Start::Hydrostatic) column.initial_state = InitialState::Hydrostatic;
  validation::add_box(column, r3(x0, y0, z0), r3(w, kH, w));
  scene.bodies.push_back(column);
  scene.boundaries.push_back(
      validation::wall_box(Contact::Slip, r3(x0, y0, z0), r3(x0 + w, validation::kFar, z0 + w), dx, fit));

  Engine engine(scene);
  const double surface = y0 + kH;
  std::vector<Vec3d> x_ref;
  for (const Vec3<T>& x : engine.positions(0)) x_ref.push_back(x.template cast<double>());
  // Exact pressure of each particle. Equilibrium start: the particles sit at their equilibrium heights, p(surface - y).
  // Stress-free start: every particle has mass rho0 dx^3 / ppc, so at rest a particle carries the weight of the mass
  // above it: p = rho0 g (surface - y_ref), whatever the compression; the bed pressure is exactly rho0 g H.
  std::vector<double> p_exact(x_ref.size());
  const JFluid::Params<double> law = JFluid::make_params<double>(column.material);
  for (std::size_t i = 0; i < x_ref.size(); ++i) {
    const double tau = kRho * kG * (surface - x_ref[i][1]);
    p_exact[i] = start == Start::Equilibrium ? hydrostatic_pressure(surface - x_ref[i][1])
                 : start == Start::Hydrostatic ? JFluid::pressure(law, JFluid::hydrostatic_state<double>(law, tau))
                                               : tau;
  }
  if (start == Start::Equilibrium)
    engine.set_volume_ratios(0, [&](const Vec3d& x) { return volume_ratio(hydrostatic_pressure(surface - x[1])); });

  // Particle rows (2 per cell at 8 ppc) by reference height; row-mean pressures are integrated in time every step.
  const double h = 0.5 * dx;
  const int rows = static_cast<int>(std::lround(kH / h));
  std::vector<int> row_of(x_ref.size()), row_count(rows, 0);
  std::vector<double> row_exact(rows, 0.0);
  for (std::size_t i = 0; i < x_ref.size(); ++i) {
    row_of[i] = static_cast<int>((x_ref[i][1] - y0) / h);
    ++row_count[row_of[i]];
    row_exact[row_of[i]] += p_exact[i];
  }
  for (int r = 0; r < rows; ++r) row_exact[r] /= row_count[r];
  auto row_means = [&]() {
    std::vector<double> m(rows, 0.0);
    const std::vector<T> p = engine.pressures(0);
    for (std::size_t i = 0; i < p.size(); ++i) m[row_of[i]] += static_cast<double>(p[i]);
    for (int r = 0; r < rows; ++r) m[r] /= row_count[r];
    return m;
  };

  ColumnResult result;
  result.particles = x_ref.size();
  result.weight_energy = engine.total_mass() * kG * kH;
  const double mass = engine.total_mass();
  std::vector<double> times{0.0}, vcm{0.0};
  std::vector<std::vector<double>> integral{std::vector<double>(rows, 0.0)};  // (sample, row) int_0^t p dt
  std::vector<double> previous = row_means();
  while (engine.time() < t_end) {
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return result;
    }
    const double t = engine.time(), ke = engine.kinetic_energy();
    result.ke_max = std::max(result.ke_max, ke);
    if (t <= 0.2 * t_end) result.ke_first = std::max(result.ke_first, ke);
    if (t >= 0.8 * t_end) result.ke_last = std::max(result.ke_last, ke);
    const std::vector<double> now = row_means();
    std::vector<double> next = integral.back();
    for (int r = 0; r < rows; ++r) next[r] += 0.5 * (previous[r] + now[r]) * s.dt;  // trapezoid rule
    integral.push_back(std::move(next));
    previous = now;
    times.push_back(t);
    vcm.push_back(engine.total_momentum()[1] / mass);
  }
  result.steps = engine.steps();

  // Equilibrium: the final field. Stress-free: the mean over whole periods.
  std::vector<double> average = previous;
  if (start == Start::StressFree) {
    std::vector<double> up;  // upward zero crossings of the centre-of-mass velocity
    for (std::size_t i = 1; i < times.size(); ++i)
      if (vcm[i - 1] < 0.0 && vcm[i] >= 0.0)
        up.push_back(times[i - 1] + vcm[i - 1] / (vcm[i - 1] - vcm[i]) * (times[i] - times[i - 1]));
    if (up.size() < 3) {
      ADD_FAILURE() << "fewer than 2 oscillation periods in " << t_end << " s";
      return result;
    }
    const double ta = up.front(), tb = up.back();
    result.periods = static_cast<int>(up.size()) - 1;
    std::vector<double> series(times.size());
    for (int r = 0; r < rows; ++r) {
      for (std::size_t i = 0; i < times.size(); ++i) series[i] = integral[i][r];
      average[r] =
          (validation::interpolate(times, series, tb) - validation::interpolate(times, series, ta)) / (tb - ta);
    }
  }

  fit_profile(result, average, row_exact, dx);
  result.seconds = clock.seconds();
  result.ok = true;

  print_column(result, start, fit, to_string(scene.simulation.precision), dx, fbar_psi);
  return result;
}

}  // namespace hydrostatic_case
}  // namespace fbar
