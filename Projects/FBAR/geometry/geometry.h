// Initial particle positions of a body: its geometry[] list (Box / Sphere / Cylinder CSG) sampled at ppc per cell.
//
// Conventions (docs/user_guide.md §2.6 and §3; SI units, metres and degrees). They follow ClaymoreUW
// (read_scene_input.h: make_box / make_sphere / make_cylinder, inside_sphere / inside_cylinder,
// elementaryToRotationMatrix, translate_rotate_translate_point, inside_partition), so its scenes keep their meaning:
//  * offset is the MIN CORNER of the object's bounding box, for every object (as scene.h documents):
//      Box       [offset, offset + span]
//      Sphere    ball of `radius` centred at offset + (radius, radius, radius); span is not used
//      Cylinder  length span[axis] along `axis` from offset[axis]; circular cross-section of `radius` centred at
//                offset + radius in the two other axes (their span components are not used)
//    ClaymoreUW's make_sphere / make_cylinder also clip the solid by the box [offset, offset + span] (span defaults
//    to the domain there), which only matters when span < 2 radius; scene_parse.cpp declares span unused for
//    spheres (with a warning) and uses only span[axis] for cylinders, and this sampler follows that contract.
//  * array / spacing: copy (a, b, c), 0 <= a < array[0] ..., is the object shifted by (a*spacing[0], b*spacing[1],
//    c*spacing[2]). A point is inside the entry when it is inside any copy.
//  * rotate [deg] about fulcrum [m]: the whole entry (all its copies; the fulcrum does not move with the copies)
//    is rotated rigidly about the world point `fulcrum` by R = Rz(rotate[2]) * Ry(rotate[1]) * Rx(rotate[0]):
//    first about X, then Y, then Z, all about the fixed world axes, right-handed (positive = counter-clockwise
//    looking down the axis towards the origin). Multiples of 90 deg are exact (no 6e-17 cosines), so a rotated
//    grid-aligned box stays grid-aligned. (ClaymoreUW rotates its sampled points instead, so a rotated body there
//    has a rotated lattice; here the lattice stays on the grid and the shape is rotated: same solid.)
//  * operation, applied in list order to the set S (empty at the start):
//      Add, Union            S = S ∪ G
//      Subtract, Difference  S = S \ G
//      Intersection          S = S ∩ G
//    so an Add after a Subtract is "impervious to the prior subtraction" (seed 0.4.2). Every test is closed
//    (a point on the surface is inside).
//  * partition_start / partition_end clip the sampled points to the half-open box [start, end) (as ClaymoreUW's
//    inside_partition, so a body split across GPUs at a shared plane has every point exactly once); then points
//    more than kDomainMarginCells (8) cells of dx outside [0, simulation.domain] are dropped: the engines hold
//    particles within that margin (boundary.cuh inside_domain), as ClaymoreUW's grid, which starts 8 cells before
//    the domain. body_drops() counts both; the scene parser warns with the counts.
//
// Sampling (per grid cell of edge dx = simulation.default_dx):
//  * ppc = n^3 (1, 8, 27, 64, ...): regular lattice of spacing h = dx/n aligned to the grid, cell-centred
//    sub-lattice x_i = (i + 0.5) h per axis (i any integer), so each full cell holds exactly ppc points.
//    (ClaymoreUW starts its lattice at the object's offset; for grid-aligned offsets the points are the same.)
//  * any other ppc: seeded jitter. Each cell (cx, cy, cz) holds floor(ppc) points, plus one more with probability
//    frac(ppc), each uniform in the cell. Every random number is a counter-based hash of
//    (simulation.seed, body_index, cx, cy, cz, sample, axis), so the result depends neither on iteration order nor on
//    the number of OpenMP threads.
//  Points are then kept when the CSG predicate says inside. Output order: x-major over the candidate lattice (or
//  cells), deterministic.
#pragma once

#include <limits>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "MnBase/Math/vec.h"
#include "geometry/geometry_files.h"
#include "geometry/particle_seed.h"
#include "scene/scene.h"

