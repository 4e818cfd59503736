// Body<M>: one material's particle bins and the launches of its kernels (G2P2G, F-bar cell sums, seepage sums, the
// element pass, partition, migration, frames, sensors), behind BodyBase's virtual functions (device_bodies.cuh).
// Included only by body_factory.cuh, so the law kernels are compiled in instances/bodies_<law>.cu alone.
#pragma once

#include "engine/gpu/device_bodies.cuh"

namespace fbar {

template <typename T, typename TG>
template <typename M>
struct MgspBenchmark<T, TG>::Body final : BodyBase {
  using Layout = ParticleLayout<M, T>;
  material_params_t<M, T> params;
  ParticleBuffer<M, T> bins[2];

  bool stores_F() const override { return M::kOutputs.deformation_gradient; }
  bool stores_logJp() const override { return M::kOutputs.log_jp; }
  bool stores_pore_pressure() const override { return M::kOutputs.pore_pressure; }
  /// Scalars of a gathered record and a checkpoint's particle before v and C: position, state, nodal F-bar's 1 - JBar.
  int stored_scalars() const override { return Layout::kScalars + (this->fbar_nodal ? 1 : 0); }
  void allocate_bins(int n) override {
    bins[0].allocate(n);
    bins[1].allocate(n);
    if (this->asflip) {
      this->particle_v[0].allocate(static_cast<std::size_t>(n) * 32 * 3);
      this->particle_v[1].allocate(static_cast<std::size_t>(n) * 32 * 3);
    }
    if (this->fbar_nodal) {
      this->particle_jbar[0].allocate(static_cast<std::size_t>(n) * 32);
      this->particle_jbar[1].allocate(static_cast<std::size_t>(n) * 32);
    }
  }
  void reallocate_bins(int which, int n) override {
    bins[which].allocate(n);
    if (this->asflip) this->particle_v[which].allocate(static_cast<std::size_t>(n) * 32 * 3);
    if (this->fbar_nodal) this->particle_jbar[which].allocate(static_cast<std::size_t>(n) * 32);
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
    if (this->fbar_nodal) {
      cuda::DeviceArray<T> bigger;
      bigger.allocate(static_cast<std::size_t>(n) * 32);
      if (keep_slots > 0)
        FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.get(), this->particle_jbar[which].get(),
                                        sizeof(T) * static_cast<std::size_t>(keep_slots), cudaMemcpyDeviceToDevice, s));
      FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
      this->particle_jbar[which].swap(bigger);
    }
  }
  int bins_capacity(int which) const override { return bins[which].bin_capacity(); }
  std::size_t bins_bytes() const override {
    return bins[0].bytes() + bins[1].bytes() + this->particle_v[0].bytes() + this->particle_v[1].bytes() +
           this->particle_jbar[0].bytes() + this->particle_jbar[1].bytes();
  }

  void upload(const Vec3d* x, const int* ids, std::size_t n, long long first_id, cudaStream_t s) override {
    // Flat bins of this batch on the host (slot = particle ID), one copy to their place in bins[0].
    const std::size_t bins_n = (n + 31) / 32;
    const std::size_t bytes = Layout::kBinBytes * bins_n;
    std::vector<std::byte> host(bytes);
    typename Layout::Buffer view(host.data(), bins_n);
    const auto state = material_initial_state<M, T>(this->spec.material);
    constexpr std::size_t S = Layout::kStateScalars;
    const std::size_t W = S + (this->fbar_nodal ? 1 : 0);  // restart_state: the law's state, then 1 - JBar
    std::vector<T> jbar(this->fbar_nodal ? n : 0);
    for (std::size_t i = 0; i < n; ++i) {
      const int id = ids ? ids[i] : static_cast<int>(first_id + static_cast<long long>(i));
      ParticleRecord<M, T> p{x[i].template cast<T>(), state, id};
      if (this->hydrostatic.active)
        p.state = material_hydrostatic_state<M, T>(params, this->hydrostatic.kirchhoff_pressure(x[i]));
      const T* restart = this->restart_state.empty() ? nullptr : this->restart_state.data() + W * static_cast<std::size_t>(id);
      if (restart) std::memcpy(&p.state, restart, sizeof(p.state));
      if (this->fbar_nodal)  // JBar starts at the particle's own J (a restart's: its checkpoint's)
        jbar[i] = restart && !std::isnan(restart[S]) ? restart[S] : one_minus_volume_ratio<M>(p.state);
      store_particle<M, T>(view, static_cast<int>(i), p);
    }
    std::byte* target = bins[0].instance().data() + Layout::kBinBytes * static_cast<std::size_t>(first_id / 32);
    if (bytes) FBAR_CUDA_CHECK(cudaMemcpyAsync(target, host.data(), bytes, cudaMemcpyHostToDevice, s));
    if (this->fbar_nodal && n)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(this->particle_jbar[0].get() + first_id, jbar.data(), sizeof(T) * n,
                                      cudaMemcpyHostToDevice, s));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
  }

  double seed_states(const ParticleSeeds& seeds) override {
    constexpr std::size_t S = Layout::kStateScalars;
    const std::size_t W = S + (this->fbar_nodal ? 1 : 0);  // nodal F-bar: 1 - JBar, NaN: the state's own
    const auto initial = material_initial_state<M, T>(this->spec.material);
    this->restart_state.assign(W * static_cast<std::size_t>(this->global_particles),
                               std::numeric_limits<T>::quiet_NaN());
    double speed = 0.0;  // of the seeded states (the others are the body's initial state)
    for (long long id = 0; id < this->global_particles; ++id) {
      auto state = initial;
      if (id >= seeds.first) {
        state = material_seeded_state<M, T>(state, seeds.at(static_cast<std::size_t>(id - seeds.first)));
        speed = std::max(speed, static_cast<double>(M::wave_speed(params, state)));
      }
      std::memcpy(this->restart_state.data() + W * static_cast<std::size_t>(id), &state, sizeof(state));
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
    p.velocity = e.grid_velocity().instance();
    p.grid_next = e.grid_sums(1 - e.gc_).view();
    p.grid_this = e.grid_sums(e.gc_).view();
    p.quantum_next = e.quantum(1 - e.gc_);
    p.initial = initial;
    p.bound_only = e.measuring_bound_;
    const bool mesh = this->is_mesh();  // its vertices always record v and C: the element pass's frames read them
    p.aux = e.record_ || mesh ? this->aux.get() : nullptr;
    if (e.capture_next_ && this->capture.x && !mesh) p.capture = this->capture;  // a mesh's: the element pass
    p.vertex_mass = mesh ? this->mesh->vertex_mass.get() : nullptr;
    if (e.asflip_) p.transported_next = e.transported(1 - e.gc_).view();
    p.asflip = this->asflip;
    p.asflip_params = this->asflip_params;
    if (this->asflip) {
      p.old_velocity = e.asflip_velocity().instance();
      p.particle_v_in = this->particle_v[e.cur_].get();
      p.particle_v_out = this->particle_v[1 - e.cur_].get();
    }
    p.fbar_psi = initial ? T(0) : this->fbar_psi;
    if (p.fbar_psi != T(0)) {
      p.fbar_sums = e.fbar_sums().view();
      p.fbar_quantum = fixed_quantum<TG>(static_cast<double>(this->volume));
    }
    p.fbar_nodal = this->fbar_nodal;  // the initial P2G too: it stresses the stored JBar
    p.fbar_fused = this->fbar_fused;
    if (this->fbar_nodal) {
      p.jbar_in = this->particle_jbar[e.cur_].get();
      p.jbar_out = this->particle_jbar[1 - e.cur_].get();
    }
    if constexpr (IsPoreFluid<M>::value) p.pore = e.pore_values().instance();
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
    if (e.measuring_bound_) p.p2g_bound_out = e.p2g_bound_d_.get() + e.bound_cur_ * e.bodies_.size() + this->index;
    // The initial P2G runs the instantiation of a step (a restart's: of the step its checkpoint followed). Kept on
    // every rank, one holding none of the body's particles too: each rank's checkpoint then has the same bytes.
    const bool capture = initial ? this->p2g_capture : p.capture.x != nullptr;
    if (!initial) this->p2g_capture = capture;
    const bool empty = e.block_count_ == 0 || this->particles == 0;
    if (p.fbar_psi != T(0) && pass != G2P2GPass::Interior) {
      // F-bar's sums first (the nodal scheme's node sums, or the cell sums), on every rank: one that holds none of
      // the body's particles adds zeros, since the halo exchange that follows is collective.
      const int blocks = e.block_count_;
      if (blocks > 0) e.fbar_sums().clear(0, blocks, e.stream_);
      if (!empty && this->fbar_nodal) {
        launch_node_sums(e, this->fbar_fused ? FbarNodeValue::Stored : FbarNodeValue::Advanced, p.fbar_quantum, dt);
      } else if (!empty) {
        FbarCellSumsParams<M, T, TG> f;
        f.in = p.in;
        f.layout = p.layout;
        f.table = p.table;
        f.sums = p.fbar_sums;
        f.quantum = p.fbar_quantum;
        f.volume = p.volume;
        f.inv_dx = p.inv_dx;
        f.stats = p.stats;
        ::fbar::fbar_cell_sums<M, T, TG><<<blocks, kParticleBlockThreads, 0, e.stream_>>>(f);
        cuda::check_launch("fbar_cell_sums");
      }
      if (e.decomposed()) e.halo_exchange({e.template halo_of<GridSet::FbarSums>()}, -1);
    }
    if (empty) return;
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
    if (mesh)
      launch_mesh_g2p2g(p, blocks, arena, transport, e.stream_);
    else if (transport && capture)
      ::fbar::launch_g2p2g<M, T, TG, true, true>(p, blocks, arena, e.stream_);
    else if (transport)
      ::fbar::launch_g2p2g<M, T, TG, true>(p, blocks, arena, e.stream_);
    else if (capture)
      ::fbar::launch_g2p2g<M, T, TG, false, true>(p, blocks, arena, e.stream_);
    else
      ::fbar::launch_g2p2g<M, T, TG, false>(p, blocks, arena, e.stream_);
    cuda::check_launch("g2p2g");
    if (mesh && pass == G2P2GPass::All && !e.measuring_bound_) mesh_pass(e);
  }

  /// Node sums of this body's particles (layout(cur)) added into e.fbar_sums() in units of `quantum`
  /// (kernels/fbar_kernels.cuh): nodal F-bar's, or a volume sensor's.
  void launch_node_sums(MgspBenchmark& e, FbarNodeValue value, double quantum, T dt) {
    const int blocks = e.block_count_;
    if (blocks == 0 || this->particles == 0) return;
    FbarNodeSumsParams<M, T, TG> f;
    f.in = bins[e.cur_].instance();
    f.layout = this->partition.layout(e.cur_);
    f.table = e.table_.view();
    f.sums = e.fbar_sums().view();
    f.quantum = quantum;
    f.jbar = this->fbar_nodal ? this->particle_jbar[e.cur_].get() : nullptr;
    f.value = value;
    f.velocity = e.grid_velocity().instance();
    f.volume = this->volume;
    f.vertex_volume = this->is_mesh() ? this->mesh->vertex_volume.get() : nullptr;
    f.dt = dt;
    f.dx = e.k_.dx;
    f.inv_dx = e.k_.inv_dx;
    f.d_inv = e.k_.d_inv;
    f.stats = e.stats_d_;
    ::fbar::fbar_node_sums<M, T, TG><<<blocks, kParticleBlockThreads, 0, e.stream_>>>(f);
    cuda::check_launch("fbar_node_sums");
  }

  void node_volume_sums(MgspBenchmark& e, double quantum) override {
    launch_node_sums(e, this->fbar_nodal ? FbarNodeValue::Stored : FbarNodeValue::OwnJ, quantum, T(0));
  }

  /// The G2P2G of a mesh's vertices (kMesh; instantiated for the element laws only).
  static void launch_mesh_g2p2g(const G2P2GParams<M, T, TG>& p, int blocks, std::size_t arena, bool transport,
                                cudaStream_t s) {
    if constexpr (kMeshLaw<M, T>) {
      if (transport)
        ::fbar::launch_g2p2g<M, T, TG, true, false, true>(p, blocks, arena, s);
      else
        ::fbar::launch_g2p2g<M, T, TG, false, false, true>(p, blocks, arena, s);
    } else {
      throw std::logic_error("GpuEngine: a mesh body with a law that is not an element law");
    }
  }

  void mesh_pass(MgspBenchmark& e) override {
    if constexpr (kMeshLaw<M, T>) {
      MeshDevice<T>& m = *this->mesh;
      const int slots = this->total_bins[e.cur_] * 32;
      if (!m.on_device() || slots == 0) return;
      MeshView<T> view = m.view();
      const auto grid = [](long long n) { return cuda::grid_for(static_cast<int>(std::max(n, 1LL)), kFemThreads); };
      BodyStepStats* stats = e.body_stats_d_ + this->index;
      m.timed = e.timing_;
      if (m.timed) {
        for (cudaEvent_t& ev : m.pass_events)
          if (!ev) FBAR_CUDA_CHECK(cudaEventCreate(&ev));
        FBAR_CUDA_CHECK(cudaEventRecord(m.pass_events[0], e.stream_));
      }
      ::fbar::mesh_index_vertices<M, T><<<grid(slots), kFemThreads, 0, e.stream_>>>(
          bins[1 - e.cur_].instance(), bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, e.k_.inv_dx,
          view);
      cuda::check_launch("mesh_index_vertices");
      ::fbar::mesh_element_pass<M, T><<<grid(view.element_count), kFemThreads, 0, e.stream_>>>(view, params, stats);
      cuda::check_launch("mesh_element_pass");
      if (view.fbar_psi != T(0)) {
        ::fbar::mesh_vertex_volume_ratio<T><<<grid(view.vertex_count), kFemThreads, 0, e.stream_>>>(view, stats);
        cuda::check_launch("mesh_vertex_volume_ratio");
        ::fbar::mesh_fbar_elements<M, T><<<grid(view.element_count), kFemThreads, 0, e.stream_>>>(view, params, stats);
        cuda::check_launch("mesh_fbar_elements");
      }
      MeshVertexParams<M, T, TG> vp;
      vp.mesh = view;
      vp.bins = bins[1 - e.cur_].instance();
      vp.params = params;
      vp.force = m.force[1 - m.force_cur].get();
      vp.table = e.table_.view();
      vp.grid_next = e.grid_sums(1 - e.gc_).view();
      vp.quantum_next = e.quantum(1 - e.gc_);
      vp.dt_next = &e.stats_d_->dt_next;
      vp.inv_dx = e.k_.inv_dx;
      vp.aux = this->aux.get();
      if (e.capture_next_ && this->capture.x) vp.capture = this->capture;
      vp.measures = this->measures();
      vp.stats = e.stats_d_;
      vp.body_stats = stats;
      vp.wave_speed = e.wave_d_.get() + (1 - e.wave_cur_) * e.bodies_.size() + this->index;
      ::fbar::mesh_vertex_pass<M, T, TG><<<grid(view.vertex_count), kFemThreads, 0, e.stream_>>>(vp);
      cuda::check_launch("mesh_vertex_pass");
      if (m.timed) FBAR_CUDA_CHECK(cudaEventRecord(m.pass_events[1], e.stream_));
    }
  }

  void seepage_sums(MgspBenchmark& e, bool bounds_only) override {
    if constexpr (IsPoreFluid<M>::value) {
      const int blocks = e.block_count_;
      if (blocks == 0) return;
      SeepageSumsParams<M, T, TG> f;
      f.in = bins[e.cur_].instance();
      f.layout = this->partition.layout(e.cur_);
      f.table = e.table_.view();
      f.sums = e.pore_sums().view();
      f.bound = e.pore_bound_d_.get();
      f.bounds_only = bounds_only;
      f.material = params;
      f.volume = this->volume;
      f.dx = e.k_.dx;
      f.inv_dx = e.k_.inv_dx;
      f.d_inv = e.k_.d_inv;
      f.gravity = e.k_.gravity;
      f.stats = e.stats_d_;
      ::fbar::seepage_sums<M, T, TG><<<blocks, kParticleBlockThreads, 0, e.stream_>>>(f);
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
        this->initial_v.size() ? this->initial_v.get() : nullptr, params, this->measures(), jbar_now(e));
    cuda::check_launch("capture_frame_state");
  }

  void mark_ids(MgspBenchmark& e) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    ::fbar::mark_ids<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, this->id_bits.get());
    cuda::check_launch("mark_ids");
  }

  void dest_from_positions(MgspBenchmark& e, int which, const int* valid, int first, int slots,
                           const int* blocks) override {
    if (slots <= first) return;
    ::fbar::dest_from_positions<M, T, TG><<<cuda::grid_for(slots - first, kPartitionThreads), kPartitionThreads,
                                      0, e.stream_>>>(
        bins[which].instance(), valid, this->particles, first, slots, e.k_.inv_dx, e.slab_of(this->index), e.table_.view(),
        this->partition.layout(1 - e.cur_).count, this->partition.dest(), e.grid_sums(0).view(), e.grid_sums(1).view(),
        e.body_stats_d_ + this->index, blocks);
    cuda::check_launch("dest_from_positions");
  }

  void record_p2g_blocks(MgspBenchmark& e) override {
    const int slots = this->total_bins[e.cur_] * 32;
    this->p2g_slots = slots;
    if (slots == 0) return;
    if (this->p2g_record.size() < 2 * static_cast<std::size_t>(slots))
      this->p2g_record.allocate(2 * static_cast<std::size_t>(this->partition.bin_capacity()) * 32);
    const int blocks = std::min(e.block_capacity_, std::max(e.block_count_, e.stats_->block_count));
    if (blocks == 0) return;
    ::fbar::record_p2g_blocks<M, T><<<blocks, kOutputThreads, 0, e.stream_>>>(
        bins[1 - e.cur_].instance(), this->partition.layout(e.cur_), slots, this->p2g_record.get());
    cuda::check_launch("record_p2g_blocks");
  }

  std::size_t migrant_bytes(const MgspBenchmark& e) const override {
    return ::fbar::migrant_bytes<M, T>(this->asflip, e.record_, this->fbar_nodal);
  }
  void pack_emigrants(MgspBenchmark& e, std::byte* lo, std::byte* hi, int capacity, int* count_lo,
                      int* count_hi) override {
    const int listed = static_cast<int>(this->emigrant_slots.size());
    if (listed == 0) return;
    ::fbar::pack_emigrants<M, T><<<cuda::grid_for(listed, kHaloThreads), kHaloThreads, 0, e.stream_>>>(
        bins[1 - e.cur_].instance(), this->emigrant_slots.get(), &e.body_stats_d_[this->index].emigrant_list,
        listed, this->partition.dest(), this->asflip ? this->particle_v[1 - e.cur_].get() : nullptr,
        e.record_ ? this->aux.get() : nullptr, lo, hi, capacity, count_lo, count_hi,
        this->fbar_nodal ? this->particle_jbar[1 - e.cur_].get() : nullptr);
    cuda::check_launch("pack_emigrants");
  }
  void unpack_immigrants(MgspBenchmark& e, int first, const std::byte* in, const int* count, int capacity) override {
    if (capacity == 0) return;
    ::fbar::unpack_immigrants<M, T><<<cuda::grid_for(capacity, kHaloThreads), kHaloThreads, 0, e.stream_>>>(
        bins[1 - e.cur_].instance(), first, in, count, capacity,
        this->asflip ? this->particle_v[1 - e.cur_].get() : nullptr, e.record_ ? this->aux.get() : nullptr,
        this->partition.layout(e.cur_).src, this->fbar_nodal ? this->particle_jbar[1 - e.cur_].get() : nullptr);
    cuda::check_launch("unpack_immigrants");
  }

  void rescale_impulse(MgspBenchmark& e, T ddt) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    if (this->is_mesh()) {  // no MLS stress: the elements' force f (ddt) at each vertex
      MeshDevice<T>& m = *this->mesh;
      if (!m.on_device() || !m.forces) return;
      ::fbar::mesh_rescale_impulse<M, T, TG><<<cuda::grid_for(slots, kFemThreads), kFemThreads, 0, e.stream_>>>(
          bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, m.force[m.force_cur].get(),
          static_cast<int>(m.mass.size()), ddt, e.k_.inv_dx, e.table_.view(), e.grid_sums(e.gc_).view(), e.quantum(e.gc_),
          e.stats_d_);
      cuda::check_launch("mesh_rescale_impulse");
      return;
    }
    ::fbar::rescale_impulse<M, T, TG><<<cuda::grid_for(slots, kPartitionThreads), kPartitionThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_), slots, params, this->volume, ddt, e.k_.dx, e.k_.inv_dx,
        e.k_.d_inv, e.table_.view(), e.grid_sums(e.gc_).view(), e.quantum(e.gc_), e.stats_d_, jbar_now(e));
    cuda::check_launch("rescale_impulse");
  }

  void sample_sensors(MgspBenchmark& e, const T* aux, SensorAccum* partials, int per_sensor) override {
    const int slots = this->total_bins[e.cur_] * 32;
    const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                      static_cast<T>(this->spec.velocity[2])}};
    ::fbar::sample_particle_sensors<M, T><<<dim3(per_sensor, e.sensors_.particle.count), kSensorThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, aux, v0, params, this->measures(),
        e.sensors_.particle, partials, jbar_now(e));
    cuda::check_launch("sample_particle_sensors");
  }

  void track(MgspBenchmark& e, const T* aux, const TrackerSet& t, double* values, double* present) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    const Vec3<T> v0{{static_cast<T>(this->spec.velocity[0]), static_cast<T>(this->spec.velocity[1]),
                      static_cast<T>(this->spec.velocity[2])}};
    ::fbar::track_particles<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, e.stream_>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, aux, v0, params, this->measures(), t,
        values, present, jbar_now(e));
    cuda::check_launch("track_particles");
  }

  void gather(MgspBenchmark& e, T* out, int* held, int* missing, cudaStream_t s, int first, int count) override {
    const int slots = this->total_bins[e.cur_] * 32;
    if (slots == 0) return;
    // aux was written at the storage slots of bins[cur] (the previous G2P2G's layout order).
    ::fbar::gather_by_id<M, T><<<cuda::grid_for(slots, kOutputThreads), kOutputThreads, 0, s>>>(
        bins[e.cur_].instance(), this->partition.layout(e.cur_).src, slots, e.aux_valid_ ? this->aux.get() : nullptr,
        static_cast<int>(this->global_particles), first, count, out, held, missing, jbar_now(e));
    cuda::check_launch("gather_by_id");
  }

  /// Nodal F-bar: the particles' 1 - JBar at the storage slots of bins[cur]; nullptr otherwise.
  const T* jbar_now(const MgspBenchmark& e) const {
    return this->fbar_nodal ? this->particle_jbar[e.cur_].get() : nullptr;
  }
  T jbar_of(const T* r) const override {
    material_state_t<M, T> s;
    std::memcpy(&s, r + 3, sizeof(s));
    return this->fbar_nodal ? T(1) - r[Layout::kScalars] : M::volume_ratio(s);
  }
  void state_of(const T* r, T& J, Mat3<T>& F, Mat3<T>& sigma, T& logJp, const Mat3<T>& C) const override {
    material_state_t<M, T> s;
    std::memcpy(&s, r + 3, sizeof(s));
    J = M::volume_ratio(s);
    if constexpr (M::kOutputs.deformation_gradient) F = s.F;
    if constexpr (M::kOutputs.log_jp) logJp = s.logJp;
    const material_state_t<M, T> stressed = this->fbar_nodal ? fbar_stress_state<M>(params, s, r[Layout::kScalars]) : s;
    sigma = cauchy_stress(M::kirchhoff_stress(params, stressed, C));
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
  double element_energy_density(const Mat3<T>& F) const override {
    if constexpr (kMeshLaw<M, T>)
      return static_cast<double>(M::energy_density(params, material_state_t<M, T>{F}));
    else
      return std::numeric_limits<double>::quiet_NaN();
  }
  double wave_speed_of(const T* r) const override {
    material_state_t<M, T> s;
    std::memcpy(&s, r + 3, sizeof(s));
    return static_cast<double>(M::wave_speed(params, s));
  }
};

}  // namespace fbar
