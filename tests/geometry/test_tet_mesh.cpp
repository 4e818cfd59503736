// Tetrahedral meshes (geometry/tet_mesh.h): ClaymoreUW's CSV pair and Gmsh MSH 4.1 read into the same mesh, the
// volume and quality measures against closed forms, and every defect the checks refuse, named by element or vertex.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "geometry/tet_mesh.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / "fbar_test_tet_mesh";
  fs::create_directories(d);
  return d;
}

std::string write(const std::string& name, const std::string& text) {
  const fs::path p = temp_dir() / name;
  std::ofstream(p) << text;
  return p.string();
}

/// The unit cube in six Kuhn tetrahedra along its diagonal (0,0,0)-(1,1,1), each oriented positively: vertex k of the
/// cube is (k & 1, (k >> 1) & 1, (k >> 2) & 1); returns the elements with vertex numbers from 1 as ClaymoreUW's CSV.
std::string cube_elements_csv(const TetMesh& cube) {
  std::string csv;
  const int axes[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : axes) {
    std::array<int, 4> t{0, 1 << p[0], (1 << p[0]) | (1 << p[1]), 7};
    if (tet_volume(cube.vertices[t[0]], cube.vertices[t[1]], cube.vertices[t[2]], cube.vertices[t[3]]) < 0)
      std::swap(t[1], t[2]);
    csv += std::to_string(t[0] + 1) + "," + std::to_string(t[1] + 1) + "," + std::to_string(t[2] + 1) + "," +
           std::to_string(t[3] + 1) + "\n";
  }
  return csv;
}

TetMesh unit_cube() {
  TetMesh m;
  for (int k = 0; k < 8; ++k) m.vertices.push_back(Vec3d{{double(k & 1), double((k >> 1) & 1), double((k >> 2) & 1)}});
  return m;
}

TEST(TetMesh, RegularTetrahedronHasQualityOne) {
  const Vec3d a{{1, 1, 1}}, b{{1, -1, -1}}, c{{-1, 1, -1}}, d{{-1, -1, 1}};  // edge 2 sqrt(2)
  EXPECT_NEAR(tet_quality(a, c, b, d), 1.0, 1e-12);
  EXPECT_NEAR(tet_quality(a, b, c, d), -1.0, 1e-12);  // the other orientation
  EXPECT_NEAR(tet_volume(a, c, b, d), std::pow(2 * std::sqrt(2.0), 3) / (6 * std::sqrt(2.0)), 1e-12);  // a^3/(6 sqrt 2)
}

// ClaymoreUW's pair: vertices x,y,z from row 0, elements a,b,c,d numbered from 1; fbar skips a header, blank lines
// and '#' lines. Six Kuhn tetrahedra fill the unit cube: volume 1; each has edges 1, 1, 1, sqrt 2, sqrt 2, sqrt 3,
// so l_rms^2 = 10/6 and q = 6 sqrt(2) (1/6) / (10/6)^1.5 = 0.6573.
TEST(TetMesh, ClaymoreUWCsvPairFillsTheCube) {
  const TetMesh cube = unit_cube();
  std::string vertices = "x,y,z\n";
  for (const Vec3d& v : cube.vertices)
    vertices += std::to_string(v[0]) + "," + std::to_string(v[1]) + "," + std::to_string(v[2]) + ",7\n\n";
  const std::string vf = write("cube_vertices.csv", vertices);
  const std::string ef = write("cube_elements.csv", "# Kuhn\n" + cube_elements_csv(cube));
  const TetMesh m = read_tet_mesh_csv(vf, ef);
  ASSERT_EQ(m.vertices.size(), 8u);
  ASSERT_EQ(m.elements.size(), 6u);
  const TetMeshStats s = check_tet_mesh(m, "meshes[0]");
  EXPECT_NEAR(s.volume, 1.0, 1e-12);
  EXPECT_NEAR(s.min_quality, 6 * std::sqrt(2.0) / 6 / std::pow(10.0 / 6, 1.5), 1e-12);
  EXPECT_EQ(s.unused_vertices, 0u);
  EXPECT_NEAR(s.min_edge, 1.0, 1e-12);
  EXPECT_NEAR(s.max_edge, std::sqrt(3.0), 1e-12);
}

