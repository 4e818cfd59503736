// Tests of body sampling (geometry.h): exact lattice counts, volume bounds, CSG, rotation, arrays, clip, jitter.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include "geometry/geometry.h"
#include "scene/scene_error.h"

namespace fbar {
namespace {

constexpr double kPi = 3.14159265358979323846;

SimulationSpec make_sim(double dx, Real3 domain = {2.0, 2.0, 2.0}, std::uint64_t seed = 0) {
  SimulationSpec s;
  s.dx = dx;
  s.domain = domain;
  s.seed = seed;
  return s;
}

GeometrySpec make_box(Real3 offset, Real3 span, GeometryOperation op = GeometryOperation::Add) {
  GeometrySpec g;
  g.object = GeometryObject::Box;
  g.operation = op;
  g.offset = offset;
  g.span = span;
  return g;
}

GeometrySpec make_sphere(Real3 offset, double radius) {
  GeometrySpec g;
  g.object = GeometryObject::Sphere;
  g.offset = offset;
  g.radius = radius;
  return g;
}

GeometrySpec make_cylinder(Real3 offset, double radius, int axis, double length) {
  GeometrySpec g;
  g.object = GeometryObject::Cylinder;
  g.offset = offset;
  g.radius = radius;
  g.axis = axis;
  g.span = {0.0, 0.0, 0.0};  // only the length along the axis is used
  g.span[axis] = length;
  return g;
}

BodySpec make_body(std::vector<GeometrySpec> geometry, double ppc) {
  BodySpec b;
  b.geometry = std::move(geometry);
  b.material.ppc = ppc;
  return b;
}

Aabb bounds_of(const std::vector<Vec3d>& pts) {
  Aabb b{Vec3d::filled(1e300), Vec3d::filled(-1e300)};
  for (const Vec3d& p : pts)
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = std::min(b.lo[d], p[d]);
      b.hi[d] = std::max(b.hi[d], p[d]);
    }
  return b;
}

/// The message of the SceneError thrown by f, and its path; fails the test when nothing is thrown.
template <typename F>
std::pair<std::string, std::string> scene_error_of(F&& f) {
  try {
    f();
  } catch (const SceneError& e) {
    return {e.path(), e.what()};
  }
  ADD_FAILURE() << "no SceneError thrown";
  return {};
}

TEST(SamplingPattern, PerfectCubesAreLatticesOthersJitter) {
  for (auto [ppc, n] : std::vector<std::pair<double, int>>{{1, 1}, {8, 2}, {27, 3}, {64, 4}, {125, 5}}) {
    const SamplingPattern p = sampling_pattern(ppc);
    EXPECT_TRUE(p.lattice) << ppc;
    EXPECT_EQ(p.per_axis, n) << ppc;
  }
  // HydroUQ's 27.000001 (ClaymoreUW's YIELD and DKT_2D scenes) is ClaymoreUW's lattice of spacing dx / 3.
  for (double ppc : {27.000001, 26.99999}) {
    EXPECT_TRUE(sampling_pattern(ppc).lattice) << ppc;
    EXPECT_EQ(sampling_pattern(ppc).per_axis, 3) << ppc;
  }
  for (double ppc : {2.0, 4.0, 5.0, 9.0, 8.5, 0.5, 27.001, 7.99}) EXPECT_FALSE(sampling_pattern(ppc).lattice) << ppc;
  EXPECT_THROW(sampling_pattern(0.0), std::invalid_argument);
  EXPECT_THROW(sampling_pattern(-8.0), std::invalid_argument);
}

// A grid-aligned box holds exactly (cells) * ppc lattice points: no tolerance, the count is an integer identity.
TEST(SampleBody, LatticeBoxExactCountAndPositions) {
  const SimulationSpec sim = make_sim(0.05);
  const BodySpec body = make_body({make_box({0.1, 0.2, 0.3}, {1.0, 0.5, 0.25})}, 8);
  const std::vector<Vec3d> pts = sample_body(body, sim, 0);
  ASSERT_EQ(pts.size(), std::size_t(20 * 10 * 5 * 8));
  const double h = 0.025;  // dx / 2
  for (const Vec3d& p : pts)
    for (int d = 0; d < 3; ++d) {
      const double i = p[d] / h - 0.5;  // cell-centred sub-lattice: integer
      ASSERT_NEAR(i, std::round(i), 1e-9);
    }
  const Aabb b = bounds_of(pts);
  const Vec3d lo{{0.1, 0.2, 0.3}}, hi{{1.1, 0.7, 0.55}};
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(b.lo[d], lo[d] + h / 2, 1e-12);
    EXPECT_NEAR(b.hi[d], hi[d] - h / 2, 1e-12);
  }
}

