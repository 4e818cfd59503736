// Validation: volumetric locking and F-bar (docs/validation.md, its locking rows; transfer.cuh, fbar_velocity_gradient).
//
// Problem: a nearly incompressible elastic block (FixedCorotated, E = 1 MPa, nu = 0.499, rho = 1000 kg/m^3), W = H =
// 0.2 m, standing on a frictionless (Slip) floor under gravity, free on its sides, in plane strain (Slip walls one
// thickness of 2 cells apart in z). The small-strain solution is uniaxial stress in the plane:
//   sigma_yy = -rho g (H - y),  sigma_xx = 0,  sigma_zz = nu sigma_yy          (plane strain)
//   pressure p = -tr(sigma) / 3 = rho g (H - y) (1 + nu) / 3
//   eps_yy = sigma_yy (1 - nu^2) / E, so the centre of mass settles by  d = rho g (1 - nu^2) H^2 / (3 E)  (98.2 um).
// The block must bulge sideways to settle: nearly isochoric motion, which quadratic B-spline MPM with 8 ppc cannot
// represent when each particle keeps its own volume (more volume constraints than nodes): its pressure field
// checkerboards, particle to particle, by more than the pressure itself. (The settlement, an integral, barely shows
// it: 0.95 of the exact value.) F-bar (FBAR_psi = 1) gives each grid cell one volume ratio. The bed is placed as
// ClaymoreUW places it (validation_support.h, LastWallNodePlane); with the bed on the zero-velocity plane the frozen
// first particle layer of a nearly incompressible solid carries tension (about -2 rho g H), with or without F-bar.
//
// Started stress-free, the block oscillates about its equilibrium (little damping: APIC, elastic); settlement and
// pressure are averaged over whole oscillation periods (between the first and last upward zero crossings of the
// centre-of-mass velocity), which removes the oscillation from the mean.
// Metrics: settlement ratio d_MPM / d; pressure error RMS over the particles of (p - p_exact) / (rho g H);
// checkerboard index RMS over the particles of (p - mean p of the particle's cell) / (rho g H).
// Shared by the CPU validation test and the GPU engine's (tests/engine/gpu/test_validation_gpu.cu): the run is
// templated on the engine (CpuEngine, or test::GpuValidationEngine with the same queries).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>
#include <vector>

#include <memory>

#include "engine/cpu/cpu_engine.h"
#include "geometry/tet_mesh.h"
#include "scene/scene_parse.h"
#include "../physics/physics_test_support.h"
#include "validation_support.h"

namespace fbar {
namespace locking_case {

using validation::r3;

constexpr double kRho = 1000.0;  // [kg/m^3]
constexpr double kG = 9.81;      // [m/s^2]
constexpr double kE = 1e6;       // [Pa]
constexpr double kH = 0.2;       // [m] height and width

struct LockingResult {
  bool ok = false;
  double settlement_ratio = 0;  // [-] time-averaged centre-of-mass drop / exact
  double pressure_rms = 0;      // [-] RMS (p - p_exact) / (rho g H)
  double checkerboard = 0;      // [-] RMS (p - cell mean) / (rho g H)
  int periods = 0;
  long long steps = 0;
  std::size_t particles = 0;
  double seconds = 0;
};

/// mesh: the block as an FEM mesh (FixedCorotated tetrahedra on cubes of dx / 2, Kuhn's six each), psi its F-bar
/// elements' ratio (use_FBAR, FBAR_ratio; physics/fem.cuh), instead of particles with F-bar's psi.
template <class Engine = CpuEngine<double>>
LockingResult run_block(double nu, double psi, double dx, int periods_wanted, bool mesh = false,
                        FbarScheme scheme = FbarScheme::Cell, bool fused = false) {
  validation::Stopwatch clock;
  const double x0 = 0.1, y0 = dx + validation::wall_inset(validation::WallFit::LastWallNodePlane, dx);
  const double z0 = y0, thickness = 2 * dx;
  Scene scene = validation::make_scene(r3(x0 + kH + 0.1, y0 + kH + 2 * dx, z0 + thickness + 2 * dx), dx,
                                       r3(0, -kG, 0));
  if (mesh) {
    const int n = static_cast<int>(std::lround(2 * kH / dx)), nz = static_cast<int>(std::lround(2 * thickness / dx));
    MeshEntrySpec& m = test::add_elastic_mesh(
        scene, box_tet_mesh(Vec3d{{x0, y0, z0}}, Vec3d{{x0 + kH, y0 + kH, z0 + thickness}}, Vec3i{{n, n, nz}}), kRho, kE,
        nu);
    m.fbar_elements = psi != 0.0;  // the elements' (not copied to the body)
    m.fbar_ratio = psi;
  } else {
    BodySpec block = validation::fixed_corotated_body(kRho, kE, nu);
    block.algorithm.use_fbar = psi != 0.0;
    block.algorithm.fbar_psi = psi;
    block.algorithm.fbar_scheme = scheme;
    block.algorithm.fbar_fused_kernel = fused;
    validation::add_box(block, r3(x0, y0, z0), r3(kH, kH, thickness));
    scene.bodies.push_back(block);
  }
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(-validation::kFar, y0, z0),
                                                  r3(validation::kFar, validation::kFar, z0 + thickness), dx,
                                                  validation::WallFit::LastWallNodePlane));
  Engine engine(scene);
  const std::vector<Vec3d> x_ref = engine.positions(0);
  const std::size_t n = x_ref.size();
  const double mass = engine.total_mass();
  auto com_y = [&]() {
    double s = 0;
    const auto& x = engine.positions(0);
    const auto& m = engine.masses(0);
    for (std::size_t p = 0; p < n; ++p) s += m[p] * x[p][1];
    return s / mass;
  };
  auto com_vy = [&]() { return engine.total_momentum()[1] / mass; };
  const double y_com0 = com_y();

