// Scenes and per-rank runs shared by the GPU decomposition test (threads) and its MPI check (one process per rank).
#pragma once

#include <cuda_runtime.h>

#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "comm/device_transport.h"
#include "comm/placement.h"
#include "comm/slab_partition.h"
#include "comm/transport.h"
#include "engine/gpu/gpu_engine.h"
#include "../cpu/decomposition_scenes.h"
#include "gpu_test_support.h"

namespace fbar::test {

struct ParticleState {
  Vec3d x, v;
  double pore_pressure = 0.0;  ///< [Pa] saturated bodies (CoupledUP); 0 otherwise
};
using StateById = std::map<std::pair<int, int>, ParticleState>;

struct RunResult {
  StateById states;
  std::vector<double> mass;  ///< per body, per particle [kg]
  std::string error;
  double time = 0.0;
  long long steps = 0;
  long long migrated = 0;
  std::size_t halo_blocks = 0;
  std::size_t halo_particle_blocks = 0;  ///< most particle blocks a step ran before the halo exchange
  bool always_owned = true;
  int rebalances = 0;        ///< times the slabs were chosen again
  long long migration_repeats = 0;  ///< steps repeated because migrants overflowed the messages (summed over ranks)
  double imbalance = 0.0;    ///< particles per rank at the end, max / mean - 1
  long long compactions = 0;  ///< grid compactions (summed over ranks)
};

/// One rank: `steps` CFL steps on CUDA device `gpu`, then every particle it holds. host: null for a run without
/// decomposition; nccl: NCCL between the ranks (each on its own GPU), else peer copies between threads; overlap:
/// GpuEngineOptions::overlap_halo; rebalance_every > 0: every that many steps the step keeps the checkpoint inputs
/// and rebalance_if_drifted() follows it (as the run loop does at frames); migrant_capacity > 0: the migration
/// messages' first capacity (GpuEngineOptions::migrant_capacity); dt > 0: steps of exactly dt instead of CFL steps.
inline RunResult run_rank(const Scene& scene, comm::Transport* host, int steps, int gpu = 0, bool nccl = false,
                          bool overlap = true, int rebalance_every = 0, int migrant_capacity = 0, double dt = 0.0) {
  RunResult out;
  try {
    FBAR_CUDA_CHECK(cudaSetDevice(gpu));
    std::unique_ptr<comm::DeviceTransport> device;
    GpuEngineOptions options;
    if (host) {
      device = nccl ? comm::make_nccl_transport(*host) : comm::make_thread_device_transport(*host);
      options.ranks = host;
      options.device_ranks = device.get();
      options.overlap_halo = overlap;
      if (migrant_capacity > 0) options.migrant_capacity = migrant_capacity;
    }
    GpuEngine<double> engine(scene, options);
    engine.set_log(nullptr);
    engine.set_record_velocities(true);
    for (int s = 0; s < steps; ++s) {
      const bool point = rebalance_every > 0 && (s + 1) % rebalance_every == 0;
      engine.keep_checkpoint_inputs(point && engine.rebalance_due());
      const StepReport r = dt > 0.0 ? engine.step(dt) : engine.step();
      if (!r.ok) {
        out.error = r.message();
        return out;
      }
      if (point) engine.rebalance_if_drifted();
      out.halo_blocks = std::max(out.halo_blocks, engine.halo_blocks());
      out.halo_particle_blocks = std::max(out.halo_particle_blocks, engine.halo_particle_blocks());
    }
    out.time = engine.time();
    out.steps = engine.steps();
    out.migrated = engine.migrated();
    out.migration_repeats = engine.migration_repeats();
    out.rebalances = engine.rebalances();
    out.compactions = engine.grid_compactions();
    out.imbalance = engine.imbalance();
    const comm::SlabPartition& slabs = engine.slabs();
    const double inv_dx = 1.0 / scene.simulation.dx;
    const std::vector<int> homes = comm::body_ranks(scene, host ? host->size() : 1);  // bodies[].gpu
    for (int b = 0; b < engine.body_count(); ++b) {
      out.mass.push_back(engine.particle_mass(b));
      const ParticleSnapshot<double> s = engine.snapshot(b);
      // The rank's frame: its particles in ID order, the same positions as its snapshot.
      const io::ParticleFrame frame = engine.frame(b);
      std::size_t k = 0;
      for (std::size_t p = 0; p < s.x.size(); ++p) {
        if (!s.present.empty() && !s.present[p]) continue;
        if (k >= frame.size() || max_abs(frame.position(k) - s.x[p]) != 0.0)
          out.error = "the frame of body " + std::to_string(b) + " differs from its snapshot at particle " +
                      std::to_string(p);
        ++k;
      }
      if (k != frame.size()) out.error = "the frame of body " + std::to_string(b) + " has extra rows";
      for (std::size_t p = 0; p < s.x.size(); ++p) {
        if (!s.present.empty() && !s.present[p]) continue;
        out.states[{b, static_cast<int>(p)}] = {s.x[p], s.v[p], s.pore_pressure.empty() ? 0.0 : s.pore_pressure[p]};
        // The GPU engine's particle block: floor((base - 1) / 4), base = floor(x / dx - 0.5).
        const double x = s.x[p][slabs.axis];
        const int block = static_cast<int>(std::floor((std::floor(x * inv_dx - 0.5) - 1.0) / 4.0));
        const int home = homes[static_cast<std::size_t>(b)];  // a placed body: its rank, wherever it goes
        if ((home >= 0 ? home : slabs.owner(block)) != engine.rank()) out.always_owned = false;
      }
    }
  } catch (const std::exception& e) {
    out.error = e.what();
    if (host) host->abort(1);  // the other ranks' collectives throw instead of waiting for this one
  }
  return out;
}


/// How far a decomposed run's particles are from one rank's (by ID; IDs missing from `many` are skipped: the
/// callers check the ID sets first).
struct Comparison {
  double max_dx = 0, max_dv = 0;  ///< [m], [m/s]
  double momentum = 0;            ///< |sum m v - sum m v'| / sum m |v| [-]
  double pore_pressure = 0;       ///< max |p - p'| / max |p| over the particles [-] (0 without pore water)
};
inline Comparison compare(const RunResult& one, const StateById& many) {
  Comparison c;
  double scale = 0;
  Vec3d pa = Vec3d::zero(), pb = Vec3d::zero();
  double p_scale = 0;
  for (const auto& [key, a] : one.states) {
    const auto it = many.find(key);
    if (it == many.end()) continue;
    const double m = one.mass[static_cast<std::size_t>(key.first)];
    c.pore_pressure = test::worst(c.pore_pressure, std::fabs(a.pore_pressure - it->second.pore_pressure));
    p_scale = test::worst(p_scale, std::fabs(a.pore_pressure));
    c.max_dx = std::max(c.max_dx, max_abs(a.x - it->second.x));
    c.max_dv = std::max(c.max_dv, max_abs(a.v - it->second.v));
    pa = pa + a.v * m;
    pb = pb + it->second.v * m;
    scale += m * norm(a.v);
  }
  c.momentum = scale > 0 ? max_abs(pa - pb) / scale : 0.0;
  c.pore_pressure = p_scale > 0 ? c.pore_pressure / p_scale : 0.0;
  return c;
}

// Tolerances. The grid's sums are order-free integers and every rank rounds with the same bound and quanta
// (engine/gpu/grid_buffer.cuh "Order-free grid sums"), so a decomposed run gives one rank's particles bit for bit
// and expect_same_run asserts that (measured on two H200s: |dx| = |dv| = 0, threads and NCCL). The tolerances below
// are what the comparison allowed before the sums were order-free (float atomics in arrival order: dam breaks |dx|
// 3.3e-16 m, |dv| 4.9e-15 m/s; saturated soil |dv| 4.3e-14 m/s, pore pressure 4.7e-14 relative), kept as the
// looser bound, and a rebalance's (below), which starts from a fresh P2G.
constexpr double kPositionTolerance = 1e-11;  // [m]
constexpr double kVelocityTolerance = 1e-12;  // [m/s]
constexpr double kMomentumTolerance = 1e-14;  // [-] of sum m |v|
constexpr double kTimeTolerance = 1e-10;      // [-] relative
// Pore pressure (saturated bodies), relative to the largest: the seepage sums add their blocks with float atomics in
// arrival order on every rank (each block's own sum is fixed point), plus the halo's one more term; a pressure follows J through the storage modulus M (1e6 Pa in
// test::saturate), so position-sized round-off (1e-16 relative) becomes about M / |p|max x 1e-15.
constexpr double kPorePressureTolerance = 1e-10;  // [-] of max |p|
// A rebalance builds the device state again from the particles (the restart path): the grid of its first step comes
// from a fresh P2G rather than the fused one, so the rebalanced run is the one-rank run to the restart's tolerance
// (GpuCheckpoint: 1e-9 m after 150 steps in double).
constexpr double kRebalancedPositionTolerance = 1e-9;  // [m]
constexpr double kRebalancedVelocityTolerance = 1e-8;  // [m/s]

}  // namespace fbar::test
