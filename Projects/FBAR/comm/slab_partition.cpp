// Slab decomposition (slab_partition.h).
#include "comm/slab_partition.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace fbar::comm {

int SlabPartition::owner(int b) const {
  // cuts is sorted; the owner is the last r with cuts[r] <= b.
  const auto it = std::upper_bound(cuts.begin() + 1, cuts.end() - 1, b);
  return static_cast<int>(it - cuts.begin()) - 1;
}

std::string SlabPartition::describe() const {
  std::ostringstream os;
  os << "xyz"[axis] << " slabs at block planes";
  for (int r = 1; r < ranks(); ++r) os << (r == 1 ? " " : ", ") << cuts[r];
  if (ranks() == 1) os << " (one rank)";
  return os.str();
}

long long PlaneCounts::total() const { return std::accumulate(counts.begin(), counts.end(), 0LL); }

PlaneCounts plane_counts(const std::vector<const SampleCount*>& counts) {
  int lo[3] = {INT_MAX, INT_MAX, INT_MAX}, hi[3] = {INT_MIN, INT_MIN, INT_MIN};
  for (const SampleCount* c : counts)
    for (const BlockCount& b : c->blocks) {
      const int v[3] = {b.bx, b.by, b.bz};
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], v[a]);
        hi[a] = std::max(hi[a], v[a]);
      }
    }
  PlaneCounts p;
  if (lo[0] > hi[0]) return p;  // no particles
  p.axis = longest_axis(lo, hi);
  p.first = lo[p.axis];
  p.counts.assign(static_cast<std::size_t>(hi[p.axis] - lo[p.axis] + 1), 0);
  for (const SampleCount* c : counts)
    for (const BlockCount& b : c->blocks) {
      const int v = p.axis == 0 ? b.bx : p.axis == 1 ? b.by : b.bz;
      p.counts[static_cast<std::size_t>(v - p.first)] += b.particles;
    }
  return p;
}

SlabPartition choose_slabs(const PlaneCounts& planes, int ranks, int min_planes, const std::vector<long long>& preload) {
  if (ranks < 1) throw std::invalid_argument("choose_slabs: ranks must be at least 1");
  min_planes = std::max(1, min_planes);
  const int n = static_cast<int>(planes.counts.size());
  SlabPartition s;
  s.axis = planes.axis;
  s.cuts.assign(static_cast<std::size_t>(ranks) + 1, 0);
  s.cuts.front() = INT_MIN;
  s.cuts.back() = INT_MAX;
  if (ranks == 1) return s;
  if (n < ranks * min_planes)
    throw std::invalid_argument("the particles span " + std::to_string(n) + " block planes along " +
                                std::string(1, "xyz"[planes.axis]) + ", fewer than " + std::to_string(ranks) +
                                " ranks x " + std::to_string(min_planes) + " planes: use fewer GPUs");
  const long long total = planes.total();
  // The spread particles each rank should take: total / ranks, or with a preload the water level T with
  // sum_r max(0, T - preload_r) = total (ranks above it take none).
  const bool preloaded = std::any_of(preload.begin(), preload.end(), [](long long w) { return w > 0; });
  const auto preload_of = [&](int r) {
    return r < static_cast<int>(preload.size()) ? static_cast<double>(preload[static_cast<std::size_t>(r)]) : 0.0;
  };
  std::vector<double> share(static_cast<std::size_t>(ranks), 0.0);
  if (preloaded) {
    // The level falls as ranks above it drop out, so a rank that dropped out stays out.
    std::vector<bool> active(static_cast<std::size_t>(ranks), true);
    for (bool changed = true; changed;) {
      changed = false;
      double sum = static_cast<double>(total);
      int count = 0;
      for (int r = 0; r < ranks; ++r)
        if (active[static_cast<std::size_t>(r)]) {
          sum += preload_of(r);
          ++count;
        }
      const double level = sum / count;
      for (int r = 0; r < ranks; ++r) {
        const bool on = active[static_cast<std::size_t>(r)] && preload_of(r) < level;
        if (active[static_cast<std::size_t>(r)] && !on) {
          active[static_cast<std::size_t>(r)] = false;
          changed = true;
        }
        share[static_cast<std::size_t>(r)] = on ? level - preload_of(r) : 0.0;
      }
    }
  }
  // Plane index (0-based) where rank r starts: the first plane whose preceding sum reaches the shares of the ranks
  // before it, then moved so that every slab keeps min_planes planes on both sides.
  std::vector<int> start(static_cast<std::size_t>(ranks) + 1, 0);
  start[ranks] = n;
  long long running = 0;
  int plane = 0;
  double before = 0.0;
  for (int r = 1; r < ranks; ++r) {
    before += share[static_cast<std::size_t>(r - 1)];
    const long long target = preloaded ? static_cast<long long>(std::ceil(before))
                                       : (total * r + ranks - 1) / ranks;  // ceil(total r / ranks)
    while (plane < n && running < target) running += planes.counts[static_cast<std::size_t>(plane++)];
    start[r] = plane;
  }
  for (int r = 1; r < ranks; ++r) start[r] = std::max(start[r], start[r - 1] + min_planes);
  for (int r = ranks - 1; r >= 1; --r) start[r] = std::min(start[r], start[r + 1] - min_planes);
  for (int r = 1; r < ranks; ++r) s.cuts[r] = planes.first + start[r];
  return s;
}

std::vector<long long> rank_counts(const SlabPartition& partition, const PlaneCounts& planes) {
  std::vector<long long> per_rank(static_cast<std::size_t>(partition.ranks()), 0);
  for (std::size_t i = 0; i < planes.counts.size(); ++i)
    per_rank[static_cast<std::size_t>(partition.owner(planes.first + static_cast<int>(i)))] += planes.counts[i];
  return per_rank;
}

double imbalance(const std::vector<long long>& per_rank) {
  if (per_rank.empty()) return 0.0;
  const long long total = std::accumulate(per_rank.begin(), per_rank.end(), 0LL);
  if (total == 0) return 0.0;
  const long long most = *std::max_element(per_rank.begin(), per_rank.end());
  return static_cast<double>(most) * static_cast<double>(per_rank.size()) / static_cast<double>(total) - 1.0;
}

}  // namespace fbar::comm