TEST(SampleBody, LatticeCountForEveryCubicPpc) {
  const SimulationSpec sim = make_sim(0.1);
  for (double ppc : {1.0, 8.0, 27.0, 64.0}) {
    const BodySpec body = make_body({make_box({0.2, 0.3, 0.4}, {0.4, 0.3, 0.2})}, ppc);
    EXPECT_EQ(sample_body(body, sim, 0).size(), std::size_t(4 * 3 * 2 * ppc)) << "ppc " << ppc;
  }
}

// Each lattice point owns the cube of edge h centred on it; the cubes tile space. With delta = h sqrt(3)/2 (half
// the cube diagonal), the cubes of the points inside a ball of radius r lie in the ball of radius r + delta, and
// every cube meeting the ball of radius r - delta has its centre inside the ball of radius r. Hence
// V(r - delta) <= N h^3 <= V(r + delta): a rigorous bound, no statistics.
TEST(SampleBody, SphereVolumeWithinLatticeBound) {
  const double dx = 0.01, h = dx / 2, r = 0.2;
  const SimulationSpec sim = make_sim(dx, {1.0, 1.0, 1.0});
  // offset = min corner of the bounding box, so the centre is (0.5, 0.5, 0.5), a symmetry point of the lattice.
  const std::vector<Vec3d> pts = sample_body(make_body({make_sphere({0.3, 0.3, 0.3}, r)}, 8), sim, 0);
  const double delta = h * std::sqrt(3.0) / 2;
  const double v = 4.0 / 3.0 * kPi * r * r * r;
  const double sampled = pts.size() * h * h * h;
  EXPECT_GE(sampled, 4.0 / 3.0 * kPi * std::pow(r - delta, 3));
  EXPECT_LE(sampled, 4.0 / 3.0 * kPi * std::pow(r + delta, 3));
  std::printf("sphere r=%g h=%g: N=%zu, N*Vp/V - 1 = %.3e (rigorous bound %.3e)\n", r, h, pts.size(),
              sampled / v - 1.0, std::pow(1 + delta / r, 3) - 1);
  // The centre: the lattice is symmetric about (0.5, 0.5, 0.5), so the centroid is exact up to round-off.
  Vec3d c = Vec3d::zero();
  for (const Vec3d& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(c[d], 0.5, 1e-12);
  const Aabb b = bounds_of(pts);
  for (int d = 0; d < 3; ++d) {
    EXPECT_GE(b.lo[d], 0.3);
    EXPECT_LE(b.lo[d], 0.3 + h);
    EXPECT_LE(b.hi[d], 0.7);
    EXPECT_GE(b.hi[d], 0.7 - h);
  }
}

// The parser's contract (scene_parse.cpp): a sphere is defined by offset and radius, span is not used.
TEST(SampleBody, SphereIgnoresSpan) {
  const SimulationSpec sim = make_sim(0.02, {1.0, 1.0, 1.0});
  const std::size_t full = sample_body(make_body({make_sphere({0.3, 0.3, 0.3}, 0.2)}, 8), sim, 0).size();
  GeometrySpec g = make_sphere({0.3, 0.3, 0.3}, 0.2);
  g.span = {0.1, 0.0, -1.0};
  EXPECT_EQ(sample_body(make_body({g}, 8), sim, 0).size(), full);
}

// Along the axis the count is exact (length / h points); across it the disk bound of the sphere test in 2-D:
// pi (r - h/sqrt2)^2 <= N_disk h^2 <= pi (r + h/sqrt2)^2.
TEST(SampleBody, CylinderAlongEachAxis) {
  const double dx = 0.02, h = dx / 2, r = 0.15, length = 0.4;
  const SimulationSpec sim = make_sim(dx, {1.0, 1.0, 1.0});
  for (int axis = 0; axis < 3; ++axis) {
    const std::vector<Vec3d> pts =
        sample_body(make_body({make_cylinder({0.2, 0.2, 0.2}, r, axis, length)}, 8), sim, 0);
    const std::size_t along = static_cast<std::size_t>(std::llround(length / h));
    ASSERT_EQ(pts.size() % along, 0u) << "axis " << axis;
    const double disk = static_cast<double>(pts.size() / along) * h * h;
    const double delta = h / std::sqrt(2.0);
    EXPECT_GE(disk, kPi * (r - delta) * (r - delta)) << "axis " << axis;
    EXPECT_LE(disk, kPi * (r + delta) * (r + delta)) << "axis " << axis;
    std::printf("cylinder axis %d: N=%zu, disk area / (pi r^2) - 1 = %.3e\n", axis, pts.size(),
                disk / (kPi * r * r) - 1.0);
    const Aabb b = bounds_of(pts);
    for (int d = 0; d < 3; ++d) {
      const double extent = d == axis ? length : 2 * r;
      EXPECT_NEAR(b.lo[d], 0.2 + h / 2, h) << "axis " << axis << " dim " << d;
      EXPECT_NEAR(b.hi[d], 0.2 + extent - h / 2, h) << "axis " << axis << " dim " << d;
    }
  }
}

// Two grid-aligned 4x4x4-cell boxes overlapping in 2x2x2 cells, ppc 1: every count is exact set arithmetic.
TEST(SampleBody, CsgOperationsCountExactly) {
  using Op = GeometryOperation;
  const SimulationSpec sim = make_sim(0.1, {1.0, 1.0, 1.0});
  auto a = [](Op op) { return make_box({0.1, 0.1, 0.1}, {0.4, 0.4, 0.4}, op); };
  auto b = [](Op op) { return make_box({0.3, 0.3, 0.3}, {0.4, 0.4, 0.4}, op); };
  auto count = [&](std::vector<GeometrySpec> g) { return sample_body(make_body(std::move(g), 1), sim, 0).size(); };
  EXPECT_EQ(count({a(Op::Add)}), 64u);
  EXPECT_EQ(count({a(Op::Add), b(Op::Subtract)}), 56u);
  EXPECT_EQ(count({a(Op::Add), b(Op::Difference)}), 56u);
  EXPECT_EQ(count({a(Op::Add), b(Op::Intersection)}), 8u);
  EXPECT_EQ(count({a(Op::Add), b(Op::Union)}), 120u);
  EXPECT_EQ(count({a(Op::Add), b(Op::Add)}), 120u);
  // Operations apply in order: an Add after a Subtract is not affected by it (seed 0.4.2).
  EXPECT_EQ(count({a(Op::Add), b(Op::Subtract), b(Op::Add)}), 120u);
  // Subtracting from the empty set leaves it empty.
  EXPECT_EQ(count({b(Op::Subtract), a(Op::Add)}), 64u);
  // Intersection first: empty body, an error naming the geometry.
  const auto [path, what] = scene_error_of([&] { count({a(Op::Intersection)}); });
  EXPECT_EQ(path, "bodies[0].geometry");
  EXPECT_NE(what.find("0 particles"), std::string::npos) << what;
  // A sphere subtracted from a box: the box count minus the points inside the sphere, which we count directly.
  GeometrySpec hole = make_sphere({0.2, 0.2, 0.2}, 0.15);
  hole.operation = Op::Subtract;
  const BodySpec holed = make_body({make_box({0.1, 0.1, 0.1}, {0.4, 0.4, 0.4}), hole}, 8);
  const std::vector<Vec3d> pts = sample_body(holed, make_sim(0.02, {1.0, 1.0, 1.0}), 0);
  std::size_t in_sphere = 0;
  const double h = 0.01;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j)
      for (int k = 0; k < 40; ++k) {
        const double x = 0.1 + (i + 0.5) * h - 0.35, y = 0.1 + (j + 0.5) * h - 0.35, z = 0.1 + (k + 0.5) * h - 0.35;
        if (x * x + y * y + z * z <= 0.15 * 0.15) ++in_sphere;
      }
  EXPECT_EQ(pts.size(), 40u * 40u * 40u - in_sphere);
  for (const Vec3d& p : pts) ASSERT_GT(norm_squared(p - Vec3d::filled(0.35)), 0.15 * 0.15);
}

