// GpuEngine<T, TG> (forwarding to the per-device MgspBenchmark<T, TG>) and run_gpu_as<T, TG> (the GPU engine in
// run_loop.h). Compiled once per precision, with the driver, by instances/driver_{single,double,mixed}.cu.
#pragma once

#include "engine/gpu/gpu_engine.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "MnSystem/host_memory.h"
#include "comm/device_transport.h"
#include "comm/placement.h"
#include "comm/slab_partition.h"
#include "comm/transport.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "MnSystem/IO/async_writer.h"
#include "engine/run_loop.h"
#include "geometry/geometry.h"
#include "engine/gpu/mgsp_benchmark.cuh"
// The parts of the driver, each defining the members of one concern (they include mgsp_benchmark.cuh first).
#include "engine/gpu/engine_setup.cuh"
#include "engine/gpu/engine_step.cuh"
#include "engine/gpu/sensors_checkpoints.cuh"
#include "engine/gpu/frame_output.cuh"
#include "engine/gpu/decomposition/slabs.cuh"
#include "engine/gpu/decomposition/halo.cuh"
#include "engine/gpu/decomposition/shared_blocks.cuh"
#include "engine/gpu/decomposition/migration.cuh"
#include "engine/gpu/decomposition/rebalance.cuh"
#include "scene/scene_error.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace gpu_engine_detail {

/// A restart's positions per body (ID order), and its velocities as the options' initial velocities.
struct RestartInput {
  std::vector<std::vector<Vec3d>> positions;
  GpuEngineOptions options;
};

inline RestartInput restart_input(const GpuEngineOptions& options) {
  RestartInput in;
  in.options = options;
  const io::Checkpoint& cp = *options.restart;
  in.options.initial_velocities.assign(cp.bodies.size(), {});
  for (std::size_t b = 0; b < cp.bodies.size(); ++b) {
    const io::CheckpointBody& body = cp.bodies[b];
    std::vector<Vec3d>& x = in.positions.emplace_back(body.particles());
    std::vector<Vec3d>& v = in.options.initial_velocities[b];
    v.resize(body.particles());
    for (std::size_t p = 0; p < body.particles(); ++p) {
      x[p] = Vec3d{{body.x[3 * p], body.x[3 * p + 1], body.x[3 * p + 2]}};
      v[p] = Vec3d{{body.v[3 * p], body.v[3 * p + 1], body.v[3 * p + 2]}};
    }
  }
  return in;
}

template <typename T, typename TG>
std::unique_ptr<MgspBenchmark<T, TG>> make_engine(const Scene& scene, const GpuEngineOptions& options) {
  if (!options.restart) return std::make_unique<MgspBenchmark<T, TG>>(scene, nullptr, options);
  const RestartInput in = restart_input(options);
  return std::make_unique<MgspBenchmark<T, TG>>(scene, &in.positions, in.options);
}

/// The options a rebalance builds the engine with again: without what only the first construction reads.
inline GpuEngineOptions kept_options(const GpuEngineOptions& options) {
  GpuEngineOptions kept = options;
  kept.initial_velocities.clear();
  kept.restart = nullptr;
  kept.restart_slab_cuts.clear();  // a rebalance chooses its own
  return kept;
}

}  // namespace gpu_engine_detail

using gpu_engine_detail::kept_options;
using gpu_engine_detail::make_engine;

template <typename T, typename TG>
GpuEngine<T, TG>::GpuEngine(const Scene& scene, const GpuEngineOptions& options)
    : impl_(make_engine<T, TG>(scene, options)), scene_(&scene), options_(kept_options(options)) {
  chosen_imbalance_ = !options.restart_slab_cuts.empty() && options.restart_chosen_imbalance >= 0.0
                          ? options.restart_chosen_imbalance
                          : impl_->imbalance();
}
template <typename T, typename TG>
GpuEngine<T, TG>::GpuEngine(const Scene& scene, const std::vector<std::vector<Vec3d>>& positions,
                        const GpuEngineOptions& options)
    : impl_(std::make_unique<MgspBenchmark<T, TG>>(scene, &positions, options)),
      scene_(&scene),
      options_(kept_options(options)) {
  chosen_imbalance_ = impl_->imbalance();
}
template <typename T, typename TG>
GpuEngine<T, TG>::~GpuEngine() = default;