namespace fbar {

/// The rotation of a geometry entry's `rotate` [deg]: R = Rz * Ry * Rx (about X first, then Y, then Z; fixed axes).
Mat3<double> euler_xyz(const Real3& deg);

/// Axis-aligned box [lo, hi] [m]. Empty when lo > hi in any axis.
struct Aabb {
  Vec3d lo;
  Vec3d hi;
  bool empty() const { return lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]; }
};

/// How points are placed inside each grid cell.
struct SamplingPattern {
  bool lattice = true;   ///< true: regular sub-lattice; false: seeded jitter
  int per_axis = 2;      ///< lattice: points per cell edge n (ppc = n^3); jitter: 0
  double ppc = 8.0;      ///< particles per cell requested
};

/// Lattice when ppc is a perfect cube of an integer, jitter otherwise. Throws std::invalid_argument for ppc <= 0.
SamplingPattern sampling_pattern(double ppc);

/// The CSG solid of one body's geometry[] list, prepared for fast point queries (rotations precomputed).
class BodyShape {
 public:
  /// Validates the entries (positive span / radius, array >= 1, readable files) and precomputes transforms; reads
  /// File geometry (geometry_files.h). froude_scaling places a facility's bed (OSU LWF / TWB objects) at scale.
  /// Throws SceneError naming bodies[body_index].geometry[j].<key>.
  BodyShape(const std::vector<GeometrySpec>& geometry, int body_index, double froude_scaling = 1.0);

  /// True when p [m] is inside the result of the operation sequence (point-file entries hold no volume).
  bool contains(const Vec3d& p) const;

  /// Bounding box of every solid Add/Union entry (rotated, all copies): no point outside it is ever inside.
  /// Empty when the list holds no such entry.
  const Aabb& bounds() const { return bounds_; }

  /// The particles of a point-file entry (geometry_files.h), every copy, in world coordinates [m], in file order
  /// (copies i-major), before the operations of later entries and the partition clip.
  struct PointSet {
    std::size_t entry = 0;
    std::vector<Vec3d> points;
    std::vector<double> seeds;  ///< has_attributes: kSeedScalars per point (geometry/particle_seed.h), else empty
  };
  /// Hands the point sets over (the sampler keeps only the particles that survive; a large file is not held twice).
  std::vector<PointSet> take_point_sets() {
    std::vector<PointSet> sets = std::move(point_sets_);
    point_sets_.clear();
    return sets;
  }
  /// Does a particle of entry `entry` (a point file, added when its entry comes) survive the later entries'
  /// operations (Subtract, Intersection, ...)?
  bool survives(const Vec3d& p, std::size_t entry) const;

  /// What reading a point file's attributes changed, per entry: a J column that holds ClaymoreUW's 1 - J (read as
  /// J = 1 - value), and particles dropped as inverted (J <= 0 or det DefGrad <= 0).
  struct FileSeedNotes {
    std::size_t entry = 0;
    std::size_t read = 0;             ///< the entry's particles as read, every copy
    std::size_t dropped = 0;          ///< inverted particles dropped, every copy
    std::string first;                ///< the first inverted one: "point 2: J = -8e-06"
    double one_minus_j_median = std::numeric_limits<double>::quiet_NaN();  ///< the J column's median when it was 1 - J
  };
  const std::vector<FileSeedNotes>& file_notes() const { return file_notes_; }

