// What the front end (cli.cpp) needs from the engines: scene summary for --check, and a run (run_loop.h).
#pragma once

#include <cstddef>
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "engine/memory_plan.h"
#include "comm/transport.h"
#include "scene/scene.h"

namespace fbar {

/// Per-body facts printed by `fbar --check` and logged at the start of a run.
struct BodySummary {
  long long particles = 0;        ///< particles after sampling and partition clipping
  double particle_volume = 0.0;   ///< [m^3] dx^3 / ppc
  double particle_mass = 0.0;     ///< [kg] rho * particle_volume
  double wave_speed = 0.0;        ///< [m/s] p-wave speed at rest (docs/user_guide.md §2.4)
  double dt_bound = 0.0;          ///< [s] CFL * dx / (wave_speed + |initial velocity|)
  double viscous_dt = 0.0;        ///< [s] CFL rho dx^2 / (3 mu) (time_step.cuh); +infinity when inviscid
  double seepage_dt = 0.0;        ///< [s] CFL dx^2 / (8 kappa M) (time_step.cuh); +infinity unless saturated
  // What the body costs on the GPU engine (a scene pays only for what it uses):
  int stored_scalars = 0;             ///< position + material state scalars per particle in a bin
  std::size_t record_bytes = 0;       ///< [B] one bin record: those scalars in the run's precision and the ID
  std::size_t gpu_bytes_per_particle = 0;  ///< [B] bins x 2, ASFLIP velocities, recorded v and C, partition, frame
  std::string gpu_bytes_detail;       ///< what the bytes are, for --check
  std::string grid_channels;          ///< the grid channels this body's P2G writes, for --check
  double throughput = 0.0;            ///< [particle-steps/s] on a kGpuRateDevice at 16M particles (kGpuRateRecord)
  std::string throughput_basis;       ///< which measurement the throughput comes from
  double gpu_ms_per_step = 0.0;       ///< [ms] particles / throughput
  // A mesh (FEM body; its particles are the vertices):
  bool mesh = false;
  long long elements = 0;
  double min_quality = 0.0;           ///< smallest element quality (geometry/tet_mesh.h)
  double min_height = 0.0;            ///< [m] smallest element height: dt <= CFL h / wave speed (physics/fem.cuh)
  std::size_t mesh_bytes = 0;         ///< [B] the CPU engine's elements and per-vertex arrays besides the particles'
  std::size_t gpu_mesh_bytes = 0;     ///< [B] the GPU engine's (mesh_device_bytes), on the mesh's GPU
};

struct SceneSummary {
  std::vector<DeviceMemoryPlan> gpu_plans;  ///< the GPU engine's plan per GPU (index = gpu id)
  std::vector<BodySummary> bodies;
  double dt = 0.0;                          ///< [s] min(default_dt, every body's dt_bound, viscous_dt, seepage_dt)
  std::size_t cpu_bytes = 0;                ///< estimated host memory of the CPU engine
  std::vector<std::size_t> gpu_bytes;       ///< estimated device memory per GPU (index = gpu id): gpu_plans' totals
  std::size_t host_setup_bytes = 0;         ///< host memory of the GPU engine's set-up (one sampling batch)
  /// Host memory of the GPU engine's run beside the set-up: the bodies' pinned frame buffers, the frame writer's
  /// pieces (one frame at a time), a checkpoint's copy of the particles or its ranges (host_checkpoint_bytes,
  /// host_checkpoint_streamed: some body is streamed), and the whole run:
  /// kHostProgramBytes + the larger of the set-up and (frames + the checkpoint when simulation.checkpoint_every > 0):
  /// the set-up's memory is given back before the first frame.
  std::size_t host_frame_pinned_bytes = 0;
  std::size_t host_frame_writer_bytes = 0;
  std::size_t host_checkpoint_bytes = 0;
  bool host_checkpoint_streamed = false;
  std::size_t host_run_bytes = 0;
  bool checkpoints = false;  ///< simulation.checkpoint_every > 0
  std::vector<std::string> device_notes;    ///< free memory of the devices present, and whether the plan fits
  /// [ms] estimated kGpuRateDevice time per step: kGpuStepOverheadMs, kGpuBodyOverheadMs per body, and every body's
  /// gpu_ms_per_step.
  double gpu_ms_per_step = 0.0;
};

/// The GPU, date and record of --check's GPU time: each law's particle-steps per second at 16M particles and the
/// parts of a step that do not scale with particles [ms], per step (the grid update, dt, the readback) and per body
/// (its G2P2G and partition launches), fitted to the record's small runs (its 16M run checks the sum).
inline constexpr const char* kGpuRateDevice = "H200";
inline constexpr const char* kGpuRateDate = "2026-12-02";
inline constexpr const char* kGpuRateRecord = "docs/benchmarks/2026-12-02-h200-check-rates.md";
inline constexpr double kGpuStepOverheadMs = 0.055;
inline constexpr double kGpuBodyOverheadMs = 0.037;

struct SummaryOptions {
  bool frames = true;  ///< the run writes frames (the GPU keeps each body's frame on the device)
  std::size_t frame_host_bytes = kFrameHostBytes;  ///< --frame-buffer (GpuEngineOptions::frame_host_bytes)
};

/// Host memory of the program and the CUDA runtime besides a scene's data: 0.30 GiB peak measured for a
/// 524,288-particle GPU run on an H200 with CUDA 13 (docs/benchmarks/2026-12-02-h200-host-memory.md).
inline constexpr std::size_t kHostProgramBytes = std::size_t(300) << 20;

/// One body's host memory for frames on the GPU engine [bytes]: its pinned download buffer (kept between frames)
/// and the writer's memory while it writes one of its frames.
struct HostFrameBytes {
  std::size_t pinned = 0, writer = 0;
};
HostFrameBytes host_frame_bytes(std::size_t particles, std::size_t scalar_bytes, int columns, int attributes,
                                const std::string& suffix, bool exterior, std::size_t frame_host_bytes, bool mesh);

/// One body's host memory while the GPU engine takes and writes a checkpoint [bytes]: what the checkpoint keeps
/// until it is written, and what one body's gather takes on top while it is read. `streamed`: the body's copy by ID
/// exceeds frame_host_bytes (not a mesh), so the checkpoint reads it from the device a range of IDs at a time.
struct HostCheckpointBytes {
  std::size_t kept = 0, transient = 0;
  bool streamed = false;
};
HostCheckpointBytes host_checkpoint_bytes(std::size_t particles, std::size_t slots, std::size_t scalar_bytes,
                                          int stored_scalars, std::size_t frame_host_bytes, bool mesh);

/// Counts every body's particles (deterministically, without storing them) and computes the time step and memory
/// estimates.
SceneSummary summarize_scene(const Scene& scene, const SummaryOptions& options = {});

/// Below this many particles (scene_work_particles) one GPU steps a scene faster than 2 or 4: measured on H200s with
/// NVLink (docs/benchmarks/2026-11-28-h200x4-small-scenes.md: the dam break's crossover near 1.6M particles, with
/// 25 % margin). `fbar --gpus=N` runs such a scene on one GPU (cli.cpp; --keep-gpus keeps N).
inline constexpr long long kMultiGpuMinParticles = 2000000;

/// The particles a scene steps, each mesh element counted as 5 (its element pass costs 0.57 ns an element-step against
/// 0.11 ns a particle-step on an H200: docs/benchmarks/2026-11-28-h200x2-fem.md): exact, or at least `cap` once the
/// count reaches it. A body whose lattice has more than 64M candidate points counts as `cap` (counting it would cost
/// more than the answer is worth); a body that cannot be sampled counts as `cap` (the engine reports it).
long long scene_work_particles(const Scene& scene, long long cap);

struct RunOptions {
  bool quiet = false;              ///< no progress lines
  std::ostream* log = nullptr;     ///< progress and failure reports; nullptr = std::cout
  /// The ranks of a decomposed run (comm/transport.h; MPI under mpirun); nullptr or one rank: no decomposition.
  /// Every rank runs the same loop; rank 0 logs.
  comm::Transport* transport = nullptr;
  /// GPU engine: the CUDA device of this rank (-1: the current one), and whether ranks share GPUs (then their
  /// device data moves by peer copies between threads; otherwise through NCCL).
  int gpu = -1;
  bool shared_gpus = false;
  /// GPU ranks: the halo-first G2P2G overlapped with the halo sums (GpuEngineOptions::overlap_halo; --halo-overlap).
  bool halo_overlap = false;
  /// GPU engine: host memory one body's frame or checkpoint download may take before it is streamed [bytes]
  /// (GpuEngineOptions::frame_host_bytes; --frame-buffer).
  std::size_t frame_host_bytes = kFrameHostBytes;
  /// --restart: a checkpoint file (io/checkpoint.h; any rank's file of the set) to continue from, or empty.
  std::string restart{};
};

struct RunResult {
  int exit_code = 0;               ///< 0 success, 2 run-time failure (docs/user_guide.md §1), 128 + signal when stopped by one
  std::string message;             ///< failure report: body, step, time, what happened
  long long steps = 0;
  double end_time = 0.0;           ///< [s]
  int frames_written = -1;         ///< the last frame written (0: the initial state); -1: none
  int stop_signal = 0;             ///< SIGINT / SIGTERM that stopped the run (stop_request.h), or 0
  std::string checkpoint{};        ///< rank 0's file of the last checkpoint written, or empty
  int restarted_from_frame = -1;   ///< --restart: the checkpoint's last frame (the run wrote the frames after it)
  /// The run ended by an exception (run_guarded), which may be this rank's alone; failures of a step and stop
  /// requests are agreed on by every rank.
  bool from_exception = false;
};

/// Runs the scene on the CPU reference engine, writing frames to scene.simulation.save_path; decomposed over the
/// ranks of options.transport when it has several (each rank writes its particles as model[m]_dev[rank]_frame[f]).
RunResult run_cpu(const Scene& scene, const RunOptions& options);

/// Calls run() and turns what it throws into a RunResult: SceneError and std::invalid_argument (the scene asks for
/// what the engine cannot do) give exit code 1, any other exception 2, with the exception's message.
RunResult run_guarded(const std::function<RunResult()>& run);

}  // namespace fbar
