// Validation: an FEM post hit by an MPM flow, against the same post as particles (issue 34). The problem and the run
// are in post_impact_case.h.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "post_impact_case.h"

namespace fbar {
namespace {

using namespace post_impact_case;

// Measured on this machine (2026-11-28, dx 0.02 m): the water reaches the post at 0.15-0.2 s; clamp force FEM /
// particles: impulse over 0-0.6 s 1.242 / 1.326 N s (-6.3 %), mean over 0.2-0.6 s 3.10 / 3.32 N (-6.6 %; per 0.1 s
// window -10 %, +2 %, -5 %, -13 %), peak 10.24 / 10.94 N (-6.4 %); before the water arrives the clamp reads 1.5e-4 N
// (FEM: the post settling under its weight) and 1e-14 N. The two posts meet the water on the grid with different
// footprints (a vertex per cell corner against 8 particles per cell), which is the size of the difference.
// Tolerances: impulse and mean force within 10 %, peak within 15 %, before the water arrives under 0.01 N. A post of
// half the mass or twice the stiffness moves each by less than that, but a post that lets the water through (no
// coupling) or a clamp that does not hold it reads nothing: both fail.
TEST(PostImpact, FemPostCarriesTheFlowLikeTheParticlePost) {
  const Result fem = run(true);
  ASSERT_TRUE(fem.ok) << fem.message;
  const Result particles = run(false);
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

}  // namespace
}  // namespace fbar
