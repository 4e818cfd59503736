// The step (mgsp_benchmark.cuh, steps 0-5): statistics, partition, growth of what overflowed, failures, the
// commit of a step and the landing on a target time. Part of MgspBenchmark.
#pragma once

#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

namespace mgsp_detail {

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

template <typename T, typename TG>
void MgspBenchmark<T, TG>::reset_stats(bool partition_only) {
  mgsp_detail::reset_step_stats<<<1, 64, 0, stream_>>>(stats_d_, body_stats_d_, body_count(), partition_only);
  cuda::check_launch("reset_step_stats");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::partition_after_g2p2g(bool dest_complete) {
  const int next = 1 - cur_;
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const LayoutView nl = b.partition.layout(next);
    activate_footprint<TG><<<cuda::grid_for(block_capacity_, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        nl.count, block_capacity_, table_.view(), grid_sums(0).view(), grid_sums(1).view());
    cuda::check_launch("activate_footprint");
  }
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const LayoutView nl = b.partition.layout(next);
    blocks_to_bins<<<cuda::grid_for(block_capacity_ + 1, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        nl.count, b.partition.bins_per_block(), block_capacity_);
    cuda::check_launch("blocks_to_bins");
    std::size_t temp = scan_temp_bytes_;
    FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(scan_temp_.get(), temp, b.partition.bins_per_block(), nl.bin_offset,
                                                  block_capacity_ + 1, stream_));
    finalize_layout<<<1, 1, 0, stream_>>>(nl.bin_offset, block_capacity_, b.partition.bin_capacity(),
                                          body_stats_d_ + b.index, stats_d_, table_.counters());
    cuda::check_launch("finalize_layout");
    // The previous layout's slots: those of layout(cur) (a G2P2G wrote bins[next] in that order, and a dest for
    // every slot of its bins), or the flat upload before the first layout exists. Decomposed (the received
    // particles' slots follow the layout's) or after dest was rewritten from positions for the valid slots alone
    // (handle_overflow: a bin growth reallocates dest), layout(cur).src says which slots hold particles.
    const bool flat = flat_source_;
    const int* valid = !flat && (decomposed() || !dest_complete) ? b.partition.layout(cur_).src : nullptr;
    const int slots = flat ? b.particles : b.source_slots;
    if (slots > 0) {
      scatter_src<<<cuda::grid_for(slots, kPartitionThreads * kScatterSlotsPerThread), kPartitionThreads, 0,
                    stream_>>>(b.partition.dest(), valid, flat ? b.particles : -1, slots, nl.bin_offset, nl.src,
                               b.partition.bin_capacity(), body_stats_d_ + b.index);
      cuda::check_launch("scatter_src");
    }
    pad_src<<<cuda::grid_for(block_capacity_, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        nl.count, nl.bin_offset, block_capacity_, nl.src, b.partition.bin_capacity());
    cuda::check_launch("pad_src");
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
  const int first_lo = dec_.halo[0].peer >= 0 ? dec_.halo[0].plane : INT_MIN;
  const int first_hi = dec_.halo[1].peer >= 0 ? dec_.halo[1].plane - 1 : INT_MIN;
  FBAR_CUDA_CHECK(cudaMemsetAsync(counters, 0, 2 * sizeof(int), stream_));
  const int capacity = b.partition.block_capacity();
  list_particle_blocks<<<cuda::grid_for(capacity, kHaloThreads), kHaloThreads, 0, stream_>>>(
      b.partition.layout(l).count, capacity, table_.view(), dec_.slab.axis, first_lo, first_hi, b.partition.layout(l).order,
      counters);
  cuda::check_launch("list_particle_blocks");
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
  channels_.grow(capacity, keep, stream_);  // each set as its lifetime says (engine/grid_channels.h)
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
  if (dec_.placed) mark_not_counted();  // per table block: the flags at the new capacity
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
  cuda::DeviceArray<ParticleDest> dest;
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
    cuda::DeviceArray<T> bigger;
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
      b->dest_from_positions(*this, 0, nullptr, 0, b->particles, b->restart_blocks.size() ? b->restart_blocks.get() : nullptr);
    else
      b->dest_from_positions(*this, next, b->partition.layout(cur_).src, 0, b->source_slots);
  }
  partition_after_g2p2g(false);
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
      f.elements = b->is_mesh() && f.kind == FailureKind::Inverted;  // the element pass counts elements
      out.push_back(f);
    }
  }
  return out;
}

