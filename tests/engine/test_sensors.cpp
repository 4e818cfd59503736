// Grid sensors (physics/sensors.cuh, io/sensor_recorder.h) on the CPU engine: the reductions, what a node
// contributes, the exact sample times of the run loop, a moving block's momentum and mass, and the same sums on 1
// and 2 ranks. The hydrostatic load cell (a wall's force against rho g h^2 / 2) is in tests/validation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cpu/decomposition_scenes.h"
#include "engine/cpu/cpu_engine.h"
#include "engine/engine_api.h"
#include "io/sensor_recorder.h"
#include "../physics/physics_test_support.h"
#include "run_support.h"

namespace fbar {
namespace {

using test::grid_sensor_spec;
using test::particle_sensor_spec;

TEST(SensorReduction, OperationsFromTheAccumulator) {
  SensorAccum a;
  for (double v : {2.0, -1.0, 4.0, 3.0}) a.add(v);
  EXPECT_DOUBLE_EQ(sensor_result(SensorOperation::Sum, a), 8.0);
  EXPECT_DOUBLE_EQ(sensor_result(SensorOperation::Count, a), 4.0);
  EXPECT_DOUBLE_EQ(sensor_result(SensorOperation::Average, a), 2.0);
  EXPECT_DOUBLE_EQ(sensor_result(SensorOperation::Max, a), 4.0);
  EXPECT_DOUBLE_EQ(sensor_result(SensorOperation::Min, a), -1.0);
  // population variance: ((0)^2 + 3^2 + 2^2 + 1^2) / 4 = 3.5
  EXPECT_NEAR(sensor_result(SensorOperation::Variance, a), 3.5, 1e-14);
  EXPECT_NEAR(sensor_result(SensorOperation::STDEV, a), std::sqrt(3.5), 1e-14);
  // Merging two halves gives the whole.
  SensorAccum lo, hi;
  lo.add(2.0);
  lo.add(-1.0);
  hi.add(4.0);
  hi.add(3.0);
  lo.merge(hi);
  EXPECT_EQ(lo.sum.value(), a.sum.value());
  EXPECT_DOUBLE_EQ(lo.max, a.max);
  EXPECT_DOUBLE_EQ(lo.min, a.min);
  // No node: Sum and Count are 0, the rest undefined.
  const SensorAccum none;
  EXPECT_EQ(sensor_result(SensorOperation::Sum, none), 0.0);
  EXPECT_EQ(sensor_result(SensorOperation::Count, none), 0.0);
  EXPECT_TRUE(std::isnan(sensor_result(SensorOperation::Max, none)));
  EXPECT_TRUE(std::isnan(sensor_result(SensorOperation::Average, none)));
}

// ExactSum: any order of the same additions, and any split into merged parts, gives the same words; the value is
// the exact sum of the values rounded to 2^-100 (checked against integers whose sum a double holds exactly), and
// non-finite values win.
TEST(SensorReduction, SumsAreOrderFree) {
  std::vector<double> v;
  for (int i = 0; i < 2000; ++i) {
    const double m = std::ldexp(1.0 + (i * 7919 % 1000) / 1000.0, (i * 37) % 120 - 60);  // 2^-60 .. 2^60
    v.push_back(i % 3 == 0 ? -m : m);
  }
  ExactSum forward, backward, split;
  for (double x : v) forward.add(x);
  for (auto it = v.rbegin(); it != v.rend(); ++it) backward.add(*it);
  ExactSum part[3];
  for (std::size_t i = 0; i < v.size(); ++i) part[(i * 13) % 3].add(v[i]);
  split.merge(part[2]);
  split.merge(part[0]);
  split.merge(part[1]);
  for (int k = 0; k < ExactSum::kWords; ++k) {
    EXPECT_EQ(forward.word[k], backward.word[k]) << "word " << k;
    EXPECT_EQ(forward.word[k], split.word[k]) << "word " << k;
  }
  // A double's plain sum of the same values depends on the order; the exact one equals the long double reference to
  // the double's rounding (the values span 120 binades, so long double cancels less but is not exact either).
  long double reference = 0;
  for (double x : v) reference += x;
  EXPECT_NEAR(forward.value(), static_cast<double>(reference), 1e-15 * std::fabs(static_cast<double>(reference)));
  // Integers: exact.
  ExactSum ints;
  long long total = 0;
  double quarters = 0.0;  // exact: multiples of 0.25 below 2^50
  for (int i = -500; i < 700; ++i) {
    ints.add(static_cast<double>(i) * 1e9 + 0.25 * (i % 4));
    total += static_cast<long long>(i) * 1000000000LL;
    quarters += 0.25 * (i % 4);
  }
  EXPECT_EQ(ints.value(), static_cast<double>(total) + quarters);
  ExactSum bad;
  bad.add(1.0);
  bad.add(std::numeric_limits<double>::infinity());
  EXPECT_EQ(bad.value(), std::numeric_limits<double>::infinity());
  bad.add(-std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(bad.value()));
}

TEST(SensorReduction, NodeValuesAndDirections) {
  // A node of mass 2 kg that P2G left with momentum p = (5, -3, 0) kg m/s, in a step of dt = 0.5 s under g = (0, -1, 0)
  // m/s^2: v* = p/m + dt g = (2.5, -2, 0); a boundary then took its x velocity: v = (0, -2, 0).
  const double m = 2.0, dt = 0.5;
  const Vec3d p{{5.0, -3.0, 0.0}}, v_free{{2.5, -2.0, 0.0}}, v{{0.0, -2.0, 0.0}};
  const GridNodeSample<double> node{m, p, v_free, v, dt};
  // Force (ClaymoreUW's): p / dt, whatever the boundaries then do.
  GridSensorParams<double> s = make_grid_sensor_params<double>(
      grid_sensor_spec("Force", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}, {1, 0, 0}, 0));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 5.0 / 0.5);
  s.sign = -1;
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 0.0);  // X-: only the negative side, as a magnitude
  s.sign = 1;
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 10.0);
  s = make_grid_sensor_params<double>(grid_sensor_spec("Force", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}, {0, 1, 0}, -1));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 3.0 / 0.5);  // Y-: |p_y| / dt, gravity not included
  // BoundaryForce (fbar's): m (v* - v) / dt, only what the boundary removed: 2 x 2.5 / 0.5 along +x, nothing along y.
  s = make_grid_sensor_params<double>(
      grid_sensor_spec("BoundaryForce", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}, {1, 0, 0}, 0));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 10.0);
  s.direction = Vec3d{{0.0, 1.0, 0.0}};
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 0.0);
  s = make_grid_sensor_params<double>(grid_sensor_spec("Momentum", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}, {0, 1, 0}, -1));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 3.0);  // Y-: |p_y| of a downward momentum
  s = make_grid_sensor_params<double>(
      grid_sensor_spec("Velocity", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}, {std::sqrt(0.6), std::sqrt(0.4), 0}, 0));
  EXPECT_NEAR(grid_sensor_value(s, node), 2.5 * std::sqrt(0.6) - 1.5 * std::sqrt(0.4), 1e-15);  // (p / m) . d
  s = make_grid_sensor_params<double>(grid_sensor_spec("Acceleration", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 5.0);  // (v* - v) / dt along +x
  s = make_grid_sensor_params<double>(grid_sensor_spec("Mass", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, node), 2.0);
  // Volume and JBar: the node's sum w V and the volume-weighted mean of JBar (from sum w V (1 - JBar)); a node
  // without volume is not read.
  GridNodeSample<double> held = node;
  held.volume = 4e-3;
  held.volume_jbar = 1e-4;  // mean 1 - JBar = 0.025
  s = make_grid_sensor_params<double>(grid_sensor_spec("Volume", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1}));
  EXPECT_DOUBLE_EQ(grid_sensor_value(s, held), 4e-3);
  EXPECT_TRUE(grid_sensor_reads(s, held));
  EXPECT_FALSE(grid_sensor_reads(s, node));
  s = make_grid_sensor_params<double>(grid_sensor_spec("JBar", SensorOperation::Average, {0, 0, 0}, {1, 1, 1}));
  EXPECT_NEAR(grid_sensor_value(s, held), 0.975, 1e-15);
  EXPECT_FALSE(grid_sensor_reads(s, node));
  // The box includes its faces.
  EXPECT_TRUE(sensor_box_contains(s.lo, s.hi, Vec3d{{1.0, 0.0, 0.5}}));
  EXPECT_FALSE(sensor_box_contains(s.lo, s.hi, Vec3d{{1.0 + 1e-12, 0.0, 0.5}}));
}

