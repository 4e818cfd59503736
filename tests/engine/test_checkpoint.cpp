// Checkpoints and restart (io/checkpoint.h, run_loop.h) on the CPU engine: the HDF5 file round-trips; a run
// restarted from a frame checkpoint, from the checkpoint a stop request wrote mid-frame, or from a failure's writes
// the same frames and sensor / tracker rows as the run that was never stopped (bit for bit, on 1 and 2 ranks); a
// two-rank checkpoint continues on one rank; a scene that does not match the checkpoint is refused by name. Also
// the run loop's surface-only frames (exterior_only).
#include <gtest/gtest.h>

#include <functional>

#include <algorithm>
#include <climits>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cpu/decomposition_scenes.h"
#include "engine/cpu/cpu_engine.h"
#include "engine/engine_api.h"
#include "engine/stop_request.h"
#include "io/checkpoint.h"
#include "../physics/physics_test_support.h"
#include "restart_cases.h"
#include "resume_support.h"
#include "run_support.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;
using test::grid_sensor_spec;
using test::particle_sensor_spec;
using test::r3;
namespace restart = test::restart;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("fbar_checkpoint_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// Runs `scene` (save_path set by the caller) through run_cpu on `ranks` ranks (threads), restarting from
/// `restart` when it is not empty; returns rank 0's result.
RunResult run_ranks(const Scene& scene, int ranks, const std::string& restart = "") {
  return test::run_cpu_ranks(scene, ranks, restart).front();
}

using restart::bytes_of;
using restart::copy_up_to_checkpoint;
using restart::expect_same_output;
using restart::restart_scene;
void expect_frame_restart(int ranks, const std::function<void(Scene&)>& change = {}, const std::string& name = "") {
  restart::expect_frame_restart(run_cpu, "cpu", ranks, change, name);
}

TEST(CheckpointFile, RoundTripsInTheRunsPrecision) {
  const fs::path dir = scratch("file");
  io::Checkpoint c;
  c.precision = "single";
  c.engine = "cpu";
  c.reason = "frame";
  c.rank = 1;
  c.ranks = 2;
  c.start_time = 0.5;
  c.time = 0.625;
  c.steps = 1234;
  c.frame = 12;
  c.last_dt = 1e-4;
  c.next_dt = 1.5e-4;
  c.max_grid_speed = 2.5;
  c.dt_scale = 0.5;
  c.clean_steps = 7;
  c.slab_axis = 2;
  c.slab_cuts = {INT_MIN, 5, INT_MAX};
  c.chosen_imbalance = 0.125;
  c.particle_sample_due = true;
  c.csv = {{"gridTarget[0]_dev[0].csv", 345}, {"particleTrack_model[0]_dev[0].csv", 99}};
  io::CheckpointBody b;
  b.law = "FixedCorotated";
  b.state_scalars = 9;
  b.global_particles = 5;
  b.max_wave_speed = 40.0;
  b.p2g_bound = 0.75;
  b.p2g_capture = true;
  for (int p = 0; p < 3; ++p) {
    b.id.push_back(4 - p);
    for (int a = 0; a < 3; ++a) b.x.push_back(static_cast<float>(0.1 * p + 0.01 * a));
    for (int a = 0; a < 3; ++a) b.v.push_back(static_cast<float>(-0.3 * p + a));
    for (int a = 0; a < 9; ++a) b.C.push_back(static_cast<float>(a * 0.7 - p));
    b.mass.push_back(0.125f);
    b.volume.push_back(static_cast<float>(1.0 / 3.0));
    for (int a = 0; a < 9; ++a) b.state.push_back(static_cast<float>(a == 0 || a == 4 || a == 8 ? 1.0 + 0.01 * p : 0.001 * a));
  }
  b.p2g_known = true;  // this rank summed particles 3 and 4 (it holds 4, 3 and 2: 2 arrived after the P2G)
  b.p2g_id = {3, 4};
  b.p2g_block = {-1, 2, 7, 0, 0, -300};
  c.bodies = {b, [] {
    io::CheckpointBody e;
    e.law = "JFluid";
    e.state_scalars = 1;
    return e;
  }()};
  const fs::path path = io::checkpoint_frame_path(dir, 12, 1);
  EXPECT_EQ(path.filename().string(), "checkpoint_frame[12]_dev[1].h5");
  io::write_checkpoint(path, c);
  EXPECT_FALSE(fs::exists(fs::path(path.string() + ".part")));
  const io::Checkpoint r = io::read_checkpoint(path);
  EXPECT_EQ(r.precision, "single");
  EXPECT_EQ(r.reason, "frame");
  EXPECT_EQ(r.rank, 1);
  EXPECT_EQ(r.ranks, 2);
  EXPECT_EQ(r.start_time, 0.5);
  EXPECT_EQ(r.time, 0.625);
  EXPECT_EQ(r.steps, 1234);
  EXPECT_EQ(r.frame, 12);
  EXPECT_EQ(r.next_dt, 1.5e-4);
  EXPECT_EQ(r.dt_scale, 0.5);
  EXPECT_EQ(r.clean_steps, 7);
  EXPECT_EQ(r.slab_axis, 2);
  EXPECT_EQ(r.slab_cuts, c.slab_cuts);
  EXPECT_EQ(r.chosen_imbalance, 0.125);
  EXPECT_TRUE(r.particle_sample_due);
  EXPECT_EQ(r.csv, c.csv);
  ASSERT_EQ(r.bodies.size(), 2u);
  EXPECT_EQ(r.bodies[0].law, "FixedCorotated");
  EXPECT_EQ(r.bodies[0].id, b.id);
  EXPECT_EQ(r.bodies[0].x, b.x);  // float values: exact through float32
  EXPECT_EQ(r.bodies[0].v, b.v);
  EXPECT_EQ(r.bodies[0].C, b.C);
  EXPECT_EQ(r.bodies[0].state, b.state);
  EXPECT_EQ(r.bodies[0].volume, b.volume);
  EXPECT_EQ(r.bodies[1].particles(), 0u);
  EXPECT_EQ(r.bodies[0].p2g_bound, 0.75);
  EXPECT_EQ(r.bodies[1].p2g_bound, -1.0);  // not known
  EXPECT_TRUE(r.bodies[0].p2g_capture);
  EXPECT_FALSE(r.bodies[1].p2g_capture);
  EXPECT_TRUE(r.bodies[0].p2g_known);
  EXPECT_EQ(r.bodies[0].p2g_id, b.p2g_id);
  EXPECT_EQ(r.bodies[0].p2g_block, b.p2g_block);
  EXPECT_FALSE(r.bodies[1].p2g_known);
  // The particle bytes of a rebalance and the merge of rank parts keep it.
  io::Checkpoint parts = c;
  for (io::CheckpointBody& body : parts.bodies) body = body.description();
  io::read_checkpoint_particle_bytes(io::checkpoint_particle_bytes(c), parts);
  EXPECT_EQ(parts.bodies[0].p2g_bound, 0.75);
  EXPECT_TRUE(parts.bodies[0].p2g_capture);
  EXPECT_FALSE(parts.bodies[1].p2g_capture);
  EXPECT_TRUE(parts.bodies[0].p2g_known);
  EXPECT_EQ(parts.bodies[0].p2g_id, b.p2g_id);
  EXPECT_EQ(parts.bodies[0].p2g_block, b.p2g_block);
  EXPECT_FALSE(parts.bodies[1].p2g_known);
  // The rank files of a set.
  EXPECT_EQ(io::checkpoint_rank_path(dir / "checkpoint_step[40]_dev[0].h5", 3).filename().string(),
            "checkpoint_step[40]_dev[3].h5");
  EXPECT_THROW(io::checkpoint_rank_path(dir / "state.h5", 1), std::invalid_argument);
  // Not a checkpoint: named.
  std::ofstream(dir / "junk.h5") << "not hdf5";
  try {
    io::read_checkpoint(dir / "junk.h5");
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("junk.h5: not an HDF5 file"), std::string::npos) << e.what();
  }
}

