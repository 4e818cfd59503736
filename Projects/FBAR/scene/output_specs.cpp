// The scene's outputs as the physics evaluates them (output_specs.h).
#include "scene/output_specs.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "physics/constitutive_models.cuh"
#include "scene/scene_error.h"
#include "scene/scene_parse.h"

namespace fbar {

bool grid_field_reads_volume(const GridFieldSpec& spec) {
  for (const std::string& a : spec.attributes)
    if (a == "Volume" || a == "JBar") return true;
  return false;
}

template <typename T>
GridFieldParams<T> make_grid_field_params(const GridFieldSpec& spec, double dx) {
  GridFieldParams<T> p;
  const double snap = dx / 128.0;
  for (int a = 0; a < 3; ++a) {
    double lo = spec.domain_start[a], hi = spec.domain_end[a];
    if (spec.blocks) {  // the whole blocks the box touches: nodes 4 b .. 4 b + 3
      lo = std::floor(lo / (4.0 * dx)) * 4.0 * dx;
      hi = (std::floor(hi / (4.0 * dx)) * 4.0 + 3.0) * dx;
    }
    p.lo[a] = static_cast<T>(lo - snap);
    p.hi[a] = static_cast<T>(hi + snap);
  }
  p.volume = grid_field_reads_volume(spec);
  return p;
}
template GridFieldParams<float> make_grid_field_params<float>(const GridFieldSpec&, double);
template GridFieldParams<double> make_grid_field_params<double>(const GridFieldSpec&, double);

std::size_t grid_field_device_bytes(const Scene& scene) {
  const double dx = scene.simulation.dx;
  std::size_t bytes = 0;
  for (const GridFieldSpec& f : scene.grid_fields) {
    if (!f.toggle) continue;
    const GridFieldParams<double> p = make_grid_field_params<double>(f, dx);
    double nodes = 1.0;
    for (int a = 0; a < 3; ++a) nodes *= std::max(0.0, std::floor((p.hi[a] - p.lo[a]) / dx) + 1.0);
    bytes += static_cast<std::size_t>(nodes) * sizeof(GridFieldNode) + sizeof(int);
  }
  return bytes;
}

bool scene_reads_node_volume(const Scene& scene) {
  if (grid_sensors_read_volume(scene.grid_sensors)) return true;
  for (const GridFieldSpec& f : scene.grid_fields)
    if (f.toggle && grid_field_reads_volume(f)) return true;
  return false;
}

bool grid_sensors_read_volume(const std::vector<GridSensorSpec>& sensors) {
  for (const GridSensorSpec& g : sensors)
    if (g.toggle && (g.attribute == "Volume" || g.attribute == "JBar")) return true;
  return false;
}

/// `spec.output_attribs` resolved in order (canonical names; an alias and its name count once). Throws
/// std::invalid_argument naming bodies[body].output_attribs for a name no engine produces.
std::vector<FrameAttributeSpec> frame_attributes(const BodySpec& spec, int body, const std::string& engine) {
  std::vector<FrameAttributeSpec> out;
  for (const std::string& requested : spec.output_attribs) {
    const std::string name = canonical_attribute(requested);
    bool seen = false;
    for (const auto& a : out) seen = seen || a.name == name;
    if (seen) continue;  // listed twice (e.g. an alias and its canonical name)
    FrameAttributeSpec a;
    if (!resolve_frame_attribute(name, a))
      throw std::invalid_argument((spec.mesh >= 0 ? "meshes[" + std::to_string(spec.mesh) + "]" : "bodies[" + std::to_string(body) + "]") +
                                  ".output_attribs: " + requested +
                                  " is not available on the " + engine);
    out.push_back(a);
  }
  return out;
}

namespace {

GridSensorQuantity quantity_of(const std::string& attribute) {
  if (attribute == "Force") return GridSensorQuantity::Force;
  if (attribute == "BoundaryForce") return GridSensorQuantity::BoundaryForce;
  if (attribute == "Acceleration") return GridSensorQuantity::Acceleration;
  if (attribute == "Momentum") return GridSensorQuantity::Momentum;
  if (attribute == "Velocity") return GridSensorQuantity::Velocity;
  if (attribute == "Mass") return GridSensorQuantity::Mass;
  if (attribute == "MassWater") return GridSensorQuantity::MassWater;
  if (attribute == "PorePressure") return GridSensorQuantity::PorePressure;
  if (attribute == "Volume") return GridSensorQuantity::Volume;
  if (attribute == "JBar") return GridSensorQuantity::JBar;
  throw std::invalid_argument("grid sensor attribute \"" + attribute + "\" has no grid quantity in this release");
}

const char* unit_of(GridSensorQuantity q) {
  switch (q) {
    case GridSensorQuantity::Force: return "N";
    case GridSensorQuantity::BoundaryForce: return "N";
    case GridSensorQuantity::Acceleration: return "m/s^2";
    case GridSensorQuantity::Momentum: return "kg m/s";
    case GridSensorQuantity::Velocity: return "m/s";
    case GridSensorQuantity::Mass: return "kg";
    case GridSensorQuantity::MassWater: return "kg";
    case GridSensorQuantity::PorePressure: return "Pa";
    case GridSensorQuantity::Volume: return "m^3";
    case GridSensorQuantity::JBar: return "-";
  }
  return "-";
}

}  // namespace

FrameAttributeSpec particle_attribute(const ParticleSensorSpec& spec) {
  FrameAttributeSpec a;
  if (!resolve_frame_attribute(canonical_attribute(spec.attribute), a) || a.column.quantity == FrameQuantity::Id)
    throw std::invalid_argument("particle sensor attribute \"" + spec.attribute + "\" is not a particle quantity");
  return a;
}

std::string column_header(SensorOperation op, const std::string& name, const std::string& unit) {
  if (op == SensorOperation::Count) return "Count [-]";
  const std::string u = unit.empty() ? "-" : unit;
  if (op == SensorOperation::Variance) return name + " variance [(" + u + ")^2]";
  return name + " [" + u + "]";
}

template <typename T>
GridSensorParams<T> make_grid_sensor_params(const GridSensorSpec& spec, double dx) {
  GridSensorParams<T> p;
  p.quantity = quantity_of(spec.attribute);
  p.sign = spec.direction_sign;
  const double snap = dx / 128.0;
  for (int a = 0; a < 3; ++a) {
    p.direction[a] = static_cast<T>(spec.direction[a]);
    p.lo[a] = static_cast<T>(spec.domain_start[a] - snap);
    p.hi[a] = static_cast<T>(spec.domain_end[a] + snap);
  }
  return p;
}
template GridSensorParams<float> make_grid_sensor_params<float>(const GridSensorSpec&, double);
template GridSensorParams<double> make_grid_sensor_params<double>(const GridSensorSpec&, double);

template <typename T>
ParticleSensorParams<T> make_particle_sensor_params(const ParticleSensorSpec& spec) {
  ParticleSensorParams<T> p;
  p.column = particle_attribute(spec).column;
  for (int a = 0; a < 3; ++a) {
    p.lo[a] = static_cast<T>(spec.domain_start[a]);
    p.hi[a] = static_cast<T>(spec.domain_end[a]);
  }
  return p;
}
template ParticleSensorParams<float> make_particle_sensor_params<float>(const ParticleSensorSpec&);
template ParticleSensorParams<double> make_particle_sensor_params<double>(const ParticleSensorSpec&);


std::size_t sensor_device_bytes(const Scene& scene) {
  const double frame = 1.0 / scene.simulation.fps;
  std::size_t grid = 0, grid_slots = 0, particle = 0, particle_slots = 0;
  for (const GridSensorSpec& s : scene.grid_sensors)
    if (s.toggle) {
      ++grid;
      grid_slots += static_cast<std::size_t>(std::ceil(frame * s.output_frequency)) + 2;
    }
  for (const ParticleSensorSpec& s : scene.particle_sensors)
    if (s.toggle) {
      ++particle;
      particle_slots += static_cast<std::size_t>(std::ceil(frame * s.output_frequency)) + 2;
    }
  if (grid + particle == 0) return 0;
  const std::size_t partials = static_cast<std::size_t>(GridSensorSet<double>::kMax) * 512;  // kSensorBlocks
  const std::size_t slots = 2 * (grid_slots * grid + particle_slots * particle * scene.bodies.size());
  return (partials + slots) * sizeof(SensorAccum);
}

double sensor_result(SensorOperation op, const SensorAccum& a) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  switch (op) {
    case SensorOperation::Sum: return a.sum.value();
    case SensorOperation::Count: return a.count;
    case SensorOperation::Max: return a.count > 0 ? a.max : nan;
    case SensorOperation::Min: return a.count > 0 ? a.min : nan;
    case SensorOperation::Average: return a.count > 0 ? a.sum.value() / a.count : nan;
    case SensorOperation::Variance:
    case SensorOperation::STDEV: {
      if (!(a.count > 0)) return nan;
      const double mean = a.sum.value() / a.count;
      const double variance = std::max(0.0, a.sum_sq.value() / a.count - mean * mean);  // population variance
      return op == SensorOperation::Variance ? variance : std::sqrt(variance);
    }
  }
  return nan;
}

