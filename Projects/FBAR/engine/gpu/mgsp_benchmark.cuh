// The GPU simulation driver (ClaymoreUW's mgsp_benchmark): all state of one device and the step, no globals.
//
// State between steps n-1 and n (cur, gc: which of the double buffers is current):
//   bins[cur]          particles of state n (storage order), per body
//   layout(cur)        their grouping by particle block (src: layout slot -> storage slot), per body
//   grid[gc]           P2G of state n (mass, momentum with the internal-force impulse of dt_p2g_)
//   table              every block any layout or grid uses (insert-only between growths; indices stable)
// Step n (dt):
//   0. dt != dt_p2g_ (a repeated step, or step(dt) with a new dt): rescale_impulse adds (dt - dt_p2g_) x the
//      stress impulse to grid[gc] (exact for rate-independent stress; see partition_kernels.cuh)
//   1. grid update: velocity = grid[gc] / m + dt g, boundaries -> velocity buffer; max |v|
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
//   3'. F-bar: the cell sums' halo exchange between fbar_cell_sums and G2P2G; after G2P2G: the halo exchange of
//       grid[1 - gc] (and the transported momentum), then migration: G2P2G marked the particles whose next block a
//       neighbour owns (kEmigrant); their records go to the neighbour, which appends the ones it receives behind
//       its own slots and records their (block, rank) before the partition. Without the halo-first overlap (the
//       default) the halo and migration messages travel in one exchange.
//   5'. agreement on the host: failures, repeats and the grid speed over ranks (so every rank takes the same
//       decision), and a rebuild of the halo lists when a rank has new blocks in a halo plane (placed bodies: any
//       new block).
#pragma once

#include <cub/device/device_scan.cuh>
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
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/memory_plan.h"
#include "engine/gpu/mgmpm_kernels.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "io/particle_frame.h"
#include "io/sensor_recorder.h"
#include "engine/gpu/partition_domain.h"
#include "engine/run_constants.h"
#include "physics/time_step.cuh"
#include "scene/scene_parse.h"

namespace fbar {

namespace mgsp_detail {

inline int grid_for(long long n, int threads) { return static_cast<int>((n + threads - 1) / threads); }

inline void check_launch(const char* what) {
  const cudaError_t e = cudaGetLastError();
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA launch of ") + what + " failed: " + cudaGetErrorString(e));
}

inline std::string format_g(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

/// Pinned host memory owned by a unique_ptr (frames hand it to the writer thread).
struct PinnedDeleter {
  void operator()(void* p) const { cudaFreeHost(p); }
};
using PinnedBytes = std::unique_ptr<void, PinnedDeleter>;
inline PinnedBytes pinned(std::size_t bytes) {
  void* p = nullptr;
  FBAR_CUDA_CHECK(cudaMallocHost(&p, bytes));
  return PinnedBytes(p);
}

/// A device array of trivially copyable T (RAII, no copy).
template <typename V>
class DeviceArray {
 public:
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  ~DeviceArray() {
    if (ptr_) cudaFree(ptr_);
  }
  void allocate(std::size_t n) {
    if (ptr_) FBAR_CUDA_CHECK(cudaFree(ptr_));
    ptr_ = nullptr;
    size_ = n;
    if (n) ptr_ = static_cast<V*>(cuda::device_malloc(sizeof(V) * n, "GPU engine buffer"));
    // Zeroed: allocations are rare, and growth copies whole arrays whose unused slots were never written. The
    // memset runs on the legacy stream, which the engine's non-blocking streams do not wait for: finish it here.
    if (n) {
      FBAR_CUDA_CHECK(cudaMemset(ptr_, 0, sizeof(V) * n));
      FBAR_CUDA_CHECK(cudaDeviceSynchronize());
    }
  }
  V* get() const { return ptr_; }
  void swap(DeviceArray& o) noexcept {
    std::swap(ptr_, o.ptr_);
    std::swap(size_, o.size_);
  }
  std::size_t size() const { return size_; }
  std::size_t bytes() const { return size_ * sizeof(V); }

 private:
  V* ptr_ = nullptr;
  std::size_t size_ = 0;
};

static __global__ void reset_step_stats(StepStats* stats, BodyStepStats* bodies, int body_count, bool partition_only) {
  const int t = threadIdx.x;
  if (t == 0) {
    if (!partition_only) {
      stats->max_speed_sq = 0;
      stats->dt_next = 0.0;
      stats->internal_error = 0;
      stats->p2g_range = 0;
    }
    stats->halo_new[0] = 0;
    stats->halo_new[1] = 0;
    stats->bin_overflow = 0;
    stats->block_count = 0;
    stats->table_overflow = 0;
  }
  for (int b = t; b < body_count; b += blockDim.x) {
    if (!partition_only) {
      for (int k = 0; k < kFailKinds; ++k) {
        bodies[b].failures[k] = 0;
        bodies[b].first_id[k] = INT_MAX;
      }
      for (int side = 0; side < 2; ++side) bodies[b].emigrants[side] = bodies[b].immigrants[side] = 0;
      bodies[b].emigrant_list = 0;
    }
    bodies[b].total_bins = 0;
    bodies[b].particles = 0;
    bodies[b].halo_blocks = 0;
    bodies[b].interior_blocks = 0;
  }
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
  double next_dt() const { return next_dt_ * (dt_scale_ / dt_scale_at_compute_); }

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
  /// Particle sensors: sample_particles() reduces the current state (v and C from the step that landed here, which
  /// keep_particle_inputs(true) made record them, when a sensor reads them) into a device slot.
  void set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors);
  void keep_particle_inputs(bool on);
  void sample_particles(int slot);
  /// Checkpoints (io/checkpoint.h): this rank's particles (with v and C of the last step, which must have recorded
  /// them: keep_checkpoint_inputs(true) before it, or the initial state) and the step state.
  io::Checkpoint checkpoint() const;
  bool checkpoint_ready() const { return aux_valid_ || steps_ == 0; }
  void keep_checkpoint_inputs(bool on);
  std::vector<SensorAccum> particle_samples(int slots) const;
  /// Trackers (as CpuEngine): the particles of `body` with the tracked IDs, found on the device by ID.
  void set_tracker(int body, const TrackerSet& set);
  void track(int body, std::vector<double>& values, std::vector<double>& present);
  long long p2g_range_repeats() const { return p2g_range_repeats_; }
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
  double total_mass() const;
  double elastic_energy() const;
  double grid_mass() const;
  std::size_t active_grid_blocks() const { return static_cast<std::size_t>(block_count_); }
  std::size_t device_bytes() const;
  int rank() const { return host_ ? host_->rank() : 0; }
  int ranks() const { return host_ ? host_->size() : 1; }
  const comm::SlabPartition& slabs() const { return slabs_; }
  /// Particles per rank after the last step (or the start), max / mean - 1; the same on every rank (0: one rank).
  double imbalance() const {
    if (!decomposed()) return 0.0;
    double total = 0.0;
    for (const auto& b : bodies_) total += static_cast<double>(b->global_particles);
    const double mean = total / ranks();
    return mean > 0.0 ? most_rank_particles_ / mean - 1.0 : 0.0;
  }
  /// Waits until the writer thread has built every frame submitted so far (their host buffers are free).
  void wait_for_frames() const {
    for (const auto& b : bodies_) {
      if (!b->frame_slot) continue;
      std::unique_lock<std::mutex> lock(b->frame_slot->mutex);
      b->frame_slot->released.wait(lock, [&] { return !b->frame_slot->busy; });
    }
  }
  long long migrated() const { return migrated_; }
  long long migration_repeats() const { return migration_repeats_; }
  std::size_t halo_blocks() const {
    return placed_ ? union_blocks_.size() : halo_[0].keys.size() + halo_[1].keys.size();
  }
  std::size_t halo_particle_blocks() const {
    std::size_t n = 0;
    for (const auto& b : bodies_) n += static_cast<std::size_t>(b->halo_blocks[cur_]);
    return n;
  }

 private:
  // ---------------------------------------------------------------- bodies (host-side polymorphism only)
  struct BodyBase {
    BodySpec spec;
    int index = 0;
    int particles = 0;             ///< on this rank (all of the body on one GPU)
    long long global_particles = 0;  ///< of the body over all ranks: IDs are 0 .. global_particles - 1
    /// Slots of bins[1 - cur] the partition reads: the G2P2G's layout slots, then the particles received this try.
    int source_slots = 0;
    int pending_particles = 0;     ///< particles on this rank after this try's migration
    /// Decomposed runs: the slots of a try's emigrants, as G2P2G lists them (2 x migrant_capacity_ entries).
    mgsp_detail::DeviceArray<int> emigrant_slots;
    T mass = T(0), volume = T(0);
    double rest_wave_speed = 0.0;
    HydrostaticProfile hydrostatic;  ///< bodies[].initial_state "hydrostatic": the upload's states (inactive: rest)
    T fbar_psi = T(0);  ///< F-bar blend (transfer.cuh), 0: off
    bool asflip = false;  ///< PIC-FLIP / ASFLIP (transfer.cuh)
    AsflipParams<T> asflip_params{T(0), T(0), T(0)};
    /// ASFLIP only: (slot, 3) particle velocities beside bins[0] / bins[1], same slots (empty otherwise).
    mgsp_detail::DeviceArray<T> particle_v[2];
    PartitionDomain partition;
    int total_bins[2] = {0, 0};  ///< bins of layout 0 / 1
    /// Decomposed runs: blocks of layout 0 / 1 listed for the halo-first G2P2G (halo particle blocks, the others).
    int halo_blocks[2] = {0, 0}, interior_blocks[2] = {0, 0};
    mgsp_detail::DeviceArray<T> aux;  ///< (slot, kAuxScalars) recorded v and C
    /// Per-particle initial velocities (GpuEngineOptions::initial_velocities): (ID, 3) on the device for the initial
    /// P2G, and on the host for snapshots before the first step; empty when the body starts at its scene velocity.
    mgsp_detail::DeviceArray<T> initial_v;
    std::vector<Vec3<T>> initial_v_host;
    /// A restart (GpuEngineOptions::restart): per particle (ID order) the APIC C on the device for the initial P2G,
    /// and the material state scalars on the host for the upload; empty otherwise.
    mgsp_detail::DeviceArray<T> initial_C;
    std::vector<T> restart_state;
    /// Output frame (GpuEngineOptions::frames): its attributes, the device copy a capture step writes (ID order),
    /// the pinned host copy the writer thread reads, and whether that host copy is still being read.
    std::vector<FrameAttributeSpec> frame_attrs;
    FrameCapture<T> capture;
    mgsp_detail::DeviceArray<T> frame_x;
    mgsp_detail::DeviceArray<float> frame_columns;
    mgsp_detail::PinnedBytes frame_host;
    struct HostSlot {
      std::mutex mutex;
      std::condition_variable released;
      bool busy = false;
      /// The writer's hold on the slot: the host buffer goes back to the step loop when it ends, also when the
      /// writing throws.
      struct Hold {
        std::shared_ptr<HostSlot> slot;
        ~Hold() {
          {
            std::lock_guard<std::mutex> lock(slot->mutex);
            slot->busy = false;
          }
          slot->released.notify_all();
        }
      };
    };
    std::shared_ptr<HostSlot> frame_slot = std::make_shared<HostSlot>();
    cudaEvent_t frame_copied = nullptr;  ///< the last download of the frame finished (the next capture waits)
    std::size_t frame_host_bytes() const {
      return static_cast<std::size_t>(particles) * (3 * sizeof(T) + sizeof(float) * capture.column_count);
    }
    /// Decomposed runs: the ID directory of the captured frame (FrameCapture::id_bits / id_offset), its scan space,
    /// the particles the last capture wrote, and the sizes of the frame buffers (they grow with arrivals).
    mgsp_detail::DeviceArray<unsigned> id_bits;
    mgsp_detail::DeviceArray<int> id_offset, id_counts;
    mgsp_detail::DeviceArray<std::byte> id_scan_temp;
    int captured_particles = 0;
    std::size_t frame_capacity = 0;
    std::size_t frame_host_size = 0;
    virtual ~BodyBase() {
      if (frame_copied) cudaEventDestroy(frame_copied);
    }
    virtual void capture_state(MgspBenchmark& e) = 0;  ///< the frame of the current state (before the first step)
    virtual void mark_ids(MgspBenchmark& e) = 0;       ///< id_bits of the particles of layout(cur)
    virtual bool stores_F() const = 0;
    virtual int stored_scalars() const = 0;
    virtual void allocate_bins(int bins) = 0;                   ///< both buffers, contents lost
    virtual void reallocate_bins(int which, int bins) = 0;      ///< one buffer, contents lost
    /// One buffer grown to `bins` bins, its first `keep_slots` slots (and ASFLIP velocities) kept.
    virtual void grow_bins_keeping(int which, int bins, int keep_slots, cudaStream_t s) = 0;
    virtual int bins_capacity(int which) const = 0;
    virtual std::size_t bins_bytes() const = 0;
    /// Particles first_id .. first_id + x.size() into bins[0] (flat: slot = ID); first_id is a multiple of 32.
    /// ids: the particles' IDs (nullptr: first_id + i).
    virtual void upload(const Vec3d* x, const int* ids, std::size_t n, long long first_id, cudaStream_t s) = 0;
    /// States of particles read with has_attributes (geometry/particle_seed.h): restart_state for every ID, the
    /// seeded ones from their seeds, the rest in the body's initial state. Returns the largest wave speed [m/s].
    virtual double seed_states(const ParticleSeeds& seeds) = 0;
    /// pass: every block of layout(cur) (one GPU, the initial P2G), or one part of its list (the halo-first step).
    virtual void g2p2g(MgspBenchmark& e, bool initial, T dt, G2P2GPass pass = G2P2GPass::All) = 0;
    virtual void dest_from_positions(MgspBenchmark& e, int bins_which, const int* valid, int first, int slots) = 0;
    virtual std::size_t migrant_bytes(const MgspBenchmark& e) const = 0;
    /// The emigrants G2P2G listed (emigrant_slots) from bins[1 - cur] into the areas lo / hi of `capacity` records
    /// (count_lo / count_hi: the body's device ints in the two message headers).
    virtual void pack_emigrants(MgspBenchmark& e, std::byte* lo, std::byte* hi, int capacity, int* count_lo,
                                int* count_hi) = 0;
    /// The min(*count, capacity) received records into slots first .. of bins[1 - cur]; the rest of the `capacity`
    /// slots marked empty.
    virtual void unpack_immigrants(MgspBenchmark& e, int first, const std::byte* in, const int* count,
                                   int capacity) = 0;
    virtual void rescale_impulse(MgspBenchmark& e, T ddt) = 0;
    virtual void gather(MgspBenchmark& e, T* out, int* missing, cudaStream_t s) = 0;
    /// Particle sensors over this body's particles into partials (sensor, CUDA block); aux: v and C, or nullptr
    /// (before the first step: the initial velocity, C = 0).
    virtual void sample_sensors(MgspBenchmark& e, const T* aux, SensorAccum* partials, int per_sensor) = 0;
    /// The tracker's particles this rank holds into values / present (device, zeroed beforehand).
    virtual void track(MgspBenchmark& e, const T* aux, const TrackerSet& t, double* values, double* present) = 0;
    virtual bool stores_logJp() const = 0;
    /// J, F, Cauchy stress and logJp of one gathered record (F and logJp left as they are for a material without).
    virtual void state_of(const T* record, T& J, Mat3<T>& F, Mat3<T>& sigma, T& logJp, const Mat3<T>& C) const = 0;
    /// psi(state) [J/m^3] of one gathered record.
    virtual double energy_density_of(const T* record) const = 0;
    /// The material's wave speed [m/s] in the state of one gathered record.
    virtual double wave_speed_of(const T* record) const = 0;
  };

  template <typename M>
  struct Body final : BodyBase {
    using Layout = ParticleLayout<M, T>;
    material_params_t<M, T> params;
    ParticleBuffer<M, T> bins[2];

    bool stores_F() const override { return M::kOutputs.deformation_gradient; }
    bool stores_logJp() const override { return M::kOutputs.log_jp; }
    int stored_scalars() const override { return Layout::kScalars; }
    void allocate_bins(int n) override {
      bins[0].allocate(n);
      bins[1].allocate(n);
      if (this->asflip) {
        this->particle_v[0].allocate(static_cast<std::size_t>(n) * 32 * 3);
        this->particle_v[1].allocate(static_cast<std::size_t>(n) * 32 * 3);
      }
    }
    void reallocate_bins(int which, int n) override {
      bins[which].allocate(n);
      if (this->asflip) this->particle_v[which].allocate(static_cast<std::size_t>(n) * 32 * 3);
    }
    void grow_bins_keeping(int which, int n, int keep_slots, cudaStream_t s) override {
      bins[which].grow_keeping(n, (keep_slots + 31) / 32, s);
      if (this->asflip) {
        mgsp_detail::DeviceArray<T> bigger;
        bigger.allocate(static_cast<std::size_t>(n) * 32 * 3);
        if (keep_slots > 0)
          FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.get(), this->particle_v[which].get(),
                                          sizeof(T) * 3 * static_cast<std::size_t>(keep_slots), cudaMemcpyDeviceToDevice, s));
        FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
        this->particle_v[which].swap(bigger);
      }
    }
    int bins_capacity(int which) const override { return bins[which].bin_capacity(); }
    std::size_t bins_bytes() const override {
      return bins[0].bytes() + bins[1].bytes() + this->particle_v[0].bytes() + this->particle_v[1].bytes();
    }

    void upload(const Vec3d* x, const int* ids, std::size_t n, long long first_id, cudaStream_t s) override {
      // Flat bins of this batch on the host (slot = particle ID), one copy to their place in bins[0].
      const std::size_t bins_n = (n + 31) / 32;
      const std::size_t bytes = Layout::kBinBytes * bins_n;
      std::vector<std::byte> host(bytes);
      typename Layout::Buffer view(host.data(), bins_n);
      const auto state = material_initial_state<M, T>(this->spec.material);
      constexpr std::size_t S = Layout::kStateScalars;
      for (std::size_t i = 0; i < n; ++i) {
        const int id = ids ? ids[i] : static_cast<int>(first_id + static_cast<long long>(i));
        ParticleRecord<M, T> p{x[i].template cast<T>(), state, id};
        if (this->hydrostatic.active)
          p.state = material_hydrostatic_state<M, T>(params, this->hydrostatic.kirchhoff_pressure(x[i]));
        if (!this->restart_state.empty())
          std::memcpy(&p.state, this->restart_state.data() + S * static_cast<std::size_t>(id), sizeof(p.state));
        store_particle<M, T>(view, static_cast<int>(i), p);
      }
      std::byte* target = bins[0].instance().data() + Layout::kBinBytes * static_cast<std::size_t>(first_id / 32);
      if (bytes) FBAR_CUDA_CHECK(cudaMemcpyAsync(target, host.data(), bytes, cudaMemcpyHostToDevice, s));
      FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
    }

    double seed_states(const ParticleSeeds& seeds) override {
      constexpr std::size_t S = Layout::kStateScalars;
      const auto initial = material_initial_state<M, T>(this->spec.material);
      this->restart_state.resize(S * static_cast<std::size_t>(this->global_particles));
      double speed = 0.0;  // of the seeded states (the others are the body's initial state)
      for (long long id = 0; id < this->global_particles; ++id) {
        auto state = initial;
        if (id >= seeds.first) {
          state = material_seeded_state<M, T>(state, seeds.at(static_cast<std::size_t>(id - seeds.first)));
          speed = std::max(speed, static_cast<double>(M::wave_speed(params, state)));
        }
        std::memcpy(this->restart_state.data() + S * static_cast<std::size_t>(id), &state, sizeof(state));
      }
      return speed;
    }