// Two ranks' parts merge into ID order with the blocks of the last P2G (io::CheckpointBody::p2g_block), which a
// particle that migrated in that step has in the other rank's part; a part without them makes them unknown, and a
// particle summed on both ranks is an error.
// A body whose datasets come from a source in pieces (io::CheckpointPieces, as the GPU engine gives a body too
// large to copy into host memory) writes the bytes of the same body held in arrays: single and double precision,
// pieces of 1, 7 and 1000 rows, the P2G datasets too.
TEST(CheckpointFile, StreamedBodyWritesTheBytesOfItsArrays) {
  const fs::path dir = scratch("streamed");
  for (const char* precision : {"single", "double"}) {
    io::Checkpoint c;
    c.precision = precision;
    c.engine = "gpu";
    c.reason = "frame";
    c.time = 0.25;
    io::CheckpointBody b;
    b.law = "FixedCorotated";
    b.state_scalars = 9;
    b.global_particles = 2000;
    b.p2g_bound = 0.5;
    b.p2g_known = true;
    for (int p = 0; p < 1501; ++p) {
      b.id.push_back(2 * p + 1);
      for (int a = 0; a < 3; ++a) b.x.push_back(std::sin(0.37 * p + a));
      for (int a = 0; a < 3; ++a) b.v.push_back(std::cos(0.11 * p - a));
      for (int a = 0; a < 9; ++a) b.C.push_back(0.001 * (p % 13) - a);
      b.mass.push_back(1e-3 * (1 + p % 3));
      b.volume.push_back(1e-6);
      for (int a = 0; a < 9; ++a) b.state.push_back(a % 4 == 0 ? 1.0 + 1e-4 * p : 1e-5 * a);
      if (p % 5 != 0) {
        b.p2g_id.push_back(2 * p + 1);
        for (int a = 0; a < 3; ++a) b.p2g_block.push_back(p % 11 - 4 * a);
      }
    }
    c.bodies = {b};
    io::write_checkpoint(dir / "arrays.h5", c);
    const std::string arrays = restart::bytes_of(dir / "arrays.h5");
    for (const std::size_t piece : {std::size_t(1), std::size_t(7), std::size_t(1000)}) {
      io::Checkpoint s = c;
      io::CheckpointBody& body = s.bodies[0];
      const io::CheckpointBody data = body;
      for (auto* v : {&body.x, &body.v, &body.C, &body.mass, &body.volume, &body.state}) v->clear();
      body.id.clear();
      body.p2g_id.clear();
      body.p2g_block.clear();
      io::CheckpointPieces pieces;
      pieces.particles = data.id.size();
      pieces.p2g_rows = data.p2g_id.size();
      pieces.pieces = [&data, piece](io::CheckpointDataset d, const std::function<void(std::size_t, const void*)>& emit) {
        auto each = [&](const auto& values, std::size_t rows, std::size_t width) {
          for (std::size_t first = 0; first < rows; first += piece)
            emit(std::min(piece, rows - first), values.data() + first * width);
        };
        const std::size_t n = data.id.size();
        switch (d) {
          case io::CheckpointDataset::Id: return each(data.id, n, 1);
          case io::CheckpointDataset::Position: return each(data.x, n, 3);
          case io::CheckpointDataset::Velocity: return each(data.v, n, 3);
          case io::CheckpointDataset::C: return each(data.C, n, 9);
          case io::CheckpointDataset::Mass: return each(data.mass, n, 1);
          case io::CheckpointDataset::Volume: return each(data.volume, n, 1);
          case io::CheckpointDataset::State: return each(data.state, n, 9);
          case io::CheckpointDataset::P2GId: return each(data.p2g_id, data.p2g_id.size(), 1);
          case io::CheckpointDataset::P2GBlock: return each(data.p2g_block, data.p2g_id.size(), 3);
        }
      };
      s.streamed = {pieces};
      io::write_checkpoint(dir / "pieces.h5", s);
      EXPECT_TRUE(restart::bytes_of(dir / "pieces.h5") == arrays) << precision << ", pieces of " << piece << " rows";
      // A source that gives fewer rows than it announced is refused.
      s.streamed[0].particles += 1;
      EXPECT_THROW(io::write_checkpoint(dir / "short.h5", s), std::logic_error);
      EXPECT_FALSE(fs::exists(dir / "short.h5"));
    }
  }
}

