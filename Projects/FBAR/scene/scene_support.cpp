// The release policy, in one place: which parsed and validated scene features this build's engine can run.
//
// Both engines run every material of MaterialTypes (constitutive_models.cuh); APIC/MLS transfers, PIC-FLIP / ASFLIP
// and F-bar; Box / Sphere / Cylinder / Bathymetry / OSU LWF / OSU TWB geometry and File geometry (.sdf solids; .csv,
// .pos, .bgeo, .h5 positions) with every operation, rotation and arrays; every boundary object (Sticky / Slip /
// Separable, Coulomb friction, constant velocity or motion files, any time window);
// .bgeo / .geo / .csv frames with the attributes material_supports_attribute() (physics/frame_attributes.h) accepts; grid sensors of Force,
// BoundaryForce, Acceleration, Momentum, Velocity and Mass; particle sensors of every particle quantity frames write.
// Everything else the scene schema names is parsed and range-checked by scene_parse.cpp, then refused here. A later
// release enables a feature by deleting its line.
#include <algorithm>
#include <array>
#include <iomanip>
#include <set>
#include <sstream>
#include <string>
#include <string_view>

#include "physics/frame_attributes.h"
#include "physics/motion_path.h"
#include "physics/sensors.cuh"
#include "scene/attributes.h"
#include "scene/output_specs.h"
#include "scene/scene_parse.h"

