// HDF5 checkpoints (checkpoint.h).
#include "io/checkpoint.h"

#include <hdf5.h>

#include <algorithm>
#include <cstring>
#include <mutex>
#include <numeric>
#include <regex>
#include <stdexcept>
#include <system_error>

#include "MnSystem/IO/h5_frame.h"
#include "physics/constitutive_models.cuh"
#include "scene/scene.h"
#include "scene/scene_parse.h"

namespace fbar::io {
namespace {

using h5_detail::Handle;
using h5_detail::untimed;

std::string describe(const std::filesystem::path& path) { return "checkpoint " + path.string(); }

// ------------------------------------------------------------------------------------------------ attributes
void put_attr(hid_t where, const char* name, hid_t type, const void* value, const std::string& file) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose, "create a scalar dataspace");
  Handle attr(H5Acreate2(where, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
              std::string("create attribute ") + name + " in " + file);
  if (H5Awrite(attr.get(), type, value) < 0)
    throw h5_detail::failure(std::string("write attribute ") + name + " of " + file);
}
void put_double(hid_t where, const char* name, double v, const std::string& file) {
  put_attr(where, name, H5T_NATIVE_DOUBLE, &v, file);
}
void put_int(hid_t where, const char* name, long long v, const std::string& file) {
  put_attr(where, name, H5T_NATIVE_LLONG, &v, file);
}
void put_string(hid_t where, const char* name, const std::string& v, const std::string& file) {
  Handle str(H5Tcopy(H5T_C_S1), H5Tclose, "make a string type");
  H5Tset_size(str.get(), std::max<std::size_t>(v.size(), 1));
  const std::string padded = v.empty() ? std::string(1, '\0') : v;
  put_attr(where, name, str.get(), padded.c_str(), file);
}

Handle open_attr(hid_t where, const char* name, const std::string& file) {
  if (H5Aexists(where, name) <= 0)
    throw std::runtime_error(file + ": attribute '" + std::string(name) + "' is missing (not an fbar checkpoint?)");
  return Handle(H5Aopen(where, name, H5P_DEFAULT), H5Aclose, std::string("open attribute ") + name + " of " + file);
}
double get_double(hid_t where, const char* name, const std::string& file) {
  Handle a = open_attr(where, name, file);
  double v = 0;
  if (H5Aread(a.get(), H5T_NATIVE_DOUBLE, &v) < 0)
    throw std::runtime_error("HDF5: cannot read attribute " + std::string(name) + " of " + file);
  return v;
}
long long get_int(hid_t where, const char* name, const std::string& file) {
  Handle a = open_attr(where, name, file);
  long long v = 0;
  if (H5Aread(a.get(), H5T_NATIVE_LLONG, &v) < 0)
    throw std::runtime_error("HDF5: cannot read attribute " + std::string(name) + " of " + file);
  return v;
}
std::string get_string(hid_t where, const char* name, const std::string& file) {
  Handle a = open_attr(where, name, file);
  Handle type(H5Aget_type(a.get()), H5Tclose, "read the type of attribute " + std::string(name));
  const std::size_t n = H5Tget_size(type.get());
  std::string v(n, '\0');
  Handle mem(H5Tcopy(H5T_C_S1), H5Tclose, "make a string type");
  H5Tset_size(mem.get(), n);
  if (H5Aread(a.get(), mem.get(), v.data()) < 0)
    throw std::runtime_error("HDF5: cannot read attribute " + std::string(name) + " of " + file);
  v.resize(std::strlen(v.c_str()));
  return v;
}

// ------------------------------------------------------------------------------------------------ datasets
template <class V>
void put_array(hid_t where, const char* name, const std::vector<V>& data, std::size_t rows, int width, hid_t file_type,
               hid_t mem_type, const std::string& file) {
  if (data.size() != rows * static_cast<std::size_t>(width))
    throw std::logic_error(std::string("checkpoint: ") + name + " has the wrong size");
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(width)};
  Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose, "create a dataspace for " + file);
  const Handle dcpl = untimed(H5P_DATASET_CREATE, file);
  Handle set(H5Dcreate2(where, name, file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose,
             std::string("create dataset ") + name + " in " + file);
  if (rows > 0 && H5Dwrite(set.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0)
    throw h5_detail::failure(std::string("write dataset ") + name + " of " + file);
}

using Emit = std::function<void(std::size_t rows, const void* values)>;
using Pieces = std::function<void(const Emit&)>;

/// A dataset of rows x width written piece by piece (pieces(emit) calls emit(rows, values) in row order, `rows` in
/// all); `narrow`: the values come as doubles and are written as float32, converted here a piece at a time (HDF5's
/// own conversion is several times slower).
void put_pieces(hid_t where, const char* name, std::size_t rows, int width, hid_t file_type, hid_t mem_type,
                bool narrow, const Pieces& pieces, const std::string& file) {
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(width)};
  Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose, "create a dataspace for " + file);
  const Handle dcpl = untimed(H5P_DATASET_CREATE, file);
  Handle set(H5Dcreate2(where, name, file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose,
             std::string("create dataset ") + name + " in " + file);
  hsize_t done = 0;
  std::vector<float> floats;
  pieces([&](std::size_t count, const void* values) {
    if (count == 0) return;
    if (done + count > rows)
      throw std::logic_error(std::string("checkpoint: more rows of ") + name + " than " + std::to_string(rows));
    if (narrow) {
      const double* d = static_cast<const double*>(values);
      floats.assign(d, d + count * static_cast<std::size_t>(width));
      values = floats.data();
    }
    const hsize_t start[2] = {done, 0};
    const hsize_t piece[2] = {static_cast<hsize_t>(count), static_cast<hsize_t>(width)};
    Handle memory(H5Screate_simple(2, piece, nullptr), H5Sclose, "create a dataspace for " + file);
    if (H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, piece, nullptr) < 0 ||
        H5Dwrite(set.get(), mem_type, memory.get(), space.get(), H5P_DEFAULT, values) < 0)
      throw h5_detail::failure(std::string("write dataset ") + name + " of " + file);
    done += count;
  });
  if (done != rows)
    throw std::logic_error(std::string("checkpoint: ") + std::to_string(done) + " rows of " + name + " for " +
                           std::to_string(rows));
}

