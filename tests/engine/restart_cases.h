// Restart cases for both engines (io/checkpoint.h, run_loop.h): a run continued from one of its checkpoints, in a
// folder holding only what the run had written by then, must write the bytes the uninterrupted run wrote: frames,
// sensor and tracker rows. test_checkpoint.cpp runs them on the CPU engine, test_checkpoint_gpu.cu on the GPU one.
#pragma once

#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "cpu/decomposition_scenes.h"
#include "engine/engine_api.h"
#include "engine/stop_request.h"
#include "io/checkpoint.h"
#include "../physics/physics_test_support.h"
#include "run_support.h"

namespace fbar::test::restart {

namespace fs = std::filesystem;

/// `b` has `a`'s bytes; on a difference, its sizes and first differing byte (not the whole files).
inline void expect_same_bytes(const std::string& a, const std::string& b, const std::string& name) {
  if (a == b) return;
  std::size_t i = 0;
  while (i < a.size() && i < b.size() && a[i] == b[i]) ++i;
  ADD_FAILURE() << name << ": the restarted run's file differs from the run's (" << b.size() << " against "
                << a.size() << " bytes, first difference at byte " << i << ")";
}

using test::RunFn;

inline fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("fbar_restart_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

inline std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Which part of two checkpoint files differs (read back: the header's fields, then each body's arrays), for a
/// failure message that says what a restart did not carry over; "" when every field read is equal.
inline std::string checkpoint_difference(const fs::path& a_path, const fs::path& b_path) {
  const io::Checkpoint a = io::read_checkpoint(a_path), b = io::read_checkpoint(b_path);
  auto field = [](const char* name, const auto& x, const auto& y) -> std::string { return x == y ? "" : name; };
  for (const std::string& d :
       {field("time", a.time, b.time), field("steps", a.steps, b.steps), field("last_dt", a.last_dt, b.last_dt),
        field("next_dt", a.next_dt, b.next_dt), field("max_grid_speed", a.max_grid_speed, b.max_grid_speed),
        field("dt_scale", a.dt_scale, b.dt_scale), field("clean_steps", a.clean_steps, b.clean_steps),
        field("slab_cuts", a.slab_cuts, b.slab_cuts), field("chosen_imbalance", a.chosen_imbalance, b.chosen_imbalance),
        field("particle_sample_due", a.particle_sample_due, b.particle_sample_due), field("csv", a.csv, b.csv),
        field("bodies", a.bodies.size(), b.bodies.size())})
    if (!d.empty()) return d;
  for (std::size_t k = 0; k < a.bodies.size(); ++k) {
    const io::CheckpointBody &x = a.bodies[k], &y = b.bodies[k];
    for (const std::string& d :
         {field("max_wave_speed", x.max_wave_speed, y.max_wave_speed), field("p2g_bound", x.p2g_bound, y.p2g_bound),
          field("p2g_capture", x.p2g_capture, y.p2g_capture), field("ID", x.id, y.id), field("Position", x.x, y.x),
          field("Velocity", x.v, y.v), field("C", x.C, y.C), field("State", x.state, y.state),
          field("Mass", x.mass, y.mass), field("Volume", x.volume, y.volume), field("P2GID", x.p2g_id, y.p2g_id),
          field("P2GBlock", x.p2g_block, y.p2g_block)})
      if (!d.empty()) return "bodies[" + std::to_string(k) + "]." + d;
  }
  return "";
}

/// expect_same_bytes of two checkpoint files, naming the field that differs.
inline void expect_same_checkpoint(const fs::path& a, const fs::path& b, const std::string& name) {
  const std::string x = bytes_of(a), y = bytes_of(b);
  if (x == y) return;
  expect_same_bytes(x, y, name);
  const std::string d = checkpoint_difference(a, b);
  ADD_FAILURE() << name << ": " << (d.empty() ? "every field read back is equal (the file layout differs)" : d + " differs");
}

/// rank 0's result of run_ranks_with (run_support.h).
inline RunResult run_ranks(RunFn run, const Scene& scene, int ranks, const std::string& restart = "",
                           std::ostream* log = nullptr) {
  return run_ranks_with(run, scene, ranks, restart, log).front();
}

/// The dam break with ASFLIP and F-bar, a Drucker-Prager block (F and logJp) beside it, two grid sensors, two
/// particle sensors and a tracker; 6 frames at 50 fps, bgeo frames (raw floats: a byte comparison is exact).
inline Scene restart_scene(const fs::path& out) {
  Scene scene = test::dam_break(true);
  BodySpec sand = test::box_body(Constitutive::DruckerPrager, r3(0.44, 0.04, 0.04), r3(0.1, 0.1, 0.12));
  sand.model = 1;
  sand.output_attribs = {"ID", "Velocity_X", "Velocity_Y", "logJp", "Pressure"};
  scene.bodies[0].output_attribs = {"ID", "Velocity_X", "Velocity_Y", "J"};
  scene.bodies.push_back(sand);
  scene.simulation.fps = 50.0;
  scene.simulation.frames = 6;
  scene.simulation.save_suffix = ".bgeo";
  scene.simulation.save_path = out.string();
  GridSensorSpec force = test::grid_sensor_spec("Force", SensorOperation::Sum, {0, 0, 0}, {0.64, 0.05, 0.2}, {0, 1, 0}, -1);
  force.output_frequency = 230.0;  // sample times between steps and frames
  GridSensorSpec mass = test::grid_sensor_spec("Mass", SensorOperation::Sum, {0, 0, 0}, {0.64, 0.4, 0.2});
  mass.output_frequency = 50.0;    // on the frame times (the checkpoint's time among them)
  scene.grid_sensors = {force, mass};
  ParticleSensorSpec gauge = test::particle_sensor_spec("Position_Y", SensorOperation::Max, {0.1, 0, 0}, {0.2, 0.4, 0.2});
  gauge.output_frequency = 100.0;
  ParticleSensorSpec speed = test::particle_sensor_spec("Velocity_X", SensorOperation::Average, {0, 0, 0}, {0.64, 0.4, 0.2});
  speed.output_frequency = 70.0;
  scene.particle_sensors = {gauge, speed};
  scene.bodies[0].track_particle_id = {0, 17, 3000};
  scene.bodies[0].track_attribs = {"Position_X", "Velocity_Y"};
  return scene;
}

/// The saturated-soil variant: body 1 CoupledUP (its pore pressure in the frames), pore-pressure and water-mass
/// grid sensors.
inline void saturate_second_body(Scene& scene) {
  test::saturate(scene.bodies[1]);
  scene.bodies[1].output_attribs = {"ID", "Velocity_X", "PorePressure", "logJp", "Pressure"};
  GridSensorSpec pore = test::grid_sensor_spec("PorePressure", SensorOperation::Average, {0, 0, 0}, {0.64, 0.4, 0.2});
  pore.output_frequency = 230.0;
  GridSensorSpec water = test::grid_sensor_spec("MassWater", SensorOperation::Sum, {0, 0, 0}, {0.64, 0.4, 0.2});
  water.output_frequency = 50.0;
  scene.grid_sensors.push_back(pore);
  scene.grid_sensors.push_back(water);
}

/// The nodal F-bar variant (ClaymoreUW's JBar, fbar_nodal.cuh): the water fused, the Drucker-Prager block split, both
/// writing JBar in their frames (the checkpoint carries 1 - JBar after each law's state).
inline void nodal_fbar_bodies(Scene& scene) {
  for (BodySpec& b : scene.bodies) {
    b.algorithm.use_fbar = true;
    b.algorithm.fbar_psi = b.material.law == Constitutive::JFluid ? 0.9 : 0.8;
    b.algorithm.fbar_scheme = FbarScheme::Nodal;
    b.algorithm.fbar_fused_kernel = b.material.law == Constitutive::JFluid;
    b.output_attribs.push_back("JBar");
  }
}

/// The mesh variant: an elastic tetrahedral block (FEM body) placed on rank 1, its frames and a .vtk beside them.
inline void add_placed_mesh(Scene& scene) {
  MeshEntrySpec& m = test::add_elastic_mesh(
      scene, box_tet_mesh(Vec3d{{0.3, 0.26, 0.06}}, Vec3d{{0.36, 0.32, 0.12}}, Vec3i{{3, 3, 3}}), 800.0, 2e5, 0.3, 1);
  m.output_attribs = {"ID", "Velocity_Y", "J"};
  append_mesh_bodies(scene);
}

/// Every frame file (model[m]_dev[d]_frame[f].*, a mesh's .vtk beside it too) of `a` after frame `from`, and every
/// CSV of `a`, has the same bytes in `b`; `streams` (model, rank) pairs write frames (2 bodies on each rank unless
/// the caller adds a body), and `csv_files` CSVs are compared; so is every frame checkpoint after `from` (their count
/// `checkpoints` when it is not -1).
inline void expect_same_output(const fs::path& a, const fs::path& b, int from, int streams, int csv_files = 7,
                               int checkpoints = -1) {
  static const std::regex frame_name(R"(model\[(\d+)\]_dev\[(\d+)\]_frame\[(\d+)\]\..*)");
  static const std::regex checkpoint_name(R"(checkpoint_frame\[(\d+)\]_dev\[\d+\]\.h5)");
  int compared_csv = 0, compared_frames = 0, compared_checkpoints = 0;
  std::set<std::pair<int, int>> writers;
  for (const auto& e : fs::directory_iterator(a)) {
    const std::string name = e.path().filename().string();
    std::smatch m;
    if (e.path().extension() == ".csv" && !std::regex_match(name, m, frame_name)) {
      ASSERT_TRUE(fs::exists(b / name)) << name;
      expect_same_bytes(bytes_of(e.path()), bytes_of(b / name), name);
      ++compared_csv;
    } else if (std::regex_match(name, m, frame_name) && std::stoi(m[3]) > from) {
      writers.insert({std::stoi(m[1]), std::stoi(m[2])});
      ASSERT_TRUE(fs::exists(b / name)) << name << ": not written by the restarted run";
      expect_same_bytes(bytes_of(e.path()), bytes_of(b / name), name);
      ++compared_frames;
    } else if (std::regex_match(name, m, checkpoint_name) && std::stoi(m[1]) > from) {
      ASSERT_TRUE(fs::exists(b / name)) << name << ": not written by the restarted run";
      expect_same_checkpoint(e.path(), b / name, name);
      ++compared_checkpoints;
    }
  }
  if (checkpoints >= 0) {
    EXPECT_EQ(compared_checkpoints, checkpoints) << "later checkpoints";
  }
  EXPECT_EQ(compared_csv, csv_files);
  EXPECT_EQ(static_cast<int>(writers.size()), streams) << "frame writers (model, rank)";
  EXPECT_GE(compared_frames, streams * (6 - from));  // .bgeo per stream and frame, and a mesh's .vtk
}

/// `b` as a user leaves it to continue a run of `a` from `checkpoint` in place: `a`'s files up to the checkpoint.
/// Later frames and frame checkpoints are removed and each sensor / tracker CSV keeps the bytes the checkpoint recorded, followed by a
/// line the restart must cut (a restart that wrote nothing would then leave both visible).
inline void copy_up_to_checkpoint(const fs::path& a, const fs::path& b, const fs::path& checkpoint, int from) {
  static const std::regex frame_name(R"(model\[\d+\]_dev\[\d+\]_frame\[(\d+)\]\..*)");
  static const std::regex checkpoint_name(R"(checkpoint_frame\[(\d+)\]_dev\[\d+\]\.h5)");
  fs::copy(a, b, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  const io::Checkpoint c = io::read_checkpoint(b / checkpoint.filename());
  ASSERT_FALSE(c.csv.empty()) << "the checkpoint recorded no sensor file";
  for (const auto& e : fs::directory_iterator(b)) {
    const std::string name = e.path().filename().string();
    std::smatch m;
    if ((std::regex_match(name, m, frame_name) || std::regex_match(name, m, checkpoint_name)) && std::stoi(m[1]) > from)
      fs::remove(e.path());
  }
  for (const auto& [name, bytes] : c.csv) {
    ASSERT_TRUE(fs::exists(b / name)) << name;
    std::string text = bytes_of(b / name);
    ASSERT_LE(static_cast<std::size_t>(bytes), text.size()) << name;
    text.resize(static_cast<std::size_t>(bytes));
    std::ofstream(b / name, std::ios::binary | std::ios::trunc) << text << "9.99,planted row after the checkpoint\n";
  }
}

/// A frame checkpoint continues bit for bit (`run`: run_cpu or run_gpu, on `ranks` thread ranks): frames, sensor rows and tracker rows; also in a fresh directory (the
/// sensor files then start again, with a warning).
inline void expect_frame_restart(RunFn run, const std::string& engine, int ranks,
                                 const std::function<void(Scene&)>& change = {}, const std::string& name = "") {
  const std::string tag = engine + std::to_string(ranks) + name;
  const fs::path a = scratch("frames_a" + tag), b = scratch("frames_b" + tag);
  Scene scene = restart_scene(a);
  if (change) change(scene);
  scene.simulation.checkpoint_every = 2;
  const RunResult full = run_ranks(run, scene, ranks);
  ASSERT_EQ(full.exit_code, 0) << full.message;
  for (int f : {2, 4, 6})
    for (int d = 0; d < ranks; ++d) EXPECT_TRUE(fs::exists(io::checkpoint_frame_path(a, f, d))) << f;
  EXPECT_FALSE(fs::exists(io::checkpoint_frame_path(a, 3, 0)));
  EXPECT_EQ(full.checkpoint, io::checkpoint_frame_path(a, 6, 0).string());
  // The same directory's files up to frame 2, continued from its checkpoint: its later frames and the CSVs' rows
  // after it are the restart's.
  copy_up_to_checkpoint(a, b, io::checkpoint_frame_path(a, 2, 0), 2);
  scene.simulation.save_path = b.string();
  const RunResult resumed = run_ranks(run, scene, ranks, io::checkpoint_frame_path(b, 2, 0).string());
  ASSERT_EQ(resumed.exit_code, 0) << resumed.message;
  EXPECT_EQ(resumed.restarted_from_frame, 2);
  EXPECT_EQ(resumed.steps, full.steps);
  EXPECT_EQ(resumed.end_time, full.end_time);
  // CSVs: the tracker's, each particle sensor's per body, each grid sensor's. Frames: each particle body on every
  // rank, a placed mesh on its own.
  int streams = 0;
  for (const BodySpec& body : scene.bodies) streams += body.mesh >= 0 ? 1 : ranks;
  expect_same_output(a, b, 2, streams,
                     1 + static_cast<int>(scene.particle_sensors.size() * scene.bodies.size() + scene.grid_sensors.size()),
                     2 * ranks);  // frames 4 and 6
}

/// SIGTERM mid-run (request_stop, as the handler records it, when frame 1's progress line is written): the run
/// stops after the step in progress (not at a frame time), writes checkpoint_step[s], and a restart from it writes
/// the uninterrupted run's bytes.
inline void expect_stop_restart(RunFn run, const std::string& engine) {
  const fs::path a = scratch("stop_a" + engine), b = scratch("stop_b" + engine);
  Scene scene = restart_scene(a);
  ASSERT_EQ(run_ranks(run, scene, 1).exit_code, 0);
  scene.simulation.save_path = b.string();
  clear_stop_request();
  test::StopWhenLogged stop("frame 1/", SIGTERM);
  std::ostream log(&stop);
  const RunResult stopped = run_ranks(run, scene, 1, "", &log);
  clear_stop_request();
  ASSERT_EQ(stopped.exit_code, 128 + SIGTERM) << stopped.message << stop.text();
  EXPECT_EQ(stopped.frames_written, 1);
  ASSERT_FALSE(stopped.checkpoint.empty());
  EXPECT_NE(stopped.checkpoint.find("checkpoint_step[" + std::to_string(stopped.steps) + "]_dev[0].h5"),
            std::string::npos)
      << stopped.checkpoint;
  EXPECT_NE(stopped.message.find("--restart="), std::string::npos) << stopped.message;
  const io::Checkpoint c = io::read_checkpoint(stopped.checkpoint);
  EXPECT_EQ(c.reason, "SIGTERM");
  EXPECT_EQ(c.steps, stopped.steps);
  EXPECT_EQ(c.frame, stopped.frames_written);
  const RunResult resumed = run_ranks(run, scene, 1, stopped.checkpoint);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.message;
  expect_same_output(a, b, stopped.frames_written, 2);
}

}  // namespace fbar::test::restart
