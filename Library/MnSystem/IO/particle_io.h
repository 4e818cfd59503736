// Particle frame files: classic Houdini .bgeo (binary, partio-compatible) and .geo (ASCII), CSV, a .bgeo reader.
//
// A ParticleFrame is N positions [m] plus named per-particle attributes (float or int32, `width` components each,
// stored particle-major: values[p * width + c]). Writers pick the format from the file suffix; every writer
// writes to "<file>.part" and renames it onto <file> only after a successful close, so a reader never sees a
// half-written frame, and every I/O failure throws std::runtime_error naming the file.
//
// Classic binary geometry ("bgeo", Houdini's pre-12 format, version 5), as partio's BGEO writer emits it
// (wdas/partio src/lib/io/BGEO.cpp). Everything big-endian, ints are int32, floats IEEE-754 binary32:
//   header (41 bytes)   'B' 'g' 'e' 'o'  'V'  int version = 5
//                       int nPoints, nPrims = 0, nPointGroups = 0, nPrimGroups = 0,
//                       int nPointAttrib, nVertexAttrib = 0, nPrimAttrib = 0, nAttrib (detail) = 0
//   per point attribute int16 name length, name bytes (no terminator), uint16 size (components),
//                       int type (0 float, 1 int, 5 vector), size x int default value (0)
//   per point           float x, y, z, w = 1 (P is implicit, never in the dictionary), then every attribute's
//                       components in dictionary order (4 bytes each)
//   (no primitives, no detail attributes)
//   extra section       byte 0x00 (begin extra), byte 0xff (end extra)
// Width-3 float attributes are written as type 5 ("vector": Houdini transforms them with the geometry), other
// floats as type 0, ints as type 1.
//
// Classic ASCII geometry ("PGEOMETRY V5"), as partio's GEO writer emits it: counts, a PointAttrib dictionary
// ("name size type defaults..."), one line per point "x y z 1 (a0 a1\tb0 ...)", one particle-system primitive
// ("Part N 0 1 ... N-1 [0]") and the "beginExtra"/"endExtra" markers. Numbers use the shortest text that reads
// back to the same float/double (std::to_chars), so ASCII output loses nothing.
//
// CSV: a header row "Position_X [m],Position_Y [m],Position_Z [m],<attributes>" (an attribute column is
// "Name [unit]", or "Name" without a unit; width-3 attributes get _X/_Y/_Z, other widths _0.._w-1), then one
// particle per row.
#pragma once

#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <charconv>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <variant>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnSystem/IO/h5_frame.h"

namespace fbar::io {

enum class AttributeType { Float, Int };

/// One per-particle attribute of a frame.
struct FrameAttribute {
  std::string name;   ///< Houdini-safe identifier: [A-Za-z_][A-Za-z0-9_]*, not "P"
  int width = 1;      ///< components per particle (1 or 3 in fbar's output; any >= 1 is accepted)
  std::string unit;   ///< unit for CSV headers, e.g. "m/s"; empty: none
  std::variant<std::vector<float>, std::vector<std::int32_t>> values;  ///< values[p * width + c]

  AttributeType type() const { return values.index() == 0 ? AttributeType::Float : AttributeType::Int; }
  std::size_t value_count() const {
    return std::visit([](const auto& v) { return v.size(); }, values);
  }
  const std::vector<float>& floats() const { return std::get<0>(values); }
  const std::vector<std::int32_t>& ints() const { return std::get<1>(values); }
};

/// N particles: positions [m] in single or double precision, plus attributes.
/// Surface-only output (ClaymoreUW's exterior_only): space is cut into cubes of edge `block` from the origin, and a
/// point is written when its cube or one of the 26 around it holds at most `threshold` points of the frame (an
/// empty cube holds 0: the points next to empty space are always written). block <= 0: every point is written.
struct ExteriorFilter {
  double block = 0.0;      ///< [m] cube edge (fbar: the 4-cell grid block, 4 dx)
  double threshold = 0.0;  ///< [points per cube]
  bool on() const { return block > 0.0; }
};

struct ParticleFrame {
  std::variant<std::vector<Vec3f>, std::vector<Vec3d>> positions;
  std::vector<FrameAttribute> attributes;
  ExteriorFilter exterior;  ///< applied by write_frame
  /// A mesh body's elements (4 point indices each, points in ID order): write_frame also writes the frame as a VTK
  /// unstructured grid of tetrahedra beside it (same name, .vtk), which ParaView opens with its attributes.
  std::shared_ptr<const std::vector<std::array<int, 4>>> tetrahedra;