// A grid sensor's box holds the nodes on its faces whatever their position's round-off (dx / 128): ClaymoreUW users
// put a box's face on a wall's node plane (x = 0.2 m at dx = 0.01: node 20, whose float position is 20 x 0.01f).
TEST(SensorReduction, BoxFacesHoldTheirNodesInFloat) {
  const GridSensorParams<float> s = make_grid_sensor_params<float>(
      grid_sensor_spec("Force", SensorOperation::Sum, {0.2, 0, 0}, {0.25, 1, 1}, {1, 0, 0}, 1), 0.01);
  for (int i = 20; i <= 25; ++i)
    EXPECT_TRUE(sensor_box_contains(s.lo, s.hi, Vec3<float>{{static_cast<float>(i) * 0.01f, 0.5f, 0.5f}})) << i;
  EXPECT_FALSE(sensor_box_contains(s.lo, s.hi, Vec3<float>{{19 * 0.01f, 0.5f, 0.5f}}));
  EXPECT_FALSE(sensor_box_contains(s.lo, s.hi, Vec3<float>{{26 * 0.01f, 0.5f, 0.5f}}));
}

TEST(SensorRecorder, SampleTimesAreExactAndEndBeforeTheRunsEnd) {
  Scene scene = test::empty_scene(test::r3(1, 1, 1), 0.1, test::r3(0, 0, 0));
  scene.simulation.save_path = (std::filesystem::path(::testing::TempDir()) / "fbar_sensor_schedule").string();
  scene.simulation.fps = 2.0;
  GridSensorSpec a = grid_sensor_spec("Mass", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1});
  a.output_frequency = 4.0;
  GridSensorSpec off = a;
  off.toggle = false;
  GridSensorSpec b = a;
  b.output_frequency = 3.0;
  scene.grid_sensors = {a, off, b};
  SensorRecorder r(scene, nullptr, 0.0, 1.0);
  ASSERT_EQ(r.grid_sensors().size(), 2u);  // the switched-off one is skipped
  std::vector<double> times;
  double t = 0.0;
  while (std::isfinite(t)) {
    if (r.grid_slot_for(t) >= 0) {
      times.push_back(t);
      r.grid_taken(t);
      if (r.grid_pending() == 3) r.flush_grid(std::vector<SensorAccum>(r.grid_pending() * 2));
    }
    t = r.next_time_after(t);
  }
  // 4 Hz: 0, .25, .5, .75; 3 Hz: 0, 1/3, 2/3 (1.0 is the end: no step starts there); shared slot at 0.
  const std::vector<double> expected{0.0, 0.25, 1.0 / 3.0, 0.5, 2.0 / 3.0, 0.75};
  ASSERT_EQ(times.size(), expected.size());
  for (std::size_t i = 0; i < times.size(); ++i) EXPECT_DOUBLE_EQ(times[i], expected[i]);
  EXPECT_EQ(r.grid_slot_for(0.1), -1);
  EXPECT_EQ(r.particle_slot_for(0.0), -1);  // no particle sensor
}

