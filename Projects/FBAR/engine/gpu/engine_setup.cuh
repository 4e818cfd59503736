// Construction: bodies counted and described, the memory plan checked against the device, buffers allocated, the
// particles sampled and uploaded, the initial P2G and partition (or a restart's state). Part of MgspBenchmark.
#pragma once

#include <cub/device/device_scan.cuh>

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

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
    dec_.host = options.ranks;
    dec_.device = options.device_ranks;
  }
  if (options.migrant_capacity < 1)
    throw std::invalid_argument("GpuEngine: migrant_capacity must be at least 1");
  dec_.migrant_capacity = options.migrant_capacity;
  dec_.slabs = comm::choose_slabs(comm::PlaneCounts{}, 1);  // all of space (a decomposed run chooses below)
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
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b)
    max_speed = std::max(max_speed, add_body(b, positions, seeds[b]));
  max_grid_speed_ = max_speed;
  if (const io::Checkpoint* cp = options.restart) restore_bodies(*cp);
  for (auto& b : bodies_)  // a restart's checkpoint holds the state instead
    if (!options.restart && !seeds[static_cast<std::size_t>(b->index)].empty())
      b->rest_wave_speed = std::max(b->rest_wave_speed, b->seed_states(seeds[static_cast<std::size_t>(b->index)]));
  if (decomposed()) choose_slabs(positions);

  plan_memory();

  initialize(positions);
  counts_.clear();
  counts_.shrink_to_fit();
  peak_bytes_ = device_bytes();
}