TEST(CheckpointFile, MergeKeepsTheBlocksOfTheLastP2G) {
  auto part = [](int rank, std::vector<std::int64_t> ids, std::vector<std::int64_t> summed) {
    io::Checkpoint c;
    c.precision = "double";
    c.rank = rank;
    c.ranks = 2;
    io::CheckpointBody b;
    b.law = "JFluid";
    b.state_scalars = 1;
    b.global_particles = 4;
    for (const std::int64_t id : ids) {
      b.id.push_back(id);
      for (int a = 0; a < 3; ++a) b.x.push_back(0.1 * static_cast<double>(id) + a);
      b.v.insert(b.v.end(), 3, 0.0);
      b.C.insert(b.C.end(), 9, 0.0);
      b.mass.push_back(1.0);
      b.volume.push_back(1.0);
      b.state.push_back(0.0);
    }
    b.p2g_known = true;
    for (const std::int64_t id : summed) {
      b.p2g_id.push_back(id);
      for (int a = 0; a < 3; ++a) b.p2g_block.push_back(static_cast<std::int32_t>(10 * id + a + rank * 100));
    }
    c.bodies.push_back(b);
    return c;
  };
  // Particle 1 was summed on rank 0 and then migrated to rank 1; particle 2 the other way.
  const io::Checkpoint merged = io::merge_checkpoints({part(0, {0, 2}, {0, 1}), part(1, {1, 3}, {3, 2})}, "test");
  const io::CheckpointBody& m = merged.bodies[0];
  ASSERT_TRUE(m.p2g_known);
  EXPECT_EQ(m.p2g_id, (std::vector<std::int64_t>{0, 1, 2, 3}));
  EXPECT_EQ(m.p2g_block, (std::vector<std::int32_t>{0, 1, 2, 10, 11, 12, 120, 121, 122, 130, 131, 132}));
  io::Checkpoint unknown = part(1, {1, 3}, {3, 2});
  unknown.bodies[0].p2g_known = false;
  EXPECT_FALSE(io::merge_checkpoints({part(0, {0, 2}, {0, 1}), unknown}, "test").bodies[0].p2g_known);
  EXPECT_THROW(io::merge_checkpoints({part(0, {0, 2}, {0, 1}), part(1, {1, 3}, {3, 1})}, "test"), std::runtime_error);
}