/// A block at 1.5 m/s along x without gravity or boundaries: the grid's momentum is the particles' (partition of
/// unity; the internal forces of an unstressed block are zero and sum to zero anyway), m v along X, 0 along Y.
/// ClaymoreUW's Force is that momentum over dt; BoundaryForce is zero (no boundary).
TEST(GridSensors, MovingBlockMomentumAndMass) {
  Scene scene = test::empty_scene(test::r3(1, 0.5, 0.5), 0.02, test::r3(0, 0, 0));
  scene.bodies.push_back(
      test::box_body(Constitutive::FixedCorotated, test::r3(0.2, 0.1, 0.1), test::r3(0.2, 0.2, 0.2), test::r3(1.5, 0, 0)));
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const Real3 lo{0, 0, 0}, hi{1, 0.5, 0.5};
  engine.set_grid_sensors({grid_sensor_spec("Momentum", SensorOperation::Sum, lo, hi, {1, 0, 0}),
                           grid_sensor_spec("Mass", SensorOperation::Sum, lo, hi),
                           grid_sensor_spec("Momentum", SensorOperation::Sum, lo, hi, {0, 1, 0}),
                           grid_sensor_spec("Velocity", SensorOperation::Max, lo, hi, {1, 0, 0}),
                           grid_sensor_spec("Velocity", SensorOperation::Min, lo, hi, {1, 0, 0}),
                           grid_sensor_spec("Force", SensorOperation::Sum, lo, hi, {1, 0, 0}),
                           grid_sensor_spec("BoundaryForce", SensorOperation::Sum, lo, hi, {1, 0, 0})});
  const double m = engine.total_mass();
  for (int step = 0; step < 20; ++step) {
    engine.set_grid_sample(step % 3);
    const StepReport r = engine.step();
    ASSERT_TRUE(r.ok);
    const std::vector<SensorAccum> s = engine.grid_samples(step % 3 + 1);
    const SensorAccum* now = &s[(step % 3) * 7];
    EXPECT_NEAR(sensor_result(SensorOperation::Sum, now[0]), 1.5 * m, 1e-12 * m);
    EXPECT_NEAR(sensor_result(SensorOperation::Sum, now[1]), m, 1e-12 * m);
    EXPECT_NEAR(sensor_result(SensorOperation::Sum, now[2]), 0.0, 1e-12 * m);
    EXPECT_NEAR(sensor_result(SensorOperation::Max, now[3]), 1.5, 1e-12);
    EXPECT_NEAR(sensor_result(SensorOperation::Min, now[4]), 1.5, 1e-12);
    EXPECT_NEAR(sensor_result(SensorOperation::Sum, now[5]), 1.5 * m / r.dt, 1e-12 * m / r.dt);  // p / dt
    EXPECT_EQ(sensor_result(SensorOperation::Sum, now[6]), 0.0);  // no boundary: no boundary force
  }
}