  std::size_t size() const {
    return std::visit([](const auto& v) { return v.size(); }, positions);
  }
  bool double_precision() const { return positions.index() == 1; }
  Vec3d position(std::size_t i) const {
    return std::visit([i](const auto& v) { return v[i].template cast<double>(); }, positions);
  }
  FrameAttribute& add(std::string name, int width, std::vector<float> values, std::string unit = {}) {
    attributes.push_back(FrameAttribute{std::move(name), width, std::move(unit), std::move(values)});
    return attributes.back();
  }
  FrameAttribute& add(std::string name, int width, std::vector<std::int32_t> values, std::string unit = {}) {
    attributes.push_back(FrameAttribute{std::move(name), width, std::move(unit), std::move(values)});
    return attributes.back();
  }
  /// The attribute called `name`, or nullptr.
  const FrameAttribute* find(std::string_view name) const {
    for (const auto& a : attributes)
      if (a.name == name) return &a;
    return nullptr;
  }
};

// ---------------------------------------------------------------------------------------------
// Validation and file names

inline bool valid_attribute_name(std::string_view name) {
  if (name.empty() || name.size() > 32767 || name == "P") return false;
  auto alpha = [](char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_'; };
  if (!alpha(name[0])) return false;
  for (char c : name)
    if (!alpha(c) && !(c >= '0' && c <= '9')) return false;
  return true;
}

/// Throws std::invalid_argument when a name is not a valid unique identifier, a width is < 1 or an attribute does
/// not hold size() * width values.
inline void validate_frame(const ParticleFrame& frame) {
  const std::size_t n = frame.size();
  for (std::size_t i = 0; i < frame.attributes.size(); ++i) {
    const FrameAttribute& a = frame.attributes[i];
    if (!valid_attribute_name(a.name))
      throw std::invalid_argument("particle attribute name \"" + a.name +
                                  "\" is not an identifier ([A-Za-z_][A-Za-z0-9_]*, not \"P\")");
    if (a.width < 1 || a.width > 65535)
      throw std::invalid_argument("particle attribute " + a.name + ": width " + std::to_string(a.width) +
                                  " (expected 1..65535)");
    if (a.value_count() != n * static_cast<std::size_t>(a.width))
      throw std::invalid_argument("particle attribute " + a.name + ": " + std::to_string(a.value_count()) +
                                  " values for " + std::to_string(n) + " particles of width " +
                                  std::to_string(a.width));
    for (std::size_t j = 0; j < i; ++j)
      if (frame.attributes[j].name == a.name)
        throw std::invalid_argument("particle attribute " + a.name + " appears twice");
  }
}

enum class FrameFormat { Bgeo, Geo, Csv, H5 };

/// ".bgeo", ".geo", ".csv" or ".h5" (case-sensitive, as ClaymoreUW's save_suffix); anything else throws
/// std::invalid_argument.
inline FrameFormat frame_format(std::string_view suffix) {
  if (suffix == ".bgeo") return FrameFormat::Bgeo;
  if (suffix == ".geo") return FrameFormat::Geo;
  if (suffix == ".csv") return FrameFormat::Csv;
  if (suffix == ".h5") return FrameFormat::H5;
  throw std::invalid_argument("no particle frame writer for suffix \"" + std::string(suffix) +
                              "\" (expected .bgeo, .geo, .csv or .h5)");
}

/// ClaymoreUW's frame file name: "model[<m>]_dev[<d>]_frame[<f>]<suffix>", e.g. model[0]_dev[0]_frame[12].bgeo
/// (docs/user_guide.md §4.1; ClaymoreUW's mgsp_benchmark.cuh writes these, and its resume scenes read them).
inline std::string frame_file_name(int model, int device, int frame, std::string_view suffix) {
  return "model[" + std::to_string(model) + "]_dev[" + std::to_string(device) + "]_frame[" + std::to_string(frame) +
         "]" + std::string(suffix);
}

/// save_path / frame_file_name(...).
inline std::filesystem::path frame_file_path(const std::filesystem::path& save_path, int model, int device, int frame,
                                             std::string_view suffix) {
  return save_path / frame_file_name(model, device, frame, suffix);
}

// ---------------------------------------------------------------------------------------------
// Implementation details

namespace detail {

inline std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

/// A file written through "<path>.part" and renamed onto <path> by commit(); removed again if never committed.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path) : path_(std::move(path)), temp_(path_) {
    temp_ += ".part";
    file_ = std::fopen(temp_.c_str(), "wb");
    if (!file_) throw std::runtime_error("cannot open " + temp_.string() + " for writing: " + errno_text(errno));
    buffer_.reserve(kChunk + 4096);
  }
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile() {
    if (file_) std::fclose(file_);
    if (!committed_) {
      std::error_code ec;
      std::filesystem::remove(temp_, ec);
    }
  }

  /// Bytes are staged in a 1 MiB buffer and written in large blocks.
  std::string& buffer() { return buffer_; }
  void maybe_flush() {
    if (buffer_.size() >= kChunk) flush();
  }
  void flush() {
    if (!buffer_.empty() && std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size())
      throw std::runtime_error("cannot write " + temp_.string() + ": " + errno_text(errno));
    buffer_.clear();
  }
  /// Appends n bytes (large blocks go to the file without a copy).
  void append(const char* data, std::size_t n) {
    if (buffer_.size() + n <= kChunk) {
      buffer_.append(data, n);
      maybe_flush();
      return;
    }
    flush();
    if (n > 0 && std::fwrite(data, 1, n, file_) != n)
      throw std::runtime_error("cannot write " + temp_.string() + ": " + errno_text(errno));
  }
  /// Reserves `n` bytes after what the buffer holds and returns their file offset; the caller fills them with
  /// write_at() (from several threads: pwrite).
  off_t reserve(std::size_t n) {
    flush();
    if (std::fflush(file_) != 0) throw std::runtime_error("cannot write " + temp_.string() + ": " + errno_text(errno));
    const off_t at = ftello(file_);
    if (at < 0 || fseeko(file_, at + static_cast<off_t>(n), SEEK_SET) != 0)
      throw std::runtime_error("cannot seek in " + temp_.string() + ": " + errno_text(errno));
    return at;
  }
  /// Writes n bytes at file offset `at` (thread-safe: pwrite on the descriptor).
  void write_at(const char* data, std::size_t n, off_t at) const {
    const int fd = fileno(file_);
    while (n > 0) {
      const ssize_t w = ::pwrite(fd, data, n, at);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) throw std::runtime_error("cannot write " + temp_.string() + ": " + errno_text(errno));
      data += w;
      n -= static_cast<std::size_t>(w);
      at += w;
    }
  }
  void commit() {
    flush();
    // fclose reports deferred write errors (a full disk): check it before the rename makes the file visible.
    const int rc = std::fclose(file_);
    file_ = nullptr;
    if (rc != 0) throw std::runtime_error("cannot write " + temp_.string() + ": " + errno_text(errno));
    std::error_code ec;
    std::filesystem::rename(temp_, path_, ec);
    if (ec) throw std::runtime_error("cannot rename " + temp_.string() + " to " + path_.string() + ": " + ec.message());
    committed_ = true;
  }

 private:
  static constexpr std::size_t kChunk = std::size_t(1) << 20;
  std::filesystem::path path_, temp_;
  std::FILE* file_ = nullptr;
  std::string buffer_;
  bool committed_ = false;
};

inline void put_be32(std::string& out, std::uint32_t v) {
  const char b[4] = {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
                     static_cast<char>(v)};
  out.append(b, 4);
}
inline void put_be16(std::string& out, std::uint16_t v) {
  const char b[2] = {static_cast<char>(v >> 8), static_cast<char>(v)};
  out.append(b, 2);
}
inline std::uint32_t bits_of(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}
inline void put_be_float(std::string& out, float f) { put_be32(out, bits_of(f)); }
/// Stores v big-endian at o (compilers turn the shifts into one byte swap and a store).
inline void store_be32(char* o, std::uint32_t v) {
  o[0] = static_cast<char>(v >> 24);
  o[1] = static_cast<char>(v >> 16);
  o[2] = static_cast<char>(v >> 8);
  o[3] = static_cast<char>(v);
}