/// The start of a try: statistics reset, the bodies' sources and migration lists, and step 0: the grid holds the
/// impulse of this dt (rescaled from dt_p2g_ when it differs).
template <typename T, typename TG>
void MgspBenchmark<T, TG>::begin_try(double dt) {
  reset_stats(false);
  for (auto& b : bodies_) {
    b->source_slots = b->total_bins[cur_] * 32;
    b->pending_particles = b->particles;
  }
  ensure_emigrant_lists();
  dec_.pending_migrated = 0;
  // 0. the grid must hold the impulse of this dt
  if (dt != dt_p2g_) {
    for (auto& b : bodies_) b->rescale_impulse(*this, static_cast<T>(dt - dt_p2g_));
    if (decomposed()) halo_exchange({grid_halo(gc_)}, gc_, true);
    dt_p2g_ = dt;
  }
  event_record(0);
}

/// Step 1: grid velocities from grid[gc] with gravity and the boundaries active at time_, the largest speed, and
/// on a sample step the grid sensors into their slot (each try overwrites it).
template <typename T, typename TG>
void MgspBenchmark<T, TG>::update_grid(double dt) {
  if (pore_ && block_count_ > 0) {  // the seepage sums of state n, every try (the update replaces them in place)
    pore_sums().clear(0, block_count_, stream_);
    // Every saturated body's bounds first (on every rank), then the sums in the quanta they set.
    FBAR_CUDA_CHECK(cudaMemsetAsync(pore_bound_d_.get(), 0, pore_bound_d_.bytes(), stream_));
    for (auto& b : bodies_) b->seepage_sums(*this, true);
    if (decomposed())  // bits of non-negative doubles: reduced as doubles
      dec_.device->allreduce_max(reinterpret_cast<double*>(pore_bound_d_.get()), kSeepageChannels, stream_);
    for (auto& b : bodies_) b->seepage_sums(*this, false);
    if (decomposed())
      halo_exchange({halo_of<GridSet::PoreSums>()}, -1);
  }
  GridUpdateParams<TG> gp{};
  if (pore_) {
    gp.pore = pore_values().instance();
    gp.pore_sums = pore_sums().view();
    gp.pore_bound = pore_bound_d_.get();
  }
  gp.grid = grid_sums(gc_).view();
  gp.quantum = quantum(gc_);
  gp.velocity = grid_velocity().instance();
  if (asflip_) {
    gp.transported = transported(gc_).view();
    gp.old_velocity = asflip_velocity().instance();
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
    update_grid_velocity_query_max<TG><<<cuda::grid_for(block_count_, kGridUpdateThreads / 64),
                                        kGridUpdateThreads, 0, stream_>>>(gp);
    cuda::check_launch("update_grid_velocity_query_max");
  }
  const bool sensors = sensors_.grid_sample_slot >= 0 && sensors_.grid.count > 0;  // a sample step
  if (!sensors && sensors_.fields.mask == 0) return;
  GridSensorSampleParams<TG> sp{};
  if ((sensors && sensors_.grid_reads_volume) || sensors_.fields.reads_volume()) {
    // every body's volume on the nodes, from the state the P2G sums hold
    if (block_count_ > 0) fbar_sums().clear(0, block_count_, stream_);
    for (auto& b : bodies_) b->node_volume_sums(*this, sensors_.volume_quantum);
    if (decomposed()) halo_exchange({halo_of<GridSet::FbarSums>()}, -1);
    sp.volume = fbar_sums().view();
    sp.volume_quantum = sensors_.volume_quantum;
  }
  sp.grid = gp.grid;
  sp.quantum = gp.quantum;
  sp.velocity = gp.velocity;
  sp.pore = gp.pore;
  sp.coords = gp.coords;
  sp.block_count = block_count_;
  sp.dt = gp.dt;
  sp.dx = gp.dx;
  sp.gravity = gp.gravity;
  sp.slab = dec_.slab;
  sp.not_counted = dec_.placed ? dec_.not_counted.get() : nullptr;
  const long long nodes = static_cast<long long>(block_count_) * 64;
  const int per_sensor = static_cast<int>(
      std::clamp<long long>((nodes + kSensorThreads - 1) / kSensorThreads, 1, kSensorBlocks));
  if (sensors) {  // each try overwrites the slot
    SensorAccum* out = sensors_.grid_samples_d.get() + static_cast<std::size_t>(sensors_.grid_sample_slot) * sensors_.grid.count;
    sp.sensors = sensors_.grid;
    sp.partials = sensors_.partials_d.get();
    sample_grid_sensors<TG><<<dim3(per_sensor, sensors_.grid.count), kSensorThreads, 0, stream_>>>(sp);
    cuda::check_launch("sample_grid_sensors");
    merge_sensor_partials<<<1, GridSensorSet<TG>::kMax, 0, stream_>>>(sp.partials, per_sensor, sensors_.grid.count,
                                                                      out);
    cuda::check_launch("merge_sensor_partials");
  }
  if (sensors_.fields.mask != 0) {  // each try records again
    FBAR_CUDA_CHECK(cudaMemsetAsync(sensors_.field_count_d.get(), 0, sensors_.field_count_d.bytes(), stream_));
    sensors_.field_dt = dt;
    for (int f = 0; f < sensors_.fields.count; ++f) {
      if (!(sensors_.fields.mask >> f & 1u)) continue;
      cuda::DeviceArray<GridFieldNode>& out = sensors_.field_nodes[static_cast<std::size_t>(f)];
      collect_grid_field<TG><<<per_sensor, kSensorThreads, 0, stream_>>>(
          sp, sensors_.fields.f[f], out.get(), static_cast<int>(out.size()), sensors_.field_count_d.get() + f);
      cuda::check_launch("collect_grid_field");
    }
  }
}

