// Readers of geometry files (geometry_files.h): SDFGen level sets and particle position files.
#include "geometry/geometry_files.h"

#include <hdf5.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include "MnSystem/IO/h5_frame.h"
#include "MnSystem/IO/particle_io.h"

namespace fbar {
namespace {

std::string lower_extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}
[[noreturn]] void fail_line(const std::string& path, long long line, const std::string& what) {
  throw std::runtime_error(path + ": line " + std::to_string(line) + ": " + what);
}

/// Parses a whole field as a double (surrounding spaces allowed); false when it is not a number.
bool parse_number(std::string_view s, double& out) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  if (s.empty()) return false;
  if (s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

std::vector<std::string_view> split(std::string_view line, bool any_space) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  if (!any_space) {
    while (true) {
      const std::size_t c = line.find(',', i);
      out.push_back(line.substr(i, c == std::string_view::npos ? std::string_view::npos : c - i));
      if (c == std::string_view::npos) break;
      i = c + 1;
    }
    return out;
  }
  const auto sep = [](char c) { return c == ',' || std::isspace(static_cast<unsigned char>(c)); };
  while (i < line.size()) {
    while (i < line.size() && sep(line[i])) ++i;
    if (i >= line.size()) break;
    std::size_t j = i;
    while (j < line.size() && !sep(line[j])) ++j;
    out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

/// A header field's name without its " [unit]" suffix and spaces.
std::string column_name(std::string_view field) {
  std::string s(field);
  const std::size_t bracket = s.find('[');
  if (bracket != std::string::npos) s.resize(bracket);
  s.erase(std::remove_if(s.begin(), s.end(), [](unsigned char c) { return std::isspace(c); }), s.end());
  return s;
}

/// The attribute `names[k]` (or `aliases[k]`) is missing: the error lists what the file holds.
[[noreturn]] void fail_missing(const std::string& path, const std::string& name, const std::vector<std::string>& held,
                               const char* what) {
  std::string list;
  for (const std::string& h : held) list += (list.empty() ? "" : ", ") + h;
  fail(path, "no " + std::string(what) + " named " + name + " (has_attributes; the file holds: " +
                 (list.empty() ? std::string("none") : list) + ")");
}

std::vector<Vec3d> read_text_points(const std::string& path, bool csv, const std::vector<std::string>& names,
                                    const std::vector<std::string>& aliases, std::vector<double>& values) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot open the file");
  if (!names.empty() && !csv)
    fail(path, "a .pos file holds positions only (has_attributes needs a .csv with a header row, a .bgeo or an .h5)");
  std::vector<Vec3d> points;
  int column[3] = {0, 1, 2};
  std::vector<int> attribute_column(names.size(), -1);
  std::string line;
  long long number = 0;
  bool first_row = true;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::string_view v(line);
    while (!v.empty() && std::isspace(static_cast<unsigned char>(v.front()))) v.remove_prefix(1);
    if (v.empty() || v.front() == '#') continue;
    const std::vector<std::string_view> fields = split(v, !csv);
    double first_value = 0.0;
    if (first_row && csv && !parse_number(fields[0], first_value)) {  // a header row names the columns
      first_row = false;
      const char* position_names[3] = {"Position_X", "Position_Y", "Position_Z"};
      for (int a = 0; a < 3; ++a) {
        const auto it = std::find_if(fields.begin(), fields.end(),
                                     [&](std::string_view f) { return column_name(f) == position_names[a]; });
        if (it != fields.end()) {
          column[a] = static_cast<int>(it - fields.begin());
        } else if (fields.size() < 3) {
          fail_line(path, number, "a header without Position_X, Position_Y, Position_Z columns");
        }
      }
      std::vector<std::string> held;
      for (std::string_view f : fields) held.push_back(column_name(f));
      for (std::size_t k = 0; k < names.size(); ++k) {
        auto it = std::find(held.begin(), held.end(), names[k]);
        if (it == held.end() && !aliases[k].empty()) it = std::find(held.begin(), held.end(), aliases[k]);
        if (it == held.end()) fail_missing(path, names[k], held, "column");
        attribute_column[k] = static_cast<int>(it - held.begin());
      }
      continue;
    }
    if (first_row && !names.empty())
      fail_line(path, number, "has_attributes needs a header row naming the columns (e.g. Position_X,Position_Y,"
                              "Position_Z," + names.front() + ")");
    first_row = false;
    Vec3d p{};
    for (int a = 0; a < 3; ++a) {
      if (static_cast<std::size_t>(column[a]) >= fields.size())
        fail_line(path, number, "expected at least " + std::to_string(column[a] + 1) + " values (x, y, z), got " +
                                    std::to_string(fields.size()));
      if (!parse_number(fields[static_cast<std::size_t>(column[a])], p[a]) || !std::isfinite(p[a]))
        fail_line(path, number, "expected a finite number, got \"" +
                                    std::string(fields[static_cast<std::size_t>(column[a])]) + "\"");
    }
    for (std::size_t k = 0; k < names.size(); ++k) {
      const std::size_t c = static_cast<std::size_t>(attribute_column[k]);
      double value = 0.0;
      if (c >= fields.size() || !parse_number(fields[c], value) || !std::isfinite(value))
        fail_line(path, number, "expected a finite number in column " + names[k] + ", got \"" +
                                    (c < fields.size() ? std::string(fields[c]) : std::string()) + "\"");
      values.push_back(value);
    }
    points.push_back(p);
  }
  if (in.bad()) fail(path, "read error");
  return points;
}

std::vector<Vec3d> read_h5_points(const std::string& path, const std::vector<std::string>& names,
                                  const std::vector<std::string>& aliases, std::vector<double>& values) {
  using io::h5_detail::Handle;
  std::lock_guard<std::mutex> lock(io::h5_detail::hdf5_mutex());
  H5E_auto2_t old_func;
  void* old_data;
  H5Eget_auto2(H5E_DEFAULT, &old_func, &old_data);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors become exceptions below, not HDF5's stack dump
  struct Restore {
    H5E_auto2_t f;
    void* d;
    ~Restore() { H5Eset_auto2(H5E_DEFAULT, f, d); }
  } restore{old_func, old_data};
  if (H5Fis_hdf5(path.c_str()) <= 0) fail(path, "not an HDF5 file");
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "open " + path);
  if (H5Lexists(file.get(), "Position", H5P_DEFAULT) <= 0)
    fail(path, "no dataset /Position (an N x 3 array of positions, as fbar's .h5 frames hold)");
  Handle set(H5Dopen2(file.get(), "Position", H5P_DEFAULT), H5Dclose, "open /Position in " + path);
  Handle space(H5Dget_space(set.get()), H5Sclose, "read the shape of /Position in " + path);
  hsize_t dims[2] = {0, 0};
  if (H5Sget_simple_extent_ndims(space.get()) != 2 || H5Sget_simple_extent_dims(space.get(), dims, nullptr) != 2 ||
      dims[1] != 3)
    fail(path, "/Position is not an N x 3 array");
  std::vector<double> raw(static_cast<std::size_t>(dims[0]) * 3);
  if (!raw.empty() && H5Dread(set.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()) < 0)
    fail(path, "cannot read /Position");
  std::vector<Vec3d> points(static_cast<std::size_t>(dims[0]));
  for (std::size_t i = 0; i < points.size(); ++i) points[i] = Vec3d{{raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]}};
  if (names.empty()) return points;
  // Attributes: datasets of N values (N or N x 1), read as doubles, stored point-major.
  std::vector<std::string> held;
  H5Literate(
      file.get(), H5_INDEX_NAME, H5_ITER_NATIVE, nullptr,
      [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
        static_cast<std::vector<std::string>*>(data)->push_back(name);
        return 0;
      },
      &held);
  const std::size_t n = points.size(), K = names.size();
  values.assign(n * K, 0.0);
  std::vector<double> column(n);
  for (std::size_t k = 0; k < K; ++k) {
    std::string name = names[k];
    if (H5Lexists(file.get(), name.c_str(), H5P_DEFAULT) <= 0 && !aliases[k].empty()) name = aliases[k];
    if (H5Lexists(file.get(), name.c_str(), H5P_DEFAULT) <= 0) fail_missing(path, names[k], held, "dataset");
    Handle a(H5Dopen2(file.get(), name.c_str(), H5P_DEFAULT), H5Dclose, "open /" + name + " in " + path);
    Handle as(H5Dget_space(a.get()), H5Sclose, "read the shape of /" + name + " in " + path);
    hsize_t ad[2] = {0, 0};
    const int rank = H5Sget_simple_extent_ndims(as.get());
    if (rank < 1 || rank > 2 || H5Sget_simple_extent_dims(as.get(), ad, nullptr) != rank || ad[0] != n ||
        (rank == 2 && ad[1] != 1))
      fail(path, "/" + name + " is not one value per point (" + std::to_string(n) + " points)");
    if (n && H5Dread(a.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, column.data()) < 0)
      fail(path, "cannot read /" + name);
    for (std::size_t i = 0; i < n; ++i) values[i * K + k] = column[i];
  }
  return points;
}