TEST(Restart, FromAFrameCheckpointContinuesBitForBit) { expect_frame_restart(1); }
TEST(Restart, FromAFrameCheckpointContinuesBitForBitOnTwoRanks) { expect_frame_restart(2); }
// Single precision (the checkpoint in float32, the run's own values) and mixed (double particles, float grid).
TEST(Restart, SingleAndMixedPrecisionContinueBitForBit) {
  expect_frame_restart(1, [](Scene& scene) { scene.simulation.precision = Precision::Single; }, "_single");
  expect_frame_restart(1, [](Scene& scene) { scene.simulation.precision = Precision::Mixed; }, "_mixed");
}

// A saturated body (CoupledUP) keeps its pore pressure and its head gradient in the checkpoint: the restarted run's
// frames (PorePressure among the columns) and its pore-pressure and water-mass sensors are the full run's bytes, on one
// rank and on two.
TEST(Restart, SaturatedSoilContinuesBitForBit) {
  const auto saturate = restart::saturate_second_body;
  expect_frame_restart(1, saturate, "_saturated");
  expect_frame_restart(2, saturate, "_saturated");
}

// Nodal F-bar (FBAR_scheme "nodal"): each particle's 1 - JBar rides in the checkpoint after its law's state, so the
// restarted run's frames (JBar among the columns) and sensors are the full run's bytes, on one rank and on two.
TEST(Restart, NodalFbarContinuesBitForBit) {
  const auto nodal = restart::nodal_fbar_bodies;
  expect_frame_restart(1, nodal, "_nodal");
  expect_frame_restart(2, nodal, "_nodal");
}

// A mesh (FEM body) placed on rank 1 continues bit for bit from its rank's checkpoint: the rank without it holds its
// elements and no vertex (the run's sensor rows over the mesh's vertices, and every other body's frames, are the
// full run's bytes), on one rank and on two.
TEST(Restart, MeshContinuesBitForBit) {
  const auto add_mesh = restart::add_placed_mesh;
  expect_frame_restart(1, add_mesh, "_mesh");
  expect_frame_restart(2, add_mesh, "_mesh");
}