// A bed object subtracted cuts the body by the ground, as ClaymoreUW's subtract_bathymetry does: ClaymoreUW's own
// scene.json carves a 2 x 1.5 x 3.5 m box (dx 0.1, ppc 8: 84,000 points) by a bed through (6, 0), (7, 0.25),
// (8, 0.75); the ground under it holds (0.125 + 0.5) m^2 x 3.5 m = 2.1875 m^3 = 17,500 points of 1/8000 m^3, and
// ClaymoreUW keeps 66,500. The bed object's span and offset (its water box when added) play no part.
TEST(SampleBody, SubtractedBathymetryRemovesTheGroundUnderTheBed) {
  const SimulationSpec sim = make_sim(0.1, {8.0, 8.0, 8.0});
  GeometrySpec bed;
  bed.object = GeometryObject::Bathymetry;
  bed.operation = GeometryOperation::Subtract;
  bed.bathymetry = {{0.0, 0.0}, {1.5, 0.5}, {2.5, 1.0}, {3.0, 0.5}, {4.0, 0.0}, {6.0, 0.0}, {7.0, 0.25}, {8.0, 0.75}};
  const std::vector<Vec3d> pts =
      sample_body(make_body({make_box({6.0, 0.0, 3.2}, {2.0, 1.5, 3.5}), bed}, 8), sim, 0);
  EXPECT_EQ(pts.size(), 66500u);
  for (const Vec3d& p : pts) {
    const double ground = p[0] < 7.0 ? 0.25 * (p[0] - 6.0) : 0.25 + 0.5 * (p[0] - 7.0);
    ASSERT_GT(p[1], ground);
  }
}

