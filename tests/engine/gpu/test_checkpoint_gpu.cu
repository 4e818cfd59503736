// Checkpoints and restart on the GPU engine: a GpuEngine continued from its own checkpoint (through the HDF5 file)
// computes the state of the run that was never stopped bit for bit, in double, single and mixed precision with
// ASFLIP, F-bar and a plastic body; run_gpu writes frame checkpoints and a SIGTERM checkpoint (one recording step
// after the request), and a restart from either writes the bytes of the uninterrupted run (restart_cases.h: also on
// two ranks, with a saturated body and with a mesh).
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "engine/engine_api.h"
#include "engine/gpu/gpu_engine.h"
#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "engine/stop_request.h"
#include "io/checkpoint.h"
#include "scene/scene_parse.h"
#include "../cpu/decomposition_scenes.h"
#include "../restart_cases.h"
#include "../resume_support.h"
#include "../run_support.h"
#include "gpu_test_support.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;
using test::r3;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("fbar_gpu_checkpoint_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// The dam break with ASFLIP and F-bar and a Drucker-Prager block beside it.
Scene two_body_scene(Precision precision) {
  Scene scene = test::dam_break(true);
  scene.simulation.precision = precision;
  BodySpec sand = test::box_body(Constitutive::DruckerPrager, r3(0.44, 0.04, 0.04), r3(0.1, 0.1, 0.12));
  sand.model = 1;
  scene.bodies.push_back(sand);
  return scene;
}

template <typename T, typename TG>
void expect_engine_restart(Precision precision) {
  const fs::path dir = scratch(std::string("engine_") + to_string(precision));
  const Scene scene = two_body_scene(precision);
  GpuEngine<T, TG> a(scene);
  a.set_log(nullptr);
  for (int s = 0; s < 150; ++s) {
    a.keep_checkpoint_inputs(s == 149);
    ASSERT_TRUE(a.step().ok);
  }
  ASSERT_TRUE(a.checkpoint_ready());
  const fs::path file = io::checkpoint_step_path(dir, a.steps(), 0);
  io::write_checkpoint(file, a.checkpoint());
  const io::Checkpoint c = io::read_checkpoint_set(file);
  EXPECT_EQ(c.engine, "gpu");
  EXPECT_EQ(c.steps, 150);
  for (const io::CheckpointBody& body : c.bodies) EXPECT_TRUE(body.p2g_known);  // the blocks of the last P2G
  GpuEngineOptions options;
  options.restart = &c;
  GpuEngine<T, TG> b(scene, options);
  b.set_log(nullptr);
  EXPECT_EQ(b.steps(), a.steps());
  EXPECT_EQ(b.time(), a.time());
  EXPECT_EQ(b.next_dt(), a.next_dt());
  EXPECT_TRUE(b.checkpoint_ready());  // the restart's P2G recorded v and C
  for (int s = 0; s < 150; ++s) {
    a.keep_checkpoint_inputs(s == 149);  // the last step records v and C in both: the snapshots read them
    b.keep_checkpoint_inputs(s == 149);
    ASSERT_TRUE(a.step().ok);
    ASSERT_TRUE(b.step().ok);
    ASSERT_EQ(b.time(), a.time()) << "step " << s + 1;  // the CFL dt: the grid speeds are the same bits
  }
  EXPECT_EQ(b.steps(), a.steps());
  for (int body = 0; body < 2; ++body) {
    const ParticleSnapshot<T> sa = a.snapshot(body), sb = b.snapshot(body);
    ASSERT_EQ(sa.x.size(), sb.x.size());
    std::size_t differ = 0;
    double worst = 0.0;
    for (std::size_t p = 0; p < sa.x.size(); ++p) {
      bool same = sa.J[p] == sb.J[p];
      for (int d = 0; d < 3; ++d) {
        same = same && sa.x[p][d] == sb.x[p][d] && sa.v[p][d] == sb.v[p][d];
        worst = test::worst(worst, std::fabs(static_cast<double>(sa.x[p][d] - sb.x[p][d])));
      }
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          same = same && sa.C[p](i, j) == sb.C[p](i, j);
          if (!sa.F.empty()) same = same && sa.F[p](i, j) == sb.F[p](i, j);
        }
      if (!sa.logJp.empty()) same = same && sa.logJp[p] == sb.logJp[p];
      differ += same ? 0 : 1;  // NaN differs
    }
    std::printf("[measured] %s restart, body %d: %zu of %zu particles differ, max |dx| %.3g m\n",
                to_string(precision), body, differ, sa.x.size(), worst);
    EXPECT_EQ(differ, 0u) << "body " << body << ": the restarted run left the uninterrupted one (max |dx| " << worst
                          << " m)";
    EXPECT_EQ(sb.logJp.empty(), sa.logJp.empty());
  }
}