    void g2p2g(MgspBenchmark& e, bool initial, T dt, G2P2GPass pass) override {
      G2P2GParams<M, T, TG> p;
      p.in = bins[e.cur_].instance();
      p.out = bins[1 - e.cur_].instance();
      p.layout = this->partition.layout(e.cur_);
      p.next_count = this->partition.layout(1 - e.cur_).count;
      p.dest = this->partition.dest();
      p.table = e.table_.view();
      p.velocity = e.velocity_.instance();
      p.grid_next = e.grid_[1 - e.gc_].instance();
      p.grid_this = e.grid_[e.gc_].instance();
      p.aux = e.record_ ? this->aux.get() : nullptr;
      if (e.capture_next_ && this->capture.x) p.capture = this->capture;
      if (e.asflip_) p.transported_next = e.transported_[1 - e.gc_].instance();
      p.asflip = this->asflip;
      p.asflip_params = this->asflip_params;
      if (this->asflip) {
        p.old_velocity = e.old_velocity_.instance();
        p.particle_v_in = this->particle_v[e.cur_].get();
        p.particle_v_out = this->particle_v[1 - e.cur_].get();
      }
      p.fbar_psi = initial ? T(0) : this->fbar_psi;
      if (p.fbar_psi != T(0)) p.fbar_sums = e.fbar_sums_.instance();
      p.material = params;
      p.mass = this->mass;
      p.volume = this->volume;
      p.initial_velocity = Vec3<T>{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                                    static_cast<T>(this->spec.velocity[2])}};
      p.initial_v = initial && this->initial_v.size() ? this->initial_v.get() : nullptr;
      p.initial_C = initial && this->initial_C.size() ? this->initial_C.get() : nullptr;
      p.dt = dt;
      p.dx = e.k_.dx;
      p.inv_dx = e.k_.inv_dx;
      p.d_inv = e.k_.d_inv;
      p.domain = e.k_.domain;
      p.dt_next = &e.stats_d_->dt_next;
      p.stats = e.stats_d_;
      p.body_stats = e.body_stats_d_ + this->index;
      p.slab = e.slab_of(this->index);
      p.emigrant_slots = e.decomposed() ? this->emigrant_slots.get() : nullptr;
      p.emigrant_capacity = static_cast<int>(this->emigrant_slots.size());
      p.wave_speed = e.wave_d_.get() + (1 - e.wave_cur_) * e.bodies_.size() + this->index;
      p.p2g_bound_in = e.p2g_bound_d_.get() + e.bound_cur_ * e.bodies_.size() + this->index;
      p.p2g_bound_out = e.p2g_bound_d_.get() + (1 - e.bound_cur_) * e.bodies_.size() + this->index;
      if (e.block_count_ == 0) return;
      if (p.fbar_psi != T(0) && pass != G2P2GPass::Interior) {  // F-bar: the cell sums first (fbar_cell_sums)
        const int blocks = e.block_count_;
        e.fbar_sums_.clear(0, blocks, e.stream_);
        FbarCellSumsParams<M, T, TG> f;
        f.in = p.in;
        f.layout = p.layout;
        f.table = p.table;
        f.sums = p.fbar_sums;
        f.volume = p.volume;
        f.inv_dx = p.inv_dx;
        f.stats = p.stats;
        fbar::fbar_cell_sums<M, T, TG><<<blocks, kG2P2GThreads, 0, e.stream_>>>(f);
        mgsp_detail::check_launch("fbar_cell_sums");
        if (e.decomposed()) e.halo_exchange({{e.fbar_sums_.instance().data(), GridFbarBuffer<TG>::kBlockBytes}}, -1);
      }
      int blocks = e.block_count_;
      p.order_first = -1;
      if (pass == G2P2GPass::Halo) {
        p.order_first = 0;
        blocks = this->halo_blocks[e.cur_];
      } else if (pass == G2P2GPass::Interior) {
        blocks = this->interior_blocks[e.cur_];
        p.order_first = this->partition.block_capacity() - blocks;
      }
      if (blocks == 0) return;
      const bool transport = static_cast<bool>(p.transported_next);
      const std::size_t arena = g2p2g_arena_bytes<TG>(transport);
      const bool capture = p.capture.x != nullptr;
      if (initial)
        fbar::g2p2g<M, T, TG, true, false><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
      else if (transport && capture)
        fbar::g2p2g<M, T, TG, false, true, true><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
      else if (transport)
        fbar::g2p2g<M, T, TG, false, true><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
      else if (capture)
        fbar::g2p2g<M, T, TG, false, false, true><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
      else
        fbar::g2p2g<M, T, TG, false, false><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
      mgsp_detail::check_launch("g2p2g");
    }

    void capture_state(MgspBenchmark& e) override {
      const int slots = this->total_bins[e.cur_] * 32;
      if (slots == 0) return;
      const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                        static_cast<T>(this->spec.velocity[2])}};
      fbar::capture_frame_state<M, T><<<mgsp_detail::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, this->capture, v0,
          this->initial_v.size() ? this->initial_v.get() : nullptr, params, this->mass, this->volume);
      mgsp_detail::check_launch("capture_frame_state");
    }

    void mark_ids(MgspBenchmark& e) override {
      const int slots = this->total_bins[e.cur_] * 32;
      if (slots == 0) return;
      fbar::mark_ids<M, T><<<mgsp_detail::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, this->id_bits.get());
      mgsp_detail::check_launch("mark_ids");
    }

    void dest_from_positions(MgspBenchmark& e, int which, const int* valid, int first, int slots) override {
      if (slots <= first) return;
      fbar::dest_from_positions<M, T, TG><<<mgsp_detail::grid_for(slots - first, kPartitionThreads), kPartitionThreads,
                                        0, e.stream_>>>(
          bins[which].instance(), valid, this->particles, first, slots, e.k_.inv_dx, e.slab_of(this->index), e.table_.view(),
          this->partition.layout(1 - e.cur_).count, this->partition.dest(), e.grid_[0].instance(),
          e.grid_[1].instance(), e.body_stats_d_ + this->index);
      mgsp_detail::check_launch("dest_from_positions");
    }

    std::size_t migrant_bytes(const MgspBenchmark& e) const override {
      return fbar::migrant_bytes<M, T>(this->asflip, e.record_);
    }
    void pack_emigrants(MgspBenchmark& e, std::byte* lo, std::byte* hi, int capacity, int* count_lo,
                        int* count_hi) override {
      const int listed = static_cast<int>(this->emigrant_slots.size());
      if (listed == 0) return;
      fbar::pack_emigrants<M, T><<<mgsp_detail::grid_for(listed, kHaloThreads), kHaloThreads, 0, e.stream_>>>(
          bins[1 - e.cur_].instance(), this->emigrant_slots.get(), &e.body_stats_d_[this->index].emigrant_list,
          listed, this->partition.dest(), this->asflip ? this->particle_v[1 - e.cur_].get() : nullptr,
          e.record_ ? this->aux.get() : nullptr, lo, hi, capacity, count_lo, count_hi);
      mgsp_detail::check_launch("pack_emigrants");
    }
    void unpack_immigrants(MgspBenchmark& e, int first, const std::byte* in, const int* count, int capacity) override {
      if (capacity == 0) return;
      fbar::unpack_immigrants<M, T><<<mgsp_detail::grid_for(capacity, kHaloThreads), kHaloThreads, 0, e.stream_>>>(
          bins[1 - e.cur_].instance(), first, in, count, capacity,
          this->asflip ? this->particle_v[1 - e.cur_].get() : nullptr, e.record_ ? this->aux.get() : nullptr,
          this->partition.layout(e.cur_).src);
      mgsp_detail::check_launch("unpack_immigrants");
    }

    void rescale_impulse(MgspBenchmark& e, T ddt) override {
      const int slots = this->total_bins[e.cur_] * 32;
      if (slots == 0) return;
      fbar::rescale_impulse<M, T, TG><<<mgsp_detail::grid_for(slots, kPartitionThreads), kPartitionThreads, 0, e.stream_>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_), slots, params, this->volume, ddt, e.k_.dx, e.k_.inv_dx,
          e.k_.d_inv, e.table_.view(), e.grid_[e.gc_].instance(), e.stats_d_);
      mgsp_detail::check_launch("rescale_impulse");
    }

    void sample_sensors(MgspBenchmark& e, const T* aux, SensorAccum* partials, int per_sensor) override {
      const int slots = this->total_bins[e.cur_] * 32;
      const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                        static_cast<T>(this->spec.velocity[2])}};
      fbar::sample_particle_sensors<M, T><<<dim3(per_sensor, e.particle_sensors_.count), kSensorThreads, 0, e.stream_>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, aux, v0, params, this->mass, this->volume,
          e.particle_sensors_, partials);
      mgsp_detail::check_launch("sample_particle_sensors");
    }

    void track(MgspBenchmark& e, const T* aux, const TrackerSet& t, double* values, double* present) override {
      const int slots = this->total_bins[e.cur_] * 32;
      if (slots == 0) return;
      const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                        static_cast<T>(this->spec.velocity[2])}};
      fbar::track_particles<M, T><<<mgsp_detail::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, aux, v0, params, this->mass, this->volume, t,
          values, present);
      mgsp_detail::check_launch("track_particles");
    }

    void gather(MgspBenchmark& e, T* out, int* missing, cudaStream_t s) override {
      const int slots = this->total_bins[e.cur_] * 32;
      if (slots == 0) return;
      // aux was written at the storage slots of bins[cur] (the previous G2P2G's layout order).
      fbar::gather_by_id<M, T><<<mgsp_detail::grid_for(slots, kOutputThreads), kOutputThreads, 0, s>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, e.aux_valid_ ? this->aux.get() : nullptr,
          static_cast<int>(this->global_particles), out, missing);
      mgsp_detail::check_launch("gather_by_id");
    }

    void state_of(const T* r, T& J, Mat3<T>& F, Mat3<T>& sigma, T& logJp, const Mat3<T>& C) const override {
      material_state_t<M, T> s;
      std::memcpy(&s, r + 3, sizeof(s));
      J = M::volume_ratio(s);
      if constexpr (M::kOutputs.deformation_gradient) F = s.F;
      if constexpr (M::kOutputs.log_jp) logJp = s.logJp;
      sigma = cauchy_stress(M::kirchhoff_stress(params, s, C));
    }
    double energy_density_of(const T* r) const override {
      material_state_t<M, T> s;
      std::memcpy(&s, r + 3, sizeof(s));
      return static_cast<double>(M::energy_density(params, s));
    }
    double wave_speed_of(const T* r) const override {
      material_state_t<M, T> s;
      std::memcpy(&s, r + 3, sizeof(s));
      return static_cast<double>(M::wave_speed(params, s));
    }
  };

  BodyBase& body_at(int b) const {
    if (b < 0 || b >= body_count()) throw std::out_of_range("GpuEngine: no body " + std::to_string(b));
    return *bodies_[b];
  }

  // ---------------------------------------------------------------- step pieces
  void reset_stats(bool partition_only);
  void partition_after_g2p2g();          ///< footprint, scan, finalize, src scatter for every body
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
  void update_record();
  /// A restart: every body's mass, volume, state and C from the checkpoint (positions and velocities came in as
  /// the constructor's positions and GpuEngineOptions::initial_velocities); time and CFL inputs.
  void restore_bodies(const io::Checkpoint& cp);  ///< record_ from the user's, the sensors' and the checkpoints' requests
  /// Sensor sample slots: at least `need` entries, the old ones kept.
  void grow_samples(mgsp_detail::DeviceArray<SensorAccum>& samples, std::size_t need);
  void ensure_sensor_partials();
  /// The first n sensor sample values, on the host (one copy and a stream sync).
  std::vector<SensorAccum> download_samples(const mgsp_detail::DeviceArray<SensorAccum>& samples, std::size_t n) const;
  void allocate_frames();
  /// Decomposed runs, before a capture: frame buffers for the rank's particles, and the ID directory of layout(cur).
  void prepare_capture(BodyBase& b);
  void initialize(const std::vector<std::vector<Vec3d>>* positions);
  void upload_sampled(BodyBase& body);
  std::vector<FailureReport> failures_of_try(double dt) const;
  void commit(double dt);
  /// Before a step: bins[1 - cur] (the G2P2G target) holds layout(cur); bins grown with headroom (after commit/init).
  void ensure_step_capacity();
  void event_record(int i) {
    if (timing_) FBAR_CUDA_CHECK(cudaEventRecord(events_[i], stream_));
  }
  std::vector<T> gather_host(int body, cudaStream_t s) const;

  // ---------------------------------------------------------------- decomposition (GpuEngineOptions::ranks)
  bool decomposed() const { return device_ != nullptr; }
  /// Chooses the slabs from every body's counts (the same on every rank: each counted the whole scene) and keeps
  /// this rank's part of each count.
  void choose_slabs(const std::vector<std::vector<Vec3d>>* positions);
  /// Whether this rank holds body b's particle at x: a placed body's rank holds all of it (comm/placement.h); else
  /// the slab of x's particle block (the device's arithmetic: x in T).
  bool owns(int body, const Vec3d& x) const;
  /// The particle blocks body b keeps on this rank: a placed body all of them (it never migrates), else the slab.
  SlabBounds slab_of(int body) const {
    return homes_.empty() || homes_[static_cast<std::size_t>(body)] < 0 ? slab_ : SlabBounds{};
  }
  /// Placed bodies: the lists of blocks shared with each rank, from every rank's new table keys (collective; the
  /// counterpart of rebuild_halo). A block that a rank has just created takes the sums of grid[summed_grid] from
  /// the lowest rank that held it before (when summed_grid >= 0), so every holder has the same values.
  void rebuild_shared(int summed_grid, const std::vector<unsigned long long>& fresh);
  /// Placed bodies: halo_exchange over the shared lists, every holder's contribution added in rank order.
  void shared_exchange(std::initializer_list<std::pair<std::byte*, std::size_t>> buffers, int grid, bool delta,
                       cudaStream_t stream);
  /// Placed bodies: not_counted_ from the lists (a block shared with a lower rank counts there).
  void mark_not_counted();
  /// Sums the listed block buffers' halo blocks with the neighbours (data, bytes per block). grid >= 0: the first
  /// buffer is grid_[grid], whose summed halo is kept for a later delta exchange; delta: add (mine + theirs) - saved.
  /// On `stream` (nullptr: the compute stream).
  void halo_exchange(std::initializer_list<std::pair<std::byte*, std::size_t>> buffers, int grid, bool delta = false,
                     cudaStream_t stream = nullptr);
  using BlockBuffers = std::vector<std::pair<std::byte*, std::size_t>>;
  /// halo_exchange in two halves (neighbour planes only), so that one exchange can carry other messages too: the
  /// packed halo messages, then, after the exchange, the sums.
  std::vector<comm::DeviceTransport::Message> pack_halo_messages(const BlockBuffers& buffers, cudaStream_t stream);
  void add_halo_messages(const BlockBuffers& buffers, int grid, bool delta, cudaStream_t stream);
  /// The buffers a step's halo sums: grid[g] and, with ASFLIP, the transported momentum.
  BlockBuffers step_halo_buffers(int g) {
    BlockBuffers out{{grid_[g].instance().data(), GridBuffer<TG>::kBlockBytes}};
    if (asflip_) out.emplace_back(transported_[g].instance().data(), GridVelocityBuffer<TG>::kBlockBytes);
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
  /// After the partition: the table blocks [halo_scanned_, count) in a halo plane (keys and counts into stats).
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
  /// migrant_most_, this rank's largest count (agree_on_try makes it every rank's; above migrant_capacity_ a message
  /// overflowed).
  void settle_migration();
  /// Decomposed runs, before a G2P2G: each body's emigrant list holds 2 x migrant_capacity_ slots.
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
  cudaStream_t halo_stream_ = nullptr;  ///< decomposed runs: the halo sums overlapping the interior G2P2G
  cudaEvent_t halo_ready_ = nullptr, halo_done_ = nullptr;  ///< halo blocks scattered / summed
  cudaEvent_t halo_events_[2] = {};  ///< kernel timing: the halo stream's sums start / end
  BlockHashTable table_;
  GridBuffer<TG> grid_[2];
  GridVelocityBuffer<TG> velocity_;
  GridFbarBuffer<TG> fbar_sums_;         ///< F-bar cell sums, allocated only when a body uses F-bar
  /// ASFLIP, allocated only when a body uses it: transported momentum of each P2G (double-buffered like grid_) and
  /// v^n from the grid update.
  GridVelocityBuffer<TG> transported_[2];
  GridVelocityBuffer<TG> old_velocity_;
  bool asflip_ = false;
  bool fbar_ = false;
  int block_capacity_ = 0;
  int block_count_ = 0;                 ///< table blocks after the last committed partition
  mgsp_detail::DeviceArray<std::byte> stats_bytes_;
  StepStats* stats_d_ = nullptr;
  BodyStepStats* body_stats_d_ = nullptr;
  mgsp_detail::PinnedBytes stats_h_;
  StepStats* stats_ = nullptr;          ///< pinned mirror
  BodyStepStats* body_stats_ = nullptr;
  mgsp_detail::DeviceArray<unsigned long long> wave_d_;  ///< (2, body) wave-speed bits: current / being reduced
  int wave_cur_ = 0;
  /// (2, body) bits of the fixed-point P2G momentum bound: the one in use / the one measured by this try.
  mgsp_detail::DeviceArray<unsigned long long> p2g_bound_d_;
  int bound_cur_ = 0;
  mgsp_detail::DeviceArray<std::byte> scan_temp_;
  std::size_t scan_temp_bytes_ = 0;
  mgsp_detail::DeviceArray<int> missing_d_;
  GridSensorSet<TG> grid_sensors_;
  int grid_sample_slot_ = -1;
  mgsp_detail::DeviceArray<SensorAccum> grid_samples_d_;     ///< (slot, sensor)
  mgsp_detail::DeviceArray<SensorAccum> sensor_partials_d_;  ///< (sensor, CUDA block) of one sample
  ParticleSensorSet<T> particle_sensors_;
  bool particle_sensors_read_v_ = false;  ///< some particle sensor reads v or C (the landing step records them)
  bool record_user_ = false;              ///< set_record_velocities
  bool sensor_keep_ = false;              ///< keep_particle_inputs: this step records v and C for sensors
  bool checkpoint_keep_ = false;          ///< keep_checkpoint_inputs: this step records v and C for a checkpoint
  mgsp_detail::DeviceArray<SensorAccum> particle_samples_d_;  ///< (slot, body, sensor)
  std::vector<TrackerSet> trackers_;     ///< (body)
  bool trackers_read_v_ = false;          ///< a tracker reads v or C (the frame-landing steps record them)
  mgsp_detail::DeviceArray<double> track_d_;  ///< values (kMaxIds x kMaxAttribs), then present (kMaxIds)

  int cur_ = 0;   ///< current particle buffer and layout
  int gc_ = 0;    ///< current grid
  bool record_ = false;
  bool capture_next_ = false;     ///< the next step captures frames
  long long captured_step_ = -1;  ///< the step whose state the device frames hold
  double output_wait_s_ = 0.0;
  bool flat_source_ = false;  ///< the partition reads the flat upload (slot = ID), not a layout
  bool aux_valid_ = false;  ///< aux holds v, C of the current state
  bool timing_ = false;
  KernelTimes times_;
  double time_ = 0.0;
  long long steps_ = 0;
  double last_dt_ = 0.0;
  double next_dt_ = 0.0;
  double dt_scale_at_compute_ = 1.0;
  double dt_p2g_ = 0.0;        ///< impulse dt inside grid[gc]
  double dt_scale_ = 1.0;
  int clean_steps_ = 0;
  long long p2g_range_repeats_ = 0;  ///< tries repeated because the fixed-point P2G bound was exceeded
  double max_grid_speed_ = 0.0;
  std::ostream* log_ = &std::cerr;

  // Decomposition (null transports: one GPU, the slab is all of space).
  comm::Transport* host_ = nullptr;
  comm::DeviceTransport* device_ = nullptr;
  comm::SlabPartition slabs_;
  SlabBounds slab_;
  /// The halo with the lower (0) and upper (1) neighbour: the union of both ranks' blocks of the shared plane.
  struct HaloSide {
    int peer = -1;                              ///< -1: no neighbour on this side
    int plane = 0;                              ///< grid-block coordinate of the shared plane along the axis
    std::vector<unsigned long long> keys;       ///< sorted union (the same list on both ranks)
    mgsp_detail::DeviceArray<int> index;        ///< table index of each key here
    mgsp_detail::DeviceArray<TG> send, recv;    ///< message buffers (every exchanged buffer's blocks, in turn)
    mgsp_detail::DeviceArray<TG> saved[2];      ///< grid[g]'s summed halo blocks (delta exchanges)
    mgsp_detail::DeviceArray<unsigned long long> fresh;  ///< new local halo keys of the last collect_halo
    mgsp_detail::DeviceArray<std::byte> migrants_out, migrants_in;
  };
  std::array<HaloSide, 2> halo_;
  int halo_scanned_ = 0;                        ///< table blocks already looked at for the halo planes
  int halo_fresh_capacity_ = 0;
  /// Records per body and side in a migration message (MigrantMessage): the same on every rank, grown (by all
  /// ranks at once, after agree_on_try) when a step sent more than half of it; a step that sent more is repeated.
  int migrant_capacity_ = 512;     ///< options_.migrant_capacity at start
  long long migration_repeats_ = 0;  ///< tries repeated because migrants overflowed the messages
  /// agree_on_try: the most particles one rank sent one side for one body (or half its emigrant list); a message
  /// overflowed when it is above migrant_capacity_
  int migrant_most_ = 0;
  long long migrated_ = 0;
  long long pending_migrated_ = 0;
  bool halo_grew_ = false;  ///< agree_on_try: some rank has new halo blocks (every rank then calls rebuild_halo)
  double most_rank_particles_ = 0.0;  ///< agree_on_try: the most particles any rank holds after the last step

  mgsp_detail::DeviceArray<unsigned long long> dt_inputs_d_;  ///< gather_dt_inputs: one reduction over the ranks

  // Placed bodies (bodies[].gpu, comm/placement.h): any set of ranks may hold a block; the sums go over these lists
  // (shared_exchange) instead of the neighbour planes, and halo_[0].fresh collects every new table block.
  std::vector<int> homes_;  ///< per body: the rank holding it whole, or kAllGpus (spread by space); empty: one GPU
  bool placed_ = false;     ///< some body is placed
  struct SharedPeer {
    std::vector<unsigned long long> keys;       ///< blocks both ranks hold, sorted (the same list on both)
    std::vector<int> blocks;                    ///< their table indices here
    mgsp_detail::DeviceArray<int> index, upos;  ///< the same on the device; upos: each entry's union position
    mgsp_detail::DeviceArray<TG> send, recv;
  };
  std::vector<SharedPeer> shared_;                                   ///< per rank (this rank's entry unused)
  std::vector<std::unordered_set<unsigned long long>> rank_keys_;    ///< every rank's table keys so far
  std::vector<int> union_blocks_;                                    ///< every shared block once, ascending
  mgsp_detail::DeviceArray<int> union_index_;
  mgsp_detail::DeviceArray<TG> union_own_, union_saved_[2];          ///< this rank's part; grid[g]'s summed values
  mgsp_detail::DeviceArray<unsigned char> not_counted_;              ///< per table block (sensors count it once)
};