/// Grid sensors Volume and JBar on a collapsing water column (compressible: J departs from 1 by ~1e-3), read
/// before each step against the particles of the same state: the nodes' Volume sums to the particles' volume
/// sum_p V0 J_p (partition of unity), and every node's JBar, a convex combination of its particles' JBar, lies
/// within their least and largest. Cell F-bar (JBar is J) and nodal F-bar (the stored JBar). (2 ranks: the run loop's
/// test below.)
TEST(GridSensors, VolumeSumsTheParticlesVolumeAndJBarIsTheirMean) {
  for (const FbarScheme scheme : {FbarScheme::Cell, FbarScheme::Nodal}) {
    Scene scene = test::dam_break(false);
    scene.bodies[0].algorithm.fbar_psi = 0.5;
    scene.bodies[0].algorithm.fbar_scheme = scheme;
    CpuEngine<double> engine(scene);
    engine.set_log(nullptr);
    const Real3 lo{0, 0, 0}, hi{0.64, 0.4, 0.2};
    engine.set_grid_sensors({grid_sensor_spec("Volume", SensorOperation::Sum, lo, hi),
                             grid_sensor_spec("JBar", SensorOperation::Min, lo, hi),
                             grid_sensor_spec("JBar", SensorOperation::Max, lo, hi),
                             grid_sensor_spec("Volume", SensorOperation::Count, lo, hi),
                             grid_sensor_spec("Mass", SensorOperation::Count, lo, hi)});
    engine.set_particle_sensors({particle_sensor_spec("Volume", SensorOperation::Sum, lo, hi),
                                 particle_sensor_spec("JBar", SensorOperation::Min, lo, hi),
                                 particle_sensor_spec("JBar", SensorOperation::Max, lo, hi)});
    double spread = 0.0;
    for (int step = 0; step < 40; ++step) {
      engine.sample_particles(0);
      engine.set_grid_sample(0);
      ASSERT_TRUE(engine.step(2e-4).ok);
      const std::vector<SensorAccum> g = engine.grid_samples(1), p = engine.particle_samples(1);
      const double volume = sensor_result(SensorOperation::Sum, p[0]);
      const double jmin = sensor_result(SensorOperation::Min, p[1]), jmax = sensor_result(SensorOperation::Max, p[2]);
      EXPECT_NEAR(sensor_result(SensorOperation::Sum, g[0]), volume, 1e-12 * volume) << "step " << step;
      EXPECT_GE(sensor_result(SensorOperation::Min, g[1]), jmin - 1e-14) << "step " << step;
      EXPECT_LE(sensor_result(SensorOperation::Max, g[2]), jmax + 1e-14) << "step " << step;
      EXPECT_EQ(sensor_result(SensorOperation::Count, g[3]), sensor_result(SensorOperation::Count, g[4]));
      spread = std::max(spread, jmax - jmin);
    }
    EXPECT_GT(spread, 1e-4) << "the column compresses: JBar is not 1 everywhere";
  }
}

/// A still water block (8 ppc: particle rows at dx/4 and 3dx/4 of each cell): a gauge (Position_Y, Max) over it
/// reads the top row, surface - dx/4, exactly; Count the particles in its column; a moving block's Velocity_X
/// Average its speed and Mass Sum its mass.
TEST(ParticleSensors, GaugeCountVelocityAndMass) {
  Scene scene = test::empty_scene(test::r3(1, 0.5, 0.5), 0.02, test::r3(0, 0, 0));
  scene.bodies.push_back(
      test::box_body(Constitutive::JFluid, test::r3(0.2, 0.1, 0.1), test::r3(0.2, 0.2, 0.2), test::r3(1.5, 0, 0)));
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  // The gauge's column: x in [0.25, 0.29] holds 4 particle columns of the block along x, 20 along z, 20 along y.
  engine.set_particle_sensors({particle_sensor_spec("Position_Y", SensorOperation::Max, {0.25, 0, 0}, {0.29, 1, 1}),
                               particle_sensor_spec("Mass", SensorOperation::Count, {0.25, 0, 0}, {0.29, 1, 1}),
                               particle_sensor_spec("Velocity_X", SensorOperation::Average, {0, 0, 0}, {1, 1, 1}),
                               particle_sensor_spec("Mass", SensorOperation::Sum, {0, 0, 0}, {1, 1, 1})});
  engine.sample_particles(0);
  ASSERT_TRUE(engine.step().ok);
  engine.sample_particles(1);
  const std::vector<SensorAccum> s = engine.particle_samples(2);
  ASSERT_EQ(s.size(), 8u);
  EXPECT_NEAR(sensor_result(SensorOperation::Max, s[0]), 0.3 - 0.005, 1e-12);
  EXPECT_EQ(sensor_result(SensorOperation::Count, s[1]), 4.0 * 20 * 20);
  EXPECT_NEAR(sensor_result(SensorOperation::Average, s[2]), 1.5, 1e-12);
  EXPECT_NEAR(sensor_result(SensorOperation::Sum, s[3]), engine.total_mass(), 1e-12 * engine.total_mass());
  // After a step the block moved 1.5 dt along x: still 1.5 m/s, the same mass.
  EXPECT_NEAR(sensor_result(SensorOperation::Average, s[6]), 1.5, 1e-12);
  EXPECT_NEAR(sensor_result(SensorOperation::Sum, s[7]), engine.total_mass(), 1e-12 * engine.total_mass());
}

/// Reads a sensor or tracker CSV: its header and rows (time, then the values).
struct Csv {
  std::string header;
  std::vector<std::vector<double>> rows;
};
Csv read_csv(const std::filesystem::path& path) {
  Csv c;
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::getline(in, c.header);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::istringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) row.push_back(std::stod(cell));
    c.rows.push_back(row);
  }
  return c;
}

