// Slab decomposition (comm/slab_partition.h): cuts follow the particles (equal counts per rank to within one plane),
// every plane has exactly one owner, slabs keep their minimum width, and impossible splits are refused by name.
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <numeric>
#include <string>
#include <vector>

#include "comm/slab_partition.h"
#include "geometry/geometry.h"
#include "scene/scene.h"

namespace fbar::comm {
namespace {

/// The sampling count of a box body of 8 ppc at dx (what the engines partition at start).
SampleCount box_count(Real3 offset, Real3 span, double dx = 0.01) {
  SimulationSpec sim;
  sim.domain = {4.0, 4.0, 4.0};
  sim.dx = dx;
  BodySpec body;
  body.material.ppc = 8;
  GeometrySpec g;
  g.object = GeometryObject::Box;
  g.offset = offset;
  g.span = span;
  body.geometry.push_back(g);
  return BodySampler(body, sim, 0).count(dx);
}

TEST(SlabPartition, UniformBoxSplitsEquallyAlongItsLongestAxis) {
  // 1.2 m along y, 0.4 m along x and z: y slabs; 4 cells per block -> 30 planes of equal counts.
  const SampleCount c = box_count({0.2, 0.2, 0.2}, {0.4, 1.2, 0.4});
  const PlaneCounts planes = plane_counts({&c});
  EXPECT_EQ(planes.axis, 1);
  EXPECT_EQ(planes.total(), c.particles);
  const long long largest_plane = *std::max_element(planes.counts.begin(), planes.counts.end());
  for (int ranks : {1, 2, 3, 4, 7}) {
    const SlabPartition s = choose_slabs(planes, ranks);
    ASSERT_EQ(s.ranks(), ranks);
    const std::vector<long long> per_rank = rank_counts(s, planes);
    EXPECT_EQ(std::accumulate(per_rank.begin(), per_rank.end(), 0LL), c.particles);
    const double mean = static_cast<double>(c.particles) / ranks;
    for (long long n : per_rank) EXPECT_LE(std::abs(static_cast<double>(n) - mean), largest_plane) << s.describe();
    EXPECT_LE(imbalance(per_rank), static_cast<double>(largest_plane) / mean + 1e-12);
  }
}

TEST(SlabPartition, CutsFollowTheParticlesNotTheDomain) {
  // A dense column at the left end and a thin layer along the floor: half the particles are in the column, so the
  // 2-rank cut lies inside the column's planes, far left of the middle of the active region.
  const SampleCount column = box_count({0.1, 0.1, 0.1}, {0.4, 0.8, 0.2});
  const SampleCount layer = box_count({0.5, 0.1, 0.1}, {2.4, 0.04, 0.2});
  const PlaneCounts planes = plane_counts({&column, &layer});
  ASSERT_EQ(planes.axis, 0);
  const SlabPartition s = choose_slabs(planes, 2);
  const int middle = planes.first + static_cast<int>(planes.counts.size()) / 2;
  EXPECT_LT(s.cuts[1], middle);
  const std::vector<long long> per_rank = rank_counts(s, planes);
  const long long largest_plane = *std::max_element(planes.counts.begin(), planes.counts.end());
  EXPECT_LE(std::llabs(per_rank[0] - per_rank[1]), 2 * largest_plane);
}

TEST(SlabPartition, EveryPlaneHasOneOwnerAndHalosAreTheCuts) {
  const SampleCount c = box_count({0.2, 0.2, 0.2}, {2.0, 0.3, 0.3});
  const PlaneCounts planes = plane_counts({&c});
  const SlabPartition s = choose_slabs(planes, 3);
  EXPECT_EQ(s.cuts.front(), INT_MIN);
  EXPECT_EQ(s.cuts.back(), INT_MAX);
  int previous = 0;
  for (int b = planes.first - 5; b < planes.first + static_cast<int>(planes.counts.size()) + 5; ++b) {
    const int r = s.owner(b);
    ASSERT_GE(r, 0);
    ASSERT_LT(r, 3);
    EXPECT_GE(r, previous) << "owners must not decrease along the axis";
    EXPECT_TRUE(s.cuts[r] <= b && b < s.cuts[r + 1]) << b;
    previous = r;
  }
  // Rank r scatters into its planes and one beyond: the plane it shares with r + 1 is that rank's first plane.
  for (int r = 0; r + 1 < 3; ++r) {
    EXPECT_EQ(s.owner(s.halo_plane(r)), r + 1);
    EXPECT_EQ(s.owner(s.halo_plane(r) - 1), r);
  }
  EXPECT_EQ(s.owner(0, 9999, -9999), s.owner(0));  // only the axis coordinate decides
}

TEST(SlabPartition, SlabsKeepTheirMinimumWidth) {
  // Nearly every particle in one plane: equal counts would give empty slabs; min_planes keeps each at 2 planes.
  PlaneCounts planes;
  planes.axis = 2;
  planes.first = -3;
  planes.counts = {1, 1, 1000000, 1, 1, 1, 1, 1};
  const SlabPartition s = choose_slabs(planes, 4, 2);
  for (int r = 0; r < 4; ++r) {
    const int lo = r == 0 ? planes.first : s.cuts[r];
    const int hi = r == 3 ? planes.first + 8 : s.cuts[r + 1];
    EXPECT_GE(hi - lo, 2) << s.describe();
  }
  EXPECT_GT(imbalance(rank_counts(s, planes)), 2.0);  // the counts say so, for the log and the rebalance
}

TEST(SlabPartition, RefusesMoreRanksThanPlanes) {
  PlaneCounts planes;
  planes.counts = {10, 10, 10};
  try {
    choose_slabs(planes, 4);
    FAIL() << "4 ranks over 3 planes must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("3 block planes"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("fewer GPUs"), std::string::npos) << e.what();
  }
}

// Work placed whole on a rank (a mesh, a placed body: comm/placement.h placed_work) is a preload: the cuts even out
// preload + slab count (100 planes of 10 particles: rank 1 holding 500 takes 250 of the 1,000, rank 0 750), and a
// rank whose preload exceeds the even share keeps only its minimum width.
TEST(SlabPartition, PreloadedRanksTakeFewerParticles) {
  PlaneCounts planes;
  planes.axis = 0;
  planes.first = 3;
  planes.counts.assign(100, 10);
  const std::vector<long long> one = rank_counts(choose_slabs(planes, 2, 1, {0, 500}), planes);
  EXPECT_EQ(one, (std::vector<long long>{750, 250}));
  const std::vector<long long> three = rank_counts(choose_slabs(planes, 3, 1, {0, 0, 400}), planes);
  EXPECT_EQ(three, (std::vector<long long>{470, 470, 60}));  // level (1000 + 400) / 3 = 466.7, whole planes
  const SlabPartition heavy = choose_slabs(planes, 2, 2, {5000, 0});
  EXPECT_EQ(rank_counts(heavy, planes), (std::vector<long long>{20, 980}));  // min_planes 2
  EXPECT_EQ(choose_slabs(planes, 2, 1, {0, 0}).cuts, choose_slabs(planes, 2).cuts);  // no preload: as before
}

TEST(SlabPartition, ImbalanceIsMaxOverMeanMinusOne) {
  EXPECT_DOUBLE_EQ(imbalance({100, 100}), 0.0);
  EXPECT_DOUBLE_EQ(imbalance({150, 50}), 0.5);
  EXPECT_DOUBLE_EQ(imbalance({0, 0, 0}), 0.0);
  EXPECT_DOUBLE_EQ(imbalance({}), 0.0);
}

}  // namespace
}  // namespace fbar::comm
