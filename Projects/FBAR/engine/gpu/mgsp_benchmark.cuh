// The GPU simulation driver (ClaymoreUW's mgsp_benchmark): all state of one device and the step, no globals. This
// file holds the state and the members' declarations; the members are defined by concern in the parts:
// device_bodies.cuh (what every body shares) and, from gpu_engine_impl.cuh: engine_setup.cuh (construction),
// engine_step.cuh (the step below), sensors_checkpoints.cuh, frame_output.cuh, and decomposition/ (slabs, halo, shared
// blocks of placed bodies, migration, rebalancing); body.cuh and body_factory.cuh hold the material's Body<M>. The
// templates are compiled in instances/ (docs/developer_guide.md "The GPU engine"). docs/developer_guide.md
// "Architecture" walks through one step.
//
// State between steps n-1 and n (cur, gc: which of the double buffers is current):
//   bins[cur]          particles of state n (storage order), per body
//   layout(cur)        their grouping by particle block (src: layout slot -> storage slot), per body
//   grid[gc]           P2G of state n (mass, momentum with the internal-force impulse of dt_p2g_)
//   table              every block any layout or grid uses (insert-only within a step; between steps the grid
//                      compaction drops the blocks no particle uses any more and renumbers the rest: compact_grid)
// Step n (dt):
//   0. dt != dt_p2g_ (a repeated step, or step(dt) with a new dt): rescale_impulse adds (dt - dt_p2g_) x the
//      stress impulse to grid[gc] (exact for rate-independent stress; see partition_kernels.cuh)
//   1. grid update: velocity = grid[gc] / m + dt g, boundaries -> velocity buffer; max |v|. Saturated bodies
//      first sum their seepage channels from bins[cur] (seepage_sums), which the update turns into each node's
//      head, inflow and pore pressure for G2P (physics/seepage.cuh)
//   2. compute_next_dt: dt_{n+1} on the device (so the P2G impulse uses it without a host round trip); the JFluid
//      wave speed in it is the one of state n (the CPU engine uses state n+1's: a one-step lag, documented)
//   3. per body g2p2g: bins[cur] -> bins[1-cur] in layout(cur) order, P2G into grid[1-gc], next blocks and ranks
//   4. per body partition: footprint activation, scan, src scatter -> layout(1-cur)
//   5. one small copy of the step statistics to pinned memory and one stream synchronisation: failures, overflow,
//      dt_{n+1}, block and bin counts. A failed step leaves cur/gc untouched (on_failure reduce_dt repeats it with
//      dt/2 from the same buffers); an overflow grows the capacities and redoes step 4 from the new positions.
// Decomposed (GpuEngineOptions::ranks; comm/slab_partition.h): each rank holds the particles of its slab of
// particle-block planes and the grid blocks they touch (a body placed with bodies[].gpu: all of it on its rank, and
// the halo is then every block several ranks hold, summed in rank order: rebuild_shared, shared_exchange); step n adds
//   0'. after a rescale: a delta exchange of the halo blocks of grid[gc]
//   2'. dt_{n+1} from the largest grid speed and wave speeds over ranks (gathered side by side, one
//       DeviceTransport::allreduce_max on the device, before compute_next_dt): every rank computes the same dt
//       (min over ranks of each rank's dt would not do: the fastest node and the stiffest particle may sit on
//       different ranks)
//   1'. saturated bodies: the seepage sums' halo exchange before the grid update
//   3'. F-bar: the cell sums' halo exchange between fbar_cell_sums and G2P2G; after G2P2G: the halo exchange of
//       grid[1 - gc] (and the transported momentum), then migration: G2P2G marked the particles whose next block a
//       neighbour owns (kEmigrant); their records go to the neighbour, which appends the ones it receives behind
//       its own slots and records their (block, rank) before the partition. Without the halo-first overlap (the
//       default) the halo and migration messages travel in one exchange.
//   5'. agreement on the host: failures, repeats and the grid speed over ranks (so every rank takes the same
//       decision), and a rebuild of the halo lists when a rank has new blocks in a halo plane (placed bodies: any
//       new block).
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <cuda_runtime.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "MnBase/Math/bspline.h"
#include "MnSystem/Cuda/device_array.cuh"
#include "MnSystem/Cuda/device_query.h"
#include "comm/device_transport.h"
#include "comm/placement.h"
#include "comm/slab_partition.h"
#include "scene/attributes.h"
#include "physics/boundary.cuh"
#include "physics/constitutive_models.cuh"
#include "engine/hydrostatic.h"
#include "engine/engine_common.h"
#include "geometry/geometry.h"
#include "engine/gpu/gpu_engine.h"
#include "engine/gpu/grid_channels.cuh"
#include "engine/gpu/decomposition/decomposition_state.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/sensor_state.cuh"
#include "engine/memory_plan.h"
#include "engine/gpu/mgmpm_kernels.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "io/particle_frame.h"
#include "io/sensor_recorder.h"
#include "engine/gpu/partition_domain.h"
#include "engine/run_constants.h"
#include "engine/mesh_elements.h"
#include "physics/time_step.cuh"
#include "scene/scene_parse.h"

