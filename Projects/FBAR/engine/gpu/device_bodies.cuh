// Bodies on the device: what every body holds (BodyBase: counts, partition, frame buffers, the virtual launches)
// and Body<M>, one material's bins and the launches of its kernels. Part of MgspBenchmark (mgsp_benchmark.cuh).
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
struct MgspBenchmark<T, TG>::BodyBase {
  BodySpec spec;
  int index = 0;
  int particles = 0;             ///< on this rank (all of the body on one GPU)
  long long global_particles = 0;  ///< of the body over all ranks: IDs are 0 .. global_particles - 1
  /// Slots of bins[1 - cur] the partition reads: the G2P2G's layout slots, then the particles received this try.
  int source_slots = 0;
  int pending_particles = 0;     ///< particles on this rank after this try's migration
  /// Decomposed runs: the slots of a try's emigrants, as G2P2G lists them (2 x dec_.migrant_capacity entries).
  cuda::DeviceArray<int> emigrant_slots;
  T mass = T(0), volume = T(0);
  double rest_wave_speed = 0.0;
  HydrostaticProfile hydrostatic;  ///< bodies[].initial_state "hydrostatic": the upload's states (inactive: rest)
  T fbar_psi = T(0);  ///< F-bar blend (transfer.cuh), 0: off
  bool asflip = false;  ///< PIC-FLIP / ASFLIP (transfer.cuh)
  AsflipParams<T> asflip_params{T(0), T(0), T(0)};
  /// ASFLIP only: (slot, 3) particle velocities beside bins[0] / bins[1], same slots (empty otherwise).
  cuda::DeviceArray<T> particle_v[2];
  PartitionDomain partition;
  int total_bins[2] = {0, 0};  ///< bins of layout 0 / 1
  /// Decomposed runs: blocks of layout 0 / 1 listed for the halo-first G2P2G (halo particle blocks, the others).
  int halo_blocks[2] = {0, 0}, interior_blocks[2] = {0, 0};
  cuda::DeviceArray<T> aux;  ///< (slot, kAuxScalars) recorded v and C
  /// Per-particle initial velocities (GpuEngineOptions::initial_velocities): (ID, 3) on the device for the initial
  /// P2G, and on the host for snapshots before the first step; empty when the body starts at its scene velocity.
  cuda::DeviceArray<T> initial_v;
  std::vector<Vec3<T>> initial_v_host;
  /// A restart (GpuEngineOptions::restart): per particle (ID order) the APIC C on the device for the initial P2G,
  /// and the material state scalars on the host for the upload; empty otherwise.
  cuda::DeviceArray<T> initial_C;
  std::vector<T> restart_state;
  /// Output frame (GpuEngineOptions::frames): its attributes, the device copy a capture step writes (ID order),
  /// the pinned host copy the writer thread reads, and whether that host copy is still being read.
  std::vector<FrameAttributeSpec> frame_attrs;
  FrameCapture<T> capture;
  cuda::DeviceArray<T> frame_x;
  cuda::DeviceArray<float> frame_columns;
  cuda::PinnedBytes frame_host;
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
  cuda::DeviceArray<unsigned> id_bits;
  cuda::DeviceArray<int> id_offset, id_counts;
  cuda::DeviceArray<std::byte> id_scan_temp;
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
  /// Saturated bodies: the seepage channels of bins[cur] added into e.pore_sums_ (kernels/seepage_kernels.cuh);
  /// nothing for other laws.
  virtual void seepage_sums(MgspBenchmark& e) = 0;
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
  /// The pore pressure [Pa] of one gathered record (materials with kOutputs.pore_pressure; NaN for others).
  virtual double pore_pressure_of(const T* record) const = 0;
  virtual bool stores_pore_pressure() const = 0;
  /// psi(state) [J/m^3] of one gathered record.
  virtual double energy_density_of(const T* record) const = 0;
  /// The material's wave speed [m/s] in the state of one gathered record.
  virtual double wave_speed_of(const T* record) const = 0;
};