// Rotations by multiples of 90 deg map the lattice onto itself when the fulcrum is a lattice symmetry point: the
// count is unchanged and the points' bounding box is the rotated box shrunk by h/2, exactly.
Vec3d rotate_x(Vec3d v, double c, double s) { return Vec3d{{v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]}}; }
Vec3d rotate_y(Vec3d v, double c, double s) { return Vec3d{{c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]}}; }
Vec3d rotate_z(Vec3d v, double c, double s) { return Vec3d{{c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]}}; }
int quarter_cos(int deg) { return deg % 360 == 0 ? 1 : std::abs(deg % 360) == 180 ? -1 : 0; }
int quarter_sin(int deg) {
  const int m = ((deg % 360) + 360) % 360;
  return m == 90 ? 1 : m == 270 ? -1 : 0;
}

TEST(SampleBody, QuarterTurnRotationsMapTheBoundingBox) {
  const double dx = 0.1, h = dx / 2;
  const SimulationSpec sim = make_sim(dx, {1.0, 1.0, 1.0});
  const Vec3d lo{{0.2, 0.3, 0.35}}, span{{0.4, 0.2, 0.1}}, fulcrum{{0.45, 0.45, 0.45}};
  const std::size_t unrotated = 4 * 2 * 1 * 8;  // 4 x 2 x 1 cells of ppc 8
  for (auto [ax, ay, az] : std::vector<std::tuple<int, int, int>>{
           {90, 0, 0}, {0, 90, 0}, {0, 0, 90}, {0, 0, -90}, {180, 0, 0}, {90, 90, 0}, {0, 90, 90}, {90, 0, 270}}) {
    GeometrySpec g = make_box({lo[0], lo[1], lo[2]}, {span[0], span[1], span[2]});
    g.rotate = {double(ax), double(ay), double(az)};
    g.fulcrum = {fulcrum[0], fulcrum[1], fulcrum[2]};
    const std::vector<Vec3d> pts = sample_body(make_body({g}, 8), sim, 0);
    EXPECT_EQ(pts.size(), unrotated) << ax << " " << ay << " " << az;
    // Expected box: corners rotated about X, then Y, then Z (world axes) about the fulcrum.
    Aabb want{Vec3d::filled(1e300), Vec3d::filled(-1e300)};
    for (int c = 0; c < 8; ++c) {
      Vec3d v{{(c & 1) ? lo[0] + span[0] : lo[0], (c & 2) ? lo[1] + span[1] : lo[1],
               (c & 4) ? lo[2] + span[2] : lo[2]}};
      v = v - fulcrum;
      v = rotate_x(v, quarter_cos(ax), quarter_sin(ax));
      v = rotate_y(v, quarter_cos(ay), quarter_sin(ay));
      v = rotate_z(v, quarter_cos(az), quarter_sin(az));
      v = v + fulcrum;
      for (int d = 0; d < 3; ++d) {
        want.lo[d] = std::min(want.lo[d], v[d]);
        want.hi[d] = std::max(want.hi[d], v[d]);
      }
    }
    const Aabb got = bounds_of(pts);
    for (int d = 0; d < 3; ++d) {
      EXPECT_NEAR(got.lo[d], want.lo[d] + h / 2, 1e-12) << ax << " " << ay << " " << az << " dim " << d;
      EXPECT_NEAR(got.hi[d], want.hi[d] - h / 2, 1e-12) << ax << " " << ay << " " << az << " dim " << d;
    }
  }
}

// A 45 deg turn is not lattice-aligned: the count obeys the cube-covering bound of the sphere test, for a box
// (a - 2 delta)(b - 2 delta)(c - 2 delta) <= N h^3 <= V + S delta + pi (a + b + c) delta^2 + 4/3 pi delta^3
// (Steiner's formula for the box grown by delta = h sqrt(3)/2), and every point maps back into the box.
TEST(SampleBody, FortyFiveDegreeRotationKeepsVolume) {
  const double dx = 0.02, h = dx / 2, a = 0.4, b = 0.2, c = 0.1;
  const SimulationSpec sim = make_sim(dx, {1.0, 1.0, 1.0});
  GeometrySpec g = make_box({0.3, 0.4, 0.45}, {a, b, c});
  g.rotate = {0.0, 0.0, 45.0};
  g.fulcrum = {0.5, 0.5, 0.5};
  const std::vector<Vec3d> pts = sample_body(make_body({g}, 8), sim, 0);
  const double delta = h * std::sqrt(3.0) / 2;
  const double sampled = pts.size() * h * h * h;
  EXPECT_GE(sampled, (a - 2 * delta) * (b - 2 * delta) * (c - 2 * delta));
  EXPECT_LE(sampled, a * b * c + 2 * (a * b + b * c + c * a) * delta + kPi * (a + b + c) * delta * delta +
                         4.0 / 3.0 * kPi * delta * delta * delta);
  std::printf("box rotated 45 deg: N*Vp/V - 1 = %.3e\n", sampled / (a * b * c) - 1.0);
  const double cs = std::sqrt(0.5);
  for (const Vec3d& p : pts) {
    const double x = 0.5 + cs * (p[0] - 0.5) + cs * (p[1] - 0.5), y = 0.5 - cs * (p[0] - 0.5) + cs * (p[1] - 0.5);
    ASSERT_GE(x, 0.3 - 1e-12);
    ASSERT_LE(x, 0.7 + 1e-12);
    ASSERT_GE(y, 0.4 - 1e-12);
    ASSERT_LE(y, 0.6 + 1e-12);
  }
}

