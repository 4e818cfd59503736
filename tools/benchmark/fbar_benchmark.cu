// GPU engine benchmark: 3D dam break (JFluid) and a falling FixedCorotated block at 8 ppc, 1M..64M particles.
//
// Per case: wall time per whole step (host work and the per-step readback included) over many steps after a
// warm-up, per-kernel CUDA-event times in a second timed run, particle-steps per second, the bytes a step must move
// per particle (from the layouts), that traffic as a fraction of the measured device copy bandwidth, and the
// device memory per particle at start and at its peak during the run (cudaMemGetInfo before construction, after
// it, and after every step), the host's peak resident memory during set-up and run (VmHWM, reset per case), and
// the set-up time (counting, sampling in batches, upload, first partition). Prints a table and writes a CSV.
// tank_box: the compact scene (a JFluid box filling its tank: compact, at rest); dam_break: the water column in a
// tank twice its width (spreading). --frames=K also captures and writes a frame (ID and positions, .bgeo) every K
// steps through the engine's asynchronous output into --frame-dir (default /tmp/fbar_benchmark_frames).
//   fbar_benchmark [--sizes=1,4,16,64] [--precisions=single,double,mixed]
//                  [--scenes=dam_break,falling_block,neo_block,sand_block,saturated_block,clay_block,hencky_block,
//                            vonmises_block,fbar_block,
//                            fbar_dam_break,asflip_dam_break,asflip_block,picflip_dam_break,flip_dam_break,
//                            nodal_dam_break,nodal_split_dam_break,nodal_block]
// fbar_block and fbar_dam_break: falling_block and dam_break with F-bar (FBAR_psi 1); asflip_dam_break and
// asflip_block with ASFLIP (alpha 0.9, beta 0 / 0.2); picflip_dam_break (alpha 0.95) and flip_dam_break (alpha 1):
// the cost of each scheme; nodal_dam_break (fused), nodal_split_dam_break and nodal_block (split): fbar_dam_break
// and fbar_block with ClaymoreUW's nodal F-bar.
//                  [--steps=100] [--warmup=20] [--csv=benchmark.csv] [--frames=0] [--frame-dir=DIR]
#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "MnSystem/Cuda/device_query.h"
#include "MnSystem/IO/async_writer.h"
#include "engine/gpu/gpu_engine.h"
#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "scene/scene_parse.h"
#include "benchmark_scenes.h"

#include "git_commit.h"  // FBAR_GIT_COMMIT, written at build time
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

/// Device-to-device copy bandwidth (bytes read + written per second), 1 GiB, median of 10.
double measure_copy_bandwidth() {
  const std::size_t bytes = std::size_t(1) << 30;
  void *a = nullptr, *b = nullptr;
  FBAR_CUDA_CHECK(cudaMalloc(&a, bytes));
  FBAR_CUDA_CHECK(cudaMalloc(&b, bytes));
  FBAR_CUDA_CHECK(cudaMemset(a, 1, bytes));
  cudaEvent_t e0, e1;
  FBAR_CUDA_CHECK(cudaEventCreate(&e0));
  FBAR_CUDA_CHECK(cudaEventCreate(&e1));
  std::vector<float> ms;
  for (int i = 0; i < 12; ++i) {
    FBAR_CUDA_CHECK(cudaEventRecord(e0));
    FBAR_CUDA_CHECK(cudaMemcpy(b, a, bytes, cudaMemcpyDeviceToDevice));
    FBAR_CUDA_CHECK(cudaEventRecord(e1));
    FBAR_CUDA_CHECK(cudaEventSynchronize(e1));
    float t = 0.f;
    FBAR_CUDA_CHECK(cudaEventElapsedTime(&t, e0, e1));
    if (i >= 2) ms.push_back(t);
  }
  std::sort(ms.begin(), ms.end());
  cudaEventDestroy(e0);
  cudaEventDestroy(e1);
  cudaFree(a);
  cudaFree(b);
  return 2.0 * static_cast<double>(bytes) / (ms[ms.size() / 2] * 1e-3);
}

using bench::make_scene;

struct Row {
  std::string scene, material, precision;
  std::size_t particles = 0;
  double ms_per_step = 0, particle_steps_per_s = 0, bytes_per_particle_step = 0, bandwidth_fraction = 0;
  double device_bytes_per_particle = 0;       ///< at start (after construction)
  double device_peak_bytes_per_particle = 0;  ///< most during the run
  double host_peak_mib = 0;                   ///< VmHWM over set-up and run
  double setup_s = 0;
  double output_wait_s = 0;
  KernelTimes kernels;
  std::size_t blocks = 0;          ///< active grid blocks after the timed steps
  std::size_t blocks_start = 0;    ///< after set-up (spreading: blocks / blocks_start > 1)
  double sim_time = 0;             ///< [s] simulated time reached (warm-up and timed steps)
  long long repeats = 0;  ///< tries repeated for the fixed-point P2G bound (warm-up and timed steps)
};