/// Body b described from the scene (its particles counted, or the given positions checked), its material's Body<M>
/// made, its initial velocities uploaded; seeds receives what a has_attributes file gives per particle. Returns
/// the largest initial speed of its particles [m/s].
template <typename T, typename TG>
double MgspBenchmark<T, TG>::add_body(int b, const std::vector<std::vector<Vec3d>>* positions, ParticleSeeds& seed) {
  const SimulationSpec& sim = scene_.simulation;
  const GpuEngineOptions& options = options_;
  double max_speed = 0.0;
  const BodySpec& spec = scene_.bodies[static_cast<std::size_t>(b)];
  const std::string where = "bodies[" + std::to_string(b) + "]";
  check_engine_body(spec, b, "GPU engine");
  const MaterialSpec& mat = spec.material;
  const AlgorithmSpec& alg = spec.algorithm;
  Aabb geometry_bounds{};  // the free surface of a hydrostatic body is its top (engine/hydrostatic.h)
  if (positions) {
    const std::vector<Vec3d>& x = (*positions)[static_cast<std::size_t>(b)];
    const Vec3d domain{{sim.domain[0], sim.domain[1], sim.domain[2]}};
    for (std::size_t p = 0; p < x.size(); ++p)
      if (!inside_domain(x[p], domain, sim.dx))
        throw std::invalid_argument(where + ": particle " + std::to_string(p) + " lies outside the domain");
    counts_.push_back(count_points(x, sim.dx));
    if (spec.initial_state == InitialState::Hydrostatic)
      geometry_bounds = body_geometry_bounds(spec, sim, b);
  } else if (spec.mesh >= 0) {  // a mesh's particles are its vertices (the parser checked them against the domain)
    counts_.push_back(count_points(scene_.meshes.at(static_cast<std::size_t>(spec.mesh)).mesh->vertices, sim.dx));
  } else {
    // Counted without storing a point (throws SceneError for particles outside the domain, or none at all).
    BodySampler sampler(spec, sim, b);
    counts_.push_back(sampler.count(sim.dx));
    seed = sampler.take_seeds(counts_.back().particles);
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
  visit_material(mat.law, [&](auto m) { bodies_.push_back(new_body<decltype(m)>(mat, hydrostatic, geometry_bounds)); });
  BodyBase& body = *bodies_.back();
  body.spec = spec;
  body.hydrostatic = hydrostatic;
  body.index = b;
  body.particles = static_cast<int>(counts_.back().particles);
  body.global_particles = counts_.back().particles;
  const double volume = sim.dx * sim.dx * sim.dx / mat.ppc;
  body.volume = static_cast<T>(volume);
  body.mass = static_cast<T>(mat.rho * volume);
  if (spec.mesh >= 0) add_mesh(body);
  body.asflip = alg.asflip_active();
  body.asflip_params = AsflipParams<T>{static_cast<T>(alg.asflip_alpha), static_cast<T>(alg.asflip_beta_min),
                                       static_cast<T>(alg.asflip_beta_max)};
  asflip_ = asflip_ || body.asflip;
  body.fbar_psi = static_cast<T>(alg.fbar_blend());
  body.fbar_nodal = alg.fbar_nodal() && spec.mesh < 0;
  body.fbar_fused = alg.fbar_fused_kernel;
  fbar_ = fbar_ || body.fbar_psi != T(0);
  pore_ = pore_ || material_has_pore_fluid(mat.law);
  max_speed = std::max(max_speed, std::sqrt(spec.velocity[0] * spec.velocity[0] +
                                            spec.velocity[1] * spec.velocity[1] +
                                            spec.velocity[2] * spec.velocity[2]));
  std::vector<Vec3d> seeded_v;  // the body's velocity, or a seed's (has_attributes)
  if (!seed.empty()) {
    seeded_v.assign(static_cast<std::size_t>(body.global_particles),
                    Vec3d{{spec.velocity[0], spec.velocity[1], spec.velocity[2]}});
    for (std::size_t i = 0; i < seed.size(); ++i) {
      const double* sv = seed.at(i) + kSeedVelocity;
      if (!std::isnan(sv[0])) seeded_v[static_cast<std::size_t>(seed.first) + i] = Vec3d{{sv[0], sv[1], sv[2]}};
    }
  }
  const bool given_v = static_cast<std::size_t>(b) < options.initial_velocities.size() &&
                       !options.initial_velocities[static_cast<std::size_t>(b)].empty();
  if (given_v || !seeded_v.empty()) {
    const std::vector<Vec3d>& v = given_v ? options.initial_velocities[static_cast<std::size_t>(b)] : seeded_v;
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
    // A copy from pageable memory may return before its DMA ends, and the non-blocking streams do not wait for it.
    FBAR_CUDA_CHECK(cudaStreamSynchronize(cudaStreamLegacy));
  }
  return max_speed;
}

/// A mesh body (physics/fem.cuh): its elements and lumped vertex masses from the scene's mesh (every rank: the
/// checkpoints and frames read the masses; the device arrays follow on the rank holding the vertices).
template <typename T, typename TG>
void MgspBenchmark<T, TG>::add_mesh(BodyBase& body) {
  const MeshEntrySpec& entry = scene_.meshes.at(static_cast<std::size_t>(body.spec.mesh));
  bool element_law = false;
  visit_material(body.spec.material.law, [&](auto m) { element_law = kMeshLaw<decltype(m), T>; });
  if (!element_law)
    throw std::invalid_argument("meshes[" + std::to_string(body.spec.mesh) + "].constitutive: " +
                                to_string(body.spec.material.law) +
                                " is not an element law (FixedCorotated, NeoHookean)");
  auto m = std::make_unique<MeshDevice<T>>();
  m->host = mesh_elements<T>(*entry.mesh);
  m->fbar_psi = entry.fbar_elements ? static_cast<T>(entry.fbar_ratio) : T(0);
  m->forces = body.spec.algorithm.use_fem;
  const double rho = body.spec.material.rho;
  T most_mass = T(0), most_volume = T(0);
  for (const double V : m->host.lumped_volume) {
    m->volume.push_back(static_cast<T>(V));
    m->mass.push_back(static_cast<T>(rho * V));
    most_mass = std::max(most_mass, m->mass.back());
    most_volume = std::max(most_volume, m->volume.back());
  }
  // The per-body values bound the vertices' (the fixed-point P2G quantum, kernels/g2p2g_kernel.cuh).
  body.mass = most_mass;
  body.volume = most_volume;
  body.mesh = std::move(m);
}

// The plan (memory_plan.h): capacities and every buffer's size, from the counts; refused before anything is
// allocated or sampled when it does not fit the device.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::plan_memory() {
  const SimulationSpec& sim = scene_.simulation;
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
    in.stored_scalars = body.stored_scalars() - (body.fbar_nodal ? 1 : 0);  // the bins' (1 - JBar: fbar_nodal)
    in.asflip = body.asflip;
    in.fbar = body.fbar_psi != T(0);
    in.fbar_nodal = body.fbar_nodal;
    in.pore = material_has_pore_fluid(body.spec.material.law);
    in.record = record || body.mesh;  // a mesh's vertices always record v and C
    in.checkpoints = sim.checkpoint_every > 0;
    if (body.mesh && counts_[b].particles > 0) {  // the rank holding the mesh
      const MeshEntrySpec& entry = scene_.meshes.at(static_cast<std::size_t>(body.spec.mesh));
      in.mesh_bytes = mesh_device_bytes(kPrecision, entry.stats.elements, entry.stats.vertices, entry.fbar_elements,
                                        body.mesh->forces);
    }
    if (options_.frames) {
      body.frame_attrs = frame_attributes(body.spec, body.index, "GPU engine");
      in.frame_columns = frame_float_columns(body.frame_attrs);
    }
    inputs.push_back(in);
  }
  plan_ = plan_device_memory(kPrecision, footprint_blocks(all), inputs, scene_reads_node_volume(scene_));
  plan_.small += sensor_device_bytes(scene_) + grid_field_device_bytes(scene_);
  if (plan_.block_capacity > DeviceLimits::kMaxBlocks)
    throw std::invalid_argument("GpuEngine: " + std::to_string(plan_.block_capacity) + " grid blocks of capacity; at most " +
                                std::to_string(DeviceLimits::kMaxBlocks) + " per device (docs/user_guide.md \"Limits\")");
  std::size_t free_bytes = 0, total_bytes = 0;
  cuda::memory_info(free_bytes, total_bytes);
  if (options_.memory_limit > 0) free_bytes = std::min(free_bytes, options_.memory_limit);
  const std::string fit = memory_fit_message(plan_, free_bytes, total_bytes, scene_, "GPU 0");
  if (!fit.empty()) throw cuda::OutOfMemory("the scene does not fit: " + fit + " (fbar --check prints the plan)");
}

