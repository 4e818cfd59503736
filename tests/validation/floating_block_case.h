// Validation: an FEM block floating in MPM water, against Archimedes and against the same block as particles.
//
// Problem (a slab: everything 2 cells thick along z between Slip walls): water (JFluid, rho 1000 kg/m^3, K 1e5 Pa,
// started hydrostatic) fills a tank 0.8 m long to 0.2 m; a block 0.2 m long and 0.1 m tall, rho 500 kg/m^3
// (FixedCorotated, E 2e5 Pa, nu 0.3), floats in its middle. Archimedes: draft d = (rho_s / rho_w) h = 0.05 m, so the
// block starts there, its bottom 0.15 m above the floor and the water's surface at 0.2 m on both sides (the water's
// geometry is the tank's box less the block's submerged part: the surface starts level). The run lasts 1.5 s (3.3
// heave periods 2 pi sqrt(d / g) = 0.45 s); the draft is the water's surface (its hydrostatic start keeps it at
// 0.2 m) less the block's mean bottom (centroid - h / 2) over 0.6 .. 1.5 s (two heave periods).
// The block is an FEM mesh (cubes of dx, Kuhn's six tetrahedra) or, for comparison, a FixedCorotated particle
// body (8 particles per cell). Templated on the engine for the GPU validation to come.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "geometry/tet_mesh.h"
#include "scene/scene_parse.h"
#include "../physics/physics_test_support.h"
#include "validation_support.h"

namespace fbar::floating_case {

using validation::r3;

constexpr double kDx = 0.02;                        // [m]
constexpr double kTank = 0.8, kDepth = 0.2;         // [m]
constexpr double kBlockL = 0.2, kBlockH = 0.1;      // [m]
constexpr double kRhoW = 1000.0, kRhoS = 500.0;     // [kg/m^3]
constexpr double kDraft = kRhoS / kRhoW * kBlockH;  // [m] 0.05
constexpr double kG = 9.81;

struct Result {
  bool ok = false;
  std::string message;
  double draft = 0;        // [m] mean over the averaging window
  double heave_range = 0;  // [m] max - min of the centroid over the window
  long long steps = 0;
  double seconds = 0;
};

/// mesh: the block as an FEM body, else as particles.
template <class Engine = CpuEngine<double>>
Result run(bool mesh) {
  validation::Stopwatch clock;
  const double x0 = 2 * kDx, y0 = 2 * kDx, z0 = 2 * kDx, t = 2 * kDx;  // the tank's low faces; slab thickness
  Scene scene = validation::make_scene(r3(x0 + kTank + 2 * kDx, y0 + 0.4, z0 + t + 2 * kDx), kDx, r3(0, -kG, 0));
  const double xb = x0 + 0.5 * (kTank - kBlockL), yb = y0 + kDepth - kDraft;  // the block's low corner
  BodySpec water = validation::jfluid_body(kRhoW, 1e5, 7.0, 1e-3);
  water.initial_state = InitialState::Hydrostatic;
  validation::add_box(water, r3(x0, y0, z0), r3(kTank, kDepth, t));
  GeometrySpec hole;
  hole.object = GeometryObject::Box;
  hole.operation = GeometryOperation::Subtract;
  hole.offset = r3(xb, yb, z0 - kDx);
  hole.span = r3(kBlockL, kBlockH, t + 2 * kDx);
  water.geometry.push_back(hole);
  scene.bodies.push_back(water);
  if (mesh) {
    const double a = kDx;
    test::add_elastic_mesh(scene,
                           box_tet_mesh(Vec3d{{xb, yb, z0}}, Vec3d{{xb + kBlockL, yb + kBlockH, z0 + t}},
                                        Vec3i{{static_cast<int>(std::lround(kBlockL / a)),
                                               static_cast<int>(std::lround(kBlockH / a)),
                                               static_cast<int>(std::lround(t / a))}}),
                           kRhoS, 2e5, 0.3);
  } else {
    BodySpec block = validation::fixed_corotated_body(kRhoS, 2e5, 0.3);
    validation::add_box(block, r3(xb, yb, z0), r3(kBlockL, kBlockH, t));
    scene.bodies.push_back(block);
  }
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(x0, y0, z0), r3(x0 + kTank, validation::kFar, z0 + t),
                                                  kDx, validation::WallFit::LastWallNodePlane));
  Engine engine(scene);
  engine.set_log(nullptr);
  Result r;
  auto centroid_y = [&] {
    double m = 0, my = 0;
    for (std::size_t i = 0; i < engine.positions(1).size(); ++i) {
      const double mi = static_cast<double>(engine.masses(1)[i]);
      m += mi;
      my += mi * static_cast<double>(engine.positions(1)[i][1]);
    }
    return my / m;
  };
  double sum = 0, lo = 1e9, hi = -1e9;
  long long n = 0;
  const double t_window = 0.6, t_end = 1.5;
  while (engine.time() < t_end) {
    const StepReport s = engine.step_toward(t_end);
    if (!s.ok) {
      r.message = s.message();
      return r;
    }
    if (engine.time() >= t_window) {
      const double c = centroid_y();
      sum += c;
      lo = std::min(lo, c);
      hi = std::max(hi, c);
      ++n;
    }
  }
  const double surface = y0 + kDepth;
  r.ok = n > 0;
  r.draft = surface - (sum / static_cast<double>(n) - 0.5 * kBlockH);
  r.heave_range = hi - lo;
  r.steps = engine.steps();
  r.seconds = clock.seconds();
  return r;
}

/// The test's assertions on `Engine` (the CPU test and the GPU engine's run the same).
template <class Engine = CpuEngine<double>>
void expect_floats_like_the_particle_block() {
  const Result fem = run<Engine>(true);
  ASSERT_TRUE(fem.ok) << fem.message;
  const Result particles = run<Engine>(false);
  ASSERT_TRUE(particles.ok) << particles.message;
  std::printf("[ floating ] Archimedes draft %.4g m; FEM block %.4g m (%+.2f dx), heave range %.3g m, %lld steps, "
              "%.1f s; particle block %.4g m (%+.2f dx), heave range %.3g m, %lld steps, %.1f s\n",
              kDraft, fem.draft, (fem.draft - kDraft) / kDx, fem.heave_range, fem.steps, fem.seconds,
              particles.draft, (particles.draft - kDraft) / kDx, particles.heave_range, particles.steps,
              particles.seconds);
  EXPECT_NEAR(fem.draft, kDraft, 0.04 * kDraft);
  EXPECT_NEAR(particles.draft, kDraft, 0.04 * kDraft);
  EXPECT_NEAR(fem.draft, particles.draft, 0.05 * kDx);
  EXPECT_LT(fem.heave_range, 0.05 * kDx);
  EXPECT_LT(particles.heave_range, 0.05 * kDx);
}


}  // namespace fbar::floating_case
