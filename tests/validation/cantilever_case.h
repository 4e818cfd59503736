// Validation: an FEM cantilever under its own weight (the coupling of physics/fem.cuh).
//
// Problem: a beam of length L = 1 m, square section h = b = 0.1 m (L / h = 10), rho = 1000 kg/m^3, E = 3e8 Pa,
// nu = 0.25, FixedCorotated tetrahedra (Kuhn's six per cube, geometry/tet_mesh.h box_tet_mesh), clamped at x = x0 by
// a Sticky wall on the grid (the beam runs 2 dx into it: its vertices there see only held nodes), loaded by gravity
// from rest. References (small deflection, static tip deflection 4.9 mm = L / 204):
//   Euler-Bernoulli  delta_EB = q L^4 / (8 E I),  q = rho g b h,  I = b h^3 / 12
//   Timoshenko       delta_T  = delta_EB + q L^2 / (2 kappa G A),  kappa = 10 (1 + nu) / (12 + 11 nu) (Cowper),
//                    G = E / (2 (1 + nu)): +1.03 % for this beam
//   first bending frequency  f_EB = (1.87510^2 / (2 pi)) sqrt(E I / (rho A)) / L^2 = 8.85 Hz; with shear (Dunkerley's
//                    combination with the shear beam's pi/(2L) sqrt(kappa G / rho)) f_T = f_EB / sqrt(1 + (f_EB/f_S)^2)
//                    = 8.80 Hz (-0.6 %); rotary inertia lowers it by a further ~0.3 % (not in the reference).
// Measured: the tip's vertical displacement u(t) (mean of the vertices of the end face x = x0 + L). Started from
// rest the beam swings about its static deflection: u = delta (1 - cos(2 pi f t)) for the first mode (97 % of the
// static tip deflection; APIC keeps the swing undamped); so delta = u_max / 2 and f = 1 / (2 t_max), u_max the
// first largest u at t_max (a parabola through the three samples around it), over 0.65 / f_T.
// Mesh sizes: n = 2, 4, 8 cubes through the thickness (cube side a = h / n), grid dx = 2 a (2 vertices per cell
// along each axis, ClaymoreUW's use of meshes as particle carriers).
// Shared by the CPU validation test and (later) the GPU engine's: the run is templated on the engine.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdio>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "geometry/tet_mesh.h"
#include "scene/scene_parse.h"
#include "../physics/physics_test_support.h"
#include "validation_support.h"

