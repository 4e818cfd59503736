// Tetrahedral meshes: ClaymoreUW's CSV pair and Gmsh MSH 4.1 ASCII, and the checks (tet_mesh.h).
#include "geometry/tet_mesh.h"

#include "physics/fem.cuh"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace fbar {

namespace {

std::string located(const std::string& file, std::size_t line, const std::string& what) {
  return file + ":" + std::to_string(line) + ": " + what;
}

/// The file's lines (without the line ends, '\r' removed), numbered from 1.
std::vector<std::string> read_lines(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file + ": cannot open the mesh file");
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  return lines;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

/// Comma-separated fields of a CSV row.
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string field;
  while (std::getline(ss, field, ',')) out.push_back(trim(field));
  return out;
}

bool parse_double(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && errno != ERANGE;
}

bool parse_long(const std::string& s, long long& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtoll(s.c_str(), &end, 10);
  return end == s.c_str() + s.size() && errno != ERANGE;
}

bool skipped_line(const std::string& t) { return t.empty() || t[0] == '#'; }

/// A header: the first row, when its first field is not a number.
bool header_row(bool first, const std::vector<std::string>& fields) {
  double v = 0.0;
  return first && !fields.empty() && !parse_double(fields[0], v);
}

/// Whitespace-separated integers (Gmsh's lines); false when a field is not an integer.
bool read_integers(const std::string& line, std::vector<long long>& out) {
  out.clear();
  std::istringstream ss(line);
  std::string field;
  while (ss >> field) {
    long long v = 0;
    if (!parse_long(field, v)) return false;
    out.push_back(v);
  }
  return true;
}

}  // namespace

TetMesh read_tet_mesh_csv(const std::string& vertices_file, const std::string& elements_file) {
  TetMesh mesh;
  {
    const std::vector<std::string> lines = read_lines(vertices_file);
    bool first = true;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const std::string t = trim(lines[i]);
      if (skipped_line(t)) continue;
      const std::vector<std::string> f = csv_fields(t);
      double x[3] = {0.0, 0.0, 0.0};
      const bool numbers = f.size() >= 3 && parse_double(f[0], x[0]) && parse_double(f[1], x[1]) &&
                           parse_double(f[2], x[2]);
      if (header_row(first, f)) {
        first = false;
        continue;
      }
      first = false;
      if (!numbers)
        throw std::runtime_error(located(vertices_file, i + 1, "got \"" + t + "\"; expected x, y, z (three numbers)"));
      if (!std::isfinite(x[0]) || !std::isfinite(x[1]) || !std::isfinite(x[2]))
        throw std::runtime_error(located(vertices_file, i + 1, "got \"" + t + "\"; expected three finite numbers"));
      mesh.vertices.push_back(Vec3d{{x[0], x[1], x[2]}});
    }
    if (mesh.vertices.empty()) throw std::runtime_error(vertices_file + ": no vertices (expected rows x, y, z)");
  }
  {
    const std::vector<std::string> lines = read_lines(elements_file);
    bool first = true;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const std::string t = trim(lines[i]);
      if (skipped_line(t)) continue;
      const std::vector<std::string> f = csv_fields(t);
      long long v[4] = {0, 0, 0, 0};
      bool integers = f.size() >= 4;
      for (int k = 0; k < 4 && integers; ++k) integers = parse_long(f[k], v[k]);
      if (header_row(first, f)) {
        first = false;
        continue;
      }
      first = false;
      if (!integers)
        throw std::runtime_error(
            located(elements_file, i + 1, "got \"" + t + "\"; expected four vertex numbers (integers, from 1)"));
      std::array<int, 4> e{};
      for (int k = 0; k < 4; ++k) {
        if (v[k] < 1 || v[k] > std::numeric_limits<int>::max())
          throw std::runtime_error(located(elements_file, i + 1,
                                           "got vertex number " + std::to_string(v[k]) +
                                               "; expected a number from 1 (ClaymoreUW's element files count "
                                               "vertices from 1)"));
        e[k] = static_cast<int>(v[k] - 1);
      }
      mesh.elements.push_back(e);
    }
    if (mesh.elements.empty()) throw std::runtime_error(elements_file + ": no elements (expected rows a, b, c, d)");
  }
  return mesh;
}

