// Sensors, trackers and checkpoints: grid and particle sensor samples into device slots, tracked particles by ID,
// and the state a checkpoint holds (io/checkpoint.h). Part of MgspBenchmark.
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_grid_sensors(const std::vector<GridSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(GridSensorSet<TG>::kMax))
    throw std::invalid_argument("grid-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(GridSensorSet<TG>::kMax) + " per run");
  sensors_.grid = GridSensorSet<TG>{};
  for (const GridSensorSpec& spec : sensors)
    sensors_.grid.s[sensors_.grid.count++] = make_grid_sensor_params<TG>(spec, static_cast<double>(k_.dx));
  sensors_.grid_sample_slot = -1;
  sensors_.grid_reads_volume = false;
  for (int i = 0; i < sensors_.grid.count; ++i)
    sensors_.grid_reads_volume = sensors_.grid_reads_volume || grid_sensor_reads_volume(sensors_.grid.s[i].quantity);
  if (sensors_.grid_reads_volume) ensure_node_volume();
  if (sensors_.grid.count > 0) ensure_sensor_partials();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_node_volume() {
  channels_.add(GridFeatures{false, false, false, true}, block_capacity_);  // the F-bar sums, on the sample steps
  double most = 0.0;
  for (const auto& b : bodies_) most = std::max(most, static_cast<double>(b->volume));
  if (decomposed()) most = dec_.host->max(most);  // every rank sums in the same quantum
  sensors_.volume_quantum = fixed_quantum<TG>(most);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_grid_fields(const std::vector<GridFieldSpec>& fields) {
  if (fields.size() > static_cast<std::size_t>(GridFieldSet<TG>::kMax))
    throw std::invalid_argument("grid-fields: " + std::to_string(fields.size()) + " enabled fields; at most " +
                                std::to_string(GridFieldSet<TG>::kMax) + " per run");
  sensors_.fields = GridFieldSet<TG>{};
  for (auto& a : sensors_.field_nodes) a.allocate(0);
  bool volume = false;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const GridFieldParams<TG> f = make_grid_field_params<TG>(fields[i], static_cast<double>(k_.dx));
    sensors_.fields.f[sensors_.fields.count++] = f;
    volume = volume || f.volume;
    double nodes = 1.0;  // the box's nodes: every record it can hold
    for (int a = 0; a < 3; ++a)
      nodes *= std::max(0.0, std::floor((static_cast<double>(f.hi[a]) - static_cast<double>(f.lo[a])) / k_.dx) + 1.0);
    sensors_.field_nodes[i].allocate(std::max<std::size_t>(1, static_cast<std::size_t>(nodes)));
  }
  sensors_.field_count_d.allocate(std::max<std::size_t>(1, fields.size()));
  if (volume) ensure_node_volume();
}

template <typename T, typename TG>
GridFieldSample MgspBenchmark<T, TG>::grid_field_sample(int field) {
  if (field < 0 || field >= sensors_.fields.count)
    throw std::logic_error("GpuEngine::grid_field_sample: no grid field " + std::to_string(field));
  int count = 0;
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&count, sensors_.field_count_d.get() + field, sizeof(int), cudaMemcpyDeviceToHost,
                                  stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  const cuda::DeviceArray<GridFieldNode>& nodes = sensors_.field_nodes[static_cast<std::size_t>(field)];
  if (count > static_cast<int>(nodes.size()))
    throw std::logic_error("GpuEngine: grid field " + std::to_string(field) + " recorded " + std::to_string(count) +
                           " nodes in a box of " + std::to_string(nodes.size()));
  GridFieldSample s;
  s.dt = sensors_.field_dt;
  s.nodes.resize(static_cast<std::size_t>(count));
  if (count > 0)
    FBAR_CUDA_CHECK(cudaMemcpy(s.nodes.data(), nodes.get(), sizeof(GridFieldNode) * count, cudaMemcpyDeviceToHost));
  return s;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_grid_sample(int slot) {
  sensors_.grid_sample_slot = slot;
  if (slot < 0 || sensors_.grid.count == 0) return;
  grow_samples(sensors_.grid_samples_d, static_cast<std::size_t>(slot + 1) * sensors_.grid.count);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::grow_samples(cuda::DeviceArray<SensorAccum>& samples, std::size_t need) {
  if (samples.size() >= need) return;
  // Grow (rare: the slots of one frame interval), keeping the slots already sampled.
  cuda::DeviceArray<SensorAccum> bigger;
  bigger.allocate(std::max(need, 2 * samples.size()));
  if (samples.size())
    FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.get(), samples.get(), samples.bytes(), cudaMemcpyDeviceToDevice, stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  samples.swap(bigger);
}

template <typename T, typename TG>
std::vector<SensorAccum> MgspBenchmark<T, TG>::grid_samples(int slots) const {
  return download_samples(sensors_.grid_samples_d, static_cast<std::size_t>(slots) * sensors_.grid.count);
}

template <typename T, typename TG>
std::vector<SensorAccum> MgspBenchmark<T, TG>::download_samples(const cuda::DeviceArray<SensorAccum>& samples,
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
  sensors_.particle = ParticleSensorSet<T>{};
  sensors_.particle_read_v = false;
  for (const ParticleSensorSpec& spec : sensors) {
    const ParticleSensorParams<T> p = make_particle_sensor_params<T>(spec);
    sensors_.particle_read_v = sensors_.particle_read_v || particle_sensor_reads_velocity(p.column);
    sensors_.particle.s[sensors_.particle.count++] = p;
  }
  if (sensors_.particle.count > 0) ensure_sensor_partials();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_sensor_partials() {
  // One sample's per-CUDA-block partials, shared by the grid and the particle sensors (at most kMax of each).
  static_assert(GridSensorSet<TG>::kMax == ParticleSensorSet<T>::kMax, "one partials buffer for both kinds");
  if (sensors_.partials_d.size() == 0)
    sensors_.partials_d.allocate(static_cast<std::size_t>(GridSensorSet<TG>::kMax) * kSensorBlocks);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::keep_particle_inputs(bool on) {
  // Only a sensor reading v or C pays for recording them, and only on the steps that may land on a sample time.
  sensor_keep_ = on && (sensors_.particle_read_v || sensors_.trackers_read_v);
  update_record();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::keep_checkpoint_inputs(bool on) {
  checkpoint_keep_ = on;
  update_record();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::sample_particles(int slot) {
  const int n = sensors_.particle.count;
  if (n == 0) return;
  const std::size_t per_slot = bodies_.size() * static_cast<std::size_t>(n);
  grow_samples(sensors_.particle_samples_d, static_cast<std::size_t>(slot + 1) * per_slot);
  const bool initial = steps_ == 0 && !aux_valid_;
  if (sensors_.particle_read_v && !initial && !aux_valid_)
    throw std::logic_error("GpuEngine::sample_particles: the step that ended here did not record v and C "
                           "(keep_particle_inputs was not set for it)");
  for (auto& b : bodies_) {
    const int slots = b->total_bins[cur_] * 32;
    const int per_sensor = static_cast<int>(std::clamp<long long>((slots + kSensorThreads - 1) / kSensorThreads, 1,
                                                                  kSensorBlocks));
    SensorAccum* out = sensors_.particle_samples_d.get() + static_cast<std::size_t>(slot) * per_slot +
                       static_cast<std::size_t>(b->index) * n;
    b->sample_sensors(*this, aux_valid_ && sensors_.particle_read_v ? b->aux.get() : nullptr, sensors_.partials_d.get(),
                      per_sensor);
    merge_sensor_partials<<<1, ParticleSensorSet<T>::kMax, 0, stream_>>>(sensors_.partials_d.get(), per_sensor, n, out);
    cuda::check_launch("merge_sensor_partials");
  }
}

template <typename T, typename TG>
std::vector<SensorAccum> MgspBenchmark<T, TG>::particle_samples(int slots) const {
  return download_samples(sensors_.particle_samples_d,
                          static_cast<std::size_t>(slots) * bodies_.size() * sensors_.particle.count);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::set_tracker(int body, const TrackerSet& set) {
  body_at(body);
  sensors_.trackers.resize(bodies_.size());
  sensors_.trackers[body] = set;
  for (int a = 0; a < set.attribs; ++a) sensors_.trackers_read_v = sensors_.trackers_read_v || particle_sensor_reads_velocity(set.column[a]);
  if (sensors_.track_d.size() == 0) sensors_.track_d.allocate(static_cast<std::size_t>(TrackerSet::kMaxIds) * (TrackerSet::kMaxAttribs + 1));
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::track(int body, std::vector<double>& values, std::vector<double>& present) {
  BodyBase& b = body_at(body);
  const TrackerSet empty{};
  const TrackerSet& t = static_cast<std::size_t>(body) < sensors_.trackers.size() ? sensors_.trackers[body] : empty;
  values.assign(static_cast<std::size_t>(t.ids) * t.attribs, 0.0);
  present.assign(t.ids, 0.0);
  if (t.ids == 0) return;
  const bool initial = steps_ == 0 && !aux_valid_;
  if (sensors_.trackers_read_v && !initial && !aux_valid_)
    throw std::logic_error("GpuEngine::track: the step that ended here did not record v and C");
  double* v_d = sensors_.track_d.get();
  double* present_d = v_d + static_cast<std::size_t>(TrackerSet::kMaxIds) * TrackerSet::kMaxAttribs;
  FBAR_CUDA_CHECK(cudaMemsetAsync(v_d, 0, sensors_.track_d.bytes(), stream_));
  b.track(*this, aux_valid_ ? b.aux.get() : nullptr, t, v_d, present_d);
  FBAR_CUDA_CHECK(cudaMemcpyAsync(values.data(), v_d, sizeof(double) * values.size(), cudaMemcpyDeviceToHost, stream_));
  FBAR_CUDA_CHECK(cudaMemcpyAsync(present.data(), present_d, sizeof(double) * present.size(), cudaMemcpyDeviceToHost,
                                  stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
}

/// Device and pinned host buffers of one range of IDs of a streamed checkpoint.
template <typename T, typename TG>
struct MgspBenchmark<T, TG>::CheckpointRange {
  int ids = 0, width = 0;
  cuda::DeviceArray<T> values_d;    ///< (ids, width): gather_by_id's rows
  cuda::DeviceArray<int> held_d;    ///< (ids): the ID where this rank holds it, else -1
  cuda::DeviceArray<int> counts_d;  ///< missing IDs, record errors
  cuda::PinnedBytes host;           ///< values (ids x width x T), then held (ids x int)
  const T* values() const { return static_cast<const T*>(host.get()); }
  const int* held() const {
    return reinterpret_cast<const int*>(static_cast<const std::byte*>(host.get()) +
                                        sizeof(T) * static_cast<std::size_t>(ids) * width);
  }
  CheckpointRange(int ids_, int width_) : ids(ids_), width(width_) {
    values_d.allocate(static_cast<std::size_t>(ids) * width);
    held_d.allocate(static_cast<std::size_t>(ids));
    counts_d.allocate(2);
    host = cuda::pinned((sizeof(T) * width + sizeof(int)) * static_cast<std::size_t>(ids));
  }
};

/// IDs per range of a streamed checkpoint (memory_plan.h checkpoint_range_ids: at most 2^20, 2^20 x 24 doubles
/// being 192 MiB of pinned memory and as much on the device).
static_assert(kAuxScalars == 12, "memory_plan.h's checkpoint sizes count v and C as 12 scalars");
template <typename T, typename TG>
int MgspBenchmark<T, TG>::checkpoint_range_ids(const BodyBase& b) const {
  return static_cast<int>(::fbar::checkpoint_range_ids(static_cast<std::size_t>(b.global_particles),
                                                       b.stored_scalars(), sizeof(T), options_.frame_host_bytes));
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::gather_range(const BodyBase& b, CheckpointRange& r, int first, int count) const {
  const cudaStream_t s = copy_stream_;
  FBAR_CUDA_CHECK(cudaMemsetAsync(r.held_d.get(), 0xff, sizeof(int) * static_cast<std::size_t>(count), s));
  FBAR_CUDA_CHECK(cudaMemsetAsync(r.counts_d.get(), 0, sizeof(int), s));
  auto* self = const_cast<MgspBenchmark*>(this);
  const_cast<BodyBase&>(b).gather(*self, r.values_d.get(), r.held_d.get(), r.counts_d.get(), s, first, count);
  const std::size_t values = sizeof(T) * static_cast<std::size_t>(count) * r.width;
  auto* host = static_cast<std::byte*>(r.host.get());
  FBAR_CUDA_CHECK(cudaMemcpyAsync(host, r.values_d.get(), values, cudaMemcpyDeviceToHost, s));
  FBAR_CUDA_CHECK(cudaMemcpyAsync(host + sizeof(T) * static_cast<std::size_t>(r.ids) * r.width, r.held_d.get(),
                                  sizeof(int) * static_cast<std::size_t>(count), cudaMemcpyDeviceToHost, s));
  int missing = 0;
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&missing, r.counts_d.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
  if (missing) throw std::runtime_error("GpuEngine: " + std::to_string(missing) + " particles with an invalid ID");
}

template <typename T, typename TG>
io::CheckpointBody MgspBenchmark<T, TG>::streamed_checkpoint_body(const BodyBase& b, double p2g_bound, bool initial,
                                                                  std::shared_ptr<const std::vector<int>> coords,
                                                                  io::CheckpointPieces& pieces) const {
  using io::CheckpointDataset;
  const int S = b.stored_scalars();
  io::CheckpointBody out;
  out.law = to_string(b.spec.material.law);
  out.state_scalars = S - 3;
  out.global_particles = b.global_particles;
  out.max_wave_speed = b.rest_wave_speed;
  out.p2g_bound = p2g_bound;
  out.p2g_capture = b.p2g_capture;
  out.p2g_known = p2g_valid_;
  const int ids = checkpoint_range_ids(b);
  const int total = static_cast<int>(b.global_particles);
  const int blocks = coords ? static_cast<int>(coords->size() / 3) : 0;
  // The P2G record of range [first, first + count) into r's held buffer as each ID's table block (-1: not summed
  // here); returns the rows, throws on a record that names a particle or block twice or out of range.
  const BodyBase* const body = &b;
  auto p2g_range = [this, body, blocks, total](CheckpointRange& r, int first, int count) -> std::size_t {
    const BodyBase& b = *body;
    const cudaStream_t s = copy_stream_;
    FBAR_CUDA_CHECK(cudaMemsetAsync(r.held_d.get(), 0xff, sizeof(int) * static_cast<std::size_t>(count), s));
    FBAR_CUDA_CHECK(cudaMemsetAsync(r.counts_d.get(), 0, sizeof(int), s));
    if (b.p2g_slots > 0) {
      p2g_blocks_by_id<<<cuda::grid_for(b.p2g_slots, kOutputThreads), kOutputThreads, 0, s>>>(
          b.p2g_record.get(), b.p2g_slots, total, blocks, first, count, r.held_d.get(), r.counts_d.get());
      cuda::check_launch("p2g_blocks_by_id");
    }
    int* held = const_cast<int*>(r.held());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(held, r.held_d.get(), sizeof(int) * static_cast<std::size_t>(count),
                                    cudaMemcpyDeviceToHost, s));
    int errors = 0;
    FBAR_CUDA_CHECK(cudaMemcpyAsync(&errors, r.counts_d.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
    if (errors)
      throw std::runtime_error("GpuEngine::checkpoint: internal error: body " + std::to_string(b.index) + ": " +
                               std::to_string(errors) + " slots of the P2G record name a particle twice or out of range");
    std::size_t rows = 0;
    for (int k = 0; k < count; ++k) rows += held[k] >= 0;
    return rows;
  };
  // The pre-pass: the rows this rank holds, the largest wave speed (written before the datasets) and the P2G rows,
  // from the same ranges the datasets are read in.
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  // One range's buffers for the pre-pass and every dataset (allocated here: the writer thread allocates nothing).
  const auto range = std::make_shared<CheckpointRange>(ids, S + kAuxScalars);
  {
    CheckpointRange& r = *range;
    std::size_t held = 0;
    for (int first = 0; first < total; first += ids) {
      const int count = std::min(ids, total - first);
      gather_range(b, r, first, count);
      for (int k = 0; k < count; ++k) {
        if (r.held()[k] < 0) continue;
        ++held;
        out.max_wave_speed =
            std::max(out.max_wave_speed, b.wave_speed_of(r.values() + static_cast<std::size_t>(k) * r.width));
      }
      if (p2g_valid_) pieces.p2g_rows += p2g_range(r, first, count);
    }
    if (held != static_cast<std::size_t>(b.particles))
      throw std::runtime_error("GpuEngine::checkpoint: " + std::to_string(held) + " particles found by ID, " +
                               std::to_string(b.particles) + " held");
    pieces.particles = held;
  }
  const Vec3d v0{{b.spec.velocity[0], b.spec.velocity[1], b.spec.velocity[2]}};
  int device = 0;
  FBAR_CUDA_CHECK(cudaGetDevice(&device));
  // The datasets in write_checkpoint's order, read on its thread (the run writes the file before the next step),
  // each a range of IDs at a time, as the whole copy's arrays hold them (the same values, the same bytes).
  pieces.pieces = [this, body, device, ids, total, S, initial, v0, coords, p2g_range, range](
                      CheckpointDataset d, const std::function<void(std::size_t, const void*)>& emit) {
    const BodyBase& b = *body;
    FBAR_CUDA_CHECK(cudaSetDevice(device));
    CheckpointRange& r = *range;
    const bool p2g = d == CheckpointDataset::P2GId || d == CheckpointDataset::P2GBlock;
    std::vector<double> values;
    std::vector<std::int64_t> id_rows;
    std::vector<std::int32_t> block_rows;
    for (int first = 0; first < total; first += ids) {
      const int count = std::min(ids, total - first);
      values.clear();
      id_rows.clear();
      block_rows.clear();
      if (p2g) {
        p2g_range(r, first, count);
        for (int k = 0; k < count; ++k) {
          const int block = r.held()[k];
          if (block < 0) continue;
          if (d == CheckpointDataset::P2GId) id_rows.push_back(first + k);
          else block_rows.insert(block_rows.end(), coords->begin() + 3 * block, coords->begin() + 3 * block + 3);
        }
        if (d == CheckpointDataset::P2GId) emit(id_rows.size(), id_rows.data());
        else emit(block_rows.size() / 3, block_rows.data());
        continue;
      }
      gather_range(b, r, first, count);
      std::size_t rows = 0;
      for (int k = 0; k < count; ++k) {
        if (r.held()[k] < 0) continue;
        ++rows;
        const long long p = first + k;
        const T* q = r.values() + static_cast<std::size_t>(k) * r.width;
        switch (d) {
          case CheckpointDataset::Id: id_rows.push_back(p); break;
          case CheckpointDataset::Position:
            for (int a = 0; a < 3; ++a) values.push_back(static_cast<double>(q[a]));
            break;
          case CheckpointDataset::Velocity:
            for (int a = 0; a < 3; ++a)
              values.push_back(!initial                    ? static_cast<double>(q[S + a])
                               : b.initial_v_host.empty() ? v0[a]
                                                           : static_cast<double>(b.initial_v_host[static_cast<std::size_t>(p)][a]));
            break;
          case CheckpointDataset::C:
            for (int i = 0; i < 9; ++i) values.push_back(initial ? 0.0 : static_cast<double>(q[S + 3 + i]));
            break;
          case CheckpointDataset::Mass: values.push_back(static_cast<double>(b.mass)); break;
          case CheckpointDataset::Volume: values.push_back(static_cast<double>(b.volume)); break;
          case CheckpointDataset::State:
            for (int i = 3; i < S; ++i) values.push_back(static_cast<double>(q[i]));
            break;
          default: break;
        }
      }
      if (d == CheckpointDataset::Id) emit(rows, id_rows.data());
      else emit(rows, values.data());
    }
  };
  return out;
}

template <typename T, typename TG>
io::Checkpoint MgspBenchmark<T, TG>::checkpoint(bool stream) const {
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
  c.dt_scale = retry_.scale;
  c.clean_steps = retry_.clean_steps;
  if (decomposed()) {
    c.slab_axis = dec_.slabs.axis;
    c.slab_cuts = dec_.slabs.cuts;
  }
  const bool initial = steps_ == 0 && !aux_valid_;  // before the first step: v = initial velocity, C = 0 exactly
  // The P2G bounds the current grid was summed with (the slot the last G2P2G read): a restart sums the same grid.
  std::vector<double> bounds(bodies_.size());
  FBAR_CUDA_CHECK(cudaMemcpy(bounds.data(), p2g_bound_d_.get() + (1 - bound_cur_) * bodies_.size(),
                             sizeof(double) * bounds.size(), cudaMemcpyDeviceToHost));
  // The table's block coordinates, for the blocks the current grid was summed from (p2g_record's indices).
  auto coords_kept = std::make_shared<std::vector<int>>();
  std::vector<int>& coords = *coords_kept;
  if (p2g_valid_) {
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // the commit's record_p2g_blocks
    const int blocks = std::min(block_capacity_, std::max(block_count_, stats_->block_count));
    coords.resize(3 * static_cast<std::size_t>(blocks));
    if (blocks)
      FBAR_CUDA_CHECK(cudaMemcpy(coords.data(), table_.view().coords, sizeof(int) * coords.size(),
                                 cudaMemcpyDeviceToHost));
  }
  std::vector<io::CheckpointPieces> pieces(bodies_.size());
  bool any_streamed = false;
  for (const auto& bp : bodies_) {
    const BodyBase& b = *bp;
    if (stream && checkpoint_streamed(static_cast<std::size_t>(b.global_particles), b.stored_scalars(), sizeof(T),
                                      options_.frame_host_bytes, b.mesh != nullptr)) {
      c.bodies.push_back(streamed_checkpoint_body(b, bounds[static_cast<std::size_t>(b.index)], initial,
                                                  p2g_valid_ ? coords_kept : nullptr,
                                                  pieces[static_cast<std::size_t>(b.index)]));
      any_streamed = true;
      continue;
    }
    const std::vector<T> r = gather_host(b.index, stream_);
    const int S = b.stored_scalars();
    const int W = S + kAuxScalars;
    io::CheckpointBody out;
    out.law = to_string(b.spec.material.law);
    out.state_scalars = S - 3;
    out.global_particles = b.global_particles;
    out.max_wave_speed = b.rest_wave_speed;
    out.p2g_bound = bounds[static_cast<std::size_t>(b.index)];
    out.p2g_capture = b.p2g_capture;
    const Vec3d v0{{b.spec.velocity[0], b.spec.velocity[1], b.spec.velocity[2]}};
    const std::size_t n = static_cast<std::size_t>(b.particles);  // this rank's
    out.id.resize(n);
    out.x.resize(3 * n);
    out.v.resize(3 * n);
    out.C.resize(9 * n);
    out.mass.assign(n, static_cast<double>(b.mass));
    out.volume.assign(n, static_cast<double>(b.volume));
    if (b.mesh && n > 0)  // the vertices' lumped masses (a mesh is whole on its rank: entry p is vertex p)
      for (std::size_t p = 0; p < n; ++p) {
        out.mass[p] = static_cast<double>(b.mesh->mass[p]);
        out.volume[p] = static_cast<double>(b.mesh->volume[p]);
      }
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
    if (p2g_valid_) {  // the particles this rank summed into the current grid, in ID order, with their blocks
      std::vector<int> record(2 * static_cast<std::size_t>(b.p2g_slots));
      if (!record.empty())
        FBAR_CUDA_CHECK(cudaMemcpy(record.data(), b.p2g_record.get(), sizeof(int) * record.size(),
                                   cudaMemcpyDeviceToHost));
      std::vector<int> block_of(static_cast<std::size_t>(b.global_particles), -1);
      for (std::size_t slot = 0; slot < record.size() / 2; ++slot) {
        const int id = record[2 * slot], block = record[2 * slot + 1];
        if (id < 0) continue;
        if (id >= b.global_particles || block < 0 || 3 * static_cast<std::size_t>(block) >= coords.size() ||
            block_of[static_cast<std::size_t>(id)] >= 0)
          throw std::runtime_error("GpuEngine::checkpoint: internal error: body " + std::to_string(b.index) +
                                   " slot " + std::to_string(slot) + " records particle " + std::to_string(id) +
                                   " in block " + std::to_string(block));
        block_of[static_cast<std::size_t>(id)] = block;
      }
      out.p2g_known = true;
      for (long long p = 0; p < b.global_particles; ++p) {
        const int block = block_of[static_cast<std::size_t>(p)];
        if (block < 0) continue;
        out.p2g_id.push_back(p);
        out.p2g_block.insert(out.p2g_block.end(), coords.begin() + 3 * block, coords.begin() + 3 * block + 3);
      }
    }
    c.bodies.push_back(std::move(out));
  }
  if (any_streamed) c.streamed = std::move(pieces);
  return c;
}

}  // namespace fbar
