// The sensors and trackers of one GPU (sensors_checkpoints.cuh evaluates them; io/sensor_recorder.h schedules them
// and writes their files): the kernels' sensor sets, the device slots of the samples taken since the last flush,
// the per-CUDA-block partials of one sample, and the tracked particles' values.
#pragma once

#include <vector>

#include "MnSystem/Cuda/device_array.cuh"
#include "physics/grid_fields.h"
#include "physics/sensors.cuh"

namespace fbar {

template <typename T, typename TG>
struct SensorState {
  GridSensorSet<TG> grid;                               ///< grid sensors (evaluated in a sample step's grid update)
  int grid_sample_slot = -1;                            ///< the slot the next step's sample goes to (-1: none)
  /// A grid sensor reads Volume or JBar: a sample step first sums every body's volume onto the nodes (the F-bar
  /// sums, in units of volume_quantum: fixed_quantum of the largest particle volume of the run's bodies).
  bool grid_reads_volume = false;
  double volume_quantum = 0.0;
  cuda::DeviceArray<SensorAccum> grid_samples_d;        ///< (slot, sensor)
  cuda::DeviceArray<SensorAccum> partials_d;            ///< (sensor, CUDA block) of one sample
  GridFieldSet<TG> fields;                              ///< grid fields (recorded in a sample step's grid update)
  cuda::DeviceArray<GridFieldNode> field_nodes[GridFieldSet<TG>::kMax];  ///< (field) its box's node count of records
  cuda::DeviceArray<int> field_count_d;                 ///< (field) records of the last sample
  double field_dt = 0.0;                                ///< [s] dt of the step that recorded them
  ParticleSensorSet<T> particle;                        ///< particle sensors
  bool particle_read_v = false;  ///< some particle sensor reads v or C (the landing step records them)
  cuda::DeviceArray<SensorAccum> particle_samples_d;    ///< (slot, body, sensor)
  std::vector<TrackerSet> trackers;                     ///< (body)
  bool trackers_read_v = false;  ///< a tracker reads v or C (the frame-landing steps record them)
  cuda::DeviceArray<double> track_d;  ///< values (kMaxIds x kMaxAttribs), then present (kMaxIds)
};

}  // namespace fbar
