// fbar --sweep on the CPU reference engine, in-process: every case checked before any runs, cases in their folders
// with run.json, a failing case reported while the others run, the gathered tables against the cases' own files,
// completed cases skipped and stopped ones resumed from their checkpoints, a folder of another sweep refused.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli_test_support.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;
using test::CliResult;
using test::run_cli;

fs::path scratch(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("fbar_test_sweep_" + std::to_string(::getpid())) / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

struct RemoveScratch : ::testing::Environment {
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(fs::temp_directory_path() / ("fbar_test_sweep_" + std::to_string(::getpid())), ec);
  }
};
[[maybe_unused]] const auto* const kRemoveScratch = ::testing::AddGlobalTestEnvironment(new RemoveScratch);

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) out.push_back(line);
  return out;
}

/// A 64-particle water cube in walls with a floor load cell and a particle gauge: a case takes well under a second.
/// `frames` frames of 1 / fps.
std::string base_scene(int frames, int fps) {
  return R"({
  "simulation": {"domain": [0.4, 0.4, 0.4], "default_dx": 0.05, "default_dt": 1e-3, "fps": )" +
         std::to_string(fps) + R"(, "frames": )" + std::to_string(frames) + R"(,
                 "save_path": "./unused", "save_suffix": ".csv", "checkpoint_every": 1},
  "bodies": [{"material": {"constitutive": "JFluid", "ppc": 8, "CFL": 0.5, "rho": 1000, "bulk_modulus": 2e5,
                           "gamma": 7.1, "viscosity": 0.001},
              "algorithm": {"use_ASFLIP": false, "use_FBAR": false},
              "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.15, 0.1, 0.15]}],
              "output_attribs": ["ID", "Pressure"]}],
  "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.05, 0.05, 0.05],
                  "domain_end": [0.35, 0.35, 0.35]}],
  "grid-sensors": [{"attribute": "Force", "operation": "Sum", "direction": "Y-", "output_frequency": 500,
                    "domain_start": [0.0, 0.0, 0.0], "domain_end": [0.4, 0.08, 0.4]}],
  "particle-sensors": [{"attribute": "Elevation", "operation": "Max", "output_frequency": 500,
                        "domain_start": [0.0, 0.0, 0.0], "domain_end": [0.4, 0.4, 0.4]}]
})";
}

/// Three cases: two densities at rest in the walls, and a cube thrown down at 60 m/s with the walls taken away,
/// which leaves the domain in its first frame (a run-time failure).
const char* kCases = R"("design": "cases", "parameters": [
    {"name": "rho", "path": "bodies[0].material.rho"},
    {"name": "throw", "path": "bodies[0].velocity", "values": [[0, 0, 0], [0, -60, 0]], "labels": ["rest", "down"]},
    {"name": "walls", "path": "boundaries", "labels": ["walls", "open"],
     "values": [[{"object": "Walls", "contact": "Separable", "domain_start": [0.05, 0.05, 0.05],
                  "domain_end": [0.35, 0.35, 0.35]}], []]}],
  "cases": [{"rho": 1000, "throw": [0, 0, 0], "walls": [{"object": "Walls", "contact": "Separable",
                                                         "domain_start": [0.05, 0.05, 0.05],
                                                         "domain_end": [0.35, 0.35, 0.35]}]},
            {"rho": 1200, "throw": [0, 0, 0], "walls": [{"object": "Walls", "contact": "Separable",
                                                         "domain_start": [0.05, 0.05, 0.05],
                                                         "domain_end": [0.35, 0.35, 0.35]}]},
            {"rho": 1000, "throw": [0, -60, 0], "walls": []}])";

/// A sweep file beside its base scene; returns the sweep file.
fs::path write_sweep(const fs::path& dir, const std::string& design, int frames = 2, int fps = 100) {
  write_text(dir / "base.json", base_scene(frames, fps));
  const fs::path file = dir / "test.sweep.json";
  write_text(file, "{\"scene\": \"base.json\", \"output\": \"out\", " + design + "}");
  return file;
}

std::string status_of(const fs::path& case_dir) {
  const std::string text = read_text(case_dir / "run.json");
  const std::size_t at = text.find("\"status\": \"");
  if (at == std::string::npos) return "none";
  const std::size_t from = at + 11;
  return text.substr(from, text.find('"', from) - from);
}