TEST(SampleBody, ArrayCopiesAreTranslatedCopies) {
  const SimulationSpec sim = make_sim(0.05, {1.0, 1.0, 1.0});
  GeometrySpec g = make_box({0.1, 0.1, 0.1}, {0.1, 0.1, 0.1});
  g.array = {3, 2, 1};
  g.spacing = {0.2, 0.3, 0.0};
  const std::vector<Vec3d> pts = sample_body(make_body({g}, 8), sim, 0);
  ASSERT_EQ(pts.size(), 6u * 64u);
  std::map<std::pair<int, int>, int> per_copy;
  for (const Vec3d& p : pts) {
    const int a = static_cast<int>(std::floor((p[0] - 0.1) / 0.2));
    const int b = static_cast<int>(std::floor((p[1] - 0.1) / 0.3));
    ASSERT_LE(p[0] - 0.1 - 0.2 * a, 0.1);  // inside copy (a, b), not in the gap
    ASSERT_LE(p[1] - 0.1 - 0.3 * b, 0.1);
    ++per_copy[{a, b}];
  }
  ASSERT_EQ(per_copy.size(), 6u);
  for (const auto& [key, n] : per_copy) EXPECT_EQ(n, 64) << key.first << "," << key.second;

  // Overlapping copies (spacing < span) are a union: [0.1, 0.5] along x holds 4 cells, not 3 x 2.
  GeometrySpec overlap = make_box({0.1, 0.1, 0.1}, {0.2, 0.1, 0.1});
  overlap.array = {3, 1, 1};
  overlap.spacing = {0.1, 0.0, 0.0};
  EXPECT_EQ(sample_body(make_body({overlap}, 1), make_sim(0.1, {1.0, 1.0, 1.0}), 0).size(), 4u);
}

TEST(SampleBody, PartitionClipsTheBody) {
  const SimulationSpec sim = make_sim(0.1, {1.0, 1.0, 1.0});
  BodySpec body = make_body({make_box({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0})}, 8);
  EXPECT_EQ(sample_body(body, sim, 0).size(), 8000u);
  body.partition_end = {0.5, 1.0, 1.0};
  EXPECT_EQ(sample_body(body, sim, 0).size(), 4000u);
  body.partition_start = {0.0, 0.25, 0.0};  // lattice y = 0.025 + 0.05 k: 15 of 20 planes have y >= 0.25
  const std::vector<Vec3d> pts = sample_body(body, sim, 0);
  EXPECT_EQ(pts.size(), 3000u);
  for (const Vec3d& p : pts) {
    ASSERT_LE(p[0], 0.5);
    ASSERT_GE(p[1], 0.25);
  }
  // A body reaching outside the domain by less than 8 cells (0.8 m here) is kept whole (x = 0.55 .. 1.45).
  BodySpec wide = make_body({make_box({0.5, 0.0, 0.0}, {1.0, 0.5, 0.5})}, 1);
  EXPECT_EQ(sample_body(wide, sim, 0).size(), 10u * 5u * 5u);
  wide.partition_end = {0.8, 1.0, 1.0};  // x = 0.55, 0.65, 0.75
  EXPECT_EQ(sample_body(wide, sim, 0).size(), 3u * 5u * 5u);
}

// A body split between two GPUs at a plane through lattice points (x = 0.45 = 4.5 dx, ppc 1): the half-open
// partition [start, end) gives every point to exactly one of the two halves.
TEST(SampleBody, SplitPartitionsShareNoPoint) {
  const SimulationSpec sim = make_sim(0.1, {1.0, 1.0, 1.0});
  BodySpec left = make_body({make_box({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0})}, 1), right = left;
  const std::size_t total = sample_body(left, sim, 0).size();
  left.partition_end = {0.45, 1.0, 1.0};
  right.partition_start = {0.45, 0.0, 0.0};
  const std::size_t a = sample_body(left, sim, 0).size(), b = sample_body(right, sim, 1).size();
  EXPECT_EQ(a + b, total);
  EXPECT_EQ(a, 400u);  // x = 0.05 .. 0.35
}

std::map<std::tuple<long, long, long>, int> per_cell(const std::vector<Vec3d>& pts, double dx) {
  std::map<std::tuple<long, long, long>, int> cells;
  for (const Vec3d& p : pts)
    ++cells[{std::lround(std::floor(p[0] / dx)), std::lround(std::floor(p[1] / dx)),
             std::lround(std::floor(p[2] / dx))}];
  return cells;
}

