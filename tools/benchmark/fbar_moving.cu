// Moving and spreading scenes against the compact box: the rate per particle-step of every frame (window of
// simulated time), with the grid compaction on and off (GpuEngineOptions::compact_grid), in one run.
//
// Scenes (JFluid, K 2e6 Pa, gamma 7.1, 8 ppc, single precision unless --precision):
//   tank_box      the compact reference: a box filling its tank, at rest (fbar_benchmark's tank_box)
//   dam_break     the water column spreading over a tank twice its width (fbar_benchmark's dam_break), 1 s
//   moving_box    tank_box's box translating at 2 m/s along x without gravity through a tank 2.5 box lengths long
//   thrown_box    a box thrown at (0.5, -2, 0.3) m/s into a tank under gravity: it lands and spreads
// Per frame: steps, ms per step, particle-steps per second, that rate over the compact box's (measured first, same
// run), grid blocks and those holding particles at the frame's end, the device memory the engine holds, and the
// grid update, G2P2G and partition per step (CUDA events; the step's other time is the dt kernel, the readback and
// the host). The compact box's rate is its mean
// over its frames after the first.
//   fbar_moving [--millions=16] [--frames=5] [--scenes=dam_break,moving_box,thrown_box] [--precision=single]
//               [--csv=moving.csv]
#include <cuda_runtime.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "MnSystem/Cuda/device_query.h"
#include "benchmark_scenes.h"
#include "engine/gpu/gpu_engine.h"
#include "git_commit.h"
#ifndef FBAR_GIT_COMMIT
#define FBAR_GIT_COMMIT "unknown"
#endif

namespace {

using namespace fbar;

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

/// The scene and the simulated time its frames cover [s].
struct Case {
  Scene scene;
  double duration = 0.0;
};

Case make_case(const std::string& name, double millions, Precision precision) {
  if (name == "tank_box") return {bench::make_scene("tank_box", millions, precision), 0.03};
  if (name == "dam_break") return {bench::make_scene("dam_break", millions, precision), 1.0};
  if (name != "moving_box" && name != "thrown_box")
    throw std::invalid_argument("--scenes: \"" + name + "\" is not tank_box, dam_break, moving_box or thrown_box");
  Scene s = bench::make_scene("tank_box", millions, precision);
  const double dx = s.simulation.dx;
  GeometrySpec& box = s.bodies[0].geometry[0];
  if (name == "moving_box") {
    // 2 m/s along x for 0.6 box lengths: the tank 2.5 box lengths long, the walls its faces (Separable).
    s.simulation.gravity = {0.0, 0.0, 0.0};
    s.bodies[0].velocity = {2.0, 0.0, 0.0};
    s.simulation.domain[0] = 2.5 * box.span[0] + 8 * dx;
    const double travel = 0.6 * box.span[0];
    for (BoundarySpec& b : s.boundaries) b.domain_end[0] = s.simulation.domain[0] - 2 * dx;
    return {s, travel / 2.0};
  }
  // thrown_box: a tall box in a tank twice as wide and long as tank_box's, thrown down and sideways.
  // The same volume (particle count) as tank_box's box: 1/sqrt(2) in x and z, twice as tall.
  box.span = {box.span[0] * std::sqrt(0.5), box.span[1] * 2.0, box.span[2] * std::sqrt(0.5)};
  s.simulation.domain = {2.0 * s.simulation.domain[0], 2.2 * box.span[1] + 8 * dx, 2.0 * s.simulation.domain[2]};
  box.offset = {0.3 * s.simulation.domain[0], 0.15 * s.simulation.domain[1], 0.3 * s.simulation.domain[2]};
  s.bodies[0].velocity = {0.5, -2.0, 0.3};
  for (BoundarySpec& b : s.boundaries)
    b.domain_end = {s.simulation.domain[0] - 2 * dx, s.simulation.domain[1] - 2 * dx, s.simulation.domain[2] - 2 * dx};
  return {s, 0.5};
}

struct Frame {
  std::string scene;
  bool compact = true;
  int frame = 0;
  double t_end = 0.0;
  long long steps = 0;
  double ms_per_step = 0.0, rate = 0.0, ratio = 0.0;
  std::size_t particles = 0, blocks = 0, device_bytes = 0;
  long long compactions = 0;
  double grid_ms = 0.0, g2p2g_ms = 0.0, partition_ms = 0.0;  ///< per step, CUDA events (KernelTimes)
  std::size_t particle_blocks = 0;                            ///< table blocks holding particles at the frame's end
};

template <typename T, typename TG>
std::vector<Frame> run_case(const std::string& name, const Case& c, bool compact, int frames) {
  GpuEngineOptions options;
  options.compact_grid = compact;
  GpuEngine<T, TG> engine(c.scene, options);
  engine.set_log(nullptr);
  engine.set_kernel_timing(true);  // a few microseconds a step, in every scene alike
  std::vector<Frame> out;
  for (int f = 0; f < frames; ++f) {
    const long long steps0 = engine.steps();
    const KernelTimes k0 = engine.kernel_times();
    const auto t0 = std::chrono::steady_clock::now();
    const StepReport r = engine.advance_to(c.duration * (f + 1) / frames);
    FBAR_CUDA_CHECK(cudaDeviceSynchronize());
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!r.ok) throw std::runtime_error(name + ": frame " + std::to_string(f + 1) + " failed: " + r.message());
    Frame row;
    row.scene = name;
    row.compact = compact;
    row.frame = f + 1;
    row.t_end = engine.time();
    row.steps = engine.steps() - steps0;
    row.particles = engine.particle_count();
    row.ms_per_step = row.steps > 0 ? 1e3 * seconds / static_cast<double>(row.steps) : 0.0;
    row.rate = row.steps > 0 ? static_cast<double>(row.particles) * static_cast<double>(row.steps) / seconds : 0.0;
    row.blocks = engine.active_grid_blocks();
    row.device_bytes = engine.device_bytes();
    row.compactions = engine.grid_compactions();
    const KernelTimes k1 = engine.kernel_times();
    const double timed = static_cast<double>(std::max(1LL, k1.steps - k0.steps));
    row.grid_ms = (k1.grid_update_ms - k0.grid_update_ms) / timed;
    row.g2p2g_ms = (k1.g2p2g_ms - k0.g2p2g_ms) / timed;
    row.partition_ms = (k1.partition_ms - k0.partition_ms) / timed;
    row.particle_blocks = engine.particle_blocks();
    out.push_back(row);
  }
  return out;
}

