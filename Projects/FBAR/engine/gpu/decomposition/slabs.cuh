// Decomposition by space (comm/slab_partition.h): the slabs chosen from every body's counts, which rank owns a
// particle, and the agreement of the ranks after each try. Part of MgspBenchmark.
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
void MgspBenchmark<T, TG>::choose_slabs(const std::vector<std::vector<Vec3d>>* positions) {
  const int n = ranks(), r = rank();
  dec_.homes = comm::body_ranks(scene_, n);
  dec_.placed = std::any_of(dec_.homes.begin(), dec_.homes.end(), [](int h) { return h >= 0; });
  std::vector<const SampleCount*> spread;  // placed bodies have no say in the slabs
  for (std::size_t b = 0; b < counts_.size(); ++b)
    if (dec_.homes[b] < 0) spread.push_back(&counts_[b]);
  if (dec_.placed) {
    options_.overlap_halo = false;  // the halo-first G2P2G lists the particle blocks next to the cuts only
    dec_.shared = std::vector<SharedPeer>(static_cast<std::size_t>(n));  // built in place: SharedPeer does not move
    dec_.rank_keys.assign(static_cast<std::size_t>(n), {});
  }
  const comm::PlaneCounts planes = comm::plane_counts(spread);
  if (options_.restart_slab_cuts.size() == static_cast<std::size_t>(n) + 1) {  // a restart keeps its run's slabs
    dec_.slabs.axis = options_.restart_slab_axis;
    dec_.slabs.cuts = options_.restart_slab_cuts;
  } else if (planes.total() > 0) {
    std::vector<long long> particles;  // every body's, whole (the counts before this rank keeps its share)
    for (const SampleCount& c : counts_) particles.push_back(c.particles);
    dec_.slabs = comm::choose_slabs(planes, n, 1, comm::placed_work(scene_, n, particles));
  } else {  // only placed bodies: rank 0 "owns" all of space, which nothing asks about
    dec_.slabs.axis = 0;
    dec_.slabs.cuts.assign(static_cast<std::size_t>(n) + 1, INT_MAX);
    dec_.slabs.cuts.front() = INT_MIN;
  }
  dec_.slab.axis = dec_.slabs.axis;
  dec_.slab.lo = dec_.slabs.cuts[static_cast<std::size_t>(r)];
  dec_.slab.hi = dec_.slabs.cuts[static_cast<std::size_t>(r) + 1];
  for (int side = 0; side < 2; ++side) {
    HaloSide& h = dec_.halo[static_cast<std::size_t>(side)];
    h.peer = side == 0 ? (r > 0 ? r - 1 : -1) : (r + 1 < n ? r + 1 : -1);
    h.plane = side == 0 ? dec_.slab.lo : dec_.slab.hi;  // rank r's particles scatter into grid planes [lo, hi]
  }
  // This rank's share of every count: the plan, the upload and the particle checks use it.
  for (std::size_t b = 0; b < counts_.size(); ++b) {
    SampleCount mine;
    mine.per_plane = counts_[b].per_plane;  // the sampler's batching (whole planes, every rank samples them all)
    const SlabBounds kept = slab_of(static_cast<int>(b));
    const bool here = dec_.homes[b] < 0 || dec_.homes[b] == r;
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
      const std::vector<Vec3d>& x = (*positions)[b];
      for (std::size_t p = 0; p < x.size(); ++p) mine += holds_at_restart(static_cast<int>(b), p, x[p]) ? 1 : 0;
      body.particles = static_cast<int>(mine);
      continue;
    }
    if (body.mesh) {  // placed whole: its rank holds every vertex
      body.particles = dec_.homes[b] == r ? static_cast<int>(body.mesh->mass.size()) : 0;
      continue;
    }
    const BodySampler sampler(body.spec, scene_.simulation, body.index);
    std::vector<Vec3d> x;
    for (long long plane = 0; plane < sampler.planes();) {
      const long long end = std::min(sampler.planes(), plane + 64);
      x.clear();
      sampler.sample_planes(plane, end, x, &counts_[b].per_plane);
      for (const Vec3d& p : x) mine += owns(static_cast<int>(b), p) ? 1 : 0;
      plane = end;
    }
    body.particles = static_cast<int>(mine);
  }
  if (log_ && r == 0) {
    *log_ << "fbar: GPU ranks " << n << ": " << (planes.total() > 0 ? dec_.slabs.describe() : std::string("no slabs"))
          << " (" << dec_.device->describe() << ")";
    if (dec_.placed) {
      const char* sep = "; placed (bodies[].gpu): ";
      for (std::size_t b = 0; b < dec_.homes.size(); ++b)
        if (dec_.homes[b] >= 0) {
          *log_ << sep << "bodies[" << b << "] on rank " << dec_.homes[b];
          sep = ", ";
        }
    }
    *log_ << "\n";
  }
}

