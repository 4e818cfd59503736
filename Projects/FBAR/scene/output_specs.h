// The scene's outputs as the physics evaluates them (no files, no ranks): a body's frame attributes, the kernel
// parameters of its grid and particle sensors, its trackers, and what they cost on the device. The engines, the run
// loop's recorders (io/sensor_recorder.h), the frames (io/particle_frame.h) and the release policy
// (scene_support.cpp) read them here.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "physics/frame_attributes.h"
#include "physics/grid_fields.h"
#include "physics/sensors.cuh"
#include "scene/attributes.h"
#include "scene/scene.h"

namespace fbar {

/// `spec.output_attribs` resolved in order (canonical names; an alias and its name count once). Throws
/// std::invalid_argument naming bodies[body].output_attribs for a name no engine produces.
std::vector<FrameAttributeSpec> frame_attributes(const BodySpec& spec, int body, const std::string& engine);

/// The kernel parameters of grid sensor `spec` (domain box and direction in the grid scalar type T). dx [m]: the box
/// is widened by dx / 128 on every side, so a node on a face (a wall's node plane, placed by ClaymoreUW users as
/// domain_start or domain_end) is inside whatever the round-off of its position in T.
template <typename T>
GridSensorParams<T> make_grid_sensor_params(const GridSensorSpec& spec, double dx = 0.0);
/// The kernel parameters of particle sensor `spec` (its attribute as a frame column; box in T).
template <typename T>
ParticleSensorParams<T> make_particle_sensor_params(const ParticleSensorSpec& spec);

/// The engines' box of grid field `spec` (widened by dx / 128 as a grid sensor's; a `blocks` field's box grown to
/// the whole grid blocks it touches, so that a block's point sums all its nodes).
template <typename T>
GridFieldParams<T> make_grid_field_params(const GridFieldSpec& spec, double dx);
/// Whether grid field `spec` reads Volume or JBar.
bool grid_field_reads_volume(const GridFieldSpec& spec);
/// Device memory the GPU engine keeps for the scene's grid fields [bytes]: per enabled field, one record per node its
/// box can hold (physics/grid_fields.h GridFieldNode).
std::size_t grid_field_device_bytes(const Scene& scene);

/// Whether an enabled grid sensor reads Volume or JBar: the engines then sum every body's volume onto the nodes on
/// the steps such a sensor samples (in the grid's F-bar sums, grid_channels.h).
bool grid_sensors_read_volume(const std::vector<GridSensorSpec>& sensors);
/// The same for the scene's enabled grid sensors and grid fields together (the grid carries the F-bar sums for them).
bool scene_reads_node_volume(const Scene& scene);

/// Whether an enabled particle sensor or a tracker of the scene reads velocities (particle_sensor_reads_velocity):
/// the GPU engine then keeps v and C per particle on the steps that land on their times (its memory plan counts
/// them).
bool sensors_read_velocity(const Scene& scene);

/// Device memory the GPU engine's sensors take [bytes]: the per-CUDA-block partials of one sample and the sample
/// slots of one frame interval (their doubling included).
std::size_t sensor_device_bytes(const Scene& scene);

/// The value a sensor reports from its sample's reduction (SensorOperation of scene.h).
double sensor_result(SensorOperation op, const SensorAccum& a);

/// "Force [N]", "Count [-]", ...: the value column's header of a grid sensor.
std::string grid_sensor_column(const GridSensorSpec& spec);
/// "Position_Y [m]", "Count [-]", ...: the value column's header of a particle sensor.
std::string particle_sensor_column(const ParticleSensorSpec& spec);

/// One body's tracker (bodies[].track_particle_id with track_attribs, or bodies[].trackers {ids, attribs}).
struct BodyTracker {
  int body = 0;
  TrackerSet set;                  ///< what the engines evaluate (IDs sorted, without repeats)
  std::vector<long long> ids;      ///< the scene's IDs, in its order (the file's column order)
  std::vector<std::string> names;  ///< the attributes' canonical names
  std::vector<std::string> units;
};

/// The trackers of `scene`: one per body with track_particle_id (attributes: track_attribs, Position_Y when none).
/// Throws SceneError naming the key for too many IDs or attributes, and for an attribute the body does not have.
std::vector<BodyTracker> make_trackers(const Scene& scene);
/// Whether one of these trackers reads velocities (particle_sensor_reads_velocity).
bool any_reads_velocity(const std::vector<BodyTracker>& trackers);

/// A particle sensor's attribute as a frame attribute (name, unit, column): the frames' own resolution. Throws
/// std::invalid_argument for a name that is not a particle quantity.
FrameAttributeSpec particle_attribute(const ParticleSensorSpec& spec);
/// The header of a value column: "Count [-]", "<name> variance [(<unit>)^2]" or "<name> [<unit>]".
std::string column_header(SensorOperation op, const std::string& name, const std::string& unit);

}  // namespace fbar