/// Runs `scene` through the run loop (run_cpu) on `ranks` ranks (threads; one rank: no transport); every rank must
/// complete.
void run_on_ranks(const Scene& scene, int ranks) {
  for (const RunResult& r : test::run_cpu_ranks(scene, ranks)) EXPECT_EQ(r.exit_code, 0) << r.message;
}

/// The dam break of the decomposition tests with two load cells (the floor's force, the water's mass) run
/// through the run loop on `ranks` ranks (threads).
std::filesystem::path run_dam_break_with_sensors(int ranks) {
  Scene scene = test::dam_break(false);
  scene.simulation.fps = 50.0;
  scene.simulation.frames = 3;
  scene.simulation.save_path =
      (std::filesystem::path(::testing::TempDir()) / ("fbar_sensors_ranks" + std::to_string(ranks))).string();
  std::filesystem::remove_all(scene.simulation.save_path);
  // The floor's load cell: the nodes up to y = 0.05, i.e. the Walls' bottom face (y = 0.04) and the empty row below
  // it; read as Y-. BoundaryForce: the force on the floor, whatever else the box holds.
  GridSensorSpec force = grid_sensor_spec("BoundaryForce", SensorOperation::Sum, {0, 0, 0}, {0.64, 0.05, 0.2}, {0, 1, 0}, -1);
  force.output_frequency = 200.0;
  GridSensorSpec mass = grid_sensor_spec("Mass", SensorOperation::Sum, {0, 0, 0}, {0.64, 0.4, 0.2});
  mass.output_frequency = 120.0;
  GridSensorSpec volume = grid_sensor_spec("Volume", SensorOperation::Sum, {0, 0, 0}, {0.64, 0.4, 0.2});
  volume.output_frequency = 120.0;
  GridSensorSpec jbar = grid_sensor_spec("JBar", SensorOperation::Average, {0, 0, 0}, {0.64, 0.4, 0.2});
  jbar.output_frequency = 120.0;
  scene.grid_sensors = {force, mass, volume, jbar};
  // A wave gauge in the column's middle (water surface: 0.24 m at the start, falling) and the particles' count.
  ParticleSensorSpec gauge = particle_sensor_spec("Position_Y", SensorOperation::Max, {0.1, 0, 0}, {0.2, 0.4, 0.2});
  gauge.output_frequency = 100.0;
  ParticleSensorSpec count = particle_sensor_spec("Pressure", SensorOperation::Count, {0, 0, 0}, {0.64, 0.4, 0.2});
  count.output_frequency = 100.0;
  scene.particle_sensors = {gauge, count};
  run_on_ranks(scene, ranks);
  return scene.simulation.save_path;
}