namespace fbar {

namespace mgsp_detail {

inline std::string format_g(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace mgsp_detail

/// Which blocks of a layout one G2P2G launch runs: all (one GPU), or the halo particle blocks / the others of a
/// decomposed rank's list (partition_domain.h), so that the halo exchange overlaps the second launch.
enum class G2P2GPass { All, Halo, Interior };

/// The device state of one GPU and its step (the engine behind GpuEngine<T, TG>). T: particle scalar type (stored
/// state, transfers, material update); TG: grid scalar type (grid buffers, the shared P2G arena, the grid update).
/// single: <float, float>; double: <double, double>; mixed: <double, float> (ClaymoreUW's choice).
template <typename T, typename TG>
class MgspBenchmark {
 public:
  /// positions: per body, given initial positions [m] (tests); nullptr: every body is sampled from the scene in
  /// batches (geometry.h BodySampler), uploaded batch by batch.
  MgspBenchmark(const Scene& scene, const std::vector<std::vector<Vec3d>>* positions,
                const GpuEngineOptions& options = {});
  ~MgspBenchmark();
  MgspBenchmark(const MgspBenchmark&) = delete;
  MgspBenchmark& operator=(const MgspBenchmark&) = delete;

  /// `following`: the target of the step after this one when this one reaches `target` (NaN: `target` itself).
  StepReport step_impl(double dt, bool cfl_dt, double target, double following = std::numeric_limits<double>::quiet_NaN());
  StepReport advance_to(double t_end);
  /// One CFL step, shortened to land on t_end when it would pass it (the device clamps the next dt likewise).
  StepReport step_toward(double t_end, double t_following = std::numeric_limits<double>::infinity());
  double next_dt() const { return next_dt_ * (retry_.scale / dt_scale_at_compute_); }

  // --- state queries
  double time() const { return time_; }
  long long steps() const { return steps_; }
  double last_dt() const { return last_dt_; }
  double max_grid_speed() const { return max_grid_speed_; }
  void set_log(std::ostream* log) { log_ = log; }
  void set_record_velocities(bool on);
  /// The next step writes every body's output frame on the device (GpuEngineOptions::frames).
  void set_frame_capture(bool on) { capture_next_ = on; }
  /// Seconds the step loop waited for the writer thread to release a frame's host buffer (output slower than the
  /// simulation).
  double output_wait_seconds() const { return output_wait_s_; }
  const DeviceMemoryPlan& memory_plan() const { return plan_; }
  std::size_t peak_device_bytes() const { return peak_bytes_; }
  void set_kernel_timing(bool on) { timing_ = on; }
  KernelTimes kernel_times() const { return times_; }
  /// Grid sensors (physics/sensors.cuh): evaluated after the grid update of a step that samples (set_grid_sample),
  /// into a device slot; grid_samples() downloads the slots (one copy per flush, not per sample).
  void set_grid_sensors(const std::vector<GridSensorSpec>& sensors);
  void set_grid_sample(int slot);
  std::vector<SensorAccum> grid_samples(int slots) const;
  /// Grid fields (physics/grid_fields.h): recorded after the grid update of a step whose mask has them
  /// (set_grid_field_sample), into one device buffer per field; grid_field_sample() downloads one (synchronously).
  void set_grid_fields(const std::vector<GridFieldSpec>& fields);
  void set_grid_field_sample(unsigned mask) { sensors_.fields.mask = mask; }
  GridFieldSample grid_field_sample(int field);
  /// The F-bar sums allocated for the nodes' volume (Volume and JBar sensors and fields) and their quantum.
  void ensure_node_volume();
  /// Particle sensors: sample_particles() reduces the current state (v and C from the step that landed here, which
  /// keep_particle_inputs(true) made record them, when a sensor reads them) into a device slot.
  void set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors);
  void keep_particle_inputs(bool on);
  void sample_particles(int slot);
  /// Checkpoints (io/checkpoint.h): this rank's particles (with v and C of the last step, which must have recorded
  /// them: keep_checkpoint_inputs(true) before it, or the initial state) and the step state. stream: a body whose
  /// copy by ID would exceed GpuEngineOptions::frame_host_bytes (not a mesh) is left on the device
  /// (io::Checkpoint::streamed): write_checkpoint reads it a range of IDs at a time, before the next step.
  io::Checkpoint checkpoint(bool stream = false) const;
  bool checkpoint_ready() const { return aux_valid_ || steps_ == 0; }
  void keep_checkpoint_inputs(bool on);
  std::vector<SensorAccum> particle_samples(int slots) const;
  /// Trackers (as CpuEngine): the particles of `body` with the tracked IDs, found on the device by ID.
  void set_tracker(int body, const TrackerSet& set);
  void track(int body, std::vector<double>& values, std::vector<double>& present);
  long long p2g_range_repeats() const { return p2g_range_repeats_; }
  long long partition_redos() const { return partition_redos_; }
  long long grid_compactions() const { return compactions_; }
  long long compacted_blocks() const { return compacted_blocks_; }
  int body_count() const { return static_cast<int>(bodies_.size()); }
  std::size_t particle_count(int body) const { return static_cast<std::size_t>(body_at(body).particles); }
  std::size_t particle_count() const {
    std::size_t n = 0;
    for (const auto& b : bodies_) n += static_cast<std::size_t>(b->particles);
    return n;
  }
  ParticleSnapshot<T> snapshot(int body) const;
  io::ParticleFrame frame(int body) const;
  void submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer);
  double particle_mass(int body) const { return static_cast<double>(body_at(body).mass); }
  double particle_volume(int body) const { return static_cast<double>(body_at(body).volume); }
  std::vector<double> particle_masses(int body) const {
    const BodyBase& b = body_at(body);
    if (b.mesh) return std::vector<double>(b.mesh->mass.begin(), b.mesh->mass.end());
    return std::vector<double>(static_cast<std::size_t>(b.global_particles), static_cast<double>(b.mass));
  }
  double total_mass() const;
  double elastic_energy() const;
  double grid_mass() const;
  std::size_t active_grid_blocks() const { return static_cast<std::size_t>(block_count_); }
  std::size_t particle_blocks() const;  ///< table blocks holding particles of some body (a device reduction)
  std::size_t grid_channel_bytes() const { return channels_.bytes(); }
  int grid_block_capacity() const { return block_capacity_; }
  std::size_t device_bytes() const;
  int rank() const { return dec_.host ? dec_.host->rank() : 0; }
  int ranks() const { return dec_.host ? dec_.host->size() : 1; }
  const comm::SlabPartition& slabs() const { return dec_.slabs; }
  /// Particles per rank after the last step (or the start), max / mean - 1; the same on every rank (0: one rank).
  double imbalance() const {
    if (!decomposed()) return 0.0;
    double total = 0.0;
    for (const auto& b : bodies_) total += static_cast<double>(b->global_particles);
    const double mean = total / ranks();
    return mean > 0.0 ? dec_.most_rank_particles / mean - 1.0 : 0.0;
  }
  /// Waits until the writer thread has built every frame submitted so far (their host buffers are free).
  /// Rebalancing (decomposition/rebalance.cuh): every rank's particles merged in ID order on every rank (collective;
  /// the restart path's input), and whether the slabs those particles ask for differ from the current ones.
  io::Checkpoint merged_checkpoint() const;
  bool slabs_change_for(const io::Checkpoint& merged) const;
  void wait_for_frames() const {
    for (const auto& b : bodies_) {
      if (!b->frame_slot) continue;
      std::unique_lock<std::mutex> lock(b->frame_slot->mutex);
      b->frame_slot->released.wait(lock, [&] { return !b->frame_slot->busy; });
    }
  }
  long long migrated() const { return dec_.migrated; }
  long long migration_repeats() const { return dec_.migration_repeats; }
  std::size_t halo_blocks() const {
    return dec_.placed ? dec_.union_blocks.size() : dec_.halo[0].keys.size() + dec_.halo[1].keys.size();
  }
  std::size_t halo_particle_blocks() const {
    std::size_t n = 0;
    for (const auto& b : bodies_) n += static_cast<std::size_t>(b->halo_blocks[cur_]);
    return n;
  }