// ClaymoreUW's resume on the GPU engine: bodies seeded from .bgeo frames (has_attributes) start in the frame's state
// (velocity, J of the water; velocity, F and logJp of the sand: equal to the CPU engine's seeding, as floats), and
// then follow the CPU engine's run of the same seeded scene to round-off (double, 20 steps of the GPU's dt).
TEST(GpuResume, ABgeoFrameSeedsBodiesAsOnTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const fs::path dir = scratch("resume_bgeo");
  Scene a = two_body_scene(Precision::Double);
  a.bodies[1].velocity = r3(0.5, 0.0, -0.25);
  test::output_state_attributes(a);
  CpuEngine<double> run(a);
  run.set_log(nullptr);
  for (int i = 0; i < 40; ++i) ASSERT_TRUE(run.step().ok);
  const Scene b = test::seeded_from_frames(a, run, dir);
  CpuEngine<double> cpu(b);
  cpu.set_log(nullptr);
  GpuEngineOptions with_frames;
  with_frames.frames = true;
  GpuEngine<double, double> gpu(b, with_frames);
  gpu.set_log(nullptr);
  {
    // Frame 0 of the seeded state (ClaymoreUW's resume writes it first): the seeds' velocities, as the CPU's frame.
    io::AsyncWriter writer(1);
    gpu.submit_frame(1, dir / "gpu_frame0.bgeo", writer);
    writer.close();
    const io::ParticleFrame written = io::read_bgeo(dir / "gpu_frame0.bgeo");
    const io::ParticleFrame seeded = cpu.frame(1);
    ASSERT_EQ(written.size(), seeded.size());
    EXPECT_EQ(written.find("Velocity_X")->floats(), seeded.find("Velocity_X")->floats());
    EXPECT_EQ(written.find("Velocity_Z")->floats(), seeded.find("Velocity_Z")->floats());
  }
  for (int k = 0; k < 2; ++k) {
    const io::ParticleFrame seeded = cpu.frame(k);
    const ParticleSnapshot<double> s = gpu.snapshot(k);
    ASSERT_EQ(s.x.size(), seeded.size()) << "body " << k;
    const std::vector<float>& vx = seeded.find("Velocity_X")->floats();
    const std::vector<float>& vz = seeded.find("Velocity_Z")->floats();
    for (std::size_t p = 0; p < s.x.size(); ++p) {
      ASSERT_EQ(static_cast<float>(s.v[p][0]), vx[p]) << "body " << k << " particle " << p;
      ASSERT_EQ(static_cast<float>(s.v[p][2]), vz[p]) << "body " << k << " particle " << p;
      if (k == 0) {
        ASSERT_EQ(static_cast<float>(s.J[p]), seeded.find("J")->floats()[p]) << "particle " << p;
      } else {
        ASSERT_EQ(static_cast<float>(s.logJp[p]), seeded.find("logJp")->floats()[p]) << "particle " << p;
        ASSERT_EQ(static_cast<float>(s.F[p](0, 1)), seeded.find("DefGrad_XY")->floats()[p]) << "particle " << p;
        ASSERT_EQ(static_cast<float>(s.F[p](2, 2)), seeded.find("DefGrad_ZZ")->floats()[p]) << "particle " << p;
      }
    }
  }
  for (int i = 0; i < 20; ++i) {
    const StepReport r = gpu.step();
    ASSERT_TRUE(r.ok);
    ASSERT_TRUE(cpu.step(r.dt).ok);
  }
  for (int k = 0; k < 2; ++k) {
    const io::ParticleFrame f = cpu.frame(k);
    const ParticleSnapshot<double> s = gpu.snapshot(k);
    double worst = 0.0;
    for (std::size_t p = 0; p < s.x.size(); ++p)
      for (int d = 0; d < 3; ++d) worst = test::worst(worst, std::fabs(s.x[p][d] - f.position(p)[d]));
    EXPECT_LT(worst, 1e-9) << "body " << k;
  }
}