// =====================================================================================================================
// Construction

template <typename T, typename TG>
MgspBenchmark<T, TG>::MgspBenchmark(const Scene& scene, const std::vector<std::vector<Vec3d>>* positions,
                                const GpuEngineOptions& options)
    : scene_(scene), options_(options) {
  if (cuda::device_count() == 0) throw std::runtime_error(cuda::no_device_reason());
  const SimulationSpec& sim = scene_.simulation;
  k_ = RunConstants<T>(scene_, "GPU engine");
  kg_ = RunConstants<TG>(scene_, "GPU engine");
  if (static_cast<bool>(options.ranks) != static_cast<bool>(options.device_ranks))
    throw std::invalid_argument("GpuEngine: a decomposed run needs both a host and a device transport");
  if (options.ranks && options.ranks->size() != options.device_ranks->size())
    throw std::invalid_argument("GpuEngine: the host and device transports have different rank counts");
  if (options.ranks && options.ranks->size() > 1) {
    host_ = options.ranks;
    device_ = options.device_ranks;
  }
  if (options.migrant_capacity < 1)
    throw std::invalid_argument("GpuEngine: migrant_capacity must be at least 1");
  migrant_capacity_ = options.migrant_capacity;
  slabs_ = comm::choose_slabs(comm::PlaneCounts{}, 1);  // all of space (a decomposed run chooses below)
  if (positions && positions->size() != scene_.bodies.size())
    throw std::invalid_argument("GpuEngine: one position list per body");
  if (scene_.bodies.size() > static_cast<std::size_t>(DtParams::kMaxBodies))
    throw std::invalid_argument("GpuEngine: at most " + std::to_string(DtParams::kMaxBodies) + " bodies per device");
  time_ = sim.time;
  if (k_.boundaries.size() > static_cast<std::size_t>(BoundarySet<TG>::kMax))
    throw std::invalid_argument("boundaries: " + std::to_string(k_.boundaries.size()) +
                                " boundary objects (arrays counted copy by copy); the GPU engine applies at most " +
                                std::to_string(BoundarySet<TG>::kMax) + " per run");

  double max_speed = 0.0;
  std::vector<ParticleSeeds> seeds(scene_.bodies.size());  // has_attributes: per-particle velocities and states
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b) {
    const BodySpec& spec = scene_.bodies[b];
    const std::string where = "bodies[" + std::to_string(b) + "]";
    const MaterialSpec& mat = spec.material;
    if (material_index(mat.law) < 0)
      throw std::invalid_argument(where + ".material.constitutive: not implemented by the GPU engine (implemented: " +
                                  supported_material_names() + ")");
    if (mat.type != "particles")
      throw std::invalid_argument(where + ".material.type: \"" + mat.type + "\" bodies are not implemented");
    const AlgorithmSpec& alg = spec.algorithm;
    if (alg.use_fem) throw std::invalid_argument(where + ".algorithm.use_FEM: not implemented by the GPU engine");
    for (const std::string& name : spec.output_attribs) {
      const std::string canonical = canonical_attribute(name);
      if (canonical.empty() || !engine_supports_attribute(mat.law, canonical))
        throw std::invalid_argument(where + ".output_attribs: " + name + " is not available on the GPU engine");
    }
    if (!(mat.ppc > 0.0)) throw std::invalid_argument(where + ".material.ppc: must be positive");
    Aabb geometry_bounds;  // the free surface of a hydrostatic body is its top (engine/hydrostatic.h)
    if (positions) {
      const std::vector<Vec3d>& x = (*positions)[b];
      const Vec3d domain{{sim.domain[0], sim.domain[1], sim.domain[2]}};
      for (std::size_t p = 0; p < x.size(); ++p)
        if (!inside_domain(x[p], domain, sim.dx))
          throw std::invalid_argument(where + ": particle " + std::to_string(p) + " lies outside the domain");
      counts_.push_back(count_points(x, sim.dx));
      if (spec.initial_state == InitialState::Hydrostatic)
        geometry_bounds = body_geometry_bounds(spec, sim, static_cast<int>(b));
    } else {
      // Counted without storing a point (throws SceneError for particles outside the domain, or none at all).
      BodySampler sampler(spec, sim, static_cast<int>(b));
      counts_.push_back(sampler.count(sim.dx));
      seeds[b] = sampler.take_seeds(counts_.back().particles);
      geometry_bounds = sampler.geometry_bounds();
    }
    const HydrostaticProfile hydrostatic = hydrostatic_profile(spec, sim, geometry_bounds.lo, geometry_bounds.hi);
    const long long slots_needed = 32 * bins_needed(counts_.back());
    if (slots_needed > DeviceLimits::kMaxSlots)
      throw std::invalid_argument(where + ": " + std::to_string(counts_.back().particles) + " particles need " +
                                  std::to_string(slots_needed) + " particle slots on one device; at most " +
                                  std::to_string(DeviceLimits::kMaxSlots) +
                                  " (2^31 - 1, docs/user_guide.md \"Limits\"): use a coarser default_dx, fewer ppc, "
                                  "or split the body with partition_start / partition_end");
    visit_material(mat.law, [&](auto m) {
      using M = decltype(m);
      auto body = std::make_unique<Body<M>>();
      body->params = M::template make_params<T>(mat);
      body->rest_wave_speed = static_cast<double>(M::wave_speed(M::template make_params<double>(mat),
                                                                M::template reference_state<double>()));
      if (hydrostatic.active) {  // the deepest particle's sound speed
        double deepest = 0.0;
        for (int c = 0; c < 8; ++c) {
          Vec3d corner;
          for (int d = 0; d < 3; ++d) corner[d] = (c >> d) & 1 ? geometry_bounds.hi[d] : geometry_bounds.lo[d];
          deepest = std::max(deepest, hydrostatic.kirchhoff_pressure(corner));
        }
        const auto params_d = M::template make_params<double>(mat);
        body->rest_wave_speed = std::max(
            body->rest_wave_speed,
            static_cast<double>(M::wave_speed(params_d, material_hydrostatic_state<M, double>(params_d, deepest))));
      }
      bodies_.push_back(std::move(body));
    });
    BodyBase& body = *bodies_.back();
    body.spec = spec;
    body.hydrostatic = hydrostatic;
    body.index = static_cast<int>(b);
    body.particles = static_cast<int>(counts_.back().particles);
    body.global_particles = counts_.back().particles;
    const double volume = sim.dx * sim.dx * sim.dx / mat.ppc;
    body.volume = static_cast<T>(volume);
    body.mass = static_cast<T>(mat.rho * volume);
    body.asflip = alg.asflip_active();
    body.asflip_params = AsflipParams<T>{static_cast<T>(alg.asflip_alpha), static_cast<T>(alg.asflip_beta_min),
                                         static_cast<T>(alg.asflip_beta_max)};
    asflip_ = asflip_ || body.asflip;
    body.fbar_psi = static_cast<T>(alg.fbar_blend());
    fbar_ = fbar_ || body.fbar_psi != T(0);
    max_speed = std::max(max_speed, std::sqrt(spec.velocity[0] * spec.velocity[0] +
                                              spec.velocity[1] * spec.velocity[1] +
                                              spec.velocity[2] * spec.velocity[2]));
    std::vector<Vec3d> seeded_v;  // the body's velocity, or a seed's (has_attributes)
    if (!seeds[b].empty()) {
      seeded_v.assign(static_cast<std::size_t>(body.global_particles),
                      Vec3d{{spec.velocity[0], spec.velocity[1], spec.velocity[2]}});
      for (std::size_t i = 0; i < seeds[b].size(); ++i) {
        const double* sv = seeds[b].at(i) + kSeedVelocity;
        if (!std::isnan(sv[0])) seeded_v[static_cast<std::size_t>(seeds[b].first) + i] = Vec3d{{sv[0], sv[1], sv[2]}};
      }
    }
    const bool given_v = b < options.initial_velocities.size() && !options.initial_velocities[b].empty();
    if (given_v || !seeded_v.empty()) {
      const std::vector<Vec3d>& v = given_v ? options.initial_velocities[b] : seeded_v;
      if (v.size() != static_cast<std::size_t>(body.global_particles))
        throw std::invalid_argument("GpuEngine: " + std::to_string(v.size()) + " initial velocities for the " +
                                    std::to_string(body.global_particles) + " particles of body " + std::to_string(b));
      std::vector<T> flat(3 * v.size());
      body.initial_v_host.resize(v.size());
      for (std::size_t p = 0; p < v.size(); ++p) {
        body.initial_v_host[p] = v[p].template cast<T>();
        for (int a = 0; a < 3; ++a) flat[3 * p + a] = static_cast<T>(v[p][a]);
        max_speed = std::max(max_speed, std::sqrt(dot(v[p], v[p])));
      }
      body.initial_v.allocate(std::max<std::size_t>(flat.size(), 1));
      if (!flat.empty())
        FBAR_CUDA_CHECK(cudaMemcpy(body.initial_v.get(), flat.data(), sizeof(T) * flat.size(), cudaMemcpyHostToDevice));
    }
  }
  max_grid_speed_ = max_speed;
  if (const io::Checkpoint* cp = options.restart) restore_bodies(*cp);
  for (auto& b : bodies_)  // a restart's checkpoint holds the state instead
    if (!options.restart && !seeds[static_cast<std::size_t>(b->index)].empty())
      b->rest_wave_speed = std::max(b->rest_wave_speed, b->seed_states(seeds[static_cast<std::size_t>(b->index)]));
  if (decomposed()) choose_slabs(positions);

  // The plan (memory_plan.h): capacities and every buffer's size, from the counts; refused before anything is
  // allocated or sampled when it does not fit the device.
  {
    std::vector<const SampleCount*> all;
    std::vector<BodyMemoryInput> inputs;
    // v and C kept for particle sensors, trackers or checkpoints (on the steps landing on their times)
    const bool record = sensors_read_velocity(scene_) || sim.checkpoint_every > 0;
    for (std::size_t b = 0; b < bodies_.size(); ++b) {
      BodyBase& body = *bodies_[b];
      all.push_back(&counts_[b]);
      BodyMemoryInput in;
      in.particles = counts_[b].particles;
      in.bins_needed = bins_needed(counts_[b]);
      in.stored_scalars = body.stored_scalars();
      in.asflip = body.asflip;
      in.fbar = body.fbar_psi != T(0);
      in.record = record;
      if (options_.frames) {
        body.frame_attrs = frame_attributes(body.spec, body.index, "GPU engine");
        in.frame_columns = frame_float_columns(body.frame_attrs);
      }
      inputs.push_back(in);
    }
    plan_ = plan_device_memory(kPrecision, footprint_blocks(all), inputs);
    plan_.small += sensor_device_bytes(scene_);
    if (plan_.block_capacity > DeviceLimits::kMaxBlocks)
      throw std::invalid_argument("GpuEngine: " + std::to_string(plan_.block_capacity) + " grid blocks of capacity; at most " +
                                  std::to_string(DeviceLimits::kMaxBlocks) + " per device (docs/user_guide.md \"Limits\")");
    std::size_t free_bytes = 0, total_bytes = 0;
    cuda::memory_info(free_bytes, total_bytes);
    if (options_.memory_limit > 0) free_bytes = std::min(free_bytes, options_.memory_limit);
    const std::string fit = memory_fit_message(plan_, free_bytes, total_bytes, scene_, "GPU 0");
    if (!fit.empty()) throw cuda::OutOfMemory("the scene does not fit: " + fit + " (fbar --check prints the plan)");
  }
  initialize(positions);
  counts_.clear();
  counts_.shrink_to_fit();
  peak_bytes_ = device_bytes();
}

