// Decomposition: rebalancing. When the particles per rank drift apart, GpuEngine::rebalance_if_drifted() builds the
// engine again from every rank's particles (the restart path) with the slabs they ask for now; these members give it
// the merged particles and say whether the slabs would change. Part of MgspBenchmark.
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
io::Checkpoint MgspBenchmark<T, TG>::merged_checkpoint() const {
  io::Checkpoint merged = checkpoint();  // collective
  std::vector<comm::Bytes> parts = dec_.host->allgather(io::checkpoint_particle_bytes(merged));
  for (io::CheckpointBody& b : merged.bodies) b = b.description();  // the header and body descriptions stay
  std::vector<io::Checkpoint> all(parts.size(), merged);
  for (std::size_t r = 0; r < parts.size(); ++r) {
    io::read_checkpoint_particle_bytes(parts[r], all[r]);
    comm::Bytes().swap(parts[r]);
  }
  return io::merge_checkpoints(std::move(all), "rebalancing at step " + std::to_string(steps_));
}

template <typename T, typename TG>
bool MgspBenchmark<T, TG>::slabs_change_for(const io::Checkpoint& merged) const {
  std::vector<SampleCount> counts;
  const std::vector<int> homes = comm::body_ranks(scene_, ranks());  // placed bodies: a preload, not planes
  std::vector<long long> particles;
  for (const io::CheckpointBody& b : merged.bodies) particles.push_back(static_cast<long long>(b.particles()));
  for (std::size_t i = 0; i < merged.bodies.size(); ++i) {
    if (homes[i] >= 0) continue;
    const io::CheckpointBody& b = merged.bodies[i];
    std::vector<Vec3d> x(b.particles());
    for (std::size_t p = 0; p < x.size(); ++p) x[p] = Vec3d{{b.x[3 * p], b.x[3 * p + 1], b.x[3 * p + 2]}};
    counts.push_back(count_points(x, scene_.simulation.dx));
  }
  std::vector<const SampleCount*> pointers;
  for (const SampleCount& c : counts) pointers.push_back(&c);
  const comm::PlaneCounts planes = comm::plane_counts(pointers);
  return planes.total() > 0 &&
         comm::choose_slabs(planes, ranks(), 1, comm::placed_work(scene_, ranks(), particles)).cuts != dec_.slabs.cuts;
}

}  // namespace fbar
