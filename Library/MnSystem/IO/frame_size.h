// The size on disk of one particle frame file, from its particle count and attributes (fbar --check), for the
// layouts particle_io.h and h5_frame.h write.
//
//   .bgeo  exact: the header, the attribute dictionary, 4 x (4 + sum of widths) bytes per particle, the 2 end bytes.
//   .h5    the datasets' bytes (positions in the run's precision, 4 bytes per attribute value) exactly, plus the HDF5
//          file's own structures (superblock, root group, one object header per dataset and its unit attribute),
//          which libhdf5 (1.10 to 1.14, default settings) allocates in blocks of 2 KiB: measured with fbar's writer,
//          1 to 3 datasets take one block, 4 to 8 two, 9 to 13 three, 14 to 16 four, which
//          kH5MetaBytes + kH5DatasetMetaBytes per dataset, rounded up to blocks, reproduces (within one block for
//          other names and units), plus the frame's .xdmf (exact but for the file name's length).
//   .csv, .geo   text: the headers exactly, each number estimated at kTextFloatChars characters (a float32's shortest
//          text, e.g. "-0.012345678"), kTextDoubleChars for a double position, an ID at its digits (IDs 0..n-1).
//          Real values with fewer digits (round numbers, zeros) make the file smaller: an estimate, not a bound.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "MnSystem/IO/particle_io.h"