template <typename T, typename TG>
MgspBenchmark<T, TG>::~MgspBenchmark() {
  // Buffers free themselves; streams and events last (no throw from a destructor).
  if (stream_) cudaStreamSynchronize(stream_);
  if (copy_stream_) cudaStreamSynchronize(copy_stream_);
  if (dec_.halo_stream) cudaStreamSynchronize(dec_.halo_stream);
  for (cudaEvent_t& e : events_)
    if (e) cudaEventDestroy(e);
  for (cudaEvent_t& e : dec_.halo_events)
    if (e) cudaEventDestroy(e);
  if (dec_.halo_ready) cudaEventDestroy(dec_.halo_ready);
  if (dec_.halo_done) cudaEventDestroy(dec_.halo_done);
  if (dec_.halo_stream) cudaStreamDestroy(dec_.halo_stream);
  if (stream_) cudaStreamDestroy(stream_);
  if (copy_stream_) cudaStreamDestroy(copy_stream_);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::initialize(const std::vector<std::vector<Vec3d>>* positions) {
  allocate_device_state(positions);  // streams, grid, bins holding the uploaded particles, statistics
  partition_upload();                // layout 0 from the flat upload
  initial_p2g();                     // the P2G of the initial state (or a restart's), ready for step 1
}

/// Streams and events, the grid and table at the plan's capacity, every body's bins with its particles uploaded
/// flat (slot = ID), frame buffers, the step statistics and the wave speeds of the rest states.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::allocate_device_state(const std::vector<std::vector<Vec3d>>* positions) {
  FBAR_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
  FBAR_CUDA_CHECK(cudaStreamCreateWithFlags(&copy_stream_, cudaStreamNonBlocking));
  for (cudaEvent_t& e : events_) FBAR_CUDA_CHECK(cudaEventCreate(&e));
  if (decomposed()) {
    // The highest priority: its pack / exchange / add kernels take SMs as the interior G2P2G's blocks retire.
    int least = 0, greatest = 0;
    FBAR_CUDA_CHECK(cudaDeviceGetStreamPriorityRange(&least, &greatest));
    FBAR_CUDA_CHECK(cudaStreamCreateWithPriority(&dec_.halo_stream, cudaStreamNonBlocking, greatest));
    FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&dec_.halo_ready, cudaEventDisableTiming));
    FBAR_CUDA_CHECK(cudaEventCreateWithFlags(&dec_.halo_done, cudaEventDisableTiming));
    for (cudaEvent_t& e : dec_.halo_events) FBAR_CUDA_CHECK(cudaEventCreate(&e));
  }

  // Capacities from the plan (options may start them smaller: tests exercise growth).
  block_capacity_ = options_.block_capacity > 0 ? options_.block_capacity : static_cast<int>(plan_.block_capacity);
  table_.allocate(block_capacity_, stream_);
  channels_.allocate(block_capacity_, GridFeatures{asflip_, fbar_, pore_});
  if (pore_) pore_bound_d_.allocate(kSeepageChannels);
  quantum_d_.allocate(2);
  mass_bound_ = 0.0;
  for (const auto& b : bodies_) mass_bound_ = std::max(mass_bound_, static_cast<double>(b->mass));
  if (decomposed()) mass_bound_ = dec_.host->max(mass_bound_);  // every rank sums in the same quanta
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    BodyBase& body = *bodies_[b];
    // The flat upload needs ceil(N/32) bins; the grouped layouts need the plan's.
    const long long flat = (body.particles + 31) / 32;
    const int bins = options_.bin_capacity > 0 ? static_cast<int>(std::max<long long>(flat, options_.bin_capacity))
                                               : static_cast<int>(plan_.bin_capacity[b]);
    body.partition.allocate(block_capacity_, bins, decomposed() && options_.overlap_halo);  // the lists' only use
    body.allocate_bins(bins);
    const std::int32_t* recorded = restart_blocks_of(static_cast<int>(b));
    std::vector<int> blocks;  // a restart's recorded blocks of the uploaded particles (3 per slot)
    if (positions && decomposed()) {
      std::vector<Vec3d> mine;
      std::vector<int> ids;
      const std::vector<Vec3d>& x = (*positions)[static_cast<std::size_t>(b)];
      for (std::size_t p = 0; p < x.size(); ++p)
        if (holds_at_restart(static_cast<int>(b), p, x[p])) {
          mine.push_back(x[p]);
          ids.push_back(static_cast<int>(p));
          if (recorded) blocks.insert(blocks.end(), recorded + 3 * p, recorded + 3 * p + 3);
        }
      body.upload(mine.data(), ids.data(), mine.size(), 0, stream_);
    } else if (positions) {
      body.upload((*positions)[b].data(), nullptr, (*positions)[b].size(), 0, stream_);
      if (recorded) blocks.assign(recorded, recorded + 3 * (*positions)[b].size());
    } else if (body.mesh) {  // the vertices, on the rank holding the mesh (a mesh is placed whole)
      const std::vector<Vec3d>& x = scene_.meshes.at(static_cast<std::size_t>(body.spec.mesh)).mesh->vertices;
      if (body.particles > 0) body.upload(x.data(), nullptr, x.size(), 0, stream_);
    } else {
      upload_sampled(body);
    }
    if (!blocks.empty()) {
      body.restart_blocks.allocate(blocks.size());
      FBAR_CUDA_CHECK(cudaMemcpyAsync(body.restart_blocks.get(), blocks.data(), sizeof(int) * blocks.size(),
                                      cudaMemcpyHostToDevice, stream_));
    }
    if (body.mesh && body.particles > 0) {  // the rank holding the vertices: the elements, and v and C recorded
      body.mesh->upload(stream_);
      body.aux.allocate(body.partition.slots() * kAuxScalars);
    }
  }
  if (positions && decomposed()) size_restart_migration(*positions);
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
  stats_h_ = cuda::pinned(stats_bytes);
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
    FBAR_CUDA_CHECK(cudaMemcpyAsync(wave_d_.get(), bits.data(), sizeof(unsigned long long) * bits.size(),
                                    cudaMemcpyHostToDevice, stream_));
  }

}