template <typename T, typename TG>
template <typename M>
struct MgspBenchmark<T, TG>::Body final : BodyBase {
  using Layout = ParticleLayout<M, T>;
  material_params_t<M, T> params;
  ParticleBuffer<M, T> bins[2];

  bool stores_F() const override { return M::kOutputs.deformation_gradient; }
  bool stores_logJp() const override { return M::kOutputs.log_jp; }
  bool stores_pore_pressure() const override { return M::kOutputs.pore_pressure; }
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
      cuda::DeviceArray<T> bigger;
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
    if constexpr (IsPoreFluid<M>::value) p.pore = e.pore_sums_.instance();
    p.gravity = e.k_.gravity;
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
      ::fbar::fbar_cell_sums<M, T, TG><<<blocks, kG2P2GThreads, 0, e.stream_>>>(f);
      cuda::check_launch("fbar_cell_sums");
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
      ::fbar::g2p2g<M, T, TG, true, false><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
    else if (transport && capture)
      ::fbar::g2p2g<M, T, TG, false, true, true><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
    else if (transport)
      ::fbar::g2p2g<M, T, TG, false, true><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
    else if (capture)
      ::fbar::g2p2g<M, T, TG, false, false, true><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
    else
      ::fbar::g2p2g<M, T, TG, false, false><<<blocks, kG2P2GThreads, arena, e.stream_>>>(p);
    cuda::check_launch("g2p2g");
  }

  void seepage_sums(MgspBenchmark& e) override {
    if constexpr (IsPoreFluid<M>::value) {
      const int blocks = e.block_count_;
      if (blocks == 0) return;
      SeepageSumsParams<M, T, TG> f;
      f.in = bins[e.cur_].instance();
      f.layout = this->partition.layout(e.cur_);
      f.table = e.table_.view();
      f.sums = e.pore_sums_.instance();
      f.material = params;
      f.volume = this->volume;
      f.dx = e.k_.dx;
      f.inv_dx = e.k_.inv_dx;
      f.d_inv = e.k_.d_inv;
      f.gravity = e.k_.gravity;
      f.stats = e.stats_d_;
      ::fbar::seepage_sums<M, T, TG><<<blocks, kG2P2GThreads, 0, e.stream_>>>(f);
      cuda::check_launch("seepage_sums");
    }
  }

  void capture_state(MgspBenchmark& e) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                      static_cast<T>(this->spec.velocity[2])}};
    ::fbar::capture_frame_state<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, this->capture, v0,
        this->initial_v.size() ? this->initial_v.get() : nullptr, params, this->mass, this->volume);
    cuda::check_launch("capture_frame_state");
  }

  void mark_ids(MgspBenchmark& e) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    ::fbar::mark_ids<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, this->id_bits.get());
    cuda::check_launch("mark_ids");
  }

  void dest_from_positions(MgspBenchmark& e, int which, const int* valid, int first, int slots) override {
    if (slots <= first) return;
    ::fbar::dest_from_positions<M, T, TG><<<cuda::grid_for(slots - first, kPartitionThreads), kPartitionThreads,
                                      0, e.stream_>>>(
        bins[which].instance(), valid, this->particles, first, slots, e.k_.inv_dx, e.slab_of(this->index), e.table_.view(),
        this->partition.layout(1 - e.cur_).count, this->partition.dest(), e.grid_[0].instance(),
        e.grid_[1].instance(), e.body_stats_d_ + this->index);
    cuda::check_launch("dest_from_positions");
  }

  std::size_t migrant_bytes(const MgspBenchmark& e) const override {
    return ::fbar::migrant_bytes<M, T>(this->asflip, e.record_);
  }
  void pack_emigrants(MgspBenchmark& e, std::byte* lo, std::byte* hi, int capacity, int* count_lo,
                      int* count_hi) override {
    const int listed = static_cast<int>(this->emigrant_slots.size());
    if (listed == 0) return;
    ::fbar::pack_emigrants<M, T><<<cuda::grid_for(listed, kHaloThreads), kHaloThreads, 0, e.stream_>>>(
        bins[1 - e.cur_].instance(), this->emigrant_slots.get(), &e.body_stats_d_[this->index].emigrant_list,
        listed, this->partition.dest(), this->asflip ? this->particle_v[1 - e.cur_].get() : nullptr,
        e.record_ ? this->aux.get() : nullptr, lo, hi, capacity, count_lo, count_hi);
    cuda::check_launch("pack_emigrants");
  }
  void unpack_immigrants(MgspBenchmark& e, int first, const std::byte* in, const int* count, int capacity) override {
    if (capacity == 0) return;
    ::fbar::unpack_immigrants<M, T><<<cuda::grid_for(capacity, kHaloThreads), kHaloThreads, 0, e.stream_>>>(
        bins[1 - e.cur_].instance(), first, in, count, capacity,
        this->asflip ? this->particle_v[1 - e.cur_].get() : nullptr, e.record_ ? this->aux.get() : nullptr,
        this->partition.layout(e.cur_).src);
    cuda::check_launch("unpack_immigrants");
  }

  void rescale_impulse(MgspBenchmark& e, T ddt) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    ::fbar::rescale_impulse<M, T, TG><<<cuda::grid_for(slots, kPartitionThreads), kPartitionThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_), slots, params, this->volume, ddt, e.k_.dx, e.k_.inv_dx,
        e.k_.d_inv, e.table_.view(), e.grid_[e.gc_].instance(), e.stats_d_);
    cuda::check_launch("rescale_impulse");
  }

  void sample_sensors(MgspBenchmark& e, const T* aux, SensorAccum* partials, int per_sensor) override {
    const int slots = this->total_bins[e.cur_] * 32;
    const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                      static_cast<T>(this->spec.velocity[2])}};
    ::fbar::sample_particle_sensors<M, T><<<dim3(per_sensor, e.sensors_.particle.count), kSensorThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, aux, v0, params, this->mass, this->volume,
        e.sensors_.particle, partials);
    cuda::check_launch("sample_particle_sensors");
  }

  void track(MgspBenchmark& e, const T* aux, const TrackerSet& t, double* values, double* present) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                      static_cast<T>(this->spec.velocity[2])}};
    ::fbar::track_particles<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, aux, v0, params, this->mass, this->volume, t,
        values, present);
    cuda::check_launch("track_particles");
  }

  void gather(MgspBenchmark& e, T* out, int* missing, cudaStream_t s) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    // aux was written at the storage slots of bins[cur] (the previous G2P2G's layout order).
    ::fbar::gather_by_id<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, s>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, e.aux_valid_ ? this->aux.get() : nullptr,
        static_cast<int>(this->global_particles), out, missing);
    cuda::check_launch("gather_by_id");
  }

  void state_of(const T* r, T& J, Mat3<T>& F, Mat3<T>& sigma, T& logJp, const Mat3<T>& C) const override {
    material_state_t<M, T> s;
    std::memcpy(&s, r + 3, sizeof(s));
    J = M::volume_ratio(s);
    if constexpr (M::kOutputs.deformation_gradient) F = s.F;
    if constexpr (M::kOutputs.log_jp) logJp = s.logJp;
    sigma = cauchy_stress(M::kirchhoff_stress(params, s, C));
  }
  double pore_pressure_of(const T* r) const override {
    if constexpr (M::kOutputs.pore_pressure) {
      material_state_t<M, T> s;
      std::memcpy(&s, r + 3, sizeof(s));
      return static_cast<double>(M::pore_pressure(s));
    } else {
      return std::numeric_limits<double>::quiet_NaN();
    }
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

}  // namespace fbar
