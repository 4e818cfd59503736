// Bodies on the device: what every body holds (BodyBase: counts, partition, frame buffers, the virtual launches the
// driver calls). Body<M>, one material's bins and its kernels' launches, is in body.cuh. Part of MgspBenchmark
// (mgsp_benchmark.cuh).
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

/// A mesh body's elements on the device (physics/fem.cuh, kernels/fem_kernels.cuh): built from the scene's mesh on
/// every rank (the vertex masses), its device arrays only on the rank holding the vertices.
template <typename T>
struct MeshDevice {
  MeshElements<T> host;              ///< elements, CSR and lumped volumes (host; the energy reads them)
  std::vector<T> mass, volume;       ///< (vertex) lumped mass [kg] and volume [m^3]
  T fbar_psi = T(0);                 ///< use_FBAR's blend
  bool forces = false;               ///< use_FEM
  cuda::DeviceArray<TetElement<T>> elements;
  cuda::DeviceArray<int> vertex_start, vertex_elements, slot;
  cuda::DeviceArray<T> vertex_mass, vertex_volume, J, vertex_J;
  cuda::DeviceArray<Vec3<T>> x, force[2];
  cuda::DeviceArray<Mat3<T>> F, H;
  int force_cur = 0;                 ///< force[force_cur]: the elements' force at the committed positions
  /// Kernel timing: the element pass of the try between the two events (created at the first timed pass).
  cudaEvent_t pass_events[2] = {nullptr, nullptr};
  bool timed = false;
  MeshDevice() = default;
  MeshDevice(const MeshDevice&) = delete;
  MeshDevice& operator=(const MeshDevice&) = delete;
  ~MeshDevice() {
    for (cudaEvent_t e : pass_events)
      if (e) cudaEventDestroy(e);
  }
  bool on_device() const { return vertex_mass.size() != 0; }
  std::size_t device_bytes() const {
    return elements.bytes() + vertex_start.bytes() + vertex_elements.bytes() + slot.bytes() + vertex_mass.bytes() +
           vertex_volume.bytes() + J.bytes() + vertex_J.bytes() + x.bytes() + force[0].bytes() + force[1].bytes() +
           F.bytes() + H.bytes();
  }
  static_assert(sizeof(TetElement<T>) == 16 + 10 * sizeof(T), "mesh_device_bytes (memory_plan.cpp) counts 16 + 10 t");
  void upload(cudaStream_t s) {
    const std::size_t ne = host.elements.size(), nv = mass.size();
    elements.allocate(std::max<std::size_t>(ne, 1));
    vertex_start.allocate(nv + 1);
    vertex_elements.allocate(std::max<std::size_t>(host.vertex_elements.size(), 1));
    slot.allocate(std::max<std::size_t>(nv, 1));
    vertex_mass.allocate(std::max<std::size_t>(nv, 1));
    vertex_volume.allocate(std::max<std::size_t>(nv, 1));
    x.allocate(std::max<std::size_t>(nv, 1));
    force[0].allocate(std::max<std::size_t>(nv, 1));
    force[1].allocate(std::max<std::size_t>(nv, 1));
    F.allocate(std::max<std::size_t>(ne, 1));
    if (forces) H.allocate(std::max<std::size_t>(ne, 1));
    if (fbar_psi != T(0)) {
      J.allocate(std::max<std::size_t>(ne, 1));
      vertex_J.allocate(std::max<std::size_t>(nv, 1));
    }
    const auto copy = [&](void* to, const void* from, std::size_t bytes) {
      if (bytes) FBAR_CUDA_CHECK(cudaMemcpyAsync(to, from, bytes, cudaMemcpyHostToDevice, s));
    };
    copy(elements.get(), host.elements.data(), sizeof(TetElement<T>) * ne);
    copy(vertex_start.get(), host.vertex_start.data(), sizeof(int) * (nv + 1));
    copy(vertex_elements.get(), host.vertex_elements.data(), sizeof(int) * host.vertex_elements.size());
    copy(vertex_mass.get(), mass.data(), sizeof(T) * nv);
    copy(vertex_volume.get(), volume.data(), sizeof(T) * nv);
    FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
  }
  MeshView<T> view() {
    MeshView<T> v;
    v.elements = elements.get();
    v.element_count = static_cast<int>(host.elements.size());
    v.vertex_start = vertex_start.get();
    v.vertex_elements = vertex_elements.get();
    v.vertex_count = static_cast<int>(mass.size());
    v.x = x.get();
    v.slot = slot.get();
    v.F = F.get();
    v.J = J.get();
    v.vertex_J = vertex_J.get();
    v.H = H.get();
    v.fbar_psi = fbar_psi;
    v.forces = forces;
    return v;
  }
};

