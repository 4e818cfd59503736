// Sensor schedules, reduction over ranks and CSV files (the run loop's side of physics/sensors.cuh).
//
// Sample times. Sensor i samples at t0 + k / output_frequency_i (k = 0, 1, ...) for every such time before the run's
// end. The run loop shortens steps so that one starts exactly at each sample time (next_time_after()).
//  * Grid sensors: the step starting at a sample time evaluates every grid sensor in its grid update, on the nodes of
//    the particles' state at that time (the engine writes one SensorAccum per sensor into the sample's slot).
//  * Particle sensors: the particles' state at the sample time (the initial state, or the state a step landed on)
//    is reduced per body and sensor into the slot.
// The row written holds the sample time itself; sensors of one kind sampling at the same time share a slot.
//
// Reduction. Each rank reduces what it holds (its particles; the grid nodes it owns: a halo node counts once, on the
// rank owning its plane); at flush (every frame, and when the run ends) the slots are summed (sum, sum of squares,
// count) and max/min-reduced over ranks in rank order, so every rank computes the same values, and rank 0 appends
// one row per due sensor.
//
// Files, in simulation.save_path (ClaymoreUW's names; i is the sensor's index in its array, m the body's model, and
// the device is 0 because every GPU's part is in the file):
//   gridTarget[i]_dev[0].csv               one per enabled grid sensor
//   particleTarget[i]_model[m]_dev[0].csv  one per enabled particle sensor and body whose material has the attribute
// Header "Time [s],<attribute> [unit]" (Count: "Count [-]"), then "time,value" rows. A sample with nothing in the box
// writes 0 for Sum and Count and nan for the others.
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "MnSystem/Comm/transport_interface.h"
#include "io/checkpoint.h"
#include "physics/sensors.cuh"
#include "scene/output_specs.h"
#include "scene/scene.h"

namespace fbar {

/// Tracker files, one per tracked body, in simulation.save_path: particleTrack_model[m]_dev[0].csv (ClaymoreUW's
/// name; dev 0: every rank's particles are in it). Header "Time [s],<attr>[<id>] [unit],..." with the attributes as
/// the outer and the IDs as the inner loop (ClaymoreUW's order); one row at the start and at every frame.
class TrackerRecorder {
 public:
  /// resume: a restarted run continues the files (truncated to the lengths the checkpoint recorded).
  TrackerRecorder(const Scene& scene, comm::Transport* transport, const io::Checkpoint* resume = nullptr);
  ~TrackerRecorder();
  TrackerRecorder(const TrackerRecorder&) = delete;
  TrackerRecorder& operator=(const TrackerRecorder&) = delete;
  const std::vector<BodyTracker>& trackers() const { return trackers_; }
  /// Whether a tracker reads velocities (the steps landing on frame times must keep v and C).
  bool reads_velocity() const { return reads_velocity_; }
  /// Reduces tracker k's sample over ranks (values: set.ids x set.attribs in sorted-ID order, 0 where absent;
  /// present: per sorted ID, 1 on the rank holding it) and writes its row (rank 0). Every rank calls it. An ID on
  /// no rank (not a particle of the body) is written as nan; throws std::runtime_error when one is on several.
  void record(std::size_t k, double time, std::vector<double> values, std::vector<double> present);
  /// Name and length [bytes] of every file this rank writes (for a checkpoint).
  void file_sizes(std::vector<std::pair<std::string, long long>>& out) const;

 private:
  comm::Transport* transport_;
  std::vector<BodyTracker> trackers_;
  bool reads_velocity_ = false;
  std::vector<std::FILE*> files_;
  std::vector<std::filesystem::path> paths_;
};

class SensorRecorder {
 public:
  /// The enabled sensors of `scene` (toggle true) for a run from t0 to t_end [s]. Rank 0 of `transport` (nullptr:
  /// one rank) creates the files and writes their headers. resume: a run restarted at resume->time (t0 is then
  /// the first run's start, so the sample times stay where they were): every file is truncated to the length the
  /// checkpoint recorded and continued; grid samples restart at resume->time (the step starting there takes it),
  /// particle samples after it (the state at resume->time was sampled before the checkpoint), or at it when the
/// checkpoint says that sample was still due (a run's last frame: no run samples its end time). A file that is
  /// missing or shorter than recorded (a restart into another --output) starts again with its header, with a
  /// warning on stderr.
  SensorRecorder(const Scene& scene, comm::Transport* transport, double t0, double t_end,
                 const io::Checkpoint* resume = nullptr);
  ~SensorRecorder();
  SensorRecorder(const SensorRecorder&) = delete;
  SensorRecorder& operator=(const SensorRecorder&) = delete;