// A GpuEngine continued from its own checkpoint (through the HDF5 file) takes the steps and computes the state of
// the engine that was never stopped, bit for bit, 150 steps on: the restart's P2G groups every particle by the block
// its last P2G summed it from and uses that P2G's bound (io::CheckpointBody::p2g_block, p2g_bound).
TEST(GpuCheckpoint, EngineContinuesFromItsCheckpointDouble) {
  FBAR_REQUIRE_DEVICE();
  expect_engine_restart<double, double>(Precision::Double);
}
TEST(GpuCheckpoint, EngineContinuesFromItsCheckpointSingle) {
  FBAR_REQUIRE_DEVICE();
  expect_engine_restart<float, float>(Precision::Single);
}
TEST(GpuCheckpoint, EngineContinuesFromItsCheckpointMixed) {
  FBAR_REQUIRE_DEVICE();
  expect_engine_restart<double, float>(Precision::Mixed);
}

// A body whose state by ID exceeds frame_host_bytes (here 4 KiB: ranges of 60 particles or fewer) is checkpointed
// from the device a range of IDs at a time (io::Checkpoint::streamed, no host copy of the body): the file has the
// bytes of the copied body's, before the first step (the initial velocities, C = 0) and after a recording step (v,
// C and the P2G blocks), in every precision.
template <typename T, typename TG>
void expect_streamed_checkpoint_is_copied_one(Precision precision) {
  const Scene scene = two_body_scene(precision);
  for (const int steps : {0, 30}) {
    const std::string tag = std::string(to_string(precision)) + "_" + std::to_string(steps);
    fs::path files[2];
    for (int streamed = 0; streamed < 2; ++streamed) {
      GpuEngineOptions o;
      if (streamed) o.frame_host_bytes = 4096;
      GpuEngine<T, TG> gpu(scene, o);
      gpu.set_log(nullptr);
      for (int s = 0; s < steps; ++s) {
        gpu.keep_checkpoint_inputs(s == steps - 1);
        ASSERT_TRUE(gpu.step().ok);
      }
      const io::Checkpoint c = gpu.checkpoint();
      if (streamed) {
        ASSERT_EQ(c.streamed.size(), 2u) << tag;
        for (std::size_t b = 0; b < 2; ++b) {
          EXPECT_TRUE(c.is_streamed(b)) << tag << " body " << b;
          EXPECT_TRUE(c.bodies[b].x.empty()) << tag << " body " << b << ": copied to the host";
          EXPECT_EQ(c.streamed[b].particles, static_cast<std::size_t>(gpu.particle_count(static_cast<int>(b))));
        }
      } else {
        EXPECT_TRUE(c.streamed.empty()) << tag;
      }
      files[streamed] = scratch("streamed_" + tag + "_" + std::to_string(streamed)) / "checkpoint.h5";
      io::write_checkpoint(files[streamed], c);
    }
    EXPECT_GT(fs::file_size(files[0]), 10000u) << tag;
    test::restart::expect_same_checkpoint(files[0], files[1], "streamed checkpoint " + tag);
  }
}
TEST(GpuCheckpoint, StreamedBodyWritesTheCopiedBodysBytesDouble) {
  FBAR_REQUIRE_DEVICE();
  expect_streamed_checkpoint_is_copied_one<double, double>(Precision::Double);
}
TEST(GpuCheckpoint, StreamedBodyWritesTheCopiedBodysBytesSingleAndMixed) {
  FBAR_REQUIRE_DEVICE();
  expect_streamed_checkpoint_is_copied_one<float, float>(Precision::Single);
  expect_streamed_checkpoint_is_copied_one<double, float>(Precision::Mixed);
}

