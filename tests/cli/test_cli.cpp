// The fbar command line in-process: bad-scene corpus, good scenes, options, exit codes, a short run and run.json.
#include <gtest/gtest.h>
#include <rapidjson/document.h>
#include <rapidjson/stringbuffer.h>
#include <rapidjson/writer.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <thread>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli.h"
#include "cli_test_support.h"
#include "engine/engine_api.h"
#include "engine/stop_request.h"
#include "geometry/tet_mesh.h"
#include "io/checkpoint.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;

const fs::path kScenes = FBAR_SCENES_DIR;

using test::CliResult;
using test::run_cli;

/// This process's scratch root; removed after the last test.
fs::path scratch_root() { return fs::temp_directory_path() / ("fbar_test_cli_" + std::to_string(::getpid())); }

struct RemoveScratch : ::testing::Environment {
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(scratch_root(), ec);
  }
};
[[maybe_unused]] const auto* const kRemoveScratch = ::testing::AddGlobalTestEnvironment(new RemoveScratch);

/// A fresh scratch directory for this test (removed first if it exists).
fs::path scratch(const std::string& name) {
  const fs::path p = scratch_root() / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p);
  out << text;
}

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> parts;
  std::stringstream ss(line);
  std::string item;
  while (std::getline(ss, item, sep)) parts.push_back(item);
  return parts;
}

// Every file of tests/scenes/bad is listed in expectations.txt as `file|exit code|JSON path|message substring`;
// `fbar --check` must exit with that code, print `fbar: error: <path>: ...` on stderr and contain the substring.
TEST(CliCorpus, BadScenesFailWithPathAndMessage) {
  std::ifstream in(kScenes / "bad" / "expectations.txt");
  ASSERT_TRUE(in) << "missing " << (kScenes / "bad" / "expectations.txt");
  std::set<std::string> listed;
  std::string line;
  int cases = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const auto f = split(line, '|');
    ASSERT_EQ(f.size(), 4u) << "malformed expectation line: " << line;
    const std::string& file = f[0];
    const int code = std::stoi(f[1]);
    const std::string& path = f[2];
    const std::string& text = f[3];
    listed.insert(file);
    SCOPED_TRACE(file);
    const CliResult r = run_cli({"--check", "--file=" + (kScenes / "bad" / file).string()});
    EXPECT_EQ(r.code, code) << r.err;
    EXPECT_EQ(r.err.rfind("fbar: error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(path + ": got "), std::string::npos) << "path '" << path << "' not named in: " << r.err;
    EXPECT_NE(r.err.find(text), std::string::npos) << "'" << text << "' not in: " << r.err;
    EXPECT_EQ(r.out.find("particles"), std::string::npos) << "a failing check printed a report";
    ++cases;
  }
  EXPECT_GE(cases, 25);
  for (const auto& e : fs::directory_iterator(kScenes / "bad")) {
    if (e.path().extension() != ".json") continue;
    EXPECT_TRUE(listed.count(e.path().filename().string())) << e.path() << " has no line in expectations.txt";
  }
}

TEST(CliCorpus, GoodScenesPassCheck) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(kScenes / "good")) {
    if (e.path().extension() != ".json") continue;
    SCOPED_TRACE(e.path().string());
    const CliResult r = run_cli({"--check", e.path().string()});
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("error"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("particles"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("time step"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("memory (GPU 0)"), std::string::npos) << r.out;
    ++n;
  }
  EXPECT_GE(n, 5);
}

TEST(Cli, CheckPrintsTheResolvedSceneWithUnits) {
  const CliResult r = run_cli({"--check", "--file=" + (kScenes / "good" / "froude_scaled_block.json").string()});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* s : {"default_dx", "default_dt", "gravity", "fps", "frames", "save_suffix", "froude_scaling",
                        "precision", "on_failure", "FixedCorotated", "youngs_modulus", " Pa", " m/s", "geometry[0]",
                        "boundaries[0]", "p-wave speed", "time step bound", "memory (CPU engine)"})
    EXPECT_NE(r.out.find(s), std::string::npos) << "'" << s << "' missing from\n" << r.out;
  // froude_scaling 2 doubles the 0.02 m grid.
  EXPECT_NE(r.out.find("0.04 m"), std::string::npos) << r.out;
}