/// The pieces of an array in memory: kPieceRows rows at a time.
template <class V>
Pieces pieces_of(const std::vector<V>& data, std::size_t rows, int width, const char* name) {
  if (data.size() != rows * static_cast<std::size_t>(width))
    throw std::logic_error(std::string("checkpoint: ") + name + " has the wrong size");
  return [&data, rows, width](const Emit& emit) {
    constexpr std::size_t kPieceRows = std::size_t(1) << 22;
    for (std::size_t first = 0; first < rows; first += kPieceRows)
      emit(std::min(kPieceRows, rows - first), data.data() + first * static_cast<std::size_t>(width));
  };
}

template <class V>
std::vector<V> get_array(hid_t where, const char* name, std::size_t rows, int width, hid_t mem_type,
                         const std::string& file) {
  if (H5Lexists(where, name, H5P_DEFAULT) <= 0)
    throw std::runtime_error(file + ": dataset '" + std::string(name) + "' is missing");
  Handle set(H5Dopen2(where, name, H5P_DEFAULT), H5Dclose, std::string("open dataset ") + name + " of " + file);
  Handle space(H5Dget_space(set.get()), H5Sclose, "read the dataspace of " + std::string(name));
  hsize_t dims[2] = {0, 0};
  const int rank = H5Sget_simple_extent_ndims(space.get());
  H5Sget_simple_extent_dims(space.get(), dims, nullptr);
  if (rank != 2 || dims[0] != rows || dims[1] != static_cast<hsize_t>(width))
    throw std::runtime_error(file + ": dataset '" + std::string(name) + "' has the wrong shape (expected " +
                             std::to_string(rows) + " x " + std::to_string(width) + ")");
  std::vector<V> out(rows * static_cast<std::size_t>(width));
  if (rows > 0 && H5Dread(set.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw std::runtime_error(std::string("HDF5: cannot read dataset ") + name + " of " + file);
  return out;
}

// HDF5 prints its own error stack to stderr on every failed call; our messages say what failed, and why.
using QuietHdf5 = h5_detail::Quiet;

/// A real array stored as float32 or float64, as double.
std::vector<double> get_reals(hid_t where, const char* name, std::size_t rows, int width, const std::string& file) {
  std::size_t bytes = 8;
  if (H5Lexists(where, name, H5P_DEFAULT) > 0) {
    Handle set(H5Dopen2(where, name, H5P_DEFAULT), H5Dclose, std::string("open dataset ") + name + " of " + file);
    Handle type(H5Dget_type(set.get()), H5Tclose, std::string("read the type of ") + name);
    bytes = H5Tget_size(type.get());
  }
  if (bytes != 4) return get_array<double>(where, name, rows, width, H5T_NATIVE_DOUBLE, file);
  const std::vector<float> narrow = get_array<float>(where, name, rows, width, H5T_NATIVE_FLOAT, file);
  return std::vector<double>(narrow.begin(), narrow.end());
}

}  // namespace

std::filesystem::path checkpoint_frame_path(const std::filesystem::path& dir, int frame, int rank) {
  return dir / ("checkpoint_frame[" + std::to_string(frame) + "]_dev[" + std::to_string(rank) + "].h5");
}

std::filesystem::path checkpoint_step_path(const std::filesystem::path& dir, long long step, int rank) {
  return dir / ("checkpoint_step[" + std::to_string(step) + "]_dev[" + std::to_string(rank) + "].h5");
}

std::filesystem::path checkpoint_rank_path(const std::filesystem::path& given, int rank) {
  const std::string name = given.filename().string();
  static const std::regex dev(R"(_dev\[(\d+)\])");
  std::smatch m;
  if (!std::regex_search(name, m, dev)) {
    if (rank == 0) return given;
    throw std::invalid_argument("--restart: " + given.string() +
                                " has no _dev[d] part, so the files of the other ranks cannot be found");
  }
  return given.parent_path() /
         (m.prefix().str() + "_dev[" + std::to_string(rank) + "]" + m.suffix().str());
}

void write_checkpoint(const std::filesystem::path& path, const Checkpoint& c) {
  const std::string file = describe(path);
  const bool single = c.precision == "single";
  std::filesystem::path part = path;
  part += ".part";
  try {
    std::lock_guard<std::mutex> lock(h5_detail::hdf5_mutex());
    QuietHdf5 quiet;
    const Handle fcpl = untimed(H5P_FILE_CREATE, part.string());
    Handle f(H5Fcreate(part.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose, "create " + part.string());
    const hid_t root = f.get();
    put_int(root, "format", c.format, file);
    put_string(root, "precision", c.precision, file);
    put_string(root, "engine", c.engine, file);
    put_string(root, "reason", c.reason, file);
    put_int(root, "rank", c.rank, file);
    put_int(root, "ranks", c.ranks, file);
    put_double(root, "start_time", c.start_time, file);
    put_double(root, "time", c.time, file);
    put_int(root, "steps", c.steps, file);
    put_int(root, "frame", c.frame, file);
    put_double(root, "last_dt", c.last_dt, file);
    put_double(root, "next_dt", c.next_dt, file);
    put_double(root, "max_grid_speed", c.max_grid_speed, file);
    put_double(root, "dt_scale", c.dt_scale, file);
    put_int(root, "clean_steps", c.clean_steps, file);
    put_int(root, "slab_axis", c.slab_axis, file);
    put_double(root, "chosen_imbalance", c.chosen_imbalance, file);
    put_int(root, "particle_sample_due", c.particle_sample_due ? 1 : 0, file);
    put_int(root, "bodies", static_cast<long long>(c.bodies.size()), file);
    put_array(root, "slab_cuts", c.slab_cuts, c.slab_cuts.size(), 1, H5T_STD_I32LE, H5T_NATIVE_INT, file);
    {
      const Handle gcpl = untimed(H5P_GROUP_CREATE, file);
      Handle g(H5Gcreate2(root, "csv", H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose, "create group csv in " + file);
      put_int(g.get(), "files", static_cast<long long>(c.csv.size()), file);
      for (std::size_t i = 0; i < c.csv.size(); ++i) {
        put_string(g.get(), ("name" + std::to_string(i)).c_str(), c.csv[i].first, file);
        put_int(g.get(), ("bytes" + std::to_string(i)).c_str(), c.csv[i].second, file);
      }
    }
    for (std::size_t b = 0; b < c.bodies.size(); ++b) {
      const CheckpointBody& body = c.bodies[b];
      const std::string group = "body" + std::to_string(b);
      const Handle gcpl = untimed(H5P_GROUP_CREATE, file);
      Handle g(H5Gcreate2(root, group.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose,
               "create group " + group + " in " + file);
      const hid_t w = g.get();
      const bool streamed = c.is_streamed(b);
      const std::size_t n = streamed ? c.streamed[b].particles : body.particles();
      put_string(w, "law", body.law, file);
      put_int(w, "state_scalars", body.state_scalars, file);
      put_int(w, "particles", static_cast<long long>(n), file);
      put_int(w, "global_particles", body.global_particles, file);
      put_double(w, "max_wave_speed", body.max_wave_speed, file);
      put_double(w, "p2g_bound", body.p2g_bound, file);
      put_int(w, "p2g_capture", body.p2g_capture ? 1 : 0, file);
      const std::size_t p2g_rows = streamed ? c.streamed[b].p2g_rows : body.p2g_id.size();
      auto source = [&](CheckpointDataset d, const auto& data, std::size_t rows, int width, const char* name) -> Pieces {
        if (!streamed) return pieces_of(data, rows, width, name);
        return [&c, b, d](const Emit& emit) { c.streamed[b].pieces(d, emit); };
      };
      auto reals = [&](CheckpointDataset d, const char* name, const std::vector<double>& data, int width) {
        put_pieces(w, name, n, width, single ? H5T_IEEE_F32LE : H5T_IEEE_F64LE, single ? H5T_NATIVE_FLOAT : H5T_NATIVE_DOUBLE,
                   single, source(d, data, n, width, name), file);
      };
      put_pieces(w, "ID", n, 1, H5T_STD_I64LE, H5T_NATIVE_INT64, false, source(CheckpointDataset::Id, body.id, n, 1, "ID"),
                 file);
      reals(CheckpointDataset::Position, "Position", body.x, 3);
      reals(CheckpointDataset::Velocity, "Velocity", body.v, 3);
      reals(CheckpointDataset::C, "C", body.C, 9);
      reals(CheckpointDataset::Mass, "Mass", body.mass, 1);
      reals(CheckpointDataset::Volume, "Volume", body.volume, 1);
      reals(CheckpointDataset::State, "State", body.state, body.state_scalars);
      put_int(w, "p2g_blocks", body.p2g_known ? 1 : 0, file);
      if (body.p2g_known) {
        put_pieces(w, "P2GID", p2g_rows, 1, H5T_STD_I64LE, H5T_NATIVE_INT64, false,
                   source(CheckpointDataset::P2GId, body.p2g_id, p2g_rows, 1, "P2GID"), file);
        put_pieces(w, "P2GBlock", p2g_rows, 3, H5T_STD_I32LE, H5T_NATIVE_INT32, false,
                   source(CheckpointDataset::P2GBlock, body.p2g_block, p2g_rows, 3, "P2GBlock"), file);
      }
    }
    if (f.release() < 0) throw h5_detail::failure("close " + part.string());
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(part, ec);  // no half-written .part left behind
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(part, path, ec);
  if (ec) throw std::runtime_error("cannot rename " + part.string() + " to " + path.string() + ": " + ec.message());
}

Checkpoint read_checkpoint(const std::filesystem::path& path, bool particles) {
  const std::string file = describe(path);
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error(file + ": no such file");
  std::lock_guard<std::mutex> lock(h5_detail::hdf5_mutex());
  QuietHdf5 quiet;
  if (H5Fis_hdf5(path.c_str()) <= 0) throw std::runtime_error(file + ": not an HDF5 file");
  Handle f(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "open " + path.string());
  const hid_t root = f.get();
  Checkpoint c;
  c.format = static_cast<int>(get_int(root, "format", file));
  if (c.format != Checkpoint::kFormat)
    throw std::runtime_error(file + ": checkpoint format " + std::to_string(c.format) + ", this fbar reads format " +
                             std::to_string(Checkpoint::kFormat));
  c.precision = get_string(root, "precision", file);
  c.engine = get_string(root, "engine", file);
  c.reason = get_string(root, "reason", file);
  c.rank = static_cast<int>(get_int(root, "rank", file));
  c.ranks = static_cast<int>(get_int(root, "ranks", file));
  c.start_time = get_double(root, "start_time", file);
  c.time = get_double(root, "time", file);
  c.steps = get_int(root, "steps", file);
  c.frame = static_cast<int>(get_int(root, "frame", file));
  c.last_dt = get_double(root, "last_dt", file);
  c.next_dt = get_double(root, "next_dt", file);
  c.max_grid_speed = get_double(root, "max_grid_speed", file);
  c.dt_scale = get_double(root, "dt_scale", file);
  c.clean_steps = static_cast<int>(get_int(root, "clean_steps", file));
  c.slab_axis = static_cast<int>(get_int(root, "slab_axis", file));
  c.chosen_imbalance = get_double(root, "chosen_imbalance", file);
  c.particle_sample_due = H5Aexists(root, "particle_sample_due") > 0 && get_int(root, "particle_sample_due", file) != 0;
  {
    Handle set(H5Dopen2(root, "slab_cuts", H5P_DEFAULT), H5Dclose, "open dataset slab_cuts of " + file);
    Handle space(H5Dget_space(set.get()), H5Sclose, "read the dataspace of slab_cuts");
    hsize_t dims[2] = {0, 0};
    H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    c.slab_cuts = get_array<int>(root, "slab_cuts", dims[0], 1, H5T_NATIVE_INT, file);
  }
  {
    Handle g(H5Gopen2(root, "csv", H5P_DEFAULT), H5Gclose, "open group csv of " + file);
    const long long n = get_int(g.get(), "files", file);
    for (long long i = 0; i < n; ++i)
      c.csv.emplace_back(get_string(g.get(), ("name" + std::to_string(i)).c_str(), file),
                         get_int(g.get(), ("bytes" + std::to_string(i)).c_str(), file));
  }
  const long long bodies = get_int(root, "bodies", file);
  if (!particles) {
    c.bodies.resize(static_cast<std::size_t>(bodies));
    return c;
  }
  for (long long b = 0; b < bodies; ++b) {
    const std::string group = "body" + std::to_string(b);
    if (H5Lexists(root, group.c_str(), H5P_DEFAULT) <= 0) throw std::runtime_error(file + ": group " + group + " is missing");
    Handle g(H5Gopen2(root, group.c_str(), H5P_DEFAULT), H5Gclose, "open group " + group + " of " + file);
    const hid_t w = g.get();
    CheckpointBody body;
    body.law = get_string(w, "law", file);
    body.state_scalars = static_cast<int>(get_int(w, "state_scalars", file));
    const auto n = static_cast<std::size_t>(get_int(w, "particles", file));
    body.global_particles = get_int(w, "global_particles", file);
    body.max_wave_speed = get_double(w, "max_wave_speed", file);
    body.p2g_bound = H5Aexists(w, "p2g_bound") > 0 ? get_double(w, "p2g_bound", file) : -1.0;
    body.p2g_capture = H5Aexists(w, "p2g_capture") > 0 && get_int(w, "p2g_capture", file) != 0;
    body.id = get_array<std::int64_t>(w, "ID", n, 1, H5T_NATIVE_INT64, file);
    body.x = get_reals(w, "Position", n, 3, file);
    body.v = get_reals(w, "Velocity", n, 3, file);
    body.C = get_reals(w, "C", n, 9, file);
    body.mass = get_reals(w, "Mass", n, 1, file);
    body.volume = get_reals(w, "Volume", n, 1, file);
    body.state = get_reals(w, "State", n, body.state_scalars, file);
    body.p2g_known = H5Aexists(w, "p2g_blocks") > 0 && get_int(w, "p2g_blocks", file) != 0;
    if (body.p2g_known) {
      hsize_t dims[2] = {0, 0};
      {
        if (H5Lexists(w, "P2GID", H5P_DEFAULT) <= 0) throw std::runtime_error(file + ": dataset 'P2GID' is missing");
        Handle set(H5Dopen2(w, "P2GID", H5P_DEFAULT), H5Dclose, "open dataset P2GID of " + file);
        Handle space(H5Dget_space(set.get()), H5Sclose, "read the dataspace of P2GID");
        H5Sget_simple_extent_dims(space.get(), dims, nullptr);
      }
      const auto m = static_cast<std::size_t>(dims[0]);
      body.p2g_id = get_array<std::int64_t>(w, "P2GID", m, 1, H5T_NATIVE_INT64, file);
      body.p2g_block = get_array<std::int32_t>(w, "P2GBlock", m, 3, H5T_NATIVE_INT32, file);
    }
    c.bodies.push_back(std::move(body));
  }
  return c;
}

Checkpoint read_checkpoint_set(const std::filesystem::path& given) {
  Checkpoint first = read_checkpoint(checkpoint_rank_path(given, 0));
  std::vector<Checkpoint> parts;
  parts.push_back(std::move(first));
  for (int r = 1; r < parts[0].ranks; ++r) {
    const std::filesystem::path p = checkpoint_rank_path(given, r);
    Checkpoint c = read_checkpoint(p);
    if (c.steps != parts[0].steps || c.time != parts[0].time || c.ranks != parts[0].ranks || c.rank != r ||
        c.bodies.size() != parts[0].bodies.size())
      throw std::runtime_error(describe(p) + ": not of the same checkpoint as rank 0's (step " +
                               std::to_string(c.steps) + " vs " + std::to_string(parts[0].steps) + ")");
    parts.push_back(std::move(c));
  }
  return merge_checkpoints(std::move(parts), describe(given));
}

Checkpoint merge_checkpoints(std::vector<Checkpoint> parts, const std::string& what) {
  if (parts.empty()) throw std::invalid_argument(what + ": no rank's state to merge");
  // Rank 0's header and body descriptions, without its particle arrays (they are read from parts[0] below).
  Checkpoint all;
  {
    std::vector<CheckpointBody> bodies = std::move(parts[0].bodies);
    all = parts[0];
    for (const CheckpointBody& b : bodies) all.bodies.push_back(b.description());
    parts[0].bodies = std::move(bodies);
  }
  all.rank = 0;
  all.ranks = 1;
  all.slab_cuts.clear();
  for (std::size_t b = 0; b < all.bodies.size(); ++b) {
    CheckpointBody& out = all.bodies[b];
    const int S = out.state_scalars;
    std::vector<const CheckpointBody*> from;
    std::size_t total = 0;
    for (const Checkpoint& c : parts) {
      from.push_back(&c.bodies[b]);
      total += c.bodies[b].particles();
      out.max_wave_speed = std::max(out.max_wave_speed, c.bodies[b].max_wave_speed);
      out.p2g_bound = std::max(out.p2g_bound, c.bodies[b].p2g_bound);  // the same on every rank
      out.p2g_capture = out.p2g_capture || c.bodies[b].p2g_capture;    // likewise
    }
    if (total != static_cast<std::size_t>(out.global_particles))
      throw std::runtime_error(what + ": body " + std::to_string(b) + " has " + std::to_string(total) +
                               " particles over the ranks' files, " + std::to_string(out.global_particles) +
                               " expected");
    // Every particle by ID: slot = ID, as a one-rank run holds them.
    out.id.assign(total, -1);
    out.x.assign(3 * total, 0.0);
    out.v.assign(3 * total, 0.0);
    out.C.assign(9 * total, 0.0);
    out.mass.assign(total, 0.0);
    out.volume.assign(total, 0.0);
    out.state.assign(static_cast<std::size_t>(S) * total, 0.0);
    for (const CheckpointBody* src : from)
      for (std::size_t p = 0; p < src->particles(); ++p) {
        const std::int64_t id = src->id[p];
        if (id < 0 || static_cast<std::size_t>(id) >= total || out.id[static_cast<std::size_t>(id)] >= 0)
          throw std::runtime_error(what + ": body " + std::to_string(b) + ": particle ID " +
                                   std::to_string(id) + " is out of range or on several ranks");
        const auto q = static_cast<std::size_t>(id);
        out.id[q] = id;
        std::copy_n(src->x.begin() + 3 * p, 3, out.x.begin() + 3 * q);
        std::copy_n(src->v.begin() + 3 * p, 3, out.v.begin() + 3 * q);
        std::copy_n(src->C.begin() + 9 * p, 9, out.C.begin() + 9 * q);
        out.mass[q] = src->mass[p];
        out.volume[q] = src->volume[p];
        std::copy_n(src->state.begin() + S * p, S, out.state.begin() + S * q);
      }
    // The blocks of the last P2G, by ID, when every rank recorded its share (each particle summed on one rank).
    out.p2g_known = std::all_of(from.begin(), from.end(), [](const CheckpointBody* c) { return c->p2g_known; });
    if (out.p2g_known) {
      out.p2g_id.resize(total);
      std::iota(out.p2g_id.begin(), out.p2g_id.end(), std::int64_t{0});
      out.p2g_block.assign(3 * total, 0);
      std::vector<char> seen(total, 0);
      std::size_t summed = 0;
      for (const CheckpointBody* src : from) {
        if (src->p2g_block.size() != 3 * src->p2g_id.size())
          throw std::runtime_error(what + ": body " + std::to_string(b) + ": P2GBlock does not match P2GID");
        for (std::size_t p = 0; p < src->p2g_id.size(); ++p) {
          const std::int64_t id = src->p2g_id[p];
          if (id < 0 || static_cast<std::size_t>(id) >= total || seen[static_cast<std::size_t>(id)])
            throw std::runtime_error(what + ": body " + std::to_string(b) + ": particle ID " + std::to_string(id) +
                                     " of P2GID is out of range or on several ranks");
          seen[static_cast<std::size_t>(id)] = 1;
          std::copy_n(src->p2g_block.begin() + 3 * p, 3, out.p2g_block.begin() + 3 * static_cast<std::size_t>(id));
          ++summed;
        }
      }
      if (summed != total)
        throw std::runtime_error(what + ": body " + std::to_string(b) + ": P2GID lists " + std::to_string(summed) +
                                 " particles over the ranks' files, " + std::to_string(total) + " expected");
    }
  }
  return all;
}

// Particle arrays as bytes: per body the particle count, the largest wave speed, then id, x, v, C, mass, volume and
// state, each as the vector's raw bytes (one process's or one host's in-memory exchange: native byte order).
namespace {
template <typename V>
void put_raw(std::vector<std::uint8_t>& out, const V* data, std::size_t n) {
  const auto* b = reinterpret_cast<const std::uint8_t*>(data);
  out.insert(out.end(), b, b + sizeof(V) * n);
}
template <typename V>
void take_raw(const std::vector<std::uint8_t>& in, std::size_t& at, V* data, std::size_t n) {
  const std::size_t bytes = sizeof(V) * n;
  if (at + bytes > in.size()) throw std::runtime_error("checkpoint particles: the byte stream ends early");
  if (bytes) std::memcpy(data, in.data() + at, bytes);
  at += bytes;
}
}  // namespace

std::vector<std::uint8_t> checkpoint_particle_bytes(const Checkpoint& c) {
  std::vector<std::uint8_t> out;
  std::size_t total = 0;
  for (const CheckpointBody& b : c.bodies)
    total += 40 + b.particles() * (8 * (1 + 3 + 3 + 9 + 1 + 1) + 8 * static_cast<std::size_t>(b.state_scalars)) +
             b.p2g_id.size() * (8 + 12);
  out.reserve(total);
  for (const CheckpointBody& b : c.bodies) {
    const std::uint64_t n = b.particles();
    put_raw(out, &n, 1);
    put_raw(out, &b.max_wave_speed, 1);
    put_raw(out, &b.p2g_bound, 1);
    const std::uint64_t capture = b.p2g_capture ? 1 : 0;
    put_raw(out, &capture, 1);
    put_raw(out, b.id.data(), n);
    put_raw(out, b.x.data(), 3 * n);
    put_raw(out, b.v.data(), 3 * n);
    put_raw(out, b.C.data(), 9 * n);
    put_raw(out, b.mass.data(), n);
    put_raw(out, b.volume.data(), n);
    put_raw(out, b.state.data(), static_cast<std::size_t>(b.state_scalars) * n);
    const std::uint64_t m = b.p2g_known ? b.p2g_id.size() : ~std::uint64_t(0);
    put_raw(out, &m, 1);
    if (b.p2g_known) {
      put_raw(out, b.p2g_id.data(), b.p2g_id.size());
      put_raw(out, b.p2g_block.data(), 3 * b.p2g_id.size());
    }
  }
  return out;
}

void read_checkpoint_particle_bytes(const std::vector<std::uint8_t>& bytes, Checkpoint& into) {
  std::size_t at = 0;
  for (CheckpointBody& b : into.bodies) {
    std::uint64_t n = 0;
    take_raw(bytes, at, &n, 1);
    take_raw(bytes, at, &b.max_wave_speed, 1);
    take_raw(bytes, at, &b.p2g_bound, 1);
    std::uint64_t capture = 0;
    take_raw(bytes, at, &capture, 1);
    b.p2g_capture = capture != 0;
    const auto S = static_cast<std::size_t>(b.state_scalars);
    b.id.resize(n);
    b.x.resize(3 * n);
    b.v.resize(3 * n);
    b.C.resize(9 * n);
    b.mass.resize(n);
    b.volume.resize(n);
    b.state.resize(S * n);
    take_raw(bytes, at, b.id.data(), n);
    take_raw(bytes, at, b.x.data(), 3 * n);
    take_raw(bytes, at, b.v.data(), 3 * n);
    take_raw(bytes, at, b.C.data(), 9 * n);
    take_raw(bytes, at, b.mass.data(), n);
    take_raw(bytes, at, b.volume.data(), n);
    take_raw(bytes, at, b.state.data(), S * n);
    std::uint64_t m = 0;
    take_raw(bytes, at, &m, 1);
    b.p2g_known = m != ~std::uint64_t(0);
    b.p2g_id.clear();
    b.p2g_block.clear();
    if (b.p2g_known) {
      b.p2g_id.resize(m);
      b.p2g_block.resize(3 * m);
      take_raw(bytes, at, b.p2g_id.data(), m);
      take_raw(bytes, at, b.p2g_block.data(), 3 * m);
    }
  }
  if (at != bytes.size()) throw std::runtime_error("checkpoint particles: bytes left over (another scene?)");
}

Checkpoint read_checkpoint_for(const std::filesystem::path& given, int rank, int ranks) {
  std::filesystem::path own;
  try {
    own = checkpoint_rank_path(given, rank);
  } catch (const std::invalid_argument&) {
    return read_checkpoint_set(given);
  }
  if (std::filesystem::is_regular_file(own)) {
    const Checkpoint header = read_checkpoint(own, false);
    if (header.ranks == ranks && header.rank == rank) return read_checkpoint(own);
  }
  return read_checkpoint_set(given);
}

void check_matches(const Checkpoint& c, const Scene& scene) {
  if (c.bodies.size() != scene.bodies.size())
    throw std::invalid_argument("--restart: the checkpoint holds " + std::to_string(c.bodies.size()) +
                                " bodies, the scene " + std::to_string(scene.bodies.size()));
  for (std::size_t b = 0; b < c.bodies.size(); ++b) {
    const CheckpointBody& body = c.bodies[b];
    const Constitutive law = scene.bodies[b].material.law;
    const std::string where = "--restart: " + body_path(scene, b);
    if (body.law != to_string(law))
      throw std::invalid_argument(where + ".material.constitutive is " + to_string(law) + ", the checkpoint's body " +
                                  std::to_string(b) + " is " + body.law);
    int scalars = -1;
    visit_material(law, [&](auto m) {
      scalars = static_cast<int>(sizeof(material_state_t<decltype(m), double>) / sizeof(double));
    });
    const bool nodal = scene.bodies[b].algorithm.fbar_nodal();  // 1 - JBar follows the law's scalars
    if (body.state_scalars != scalars + (nodal ? 1 : 0))
      throw std::invalid_argument(where + ": the checkpoint stores " + std::to_string(body.state_scalars) +
                                  " state scalars per particle, " + body.law + " has " + std::to_string(scalars) +
                                  (nodal ? " and the nodal F-bar (FBAR_scheme \"nodal\") 1 more" : ""));
  }
}

}  // namespace fbar::io
