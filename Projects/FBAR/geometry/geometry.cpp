// Body sampling: CSG point predicate over Box/Sphere/Cylinder entries and lattice / seeded-jitter point generation.
#include "geometry/geometry.h"

#include <algorithm>
#include <filesystem>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <tuple>
#include <stdexcept>
#include <string>

#include "geometry/particle_seed.h"
#include "physics/boundary.cuh"
#include "scene/attributes.h"
#include "scene/facilities.h"
#include "scene/scene_error.h"
#include "scene/scene_parse.h"

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

}  // namespace

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

namespace {

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
                   "at least one particle: the geometry after its operations, the partition_start/partition_end "
                   "clip and simulation.domain widened by 8 cells of default_dx must contain a sampling point");
}

/// The seeds (particle_seed.h) of a point file's particles from its attributes (names g.input_attribs, point-major):
/// velocities rotated with the entry and scaled by `velocity_scale` (Froude: s^0.5), F rotated as R F R^T (the
/// particle's rest shape is placed rotated too). A point whose J or det F is not positive (an inverted particle:
/// ClaymoreUW writes such points into its own frames) is marked in `invalid` and the first one described in
/// `notes.first`; the caller drops them. A J column in ClaymoreUW's 1 - J is read as such (`notes.one_minus_j_median`).
std::vector<double> file_seeds(const GeometrySpec& g, const std::vector<double>& attributes, std::size_t n,
                               const Mat3<double>& rot, double velocity_scale, std::vector<char>& invalid,
                               BodyShape::FileSeedNotes& notes) {
  invalid.assign(n, 0);
  const std::vector<std::string>& names = g.input_attribs;
  const std::size_t K = names.size();
  const bool j_listed = std::find(names.begin(), names.end(), "J") != names.end();
  std::vector<int> slot(K);
  std::size_t j_column = K;
  for (std::size_t k = 0; k < K; ++k) {
    slot[k] = seed_slot(names[k]);
    if (names[k] == "JBar" && j_listed) slot[k] = kSeedIgnored;  // J wins; F-bar recomputes JBar every step
    if (slot[k] == kSeedJ) j_column = k;
  }
  // ClaymoreUW writes 1 - J under the names J and JBar (mgmpm_kernels.cuh, "Currently outputs (1 - J), not J") and
  // reads the column back into its 1 - J slot; fbar's frames hold J. A column whose median lies within 0.5 of 0 is
  // ClaymoreUW's (a body whose median particle has lost half its volume is not a body one resumes): J = 1 - value.
  bool one_minus_j = false;
  if (j_column < K && n > 0) {
    std::vector<double> column(n);
    for (std::size_t p = 0; p < n; ++p) column[p] = attributes[p * K + j_column];
    std::nth_element(column.begin(), column.begin() + static_cast<std::ptrdiff_t>(n / 2), column.end());
    const double median = column[n / 2];
    if (std::fabs(median) < 0.5) {
      one_minus_j = true;
      notes.one_minus_j_median = median;
    }
  }
  std::vector<double> out(n * kSeedScalars, seed_unset());
  for (std::size_t p = 0; p < n; ++p) {
    double* s = out.data() + p * kSeedScalars;
    for (std::size_t k = 0; k < K; ++k)
      if (slot[k] >= 0) s[slot[k]] = attributes[p * K + k];
    if (one_minus_j) s[kSeedJ] = 1.0 - s[kSeedJ];
    const auto mark = [&](const std::string& what) {
      if (notes.first.empty()) notes.first = "point " + std::to_string(p) + ": " + what;
      invalid[p] = 1;
    };
    if (!std::isnan(s[kSeedVelocity])) {
      Vec3d v{{s[kSeedVelocity], s[kSeedVelocity + 1], s[kSeedVelocity + 2]}};
      v = rot * v * velocity_scale;
      for (int a = 0; a < 3; ++a) s[kSeedVelocity + a] = v[a];
    }
    if (!std::isnan(s[kSeedDefGrad])) {
      Mat3<double> F;
      for (int i = 0; i < 3; ++i)
        for (int c = 0; c < 3; ++c) F(i, c) = s[kSeedDefGrad + 3 * i + c];
      if (!(determinant(F) > 0.0)) {
        mark("det(DefGrad) = " + fmt(determinant(F)));
        continue;
      }
      F = rot * F * transpose(rot);
      for (int i = 0; i < 3; ++i)
        for (int c = 0; c < 3; ++c) s[kSeedDefGrad + 3 * i + c] = F(i, c);
    }
    if (!std::isnan(s[kSeedJ]) && !(s[kSeedJ] > 0.0)) mark("J = " + fmt(s[kSeedJ]));
  }
  return out;
}

}  // namespace

