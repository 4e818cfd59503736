// The command line with the GPU engine linked (as the fbar executable has it): backend choice, messages, run.json.
#include <gtest/gtest.h>
#include <rapidjson/document.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

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

}  // namespace
}  // namespace fbar