template <typename T, typename TG>
MgspBenchmark<T, TG>::~MgspBenchmark() {
  // Buffers free themselves; streams and events last (no throw from a destructor).
  if (stream_) cudaStreamSynchronize(stream_);
  if (copy_stream_) cudaStreamSynchronize(copy_stream_);
  if (halo_stream_) cudaStreamSynchronize(halo_stream_);
  for (cudaEvent_t& e : events_)
    if (e) cudaEventDestroy(e);
  for (cudaEvent_t& e : halo_events_)
    if (e) cudaEventDestroy(e);
  if (halo_ready_) cudaEventDestroy(halo_ready_);
  if (halo_done_) cudaEventDestroy(halo_done_);
  if (halo_stream_) cudaStreamDestroy(halo_stream_);
  if (stream_) cudaStreamDestroy(stream_);
  if (copy_stream_) cudaStreamDestroy(copy_stream_);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::initialize(const std::vector<std::vector<Vec3d>>* positions) {
  FBAR_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
  FBAR_CUDA_CHECK(cudaStreamCreateWithFlags(&copy_stream_, cudaStreamNonBlocking));
  for (cudaEvent_t& e : events_) FBAR_CUDA_CHECK(cudaEventCreate(&e));
  if (decomposed()) {
    // The highest priority: its pack / exchange / add kernels take SMs as the interior G2P2G's blocks retire.
    int least = 0, greatest = 0;
    FBAR_CUDA_CHECK(cudaDeviceGetStreamPriorityRange(&least, &greatest));
    FBAR_CUDA_CHECK(cudaStreamCreateWithPriority(&halo_stream_, cudaStreamNonBlocking, greatest));
    FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&halo_ready_, cudaEventDisableTiming));
    FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&halo_done_, cudaEventDisableTiming));
    for (cudaEvent_t& e : halo_events_) FBAR_CUDA_CHECK(cudaEventCreate(&e));
  }

  // Capacities from the plan (options may start them smaller: tests exercise growth).
  block_capacity_ = options_.block_capacity > 0 ? options_.block_capacity : static_cast<int>(plan_.block_capacity);
  table_.allocate(block_capacity_, stream_);
  grid_[0].allocate(block_capacity_);
  grid_[1].allocate(block_capacity_);
  velocity_.allocate(block_capacity_);
  if (fbar_) fbar_sums_.allocate(block_capacity_);
  if (asflip_) {
    transported_[0].allocate(block_capacity_);
    transported_[1].allocate(block_capacity_);
    old_velocity_.allocate(block_capacity_);
  }
  FBAR_CUDA_CHECK(cudaMemsetAsync(grid_[0].instance().data(), 0, grid_[0].bytes(), stream_));
  FBAR_CUDA_CHECK(cudaMemsetAsync(grid_[1].instance().data(), 0, grid_[1].bytes(), stream_));
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    BodyBase& body = *bodies_[b];
    // The flat upload needs ceil(N/32) bins; the grouped layouts need the plan's.
    const long long flat = (body.particles + 31) / 32;
    const int bins = options_.bin_capacity > 0 ? static_cast<int>(std::max<long long>(flat, options_.bin_capacity))
                                               : static_cast<int>(plan_.bin_capacity[b]);
    body.partition.allocate(block_capacity_, bins, decomposed() && options_.overlap_halo);  // the lists' only use
    body.allocate_bins(bins);
    if (positions && decomposed()) {
      std::vector<Vec3d> mine;
      std::vector<int> ids;
      const std::vector<Vec3d>& x = (*positions)[b];
      for (std::size_t p = 0; p < x.size(); ++p)
        if (owns(static_cast<int>(b), x[p])) {
          mine.push_back(x[p]);
          ids.push_back(static_cast<int>(p));
        }
      body.upload(mine.data(), ids.data(), mine.size(), 0, stream_);
    } else if (positions) {
      body.upload((*positions)[b].data(), nullptr, (*positions)[b].size(), 0, stream_);
    } else {
      upload_sampled(body);
    }
  }
  allocate_frames();
  std::size_t temp = 0;
  FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, temp, static_cast<int*>(nullptr), static_cast<int*>(nullptr),
                                                block_capacity_ + 1, stream_));
  scan_temp_.allocate(temp);
  scan_temp_bytes_ = temp;
  const std::size_t stats_bytes = sizeof(StepStats) + sizeof(BodyStepStats) * bodies_.size();
  stats_bytes_.allocate(stats_bytes);  // zeroed: the per-step readback also copies the structs' padding
  stats_d_ = reinterpret_cast<StepStats*>(stats_bytes_.get());
  body_stats_d_ = reinterpret_cast<BodyStepStats*>(stats_bytes_.get() + sizeof(StepStats));
  stats_h_ = mgsp_detail::pinned(stats_bytes);
  stats_ = static_cast<StepStats*>(stats_h_.get());
  body_stats_ = reinterpret_cast<BodyStepStats*>(static_cast<std::byte*>(stats_h_.get()) + sizeof(StepStats));
  wave_d_.allocate(2 * bodies_.size());
  p2g_bound_d_.allocate(2 * bodies_.size());  // zeroed
  bound_cur_ = 0;  // the initial P2G (float atomics) measures the bound of the first step into slot 1
  missing_d_.allocate(1);
  {
    std::vector<unsigned long long> bits(2 * bodies_.size());
    for (std::size_t b = 0; b < bodies_.size(); ++b) {
      double c = bodies_[b]->rest_wave_speed;
      std::memcpy(&bits[b], &c, sizeof(double));
      bits[bodies_.size() + b] = 0;
    }
    FBAR_CUDA_CHECK(cudaMemcpy(wave_d_.get(), bits.data(), sizeof(unsigned long long) * bits.size(),
                               cudaMemcpyHostToDevice));
  }

  // Layout 0 from the flat upload (storage bins[0], slot = ID).
  cur_ = 1;  // dest_from_positions and the partition write layout(1 - cur_) = layout(0)
  gc_ = 0;
  flat_source_ = true;
  reset_stats(false);
  for (auto& b : bodies_) {
    FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(0).count, 0, sizeof(int) * block_capacity_, stream_));
    b->dest_from_positions(*this, 0, nullptr, 0, b->particles);
  }
  partition_after_g2p2g();
  read_stats();
  while (handle_overflow()) {
  }
  for (auto& b : bodies_) {
    take_layout_stats(*b, 0);
    if (body_stats_[b->index].particles != b->particles)
      throw std::runtime_error("GpuEngine: initial partition placed " + std::to_string(body_stats_[b->index].particles) +
                               " of " + std::to_string(b->particles) + " particles of body " + std::to_string(b->index));
  }
  block_count_ = stats_->block_count;
  if (decomposed()) {  // the initial P2G writes the footprints of layout 0: halo lists first
    rebuild_halo(-1);
  }
  flat_source_ = false;
  for (auto& b : bodies_)  // the initial G2P2G writes bins[1] in layout(0) order
    if (b->bins_capacity(1) < b->partition.bin_capacity()) b->reallocate_bins(1, b->partition.bin_capacity());

  // The P2G of the initial state with dt_0 (the CPU engine's first next_dt(); a restart's next dt).
  double dt0 = k_.default_dt;
  for (const auto& b : bodies_)
    dt0 = min_time_step(dt0, cfl_time_step(b->spec.material.cfl, scene_.simulation.dx, b->rest_wave_speed, max_grid_speed_));
  const io::Checkpoint* restart = options_.restart;
  if (restart) {
    dt0 = restart->next_dt;
    checkpoint_keep_ = true;  // the initial P2G records v and C: a checkpoint or snapshot may follow at once
    update_record();
  }
  cur_ = 0;
  gc_ = 1;  // the initial P2G goes into grid[1 - gc_] = grid[0]
  reset_stats(false);
  {
    // dt_next of the initial P2G is dt0: written by compute_next_dt with a fixed dt.
    DtParams dp{};
    dp.body_count = 0;
    dp.wave_speed = wave_d_.get();
    dp.fixed_dt = dt0;
    dp.t_next = time_;
    dp.t_target = std::numeric_limits<double>::infinity();
    dp.stats = stats_d_;
    dp.scale = 1.0;
    compute_next_dt<<<1, 1, 0, stream_>>>(dp);
    mgsp_detail::check_launch("compute_next_dt");
  }
  grid_[0].clear(0, block_capacity_, stream_);
  if (asflip_) transported_[0].clear(0, block_capacity_, stream_);
  for (auto& b : bodies_) {
    FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(1).count, 0, sizeof(int) * block_capacity_, stream_));
    b->source_slots = b->total_bins[0] * 32;
    b->pending_particles = b->particles;
  }
  ensure_emigrant_lists();
  for (auto& b : bodies_) b->g2p2g(*this, true, T(0));
  if (decomposed()) {
    if (asflip_)
      halo_exchange({{grid_[0].instance().data(), GridBuffer<TG>::kBlockBytes},
                     {transported_[0].instance().data(), GridVelocityBuffer<TG>::kBlockBytes}},
                    0);
    else
      halo_exchange({{grid_[0].instance().data(), GridBuffer<TG>::kBlockBytes}}, 0);
    migrate_particles();
  }
  partition_after_g2p2g();
  read_stats();
  while (handle_overflow()) {
  }
  if (decomposed()) {
    settle_migration();
    agree_on_try();
    if (migrant_most_ > migrant_capacity_)  // the initial P2G moves nothing: no rank sends any
      throw std::runtime_error("GpuEngine: internal error: the initial P2G sent more particles than one message holds");
  }
  if (stats_->internal_error) throw std::runtime_error("GpuEngine: internal error in the initial P2G");
  for (auto& b : bodies_) {
    take_layout_stats(*b, 1);
    if (body_stats_[b->index].particles != b->pending_particles)
      throw std::runtime_error("GpuEngine: the initial P2G's partition placed " +
                               std::to_string(body_stats_[b->index].particles) + " of " +
                               std::to_string(b->pending_particles) + " particles of body " + std::to_string(b->index));
    b->particles = b->pending_particles;
  }
  migrated_ += pending_migrated_;
  block_count_ = stats_->block_count;
  if (decomposed() && halo_grew_) rebuild_halo(0);
  cur_ = 1;
  gc_ = 0;
  // The initial G2P2G measured the wave speed of the state the run starts from into slot 1: the first step's dt
  // reads it (with the rest wave speed as a floor), as every later step reads what the step before measured. A
  // restart then takes the dt the uninterrupted run took (slot 0 held only the rest wave speed: 1e-7 m apart after
  // 40 steps of a dam break).
  wave_cur_ = 1;
  bound_cur_ = 1;
  dt_p2g_ = dt0;
  next_dt_ = dt0;
  aux_valid_ = record_;
  for (auto& b : bodies_) std::vector<T>().swap(b->restart_state);  // uploaded (restart or has_attributes)
  if (restart) {
    checkpoint_keep_ = false;
    update_record();
    steps_ = restart->steps;
    last_dt_ = restart->last_dt;
    dt_scale_ = restart->dt_scale;
    dt_scale_at_compute_ = restart->dt_scale;
    next_dt_ = restart->next_dt;
    clean_steps_ = restart->clean_steps;
    for (auto& b : bodies_) {  // uploaded and scattered: the host copies are not needed again
      std::vector<Vec3<T>>().swap(b->initial_v_host);
      mgsp_detail::DeviceArray<T> done;
      b->initial_C.swap(done);
    }
  }
  ensure_step_capacity();  // the first step writes bins[0], sized for the flat upload only
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::restore_bodies(const io::Checkpoint& cp) {
  io::check_matches(cp, scene_);
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const io::CheckpointBody& c = cp.bodies[static_cast<std::size_t>(b.index)];
    const std::string where = "--restart: bodies[" + std::to_string(b.index) + "]";
    const int S = b.stored_scalars() - 3;  // = c.state_scalars (check_matches)
    const std::size_t n = c.particles();
    if (static_cast<long long>(n) != b.global_particles)
      throw std::invalid_argument(where + ": " + std::to_string(n) + " particles in the checkpoint, " +
                                  std::to_string(b.global_particles) + " given");
    for (std::size_t p = 0; p < n; ++p)
      if (c.id[p] != static_cast<std::int64_t>(p))
        throw std::invalid_argument(where + ": the GPU engine restarts from particles in ID order "
                                    "(io::read_checkpoint_set)");
    if (n > 0) {
      b.mass = static_cast<T>(c.mass[0]);
      b.volume = static_cast<T>(c.volume[0]);
      for (std::size_t p = 0; p < n; ++p)
        if (static_cast<T>(c.mass[p]) != b.mass || static_cast<T>(c.volume[p]) != b.volume)
          throw std::invalid_argument(where + ": particle " + std::to_string(p) +
                                      " has its own mass or volume; the GPU engine keeps one per body (restart "
                                      "this checkpoint on the CPU engine, --backend=cpu)");
    }
    b.restart_state.resize(static_cast<std::size_t>(S) * n);
    for (std::size_t i = 0; i < b.restart_state.size(); ++i) b.restart_state[i] = static_cast<T>(c.state[i]);
    std::vector<T> C(9 * n);
    for (std::size_t i = 0; i < C.size(); ++i) C[i] = static_cast<T>(c.C[i]);
    b.initial_C.allocate(std::max<std::size_t>(C.size(), 1));
    if (!C.empty())
      FBAR_CUDA_CHECK(cudaMemcpy(b.initial_C.get(), C.data(), sizeof(T) * C.size(), cudaMemcpyHostToDevice));
  }
  time_ = cp.time;
  max_grid_speed_ = cp.max_grid_speed;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::upload_sampled(BodyBase& body) {
  // Batches of whole x-planes of about kSampleBatchParticles, uploaded in ID order; a batch ends on a multiple of
  // 32 particles (the rest waits for the next), so every upload fills whole bins of the flat layout. A decomposed
  // run keeps the particles of its slab (with their IDs: the sampling order over the whole body).
  const BodySampler sampler(body.spec, scene_.simulation, body.index);
  const std::vector<long long>& per_plane = counts_[body.index].per_plane;
  std::vector<Vec3d> sampled, pending;  // sampled: a decomposed rank's batch before it keeps its slab's points
  std::vector<int> pending_ids;         // a decomposed rank's IDs (one GPU: slot = ID, no list)
  long long next_id = 0, next_slot = 0, plane = 0;
  const long long planes = sampler.planes();
  while (plane < planes) {
    long long end = plane, n = static_cast<long long>(pending.size());
    while (end < planes && (end == plane || n + per_plane[static_cast<std::size_t>(end)] <= options_.sample_batch))
      n += per_plane[static_cast<std::size_t>(end++)];
    if (decomposed()) {
      sampled.clear();
      sampler.sample_planes(plane, end, sampled);
      for (const Vec3d& x : sampled) {
        if (owns(body.index, x)) {
          pending.push_back(x);
          pending_ids.push_back(static_cast<int>(next_id));
        }
        ++next_id;
      }
    } else {
      const std::size_t before = pending.size();
      sampler.sample_planes(plane, end, pending);
      next_id += static_cast<long long>(pending.size() - before);
    }
    plane = end;
    const std::size_t send = plane == planes ? pending.size() : pending.size() / 32 * 32;
    if (next_slot + static_cast<long long>(send) > body.particles)
      throw std::runtime_error("GpuEngine: sampling body " + std::to_string(body.index) + " gave more particles than counted");
    body.upload(pending.data(), decomposed() ? pending_ids.data() : nullptr, send, next_slot, stream_);
    next_slot += static_cast<long long>(send);
    pending.erase(pending.begin(), pending.begin() + static_cast<std::ptrdiff_t>(send));
    if (decomposed()) pending_ids.erase(pending_ids.begin(), pending_ids.begin() + static_cast<std::ptrdiff_t>(send));
  }
  if (next_slot != body.particles || next_id != body.global_particles)
    throw std::runtime_error("GpuEngine: sampling body " + std::to_string(body.index) + " gave " +
                             std::to_string(next_slot) + " of " + std::to_string(next_id) + " particles here, " +
                             std::to_string(body.particles) + " of " + std::to_string(body.global_particles) +
                             " counted");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_record_velocities(bool on) {
  record_user_ = on;
  update_record();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::update_record() {
  record_ = record_user_ || sensor_keep_ || checkpoint_keep_;
  if (record_) ensure_aux();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::allocate_frames() {
  if (!options_.frames) return;
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;  // frame_attrs: resolved for the plan
    const FrameNeeds needs = frame_needs(b.frame_attrs);
    FrameCapture<T> cap;
    if (frame_float_columns(b.frame_attrs) > kMaxFrameColumns)
      throw std::invalid_argument("bodies[" + std::to_string(b.index) + "].output_attribs: more than " +
                                  std::to_string(kMaxFrameColumns) + " attributes besides ID");
    for (const FrameAttributeSpec& a : b.frame_attrs)
      if (a.column.quantity != FrameQuantity::Id) cap.column[cap.column_count++] = a.column;
    cap.sigma = needs.sigma;
    // One GPU: one entry per ID. A decomposed rank: its particles now, with room for arrivals (prepare_capture
    // grows it), in ID order through the directory.
    const std::size_t n = decomposed() ? static_cast<std::size_t>(b.particles) * 5 / 4 + 1024
                                       : static_cast<std::size_t>(b.particles);
    cap.particles = static_cast<int>(n);
    b.frame_capacity = n;
    if (decomposed()) {
      const std::size_t words = static_cast<std::size_t>((b.global_particles + 31) / 32);
      b.id_bits.allocate(std::max<std::size_t>(words, 1));
      b.id_offset.allocate(words + 1);
      b.id_counts.allocate(words + 1);
      std::size_t temp = 0;
      FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, temp, static_cast<int*>(nullptr), static_cast<int*>(nullptr),
                                                    static_cast<int>(words) + 1, stream_));
      b.id_scan_temp.allocate(std::max<std::size_t>(temp, 1));
      cap.id_bits = b.id_bits.get();
      cap.id_offset = b.id_offset.get();
    }
    b.frame_x.allocate(3 * n);
    b.frame_columns.allocate(static_cast<std::size_t>(cap.column_count) * n);
    cap.x = b.frame_x.get();
    cap.columns = b.frame_columns.get();
    b.capture = cap;
    FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&b.frame_copied, cudaEventDisableTiming));
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_aux() {
  for (auto& b : bodies_) {
    const std::size_t need = b->partition.slots() * kAuxScalars;
    if (b->aux.size() < need) b->aux.allocate(need);
  }
}

// =====================================================================================================================
// Step pieces

