// The sensors and trackers of one GPU (sensors_checkpoints.cuh evaluates them; io/sensor_recorder.h schedules them
// and writes their files): the kernels' sensor sets, the device slots of the samples taken since the last flush,
// the per-CUDA-block partials of one sample, and the tracked particles' values.
#pragma once

#include <vector>

#include "MnSystem/Cuda/device_array.cuh"
#include "physics/sensors.cuh"

namespace fbar {

template <typename T, typename TG>
struct SensorState {
  GridSensorSet<TG> grid;                               ///< grid sensors (evaluated in a sample step's grid update)
  int grid_sample_slot = -1;                            ///< the slot the next step's sample goes to (-1: none)
  cuda::DeviceArray<SensorAccum> grid_samples_d;        ///< (slot, sensor)
  cuda::DeviceArray<SensorAccum> partials_d;            ///< (sensor, CUDA block) of one sample
  ParticleSensorSet<T> particle;                        ///< particle sensors
  bool particle_read_v = false;  ///< some particle sensor reads v or C (the landing step records them)
  cuda::DeviceArray<SensorAccum> particle_samples_d;    ///< (slot, body, sensor)
  std::vector<TrackerSet> trackers;                     ///< (body)
  bool trackers_read_v = false;  ///< a tracker reads v or C (the frame-landing steps record them)
  cuda::DeviceArray<double> track_d;  ///< values (kMaxIds x kMaxAttribs), then present (kMaxIds)
};

}  // namespace fbar
