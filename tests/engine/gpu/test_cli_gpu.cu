// The command line with the GPU engine linked (as the fbar executable has it): backend choice, messages, run.json.
#include <gtest/gtest.h>
#include <rapidjson/document.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "../../cli/cli_test_support.h"
#include "MnSystem/Cuda/device_query.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;

const fs::path kTinyFluid = fs::path(FBAR_SOURCE_DIR) / "tests" / "scenes" / "good" / "tiny_fluid.json";
/// 7,200 water particles over several block planes: two ranks can share it.
const fs::path kDecomposedDamBreak =
    fs::path(FBAR_SOURCE_DIR) / "tests" / "scenes" / "good" / "decomposed_dam_break.json";

EngineSet with_gpu() {
  EngineSet e;
  e.run_gpu = &run_gpu;
  return e;
}

fs::path scratch(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("fbar_test_cli_gpu_" + std::to_string(::getpid())) / name;
  fs::remove_all(p);
  return p;
}

std::string backend_in_run_json(const fs::path& dir) {
  std::ifstream in(dir / "run.json");
  std::stringstream ss;
  ss << in.rdbuf();
  rapidjson::Document doc;
  doc.Parse(ss.str().c_str());
  if (doc.HasParseError() || !doc.HasMember("backend")) return "(unreadable run.json)";
  return doc["backend"].GetString();
}

// Without a device (CI): --backend=gpu is a run-time error that says why; auto falls back to the CPU engine with a
// warning that says why, and run.json records the engine that ran.
TEST(CliGpu, WithoutADeviceGpuFailsAndAutoFallsBackToCpu) {
  if (cuda::device_count() > 0) GTEST_SKIP() << "a CUDA device is present: the fallback cannot be exercised";
  const test::CliResult g = test::run_cli({"--backend=gpu", "--file=" + kTinyFluid.string()}, with_gpu());
  EXPECT_EQ(g.code, 2);
  EXPECT_NE(g.err.find("fbar: error: --backend=gpu: no CUDA device"), std::string::npos) << g.err;
  const fs::path out = scratch("auto_cpu");
  const test::CliResult a = test::run_cli(
      {"--backend=auto", "--quiet", "--frames=1", "--output=" + out.string(), "--file=" + kTinyFluid.string()},
      with_gpu());
  EXPECT_EQ(a.code, 0) << a.err;
  EXPECT_NE(a.err.find("fbar: warning: no CUDA device"), std::string::npos) << a.err;
  EXPECT_NE(a.err.find("running on the CPU reference engine"), std::string::npos) << a.err;
  EXPECT_EQ(backend_in_run_json(out), "cpu");
  fs::remove_all(out.parent_path());
}

// With a device: auto and gpu run the GPU engine (no warning), write the frames and record "gpu" in run.json.
TEST(CliGpu, AutoAndGpuRunTheGpuEngine) {
  FBAR_REQUIRE_DEVICE();
  for (const char* backend : {"--backend=auto", "--backend=gpu"}) {
    const fs::path out = scratch(std::string("run_") + (backend + 10));
    const test::CliResult r = test::run_cli(
        {backend, "--quiet", "--frames=1", "--output=" + out.string(), "--file=" + kTinyFluid.string()}, with_gpu());
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
    EXPECT_EQ(backend_in_run_json(out), "gpu") << backend;
    EXPECT_TRUE(fs::exists(out / "model[0]_dev[0]_frame[1].csv")) << backend;
    fs::remove_all(out.parent_path());
  }
}

