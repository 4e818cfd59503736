// Grid compaction (GpuEngineOptions::compact_grid, MgspBenchmark::compact_grid): blocks crossing the domain leave
// grid blocks behind them; between steps the engine drops those no particle uses any more and renumbers the rest.
// The run must give the same bytes as one that keeps every block, its block count must stay near what the bodies
// cover (the other run's grows with the distance travelled), and the bodies must still move as the CPU engine's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>

#include "engine/cpu/cpu_engine.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"

namespace fbar {
namespace {

/// Two blocks crossing a 3 m domain along x in opposite directions (in separate lanes of y), without gravity or
/// walls: a JFluid block at +4 m/s and a NeoHookean one at -4 m/s (K 1e4 Pa, E 1e5 Pa: wave speeds ~3 and ~12 m/s,
/// CFL step above 1e-3 s). 0.5 s: 2 m, 40 cells, 10 grid blocks of travel for blocks 1.5-2 grid blocks long.
/// schemes: the JFluid block with ASFLIP and F-bar (the transported momentum and the cell sums), the other with F-bar.
Scene crossing_blocks(Precision precision, bool schemes) {
  Scene scene = test::small_scene(Constitutive::JFluid, precision, {4.0, 0.0, 0.0}, false);
  scene.simulation.domain = {3.0, 1.0, 1.0};
  scene.simulation.gravity = {0.0, 0.0, 0.0};
  BodySpec& water = scene.bodies[0];
  water.material.bulk_modulus = 1e4;
  water.geometry[0].offset = {0.2, 0.1, 0.35};
  water.output_attribs = {"ID"};
  BodySpec solid = water;
  solid.material.law = Constitutive::NeoHookean;
  solid.geometry[0].offset = {2.5, 0.5, 0.35};
  solid.velocity = {-4.0, 0.0, 0.0};
  if (schemes) {
    water.algorithm.use_asflip = true;
    water.algorithm.asflip_alpha = 0.9;
    water.algorithm.asflip_beta_min = 0.0;
    water.algorithm.asflip_beta_max = 0.2;
    water.algorithm.use_fbar = true;
    water.algorithm.fbar_psi = 1.0;
    water.algorithm.fbar_scheme = FbarScheme::Cell;
    solid.algorithm.use_fbar = true;
    solid.algorithm.fbar_psi = 0.5;
    solid.algorithm.fbar_scheme = FbarScheme::Cell;
  }
  scene.bodies.push_back(solid);
  return scene;
}

template <typename T, typename TG>
void expect_compaction_changes_no_bit(bool schemes) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = crossing_blocks(std::is_same_v<T, float> ? Precision::Single : Precision::Double, schemes);
  const auto positions = test::sample_scene(scene);
  GpuEngineOptions keep;
  keep.compact_grid = false;
  GpuEngine<T, TG> compacting(scene, positions);
  GpuEngine<T, TG> keeping(scene, positions, keep);
  CpuEngine<T, TG> cpu(scene, positions);
  for (auto* e : {&compacting, &keeping}) {
    e->set_log(nullptr);
    e->set_record_velocities(true);
  }
  const std::size_t start_blocks = compacting.active_grid_blocks();
  std::size_t most_blocks = start_blocks;
  const double dt = 1e-3;
  const int steps = 500;
  for (int s = 0; s < steps; ++s) {
    ASSERT_TRUE(compacting.step(dt).ok) << "step " << s;
    ASSERT_TRUE(keeping.step(dt).ok) << "step " << s;
    ASSERT_TRUE(cpu.step(dt).ok) << "step " << s;
    most_blocks = std::max(most_blocks, compacting.active_grid_blocks());
  }
  std::cout << "[measured] grid compaction: blocks at start " << start_blocks << ", most while compacting "
            << most_blocks << ", at the end " << compacting.active_grid_blocks() << " (keeping every block: "
            << keeping.active_grid_blocks() << "), " << compacting.grid_compactions() << " compactions dropped "
            << compacting.compacted_blocks() << " blocks\n";
  EXPECT_EQ(keeping.grid_compactions(), 0);
  // 63 blocks in use: a compaction once 64 more accumulated (the floor of the 1/8 rule), twice over the run.
  EXPECT_GE(compacting.grid_compactions(), 2) << "the blocks travelled 10 grid blocks";
  // Kept: the bodies' footprint and at most 1/8 more (64 blocks at least) before a compaction, plus one step's new
  // blocks. Without compaction the table holds every block the bodies crossed (3x the start here).
  EXPECT_LE(most_blocks, start_blocks + std::max<std::size_t>(start_blocks / 8, 64) + 16);
  EXPECT_GT(keeping.active_grid_blocks(), 3 * start_blocks);
  for (int b = 0; b < compacting.body_count(); ++b) {
    SCOPED_TRACE("body " + std::to_string(b));
    const ParticleSnapshot<T> c = compacting.snapshot(b), k = keeping.snapshot(b);
    ASSERT_EQ(c.x.size(), k.x.size());
    EXPECT_EQ(std::memcmp(c.x.data(), k.x.data(), sizeof(c.x[0]) * c.x.size()), 0) << "positions differ";
    EXPECT_EQ(std::memcmp(c.v.data(), k.v.data(), sizeof(c.v[0]) * c.v.size()), 0) << "velocities differ";
    EXPECT_EQ(std::memcmp(c.J.data(), k.J.data(), sizeof(c.J[0]) * c.J.size()), 0) << "J differs";
    // The physics: as the CPU engine, and each block's centroid carried 2 m (4 m/s x 0.5 s; no force acts on it).
    const double ex = test::max_diff(c.x, cpu.positions(b));
    const double tolerance = std::is_same_v<TG, float> ? 1e-4 : 1e-11;
    EXPECT_LE(ex, tolerance) << "NaN fails too";
    double shift = 0.0;
    for (std::size_t p = 0; p < c.x.size(); ++p) shift += static_cast<double>(c.x[p][0]) - positions[b][p][0];
    shift /= static_cast<double>(c.x.size());
    const double expected = (b == 0 ? 4.0 : -4.0) * dt * steps;
    EXPECT_NEAR(shift, expected, 1e-4 * std::fabs(expected));
    std::cout << "[measured] body " << b << ": |x - x_cpu| " << ex << " m, centroid moved " << shift << " m\n";
  }
}

TEST(GridCompaction, CrossingBlocksChangeNoBitFloat) { expect_compaction_changes_no_bit<float, float>(false); }
TEST(GridCompaction, CrossingBlocksWithAsflipAndFbarChangeNoBitDouble) {
  expect_compaction_changes_no_bit<double, double>(true);
}
TEST(GridCompaction, CrossingBlocksWithAsflipAndFbarChangeNoBitMixed) {
  expect_compaction_changes_no_bit<double, float>(true);
}

}  // namespace
}  // namespace fbar
