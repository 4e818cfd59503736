// Every runnable scene (scenes/*.json and the default scene) on the GPU engine against the CPU reference engine.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cpu_engine.h"
#include "gpu_engine.h"
#include "gpu_test_support.h"
#include "scene_parse.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> runnable_scenes() {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(fs::path(FBAR_SOURCE_DIR) / "scenes"))
    if (e.path().extension() == ".json") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  files.push_back(fs::path(FBAR_SOURCE_DIR) / "Projects" / "FBAR" / "scene.json");
  return files;
}

// 30 steps of each scene with the CPU engine's CFL time step, given to both engines. The engines run the same
// physics functions; what differs is the summation order of P2G (and the GPU's fixed-point arena, whose rounding is
// float-sized): after 60 steps of the small test scenes positions agree to ~2e-7 m and velocities to ~6e-6 m/s
// (test_gpu_vs_cpu.cu). Same tolerances here as there: 5e-6 m and 1e-4 m/s in single precision, 1e-12 in double.
template <typename T>
void run_scene_on_both(const Scene& scene, const std::string& name) {
  const auto positions = test::sample_scene(scene);
  CpuEngine<T> cpu(scene, positions);
  GpuEngine<T> gpu(scene, positions);
  gpu.set_record_velocities(true);
  for (int s = 0; s < 30; ++s) {
    const double dt = cpu.next_dt();
    const StepReport rc = cpu.step(dt);
    const StepReport rg = gpu.step(dt);
    ASSERT_TRUE(rc.ok) << name << ": " << rc.message();
    ASSERT_TRUE(rg.ok) << name << ": " << rg.message();
  }
  const bool single = std::is_same_v<T, float>;
  double ex = 0.0, ev = 0.0;
  for (int b = 0; b < gpu.body_count(); ++b) {
    const ParticleSnapshot<T> g = gpu.snapshot(b);
    ex = std::max(ex, test::max_diff(g.x, cpu.positions(b)));
    ev = std::max(ev, test::max_diff(g.v, cpu.velocities(b)));
  }
  std::cout << "[measured] scene " << name << ": " << cpu.particle_count() << " particles, 30 steps to t = "
            << cpu.time() << " s: |dx| " << ex << " m, |dv| " << ev << " m/s\n";
  EXPECT_EQ(gpu.particle_count(), cpu.particle_count());
  EXPECT_LE(ex, single ? 5e-6 : 1e-12) << name;
  EXPECT_LE(ev, single ? 1e-4 : 1e-12) << name;
}

TEST(GpuScenes, EveryRunnableSceneMatchesCpu) {
  FBAR_REQUIRE_DEVICE();
  for (const fs::path& file : runnable_scenes()) {
    const Scene scene = parse_scene_file(file.string(), ParseOptions{});
    const std::string name = file.filename().string();
    if (scene.simulation.precision == Precision::Double) run_scene_on_both<double>(scene, name);
    else run_scene_on_both<float>(scene, name);
  }
}

}  // namespace
}  // namespace fbar