TetMesh read_gmsh_msh41(const std::string& file) {
  const std::vector<std::string> lines = read_lines(file);
  TetMesh mesh;
  std::unordered_map<long long, int> node_index;  // Gmsh node tag -> vertex index
  bool format_seen = false, nodes_seen = false, elements_seen = false;
  std::vector<long long> ints;
  auto fail = [&](std::size_t i, const std::string& what) -> std::runtime_error {
    return std::runtime_error(located(file, i + 1, what));
  };
  auto need = [&](std::size_t i, const char* what) {
    if (i >= lines.size()) throw std::runtime_error(file + ": ends inside " + std::string(what));
  };
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string t = trim(lines[i]);
    if (t.empty()) continue;
    if (t == "$MeshFormat") {
      need(i + 1, "$MeshFormat");
      std::istringstream ss(lines[i + 1]);
      std::string version;
      int type = -1, size = 0;
      ss >> version >> type >> size;
      if (version != "4.1")
        throw fail(i + 1, "got MSH version " + version + "; expected 4.1 (export with gmsh -3 -format msh41)");
      if (type != 0)
        throw fail(i + 1, "a binary MSH file; expected ASCII (export with gmsh -3 -format msh41, without -bin)");
      format_seen = true;
      i += 1;
    } else if (t == "$Nodes") {
      if (!format_seen) throw fail(i, "$Nodes before $MeshFormat; expected a MSH 4.1 file");
      std::size_t at = i + 1;
      need(at, "$Nodes");
      if (!read_integers(lines[at], ints) || ints.size() < 4)
        throw fail(at, "expected numEntityBlocks numNodes minNodeTag maxNodeTag");
      const long long blocks = ints[0], total = ints[1];
      ++at;
      for (long long b = 0; b < blocks; ++b) {
        need(at, "$Nodes");
        if (!read_integers(lines[at], ints) || ints.size() < 4)
          throw fail(at, "expected entityDim entityTag parametric numNodesInBlock");
        const long long n = ints[3];  // parametric coordinates (ints[2]) follow x y z on the line: not needed
        const std::size_t tags = at + 1, coords = at + 1 + static_cast<std::size_t>(n);
        need(coords + static_cast<std::size_t>(n) - (n > 0 ? 1 : 0), "$Nodes");
        for (long long k = 0; k < n; ++k) {
          long long tag = 0;
          if (!parse_long(trim(lines[tags + k]), tag)) throw fail(tags + k, "expected a node tag (an integer)");
          std::istringstream ss(lines[coords + k]);
          double x = 0, y = 0, z = 0;
          if (!(ss >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
            throw fail(coords + k, "expected x y z (three finite numbers)");
          if (!node_index.emplace(tag, static_cast<int>(mesh.vertices.size())).second)
            throw fail(tags + k, "node tag " + std::to_string(tag) + " given twice");
          mesh.vertices.push_back(Vec3d{{x, y, z}});
        }
        at = coords + static_cast<std::size_t>(n);
      }
      if (static_cast<long long>(mesh.vertices.size()) != total)
        throw fail(i + 1, "the header announces " + std::to_string(total) + " nodes; the blocks hold " +
                              std::to_string(mesh.vertices.size()));
      need(at, "$Nodes");
      if (trim(lines[at]) != "$EndNodes") throw fail(at, "expected $EndNodes");
      nodes_seen = true;
      i = at;
    } else if (t == "$Elements") {
      if (!nodes_seen) throw fail(i, "$Elements before $Nodes; expected the nodes first (MSH 4.1)");
      std::size_t at = i + 1;
      need(at, "$Elements");
      if (!read_integers(lines[at], ints) || ints.size() < 4)
        throw fail(at, "expected numEntityBlocks numElements minElementTag maxElementTag");
      const long long blocks = ints[0];
      ++at;
      for (long long b = 0; b < blocks; ++b) {
        need(at, "$Elements");
        if (!read_integers(lines[at], ints) || ints.size() < 4)
          throw fail(at, "expected entityDim entityTag elementType numElementsInBlock");
        const long long type = ints[2], n = ints[3];
        if (type != 4 && type != 15 && type != 1 && type != 2)
          throw fail(at, "element type " + std::to_string(type) +
                             "; expected 4-node tetrahedra (type 4; points, lines and triangles are skipped): mesh "
                             "the volume with linear tetrahedra (gmsh -3 -order 1)");
        for (long long k = 0; k < n; ++k) {
          const std::size_t row = at + 1 + static_cast<std::size_t>(k);
          need(row, "$Elements");
          if (type != 4) continue;
          if (!read_integers(lines[row], ints) || ints.size() < 5)
            throw fail(row, "expected elementTag and four node tags");
          std::array<int, 4> e{};
          for (int c = 0; c < 4; ++c) {
            const auto it = node_index.find(ints[1 + c]);
            if (it == node_index.end())
              throw fail(row, "node tag " + std::to_string(ints[1 + c]) + " is not among the $Nodes");
            e[c] = it->second;
          }
          mesh.elements.push_back(e);
        }
        at += 1 + static_cast<std::size_t>(n);
      }
      need(at, "$Elements");
      if (trim(lines[at]) != "$EndElements") throw fail(at, "expected $EndElements");
      elements_seen = true;
      i = at;
    } else if (t[0] == '$' && t.rfind("$End", 0) != 0) {  // another section: skipped to its end
      const std::string end = "$End" + t.substr(1);
      std::size_t at = i + 1;
      while (at < lines.size() && trim(lines[at]) != end) ++at;
      if (at >= lines.size()) throw std::runtime_error(file + ": " + t + " has no " + end);
      i = at;
    }
  }
  if (!format_seen) throw std::runtime_error(file + ": no $MeshFormat; expected a Gmsh MSH 4.1 ASCII file");
  if (!elements_seen || mesh.elements.empty())
    throw std::runtime_error(file + ": no 4-node tetrahedra (element type 4); expected a volume mesh (gmsh -3)");
  return mesh;
}

double tet_volume(const Vec3d& x0, const Vec3d& x1, const Vec3d& x2, const Vec3d& x3) {
  return dot(x1 - x0, cross(x2 - x0, x3 - x0)) / 6.0;
}

double tet_quality(const Vec3d& x0, const Vec3d& x1, const Vec3d& x2, const Vec3d& x3) {
  const Vec3d* x[4] = {&x0, &x1, &x2, &x3};
  double sum = 0.0;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      const Vec3d d = *x[b] - *x[a];
      sum += dot(d, d);
    }
  const double l_rms = std::sqrt(sum / 6.0);
  if (!(l_rms > 0.0)) return 0.0;
  return 6.0 * std::sqrt(2.0) * tet_volume(x0, x1, x2, x3) / (l_rms * l_rms * l_rms);
}

