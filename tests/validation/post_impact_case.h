// Validation: an FEM post hit by an MPM flow, against the same post as particles.
//
// Problem (a slab, 2 cells thick along z between Slip walls): a water column (JFluid, rho 1000 kg/m^3, K 1e5 Pa,
// 0.2 m wide, 0.2 m tall, started hydrostatic) collapses along a Slip floor onto an elastic post 0.3 m downstream
// (0.04 m wide, 0.12 m above the floor, rho 1000 kg/m^3, E 1e7 Pa, nu 0.3), whose foot runs 3 cells into the floor
// and is clamped there by a Sticky Box that the water's stencils never reach (its top 2 cells below the floor). A grid
// sensor reads the Box's BoundaryForce along x: what the post passes to its clamp, the water's load on it. The post
// is an FEM mesh (cubes of dx, Kuhn's six tetrahedra) or a FixedCorotated particle body (8 particles per cell); both
// carry the same water the same way, so their clamp forces must agree: the impulse (the time integral of the force)
// over the impact and the mean force afterwards, when the water banks up against the post.
// Templated on the engine for the GPU validation to come.
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

namespace fbar::post_impact_case {

using validation::r3;

constexpr double kDx = 0.02;                            // [m]
constexpr double kColumn = 0.2;                         // [m] the water column's width and height
constexpr double kGap = 0.3;                            // [m] from the column's face to the post
constexpr double kPostW = 0.04, kPostH = 0.12;          // [m]
constexpr double kEmbed = 3 * kDx;                      // [m] of the post below the floor
constexpr double kG = 9.81;
constexpr double kTEnd = 0.6;                           // [s]

struct Result {
  bool ok = false;
  std::string message;
  std::vector<double> t, force;  // [s], [N] the clamp's BoundaryForce along x, every step
  long long steps = 0;
  double seconds = 0;
  /// [N s] the integral of the force over [t0, t1]
  double impulse(double t0, double t1) const {
    double s = 0;
    for (std::size_t i = 1; i < t.size(); ++i)
      if (t[i] > t0 && t[i] <= t1) s += force[i] * (t[i] - t[i - 1]);
    return s;
  }
  double mean(double t0, double t1) const { return impulse(t0, t1) / (t1 - t0); }
};

template <class Engine = CpuEngine<double>>
Result run(bool mesh) {
  validation::Stopwatch clock;
  const double x0 = 2 * kDx, y0 = 6 * kDx, z0 = 2 * kDx, t = 2 * kDx;  // tank's low faces (floor at y0), thickness
  const double xp = x0 + kColumn + kGap;                                // the post's upstream face
  Scene scene = validation::make_scene(r3(xp + kPostW + 0.3, y0 + 0.4, z0 + t + 2 * kDx), kDx, r3(0, -kG, 0));
  BodySpec water = validation::jfluid_body(1000.0, 1e5, 7.0, 1e-3);
  water.initial_state = InitialState::Hydrostatic;
  validation::add_box(water, r3(x0, y0, z0), r3(kColumn, kColumn, t));
  scene.bodies.push_back(water);
  const Vec3d lo{{xp, y0 - kEmbed, z0}}, hi{{xp + kPostW, y0 + kPostH, z0 + t}};
  if (mesh) {
    test::add_elastic_mesh(scene,
                           box_tet_mesh(lo, hi, Vec3i{{static_cast<int>(std::lround(kPostW / kDx)),
                                                       static_cast<int>(std::lround((kPostH + kEmbed) / kDx)),
                                                       static_cast<int>(std::lround(t / kDx))}}),
                           1000.0, 1e7, 0.3);
  } else {
    BodySpec post = validation::fixed_corotated_body(1000.0, 1e7, 0.3);
    validation::add_box(post, r3(lo[0], lo[1], lo[2]), r3(kPostW, kPostH + kEmbed, t));
    scene.bodies.push_back(post);
  }
  // Floor and ends: Slip walls (the water slides); the post's foot below the floor is held by the Sticky Box.
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(x0, y0, z0), r3(scene.simulation.domain[0] - 2 * kDx,
                                                  validation::kFar, z0 + t), kDx, validation::WallFit::LastWallNodePlane));
  BoundarySpec clamp;
  clamp.object = BoundaryObject::Box;
  clamp.contact = Contact::Sticky;
  clamp.domain_start = r3(xp - kDx, 0.0, 0.0);
  clamp.domain_end = r3(xp + kPostW + kDx, y0 - 2 * kDx, scene.simulation.domain[2]);
  scene.boundaries.push_back(clamp);
  Engine engine(scene);
  engine.set_log(nullptr);
  GridSensorSpec sensor;
  sensor.attribute = "BoundaryForce";
  sensor.operation = SensorOperation::Sum;
  sensor.direction = r3(1, 0, 0);
  sensor.domain_start = clamp.domain_start;
  sensor.domain_end = clamp.domain_end;
  engine.set_grid_sensors({sensor});
  engine.set_grid_sample(0);
  Result r;
  r.t.push_back(0.0);
  r.force.push_back(0.0);
  while (engine.time() < kTEnd) {
    const StepReport s = engine.step_toward(kTEnd);
    if (!s.ok) {
      r.message = s.message();
      return r;
    }
    r.t.push_back(engine.time());
    r.force.push_back(engine.grid_samples(1)[0].sum.value());
  }
  r.ok = true;
  r.steps = engine.steps();
  r.seconds = clock.seconds();
  return r;
}

/// The test's assertions on `Engine` (the CPU test and the GPU engine's run the same).
template <class Engine = CpuEngine<double>>
void expect_carries_the_flow_like_the_particle_post() {
  const Result fem = run<Engine>(true);
  ASSERT_TRUE(fem.ok) << fem.message;
  const Result particles = run<Engine>(false);
  ASSERT_TRUE(particles.ok) << particles.message;
  for (double t0 : {0.0, 0.1, 0.2, 0.3, 0.4, 0.5})
    std::printf("[ post ] t %.1f-%.1f s: mean clamp force FEM %.4g N, particles %.4g N\n", t0, t0 + 0.1,
                fem.mean(t0, t0 + 0.1), particles.mean(t0, t0 + 0.1));
  std::printf("[ post ] impulse 0-0.6 s: FEM %.4g N s, particles %.4g N s; peak %.4g / %.4g N; steps %lld / %lld, "
              "%.1f / %.1f s\n",
              fem.impulse(0, kTEnd), particles.impulse(0, kTEnd), *std::max_element(fem.force.begin(), fem.force.end()),
              *std::max_element(particles.force.begin(), particles.force.end()), fem.steps, particles.steps,
              fem.seconds, particles.seconds);
  EXPECT_NEAR(fem.impulse(0, kTEnd), particles.impulse(0, kTEnd), 0.10 * particles.impulse(0, kTEnd));
  EXPECT_NEAR(fem.mean(0.2, kTEnd), particles.mean(0.2, kTEnd), 0.10 * particles.mean(0.2, kTEnd));
  const double peak_fem = *std::max_element(fem.force.begin(), fem.force.end());
  const double peak_particles = *std::max_element(particles.force.begin(), particles.force.end());
  EXPECT_NEAR(peak_fem, peak_particles, 0.15 * peak_particles);
  EXPECT_LT(std::fabs(fem.mean(0, 0.15)), 0.01);
  EXPECT_LT(std::fabs(particles.mean(0, 0.15)), 0.01);
  EXPECT_GT(particles.mean(0.2, kTEnd), 1.0);  // the water loads the post
}


}  // namespace fbar::post_impact_case