namespace fbar {

namespace {

std::string q(std::string_view s) { return "\"" + std::string(s) + "\""; }
std::string idx(const char* array, std::size_t i) { return std::string(array) + "[" + std::to_string(i) + "]"; }

/// Throws the "not supported yet" error: `expected` says what this release runs, `key` names the feature.
[[noreturn]] void refuse(const std::string& path, const std::string& value, const std::string& expected,
                         const std::string& key, const char* unit = "") {
  throw SceneError(path, value, expected + "; " + key + " is not supported yet in this release", unit);
}

}  // namespace

void check_supported(const Scene& scene) {
  const SimulationSpec& sim = scene.simulation;
  for (std::size_t i = 0; i < scene.bodies.size(); ++i) {
    const BodySpec& b = scene.bodies[i];
    const std::string p = b.mesh >= 0 ? idx("meshes", static_cast<std::size_t>(b.mesh)) : idx("bodies", i);
    const MaterialSpec& m = b.material;
    const AlgorithmSpec& a = b.algorithm;
    if (m.type != "particles") refuse(p + ".material.type", q(m.type), "\"particles\"", "material type mesh");
    if (material_index(m.law) < 0)  // the laws of MaterialTypes (constitutive_models.cuh) run
      refuse(p + ".material.constitutive", q(to_string(m.law)), "one of " + supported_material_names(),
             std::string("constitutive ") + to_string(m.law));
    if (a.type != "particles") refuse(p + ".algorithm.type", q(a.type), "\"particles\"", "algorithm type mesh");
    if (a.use_fem && b.mesh < 0) refuse(p + ".algorithm.use_FEM", "true", "false", "use_FEM");
    // ASFLIP / PIC-FLIP (alpha, beta) and F-bar (FBAR_psi) run on both engines.
    for (std::size_t j = 0; j < b.geometry.size(); ++j) {
      const GeometrySpec& g = b.geometry[j];
      const std::string gp = p + "." + idx("geometry", j);
      bool stores_logjp = false;
      visit_material(m.law, [&](auto mm) { stores_logjp = decltype(mm)::kOutputs.log_jp; });
      if (g.object == GeometryObject::File && g.has_attributes)
        for (std::size_t k = 0; k < g.input_attribs.size(); ++k) {
          if (g.input_attribs[k] == "logJp" && !stores_logjp)
            throw SceneError(gp + ".input_attribs[" + std::to_string(k) + "]", "\"logJp\"",
                             std::string("an attribute a ") + to_string(m.law) +
                                 " particle stores (logJp seeds NACC and DruckerPrager bodies)");
        }
    }
    if (b.track_particle_id.empty() && !b.track_attribs.empty())
      throw SceneError(p + ".track_attribs", q(b.track_attribs.front()),
                       "track_particle_id as well (the particles whose attributes are tracked)");
    for (std::size_t k = 0; k < b.output_attribs.size(); ++k) {
      const std::string& name = b.output_attribs[k];
      // The engine's own list decides (DefGrad_* only for a material that stores F), so --check and a run agree.
      if (!material_supports_attribute(m.law, name)) {
        MaterialOutputs outputs{false, false};
        visit_material(m.law, [&](auto law) { outputs = decltype(law)::kOutputs; });
        const std::string law = to_string(m.law);
        const std::string expected =
            std::string("one of ID, Mass, Volume, Position_*, Velocity_*, Velocity_Magnitude, J, Pressure, "
                        "VonMisesStress, StressCauchy_* (components, Invariant1-3, 1-3)") +
            (outputs.deformation_gradient
                 ? ", DefGrad_*, StressPK1_*, StressPK2_*, StrainSmall_* (each: components, Invariant1-3, 1-3), "
                   "Dilation, VonMisesStrain"
                 : "") +
            (outputs.log_jp ? ", logJp" : "") + (outputs.pore_pressure ? ", PorePressure" : "") + " for " + law;
        const std::string canonical = canonical_attribute(name);
        if (canonical.empty())  // a name fbar does not write at all
          refuse(p + "." + idx("output_attribs", k), q(name), expected, "output attribute " + name);
        // An attribute fbar writes, but not for this law (its state has no such quantity).
        throw SceneError(p + "." + idx("output_attribs", k), q(name),
                         expected + " (a " + law + " body has no " +
                             (canonical == "PorePressure" ? "pore water: PorePressure is a CoupledUP body's"
                                                          : "such quantity in its state") +
                             ")");
      }
    }
    std::set<std::string> columns;  // an alias and its name are one column
    for (const std::string& name : b.output_attribs)
      if (canonical_attribute(name) != "ID") columns.insert(canonical_attribute(name));
    const int float_columns = static_cast<int>(columns.size());
    if (float_columns > kMaxFrameColumns)
      throw SceneError(p + ".output_attribs", std::to_string(float_columns) + " attributes besides ID",
                       "at most " + std::to_string(kMaxFrameColumns) + " per body (the GPU's frame table)");
  }

  for (std::size_t i = 0; i < scene.boundaries.size(); ++i) {
    const BoundarySpec& b = scene.boundaries[i];
    const std::string p = idx("boundaries", i);
    if (!b.file.empty()) {  // the file must hold what the scene says (read here so that --check tells)
      try {
        MotionPath::load(b.file, sim.froude_scaling, b.output_frequency, p + ".file");
      } catch (const std::invalid_argument& e) {
        const std::string why = e.what();
        throw SceneError(p + ".file", q(b.file),
                         "a motion file of rows 'time, displacement, velocity' at output_frequency (" +
                             why.substr(why.find(": ") + 2) + ")");
      }
    }
    // Every object runs: facility objects are built from generic pieces (scene/facilities.h expand_boundary).
  }
  make_trackers(scene);  // throws for too many IDs or attributes, or an attribute a body does not have
  int enabled = 0;
  for (std::size_t i = 0; i < scene.grid_sensors.size(); ++i) {
    const GridSensorSpec& g = scene.grid_sensors[i];
    if (!g.toggle) continue;
    ++enabled;
    if (g.attribute == "MassWater" || g.attribute == "PorePressure") {
      bool saturated = false;  // only saturated (CoupledUP) bodies carry pore water to the grid
      for (const BodySpec& b : scene.bodies) saturated = saturated || material_has_pore_fluid(b.material.law);
      if (!saturated)
        throw SceneError(idx("grid-sensors", i) + ".attribute", q(g.attribute),
                         "a grid attribute the scene has: " + g.attribute +
                             " is the pore water of CoupledUP bodies, and the scene has none");
    }
  }
  int fields = 0;
  for (std::size_t i = 0; i < scene.grid_fields.size(); ++i) {
    const GridFieldSpec& f = scene.grid_fields[i];
    if (!f.toggle) continue;
    ++fields;
    bool saturated = false;
    for (const BodySpec& b : scene.bodies) saturated = saturated || material_has_pore_fluid(b.material.law);
    for (std::size_t k = 0; k < f.attributes.size(); ++k)
      if (!saturated && (f.attributes[k] == "MassWater" || f.attributes[k] == "PorePressure"))
        throw SceneError(idx("grid-fields", i) + "." + idx("attributes", k), q(f.attributes[k]),
                         "a grid attribute the scene has: " + f.attributes[k] +
                             " is the pore water of CoupledUP bodies, and the scene has none");
  }
  if (fields > GridFieldSet<double>::kMax)
    throw SceneError("grid-fields", std::to_string(fields) + " enabled fields",
                     "at most " + std::to_string(GridFieldSet<double>::kMax) + " (switch some off with toggle: false)");
  if (enabled > GridSensorSet<double>::kMax)
    throw SceneError("grid-sensors", std::to_string(enabled) + " enabled sensors",
                     "at most " + std::to_string(GridSensorSet<double>::kMax) + " (switch some off with toggle: false)");
  enabled = 0;
  for (std::size_t i = 0; i < scene.particle_sensors.size(); ++i) {
    const ParticleSensorSpec& s = scene.particle_sensors[i];
    if (!s.toggle) continue;
    ++enabled;
    const std::string path = idx("particle-sensors", i) + ".attribute";
    FrameColumn column;
    try {
      column = make_particle_sensor_params<double>(s).column;
    } catch (const std::invalid_argument&) {
      throw SceneError(path, q(s.attribute), "a particle quantity (Position_*, Velocity_*, Mass, Volume, J, Pressure, ...; not ID)");
    }
    bool some_body = false;
    for (const BodySpec& b : scene.bodies) some_body = some_body || material_has(b.material.law, column.quantity);
    if (!some_body)
      throw SceneError(path, q(s.attribute), "an attribute some body's material has (no body stores it)");
  }
  if (enabled > ParticleSensorSet<double>::kMax)
    throw SceneError("particle-sensors", std::to_string(enabled) + " enabled sensors",
                     "at most " + std::to_string(ParticleSensorSet<double>::kMax) +
                         " (switch some off with toggle: false)");
}

}  // namespace fbar