// A scene below kMultiGpuMinParticles runs on one GPU when --gpus=N asks for more (one GPU steps it faster: the
// note says so and only rank 0's files appear); --keep-gpus runs the N ranks (rank 1 writes its part of the water).
TEST(CliGpu, SmallSceneRunsOnOneGpuUnlessKept) {
  FBAR_REQUIRE_DEVICE();
  for (const bool keep : {false, true}) {
    const fs::path out = scratch(keep ? "small_kept" : "small");
    std::vector<std::string> args = {"--gpus=2", "--quiet", "--frames=1", "--output=" + out.string(),
                                      "--file=" + kDecomposedDamBreak.string()};
    if (keep) args.push_back("--keep-gpus");
    const test::CliResult r = test::run_cli(args, with_gpu());
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("running on one GPU") != std::string::npos, !keep) << r.err;
    EXPECT_TRUE(fs::exists(out / "model[0]_dev[0]_frame[1].csv"));
    EXPECT_EQ(fs::exists(out / "model[0]_dev[1]_frame[1].csv"), keep) << (keep ? "kept" : "reduced");
    fs::remove_all(out.parent_path());
  }
}

/// Every file under `dir` (relative path -> bytes), run.json (wall-clock times) aside.
std::map<std::string, std::string> output_files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file() || e.path().filename() == "run.json") continue;
    std::ifstream in(e.path(), std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    files[fs::relative(e.path(), dir).string()] = ss.str();
  }
  return files;
}

// Runs that repeat bit for bit (grid_buffer.cuh "Order-free grid sums", physics/sensors.cuh ExactSum): the same
// scene twice, in single and double precision, writes the same bytes: frames, the load cells' and gauges' CSVs, the
// trackers and the checkpoints.
TEST(CliGpu, TwoRunsWriteTheSameBytes) {
  FBAR_REQUIRE_DEVICE();
  const fs::path scene = fs::path(FBAR_SOURCE_DIR) / "tests" / "scenes" / "good" / "decomposed_sensors.json";
  std::string text;
  {
    std::ifstream in(scene);
    std::stringstream ss;
    ss << in.rdbuf();
    text = ss.str();
  }
  for (const std::string precision : {"single", "double"}) {
    SCOPED_TRACE(precision);
    std::string patched = text;
    const std::size_t at = patched.find("\"precision\": \"double\"");
    ASSERT_NE(at, std::string::npos);
    patched.replace(at, std::string("\"precision\": \"double\"").size(), "\"precision\": \"" + precision + "\"");
    const fs::path base = scratch("repeat_" + precision);
    fs::create_directories(base);
    const fs::path file = base / "scene.json";
    std::ofstream(file) << patched;
    std::map<std::string, std::string> runs[2];
    for (int run = 0; run < 2; ++run) {
      const fs::path out = base / ("run" + std::to_string(run));
      const test::CliResult r = test::run_cli(
          {"--backend=gpu", "--quiet", "--output=" + out.string(), "--file=" + file.string()}, with_gpu());
      ASSERT_EQ(r.code, 0) << r.err;
      runs[run] = output_files(out);
    }
    ASSERT_FALSE(runs[0].empty());
    std::size_t sensors = 0, checkpoints = 0;
    for (const auto& [name, bytes] : runs[0]) {
      sensors += name.find("Target") != std::string::npos || name.find("Track") != std::string::npos;
      checkpoints += name.find("checkpoint") != std::string::npos;
      const auto it = runs[1].find(name);
      ASSERT_NE(it, runs[1].end()) << name << " is missing from the second run";
      EXPECT_TRUE(it->second == bytes) << name << " differs between two runs";
    }
    EXPECT_EQ(runs[0].size(), runs[1].size());
    EXPECT_GT(sensors, 0u) << "no sensor files were compared";
    EXPECT_GT(checkpoints, 0u) << "no checkpoint was compared";
  }
  fs::remove_all(scratch("").parent_path());
}


/// The table rows of a gathered sweep (sweep_table.csv) as (row key, value).
std::vector<std::pair<std::string, double>> table_rows(const fs::path& sweep_dir) {
  std::ifstream in(sweep_dir / "sweep_table.csv");
  std::vector<std::pair<std::string, double>> rows;
  std::string line;
  std::getline(in, line);  // the header
  while (std::getline(in, line)) {
    const std::size_t comma = line.rfind(',');
    rows.emplace_back(line.substr(0, comma), std::stod(line.substr(comma + 1)));
  }
  return rows;
}