template <typename T, typename TG>
std::vector<Frame> run_all(const std::vector<std::string>& scenes, double millions, int frames, Precision precision) {
  std::vector<Frame> rows = run_case<T, TG>("tank_box", make_case("tank_box", millions, precision), true, frames);
  double compact_rate = 0.0;
  for (std::size_t i = 1; i < rows.size(); ++i) compact_rate += rows[i].rate;
  compact_rate /= static_cast<double>(rows.size() > 1 ? rows.size() - 1 : 1);
  if (rows.size() == 1) compact_rate = rows[0].rate;
  for (const std::string& name : scenes) {
    const Case c = make_case(name, millions, precision);
    for (const bool compact : {true, false}) {
      const std::vector<Frame> r = run_case<T, TG>(name, c, compact, frames);
      rows.insert(rows.end(), r.begin(), r.end());
    }
  }
  for (Frame& f : rows) f.ratio = f.rate / compact_rate;
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  double millions = 16;
  int frames = 5;
  std::vector<std::string> scenes = {"dam_break", "moving_box", "thrown_box"};
  std::string precision_name = "single", csv = "moving.csv";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&](const char* key) { return a.substr(std::string(key).size()); };
    if (a.rfind("--millions=", 0) == 0) millions = std::stod(value("--millions="));
    else if (a.rfind("--frames=", 0) == 0) frames = std::stoi(value("--frames="));
    else if (a.rfind("--scenes=", 0) == 0) scenes = split(value("--scenes="));
    else if (a.rfind("--precision=", 0) == 0) precision_name = value("--precision=");
    else if (a.rfind("--csv=", 0) == 0) csv = value("--csv=");
    else {
      std::cerr << "fbar_moving: unknown argument " << a << "\n";
      return 2;
    }
  }
  try {
    if (cuda::device_count() == 0) {
      std::cerr << "fbar_moving: " << cuda::no_device_reason() << "\n";
      return 77;
    }
    const Precision precision = precision_name == "double" ? Precision::Double
                                : precision_name == "mixed" ? Precision::Mixed
                                                            : Precision::Single;
    std::vector<Frame> rows = precision == Precision::Double ? run_all<double, double>(scenes, millions, frames, precision)
                              : precision == Precision::Mixed ? run_all<double, float>(scenes, millions, frames, precision)
                                                              : run_all<float, float>(scenes, millions, frames, precision);
    std::ofstream out(csv);
    out << "scene,compact_grid,frame,t_end_s,steps,particles,ms_per_step,particle_steps_per_s,ratio_to_compact,blocks,"
           "device_mib,compactions,grid_update_ms,g2p2g_ms,partition_ms,particle_blocks,precision,commit\n";
    std::printf("%-11s %-7s %5s %8s %6s %8s %10s %7s %7s %7s %7s %7s %6s %4s\n", "scene", "compact", "frame",
                "t_end s", "steps", "ms/step", "p-steps/s", "ratio", "blocks", "p-blk", "grid", "g2p2g", "part", "cmp");
    for (const Frame& f : rows) {
      const double mib = static_cast<double>(f.device_bytes) / (1 << 20);
      std::printf("%-11s %-7s %5d %8.4f %6lld %8.4f %10.4g %7.3f %7zu %7zu %7.4f %7.4f %6.4f %4lld\n",
                  f.scene.c_str(), f.compact ? "on" : "off", f.frame, f.t_end, f.steps, f.ms_per_step, f.rate, f.ratio,
                  f.blocks, f.particle_blocks, f.grid_ms, f.g2p2g_ms, f.partition_ms, f.compactions);
      out << f.scene << "," << (f.compact ? "on" : "off") << "," << f.frame << "," << f.t_end << "," << f.steps << ","
          << f.particles << "," << f.ms_per_step << "," << f.rate << "," << f.ratio << "," << f.blocks << "," << mib
          << "," << f.compactions << "," << f.grid_ms << "," << f.g2p2g_ms << "," << f.partition_ms << ","
          << f.particle_blocks << "," << precision_name << "," << FBAR_GIT_COMMIT << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "fbar_moving: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