/// Runs body(lo, hi) over [0, n) split across up to `threads` threads (the calling one included).
template <class Body>
void parallel_ranges(std::size_t n, unsigned threads, const Body& body) {
  const std::size_t parts = std::max<std::size_t>(1, std::min<std::size_t>(threads, n / 4096));
  if (parts <= 1) {
    body(std::size_t(0), n);
    return;
  }
  std::vector<std::thread> pool;
  std::exception_ptr error;
  std::mutex error_mutex;
  auto run = [&](std::size_t k) {
    try {
      body(n * k / parts, n * (k + 1) / parts);
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
    }
  };
  for (std::size_t k = 1; k < parts; ++k) pool.emplace_back(run, k);
  run(0);
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// Shortest text that reads back to the same value (locale-independent).
template <typename T>
void put_text(std::string& out, T v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, r.ptr);
}

/// Cursor over a whole file in memory; every read is bounds-checked.
class ByteReader {
 public:
  ByteReader(std::string data, std::string name) : data_(std::move(data)), name_(std::move(name)) {}
  std::uint32_t be32() {
    need(4);
    const auto* p = reinterpret_cast<const unsigned char*>(data_.data() + pos_);
    pos_ += 4;
    return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
  }
  std::uint16_t be16() {
    need(2);
    const auto* p = reinterpret_cast<const unsigned char*>(data_.data() + pos_);
    pos_ += 2;
    return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
  }
  unsigned char byte() {
    need(1);
    return static_cast<unsigned char>(data_[pos_++]);
  }
  std::string bytes(std::size_t n) {
    need(n);
    std::string s = data_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  float be_float() {
    const std::uint32_t u = be32();
    float f;
    std::memcpy(&f, &u, 4);
    return f;
  }
  std::size_t remaining() const { return data_.size() - pos_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(name_ + ": " + what + " (at byte " + std::to_string(pos_) + ")");
  }

 private:
  void need(std::size_t n) const {
    if (data_.size() - pos_ < n) fail("file ends early");
  }
  std::string data_, name_;
  std::size_t pos_ = 0;
};

inline std::string read_whole_file(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw std::runtime_error("cannot open " + path.string() + ": " + errno_text(errno));
  std::string data;
  char chunk[1 << 16];
  std::size_t got;
  while ((got = std::fread(chunk, 1, sizeof(chunk), f)) > 0) data.append(chunk, got);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) throw std::runtime_error("cannot read " + path.string());
  return data;
}

/// Classic bgeo/geo attribute type codes (partio BGEO.cpp / GEO.cpp).
constexpr int kHoudiniFloat = 0;
constexpr int kHoudiniInt = 1;
constexpr int kHoudiniVector = 5;
inline int houdini_type(const FrameAttribute& a) {
  if (a.type() == AttributeType::Int) return kHoudiniInt;
  return a.width == 3 ? kHoudiniVector : kHoudiniFloat;
}