template <typename T, typename TG>
struct MgspBenchmark<T, TG>::BodyBase {
  BodySpec spec;
  /// A mesh body (spec.mesh >= 0): its elements and vertex masses; null for particle bodies.
  std::unique_ptr<MeshDevice<T>> mesh;
  bool is_mesh() const { return mesh != nullptr; }
  /// The body's masses for the kernels that read them (a mesh's per vertex, on the rank holding it).
  ParticleMeasures<T> measures() const {
    ParticleMeasures<T> m{mass, volume, nullptr, nullptr};
    if (mesh && mesh->on_device()) {
      m.vertex_mass = mesh->vertex_mass.get();
      m.vertex_volume = mesh->vertex_volume.get();
    }
    return m;
  }
  /// [kg], [m^3] of the particle with this ID.
  T mass_of(std::size_t id) const { return mesh ? mesh->mass[id] : mass; }
  T volume_of(std::size_t id) const { return mesh ? mesh->volume[id] : volume; }
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
  bool fbar_nodal = false;  ///< nodal F-bar (physics/fbar_nodal.cuh), else the cell scheme
  bool fbar_fused = false;  ///< nodal F-bar's fused variant (FBAR_fused_kernel), else the split one
  /// Nodal F-bar only: (slot) each particle's 1 - JBar beside bins[0] / bins[1], same slots (empty otherwise).
  cuda::DeviceArray<T> particle_jbar[2];
  bool asflip = false;  ///< PIC-FLIP / ASFLIP (transfer.cuh)
  AsflipParams<T> asflip_params{T(0), T(0), T(0)};
  /// ASFLIP only: (slot, 3) particle velocities beside bins[0] / bins[1], same slots (empty otherwise).
  cuda::DeviceArray<T> particle_v[2];
  PartitionDomain partition;
  int total_bins[2] = {0, 0};  ///< bins of layout 0 / 1
  /// Decomposed runs: blocks of layout 0 / 1 listed for the halo-first G2P2G (halo particle blocks, the others).
  int halo_blocks[2] = {0, 0}, interior_blocks[2] = {0, 0};
  cuda::DeviceArray<T> aux;  ///< (slot, kAuxScalars) recorded v and C
  /// A step that records for a checkpoint also records, per slot of the layout its G2P2G read, the particle's ID and
  /// the table index of the block it was summed from (record_p2g_blocks; -1 for an empty lane): what a checkpoint
  /// keeps so that a restart groups the particles as the run did. p2g_slots: the slots written.
  cuda::DeviceArray<int> p2g_record;
  int p2g_slots = 0;
  /// A restart whose checkpoint kept those blocks: the block coordinates (3 per slot) of the flat upload, read by
  /// the initial partition (dest_from_positions) and freed after it.
  cuda::DeviceArray<int> restart_blocks;
  /// Whether the last G2P2G was a frame step's (the kCapture instantiation): a checkpoint keeps it and a restart's
  /// P2G runs that instantiation again, so that it sums the grid with the machine code its run did.
  bool p2g_capture = false;
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
    /// A streamed frame (GpuEngineOptions::frame_host_bytes): the writer reads the device frame too, so the next
    /// capture waits for the release.
    bool device = false;
    /// The writer's hold on the slot: the host buffer (and a streamed frame's device frame) goes back to the step
    /// loop when it ends, also when the writing throws.
    struct Hold {
      std::shared_ptr<HostSlot> slot;
      ~Hold() {
        {
          std::lock_guard<std::mutex> lock(slot->mutex);
          slot->busy = false;
          slot->device = false;
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
  /// Saturated bodies: the seepage channels of bins[cur] added into e.pore_sums() (kernels/seepage_kernels.cuh), or
  /// (bounds_only) their bounds raised in e.pore_bound_d_; nothing for other laws.
  virtual void seepage_sums(MgspBenchmark& e, bool bounds_only) = 0;
  /// A Volume or JBar grid sensor's sample: this body's w V (1 - JBar) and w V of bins[cur] added into
  /// e.fbar_sums() in units of `quantum` (kernels/fbar_kernels.cuh fbar_node_sums).
  virtual void node_volume_sums(MgspBenchmark& e, double quantum) = 0;
  /// blocks: a restart's recorded block per slot (3 ints), or nullptr to take each particle's from its position.
  virtual void dest_from_positions(MgspBenchmark& e, int bins_which, const int* valid, int first, int slots,
                                   const int* blocks = nullptr) = 0;
  /// Into p2g_record: the IDs and blocks of layout(cur)'s particles, which the G2P2G just wrote to bins[1 - cur].
  virtual void record_p2g_blocks(MgspBenchmark& e) = 0;
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
  /// A mesh body, after the G2P2G wrote bins[1 - cur] in layout(cur)'s order: the element pass
  /// (kernels/fem_kernels.cuh) into those bins, mesh->force[1 - force_cur] and grid[1 - gc].
  virtual void mesh_pass(MgspBenchmark& e) = 0;
  /// The particles with IDs first .. first + count - 1 into out (count x (stored scalars + kAuxScalars), ID
  /// order; kernels/output_kernels.cuh gather_by_id) and their IDs into held (nullptr: not written).
  virtual void gather(MgspBenchmark& e, T* out, int* held, int* missing, cudaStream_t s, int first, int count) = 0;
  /// Particle sensors over this body's particles into partials (sensor, CUDA block); aux: v and C, or nullptr
  /// (before the first step: the initial velocity, C = 0).
  virtual void sample_sensors(MgspBenchmark& e, const T* aux, SensorAccum* partials, int per_sensor) = 0;
  /// The tracker's particles this rank holds into values / present (device, zeroed beforehand).
  virtual void track(MgspBenchmark& e, const T* aux, const TrackerSet& t, double* values, double* present) = 0;
  virtual bool stores_logJp() const = 0;
  /// JBar of one gathered record: nodal F-bar's, else J.
  virtual T jbar_of(const T* record) const = 0;
  /// J, F, Cauchy stress and logJp of one gathered record (F and logJp left as they are for a material without).
  virtual void state_of(const T* record, T& J, Mat3<T>& F, Mat3<T>& sigma, T& logJp, const Mat3<T>& C) const = 0;
  /// The pore pressure [Pa] of one gathered record (materials with kOutputs.pore_pressure; NaN for others).
  virtual double pore_pressure_of(const T* record) const = 0;
  virtual bool stores_pore_pressure() const = 0;
  /// psi(state) [J/m^3] of one gathered record.
  virtual double energy_density_of(const T* record) const = 0;
  /// psi(F) [J/m^3] of an element law at gradient F (a mesh's elements; NaN for other laws).
  virtual double element_energy_density(const Mat3<T>& F) const = 0;
  /// The material's wave speed [m/s] in the state of one gathered record.
  virtual double wave_speed_of(const T* record) const = 0;
};

}  // namespace fbar