 private:
  // ---------------------------------------------------------------- bodies (host-side polymorphism only)
  /// A body on the device (device_bodies.cuh): BodyBase holds what every material shares, Body<M> its bins and
  /// the launches of its material's kernels (host-side polymorphism only).
  struct BodyBase;
  template <typename M>
  struct Body;

  /// sum_e V0_e psi(F_e) of a mesh body on the rank holding it, from the element pass's gradients [J].
  double mesh_energy(const BodyBase& b) const;
  BodyBase& body_at(int b) const {
    if (b < 0 || b >= body_count()) throw std::out_of_range("GpuEngine: no body " + std::to_string(b));
    return *bodies_[b];
  }

  // ---------------------------------------------------------------- step pieces
  void reset_stats(bool partition_only);
  /// Footprint, scan, finalize, src scatter for every body. dest_complete: this try's G2P2G wrote the dest of every
  /// slot of layout(cur) (false when dest was rewritten from positions for the valid slots alone).
  void partition_after_g2p2g(bool dest_complete = true);
  void read_stats();                     ///< the one small copy + synchronisation of a step
  bool handle_overflow();                ///< grows what overflowed and redoes the partition; true if it did
  void grow_blocks(int needed);
  void grow_blocks_to(int capacity);
  /// The error of a growth the device could not hold: step, time, what grew, memory held, what would help.
  cuda::OutOfMemory growth_failure(const std::string& what, const cuda::OutOfMemory& e) const;
  void grow_bins_to(BodyBase& b, int keep, int capacity);
  void grow_bins(BodyBase& b, int layout_keep, int needed);
  /// Decomposed runs, in the migration: room for `needed` bins in bins[1 - cur] while keeping what this step's G2P2G
  /// wrote there (its first `written` slots, their destinations and recorded v and C) and layout(cur).
  void grow_for_arrivals(BodyBase& b, int written, long long needed);
  void ensure_aux();
  /// At a commit (GpuEngineOptions::compact_grid): compact_grid() once the table holds 1/8 more blocks than the last
  /// check found in use.
  void maybe_compact_grid();
  /// Drops the table blocks that neither a particle block of layout(cur) nor its 2x2x2 arena nor a halo list uses
  /// (blocks a moving or spreading body left: the grid update, the clear and the per-block passes would visit them
  /// every step), when that is at least 1/16 of those kept; the kept ones are renumbered in the order of their keys,
  /// and grid[gc] (with the transported momentum), every layout(cur), the arena caches and the halo lists move with
  /// them. Results do not change (the sums are order-free). True when it compacted.
  bool compact_grid();
  void update_record();
  /// A restart: every body's mass, volume, state and C from the checkpoint (positions and velocities came in as
  /// the constructor's positions and GpuEngineOptions::initial_velocities); time and CFL inputs.
  void restore_bodies(const io::Checkpoint& cp);  ///< record_ from the user's, the sensors' and the checkpoints' requests
  /// Sensor sample slots: at least `need` entries, the old ones kept.
  void grow_samples(cuda::DeviceArray<SensorAccum>& samples, std::size_t need);
  void ensure_sensor_partials();
  /// The first n sensor sample values, on the host (one copy and a stream sync).
  std::vector<SensorAccum> download_samples(const cuda::DeviceArray<SensorAccum>& samples, std::size_t n) const;
  void allocate_frames();
  /// submit_frame's parts (frame_output.cuh).
  void wait_for_frame_slot(BodyBase& b, io::AsyncWriter& writer);
  /// Until the writer no longer reads body b's device frame (a streamed frame); the wait counts as output wait.
  void wait_for_device_frame(BodyBase& b);
  void submit_bgeo_records(BodyBase& b, const std::filesystem::path& path, io::AsyncWriter& writer, std::size_t n,
                           std::size_t words, bool by_directory);
  /// Decomposed runs, before a capture: frame buffers for the rank's particles, and the ID directory of layout(cur).
  void prepare_capture(BodyBase& b);
  /// Construction (engine_setup.cuh): body b from the scene (returns its largest initial speed); the memory plan,
  /// refused before anything is allocated when it does not fit; buffers, upload, the initial P2G and partition.
  double add_body(int b, const std::vector<std::vector<Vec3d>>* positions, ParticleSeeds& seed);
  /// The Body<M> of a scene material (body_factory.cuh, compiled with the law's kernels in instances/bodies_slot_*.cu;
  /// nothing for a NoLaw placeholder).
  template <typename M>
  std::unique_ptr<BodyBase> new_body(const MaterialSpec& mat, const HydrostaticProfile& hydrostatic,
                                     const Aabb& geometry_bounds) const;
  template <typename M>
  std::unique_ptr<BodyBase> new_law_body(const MaterialSpec& mat, const HydrostaticProfile& hydrostatic,
                                         const Aabb& geometry_bounds) const;
  void add_mesh(BodyBase& body);
  void plan_memory();
  void initialize(const std::vector<std::vector<Vec3d>>* positions);
  void allocate_device_state(const std::vector<std::vector<Vec3d>>* positions);
  void partition_upload();
  void initial_p2g();
  /// compute_next_dt with the next grid's quanta, its inputs reduced over the ranks first (engine_step.cuh).
  void launch_dt(DtParams& dp);
  void upload_sampled(BodyBase& body);
  std::vector<FailureReport> failures_of_try(double dt) const;
  /// The phases of a try (engine_step.cuh; steps 0-3 of the header).
  void begin_try(double dt);
  void update_grid(double dt);
  void launch_next_dt(double dt, bool cfl_dt, double target, double following);
  void g2p2g_step(double dt);
  void add_kernel_times();
  void commit(double dt);
  /// Before a step: bins[1 - cur] (the G2P2G target) holds layout(cur); bins grown with headroom (after commit/init).
  void ensure_step_capacity();
  void event_record(int i) {
    if (timing_) FBAR_CUDA_CHECK(cudaEventRecord(events_[i], stream_));
  }
  std::vector<T> gather_host(int body, cudaStream_t s) const;
  /// A streamed checkpoint (sensors_checkpoints.cuh): IDs per range, and body b's particles with IDs first ..
  /// first + count - 1 into `host` (count x (stored scalars + kAuxScalars)) and which of them this rank holds into
  /// held_host (the ID, or -1), through device buffers of a range; on copy_stream_.
  struct CheckpointRange;
  int checkpoint_range_ids(const BodyBase& b) const;
  void gather_range(const BodyBase& b, CheckpointRange& r, int first, int count) const;
  /// Body b's checkpoint without its arrays, and the source of its datasets (io::CheckpointPieces); coords: the
  /// table's block coordinates of the current grid (p2g_valid_).
  io::CheckpointBody streamed_checkpoint_body(const BodyBase& b, double p2g_bound, bool initial,
                                              std::shared_ptr<const std::vector<int>> coords,
                                              io::CheckpointPieces& pieces) const;