inline std::vector<std::string> column_names(const FrameAttribute& a) {
  const std::string unit = a.unit.empty() ? std::string() : " [" + a.unit + "]";
  if (a.width == 1) return {a.name + unit};
  std::vector<std::string> names;
  static constexpr const char* kXyz[3] = {"_X", "_Y", "_Z"};
  for (int c = 0; c < a.width; ++c)
    names.push_back(a.name + (a.width == 3 ? std::string(kXyz[c]) : "_" + std::to_string(c)) + unit);
  return names;
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------
// Writers
//
// Every writer reads its frame through a FrameStream, a piece of `piece` points at a time, so a frame of any size
// is written with the host memory of a few pieces: a ParticleFrame in memory is one source (stream_of), the GPU
// engine's device buffers another. The exterior filter is applied while streaming: two passes over the positions
// (count the points of each cube, then mark the points kept: one bit each) before the file is written.

/// One attribute of a streamed frame: a FrameAttribute without its values.
struct StreamAttribute {
  std::string name;
  int width = 1;
  std::string unit;
  AttributeType type = AttributeType::Float;
};

/// A frame read piece by piece. read_positions(first, count, out) writes the 3 x count coordinates [m] of points
/// [first, first + count) to `out` (double when double_precision, float otherwise); read_values(a, first, count,
/// out) writes count x width 4-byte values of attribute a (float, or int32 for an Int attribute). Within a pass
/// each column's reads come in increasing `first`; a writer makes several passes (the exterior filter's two, one
/// per HDF5 dataset), each from point 0.
/// Points a frame writer reads at a time (FrameStream::piece's default): 48 MB of single-precision positions.
inline constexpr std::size_t kFramePiecePoints = std::size_t(1) << 22;

struct FrameStream {
  std::size_t points = 0;
  bool double_precision = false;
  std::vector<StreamAttribute> attributes;
  ExteriorFilter exterior;                   ///< applied by the writers
  std::size_t piece = kFramePiecePoints;  ///< points per read
  std::function<void(std::size_t first, std::size_t count, void* out)> read_positions;
  std::function<void(std::size_t attribute, std::size_t first, std::size_t count, void* out)> read_values;
};

/// The stream of a frame in memory (which must outlive it): its points, attributes and exterior filter.
inline FrameStream stream_of(const ParticleFrame& frame, std::size_t piece = kFramePiecePoints) {
  validate_frame(frame);
  FrameStream s;
  s.points = frame.size();
  s.double_precision = frame.double_precision();
  s.exterior = frame.exterior;
  s.piece = piece;
  for (const FrameAttribute& a : frame.attributes) s.attributes.push_back({a.name, a.width, a.unit, a.type()});
  s.read_positions = [&frame](std::size_t first, std::size_t count, void* out) {
    std::visit(
        [&](const auto& xs) {
          using V = typename std::decay_t<decltype(xs)>::value_type;
          if (count) std::memcpy(out, xs.data() + first, count * sizeof(V));
        },
        frame.positions);
  };
  s.read_values = [&frame](std::size_t a, std::size_t first, std::size_t count, void* out) {
    const FrameAttribute& at = frame.attributes[a];
    const std::size_t w = static_cast<std::size_t>(at.width);
    std::visit([&](const auto& v) { if (count) std::memcpy(out, v.data() + first * w, count * w * 4); }, at.values);
  };
  return s;
}

namespace detail {

static_assert(sizeof(Vec3f) == 3 * sizeof(float) && sizeof(Vec3d) == 3 * sizeof(double),
              "frame positions are read as packed coordinates");

inline int houdini_type(const StreamAttribute& a) {
  if (a.type == AttributeType::Int) return kHoudiniInt;
  return a.width == 3 ? kHoudiniVector : kHoudiniFloat;
}

inline std::vector<std::string> column_names(const StreamAttribute& a) {
  return column_names(FrameAttribute{a.name, a.width, a.unit, {}});
}

/// A FrameStream read in pieces with its exterior filter applied: each piece holds only the points written.
class FrameReader {
 public:
  struct Piece {
    std::size_t rows = 0;                   ///< points of the piece that are written
    std::vector<char> positions;            ///< rows x 3 coordinates (the stream's precision)
    std::vector<std::vector<char>> values;  ///< per attribute asked for: rows x width x 4 bytes
  };

  explicit FrameReader(const FrameStream& s) : s_(s) {
    for (std::size_t i = 0; i < s.attributes.size(); ++i) {
      const StreamAttribute& a = s.attributes[i];
      if (!valid_attribute_name(a.name))
        throw std::invalid_argument("particle attribute name \"" + a.name +
                                    "\" is not an identifier ([A-Za-z_][A-Za-z0-9_]*, not \"P\")");
      if (a.width < 1 || a.width > 65535)
        throw std::invalid_argument("particle attribute " + a.name + ": width " + std::to_string(a.width) +
                                    " (expected 1..65535)");
      for (std::size_t j = 0; j < i; ++j)
        if (s.attributes[j].name == a.name)
          throw std::invalid_argument("particle attribute " + a.name + " appears twice");
    }
    if (s.piece == 0) throw std::invalid_argument("FrameStream: piece must be at least 1 point");
    rows_ = s.points;
    if (s.exterior.on() && s.points > 0) mark_exterior();
  }

  std::size_t rows() const { return rows_; }
  std::size_t coordinate_bytes() const { return s_.double_precision ? 8 : 4; }
  double coordinate(const char* xs, std::size_t i) const {
    if (s_.double_precision) {
      double d;
      std::memcpy(&d, xs + 8 * i, 8);
      return d;
    }
    float f;
    std::memcpy(&f, xs + 4 * i, 4);
    return static_cast<double>(f);
  }

  /// f(piece) for every piece with points written, in order; the positions when `positions`, and the values of
  /// the attributes listed in `attributes` (piece.values[k] holds attributes[k]'s).
  template <class F>
  void each_piece(bool positions, const std::vector<std::size_t>& attributes, F&& f) const {
    Piece piece;
    piece.values.resize(attributes.size());
    std::vector<char> scratch;
    const std::size_t cb = coordinate_bytes();
    for (std::size_t first = 0; first < s_.points; first += s_.piece) {
      const std::size_t count = std::min(s_.piece, s_.points - first);
      const std::size_t rows = kept_in(first, count);
      if (rows == 0) continue;
      piece.rows = rows;
      const bool all = rows == count;  // nothing to drop: read straight into the piece
      auto read = [&](std::vector<char>& into, std::size_t record, auto&& reader) {
        into.resize(rows * record);
        if (all) {
          reader(into.data());
          return;
        }
        scratch.resize(count * record);
        reader(scratch.data());
        std::size_t r = 0;
        for (std::size_t i = 0; i < count; ++i)
          if (kept(first + i)) std::memcpy(into.data() + record * r++, scratch.data() + record * i, record);
      };
      if (positions) read(piece.positions, 3 * cb, [&](void* out) { s_.read_positions(first, count, out); });
      for (std::size_t k = 0; k < attributes.size(); ++k) {
        const std::size_t a = attributes[k];
        read(piece.values[k], 4 * static_cast<std::size_t>(s_.attributes[a].width),
             [&](void* out) { s_.read_values(a, first, count, out); });
      }
      f(static_cast<const Piece&>(piece));
    }
  }

 private:
  bool kept(std::size_t p) const { return keep_.empty() || ((keep_[p >> 6] >> (p & 63)) & 1u); }
  std::size_t kept_in(std::size_t first, std::size_t count) const {
    if (keep_.empty()) return count;
    std::size_t k = 0;
    for (std::size_t p = first; p < first + count; ++p) k += kept(p);
    return k;
  }

  /// The exterior filter (ExteriorFilter): the points of each cube counted in a first pass over the positions, one
  /// decision per occupied cube, the points kept marked in a second pass.
  void mark_exterior() {
    const double inv = 1.0 / s_.exterior.block;
    auto pack = [](long long i, long long j, long long k) {  // 21 bits per axis, offset to stay non-negative
      const auto u = [](long long c) { return static_cast<std::uint64_t>(c + (1LL << 20)) & 0x1fffffULL; };
      return (u(i) << 42) | (u(j) << 21) | u(k);
    };
    const std::size_t cb = coordinate_bytes();
    std::vector<char> xs;
    auto each_cube = [&](auto&& visit) {
      for (std::size_t first = 0; first < s_.points; first += s_.piece) {
        const std::size_t count = std::min(s_.piece, s_.points - first);
        xs.resize(3 * cb * count);
        s_.read_positions(first, count, xs.data());
        for (std::size_t i = 0; i < count; ++i) {
          long long c[3];
          for (int a = 0; a < 3; ++a) c[a] = static_cast<long long>(std::floor(coordinate(xs.data(), 3 * i + a) * inv));
          visit(first + i, c);
        }
      }
    };
    std::unordered_map<std::uint64_t, long long> count;
    each_cube([&](std::size_t, const long long* c) { ++count[pack(c[0], c[1], c[2])]; });
    std::unordered_map<std::uint64_t, char> keep;
    keep.reserve(count.size());
    keep_.assign((s_.points + 63) / 64, 0);
    rows_ = 0;
    each_cube([&](std::size_t p, const long long* c) {
      const std::uint64_t key = pack(c[0], c[1], c[2]);
      auto it = keep.find(key);
      if (it == keep.end()) {
        bool exterior = false;
        for (int di = -1; di <= 1 && !exterior; ++di)
          for (int dj = -1; dj <= 1 && !exterior; ++dj)
            for (int dk = -1; dk <= 1 && !exterior; ++dk) {
              const auto n = count.find(pack(c[0] + di, c[1] + dj, c[2] + dk));
              exterior = static_cast<double>(n == count.end() ? 0 : n->second) <= s_.exterior.threshold;
            }
        it = keep.emplace(key, exterior ? 1 : 0).first;
      }
      if (it->second) {
        keep_[p >> 6] |= std::uint64_t(1) << (p & 63);
        ++rows_;
      }
    });
    if (rows_ == s_.points) keep_.clear();  // every point kept
  }

  const FrameStream& s_;
  std::vector<std::uint64_t> keep_;  ///< bit p: point p is written (empty: every point)
  std::size_t rows_ = 0;
};

inline std::vector<std::size_t> every_attribute(const FrameStream& s) {
  std::vector<std::size_t> all(s.attributes.size());
  for (std::size_t a = 0; a < all.size(); ++a) all[a] = a;
  return all;
}

inline std::uint32_t word_at(const char* p) {
  std::uint32_t u;
  std::memcpy(&u, p, 4);
  return u;
}

}  // namespace detail

/// One point attribute of a bgeo's dictionary: name, components, Houdini type code (0 float, 1 int, 5 vector).
struct BgeoAttribute {
  std::string name;
  int width = 1;
  int type = 0;
};

/// The bgeo header (magic, counts, attribute dictionary) of n points with `attributes`: what precedes the records.
inline std::string bgeo_header(std::size_t n, const std::vector<BgeoAttribute>& attributes) {
  std::string out;
  out.append("Bgeo", 4);
  out.push_back('V');
  detail::put_be32(out, 5);                                                 // version
  detail::put_be32(out, static_cast<std::uint32_t>(n));                     // nPoints
  for (int i = 0; i < 3; ++i) detail::put_be32(out, 0);                     // nPrims, nPointGroups, nPrimGroups
  detail::put_be32(out, static_cast<std::uint32_t>(attributes.size()));     // nPointAttrib
  for (int i = 0; i < 3; ++i) detail::put_be32(out, 0);                     // nVertexAttrib, nPrimAttrib, nAttrib
  for (const BgeoAttribute& a : attributes) {
    detail::put_be16(out, static_cast<std::uint16_t>(a.name.size()));
    out.append(a.name);
    detail::put_be16(out, static_cast<std::uint16_t>(a.width));
    detail::put_be32(out, static_cast<std::uint32_t>(a.type));
    for (int c = 0; c < a.width; ++c) detail::put_be32(out, 0);           // default value
  }
  return out;
}

/// A bgeo whose point records (big-endian, 16 + 4 x components bytes each, as write_bgeo lays them out) are
/// already serialised, e.g. by the GPU into a pinned buffer: the header, the records written by several threads at
/// their offsets, the end marks. Throws std::invalid_argument / std::runtime_error as write_bgeo.
inline void write_bgeo_records(const std::filesystem::path& path, std::size_t n,
                               const std::vector<BgeoAttribute>& attributes, const char* records) {
  if (n > 0x7fffffffu) throw std::invalid_argument(path.string() + ": bgeo holds at most 2^31-1 points");
  std::size_t record = 16;
  for (const BgeoAttribute& a : attributes) record += 4 * static_cast<std::size_t>(a.width);
  detail::AtomicFile file(path);
  file.buffer() = bgeo_header(n, attributes);
  const off_t base = file.reserve(n * record);
  const std::size_t piece = std::max<std::size_t>(1, (std::size_t(8) << 20) / record);
  const unsigned threads = std::max(1u, std::min(8u, std::thread::hardware_concurrency() / 2));
  detail::parallel_ranges(n, threads, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t first = lo; first < hi; first += piece) {
      const std::size_t count = std::min(piece, hi - first);
      file.write_at(records + first * record, count * record, base + static_cast<off_t>(first * record));
    }
  });
  std::string& out = file.buffer();
  out.push_back(static_cast<char>(0x00));  // begin extra
  out.push_back(static_cast<char>(0xff));  // end extra
  file.commit();
}

