// The GPU engine's public interface (host code may include it): GpuEngine<T> and run_gpu().
//
// Claymore's sparse MLS-MPM on one GPU (mgsp_benchmark.cuh holds the per-device state and the step; the kernels
// are in mgmpm_kernels.cuh). It runs the same physics functions as the CPU reference engine and reports failures
// with the same FailureReport / StepReport types, so tests compare the two engines particle by particle (by ID).
// Precision: GpuEngine<float> (simulation.precision "single"), GpuEngine<double> ("double") or
// GpuEngine<double, float> ("mixed": particle state and transfers in double, grid storage, the shared P2G arena and
// the grid update in single).
#pragma once

#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "engine/engine_common.h"
#include "engine/engine_api.h"
#include "engine/gpu/gpu_architectures.h"
#include "engine/memory_plan.h"
#include "io/checkpoint.h"
#include "physics/grid_fields.h"
#include "physics/sensors.cuh"
#include "scene/scene.h"

namespace fbar {
namespace comm {
class Transport;
class DeviceTransport;
struct SlabPartition;
}  // namespace comm

/// One body's particles in ID order, copied from the device.
template <typename T>
struct ParticleSnapshot {
  std::vector<Vec3<T>> x;   ///< [m]
  std::vector<Vec3<T>> v;   ///< [m/s] G2P velocity of the last step (zero unless velocities are recorded)
  std::vector<Mat3<T>> C;   ///< [1/s] APIC affine matrix of the last step (idem)
  std::vector<T> J;         ///< [-] volume ratio of the stored state
  std::vector<T> jbar;      ///< [-] the volume ratio the stress sees: nodal F-bar's JBar, else J
  std::vector<Mat3<T>> F;   ///< [-] deformation gradient (materials that store F; empty otherwise)
  std::vector<T> logJp;     ///< [-] plastic state (materials that store logJp; empty otherwise)
  std::vector<T> pore_pressure;  ///< [Pa] saturated materials (CoupledUP; empty otherwise)
  std::vector<Mat3<T>> sigma;  ///< [Pa] Cauchy stress of the stored state (with the recorded C for rate terms)
  /// Decomposed runs: present[id] says whether this rank holds particle `id` (the arrays are indexed by ID over the
  /// whole body; absent entries are NaN). Empty: every particle is present.
  std::vector<char> present;
};

/// Accumulated device time per kernel family (CUDA events, when timing is on) [ms].
struct KernelTimes {
  double grid_update_ms = 0.0;  ///< grid update + dt
  double g2p2g_ms = 0.0;        ///< fused G2P2G, all bodies (mesh bodies' element passes included)
  double fem_ms = 0.0;          ///< of g2p2g_ms: the element passes of mesh bodies (kernels/fem_kernels.cuh)
  double partition_ms = 0.0;    ///< footprint activation, scan, src scatter
  double halo_ms = 0.0;         ///< decomposed runs: the halo sums (pack, exchange, add) not hidden behind G2P2G
  double halo_hidden_ms = 0.0;  ///< decomposed runs: the part of the halo sums that overlapped the interior G2P2G
  double migration_ms = 0.0;    ///< decomposed runs: emigrants packed, counts and records exchanged, arrivals placed
  long long steps = 0;          ///< steps timed
};

/// Starting capacities (0: sized from the scene). Both grow at run time; tests start them small to exercise that.
struct GpuEngineOptions {
  int block_capacity = 0;  ///< grid blocks (hash table, grid buffers, per-block partition arrays)
  int bin_capacity = 0;    ///< particle bins per body (at least what the initial upload needs)
  /// Grow the blocks and bins between steps when they fill up (3/4, 9/10), so that a step rarely outgrows them;
  /// false: only when a step outgrew them, inside it (tests of that path).
  bool grow_ahead = true;
  /// Drop the grid blocks no particle uses any more between steps (a moving or spreading body leaves them behind),
  /// once they are 1/8 of those in use: the grid update, the clear and the per-block passes then visit only what
  /// the particles need, and memory stays flat. Results are the same bytes either way; false: the table keeps every
  /// block until the run ends (the benchmark's comparison).
  bool compact_grid = true;
  /// Per body, per particle (ID order) initial velocities [m/s], as CpuEngine::set_velocities gives them (tests,
  /// restarts); a body without an entry, or with an empty one, starts at its scene velocity.
  std::vector<std::vector<Vec3d>> initial_velocities;
  /// Plan and keep every body's output frame on the device (submit_frame); the run loop sets it.
  bool frames = false;
  /// Host memory a frame's download may take per body [bytes]: a frame that needs more (positions, columns and, on
  /// a rank of a decomposed run, its ID directory) is streamed to its file a piece at a time through a pinned
  /// buffer of one piece's positions (or this size if smaller), the device frame held until the writer has written
  /// it (the next capture waits for that). A checkpoint of a body whose copy by ID (stored scalars, v and C) needs
  /// more is read from the device a range of IDs at a time while its file is written (checkpoint()). Tests make it
  /// small.
  std::size_t frame_host_bytes = kFrameHostBytes;
  /// Treat the device as having at most this much free memory [bytes] when checking the plan (0: what it has).
  std::size_t memory_limit = 0;
  /// Particles sampled and uploaded per batch at start (host memory is O(batch)); tests make it small.
  long long sample_batch = kSampleBatchParticles;
  /// A decomposed run (comm/slab_partition.h): this rank's host transport (agreement on the host) and device
  /// transport (halo blocks, migrating particles, the time step). Both or neither; neither: one GPU runs the scene.
  /// Every rank is constructed with the same scene and options and steps in lockstep.
  comm::Transport* ranks = nullptr;
  comm::DeviceTransport* device_ranks = nullptr;
  /// Decomposed runs: G2P2G runs the particle blocks that scatter into a shared grid plane first, then the others
  /// while a second stream sums the shared planes with the neighbours (false: the sums after the whole G2P2G; the
  /// benchmark compares both). The result is the same either way, to the order of the atomic sums. Off by default:
  /// between H100s of one node the sums take 0.03 ms exposed, less than the overlap costs G2P2G (a second launch,
  /// NCCL's kernels beside it; docs/benchmarks/2026-11-27-h100x4-multi-gpu.md). On for slow links between nodes
  /// (fbar --halo-overlap=on).
  bool overlap_halo = false;
  /// Decomposed runs: the particles per body that one migration message to a neighbour holds at first (the
  /// messages grow, on every rank alike, when a step fills more than half; a step that overflows them is repeated).
  /// Tests make it small to run the growth.
  int migrant_capacity = 512;
  /// Decomposed runs: rebalance_if_drifted() chooses the slabs again when the particles per rank drifted apart by
  /// more than this (max / mean - 1) and by 1.5 x the imbalance the last choice left (<= 0: never). The CPU
  /// engine's rule and default.
  double rebalance_threshold = 0.25;
  /// Continue from a checkpoint (io/checkpoint.h) holding every particle in ID order (io::read_checkpoint_set):
  /// positions, velocities, C, state, time and the next dt from it, nothing sampled. The initial P2G then makes the
  /// grid the continuous run had, to the order of its atomic sums. Must outlive the constructor only.
  const io::Checkpoint* restart = nullptr;
  /// A restart on as many ranks as wrote the checkpoint: their slabs (comm::SlabPartition's axis and cuts, ranks + 1
  /// entries) and the imbalance they were chosen with, so that every rank holds the particles it held and writes
  /// the frames it would have written; empty cuts: the slabs are chosen from the restart's positions.
  int restart_slab_axis = 0;
  std::vector<int> restart_slab_cuts;
  double restart_chosen_imbalance = -1.0;
};

template <typename T, typename TG>
class MgspBenchmark;


/// T: particle scalar type (stored state, snapshots, frames); TG: grid scalar type (grid buffers, P2G sums, grid
/// update). GpuEngine<float> is "single", GpuEngine<double> "double", GpuEngine<double, float> "mixed".
template <typename T, typename TG = T>
class GpuEngine {
 public:
  /// Samples every body (geometry.h) and starts the device state on the current CUDA device. Throws
  /// std::invalid_argument for what the GPU engine does not implement, std::runtime_error for CUDA failures.
  explicit GpuEngine(const Scene& scene, const GpuEngineOptions& options = {});
  /// As above with given initial positions [m] per body (tests).
  GpuEngine(const Scene& scene, const std::vector<std::vector<Vec3d>>& positions,
            const GpuEngineOptions& options = {});
  ~GpuEngine();
  GpuEngine(const GpuEngine&) = delete;
  GpuEngine& operator=(const GpuEngine&) = delete;

