// FEM bodies in MPM water on the GPU engine: the cost of a mesh beside the particle rows, and partition by
// method on two GPUs.
//
//   fbar_fem_benchmark [--water=16] [--cells=50,70,48] [--steps=40] [--warmup=10] [--precision=single] [--csv=FILE]
//
// The scene: fbar_benchmark's dam break (JFluid, 8 ppc, --water million particles) and an elastic block meshed in
// cubes of six tetrahedra (--cells per axis: 50 x 70 x 48 cubes = 1,008,000 tetrahedra) standing on the tank's floor
// beyond the water (FixedCorotated, E 2e6 Pa, nu 0.3, rho 1000). Cases: the water alone on one GPU, water and mesh on
// one GPU, and (with two GPUs) the mesh whole on GPU 1 while the water is spread over both (partition by method,
// threads with NCCL). Per case: wall time per step (max over ranks), particle-steps per second, the split of a step
// from CUDA events in a second timed run (G2P2G of all bodies, of which the element pass; grid update; partition;
// halo sums), the element pass per element-step and per vertex-step, and the device memory the engine holds (rank 0;
// and the mesh's bytes per element).
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "MnSystem/Cuda/device_query.h"
#include "benchmark_scenes.h"
#include "rank_timing.h"
#include "comm/device_transport.h"
#include "comm/transport.h"
#include "engine/gpu/gpu_engine.h"
#include "geometry/tet_mesh.h"
#include "scene/scene_parse.h"

#include "git_commit.h"
#ifndef FBAR_GIT_COMMIT
#define FBAR_GIT_COMMIT "unknown"
#endif

namespace {

using namespace fbar;

struct CaseResult {
  double ms_per_step = 0;
  KernelTimes kernels;
  std::size_t particles = 0, vertices = 0, elements = 0;
  std::size_t device_bytes = 0, peak_bytes = 0;
  std::string error;
};

/// The dam break with (cells > 0) a meshed block on `mesh_gpu`.
Scene make_case(double water, const std::vector<int>& cells, Precision precision, int mesh_gpu) {
  Scene scene = bench::make_scene("dam_break", water, precision);
  if (cells.empty()) return scene;
  const double dx = scene.simulation.dx;
  // Beyond the water's 2k-cell column: from 0.6 of the tank's length, 0.4 m x 0.56 m x 0.384 m (at dx 0.01).
  const Vec3d lo{{0.6 * scene.simulation.domain[0], 4 * dx, 4 * dx}};
  const Vec3d hi{{lo[0] + 0.8 * dx * cells[0], lo[1] + 0.8 * dx * cells[1], lo[2] + 0.8 * dx * cells[2]}};
  MeshEntrySpec m;
  m.law = Constitutive::FixedCorotated;
  m.rho = 1000.0;
  m.youngs_modulus = 2e6;
  m.poisson_ratio = 0.3;
  m.use_fem = true;
  m.use_asflip = false;
  m.gpu = mesh_gpu;
  m.output_attribs = {"ID"};
  m.mesh = std::make_shared<const TetMesh>(box_tet_mesh(lo, hi, Vec3i{{cells[0], cells[1], cells[2]}}));
  scene.meshes.push_back(std::move(m));
  append_mesh_bodies(scene);
  return scene;
}

template <typename T, typename TG>
CaseResult run_rank(const Scene& scene, comm::Transport* host, int device, int steps, int warmup) {
  CaseResult out;
  try {
    FBAR_CUDA_CHECK(cudaSetDevice(device));
    std::unique_ptr<comm::DeviceTransport> dev;
    GpuEngineOptions options;
    if (host && host->size() > 1) {
      dev = comm::make_nccl_transport(*host);
      options.ranks = host;
      options.device_ranks = dev.get();
    }
    GpuEngine<T, TG> engine(scene, options);
    engine.set_log(nullptr);
    const bench::StepTiming timing = bench::time_steps(engine, host, steps, warmup);
    out.ms_per_step = timing.ms_per_step;
    out.kernels = timing.kernels;
    out.particles = engine.particle_count();
    if (!scene.meshes.empty()) {
      const int b = static_cast<int>(scene.bodies.size()) - 1;
      out.vertices = engine.particle_count(b);
      out.elements = out.vertices > 0 ? scene.meshes[0].mesh->elements.size() : 0;
    }
    out.device_bytes = engine.device_bytes();
    out.peak_bytes = engine.peak_device_bytes();
  } catch (const std::exception& e) {
    out.error = e.what();
    if (host) host->abort(1);
  }
  return out;
}

template <typename T, typename TG>
CaseResult run_case(const Scene& scene, int ranks, int steps, int warmup) {
  if (ranks == 1) return run_rank<T, TG>(scene, nullptr, 0, steps, warmup);
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(ranks);
  std::vector<CaseResult> results(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] { results[r] = run_rank<T, TG>(scene, hosts[r].get(), r, steps, warmup); });
  for (auto& t : threads) t.join();
  CaseResult merged = results[0];
  merged.particles = merged.vertices = merged.elements = 0;
  for (const CaseResult& r : results) {
    if (!r.error.empty()) merged.error += r.error + "; ";
    merged.ms_per_step = std::max(merged.ms_per_step, r.ms_per_step);
    merged.particles += r.particles;
    merged.vertices += r.vertices;
    merged.elements += r.elements;
    if (r.elements > 0) merged.kernels.fem_ms = r.kernels.fem_ms;  // the mesh's rank
  }
  return merged;
}