template <typename T, typename TG>
void MgspBenchmark<T, TG>::reset_stats(bool partition_only) {
  mgsp_detail::reset_step_stats<<<1, 64, 0, stream_>>>(stats_d_, body_stats_d_, body_count(), partition_only);
  mgsp_detail::check_launch("reset_step_stats");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::partition_after_g2p2g() {
  const int next = 1 - cur_;
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const LayoutView nl = b.partition.layout(next);
    activate_footprint<TG><<<mgsp_detail::grid_for(block_capacity_, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        nl.count, block_capacity_, table_.view(), grid_[0].instance(), grid_[1].instance());
    mgsp_detail::check_launch("activate_footprint");
  }
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const LayoutView nl = b.partition.layout(next);
    blocks_to_bins<<<mgsp_detail::grid_for(block_capacity_ + 1, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        nl.count, b.partition.bins_per_block(), block_capacity_);
    mgsp_detail::check_launch("blocks_to_bins");
    std::size_t temp = scan_temp_bytes_;
    FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(scan_temp_.get(), temp, b.partition.bins_per_block(), nl.bin_offset,
                                                  block_capacity_ + 1, stream_));
    finalize_layout<<<1, 1, 0, stream_>>>(nl.bin_offset, block_capacity_, b.partition.bin_capacity(),
                                          body_stats_d_ + b.index, stats_d_, table_.counters());
    mgsp_detail::check_launch("finalize_layout");
    // The previous layout's slots: those of layout(cur) (a G2P2G wrote bins[next] in that order), or the flat
    // upload before the first layout exists.
    const bool flat = flat_source_;
    const int* valid = flat ? nullptr : b.partition.layout(cur_).src;
    const int slots = flat ? b.particles : b.source_slots;
    if (slots > 0) {
      scatter_src<<<mgsp_detail::grid_for(slots, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
          b.partition.dest(), valid, b.particles, slots, nl.bin_offset, nl.src, b.partition.bin_capacity(),
          body_stats_d_ + b.index);
      mgsp_detail::check_launch("scatter_src");
    }
    pad_src<<<mgsp_detail::grid_for(block_capacity_, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        nl.count, nl.bin_offset, block_capacity_, nl.src, b.partition.bin_capacity());
    mgsp_detail::check_launch("pad_src");
    if (b.partition.ordered()) list_blocks(b, next, &body_stats_d_[b.index].halo_blocks);
  }
  if (decomposed()) collect_halo();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::list_blocks(BodyBase& b, int l, int* counters) {
  static_assert(offsetof(BodyStepStats, interior_blocks) == offsetof(BodyStepStats, halo_blocks) + sizeof(int),
                "list_particle_blocks counts into two adjacent ints");
  // Rank r's particle planes [lo, hi) scatter into grid planes [lo, hi]: plane lo is shared with rank r - 1 and
  // plane hi with rank r + 1, so the particle planes lo and hi - 1 are the halo particle planes.
  const int first_lo = halo_[0].peer >= 0 ? halo_[0].plane : INT_MIN;
  const int first_hi = halo_[1].peer >= 0 ? halo_[1].plane - 1 : INT_MIN;
  FBAR_CUDA_CHECK(cudaMemsetAsync(counters, 0, 2 * sizeof(int), stream_));
  const int capacity = b.partition.block_capacity();
  list_particle_blocks<<<mgsp_detail::grid_for(capacity, kHaloThreads), kHaloThreads, 0, stream_>>>(
      b.partition.layout(l).count, capacity, table_.view(), slab_.axis, first_lo, first_hi, b.partition.layout(l).order,
      counters);
  mgsp_detail::check_launch("list_particle_blocks");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::read_stats() {
  FBAR_CUDA_CHECK(cudaMemcpyAsync(stats_h_.get(), stats_bytes_.get(), stats_bytes_.bytes(), cudaMemcpyDeviceToHost,
                                  stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
}

template <typename T, typename TG>
cuda::OutOfMemory MgspBenchmark<T, TG>::growth_failure(const std::string& what, const cuda::OutOfMemory& e) const {
  return cuda::OutOfMemory("GpuEngine: at step " + std::to_string(steps_ + 1) + " (t = " + mgsp_detail::format_g(time_) +
                           " s) " + what + ", " + format_bytes(static_cast<double>(device_bytes())) + " held): " +
                           e.what() +
                           ". fbar --check plans the memory at start; a scene that spreads needs room to grow: "
                           "coarser default_dx, fewer ppc, or more GPUs");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_blocks(int needed) {
  long long wanted = block_capacity_;
  while (wanted < needed) wanted *= 2;
  if (wanted > DeviceLimits::kMaxBlocks)
    throw std::runtime_error("GpuEngine: the active grid needs " + std::to_string(wanted) + " blocks at step " +
                             std::to_string(steps_ + 1) + "; at most " + std::to_string(DeviceLimits::kMaxBlocks) +
                             " per device (docs/user_guide.md \"Limits\")");
  const int capacity = static_cast<int>(wanted);
  try {
    grow_blocks_to(capacity);
  } catch (const cuda::OutOfMemory& e) {
    throw growth_failure("the active grid outgrew its capacity (" + std::to_string(block_capacity_) + " -> " +
                             std::to_string(capacity) + " blocks",
                         e);
  }
  peak_bytes_ = std::max(peak_bytes_, device_bytes());
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_blocks_to(int capacity) {
  if (log_)
    *log_ << "fbar: GPU engine: grid blocks " << block_capacity_ << " -> " << capacity << " (hash table, grids)\n";
  const int keep = std::min(block_capacity_, std::max(block_count_, stats_->block_count));
  table_.grow(capacity, stream_);
  grid_[0].grow(capacity, keep, stream_);
  grid_[1].grow(capacity, keep, stream_);
  velocity_.grow(capacity, keep, stream_);
  if (fbar_) fbar_sums_.grow(capacity, 0, stream_);  // refilled before every use
  if (asflip_) {
    transported_[0].grow(capacity, keep, stream_);
    transported_[1].grow(capacity, keep, stream_);
    old_velocity_.grow(capacity, keep, stream_);
  }
  grid_[0].clear(keep, capacity, stream_);
  grid_[1].clear(keep, capacity, stream_);
  for (auto& b : bodies_) {
    b->partition.grow_blocks(capacity, cur_, stream_);
    // The kept layout's list again, at the new capacity (same counts: the same H and I the host holds).
    if (b->partition.ordered()) list_blocks(*b, cur_, b->partition.list_counters());
  }
  block_capacity_ = capacity;
  std::size_t temp = 0;
  FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, temp, static_cast<int*>(nullptr), static_cast<int*>(nullptr),
                                                block_capacity_ + 1, stream_));
  scan_temp_.allocate(temp);
  scan_temp_bytes_ = temp;
  if (placed_) mark_not_counted();  // per table block: the flags at the new capacity
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_bins(BodyBase& b, int keep, int needed) {
  long long wanted = std::max(64, b.partition.bin_capacity());
  while (wanted < needed) wanted = wanted + wanted / 2;
  const long long max_bins = DeviceLimits::kMaxSlots / 32;
  if (needed > max_bins)
    throw std::runtime_error("GpuEngine: body " + std::to_string(b.index) + " needs " + std::to_string(32LL * needed) +
                             " particle slots at step " + std::to_string(steps_ + 1) + "; at most " +
                             std::to_string(DeviceLimits::kMaxSlots) + " per body and device (docs/user_guide.md \"Limits\")");
  const int capacity = static_cast<int>(std::min(wanted, max_bins));
  try {
    grow_bins_to(b, keep, capacity);
  } catch (const cuda::OutOfMemory& e) {
    throw growth_failure("the particle bins of body " + std::to_string(b.index) + " outgrew their capacity (" +
                             std::to_string(b.partition.bin_capacity()) + " -> " + std::to_string(capacity) + " bins",
                         e);
  }
  peak_bytes_ = std::max(peak_bytes_, device_bytes());
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_for_arrivals(BodyBase& b, int written, long long needed) {
  if (needed > DeviceLimits::kMaxSlots / 32)
    throw std::runtime_error("GpuEngine: rank " + std::to_string(rank()) + " needs " + std::to_string(32 * needed) +
                             " particle slots for body " + std::to_string(b.index) + " at step " +
                             std::to_string(steps_ + 1) + "; at most " + std::to_string(DeviceLimits::kMaxSlots) +
                             " per body and device (docs/user_guide.md \"Limits\")");
  // The destinations G2P2G recorded (the partition's growth does not keep them).
  mgsp_detail::DeviceArray<ParticleDest> dest;
  dest.allocate(static_cast<std::size_t>(std::max(written, 1)));
  if (written > 0)
    FBAR_CUDA_CHECK(cudaMemcpyAsync(dest.get(), b.partition.dest(), sizeof(ParticleDest) * written,
                                    cudaMemcpyDeviceToDevice, stream_));
  if (needed > b.partition.bin_capacity()) grow_bins(b, cur_, static_cast<int>(needed));
  if (written > 0)
    FBAR_CUDA_CHECK(cudaMemcpyAsync(b.partition.dest(), dest.get(), sizeof(ParticleDest) * written,
                                    cudaMemcpyDeviceToDevice, stream_));
  if (b.bins_capacity(1 - cur_) < b.partition.bin_capacity())
    b.grow_bins_keeping(1 - cur_, b.partition.bin_capacity(), written, stream_);
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  peak_bytes_ = std::max(peak_bytes_, device_bytes());
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_bins_to(BodyBase& b, int keep, int capacity) {
  if (log_)
    *log_ << "fbar: GPU engine: body " << b.index << " particle bins " << b.partition.bin_capacity() << " -> "
          << capacity << "\n";
  b.partition.grow_bins(capacity, keep, stream_);
  if (record_ || b.aux.size() != 0) {
    // Keep what the last G2P2G recorded (a frame may still read it).
    mgsp_detail::DeviceArray<T> bigger;
    bigger.allocate(b.partition.slots() * kAuxScalars);
    if (b.aux.size())
      FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.get(), b.aux.get(), b.aux.bytes(), cudaMemcpyDeviceToDevice, stream_));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
    b.aux.swap(bigger);
  }
}

/// After read_stats: grows the table/grids or the bins if the partition overflowed, then redoes the partition from
/// the particles' new positions. Returns true when it did (read_stats() was called again).
template <typename T, typename TG>
bool MgspBenchmark<T, TG>::handle_overflow() {
  bool grew = false;
  if (stats_->table_overflow > 0 || stats_->block_count > block_capacity_) {
    grow_blocks(2 * block_capacity_);
    grew = true;
  }
  for (auto& b : bodies_)
    if (body_stats_[b->index].total_bins > b->partition.bin_capacity()) {
      grow_bins(*b, cur_, body_stats_[b->index].total_bins * 3 / 2);
      grew = true;
    }
  if (!grew) return false;
  // Redo: dest and counts of the next layout from the positions G2P2G wrote (bins[1 - cur] in layout(cur) order).
  reset_stats(true);
  const int next = 1 - cur_;
  for (auto& b : bodies_) {
    FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(next).count, 0, sizeof(int) * block_capacity_, stream_));
    if (flat_source_)
      b->dest_from_positions(*this, 0, nullptr, 0, b->particles);
    else
      b->dest_from_positions(*this, next, b->partition.layout(cur_).src, 0, b->source_slots);
  }
  partition_after_g2p2g();
  read_stats();
  return true;
}

template <typename T, typename TG>
std::vector<FailureReport> MgspBenchmark<T, TG>::failures_of_try(double dt) const {
  std::vector<FailureReport> out;
  static constexpr FailureKind kKinds[kFailKinds] = {FailureKind::NonFinite, FailureKind::CflViolation,
                                                     FailureKind::LeftDomain, FailureKind::Inverted};
  for (const auto& b : bodies_) {
    const BodyStepStats& s = body_stats_[b->index];
    for (int k = 0; k < kFailKinds; ++k) {
      if (s.failures[k] == 0) continue;
      FailureReport f;
      f.kind = kKinds[k];
      f.body = b->index;
      f.step = steps_ + 1;
      f.time = time_;
      f.dt = static_cast<double>(static_cast<T>(dt));  // the step size the kernels used (as the CPU engine reports)
      f.count = s.failures[k];
      f.first_particle = s.first_id[k];
      out.push_back(f);
    }
  }
  return out;
}

template <typename T, typename TG>
StepReport MgspBenchmark<T, TG>::step_impl(double dt, bool cfl_dt, double target, double following) {
  if (!(dt > 0.0) || !std::isfinite(dt)) throw std::invalid_argument("GpuEngine::step: dt must be positive");
  // Seeded or restarted velocities (by ID): read by the initial P2G and by frame 0's capture; not needed any more.
  for (auto& b : bodies_)
    if (b->initial_v.size()) {
      mgsp_detail::DeviceArray<T> done;
      b->initial_v.swap(done);
    }
  StepReport report;
  int range_repeats = 0, migration_tries = 0;
  for (;;) {
    reset_stats(false);
    for (auto& b : bodies_) {
      b->source_slots = b->total_bins[cur_] * 32;
      b->pending_particles = b->particles;
    }
    ensure_emigrant_lists();
    pending_migrated_ = 0;
    // 0. the grid must hold the impulse of this dt
    if (dt != dt_p2g_) {
      for (auto& b : bodies_) b->rescale_impulse(*this, static_cast<T>(dt - dt_p2g_));
      if (decomposed()) halo_exchange({{grid_[gc_].instance().data(), GridBuffer<TG>::kBlockBytes}}, gc_, true);
      dt_p2g_ = dt;
    }
    event_record(0);
    // 1. grid update
    {
      GridUpdateParams<TG> gp{};
      gp.grid = grid_[gc_].instance();
      gp.velocity = velocity_.instance();
      if (asflip_) {
        gp.transported = transported_[gc_].instance();
        gp.old_velocity = old_velocity_.instance();
      }
      gp.coords = table_.view().coords;
      gp.block_count = block_count_;
      gp.dt = static_cast<TG>(dt);
      gp.dx = kg_.dx;
      gp.gravity = kg_.gravity;
      gp.boundaries.count = 0;
      gp.boundaries.profiles = kg_.profiles;
      for (std::size_t i = 0; i < kg_.boundaries.size(); ++i)
        if (boundary_active(kg_.boundaries[i], time_)) gp.boundaries.b[gp.boundaries.count++] = kg_.boundary_at_time(i, time_);
      gp.stats = stats_d_;
      if (block_count_ > 0) {
        update_grid_velocity_query_max<TG><<<mgsp_detail::grid_for(block_count_, kGridUpdateThreads / 64),
                                            kGridUpdateThreads, 0, stream_>>>(gp);
        mgsp_detail::check_launch("update_grid_velocity_query_max");
      }
      if (grid_sample_slot_ >= 0 && grid_sensors_.count > 0) {  // a sample step (each try overwrites the slot)
        SensorAccum* out = grid_samples_d_.get() + static_cast<std::size_t>(grid_sample_slot_) * grid_sensors_.count;
        GridSensorSampleParams<TG> sp{};
        sp.grid = gp.grid;
        sp.velocity = gp.velocity;
        sp.coords = gp.coords;
        sp.block_count = block_count_;
        sp.dt = gp.dt;
        sp.dx = gp.dx;
        sp.gravity = gp.gravity;
        sp.slab = slab_;
        sp.not_counted = placed_ ? not_counted_.get() : nullptr;
        sp.sensors = grid_sensors_;
        sp.partials = sensor_partials_d_.get();
        const long long nodes = static_cast<long long>(block_count_) * 64;
        const int per_sensor = static_cast<int>(
            std::clamp<long long>((nodes + kSensorThreads - 1) / kSensorThreads, 1, kSensorBlocks));
        sample_grid_sensors<TG><<<dim3(per_sensor, grid_sensors_.count), kSensorThreads, 0, stream_>>>(sp);
        mgsp_detail::check_launch("sample_grid_sensors");
        merge_sensor_partials<<<1, GridSensorSet<TG>::kMax, 0, stream_>>>(sp.partials, per_sensor, grid_sensors_.count,
                                                                          out);
        mgsp_detail::check_launch("merge_sensor_partials");
      }
    }
    // 2. dt of the next step (its P2G impulse)
    {
      DtParams dp{};
      dp.body_count = body_count();
      for (const auto& b : bodies_) dp.bodies[b->index] = DtBody{b->spec.material.cfl, b->rest_wave_speed};
      dp.wave_speed = wave_d_.get() + wave_cur_ * bodies_.size();
      dp.default_dt = k_.default_dt;
      dp.dx = scene_.simulation.dx;
      dp.scale = dt_scale_;
      dp.fixed_dt = cfl_dt ? 0.0 : dt;
      // A step that reaches the target ends exactly on it (step_toward sets the clock so): time_ + dt may miss it
      // by an ulp, which would leave the next step a sliver of 1e-19 s.
      const bool reaches = dt >= target - time_;
      dp.t_next = reaches ? target : time_ + dt;
      // Landing on the target, the next step heads for `following`: its dt is clamped for that one.
      dp.t_target = reaches && !std::isnan(following) ? following : target;
      dp.stats = stats_d_;
      if (decomposed()) {  // the maxima are stored as the bits of non-negative doubles: reduce them as doubles,
        // the grid speed and every body's wave speed in one message (one NCCL call a step)
        if (dt_inputs_d_.size() < bodies_.size() + 1) dt_inputs_d_.allocate(bodies_.size() + 1);
        gather_dt_inputs<<<1, DtParams::kMaxBodies, 0, stream_>>>(stats_d_, wave_d_.get() + wave_cur_ * bodies_.size(),
                                                                   body_count(), dt_inputs_d_.get());
        mgsp_detail::check_launch("gather_dt_inputs");
        device_->allreduce_max(reinterpret_cast<double*>(dt_inputs_d_.get()), body_count() + 1, stream_);
        dp.reduced = dt_inputs_d_.get();
      }
      compute_next_dt<<<1, 1, 0, stream_>>>(dp);
      mgsp_detail::check_launch("compute_next_dt");
    }
    event_record(1);
    // 3. G2P2G
    grid_[1 - gc_].clear(0, block_count_, stream_);
    // New blocks appear during G2P2G (its leader threads zero them in grid_); the transported sums are cleared whole.
    if (asflip_) transported_[1 - gc_].clear(0, block_capacity_, stream_);
    FBAR_CUDA_CHECK(cudaMemsetAsync(wave_d_.get() + (1 - wave_cur_) * bodies_.size(), 0,
                                    sizeof(unsigned long long) * bodies_.size(), stream_));
    FBAR_CUDA_CHECK(cudaMemsetAsync(p2g_bound_d_.get() + (1 - bound_cur_) * bodies_.size(), 0,
                                    sizeof(unsigned long long) * bodies_.size(), stream_));
    for (auto& b : bodies_)
      FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(1 - cur_).count, 0, sizeof(int) * block_capacity_, stream_));
    if (capture_next_)  // the device frames are overwritten: their last download must be done
      for (auto& b : bodies_) {
        if (b->frame_copied) FBAR_CUDA_CHECK(cudaStreamWaitEvent(stream_, b->frame_copied, 0));
        if (decomposed() && b->capture.x) prepare_capture(*b);
      }
    if (decomposed() && !options_.overlap_halo && !placed_) {
      // The halo sums and the migration in one exchange (one NCCL group a step): both follow the whole G2P2G.
      for (auto& b : bodies_) b->g2p2g(*this, false, static_cast<T>(dt));
      event_record(2);
      const BlockBuffers halo = step_halo_buffers(1 - gc_);
      std::vector<comm::DeviceTransport::Message> messages = pack_halo_messages(halo, stream_);
      MigrantMessage msg;
      const std::vector<comm::DeviceTransport::Message> migrants = pack_migrant_messages(msg);
      messages.insert(messages.end(), migrants.begin(), migrants.end());
      device_->exchange(messages, stream_);
      add_halo_messages(halo, 1 - gc_, false, stream_);
      event_record(4);
      unpack_migrant_messages(msg);
      event_record(5);
    } else if (decomposed()) {
      g2p2g_and_halo(static_cast<T>(dt));
      event_record(4);
      migrate_particles();
      event_record(5);
    } else {
      for (auto& b : bodies_) b->g2p2g(*this, false, static_cast<T>(dt));
      event_record(2);
      event_record(4);
      event_record(5);
    }
    // 4. partition of the next step
    partition_after_g2p2g();
    event_record(3);
    // 5. the step's one readback
    read_stats();
    if (decomposed()) {
      settle_migration();
      agree_on_try();
    }
    if (stats_->internal_error)
      throw std::runtime_error("GpuEngine: internal error (" + std::to_string(stats_->internal_error) +
                               " arena lookups or particles outside their block) at step " +
                               std::to_string(steps_ + 1));
    if (decomposed() && migrant_most_ > migrant_capacity_) {
      // Some rank sent more particles one way than a message holds: every rank grows the messages alike and
      // repeats the try (the try's state is still the step's start). Twice in a row is an engine bug.
      if (++migration_tries > 2)
        throw std::runtime_error("GpuEngine: the migration messages did not grow enough at step " +
                                 std::to_string(steps_ + 1));
      migrant_capacity_ = std::max(2 * migrant_capacity_, 2 * migrant_most_);
      ++migration_repeats_;
      continue;
    }
    // A step that used more than half of the messages' room grows them for the next one (every rank alike).
    if (decomposed() && 2 * migrant_most_ > migrant_capacity_) migrant_capacity_ = 2 * migrant_most_;
    std::vector<FailureReport> failures = failures_of_try(dt);
    if (failures.empty() && stats_->p2g_range > 0) {
      // Contributions grew past the fixed-point bound (kernels/g2p2g_kernel.cuh): repeat the try with the bound it
      // measured, which covers every particle of the same state. Not a failure; twice in a row is an engine bug.
      if (++range_repeats > 2)
        throw std::runtime_error("GpuEngine: the fixed-point P2G bound did not converge at step " +
                                 std::to_string(steps_ + 1));
      bound_cur_ = 1 - bound_cur_;
      ++p2g_range_repeats_;
      block_count_ = std::max(block_count_, std::min(stats_->block_count, block_capacity_));
      continue;
    }
    if (failures.empty()) {
      while (handle_overflow()) {
      }
      for (const auto& b : bodies_)
        if (body_stats_[b->index].particles != b->pending_particles)
          throw std::runtime_error("GpuEngine: the partition of body " + std::to_string(b->index) + " placed " +
                                   std::to_string(body_stats_[b->index].particles) + " of " +
                                   std::to_string(b->pending_particles) + " particles at step " +
                                   std::to_string(steps_ + 1));
      if (timing_) {
        float ms = 0.f;
        FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[0], events_[1]));
        times_.grid_update_ms += ms;
        FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[1], events_[2]));
        times_.g2p2g_ms += ms;
        FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[2], events_[4]));
        times_.halo_ms += ms;
        if (decomposed() && options_.overlap_halo) {  // hidden: what the halo stream took beyond the exposed part
          float total = 0.f;
          FBAR_CUDA_CHECK(cudaEventElapsedTime(&total, halo_events_[0], halo_events_[1]));
          times_.halo_hidden_ms += std::max(0.f, total - ms);
        }
        FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[4], events_[5]));
        times_.migration_ms += ms;
        FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[5], events_[3]));
        times_.partition_ms += ms;
        ++times_.steps;
      }
      commit(dt);
      report.dt = dt;
      report.steps = 1;
      if (cfl_dt && dt_scale_ < 1.0 && ++clean_steps_ >= kRecoverSteps) {
        dt_scale_ = std::min(1.0, 2.0 * dt_scale_);
        clean_steps_ = 0;
      }
      return report;
    }
    if (scene_.simulation.on_failure == OnFailure::ReduceDt && report.retries < kMaxStepRetries) {
      if (log_)
        for (const FailureReport& f : failures)
          *log_ << "fbar: " << f.describe() << "; retrying the step with dt = " << mgsp_detail::format_g(dt / 2)
                << " s\n";
      report.retried.insert(report.retried.end(), failures.begin(), failures.end());
      ++report.retries;
      dt *= 0.5;
      if (cfl_dt) {
        dt_scale_ *= 0.5;
        clean_steps_ = 0;
      }
      // Blocks inserted by the failed try stay in the table (zeroed in both grids); count them from now on.
      block_count_ = std::max(block_count_, std::min(stats_->block_count, block_capacity_));
      continue;
    }
    report.ok = false;
    report.dt = dt;
    report.failures = std::move(failures);
    if (record_) aux_valid_ = false;  // the failed try wrote over the recorded v and C
    return report;
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::commit(double dt) {
  for (auto& b : bodies_) {
    take_layout_stats(*b, 1 - cur_);
    b->particles = b->pending_particles;
  }
  migrated_ += pending_migrated_;
  cur_ = 1 - cur_;
  gc_ = 1 - gc_;
  wave_cur_ = 1 - wave_cur_;
  bound_cur_ = 1 - bound_cur_;
  time_ += dt;
  ++steps_;
  if (capture_next_) captured_step_ = steps_;
  last_dt_ = dt;
  dt_p2g_ = stats_->dt_next;
  next_dt_ = stats_->dt_next;
  dt_scale_at_compute_ = dt_scale_;
  double max_speed_sq = 0.0;
  std::memcpy(&max_speed_sq, &stats_->max_speed_sq, sizeof(double));
  max_grid_speed_ = std::sqrt(max_speed_sq);
  block_count_ = stats_->block_count;
  aux_valid_ = record_;
  if (decomposed() && halo_grew_) rebuild_halo(gc_);  // agreed: all ranks or none
  // Headroom for the next step (grow between steps, never inside one): blocks at 3/4, bins at 9/10 of capacity.
  if (block_count_ > block_capacity_ * 3 / 4) grow_blocks(2 * block_capacity_);
  ensure_step_capacity();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_step_capacity() {
  for (auto& b : bodies_) {
    const int need = b->total_bins[cur_];
    if (need > b->partition.bin_capacity() * 9 / 10) grow_bins(*b, cur_, need * 3 / 2);
    // The next G2P2G writes bins[1 - cur] (the previous state, free now) in layout(cur) order: it must hold every
    // bin of that layout (the partition's bin capacity bounds it).
    if (b->bins_capacity(1 - cur_) < b->partition.bin_capacity()) b->reallocate_bins(1 - cur_, b->partition.bin_capacity());
  }
  peak_bytes_ = std::max(peak_bytes_, device_bytes());
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_grid_sensors(const std::vector<GridSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(GridSensorSet<TG>::kMax))
    throw std::invalid_argument("grid-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(GridSensorSet<TG>::kMax) + " per run");
  grid_sensors_ = GridSensorSet<TG>{};
  for (const GridSensorSpec& spec : sensors)
    grid_sensors_.s[grid_sensors_.count++] = make_grid_sensor_params<TG>(spec, static_cast<double>(k_.dx));
  grid_sample_slot_ = -1;
  if (grid_sensors_.count > 0) ensure_sensor_partials();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_grid_sample(int slot) {
  grid_sample_slot_ = slot;
  if (slot < 0 || grid_sensors_.count == 0) return;
  grow_samples(grid_samples_d_, static_cast<std::size_t>(slot + 1) * grid_sensors_.count);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_samples(mgsp_detail::DeviceArray<SensorAccum>& samples, std::size_t need) {
  if (samples.size() >= need) return;
  // Grow (rare: the slots of one frame interval), keeping the slots already sampled.
  mgsp_detail::DeviceArray<SensorAccum> bigger;
  bigger.allocate(std::max(need, 2 * samples.size()));
  if (samples.size())
    FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.get(), samples.get(), samples.bytes(), cudaMemcpyDeviceToDevice, stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  samples.swap(bigger);
}

template <typename T, typename TG>
std::vector<SensorAccum> MgspBenchmark<T, TG>::grid_samples(int slots) const {
  return download_samples(grid_samples_d_, static_cast<std::size_t>(slots) * grid_sensors_.count);
}

template <typename T, typename TG>
std::vector<SensorAccum> MgspBenchmark<T, TG>::download_samples(const mgsp_detail::DeviceArray<SensorAccum>& samples,
                                                                std::size_t n) const {
  std::vector<SensorAccum> host(n);
  if (n == 0) return host;
  if (samples.size() < n) throw std::logic_error("GpuEngine: fewer sensor slots were sampled than asked for");
  FBAR_CUDA_CHECK(cudaMemcpyAsync(host.data(), samples.get(), sizeof(SensorAccum) * n, cudaMemcpyDeviceToHost, stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  return host;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(ParticleSensorSet<T>::kMax))
    throw std::invalid_argument("particle-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(ParticleSensorSet<T>::kMax) + " per run");
  particle_sensors_ = ParticleSensorSet<T>{};
  particle_sensors_read_v_ = false;
  for (const ParticleSensorSpec& spec : sensors) {
    const ParticleSensorParams<T> p = make_particle_sensor_params<T>(spec);
    particle_sensors_read_v_ = particle_sensors_read_v_ || particle_sensor_reads_velocity(p.column);
    particle_sensors_.s[particle_sensors_.count++] = p;
  }
  if (particle_sensors_.count > 0) ensure_sensor_partials();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_sensor_partials() {
  // One sample's per-CUDA-block partials, shared by the grid and the particle sensors (at most kMax of each).
  static_assert(GridSensorSet<TG>::kMax == ParticleSensorSet<T>::kMax, "one partials buffer for both kinds");
  if (sensor_partials_d_.size() == 0)
    sensor_partials_d_.allocate(static_cast<std::size_t>(GridSensorSet<TG>::kMax) * kSensorBlocks);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::keep_particle_inputs(bool on) {
  // Only a sensor reading v or C pays for recording them, and only on the steps that may land on a sample time.
  sensor_keep_ = on && (particle_sensors_read_v_ || trackers_read_v_);
  update_record();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::keep_checkpoint_inputs(bool on) {
  checkpoint_keep_ = on;
  update_record();
}

template <typename T, typename TG>
io::Checkpoint MgspBenchmark<T, TG>::checkpoint() const {
  if (!checkpoint_ready())
    throw std::logic_error("GpuEngine::checkpoint: the last step did not record the particles' v and C "
                           "(keep_checkpoint_inputs(true) before it)");
  io::Checkpoint c;
  c.engine = "gpu";
  c.precision = to_string(scene_.simulation.precision);
  c.rank = rank();
  c.ranks = ranks();
  c.time = time_;
  c.steps = steps_;
  c.last_dt = last_dt_;
  c.next_dt = next_dt();
  c.max_grid_speed = max_grid_speed_;
  c.dt_scale = dt_scale_;
  c.clean_steps = clean_steps_;
  if (decomposed()) {
    c.slab_axis = slabs_.axis;
    c.slab_cuts = slabs_.cuts;
  }
  const bool initial = steps_ == 0 && !aux_valid_;  // before the first step: v = initial velocity, C = 0 exactly
  for (const auto& bp : bodies_) {
    const BodyBase& b = *bp;
    const std::vector<T> r = gather_host(b.index, stream_);
    const int S = b.stored_scalars();
    const int W = S + kAuxScalars;
    io::CheckpointBody out;
    out.law = to_string(b.spec.material.law);
    out.state_scalars = S - 3;
    out.global_particles = b.global_particles;
    out.max_wave_speed = b.rest_wave_speed;
    const Vec3d v0{{b.spec.velocity[0], b.spec.velocity[1], b.spec.velocity[2]}};
    const std::size_t n = static_cast<std::size_t>(b.particles);  // this rank's
    out.id.resize(n);
    out.x.resize(3 * n);
    out.v.resize(3 * n);
    out.C.resize(9 * n);
    out.mass.assign(n, static_cast<double>(b.mass));
    out.volume.assign(n, static_cast<double>(b.volume));
    out.state.resize(static_cast<std::size_t>(S - 3) * n);
    std::size_t k = 0;
    for (long long p = 0; p < b.global_particles; ++p) {
      const T* q = r.data() + static_cast<std::size_t>(p) * W;
      if (decomposed() && std::isnan(q[0])) continue;  // another rank's particle
      if (k == n) throw std::runtime_error("GpuEngine::checkpoint: more particles by ID than the rank holds");
      out.id[k] = p;
      for (int a = 0; a < 3; ++a) {
        out.x[3 * k + a] = static_cast<double>(q[a]);
        out.v[3 * k + a] = !initial                    ? static_cast<double>(q[S + a])
                           : b.initial_v_host.empty() ? v0[a]
                                                       : static_cast<double>(b.initial_v_host[static_cast<std::size_t>(p)][a]);
      }
      for (int i = 0; i < 9; ++i) out.C[9 * k + i] = initial ? 0.0 : static_cast<double>(q[S + 3 + i]);
      for (int i = 3; i < S; ++i) out.state[static_cast<std::size_t>(S - 3) * k + (i - 3)] = static_cast<double>(q[i]);
      out.max_wave_speed = std::max(out.max_wave_speed, b.wave_speed_of(q));
      ++k;
    }
    if (k != n)
      throw std::runtime_error("GpuEngine::checkpoint: " + std::to_string(k) + " particles found by ID, " +
                               std::to_string(n) + " held");
    c.bodies.push_back(std::move(out));
  }
  return c;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::sample_particles(int slot) {
  const int n = particle_sensors_.count;
  if (n == 0) return;
  const std::size_t per_slot = bodies_.size() * static_cast<std::size_t>(n);
  grow_samples(particle_samples_d_, static_cast<std::size_t>(slot + 1) * per_slot);
  const bool initial = steps_ == 0 && !aux_valid_;
  if (particle_sensors_read_v_ && !initial && !aux_valid_)
    throw std::logic_error("GpuEngine::sample_particles: the step that ended here did not record v and C "
                           "(keep_particle_inputs was not set for it)");
  for (auto& b : bodies_) {
    const int slots = b->total_bins[cur_] * 32;
    const int per_sensor = static_cast<int>(std::clamp<long long>((slots + kSensorThreads - 1) / kSensorThreads, 1,
                                                                  kSensorBlocks));
    SensorAccum* out = particle_samples_d_.get() + static_cast<std::size_t>(slot) * per_slot +
                       static_cast<std::size_t>(b->index) * n;
    b->sample_sensors(*this, aux_valid_ && particle_sensors_read_v_ ? b->aux.get() : nullptr, sensor_partials_d_.get(),
                      per_sensor);
    merge_sensor_partials<<<1, ParticleSensorSet<T>::kMax, 0, stream_>>>(sensor_partials_d_.get(), per_sensor, n, out);
    mgsp_detail::check_launch("merge_sensor_partials");
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_tracker(int body, const TrackerSet& set) {
  body_at(body);
  trackers_.resize(bodies_.size());
  trackers_[body] = set;
  for (int a = 0; a < set.attribs; ++a) trackers_read_v_ = trackers_read_v_ || particle_sensor_reads_velocity(set.column[a]);
  if (track_d_.size() == 0) track_d_.allocate(static_cast<std::size_t>(TrackerSet::kMaxIds) * (TrackerSet::kMaxAttribs + 1));
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::track(int body, std::vector<double>& values, std::vector<double>& present) {
  BodyBase& b = body_at(body);
  const TrackerSet empty{};
  const TrackerSet& t = static_cast<std::size_t>(body) < trackers_.size() ? trackers_[body] : empty;
  values.assign(static_cast<std::size_t>(t.ids) * t.attribs, 0.0);
  present.assign(t.ids, 0.0);
  if (t.ids == 0) return;
  const bool initial = steps_ == 0 && !aux_valid_;
  if (trackers_read_v_ && !initial && !aux_valid_)
    throw std::logic_error("GpuEngine::track: the step that ended here did not record v and C");
  double* v_d = track_d_.get();
  double* present_d = v_d + static_cast<std::size_t>(TrackerSet::kMaxIds) * TrackerSet::kMaxAttribs;
  FBAR_CUDA_CHECK(cudaMemsetAsync(v_d, 0, track_d_.bytes(), stream_));
  b.track(*this, aux_valid_ ? b.aux.get() : nullptr, t, v_d, present_d);
  FBAR_CUDA_CHECK(cudaMemcpyAsync(values.data(), v_d, sizeof(double) * values.size(), cudaMemcpyDeviceToHost, stream_));
  FBAR_CUDA_CHECK(cudaMemcpyAsync(present.data(), present_d, sizeof(double) * present.size(), cudaMemcpyDeviceToHost,
                                  stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
}

template <typename T, typename TG>
std::vector<SensorAccum> MgspBenchmark<T, TG>::particle_samples(int slots) const {
  return download_samples(particle_samples_d_,
                          static_cast<std::size_t>(slots) * bodies_.size() * particle_sensors_.count);
}

template <typename T, typename TG>
StepReport MgspBenchmark<T, TG>::step_toward(double t_end, double t_following) {
  const StepPlan plan = plan_step_toward(time_, t_end, next_dt());  // the CPU engine's rule (engine_common.h)
  StepReport r = step_impl(plan.dt, true, t_end, t_following);
  if (r.ok && plan.last && r.retries == 0) time_ = t_end;  // land on the target exactly, not t_end +- round-off
  return r;
}

template <typename T, typename TG>
StepReport MgspBenchmark<T, TG>::advance_to(double t_end) {
  StepReport total;
  while (time_ < t_end && total.absorb(step_toward(t_end))) {
  }
  return total;
}

// =====================================================================================================================
// Queries and output

template <typename T, typename TG>
std::vector<T> MgspBenchmark<T, TG>::gather_host(int body, cudaStream_t s) const {
  BodyBase& b = body_at(body);
  const int W = b.stored_scalars() + kAuxScalars;
  // By ID over the whole body; a decomposed rank holds some IDs only (the others stay NaN: all bits set).
  const std::size_t n = static_cast<std::size_t>(b.global_particles) * W;
  mgsp_detail::DeviceArray<T> out;
  out.allocate(std::max<std::size_t>(n, 1));
  if (decomposed() && n) FBAR_CUDA_CHECK(cudaMemsetAsync(out.get(), 0xff, sizeof(T) * n, s));
  FBAR_CUDA_CHECK(cudaMemsetAsync(missing_d_.get(), 0, sizeof(int), s));
  auto* self = const_cast<MgspBenchmark*>(this);
  b.gather(*self, out.get(), missing_d_.get(), s);
  std::vector<T> host(n);
  int missing = 0;
  if (n) FBAR_CUDA_CHECK(cudaMemcpyAsync(host.data(), out.get(), sizeof(T) * n, cudaMemcpyDeviceToHost, s));
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&missing, missing_d_.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
  if (missing) throw std::runtime_error("GpuEngine: " + std::to_string(missing) + " particles with an invalid ID");
  return host;
}

template <typename T, typename TG>
ParticleSnapshot<T> MgspBenchmark<T, TG>::snapshot(int body) const {
  BodyBase& b = body_at(body);
  const std::vector<T> r = gather_host(body, stream_);
  const int S = b.stored_scalars();
  const int W = S + kAuxScalars;
  ParticleSnapshot<T> snap;
  const std::size_t n = static_cast<std::size_t>(b.global_particles);
  if (decomposed()) snap.present.assign(n, 0);
  snap.x.resize(n);
  snap.v.resize(n);
  snap.C.resize(n);
  snap.J.resize(n);
  snap.sigma.resize(n);
  if (b.stores_F()) snap.F.resize(n);
  if (b.stores_logJp()) snap.logJp.resize(n);
  const bool initial = steps_ == 0 && !aux_valid_;  // before the first step: v = initial velocity, C = 0 exactly
  const Vec3<T> v0{{static_cast<T>(b.spec.velocity[0]), static_cast<T>(b.spec.velocity[1]),
                    static_cast<T>(b.spec.velocity[2])}};
  for (std::size_t p = 0; p < n; ++p) {
    const T* q = r.data() + p * W;
    if (decomposed()) {
      if (std::isnan(q[0])) continue;
      snap.present[p] = 1;
    }
    snap.x[p] = Vec3<T>{{q[0], q[1], q[2]}};
    snap.v[p] = !initial ? Vec3<T>{{q[S], q[S + 1], q[S + 2]}} : b.initial_v_host.empty() ? v0 : b.initial_v_host[p];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) snap.C[p](i, j) = q[S + 3 + 3 * i + j];
    Mat3<T> F = Mat3<T>::identity(), sigma;
    T logJp = T(0);
    b.state_of(q, snap.J[p], F, sigma, logJp, snap.C[p]);
    snap.sigma[p] = sigma;
    if (b.stores_F()) snap.F[p] = F;
    if (b.stores_logJp()) snap.logJp[p] = logJp;
  }
  return snap;
}

template <typename T, typename TG>
io::ParticleFrame MgspBenchmark<T, TG>::frame(int body) const {
  const BodyBase& b = body_at(body);
  ParticleSnapshot<T> s = snapshot(body);
  // A decomposed rank's frame: its particles only, in ID order, with their IDs.
  std::vector<std::int64_t> ids;
  if (!s.present.empty()) {
    std::size_t w = 0;
    for (std::size_t p = 0; p < s.present.size(); ++p) {
      if (!s.present[p]) continue;
      ids.push_back(static_cast<std::int64_t>(p));
      s.x[w] = s.x[p];
      s.v[w] = s.v[p];
      s.C[w] = s.C[p];
      s.J[w] = s.J[p];
      s.sigma[w] = s.sigma[p];
      if (!s.F.empty()) s.F[w] = s.F[p];
      if (!s.logJp.empty()) s.logJp[w] = s.logJp[p];
      ++w;
    }
    for (auto* v : {&s.x, &s.v}) v->resize(w);
    for (auto* v : {&s.C, &s.sigma}) v->resize(w);
    s.J.resize(w);
    if (!s.F.empty()) s.F.resize(w);
    if (!s.logJp.empty()) s.logJp.resize(w);
  }
  FrameSource<T> src;
  if (!s.present.empty()) src.id = &ids;
  src.x = &s.x;
  src.v = &s.v;
  src.mass = [&](std::size_t) { return b.mass; };
  src.volume0 = [&](std::size_t) { return b.volume; };
  src.J = [&] { return s.J; };
  src.F = [&] {
    if (!b.stores_F()) throw std::invalid_argument("DefGrad: the body's material stores no deformation gradient");
    return s.F;
  };
  src.logJp = [&] {
    if (!b.stores_logJp()) throw std::invalid_argument("logJp: the body's material stores no plastic state");
    return s.logJp;
  };
  src.sigma = [&] { return s.sigma; };  // from the state and the recorded C (snapshot)
  return build_frame(b.spec, body, src, "GPU engine");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer) {
  // The frame is on the device already (the capture step, or capture_state before the first step). Its download
  // runs on the copy stream into the body's pinned buffer, which the writer thread turns into the file; the step
  // loop waits only when that buffer is still being read from the previous frame (output slower than simulation).
  BodyBase& b = body_at(body);
  if (!b.capture.x)
    throw std::logic_error("GpuEngine::submit_frame: frames were not planned (GpuEngineOptions::frames)");
  if (captured_step_ != steps_) {
    if (steps_ != 0 || captured_step_ >= 0)
      throw std::logic_error("GpuEngine::submit_frame: step " + std::to_string(steps_) +
                             " did not capture a frame (set_frame_capture(true) before the step that lands on it)");
    if (decomposed()) prepare_capture(b);
    b.capture_state(*this);
  }
  {
    const auto t0 = std::chrono::steady_clock::now();
    std::unique_lock<std::mutex> lock(b.frame_slot->mutex);
    while (b.frame_slot->busy) {
      b.frame_slot->released.wait_for(lock, std::chrono::milliseconds(50));
      if (b.frame_slot->busy && writer.failed()) {
        lock.unlock();
        writer.flush();  // rethrows the writer's error
        lock.lock();
      }
    }
    b.frame_slot->busy = true;
    output_wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const bool by_directory = decomposed();
  const std::size_t n = static_cast<std::size_t>(by_directory ? b.captured_particles : b.particles);
  const int columns = b.capture.column_count;
  const std::size_t words = by_directory ? static_cast<std::size_t>((b.global_particles + 31) / 32) : 0;
  const io::ExteriorFilter exterior = exterior_filter(scene_, body);
  // A .bgeo frame without the exterior filter: the GPU writes the file's point records into the pinned buffer
  // (pack_bgeo_records) and the writer thread only writes them out. Other formats: positions and columns come down
  // and the writer builds the frame.
  const bool records = path.extension() == ".bgeo" && !exterior.on() &&
                       b.frame_attrs.size() <= static_cast<std::size_t>(kMaxFrameColumns) + 1;
  const std::size_t record_bytes = 4 * (4 + b.frame_attrs.size());
  const std::size_t host_bytes =
      records ? n * record_bytes : n * (3 * sizeof(T) + sizeof(float) * columns) + words * sizeof(unsigned);
  if (!b.frame_host || b.frame_host_size < host_bytes) {  // the writer has released it (busy was false)
    b.frame_host = mgsp_detail::pinned(std::max<std::size_t>(host_bytes, 1));
    b.frame_host_size = std::max<std::size_t>(host_bytes, 1);
  }
  cudaEvent_t ready;
  FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&ready, cudaEventDisableTiming));
  FBAR_CUDA_CHECK(cudaEventRecord(ready, stream_));
  FBAR_CUDA_CHECK(cudaStreamWaitEvent(copy_stream_, ready, 0));
  FBAR_CUDA_CHECK(cudaEventDestroy(ready));
  auto* host = static_cast<std::byte*>(b.frame_host.get());
  if (records) {
    BgeoPack<T> pack;
    pack.x = b.frame_x.get();
    pack.columns = b.frame_columns.get();
    pack.stride = static_cast<std::size_t>(b.capture.particles);
    pack.entries = static_cast<int>(n);
    if (by_directory) {
      pack.id_bits = b.id_bits.get();
      pack.id_offset = b.id_offset.get();
      pack.words = static_cast<int>(words);
    }
    pack.attributes = static_cast<int>(b.frame_attrs.size());
    std::vector<io::BgeoAttribute> dictionary;
    int column = 0;
    for (std::size_t a = 0; a < b.frame_attrs.size(); ++a) {
      const bool id = b.frame_attrs[a].column.quantity == FrameQuantity::Id;
      pack.source[a] = id ? -1 : column++;
      dictionary.push_back({b.frame_attrs[a].name, 1, id ? io::detail::kHoudiniInt : io::detail::kHoudiniFloat});
    }
    unsigned* out = nullptr;
    FBAR_CUDA_CHECK(cudaHostGetDevicePointer(reinterpret_cast<void**>(&out), host, 0));
    if (n) {
      pack_bgeo_records<T><<<64, kOutputThreads, 0, copy_stream_>>>(pack, out);
      mgsp_detail::check_launch("pack_bgeo_records");
    }
    FBAR_CUDA_CHECK(cudaEventRecord(b.frame_copied, copy_stream_));
    const cudaEvent_t copied = b.frame_copied;
    const std::shared_ptr<typename BodyBase::HostSlot> slot = b.frame_slot;
    writer.submit_job([=] {
      const typename BodyBase::HostSlot::Hold hold{slot};  // released once written
      const auto t0 = std::chrono::steady_clock::now();
      FBAR_CUDA_CHECK(cudaEventSynchronize(copied));
      const auto t1 = std::chrono::steady_clock::now();
      io::write_bgeo_records(path, n, dictionary, reinterpret_cast<const char*>(host));
      if (std::getenv("FBAR_OUTPUT_TIMING")) {  // the writer's phases, for the output benchmark
        const auto t2 = std::chrono::steady_clock::now();
        const double wait = std::chrono::duration<double>(t1 - t0).count();
        const double write = std::chrono::duration<double>(t2 - t1).count();
        std::fprintf(stderr, "fbar: output timing: %s: records on the host after %.3f s, written in %.3f s (%.2f GB/s)\n",
                     path.filename().string().c_str(), wait, write, 1e-9 * static_cast<double>(n * record_bytes) / write);
      }
    });
    return;
  }
  if (n) {
    FBAR_CUDA_CHECK(cudaMemcpyAsync(host, b.frame_x.get(), 3 * n * sizeof(T), cudaMemcpyDeviceToHost, copy_stream_));
    // Column c of the device frame starts at c x capture.particles (a decomposed rank's frame has room for
    // arrivals); the host copy packs them at c x n.
    if (columns)
      FBAR_CUDA_CHECK(cudaMemcpy2DAsync(host + 3 * n * sizeof(T), n * sizeof(float), b.frame_columns.get(),
                                        static_cast<std::size_t>(b.capture.particles) * sizeof(float),
                                        n * sizeof(float), static_cast<std::size_t>(columns), cudaMemcpyDeviceToHost,
                                        copy_stream_));
  }
  if (words)  // the IDs of the rank's entries: the directory's set bits, in order
    FBAR_CUDA_CHECK(cudaMemcpyAsync(host + n * (3 * sizeof(T) + sizeof(float) * columns), b.id_bits.get(),
                                    words * sizeof(unsigned), cudaMemcpyDeviceToHost, copy_stream_));
  FBAR_CUDA_CHECK(cudaEventRecord(b.frame_copied, copy_stream_));
  const cudaEvent_t copied = b.frame_copied;
  const std::vector<FrameAttributeSpec> attrs = b.frame_attrs;
  const std::shared_ptr<typename BodyBase::HostSlot> slot = b.frame_slot;
  writer.submit_job([=] {
    io::ParticleFrame f;
    f.exterior = exterior;
    {
      const typename BodyBase::HostSlot::Hold hold{slot};  // released once the frame is built
      FBAR_CUDA_CHECK(cudaEventSynchronize(copied));
      // The copies out of the pinned buffer run on several threads (a 16M-particle frame is 0.4 GB of them).
      const unsigned threads = std::max(1u, std::min(8u, std::thread::hardware_concurrency() / 2));
      const T* x = reinterpret_cast<const T*>(host);
      std::vector<Vec3<T>> positions(n);
      io::detail::parallel_ranges(n, threads, [&](std::size_t lo, std::size_t hi) {
        for (std::size_t p = lo; p < hi; ++p) positions[p] = Vec3<T>{{x[3 * p], x[3 * p + 1], x[3 * p + 2]}};
      });
      f.positions = std::move(positions);
      const float* col = reinterpret_cast<const float*>(host + 3 * n * sizeof(T));
      for (const FrameAttributeSpec& a : attrs) {
        if (a.column.quantity == FrameQuantity::Id) {
          std::vector<std::int32_t> ids(n);
          if (words) {  // a decomposed rank's IDs, ascending
            const auto* bits = reinterpret_cast<const unsigned*>(host + n * (3 * sizeof(T) + sizeof(float) * columns));
            std::size_t k = 0;
            for (std::size_t w = 0; w < words && k < n; ++w)
              for (unsigned m = bits[w]; m != 0 && k < n; m &= m - 1)
                ids[k++] = static_cast<std::int32_t>(32 * w + static_cast<std::size_t>(__builtin_ctz(m)));
          } else {
            io::detail::parallel_ranges(n, threads, [&](std::size_t lo, std::size_t hi) {  // frames are in ID order
              std::iota(ids.begin() + lo, ids.begin() + hi, static_cast<std::int32_t>(lo));
            });
          }
          f.add(a.name, 1, std::move(ids));
        } else {
          std::vector<float> values(n);
          io::detail::parallel_ranges(n, threads, [&](std::size_t lo, std::size_t hi) {
            std::copy(col + lo, col + hi, values.begin() + lo);
          });
          f.add(a.name, 1, std::move(values), a.unit);
          col += n;
        }
      }
    }
    io::write_frame(path, f);
  });
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::total_mass() const {
  double m = 0.0;
  for (const auto& b : bodies_) m += static_cast<double>(b->particles) * static_cast<double>(b->mass);
  return m;
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::elastic_energy() const {
  double e = 0.0;
  for (int body = 0; body < body_count(); ++body) {
    const BodyBase& b = body_at(body);
    const std::vector<T> r = gather_host(body, stream_);
    const int W = b.stored_scalars() + kAuxScalars;
    for (std::size_t p = 0; p < static_cast<std::size_t>(b.global_particles); ++p)
      if (!decomposed() || !std::isnan(r[p * W]))
        e += static_cast<double>(b.volume) * b.energy_density_of(r.data() + p * W);
  }
  return e;
}

template <typename T, typename TG>
double MgspBenchmark<T, TG>::grid_mass() const {
  using L = GridLayout<TG>;
  const std::size_t bytes = GridBuffer<TG>::kBlockBytes * static_cast<std::size_t>(block_count_);
  std::vector<std::byte> host(bytes);
  if (bytes) FBAR_CUDA_CHECK(cudaMemcpy(host.data(), grid_[gc_].instance().data(), bytes, cudaMemcpyDeviceToHost));
  typename L::Buffer view(host.data(), static_cast<std::size_t>(block_count_));
  double m = 0.0;
  for (int b = 0; b < block_count_; ++b) {
    const auto g = view.ch(placeholder::_0, b);
    for (int n = 0; n < 64; ++n) m += static_cast<double>(g.val_1d(fbar::grid_mass, n));
  }
  return m;
}

template <typename T, typename TG>
std::size_t MgspBenchmark<T, TG>::device_bytes() const {
  std::size_t bytes = table_.bytes() + grid_[0].bytes() + grid_[1].bytes() + velocity_.bytes() + fbar_sums_.bytes() +
                      transported_[0].bytes() + transported_[1].bytes() + old_velocity_.bytes() +
                      stats_bytes_.bytes() + wave_d_.bytes() + p2g_bound_d_.bytes() + scan_temp_.bytes() +
                      grid_samples_d_.bytes() + particle_samples_d_.bytes() + sensor_partials_d_.bytes() +
                      track_d_.bytes();
  for (const auto& b : bodies_)
    bytes += b->bins_bytes() + b->partition.bytes() + b->aux.bytes() + b->frame_x.bytes() + b->frame_columns.bytes();
  return bytes;
}

// =====================================================================================================================
// Decomposition (comm/slab_partition.h, comm/device_transport.h)

template <typename T, typename TG>
void MgspBenchmark<T, TG>::choose_slabs(const std::vector<std::vector<Vec3d>>* positions) {
  const int n = ranks(), r = rank();
  homes_ = comm::body_ranks(scene_, n);
  placed_ = std::any_of(homes_.begin(), homes_.end(), [](int h) { return h >= 0; });
  std::vector<const SampleCount*> spread;  // placed bodies have no say in the slabs
  for (std::size_t b = 0; b < counts_.size(); ++b)
    if (homes_[b] < 0) spread.push_back(&counts_[b]);
  if (placed_) {
    options_.overlap_halo = false;  // the halo-first G2P2G lists the particle blocks next to the cuts only
    shared_ = std::vector<SharedPeer>(static_cast<std::size_t>(n));  // built in place: SharedPeer does not move
    rank_keys_.assign(static_cast<std::size_t>(n), {});
  }
  const comm::PlaneCounts planes = comm::plane_counts(spread);
  if (planes.total() > 0) {
    slabs_ = comm::choose_slabs(planes, n);
  } else {  // only placed bodies: rank 0 "owns" all of space, which nothing asks about
    slabs_.axis = 0;
    slabs_.cuts.assign(static_cast<std::size_t>(n) + 1, INT_MAX);
    slabs_.cuts.front() = INT_MIN;
  }
  slab_.axis = slabs_.axis;
  slab_.lo = slabs_.cuts[static_cast<std::size_t>(r)];
  slab_.hi = slabs_.cuts[static_cast<std::size_t>(r) + 1];
  for (int side = 0; side < 2; ++side) {
    HaloSide& h = halo_[static_cast<std::size_t>(side)];
    h.peer = side == 0 ? (r > 0 ? r - 1 : -1) : (r + 1 < n ? r + 1 : -1);
    h.plane = side == 0 ? slab_.lo : slab_.hi;  // rank r's particles scatter into grid planes [lo, hi]
  }
  // This rank's share of every count: the plan, the upload and the particle checks use it.
  for (std::size_t b = 0; b < counts_.size(); ++b) {
    SampleCount mine;
    mine.per_plane = counts_[b].per_plane;  // the sampler's batching (whole planes, every rank samples them all)
    const SlabBounds kept = slab_of(static_cast<int>(b));
    const bool here = homes_[b] < 0 || homes_[b] == r;
    for (const BlockCount& c : counts_[b].blocks)
      if (here && kept.owns(c.bx, c.by, c.bz)) {
        mine.blocks.push_back(c);
        mine.particles += c.particles;
      }
    counts_[b] = std::move(mine);
  }
  // The counts above used the host's block of each point; the upload uses the device arithmetic (owns()), which
  // can differ for a point on a block face: count again exactly when positions are sampled.
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    BodyBase& body = *bodies_[b];
    long long mine = 0;
    if (positions) {
      for (const Vec3d& p : (*positions)[b]) mine += owns(static_cast<int>(b), p) ? 1 : 0;
      body.particles = static_cast<int>(mine);
      continue;
    }
    const BodySampler sampler(body.spec, scene_.simulation, body.index);
    std::vector<Vec3d> x;
    for (long long plane = 0; plane < sampler.planes();) {
      const long long end = std::min(sampler.planes(), plane + 64);
      x.clear();
      sampler.sample_planes(plane, end, x);
      for (const Vec3d& p : x) mine += owns(static_cast<int>(b), p) ? 1 : 0;
      plane = end;
    }
    body.particles = static_cast<int>(mine);
  }
  if (log_ && r == 0) {
    *log_ << "fbar: GPU ranks " << n << ": " << (planes.total() > 0 ? slabs_.describe() : std::string("no slabs"))
          << " (" << device_->describe() << ")";
    if (placed_) {
      const char* sep = "; placed (bodies[].gpu): ";
      for (std::size_t b = 0; b < homes_.size(); ++b)
        if (homes_[b] >= 0) {
          *log_ << sep << "bodies[" << b << "] on rank " << homes_[b];
          sep = ", ";
        }
    }
    *log_ << "\n";
  }
}

template <typename T, typename TG>
bool MgspBenchmark<T, TG>::owns(int body, const Vec3d& x) const {
  if (!homes_.empty() && homes_[static_cast<std::size_t>(body)] >= 0) return homes_[static_cast<std::size_t>(body)] == rank();
  const QuadraticBspline<T> s = quadratic_bspline_inv(x.template cast<T>(), k_.inv_dx);
  return slab_.owns(floor_div4(s.base[0] - 1), floor_div4(s.base[1] - 1), floor_div4(s.base[2] - 1));
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::g2p2g_and_halo(T dt) {
  auto sums = [&](cudaStream_t s) {
    if (asflip_)
      halo_exchange({{grid_[1 - gc_].instance().data(), GridBuffer<TG>::kBlockBytes},
                     {transported_[1 - gc_].instance().data(), GridVelocityBuffer<TG>::kBlockBytes}},
                    1 - gc_, false, s);
    else
      halo_exchange({{grid_[1 - gc_].instance().data(), GridBuffer<TG>::kBlockBytes}}, 1 - gc_, false, s);
  };
  if (!options_.overlap_halo) {
    for (auto& b : bodies_) b->g2p2g(*this, false, dt);
    event_record(2);
    sums(stream_);
    return;
  }
  // The halo particle blocks of every body first: after them no launch of this step writes a block of a shared
  // plane (a particle block B scatters into blocks B .. B + 1 only). fbar_sums_ holds one body's cell sums at a
  // time, so an F-bar body with another F-bar body after it runs its other blocks at once.
  int fbar_left = 0;
  for (const auto& b : bodies_) fbar_left += b->fbar_psi != T(0);
  std::vector<BodyBase*> rest;
  for (auto& b : bodies_) {
    b->g2p2g(*this, false, dt, G2P2GPass::Halo);
    if (b->fbar_psi != T(0) && --fbar_left > 0)
      b->g2p2g(*this, false, dt, G2P2GPass::Interior);
    else
      rest.push_back(b.get());
  }
  FBAR_CUDA_CHECK(cudaEventRecord(halo_ready_, stream_));
  // The other blocks on the compute stream, queued before the exchange (a host-ordered transport may block in it).
  for (BodyBase* b : rest) b->g2p2g(*this, false, dt, G2P2GPass::Interior);
  event_record(2);
  FBAR_CUDA_CHECK(cudaStreamWaitEvent(halo_stream_, halo_ready_, 0));
  if (timing_) FBAR_CUDA_CHECK(cudaEventRecord(halo_events_[0], halo_stream_));
  sums(halo_stream_);
  if (timing_) FBAR_CUDA_CHECK(cudaEventRecord(halo_events_[1], halo_stream_));
  FBAR_CUDA_CHECK(cudaEventRecord(halo_done_, halo_stream_));
  FBAR_CUDA_CHECK(cudaStreamWaitEvent(stream_, halo_done_, 0));
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::halo_exchange(std::initializer_list<std::pair<std::byte*, std::size_t>> buffers, int grid,
                                         bool delta, cudaStream_t stream) {
  if (!stream) stream = stream_;
  if (placed_) {
    shared_exchange(buffers, grid, delta, stream);
    return;
  }
  const BlockBuffers list(buffers);
  device_->exchange(pack_halo_messages(list, stream), stream);
  add_halo_messages(list, grid, delta, stream);
}

template <typename T, typename TG>
std::vector<comm::DeviceTransport::Message> MgspBenchmark<T, TG>::pack_halo_messages(const BlockBuffers& buffers,
                                                                                     cudaStream_t stream) {
  std::size_t per_block = 0;  // scalars of every listed buffer's block
  for (const auto& [data, bytes] : buffers) per_block += bytes / sizeof(TG);
  std::vector<comm::DeviceTransport::Message> messages;
  for (HaloSide& h : halo_) {
    if (h.peer < 0) continue;
    const int n = static_cast<int>(h.keys.size());
    const std::size_t scalars = static_cast<std::size_t>(n) * per_block;
    if (h.send.size() < scalars) {
      h.send.allocate(scalars);
      h.recv.allocate(scalars);
    }
    std::size_t offset = 0;
    for (const auto& [data, bytes] : buffers) {
      const int block_scalars = static_cast<int>(bytes / sizeof(TG));
      if (n > 0) {
        pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(n) * block_scalars, kHaloThreads), kHaloThreads, 0,
                        stream>>>(reinterpret_cast<const TG*>(data), block_scalars, h.index.get(), n,
                                   h.send.get() + offset);
        mgsp_detail::check_launch("pack_halo");
      }
      offset += static_cast<std::size_t>(n) * block_scalars;
    }
    comm::DeviceTransport::Message m;
    m.peer = h.peer;
    m.send = h.send.get();
    m.recv = h.recv.get();
    m.send_bytes = m.recv_bytes = scalars * sizeof(TG);
    messages.push_back(m);
  }
  return messages;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::add_halo_messages(const BlockBuffers& buffers, int grid, bool delta, cudaStream_t stream) {
  const bool save = grid >= 0;
  for (HaloSide& h : halo_) {
    if (h.peer < 0 || h.keys.empty()) continue;
    const int n = static_cast<int>(h.keys.size());
    std::size_t offset = 0;
    bool first = true;
    for (const auto& [data, bytes] : buffers) {
      const int block_scalars = static_cast<int>(bytes / sizeof(TG));
      TG* target = reinterpret_cast<TG*>(data);
      const std::size_t count = static_cast<std::size_t>(n) * block_scalars;
      const bool saved = first && delta;
      if (saved && h.saved[grid].size() < count) throw std::logic_error("GpuEngine: a delta exchange before any sum");
      add_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count), kHaloThreads), kHaloThreads, 0, stream>>>(
          target, block_scalars, h.index.get(), n, h.recv.get() + offset, saved ? h.saved[grid].get() : nullptr);
      mgsp_detail::check_launch("add_halo");
      if (first && save) {  // the sums both ranks now hold, for a later delta exchange
        if (h.saved[grid].size() < count) h.saved[grid].allocate(count);
        pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count), kHaloThreads), kHaloThreads, 0, stream>>>(
            target, block_scalars, h.index.get(), n, h.saved[grid].get());
        mgsp_detail::check_launch("pack_halo");
      }
      offset += count;
      first = false;
    }
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::collect_halo() {
  if (halo_fresh_capacity_ == 0) {
    halo_fresh_capacity_ = 1024;
    for (HaloSide& h : halo_) h.fresh.allocate(static_cast<std::size_t>(halo_fresh_capacity_));
  }
  const int limit = block_capacity_ - halo_scanned_;
  if (limit <= 0) return;
  if (placed_) {  // every new block may be shared with any rank
    collect_new_blocks<<<mgsp_detail::grid_for(limit, kHaloThreads), kHaloThreads, 0, stream_>>>(
        table_.view(), halo_scanned_, halo_[0].fresh.get(), halo_fresh_capacity_, stats_d_->halo_new);
    mgsp_detail::check_launch("collect_new_blocks");
    return;
  }
  collect_halo_blocks<<<mgsp_detail::grid_for(limit, kHaloThreads), kHaloThreads, 0, stream_>>>(
      table_.view(), halo_scanned_, slab_.axis, halo_[0].peer >= 0 ? halo_[0].plane : INT_MIN,
      halo_[1].peer >= 0 ? halo_[1].plane : INT_MIN, halo_[0].fresh.get(), halo_[1].fresh.get(), halo_fresh_capacity_,
      stats_d_->halo_new);
  mgsp_detail::check_launch("collect_halo_blocks");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::prepare_capture(BodyBase& b) {
  if (static_cast<std::size_t>(b.particles) > b.frame_capacity) {  // arrivals outgrew the frame: the download first
    if (b.frame_copied) FBAR_CUDA_CHECK(cudaEventSynchronize(b.frame_copied));
    const std::size_t n = static_cast<std::size_t>(b.particles) * 5 / 4 + 1024;
    b.frame_x.allocate(3 * n);
    b.frame_columns.allocate(static_cast<std::size_t>(b.capture.column_count) * n);
    b.capture.x = b.frame_x.get();
    b.capture.columns = b.frame_columns.get();
    b.capture.particles = static_cast<int>(n);
    b.frame_capacity = n;
    peak_bytes_ = std::max(peak_bytes_, device_bytes());
  }
  const int words = static_cast<int>((b.global_particles + 31) / 32);
  FBAR_CUDA_CHECK(cudaMemsetAsync(b.id_bits.get(), 0, sizeof(unsigned) * std::max(words, 1), stream_));
  b.mark_ids(*this);
  count_id_bits<<<mgsp_detail::grid_for(words + 1, kOutputThreads), kOutputThreads, 0, stream_>>>(
      b.id_bits.get(), words, b.id_counts.get());
  mgsp_detail::check_launch("count_id_bits");
  std::size_t temp = b.id_scan_temp.size();
  FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(b.id_scan_temp.get(), temp, b.id_counts.get(), b.id_offset.get(),
                                                words + 1, stream_));
  b.captured_particles = b.particles;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::rebuild_halo(int summed_grid) {
  // 1. This rank's new keys per side (collected after the last partition; collected again when they overflowed).
  std::array<std::vector<unsigned long long>, 2> fresh;
  const int fresh_count[2] = {stats_->halo_new[0], stats_->halo_new[1]};
  if (std::max(fresh_count[0], fresh_count[1]) > halo_fresh_capacity_) {
    while (halo_fresh_capacity_ < std::max(fresh_count[0], fresh_count[1])) halo_fresh_capacity_ *= 2;
    for (HaloSide& h : halo_) h.fresh.allocate(static_cast<std::size_t>(halo_fresh_capacity_));
    FBAR_CUDA_CHECK(cudaMemsetAsync(stats_d_->halo_new, 0, sizeof(stats_d_->halo_new), stream_));
    collect_halo();
  }
  for (int side = 0; side < 2; ++side) {
    fresh[side].resize(static_cast<std::size_t>(fresh_count[side]));
    if (fresh_count[side] > 0)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(fresh[side].data(), halo_[side].fresh.get(),
                                      sizeof(unsigned long long) * fresh[side].size(), cudaMemcpyDeviceToHost, stream_));
  }
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  halo_scanned_ = std::max(halo_scanned_, std::min(stats_->block_count, block_capacity_));
  if (placed_) {
    rebuild_shared(summed_grid, fresh[0]);
    return;
  }
  // 2. To the neighbours, and theirs back.
  std::vector<int> peers;
  std::vector<comm::Bytes> send;
  for (int side = 0; side < 2; ++side) {
    if (halo_[side].peer < 0) continue;
    peers.push_back(halo_[side].peer);
    const auto* b = reinterpret_cast<const std::uint8_t*>(fresh[side].data());
    send.emplace_back(b, b + sizeof(unsigned long long) * fresh[side].size());
  }
  const std::vector<comm::Bytes> received = host_->exchange(peers, send);
  // 3. The union, sorted (the same list on both sides), inserted here where absent, and its table indices.
  std::size_t i = 0;
  for (int side = 0; side < 2; ++side) {
    HaloSide& h = halo_[side];
    if (h.peer < 0) continue;
    const comm::Bytes& theirs = received[i++];
    std::vector<unsigned long long> all = h.keys;
    all.insert(all.end(), fresh[side].begin(), fresh[side].end());
    const std::size_t k = theirs.size() / sizeof(unsigned long long);
    const std::size_t at = all.size();
    all.resize(at + k);
    if (k) std::memcpy(all.data() + at, theirs.data(), theirs.size());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    if (all.size() == h.keys.size()) continue;
    h.keys = std::move(all);
    const int n = static_cast<int>(h.keys.size());
    mgsp_detail::DeviceArray<unsigned long long> keys;
    keys.allocate(h.keys.size());
    h.index.allocate(h.keys.size());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(keys.get(), h.keys.data(), sizeof(unsigned long long) * h.keys.size(),
                                    cudaMemcpyHostToDevice, stream_));
    for (;;) {
      insert_halo_blocks<TG><<<mgsp_detail::grid_for(n, kHaloThreads), kHaloThreads, 0, stream_>>>(
          table_.view(), keys.get(), n, h.index.get(), grid_[0].instance(), grid_[1].instance());
      mgsp_detail::check_launch("insert_halo_blocks");
      TableCounters c{};
      FBAR_CUDA_CHECK(cudaMemcpyAsync(&c, table_.counters(), sizeof(c), cudaMemcpyDeviceToHost, stream_));
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
      if (c.overflow == 0 && c.block_count <= block_capacity_) {
        block_count_ = std::max(block_count_, c.block_count);
        break;
      }
      grow_blocks(2 * block_capacity_);  // keeps every block; the inserts are repeated (existing ones are found)
    }
    // The summed values both ranks hold, in the new list's order (a block new to the list is zero on both sides:
    // it was created after the P2G that filled the grid), for a delta exchange before the next sum.
    constexpr int kScalars = static_cast<int>(GridBuffer<TG>::kBlockBytes / sizeof(TG));
    const std::size_t count = static_cast<std::size_t>(n) * kScalars;
    for (int g = 0; g < 2; ++g) h.saved[g].allocate(count);  // the other grid is summed (and saved) before its use
    if (summed_grid >= 0) {
      pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count), kHaloThreads), kHaloThreads, 0, stream_>>>(
          reinterpret_cast<const TG*>(grid_[summed_grid].instance().data()), kScalars, h.index.get(), n,
          h.saved[summed_grid].get());
      mgsp_detail::check_launch("pack_halo");
    }
  }
  // Blocks inserted here are halo blocks already listed: not new for the next collect.
  halo_scanned_ = std::max(halo_scanned_, block_count_);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::rebuild_shared(int summed_grid, const std::vector<unsigned long long>& fresh_here) {
  using Key = unsigned long long;
  const int r = rank(), n = ranks();
  // 1. Every rank's new keys (table blocks are never removed: a rank's keys only grow).
  std::vector<std::vector<Key>> fresh(static_cast<std::size_t>(n));
  {
    comm::Bytes packed(sizeof(Key) * fresh_here.size());
    if (!packed.empty()) std::memcpy(packed.data(), fresh_here.data(), packed.size());
    const std::vector<comm::Bytes> all = host_->allgather(packed);
    for (int q = 0; q < n; ++q) {
      fresh[q].resize(all[q].size() / sizeof(Key));
      if (!fresh[q].empty()) std::memcpy(fresh[q].data(), all[q].data(), all[q].size());
      std::sort(fresh[q].begin(), fresh[q].end());
    }
  }
  // 2. Before the new keys join: a new block's lowest earlier holder (-1: nobody held it, its sums are zero
  // everywhere). It sends grid[summed_grid]'s values of the block to the ranks that have just created it.
  auto earliest = [&](Key k) {
    for (int q = 0; q < n; ++q)
      if (rank_keys_[q].count(k)) return q;
    return -1;
  };
  std::vector<std::vector<Key>> sync_out(static_cast<std::size_t>(n)), sync_in(static_cast<std::size_t>(n));
  for (int q = 0; q < n; ++q) {
    if (q == r) continue;
    for (Key k : fresh[q])
      if (earliest(k) == r) sync_out[q].push_back(k);
  }
  for (Key k : fresh[r]) {
    const int d = earliest(k);
    if (d >= 0) sync_in[d].push_back(k);
  }
  // 3. New entries of each peer's list: a block both ranks now hold that one of them has just created.
  std::vector<bool> changed(static_cast<std::size_t>(n), false);
  for (int q = 0; q < n; ++q) {
    if (q == r) continue;
    std::vector<Key> added;
    for (Key k : fresh[r])
      if (rank_keys_[q].count(k) || std::binary_search(fresh[q].begin(), fresh[q].end(), k)) added.push_back(k);
    for (Key k : fresh[q])
      if (rank_keys_[r].count(k)) added.push_back(k);
    if (added.empty()) continue;
    SharedPeer& peer = shared_[q];
    peer.keys.insert(peer.keys.end(), added.begin(), added.end());
    std::sort(peer.keys.begin(), peer.keys.end());
    peer.keys.erase(std::unique(peer.keys.begin(), peer.keys.end()), peer.keys.end());
    changed[q] = true;
  }
  for (int q = 0; q < n; ++q) rank_keys_[q].insert(fresh[q].begin(), fresh[q].end());
  // 4. Table indices of the changed lists (every key is in the table here: found, not inserted), the union and each
  // entry's place in it.
  bool any = false;
  for (int q = 0; q < n; ++q) {
    if (!changed[q]) continue;
    any = true;
    SharedPeer& peer = shared_[q];
    const int count = static_cast<int>(peer.keys.size());
    mgsp_detail::DeviceArray<Key> keys;
    keys.allocate(peer.keys.size());
    peer.index.allocate(peer.keys.size());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(keys.get(), peer.keys.data(), sizeof(Key) * peer.keys.size(),
                                    cudaMemcpyHostToDevice, stream_));
    insert_halo_blocks<TG><<<mgsp_detail::grid_for(count, kHaloThreads), kHaloThreads, 0, stream_>>>(
        table_.view(), keys.get(), count, peer.index.get(), grid_[0].instance(), grid_[1].instance());
    mgsp_detail::check_launch("insert_halo_blocks");
    peer.blocks.resize(peer.keys.size());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(peer.blocks.data(), peer.index.get(), sizeof(int) * peer.blocks.size(),
                                    cudaMemcpyDeviceToHost, stream_));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
    for (int b : peer.blocks)
      if (b < 0)
        throw std::logic_error("GpuEngine: a shared block is missing from this rank's table (rank " + std::to_string(r) +
                               ", peer " + std::to_string(q) + ")");
  }
  if (any) {
    std::vector<int> all;
    for (int q = 0; q < n; ++q) all.insert(all.end(), shared_[q].blocks.begin(), shared_[q].blocks.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    union_blocks_ = std::move(all);
    union_index_.allocate(std::max<std::size_t>(union_blocks_.size(), 1));
    if (!union_blocks_.empty())
      FBAR_CUDA_CHECK(cudaMemcpyAsync(union_index_.get(), union_blocks_.data(), sizeof(int) * union_blocks_.size(),
                                      cudaMemcpyHostToDevice, stream_));
    for (int q = 0; q < n; ++q) {
      SharedPeer& peer = shared_[q];
      if (q == r || peer.blocks.empty()) continue;
      std::vector<int> upos(peer.blocks.size());
      for (std::size_t k = 0; k < upos.size(); ++k)
        upos[k] = static_cast<int>(std::lower_bound(union_blocks_.begin(), union_blocks_.end(), peer.blocks[k]) -
                                   union_blocks_.begin());
      peer.upos.allocate(upos.size());
      FBAR_CUDA_CHECK(cudaMemcpyAsync(peer.upos.get(), upos.data(), sizeof(int) * upos.size(), cudaMemcpyHostToDevice,
                                      stream_));
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // upos is a host temporary
    }
  }
  if (any || not_counted_.size() < static_cast<std::size_t>(block_capacity_)) mark_not_counted();
  // 5. The just-created blocks take their summed values (grid[summed_grid]) from their lowest earlier holder, whose
  // values every earlier holder shares; then the summed values of the whole union are kept for a delta exchange.
  if (summed_grid < 0) return;
  constexpr int kScalars = static_cast<int>(GridBuffer<TG>::kBlockBytes / sizeof(TG));
  TG* grid = reinterpret_cast<TG*>(grid_[summed_grid].instance().data());
  std::unordered_map<Key, int> where;
  for (int q = 0; q < n; ++q)
    for (std::size_t k = 0; k < shared_[q].keys.size(); ++k) where[shared_[q].keys[k]] = shared_[q].blocks[k];
  auto indices = [&](const std::vector<Key>& keys) {
    std::vector<int> out;
    for (Key k : keys) {
      const auto it = where.find(k);
      if (it == where.end()) throw std::logic_error("GpuEngine: a block to synchronise is not shared");
      out.push_back(it->second);
    }
    return out;
  };
  std::vector<mgsp_detail::DeviceArray<int>> out_index(static_cast<std::size_t>(n)), in_index(static_cast<std::size_t>(n));
  std::vector<mgsp_detail::DeviceArray<TG>> out_values(static_cast<std::size_t>(n)), in_values(static_cast<std::size_t>(n));
  std::vector<comm::DeviceTransport::Message> messages;
  for (int q = 0; q < n; ++q) {
    if (q == r || (sync_out[q].empty() && sync_in[q].empty())) continue;
    comm::DeviceTransport::Message m;
    m.peer = q;
    if (!sync_out[q].empty()) {
      const std::vector<int> idx = indices(sync_out[q]);
      out_index[q].allocate(idx.size());
      out_values[q].allocate(idx.size() * kScalars);
      FBAR_CUDA_CHECK(cudaMemcpyAsync(out_index[q].get(), idx.data(), sizeof(int) * idx.size(), cudaMemcpyHostToDevice,
                                      stream_));
      const int count = static_cast<int>(idx.size());
      pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count) * kScalars, kHaloThreads), kHaloThreads, 0,
                      stream_>>>(grid, kScalars, out_index[q].get(), count, out_values[q].get());
      mgsp_detail::check_launch("pack_halo");
      m.send = out_values[q].get();
      m.send_bytes = sizeof(TG) * idx.size() * kScalars;
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // idx is a host temporary
    }
    if (!sync_in[q].empty()) {
      const std::vector<int> idx = indices(sync_in[q]);
      in_index[q].allocate(idx.size());
      in_values[q].allocate(idx.size() * kScalars);
      FBAR_CUDA_CHECK(cudaMemcpyAsync(in_index[q].get(), idx.data(), sizeof(int) * idx.size(), cudaMemcpyHostToDevice,
                                      stream_));
      m.recv = in_values[q].get();
      m.recv_bytes = sizeof(TG) * idx.size() * kScalars;
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
    }
    messages.push_back(m);
  }
  device_->exchange(messages, stream_);
  for (int q = 0; q < n; ++q) {
    if (sync_in[q].empty()) continue;
    const int count = static_cast<int>(sync_in[q].size());  // a new block is zero here: adding sets it
    add_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count) * kScalars, kHaloThreads), kHaloThreads, 0,
                   stream_>>>(grid, kScalars, in_index[q].get(), count, in_values[q].get(), nullptr);
    mgsp_detail::check_launch("add_halo");
  }
  const std::size_t count = union_blocks_.size() * kScalars;
  for (int g = 0; g < 2; ++g)
    if (union_saved_[g].size() < count) union_saved_[g].allocate(count);  // the other grid: saved at its sum
  if (!union_blocks_.empty()) {
    pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count), kHaloThreads), kHaloThreads, 0, stream_>>>(
        grid, kScalars, union_index_.get(), static_cast<int>(union_blocks_.size()), union_saved_[summed_grid].get());
    mgsp_detail::check_launch("pack_halo");
  }
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // the message buffers are freed on return
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::shared_exchange(std::initializer_list<std::pair<std::byte*, std::size_t>> buffers, int grid,
                                           bool delta, cudaStream_t stream) {
  const int r = rank(), n = ranks();
  const int held = static_cast<int>(union_blocks_.size());
  if (held == 0) {  // nothing shared here (no rank has a message for this one): still a collective for the others
    device_->exchange({}, stream);
    return;
  }
  std::size_t per_block = 0;
  for (const auto& [data, bytes] : buffers) per_block += bytes / sizeof(TG);
  // 1. Each peer's blocks out, theirs in.
  std::vector<comm::DeviceTransport::Message> messages;
  for (int q = 0; q < n; ++q) {
    SharedPeer& peer = shared_[q];
    if (q == r || peer.blocks.empty()) continue;
    const int count = static_cast<int>(peer.blocks.size());
    const std::size_t scalars = static_cast<std::size_t>(count) * per_block;
    if (peer.send.size() < scalars) {
      peer.send.allocate(scalars);
      peer.recv.allocate(scalars);
    }
    std::size_t offset = 0;
    for (const auto& [data, bytes] : buffers) {
      const int block_scalars = static_cast<int>(bytes / sizeof(TG));
      pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(count) * block_scalars, kHaloThreads), kHaloThreads,
                      0, stream>>>(reinterpret_cast<const TG*>(data), block_scalars, peer.index.get(), count,
                                   peer.send.get() + offset);
      mgsp_detail::check_launch("pack_halo");
      offset += static_cast<std::size_t>(count) * block_scalars;
    }
    comm::DeviceTransport::Message m;
    m.peer = q;
    m.send = peer.send.get();
    m.recv = peer.recv.get();
    m.send_bytes = m.recv_bytes = scalars * sizeof(TG);
    messages.push_back(m);
  }
  // 2. This rank's own part of every shared block (before the exchange returns: the sums below overwrite it).
  const std::size_t own = static_cast<std::size_t>(held) * per_block;
  if (union_own_.size() < own) union_own_.allocate(own);
  {
    std::size_t offset = 0;
    for (const auto& [data, bytes] : buffers) {
      const int block_scalars = static_cast<int>(bytes / sizeof(TG));
      pack_halo<TG><<<mgsp_detail::grid_for(static_cast<long long>(held) * block_scalars, kHaloThreads), kHaloThreads,
                      0, stream>>>(reinterpret_cast<const TG*>(data), block_scalars, union_index_.get(), held,
                                   union_own_.get() + offset);
      mgsp_detail::check_launch("pack_halo");
      offset += static_cast<std::size_t>(held) * block_scalars;
    }
  }
  device_->exchange(messages, stream);
  // 3. Every holder: from zero (a delta exchange: from the saved sums, adding each part minus them), each rank's part
  // in rank order.
  std::size_t offset = 0, own_offset = 0;
  bool first = true;
  for (const auto& [data, bytes] : buffers) {
    const int block_scalars = static_cast<int>(bytes / sizeof(TG));
    TG* target = reinterpret_cast<TG*>(data);
    const bool use_saved = first && delta;
    if (use_saved && union_saved_[grid].size() < static_cast<std::size_t>(held) * block_scalars)
      throw std::logic_error("GpuEngine: a delta exchange before any sum");
    const TG* saved = use_saved ? union_saved_[grid].get() : nullptr;
    const long long all = static_cast<long long>(held) * block_scalars;
    start_shared<TG><<<mgsp_detail::grid_for(all, kHaloThreads), kHaloThreads, 0, stream>>>(
        target, block_scalars, union_index_.get(), held, saved);
    mgsp_detail::check_launch("start_shared");
    for (int q = 0; q < n; ++q) {
      if (q == r) {
        add_shared<TG><<<mgsp_detail::grid_for(all, kHaloThreads), kHaloThreads, 0, stream>>>(
            target, block_scalars, union_index_.get(), held, union_own_.get() + own_offset, saved, nullptr);
        mgsp_detail::check_launch("add_shared");
        continue;
      }
      SharedPeer& peer = shared_[q];
      if (peer.blocks.empty()) continue;
      const int count = static_cast<int>(peer.blocks.size());
      add_shared<TG><<<mgsp_detail::grid_for(static_cast<long long>(count) * block_scalars, kHaloThreads), kHaloThreads,
                       0, stream>>>(target, block_scalars, peer.index.get(), count,
                                    peer.recv.get() + offset * count, saved, peer.upos.get());
      mgsp_detail::check_launch("add_shared");
    }
    if (first && grid >= 0) {  // the sums every holder now has, for a later delta exchange
      if (union_saved_[grid].size() < static_cast<std::size_t>(all)) union_saved_[grid].allocate(all);
      pack_halo<TG><<<mgsp_detail::grid_for(all, kHaloThreads), kHaloThreads, 0, stream>>>(
          target, block_scalars, union_index_.get(), held, union_saved_[grid].get());
      mgsp_detail::check_launch("pack_halo");
    }
    offset += static_cast<std::size_t>(block_scalars);
    own_offset += static_cast<std::size_t>(held) * block_scalars;
    first = false;
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::mark_not_counted() {
  not_counted_.allocate(static_cast<std::size_t>(block_capacity_));
  FBAR_CUDA_CHECK(cudaMemsetAsync(not_counted_.get(), 0, static_cast<std::size_t>(block_capacity_), stream_));
  for (int q = 0; q < rank(); ++q) {
    const SharedPeer& peer = shared_[q];
    if (peer.blocks.empty()) continue;
    const int count = static_cast<int>(peer.blocks.size());
    mark_blocks<<<mgsp_detail::grid_for(count, kHaloThreads), kHaloThreads, 0, stream_>>>(peer.index.get(), count,
                                                                                       not_counted_.get());
    mgsp_detail::check_launch("mark_blocks");
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::migrate_particles() {
  MigrantMessage msg;
  device_->exchange(pack_migrant_messages(msg), stream_);
  unpack_migrant_messages(msg);
}

template <typename T, typename TG>
std::vector<comm::DeviceTransport::Message> MgspBenchmark<T, TG>::pack_migrant_messages(MigrantMessage& msg) {
  // No host round trip: the messages have a size every rank knows (MigrantMessage), the counts travel in their
  // headers, and the host reads them with the step's one readback (settle_migration).
  static_assert(MigrantMessage::kHeaderBytes >= sizeof(int) * DtParams::kMaxBodies, "a count per body in the header");
  const int nb = body_count();
  msg = MigrantMessage{};
  msg.capacity = migrant_capacity_;
  msg.bodies = nb;
  for (auto& b : bodies_) msg.widest = std::max(msg.widest, b->migrant_bytes(*this));
  const std::size_t bytes = msg.bytes();
  for (HaloSide& h : halo_) {
    if (h.migrants_out.size() < bytes) h.migrants_out.allocate(bytes);
    if (h.peer >= 0 && h.migrants_in.size() < bytes) h.migrants_in.allocate(bytes);
  }
  // 1. Pack: each body into its area of both sides' messages, counted in the headers.
  for (HaloSide& h : halo_)
    FBAR_CUDA_CHECK(cudaMemsetAsync(h.migrants_out.get(), 0, MigrantMessage::kHeaderBytes, stream_));
  auto header = [](mgsp_detail::DeviceArray<std::byte>& a) { return reinterpret_cast<int*>(a.get()); };
  for (auto& b : bodies_)
    b->pack_emigrants(*this, halo_[0].migrants_out.get() + msg.area(b->index),
                      halo_[1].migrants_out.get() + msg.area(b->index), msg.capacity,
                      header(halo_[0].migrants_out) + b->index, header(halo_[1].migrants_out) + b->index);
  // 2. The whole messages to the neighbours (the same size both ways).
  std::vector<comm::DeviceTransport::Message> messages;
  for (HaloSide& h : halo_) {
    if (h.peer < 0) continue;
    comm::DeviceTransport::Message m;
    m.peer = h.peer;
    m.send = h.migrants_out.get();
    m.send_bytes = bytes;
    m.recv = h.migrants_in.get();
    m.recv_bytes = bytes;
    messages.push_back(m);
  }
  return messages;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::unpack_migrant_messages(const MigrantMessage& msg) {
  const int nb = body_count();
  auto header = [](mgsp_detail::DeviceArray<std::byte>& a) { return reinterpret_cast<int*>(a.get()); };
  // 3. Immigrants behind the G2P2G's slots, `capacity` slots per neighbour (those past its count marked empty);
  // their (block, rank) before the partition.
  int sides = 0;
  for (const HaloSide& h : halo_) sides += h.peer >= 0 ? 1 : 0;
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const int first = b.source_slots;
    const long long end = first + static_cast<long long>(sides) * msg.capacity;
    const long long room = 32LL * std::min(b.bins_capacity(1 - cur_), b.partition.bin_capacity());
    if (end > room) grow_for_arrivals(b, first, (end + 31) / 32);
    int slot = first;
    for (HaloSide& h : halo_) {
      if (h.peer < 0) continue;
      b.unpack_immigrants(*this, slot, h.migrants_in.get() + msg.area(b.index), header(h.migrants_in) + b.index,
                          msg.capacity);
      slot += msg.capacity;
    }
    b.source_slots = slot;
    b.dest_from_positions(*this, 1 - cur_, b.partition.layout(cur_).src, first, slot);
  }
  record_migrant_counts<<<1, 64, 0, stream_>>>(
      nb, header(halo_[0].migrants_out), header(halo_[1].migrants_out),
      halo_[0].peer >= 0 ? header(halo_[0].migrants_in) : nullptr,
      halo_[1].peer >= 0 ? header(halo_[1].migrants_in) : nullptr, body_stats_d_);
  mgsp_detail::check_launch("record_migrant_counts");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::settle_migration() {
  migrant_most_ = 0;
  for (auto& b : bodies_) {
    const BodyStepStats& s = body_stats_[b->index];
    int leaving = 0, arriving = 0;
    for (int side = 0; side < 2; ++side) {
      leaving += s.emigrants[side];
      arriving += s.immigrants[side];
      migrant_most_ = std::max({migrant_most_, s.emigrants[side], s.immigrants[side]});
    }
    // G2P2G lists at most 2 x capacity emigrants (emigrant_slots): more, and half the list is above the capacity.
    migrant_most_ = std::max(migrant_most_, (s.emigrant_list + 1) / 2);
    pending_migrated_ += leaving;
    b->pending_particles = b->particles - leaving + arriving;
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_emigrant_lists() {
  if (!decomposed()) return;
  const std::size_t entries = 2 * static_cast<std::size_t>(migrant_capacity_);
  for (auto& b : bodies_)
    if (b->emigrant_slots.size() != entries) b->emigrant_slots.allocate(entries);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::agree_on_try() {
  // One allgather of every rank's numbers, reduced here in rank order (the same result on every rank): the host
  // round trips of a decomposed step cost GPU idle time, so the step has this one.
  const int nb = body_count();
  enum : int { kInternal, kRange, kHaloNew, kSpeed, kParticles, kMigrants, kFixed };
  std::vector<long long> mine(static_cast<std::size_t>(kFixed + 2 * kFailKinds * nb));
  mine[kInternal] = stats_->internal_error;
  mine[kRange] = stats_->p2g_range;
  mine[kHaloNew] = static_cast<long long>(stats_->halo_new[0]) + stats_->halo_new[1];
  mine[kSpeed] = static_cast<long long>(stats_->max_speed_sq);  // bits of a non-negative double: integer order
  long long held = 0;
  for (const auto& b : bodies_) held += b->pending_particles;
  mine[kParticles] = held;
  mine[kMigrants] = migrant_most_;
  for (int b = 0; b < nb; ++b)
    for (int k = 0; k < kFailKinds; ++k) {
      mine[static_cast<std::size_t>(kFixed + kFailKinds * b + k)] = body_stats_[b].failures[k];
      mine[static_cast<std::size_t>(kFixed + kFailKinds * (nb + b) + k)] = body_stats_[b].first_id[k];
    }
  comm::Bytes packed(mine.size() * sizeof(long long));
  std::memcpy(packed.data(), mine.data(), packed.size());
  const std::vector<comm::Bytes> all = host_->allgather(packed);
  std::vector<long long> v(mine.size()), agreed(mine.size());
  for (std::size_t r = 0; r < all.size(); ++r) {
    if (all[r].size() != packed.size()) throw std::logic_error("GpuEngine: ranks disagree on the step's counters");
    std::memcpy(v.data(), all[r].data(), packed.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      const bool first_ids = i >= static_cast<std::size_t>(kFixed + kFailKinds * nb);
      const bool maximum = i == kSpeed || i == kParticles || i == kMigrants;
      if (r == 0)
        agreed[i] = v[i];
      else if (first_ids)
        agreed[i] = std::min(agreed[i], v[i]);
      else if (maximum)
        agreed[i] = std::max(agreed[i], v[i]);
      else
        agreed[i] += v[i];
    }
  }
  stats_->internal_error = static_cast<int>(agreed[kInternal]);
  stats_->p2g_range = static_cast<int>(agreed[kRange]);
  halo_grew_ = agreed[kHaloNew] > 0;  // stats_->halo_new stays this rank's: rebuild_halo sends those
  stats_->max_speed_sq = static_cast<unsigned long long>(agreed[kSpeed]);
  most_rank_particles_ = static_cast<double>(agreed[kParticles]);
  migrant_most_ = static_cast<int>(agreed[kMigrants]);
  for (int b = 0; b < nb; ++b)
    for (int k = 0; k < kFailKinds; ++k) {
      body_stats_[b].failures[k] = static_cast<int>(agreed[static_cast<std::size_t>(kFixed + kFailKinds * b + k)]);
      body_stats_[b].first_id[k] =
          static_cast<int>(agreed[static_cast<std::size_t>(kFixed + kFailKinds * (nb + b) + k)]);
    }
}

}  // namespace fbar