  StepReport step();                     ///< one step with the CFL time step (next_dt())
  StepReport step(double dt);            ///< one step of exactly dt [s] (reduce_dt may still halve it)
  StepReport advance_to(double t_end);   ///< CFL steps until time() == t_end (the last one shortened)
  /// One CFL step of advance_to(t_end). `t_following`: where the next step will head when this one lands on t_end
  /// (the device fixes the next dt during this step; knowing it spares a rescaled P2G impulse).
  StepReport step_toward(double t_end, double t_following = std::numeric_limits<double>::infinity());

  double time() const;
  long long steps() const;
  double last_dt() const;
  double next_dt() const;
  double max_grid_speed() const;         ///< [m/s] of the last grid update
  void set_log(std::ostream* log);
  /// G2P2G also writes v and C per particle (12 scalars) for snapshots and frames (off: bins only).
  void set_record_velocities(bool on);
  /// Times each kernel family with CUDA events (adds a few microseconds per step).
  void set_kernel_timing(bool on);
  KernelTimes kernel_times() const;
  /// Steps repeated because P2G contributions outgrew the fixed-point bound of the last step (single precision).
  long long p2g_range_repeats() const;
  /// Partitions redone inside a step: the step's particles outgrew the grid blocks' or a body's bins' capacity, the
  /// engine grew it and partitioned again from the particles' new positions (MgspBenchmark::handle_overflow).
  long long partition_redos() const;
  /// Grid compactions so far (GpuEngineOptions::compact_grid) and the blocks they dropped.
  long long grid_compactions() const;
  long long compacted_blocks() const;