// A sweep packed on one GPU (three cases at once, each on its thread and streams) writes the bytes the same sweep
// writes one case at a time (the engine's runs repeat bit for bit, whatever else shares the GPU), and its table
// agrees with the CPU engine's: double precision at a fixed step (default_dt below every bound), so the engines'
// sums differ by their order only, 1e-9 of each quantity's range (test_sensors_gpu.cu) plus the CSVs' 9 digits.
TEST(CliGpu, PackedSweepMatchesOneCaseAtATimeAndTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const fs::path dir = scratch("sweep");
  fs::create_directories(dir);
  std::ofstream(dir / "base.json") << R"({
    "simulation": {"domain": [0.4, 0.4, 0.4], "default_dx": 0.05, "default_dt": 1e-4, "fps": 100, "frames": 2,
                   "precision": "double", "save_suffix": ".csv"},
    "bodies": [{"material": {"constitutive": "JFluid", "rho": 1000, "bulk_modulus": 2e5, "viscosity": 0.001},
                "algorithm": {"use_ASFLIP": false, "use_FBAR": false},
                "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.15, 0.1, 0.15]}],
                "output_attribs": ["ID", "Pressure"]}],
    "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.05, 0.05, 0.05],
                    "domain_end": [0.35, 0.35, 0.35]}],
    "grid-sensors": [{"attribute": "Force", "operation": "Sum", "direction": "Y-", "output_frequency": 500,
                      "domain_start": [0, 0, 0], "domain_end": [0.4, 0.08, 0.4]}],
    "particle-sensors": [{"attribute": "Elevation", "operation": "Max", "output_frequency": 500,
                          "domain_start": [0, 0, 0], "domain_end": [0.4, 0.4, 0.4]}]})";
  std::ofstream(dir / "s.sweep.json") << R"({"scene": "base.json", "output": "packed", "parameters": [
      {"name": "rho", "path": "bodies[0].material.rho", "values": [1000, 1100, 1200]},
      {"name": "x", "path": "bodies[0].geometry[0].offset[0]", "values": [0.12, 0.18]}]})";
  const std::string sweep = "--sweep=" + (dir / "s.sweep.json").string();
  const test::CliResult packed = test::run_cli({sweep, "--backend=gpu", "--jobs=3"}, with_gpu());
  ASSERT_EQ(packed.code, 0) << packed.err;
  EXPECT_NE(packed.out.find("6 cases to run; on GPU 0 (3 at once)"), std::string::npos) << packed.out;
  const test::CliResult alone =
      test::run_cli({sweep, "--backend=gpu", "--jobs=1", "--quiet", "--output=" + (dir / "alone").string()}, with_gpu());
  ASSERT_EQ(alone.code, 0) << alone.err;
  const test::CliResult cpu =
      test::run_cli({sweep, "--backend=cpu", "--quiet", "--output=" + (dir / "cpu").string()}, with_gpu());
  ASSERT_EQ(cpu.code, 0) << cpu.err;
  for (int c = 0; c < 6; ++c) {
    const std::string folder = "case_000" + std::to_string(c);
    const auto a = output_files(dir / "packed" / folder), b = output_files(dir / "alone" / folder);
    ASSERT_GT(a.size(), 4u) << folder;
    for (const auto& [name, bytes] : a) {
      if (name == "log.txt" || name == "scene.json") continue;  // times; the case's save_path
      const auto it = b.find(name);
      ASSERT_NE(it, b.end()) << folder << "/" << name;
      EXPECT_TRUE(it->second == bytes) << folder << "/" << name << " differs between packed and one at a time";
    }
  }
  const auto g = table_rows(dir / "packed"), c = table_rows(dir / "cpu");
  ASSERT_EQ(g.size(), c.size());
  ASSERT_GT(g.size(), 100u);
  std::map<std::string, double> range;  // per sensor and quantity: the largest magnitude
  for (const auto& [key, v] : c) {
    const std::string series = key.substr(key.find(',', key.find(',', key.find(',') + 1) + 1) + 1);
    double& r = range[series.substr(0, series.rfind(','))];
    r = std::max(r, std::fabs(v));
  }
  for (std::size_t i = 0; i < g.size(); ++i) {
    ASSERT_EQ(g[i].first, c[i].first) << "row " << i;
    const std::string series = g[i].first.substr(g[i].first.find(',', g[i].first.find(',', g[i].first.find(',') + 1) + 1) + 1);
    const double scale = range[series.substr(0, series.rfind(','))];
    EXPECT_NEAR(g[i].second, c[i].second, 1e-8 * scale + 1e-12) << g[i].first;
  }
  fs::remove_all(dir.parent_path());
}