std::string grid_sensor_column(const GridSensorSpec& spec) {
  return column_header(spec.operation, spec.attribute, unit_of(quantity_of(spec.attribute)));
}

std::string particle_sensor_column(const ParticleSensorSpec& spec) {
  const FrameAttributeSpec a = particle_attribute(spec);
  return column_header(spec.operation, a.name, a.unit);
}


// ---------------------------------------------------------------------------------------------------------------
// Trackers

std::vector<BodyTracker> make_trackers(const Scene& scene) {
  std::vector<BodyTracker> out;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const BodySpec& body = scene.bodies[b];
    if (body.track_particle_id.empty()) continue;
    const std::string where = body_path(scene, b);
    BodyTracker t;
    t.body = static_cast<int>(b);
    t.ids = body.track_particle_id;
    std::vector<long long> sorted = t.ids;
    std::sort(sorted.begin(), sorted.end());
    sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
    if (sorted.size() > static_cast<std::size_t>(TrackerSet::kMaxIds))
      throw SceneError(where + ".track_particle_id", std::to_string(sorted.size()) + " ids",
                       "at most " + std::to_string(TrackerSet::kMaxIds) + " particle IDs per body");
    for (long long id : sorted) {
      if (id > std::numeric_limits<int>::max())
        throw SceneError(where + ".track_particle_id", std::to_string(id), "a particle ID below 2^31");
      t.set.id[t.set.ids++] = static_cast<int>(id);
    }
    std::vector<std::string> attribs = body.track_attribs;
    if (attribs.empty()) attribs = {"Position_Y"};  // ClaymoreUW's default
    BodySpec probe;
    probe.output_attribs = attribs;
    const std::vector<FrameAttributeSpec> a = frame_attributes(probe, static_cast<int>(b), "trackers");
    if (a.size() > static_cast<std::size_t>(TrackerSet::kMaxAttribs))
      throw SceneError(where + ".track_attribs", std::to_string(a.size()) + " attributes",
                       "at most " + std::to_string(TrackerSet::kMaxAttribs));
    for (std::size_t k = 0; k < a.size(); ++k) {
      if (a[k].column.quantity == FrameQuantity::Id || !material_has(body.material.law, a[k].column.quantity))
        throw SceneError(where + ".track_attribs[" + std::to_string(k) + "]", "\"" + a[k].name + "\"",
                         std::string("an attribute of the body's material ") + to_string(body.material.law) + " (not ID)");
      t.set.column[t.set.attribs++] = a[k].column;
      t.names.push_back(a[k].name);
      t.units.push_back(a[k].unit);
    }
    out.push_back(std::move(t));
  }
  return out;
}

bool any_reads_velocity(const std::vector<BodyTracker>& trackers) {
  for (const BodyTracker& t : trackers)
    for (int a = 0; a < t.set.attribs; ++a)
      if (particle_sensor_reads_velocity(t.set.column[a])) return true;
  return false;
}

bool sensors_read_velocity(const Scene& scene) {
  for (const ParticleSensorSpec& s : scene.particle_sensors)
    if (s.toggle && particle_sensor_reads_velocity(particle_attribute(s).column)) return true;
  return any_reads_velocity(make_trackers(scene));
}

}  // namespace fbar