/// Step 2: dt of the next step on the device (its P2G impulse), from the wave speeds this state measured and the
/// grid speed (decomposed: reduced over the ranks first); clamped to land on `target`, then on `following`.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::launch_next_dt(double dt, bool cfl_dt, double target, double following) {
  DtParams dp{};
  dp.body_count = body_count();
  for (const auto& b : bodies_) dp.bodies[b->index] = DtBody{b->spec.material.cfl, b->rest_wave_speed};
  dp.wave_speed = wave_d_.get() + wave_cur_ * bodies_.size();
  dp.default_dt = k_.default_dt;
  dp.dx = scene_.simulation.dx;
  dp.scale = retry_.scale;
  dp.fixed_dt = cfl_dt ? 0.0 : dt;
  // A step that reaches the target ends exactly on it (step_toward sets the clock so): time_ + dt may miss it
  // by an ulp, which would leave the next step a sliver of 1e-19 s.
  const bool reaches = dt >= target - time_;
  dp.t_next = reaches ? target : time_ + dt;
  // Landing on the target, the next step heads for `following`: its dt is clamped for that one.
  dp.t_target = reaches && !std::isnan(following) ? following : target;
  dp.stats = stats_d_;
  launch_dt(dp);
}

/// compute_next_dt with the quanta of the grid the next P2G sums into (grid[1 - gc]) from the P2G bounds this try's
/// G2P2G reads; decomposed, its inputs reduced over the ranks first (the maxima are stored as the bits of
/// non-negative doubles: reduced as doubles, the grid speed, every body's wave speed and P2G bound in one message,
/// one NCCL call a step), so every rank takes the same dt, bounds and quanta.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::launch_dt(DtParams& dp) {
  const int n = body_count();
  dp.quantum = quantum(1 - gc_);
  dp.p2g_bound = p2g_bound_d_.get() + bound_cur_ * bodies_.size();
  dp.bound_count = n;
  dp.mass_bound = mass_bound_;
  dp.headroom = kP2GHeadroom;
  dp.fraction_bits = FixedSumFormat<TG>::kFractionBits;
  if (decomposed()) {
    if (dec_.dt_inputs_d.size() < static_cast<std::size_t>(2 * n + 1)) dec_.dt_inputs_d.allocate(2 * n + 1);
    gather_dt_inputs<<<1, DtParams::kMaxBodies, 0, stream_>>>(stats_d_, wave_d_.get() + wave_cur_ * bodies_.size(),
                                                               dp.p2g_bound, n, dec_.dt_inputs_d.get());
    cuda::check_launch("gather_dt_inputs");
    dec_.device->allreduce_max(reinterpret_cast<double*>(dec_.dt_inputs_d.get()), 2 * n + 1, stream_);
    dp.reduced = dec_.dt_inputs_d.get();
  }
  compute_next_dt<<<1, 1, 0, stream_>>>(dp);
  cuda::check_launch("compute_next_dt");
}

