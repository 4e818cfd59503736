// The timing loop the multi-rank GPU benchmarks share (fbar_scaling, fbar_fem_benchmark): one rank's engine, set up
// by the caller, steps `warmup` times, waits for every rank, then `steps` timed steps give the wall time per step,
// and `steps` more with kernel timing give the split of a step.
#pragma once

#include <cuda_runtime.h>

#include <chrono>
#include <stdexcept>

#include "MnSystem/Cuda/device_query.h"
#include "comm/transport.h"
#include "engine/gpu/gpu_engine.h"

namespace fbar::bench {

struct StepTiming {
  double ms_per_step = 0;  ///< [ms] wall time per whole step (host work and the per-step readback included)
  KernelTimes kernels;     ///< the phases of the second `steps` steps, from CUDA events
};

/// host: the ranks' host transport (a barrier before the timed steps), or nullptr for one rank.
template <class Engine>
StepTiming time_steps(Engine& engine, comm::Transport* host, int steps, int warmup) {
  StepTiming out;
  for (int s = 0; s < warmup; ++s)
    if (!engine.step().ok) throw std::runtime_error("a warm-up step failed");
  if (host) host->barrier();
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < steps; ++s)
    if (!engine.step().ok) throw std::runtime_error("a timed step failed");
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  out.ms_per_step = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / steps;
  engine.set_kernel_timing(true);
  for (int s = 0; s < steps; ++s)
    if (!engine.step().ok) throw std::runtime_error("a timed step failed");
  out.kernels = engine.kernel_times();
  return out;
}

}  // namespace fbar::bench