TEST(SampleBody, JitterIsDeterministicAndFillsEveryCell) {
  const double dx = 0.1;
  const BodySpec body = make_body({make_box({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0})}, 5);
  const std::vector<Vec3d> a = sample_body(body, make_sim(dx, {1.0, 1.0, 1.0}, 42), 0);
  ASSERT_EQ(a.size(), 5000u);
  const auto cells = per_cell(a, dx);
  ASSERT_EQ(cells.size(), 1000u);
  for (const auto& [cell, n] : cells) ASSERT_EQ(n, 5);

  // Same seed: bitwise identical, whatever the thread count.
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const std::vector<Vec3d> serial = sample_body(body, make_sim(dx, {1.0, 1.0, 1.0}, 42), 0);
  omp_set_num_threads(std::max(2, threads));
  const std::vector<Vec3d> parallel = sample_body(body, make_sim(dx, {1.0, 1.0, 1.0}, 42), 0);
  omp_set_num_threads(threads);
  ASSERT_EQ(serial.size(), a.size());
  ASSERT_EQ(parallel.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_TRUE(serial[i] == a[i]) << i;
    ASSERT_TRUE(parallel[i] == a[i]) << i;
  }

  // Another seed, or another body with the same seed: different points.
  for (const std::vector<Vec3d>& other :
       {sample_body(body, make_sim(dx, {1.0, 1.0, 1.0}, 43), 0),
        sample_body(body, make_sim(dx, {1.0, 1.0, 1.0}, 42), 1)}) {
    ASSERT_EQ(other.size(), a.size());
    std::size_t same = 0;
    for (std::size_t i = 0; i < a.size(); ++i) same += other[i] == a[i];
    EXPECT_EQ(same, 0u);
  }

  // Uniform in the cell: the mean of the 15000 in-cell coordinates is 1/2 with standard deviation
  // sqrt(1/12 / 15000) = 2.4e-3; 5 sigma = 0.012 (a false failure has probability < 1e-6).
  double mean = 0.0;
  for (const Vec3d& p : a)
    for (int d = 0; d < 3; ++d) mean += p[d] / dx - std::floor(p[d] / dx);
  mean /= 3.0 * a.size();
  EXPECT_NEAR(mean, 0.5, 0.012);
}

// ppc 2.5: every cell holds 2 or 3 points; the total is 2000 + Binomial(1000, 1/2): mean 2500, sigma 15.8.
TEST(SampleBody, FractionalPpcJittersTheCount) {
  const double dx = 0.1;
  const std::vector<Vec3d> pts =
      sample_body(make_body({make_box({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0})}, 2.5), make_sim(dx, {1.0, 1.0, 1.0}, 7), 0);
  EXPECT_NEAR(static_cast<double>(pts.size()), 2500.0, 5 * 15.8);
  const auto cells = per_cell(pts, dx);
  EXPECT_EQ(cells.size(), 1000u);
  for (const auto& [cell, n] : cells) ASSERT_TRUE(n == 2 || n == 3) << n;
}

// Particles within kDomainMarginCells (8) cells outside [0, domain] are kept, as ClaymoreUW keeps them in its grid's
// 8-cell margin and as the engines hold them (inside_domain); those beyond it are dropped, and body_drops counts
// them apart from what the partition drops.
TEST(SampleBody, OutsideTheDomainMarginIsDroppedAndCounted) {
  const SimulationSpec sim = make_sim(0.1, {1.0, 1.0, 1.0});  // margin 0.8 m: [-0.8, 1.8] per axis
  // x = 0.85, 0.95, 1.05, 1.15: all within the margin, none dropped.
  const BodySpec near = make_body({make_box({0.8, 0.1, 0.1}, {0.4, 0.1, 0.1})}, 1);
  EXPECT_EQ(sample_body(near, sim, 3).size(), 4u);
  BodyDrops d = body_drops(near, sim, 3);
  EXPECT_EQ(d.particles, 4);
  EXPECT_EQ(d.outside_domain, 0);
  // x = 1.65, 1.75, 1.85, 1.95: two of the four points are beyond x = 1.8.
  const BodySpec body = make_body({make_box({1.6, 0.1, 0.1}, {0.4, 0.1, 0.1})}, 1);
  const std::vector<Vec3d> pts = sample_body(body, sim, 3);
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_NEAR(pts[0][0], 1.65, 1e-12);
  EXPECT_NEAR(pts[1][0], 1.75, 1e-12);
  d = body_drops(body, sim, 3);
  EXPECT_EQ(d.particles, 2);
  EXPECT_EQ(d.outside_domain, 2);
  EXPECT_EQ(d.outside_partition, 0);
  // Below zero too: a box from y = -1.0 to 0.3 keeps y = -0.75 .. 0.25 (11 of 13 planes).
  const BodySpec below = make_body({make_box({0.1, -1.0, 0.1}, {0.1, 1.3, 0.1})}, 1);
  const std::vector<Vec3d> kept = sample_body(below, sim, 0);
  ASSERT_EQ(kept.size(), 11u);
  EXPECT_NEAR(kept.front()[1], -0.75, 1e-12);
  d = body_drops(below, sim, 0);
  EXPECT_EQ(d.outside_domain, 2);
  // The margin is 8 cells of default_dx: with dx = 0.05 (margin 0.4 m, lattice spacing 0.05) the same box keeps
  // y = -0.375 .. 0.275, 14 planes of 2 x 2 points.
  EXPECT_EQ(sample_body(below, make_sim(0.05, {1.0, 1.0, 1.0}), 0).size(), 14u * 2u * 2u);
  // Entirely beyond the margin: no particle remains, an error that names the body's geometry.
  const BodySpec gone = make_body({make_box({-1.2, 0.1, 0.1}, {0.3, 0.1, 0.1})}, 1);
  const auto [path, what] = scene_error_of([&] { sample_body(gone, sim, 2); });
  EXPECT_EQ(path, "bodies[2].geometry");
  EXPECT_NE(what.find("simulation.domain widened by 8 cells of default_dx must contain a sampling point"),
            std::string::npos)
      << what;
}

