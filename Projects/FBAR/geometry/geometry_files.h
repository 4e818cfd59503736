// Geometry read from files (bodies[].geometry[] with object File): a signed-distance field (.sdf) is a solid that the
// body's lattice samples like any other shape; a point file (.csv, .pos, .bgeo, .h5) is a list of particle positions
// used as they are. Placement follows ClaymoreUW's loader (read_scene_input.h, "File"), in metres:
//
//  * .sdf  SDFGen's text format: "ni nj nk", "origin_x origin_y origin_z", "dx", then ni*nj*nk values, i fastest
//          (value (i, j, k) at i + ni (j + nj k)); negative inside. Grid index `padding` (SDFGen's padding, default 1)
//          is placed at `offset` and one index is dx * scaling_factor metres, so
//              index(p) = (p - offset) / (dx * scaling_factor) + padding,
//          and p is inside when the trilinear value there is <= 0 (outside the grid: outside). The file's origin line
//          is read and not used (ClaymoreUW ignores it too: `offset` places the object). The body's ppc decides the
//          sampling, as for every shape (ClaymoreUW's sampler also ends at default_dx / cbrt(ppc)).
//  * point files: each position p_file [m] becomes offset + scaling_factor * p_file (ClaymoreUW applies neither
//          scaling_factor nor, for .csv, Froude scaling; fbar applies both, see the user guide). Formats:
//            .csv  comma-separated; the first three columns are x, y, z, or the columns named Position_X/_Y/_Z in a
//                  header row (a first row whose first field is not a number is a header; fbar's own CSV frames
//                  read back). Empty lines and lines starting with '#' are skipped.
//            .pos  x y z per line, separated by spaces, tabs or commas; '#' starts a comment line.
//            .bgeo classic Houdini bgeo (partio's format; fbar's frames): the point positions.
//            .h5   fbar's HDF5 frame (io/h5_frame.h): the dataset /Position, N x 3.
//          With has_attributes, named values per point come with the positions: .csv header columns, .bgeo attributes
//          and .h5 datasets of one value per point (geometry/particle_seed.h says what they seed).
// Errors throw std::runtime_error naming the file and, for text formats, the line.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "MnBase/Math/vec.h"

namespace fbar {

/// A signed-distance field on a regular grid (SDFGen's .sdf), in the file's units.
struct SdfGrid {
  int n[3] = {0, 0, 0};
  Vec3d origin{};      ///< as written in the file (not used for placement)
  double dx = 0.0;     ///< grid spacing in the file's length unit
  std::vector<float> phi;  ///< n[0] * n[1] * n[2] values, i fastest

  float at(int i, int j, int k) const {
    return phi[static_cast<std::size_t>(i) + static_cast<std::size_t>(n[0]) * (j + static_cast<std::size_t>(n[1]) * k)];
  }
  /// Trilinear value at continuous grid indices u (0 .. n-1 per axis); +infinity outside the grid.
  double value(const Vec3d& u) const;
};

/// Reads an SDFGen .sdf file. Throws std::runtime_error naming the file (and what is wrong) for a bad header,
/// fewer values than ni*nj*nk, or a non-finite value.
std::shared_ptr<const SdfGrid> read_sdf(const std::string& path);

enum class GeometryFileKind { Sdf, Points, Unknown };

/// What a file name's extension (case-insensitive) holds: .sdf a solid; .csv, .pos, .bgeo, .h5 points.
GeometryFileKind geometry_file_kind(const std::string& path);

/// The extensions read, for error messages.
const char* geometry_file_extensions();

/// Reads the positions [file units] of a point file (.csv, .pos, .bgeo, .h5). Throws std::runtime_error naming the
/// file (and line) for anything it cannot read, and for a file without points.
std::vector<Vec3d> read_point_file(const std::string& path);

/// The same, with the named per-point attributes (has_attributes): values[p * names.size() + k] is attribute
/// names[k] of point p. A name matches a .csv header column (without its " [unit]"), a .bgeo attribute or an .h5
/// dataset of one value per point, exactly; `aliases[k]`, when not empty, is tried when names[k] is absent. Throws
/// std::runtime_error naming the file and the attribute (with the names the file holds) when one is missing, has
/// more than one component or a non-finite value; a .pos file holds no names.
std::vector<Vec3d> read_point_file(const std::string& path, const std::vector<std::string>& names,
                                   const std::vector<std::string>& aliases, std::vector<double>& values);

}  // namespace fbar
