// Validation: axial vibration of a clamped-free elastic bar (docs/validation.md; Bardenhagen 2002).
//
// Problem: L = 25 m, E = 100 Pa, rho = 1 kg/m^3, nu = 0, clamped at x = 0, free at x = L, initial velocity
// v(x, 0) = v0 sin(pi x / (2 L)), v0 = 0.1 m/s (the first mode). Exact (linear elasticity):
//   c = sqrt(E / rho) = 10 m/s, omega = pi c / (2 L), T1 = 4 L / c = 10 s,
//   u(x, t) = (v0 / omega) sin(pi x / (2 L)) sin(omega t): tip amplitude v0 / omega = 0.15915 m,
//   centre-of-mass velocity v_cm(t) = (2 / pi) v0 cos(omega t): amplitude 0.063662 m/s.
// With nu = 0 the bar and the laterally confined p-wave speeds agree (lambda = 0: c_p = sqrt((lambda+2mu)/rho) =
// sqrt(E/rho)), so a thin 3D bar between lateral slip walls (1 x 1 cell cross-section, 2 x 2 particles) is exactly
// the 1D bar. FixedCorotated (its small-strain limit is linear elasticity; the peak strain v0/c = 1 % adds a
// geometric nonlinearity of the same order on the stress and far less on the period).
// Shared by the CPU validation test and the GPU engine's (tests/engine/gpu/test_validation_gpu.cu): the run is
// templated on the engine (CpuEngine, or test::GpuValidationEngine with the same queries).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace bar_case {

using validation::kPi;
using validation::r3;

constexpr double kL = 25.0;                      // [m]
constexpr double kE = 100.0;                     // [Pa]
constexpr double kRho = 1.0;                     // [kg/m^3]
constexpr double kV0 = 0.1;                      // [m/s]
constexpr double kC = 10.0;                      // [m/s] sqrt(E / rho)
constexpr double kPeriod = 4 * kL / kC;          // [s] 10
constexpr double kOmega = 2 * kPi / kPeriod;     // [1/s]
constexpr double kVcmAmplitude = 2 / kPi * kV0;  // [m/s] 0.063662
constexpr double kTipAmplitude = kV0 / kOmega;   // [m] 0.15915

struct BarResult {
  bool ok = false;
  double period = 0;  // [s] from the centre-of-mass velocity zero crossings
  int crossings = 0;
  std::vector<double> peaks;                  // [m/s] |v_cm| extremum in each half period (t = 0, T/2, T, ...)
  double tip_amplitude = 0;                   // [m] largest |mean tip-row displacement| in the first half period
  double energy0 = 0, energy_end = 0;         // [J] kinetic + elastic
  double energy_max = 0, energy_min = 1e300;  // [J] over the run
  double dt = 0;                              // [s] last step size
  long long steps = 0;
  std::size_t particles = 0;
  double seconds = 0;
};

using validation::kApic;
using validation::Scheme;