// ClaymoreUW's inside_partition drops geometry outside [partition_start, partition_end) without a word; body_drops
// counts what fbar drops so that the parser can say so.
TEST(SampleBody, BodyDropsCountsThePartitionClip) {
  const SimulationSpec sim = make_sim(0.1, {1.0, 1.0, 1.0});
  BodySpec body = make_body({make_box({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0})}, 1);  // 1000 points
  BodyDrops d = body_drops(body, sim, 0);
  EXPECT_EQ(d.particles, 1000);
  EXPECT_EQ(d.outside_partition, 0);
  EXPECT_TRUE(d.partition_counted);
  body.partition_end = {0.5, 1.0, 1.0};
  d = body_drops(body, sim, 0);
  EXPECT_EQ(d.particles, 500);
  EXPECT_EQ(d.outside_partition, 500);
  EXPECT_EQ(d.outside_domain, 0);
  // Both clips: a box from x = 1.5 to 2.5 clipped at x < 2.2 by the partition; x = 1.55 .. 1.75 lie within the
  // 8-cell margin (x <= 1.8) and are kept, x = 1.85 .. 2.15 lie in the partition but beyond the margin, x = 2.25 ..
  // 2.45 outside the partition.
  BodySpec both = make_body({make_box({1.5, 0.1, 0.1}, {1.0, 0.1, 0.1})}, 1);
  both.partition_end = {2.2, 1.0, 1.0};
  d = body_drops(both, sim, 0);
  EXPECT_EQ(d.particles, 3);
  EXPECT_EQ(d.outside_domain, 4);
  EXPECT_EQ(d.outside_partition, 3);
}

TEST(SampleBody, InvalidEntriesNameTheirKey) {
  const SimulationSpec sim = make_sim(0.1, {1.0, 1.0, 1.0});
  EXPECT_EQ(scene_error_of([&] { sample_body(make_body({make_sphere({0.1, 0.1, 0.1}, 0.0)}, 8), sim, 1); }).first,
            "bodies[1].geometry[0].radius");
  GeometrySpec file;
  file.object = GeometryObject::File;
  EXPECT_EQ(scene_error_of([&] {
              sample_body(make_body({make_box({0.1, 0.1, 0.1}, {0.1, 0.1, 0.1}), file}, 8), sim, 2);
            }).first,
            "bodies[2].geometry[1].file");
  GeometrySpec arr = make_box({0.1, 0.1, 0.1}, {0.1, 0.1, 0.1});
  arr.array = {1, 0, 1};
  EXPECT_EQ(scene_error_of([&] { sample_body(make_body({arr}, 8), sim, 0); }).first, "bodies[0].geometry[0].array");
  EXPECT_EQ(scene_error_of([&] { sample_body(make_body({make_box({0.1, 0.1, 0.1}, {0.1, -0.1, 0.1})}, 8), sim, 0); })
                .first,
            "bodies[0].geometry[0].span");
  EXPECT_EQ(scene_error_of([&] { sample_body(make_body({make_box({0.1, 0.1, 0.1}, {0.1, 0.1, 0.1})}, 0), sim, 4); })
                .first,
            "bodies[4].material.ppc");
  EXPECT_EQ(scene_error_of([&] { sample_body(make_body({}, 8), sim, 0); }).first, "bodies[0].geometry");
}

// 4 million particles (a 1 x 1 x 0.5 m box, dx = 1 cm, ppc 8): the lattice count is exact at this size (no int
// overflow, no lost plane). The sampling time is printed and recorded (RecordProperty "seconds") as a figure, not
// asserted: a shared CI machine gives it no budget to hold.
TEST(SampleBody, FourMillionParticlesCountIsExact) {
  const SimulationSpec sim = make_sim(0.01, {1.0, 1.0, 1.0});
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Vec3d> pts = sample_body(make_body({make_box({0.0, 0.0, 0.0}, {1.0, 1.0, 0.5})}, 8), sim, 0);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(pts.size(), 4000000u);
  std::printf("sampled %zu particles in %.2f s with %d threads\n", pts.size(), seconds, omp_get_max_threads());
  RecordProperty("seconds", std::to_string(seconds));
}

}  // namespace
}  // namespace fbar