// "Run longer": a run of 3 frames continued from its last frame's checkpoint to 6 frames writes what one 6-frame run
// writes. No run samples its own end time, so the particle sensors' sample at frame 3's time is still due when the
// checkpoint is taken; the restarted run takes it first (the checkpoint records that it is due).
TEST(Restart, FromTheLastFrameRunsLongerBitForBit) {
  const fs::path a = scratch("longer_a"), b = scratch("longer_b");
  Scene scene = restart_scene(a);
  const RunResult full = run_ranks(scene, 1);
  ASSERT_EQ(full.exit_code, 0) << full.message;
  scene.simulation.save_path = b.string();
  scene.simulation.frames = 3;
  scene.simulation.checkpoint_every = 3;
  ASSERT_EQ(run_ranks(scene, 1).exit_code, 0);
  EXPECT_TRUE(io::read_checkpoint(io::checkpoint_frame_path(b, 3, 0).string()).particle_sample_due);
  scene.simulation.frames = 6;
  const RunResult longer = run_ranks(scene, 1, io::checkpoint_frame_path(b, 3, 0).string());
  ASSERT_EQ(longer.exit_code, 0) << longer.message;
  EXPECT_EQ(longer.steps, full.steps);
  expect_same_output(a, b, 3, 2);
}

// A two-rank checkpoint continued on one rank (the set merged in ID order): the same physics to round-off (the
// halo sums' order differs), every particle present once. The sensors' 9 printed digits bound what can be seen.
constexpr double kMergedTolerance = 1e-8;
TEST(Restart, TwoRankCheckpointContinuesOnOneRank) {
  const fs::path a = scratch("merge_a"), b = scratch("merge_b");
  Scene scene = restart_scene(a);
  scene.simulation.checkpoint_every = 3;
  ASSERT_EQ(run_ranks(scene, 2).exit_code, 0);
  const io::Checkpoint merged = io::read_checkpoint_set(io::checkpoint_frame_path(a, 3, 1));
  ASSERT_EQ(merged.ranks, 1);
  for (const io::CheckpointBody& body : merged.bodies)
    for (std::size_t p = 0; p < body.particles(); ++p) ASSERT_EQ(body.id[p], static_cast<std::int64_t>(p));
  scene.simulation.save_path = b.string();
  const RunResult r = run_ranks(scene, 1, io::checkpoint_frame_path(a, 3, 0).string());
  ASSERT_EQ(r.exit_code, 0) << r.message;
  // The gauge (max water height) and the mean x velocity at the samples after frame 3 agree with the two-rank run
  // (the sensor files in b start with the restart's rows: a fresh directory).
  auto rows = [](const fs::path& file) {
    std::ifstream in(file);
    std::string line;
    std::getline(in, line);
    std::vector<std::pair<double, double>> out;
    while (std::getline(in, line)) {
      const auto comma = line.find(',');
      out.emplace_back(std::stod(line.substr(0, comma)), std::stod(line.substr(comma + 1)));
    }
    return out;
  };
  for (const char* name : {"particleTarget[0]_model[0]_dev[0].csv", "particleTarget[1]_model[0]_dev[0].csv"}) {
    const auto two = rows(a / name), one = rows(b / name);
    ASSERT_FALSE(one.empty()) << name;
    std::size_t matched = 0;
    double worst = 0.0;
    for (const auto& [t, value] : one)
      for (const auto& [t2, value2] : two)
        if (t == t2) {
          const double d = std::fabs(value - value2) / (1.0 + std::fabs(value2));
          worst = std::isnan(d) || std::isnan(worst) ? std::nan("") : std::max(worst, d);
          ++matched;
        }
    EXPECT_EQ(matched, one.size()) << name;
    std::printf("[measured] %s: two ranks against their checkpoint continued on one: %.3g relative\n", name, worst);
    EXPECT_LE(worst, kMergedTolerance) << name;
  }
}

// SIGTERM mid-run: the restart from checkpoint_step[s] writes what the uninterrupted run wrote (restart_cases.h).
TEST(Restart, AfterAStopRequestContinuesBitForBit) { restart::expect_stop_restart(run_cpu, "cpu"); }