/// run_gpu with a 4 KiB --frame-buffer: every particle body's checkpoint is streamed.
RunResult run_gpu_streamed(const Scene& scene, const RunOptions& options) {
  RunOptions o = options;
  o.frame_host_bytes = 4096;
  return run_gpu(scene, o);
}

// Through run_gpu on 1 and 2 ranks (with a placed mesh, which is never streamed, on two): a run whose checkpoints are
// streamed writes the checkpoint files of a run whose checkpoints are copied, and a restart from one writes the
// uninterrupted run's bytes.
TEST(GpuRestart, StreamedCheckpointsWriteTheCopiedOnesBytesAndContinue) {
  FBAR_REQUIRE_DEVICE();
  for (const int ranks : {1, 2}) {
    const std::string tag = std::to_string(ranks);
    const fs::path a = test::restart::scratch("copied_" + tag), b = test::restart::scratch("streamed_" + tag);
    Scene scene = test::restart::restart_scene(a);
    if (ranks == 2) test::restart::add_placed_mesh(scene);
    scene.simulation.checkpoint_every = 2;
    ASSERT_EQ(test::restart::run_ranks(run_gpu, scene, ranks).exit_code, 0);
    scene.simulation.save_path = b.string();
    ASSERT_EQ(test::restart::run_ranks(run_gpu_streamed, scene, ranks).exit_code, 0);
    for (int f : {2, 4, 6})
      for (int d = 0; d < ranks; ++d)
        test::restart::expect_same_checkpoint(io::checkpoint_frame_path(a, f, d), io::checkpoint_frame_path(b, f, d),
                                              "ranks " + tag + " frame " + std::to_string(f) + " dev " +
                                                  std::to_string(d));
  }
  test::restart::expect_frame_restart(run_gpu_streamed, "gpu", 2, {}, "_streamed");
}

// Through run_gpu, the cases the CPU engine passes (restart_cases.h): a frame checkpoint continued in a folder
// holding only what the run had written by then writes the uninterrupted run's bytes (frames, sensor and tracker
// rows), on one rank and on two thread ranks sharing the GPU, in every precision, with a saturated body and with a
// placed mesh; a SIGTERM checkpoint (taken after the step in progress, not at a frame time) likewise.
TEST(GpuRestart, FromAFrameCheckpointWritesTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_frame_restart(run_gpu, "gpu", 1);
}
TEST(GpuRestart, FromAFrameCheckpointWritesTheSameBytesOnTwoRanks) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_frame_restart(run_gpu, "gpu", 2);
}
TEST(GpuRestart, SingleAndMixedPrecisionWriteTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_frame_restart(run_gpu, "gpu", 1, [](Scene& scene) { scene.simulation.precision = Precision::Single; },
                                      "_single");
  test::restart::expect_frame_restart(run_gpu, "gpu", 2, [](Scene& scene) { scene.simulation.precision = Precision::Mixed; },
                                      "_mixed");
}
TEST(GpuRestart, SaturatedSoilWritesTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_frame_restart(run_gpu, "gpu", 1, test::restart::saturate_second_body, "_saturated");
  test::restart::expect_frame_restart(run_gpu, "gpu", 2, test::restart::saturate_second_body, "_saturated");
}
TEST(GpuRestart, NodalFbarWritesTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_frame_restart(run_gpu, "gpu", 1, test::restart::nodal_fbar_bodies, "_nodal");
  test::restart::expect_frame_restart(run_gpu, "gpu", 2, test::restart::nodal_fbar_bodies, "_nodal");
}
TEST(GpuRestart, MeshWritesTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_frame_restart(run_gpu, "gpu", 1, test::restart::add_placed_mesh, "_mesh");
  test::restart::expect_frame_restart(run_gpu, "gpu", 2, test::restart::add_placed_mesh, "_mesh");
}
TEST(GpuRestart, AfterAStopRequestWritesTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  test::restart::expect_stop_restart(run_gpu, "gpu");
}