/// Step 3: G2P2G of every body into grid[1 - gc] and bins[1 - cur]; decomposed, the halo sums and the migration
/// (in one exchange, or overlapping the interior G2P2G: options_.overlap_halo).
template <typename T, typename TG>
void MgspBenchmark<T, TG>::g2p2g_step(double dt) {
  grid_sums(1 - gc_).clear(0, block_count_, stream_);
  // New blocks appear during G2P2G (its leader threads zero them in grid_); the transported sums are cleared whole.
  if (asflip_) transported(1 - gc_).clear(0, block_capacity_, stream_);
  FBAR_CUDA_CHECK(cudaMemsetAsync(wave_d_.get() + (1 - wave_cur_) * bodies_.size(), 0,
                                  sizeof(unsigned long long) * bodies_.size(), stream_));
  FBAR_CUDA_CHECK(cudaMemsetAsync(p2g_bound_d_.get() + (1 - bound_cur_) * bodies_.size(), 0,
                                  sizeof(unsigned long long) * bodies_.size(), stream_));
  for (auto& b : bodies_)
    FBAR_CUDA_CHECK(cudaMemsetAsync(b->partition.layout(1 - cur_).count, 0, sizeof(int) * block_capacity_, stream_));
  if (capture_next_)  // the device frames are overwritten: their last download must be done
    for (auto& b : bodies_) {
      wait_for_device_frame(*b);
      if (b->frame_copied) FBAR_CUDA_CHECK(cudaStreamWaitEvent(stream_, b->frame_copied, 0));
      if (decomposed() && b->capture.x) prepare_capture(*b);
    }
  if (decomposed() && !options_.overlap_halo && !dec_.placed) {
    // The halo sums and the migration in one exchange (one NCCL group a step): both follow the whole G2P2G.
    for (auto& b : bodies_) b->g2p2g(*this, false, static_cast<T>(dt));
    event_record(2);
    const BlockBuffers halo = step_halo_buffers(1 - gc_);
    std::vector<comm::DeviceTransport::Message> messages = pack_halo_messages(halo, stream_);
    MigrantMessage msg;
    const std::vector<comm::DeviceTransport::Message> migrants = pack_migrant_messages(msg);
    messages.insert(messages.end(), migrants.begin(), migrants.end());
    dec_.device->exchange(messages, stream_);
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
}

/// Kernel timing (set_kernel_timing): the phases of the committed try, from the step's events.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::add_kernel_times() {
  float ms = 0.f;
  FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[0], events_[1]));
  times_.grid_update_ms += ms;
  FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[1], events_[2]));
  times_.g2p2g_ms += ms;
  for (const auto& b : bodies_)
    if (b->mesh && b->mesh->timed) {
      FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, b->mesh->pass_events[0], b->mesh->pass_events[1]));
      times_.fem_ms += ms;
    }
  FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[2], events_[4]));
  times_.halo_ms += ms;
  if (decomposed() && options_.overlap_halo) {  // hidden: what the halo stream took beyond the exposed part
    float total = 0.f;
    FBAR_CUDA_CHECK(cudaEventElapsedTime(&total, dec_.halo_events[0], dec_.halo_events[1]));
    times_.halo_hidden_ms += std::max(0.f, total - ms);
  }
  FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[4], events_[5]));
  times_.migration_ms += ms;
  FBAR_CUDA_CHECK(cudaEventElapsedTime(&ms, events_[5], events_[3]));
  times_.partition_ms += ms;
  ++times_.steps;
}

