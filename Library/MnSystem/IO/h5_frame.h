// Particle frames as HDF5 with an XDMF description (ParaView opens the .xdmf directly).
//
// <name>.h5 holds one dataset per quantity, each with a string attribute "unit" (absent when dimensionless):
//   /Position           N x 3, float32 or float64 (the frame's position precision)
//   /<attribute>        N (width 1) or N x width, float32 (int32 for ID), as the bgeo and CSV writers write them
// <name>.xdmf (XDMF 3) is written next to it: a Polyvertex grid of N points whose geometry and attributes point into
// the .h5 by its file name (the two files stay together). The .h5 is written to <name>.h5.part and renamed, as the
// other formats; the .xdmf last, so a reader that finds the .xdmf finds a complete .h5.
// HDF5 calls are serialised by a process-wide mutex: several writer threads (one per rank of fbar --gpus) may write
// at once, and a distribution's libhdf5 is usually not built thread-safe.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace fbar::io {

struct ParticleFrame;

namespace h5_detail {

inline std::mutex& hdf5_mutex() {
  static std::mutex m;
  return m;
}

/// HDF5 prints its own error stack (tens of lines) to stderr on every failed call. Inside a Quiet scope it does
/// not: the caller's message says what failed, with the system's reason taken from the stack (failure()).
class Quiet {
 public:
  Quiet() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  Quiet(const Quiet&) = delete;
  Quiet& operator=(const Quiet&) = delete;
  ~Quiet() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

/// The system's reason on HDF5's error stack for the call that just failed ("No space left on device": the file
/// drivers record "errno = 28, error message = '...'"), or the innermost description when none is there.
inline std::string system_reason() {
  struct Found {
    std::string errno_text, innermost;
  } found;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_DOWNWARD,
      [](unsigned, const H5E_error2_t* e, void* data) -> herr_t {
        auto& f = *static_cast<Found*>(data);
        const std::string desc = e->desc ? e->desc : "";
        const std::string key = "error message = '";
        const std::size_t at = desc.find(key);
        if (at != std::string::npos && f.errno_text.empty()) {
          const std::size_t end = desc.find('\'', at + key.size());
          f.errno_text = desc.substr(at + key.size(), end == std::string::npos ? std::string::npos : end - at - key.size());
        }
        if (f.innermost.empty() && !desc.empty()) f.innermost = desc;
        return 0;
      },
      &found);
  return found.errno_text.empty() ? found.innermost : found.errno_text;
}

/// "HDF5: cannot <what>: <the system's reason>" for the call that just failed.
inline std::runtime_error failure(const std::string& what) {
  const std::string reason = system_reason();
  return std::runtime_error("HDF5: cannot " + what + (reason.empty() ? std::string() : ": " + reason));
}

/// Closes an HDF5 handle on scope exit (close: H5Fclose, H5Dclose, ...).
class Handle {
 public:
  Handle(hid_t id, herr_t (*close)(hid_t), const std::string& what) : id_(id), close_(close) {
    if (id_ < 0) throw failure(what);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  hid_t get() const { return id_; }
  herr_t release() {
    const herr_t r = close_(id_);
    id_ = -1;
    return r;
  }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

/// A creation property list of class `cls` (H5P_DATASET_CREATE, H5P_GROUP_CREATE, H5P_FILE_CREATE) without object
/// times: HDF5 stamps every object with the clock by default, so two runs' files would differ in those bytes alone.
inline Handle untimed(hid_t cls, const std::string& where) {
  const hid_t p = H5Pcreate(cls);
  if (p >= 0 && H5Pset_obj_track_times(p, 0) < 0) {
    H5Pclose(p);
    throw failure("turn off object times in " + where);
  }
  return Handle(p, H5Pclose, "create a property list for " + where);
}

/// A dataset of n x width values written piece by piece: pieces(emit) calls emit(rows, data) for consecutive
/// pieces of rows x width values (`type` in memory and in the file), n rows in all; then its unit.
template <class Pieces>
void write_dataset_pieces(hid_t file, const std::string& name, hid_t type, std::size_t n, int width,
                          const std::string& unit, const std::string& where, const Pieces& pieces) {
  const hsize_t dims[2] = {static_cast<hsize_t>(n), static_cast<hsize_t>(width)};
  const int rank = width == 1 ? 1 : 2;
  Handle space(H5Screate_simple(rank, dims, nullptr), H5Sclose, "create a dataspace for " + where);
  const Handle dcpl = untimed(H5P_DATASET_CREATE, where);
  Handle set(H5Dcreate2(file, name.c_str(), type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose,
             "create dataset " + name + " in " + where);
  hsize_t offset = 0;
  pieces([&](std::size_t rows, const void* data) {
    if (rows == 0) return;
    if (offset + rows > n) throw std::logic_error("write_dataset_pieces: more rows than " + std::to_string(n));
    const hsize_t start[2] = {offset, 0};
    const hsize_t count[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(width)};
    Handle memory(H5Screate_simple(rank, count, nullptr), H5Sclose, "create a dataspace for " + where);
    if (H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) < 0 ||
        H5Dwrite(set.get(), type, memory.get(), space.get(), H5P_DEFAULT, data) < 0)
      throw failure("write dataset " + name + " of " + where);
    offset += rows;
  });
  if (offset != n)
    throw std::logic_error("write_dataset_pieces: " + std::to_string(offset) + " rows of " + std::to_string(n));
  if (!unit.empty()) {
    Handle str(H5Tcopy(H5T_C_S1), H5Tclose, "make a string type");
    H5Tset_size(str.get(), unit.size());
    Handle scalar(H5Screate(H5S_SCALAR), H5Sclose, "create a scalar dataspace");
    Handle attr(H5Acreate2(set.get(), "unit", str.get(), scalar.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                "create the unit of " + name);
    if (H5Awrite(attr.get(), str.get(), unit.c_str()) < 0)
      throw failure("write the unit of " + name + " in " + where);
  }
}

/// The XDMF DataItem of a dataset: dimensions, number type and precision, and "<file>:/<name>".
inline std::string data_item(std::size_t n, int width, bool integer, int bytes, const std::string& file,
                             const std::string& name) {
  std::string dims = std::to_string(n) + (width == 1 ? "" : " " + std::to_string(width));
  return "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + (integer ? "Int" : "Float") + "\" Precision=\"" +
         std::to_string(bytes) + "\" Format=\"HDF\">" + file + ":/" + name + "</DataItem>";
}

}  // namespace h5_detail

}  // namespace fbar::io