/// The numbers of a CSV frame (header skipped), row by row.
std::vector<std::vector<double>> read_frame(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) row.push_back(std::stod(cell));
    rows.push_back(row);
  }
  return rows;
}

void expect_same_frames(const fs::path& a, const fs::path& b, int from, int to) {
  for (int f = from; f <= to; ++f)
    for (int m = 0; m < 2; ++m) {
      const std::string name = io::frame_file_name(m, 0, f, ".csv");
      ASSERT_TRUE(fs::exists(b / name)) << name;
      const auto ra = read_frame(a / name);
      ASSERT_FALSE(ra.empty()) << name;
      test::restart::expect_same_bytes(test::restart::bytes_of(a / name), test::restart::bytes_of(b / name), name);
    }
}

// run_gpu: checkpoint_every = 2 writes frames 2 and 4; a restart from frame 2 writes frames 3..5 as the full run did;
// SIGTERM mid-run writes a checkpoint after one more (recording) step, and a restart from it completes the run.
TEST(GpuCheckpoint, RunGpuRestartsFromFrameAndSignalCheckpoints) {
  FBAR_REQUIRE_DEVICE();
  const fs::path a = scratch("run_a"), b = scratch("run_b"), c = scratch("run_c");
  Scene scene = two_body_scene(Precision::Double);
  scene.simulation.fps = 50.0;
  scene.simulation.frames = 5;
  scene.simulation.save_suffix = ".csv";
  scene.simulation.checkpoint_every = 2;
  scene.bodies[0].output_attribs = {"ID", "Velocity_X", "Velocity_Y", "J"};
  scene.bodies[1].output_attribs = {"ID", "logJp", "Pressure"};
  RunOptions options;
  options.quiet = true;
  scene.simulation.save_path = a.string();
  const RunResult full = run_gpu(scene, options);
  ASSERT_EQ(full.exit_code, 0) << full.message;
  EXPECT_TRUE(fs::exists(io::checkpoint_frame_path(a, 2, 0)));
  EXPECT_TRUE(fs::exists(io::checkpoint_frame_path(a, 4, 0)));
  scene.simulation.save_path = b.string();
  options.restart = io::checkpoint_frame_path(a, 2, 0).string();
  const RunResult resumed = run_gpu(scene, options);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.message;
  EXPECT_EQ(resumed.restarted_from_frame, 2);
  EXPECT_FALSE(fs::exists(b / io::frame_file_name(0, 0, 2, ".csv")));
  expect_same_frames(a, b, 3, 5);

  // A stop request when frame 1's progress line is written (as a signal arriving then): the next step records v and
  // C, then the checkpoint.
  scene.simulation.save_path = c.string();
  scene.simulation.checkpoint_every = 0;
  options.restart.clear();
  clear_stop_request();
  test::StopWhenLogged stop("frame 1/", SIGTERM);
  std::ostream log(&stop);
  RunOptions logged = options;
  logged.quiet = false;
  logged.log = &log;
  const RunResult stopped = run_gpu(scene, logged);
  clear_stop_request();
  ASSERT_EQ(stopped.exit_code, 128 + SIGTERM) << stopped.message << stop.text();
  EXPECT_EQ(stopped.frames_written, 1);
  ASSERT_FALSE(stopped.checkpoint.empty()) << stopped.message;
  const io::Checkpoint cp = io::read_checkpoint(stopped.checkpoint);
  EXPECT_EQ(cp.reason, "SIGTERM");
  EXPECT_EQ(cp.steps, stopped.steps);  // one recording step after the request
  options.restart = stopped.checkpoint;
  const RunResult rest = run_gpu(scene, options);
  ASSERT_EQ(rest.exit_code, 0) << rest.message;
  expect_same_frames(a, c, stopped.frames_written + 1, 5);
}

}  // namespace
}  // namespace fbar