// A failure writes the state before the failed step; restarting from it fails again at the same step.
TEST(Restart, AFailureWritesTheStateBeforeTheFailedStep) {
  const fs::path dir = scratch("failure");
  Scene scene = test::empty_scene(r3(0.3, 1, 1), 0.025, r3(0, 0, 0));
  // The block's front leaves the domain plus its 8-cell margin (x > 0.5 m) in the step starting at 0.206 s.
  scene.bodies.push_back(test::box_body(Constitutive::JFluid, r3(0.2, 0.2, 0.2), r3(0.1, 0.1, 0.1), r3(1.0, 0, 0)));
  scene.bodies[0].material.bulk_modulus = 1e4;  // c = 3.2 m/s: stable 1 ms steps while it travels
  scene.simulation.default_dt = 1e-3;
  scene.simulation.fps = 50.0;
  scene.simulation.frames = 15;
  scene.simulation.save_path = dir.string();
  const RunResult r = run_ranks(scene, 1);
  ASSERT_EQ(r.exit_code, 2);
  EXPECT_NE(r.message.find("left the domain"), std::string::npos) << r.message;
  ASSERT_FALSE(r.checkpoint.empty()) << r.message;
  EXPECT_NE(r.message.find("checkpoint of the state before the failed step: " + r.checkpoint), std::string::npos);
  const io::Checkpoint c = io::read_checkpoint(r.checkpoint);
  EXPECT_EQ(c.reason, "failure");
  EXPECT_EQ(c.steps, r.steps);
  const RunResult again = run_ranks(scene, 1, r.checkpoint);
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_EQ(again.steps, r.steps);
  EXPECT_EQ(again.message.substr(0, again.message.find('\n')), r.message.substr(0, r.message.find('\n')));
}

// A checkpoint that does not fit the scene is refused, naming what differs.
TEST(Restart, ASceneThatDoesNotMatchIsRefused) {
  const fs::path dir = scratch("mismatch");
  Scene scene = restart_scene(dir);
  scene.simulation.frames = 1;
  scene.simulation.checkpoint_every = 1;
  ASSERT_EQ(run_ranks(scene, 1).exit_code, 0);
  Scene other = scene;
  other.bodies[1].material.law = Constitutive::FixedCorotated;
  other.bodies[1].output_attribs = {"ID"};
  const RunResult r = run_ranks(other, 1, io::checkpoint_frame_path(dir, 1, 0).string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.message.find("bodies[1].material.constitutive is FixedCorotated, the checkpoint's body 1 is DruckerPrager"),
            std::string::npos)
      << r.message;
  Scene fewer = scene;
  fewer.bodies.pop_back();
  const RunResult r2 = run_ranks(fewer, 1, io::checkpoint_frame_path(dir, 1, 0).string());
  EXPECT_EQ(r2.exit_code, 1);
  EXPECT_NE(r2.message.find("the checkpoint holds 2 bodies, the scene 1"), std::string::npos) << r2.message;
}

