// Failure reports of the GPU engine: each kind forced, reported with body, step, time, count and first particle
// exactly as the CPU reference engine reports it (the same checks on the same state), and reduce_dt repeats.
#include <gtest/gtest.h>

#include <filesystem>
#include <limits>
#include <sstream>

#include "engine/cpu/cpu_engine.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"

namespace fbar {
namespace {

/// Steps both engines with dt until one fails (at most max_steps); returns both last reports.
template <typename T>
std::pair<StepReport, StepReport> run_until_failure(const Scene& scene, double dt, int max_steps) {
  const auto positions = test::sample_scene(scene);
  CpuEngine<T> cpu(scene, positions);
  GpuEngine<T> gpu(scene, positions);
  std::ostringstream sink;
  cpu.set_log(&sink);
  gpu.set_log(&sink);
  StepReport rc, rg;
  for (int s = 0; s < max_steps && rc.ok && rg.ok; ++s) {
    rc = cpu.step(dt);
    rg = gpu.step(dt);
  }
  return {rc, rg};
}

void expect_same_failure(const StepReport& rc, const StepReport& rg, FailureKind kind, double count_tolerance) {
  ASSERT_FALSE(rc.ok) << "the CPU engine did not fail: the scene does not force the failure";
  ASSERT_FALSE(rg.ok) << "the GPU engine did not report the failure";
  const FailureReport* fc = nullptr;
  const FailureReport* fg = nullptr;
  for (const auto& f : rc.failures)
    if (f.kind == kind) fc = &f;
  for (const auto& f : rg.failures)
    if (f.kind == kind) fg = &f;
  ASSERT_NE(fc, nullptr);
  ASSERT_NE(fg, nullptr) << "GPU report: " << rg.message();
  std::cout << "[measured] CPU: " << fc->describe() << "\n[measured] GPU: " << fg->describe() << "\n";
  EXPECT_EQ(fg->body, fc->body);
  EXPECT_EQ(fg->step, fc->step);
  EXPECT_DOUBLE_EQ(fg->time, fc->time);
  EXPECT_DOUBLE_EQ(fg->dt, fc->dt);
  EXPECT_NEAR(static_cast<double>(fg->count), static_cast<double>(fc->count), count_tolerance * fc->count);
  EXPECT_GT(fg->count, 0);
  EXPECT_FALSE(fg->describe().empty());
}

// NaN: an infinite bulk modulus makes the pressure at rest (K/gamma) expm1(0) = inf * 0 = NaN in every particle's
// first stress, so the first step's velocities are NaN everywhere: every particle, in both engines.
template <typename T>
void nan_test() {
  Scene scene = test::small_scene(Constitutive::JFluid, std::is_same_v<T, double> ? Precision::Double : Precision::Single);
  scene.bodies[0].material.bulk_modulus = std::numeric_limits<double>::infinity();
  const auto [rc, rg] = run_until_failure<T>(scene, 1e-4, 3);
  expect_same_failure(rc, rg, FailureKind::NonFinite, 0.0);
}
TEST(GpuFailures, NonFiniteFloat) {
  FBAR_REQUIRE_DEVICE();
  nan_test<float>();
}
TEST(GpuFailures, NonFiniteDouble) {
  FBAR_REQUIRE_DEVICE();
  nan_test<double>();
}

// CFL: a block at 10 m/s with dt = 0.01 s moves 0.1 m = 2 dx in its first step (no walls, no gravity effect worth
// naming): every particle violates the one-cell bound; none leaves the 1 m box.
template <typename T>
void cfl_test() {
  Scene scene = test::small_scene(Constitutive::FixedCorotated,
                                  std::is_same_v<T, double> ? Precision::Double : Precision::Single, {10.0, 0.0, 0.0},
                                  false);
  scene.bodies[0].geometry[0].offset = {0.2, 0.4, 0.35};
  scene.simulation.default_dt = 0.01;
  const auto [rc, rg] = run_until_failure<T>(scene, 0.01, 1);
  expect_same_failure(rc, rg, FailureKind::CflViolation, 0.0);
  EXPECT_EQ(rg.failures.front().count, static_cast<long long>(test::sample_scene(scene)[0].size()));
}
TEST(GpuFailures, CflFloat) {
  FBAR_REQUIRE_DEVICE();
  cfl_test<float>();
}
TEST(GpuFailures, CflDouble) {
  FBAR_REQUIRE_DEVICE();
  cfl_test<double>();
}

// Leaving the domain: a block moving +x at 2 m/s with its front 5 cm from the open end (no walls), 0.02 m per step:
// the front crosses x = 1.4 m (the domain plus kDomainMarginCells = 8 cells) at the same step in both engines. A soft
// fluid (c = 1 m/s) keeps the 0.01 s steps stable while it travels. float: a particle within round-off of the face may
// cross one step apart, hence 2 % on the count; double: exact.
template <typename T>
void leave_test() {
  Scene scene = test::small_scene(Constitutive::JFluid, std::is_same_v<T, double> ? Precision::Double : Precision::Single,
                                  {2.0, 0.0, 0.0}, false);
  scene.bodies[0].geometry[0].offset = {0.65, 0.4, 0.35};
  scene.simulation.gravity = {0.0, 0.0, 0.0};
  scene.bodies[0].material.bulk_modulus = 1e3;
  const auto [rc, rg] = run_until_failure<T>(scene, 0.01, 60);
  expect_same_failure(rc, rg, FailureKind::LeftDomain, std::is_same_v<T, double> ? 0.0 : 0.02);
}
TEST(GpuFailures, LeftDomainFloat) {
  FBAR_REQUIRE_DEVICE();
  leave_test<float>();
}
TEST(GpuFailures, LeftDomainDouble) {
  FBAR_REQUIRE_DEVICE();
  leave_test<double>();
}

// on_failure = reduce_dt: the CFL scene at 12 m/s repeated with dt/2, dt/4: 0.12, 0.06 m fail, 0.0025 s moves 0.03 m < dx; both engines
// retry the same number of times, log it, and end in the same state (the GPU rescales the P2G impulse of the
// kept grid; FixedCorotated's stress is rate independent, so the repeat is exact up to round-off).
TEST(GpuFailures, ReduceDtRepeatsTheStepLikeCpu) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = test::small_scene(Constitutive::FixedCorotated, Precision::Double, {12.0, 0.0, 0.0}, false);
  scene.bodies[0].geometry[0].offset = {0.2, 0.4, 0.35};
  scene.simulation.on_failure = OnFailure::ReduceDt;
  const auto positions = test::sample_scene(scene);
  CpuEngine<double> cpu(scene, positions);
  GpuEngine<double> gpu(scene, positions);
  std::ostringstream log_c, log_g;
  cpu.set_log(&log_c);
  gpu.set_log(&log_g);
  gpu.set_record_velocities(true);
  const StepReport rc = cpu.step(0.01);
  const StepReport rg = gpu.step(0.01);
  ASSERT_TRUE(rc.ok);
  ASSERT_TRUE(rg.ok) << rg.message();
  EXPECT_EQ(rg.retries, rc.retries);
  EXPECT_GE(rg.retries, 1);
  EXPECT_DOUBLE_EQ(rg.dt, rc.dt);
  EXPECT_NE(log_g.str().find("retrying the step"), std::string::npos);
  EXPECT_LE(test::max_diff(gpu.snapshot(0).x, cpu.positions(0)), 1e-12);
  EXPECT_LE(test::max_diff(gpu.snapshot(0).v, cpu.velocities(0)), 1e-10);
  // And the following steps go on matching (the grid of the next step used the repeated dt).
  for (int s = 0; s < 5; ++s) {
    ASSERT_TRUE(cpu.step(rc.dt).ok);
    ASSERT_TRUE(gpu.step(rc.dt).ok);
  }
  EXPECT_LE(test::max_diff(gpu.snapshot(0).x, cpu.positions(0)), 1e-12);
}

// simulation.precision "mixed" runs on the GPU engine (GpuEngine<double, float>) through run_gpu and says so.
TEST(GpuFailures, MixedPrecisionRunsFromTheScene) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = test::small_scene(Constitutive::JFluid, Precision::Mixed);
  scene.simulation.frames = 2;
  scene.simulation.fps = 200;
  scene.simulation.save_path = (std::filesystem::temp_directory_path() / "fbar_gpu_mixed").string();
  std::filesystem::remove_all(scene.simulation.save_path);
  std::ostringstream log;
  RunOptions options;
  options.log = &log;
  const RunResult r = run_gpu(scene, options);
  EXPECT_EQ(r.exit_code, 0) << r.message;
  EXPECT_NEAR(r.end_time, 0.01, 1e-12);
  EXPECT_NE(log.str().find("mixed: particles double, grid single"), std::string::npos) << log.str();
  std::size_t frames = 0;
  for (const auto& e : std::filesystem::directory_iterator(scene.simulation.save_path)) frames += e.is_regular_file();
  EXPECT_EQ(frames, 3u) << "frames 0, 1 and 2";
}

}  // namespace
}  // namespace fbar