SamplingPattern sampling_pattern(double ppc) {
  if (!(ppc > 0.0) || !std::isfinite(ppc)) throw std::invalid_argument("ppc must be a positive finite number");
  SamplingPattern p;
  p.ppc = ppc;
  // A cube within 1e-6 (relative) is a cube: HydroUQ writes ppc 27.000001, which ClaymoreUW samples on its
  // lattice of spacing dx / cbrt(ppc), 4e-9 off dx / 3 (read_scene_input.h make_box, L452).
  const long long n = std::llround(std::cbrt(ppc));
  const double cube = static_cast<double>(n * n * n);
  if (n >= 1 && std::fabs(ppc - cube) <= 1e-6 * cube) {
    p.lattice = true;
    p.per_axis = static_cast<int>(n);
  } else {
    p.lattice = false;
    p.per_axis = 0;
  }
  return p;
}

/// A point-file entry (.csv, .pos, .bgeo, .h5 points): its particles read (with their seeds when has_attributes),
/// inverted ones dropped and noted, then copied by array and rotated into one PointSet.
void BodyShape::add_point_file(const GeometrySpec& g, std::size_t j, const std::string& path, const Vec3d& offset,
                               double froude_scaling) {
  if (g.operation != GeometryOperation::Add && g.operation != GeometryOperation::Union)
    throw SceneError(path + ".operation", std::string("\"") + to_string(g.operation) + "\"",
                     "Add or Union for a point file (particles hold no volume to subtract or intersect; "
                     "use an .sdf file for that)");
  std::vector<double> attributes;
  std::vector<std::string> names, aliases;
  if (g.has_attributes) {
    names = g.input_attribs;
    for (const std::string& n : names) {  // a file may hold an alias's name (DefGrad_Determinant for J)
      std::string alias;
      for (const auto& a : kParticleAttributeAliases)
        if (a.second == n) alias = std::string(a.first);
      aliases.push_back(alias);
    }
  }
  std::vector<Vec3d> file_points = read_point_file(g.file, names, aliases, attributes);
  const Mat3<double> rot = euler_xyz(g.rotate);
  const bool rotated = g.rotate[0] != 0.0 || g.rotate[1] != 0.0 || g.rotate[2] != 0.0;
  const std::size_t copies = static_cast<std::size_t>(g.array[0]) * g.array[1] * g.array[2];
  FileSeedNotes notes;
  notes.entry = j;
  notes.read = file_points.size() * copies;
  std::vector<char> invalid;
  std::vector<double> seeds =
      names.empty() ? std::vector<double>{}
                    : file_seeds(g, attributes, file_points.size(), rot,
                                 std::sqrt(g.use_froude_scaling ? froude_scaling : 1.0), invalid, notes);
  if (!notes.first.empty()) {  // inverted particles: dropped, and said (audit_bodies)
    std::size_t kept = 0;
    for (std::size_t p = 0; p < file_points.size(); ++p) {
      if (invalid[p]) continue;
      file_points[kept] = file_points[p];
      std::copy_n(seeds.begin() + static_cast<std::ptrdiff_t>(p * kSeedScalars), kSeedScalars,
                  seeds.begin() + static_cast<std::ptrdiff_t>(kept * kSeedScalars));
      ++kept;
    }
    notes.dropped = (file_points.size() - kept) * copies;
    file_points.resize(kept);
    seeds.resize(kept * kSeedScalars);
  }
  if (notes.dropped > 0 || !std::isnan(notes.one_minus_j_median)) file_notes_.push_back(notes);
  PointSet set;
  set.entry = j;
  set.points.reserve(file_points.size() * copies);
  set.seeds.reserve(seeds.size() * copies);
  const Vec3d fulcrum = to_vec(g.fulcrum);
  for (int a = 0; a < g.array[0]; ++a)
    for (int b = 0; b < g.array[1]; ++b)
      for (int c = 0; c < g.array[2]; ++c) {
        const Vec3d shift{{a * g.spacing[0], b * g.spacing[1], c * g.spacing[2]}};
        for (const Vec3d& q : file_points) {
          const Vec3d local = offset + q * g.scaling_factor + shift;
          set.points.push_back(rotated ? rot * (local - fulcrum) + fulcrum : local);
        }
        set.seeds.insert(set.seeds.end(), seeds.begin(), seeds.end());
      }
  point_sets_.push_back(std::move(set));
}