// --check: every case checked and listed with its particles and time; nothing is written.
TEST(SweepCli, CheckListsEveryCase) {
  const fs::path dir = scratch("check");
  const fs::path file = write_sweep(dir, kCases);
  const CliResult r = run_cli({"--sweep=" + file.string(), "--check"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("is valid: 3 cases"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("rho=1200, throw=rest, walls=walls"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("rho=1000, throw=down, walls=open"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("64"), std::string::npos) << r.out;  // each case's particles
  EXPECT_FALSE(fs::exists(dir / "out")) << "--check wrote the sweep's folder";
  // A case the scene refuses stops the sweep before anything runs, naming the case.
  const fs::path bad = write_sweep(scratch("check_bad"), R"("parameters": [{"name": "rho",
      "path": "bodies[0].material.rho", "values": [1000, -1]}])");
  const CliResult refused = run_cli({"--sweep=" + bad.string(), "--backend=cpu"});
  EXPECT_EQ(refused.code, 1);
  EXPECT_NE(refused.err.find("sweep case 1 (rho=-1): bodies[0].material.rho: got -1"), std::string::npos)
      << refused.err;
  EXPECT_FALSE(fs::exists(bad.parent_path() / "out" / "case_0000" / "run.json")) << "a case ran before the check";
  // Options that go with --sweep only.
  EXPECT_EQ(run_cli({"--jobs=2", "--file=" + (dir / "base.json").string()}).code, 1);
  EXPECT_EQ(run_cli({"--sweep=" + file.string(), "--cases=0,x"}).code, 1);
}

// A run: the failing case is reported with its reason and the others complete; the tables hold every sample of the
// completed cases' files, as those files write them; the summary's peak, mean and impulse follow from the samples.
TEST(SweepCli, RunsCasesAndGathersOneTable) {
  const fs::path dir = scratch("run");
  const fs::path file = write_sweep(dir, kCases);
  const CliResult r = run_cli({"--sweep=" + file.string(), "--backend=cpu"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("fbar: sweep: case 2 (rho=1000, throw=down, walls=open) failed: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("left the domain"), std::string::npos) << r.err;
  const fs::path out = dir / "out";
  EXPECT_EQ(status_of(out / "case_0000"), "completed");
  EXPECT_EQ(status_of(out / "case_0001"), "completed");
  EXPECT_EQ(status_of(out / "case_0002"), "failed");
  EXPECT_TRUE(fs::is_regular_file(out / "case_0001" / "scene.json"));
  EXPECT_NE(read_text(out / "case_0001" / "scene.json").find("\"rho\": 1200"), std::string::npos);
  EXPECT_TRUE(fs::is_regular_file(out / "case_0001" / "model[0]_dev[0]_frame[2].csv"));

  // sweep_cases.csv: one line per case with its status.
  const auto cases = lines_of(read_text(out / "sweep_cases.csv"));
  ASSERT_EQ(cases.size(), 4u);
  EXPECT_EQ(cases[0].rfind("case,rho,throw,walls,status,", 0), 0u) << cases[0];
  EXPECT_EQ(cases[2].rfind("1,1200,rest,walls,completed,", 0), 0u) << cases[2];
  EXPECT_EQ(cases[3].rfind("2,1000,down,open,failed,", 0), 0u) << cases[3];

  // sweep_table.csv against the cases' own sensor files, row for row.
  const auto table = lines_of(read_text(out / "sweep_table.csv"));
  ASSERT_FALSE(table.empty());
  EXPECT_EQ(table[0], "case,rho,throw,walls,sensor,quantity,time [s],value");
  std::size_t row = 1;
  for (int c : {0, 1}) {
    const std::string params = c == 0 ? "0,1000,rest,walls" : "1,1200,rest,walls";
    for (const std::string sensor : {"gridTarget[0]_dev[0]", "particleTarget[0]_model[0]_dev[0]"}) {
      const auto own = lines_of(read_text(out / ("case_000" + std::to_string(c)) / (sensor + ".csv")));
      ASSERT_GT(own.size(), 5u) << sensor;  // 0.02 s at 500 Hz: 10 samples
      const std::string quantity = own[0].substr(own[0].find(',') + 1);
      for (std::size_t k = 1; k < own.size(); ++k, ++row) {
        ASSERT_LT(row, table.size());
        EXPECT_EQ(table[row], params + "," + sensor + "," + quantity + "," + own[k]) << "row " << row;
      }
    }
  }
  EXPECT_EQ(row, table.size()) << "the table has rows no case file has";

  // sweep_summary.csv: peak (largest magnitude), mean and trapezoidal impulse of case 1's load cell.
  const auto own = lines_of(read_text(out / "case_0001" / "gridTarget[0]_dev[0].csv"));
  double peak = 0.0, sum = 0.0, impulse = 0.0, t_prev = 0.0, v_prev = 0.0;
  for (std::size_t k = 1; k < own.size(); ++k) {
    const double t = std::stod(own[k].substr(0, own[k].find(','))), v = std::stod(own[k].substr(own[k].find(',') + 1));
    if (std::fabs(v) > std::fabs(peak)) peak = v;
    sum += v;
    if (k > 1) impulse += 0.5 * (v + v_prev) * (t - t_prev);
    t_prev = t;
    v_prev = v;
  }
  bool found = false;
  for (const std::string& line : lines_of(read_text(out / "sweep_summary.csv"))) {
    if (line.rfind("1,1200,rest,walls,gridTarget[0]_dev[0],", 0) != 0) continue;
    found = true;
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    ASSERT_EQ(f.size(), 11u) << line;
    EXPECT_EQ(std::stoll(f[6]), static_cast<long long>(own.size() - 1));
    EXPECT_NEAR(std::stod(f[7]), peak, 1e-8 * std::fabs(peak) + 1e-12) << line;
    EXPECT_NEAR(std::stod(f[9]), sum / static_cast<double>(own.size() - 1), 1e-8 * std::fabs(peak) + 1e-12) << line;
    EXPECT_NEAR(std::stod(f[10]), impulse, 1e-8 * std::fabs(impulse) + 1e-12) << line;
    EXPECT_GT(peak, 0.0) << "the floor carries the water: a load cell reading nothing tests nothing";
  }
  EXPECT_TRUE(found);

  // sweep_table.h5: the table's values as numbers.
  const hid_t h5 = H5Fopen((out / "sweep_table.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(h5, 0);
  const hid_t values = H5Dopen2(h5, "/table/value", H5P_DEFAULT);
  ASSERT_GE(values, 0);
  const hid_t space = H5Dget_space(values);
  EXPECT_EQ(H5Sget_simple_extent_npoints(space), static_cast<hssize_t>(table.size() - 1));
  H5Sclose(space);
  H5Dclose(values);
  H5Fclose(h5);

  // Again: the completed cases are not run again (their run.json unchanged), the failed one is reported, not rerun.
  const std::string before = read_text(out / "case_0000" / "run.json");
  const std::string failed_before = read_text(out / "case_0002" / "run.json");
  const CliResult again = run_cli({"--sweep=" + file.string(), "--backend=cpu"});
  EXPECT_EQ(again.code, 2);
  EXPECT_NE(again.out.find("0 cases to run, 2 completed before, 1 failed before"), std::string::npos) << again.out;
  EXPECT_NE(again.err.find("case 2 (rho=1000, throw=down, walls=open) failed before"), std::string::npos) << again.err;
  EXPECT_EQ(read_text(out / "case_0000" / "run.json"), before);
  EXPECT_EQ(read_text(out / "case_0002" / "run.json"), failed_before);
  // --retry-failed runs it again (and it fails again).
  const CliResult retry = run_cli({"--sweep=" + file.string(), "--backend=cpu", "--retry-failed", "--cases=2"});
  EXPECT_EQ(retry.code, 2);
  EXPECT_NE(retry.out.find("1 cases to run"), std::string::npos) << retry.out;
  EXPECT_NE(read_text(out / "case_0002" / "run.json"), failed_before);

  // Another sweep into the same folder is refused: its cases would mix with these.
  write_text(file, "{\"scene\": \"base.json\", \"output\": \"out\", \"parameters\": [{\"name\": \"rho\", "
                   "\"path\": \"bodies[0].material.rho\", \"values\": [800]}]}");
  const CliResult other = run_cli({"--sweep=" + file.string(), "--backend=cpu"});
  EXPECT_EQ(other.code, 1);
  EXPECT_NE(other.err.find("holds another sweep"), std::string::npos) << other.err;
}

// SIGTERM stops the running case at its next step with a checkpoint (run.json "interrupted"); the same command
// resumes it from the checkpoint (here found as after a hard kill: the newest in the case's folder) and skips the
// cases done. The resumed sweep's table equals, byte for byte, that of
// the same sweep run without a stop (a restart continues a run exactly).
TEST(SweepCli, StoppedSweepResumesFromCheckpoints) {
  const std::string design = R"("parameters": [{"name": "rho", "path": "bodies[0].material.rho",
                                                "values": [1000, 1100]}])";
  const fs::path whole_dir = scratch("whole");
  const fs::path whole = write_sweep(whole_dir, design, 8, 10);
  ASSERT_EQ(run_cli({"--sweep=" + whole.string(), "--backend=cpu", "--quiet"}).code, 0);

  const fs::path dir = scratch("stopped");
  const fs::path file = write_sweep(dir, design, 8, 10);
  const fs::path first_frame = dir / "out" / "case_0000" / "model[0]_dev[0]_frame[2].csv";
  CliResult r;
  std::thread run([&] { r = run_cli({"--sweep=" + file.string(), "--backend=cpu", "--quiet"}); });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(first_frame) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const bool started = fs::exists(first_frame);
  if (started) std::raise(SIGTERM);
  run.join();
  ASSERT_TRUE(started) << r.err;
  ASSERT_EQ(r.code, 128 + SIGTERM) << r.err;
  EXPECT_NE(r.err.find("the same command resumes the sweep"), std::string::npos) << r.err;
  EXPECT_EQ(status_of(dir / "out" / "case_0000"), "interrupted");
  EXPECT_FALSE(fs::exists(dir / "out" / "case_0001" / "run.json")) << "a case started after the stop";
  EXPECT_FALSE(fs::exists(dir / "out" / "sweep_table.csv")) << "a stopped sweep gathered";

  // A process killed outright (SIGKILL, a node lost) leaves run.json as the run's start wrote it: status "running",
  // no checkpoint named. The sweep then continues from the newest checkpoint in the case's folder.
  write_text(dir / "out" / "case_0000" / "run.json", "{\"status\": \"running\"}");
  const CliResult resumed = run_cli({"--sweep=" + file.string(), "--backend=cpu"});
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  EXPECT_NE(read_text(dir / "out" / "case_0000" / "run.json").find("\"restarted_from_frame\""), std::string::npos);
  EXPECT_EQ(read_text(dir / "out" / "sweep_table.csv"), read_text(whole_dir / "out" / "sweep_table.csv"));
  EXPECT_EQ(read_text(dir / "out" / "sweep_summary.csv"), read_text(whole_dir / "out" / "sweep_summary.csv"));
}

// On the CPU engine --jobs=2 runs two cases at once, each with half the cores: every case writes the bytes it
// writes when the cases run one at a time (frames, sensors and the gathered table).
TEST(SweepCli, CpuCasesAtOnceWriteWhatTheyWriteAlone) {
  const fs::path dir = scratch("jobs");
  const fs::path file = write_sweep(dir, R"("parameters": [{"name": "rho", "path": "bodies[0].material.rho",
                                                "values": [1000, 1100, 1200, 1300]}])");
  ASSERT_EQ(run_cli({"--sweep=" + file.string(), "--backend=cpu", "--quiet", "--jobs=1",
                     "--output=" + (dir / "one").string()}).code, 0);
  const CliResult two = run_cli({"--sweep=" + file.string(), "--backend=cpu", "--jobs=2",
                                 "--output=" + (dir / "two").string()});
  ASSERT_EQ(two.code, 0) << two.err;
  EXPECT_NE(two.out.find("4 cases to run; on the CPU engine (2 at once)"), std::string::npos) << two.out;
  int compared = 0;
  for (int c = 0; c < 4; ++c) {
    const std::string folder = "case_000" + std::to_string(c);
    for (const auto& e : fs::directory_iterator(dir / "one" / folder)) {
      const std::string name = e.path().filename().string();
      if (name == "run.json" || name == "log.txt" || name == "scene.json") continue;  // times; the folder's name
      EXPECT_EQ(read_text(dir / "two" / folder / name), read_text(e.path())) << folder << "/" << name;
      ++compared;
    }
  }
  EXPECT_GE(compared, 4 * 4);  // 3 frames and 2 sensor files a case (checkpoints too)
  EXPECT_EQ(read_text(dir / "two" / "sweep_table.csv"), read_text(dir / "one" / "sweep_table.csv"));
}

}  // namespace
}  // namespace fbar