VertexOutside vertex_outside(const TetMesh& mesh, const Vec3d& offset, const Vec3d& lo, const Vec3d& hi) {
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const Vec3d x = mesh.vertices[v] + offset;
    for (int a = 0; a < 3; ++a)
      if (x[a] < lo[a] || x[a] > hi[a]) return VertexOutside{static_cast<long long>(v), a};
  }
  return {};
}

TetMeshStats check_tet_mesh(const TetMesh& mesh, const std::string& where) {
  TetMeshStats s;
  s.vertices = mesh.vertices.size();
  s.elements = mesh.elements.size();
  if (mesh.elements.empty()) throw std::runtime_error(where + ": no elements");
  const int n = static_cast<int>(mesh.vertices.size());
  auto fmt = [](double v) {
    std::ostringstream o;
    o.precision(6);
    o << v;
    return o.str();
  };
  std::vector<char> used(mesh.vertices.size(), 0);
  s.min_quality = std::numeric_limits<double>::infinity();
  s.min_edge = std::numeric_limits<double>::infinity();
  s.min_height = std::numeric_limits<double>::infinity();
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const std::array<int, 4>& t = mesh.elements[e];
    const std::string name = where + ": element " + std::to_string(e) + " (vertices " + std::to_string(t[0]) + ", " +
                             std::to_string(t[1]) + ", " + std::to_string(t[2]) + ", " + std::to_string(t[3]) + ")";
    for (int c = 0; c < 4; ++c) {
      if (t[c] < 0 || t[c] >= n)
        throw std::runtime_error(name + ": vertex " + std::to_string(t[c]) + " does not exist (the mesh has " +
                                 std::to_string(n) + " vertices, 0 to " + std::to_string(n - 1) + ")");
      for (int d = 0; d < c; ++d)
        if (t[d] == t[c]) throw std::runtime_error(name + ": vertex " + std::to_string(t[c]) + " twice");
    }
    const Vec3d& x0 = mesh.vertices[t[0]];
    const Vec3d& x1 = mesh.vertices[t[1]];
    const Vec3d& x2 = mesh.vertices[t[2]];
    const Vec3d& x3 = mesh.vertices[t[3]];
    const double q = tet_quality(x0, x1, x2, x3);
    const double v = tet_volume(x0, x1, x2, x3);
    if (v < 0.0 && q <= -kMinTetQuality)
      throw std::runtime_error(name + ": inverted (signed volume " + fmt(v) +
                               "); expected (x1 - x0) . ((x2 - x0) x (x3 - x0)) > 0: swap two of its vertices");
    if (q < kMinTetQuality)
      throw std::runtime_error(name + ": degenerate (quality " + fmt(q) + ", volume " + fmt(v) +
                               "); expected a quality 6 sqrt(2) V / l_rms^3 of at least " + fmt(kMinTetQuality));
    if (q < s.min_quality * (1.0 - 1e-9)) {  // equal qualities up to rounding keep the first element (a scaled
      s.min_quality = q;                     // copy of the mesh names the same one)
      s.worst_element = e;
    }
    s.volume += v;
    s.min_height = std::min(s.min_height, tet_min_height(x0, x1, x2, x3));
    const Vec3d* x[4] = {&x0, &x1, &x2, &x3};
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const double l = norm(*x[b] - *x[a]);
        s.min_edge = std::min(s.min_edge, l);
        s.max_edge = std::max(s.max_edge, l);
      }
    for (int c = 0; c < 4; ++c) used[t[c]] = 1;
  }
  s.unused_vertices = static_cast<std::size_t>(std::count(used.begin(), used.end(), 0));
  return s;
}