BodyShape::BodyShape(const std::vector<GeometrySpec>& geometry, int body_index, double froude_scaling) {
  const double inf = std::numeric_limits<double>::infinity();
  bounds_ = Aabb{Vec3d{{inf, inf, inf}}, Vec3d{{-inf, -inf, -inf}}};
  entries_.reserve(geometry.size());
  for (std::size_t j = 0; j < geometry.size(); ++j) {
    const GeometrySpec& g = geometry[j];
    const std::string path = "bodies[" + std::to_string(body_index) + "].geometry[" + std::to_string(j) + "]";
    Entry e;
    e.object = g.object;
    e.operation = g.operation;
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
      case GeometryObject::File: {
        const GeometryFileKind kind = geometry_file_kind(g.file);
        if (kind == GeometryFileKind::Unknown)
          throw SceneError(path + ".file", "\"" + g.file + "\"", std::string("a file ending in ") + geometry_file_extensions());
        if (!(g.scaling_factor > 0.0) || !std::isfinite(g.scaling_factor))
          throw SceneError(path + ".scaling_factor", fmt(g.scaling_factor), "a positive number");
        try {
          if (kind == GeometryFileKind::Sdf) {
            e.sdf = read_sdf(g.file);
            e.sdf_h = e.sdf->dx * g.scaling_factor;
            e.sdf_padding = g.padding;
            e.centre = offset;
            for (int d = 0; d < 3; ++d) {
              e.lo[d] = offset[d] - e.sdf_padding * e.sdf_h;
              e.hi[d] = offset[d] + (e.sdf->n[d] - 1 - e.sdf_padding) * e.sdf_h;
            }
          } else {
            add_point_file(g, j, path, offset, froude_scaling);
            e.points = true;
          }
        } catch (const std::runtime_error& err) {
          if (dynamic_cast<const SceneError*>(&err)) throw;
          throw SceneError(path + ".file", "\"" + g.file + "\"", std::string("a readable geometry file (") + err.what() + ")");
        }
        break;
      }
      case GeometryObject::Bathymetry:
      case GeometryObject::OsuLwf:
      case GeometryObject::OsuTwb: {
        check_span(g.span, path, to_string(g.object));
        e.lo = offset;
        e.hi = offset + to_vec(g.span);
        BedPoints bed;
        if (g.object == GeometryObject::Bathymetry || g.use_custom_bathymetry) {
          bed = g.bathymetry;
        } else {  // the facility's bed, its origin (the wave-maker's neutral position, the floor) at the offset,
                  // the LWF's 0.1 m (x s) further along x, as ClaymoreUW places it (facilities.h)
          const double s = g.use_froude_scaling ? froude_scaling : 1.0;
          const bool lwf = g.object == GeometryObject::OsuLwf;
          bed = place_bed(lwf ? osu_lwf_bathymetry() : osu_twb_bathymetry(), s,
                          offset[0] + (lwf ? kOsuLwfNeutralFromWater * s : 0.0), offset[1]);
        }
        if (bed.size() < 2)
          throw SceneError(path + ".bathymetry", std::to_string(bed.size()) + " point(s)", "at least 2 [x, y] points", "m");
        e.bed = std::make_shared<const BedPoints>(std::move(bed));
        // Subtracted, a bed object cuts the body by the ground: what lies at or below the bed goes, whatever the
        // entry's span, offset and copies (ClaymoreUW's subtract_bathymetry, read_scene_input.h; subtracting a
        // facility's built-in bed removes nothing there: it prints that the operation is missing).
        e.ground = g.operation == GeometryOperation::Subtract || g.operation == GeometryOperation::Difference;
        break;
      }
    }
    for (int d = 0; d < 3; ++d) {
      e.copies[d] = g.array[d];
      e.spacing[d] = g.spacing[d];
    }
    e.fulcrum = to_vec(g.fulcrum);
    e.rotated = g.rotate[0] != 0.0 || g.rotate[1] != 0.0 || g.rotate[2] != 0.0;
    const Mat3<double> rot = euler_xyz(g.rotate);
    e.world_to_local = transpose(rot);

    if (!e.points && (g.operation == GeometryOperation::Add || g.operation == GeometryOperation::Union)) {
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
  if (e.ground) return p[1] <= bed_height(*e.bed, p[0]);
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
          case GeometryObject::File:
            if (e.sdf) {
              const Vec3d u = (qs - e.centre) / e.sdf_h + Vec3d{{e.sdf_padding, e.sdf_padding, e.sdf_padding}};
              if (e.sdf->value(u) <= 0.0) return true;
            }
            break;
          case GeometryObject::Bathymetry:
          case GeometryObject::OsuLwf:
          case GeometryObject::OsuTwb:
            if (qs[1] >= bed_height(*e.bed, qs[0])) return true;
            break;
        }
      }
  return false;
}