  // ---------------------------------------------------------------- decomposition (GpuEngineOptions::ranks)
  bool decomposed() const { return dec_.device != nullptr; }
  /// Chooses the slabs from every body's counts (the same on every rank: each counted the whole scene) and keeps
  /// this rank's part of each count.
  void choose_slabs(const std::vector<std::vector<Vec3d>>* positions);
  /// Whether this rank holds body b's particle at x: a placed body's rank holds all of it (comm/placement.h); else
  /// the slab of x's particle block (the device's arithmetic: x in T).
  bool owns(int body, const Vec3d& x) const;
  /// A restart's recorded block of each particle of body b (3 per ID: io::CheckpointBody::p2g_block), or nullptr
  /// when the checkpoint has none (the restart groups by position). Only during construction (options_.restart).
  const std::int32_t* restart_blocks_of(int body) const;
  /// Whether this rank takes particle p (at x) of a restart's positions: the owner of its recorded block, else
  /// owns(body, x).
  bool holds_at_restart(int body, std::size_t p, const Vec3d& x) const;
  /// Decomposed restarts by recorded blocks: migration messages large enough for the initial P2G's (collective).
  void size_restart_migration(const std::vector<std::vector<Vec3d>>& positions);
  /// The particle blocks body b keeps on this rank: a placed body all of them (it never migrates), else the slab.
  SlabBounds slab_of(int body) const {
    return dec_.homes.empty() || dec_.homes[static_cast<std::size_t>(body)] < 0 ? dec_.slab : SlabBounds{};
  }
  /// Placed bodies: the lists of blocks shared with each rank, from every rank's new table keys (collective; the
  /// counterpart of rebuild_halo). A block that a rank has just created takes the sums of grid[summed_grid] from
  /// the lowest rank that held it before (when summed_grid >= 0), so every holder has the same values.
  void rebuild_shared(int summed_grid, const std::vector<unsigned long long>& fresh);
  bool index_shared_lists(const std::vector<bool>& changed);
  void sync_new_shared_blocks(int summed_grid, const std::vector<std::vector<unsigned long long>>& sync_out,
                              const std::vector<std::vector<unsigned long long>>& sync_in);
  /// Placed bodies: halo_exchange over the shared lists, every holder's contribution added in rank order.
  using BlockBuffers = std::vector<HaloBuffer>;
  void shared_exchange(const BlockBuffers& buffers, int grid, bool delta,
                       cudaStream_t stream);
  /// Placed bodies: dec_.not_counted from the lists (a block shared with a lower rank counts there).
  void mark_not_counted();
  /// Sums the listed block buffers' halo blocks with the neighbours (data, bytes per block). grid >= 0: the first
  /// buffer is grid_sums(grid), whose summed halo is kept for a later delta exchange; delta: add (mine + theirs) - saved.
  /// On `stream` (nullptr: the compute stream).
  void halo_exchange(const BlockBuffers& buffers, int grid, bool delta = false,
                     cudaStream_t stream = nullptr);
  /// halo_exchange in two halves (neighbour planes only), so that one exchange can carry other messages too: the
  /// packed halo messages, then, after the exchange, the sums.
  std::vector<comm::DeviceTransport::Message> pack_halo_messages(const BlockBuffers& buffers, cudaStream_t stream);
  void add_halo_messages(const BlockBuffers& buffers, int grid, bool delta, cudaStream_t stream);
  /// Copy `copy` of grid channel set S as a halo buffer (a fixed-point set's words are summed as integers).
  template <GridSet S>
  HaloBuffer halo_of(int copy = 0) const {
    const auto& buffer = channels_.template get<S>(copy);
    return HaloBuffer{buffer.data(), buffer.kBlockBytes, grid_set(S).storage == GridStorage::FixedSum};
  }
  /// grid[g]'s fixed-point words as a halo buffer.
  HaloBuffer grid_halo(int g) const { return halo_of<GridSet::Sums>(g); }
  /// The quanta of grid[g]'s sums (device).
  GridQuantum* quantum(int g) const { return quantum_d_.get() + g; }
  /// The buffers a step's halo sums: copy g of each halo-summed AcrossSteps channel set (grid[g] first and, with
  /// ASFLIP, the transported momentum).
  BlockBuffers step_halo_buffers(int g) const {
    BlockBuffers out;
    channels_.each_step_halo(g, [&](const GridSetDecl&, std::byte* data, std::size_t block_bytes) {
      out.push_back(HaloBuffer{data, block_bytes, true});
    });
    return out;
  }
  /// Step 3 of a decomposed rank: G2P2G of the halo particle blocks, then of the others on the compute stream while
  /// the halo stream sums grid[1 - gc] (and the transported momentum) with the neighbours; the compute stream then
  /// waits for the sums (options_.overlap_halo; otherwise G2P2G and the sums one after the other).
  void g2p2g_and_halo(T dt);
  /// Lists layout `l` of body b for the halo-first G2P2G (counters: 2 device ints, zeroed here).
  void list_blocks(BodyBase& b, int l, int* counters);
  /// total_bins and the listed block counts of layout l from the step's statistics.
  void take_layout_stats(BodyBase& b, int l) {
    const BodyStepStats& s = body_stats_[b.index];
    b.total_bins[l] = s.total_bins;
    b.halo_blocks[l] = s.halo_blocks;
    b.interior_blocks[l] = s.interior_blocks;
  }
  /// After the partition: the table blocks [dec_.halo_scanned, count) in a halo plane (keys and counts into stats).
  void collect_halo();
  /// Collective: every rank's new halo blocks go to its neighbours; both sides then hold (and list, sorted) the
  /// union of the plane's blocks. summed_grid: the grid holding summed P2G values (saved for delta exchanges), or
  /// -1 before the first P2G.
  void rebuild_halo(int summed_grid);
  /// Collective, after G2P2G and the halo sums: emigrants out, immigrants in (behind the G2P2G's slots).
  void migrate_particles();
  /// migrate_particles in two halves: the emigrants packed (the messages to send; msg: their layout), then, after
  /// the exchange, the immigrants appended.
  std::vector<comm::DeviceTransport::Message> pack_migrant_messages(MigrantMessage& msg);
  void unpack_migrant_messages(const MigrantMessage& msg);
  /// After read_stats: each body's particles after the migration, from the counts the step's readback brought, and
  /// dec_.migrant_most, this rank's largest count (agree_on_try makes it every rank's; above dec_.migrant_capacity a message
  /// overflowed).
  void settle_migration();
  /// Decomposed runs, before a G2P2G: each body's emigrant list holds 2 x dec_.migrant_capacity slots.
  void ensure_emigrant_lists();
  /// Collective, after read_stats and settle_migration: failure counts, first IDs, repeats, grid speed, the most
  /// particles and migrants of a rank and new halo blocks over ranks, in one collective.
  void agree_on_try();