// Surface-only frames through the run loop (output.exterior_only, or simulation.particles_output_exterior_only):
// a 0.4 m cube on the 4-cell blocks (dx 0.025: 4 x 4 x 4 blocks of 512 particles) writes its 56 shell blocks and
// drops the 8 inner ones, whose neighbours all hold 512 > 128 particles.
// ClaymoreUW's resume: a body seeded from a .bgeo frame (has_attributes, input_attribs matched by name) starts in
// the state the frame holds, for a fluid (J, velocity) and a solid with plasticity (F, logJp, velocity), and goes on
// as the run that wrote the frame does (APIC's C is not in a frame, so only closely).
TEST(Resume, ABgeoFrameSeedsFluidAndSolidBodies) {
  const fs::path dir = scratch("resume_bgeo");
  Scene a = restart_scene(dir);
  a.grid_sensors.clear();
  a.particle_sensors.clear();
  a.bodies[0].track_particle_id.clear();
  a.bodies[0].track_attribs.clear();
  a.bodies[1].velocity = r3(0.5, 0.0, -0.25);
  test::output_state_attributes(a);
  CpuEngine<double> run(a);
  run.set_log(nullptr);
  for (int i = 0; i < 40; ++i) ASSERT_TRUE(run.step().ok);
  CpuEngine<double> resumed(test::seeded_from_frames(a, run, dir));
  resumed.set_log(nullptr);
  for (int k = 0; k < 2; ++k) {
    const io::ParticleFrame written = io::read_bgeo(test::resume_frame(dir, static_cast<std::size_t>(k)));
    const io::ParticleFrame seeded = resumed.frame(k);
    ASSERT_EQ(seeded.size(), written.size()) << "body " << k;
    for (std::size_t p = 0; p < written.size(); ++p)
      for (int d = 0; d < 3; ++d)
        ASSERT_EQ(static_cast<float>(seeded.position(p)[d]), static_cast<float>(written.position(p)[d]));
    for (const io::FrameAttribute& w : written.attributes) {
      const io::FrameAttribute* s = seeded.find(w.name);
      ASSERT_NE(s, nullptr) << w.name;
      ASSERT_EQ(s->values.index(), w.values.index()) << w.name;
      EXPECT_TRUE(s->values == w.values) << "body " << k << ": " << w.name << " is not the frame's";
    }
  }
  // The sand has yielded (logJp != 0) and the water is compressed (J != 1): the seeds carried real state.
  const io::ParticleFrame sand = resumed.frame(1);
  const std::vector<float>& logjp = sand.find("logJp")->floats();
  const auto [lo, hi] = std::minmax_element(logjp.begin(), logjp.end());
  EXPECT_GT(std::max(-*lo, *hi), 1e-4f);
  const std::vector<float>& J = resumed.frame(0).find("J")->floats();
  EXPECT_LT(*std::min_element(J.begin(), J.end()), 0.9999f);

  // Ten more steps of the same sizes: the resumed run follows the original (it lacks C and the float rounding of
  // the frame) within 5 % of the displacement of those steps (measured: 0.3 % water, 1.8 % sand).
  std::vector<std::vector<Vec3d>> before(2);
  for (int k = 0; k < 2; ++k) {
    const io::ParticleFrame f = run.frame(k);
    for (std::size_t p = 0; p < f.size(); ++p) before[static_cast<std::size_t>(k)].push_back(f.position(p));
  }
  for (int i = 0; i < 10; ++i) {
    const StepReport r = run.step();
    ASSERT_TRUE(r.ok);
    ASSERT_TRUE(resumed.step(r.dt).ok);
  }
  for (int k = 0; k < 2; ++k) {
    const io::ParticleFrame fa = run.frame(k), fb = resumed.frame(k);
    double moved = 0.0, apart = 0.0;
    for (std::size_t p = 0; p < fa.size(); ++p) {
      moved += norm(fa.position(p) - before[static_cast<std::size_t>(k)][p]);
      apart += norm(fa.position(p) - fb.position(p));
    }
    EXPECT_LT(apart, 0.05 * moved) << "body " << k << ": mean displacement " << moved / fa.size()
                                   << " m, mean difference " << apart / fa.size() << " m";
  }
}

TEST(Frames, ExteriorOnlyWritesTheSurfaceBlocks) {
  const fs::path dir = scratch("exterior");
  Scene scene = test::empty_scene(r3(1, 1, 1), 0.025, r3(0, 0, 0));
  scene.bodies.push_back(test::box_body(Constitutive::JFluid, r3(0.1, 0.1, 0.1), r3(0.4, 0.4, 0.4)));
  scene.bodies[0].output_attribs = {"ID"};
  scene.simulation.frames = 1;
  scene.simulation.save_suffix = ".csv";
  auto rows = [&](const Scene& s) {
    EXPECT_EQ(run_ranks(s, 1).exit_code, 0);
    std::ifstream in(dir / "model[0]_dev[0]_frame[0].csv");
    long long n = -1;  // the header
    for (std::string line; std::getline(in, line);) ++n;
    return n;
  };
  scene.simulation.save_path = dir.string();
  EXPECT_EQ(rows(scene), 32768);
  scene.bodies[0].output_exterior_only = true;
  EXPECT_EQ(rows(scene), 56 * 512);
  scene.bodies[0].output_exterior_only = false;
  scene.simulation.particles_output_exterior_only = true;
  EXPECT_EQ(rows(scene), 56 * 512);
  scene.bodies[0].exterior_threshold = 512;  // every block qualifies
  EXPECT_EQ(rows(scene), 32768);
}

}  // namespace
}  // namespace fbar
