// Spatial decomposition of the particles over ranks (GPUs): slabs of particle blocks along one axis.
//
// A particle belongs to its engine's particle block B, whose 2x2x2 footprint of grid blocks B..B+1 holds the 27-node
// stencil of every particle in it (CPU engine: B = floor(base / 4); GPU engine: floor((base - 1) / 4) for its
// off-by-2 arena, geometry.h particle_block(); base = floor(x/dx - 0.5)). Rank r owns the particle blocks whose coordinate along `axis` lies in
// [cuts[r], cuts[r + 1]); its particles touch the grid blocks of [cuts[r], cuts[r + 1]] along the axis, i.e. its own
// planes and one plane beyond its upper cut. That plane (cuts[r + 1]) is the halo between ranks r and r + 1: both
// scatter into it, and after P2G each adds the other's sums (a + b = b + a: both hold the same values, bit for bit).
// With every slab at least one plane wide no grid block is shared by three ranks. A particle whose block leaves the
// slab after G2P migrates to the owner of its new block.
//
// The cuts are chosen at start from the particle distribution (equal particle counts per rank, along the axis of
// the largest extent of the active region) and again when the counts per rank drift apart (imbalance()).
#pragma once

#include <climits>
#include <string>
#include <vector>

#include "geometry/geometry.h"

namespace fbar::comm {

struct SlabPartition {
  int axis = 0;           ///< 0 x, 1 y, 2 z
  std::vector<int> cuts;  ///< ranks + 1 block coordinates; cuts.front() = INT_MIN, cuts.back() = INT_MAX

  int ranks() const { return static_cast<int>(cuts.size()) - 1; }
  /// The rank owning particle block coordinate `b` along the axis.
  int owner(int b) const;
  /// The rank owning particle block (bx, by, bz).
  int owner(int bx, int by, int bz) const { return owner(axis == 0 ? bx : axis == 1 ? by : bz); }
  /// The grid-block plane rank r shares with rank r + 1 (r + 1 < ranks()).
  int halo_plane(int r) const { return cuts[r + 1]; }
  /// "x slabs: ... | 12 | 25 | ..." for logs.
  std::string describe() const;
};

/// Particles per particle-block plane along `axis` of every body's count (first: the lowest plane with particles).
struct PlaneCounts {
  int axis = 0;
  int first = 0;                  ///< block coordinate of counts[0]
  std::vector<long long> counts;  ///< particles per plane
  long long total() const;
};
/// The axis of the largest extent of the block range [lo, hi] (ties: x, then y, then z).
template <typename V>
int longest_axis(const V (&lo)[3], const V (&hi)[3]) {
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
  return axis;
}

/// The planes of `counts` along the axis of their largest extent (in blocks; ties: x, then y, then z).
PlaneCounts plane_counts(const std::vector<const SampleCount*>& counts);

/// Cuts for `ranks` slabs with particle counts as equal as whole planes allow (each cut at the first plane where
/// the running count reaches r / ranks of the total), every slab at least `min_planes` planes wide. Throws
/// std::invalid_argument when the active region has fewer than ranks x min_planes planes (the message names both).
/// preload[r] (empty: none): work rank r holds besides its slab (bodies placed whole on it, placed_work in
/// comm/placement.h); the slabs then even out preload + slab count instead (water-filling: a rank whose preload
/// exceeds the even share gets no more than its min_planes planes).
SlabPartition choose_slabs(const PlaneCounts& planes, int ranks, int min_planes = 1,
                           const std::vector<long long>& preload = {});

/// Particles of each rank under `partition`.
std::vector<long long> rank_counts(const SlabPartition& partition, const PlaneCounts& planes);

/// max / mean - 1 of the counts per rank (0: perfectly balanced; 0 for no particles).
double imbalance(const std::vector<long long>& per_rank);

}  // namespace fbar::comm