 private:
  /// One geometry entry in its own frame: copy 0 unrotated, plus how to map a world point into that frame.
  struct Entry {
    GeometryObject object = GeometryObject::Box;
    GeometryOperation operation = GeometryOperation::Add;
    bool points = false;      ///< a point file: no volume, its particles are in point_sets_
    bool ground = false;      ///< a bed object subtracted: the ground below its bed (y <= bed(x)), unbounded
    Vec3d lo{};               ///< [m] bounding box of copy 0, unrotated
    Vec3d hi{};
    Vec3d centre{};           ///< [m] sphere centre; cylinder: centre of the cross-section (axis component unused);
                              ///< .sdf: the offset (where grid index `padding` lies)
    double radius_sq = 0.0;   ///< [m^2]
    int axis = 0;             ///< cylinder axis
    std::shared_ptr<const SdfGrid> sdf;  ///< .sdf: the level set
    double sdf_h = 0.0;       ///< [m] .sdf: metres per grid index (dx * scaling_factor)
    double sdf_padding = 1.0; ///< .sdf: the grid index placed at the offset
    std::shared_ptr<const std::vector<std::array<double, 2>>> bed;  ///< [m] bed objects: the profile (world x, y)
    Int3 copies{1, 1, 1};
    Vec3d spacing{};          ///< [m]
    bool rotated = false;
    Mat3<double> world_to_local = Mat3<double>::identity();  ///< R^T
    Vec3d fulcrum{};          ///< [m]
  };
  static bool entry_contains(const Entry& e, const Vec3d& p);
  void add_point_file(const GeometrySpec& g, std::size_t j, const std::string& path, const Vec3d& offset,
                      double froude_scaling);

  std::vector<Entry> entries_;
  std::vector<PointSet> point_sets_;
  std::vector<FileSeedNotes> file_notes_;
  Aabb bounds_;
};

/// Particles of one particle block (the GPU engine's grouping: B = floor((floor(x/dx - 0.5) - 1) / 4) per axis).
struct BlockCount {
  int bx, by, bz;
  long long particles;
};

/// What sampling a body would produce, counted without storing a point: the particle count and the particles per
/// particle block (the GPU engine sizes its buffers from it before it samples).
struct SampleCount {
  long long particles = 0;
  std::vector<BlockCount> blocks;  ///< blocks holding particles, in (bx, by, bz) order
  std::vector<long long> per_plane;  ///< particles of each x-plane of the candidate lattice (BodySampler::planes())
};

/// One body's sampling, split by x-plane of the candidate lattice so that it can be counted first and then produced
/// in bounded batches (the GPU engine uploads each batch before sampling the next: host memory stays O(batch)).
/// sample_planes(0, planes()) is exactly sample_body()'s output, in the same order.
/// Which clips a BodySampler applies. A body's particles are its geometry's, less those outside
/// [partition_start, partition_end) (half-open; not for .bgeo / .h5 frames) and those outside [0, simulation.domain]
/// widened by kDomainMarginCells cells of dx (closed; inside_domain). Both are on for every run; body_drops() turns
/// them off to count what they drop.
struct SamplerClip {
  bool partition = true;
  bool domain = true;
};

class BodySampler {
 public:
  /// Validates the body's sampling inputs; throws SceneError as sample_body does.
  BodySampler(const BodySpec& body, const SimulationSpec& sim, int body_index, SamplerClip clip = {});
  /// Candidate lattice points (or cells) of the solid entries: the cost of count() and of sampling.
  double candidates() const { return static_cast<double>(count_[0]) * count_[1] * count_[2]; }
  /// Batches: the x-planes of the candidate lattice, then the particles of point files in chunks of kPointChunk.
  long long planes() const { return count_[0] + point_chunks_; }
  static constexpr long long kPointChunk = 1 << 20;
  /// Appends the points of planes [first, last) in order (OpenMP over planes, deterministic). With per_plane (the
  /// counts of count(), indexed by plane) each thread writes its planes straight into `out`, grown once: no point
  /// is allocated in a worker thread, whose arena glibc would keep resident after the set-up (malloc_trim does not
  /// shrink a thread arena's top); a plane whose points differ from its count throws std::runtime_error.
  void sample_planes(long long first, long long last, std::vector<Vec3d>& out,
                     const std::vector<long long>* per_plane = nullptr) const;
  /// Counts particles and particles per block (OpenMP over planes). Throws SceneError, as sample_body, when no
  /// particle remains.
  SampleCount count(double dx) const;
  /// Is p beyond simulation.domain widened by kDomainMarginCells cells (and the domain clip on)?
  bool outside_domain(const Vec3d& p) const;
  const std::string& path() const { return path_; }
  /// The seeds of the point-file particles (has_attributes; empty when no entry has attributes), which are the last
  /// point_particles() of the body's total_particles in ID order. Hands them over (call once).
  ParticleSeeds take_seeds(long long total_particles);
  std::size_t point_particles() const { return points_.size(); }
  /// Bounding box of the body's geometry [m]: its solid entries (BodyShape::bounds) and its point-file particles,
  /// before the partition clip (a hydrostatic body's free surface is the top of its whole geometry).
  Aabb geometry_bounds() const;
  /// What reading point-file attributes changed (BodyShape::file_notes).
  const std::vector<BodyShape::FileSeedNotes>& file_notes() const { return shape_->file_notes(); }