template <typename T, typename TG>
bool MgspBenchmark<T, TG>::owns(int body, const Vec3d& x) const {
  if (!dec_.homes.empty() && dec_.homes[static_cast<std::size_t>(body)] >= 0) return dec_.homes[static_cast<std::size_t>(body)] == rank();
  const QuadraticBspline<T> s = quadratic_bspline_inv(x.template cast<T>(), k_.inv_dx);
  return dec_.slab.owns(floor_div4(s.base[0] - 1), floor_div4(s.base[1] - 1), floor_div4(s.base[2] - 1));
}

template <typename T, typename TG>
const std::int32_t* MgspBenchmark<T, TG>::restart_blocks_of(int body) const {
  const io::Checkpoint* cp = options_.restart;
  if (!cp || body < 0 || static_cast<std::size_t>(body) >= cp->bodies.size()) return nullptr;
  const io::CheckpointBody& c = cp->bodies[static_cast<std::size_t>(body)];
  if (!c.p2g_known || c.p2g_block.size() != 3 * c.particles() || c.p2g_id.size() != c.particles()) return nullptr;
  return c.p2g_block.data();  // merged: ID order (io::merge_checkpoints)
}

template <typename T, typename TG>
bool MgspBenchmark<T, TG>::holds_at_restart(int body, std::size_t p, const Vec3d& x) const {
  const std::int32_t* k = restart_blocks_of(body);
  if (!k || (!dec_.homes.empty() && dec_.homes[static_cast<std::size_t>(body)] >= 0)) return owns(body, x);
  return dec_.slab.owns(k[3 * p], k[3 * p + 1], k[3 * p + 2]);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::size_restart_migration(const std::vector<std::vector<Vec3d>>& positions) {
  // A restart that groups the particles by their recorded blocks holds each where its last P2G was summed; the
  // initial P2G then sends those whose own block lies in a neighbour's slab, as that step's migration did. The
  // messages are sized for them beforehand (every rank counts every particle: the same result everywhere).
  bool any = false;
  for (std::size_t b = 0; b < bodies_.size(); ++b) any = any || restart_blocks_of(static_cast<int>(b)) != nullptr;
  if (!any) return;
  long long most = 0;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    if (!restart_blocks_of(static_cast<int>(b))) continue;
    long long side_count[2] = {0, 0};
    const std::vector<Vec3d>& x = positions[b];
    for (std::size_t p = 0; p < x.size(); ++p) {
      if (!holds_at_restart(static_cast<int>(b), p, x[p]) || owns(static_cast<int>(b), x[p])) continue;
      const QuadraticBspline<T> s = quadratic_bspline_inv(x[p].template cast<T>(), k_.inv_dx);
      ++side_count[dec_.slab.side(floor_div4(s.base[0] - 1), floor_div4(s.base[1] - 1), floor_div4(s.base[2] - 1))];
    }
    most = std::max({most, side_count[0], side_count[1]});
  }
  const long long agreed = static_cast<long long>(dec_.host->max(static_cast<double>(most)));
  if (agreed > dec_.migrant_capacity) dec_.migrant_capacity = static_cast<int>(2 * agreed);
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
  mine[kMigrants] = dec_.migrant_most;
  for (int b = 0; b < nb; ++b)
    for (int k = 0; k < kFailKinds; ++k) {
      mine[static_cast<std::size_t>(kFixed + kFailKinds * b + k)] = body_stats_[b].failures[k];
      mine[static_cast<std::size_t>(kFixed + kFailKinds * (nb + b) + k)] = body_stats_[b].first_id[k];
    }
  comm::Bytes packed(mine.size() * sizeof(long long));
  std::memcpy(packed.data(), mine.data(), packed.size());
  const std::vector<comm::Bytes> all = dec_.host->allgather(packed);
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
  dec_.halo_grew = agreed[kHaloNew] > 0;  // stats_->halo_new stays this rank's: rebuild_halo sends those
  stats_->max_speed_sq = static_cast<unsigned long long>(agreed[kSpeed]);
  dec_.most_rank_particles = static_cast<double>(agreed[kParticles]);
  dec_.migrant_most = static_cast<int>(agreed[kMigrants]);
  for (int b = 0; b < nb; ++b)
    for (int k = 0; k < kFailKinds; ++k) {
      body_stats_[b].failures[k] = static_cast<int>(agreed[static_cast<std::size_t>(kFixed + kFailKinds * b + k)]);
      body_stats_[b].first_id[k] =
          static_cast<int>(agreed[static_cast<std::size_t>(kFixed + kFailKinds * (nb + b) + k)]);
    }
}

}  // namespace fbar