/// Mean of a sensor file's values at t >= t0.
double mean_from(const Csv& c, double t0) {
  double sum = 0.0;
  int n = 0;
  for (const auto& row : c.rows)
    if (row[0] >= t0) sum += row[1], ++n;
  return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

// Load cells placed as ClaymoreUW users place them (against each wall of a tank, from outside) read the wall's load:
// the Walls act on the face node plane and outside it, and Force is the P2G momentum over dt (ClaymoreUW's meaning),
// which at those held nodes of a tank at rest is the internal force the water puts on them. Reference:
// rho g H^2 D / 2 = 7.848 N. Budget: the Tait compressibility at K = 5e5 Pa shifts the load by about
// rho g H / K = 0.4 %; the free-surface row's truncated stencil and the wall layer's bottom cell give an error
// second order in dx / H, like the wall load of test_load_cell.cpp (0.016 % at H / 10): 1 % in all (measured
// +0.38 % on 1 and 2 ranks; ClaymoreUW itself reads 7.824 N, -0.3 %, on its own walls). A load on the wrong node
// plane reads 7 % or 87 % (what fbar read before it took ClaymoreUW's wall nodes). 1 and 2 ranks (the cut between
// the walls) give the same files.
TEST(GridSensors, ClaymorePlacedTankLoadCellsReadTheWallLoad) {
  std::vector<std::filesystem::path> dirs;
  for (int ranks : {1, 2}) {
    Scene scene = test::claymore_tank();
    scene.simulation.fps = 20.0;
    scene.simulation.frames = 2;
    for (GridSensorSpec& g : scene.grid_sensors) g.output_frequency = 200.0;
    scene.simulation.save_path =
        (std::filesystem::path(::testing::TempDir()) / ("fbar_claymore_tank" + std::to_string(ranks))).string();
    std::filesystem::remove_all(scene.simulation.save_path);
    run_on_ranks(scene, ranks);
    dirs.push_back(scene.simulation.save_path);
  }
  for (const auto& dir : dirs)
    for (int wall : {0, 1}) {
      const Csv c = read_csv(dir / ("gridTarget[" + std::to_string(wall) + "]_dev[0].csv"));
      ASSERT_EQ(c.rows.size(), 20u);
      const double mean = mean_from(c, 0.02);
      std::printf("%s wall %d: %.5g N (rho g H^2 D / 2 = %.5g N, %+.2f %%)\n", dir.filename().c_str(), wall, mean,
                  test::kClaymoreTankLoad, 100 * (mean / test::kClaymoreTankLoad - 1));
      EXPECT_NEAR(mean, test::kClaymoreTankLoad, 0.01 * test::kClaymoreTankLoad) << dir << " wall " << wall;
    }
  for (int wall : {0, 1}) {
    const std::string name = "gridTarget[" + std::to_string(wall) + "]_dev[0].csv";
    const Csv a = read_csv(dirs[0] / name), b = read_csv(dirs[1] / name);
    ASSERT_EQ(a.rows.size(), b.rows.size());
    for (std::size_t k = 0; k < a.rows.size(); ++k)
      EXPECT_NEAR(b.rows[k][1], a.rows[k][1], 1e-9 * test::kClaymoreTankLoad) << name << " sample " << k;
  }
}

// A dam break hits the right wall: on the held nodes of a Slip wall, ClaymoreUW's Force (p / dt) and fbar's exact
// BoundaryForce (m (v* - v) / dt) along the wall's normal are the same number at every step (v_x = 0 after the
// projection, g_x = 0), while the impact builds up; a box that also takes the first free node row reads more.
TEST(GridSensors, ForceEqualsBoundaryForceOnAHeldWallDuringImpact) {
  const Scene scene = test::dam_break(false);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const Real3 lo{0.595, -1.0, -1.0}, hi{1.0, 1.0, 1.0};  // the right wall's face is x = 0.60
  engine.set_grid_sensors({grid_sensor_spec("Force", SensorOperation::Sum, lo, hi, {1, 0, 0}, 1),
                           grid_sensor_spec("BoundaryForce", SensorOperation::Sum, lo, hi, {1, 0, 0}, 1),
                           grid_sensor_spec("Force", SensorOperation::Sum, {0.575, -1, -1}, hi, {1, 0, 0}, 1)});
  double peak = 0.0, wider = 0.0;
  while (engine.time() < 0.25) {
    engine.set_grid_sample(0);
    const StepReport r = engine.step();
    ASSERT_TRUE(r.ok) << r.message();
    const std::vector<SensorAccum> a = engine.grid_samples(1);
    const double force = sensor_result(SensorOperation::Sum, a[0]);
    const double reaction = sensor_result(SensorOperation::Sum, a[1]);
    EXPECT_NEAR(force, reaction, 1e-9 * (1.0 + std::fabs(reaction))) << "t = " << engine.time();
    peak = std::max(peak, reaction);
    wider = std::max(wider, sensor_result(SensorOperation::Sum, a[2]));
  }
  // The water (0.3 m wide, 0.2 m tall, 0.12 m deep) reaches the wall: its hydrostatic load alone would be
  // rho g h^2 D / 2 = 23.5 N for h = 0.2 m; the wave's run-up loads the wall with the same order of force.
  EXPECT_GT(peak, 5.0);
  EXPECT_GT(wider, peak);  // the first free row adds its momentum over dt: Force outside held nodes is not a load
}

TEST(GridSensors, RunLoopWritesExactSampleTimesAndRanksAgree) {
  const std::filesystem::path one = run_dam_break_with_sensors(1);
  const std::filesystem::path two = run_dam_break_with_sensors(2);
  const Csv f1 = read_csv(one / "gridTarget[0]_dev[0].csv"), f2 = read_csv(two / "gridTarget[0]_dev[0].csv");
  const Csv m1 = read_csv(one / "gridTarget[1]_dev[0].csv"), m2 = read_csv(two / "gridTarget[1]_dev[0].csv");
  EXPECT_EQ(f1.header, "Time [s],BoundaryForce [N]");
  EXPECT_EQ(m1.header, "Time [s],Mass [kg]");
  // 3 frames at 50 fps = 0.06 s: 200 Hz gives 12 samples (t = k / 200, k < 12), 120 Hz gives 8 (k / 120, k < 8; 7.2).
  ASSERT_EQ(f1.rows.size(), 12u);
  ASSERT_EQ(m1.rows.size(), 8u);
  for (std::size_t k = 0; k < f1.rows.size(); ++k) EXPECT_NEAR(f1.rows[k][0], k / 200.0, 1e-12);
  for (std::size_t k = 0; k < m1.rows.size(); ++k) EXPECT_NEAR(m1.rows[k][0], k / 120.0, 1e-12);
  // The water's mass on the grid: 0.3 x 0.2 x 0.12 m of rho 1000 (partition of unity).
  for (const auto& row : m1.rows) EXPECT_NEAR(row[1], 1000.0 * 0.3 * 0.2 * 0.12, 1e-9);
  // Two ranks: the same rows; the sums differ by summation order only (halo nodes count once).
  ASSERT_EQ(f2.rows.size(), f1.rows.size());
  ASSERT_EQ(m2.rows.size(), m1.rows.size());
  for (std::size_t k = 0; k < f1.rows.size(); ++k) {
    EXPECT_EQ(f2.rows[k][0], f1.rows[k][0]);
    EXPECT_NEAR(f2.rows[k][1], f1.rows[k][1], 1e-9 * (1.0 + std::fabs(f1.rows[k][1])));
  }
  for (std::size_t k = 0; k < m1.rows.size(); ++k) EXPECT_NEAR(m2.rows[k][1], m1.rows[k][1], 1e-12);
  // Volume and JBar: the water's volume within its compression (J = 1 - O(1e-3)), JBar near 1; 2 ranks the same.
  const Csv v1 = read_csv(one / "gridTarget[2]_dev[0].csv"), v2 = read_csv(two / "gridTarget[2]_dev[0].csv");
  const Csv j1 = read_csv(one / "gridTarget[3]_dev[0].csv"), j2 = read_csv(two / "gridTarget[3]_dev[0].csv");
  EXPECT_EQ(v1.header, "Time [s],Volume [m^3]");
  EXPECT_EQ(j1.header, "Time [s],JBar [-]");
  ASSERT_EQ(v1.rows.size(), 8u);
  ASSERT_EQ(v2.rows.size(), 8u);
  ASSERT_EQ(j2.rows.size(), j1.rows.size());
  for (std::size_t k = 0; k < v1.rows.size(); ++k) {
    EXPECT_NEAR(v1.rows[k][1], 0.3 * 0.2 * 0.12, 1e-2 * 0.3 * 0.2 * 0.12) << "sample " << k;
    EXPECT_NEAR(v2.rows[k][1], v1.rows[k][1], 1e-12 * v1.rows[k][1]) << "sample " << k;
    EXPECT_NEAR(j1.rows[k][1], 1.0, 1e-2) << "sample " << k;
    EXPECT_NEAR(j2.rows[k][1], j1.rows[k][1], 1e-12) << "sample " << k;
  }
  // Particle sensors: 100 Hz over 0.06 s = 6 samples of the state at t = k / 100 (the initial state first).
  const Csv g1 = read_csv(one / "particleTarget[0]_model[0]_dev[0].csv"), g2 = read_csv(two / "particleTarget[0]_model[0]_dev[0].csv");
  const Csv c1 = read_csv(one / "particleTarget[1]_model[0]_dev[0].csv"), c2 = read_csv(two / "particleTarget[1]_model[0]_dev[0].csv");
  EXPECT_EQ(g1.header, "Time [s],Position_Y [m]");
  EXPECT_EQ(c1.header, "Time [s],Count [-]");
  ASSERT_EQ(g1.rows.size(), 6u);
  ASSERT_EQ(g2.rows.size(), 6u);
  ASSERT_EQ(c2.rows.size(), 6u);
  EXPECT_NEAR(g1.rows[0][1], 0.24 - 0.005, 1e-9);  // the top particle row of the still column
  for (std::size_t k = 0; k < g1.rows.size(); ++k) {
    EXPECT_NEAR(g1.rows[k][0], k / 100.0, 1e-12);
    EXPECT_EQ(g2.rows[k][0], g1.rows[k][0]);
    EXPECT_NEAR(g2.rows[k][1], g1.rows[k][1], 1e-12);  // the same particles, states to round-off
    EXPECT_EQ(c1.rows[k][1], 7200.0);                         // 0.3 x 0.2 x 0.12 m at 8 ppc, dx 0.02
    EXPECT_EQ(c2.rows[k][1], 7200.0);
  }
  EXPECT_LT(g1.rows.back()[1], g1.rows.front()[1] - 1e-3);  // the collapsing column's top has fallen
  // The floor carries the water: a positive load, first only the weight of the mass at the floor's nodes (the
  // column starts stress-free), then of the order of the whole weight as the pressure builds.
  const double weight = 1000.0 * 0.3 * 0.2 * 0.12 * 9.81;
  for (const auto& row : f1.rows) {
    EXPECT_GT(row[1], 0.0);
    EXPECT_LT(row[1], 3.0 * weight);
  }
  EXPECT_GT(f1.rows.back()[1], 0.3 * weight);
}

/// Trackers follow particles by ID through migration: the travelling block (every particle crosses the cuts) on 1
/// and 2 ranks writes the same rows, and each tracked particle moves at the block's 2 m/s.
TEST(Trackers, FollowParticlesAcrossRanks) {
  auto run = [](int ranks) {
    Scene scene = test::travelling_block();
    scene.simulation.fps = 25.0;
    scene.simulation.frames = 3;
    scene.simulation.save_path =
        (std::filesystem::path(::testing::TempDir()) / ("fbar_trackers_ranks" + std::to_string(ranks))).string();
    std::filesystem::remove_all(scene.simulation.save_path);
    scene.bodies[0].track_particle_id = {100, 0, 4095};
    scene.bodies[0].track_attribs = {"Position_X", "Velocity_X", "J"};
    run_on_ranks(scene, ranks);
    return std::filesystem::path(scene.simulation.save_path) / "particleTrack_model[0]_dev[0].csv";
  };
  const Csv c1 = read_csv(run(1)), c2 = read_csv(run(2));
  const std::string &h1 = c1.header, &h2 = c2.header;
  const std::vector<std::vector<double>>&r1 = c1.rows, &r2 = c2.rows;
  // Attributes outer, IDs inner, in the scene's order (ClaymoreUW's layout).
  EXPECT_EQ(h1, "Time [s],Position_X[100] [m],Position_X[0] [m],Position_X[4095] [m],Velocity_X[100] [m/s],"
                "Velocity_X[0] [m/s],Velocity_X[4095] [m/s],J[100] [-],J[0] [-],J[4095] [-]");
  EXPECT_EQ(h2, h1);
  ASSERT_EQ(r1.size(), 4u);  // the start and 3 frames
  ASSERT_EQ(r2.size(), r1.size());
  for (std::size_t k = 0; k < r1.size(); ++k) {
    EXPECT_NEAR(r1[k][0], k / 25.0, 1e-12);
    for (std::size_t c = 0; c < r1[k].size(); ++c) EXPECT_NEAR(r2[k][c], r1[k][c], 1e-9) << "row " << k << ", column " << c;
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(r1[k][1 + i] - r1[0][1 + i], 2.0 * r1[k][0], 1e-6);  // x(t) = x(0) + 2 t (float output)
      EXPECT_NEAR(r1[k][4 + i], 2.0, 1e-6);
      EXPECT_NEAR(r1[k][7 + i], 1.0, 1e-6);
    }
  }
  // Three different particles: their starting positions differ.
  EXPECT_NE(r1[0][1], r1[0][3]);
}