bool BodyShape::contains(const Vec3d& p) const {
  bool inside = false;
  for (const Entry& e : entries_) {
    if (e.points) continue;
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

bool BodyShape::survives(const Vec3d& p, std::size_t entry) const {
  bool inside = true;
  for (std::size_t j = entry + 1; j < entries_.size() && inside; ++j) {
    const Entry& e = entries_[j];
    if (e.points) continue;
    switch (e.operation) {
      case GeometryOperation::Add:
      case GeometryOperation::Union: break;
      case GeometryOperation::Subtract:
      case GeometryOperation::Difference: inside = !entry_contains(e, p); break;
      case GeometryOperation::Intersection: inside = entry_contains(e, p); break;
    }
  }
  return inside;
}

namespace {

/// Particle block of a coordinate (per axis): B = floor((base - 1) / 4), base = floor(x / dx - 0.5), as the GPU
/// engine groups particles (partition_domain.h).
long long particle_block(double x, double inv_dx) {
  const long long base = static_cast<long long>(std::floor(x * inv_dx - 0.5));
  return static_cast<long long>(std::floor(static_cast<double>(base - 1) / 4.0));
}

/// Particles per block in an ordered map (sparse bodies and given point lists).
struct BlockTally {
  std::map<std::tuple<long long, long long, long long>, long long> blocks;
  void add(const Vec3d& p, double inv_dx) {
    ++blocks[{particle_block(p[0], inv_dx), particle_block(p[1], inv_dx), particle_block(p[2], inv_dx)}];
  }
  void emit(SampleCount& c) const {
    for (const auto& [key, n] : blocks)
      c.blocks.push_back(BlockCount{static_cast<int>(std::get<0>(key)), static_cast<int>(std::get<1>(key)),
                                    static_cast<int>(std::get<2>(key)), n});
  }
};

}  // namespace

BodySampler::BodySampler(const BodySpec& body, const SimulationSpec& sim, int body_index, SamplerClip clip)
    : body_index_(body_index),
      seed_(sim.seed),
      path_("bodies[" + std::to_string(body_index) + "].geometry"),
      clip_domain_(clip.domain) {
  const std::string body_path = "bodies[" + std::to_string(body_index) + "]";
  const std::string& path = path_;
  if (!(sim.dx > 0.0) || !std::isfinite(sim.dx))
    throw SceneError("simulation.default_dx", fmt(sim.dx), "a positive number", "m");
  try {
    pattern_ = sampling_pattern(body.material.ppc);
  } catch (const std::invalid_argument&) {
    throw SceneError(body_path + ".material.ppc", fmt(body.material.ppc), "a positive number of particles per cell");
  }
  if (body.geometry.empty()) throw SceneError(path, "[]", "at least one geometry entry");

  shape_ = std::make_shared<BodyShape>(body.geometry, body_index, sim.froude_scaling);
  const double inf = std::numeric_limits<double>::infinity();
  part_lo_ = clip.partition ? to_vec(body.partition_start) : Vec3d{{-inf, -inf, -inf}};
  part_hi_ = clip.partition ? to_vec(body.partition_end) : Vec3d{{inf, inf, inf}};
  domain_ = Vec3d{{sim.domain[0], sim.domain[1], sim.domain[2]}};
  dx_ = sim.dx;
  // Point-file particles: the partition clip (half-open, as the lattice) and the later entries' operations. A
  // particle frame (.bgeo, .h5) is not clipped: ClaymoreUW reads frames without the partition (its resume scenes
  // keep their first run's partition_end, which a wave crest of the frame may have risen above), and a .csv / .pos
  // file is, as ClaymoreUW clips its csv files.
  std::vector<BodyShape::PointSet> sets = shape_->take_point_sets();
  const bool seeded = std::any_of(sets.begin(), sets.end(), [](const auto& s) { return !s.seeds.empty(); });
  for (BodyShape::PointSet& set : sets) {
    std::vector<Vec3d>& pts = set.points;
    if (seeded && set.seeds.empty()) set.seeds.assign(pts.size() * kSeedScalars, seed_unset());
    const std::string ext = std::filesystem::path(body.geometry[set.entry].file).extension().string();
    const bool clipped = ext != ".bgeo" && ext != ".h5";
    std::size_t kept = 0;  // compact points (and their seeds) in place, in order
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Vec3d& p = pts[i];
      const bool inside_partition = p[0] >= part_lo_[0] && p[0] < part_hi_[0] && p[1] >= part_lo_[1] &&
                                    p[1] < part_hi_[1] && p[2] >= part_lo_[2] && p[2] < part_hi_[2];
      if (!((inside_partition || !clipped) && !outside_domain(p) && shape_->survives(p, set.entry))) continue;
      if (kept != i) {
        pts[kept] = p;
        if (seeded)
          std::copy_n(set.seeds.begin() + static_cast<std::ptrdiff_t>(i * kSeedScalars), kSeedScalars,
                      set.seeds.begin() + static_cast<std::ptrdiff_t>(kept * kSeedScalars));
      }
      ++kept;
    }
    pts.resize(kept);
    if (seeded) set.seeds.resize(kept * kSeedScalars);
    if (points_.empty()) {
      points_ = std::move(pts);
      seeds_ = std::move(set.seeds);
    } else {
      points_.insert(points_.end(), pts.begin(), pts.end());
      seeds_.insert(seeds_.end(), set.seeds.begin(), set.seeds.end());
      std::vector<Vec3d>().swap(pts);
      std::vector<double>().swap(set.seeds);
    }
  }
  point_chunks_ = (static_cast<long long>(points_.size()) + kPointChunk - 1) / kPointChunk;
  Aabb box = shape_->bounds();
  for (int d = 0; d < 3; ++d) {
    box.lo[d] = std::max(box.lo[d], part_lo_[d]);
    box.hi[d] = std::min(box.hi[d], part_hi_[d]);
    if (clip_domain_) {  // the domain widened by the margin in which particles may stand (boundary.cuh)
      const double margin = kDomainMarginCells * dx_;
      box.lo[d] = std::max(box.lo[d], -margin);
      box.hi[d] = std::min(box.hi[d], domain_[d] + margin);
    }
  }
  if (box.empty()) {  // no solid to sample: only point files (or nothing)
    if (points_.empty()) throw_no_particles(path);
    return;
  }

  // Candidate points: the lattice (spacing h) or cells (edge dx) covering `box`, one extra on each side so that
  // rounding in the index computation never loses a point; the predicate decides.
  h_ = pattern_.lattice ? sim.dx / pattern_.per_axis : sim.dx;
  double candidates = 1.0;
  for (int d = 0; d < 3; ++d) {
    const double lo = pattern_.lattice ? box.lo[d] / h_ - 0.5 : box.lo[d] / h_;
    const double hi = pattern_.lattice ? box.hi[d] / h_ - 0.5 : box.hi[d] / h_;
    if (!std::isfinite(lo) || !std::isfinite(hi) || std::fabs(lo) > 9e15 || std::fabs(hi) > 9e15)
      throw SceneError(path, "bounding box " + fmt3(box.lo) + " to " + fmt3(box.hi),
                       "a finite geometry (clip it with partition_start/partition_end)", "m");
    first_[d] = static_cast<long long>(std::floor(lo)) - 1;
    count_[d] = static_cast<long long>(std::ceil(hi)) + 1 - first_[d] + 1;
    candidates *= static_cast<double>(count_[d]);
  }
  if (candidates > kMaxCandidates)
    throw SceneError(path, fmt(candidates) + " candidate sampling points in bounding box " + fmt3(box.lo) + " to " +
                               fmt3(box.hi),
                     "at most 2^36 (check default_dx, ppc and the geometry's span)");
}

template <typename F>
void BodySampler::visit_plane(long long ix, F&& f) const {
  // The partition box is half-open, [start, end): a body split between GPUs at a plane through lattice points
  // (ClaymoreUW's inside_partition) gives each point to exactly one of them.
  auto keep = [&](const Vec3d& p) {
    return p[0] >= part_lo_[0] && p[0] < part_hi_[0] && p[1] >= part_lo_[1] && p[1] < part_hi_[1] &&
           p[2] >= part_lo_[2] && p[2] < part_hi_[2] && !outside_domain(p) && shape_->contains(p);
  };
  const double ppc_floor = std::floor(pattern_.ppc);
  const double ppc_frac = pattern_.ppc - ppc_floor;
  const int base = static_cast<int>(ppc_floor);
  const long long i = first_[0] + ix;
  for (long long j = first_[1]; j < first_[1] + count_[1]; ++j)
    for (long long k = first_[2]; k < first_[2] + count_[2]; ++k) {
      if (pattern_.lattice) {
        const Vec3d p{{(static_cast<double>(i) + 0.5) * h_, (static_cast<double>(j) + 0.5) * h_,
                       (static_cast<double>(k) + 0.5) * h_}};
        if (keep(p)) f(p);
      } else {
        const std::uint64_t key = cell_key(seed_, body_index_, i, j, k);
        const int n = base + ((ppc_frac > 0.0 && uniform(key, 3ull * (base + 1)) < ppc_frac) ? 1 : 0);
        for (int s = 0; s < n; ++s) {
          const Vec3d p{{(static_cast<double>(i) + uniform(key, 3ull * s + 0)) * h_,
                         (static_cast<double>(j) + uniform(key, 3ull * s + 1)) * h_,
                         (static_cast<double>(k) + uniform(key, 3ull * s + 2)) * h_}};
          if (keep(p)) f(p);
        }
      }
    }
}

void BodySampler::sample_planes(long long first, long long last, std::vector<Vec3d>& out,
                                const std::vector<long long>* per_plane) const {
  first = std::max(first, 0LL);
  last = std::min(last, planes());
  if (first >= last) return;
  if (last > count_[0]) {  // point-file chunks after the lattice planes
    sample_planes(first, count_[0], out, per_plane);
    const long long from = std::max(first, count_[0]) - count_[0], to = last - count_[0];
    const std::size_t begin = static_cast<std::size_t>(from * kPointChunk);
    const std::size_t end = std::min(points_.size(), static_cast<std::size_t>(to * kPointChunk));
    out.insert(out.end(), points_.begin() + static_cast<std::ptrdiff_t>(begin),
               points_.begin() + static_cast<std::ptrdiff_t>(end));
    return;
  }
  if (per_plane) {
    // Each plane's points at its counted offset: one allocation, on this thread, and no concatenation.
    if (static_cast<long long>(per_plane->size()) < last)
      throw std::runtime_error(path_ + ": " + std::to_string(per_plane->size()) + " plane counts for plane " +
                               std::to_string(last - 1));
    std::vector<std::size_t> offset(static_cast<std::size_t>(last - first) + 1, out.size());
    for (long long ix = first; ix < last; ++ix)
      offset[static_cast<std::size_t>(ix - first) + 1] =
          offset[static_cast<std::size_t>(ix - first)] + static_cast<std::size_t>((*per_plane)[static_cast<std::size_t>(ix)]);
    out.reserve(offset.back());
    out.resize(offset.back());
    long long wrong = -1;  // a plane whose points are not its count
#pragma omp parallel for schedule(dynamic, 1)
    for (long long ix = first; ix < last; ++ix) {
      std::size_t at = offset[static_cast<std::size_t>(ix - first)];
      const std::size_t end = offset[static_cast<std::size_t>(ix - first) + 1];
      visit_plane(ix, [&](const Vec3d& p) {
        if (at < end) out[at] = p;
        ++at;
      });
      if (at != end) {
#pragma omp critical(fbar_sample_planes_wrong)
        wrong = std::max(wrong, ix);
      }
    }
    if (wrong >= 0)
      throw std::runtime_error(path_ + ": plane " + std::to_string(wrong) + " sampled other points than counted");
    return;
  }
  // One output vector per x-plane, concatenated in plane order: deterministic for any thread count.
  std::vector<std::vector<Vec3d>> planes(static_cast<std::size_t>(last - first));
#pragma omp parallel for schedule(dynamic, 1)
  for (long long ix = first; ix < last; ++ix) {
    std::vector<Vec3d>& pl = planes[static_cast<std::size_t>(ix - first)];
    visit_plane(ix, [&](const Vec3d& p) { pl.push_back(p); });
  }
  std::size_t total = out.size();
  for (const auto& pl : planes) total += pl.size();
  out.reserve(total);
  for (auto& pl : planes) {
    out.insert(out.end(), pl.begin(), pl.end());
    std::vector<Vec3d>().swap(pl);
  }
}

bool BodySampler::outside_domain(const Vec3d& p) const {
  // The engines' own test (inside_domain, boundary.cuh): the domain widened by kDomainMarginCells cells.
  return clip_domain_ && !inside_domain(p, domain_, dx_);
}

SampleCount BodySampler::count(double dx) const {
  if (points_.empty()) return count_lattice(dx);
  // Point-file particles join the lattice's counts: one ordered tally of both.
  SampleCount c = count_[0] > 0 ? count_lattice(dx, true) : SampleCount{};
  BlockTally tally;
  for (const BlockCount& b : c.blocks) tally.blocks[{b.bx, b.by, b.bz}] += b.particles;
  c.blocks.clear();
  const double inv_dx = 1.0 / dx;
  for (long long chunk = 0; chunk < point_chunks_; ++chunk) {
    const std::size_t begin = static_cast<std::size_t>(chunk * kPointChunk);
    const std::size_t end = std::min(points_.size(), begin + static_cast<std::size_t>(kPointChunk));
    c.per_plane.push_back(static_cast<long long>(end - begin));
    for (std::size_t i = begin; i < end; ++i) tally.add(points_[i], inv_dx);
  }
  c.particles += static_cast<long long>(points_.size());
  tally.emit(c);
  return c;
}

SampleCount BodySampler::count_lattice(double dx, bool may_be_empty) const {
  // Particle blocks as the GPU engine forms them (partition_domain.h): B = floor((base - 1) / 4) per axis with
  // base = floor(x / dx - 0.5). Counted into a dense box of blocks (planes in parallel, atomic increments); every
  // candidate point lies inside it, so no count is lost.
  const double inv_dx = 1.0 / dx;
  auto block_of = [&](double x) { return particle_block(x, inv_dx); };
  long long blo[3], bn[3];
  double dense = 1.0;
  for (int d = 0; d < 3; ++d) {
    const double lo = static_cast<double>(first_[d]) * h_ - h_, hi = static_cast<double>(first_[d] + count_[d]) * h_ + h_;
    blo[d] = block_of(lo) - 1;
    bn[d] = block_of(hi) + 2 - blo[d];
    dense *= static_cast<double>(bn[d]);
  }
  if (dense > 268435456.0)  // 2^28 blocks (1 GiB of counters): a body this sparse is counted per plane in maps
    return count_sparse(dx, may_be_empty);
  SampleCount c;
  std::vector<std::uint32_t> counts(static_cast<std::size_t>(dense), 0u);
  c.per_plane.assign(static_cast<std::size_t>(count_[0]), 0);
  std::size_t particles = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : particles)
  for (long long ix = 0; ix < count_[0]; ++ix) {
    long long in_plane = 0;
    visit_plane(ix, [&](const Vec3d& p) {
      ++particles;
      ++in_plane;
      const long long b0 = block_of(p[0]) - blo[0], b1 = block_of(p[1]) - blo[1], b2 = block_of(p[2]) - blo[2];
      std::uint32_t& slot = counts[static_cast<std::size_t>((b0 * bn[1] + b1) * bn[2] + b2)];
#pragma omp atomic
      ++slot;
    });
    c.per_plane[static_cast<std::size_t>(ix)] = in_plane;
  }
  if (particles == 0 && !may_be_empty) throw_no_particles(path_);
  c.particles = static_cast<long long>(particles);
  for (long long i = 0; i < bn[0]; ++i)
    for (long long j = 0; j < bn[1]; ++j)
      for (long long k = 0; k < bn[2]; ++k) {
        const std::uint32_t n = counts[static_cast<std::size_t>((i * bn[1] + j) * bn[2] + k)];
        if (n == 0) continue;
        c.blocks.push_back(BlockCount{static_cast<int>(blo[0] + i), static_cast<int>(blo[1] + j),
                                      static_cast<int>(blo[2] + k), static_cast<long long>(n)});
      }
  return c;
}