std::vector<int> split_ints(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stoi(item));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  double water = 16;
  std::vector<int> cells = {50, 70, 48};
  int steps = 40, warmup = 10;
  std::string precision_name = "single", csv;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* key) { return a.substr(std::string(key).size()); };
    if (a.rfind("--water=", 0) == 0) water = std::stod(value("--water="));
    else if (a.rfind("--cells=", 0) == 0) cells = split_ints(value("--cells="));
    else if (a.rfind("--steps=", 0) == 0) steps = std::stoi(value("--steps="));
    else if (a.rfind("--warmup=", 0) == 0) warmup = std::stoi(value("--warmup="));
    else if (a.rfind("--precision=", 0) == 0) precision_name = value("--precision=");
    else if (a.rfind("--csv=", 0) == 0) csv = value("--csv=");
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  if (cells.size() != 3) {
    std::fprintf(stderr, "--cells: three counts\n");
    return 2;
  }
  const Precision precision = precision_name == "double" ? Precision::Double
                              : precision_name == "mixed" ? Precision::Mixed
                                                          : Precision::Single;
  const int devices = cuda::device_count();
  if (devices == 0) {
    std::fprintf(stderr, "no CUDA device: %s\n", cuda::no_device_reason().c_str());
    return 1;
  }
  cudaDeviceProp prop{};
  cudaGetDeviceProperties(&prop, 0);
  std::printf("fbar_fem_benchmark %s, %s x %d visible, precision %s, %d warm-up + %d timed steps\n", FBAR_GIT_COMMIT,
              prop.name, devices, precision_name.c_str(), warmup, steps);
  struct Case {
    const char* name;
    int ranks;
    bool mesh;
  };
  std::vector<Case> cases = {{"water", 1, false}, {"water+mesh", 1, true}};
  if (devices >= 2) cases.push_back({"by method", 2, true});
  std::ofstream out;
  if (!csv.empty()) {
    out.open(csv);
    out << "case,gpus,particles,vertices,elements,ms_per_step,particle_steps_per_s,g2p2g_ms,fem_ms,grid_ms,"
           "partition_ms,halo_ms,fem_ns_per_element_step,fem_ns_per_vertex_step,device_bytes,peak_bytes,commit,device\n";
  }
  std::printf("%-11s %4s %10s %8s %9s %8s %10s | %7s %7s %7s %7s %7s | %9s %9s | %9s %9s\n", "case", "gpus",
              "particles", "vertices", "elements", "ms/step", "p-steps/s", "g2p2g", "fem", "grid", "part", "halo",
              "ns/elem", "ns/vert", "dev MiB", "peak MiB");
  for (const Case& c : cases) {
    const Scene scene = make_case(water, c.mesh ? cells : std::vector<int>{}, precision, c.ranks > 1 ? 1 : 0);
    CaseResult r;
    switch (precision) {
      case Precision::Double: r = run_case<double, double>(scene, c.ranks, steps, warmup); break;
      case Precision::Mixed: r = run_case<double, float>(scene, c.ranks, steps, warmup); break;
      default: r = run_case<float, float>(scene, c.ranks, steps, warmup); break;
    }
    if (!r.error.empty()) {
      std::printf("%-11s %4d error: %s\n", c.name, c.ranks, r.error.c_str());
      continue;
    }
    const double k = r.kernels.steps > 0 ? 1.0 / static_cast<double>(r.kernels.steps) : 0.0;
    const double fem = r.kernels.fem_ms * k;
    const double per_element = r.elements > 0 ? fem * 1e6 / static_cast<double>(r.elements) : 0.0;
    const double per_vertex = r.vertices > 0 ? fem * 1e6 / static_cast<double>(r.vertices) : 0.0;
    const double mib = 1.0 / (1024.0 * 1024.0);
    std::printf("%-11s %4d %10zu %8zu %9zu %8.3f %10.3e | %7.3f %7.3f %7.3f %7.3f %7.3f | %9.3f %9.3f | %9.1f %9.1f\n",
                c.name, c.ranks, r.particles, r.vertices, r.elements, r.ms_per_step,
                static_cast<double>(r.particles) * 1e3 / r.ms_per_step, r.kernels.g2p2g_ms * k, fem,
                r.kernels.grid_update_ms * k, r.kernels.partition_ms * k, r.kernels.halo_ms * k, per_element,
                per_vertex, static_cast<double>(r.device_bytes) * mib, static_cast<double>(r.peak_bytes) * mib);
    if (out)
      out << c.name << "," << c.ranks << "," << r.particles << "," << r.vertices << "," << r.elements << ","
          << r.ms_per_step << "," << static_cast<double>(r.particles) * 1e3 / r.ms_per_step << ","
          << r.kernels.g2p2g_ms * k << "," << fem << "," << r.kernels.grid_update_ms * k << ","
          << r.kernels.partition_ms * k << "," << r.kernels.halo_ms * k << "," << per_element << "," << per_vertex
          << "," << r.device_bytes << "," << r.peak_bytes << "," << FBAR_GIT_COMMIT << "," << prop.name << "\n";
  }
  return 0;
}