/// The named one-component attributes of a bgeo frame, point-major.
void bgeo_attributes(const std::string& path, const io::ParticleFrame& frame, const std::vector<std::string>& names,
                     const std::vector<std::string>& aliases, std::vector<double>& values) {
  const std::size_t n = frame.size(), K = names.size();
  values.assign(n * K, 0.0);
  for (std::size_t k = 0; k < K; ++k) {
    const io::FrameAttribute* a = frame.find(names[k]);
    if (!a && !aliases[k].empty()) a = frame.find(aliases[k]);
    if (!a) {
      std::vector<std::string> held;
      for (const io::FrameAttribute& h : frame.attributes) held.push_back(h.name);
      fail_missing(path, names[k], held, "attribute");
    }
    if (a->width != 1)
      fail(path, "attribute " + a->name + " has " + std::to_string(a->width) +
                     " components per point (has_attributes reads one-component attributes such as Velocity_X)");
    std::visit(
        [&](const auto& v) {
          for (std::size_t i = 0; i < n; ++i) values[i * K + k] = static_cast<double>(v[i]);
        },
        a->values);
  }
}

}  // namespace

double SdfGrid::value(const Vec3d& u) const {
  int base[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    if (!(u[a] >= 0.0) || u[a] > static_cast<double>(n[a] - 1)) return std::numeric_limits<double>::infinity();
    base[a] = std::min(static_cast<int>(u[a]), std::max(n[a] - 2, 0));
    f[a] = u[a] - base[a];
  }
  const auto w = [&](int a, int o) { return n[a] == 1 ? (o == 0 ? 1.0 : 0.0) : (o == 0 ? 1.0 - f[a] : f[a]); };
  double sum = 0.0;
  for (int c = 0; c < 8; ++c) {
    const int o[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
    const double weight = w(0, o[0]) * w(1, o[1]) * w(2, o[2]);
    if (weight == 0.0) continue;
    sum += weight * at(std::min(base[0] + o[0], n[0] - 1), std::min(base[1] + o[1], n[1] - 1),
                       std::min(base[2] + o[2], n[2] - 1));
  }
  return sum;
}

std::shared_ptr<const SdfGrid> read_sdf(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot open the file");
  auto grid = std::make_shared<SdfGrid>();
  long long n[3];
  if (!(in >> n[0] >> n[1] >> n[2]))
    fail(path, "expected the grid size \"ni nj nk\" on the first line (SDFGen's .sdf format)");
  for (int a = 0; a < 3; ++a) {
    if (n[a] < 2 || n[a] > 100000)
      fail(path, "grid size " + std::to_string(n[a]) + " on axis " + std::to_string(a) + " (expected 2 .. 100000)");
    grid->n[a] = static_cast<int>(n[a]);
  }
  if (static_cast<double>(n[0]) * n[1] * n[2] > 2e9) fail(path, "more than 2e9 grid values");
  if (!(in >> grid->origin[0] >> grid->origin[1] >> grid->origin[2]))
    fail(path, "expected the origin \"x y z\" on the second line (SDFGen's .sdf format)");
  if (!(in >> grid->dx) || !(grid->dx > 0.0) || !std::isfinite(grid->dx))
    fail(path, "expected a positive grid spacing dx on the third line (SDFGen's .sdf format)");
  const std::size_t total = static_cast<std::size_t>(n[0] * n[1] * n[2]);
  grid->phi.resize(total);
  for (std::size_t i = 0; i < total; ++i) {
    double v;
    if (!(in >> v))
      fail(path, "holds " + std::to_string(i) + " of the " + std::to_string(total) + " values that its size " +
                     std::to_string(n[0]) + " x " + std::to_string(n[1]) + " x " + std::to_string(n[2]) + " needs");
    if (!std::isfinite(v)) fail(path, "value " + std::to_string(i) + " is not finite");
    grid->phi[i] = static_cast<float>(v);
  }
  std::string extra;
  if (in >> extra) fail(path, "holds more than the " + std::to_string(total) + " values its size needs");
  return grid;
}

GeometryFileKind geometry_file_kind(const std::string& path) {
  const std::string e = lower_extension(path);
  if (e == ".sdf") return GeometryFileKind::Sdf;
  if (e == ".csv" || e == ".pos" || e == ".bgeo" || e == ".h5") return GeometryFileKind::Points;
  return GeometryFileKind::Unknown;
}

const char* geometry_file_extensions() { return ".sdf (a solid), .csv, .pos, .bgeo or .h5 (particle positions)"; }

std::vector<Vec3d> read_point_file(const std::string& path) {
  std::vector<double> none;
  return read_point_file(path, {}, {}, none);
}

std::vector<Vec3d> read_point_file(const std::string& path, const std::vector<std::string>& names,
                                   const std::vector<std::string>& aliases, std::vector<double>& values) {
  if (aliases.size() != names.size()) throw std::invalid_argument("read_point_file: one alias per name");
  values.clear();
  const std::string e = lower_extension(path);
  std::vector<Vec3d> points;
  if (e == ".csv" || e == ".pos") {
    points = read_text_points(path, e == ".csv", names, aliases, values);
  } else if (e == ".bgeo") {
    const io::ParticleFrame frame = io::read_bgeo(path);
    if (!names.empty()) bgeo_attributes(path, frame, names, aliases, values);
    std::visit(
        [&](const auto& x) {
          points.reserve(x.size());
          for (const auto& p : x)
            points.push_back(Vec3d{{static_cast<double>(p[0]), static_cast<double>(p[1]), static_cast<double>(p[2])}});
        },
        frame.positions);
  } else if (e == ".h5") {
    points = read_h5_points(path, names, aliases, values);
  } else {
    fail(path, std::string("not a point file (expected ") + geometry_file_extensions() + ")");
  }
  if (points.empty()) fail(path, "holds no points");
  for (const Vec3d& p : points)
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) fail(path, "holds a non-finite position");
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
      fail(path, "attribute " + names[i % names.size()] + " of point " + std::to_string(i / names.size()) +
                     " is not finite");
  return points;
}

}  // namespace fbar