SampleCount BodySampler::count_sparse(double dx, bool may_be_empty) const {
  SampleCount c;
  BlockTally tally;
  const double inv_dx = 1.0 / dx;
  c.per_plane.assign(static_cast<std::size_t>(count_[0]), 0);
  for (long long ix = 0; ix < count_[0]; ++ix) {
    visit_plane(ix, [&](const Vec3d& p) {
      ++c.particles;
      ++c.per_plane[static_cast<std::size_t>(ix)];
      tally.add(p, inv_dx);
    });
  }
  if (c.particles == 0 && !may_be_empty) throw_no_particles(path_);
  tally.emit(c);
  return c;
}

SampleCount count_points(const std::vector<Vec3d>& points, double dx) {
  SampleCount c;
  c.particles = static_cast<long long>(points.size());
  BlockTally tally;
  for (const Vec3d& p : points) tally.add(p, 1.0 / dx);
  tally.emit(c);
  return c;
}

ParticleSeeds BodySampler::take_seeds(long long total_particles) {
  ParticleSeeds s;
  s.first = total_particles - static_cast<long long>(points_.size());
  s.values = std::move(seeds_);
  seeds_.clear();
  return s;
}

Aabb points_bounds(const std::vector<Vec3d>& points) {
  const double inf = std::numeric_limits<double>::infinity();
  Aabb box{Vec3d{{inf, inf, inf}}, Vec3d{{-inf, -inf, -inf}}};
  for (const Vec3d& p : points)
    for (int d = 0; d < 3; ++d) {
      box.lo[d] = std::min(box.lo[d], p[d]);
      box.hi[d] = std::max(box.hi[d], p[d]);
    }
  return box;
}

