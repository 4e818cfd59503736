// GPU strong and weak scaling of the decomposed engine: the dam break of fbar_benchmark (JFluid, 8 ppc) on 1..N
// ranks, one rank per GPU.
//
//   fbar_scaling [--ranks=1,2] [--strong=32] [--weak=16] [--steps=50] [--warmup=10] [--precision=single]
//                [--scene=dam_break] [--overlap=both|on|off] [--csv=FILE]
// Without a launcher the ranks are threads of this process: rank r on GPU r % (visible GPUs); NCCL when every rank
// has a GPU of its own, peer copies between the threads otherwise (several ranks on one GPU: a check of the
// decomposition's overhead, not a scaling figure; the table says "shared"). Under mpirun / srun (one process per
// rank, GPU = local rank % visible GPUs) the ranks are the MPI world and --ranks is its size; NCCL moves the data.
// Per case: wall time per step (max over ranks; the ranks step in lockstep), particle-steps per second, the
// efficiency against one rank (strong: t1 / (N tN) at a fixed total; weak: particle-steps per second per GPU over
// one GPU's, at about the same size per rank), and
// rank 0's split of a step from CUDA events in a second timed run (grid update, G2P2G, halo sums, migration,
// partition; halo: the exposed part of the halo sums, hidden: the part that overlapped the interior G2P2G). Every
// case on more than one rank runs with the halo-first overlap (GpuEngineOptions::overlap_halo) and without it
// (--overlap=both, the default), so the table shows what the overlap hides.
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
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
#include "comm/mpi_transport.h"
#include "comm/transport.h"
#include "engine/gpu/gpu_engine.h"

#include "git_commit.h"
#ifndef FBAR_GIT_COMMIT
#define FBAR_GIT_COMMIT "unknown"
#endif

namespace {

using namespace fbar;

struct RankResult {
  double ms_per_step = 0;
  KernelTimes kernels;
  std::size_t particles = 0, halo_blocks = 0;
  long long migrated = 0;
  std::string error;
};

std::vector<int> split_ints(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stoi(item));
  return out;
}

template <typename T, typename TG>
RankResult run_rank(const Scene& scene, comm::Transport* host, bool nccl, int device, int steps, int warmup,
                    bool overlap) {
  RankResult out;
  try {
    FBAR_CUDA_CHECK(cudaSetDevice(device));
    std::unique_ptr<comm::DeviceTransport> dev;
    GpuEngineOptions options;
    if (host && host->size() > 1) {
      dev = nccl ? comm::make_nccl_transport(*host) : comm::make_thread_device_transport(*host);
      options.ranks = host;
      options.device_ranks = dev.get();
      options.overlap_halo = overlap;
    }
    GpuEngine<T, TG> engine(scene, options);
    engine.set_log(nullptr);
    const bench::StepTiming timing = bench::time_steps(engine, host, steps, warmup);
    out.ms_per_step = timing.ms_per_step;
    out.kernels = timing.kernels;
    out.particles = engine.particle_count();
    out.halo_blocks = engine.halo_blocks();
    out.migrated = engine.migrated();
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  return out;
}

RankResult run_case_typed(const Scene& scene, int ranks, int devices, int steps, int warmup, Precision precision,
                          comm::Transport* mpi, bool overlap, bool& shared) {
  auto run = [&](comm::Transport* host, bool nccl, int device) {
    switch (precision) {
      case Precision::Double: return run_rank<double, double>(scene, host, nccl, device, steps, warmup, overlap);
      case Precision::Mixed: return run_rank<double, float>(scene, host, nccl, device, steps, warmup, overlap);
      default: return run_rank<float, float>(scene, host, nccl, device, steps, warmup, overlap);
    }
  };
  if (mpi) {  // this process is one rank of the MPI world
    shared = false;
    RankResult r = run(mpi, true, mpi->rank() % devices);
    double t = mpi->max(r.ms_per_step);
    r.ms_per_step = t;
    long long p = mpi->sum(static_cast<long long>(r.particles));
    r.particles = static_cast<std::size_t>(p);
    return r;
  }
  shared = ranks > devices;
  if (ranks == 1) return run(nullptr, false, 0);
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(ranks);
  std::vector<RankResult> results(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] { results[r] = run(hosts[r].get(), !shared, r % devices); });
  for (auto& t : threads) t.join();
  RankResult merged = results[0];
  merged.particles = 0;
  for (const RankResult& r : results) {
    if (!r.error.empty()) merged.error += r.error + "; ";
    merged.ms_per_step = std::max(merged.ms_per_step, r.ms_per_step);
    merged.particles += r.particles;
    merged.migrated += r.migrated;
  }
  return merged;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> ranks_list = {1, 2};
  double strong = 32, weak = 16;
  int steps = 50, warmup = 10;
  std::string precision_name = "single", scene_name = "dam_break", csv, overlap_name = "both";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* key) { return a.substr(std::string(key).size()); };
    if (a.rfind("--ranks=", 0) == 0) ranks_list = split_ints(value("--ranks="));
    else if (a.rfind("--strong=", 0) == 0) strong = std::stod(value("--strong="));
    else if (a.rfind("--weak=", 0) == 0) weak = std::stod(value("--weak="));
    else if (a.rfind("--steps=", 0) == 0) steps = std::stoi(value("--steps="));
    else if (a.rfind("--warmup=", 0) == 0) warmup = std::stoi(value("--warmup="));
    else if (a.rfind("--precision=", 0) == 0) precision_name = value("--precision=");
    else if (a.rfind("--scene=", 0) == 0) scene_name = value("--scene=");
    else if (a.rfind("--csv=", 0) == 0) csv = value("--csv=");
    else if (a.rfind("--overlap=", 0) == 0) overlap_name = value("--overlap=");
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  const Precision precision = precision_name == "double" ? Precision::Double
                              : precision_name == "mixed" ? Precision::Mixed
                                                          : Precision::Single;
  const int devices = cuda::device_count();
  if (devices == 0) {
    std::fprintf(stderr, "no CUDA device: %s\n", cuda::no_device_reason().c_str());
    return 1;
  }
  std::unique_ptr<comm::Transport> mpi;