std::string describe(const TetMeshStats& s) {
  std::ostringstream out;
  out.precision(4);
  out << s.vertices << " vertices, " << s.elements << " tetrahedra, volume " << s.volume << " m^3, edges "
      << s.min_edge << " to " << s.max_edge << " m, smallest quality " << s.min_quality << " (element "
      << s.worst_element << ")";
  if (s.unused_vertices > 0) out << ", " << s.unused_vertices << " vertices in no element";
  return out.str();
}

TetMesh box_tet_mesh(const Vec3d& lo, const Vec3d& hi, const Vec3i& cells) {
  for (int a = 0; a < 3; ++a)
    if (cells[a] < 1 || !(hi[a] > lo[a])) throw std::invalid_argument("box_tet_mesh: an empty box or no cells");
  TetMesh m;
  const int n1 = cells[1] + 1, n2 = cells[2] + 1;
  for (int i = 0; i <= cells[0]; ++i)
    for (int j = 0; j <= cells[1]; ++j)
      for (int k = 0; k <= cells[2]; ++k)
        m.vertices.push_back(Vec3d{{lo[0] + (hi[0] - lo[0]) * i / cells[0], lo[1] + (hi[1] - lo[1]) * j / cells[1],
                                    lo[2] + (hi[2] - lo[2]) * k / cells[2]}});
  const auto id = [&](int i, int j, int k) { return (i * n1 + j) * n2 + k; };
  // The six paths from corner (0,0,0) to (1,1,1) along the axes in each order: one tetrahedron per path.
  static constexpr int kOrder[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int i = 0; i < cells[0]; ++i)
    for (int j = 0; j < cells[1]; ++j)
      for (int k = 0; k < cells[2]; ++k)
        for (const auto& order : kOrder) {
          int c[3] = {i, j, k};
          std::array<int, 4> e;
          e[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[order[s]];
            e[static_cast<std::size_t>(s) + 1] = id(c[0], c[1], c[2]);
          }
          // An odd permutation of the axes gives a left-handed tetrahedron: swap two vertices.
          if (tet_volume(m.vertices[e[0]], m.vertices[e[1]], m.vertices[e[2]], m.vertices[e[3]]) < 0) std::swap(e[2], e[3]);
          m.elements.push_back(e);
        }
  return m;
}

}  // namespace fbar
