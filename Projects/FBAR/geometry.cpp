// Body sampling: CSG point predicate over Box/Sphere/Cylinder entries and lattice / seeded-jitter point generation.
#include "geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

#include "scene_error.h"

namespace fbar {
namespace {

constexpr double kPi = 3.14159265358979323846;
/// Refuse candidate lattices above this many points: a typo in dx or span would otherwise exhaust memory.
constexpr double kMaxCandidates = 68719476736.0;  // 2^36

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}
std::string fmt3(const Vec3d& v) { return "[" + fmt(v[0]) + ", " + fmt(v[1]) + ", " + fmt(v[2]) + "]"; }
std::string fmt3(const Real3& v) { return "[" + fmt(v[0]) + ", " + fmt(v[1]) + ", " + fmt(v[2]) + "]"; }
Vec3d to_vec(const Real3& a) { return Vec3d{{a[0], a[1], a[2]}}; }

/// cos and sin of an angle in degrees; exact for multiples of 90 deg so grid-aligned shapes stay grid-aligned.
void cos_sin_deg(double deg, double& c, double& s) {
  const double quarter = deg / 90.0;
  if (std::isfinite(quarter) && quarter == std::round(quarter) && std::fabs(quarter) < 1e15) {
    const long long k = ((static_cast<long long>(std::round(quarter)) % 4) + 4) % 4;
    static constexpr double kCos[4] = {1.0, 0.0, -1.0, 0.0};
    static constexpr double kSin[4] = {0.0, 1.0, 0.0, -1.0};
    c = kCos[k];
    s = kSin[k];
    return;
  }
  const double rad = deg * kPi / 180.0;
  c = std::cos(rad);
  s = std::sin(rad);
}

/// R = Rz(ez) * Ry(ey) * Rx(ex): rotation about X first, then Y, then Z (fixed world axes), angles in degrees.
Mat3<double> euler_xyz(const Real3& deg) {
  double cx, sx, cy, sy, cz, sz;
  cos_sin_deg(deg[0], cx, sx);
  cos_sin_deg(deg[1], cy, sy);
  cos_sin_deg(deg[2], cz, sz);
  const Mat3<double> rx{{{1, 0, 0}, {0, cx, -sx}, {0, sx, cx}}};
  const Mat3<double> ry{{{cy, 0, sy}, {0, 1, 0}, {-sy, 0, cy}}};
  const Mat3<double> rz{{{cz, -sz, 0}, {sz, cz, 0}, {0, 0, 1}}};
  return rz * (ry * rx);
}

bool all_finite(const Real3& a) { return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]); }

void check_span(const Real3& span, const std::string& path, const char* object) {
  for (int d = 0; d < 3; ++d)
    if (!(span[d] > 0.0) || !std::isfinite(span[d]))
      throw SceneError(path + ".span", fmt3(span), std::string("three positive numbers for a ") + object, "m");
}

// Counter-based random numbers (SplitMix64 finaliser, Steele, Lea & Flood 2014): the value for a counter depends
// only on (seed, body, cell, counter), never on which thread asks or in which order.
constexpr std::uint64_t kGolden = 0x9e3779b97f4a7c15ull;
constexpr std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
std::uint64_t cell_key(std::uint64_t seed, int body, long long cx, long long cy, long long cz) {
  std::uint64_t h = mix64(seed + kGolden);
  h = mix64(h ^ (static_cast<std::uint64_t>(static_cast<std::int64_t>(body)) + kGolden));
  h = mix64(h ^ (static_cast<std::uint64_t>(cx) + 2 * kGolden));
  h = mix64(h ^ (static_cast<std::uint64_t>(cy) + 3 * kGolden));
  h = mix64(h ^ (static_cast<std::uint64_t>(cz) + 4 * kGolden));
  return h;
}
/// Uniform in [0, 1) with 53 random bits: element `counter` of the SplitMix64 stream started at `key`.
double uniform(std::uint64_t key, std::uint64_t counter) {
  return static_cast<double>(mix64(key + (counter + 1) * kGolden) >> 11) * 0x1.0p-53;
}

bool in_closed_box(const Vec3d& p, const Vec3d& lo, const Vec3d& hi) {
  return p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2];
}

[[noreturn]] void throw_no_particles(const std::string& path) {
  throw SceneError(path, "0 particles",
                   "at least one particle: the geometry after its operations and the partition_start/partition_end "
                   "clip must contain a sampling point");
}

}  // namespace

SamplingPattern sampling_pattern(double ppc) {
  if (!(ppc > 0.0) || !std::isfinite(ppc)) throw std::invalid_argument("ppc must be a positive finite number");
  SamplingPattern p;
  p.ppc = ppc;
  const long long n = std::llround(std::cbrt(ppc));
  if (n >= 1 && static_cast<double>(n * n * n) == ppc) {
    p.lattice = true;
    p.per_axis = static_cast<int>(n);
  } else {
    p.lattice = false;
    p.per_axis = 0;
  }
  return p;
}