/// adjust: applied to the scene before the engine is built (a test of scene-level scaling).
template <class Engine = CpuEngine<double>>
BarResult run_bar(double dx, double periods, validation::WallFit fit = validation::WallFit::LastWallNodePlane,
                  const Scheme& scheme = kApic, const std::function<void(Scene&)>& adjust = {}) {
  validation::Stopwatch clock;
  const double x0 = dx + validation::wall_inset(fit, dx), y0 = x0, z0 = x0;  // material faces (validation_support.h)
  Scene scene = validation::make_scene(r3(x0 + kL + 4 * dx, y0 + 2.5 * dx, z0 + 2.5 * dx), dx, r3(0, 0, 0));
  BodySpec bar = validation::fixed_corotated_body(kRho, kE, 0.0);
  validation::set_scheme(bar, scheme);
  validation::add_box(bar, r3(x0, y0, z0), r3(kL, dx, dx));
  scene.bodies.push_back(bar);
  // Clamp: sticky wall against the bar's end x = x0; lateral: slip walls against the bar's faces.
  scene.boundaries.push_back(validation::wall_box(Contact::Sticky, r3(x0, -validation::kFar, -validation::kFar),
                                                  r3(validation::kFar, validation::kFar, validation::kFar), dx, fit));
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(-validation::kFar, y0, z0),
                                                  r3(validation::kFar, y0 + dx, z0 + dx), dx, fit));
  if (adjust) adjust(scene);

  Engine engine(scene);
  engine.set_velocities(0, [&](const Vec3d& x) { return Vec3d{{kV0 * std::sin(kPi * (x[0] - x0) / (2 * kL)), 0, 0}}; });
  std::vector<Vec3d> x_ref;  // in double whatever the engine's precision (the study runs single and mixed too)
  for (const auto& x : engine.positions(0)) x_ref.push_back(x.template cast<double>());
  double tip_ref = 0;
  for (const Vec3d& x : x_ref) tip_ref = std::max(tip_ref, x[0]);
  std::vector<std::size_t> tip;  // the last particle row (largest x)
  for (std::size_t i = 0; i < x_ref.size(); ++i)
    if (x_ref[i][0] > tip_ref - 1e-9) tip.push_back(i);

  BarResult r;
  r.particles = x_ref.size();
  const double mass = engine.total_mass();
  r.energy0 = engine.kinetic_energy() + engine.elastic_energy();
  std::vector<double> times{0.0}, vcm{engine.total_momentum()[0] / mass};
  const double t_end = periods * kPeriod;
  while (engine.time() < t_end) {
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return r;
    }
    const double e = engine.kinetic_energy() + engine.elastic_energy();
    r.energy_max = std::max(r.energy_max, e);
    r.energy_min = std::min(r.energy_min, e);
    times.push_back(engine.time());
    vcm.push_back(engine.total_momentum()[0] / mass);
    if (engine.time() < 0.5 * kPeriod) {
      double u = 0;
      for (std::size_t i : tip) u += engine.positions(0)[i][0] - x_ref[i][0];
      r.tip_amplitude = std::max(r.tip_amplitude, std::fabs(u / tip.size()));
    }
  }
  r.steps = engine.steps();
  r.dt = engine.last_dt();
  r.energy_end = engine.kinetic_energy() + engine.elastic_energy();
  const std::vector<double> zeros = validation::zero_crossings(times, vcm);
  r.crossings = static_cast<int>(zeros.size());
  if (zeros.size() < 5) {
    ADD_FAILURE() << "only " << zeros.size() << " zero crossings of v_cm in " << t_end << " s";
    return r;
  }
  // Crossings k and k + 4 are two periods apart; average over all such pairs.
  double sum = 0;
  int pairs = 0;
  for (std::size_t k = 0; k + 4 < zeros.size(); ++k, ++pairs) sum += 0.5 * (zeros[k + 4] - zeros[k]);
  r.period = sum / pairs;
  // Extrema of v_cm: at t = 0, then one between consecutive zero crossings.
  r.peaks.push_back(std::fabs(vcm[0]));
  for (std::size_t k = 0; k + 1 < zeros.size(); ++k) {
    double peak = 0;
    for (std::size_t i = 0; i < times.size(); ++i)
      if (times[i] > zeros[k] && times[i] < zeros[k + 1]) peak = std::max(peak, std::fabs(vcm[i]));
    r.peaks.push_back(peak);
  }
  r.seconds = clock.seconds();
  r.ok = true;
  std::printf("vibrating bar, dx = %g m (L/dx = %g): %zu particles, %lld steps, %.2f s wall\n", dx, kL / dx,
              r.particles, r.steps, r.seconds);
  std::printf("  period %.5f s (exact %.1f, error %+.3f %%) from %d zero crossings\n", r.period, kPeriod,
              100 * (r.period / kPeriod - 1), r.crossings);
  std::printf("  |v_cm| extrema:");
  for (double p : r.peaks) std::printf(" %.6f", p);
  std::printf(" (exact %.6f)\n  tip amplitude %.5f m (exact %.5f, error %+.3f %%); energy %.6g -> %.6g J (%+.3f %%)\n",
              kVcmAmplitude, r.tip_amplitude, kTipAmplitude, 100 * (r.tip_amplitude / kTipAmplitude - 1), r.energy0,
              r.energy_end, 100 * (r.energy_end / r.energy0 - 1));
  std::printf("  energy range over the run %+.3f %% .. %+.3f %%, dt %.4g, omega dt %.4g\n",
              100 * (r.energy_min / r.energy0 - 1), 100 * (r.energy_max / r.energy0 - 1), r.dt, kOmega * r.dt);
  return r;
}

}  // namespace bar_case
}  // namespace fbar