  int body_count() const;
  std::size_t particle_count(int body) const;
  std::size_t particle_count() const;
  ParticleSnapshot<T> snapshot(int body) const;
  /// The body's output_attribs (canonical names), as the CPU engine writes them; a decomposed rank's frame holds
  /// its particles in ID order (the ID column, when asked for, says which).
  io::ParticleFrame frame(int body) const;
  /// The next step writes every body's output frame on the device (needs GpuEngineOptions::frames): set it for
  /// the step that lands on a frame time.
  void set_frame_capture(bool on);
  /// Queues the body's frame on `writer`: the frame the last step captured (or, before the first step, the
  /// initial state's) is downloaded on the copy stream into the body's pinned buffer, and the writer thread builds
  /// and writes the file. The step loop waits only while the previous frame's buffer is still being read.
  void submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer);
  double output_wait_seconds() const;      ///< [s] spent waiting in submit_frame for the writer
  /// Grid sensors (as CpuEngine): the sensors a sampling step evaluates; the slot the next steps sample into
  /// (-1: none); this rank's values of slots [0, slots), slot-major (one download).
  void set_grid_sensors(const std::vector<GridSensorSpec>& sensors);
  void set_grid_sample(int slot);
  std::vector<SensorAccum> grid_samples(int slots) const;
  /// Grid fields (as CpuEngine): the fields a sampling step records; the mask of the next steps' fields (0: none);
  /// this rank's nodes of a field's last sample (one download).
  void set_grid_fields(const std::vector<GridFieldSpec>& fields);
  void set_grid_field_sample(unsigned mask);
  GridFieldSample grid_field_sample(int field);
  /// Particle sensors (as CpuEngine): keep_particle_inputs(true) for the steps that may land on a sample time makes
  /// them record v and C when a sensor reads them; sample_particles(slot) reduces the current state.
  void set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors);
  void keep_particle_inputs(bool on);
  void sample_particles(int slot);
  std::vector<SensorAccum> particle_samples(int slots) const;
  /// Trackers (as CpuEngine): the tracked particles of `body` this rank holds, found by ID on the device.
  void set_tracker(int body, const TrackerSet& set);
  void track(int body, std::vector<double>& values, std::vector<double>& present);
  /// Checkpoints (io/checkpoint.h; the run loop's interface): this rank's state, collective on several ranks; ready
  /// when the last step recorded the particles' v and C (keep_checkpoint_inputs(true) before it) or before the
  /// first step. A body above frame_host_bytes comes without its arrays (io::Checkpoint::streamed): write the file
  /// before the next step.
  io::Checkpoint checkpoint() const;
  bool checkpoint_ready() const;
  void keep_checkpoint_inputs(bool on);
  const DeviceMemoryPlan& memory_plan() const;  ///< what the engine planned and allocated at start
  std::size_t peak_device_bytes() const;   ///< most device memory the engine's buffers held so far
  std::string resource_note() const;       ///< device memory now and at its peak, for progress lines

  double particle_mass(int body) const;    ///< [kg] every particle of the body (rho dx^3 / ppc, as CpuEngine)
  double particle_volume(int body) const;  ///< [m^3] reference volume V0 of every particle of the body
  /// [kg] each particle's mass by ID (a mesh body's lumped vertex masses; particle_mass() for every particle of
  /// another body), as CpuEngine::masses gives them.
  std::vector<double> particle_masses(int body) const;
  double total_mass() const;             ///< [kg] particles x per-body mass
  double elastic_energy() const;         ///< [J] sum V0 psi(state), in double on the host (as CpuEngine)
  double grid_mass() const;              ///< [kg] sum of node masses of the current grid (P2G of this state)
  std::size_t active_grid_blocks() const;
  /// The grid blocks holding particles of some body (a reduction on the device and a synchronisation: diagnostics
  /// and benchmarks, not every step).
  std::size_t particle_blocks() const;
  std::size_t device_bytes() const;      ///< device memory held by the engine's buffers
  /// Device memory of the grid's channel sets (engine/grid_channels.h) and the block capacity they are sized for.
  std::size_t grid_channel_bytes() const;
  int grid_block_capacity() const;

  // Decomposed runs (GpuEngineOptions::ranks); one rank otherwise.
  int rank() const;
  int ranks() const;
  const comm::SlabPartition& slabs() const;  ///< the particle-block planes of every rank
  long long migrated() const;               ///< particles this rank sent to others so far
  /// Steps repeated because some rank's migrants overflowed the migration messages (GpuEngineOptions).
  long long migration_repeats() const;
  std::size_t halo_blocks() const;          ///< grid blocks this rank shares with its neighbours now
  /// Particle blocks (all bodies) the next G2P2G runs first because they scatter into a shared plane.
  std::size_t halo_particle_blocks() const;
  /// Particles per rank after the last step, max / mean - 1 (the same on every rank; 0 on one rank).
  double imbalance() const;
  /// The particles drifted apart beyond GpuEngineOptions::rebalance_threshold since the slabs were last chosen
  /// (the same answer on every rank). The run loop then keeps the checkpoint inputs on the step landing on the next
  /// frame and calls rebalance_if_drifted() after that frame's output.
  bool rebalance_due() const;
  /// Collective. When rebalance_due() and checkpoint_ready(): the slabs are chosen again from every particle and
  /// the particles go to their new ranks, through the restart path (every rank's checkpoint() gathered in host
  /// memory, the device state rebuilt from it: about 150 bytes per particle of the whole scene on every rank, for
  /// as long as it takes). Sensors, trackers and settings carry over. Frames submitted before must have been
  /// written (io::AsyncWriter::flush). Returns whether the slabs changed.
  bool rebalance_if_drifted();
  int rebalances() const;                   ///< times rebalance_if_drifted() chose new slabs

 private:
  void replay_settings();
  std::unique_ptr<MgspBenchmark<T, TG>> impl_;
  // What a rebalance needs to build the engine again, and what it carries over.
  const Scene* scene_ = nullptr;  ///< the caller's (outlives the engine, as for MgspBenchmark's construction)
  GpuEngineOptions options_;      ///< without initial velocities and restart (used at construction only)
  std::ostream* log_ = nullptr;
  bool record_velocities_ = false, timing_ = false, frame_capture_ = false, particle_inputs_ = false,
       checkpoint_inputs_ = false;
  int grid_sample_ = -1;
  std::vector<GridSensorSpec> grid_sensors_;
  unsigned grid_field_mask_ = 0;
  std::vector<GridFieldSpec> grid_fields_;
  std::vector<ParticleSensorSpec> particle_sensors_;
  std::vector<std::pair<int, TrackerSet>> trackers_;
  KernelTimes earlier_times_;          ///< of the engines before the last rebalance
  long long earlier_migrated_ = 0, earlier_repeats_ = 0, earlier_migration_repeats_ = 0, earlier_redos_ = 0;
  long long earlier_compactions_ = 0, earlier_compacted_ = 0;
  double earlier_wait_s_ = 0.0;
  std::size_t earlier_peak_ = 0;
  double chosen_imbalance_ = 0.0;     ///< right after the slabs were last chosen
  int rebalances_ = 0;
};

