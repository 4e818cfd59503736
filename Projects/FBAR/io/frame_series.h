// frames.xdmf: every .h5 frame of a run as one time series, for ParaView (open it, scrub time).
//
// Each rank writes its own frame files, model[m]_dev[d]_frame[f].h5 with its .xdmf (MnSystem/IO/h5_frame.h). Rank 0
// keeps frames.xdmf in the output folder: an XDMF 3 Temporal collection with one Spatial collection per frame (its
// <Time> the frame's simulated time); in it one Spatial collection per body ("bodies[i]") holding one Uniform
// Polyvertex grid per frame file of that body ("model[m]_dev[d]"), whose DataItems point into the .h5 files by file
// name, as the per-frame .xdmf files do. A file with no particles is left out of its frame's collection (some readers
// refuse zero-sized datasets), and so is a body none of whose files holds a particle.
//
// A frame enters the series once every file of it is complete: its .xdmf exists (each rank writes the .h5 first and
// renames it into place, the .xdmf last), so rank 0 finds the other ranks' frames on disk, whether they are threads of
// its process or MPI processes sharing the output folder. frames.xdmf is rewritten through "frames.xdmf.part" and a
// rename whenever a frame is added, so a reader opening it while the run goes on reads a valid file with the frames
// complete so far.
#pragma once

#include <filesystem>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace fbar::io {

/// The name of the series file in the output folder.
inline constexpr const char* kFrameSeriesName = "frames.xdmf";

class FrameSeries {
 public:
  /// body_files[i]: the (model, device) pairs of body i's frame files, one per rank that writes the body.
  FrameSeries(std::filesystem::path dir, std::vector<std::vector<std::pair<int, int>>> body_files,
              std::string suffix = ".h5");

  /// Frame `frame` (simulated time `time` [s]) was handed to the writers of every rank.
  void expect(int frame, double time);
  /// Adds every expected frame whose files are all complete and rewrites frames.xdmf when one was added. Returns the
  /// number of frames added. Thread-safe (the run loop calls expect(), the writer thread update()).
  int update();
  /// The expected frames not in the series yet, each with the first of its files that is missing.
  std::vector<std::pair<int, std::string>> missing() const;
  /// Frames in the series.
  int size() const;
  std::filesystem::path path() const { return dir_ / kFrameSeriesName; }

 private:
  struct Frame {
    int frame = 0;
    double time = 0.0;
    std::string xml;  ///< its Spatial collection, indented
  };
  /// The frame's collection, or "" with `missing` set when a file is not complete yet.
  std::string frame_xml(int frame, double time, std::string& missing) const;
  void write() const;

  std::filesystem::path dir_;
  std::vector<std::vector<std::pair<int, int>>> body_files_;
  std::string suffix_;
  mutable std::mutex mutex_;
  std::vector<std::pair<int, double>> pending_;  ///< expected, not in the series yet
  std::vector<Frame> done_;                      ///< in the series, by frame
};

}  // namespace fbar::io