 private:
  template <typename F>
  void visit_plane(long long ix, F&& f) const;
  SampleCount count_lattice(double dx, bool may_be_empty = false) const;
  SampleCount count_sparse(double dx, bool may_be_empty) const;

  int body_index_ = 0;
  std::uint64_t seed_ = 0;
  std::string path_;
  SamplingPattern pattern_;
  std::shared_ptr<BodyShape> shape_;
  Vec3d part_lo_{}, part_hi_{}, domain_{};
  double dx_ = 0.0;  ///< simulation.default_dx [m]: the margin around the domain is kDomainMarginCells of it
  bool clip_domain_ = true;
  std::vector<Vec3d> points_;    ///< point-file particles kept (partition clip, later operations), in order
  std::vector<double> seeds_;    ///< their seeds (kSeedScalars each), or empty
  long long point_chunks_ = 0;
  double h_ = 0.0;
  long long first_[3] = {0, 0, 0}, count_[3] = {0, 0, 0};
};

/// The same counts for given points (tests, restarts).
SampleCount count_points(const std::vector<Vec3d>& points, double dx);

/// What the clips of a body drop (ClaymoreUW drops geometry outside the partition without a word, and keeps particles
/// outside its domain within its 8-cell grid margin, as fbar's engines do: kDomainMarginCells).
struct BodyDrops {
  long long particles = 0;          ///< the body's particles (both clips)
  long long outside_partition = 0;  ///< geometry particles outside [partition_start, partition_end)
  long long outside_domain = 0;     ///< particles inside the partition but beyond the margin around the domain
  bool partition_counted = true;    ///< false: the unclipped geometry is too large to count (outside_partition = 0)
  std::vector<BodyShape::FileSeedNotes> file_notes;  ///< what reading point-file attributes changed
};
/// Counts a body's particles with and without its clips (up to three counts; the unclipped one only when its
/// candidate lattice is at most 4 x the clipped one's + 2^26 points). Throws SceneError as sample_body does.
BodyDrops body_drops(const BodySpec& body, const SimulationSpec& sim, int body_index);

/// Samples body `body_index` of a scene (see the file comment for every convention). Particles outside the
/// partition or outside [0, simulation.domain] are dropped (body_drops counts them).
/// Throws SceneError at "bodies[i].geometry" when no particle remains, or when the candidate lattice is unreasonably large
/// (> 2^36 points); invalid entries throw at "bodies[i].geometry[j].<key>"; a bad ppc throws at
/// "bodies[i].material.ppc".
/// `seeds`, when given, receives the seeds of point files read with has_attributes (empty when none).
/// `bounds`, when given, receives BodySampler::geometry_bounds().
/// A mesh's body (BodySpec::mesh >= 0) gives the mesh's vertices in order (bounds: theirs; no seeds).
std::vector<Vec3d> sample_body(const BodySpec& body, const SimulationSpec& sim, int body_index,
                               ParticleSeeds* seeds = nullptr, Aabb* bounds = nullptr);

/// Bounding box of given points [m] (empty Aabb for none).
Aabb points_bounds(const std::vector<Vec3d>& points);

/// BodySampler::geometry_bounds() of body `body_index` (engines given their particles' positions: the free surface of
/// a hydrostatic body is the top of its geometry, not its top particle, which lies half a particle spacing below).
Aabb body_geometry_bounds(const BodySpec& body, const SimulationSpec& sim, int body_index);

}  // namespace fbar
