// Tetrahedral meshes of FEM bodies (ClaymoreUW's meshes[]), read and checked before anything runs on them. The scene
// parser reads and checks every meshes[] entry with them (scene_parse.cpp read_mesh_entry) and keeps the mesh, which
// becomes a body (append_mesh_bodies); physics/fem.cuh says how its elements run.
//
// Files:
//  * ClaymoreUW's pair (meshes[].file_vertices, meshes[].file_elements; its loader read_scene_input.h): vertices
//    "x,y,z" per line [file units], row k (from 0) is vertex k; elements "a,b,c,d" per line, vertex numbers from 1
//    (ClaymoreUW subtracts 1). Further columns are ignored, as ClaymoreUW does. fbar also skips empty lines and lines
//    starting with '#' (ClaymoreUW pushes an uninitialised row for a blank line) and a header row (a first row whose
//    first field is not a number; ClaymoreUW's stof would throw on it).
//  * Gmsh's MSH 4.1 ASCII format ($MeshFormat 4.1 0 8, $Nodes, $Elements): the 4-node tetrahedra (element type 4);
//    points, lines and triangles (types 15, 1, 2: the boundary entities Gmsh writes with the volume) are skipped; any
//    other type (a 10-node tetrahedron, a hexahedron, ...) is an error naming it. Node tags may be sparse. A binary
//    MSH file, or another version, is an error saying how to export (gmsh -3 -format msh41 file.geo).
// Checks (check_tet_mesh): every element's four vertex indices exist and differ; its signed volume
// V = (x1 - x0) . ((x2 - x0) x (x3 - x0)) / 6 is positive (ClaymoreUW keeps an inverted element and flips its
// force); its quality q = 6 sqrt(2) V / l_rms^3 (l_rms the root mean square of its six edges: 1 for the regular
// tetrahedron, 0 when flat) is at least kMinTetQuality (below it the element is degenerate: its stiffness, and so the
// time step, are meaningless). Errors name the element (from 0). vertex_outside finds a vertex outside a box.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "MnBase/Math/vec.h"

namespace fbar {

/// Vertices [file units] and 4-vertex elements (indices from 0 into `vertices`).
struct TetMesh {
  std::vector<Vec3d> vertices;
  std::vector<std::array<int, 4>> elements;
};

/// An element of smaller quality (6 sqrt(2) V / l_rms^3) is degenerate (an error).
inline constexpr double kMinTetQuality = 1e-6;

/// Reads ClaymoreUW's vertex and element CSV files. Throws std::runtime_error naming the file and line for a row
/// with fewer than three numbers (vertices) or four integers (elements), a non-finite coordinate, or a vertex number
/// below 1; a file without rows is an error too. Vertex numbers beyond the vertex count are left to check_tet_mesh.
TetMesh read_tet_mesh_csv(const std::string& vertices_file, const std::string& elements_file);

/// Reads the tetrahedra of a Gmsh MSH 4.1 ASCII file (above). Throws std::runtime_error naming the file and line.
TetMesh read_gmsh_msh41(const std::string& file);

/// What check_tet_mesh measured.
struct TetMeshStats {
  std::size_t vertices = 0, elements = 0;
  std::size_t unused_vertices = 0;   ///< vertices no element uses (they carry no mass: a warning for the scene)
  double volume = 0.0;               ///< [file units^3] sum of the elements' volumes
  double min_quality = 0.0;          ///< smallest q over the elements
  std::size_t worst_element = 0;     ///< the element of min_quality
  double min_edge = 0.0, max_edge = 0.0;  ///< [file units] shortest and longest element edge
  double min_height = 0.0;           ///< [file units] smallest element height 3 V / largest face (the FEM step's length)
};

/// "8 vertices, 6 tetrahedra, volume 0.001 m^3, edges 0.1 to 0.1732 m, smallest quality 0.6573 (element 1)" (and the
/// vertices in no element, when some are): what --check and the scene's summary say of a mesh.
std::string describe(const TetMeshStats& s);

/// Signed volume of the tetrahedron (x0, x1, x2, x3): positive when (x1 - x0, x2 - x0, x3 - x0) is right-handed.
double tet_volume(const Vec3d& x0, const Vec3d& x1, const Vec3d& x2, const Vec3d& x3);
/// Quality 6 sqrt(2) V / l_rms^3 (negative for an inverted element).
double tet_quality(const Vec3d& x0, const Vec3d& x1, const Vec3d& x2, const Vec3d& x3);

/// Checks the elements of `mesh` (file comment) and measures it; `where` prefixes every message.
/// Throws std::runtime_error("<where>: element 12 (vertices 3, 8, 9, 14): ...").
TetMeshStats check_tet_mesh(const TetMesh& mesh, const std::string& where);

/// The first vertex that lies outside [lo, hi] once moved by `offset`, and the first axis it leaves along; -1 when
/// every vertex lies inside.
struct VertexOutside {
  long long vertex = -1;
  int axis = -1;
};
VertexOutside vertex_outside(const TetMesh& mesh, const Vec3d& offset, const Vec3d& lo, const Vec3d& hi);

/// The box [lo, hi] cut into cells[0] x cells[1] x cells[2] cubes of six tetrahedra each (Kuhn's subdivision along
/// the cube's diagonal from its low to its high corner: conforming across cubes, every element of quality 0.6573
/// when the cells are cubes). Vertices in x-major order: vertex (i, j, k) is (i (cells[1] + 1) + j) (cells[2] + 1) + k.
/// For tests, benchmarks and programs that build a mesh in code (a box of a scene: a Gmsh or CSV file).
TetMesh box_tet_mesh(const Vec3d& lo, const Vec3d& hi, const Vec3i& cells);

}  // namespace fbar