/// Bytes one step must move per particle: the bin read and written by G2P2G, its src read and dest write, the
/// partition's dest read and src write; plus the grid (update: 4 channels read, 3 written; clear: 4 written; G2P2G:
/// 3 channels of 8 blocks read and 4 written per particle block, approximated by the active blocks) over N.
template <typename M, typename T, typename TG>
double bytes_per_particle_step(std::size_t particles, std::size_t blocks) {
  const double bin = static_cast<double>(ParticleLayout<M, T>::kParticleBytes);
  const double particle = 2 * bin + 4 + 8 + 8 + 4 + 4;
  const double grid = static_cast<double>(blocks) * 64 * sizeof(TG) * (4 + 3 + 4 + 3 + 4);
  return particle + grid / static_cast<double>(particles);
}

/// T, TG: particle and grid scalar types (<float, float> single, <double, double> double, <double, float> mixed).
/// Peak resident memory of this process [KiB] since the last reset_host_peak().
double host_peak_kib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6));
  return 0.0;
}
void reset_host_peak() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";  // resets VmHWM to the current resident size (Linux >= 4.0)
}

struct FrameOptions {
  int every = 0;  ///< steps between frames, 0: none
  std::string dir = "/tmp/fbar_benchmark_frames";
};

template <typename T, typename TG>
Row run_case(const std::string& scene_name, double millions, int steps, int warmup, double bandwidth,
             const FrameOptions& frames) {
  Row row;
  row.scene = scene_name;
  const Precision precision = !std::is_same_v<T, TG>       ? Precision::Mixed
                              : std::is_same_v<T, double> ? Precision::Double
                                                          : Precision::Single;
  row.precision = to_string(precision);
  const Scene scene = make_scene(scene_name, millions, precision);
  row.material = to_string(scene.bodies[0].material.law);
  std::size_t free0 = 0, total = 0, free_min = 0, free_now = 0;
  FBAR_CUDA_CHECK(cudaMemGetInfo(&free0, &total));
  reset_host_peak();
  GpuEngineOptions options;
  options.frames = frames.every > 0;
  const auto s0 = std::chrono::steady_clock::now();
  GpuEngine<T, TG> engine(scene, options);
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  row.setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
  FBAR_CUDA_CHECK(cudaMemGetInfo(&free_min, &total));
  const std::size_t free_start = free_min;
  engine.set_log(&std::cerr);
  row.particles = engine.particle_count();
  row.blocks_start = engine.active_grid_blocks();
  std::filesystem::create_directories(frames.dir);
  io::AsyncWriter writer(1);
  int frame = 0;
  auto one_step = [&](int i, const char* what) {
    if (frames.every > 0) engine.set_frame_capture((i + 1) % frames.every == 0);
    const StepReport r = engine.step();
    if (!r.ok) throw std::runtime_error(std::string(what) + " step failed: " + r.message());
    if (frames.every > 0 && (i + 1) % frames.every == 0)
      engine.submit_frame(0, std::filesystem::path(frames.dir) / ("frame" + std::to_string(frame++ % 4) + ".bgeo"),
                          writer);
    FBAR_CUDA_CHECK(cudaMemGetInfo(&free_now, &total));
    free_min = std::min(free_min, free_now);
  };
  for (int i = 0; i < warmup; ++i) one_step(i, "warm-up");
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < steps; ++i) one_step(i, "timed");
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  writer.close();
  row.sim_time = engine.time();
  row.output_wait_s = engine.output_wait_seconds();
  engine.set_kernel_timing(true);
  for (int i = 0; i < steps; ++i) {
    const StepReport r = engine.step();
    if (!r.ok) throw std::runtime_error("step failed: " + r.message());
  }
  row.kernels = engine.kernel_times();
  row.host_peak_mib = host_peak_kib() / 1024.0;
  row.blocks = engine.active_grid_blocks();
  row.repeats = engine.p2g_range_repeats();
  row.ms_per_step = 1e3 * seconds / steps;
  row.particle_steps_per_s = static_cast<double>(row.particles) / (seconds / steps);
  visit_material(scene.bodies[0].material.law, [&](auto m) {
    row.bytes_per_particle_step = bytes_per_particle_step<decltype(m), T, TG>(row.particles, row.blocks);
  });
  row.bandwidth_fraction = row.bytes_per_particle_step * row.particle_steps_per_s / bandwidth;
  row.device_bytes_per_particle = static_cast<double>(free0 - free_start) / static_cast<double>(row.particles);
  row.device_peak_bytes_per_particle = static_cast<double>(free0 - free_min) / static_cast<double>(row.particles);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> sizes{"1", "4", "16", "64"}, precisions{"single", "double"},
      scenes{"dam_break", "falling_block"};
  int steps = 100, warmup = 20;
  std::string csv = "benchmark.csv";
  FrameOptions frames;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* key) { return a.substr(std::string(key).size()); };
    if (a.rfind("--sizes=", 0) == 0) sizes = split(value("--sizes="));
    else if (a.rfind("--precisions=", 0) == 0) precisions = split(value("--precisions="));
    else if (a.rfind("--scenes=", 0) == 0) scenes = split(value("--scenes="));
    else if (a.rfind("--steps=", 0) == 0) steps = std::stoi(value("--steps="));
    else if (a.rfind("--warmup=", 0) == 0) warmup = std::stoi(value("--warmup="));
    else if (a.rfind("--csv=", 0) == 0) csv = value("--csv=");
    else if (a.rfind("--frames=", 0) == 0) frames.every = std::stoi(value("--frames="));
    else if (a.rfind("--frame-dir=", 0) == 0) frames.dir = value("--frame-dir=");
    else {
      std::cerr << "unknown argument " << a << "\n";
      return 1;
    }
  }
  if (fbar::cuda::device_count() == 0) {
    std::cerr << fbar::cuda::no_device_reason() << "\n";
    return 1;
  }
  cudaDeviceProp prop{};
  FBAR_CUDA_CHECK(cudaGetDeviceProperties(&prop, 0));
  const double bandwidth = measure_copy_bandwidth();
  // The commit the numbers belong to: FBAR_COMMIT from the environment (a copied tree may carry a stale .git), else
  // the one of the build (tools/benchmark/git_commit.cmake).
  const char* env_commit = std::getenv("FBAR_COMMIT");
  const std::string commit = env_commit && *env_commit ? env_commit : FBAR_GIT_COMMIT;
  std::printf("device: %s, %d SMs; measured D2D copy bandwidth %.0f GB/s (read + write); commit %s\n", prop.name,
              prop.multiProcessorCount, bandwidth / 1e9, commit.c_str());
  std::ofstream out(csv);
  out << "scene,material,particles,precision,ms_per_step,particle_steps_per_s,bytes_per_particle_step,"
         "bandwidth_fraction,device_bytes_per_particle,device_peak_bytes_per_particle,host_peak_mib,setup_s,"
         "frames_every,output_wait_s,blocks_start,blocks,sim_time_s,commit\n";
  std::printf("%-14s %-15s %10s %-7s %9s %12s %8s %7s %8s %8s %9s %7s | %8s %8s %8s %8s %8s %7s %7s\n", "scene",
              "material", "particles", "prec", "ms/step", "p-steps/s", "B/p/step", "bw frac", "dev B/p", "peak B/p",
              "host MiB", "setup s", "grid ms", "g2p2g ms", "part ms", "blocks0", "blocks", "t [s]", "repeats");
  for (const std::string& scene : scenes)
    for (const std::string& precision : precisions)
      for (const std::string& size : sizes) {
        Row r;
        try {
          if (precision == "double")
            r = run_case<double, double>(scene, std::stod(size), steps, warmup, bandwidth, frames);
          else if (precision == "mixed")
            r = run_case<double, float>(scene, std::stod(size), steps, warmup, bandwidth, frames);
          else if (precision == "single")
            r = run_case<float, float>(scene, std::stod(size), steps, warmup, bandwidth, frames);
          else
            throw std::invalid_argument("--precisions: \"" + precision + "\" is not single, double or mixed");
        } catch (const std::exception& e) {
          std::printf("%-14s %-7s %sM: failed: %s\n", scene.c_str(), precision.c_str(), size.c_str(), e.what());
          cudaGetLastError();
          continue;
        }
        const double n = static_cast<double>(r.kernels.steps > 0 ? r.kernels.steps : 1);
        std::printf("%-14s %-15s %10zu %-7s %9.3f %12.3e %8.1f %7.3f %8.1f %8.1f %9.0f %7.1f | %8.3f %8.3f %8.3f %8zu %8zu %7.4f %7lld\n",
                    r.scene.c_str(), r.material.c_str(), r.particles, r.precision.c_str(), r.ms_per_step,
                    r.particle_steps_per_s, r.bytes_per_particle_step, r.bandwidth_fraction,
                    r.device_bytes_per_particle, r.device_peak_bytes_per_particle, r.host_peak_mib, r.setup_s,
                    r.kernels.grid_update_ms / n, r.kernels.g2p2g_ms / n,
                    r.kernels.partition_ms / n, r.blocks_start, r.blocks, r.sim_time, r.repeats);
        std::fflush(stdout);
        out << r.scene << ',' << r.material << ',' << r.particles << ',' << r.precision << ',' << r.ms_per_step << ','
            << r.particle_steps_per_s << ',' << r.bytes_per_particle_step << ',' << r.bandwidth_fraction << ','
            << r.device_bytes_per_particle << ',' << r.device_peak_bytes_per_particle << ',' << r.host_peak_mib << ','
            << r.setup_s << ',' << frames.every << ',' << r.output_wait_s << ',' << r.blocks_start << ',' << r.blocks << ','
            << r.sim_time << ',' << commit << '\n';
        out.flush();
      }
  return 0;
}