#ifdef FBAR_HAS_MPI
  if (comm::launched_by_mpi()) {
    mpi = std::make_unique<comm::MpiTransport>();
    ranks_list = {mpi->size()};
  }
#endif
  const bool lead = !mpi || mpi->rank() == 0;
  cudaDeviceProp prop{};
  cudaGetDeviceProperties(&prop, 0);
  if (lead)
    std::printf("fbar_scaling %s, %s x %d visible, %s, precision %s, %d warm-up + %d timed steps%s\n", FBAR_GIT_COMMIT,
                prop.name, devices, scene_name.c_str(), precision_name.c_str(), warmup, steps,
                mpi ? " (MPI ranks, NCCL)" : "");
  std::ofstream out;
  if (lead && !csv.empty()) {
    out.open(csv);
    out << "mode,ranks,transport,overlap,particles,ms_per_step,particle_steps_per_s,efficiency,grid_ms,g2p2g_ms,"
           "halo_exposed_ms,halo_hidden_ms,migration_ms,partition_ms,halo_blocks,migrated,commit,device\n";
  }
  if (lead)
    std::printf("%-6s %5s %-8s %-4s %10s %9s %11s %6s | %8s %8s %8s %8s %8s %8s %6s %8s\n", "mode", "ranks",
                "transport", "ovl", "particles", "ms/step", "p-steps/s", "eff", "grid", "g2p2g", "halo", "hidden",
                "migr", "part", "halo b", "migrated");
  std::vector<bool> overlaps;
  if (overlap_name != "off") overlaps.push_back(true);
  if (overlap_name != "on") overlaps.push_back(false);
  for (const char* mode : {"strong", "weak"}) {
    double t1 = 0, p1 = 0;
    for (int n : ranks_list)
    for (const bool overlap : overlaps) {
      if (n == 1 && overlap != overlaps.front()) continue;  // one rank has no halo
      const bool is_strong = std::string(mode) == "strong";
      const double millions = is_strong ? strong : weak * n;
      const Scene scene = bench::make_scene(scene_name, millions, precision);
      bool shared = false;
      const RankResult r = run_case_typed(scene, n, devices, steps, warmup, precision, mpi.get(), overlap, shared);
      if (!r.error.empty()) {
        if (lead) std::printf("%-6s %5d error: %s\n", mode, n, r.error.c_str());
        continue;
      }
      if (n == 1) {
        t1 = r.ms_per_step;
        p1 = static_cast<double>(r.particles);
      }
      // Strong: t1 / (n tN) at the same total. Weak: particle-steps per second per GPU against one GPU's, since the
      // scene builder's sizes are not exactly proportional (15.8M on one rank, 32.0M on two); equal to t1 / tN
      // when they are.
      const double eff = t1 <= 0 ? 0.0
                         : is_strong
                             ? t1 / (n * r.ms_per_step)
                             : (static_cast<double>(r.particles) / (n * r.ms_per_step)) / (p1 / t1);
      const double k = r.kernels.steps > 0 ? 1.0 / static_cast<double>(r.kernels.steps) : 0.0;
      const std::string transport = n == 1 ? "-" : shared ? "shared" : "nccl";
      const char* ovl = n == 1 ? "-" : overlap ? "on" : "off";
      if (!lead) continue;
      std::printf("%-6s %5d %-8s %-4s %10zu %9.3f %11.3e %6.3f | %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %6zu %8lld\n", mode,
                  n, transport.c_str(), ovl, r.particles, r.ms_per_step,
                  static_cast<double>(r.particles) * 1e3 / r.ms_per_step, eff, r.kernels.grid_update_ms * k,
                  r.kernels.g2p2g_ms * k, r.kernels.halo_ms * k, r.kernels.halo_hidden_ms * k, r.kernels.migration_ms * k,
                  r.kernels.partition_ms * k, r.halo_blocks, r.migrated);
      if (out)
        out << mode << "," << n << "," << transport << "," << ovl << "," << r.particles << "," << r.ms_per_step << ","
            << static_cast<double>(r.particles) * 1e3 / r.ms_per_step << "," << eff << "," << r.kernels.grid_update_ms * k
            << "," << r.kernels.g2p2g_ms * k << "," << r.kernels.halo_ms * k << "," << r.kernels.halo_hidden_ms * k
            << "," << r.kernels.migration_ms * k << ","
            << r.kernels.partition_ms * k << "," << r.halo_blocks << "," << r.migrated << "," << FBAR_GIT_COMMIT << ","
            << prop.name << "\n";
    }
  }
  return 0;
}