BodyShape::BodyShape(const std::vector<GeometrySpec>& geometry, int body_index) {
  const double inf = std::numeric_limits<double>::infinity();
  bounds_ = Aabb{Vec3d{{inf, inf, inf}}, Vec3d{{-inf, -inf, -inf}}};
  entries_.reserve(geometry.size());
  for (std::size_t j = 0; j < geometry.size(); ++j) {
    const GeometrySpec& g = geometry[j];
    const std::string path = "bodies[" + std::to_string(body_index) + "].geometry[" + std::to_string(j) + "]";
    Entry e;
    e.object = g.object;
    e.operation = g.operation;
    if (g.object == GeometryObject::File)
      throw SceneError(path + ".object", "\"File\"",
                       "\"Box\", \"Sphere\" or \"Cylinder\" (File geometry is not supported by the sampler yet)");
    if (!all_finite(g.offset)) throw SceneError(path + ".offset", fmt3(g.offset), "three finite numbers", "m");
    if (!all_finite(g.rotate)) throw SceneError(path + ".rotate", fmt3(g.rotate), "three finite numbers", "deg");
    if (!all_finite(g.fulcrum)) throw SceneError(path + ".fulcrum", fmt3(g.fulcrum), "three finite numbers", "m");
    if (!all_finite(g.spacing)) throw SceneError(path + ".spacing", fmt3(g.spacing), "three finite numbers", "m");
    for (int d = 0; d < 3; ++d)
      if (g.array[d] < 1)
        throw SceneError(path + ".array",
                         "[" + std::to_string(g.array[0]) + ", " + std::to_string(g.array[1]) + ", " +
                             std::to_string(g.array[2]) + "]",
                         "three integers >= 1");

    const Vec3d offset = to_vec(g.offset);
    switch (g.object) {
      case GeometryObject::Box:
        check_span(g.span, path, "Box");
        e.lo = offset;
        e.hi = offset + to_vec(g.span);
        break;
      case GeometryObject::Sphere: {
        if (!(g.radius > 0.0) || !std::isfinite(g.radius))
          throw SceneError(path + ".radius", fmt(g.radius), "a positive number for a Sphere", "m");
        // offset = min corner of the bounding box (geometry.h); span is not used.
        for (int d = 0; d < 3; ++d) {
          e.lo[d] = offset[d];
          e.hi[d] = offset[d] + 2.0 * g.radius;
          e.centre[d] = offset[d] + g.radius;
        }
        e.radius_sq = g.radius * g.radius;
        break;
      }
      case GeometryObject::Cylinder: {
        if (g.axis < 0 || g.axis > 2) throw SceneError(path + ".axis", std::to_string(g.axis), "\"X\", \"Y\" or \"Z\"");
        if (!(g.radius > 0.0) || !std::isfinite(g.radius))
          throw SceneError(path + ".radius", fmt(g.radius), "a positive number for a Cylinder", "m");
        const double length = g.span[g.axis];
        if (!(length > 0.0) || !std::isfinite(length))
          throw SceneError(path + ".span", fmt3(g.span),
                           "a positive cylinder length span[" + std::to_string(g.axis) + "] along its axis", "m");
        e.axis = g.axis;
        e.radius_sq = g.radius * g.radius;
        for (int d = 0; d < 3; ++d) {  // offset = min corner of the bounding box (geometry.h)
          e.lo[d] = offset[d];
          e.hi[d] = offset[d] + (d == g.axis ? length : 2.0 * g.radius);
          e.centre[d] = offset[d] + (d == g.axis ? 0.5 * length : g.radius);
        }
        break;
      }
      case GeometryObject::File: break;  // refused above
    }
    for (int d = 0; d < 3; ++d) {
      e.copies[d] = g.array[d];
      e.spacing[d] = g.spacing[d];
    }
    e.fulcrum = to_vec(g.fulcrum);
    e.rotated = g.rotate[0] != 0.0 || g.rotate[1] != 0.0 || g.rotate[2] != 0.0;
    const Mat3<double> rot = euler_xyz(g.rotate);
    e.world_to_local = transpose(rot);

    if (g.operation == GeometryOperation::Add || g.operation == GeometryOperation::Union) {
      // Box of all copies in the local frame, then its 8 corners rotated into the world.
      Vec3d lo = e.lo, hi = e.hi;
      for (int d = 0; d < 3; ++d) {
        const double shift = (e.copies[d] - 1) * e.spacing[d];
        lo[d] += std::min(0.0, shift);
        hi[d] += std::max(0.0, shift);
      }
      for (int c = 0; c < 8; ++c) {
        const Vec3d corner{{(c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]}};
        const Vec3d w = e.rotated ? rot * (corner - e.fulcrum) + e.fulcrum : corner;
        for (int d = 0; d < 3; ++d) {
          bounds_.lo[d] = std::min(bounds_.lo[d], w[d]);
          bounds_.hi[d] = std::max(bounds_.hi[d], w[d]);
        }
      }
    }
    entries_.push_back(e);
  }
}