/// Layout 0 of every body from the flat upload (storage bins[0], slot = ID), and the halo lists of its blocks.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::partition_upload() {
  cur_ = 1;  // dest_from_positions and the partition write layout(1 - cur_) = layout(0)
  gc_ = 0;
  flat_source_ = true;
  reset_stats(false);
  for (auto& b : bodies_) {
    FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(0).count, 0, sizeof(int) * block_capacity_, stream_));
    // A restart whose checkpoint kept the blocks of its last P2G groups each particle there (partition_kernels.cuh).
    b->dest_from_positions(*this, 0, nullptr, 0, b->particles, b->restart_blocks.size() ? b->restart_blocks.get() : nullptr);
  }
  partition_after_g2p2g();
  read_stats();
  while (handle_overflow()) {
  }
  for (auto& b : bodies_) {
    cuda::DeviceArray<int> done;
    b->restart_blocks.swap(done);
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
}

/// The P2G of the initial state with dt_0 (a restart's next dt), its partition and the state a first step reads.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::initial_p2g() {
  // dt_0: the CPU engine's first next_dt(); a restart's next dt.
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
  // dt_next of the initial P2G is dt0: written by compute_next_dt with a fixed dt, first for the pass that measures
  // the P2G bound, then with the quanta of grid[0] from that bound.
  DtParams dp{};
  dp.body_count = 0;
  dp.wave_speed = wave_d_.get();
  dp.fixed_dt = dt0;
  dp.dx = scene_.simulation.dx;  // the momentum quantum's floor M dx / dt, as every step's (launch_next_dt)
  dp.t_next = time_;
  dp.t_target = std::numeric_limits<double>::infinity();
  dp.stats = stats_d_;
  dp.scale = 1.0;
  compute_next_dt<<<1, 1, 0, stream_>>>(dp);
  cuda::check_launch("compute_next_dt");
  grid_sums(0).clear(0, block_capacity_, stream_);
  if (asflip_) transported(0).clear(0, block_capacity_, stream_);
  for (auto& b : bodies_) {
    FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(1).count, 0, sizeof(int) * block_capacity_, stream_));
    b->source_slots = b->total_bins[0] * 32;
    b->pending_particles = b->particles;
  }
  ensure_emigrant_lists();
  // The bound the arena and the grid's quanta use, in slot bound_cur_: a restart's checkpoint holds the one its run
  // summed this grid with (so the restart sums the same bits), else a first pass measures it.
  const bool bounds_known = restart && std::all_of(restart->bodies.begin(), restart->bodies.end(),
                                                   [](const io::CheckpointBody& b) { return b.p2g_bound >= 0.0; });
  if (bounds_known) {
    std::vector<double> bounds;
    for (const io::CheckpointBody& b : restart->bodies) bounds.push_back(b.p2g_bound);
    FBAR_CUDA_CHECK(cudaMemcpyAsync(p2g_bound_d_.get() + bound_cur_ * bodies_.size(), bounds.data(),
                                    sizeof(double) * bounds.size(), cudaMemcpyHostToDevice, stream_));
  } else {
    measuring_bound_ = true;
    for (auto& b : bodies_) b->g2p2g(*this, true, T(0));
    measuring_bound_ = false;
  }
  launch_dt(dp);
  for (auto& b : bodies_) b->g2p2g(*this, true, T(0));
  if (decomposed()) {
    halo_exchange(step_halo_buffers(0), 0);
    migrate_particles();
  }
  partition_after_g2p2g();
  read_stats();
  while (handle_overflow()) {
  }
  if (decomposed()) {
    settle_migration();
    agree_on_try();
    if (dec_.migrant_most > dec_.migrant_capacity)  // the initial P2G moves nothing: no rank sends any
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
  dec_.migrated += dec_.pending_migrated;
  for (auto& b : bodies_)  // the element pass wrote the forces at the start positions
    if (b->mesh) b->mesh->force_cur = 1 - b->mesh->force_cur;
  block_count_ = stats_->block_count;
  record_p2g_blocks();  // layout(0) was read, bins[1] written
  if (decomposed() && dec_.halo_grew) rebuild_halo(0);
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
    retry_.scale = restart->dt_scale;
    dt_scale_at_compute_ = restart->dt_scale;
    next_dt_ = restart->next_dt;
    retry_.clean_steps = restart->clean_steps;
    for (auto& b : bodies_) {  // uploaded and scattered: the host copies are not needed again
      std::vector<Vec3<T>>().swap(b->initial_v_host);
      cuda::DeviceArray<T> done;
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
    if (n > 0 && b.mesh) {  // a mesh's lumped masses are the mesh's (the checkpoint holds the same)
      for (std::size_t p = 0; p < n; ++p)
        if (static_cast<T>(c.mass[p]) != b.mesh->mass[p])
          throw std::invalid_argument(where + ": vertex " + std::to_string(p) + " has mass " +
                                      std::to_string(c.mass[p]) + " kg in the checkpoint, " +
                                      std::to_string(static_cast<double>(b.mesh->mass[p])) + " kg from the mesh");
    } else if (n > 0) {
      b.mass = static_cast<T>(c.mass[0]);
      b.volume = static_cast<T>(c.volume[0]);
      for (std::size_t p = 0; p < n; ++p)
        if (static_cast<T>(c.mass[p]) != b.mass || static_cast<T>(c.volume[p]) != b.volume)
          throw std::invalid_argument(where + ": particle " + std::to_string(p) +
                                      " has its own mass or volume; the GPU engine keeps one per body (restart "
                                      "this checkpoint on the CPU engine, --backend=cpu)");
    }
    b.p2g_capture = c.p2g_capture;  // the instantiation the restart's P2G runs
    b.restart_state.resize(static_cast<std::size_t>(S) * n);
    for (std::size_t i = 0; i < b.restart_state.size(); ++i) b.restart_state[i] = static_cast<T>(c.state[i]);
    std::vector<T> C(9 * n);
    for (std::size_t i = 0; i < C.size(); ++i) C[i] = static_cast<T>(c.C[i]);
    b.initial_C.allocate(std::max<std::size_t>(C.size(), 1));
    if (!C.empty())
      FBAR_CUDA_CHECK(cudaMemcpy(b.initial_C.get(), C.data(), sizeof(T) * C.size(), cudaMemcpyHostToDevice));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(cudaStreamLegacy));  // as for initial_v: the DMA may still be running
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
      sampler.sample_planes(plane, end, sampled, &per_plane);
      for (const Vec3d& x : sampled) {
        if (owns(body.index, x)) {
          pending.push_back(x);
          pending_ids.push_back(static_cast<int>(next_id));
        }
        ++next_id;
      }
    } else {
      const std::size_t before = pending.size();
      sampler.sample_planes(plane, end, pending, &per_plane);
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
void MgspBenchmark<T, TG>::ensure_aux() {
  for (auto& b : bodies_) {
    const std::size_t need = b->partition.slots() * kAuxScalars;
    if (b->aux.size() < need) b->aux.allocate(need);
  }
}

}  // namespace fbar