// Eight spreading dam breaks at once on one GPU, each growing its grid (hash table, blocks, partition) while the
// others step: each case writes the bytes it writes alone. (Growth once cleared a grown table's arena on the legacy
// stream, unordered with the engine's streams: alone the clear always came first, with other runs on the device it
// could land after the copy of the old entries, and a case failed with "arena lookups outside their block".)
TEST(CliGpu, PackedSpreadingCasesGrowAsTheyDoAlone) {
  FBAR_REQUIRE_DEVICE();
  const fs::path dir = scratch("sweep_growth");
  fs::create_directories(dir);
  std::ofstream(dir / "tank.json") << R"({
    "simulation": {"domain": [1.32, 0.52, 0.36], "default_dx": 0.02, "fps": 4, "frames": 1, "save_suffix": ".bgeo"},
    "bodies": [{"material": {"constitutive": "JFluid", "rho": 1000, "bulk_modulus": 2e6, "viscosity": 0.001},
                "algorithm": {"use_ASFLIP": false, "use_FBAR": false},
                "geometry": [{"object": "Box", "span": [0.56, 0.28, 0.2], "offset": [0.04, 0.04, 0.06]}],
                "output_attribs": ["ID", "Velocity_X"]}],
    "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.02, 0.02, 0.02],
                    "domain_end": [1.30, 0.50, 0.34]}],
    "grid-sensors": [{"attribute": "Force", "operation": "Sum", "direction": "X+", "output_frequency": 200,
                      "domain_start": [1.26, 0, 0], "domain_end": [1.32, 0.52, 0.36]}]})";
  std::ofstream(dir / "g.sweep.json") << R"({"scene": "tank.json", "output": "packed", "parameters": [
      {"name": "x", "path": "bodies[0].geometry[0].offset[0]", "values": [0.04, 0.08, 0.12, 0.16]},
      {"name": "rho", "path": "bodies[0].material.rho", "values": [1000, 1100]}]})";
  const std::string sweep = "--sweep=" + (dir / "g.sweep.json").string();
  const test::CliResult packed = test::run_cli({sweep, "--backend=gpu", "--jobs=8", "--quiet"}, with_gpu());
  ASSERT_EQ(packed.code, 0) << packed.err;
  const test::CliResult alone =
      test::run_cli({sweep, "--backend=gpu", "--jobs=1", "--quiet", "--output=" + (dir / "alone").string()}, with_gpu());
  ASSERT_EQ(alone.code, 0) << alone.err;
  for (int c = 0; c < 8; ++c) {
    const std::string folder = "case_000" + std::to_string(c);
    const auto a = output_files(dir / "packed" / folder), b = output_files(dir / "alone" / folder);
    ASSERT_GT(a.size(), 3u) << folder;
    for (const auto& [name, bytes] : a) {
      if (name == "log.txt" || name == "scene.json") continue;
      const auto it = b.find(name);
      ASSERT_NE(it, b.end()) << folder << "/" << name;
      EXPECT_TRUE(it->second == bytes) << folder << "/" << name << " differs between packed and one at a time";
    }
  }
  fs::remove_all(dir.parent_path());
}

}  // namespace
}  // namespace fbar