template <typename T, typename TG>
StepReport MgspBenchmark<T, TG>::step_impl(double dt, bool cfl_dt, double target, double following) {
  if (!(dt > 0.0) || !std::isfinite(dt)) throw std::invalid_argument("GpuEngine::step: dt must be positive");
  // Seeded or restarted velocities (by ID): read by the initial P2G and by frame 0's capture; not needed any more.
  for (auto& b : bodies_)
    if (b->initial_v.size()) {
      cuda::DeviceArray<T> done;
      b->initial_v.swap(done);
    }
  StepReport report;
  int range_repeats = 0, migration_tries = 0;
  for (;;) {
    begin_try(dt);
    update_grid(dt);  // 1. grid update (and the grid sensors of a sample step)
    launch_next_dt(dt, cfl_dt, target, following);  // 2. dt of the next step (its P2G impulse)
    event_record(1);
    g2p2g_step(dt);  // 3. G2P2G (and, decomposed, the halo sums and the migration)
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
    if (decomposed() && dec_.migrant_most > dec_.migrant_capacity) {
      // Some rank sent more particles one way than a message holds: every rank grows the messages alike and
      // repeats the try (the try's state is still the step's start). Twice in a row is an engine bug.
      if (++migration_tries > 2)
        throw std::runtime_error("GpuEngine: the migration messages did not grow enough at step " +
                                 std::to_string(steps_ + 1));
      dec_.migrant_capacity = std::max(2 * dec_.migrant_capacity, 2 * dec_.migrant_most);
      ++dec_.migration_repeats;
      continue;
    }
    // A step that used more than half of the messages' room grows them for the next one (every rank alike).
    if (decomposed() && 2 * dec_.migrant_most > dec_.migrant_capacity) dec_.migrant_capacity = 2 * dec_.migrant_most;
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
      while (handle_overflow()) ++partition_redos_;
      for (const auto& b : bodies_)
        if (body_stats_[b->index].particles != b->pending_particles)
          throw std::runtime_error("GpuEngine: the partition of body " + std::to_string(b->index) + " placed " +
                                   std::to_string(body_stats_[b->index].particles) + " of " +
                                   std::to_string(b->pending_particles) + " particles at step " +
                                   std::to_string(steps_ + 1));
      if (timing_) add_kernel_times();
      commit(dt);
      report.dt = dt;
      report.steps = 1;
      retry_.committed(cfl_dt);
      return report;
    }
    if (retry_.retry(scene_.simulation.on_failure, failures, cfl_dt, dt, report, log_)) {
      // Blocks inserted by the failed try stay in the table (zeroed in both grids); count them from now on.
      block_count_ = std::max(block_count_, std::min(stats_->block_count, block_capacity_));
      continue;
    }
    report.ok = false;
    report.dt = dt;
    report.failures = std::move(failures);
    if (record_) aux_valid_ = false;  // the failed try wrote over the recorded v and C
    p2g_valid_ = false;
    return report;
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::commit(double dt) {
  record_p2g_blocks();  // before the flip: layout(cur) is the one this G2P2G read
  for (auto& b : bodies_) {
    take_layout_stats(*b, 1 - cur_);
    b->particles = b->pending_particles;
    if (b->mesh) b->mesh->force_cur = 1 - b->mesh->force_cur;  // the forces at the committed positions
  }
  dec_.migrated += dec_.pending_migrated;
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
  dt_scale_at_compute_ = retry_.scale;
  double max_speed_sq = 0.0;
  std::memcpy(&max_speed_sq, &stats_->max_speed_sq, sizeof(double));
  max_grid_speed_ = std::sqrt(max_speed_sq);
  block_count_ = stats_->block_count;
  aux_valid_ = record_;
  if (decomposed() && dec_.halo_grew) {
    rebuild_halo(gc_);  // agreed: all ranks or none
  } else if (decomposed()) {
    // No rank found a new halo block in this step's table: every block it holds has been looked at.
    dec_.halo_scanned = std::max(dec_.halo_scanned, std::min(block_count_, block_capacity_));
  }
  maybe_compact_grid();  // before the headroom check: dropped blocks need no room
  // Headroom for the next step (grow between steps, rarely inside one): blocks at 3/4, bins at 9/10 of capacity.
  if (options_.grow_ahead && block_count_ > block_capacity_ * 3 / 4) grow_blocks(2 * block_capacity_);
  ensure_step_capacity();
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::maybe_compact_grid() {
  // Not with placed bodies (their shared-block lists and per-block flags are not renumbered), nor when a checkpoint
  // is about to read the table indices this step's G2P2G recorded (p2g_record), nor before the halo planes saw every
  // block.
  if (!options_.compact_grid || dec_.placed || p2g_valid_ || block_count_ < compact_check_at_) return;
  if (decomposed() && dec_.halo_scanned < block_count_) return;
  compact_grid();
}

template <typename T, typename TG>
bool MgspBenchmark<T, TG>::compact_grid() {
  const int count = block_count_;
  if (count == 0) return false;
  // Scratch: the velocity buffer, which nothing reads between a commit and the next grid update (the update
  // rewrites every block before G2P2G reads one).
  std::byte* const base = reinterpret_cast<std::byte*>(grid_velocity().instance().data());
  std::size_t used = 0;
  const auto take = [&](std::size_t bytes) {
    std::byte* p = base + used;
    used += (bytes + 255) / 256 * 256;
    return p;
  };
  const std::size_t n = static_cast<std::size_t>(count);
  int* live = reinterpret_cast<int*>(take(sizeof(int) * (n + 1)));
  int* position = reinterpret_cast<int*>(take(sizeof(int) * (n + 1)));  // then: old index -> new index
  auto* keys_in = reinterpret_cast<unsigned long long*>(take(sizeof(unsigned long long) * n));
  auto* keys_out = reinterpret_cast<unsigned long long*>(take(sizeof(unsigned long long) * n));
  int* old_in = reinterpret_cast<int*>(take(sizeof(int) * n));
  int* old_of_new = reinterpret_cast<int*>(take(sizeof(int) * n));
  int* table_scratch = reinterpret_cast<int*>(take(sizeof(int) * 11 * n));
  int* count_tmp = reinterpret_cast<int*>(take(sizeof(int) * n));
  int* old_bin = reinterpret_cast<int*>(take(sizeof(int) * n));
  int* total_d = reinterpret_cast<int*>(take(sizeof(int) * bodies_.size()));
  std::size_t sort_bytes = 0;
  FBAR_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, sort_bytes, keys_in, keys_out, old_in, old_of_new, count,
                                                  0, 63, stream_));
  std::byte* sort_temp = take(sort_bytes);
  compact_check_at_ = count + std::max(count / 8, 64);
  if (used > grid_velocity().bytes()) return false;  // ~100 of its 768 bytes a block: does not happen
  // 1. Which blocks stay: every layout's particle blocks and their arenas, and the halo lists.
  FBAR_CUDA_CHECK(cudaMemsetAsync(live, 0, sizeof(int) * (n + 1), stream_));
  for (auto& b : bodies_) {
    mark_live_blocks<<<cuda::grid_for(count, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        b->partition.layout(cur_).count, count, table_.view(), live);
    cuda::check_launch("mark_live_blocks");
  }
  if (decomposed())
    for (const HaloSide& h : dec_.halo)
      if (h.peer >= 0 && !h.keys.empty()) {
        const int listed = static_cast<int>(h.keys.size());
        mark_listed_blocks<<<cuda::grid_for(listed, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
            h.index.get(), listed, live);
        cuda::check_launch("mark_listed_blocks");
      }
  std::size_t temp = scan_temp_bytes_;
  FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(scan_temp_.get(), temp, live, position, count + 1, stream_));
  int kept = 0;
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&kept, position + count, sizeof(int), cudaMemcpyDeviceToHost, stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  compact_check_at_ = kept + std::max(kept / 8, 64);
  if (count - kept < std::max(kept / 16, 1)) return false;  // too few to drop: not worth the moves
  // 2. The kept blocks in the order of their keys (x, then y, then z: neighbours along z are neighbours in memory,
  // as the first partition of a box leaves them), and each old index's new one.
  pack_kept_blocks<<<cuda::grid_for(count, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
      live, position, count, table_.view(), keys_in, old_in);
  cuda::check_launch("pack_kept_blocks");
  FBAR_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(sort_temp, sort_bytes, keys_in, keys_out, old_in, old_of_new, kept,
                                                  0, 63, stream_));
  int* const new_index = position;
  FBAR_CUDA_CHECK(cudaMemsetAsync(new_index, 0xff, sizeof(int) * n, stream_));
  invert_block_order<<<cuda::grid_for(kept, kPartitionThreads), kPartitionThreads, 0, stream_>>>(old_of_new, kept,
                                                                                                  new_index);
  cuda::check_launch("invert_block_order");
  // 3. The table, then the per-block state a step reads before writing it: the current grid's sums (and ASFLIP's
  // transported momentum), moved through the other grid (free until the next G2P2G clears it).
  table_.renumber(old_of_new, new_index, kept, count, table_scratch, stream_);
  const auto move = [&](std::byte* current, std::byte* spare, std::size_t block_bytes) {
    const int words = static_cast<int>(block_bytes / sizeof(uint4));
    const int grid = static_cast<int>(std::min<long long>(
        (static_cast<long long>(kept) * words + kPartitionThreads - 1) / kPartitionThreads, 65536));
    gather_blocks<<<grid, kPartitionThreads, 0, stream_>>>(reinterpret_cast<const uint4*>(current),
                                                           reinterpret_cast<uint4*>(spare), words, old_of_new, kept);
    cuda::check_launch("gather_blocks");
    FBAR_CUDA_CHECK(cudaMemcpyAsync(current, spare, block_bytes * kept, cudaMemcpyDeviceToDevice, stream_));
    FBAR_CUDA_CHECK(cudaMemsetAsync(current + block_bytes * kept, 0, block_bytes * (n - kept), stream_));
  };
  channels_.each_carried(gc_, move);  // the AcrossSteps sets (grid_channels.cuh checks their 16-byte words)
  // 4. Each layout: counts at the new indices, bin offsets scanned again, each block's bins moved with it (through
  // the other layout's src, which the next partition rewrites).
  std::vector<int> total(bodies_.size(), 0);
  for (auto& b : bodies_) {
    const LayoutView l = b->partition.layout(cur_);
    const LayoutView spare = b->partition.layout(1 - cur_);
    gather_layout_blocks<<<cuda::grid_for(kept, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        l.count, l.bin_offset, old_of_new, kept, count_tmp, old_bin);
    cuda::check_launch("gather_layout_blocks");
    FBAR_CUDA_CHECK(cudaMemcpyAsync(l.count, count_tmp, sizeof(int) * kept, cudaMemcpyDeviceToDevice, stream_));
    FBAR_CUDA_CHECK(cudaMemsetAsync(l.count + kept, 0, sizeof(int) * (n - kept), stream_));
    blocks_to_bins<<<cuda::grid_for(block_capacity_ + 1, kPartitionThreads), kPartitionThreads, 0, stream_>>>(
        l.count, b->partition.bins_per_block(), block_capacity_);
    cuda::check_launch("blocks_to_bins");
    temp = scan_temp_bytes_;
    FBAR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(scan_temp_.get(), temp, b->partition.bins_per_block(), l.bin_offset,
                                                  block_capacity_ + 1, stream_));
    move_block_bins<<<cuda::grid_for(kept, kPartitionThreads / 32), kPartitionThreads, 0, stream_>>>(
        l.src, spare.src, l.count, l.bin_offset, old_bin, kept);
    cuda::check_launch("move_block_bins");
    const std::size_t slots = static_cast<std::size_t>(b->total_bins[cur_]) * 32;
    if (slots > 0)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(l.src, spare.src, sizeof(int) * slots, cudaMemcpyDeviceToDevice, stream_));
    FBAR_CUDA_CHECK(cudaMemcpyAsync(total_d + b->index, l.bin_offset + block_capacity_, sizeof(int),
                                    cudaMemcpyDeviceToDevice, stream_));
    if (b->partition.ordered()) list_blocks(*b, cur_, b->partition.list_counters());
  }
  // 5. A decomposed rank's halo lists name the new indices.
  if (decomposed())
    for (HaloSide& h : dec_.halo)
      if (h.peer >= 0 && !h.keys.empty()) {
        const int listed = static_cast<int>(h.keys.size());
        renumber_list<<<cuda::grid_for(listed, kPartitionThreads), kPartitionThreads, 0, stream_>>>(h.index.get(),
                                                                                                   listed, new_index);
        cuda::check_launch("renumber_list");
      }
  FBAR_CUDA_CHECK(cudaMemcpyAsync(total.data(), total_d, sizeof(int) * total.size(), cudaMemcpyDeviceToHost,
                                  stream_));
  TableCounters counters{};
  FBAR_CUDA_CHECK(cudaMemcpyAsync(&counters, table_.counters(), sizeof(counters), cudaMemcpyDeviceToHost, stream_));
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  for (const auto& b : bodies_)
    if (total[b->index] != b->total_bins[cur_])
      throw std::logic_error("GpuEngine: the grid compaction at step " + std::to_string(steps_) + " left body " +
                             std::to_string(b->index) + " " + std::to_string(total[b->index]) + " bins instead of " +
                             std::to_string(b->total_bins[cur_]));
  if (counters.overflow != 0 || counters.block_count != kept)
    throw std::logic_error("GpuEngine: the grid compaction at step " + std::to_string(steps_) +
                           " could not rebuild the hash table");
  block_count_ = kept;
  stats_->block_count = kept;
  if (decomposed()) dec_.halo_scanned = kept;
  ++compactions_;
  compacted_blocks_ += count - kept;
  return true;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_step_capacity() {
  for (auto& b : bodies_) {
    const int need = b->total_bins[cur_];
    if (options_.grow_ahead && need > b->partition.bin_capacity() * 9 / 10) grow_bins(*b, cur_, need * 3 / 2);
    // The next G2P2G writes bins[1 - cur] (the previous state, free now) in layout(cur) order: it must hold every
    // bin of that layout (the partition's bin capacity bounds it).
    if (b->bins_capacity(1 - cur_) < b->partition.bin_capacity()) b->reallocate_bins(1 - cur_, b->partition.bin_capacity());
  }
  peak_bytes_ = std::max(peak_bytes_, device_bytes());
}

template <typename T, typename TG>
StepReport MgspBenchmark<T, TG>::step_toward(double t_end, double t_following) {
  const StepPlan plan = plan_step_toward(time_, t_end, next_dt());  // the CPU engine's rule (engine_common.h)
  StepReport r = step_impl(plan.dt, true, t_end, t_following);
  plan.land(time_, t_end, r);
  return r;
}

template <typename T, typename TG>
StepReport MgspBenchmark<T, TG>::advance_to(double t_end) {
  StepReport total;
  while (time_ < t_end && total.absorb(step_toward(t_end))) {
  }
  return total;
}

}  // namespace fbar