/// Classic binary Houdini geometry, byte for byte what partio's writeBGEO produces for the same data
/// (positions are stored as float). Throws std::invalid_argument (bad frame, > 2^31-1 points) or
/// std::runtime_error (I/O). The bgeo of a streamed frame: the header, then each piece's records (x y z w = 1,
/// every attribute's components), serialised by several threads (a 16M-particle frame with 4 attributes is
/// 0.58 GB: byte by byte on one thread it took 1.3 s) and appended.
inline void write_bgeo(const std::filesystem::path& path, const FrameStream& s) {
  const detail::FrameReader reader(s);
  const std::size_t n = reader.rows();
  if (n > 0x7fffffffu) throw std::invalid_argument(path.string() + ": bgeo holds at most 2^31-1 points");
  std::vector<BgeoAttribute> dictionary;
  std::size_t record = 16;
  for (const StreamAttribute& a : s.attributes) {
    dictionary.push_back({a.name, a.width, detail::houdini_type(a)});
    record += 4 * static_cast<std::size_t>(a.width);
  }
  detail::AtomicFile file(path);
  file.buffer() = bgeo_header(n, dictionary);
  const unsigned threads = std::max(1u, std::min(8u, std::thread::hardware_concurrency() / 2));
  std::vector<char> records;
  reader.each_piece(true, detail::every_attribute(s), [&](const detail::FrameReader::Piece& p) {
    records.resize(p.rows * record);
    detail::parallel_ranges(p.rows, threads, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        char* o = records.data() + i * record;
        for (int a = 0; a < 3; ++a)
          detail::store_be32(o + 4 * a, detail::bits_of(static_cast<float>(
                                            reader.coordinate(p.positions.data(), 3 * i + static_cast<std::size_t>(a)))));
        detail::store_be32(o + 12, detail::bits_of(1.0f));  // homogeneous w
        o += 16;
        for (std::size_t k = 0; k < s.attributes.size(); ++k) {
          const std::size_t w = static_cast<std::size_t>(s.attributes[k].width);
          const char* v = p.values[k].data() + 4 * w * i;
          for (std::size_t c = 0; c < w; ++c, o += 4) detail::store_be32(o, detail::word_at(v + 4 * c));
        }
      }
    });
    file.append(records.data(), records.size());
  });
  std::string& out = file.buffer();
  out.push_back(static_cast<char>(0x00));  // begin extra
  out.push_back(static_cast<char>(0xff));  // end extra
  file.commit();
}