Aabb body_geometry_bounds(const BodySpec& body, const SimulationSpec& sim, int body_index) {
  return BodySampler(body, sim, body_index).geometry_bounds();
}

Aabb BodySampler::geometry_bounds() const {
  Aabb box = shape_->bounds();
  const Aabb pts = points_bounds(points_);
  for (int d = 0; d < 3; ++d) {
    box.lo[d] = std::min(box.lo[d], pts.lo[d]);
    box.hi[d] = std::max(box.hi[d], pts.hi[d]);
  }
  return box;
}

std::vector<Vec3d> sample_body(const BodySpec& body, const SimulationSpec& sim, int body_index, ParticleSeeds* seeds,
                               Aabb* bounds) {
  if (body.mesh >= 0) {  // a mesh's body: its vertices, vertex k particle k (scene.h)
    if (!body.tet_mesh || body.tet_mesh->vertices.empty())
      throw std::invalid_argument("meshes[" + std::to_string(body.mesh) + "]: the body has no mesh");
    if (seeds) *seeds = ParticleSeeds{};
    if (bounds) *bounds = points_bounds(body.tet_mesh->vertices);
    return body.tet_mesh->vertices;
  }
  BodySampler sampler(body, sim, body_index);
  if (bounds) *bounds = sampler.geometry_bounds();
  std::vector<Vec3d> points;
  sampler.sample_planes(0, sampler.planes(), points);
  if (points.empty()) throw_no_particles(sampler.path());
  if (seeds) *seeds = sampler.take_seeds(static_cast<long long>(points.size()));
  return points;
}