extern template class GpuEngine<float, float>;
extern template class GpuEngine<double, double>;
extern template class GpuEngine<double, float>;
/// Mixed precision (simulation.precision "mixed"): particles in double, the grid in single (ClaymoreUW's choice).
using MixedGpuEngine = GpuEngine<double, float>;

/// Runs the scene on the GPU engine (device 0), writing frames like run_cpu. Exit code 1: scene not supported;
/// 2: run-time failure (CFL, NaN, left domain, CUDA error).
RunResult run_gpu(const Scene& scene, const RunOptions& options);
/// run_gpu's run at one precision (gpu_engine_impl.cuh; compiled per precision in instances/driver_*.cu).
template <typename T, typename TG>
RunResult run_gpu_as(const Scene& scene, const RunOptions& options, std::ostream& log);
extern template RunResult run_gpu_as<float, float>(const Scene&, const RunOptions&, std::ostream&);
extern template RunResult run_gpu_as<double, double>(const Scene&, const RunOptions&, std::ostream&);
extern template RunResult run_gpu_as<double, float>(const Scene&, const RunOptions&, std::ostream&);

/// Whether this build's GPU engine runs on CUDA device `device` (gpu_check.cu): the architectures compiled in
/// (FBAR_CUDA_ARCHITECTURES) against its compute capability (gpu_code_fit), confirmed by loading one of the
/// library's kernels there. The message (why not, or the JIT note) starts with "GPU d (name, compute capability
/// X.Y)". Leaves the current device as it was.
GpuCodeFit gpu_engine_fit(int device);

}  // namespace fbar