  static constexpr Precision kPrecision = !std::is_same_v<T, TG>      ? Precision::Mixed
                                           : std::is_same_v<T, double> ? Precision::Double
                                                                       : Precision::Single;
  Scene scene_;
  GpuEngineOptions options_;
  DeviceMemoryPlan plan_;            ///< what the engine allocated at start (memory_plan.h)
  std::vector<SampleCount> counts_;  ///< per body: particles per particle block at start (released after start)
  std::size_t peak_bytes_ = 0;       ///< most device memory the engine's buffers held
  RunConstants<T> k_;    ///< dx, gravity, domain, default dt, boundaries (from the scene): particle side
  RunConstants<TG> kg_;  ///< the same in the grid scalar type: the grid update
  std::vector<std::unique_ptr<BodyBase>> bodies_;

  cudaStream_t stream_ = nullptr;       ///< compute stream
  cudaStream_t copy_stream_ = nullptr;  ///< frame downloads
  cudaEvent_t events_[6] = {};  ///< step phases (kernel timing): grid | dt + G2P2G | halo | migration | partition
  BlockHashTable table_;
  /// The grid's channel sets (engine/grid_channels.h, grid_channels.cuh): P2G sums (double-buffered: grid_sums(gc_)
  /// is the committed step's), velocity, ASFLIP's transported momentum (double-buffered like the sums) and v^n,
  /// F-bar's cell sums, the seepage channels of saturated bodies (summed from the particles at the start of every
  /// try into pore_sums(), then the grid update's h_i, r_i and p_i in pore_values(): kernels/seepage_kernels.cuh).
  GridChannels<TG> channels_;
  GridBuffer<TG>& grid_sums(int g) { return channels_.template get<GridSet::Sums>(g); }
  const GridBuffer<TG>& grid_sums(int g) const { return channels_.template get<GridSet::Sums>(g); }
  GridVelocityBuffer<TG>& grid_velocity() { return channels_.template get<GridSet::Velocity>(); }
  FbarSumBuffer<TG>& fbar_sums() { return channels_.template get<GridSet::FbarSums>(); }
  GridPoreBuffer<TG>& pore_values() { return channels_.template get<GridSet::PoreValues>(); }
  PoreSumBuffer<TG>& pore_sums() { return channels_.template get<GridSet::PoreSums>(); }
  TransportedBuffer<TG>& transported(int g) { return channels_.template get<GridSet::Transported>(g); }
  const TransportedBuffer<TG>& transported(int g) const { return channels_.template get<GridSet::Transported>(g); }
  GridVelocityBuffer<TG>& asflip_velocity() { return channels_.template get<GridSet::OldVelocity>(); }
  cuda::DeviceArray<unsigned long long> pore_bound_d_;  ///< (channel) bits of B_c (kernels/seepage_kernels.cuh)
  bool asflip_ = false;
  bool fbar_ = false;
  bool pore_ = false;  ///< some body is saturated (CoupledUP): the grid carries the seepage channels
  int block_capacity_ = 0;
  int block_count_ = 0;                 ///< table blocks after the last committed partition
  cuda::DeviceArray<std::byte> stats_bytes_;
  StepStats* stats_d_ = nullptr;
  BodyStepStats* body_stats_d_ = nullptr;
  cuda::PinnedBytes stats_h_;
  StepStats* stats_ = nullptr;          ///< pinned mirror
  BodyStepStats* body_stats_ = nullptr;
  cuda::DeviceArray<unsigned long long> wave_d_;  ///< (2, body) wave-speed bits: current / being reduced
  int wave_cur_ = 0;
  /// (2, body) bits of the fixed-point P2G momentum bound: the one in use / the one measured by this try.
  cuda::DeviceArray<unsigned long long> p2g_bound_d_;
  int bound_cur_ = 0;
  /// (grid) the quanta of grid_sums(g) and transported(g) (compute_next_dt writes those of the grid a P2G sums into).
  cuda::DeviceArray<GridQuantum> quantum_d_;
  double mass_bound_ = 0.0;  ///< [kg] the largest particle (vertex) mass of any body: the mass quantum's scale
  bool measuring_bound_ = false;  ///< the initial P2G's first pass (G2P2GParams::bound_only)
  cuda::DeviceArray<std::byte> scan_temp_;
  std::size_t scan_temp_bytes_ = 0;
  cuda::DeviceArray<int> missing_d_;
  SensorState<T, TG> sensors_;             ///< sensors and trackers on the device (sensors_checkpoints.cuh)
  bool record_user_ = false;              ///< set_record_velocities
  bool sensor_keep_ = false;              ///< keep_particle_inputs: this step records v and C for sensors
  bool checkpoint_keep_ = false;          ///< keep_checkpoint_inputs: this step records v and C for a checkpoint