  /// Enabled sensors, in scene order: what the engine evaluates (slot values come in this order).
  const std::vector<GridSensorSpec>& grid_sensors() const { return grid_specs_; }
  const std::vector<ParticleSensorSpec>& particle_sensors() const { return particle_specs_; }
  /// Times closer than this are the same time (a billionth of the shortest sample interval) [s].
  double tolerance() const { return tolerance_; }
  /// [s] the first sample time of any sensor after t (beyond the tolerance), +infinity when none is left.
  double next_time_after(double t) const;

  /// The slot the step starting at time t must fill with its grid sample, or -1 when no grid sensor samples at t.
  int grid_slot_for(double t) const { return grid_.slot_for(t); }
  /// The step starting at t (grid_slot_for(t) >= 0) was committed: its slot is taken, the due sensors move on.
  void grid_taken(double t) { grid_.taken(t); }
  int grid_pending() const { return grid_.pending(); }
  /// The slot the particle state at time t fills, or -1 when no particle sensor samples at t.
  int particle_slot_for(double t) const { return particle_.slot_for(t); }
  void particle_taken(double t) { particle_.taken(t); }
  int particle_pending() const { return particle_.pending(); }
  /// Whether a particle sensor samples at t (the step landing there must keep what the sensors read).
  bool particle_due(double t) const { return particle_.slot_for(t) >= 0; }
  /// A particle sample at t has not been taken, also at the run's end (a checkpoint there: the restart takes it).
  bool particle_untaken_at(double t) const { return particle_.untaken_at(t); }

  /// Reduce this rank's values of the pending slots over ranks and write the rows (rank 0); every rank calls them at
  /// the same points. Grid: values[slot * sensors + i]; particle: values[(slot * bodies + body) * sensors + i].
  void flush_grid(const std::vector<SensorAccum>& values) { grid_.flush(values, transport_); }
  void flush_particles(const std::vector<SensorAccum>& values) { particle_.flush(values, transport_); }
  /// Name and length [bytes] of every file this rank writes (for a checkpoint; call after the flushes).
  void file_sizes(std::vector<std::pair<std::string, long long>>& out) const {
    grid_.file_sizes(out);
    particle_.file_sizes(out);
  }

 private:
  /// One kind's sensors, slots and files.
  class Schedule {
   public:
    struct Output {
      std::size_t sensor = 0;  ///< in the schedule
      std::size_t value = 0;   ///< index within a slot's values
      SensorOperation op = SensorOperation::Sum;
      std::filesystem::path path;
      std::FILE* file = nullptr;  ///< rank 0 only
    };
    ~Schedule();
    void add_sensor(double interval);
    void add_output(Output o, const std::string& header, bool writer, const io::Checkpoint* resume);
    /// A restarted run: the next sample of every sensor is the first at or after t (`after`: after t).
    void resume(double t, bool after);
    void file_sizes(std::vector<std::pair<std::string, long long>>& out) const;
    void finish(double t0, double t_end, double tolerance, std::size_t values_per_slot);
    std::size_t sensors() const { return intervals_.size(); }
    double next_time_after(double t) const;
    /// Some sensor's next sample is at t (not taken yet), whether or not t is before the run's end.
    bool untaken_at(double t) const;
    int slot_for(double t) const;
    void taken(double t);
    int pending() const { return static_cast<int>(slot_times_.size()); }
    void flush(const std::vector<SensorAccum>& values, comm::Transport* transport);

   private:
    double sample_time(std::size_t i, long long k) const { return t0_ + static_cast<double>(k) * intervals_[i]; }
    bool due(std::size_t i, double t) const;
    double t0_ = 0.0, t_end_ = 0.0, tolerance_ = 0.0;
    int capacity_ = 0;
    std::size_t values_per_slot_ = 0;
    std::vector<double> intervals_;           ///< (sensor) [s]
    std::vector<long long> next_;             ///< (sensor) index k of its next sample
    std::vector<Output> outputs_;
    std::vector<double> slot_times_;          ///< (pending slot) sample time
    std::vector<std::vector<char>> slot_due_;  ///< (pending slot, sensor)
  };

  comm::Transport* transport_;
  double tolerance_ = 0.0;
  std::vector<GridSensorSpec> grid_specs_;
  std::vector<ParticleSensorSpec> particle_specs_;
  Schedule grid_, particle_;
};

}  // namespace fbar