namespace detail {

/// The text of component c of attribute a's values for one point (`v`: its width x 4 bytes).
inline void put_value(std::string& out, const StreamAttribute& a, const char* v, std::size_t c) {
  const std::uint32_t u = word_at(v + 4 * c);
  if (a.type == AttributeType::Float) {
    float f;
    std::memcpy(&f, &u, 4);
    put_text(out, f);
  } else {
    put_text(out, static_cast<std::int32_t>(u));
  }
}

/// The text of coordinate i of a piece's positions, in the stream's precision.
inline void put_coordinate(std::string& out, const FrameReader& reader, const char* xs, std::size_t i) {
  if (reader.coordinate_bytes() == 8)
    put_text(out, reader.coordinate(xs, i));
  else
    put_text(out, static_cast<float>(reader.coordinate(xs, i)));
}

}  // namespace detail

/// Classic ASCII Houdini geometry (PGEOMETRY V5), the layout of partio's writeGEO.
inline void write_geo(const std::filesystem::path& path, const FrameStream& s) {
  const detail::FrameReader reader(s);
  const std::size_t n = reader.rows();
  detail::AtomicFile file(path);
  std::string& out = file.buffer();
  const bool has_prim = n > 0;  // an empty particle primitive is not written
  out += "PGEOMETRY V5\n";
  out += "NPoints " + std::to_string(n) + " NPrims " + (has_prim ? "1" : "0") + "\n";
  out += "NPointGroups 0 NPrimGroups 0\n";
  out += "NPointAttrib " + std::to_string(s.attributes.size()) + " NVertexAttrib 0 NPrimAttrib " +
         (has_prim ? "1" : "0") + " NAttrib 0\n";
  if (!s.attributes.empty()) {
    out += "PointAttrib\n";
    for (const StreamAttribute& a : s.attributes) {
      const int t = detail::houdini_type(a);
      out += a.name + " " + std::to_string(a.width) + " " +
             (t == detail::kHoudiniInt ? "int" : t == detail::kHoudiniVector ? "vector" : "float");
      for (int c = 0; c < a.width; ++c) out += " 0";
      out += "\n";
    }
  }
  reader.each_piece(true, detail::every_attribute(s), [&](const detail::FrameReader::Piece& p) {
    for (std::size_t i = 0; i < p.rows; ++i) {
      for (std::size_t d = 0; d < 3; ++d) {
        detail::put_coordinate(out, reader, p.positions.data(), 3 * i + d);
        out.push_back(' ');
      }
      out.push_back('1');
      if (!s.attributes.empty()) out += " (";
      for (std::size_t k = 0; k < s.attributes.size(); ++k) {
        const StreamAttribute& a = s.attributes[k];
        if (k > 0) out.push_back('\t');
        const std::size_t w = static_cast<std::size_t>(a.width);
        for (std::size_t c = 0; c < w; ++c) {
          if (c > 0) out.push_back(' ');
          detail::put_value(out, a, p.values[k].data() + 4 * w * i, c);
        }
      }
      if (!s.attributes.empty()) out.push_back(')');
      out.push_back('\n');
      file.maybe_flush();
    }
  });
  if (has_prim) {
    out += "PrimitiveAttrib\ngenerator 1 index 1 papi\nPart " + std::to_string(n);
    for (std::size_t p = 0; p < n; ++p) {
      out.push_back(' ');
      detail::put_text(out, p);
      file.maybe_flush();
    }
    out += " [0]\n";
  }
  out += "beginExtra\nendExtra\n";
  file.commit();
}

/// CSV with a header row of names and units; one particle per row.
inline void write_csv(const std::filesystem::path& path, const FrameStream& s) {
  const detail::FrameReader reader(s);
  detail::AtomicFile file(path);
  std::string& out = file.buffer();
  out += "Position_X [m],Position_Y [m],Position_Z [m]";
  for (const StreamAttribute& a : s.attributes)
    for (const std::string& col : detail::column_names(a)) out += "," + col;
  out.push_back('\n');
  reader.each_piece(true, detail::every_attribute(s), [&](const detail::FrameReader::Piece& p) {
    for (std::size_t i = 0; i < p.rows; ++i) {
      for (std::size_t d = 0; d < 3; ++d) {
        if (d > 0) out.push_back(',');
        detail::put_coordinate(out, reader, p.positions.data(), 3 * i + d);
      }
      for (std::size_t k = 0; k < s.attributes.size(); ++k) {
        const std::size_t w = static_cast<std::size_t>(s.attributes[k].width);
        for (std::size_t c = 0; c < w; ++c) {
          out.push_back(',');
          detail::put_value(out, s.attributes[k], p.values[k].data() + 4 * w * i, c);
        }
      }
      out.push_back('\n');
      file.maybe_flush();
    }
  });
  file.commit();
}