bool BodyShape::entry_contains(const Entry& e, const Vec3d& p) {
  const Vec3d q = e.rotated ? e.world_to_local * (p - e.fulcrum) + e.fulcrum : p;
  // Copies that can hold q: solve lo <= q - a*s <= hi for a per axis. The range is widened by one on each side
  // so that rounding in the division never drops a copy; the exact test below decides.
  long long a_lo[3], a_hi[3];
  for (int d = 0; d < 3; ++d) {
    const double s = e.spacing[d];
    if (e.copies[d] == 1 || s == 0.0) {
      a_lo[d] = a_hi[d] = 0;
      continue;
    }
    double t0 = (q[d] - e.hi[d]) / s, t1 = (q[d] - e.lo[d]) / s;
    if (t0 > t1) std::swap(t0, t1);
    a_lo[d] = std::max<long long>(0, static_cast<long long>(std::ceil(t0)) - 1);
    a_hi[d] = std::min<long long>(e.copies[d] - 1, static_cast<long long>(std::floor(t1)) + 1);
    if (a_lo[d] > a_hi[d]) return false;
  }
  for (long long a = a_lo[0]; a <= a_hi[0]; ++a)
    for (long long b = a_lo[1]; b <= a_hi[1]; ++b)
      for (long long c = a_lo[2]; c <= a_hi[2]; ++c) {
        const Vec3d qs{{q[0] - a * e.spacing[0], q[1] - b * e.spacing[1], q[2] - c * e.spacing[2]}};
        if (!in_closed_box(qs, e.lo, e.hi)) continue;
        switch (e.object) {
          case GeometryObject::Box: return true;
          case GeometryObject::Sphere:
            if (norm_squared(qs - e.centre) <= e.radius_sq) return true;
            break;
          case GeometryObject::Cylinder: {
            double r2 = 0.0;
            for (int d = 0; d < 3; ++d)
              if (d != e.axis) r2 += (qs[d] - e.centre[d]) * (qs[d] - e.centre[d]);
            if (r2 <= e.radius_sq) return true;
            break;
          }
          case GeometryObject::File: break;
        }
      }
  return false;
}

bool BodyShape::contains(const Vec3d& p) const {
  bool inside = false;
  for (const Entry& e : entries_) {
    switch (e.operation) {
      case GeometryOperation::Add:
      case GeometryOperation::Union:
        if (!inside) inside = entry_contains(e, p);
        break;
      case GeometryOperation::Subtract:
      case GeometryOperation::Difference:
        if (inside) inside = !entry_contains(e, p);
        break;
      case GeometryOperation::Intersection:
        if (inside) inside = entry_contains(e, p);
        break;
    }
  }
  return inside;
}

