// Grid-sensor schedule, reduction over ranks and CSV files (the run loop's side of physics/sensors.cuh).
//
// Sample times. Sensor i samples at t0 + k / output_frequency_i (k = 0, 1, ...) for every such time before the run's
// end. The run loop shortens steps so that one starts exactly at each sample time (next_time()); that step's grid
// update evaluates every sensor on the nodes of the particles' state at the sample time (the engine writes one
// SensorAccum per sensor into the sample's slot), and the row written holds the sample time itself. Samples of
// several sensors at the same time share a slot.
//
// Reduction. Each rank accumulates the nodes it owns (a halo node counts once, on the rank owning its plane); at
// flush() (every frame, and when the run ends) the slots are summed (sum, sum of squares, count) and max/min-reduced
// over ranks in rank order, so every rank computes the same values, and rank 0 appends one row per due sensor.
//
// Files, in simulation.save_path, one per enabled sensor (ClaymoreUW's names; the index is the sensor's place in
// the scene's grid-sensors array, and the device is 0 because every GPU's nodes are in it):
//   gridTarget[i]_dev[0].csv    header "Time [s],<Attribute> [unit]" (Count: "Count [-]"), then "time,value" rows.
// A sample with no node in the box writes 0 for Sum and Count and nan for the others.
#pragma once

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "comm/transport.h"
#include "physics/sensors.cuh"
#include "scene/scene.h"

namespace fbar {

/// The kernel parameters of grid sensor `spec` (domain box and direction in the grid scalar type T).
template <typename T>
GridSensorParams<T> make_grid_sensor_params(const GridSensorSpec& spec);

/// The value a sensor reports from its sample's reduction (SensorOperation of scene.h).
double sensor_result(SensorOperation op, const SensorAccum& a);

/// "Force [N]", "Count [-]", ...: the value column's header of a grid sensor.
std::string grid_sensor_column(const GridSensorSpec& spec);

class SensorRecorder {
 public:
  /// The enabled grid sensors of `scene` (toggle true) for a run from t0 to t_end [s]. Rank 0 of `transport`
  /// (nullptr: one rank) creates the files and writes their headers.
  SensorRecorder(const Scene& scene, comm::Transport* transport, double t0, double t_end);
  ~SensorRecorder();
  SensorRecorder(const SensorRecorder&) = delete;
  SensorRecorder& operator=(const SensorRecorder&) = delete;

  bool empty() const { return grid_.empty(); }
  /// Enabled grid sensors, in scene order: what the engine evaluates (slot values come in this order).
  const std::vector<GridSensorSpec>& grid_sensors() const { return specs_; }
  /// Slots an engine must hold between two flushes (the samples of one frame interval, bounded from the rates).
  int capacity() const { return capacity_; }

  /// [s] the next sample time (+infinity when none is left before the end).
  double next_time() const;
  /// [s] the first sample time after t (beyond the tolerance): where a step starting at t must end at the latest.
  double next_time_after(double t) const;
  /// Times closer than this are the same time (a billionth of the shortest sample interval) [s].
  double tolerance() const { return tolerance_; }
  /// The slot the step starting at time t must fill, or -1 when no sensor samples at t.
  int slot_for(double t) const;
  /// The step starting at t (slot_for(t) >= 0) was committed: its slot is taken and the due sensors move on.
  void taken(double t);
  /// Slots taken since the last flush.
  int pending() const { return static_cast<int>(slots_.size()); }
  /// Reduces this rank's values of the pending slots (slot-major: values[slot * sensors + i]) over ranks and writes
  /// the rows (rank 0). Every rank calls it at the same points.
  void flush(const std::vector<SensorAccum>& values);

 private:
  struct Sensor {
    std::size_t scene_index = 0;
    double interval = 0.0;  ///< [s]
    long long next = 0;     ///< index k of the next sample
    std::FILE* file = nullptr;
    std::filesystem::path path;
  };
  struct Slot {
    double time = 0.0;
    std::vector<char> due;  ///< (sensor) whether it samples at this time
  };
  double sample_time(const Sensor& s, long long k) const { return t0_ + static_cast<double>(k) * s.interval; }
  bool due(const Sensor& s, double t) const;

  comm::Transport* transport_;
  double t0_, t_end_;
  double tolerance_ = 0.0;
  int capacity_ = 0;
  std::vector<GridSensorSpec> specs_;
  std::vector<Sensor> grid_;
  std::vector<Slot> slots_;
};

}  // namespace fbar
