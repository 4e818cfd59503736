// Grid fields (scene "grid-fields", physics/grid_fields.h): their sample times, the ranks' nodes gathered, and the
// files.
//
// Sample times. Field i samples at t0 + k / output_frequency_i (k = 0, 1, ...) for every such time before the run's
// end; the run loop starts a step exactly at each (next_time_after()), and that step's grid update records the
// nodes (the P2G state at the sample time, as the grid sensors read it).
//
// Files, in simulation.save_path (i: the field's index in grid-fields, switched-off ones counted; k: the sample's
// index, from 0 at t0):
//   gridField[i]_frame[k]<save_suffix>  the nodes of mass inside the box, ordered by node index (x, then y, then
//                                       z), or one point per grid block (`blocks`); position [m] and the attributes
//                                       (physics/grid_fields.h), in any frame format (.h5 with its .xdmf)
//   gridField[i].xdmf                   (.h5) every sample of field i with nodes as one time series: open it in
//                                       ParaView
// Every rank records the nodes it owns; the ranks' nodes are gathered and rank 0 writes, so 1 and N ranks write the
// same bytes. A restarted run continues the samples (and the series) from the checkpoint's time.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "MnSystem/Comm/transport_interface.h"
#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "io/checkpoint.h"
#include "physics/grid_fields.h"
#include "scene/scene.h"

namespace fbar {

/// The file name of field i's sample k: "gridField[<i>]_frame[<k>]<suffix>".
std::string grid_field_file_name(std::size_t field, long long sample, const std::string& suffix);
/// The series file of field i: "gridField[<i>].xdmf".
std::string grid_field_series_name(std::size_t field);

/// The frame of field `spec` from every rank's nodes (in any order; none twice), at grid spacing dx [m] and step dt
/// [s]: points ordered by node index, positions and the spec's attributes (physics/grid_fields.h).
io::ParticleFrame grid_field_frame(const GridFieldSpec& spec, std::vector<GridFieldNode> nodes, double dx, double dt);

class GridFieldRecorder {
 public:
  /// The enabled fields of `scene` for a run from t0 to t_end [s]; resume: a run restarted at resume->time continues
  /// the samples from there (the step starting at resume->time takes the sample due then) and rank 0 its series
  /// with the samples the first run wrote before that time.
  GridFieldRecorder(const Scene& scene, comm::Transport* transport, double t0, double t_end,
                    const io::Checkpoint* resume = nullptr);

  /// Enabled fields, in scene order (the engine's field i is this list's i).
  const std::vector<GridFieldSpec>& fields() const { return specs_; }
  /// Times closer than this are the same time (a billionth of the shortest interval) [s].
  double tolerance() const { return tolerance_; }
  /// [s] the first sample time of any field after t (beyond the tolerance), +infinity when none is left.
  double next_time_after(double t) const;
  /// Bit i set when field i samples at t (the step starting at t records it).
  unsigned due_mask(double t) const;
  /// Field i's sample at t, taken by a step of dt: this rank's nodes. Collective (every rank calls it for the same
  /// fields in the same order); rank 0 queues the frame (and the series) on `writer`.
  void record(std::size_t i, double t, double dt, std::vector<GridFieldNode> nodes, io::AsyncWriter& writer);
  /// The fields due at t were recorded: they move on to their next sample.
  void taken(double t);

 private:
  double sample_time(std::size_t i, long long k) const { return t0_ + static_cast<double>(k) * intervals_[i]; }
  bool due(std::size_t i, double t) const;

  comm::Transport* transport_;
  std::vector<GridFieldSpec> specs_;
  std::vector<std::size_t> index_;  ///< (enabled field) its index in the scene's grid-fields (the files')
  std::filesystem::path dir_;
  std::string suffix_;
  double dx_ = 0.0;
  double t0_ = 0.0, t_end_ = 0.0, tolerance_ = 0.0;
  std::vector<double> intervals_;  ///< (field) [s]
  std::vector<long long> next_;    ///< (field) index k of its next sample
  /// (field) its samples' (time, grid content of the sample's .xdmf) for the series (rank 0, .h5 frames; the
  /// writer gets a copy of the series text after each sample's files).
  struct SeriesEntry {
    double time;
    std::string grid;
  };
  std::vector<std::vector<SeriesEntry>> series_;
};

}  // namespace fbar