std::vector<Vec3d> sample_body(const BodySpec& body, const SimulationSpec& sim, int body_index) {
  const std::string body_path = "bodies[" + std::to_string(body_index) + "]";
  const std::string path = body_path + ".geometry";
  if (!(sim.dx > 0.0) || !std::isfinite(sim.dx))
    throw SceneError("simulation.default_dx", fmt(sim.dx), "a positive number", "m");
  SamplingPattern pattern;
  try {
    pattern = sampling_pattern(body.material.ppc);
  } catch (const std::invalid_argument&) {
    throw SceneError(body_path + ".material.ppc", fmt(body.material.ppc), "a positive number of particles per cell");
  }
  if (body.geometry.empty()) throw SceneError(path, "[]", "at least one Box, Sphere or Cylinder entry");

  const BodyShape shape(body.geometry, body_index);
  const Vec3d part_lo = to_vec(body.partition_start), part_hi = to_vec(body.partition_end);
  Aabb box = shape.bounds();
  for (int d = 0; d < 3; ++d) {
    box.lo[d] = std::max(box.lo[d], part_lo[d]);
    box.hi[d] = std::min(box.hi[d], part_hi[d]);
  }
  if (box.empty()) throw_no_particles(path);

  // Candidate points: the lattice (spacing h) or cells (edge dx) covering `box`, one extra on each side so that
  // rounding in the index computation never loses a point; the predicate decides.
  const double h = pattern.lattice ? sim.dx / pattern.per_axis : sim.dx;
  long long first[3], count[3];
  double candidates = 1.0;
  for (int d = 0; d < 3; ++d) {
    const double lo = pattern.lattice ? box.lo[d] / h - 0.5 : box.lo[d] / h;
    const double hi = pattern.lattice ? box.hi[d] / h - 0.5 : box.hi[d] / h;
    if (!std::isfinite(lo) || !std::isfinite(hi) || std::fabs(lo) > 9e15 || std::fabs(hi) > 9e15)
      throw SceneError(path, "bounding box " + fmt3(box.lo) + " to " + fmt3(box.hi),
                       "a finite geometry (clip it with partition_start/partition_end)", "m");
    first[d] = static_cast<long long>(std::floor(lo)) - 1;
    count[d] = static_cast<long long>(std::ceil(hi)) + 1 - first[d] + 1;
    candidates *= static_cast<double>(count[d]);
  }
  if (candidates > kMaxCandidates)
    throw SceneError(path, fmt(candidates) + " candidate sampling points in bounding box " + fmt3(box.lo) + " to " +
                               fmt3(box.hi),
                     "at most 2^36 (check default_dx, ppc and the geometry's span)");

  // The partition box is half-open, [start, end): a body split between GPUs at a plane through lattice points
  // (ClaymoreUW's inside_partition) gives each point to exactly one of them.
  auto in_partition = [&](const Vec3d& p) {
    return p[0] >= part_lo[0] && p[0] < part_hi[0] && p[1] >= part_lo[1] && p[1] < part_hi[1] &&
           p[2] >= part_lo[2] && p[2] < part_hi[2];
  };
  auto keep = [&](const Vec3d& p) { return in_partition(p) && shape.contains(p); };

  // One output vector per x-plane, concatenated in plane order: deterministic for any thread count.
  std::vector<std::vector<Vec3d>> planes(static_cast<std::size_t>(count[0]));
  const double ppc_floor = std::floor(pattern.ppc);
  const double ppc_frac = pattern.ppc - ppc_floor;
  const int base = static_cast<int>(ppc_floor);
#pragma omp parallel for schedule(dynamic, 1)
  for (long long ix = 0; ix < count[0]; ++ix) {
    std::vector<Vec3d>& out = planes[static_cast<std::size_t>(ix)];
    const long long i = first[0] + ix;
    for (long long j = first[1]; j < first[1] + count[1]; ++j)
      for (long long k = first[2]; k < first[2] + count[2]; ++k) {
        if (pattern.lattice) {
          const Vec3d p{{(static_cast<double>(i) + 0.5) * h, (static_cast<double>(j) + 0.5) * h,
                         (static_cast<double>(k) + 0.5) * h}};
          if (keep(p)) out.push_back(p);
        } else {
          const std::uint64_t key = cell_key(sim.seed, body_index, i, j, k);
          const int n = base + ((ppc_frac > 0.0 && uniform(key, 3ull * (base + 1)) < ppc_frac) ? 1 : 0);
          for (int s = 0; s < n; ++s) {
            const Vec3d p{{(static_cast<double>(i) + uniform(key, 3ull * s + 0)) * h,
                           (static_cast<double>(j) + uniform(key, 3ull * s + 1)) * h,
                           (static_cast<double>(k) + uniform(key, 3ull * s + 2)) * h}};
            if (keep(p)) out.push_back(p);
          }
        }
      }
  }

  std::size_t total = 0;
  for (const auto& pl : planes) total += pl.size();
  if (total == 0) throw_no_particles(path);
  std::vector<Vec3d> points;
  points.reserve(total);
  for (auto& pl : planes) {
    points.insert(points.end(), pl.begin(), pl.end());
    std::vector<Vec3d>().swap(pl);
  }

  // The engine owns its boundary margins; here we only refuse particles outside the simulated box itself.
  std::size_t outside = 0;
  const Vec3d* first_outside = nullptr;
  for (const Vec3d& p : points) {
    const bool out = p[0] < 0.0 || p[1] < 0.0 || p[2] < 0.0 || p[0] > sim.domain[0] || p[1] > sim.domain[1] ||
                     p[2] > sim.domain[2];
    if (out) {
      if (!first_outside) first_outside = &p;
      ++outside;
    }
  }
  if (outside > 0)
    throw SceneError(path,
                     std::to_string(outside) + " of " + std::to_string(points.size()) +
                         " particles outside simulation.domain [0, " + fmt(sim.domain[0]) + "] x [0, " +
                         fmt(sim.domain[1]) + "] x [0, " + fmt(sim.domain[2]) + "], first at " +
                         fmt3(*first_outside),
                     "every particle inside simulation.domain (move or shrink the geometry, or clip it with "
                     "partition_start/partition_end)",
                     "m");
  return points;
}

}  // namespace fbar