/// HDF5 frame and its XDMF description (h5_frame.h): `path` ends in .h5; the .xdmf goes next to it. Each dataset
/// is written piece by piece (a pass over the stream per dataset).
inline void write_h5(const std::filesystem::path& path, const FrameStream& s) {
  const detail::FrameReader reader(s);
  const std::size_t n = reader.rows();
  const std::string file_name = path.filename().string();
  std::filesystem::path temp = path;
  temp += ".part";
  try {
    std::lock_guard<std::mutex> lock(h5_detail::hdf5_mutex());
    const h5_detail::Quiet quiet;  // the error's reason goes into the message, not HDF5's stack onto stderr
    const h5_detail::Handle fcpl = h5_detail::untimed(H5P_FILE_CREATE, temp.string());
    h5_detail::Handle file(H5Fcreate(temp.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose,
                           "create " + temp.string());
    h5_detail::write_dataset_pieces(
        file.get(), "Position", s.double_precision ? H5T_NATIVE_DOUBLE : H5T_NATIVE_FLOAT, n, 3, "m", path.string(),
        [&](const auto& emit) {
          reader.each_piece(true, {}, [&](const detail::FrameReader::Piece& p) { emit(p.rows, p.positions.data()); });
        });
    for (std::size_t a = 0; a < s.attributes.size(); ++a) {
      const StreamAttribute& at = s.attributes[a];
      h5_detail::write_dataset_pieces(
          file.get(), at.name, at.type == AttributeType::Int ? H5T_NATIVE_INT32 : H5T_NATIVE_FLOAT, n, at.width,
          at.unit, path.string(), [&](const auto& emit) {
            reader.each_piece(false, {a}, [&](const detail::FrameReader::Piece& p) { emit(p.rows, p.values[0].data()); });
          });
    }
    if (file.release() < 0) throw h5_detail::failure("close " + temp.string());
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(temp, ec);  // no half-written .part left behind
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);
  if (ec) throw std::runtime_error("cannot rename " + temp.string() + " to " + path.string() + ": " + ec.message());

  std::string x = "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n  <Grid Name=\"particles\" GridType=\"Uniform\">\n";
  x += "   <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + std::to_string(n) + "\" NodesPerElement=\"1\"/>\n";
  x += "   <Geometry GeometryType=\"XYZ\">\n    " +
       h5_detail::data_item(n, 3, false, s.double_precision ? 8 : 4, file_name, "Position") + "\n   </Geometry>\n";
  for (const StreamAttribute& a : s.attributes) {
    const char* kind = a.width == 1 ? "Scalar" : a.width == 3 ? "Vector" : "Matrix";
    x += "   <Attribute Name=\"" + a.name + "\" AttributeType=\"" + kind + "\" Center=\"Node\">\n    " +
         h5_detail::data_item(n, a.width, a.type == AttributeType::Int, 4, file_name, a.name) + "\n   </Attribute>\n";
  }
  x += "  </Grid>\n </Domain>\n</Xdmf>\n";
  std::filesystem::path xdmf = path;
  xdmf.replace_extension(".xdmf");
  detail::AtomicFile out(xdmf);
  out.buffer() = x;
  out.commit();
}

/// Writes a streamed frame in the format named by path's extension (.bgeo, .geo, .csv, .h5), its exterior filter
/// applied.
inline void write_frame(const std::filesystem::path& path, const FrameStream& s) {
  switch (frame_format(path.extension().string())) {
    case FrameFormat::Bgeo: write_bgeo(path, s); break;
    case FrameFormat::Geo: write_geo(path, s); break;
    case FrameFormat::Csv: write_csv(path, s); break;
    case FrameFormat::H5: write_h5(path, s); break;
  }
}

/// The stream of every point of a frame in memory: its exterior filter is not applied (write_frame applies it).
inline FrameStream every_point(const ParticleFrame& frame) {
  FrameStream s = stream_of(frame);
  s.exterior = {};
  return s;
}
inline void write_bgeo(const std::filesystem::path& path, const ParticleFrame& frame) {
  write_bgeo(path, every_point(frame));
}
inline void write_geo(const std::filesystem::path& path, const ParticleFrame& frame) {
  write_geo(path, every_point(frame));
}
inline void write_csv(const std::filesystem::path& path, const ParticleFrame& frame) {
  write_csv(path, every_point(frame));
}
inline void write_h5(const std::filesystem::path& path, const ParticleFrame& frame) {
  write_h5(path, every_point(frame));
}

/// The points of `frame` that frame.exterior keeps, with their attributes, in their order (the filter is off in the
/// result).
inline ParticleFrame exterior_points(const ParticleFrame& frame) {
  const FrameStream s = stream_of(frame, std::max<std::size_t>(frame.size(), 1));
  const detail::FrameReader reader(s);
  ParticleFrame out;
  std::vector<char> xs;
  std::vector<std::vector<char>> values(s.attributes.size());
  reader.each_piece(true, detail::every_attribute(s), [&](const detail::FrameReader::Piece& p) {
    xs = p.positions;
    values = p.values;
  });
  const std::size_t n = reader.rows();
  auto copy = [](auto& into, const std::vector<char>& from, std::size_t count) {
    into.resize(count);
    if (count) std::memcpy(into.data(), from.data(), sizeof(into[0]) * count);
  };
  if (s.double_precision) {
    std::vector<Vec3d> x;
    copy(x, xs, n);
    out.positions = std::move(x);
  } else {
    std::vector<Vec3f> x;
    copy(x, xs, n);
    out.positions = std::move(x);
  }
  for (std::size_t a = 0; a < s.attributes.size(); ++a) {
    const StreamAttribute& at = s.attributes[a];
    const std::size_t count = n * static_cast<std::size_t>(at.width);
    if (at.type == AttributeType::Int) {
      std::vector<std::int32_t> v;
      copy(v, values[a], count);
      out.add(at.name, at.width, std::move(v), at.unit);
    } else {
      std::vector<float> v;
      copy(v, values[a], count);
      out.add(at.name, at.width, std::move(v), at.unit);
    }
  }
  return out;
}

/// Legacy VTK (binary, big-endian) unstructured grid of the frame's points and `frame.tetrahedra` (cell type 10),
/// the attributes as point data (width 1: SCALARS, 3: VECTORS, others FIELD arrays); positions in the frame's
/// precision. Written atomically like the other formats.
inline void write_vtk_tetrahedra(const std::filesystem::path& path, const ParticleFrame& frame) {
  validate_frame(frame);
  const std::size_t n = frame.size();
  const auto& cells = *frame.tetrahedra;
  std::string out = "# vtk DataFile Version 3.0\nfbar mesh frame\nBINARY\nDATASET UNSTRUCTURED_GRID\n";
  out += "POINTS " + std::to_string(n) + (frame.double_precision() ? " double\n" : " float\n");
  for (std::size_t p = 0; p < n; ++p) {
    const Vec3d x = frame.position(p);
    for (int a = 0; a < 3; ++a) {
      if (frame.double_precision()) {
        std::uint64_t u;
        std::memcpy(&u, &x[a], 8);
        detail::put_be32(out, static_cast<std::uint32_t>(u >> 32));
        detail::put_be32(out, static_cast<std::uint32_t>(u));
      } else {
        detail::put_be_float(out, static_cast<float>(x[a]));
      }
    }
  }
  out += "\nCELLS " + std::to_string(cells.size()) + " " + std::to_string(5 * cells.size()) + "\n";
  for (const auto& c : cells) {
    detail::put_be32(out, 4);
    for (int k = 0; k < 4; ++k) {
      if (c[static_cast<std::size_t>(k)] < 0 || static_cast<std::size_t>(c[static_cast<std::size_t>(k)]) >= n)
        throw std::runtime_error(path.string() + ": an element names point " + std::to_string(c[static_cast<std::size_t>(k)]) +
                                 " of a frame of " + std::to_string(n) + " points");
      detail::put_be32(out, static_cast<std::uint32_t>(c[static_cast<std::size_t>(k)]));
    }
  }
  out += "\nCELL_TYPES " + std::to_string(cells.size()) + "\n";
  for (std::size_t e = 0; e < cells.size(); ++e) detail::put_be32(out, 10);  // VTK_TETRA
  out += "\nPOINT_DATA " + std::to_string(n) + "\n";
  for (const FrameAttribute& a : frame.attributes) {
    const bool is_int = a.type() == AttributeType::Int;
    const char* type = is_int ? "int" : "float";
    if (a.width == 1)
      out += "SCALARS " + a.name + " " + type + " 1\nLOOKUP_TABLE default\n";
    else if (a.width == 3)
      out += "VECTORS " + a.name + " " + type + "\n";
    else
      out += "FIELD FieldData 1\n" + a.name + " " + std::to_string(a.width) + " " + std::to_string(n) + " " + type + "\n";
    const std::size_t count = n * static_cast<std::size_t>(a.width);
    for (std::size_t i = 0; i < count; ++i) {
      if (is_int)
        detail::put_be32(out, static_cast<std::uint32_t>(a.ints()[i]));
      else
        detail::put_be_float(out, a.floats()[i]);
    }
    out += "\n";
  }
  detail::AtomicFile file(path);
  file.buffer() = std::move(out);
  file.commit();
}

/// Writes `frame` in the format named by path's extension (.bgeo, .geo, .csv, .h5), its exterior filter applied;
/// a mesh's frame also as the .vtk of its tetrahedra beside it (every vertex).
inline void write_frame(const std::filesystem::path& path, const ParticleFrame& frame) {
  if (frame.tetrahedra) {  // the whole mesh (connectivity needs every vertex), then the points as asked
    std::filesystem::path vtk = path;
    write_vtk_tetrahedra(vtk.replace_extension(".vtk"), frame);
  }
  write_frame(path, stream_of(frame));
}

// ---------------------------------------------------------------------------------------------
// Reader

/// Reads a classic (version 5) bgeo: the points and their float / int / vector attributes (positions as float).
/// Primitives, groups and detail attributes after the points are not read. Throws std::runtime_error naming the
/// file for anything else (new-style JSON bgeo, indexed-string attributes, truncation, trailing garbage in a
/// file without primitives).
inline ParticleFrame read_bgeo(const std::filesystem::path& path) {
  detail::ByteReader in(detail::read_whole_file(path), path.string());
  const std::string magic = in.bytes(4);
  if (magic != "Bgeo") {
    if (magic == std::string("\x7fNSJ", 4)) in.fail("new-style (JSON) bgeo; only classic bgeo is supported");
    in.fail("not a classic bgeo file (magic is not \"Bgeo\")");
  }
  if (in.byte() != 'V') in.fail("missing 'V' after the magic");
  const std::uint32_t version = in.be32();
  if (version != 5) in.fail("bgeo version " + std::to_string(version) + " (expected 5)");
  // nPoints, nPrims, nPointGroups, nPrimGroups, nPointAttrib, nVertexAttrib, nPrimAttrib, nAttrib
  std::uint32_t counts[8];
  for (auto& c : counts) c = in.be32();
  const std::uint32_t n_points = counts[0], n_prims = counts[1], n_point_groups = counts[2],
                      n_prim_groups = counts[3], n_point_attrib = counts[4], n_detail_attrib = counts[7];
  if (n_points > 0x7fffffffu) in.fail("negative point count");
  if (in.remaining() / 16 < n_points) in.fail("file ends early");  // each point holds at least P and w

  ParticleFrame frame;
  struct Layout {
    int width;
    bool is_int;
  };
  std::vector<Layout> layout;
  for (std::uint32_t i = 0; i < n_point_attrib; ++i) {
    const std::uint16_t len = in.be16();
    std::string name = in.bytes(len);
    const int width = in.be16();
    const int type = static_cast<int>(in.be32());
    if (type != detail::kHoudiniFloat && type != detail::kHoudiniInt && type != detail::kHoudiniVector)
      in.fail("attribute " + name + " has type " + std::to_string(type) + " (supported: 0 float, 1 int, 5 vector)");
    for (int c = 0; c < width; ++c) in.be32();  // default values
    const bool is_int = type == detail::kHoudiniInt;
    if (in.remaining() / 4 < std::size_t(n_points) * width) in.fail("file ends early");
    if (is_int)
      frame.add(std::move(name), width, std::vector<std::int32_t>(std::size_t(n_points) * width));
    else
      frame.add(std::move(name), width, std::vector<float>(std::size_t(n_points) * width));
    layout.push_back({width, is_int});
  }
  std::vector<Vec3f> x(n_points);
  for (std::uint32_t p = 0; p < n_points; ++p) {
    x[p] = Vec3f{{in.be_float(), in.be_float(), in.be_float()}};
    in.be_float();  // w
    for (std::size_t i = 0; i < layout.size(); ++i) {
      const std::size_t base = std::size_t(p) * layout[i].width;
      auto& values = frame.attributes[i].values;
      for (int c = 0; c < layout[i].width; ++c) {
        if (layout[i].is_int)
          std::get<1>(values)[base + c] = static_cast<std::int32_t>(in.be32());
        else
          std::get<0>(values)[base + c] = in.be_float();
      }
    }
  }
  frame.positions = std::move(x);
  if (n_prims == 0 && n_point_groups == 0 && n_prim_groups == 0 && n_detail_attrib == 0) {
    if (in.byte() != 0x00 || in.byte() != 0xff) in.fail("missing extra-section markers 0x00 0xff");
    if (in.remaining() != 0) in.fail("unexpected bytes after the end of the geometry");
  }
  return frame;
}

}  // namespace fbar::io