  // Running time integrals (trapezoid) of the particle pressures and the centre-of-mass height, with snapshots at
  // the upward zero crossings of the centre-of-mass velocity (interpolated between the two steps around it).
  std::vector<double> integral(n, 0.0), previous_integral(n, 0.0);
  std::vector<double> p_prev(n, 0.0);
  double y_integral = 0.0, y_prev = y_com0, v_prev = 0.0;
  struct Snapshot {
    double t, y_integral;
    std::vector<double> integral;
  };
  std::vector<Snapshot> crossings;
  LockingResult r;
  r.particles = n;
  const double period_estimate = 4 * kH / std::sqrt(kE / (1 - nu * nu) / kRho);
  while (static_cast<int>(crossings.size()) <= periods_wanted && engine.time() < 30 * period_estimate) {
    const double t0 = engine.time();
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return r;
    }
    ++r.steps;
    const double t1 = engine.time(), dt = t1 - t0;
    const std::vector<double> p = engine.pressures(0);
    previous_integral = integral;
    for (std::size_t i = 0; i < n; ++i) integral[i] += 0.5 * dt * (p_prev[i] + p[i]);
    p_prev = p;
    const double y = com_y(), v = com_vy();
    const double y_integral_before = y_integral;
    y_integral += 0.5 * dt * (y_prev + y);
    y_prev = y;
    if (v_prev < 0.0 && v >= 0.0) {
      const double f = -v_prev / (v - v_prev);
      Snapshot snap{t0 + f * dt, y_integral_before + f * (y_integral - y_integral_before), std::vector<double>(n)};
      for (std::size_t i = 0; i < n; ++i)
        snap.integral[i] = previous_integral[i] + f * (integral[i] - previous_integral[i]);
      crossings.push_back(std::move(snap));
    }
    v_prev = v;
  }
  if (crossings.size() < 3) {
    ADD_FAILURE() << "fewer than two oscillation periods in " << engine.time() << " s";
    return r;
  }
  const Snapshot& a = crossings.front();
  const Snapshot& b = crossings.back();
  const double span = b.t - a.t;
  r.periods = static_cast<int>(crossings.size()) - 1;
  const double settlement = y_com0 - (b.y_integral - a.y_integral) / span;
  r.settlement_ratio = settlement / (kRho * kG * (1 - nu * nu) * kH * kH / (3 * kE));

  const double scale = kRho * kG * kH;
  std::vector<double> mean_p(n);
  std::map<std::tuple<int, int, int>, std::pair<double, int>> cells;  // cell of the reference position
  auto cell_of = [&](const Vec3d& x) {
    return std::make_tuple(static_cast<int>(std::floor(x[0] / dx)), static_cast<int>(std::floor(x[1] / dx)),
                           static_cast<int>(std::floor(x[2] / dx)));
  };
  double err2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mean_p[i] = (b.integral[i] - a.integral[i]) / span;
    const double exact = kRho * kG * (y0 + kH - x_ref[i][1]) * (1 + nu) / 3;
    err2 += (mean_p[i] - exact) * (mean_p[i] - exact);
    auto& c = cells[cell_of(x_ref[i])];
    c.first += mean_p[i];
    ++c.second;
  }
  double cb2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& c = cells[cell_of(x_ref[i])];
    const double d = mean_p[i] - c.first / c.second;
    cb2 += d * d;
  }
  r.pressure_rms = std::sqrt(err2 / n) / scale;
  r.checkerboard = std::sqrt(cb2 / n) / scale;
  r.ok = true;
  r.seconds = clock.seconds();
  std::printf("%s block nu %.4f psi %.2f dx %.4f: settlement / exact %.4f, pressure RMS error %.4f rho g H, "
              "checkerboard %.4f rho g H (%d periods, %lld steps, %zu particles, %.1f s)\n",
              mesh ? "FEM" : "particle", nu, psi, dx, r.settlement_ratio, r.pressure_rms, r.checkerboard, r.periods, r.steps, r.particles,
              r.seconds);
  return r;
}

}  // namespace locking_case
}  // namespace fbar