std::string error_of(const TetMesh& m) {
  try {
    check_tet_mesh(m, "meshes[2]");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no error";
}

TEST(TetMesh, ChecksNameTheElementOrVertex) {
  TetMesh m = unit_cube();
  m.elements = {{0, 1, 3, 7}};
  if (tet_volume(m.vertices[0], m.vertices[1], m.vertices[3], m.vertices[7]) < 0) m.elements[0] = {0, 3, 1, 7};
  EXPECT_EQ(error_of(m), "no error");
  TetMesh missing = m;
  missing.elements.push_back({0, 1, 2, 8});
  EXPECT_EQ(error_of(missing), "meshes[2]: element 1 (vertices 0, 1, 2, 8): vertex 8 does not exist (the mesh has 8 "
                               "vertices, 0 to 7)");
  TetMesh inverted = m;
  std::swap(inverted.elements[0][1], inverted.elements[0][2]);
  EXPECT_NE(error_of(inverted).find("element 0 (vertices"), std::string::npos);
  EXPECT_NE(error_of(inverted).find("inverted (signed volume -0.166667)"), std::string::npos) << error_of(inverted);
  TetMesh flat = m;
  flat.elements[0] = {0, 1, 2, 3};  // the cube's bottom face
  EXPECT_NE(error_of(flat).find("element 0 (vertices 0, 1, 2, 3): degenerate (quality 0"), std::string::npos)
      << error_of(flat);
  TetMesh twice = m;
  twice.elements[0] = {0, 1, 1, 7};
  EXPECT_EQ(error_of(twice), "meshes[2]: element 0 (vertices 0, 1, 1, 7): vertex 1 twice");
  TetMesh spare = m;
  spare.vertices.push_back(Vec3d{{0.5, 0.5, 0.5}});
  EXPECT_EQ(check_tet_mesh(spare, "meshes[2]").unused_vertices, 5u);  // 4 cube corners + 1
}

// vertex_outside: the first vertex (moved by the offset) outside the box, and the axis it leaves along.
TEST(TetMesh, VertexOutsideTheBox) {
  const TetMesh cube = unit_cube();
  const Vec3d lo{{0, 0, 0}}, hi{{1, 1, 1}};
  EXPECT_EQ(vertex_outside(cube, Vec3d::zero(), lo, hi).vertex, -1);
  const VertexOutside z = vertex_outside(cube, Vec3d::zero(), lo, Vec3d{{1, 1, 0.5}});
  EXPECT_EQ(z.vertex, 4);  // (0, 0, 1), the first with z > 0.5
  EXPECT_EQ(z.axis, 2);
  const VertexOutside x = vertex_outside(cube, Vec3d{{-0.25, 0, 0}}, lo, hi);
  EXPECT_EQ(x.vertex, 0);
  EXPECT_EQ(x.axis, 0);
}

TEST(TetMesh, CsvErrorsNameFileAndLine) {
  const std::string vf = write("v.csv", "0,0,0\n1,0,0\n0,1,0\n0,0,1\n");
  auto error = [&](const std::string& vertices, const std::string& elements) {
    try {
      read_tet_mesh_csv(vertices, elements);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error(vf, write("e1.csv", "1,2,3,4\n")), "no error");
  EXPECT_EQ(error(vf, write("e2.csv", "1,2,3,4\n1,2,3\n")),
            write("e2.csv", "1,2,3,4\n1,2,3\n") + ":2: got \"1,2,3\"; expected four vertex numbers (integers, from 1)");
  EXPECT_NE(error(vf, write("e3.csv", "0,1,2,3\n")).find(":1: got vertex number 0; expected a number from 1"),
            std::string::npos);
  const std::string bad_v = write("v2.csv", "0,0,0\n1,0\n");
  EXPECT_EQ(error(bad_v, write("e1.csv", "1,2,3,4\n")), bad_v + ":2: got \"1,0\"; expected x, y, z (three numbers)");
  const std::string nan_v = write("v3.csv", "0,0,nan\n");
  EXPECT_NE(error(nan_v, write("e1.csv", "1,2,3,4\n")).find(":1: got \"0,0,nan\"; expected three finite numbers"),
            std::string::npos);
  EXPECT_EQ(error(vf, write("e4.csv", "\n# nothing\n")), (temp_dir() / "e4.csv").string() +
                                                             ": no elements (expected rows a, b, c, d)");
  EXPECT_NE(error(vf, (temp_dir() / "missing.csv").string()).find("cannot open the mesh file"), std::string::npos);
}

// Gmsh MSH 4.1 ASCII: two node blocks with sparse tags, a triangle block (skipped) and two tetrahedra sharing a face:
// (0,0,0) (1,0,0) (0,1,0) (0,0,1) and the same face with (0,0,-1) below, volume 1/6 each.
std::string msh41(const std::string& version = "4.1 0 8", const std::string& tet_type = "4") {
  return "$MeshFormat\n" + version + "\n$EndMeshFormat\n"
         "$PhysicalNames\n1\n3 1 \"soil\"\n$EndPhysicalNames\n"
         "$Entities\n0 0 1 1\n1 0 0 0 1 1 0 0\n1 0 0 -1 1 1 1 0 0\n$EndEntities\n"
         "$Nodes\n2 5 10 50\n"
         "2 1 0 3\n10\n20\n30\n0 0 0\n1 0 0\n0 1 0\n"
         "3 1 0 2\n40\n50\n0 0 1\n0 0 -1\n"
         "$EndNodes\n"
         "$Elements\n2 3 1 3\n"
         "2 1 2 1\n1 10 20 30\n"
         "3 1 " + tet_type + " 2\n2 10 20 30 40\n3 10 30 20 50\n"
         "$EndElements\n";
}

TEST(TetMesh, GmshMsh41TetrahedraWithSparseTags) {
  const TetMesh m = read_gmsh_msh41(write("two.msh", msh41()));
  ASSERT_EQ(m.vertices.size(), 5u);
  ASSERT_EQ(m.elements.size(), 2u);
  EXPECT_EQ(m.elements[0], (std::array<int, 4>{0, 1, 2, 3}));
  EXPECT_EQ(m.elements[1], (std::array<int, 4>{0, 2, 1, 4}));
  const TetMeshStats s = check_tet_mesh(m, "meshes[0]");
  EXPECT_NEAR(s.volume, 2.0 / 6.0, 1e-15);
  EXPECT_EQ(s.unused_vertices, 0u);
}

TEST(TetMesh, GmshFilesItCannotReadSaySo) {
  auto error = [](const std::string& file) {
    try {
      read_gmsh_msh41(file);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string old = write("old.msh", msh41("2.2 0 8"));
  EXPECT_EQ(error(old), old + ":2: got MSH version 2.2; expected 4.1 (export with gmsh -3 -format msh41)");
  const std::string bin = write("bin.msh", msh41("4.1 1 8"));
  EXPECT_EQ(error(bin), bin + ":2: a binary MSH file; expected ASCII (export with gmsh -3 -format msh41, without -bin)");
  const std::string hex = write("hex.msh", msh41("4.1 0 8", "11"));
  EXPECT_NE(error(hex).find(":32: element type 11; expected 4-node tetrahedra"), std::string::npos) << error(hex);
  const std::string none = write("none.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n0 0 0 0\n$EndNodes\n");
  EXPECT_EQ(error(none), none + ": no 4-node tetrahedra (element type 4); expected a volume mesh (gmsh -3)");
}

}  // namespace
}  // namespace fbar