namespace fbar {
namespace {

// The counting pass (what the GPU engine plans with) agrees with sampling: the same particle count, per-plane
// counts that sum to it, and per-block counts equal to grouping the sampled points by block (count_points); the
// batches of planes concatenate to sample_body's output. Lattice (ppc 8) and jitter (ppc 5), with CSG.
TEST(BodySampler, CountAndBatchesAgreeWithSampling) {
  const SimulationSpec sim = make_sim(0.05, {2.0, 1.0, 1.0});
  for (double ppc : {8.0, 5.0}) {
    const BodySpec body = make_body({make_box({0.1, 0.2, 0.15}, {1.3, 0.55, 0.6}), make_sphere({0.4, 0.3, 0.3}, 0.15),
                                     make_box({0.5, 0.3, 0.3}, {0.2, 0.2, 0.2}, GeometryOperation::Subtract)},
                                    ppc);
    const std::vector<Vec3d> all = sample_body(body, sim, 0);
    const BodySampler sampler(body, sim, 0);
    const SampleCount c = sampler.count(sim.dx);
    EXPECT_EQ(c.particles, static_cast<long long>(all.size())) << "ppc " << ppc;
    long long planes = 0;
    for (long long n : c.per_plane) planes += n;
    EXPECT_EQ(planes, c.particles);
    const SampleCount direct = count_points(all, sim.dx);
    ASSERT_EQ(c.blocks.size(), direct.blocks.size());
    for (std::size_t i = 0; i < c.blocks.size(); ++i) {
      EXPECT_EQ(c.blocks[i].bx, direct.blocks[i].bx);
      EXPECT_EQ(c.blocks[i].by, direct.blocks[i].by);
      EXPECT_EQ(c.blocks[i].bz, direct.blocks[i].bz);
      EXPECT_EQ(c.blocks[i].particles, direct.blocks[i].particles);
    }
    std::vector<Vec3d> batched;
    for (long long p = 0; p < sampler.planes(); p += 3) sampler.sample_planes(p, p + 3, batched);
    ASSERT_EQ(batched.size(), all.size());
    for (std::size_t i = 0; i < all.size(); ++i) ASSERT_EQ(batched[i], all[i]) << i;
    // Written at the counted offsets (the GPU engine's set-up): the same points in the same order; a count that
    // is not the plane's is an error, not a hole or an overrun.
    std::vector<Vec3d> counted;
    for (long long p = 0; p < sampler.planes(); p += 3) sampler.sample_planes(p, p + 3, counted, &c.per_plane);
    ASSERT_EQ(counted.size(), all.size());
    for (std::size_t i = 0; i < all.size(); ++i) ASSERT_EQ(counted[i], all[i]) << i;
    std::vector<long long> wrong = c.per_plane;
    const std::size_t nonempty = static_cast<std::size_t>(
        std::find_if(wrong.begin(), wrong.end(), [](long long n) { return n > 0; }) - wrong.begin());
    ASSERT_LT(nonempty, wrong.size());
    for (const long long delta : {-1LL, 1LL}) {
      wrong[nonempty] = c.per_plane[nonempty] + delta;
      std::vector<Vec3d> out;
      EXPECT_THROW(sampler.sample_planes(0, sampler.planes(), out, &wrong), std::runtime_error) << delta;
    }
  }
}

// The count drops what sampling drops (particles beyond the domain's 8-cell margin), and refuses what it refuses
// (no particle).
TEST(BodySampler, CountAgreesWithSamplingOutsideTheDomain) {
  const SimulationSpec sim = make_sim(0.05, {1.0, 1.0, 1.0});  // margin 0.4 m
  const BodySpec body = make_body({make_box({1.2, 0.1, 0.1}, {0.4, 0.2, 0.2})}, 8);
  const std::vector<Vec3d> sampled = sample_body(body, sim, 0);
  EXPECT_EQ(static_cast<long long>(sampled.size()), BodySampler(body, sim, 0).count(sim.dx).particles);
  EXPECT_EQ(sampled.size(), 8u * 8u * 8u);  // x 1.2 .. 1.4: 8 lattice planes of 8 x 8 (ppc 8, dx 0.05)
  const BodySpec gone = make_body({make_box({1.5, 0.1, 0.1}, {0.4, 0.2, 0.2})}, 8);
  const auto sampled_error = scene_error_of([&] { sample_body(gone, sim, 0); });
  const auto counted_error = scene_error_of([&] { BodySampler(gone, sim, 0).count(sim.dx); });
  EXPECT_EQ(sampled_error.first, counted_error.first);
  EXPECT_EQ(sampled_error.second, counted_error.second);
}

}  // namespace
}  // namespace fbar