namespace fbar::cantilever_case {

using validation::kPi;
using validation::r3;

constexpr double kL = 1.0, kH = 0.1, kB = 0.1;  // [m]
constexpr double kRho = 1000.0;                 // [kg/m^3]
constexpr double kE = 3e8;                      // [Pa]
constexpr double kNu = 0.25;
constexpr double kG = 9.81;                     // [m/s^2]

struct Reference {
  double delta_eb, delta_t;  // [m] static tip deflection: Euler-Bernoulli, Timoshenko
  double f_eb, f_t;          // [Hz] first bending frequency: Euler-Bernoulli, with shear (Dunkerley)
};

inline Reference reference() {
  const double A = kB * kH, I = kB * kH * kH * kH / 12.0, q = kRho * kG * A;
  const double shear_modulus = kE / (2 * (1 + kNu)), kappa = 10 * (1 + kNu) / (12 + 11 * kNu);
  Reference r;
  r.delta_eb = q * std::pow(kL, 4) / (8 * kE * I);
  r.delta_t = r.delta_eb + q * kL * kL / (2 * kappa * shear_modulus * A);
  const double beta = 1.87510407;
  r.f_eb = beta * beta / (2 * kPi) * std::sqrt(kE * I / (kRho * A)) / (kL * kL);
  const double f_shear = 1.0 / (4 * kL) * std::sqrt(kappa * shear_modulus / kRho);  // (pi / 2L) sqrt(kG/rho) / 2pi
  r.f_t = r.f_eb / std::sqrt(1 + (r.f_eb / f_shear) * (r.f_eb / f_shear));
  return r;
}

struct Result {
  bool ok = false;
  std::string message;
  double delta = 0, frequency = 0;  // [m], [Hz]
  long long steps = 0;
  std::size_t vertices = 0, elements = 0;
  double seconds = 0;
};

/// The beam with n cubes through its thickness; `fbar` runs ClaymoreUW's Tetrahedron_FBar elements.
template <class Engine = CpuEngine<double>>
Result run(int n, bool fbar = false) {
  validation::Stopwatch clock;
  const double a = kH / n, dx = 2 * a;
  const double x0 = 4 * dx, y0 = 4 * dx, z0 = 2 * dx;  // the clamp plane x0 and the beam's low faces (node planes)
  const double embed = 2 * dx;                        // of the beam inside the clamp
  Scene scene = validation::make_scene(r3(x0 + kL + 4 * dx, y0 + kH + 4 * dx, z0 + kB + 2 * dx), dx, r3(0, -kG, 0));
  const int along = static_cast<int>(std::lround((kL + embed) / a));
  MeshEntrySpec& m = test::add_elastic_mesh(
      scene, box_tet_mesh(Vec3d{{x0 - embed, y0, z0}}, Vec3d{{x0 + kL, y0 + kH, z0 + kB}}, Vec3i{{along, n, n}}), kRho,
      kE, kNu);
  m.fbar_elements = fbar;  // the elements' (not copied to the body)
  scene.boundaries.push_back(validation::wall_box(Contact::Sticky, r3(x0, -validation::kFar, -validation::kFar),
                                                  r3(validation::kFar, validation::kFar, validation::kFar), dx,
                                                  validation::WallFit::LastWallNodePlane));
  Engine engine(scene);
  std::vector<std::size_t> tip;
  // A copy: positions() may return a cache that the next step replaces (the GPU engine's snapshot).
  const auto x_start = engine.positions(0);
  for (std::size_t v = 0; v < x_start.size(); ++v)
    if (std::fabs(static_cast<double>(x_start[v][0]) - (x0 + kL)) < 1e-9) tip.push_back(v);
  auto tip_y = [&] {
    double s = 0;
    const auto& x = engine.positions(0);  // once a step (the GPU engine downloads a snapshot per call)
    for (std::size_t v : tip) s += static_cast<double>(x[v][1]);
    return s / static_cast<double>(tip.size());
  };
  const double y_start = tip_y();
  const Reference ref = reference();
  const double t_end = 0.65 / ref.f_t;
  std::vector<double> t{0.0}, u{0.0};
  Result r;
  while (engine.time() < t_end) {
    const StepReport s = engine.step();
    if (!s.ok) {
      r.message = s.message();
      return r;
    }
    t.push_back(engine.time());
    u.push_back(y_start - tip_y());  // downwards positive
  }
  // The first largest u (the half period), refined by a parabola through its neighbours (equal steps there).
  std::size_t k = 0;
  for (std::size_t i = 1; i < u.size(); ++i)
    if (u[i] > u[k]) k = i;
  double t_max = t[k], u_max = u[k];
  if (k > 0 && k + 1 < u.size()) {
    const double denom = u[k - 1] - 2 * u[k] + u[k + 1];
    const double h = 0.5 * (t[k + 1] - t[k - 1]);
    if (denom < 0) {
      const double s = 0.5 * (u[k - 1] - u[k + 1]) / denom;  // in steps, |s| <= 1/2
      t_max = t[k] + s * h;
      u_max = u[k] - 0.25 * (u[k - 1] - u[k + 1]) * s;
    }
  }
  if (k + 1 >= u.size()) {
    r.message = "the tip was still going down at the end of the run";
    return r;
  }
  r.ok = true;
  r.delta = 0.5 * u_max;
  r.frequency = 1.0 / (2 * t_max);
  r.steps = engine.steps();
  r.vertices = x_start.size();
  r.elements = scene.meshes[0].mesh->elements.size();
  r.seconds = clock.seconds();
  return r;
}

/// The test's assertions on `Engine` (the CPU test and the GPU engine's run the same).
template <class Engine = CpuEngine<double>>
void expect_converges_to_timoshenko() {
  const Reference ref = reference();
  double delta[3], f[3];
  const int sizes[3] = {2, 4, 8};
  for (int i = 0; i < 3; ++i) {
    const Result r = run<Engine>(sizes[i]);
    ASSERT_TRUE(r.ok) << r.message;
    delta[i] = r.delta;
    f[i] = r.frequency;
    std::printf("[ cantilever ] n = %d: %zu vertices, %zu tetrahedra, %lld steps, %.1f s: tip deflection %.5g m "
                "(%+.2f %% of Timoshenko %.5g m), first frequency %.5g Hz (%+.2f %% of %.5g Hz)\n",
                sizes[i], r.vertices, r.elements, r.steps, r.seconds, r.delta, 100 * (r.delta / ref.delta_t - 1),
                ref.delta_t, r.frequency, 100 * (r.frequency / ref.f_t - 1), ref.f_t);
  }
  double e_delta[3], e_f[3];
  for (int i = 0; i < 3; ++i) {
    e_delta[i] = std::fabs(delta[i] / ref.delta_t - 1);
    e_f[i] = std::fabs(f[i] / ref.f_t - 1);
  }
  EXPECT_LT(e_delta[2], 0.04);
  EXPECT_LT(e_f[2], 0.03);
  for (int i = 1; i < 3; ++i) {
    EXPECT_LT(e_delta[i], 0.5 * e_delta[i - 1]) << "n = " << sizes[i];
    EXPECT_LT(e_f[i], 0.5 * e_f[i - 1]) << "n = " << sizes[i];
  }
  const double order_delta = std::log2(e_delta[1] / e_delta[2]), order_f = std::log2(e_f[1] / e_f[2]);
  const double delta_extrapolated = delta[2] + (delta[2] - delta[1]) / 3, f_extrapolated = f[2] + (f[2] - f[1]) / 3;
  std::printf("[ cantilever ] observed order %.2f (deflection), %.2f (frequency); extrapolated %.5g m (%+.2f %%), "
              "%.5g Hz (%+.2f %%)\n",
              order_delta, order_f, delta_extrapolated, 100 * (delta_extrapolated / ref.delta_t - 1), f_extrapolated,
              100 * (f_extrapolated / ref.f_t - 1));
  EXPECT_GT(order_delta, 1.5);
  EXPECT_GT(order_f, 1.5);
  EXPECT_NEAR(delta_extrapolated, ref.delta_t, 0.03 * ref.delta_t);
  EXPECT_NEAR(f_extrapolated, ref.f_t, 0.01 * ref.f_t);
}


}  // namespace fbar::cantilever_case