template <typename T, typename TG>
StepReport GpuEngine<T, TG>::step() {
  return impl_->step_impl(impl_->next_dt(), true, std::numeric_limits<double>::infinity());
}
template <typename T, typename TG>
StepReport GpuEngine<T, TG>::step(double dt) {
  return impl_->step_impl(dt, false, std::numeric_limits<double>::infinity());
}
template <typename T, typename TG>
StepReport GpuEngine<T, TG>::advance_to(double t_end) {
  return impl_->advance_to(t_end);
}
template <typename T, typename TG>
StepReport GpuEngine<T, TG>::step_toward(double t_end, double t_following) {
  return impl_->step_toward(t_end, t_following);
}
template <typename T, typename TG>
double GpuEngine<T, TG>::time() const { return impl_->time(); }
template <typename T, typename TG>
long long GpuEngine<T, TG>::steps() const { return impl_->steps(); }
template <typename T, typename TG>
double GpuEngine<T, TG>::last_dt() const { return impl_->last_dt(); }
template <typename T, typename TG>
double GpuEngine<T, TG>::next_dt() const { return impl_->next_dt(); }
template <typename T, typename TG>
double GpuEngine<T, TG>::max_grid_speed() const { return impl_->max_grid_speed(); }
template <typename T, typename TG>
void GpuEngine<T, TG>::set_log(std::ostream* log) {
  log_ = log;
  impl_->set_log(log);
}
template <typename T, typename TG>
void GpuEngine<T, TG>::set_record_velocities(bool on) {
  record_velocities_ = on;
  impl_->set_record_velocities(on);
}
template <typename T, typename TG>
void GpuEngine<T, TG>::set_kernel_timing(bool on) {
  timing_ = on;
  impl_->set_kernel_timing(on);
}
template <typename T, typename TG>
KernelTimes GpuEngine<T, TG>::kernel_times() const {
  KernelTimes t = impl_->kernel_times();
  const KernelTimes& e = earlier_times_;
  t.grid_update_ms += e.grid_update_ms;
  t.g2p2g_ms += e.g2p2g_ms;
  t.fem_ms += e.fem_ms;
  t.partition_ms += e.partition_ms;
  t.halo_ms += e.halo_ms;
  t.halo_hidden_ms += e.halo_hidden_ms;
  t.migration_ms += e.migration_ms;
  t.steps += e.steps;
  return t;
}
template <typename T, typename TG>
long long GpuEngine<T, TG>::p2g_range_repeats() const { return earlier_repeats_ + impl_->p2g_range_repeats(); }
template <typename T, typename TG>
long long GpuEngine<T, TG>::partition_redos() const { return earlier_redos_ + impl_->partition_redos(); }
template <typename T, typename TG>
long long GpuEngine<T, TG>::grid_compactions() const { return earlier_compactions_ + impl_->grid_compactions(); }
template <typename T, typename TG>
long long GpuEngine<T, TG>::compacted_blocks() const { return earlier_compacted_ + impl_->compacted_blocks(); }
template <typename T, typename TG>
int GpuEngine<T, TG>::body_count() const { return impl_->body_count(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::particle_count(int body) const { return impl_->particle_count(body); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::particle_count() const { return impl_->particle_count(); }
template <typename T, typename TG>
ParticleSnapshot<T> GpuEngine<T, TG>::snapshot(int body) const { return impl_->snapshot(body); }
template <typename T, typename TG>
io::ParticleFrame GpuEngine<T, TG>::frame(int body) const { return impl_->frame(body); }
template <typename T, typename TG>
void GpuEngine<T, TG>::set_frame_capture(bool on) {
  frame_capture_ = on;
  impl_->set_frame_capture(on);
}
template <typename T, typename TG>
double GpuEngine<T, TG>::output_wait_seconds() const { return earlier_wait_s_ + impl_->output_wait_seconds(); }
template <typename T, typename TG>
void GpuEngine<T, TG>::set_grid_sensors(const std::vector<GridSensorSpec>& sensors) {
  grid_sensors_ = sensors;
  impl_->set_grid_sensors(sensors);
}
template <typename T, typename TG>
void GpuEngine<T, TG>::set_grid_sample(int slot) {
  grid_sample_ = slot;
  impl_->set_grid_sample(slot);
}
template <typename T, typename TG>
std::vector<SensorAccum> GpuEngine<T, TG>::grid_samples(int slots) const { return impl_->grid_samples(slots); }

template <typename T, typename TG>
void GpuEngine<T, TG>::set_grid_fields(const std::vector<GridFieldSpec>& fields) {
  grid_fields_ = fields;
  impl_->set_grid_fields(fields);
}

template <typename T, typename TG>
void GpuEngine<T, TG>::set_grid_field_sample(unsigned mask) {
  grid_field_mask_ = mask;
  impl_->set_grid_field_sample(mask);
}

template <typename T, typename TG>
GridFieldSample GpuEngine<T, TG>::grid_field_sample(int field) { return impl_->grid_field_sample(field); }
template <typename T, typename TG>
void GpuEngine<T, TG>::set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors) {
  particle_sensors_ = sensors;
  impl_->set_particle_sensors(sensors);
}
template <typename T, typename TG>
void GpuEngine<T, TG>::keep_particle_inputs(bool on) {
  particle_inputs_ = on;
  impl_->keep_particle_inputs(on);
}
template <typename T, typename TG>
void GpuEngine<T, TG>::sample_particles(int slot) { impl_->sample_particles(slot); }
template <typename T, typename TG>
std::vector<SensorAccum> GpuEngine<T, TG>::particle_samples(int slots) const { return impl_->particle_samples(slots); }
template <typename T, typename TG>
void GpuEngine<T, TG>::set_tracker(int body, const TrackerSet& set) {
  impl_->set_tracker(body, set);
  for (auto& [b, t] : trackers_)
    if (b == body) {
      t = set;
      return;
    }
  trackers_.emplace_back(body, set);
}
template <typename T, typename TG>
void GpuEngine<T, TG>::track(int body, std::vector<double>& values, std::vector<double>& present) {
  impl_->track(body, values, present);
}
template <typename T, typename TG>
io::Checkpoint GpuEngine<T, TG>::checkpoint() const {
  io::Checkpoint c = impl_->checkpoint(true);  // a body above frame_host_bytes streamed: written before the next step
  c.chosen_imbalance = chosen_imbalance_;  // a restart on as many ranks keeps the slabs and this
  return c;
}
template <typename T, typename TG>
bool GpuEngine<T, TG>::checkpoint_ready() const { return impl_->checkpoint_ready(); }
template <typename T, typename TG>
void GpuEngine<T, TG>::keep_checkpoint_inputs(bool on) {
  checkpoint_inputs_ = on;
  impl_->keep_checkpoint_inputs(on);
}
template <typename T, typename TG>
const DeviceMemoryPlan& GpuEngine<T, TG>::memory_plan() const { return impl_->memory_plan(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::peak_device_bytes() const { return std::max(earlier_peak_, impl_->peak_device_bytes()); }
template <typename T, typename TG>
std::string GpuEngine<T, TG>::resource_note() const {
  const HostMemory host = host_memory();
  std::string note = "device memory " + format_bytes(static_cast<double>(device_bytes())) + ", peak " +
                     format_bytes(static_cast<double>(peak_device_bytes())) + "; host memory " +
                     format_bytes(static_cast<double>(host.resident)) + ", peak " +
                     format_bytes(static_cast<double>(host.peak));
  if (ranks() > 1)
    note = std::to_string(ranks()) + " GPU ranks, rank " + std::to_string(rank()) + ": " +
           std::to_string(particle_count()) + " particles, " + std::to_string(migrated()) + " migrated from it, " +
           note;
  return note;
}
template <typename T, typename TG>
void GpuEngine<T, TG>::submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer) {
  impl_->submit_frame(body, path, writer);
}
template <typename T, typename TG>
double GpuEngine<T, TG>::particle_mass(int body) const { return impl_->particle_mass(body); }
template <typename T, typename TG>
double GpuEngine<T, TG>::particle_volume(int body) const { return impl_->particle_volume(body); }
template <typename T, typename TG>
double GpuEngine<T, TG>::total_mass() const { return impl_->total_mass(); }
template <typename T, typename TG>
std::vector<double> GpuEngine<T, TG>::particle_masses(int body) const { return impl_->particle_masses(body); }
template <typename T, typename TG>
double GpuEngine<T, TG>::elastic_energy() const { return impl_->elastic_energy(); }
template <typename T, typename TG>
double GpuEngine<T, TG>::grid_mass() const { return impl_->grid_mass(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::active_grid_blocks() const { return impl_->active_grid_blocks(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::particle_blocks() const { return impl_->particle_blocks(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::device_bytes() const { return impl_->device_bytes(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::grid_channel_bytes() const { return impl_->grid_channel_bytes(); }
template <typename T, typename TG>
int GpuEngine<T, TG>::grid_block_capacity() const { return impl_->grid_block_capacity(); }
template <typename T, typename TG>
int GpuEngine<T, TG>::rank() const { return impl_->rank(); }
template <typename T, typename TG>
int GpuEngine<T, TG>::ranks() const { return impl_->ranks(); }
template <typename T, typename TG>
const comm::SlabPartition& GpuEngine<T, TG>::slabs() const { return impl_->slabs(); }
template <typename T, typename TG>
long long GpuEngine<T, TG>::migrated() const { return earlier_migrated_ + impl_->migrated(); }
template <typename T, typename TG>
long long GpuEngine<T, TG>::migration_repeats() const {
  return earlier_migration_repeats_ + impl_->migration_repeats();
}
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::halo_blocks() const { return impl_->halo_blocks(); }
template <typename T, typename TG>
std::size_t GpuEngine<T, TG>::halo_particle_blocks() const { return impl_->halo_particle_blocks(); }
template <typename T, typename TG>
double GpuEngine<T, TG>::imbalance() const { return impl_->imbalance(); }
template <typename T, typename TG>
int GpuEngine<T, TG>::rebalances() const { return rebalances_; }
template <typename T, typename TG>
bool GpuEngine<T, TG>::rebalance_due() const {
  const double now = impl_->imbalance();
  return ranks() > 1 && options_.rebalance_threshold > 0.0 && now > options_.rebalance_threshold &&
         now > 1.5 * chosen_imbalance_;
}

template <typename T, typename TG>
bool GpuEngine<T, TG>::rebalance_if_drifted() {
  if (!rebalance_due() || !impl_->checkpoint_ready()) return false;  // the same on every rank
  const double drifted = impl_->imbalance();
  const auto start = std::chrono::steady_clock::now();
  io::Checkpoint merged = impl_->merged_checkpoint();  // collective: every rank's particles, in ID order
  if (!impl_->slabs_change_for(merged)) {  // whole block planes allow no better split: wait for a larger drift
    chosen_imbalance_ = drifted;
    return false;
  }
  impl_->wait_for_frames();
  earlier_times_ = kernel_times();
  earlier_migrated_ = migrated();
  earlier_migration_repeats_ = migration_repeats();
  earlier_repeats_ = p2g_range_repeats();
  earlier_redos_ = partition_redos();
  earlier_compactions_ = grid_compactions();
  earlier_compacted_ = compacted_blocks();
  earlier_wait_s_ = output_wait_seconds();
  earlier_peak_ = peak_device_bytes();
  impl_.reset();  // the device memory first
  GpuEngineOptions options = options_;
  options.restart = &merged;
  impl_ = make_engine<T, TG>(*scene_, options);
  replay_settings();
  chosen_imbalance_ = impl_->imbalance();
  ++rebalances_;
  if (log_ && rank() == 0)
    *log_ << "fbar: particles per GPU rank drifted apart (imbalance " << mgsp_detail::format_g(100 * drifted)
          << " % > " << mgsp_detail::format_g(100 * options_.rebalance_threshold) << " %) at step " << steps()
          << ": new " << impl_->slabs().describe() << ", imbalance " << mgsp_detail::format_g(100 * chosen_imbalance_)
          << " % (" << mgsp_detail::format_g(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count())
          << " s)\n";
  return true;
}

template <typename T, typename TG>
void GpuEngine<T, TG>::replay_settings() {
  impl_->set_log(log_);
  impl_->set_record_velocities(record_velocities_);
  impl_->set_kernel_timing(timing_);
  if (!grid_sensors_.empty()) impl_->set_grid_sensors(grid_sensors_);
  if (!grid_fields_.empty()) impl_->set_grid_fields(grid_fields_);
  impl_->set_grid_field_sample(grid_field_mask_);
  if (!particle_sensors_.empty()) impl_->set_particle_sensors(particle_sensors_);
  for (const auto& [body, set] : trackers_) impl_->set_tracker(body, set);
  impl_->set_grid_sample(grid_sample_);
  impl_->keep_particle_inputs(particle_inputs_);
  impl_->keep_checkpoint_inputs(checkpoint_inputs_);
  impl_->set_frame_capture(frame_capture_);
}

template <typename T, typename TG>
RunResult run_gpu_as(const Scene& scene, const RunOptions& options, std::ostream& log) {
  GpuEngineOptions engine_options;
  engine_options.frames = true;
  engine_options.frame_host_bytes = options.frame_host_bytes;
  std::unique_ptr<comm::DeviceTransport> device;  // a decomposed run: NCCL, or peer copies when ranks share GPUs
  if (options.transport && options.transport->size() > 1) {
    device = options.shared_gpus ? comm::make_thread_device_transport(*options.transport)
                                 : comm::make_nccl_transport(*options.transport);
    engine_options.ranks = options.transport;
    engine_options.device_ranks = device.get();
    engine_options.overlap_halo = options.halo_overlap;
  }
  const auto setup_start = std::chrono::steady_clock::now();
  // A restart: every rank reads the whole set (in ID order) and keeps the particles of its slab.
  std::unique_ptr<io::Checkpoint> restart;
  if (!options.restart.empty()) {
    restart = std::make_unique<io::Checkpoint>(io::read_checkpoint_set(options.restart));
    engine_options.restart = restart.get();
    // Written by as many ranks: their slabs again (read_checkpoint_set's merge keeps none), so that each rank
    // continues with the particles it held.
    const int ranks = options.transport ? options.transport->size() : 1;
    const io::Checkpoint first = io::read_checkpoint(io::checkpoint_rank_path(options.restart, 0), false);
    if (ranks > 1 && first.ranks == ranks && first.slab_cuts.size() == static_cast<std::size_t>(ranks) + 1) {
      engine_options.restart_slab_axis = first.slab_axis;
      engine_options.restart_slab_cuts = first.slab_cuts;
      engine_options.restart_chosen_imbalance = first.chosen_imbalance;
    }
  }
  GpuEngine<T, TG> engine(scene, engine_options);
  if (restart) {
    for (io::CheckpointBody& b : restart->bodies) b = io::CheckpointBody{};  // on the device now
    engine_options.restart = nullptr;
  }
#if defined(__GLIBC__)
  // The set-up's sampling batches are freed; give their pages back (the 1e9-particle run's peak went from 1.55 to
  // 1.47 GiB: docs/benchmarks/2026-12-02-h200-host-memory.md; --check still counts the set-up as resident).
  malloc_trim(0);
#endif
  const HostMemory setup_host = host_memory();
  const double setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - setup_start).count();
  engine.set_log(&log);
  const std::string line =
      std::string("fbar: GPU engine (") + precision_description(scene.simulation.precision) + "), " +
      std::to_string(engine.particle_count()) + " particles" +
      (engine.ranks() > 1 ? " on rank 0 of " + std::to_string(engine.ranks()) : std::string()) + ", " +
      std::to_string(engine.body_count()) + " bodies, " +
      format_bytes(static_cast<double>(engine.device_bytes())) + " on the device (" +
      format_bytes(static_cast<double>(engine.memory_plan().total())) + " planned), set-up " +
      mgsp_detail::format_g(setup_s) + " s (host memory " + format_bytes(static_cast<double>(setup_host.peak)) +
      " at most, " + format_bytes(static_cast<double>(setup_host.resident)) + " kept)";
  return run_frames(engine, scene, options, log, line, restart.get());
}

}  // namespace fbar