namespace fbar::io {

/// What a frame file holds per particle, without the values.
struct FrameLayoutAttribute {
  std::string name;
  int width = 1;
  bool integer = false;  ///< int32 (ID) rather than float
  std::string unit;      ///< "" none
};

struct FrameLayout {
  bool double_positions = false;  ///< positions as float64 (.h5, .csv, .geo; .bgeo is always float32)
  std::vector<FrameLayoutAttribute> attributes;
};

struct FrameFileSize {
  double bytes = 0.0;     ///< the estimate (exact for .bgeo)
  double data = 0.0;      ///< the part that grows with the particles
  double headers = 0.0;   ///< the rest: what each file costs however few particles it holds
  bool exact = false;     ///< .bgeo
};

inline constexpr double kH5MetaBytes = 600.0;         ///< superblock, root group and its heap
inline constexpr double kH5DatasetMetaBytes = 400.0;  ///< one dataset's object header, name and "unit" attribute
inline constexpr double kH5MetaBlock = 2048.0;        ///< libhdf5's metadata block (H5Pset_meta_block_size default)
inline constexpr double kTextFloatChars = 11.0;   ///< estimated characters of one float32 value as text
inline constexpr double kTextDoubleChars = 19.0;  ///< estimated characters of one double position as text

namespace size_detail {

/// Sum of the decimal digits of 0, 1, ..., n-1.
inline double digits_below(std::size_t n) {
  double total = 0.0;
  std::size_t lo = 0, hi = 10;
  int digits = 1;
  while (lo < n) {
    const std::size_t top = n < hi ? n : hi;
    total += static_cast<double>(top - lo) * digits;
    lo = hi;
    if (hi > static_cast<std::size_t>(-1) / 10) break;
    hi *= 10;
    ++digits;
  }
  return total;
}

inline std::string dims(std::size_t n, int width) {
  return std::to_string(n) + (width == 1 ? "" : " " + std::to_string(width));
}

}  // namespace size_detail

/// The bytes of one frame file of `n` particles with `layout` in `format` (.h5: with its .xdmf).
inline FrameFileSize frame_file_size(FrameFormat format, std::size_t n, const FrameLayout& layout) {
  using size_detail::digits_below;
  FrameFileSize s;
  const double N = static_cast<double>(n);
  int widths = 0;
  for (const auto& a : layout.attributes) widths += a.width;
  switch (format) {
    case FrameFormat::Bgeo: {
      s.exact = true;
      s.headers = 41.0 + 2.0;  // header, extra-section markers
      for (const auto& a : layout.attributes) s.headers += 2.0 + a.name.size() + 2.0 + 4.0 + 4.0 * a.width;
      s.data = N * (16.0 + 4.0 * widths);
      break;
    }
    case FrameFormat::H5: {
      s.data = N * ((layout.double_positions ? 24.0 : 12.0) + 4.0 * widths);
      const double meta = kH5MetaBytes + kH5DatasetMetaBytes * (1.0 + static_cast<double>(layout.attributes.size()));
      s.headers = kH5MetaBlock * std::ceil(meta / kH5MetaBlock);
      // The .xdmf, as write_h5 writes it (its file name: the .h5's, "model[m]_dev[d]_frame[f].h5", about 26 chars).
      const double name = 26.0;
      std::string x = "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n  <Grid Name=\"particles\" "
                      "GridType=\"Uniform\">\n";
      x += "   <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + std::to_string(n) +
           "\" NodesPerElement=\"1\"/>\n";
      auto item = [&](int width, bool integer, int bytes, const std::string& dataset) {
        return "<DataItem Dimensions=\"" + size_detail::dims(n, width) + "\" NumberType=\"" +
               (integer ? "Int" : "Float") + "\" Precision=\"" + std::to_string(bytes) + "\" Format=\"HDF\">" + ":/" +
               dataset + "</DataItem>";
      };
      x += "   <Geometry GeometryType=\"XYZ\">\n    " + item(3, false, layout.double_positions ? 8 : 4, "Position") +
           "\n   </Geometry>\n";
      for (const auto& a : layout.attributes) {
        const char* kind = a.width == 1 ? "Scalar" : a.width == 3 ? "Vector" : "Matrix";
        x += "   <Attribute Name=\"" + a.name + "\" AttributeType=\"" + kind + "\" Center=\"Node\">\n    " +
             item(a.width, a.integer, 4, a.name) + "\n   </Attribute>\n";
      }
      x += "  </Grid>\n </Domain>\n</Xdmf>\n";
      s.headers += static_cast<double>(x.size()) + name * (1.0 + static_cast<double>(layout.attributes.size()));
      break;
    }
    case FrameFormat::Csv: {
      std::string header = "Position_X [m],Position_Y [m],Position_Z [m]";
      for (const auto& a : layout.attributes)
        for (int c = 0; c < a.width; ++c) {
          std::string col = a.name;
          if (a.width == 3) col += std::string("_") + "XYZ"[c];
          else if (a.width > 1) col += "_" + std::to_string(c);
          header += "," + col + (a.unit.empty() ? "" : " [" + a.unit + "]");
        }
      s.headers = static_cast<double>(header.size()) + 1.0;
      const double pos = layout.double_positions ? kTextDoubleChars : kTextFloatChars;
      double row = 3.0 * pos + 2.0 + 1.0;  // positions, two commas, the newline
      for (const auto& a : layout.attributes) {
        row += a.width;  // the commas
        if (!a.integer) row += a.width * kTextFloatChars;
        else s.data += a.width * digits_below(n);
      }
      s.data += N * row;
      break;
    }
    case FrameFormat::Geo: {
      const bool prim = n > 0;
      std::string h = "PGEOMETRY V5\nNPoints " + std::to_string(n) + " NPrims " + (prim ? "1" : "0") +
                      "\nNPointGroups 0 NPrimGroups 0\nNPointAttrib " + std::to_string(layout.attributes.size()) +
                      " NVertexAttrib 0 NPrimAttrib " + (prim ? "1" : "0") + " NAttrib 0\n";
      if (!layout.attributes.empty()) {
        h += "PointAttrib\n";
        for (const auto& a : layout.attributes) {
          h += a.name + " " + std::to_string(a.width) + " " +
               (a.integer ? "int" : a.width == 3 ? "vector" : "float");
          for (int c = 0; c < a.width; ++c) h += " 0";
          h += "\n";
        }
      }
      if (prim) h += "PrimitiveAttrib\ngenerator 1 index 1 papi\nPart " + std::to_string(n) + " [0]\n";
      h += "beginExtra\nendExtra\n";
      s.headers = static_cast<double>(h.size());
      const double pos = layout.double_positions ? kTextDoubleChars : kTextFloatChars;
      double row = 3.0 * (pos + 1.0) + 1.0 + 1.0;  // "x y z 1\n"
      if (!layout.attributes.empty()) row += 3.0;   // " (" and ")"
      for (std::size_t i = 0; i < layout.attributes.size(); ++i) {
        const auto& a = layout.attributes[i];
        row += (i > 0 ? 1.0 : 0.0) + (a.width - 1);  // tab before an attribute, spaces between components
        if (!a.integer) row += a.width * kTextFloatChars;
        else s.data += a.width * digits_below(n);
      }
      s.data += N * row + N + digits_below(n);  // the points, then " p" for each in the primitive
      break;
    }
  }
  s.bytes = s.data + s.headers;
  return s;
}

}  // namespace fbar::io