// --check says whether several GPUs pay for the scene (kMultiGpuMinParticles), counting as a run would
// (scene_work_particles: a mesh element as 5 particles).
TEST(Cli, CheckSaysWhetherSeveralGpusPay) {
  const fs::path file = kScenes / "good" / "tiny_fluid.json";
  const CliResult r = run_cli({"--check", "--file=" + file.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("GPU ranks"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("one: below 2000000 particles"), std::string::npos) << r.out;
  Scene scene = parse_scene_file(file.string(), ParseOptions{});
  const long long particles = summarize_scene(scene).bodies.at(0).particles;
  EXPECT_EQ(scene_work_particles(scene, kMultiGpuMinParticles), particles);
  EXPECT_GE(scene_work_particles(scene, 10), 10);  // stops once the count reaches the cap
  MeshEntrySpec m;
  m.use_fem = true;
  m.mesh = std::make_shared<const TetMesh>(box_tet_mesh(Vec3d{{0.1, 0.1, 0.1}}, Vec3d{{0.2, 0.2, 0.2}}, Vec3i{{2, 2, 2}}));
  scene.meshes.push_back(m);
  append_mesh_bodies(scene);
  EXPECT_EQ(scene_work_particles(scene, kMultiGpuMinParticles), particles + 27 + 5 * 48);
}

TEST(Cli, HelpListsEveryOption) {
  const CliResult r = run_cli({"--help"});
  EXPECT_EQ(r.code, 0);
  for (const char* o : {"--file", "-f FILE", "--check", "--backend=auto|gpu|cpu", "--output", "--frames", "--quiet",
                        "--allow-unknown-keys", "--data-dir", "--version", "--help", "--gpus=N",
                        "--halo-overlap=on|off"})
    EXPECT_NE(r.out.find(o), std::string::npos) << o;
}

TEST(Cli, Version) {
  const CliResult r = run_cli({"--version"});
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.out.rfind(std::string("fbar ") + FBAR_VERSION, 0), 0u) << r.out;
}

TEST(Cli, BadOptionsExitOne) {
  CliResult r = run_cli({"--frame=3"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("fbar: error: unknown option '--frame'; did you mean '--frames'?"), std::string::npos) << r.err;
  r = run_cli({"--frames=0", "x.json"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--frames: got '0'; expected an integer >= 1"), std::string::npos) << r.err;
  r = run_cli({"--backend=tpu"});
  EXPECT_EQ(r.code, 1);
  r = run_cli({"a.json", "b.json"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("more than one scene file"), std::string::npos) << r.err;
  r = run_cli({"--check=yes"});
  EXPECT_EQ(r.code, 1);
  r = run_cli({"--gpus=0", "x.json"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--gpus: got '0'; expected an integer from 1 to 1024"), std::string::npos) << r.err;
  r = run_cli({"--halo-overlap=yes", "x.json"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--halo-overlap: got 'yes'; expected on or off"), std::string::npos) << r.err;
}

// GPU ranks need the GPU engine: with the CPU engine (--backend=cpu, or a build without the GPU engine) --gpus=2 is
// refused before anything runs, with the reason.
TEST(Cli, GpuRanksNeedTheGpuEngine) {
  const CliResult r = run_cli({"--backend=cpu", "--gpus=2", "--quiet", "--file",
                               (kScenes / "good" / "tiny_fluid.json").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--gpus=2: the scene runs on the CPU reference engine"), std::string::npos) << r.err;
}

TEST(Cli, GpuBackendIsNotInThisBuild) {
  const CliResult r = run_cli({"--backend=gpu", "--file", (kScenes / "good" / "tiny_fluid.json").string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("fbar: error: --backend=gpu: the GPU engine is not available in this build"), std::string::npos)
      << r.err;
}

TEST(Cli, DefaultSceneIsSceneJsonInTheWorkingDirectory) {
  const fs::path dir = scratch("default_scene");
  const fs::path old = fs::current_path();
  fs::current_path(dir);
  const CliResult missing = run_cli({"--check"});
  fs::copy_file(kScenes / "good" / "tiny_fluid.json", dir / "scene.json");
  const CliResult present = run_cli({"--check"});
  fs::current_path(old);
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.err.find("fbar: error: --file: got \"scene.json\"; expected an existing scene file"),
            std::string::npos)
      << missing.err;
  EXPECT_EQ(present.code, 0) << present.err;
}

TEST(Cli, AllowUnknownKeysTurnsTheErrorIntoAWarning) {
  const fs::path dir = scratch("unknown_keys");
  std::ifstream in(kScenes / "good" / "tiny_fluid.json");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  text.replace(text.find("\"simulation\": {"), 15, "\"simulation\": {\"colour\": \"blue\", ");
  write_text(dir / "scene.json", text);
  const CliResult strict = run_cli({"--check", (dir / "scene.json").string()});
  EXPECT_EQ(strict.code, 1);
  EXPECT_NE(strict.err.find("simulation.colour: got unknown key \"colour\""), std::string::npos) << strict.err;
  const CliResult lenient = run_cli({"--check", "--allow-unknown-keys", (dir / "scene.json").string()});
  EXPECT_EQ(lenient.code, 0) << lenient.err;
  EXPECT_NE(lenient.err.find("fbar: warning: simulation.colour: ignored"), std::string::npos) << lenient.err;
}

// One frame of a 64-particle water box on the CPU reference engine: exit 0, frames and run.json in --output,
// and run.json's "scene" reads back to the scene that ran.
TEST(Cli, RunWritesRunJsonWithTheResolvedScene) {
  const fs::path out = scratch("run") / "frames";  // created by fbar
  const fs::path scene_file = kScenes / "good" / "tiny_fluid.json";
  const auto t0 = std::chrono::steady_clock::now();
  const CliResult r = run_cli({"--backend=auto", "--quiet", "--frames=1", "--output=" + out.string(),
                               "--file=" + scene_file.string()});
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("fbar: warning: no GPU engine in this build; running on the CPU reference engine"),
            std::string::npos)
      << r.err;
  ASSERT_TRUE(fs::is_regular_file(out / "run.json"));

  std::ifstream in(out / "run.json");
  std::stringstream ss;
  ss << in.rdbuf();
  rapidjson::Document doc;
  doc.Parse<rapidjson::kParseNanAndInfFlag | rapidjson::kParseFullPrecisionFlag>(ss.str().c_str());
  ASSERT_FALSE(doc.HasParseError()) << ss.str();
  EXPECT_STREQ(doc["fbar_version"].GetString(), FBAR_VERSION);
  EXPECT_STREQ(doc["backend"].GetString(), "cpu");
  EXPECT_STREQ(doc["precision"].GetString(), "single");
  EXPECT_EQ(doc["exit_code"].GetInt(), 0);
  EXPECT_STREQ(doc["status"].GetString(), "completed");
  EXPECT_EQ(doc["frames_written"].GetInt(), 1);
  EXPECT_GT(doc["steps"].GetInt64(), 0);
  // The run's wall time: positive (the run took steps) and within the time cli_main took, measured around it here.
  EXPECT_GT(doc["wall_time_s"].GetDouble(), 0.0);
  EXPECT_LE(doc["wall_time_s"].GetDouble(), elapsed_s);
  ASSERT_TRUE(doc.HasMember("scene"));

  rapidjson::StringBuffer sb;
  rapidjson::Writer<rapidjson::StringBuffer> w(sb);
  doc["scene"].Accept(w);
  const Scene ran = parse_scene_string(sb.GetString(), ParseOptions{});
  Scene expected = parse_scene_file(scene_file.string(), ParseOptions{});
  expected.simulation.frames = 1;
  expected.simulation.save_path = out.string();
  EXPECT_TRUE(ran == expected) << sb.GetString();
}

// A scene of one FEM mesh and no particle body runs on the CPU reference engine: the mesh's frames (its 648
// vertices), its tracker and sensor files, and run.json completed.
TEST(Cli, MeshOnlySceneRuns) {
  const fs::path out = scratch("mesh_only") / "out";
  const CliResult r = run_cli({"--backend=cpu", "--quiet", "--output=" + out.string(),
                               (kScenes / "good" / "mesh_only_post.json").string()});
  ASSERT_EQ(r.code, 0) << r.err;
  for (int f : {0, 1}) {
    std::ifstream frame(out / ("model[0]_dev[0]_frame[" + std::to_string(f) + "].csv"));
    ASSERT_TRUE(frame) << "frame " << f;
    std::string line;
    int rows = -1;  // the header
    while (std::getline(frame, line)) ++rows;
    EXPECT_EQ(rows, 648) << "frame " << f;
  }
  EXPECT_TRUE(fs::exists(out / "particleTrack_model[0]_dev[0].csv"));
  EXPECT_TRUE(fs::exists(out / "gridTarget[0]_dev[0].csv"));
  std::ifstream in(out / "run.json");
  std::stringstream ss;
  ss << in.rdbuf();
  rapidjson::Document doc;
  doc.Parse<rapidjson::kParseNanAndInfFlag>(ss.str().c_str());
  ASSERT_FALSE(doc.HasParseError()) << ss.str();
  EXPECT_STREQ(doc["status"].GetString(), "completed");
  EXPECT_EQ(doc["frames_written"].GetInt(), 1);
}

// SIGTERM (a batch system's time limit, `kill`, `timeout`) stops the run at the next step with a checkpoint: run.json
// says "interrupted" with the signal, the step, the last frame written and the checkpoint, and the exit code is
// 128 + 15 as a shell reports a killed process. A SIGTERM repeated at once does not end the process. --restart from
// the checkpoint continues to the frames asked for.
TEST(Cli, SigtermStopsTheRunAndWritesRunJson) {
  const fs::path dir = scratch("sigterm");
  const fs::path out = dir / "frames";
  std::string scene;
  {
    std::ifstream in(kScenes / "good" / "tiny_fluid.json");
    std::stringstream ss;
    ss << in.rdbuf();
    scene = ss.str();
  }
  // 1000 frames of 1 s (about 1000 steps each): far longer than the test waits.
  auto set = [&](const std::string& from, const std::string& to) {
    const std::size_t at = scene.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    scene.replace(at, from.size(), to);
  };
  set("\"fps\": 100", "\"fps\": 1");
  set("\"frames\": 2", "\"frames\": 1000");
  write_text(dir / "long.json", scene);
  CliResult r;
  std::thread run([&] {
    r = run_cli({"--backend=cpu", "--quiet", "--output=" + out.string(), "--file=" + (dir / "long.json").string()});
  });
  // Wait for frame 1 (the run loop, and so the handler, is running), then send the signal.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(out / "model[0]_dev[0]_frame[1].csv") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const bool started = fs::exists(out / "model[0]_dev[0]_frame[1].csv");
  if (started) {  // only while the run (and its handler) is known to be there
    // Twice, as coreutils `timeout` does (the process, then its group): the second must not end the process.
    std::raise(SIGTERM);
    std::raise(SIGTERM);
  }
  run.join();
  ASSERT_TRUE(started) << "frame 1 never appeared: " << r.err;
  EXPECT_EQ(r.code, 128 + SIGTERM) << r.err;
  EXPECT_NE(r.err.find("stopped by SIGTERM at step"), std::string::npos) << r.err;
  ASSERT_TRUE(fs::is_regular_file(out / "run.json"));
  std::ifstream in(out / "run.json");
  std::stringstream ss;
  ss << in.rdbuf();
  rapidjson::Document doc;
  doc.Parse<rapidjson::kParseNanAndInfFlag | rapidjson::kParseFullPrecisionFlag>(ss.str().c_str());
  ASSERT_FALSE(doc.HasParseError()) << ss.str();
  EXPECT_STREQ(doc["status"].GetString(), "interrupted");
  EXPECT_STREQ(doc["signal"].GetString(), "SIGTERM");
  EXPECT_EQ(doc["exit_code"].GetInt(), 128 + SIGTERM);
  const int written = doc["frames_written"].GetInt();
  EXPECT_GE(written, 1);
  EXPECT_LT(written, 1000);
  EXPECT_TRUE(fs::exists(out / ("model[0]_dev[0]_frame[" + std::to_string(written) + "].csv")));
  EXPECT_FALSE(fs::exists(out / ("model[0]_dev[0]_frame[" + std::to_string(written + 1) + "].csv")));
  EXPECT_GT(doc["steps"].GetInt64(), 0);
  ASSERT_TRUE(doc.HasMember("checkpoint")) << ss.str();
  const std::string checkpoint = doc["checkpoint"].GetString();
  EXPECT_EQ(checkpoint, (out / ("checkpoint_step[" + std::to_string(doc["steps"].GetInt64()) + "]_dev[0].h5")).string());
  EXPECT_TRUE(fs::is_regular_file(checkpoint));
  EXPECT_NE(r.err.find("--restart=" + checkpoint), std::string::npos) << r.err;
  // The handler is gone after the run: the default action is back.
  struct sigaction now {};
  sigaction(SIGTERM, nullptr, &now);
  EXPECT_EQ(now.sa_handler, SIG_DFL);
  // Continue for two more frames from the checkpoint.
  const CliResult more =
      run_cli({"--backend=cpu", "--quiet", "--output=" + out.string(), "--frames=" + std::to_string(written + 2),
               "--restart=" + checkpoint, "--file=" + (dir / "long.json").string()});
  ASSERT_EQ(more.code, 0) << more.err;
  EXPECT_TRUE(fs::exists(out / ("model[0]_dev[0]_frame[" + std::to_string(written + 2) + "].csv")));
  std::ifstream again(out / "run.json");
  std::stringstream text;
  text << again.rdbuf();
  EXPECT_NE(text.str().find("\"restarted_from_frame\": " + std::to_string(written)), std::string::npos) << text.str();
  // A checkpoint that is not there: exit 1, named; a run refused before it starts writes no run.json.
  const fs::path refused = dir / "refused";
  const CliResult missing = run_cli({"--backend=cpu", "--restart=" + (dir / "nope.h5").string(),
                                     "--output=" + refused.string(), "--file=" + (dir / "long.json").string()});
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.err.find("nope.h5: no such file"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(refused / "run.json")) << "a refused run wrote run.json";
}

/// Runs `body` in a child process; returns its wait status.
int in_child(void (*body)()) {
  const pid_t pid = fork();
  if (pid == 0) {
    body();
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

// A second signal ends the process at once, by that signal; a SIGTERM repeated within 2 s is the same request.
TEST(StopSignals, ASecondSignalEndsTheProcessAtOnce) {
  int status = in_child([] {
    const StopSignals handlers;
    std::raise(SIGINT);
    if (stop_signal() != SIGINT) _exit(3);  // recorded, not ended
    std::raise(SIGINT);
    _exit(4);  // not reached
  });
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << status;
  status = in_child([] {
    const StopSignals handlers;
    std::raise(SIGTERM);
    std::raise(SIGTERM);  // a sender's repeat: still the first request
    if (stop_signal() != SIGTERM) _exit(3);
  });
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  status = in_child([] {
    const StopSignals handlers;
    std::raise(SIGTERM);
    std::this_thread::sleep_for(std::chrono::milliseconds(2100));
    std::raise(SIGTERM);
    _exit(4);
  });
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status;
  status = in_child([] {
    const StopSignals handlers;
    std::raise(SIGTERM);
    std::raise(SIGINT);  // Ctrl-C after a SIGTERM
    _exit(4);
  });
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << status;
}

}  // namespace
}  // namespace fbar