BodyDrops body_drops(const BodySpec& body, const SimulationSpec& sim, int body_index) {
  BodyDrops out;
  const BodySampler clipped(body, sim, body_index);
  out.particles = clipped.count(sim.dx).particles;
  out.file_notes = clipped.file_notes();
  const BodySampler in_partition(body, sim, body_index, SamplerClip{true, false});
  const long long partition_particles = in_partition.count(sim.dx).particles;
  out.outside_domain = partition_particles - out.particles;
  bool open = true;  // no partition given: nothing to drop
  for (int d = 0; d < 3; ++d)
    open = open && std::isinf(body.partition_start[d]) && body.partition_start[d] < 0 &&
           std::isinf(body.partition_end[d]) && body.partition_end[d] > 0;
  if (open) return out;
  try {
    const BodySampler whole(body, sim, body_index, SamplerClip{false, false});
    if (whole.candidates() > 4.0 * in_partition.candidates() + 67108864.0) {
      out.partition_counted = false;
      return out;
    }
    const SampleCount all = whole.count(sim.dx);
    out.outside_partition = all.particles - partition_particles;
  } catch (const SceneError&) {  // an unbounded geometry, or too many points: the partition is what bounds it
    out.partition_counted = false;
  }
  return out;
}

}  // namespace fbar