// ClaymoreUW's scene.json tracks IDs its body does not have: ClaymoreUW writes 0.0 for them, fbar runs and writes
// NaN in their columns (the parser warns). Empty (inverted) sensor boxes run too: Sum and Count read 0, the other
// operations NaN. One rank and two (the IDs' presence is reduced over ranks).
TEST(Trackers, AnIdNoParticleHasReadsNaNAndEmptySensorsRun) {
  for (int ranks : {1, 2}) {
    Scene scene = test::travelling_block();
    scene.simulation.frames = 2;
    scene.simulation.save_path =
        (std::filesystem::path(::testing::TempDir()) / ("fbar_trackers_missing" + std::to_string(ranks))).string();
    std::filesystem::remove_all(scene.simulation.save_path);
    scene.bodies[0].track_particle_id = {9999999, 0};
    scene.bodies[0].track_attribs = {"Position_X"};
    // Boxes with domain_end[0] < domain_start[0] (ClaymoreUW's DKT_2D scene has one): they hold nothing.
    ParticleSensorSpec max = particle_sensor_spec("Position_Y", SensorOperation::Max, {0.5, 0, 0}, {0.1, 0.2, 0.2});
    ParticleSensorSpec count = particle_sensor_spec("Position_Y", SensorOperation::Count, {0.5, 0, 0}, {0.1, 0.2, 0.2});
    scene.particle_sensors = {max, count};
    GridSensorSpec mass = grid_sensor_spec("Mass", SensorOperation::Sum, {0.5, 0, 0}, {0.1, 0.2, 0.2});
    GridSensorSpec mean = grid_sensor_spec("Mass", SensorOperation::Average, {0.5, 0, 0}, {0.1, 0.2, 0.2});
    scene.grid_sensors = {mass, mean};
    run_on_ranks(scene, ranks);
    const std::filesystem::path dir(scene.simulation.save_path);
    const Csv t = read_csv(dir / "particleTrack_model[0]_dev[0].csv");
    EXPECT_EQ(t.header, "Time [s],Position_X[9999999] [m],Position_X[0] [m]");
    ASSERT_EQ(t.rows.size(), 3u) << ranks;  // the start and 2 frames
    for (const auto& row : t.rows) {
      ASSERT_EQ(row.size(), 3u);
      EXPECT_TRUE(std::isnan(row[1])) << row[1];
      EXPECT_NEAR(row[2] - t.rows[0][2], 2.0 * row[0], 1e-6);  // particle 0 is there, moving at 2 m/s
    }
    for (const char* name : {"particleTarget[0]_model[0]_dev[0].csv", "particleTarget[1]_model[0]_dev[0].csv",
                             "gridTarget[0]_dev[0].csv", "gridTarget[1]_dev[0].csv"}) {
      const Csv c = read_csv(dir / name);
      ASSERT_FALSE(c.rows.empty()) << name;
      const bool zero = std::string(name).find("Target[1]") == std::string::npos
                            ? std::string(name).rfind("grid", 0) == 0  // gridTarget[0]: Sum
                            : std::string(name).rfind("particle", 0) == 0;  // particleTarget[1]: Count
      for (const auto& row : c.rows) {
        ASSERT_EQ(row.size(), 2u) << name;
        if (zero) EXPECT_EQ(row[1], 0.0) << name;
        else EXPECT_TRUE(std::isnan(row[1])) << name << ": " << row[1];
      }
    }
  }
}

}  // namespace
}  // namespace fbar