  int cur_ = 0;   ///< current particle buffer and layout
  int gc_ = 0;    ///< current grid
  bool record_ = false;
  bool capture_next_ = false;     ///< the next step captures frames
  long long captured_step_ = -1;  ///< the step whose state the device frames hold
  double output_wait_s_ = 0.0;
  bool flat_source_ = false;  ///< the partition reads the flat upload (slot = ID), not a layout
  bool aux_valid_ = false;  ///< aux holds v, C of the current state
  /// Each body's p2g_record holds the blocks the current grid was summed from (the last G2P2G recorded what a
  /// checkpoint needs).
  bool p2g_valid_ = false;
  /// After a G2P2G (the initial one, or a committed step's, before the flip): when it recorded for a checkpoint
  /// (keep_checkpoint_inputs), each body's particles of layout(cur) with their blocks into p2g_record; sets p2g_valid_.
  /// Steps that record v and C only for sensors skip it (a checkpoint or rebalance after them groups by position).
  void record_p2g_blocks() {
    p2g_valid_ = record_ && checkpoint_keep_;
    if (p2g_valid_)
      for (auto& b : bodies_) b->record_p2g_blocks(*this);
  }
  bool timing_ = false;
  KernelTimes times_;
  double time_ = 0.0;
  long long steps_ = 0;
  double last_dt_ = 0.0;
  double next_dt_ = 0.0;
  double dt_scale_at_compute_ = 1.0;
  double dt_p2g_ = 0.0;        ///< impulse dt inside grid[gc]
  DtRetryPolicy retry_;  ///< on_failure = reduce_dt (engine_common.h)
  long long p2g_range_repeats_ = 0;  ///< tries repeated because the fixed-point P2G bound was exceeded
  long long partition_redos_ = 0;    ///< partitions redone inside a step after a growth (handle_overflow)
  long long compactions_ = 0;        ///< grid compactions (compact_grid)
  long long compacted_blocks_ = 0;   ///< blocks they dropped
  int compact_check_at_ = 0;         ///< the block count at which the next commit looks for blocks to drop
  double max_grid_speed_ = 0.0;
  std::ostream* log_ = &std::cerr;

  // Decomposition (decomposition/decomposition_state.cuh; null transports: one GPU, the slab all of space).
  using HaloSide = fbar::HaloSide<TG>;
  using SharedPeer = fbar::SharedPeer<TG>;
  DecompositionState<TG> dec_;
};

}  // namespace fbar

// What every body holds (the driver's view of a body); the parts defining the members are included by
// gpu_engine_impl.cuh (the driver's units), Body<M> by body_factory.cuh (the laws' units).
#include "engine/gpu/device_bodies.cuh"

namespace fbar {
// Each precision's driver is compiled once, in instances/driver_{single,double,mixed}.cu; the bodies of each law in
// instances/bodies_<law>.cu (body_factory.cuh).
extern template class MgspBenchmark<float, float>;
extern template class MgspBenchmark<double, double>;
extern template class MgspBenchmark<double, float>;
}  // namespace fbar
