// Writes the resolved Scene back as scene JSON (run.json, round-trip tests), names of its enums, and equality.
//
// The written document uses canonical key names and values only, writes every key the scene's objects use (a
// body's material carries the parameters of its law, a geometry entry the keys of its object), and marks the
// scene `froude_scaling_applied` so that reading it back yields the same Scene bit for bit: doubles are written in
// shortest round-trip form and read with full precision.
#include <rapidjson/stringbuffer.h>
#include <rapidjson/writer.h>

#include <cmath>
#include <limits>

#include "scene/scene_parse.h"

#include "physics/constitutive_models.cuh"

namespace fbar {

namespace rj = rapidjson;

// ---------------------------------------------------------------------------------------------------------------
// Names
// ---------------------------------------------------------------------------------------------------------------

const char* to_string(Precision p) {
  switch (p) {
    case Precision::Single: return "single";
    case Precision::Double: return "double";
    case Precision::Mixed: return "mixed";
  }
  return "?";
}
const char* precision_description(Precision p) {
  return p == Precision::Mixed ? "mixed: particles double, grid single" : to_string(p);
}
const char* to_string(OnFailure f) { return f == OnFailure::Stop ? "stop" : "reduce_dt"; }
const char* to_string(InitialState s) { return s == InitialState::Rest ? "rest" : "hydrostatic"; }
const char* to_string(Backend b) {
  switch (b) {
    case Backend::Auto: return "auto";
    case Backend::Gpu: return "gpu";
    case Backend::Cpu: return "cpu";
  }
  return "?";
}
const char* to_string(Constitutive c) {
  const char* name = "?";
  visit_material(c, [&](auto m) { name = decltype(m)::kJsonName; });
  return name;
}
const char* to_string(GeometryObject o) {
  switch (o) {
    case GeometryObject::Box: return "Box";
    case GeometryObject::Sphere: return "Sphere";
    case GeometryObject::Cylinder: return "Cylinder";
    case GeometryObject::File: return "File";
    case GeometryObject::Bathymetry: return "Bathymetry";
    case GeometryObject::OsuLwf: return "OSU LWF";
    case GeometryObject::OsuTwb: return "OSU TWB";
  }
  return "?";
}
const char* to_string(GeometryOperation o) {
  switch (o) {
    case GeometryOperation::Add: return "Add";
    case GeometryOperation::Subtract: return "Subtract";
    case GeometryOperation::Union: return "Union";
    case GeometryOperation::Intersection: return "Intersection";
    case GeometryOperation::Difference: return "Difference";
  }
  return "?";
}
const char* to_string(BoundaryObject o) {
  switch (o) {
    case BoundaryObject::Walls: return "Walls";
    case BoundaryObject::Box: return "Box";
    case BoundaryObject::Sphere: return "Sphere";
    case BoundaryObject::Cylinder: return "Cylinder";
    case BoundaryObject::Plane: return "Plane";
    case BoundaryObject::Floor: return "Floor";
    case BoundaryObject::Bathymetry: return "Bathymetry";
    case BoundaryObject::Velocity: return "Velocity";
    case BoundaryObject::Piston: return "Piston";
    case BoundaryObject::Pump: return "Pump";
    case BoundaryObject::HalfSpace: return "HalfSpace";
    case BoundaryObject::OSU_LWF_RAMP: return "OSU_LWF_RAMP";
    case BoundaryObject::OSU_LWF_PADDLE: return "OSU_LWF_PADDLE";
    case BoundaryObject::OSU_TWB_RAMP: return "OSU_TWB_RAMP";
    case BoundaryObject::OSU_TWB_PADDLE: return "OSU_TWB_PADDLE";
    case BoundaryObject::USGS_RAMP: return "USGS_RAMP";
    case BoundaryObject::USGS_GATE: return "USGS_GATE";
    case BoundaryObject::WASIRF_PUMP: return "WASIRF_PUMP";
    case BoundaryObject::TOKYO_HARBOR: return "TOKYO_HARBOR";
  }
  return "?";
}
const char* to_string(Contact c) {
  switch (c) {
    case Contact::Sticky: return "Sticky";
    case Contact::Slip: return "Slip";
    case Contact::Separable: return "Separable";
  }
  return "?";
}
const char* to_string(SensorOperation o) {
  switch (o) {
    case SensorOperation::Sum: return "Sum";
    case SensorOperation::Max: return "Max";
    case SensorOperation::Min: return "Min";
    case SensorOperation::Count: return "Count";
    case SensorOperation::Average: return "Average";
    case SensorOperation::STDEV: return "STDEV";
    case SensorOperation::Variance: return "Variance";
  }
  return "?";
}
const char* axis_name(int axis) { return axis == 0 ? "X" : axis == 1 ? "Y" : "Z"; }

// ---------------------------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------------------------

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// True when every component is infinite with the given sign (an open partition bound).
bool is_open(const Real3& v, int sign) {
  for (double x : v)
    if (x != sign * kInf) return false;
  return true;
}

/// Thin layer over a RapidJSON writer: key/value pairs of the types a scene holds.
template <class W>
class SceneWriter {
 public:
  explicit SceneWriter(W& w) : w_(w) {}

  void key(const char* k) { w_.Key(k); }
  void num(const char* k, double x) { key(k); w_.Double(x); }
  void integer(const char* k, long long x) { key(k); w_.Int64(x); }
  void boolean(const char* k, bool x) { key(k); w_.Bool(x); }
  void str(const char* k, const std::string& s) { key(k); w_.String(s.c_str(), static_cast<rj::SizeType>(s.size())); }
  template <std::size_t N>
  void reals(const char* k, const std::array<double, N>& v) {
    key(k);
    w_.StartArray();
    for (double x : v) w_.Double(x);
    w_.EndArray();
  }
  /// [[x, y], ...] (bed profiles)
  void points(const char* k, const std::vector<std::array<double, 2>>& v) {
    key(k);
    w_.StartArray();
    for (const auto& p : v) {
      w_.StartArray();
      w_.Double(p[0]);
      w_.Double(p[1]);
      w_.EndArray();
    }
    w_.EndArray();
  }
  void ints(const char* k, const Int3& v) {
    key(k);
    w_.StartArray();
    for (int x : v) w_.Int(x);
    w_.EndArray();
  }
  void ids(const char* k, const std::vector<long long>& v) {
    key(k);
    w_.StartArray();
    for (long long x : v) w_.Int64(x);
    w_.EndArray();
  }
  void names(const char* k, const std::vector<std::string>& v) {
    key(k);
    w_.StartArray();
    for (const auto& s : v) w_.String(s.c_str(), static_cast<rj::SizeType>(s.size()));
    w_.EndArray();
  }

  void scene(const Scene& s) {
    w_.StartObject();
    for (const auto& [k, v] : s.wrapper) {  // HydroUQ's metadata, first as HydroUQ writes it
      key(k.c_str());
      w_.String(v.c_str(), static_cast<rj::SizeType>(v.size()));
    }
    simulation(s.simulation);
    key("bodies");
    w_.StartArray();
    for (const auto& b : s.bodies)
      if (b.mesh < 0) body(b);  // a mesh's body is its meshes[] entry, written below
    w_.EndArray();
    key("boundaries");
    w_.StartArray();
    for (const auto& b : s.boundaries) boundary(b);
    w_.EndArray();
    key("grid-sensors");
    w_.StartArray();
    for (const auto& g : s.grid_sensors) grid_sensor(g);
    w_.EndArray();
    key("particle-sensors");
    w_.StartArray();
    for (const auto& p : s.particle_sensors) particle_sensor(p);
    w_.EndArray();
    if (!s.grid_fields.empty()) {
      key("grid-fields");
      w_.StartArray();
      for (const auto& f : s.grid_fields) grid_field(f);
      w_.EndArray();
    }
    if (!s.meshes.empty()) {  // what this release reads of them: the files (resolved) and the offset
      key("meshes");
      w_.StartArray();
      for (const MeshEntrySpec& m : s.meshes) {
        w_.StartObject();
        integer("gpu", m.gpu);
        str("constitutive", m.law == Constitutive::FixedCorotated ? "Meshed" : to_string(m.law));
        if (!m.file_vertices.empty()) {
          str("file_vertices", m.file_vertices);
          str("file_elements", m.file_elements);
        }
        if (!m.file.empty()) str("file", m.file);
        reals("offset", m.offset);
        reals("velocity", m.velocity);
        num("rho", m.rho);
        num("youngs_modulus", m.youngs_modulus);
        num("poisson_ratio", m.poisson_ratio);
        num("ppc", m.ppc);
        boolean("use_FEM", m.use_fem);
        boolean("use_ASFLIP", m.use_asflip);
        num("alpha", m.alpha);
        num("beta_min", m.beta_min);
        num("beta_max", m.beta_max);
        boolean("use_FBAR", m.fbar_elements);
        num("FBAR_ratio", m.fbar_ratio);
        boolean("FBAR_fused_kernel", m.fbar_fused_kernel);
        names("output_attribs", m.output_attribs);
        names("track_attribs", m.track_attribs);
        ids("track_particle_id", m.track_particle_id);
        w_.EndObject();
      }
      w_.EndArray();
    }
    w_.EndObject();
  }

 private:
  void simulation(const SimulationSpec& s) {
    key("simulation");
    w_.StartObject();
    reals("domain", s.domain);
    num("default_dx", s.dx);
    num("default_dt", s.default_dt);
    reals("gravity", s.gravity);
    num("time", s.time);
    num("fps", s.fps);
    integer("frames", s.frames);
    str("save_path", s.save_path);
    str("save_suffix", s.save_suffix);
    boolean("particles_output_exterior_only", s.particles_output_exterior_only);
    num("froude_scaling", s.froude_scaling);
    boolean("froude_scaling_applied", s.froude_scaling_applied);
    if (s.cauchy_scaling != CauchyScaling::Default) boolean("use_cauchy_scaling", s.cauchy_scaling == CauchyScaling::On);
    if (s.cauchy_scaling == CauchyScaling::On) num("cauchy_bulk_ratio", s.cauchy_bulk_ratio);
    integer("info_rate", s.info_rate);
    integer("checkpoint_every", s.checkpoint_every);
    str("precision", to_string(s.precision));
    str("on_failure", to_string(s.on_failure));
    key("seed");
    w_.Uint64(s.seed);
    w_.EndObject();
  }

  void body(const BodySpec& b) {
    w_.StartObject();
    if (b.gpu == kAllGpus)
      str("gpu", "all");
    else
      integer("gpu", b.gpu);
    integer("model", b.model);
    reals("velocity", b.velocity);
    if (b.initial_state != InitialState::Rest) str("initial_state", to_string(b.initial_state));
    // Open bounds (the default) are omitted: infinity has no standard JSON spelling.
    if (!is_open(b.partition_start, -1)) reals("partition_start", b.partition_start);
    if (!is_open(b.partition_end, +1)) reals("partition_end", b.partition_end);
    ids("track_particle_id", b.track_particle_id);
    names("output_attribs", b.output_attribs);
    names("track_attribs", b.track_attribs);
    names("target_attribs", b.target_attribs);
    if (b.output_exterior_only || b.exterior_threshold != 128.0) {
      key("output");
      w_.StartObject();
      boolean("exterior_only", b.output_exterior_only);
      num("exterior_threshold", b.exterior_threshold);
      w_.EndObject();
    }
    material(b.material);
    algorithm(b.algorithm);
    key("geometry");
    w_.StartArray();
    for (const auto& g : b.geometry) geometry(g);
    w_.EndArray();
    w_.EndObject();
  }

  void material(const MaterialSpec& m) {
    key("material");
    w_.StartObject();
    str("type", m.type);
    str("constitutive", to_string(m.law));
    num("ppc", m.ppc);
    num("CFL", m.cfl);
    num("rho", m.rho);
    for_each_material_parameter(m.law, [&](const MaterialParameter& p) {
      if (p.is_flag())
        boolean(p.key, m.*(p.flag));
      else if (std::isfinite(m.*(p.number)))  // an infinite value is the key's absence (tension_cutoff: none)
        num(p.key, m.*(p.number));
    });
    w_.EndObject();
  }

  void algorithm(const AlgorithmSpec& a) {
    key("algorithm");
    w_.StartObject();
    str("type", a.type);
    boolean("use_ASFLIP", a.use_asflip);
    num("ASFLIP_alpha", a.asflip_alpha);
    num("ASFLIP_beta_min", a.asflip_beta_min);
    num("ASFLIP_beta_max", a.asflip_beta_max);
    boolean("use_FBAR", a.use_fbar);
    num("FBAR_psi", a.fbar_psi);
    boolean("FBAR_fused_kernel", a.fbar_fused_kernel);
    str("FBAR_scheme", a.fbar_scheme == FbarScheme::Nodal ? "nodal" : "cell");
    boolean("use_FEM", a.use_fem);
    w_.EndObject();
  }

  void geometry(const GeometrySpec& g) {
    w_.StartObject();
    str("object", to_string(g.object));
    str("operation", to_string(g.operation));
    switch (g.object) {
      case GeometryObject::Box: reals("span", g.span); break;
      case GeometryObject::Sphere: num("radius", g.radius); break;
      case GeometryObject::Cylinder:
        reals("span", g.span);
        num("radius", g.radius);
        str("axis", axis_name(g.axis));
        break;
      case GeometryObject::File:
        str("file", g.file);
        integer("padding", g.padding);
        num("scaling_factor", g.scaling_factor);
        boolean("has_attributes", g.has_attributes);
        names("input_attribs", g.input_attribs);
        break;
      case GeometryObject::Bathymetry:
      case GeometryObject::OsuLwf:
      case GeometryObject::OsuTwb:
        reals("span", g.span);
        if (g.object != GeometryObject::Bathymetry) boolean("use_custom_bathymetry", g.use_custom_bathymetry);
        if (!g.bathymetry.empty()) points("bathymetry", g.bathymetry);
        break;
    }
    reals("offset", g.offset);
    reals("rotate", g.rotate);
    reals("fulcrum", g.fulcrum);
    ints("array", g.array);
    reals("spacing", g.spacing);
    boolean("use_froude_scaling", g.use_froude_scaling);
    ids("track_particle_id", g.track_particle_id);
    w_.EndObject();
  }

  void boundary(const BoundarySpec& b) {
    w_.StartObject();
    str("object", to_string(b.object));
    str("contact", to_string(b.contact));
    reals("domain_start", b.domain_start);
    reals("domain_end", b.domain_end);
    if (!(b.time[0] == 0.0 && b.time[1] == kInf)) reals("time", b.time);  // default: always active
    num("friction_static", b.friction_static);
    num("friction_dynamic", b.friction_dynamic);
    if (b.file.empty()) {
      reals("velocity", b.velocity);
    } else {
      str("file", b.file);
      num("output_frequency", b.output_frequency);
    }
    if (b.angular_velocity != Real3{0.0, 0.0, 0.0}) {  // fbar's rotation
      reals("angular_velocity", b.angular_velocity);
      reals("rotation_center", b.rotation_center);
    }
    ints("array", b.array);
    reals("spacing", b.spacing);
    const bool has_bathymetry = b.object == BoundaryObject::Bathymetry || b.object == BoundaryObject::OSU_LWF_RAMP ||
                                b.object == BoundaryObject::OSU_TWB_RAMP || b.object == BoundaryObject::USGS_RAMP;
    if (has_bathymetry) {
      boolean("use_custom_bathymetry", b.use_custom_bathymetry);
      points("bathymetry", b.bathymetry);
    }
    w_.EndObject();
  }

  void grid_field(const GridFieldSpec& f) {
    w_.StartObject();
    if (!f.name.empty()) str("name", f.name);
    if (!f.toggle) boolean("toggle", false);
    key("attributes");
    w_.StartArray();
    for (const std::string& a : f.attributes) w_.String(a.c_str());
    w_.EndArray();
    num("output_frequency", f.output_frequency);
    reals("domain_start", f.domain_start);
    reals("domain_end", f.domain_end);
    if (f.blocks) boolean("blocks", true);
    w_.EndObject();
  }

  void grid_sensor(const GridSensorSpec& g) {
    w_.StartObject();
    if (!g.name.empty()) str("name", g.name);
    if (!g.toggle) boolean("toggle", false);
    str("attribute", g.attribute);
    str("operation", to_string(g.operation));
    // Axis directions in ClaymoreUW's spelling (X, X+, X-), any other direction as a vector.
    int axis = -1;
    for (int d = 0; d < 3; ++d) {
      const Real3 e{d == 0 ? 1.0 : 0.0, d == 1 ? 1.0 : 0.0, d == 2 ? 1.0 : 0.0};
      if (g.direction == e) axis = d;
    }
    if (axis >= 0) {
      str("direction", std::string(axis_name(axis)) + (g.direction_sign > 0 ? "+" : g.direction_sign < 0 ? "-" : ""));
    } else {
      reals("direction", g.direction);
    }
    num("output_frequency", g.output_frequency);
    reals("domain_start", g.domain_start);
    reals("domain_end", g.domain_end);
    w_.EndObject();
  }

  void particle_sensor(const ParticleSensorSpec& p) {
    w_.StartObject();
    if (!p.name.empty()) str("name", p.name);
    if (!p.toggle) boolean("toggle", false);
    str("attribute", p.attribute);
    str("operation", to_string(p.operation));
    num("output_frequency", p.output_frequency);
    reals("domain_start", p.domain_start);
    reals("domain_end", p.domain_end);
    w_.EndObject();
  }

  W& w_;
};

}  // namespace

std::string write_scene_json(const Scene& scene, bool pretty) {
  rj::StringBuffer sb;
  // Infinity is written only for a partly open partition bound or time window, which no parsed scene has
  // (the reader accepts it there). RapidJSON 1.1's PrettyWriter drops the writer flags, hence indent_json().
  rj::Writer<rj::StringBuffer, rj::UTF8<>, rj::UTF8<>, rj::CrtAllocator, rj::kWriteNanAndInfFlag> w(sb);
  SceneWriter<decltype(w)>(w).scene(scene);
  std::string compact(sb.GetString(), sb.GetSize());
  return pretty ? indent_json(compact) : compact;
}

std::string indent_json(std::string_view compact) {
  std::string out;
  int depth = 0;
  bool in_string = false, escaped = false;
  auto newline = [&]() {
    out += '\n';
    out.append(static_cast<std::size_t>(2 * depth), ' ');
  };
  for (std::size_t i = 0; i < compact.size(); ++i) {
    const char c = compact[i];
    if (in_string) {
      out += c;
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
      continue;
    }
    switch (c) {
      case '"':
        in_string = true;
        out += c;
        break;
      case '{':
      case '[': {
        const char close = c == '{' ? '}' : ']';
        if (i + 1 < compact.size() && compact[i + 1] == close) {  // empty container
          out += c;
          out += close;
          ++i;
          break;
        }
        if (c == '[') {  // an array of scalars stays on one line
          std::size_t j = i + 1;
          bool str = false, esc = false, flat = true;
          for (; j < compact.size(); ++j) {
            const char d = compact[j];
            if (str) {
              if (esc) esc = false;
              else if (d == '\\') esc = true;
              else if (d == '"') str = false;
            } else if (d == '"') {
              str = true;
            } else if (d == '[' || d == '{') {
              flat = false;
              break;
            } else if (d == ']') {
              break;
            }
          }
          if (flat) {
            for (std::size_t k = i; k <= j && k < compact.size(); ++k) {
              out += compact[k];
              if (compact[k] == ',' ) out += ' ';
            }
            i = j;
            break;
          }
        }
        out += c;
        ++depth;
        newline();
        break;
      }
      case '}':
      case ']':
        --depth;
        newline();
        out += c;
        break;
      case ',':
        out += c;
        newline();
        break;
      case ':':
        out += ": ";
        break;
      default:
        out += c;
    }
  }
  out += '\n';
  return out;
}

// ---------------------------------------------------------------------------------------------------------------
// Equality
// ---------------------------------------------------------------------------------------------------------------

bool operator==(const SimulationSpec& a, const SimulationSpec& b) {
  return a.domain == b.domain && a.dx == b.dx && a.default_dt == b.default_dt && a.gravity == b.gravity &&
         a.time == b.time && a.fps == b.fps && a.frames == b.frames && a.save_path == b.save_path &&
         a.save_suffix == b.save_suffix && a.particles_output_exterior_only == b.particles_output_exterior_only &&
         a.froude_scaling == b.froude_scaling && a.froude_scaling_applied == b.froude_scaling_applied &&
         a.cauchy_scaling == b.cauchy_scaling && a.cauchy_bulk_ratio == b.cauchy_bulk_ratio && a.info_rate == b.info_rate && a.checkpoint_every == b.checkpoint_every && a.precision == b.precision && a.on_failure == b.on_failure && a.seed == b.seed;
}
bool operator==(const MaterialSpec& a, const MaterialSpec& b) {
  return a.law == b.law && a.type == b.type && a.ppc == b.ppc && a.cfl == b.cfl && a.rho == b.rho &&
         a.bulk_modulus == b.bulk_modulus && a.gamma == b.gamma && a.viscosity == b.viscosity &&
         a.tension_cutoff == b.tension_cutoff && a.tensile_yield_strength == b.tensile_yield_strength &&
         a.hardening_modulus == b.hardening_modulus &&
         a.youngs_modulus == b.youngs_modulus && a.poisson_ratio == b.poisson_ratio &&
         a.friction_angle == b.friction_angle && a.cohesion == b.cohesion && a.logJp0 == b.logJp0 &&
         a.beta == b.beta && a.vol_correction == b.vol_correction && a.xi == b.xi && a.hardening == b.hardening;
}
bool operator==(const AlgorithmSpec& a, const AlgorithmSpec& b) {
  return a.type == b.type && a.use_asflip == b.use_asflip && a.asflip_alpha == b.asflip_alpha &&
         a.asflip_beta_min == b.asflip_beta_min && a.asflip_beta_max == b.asflip_beta_max &&
         a.use_fbar == b.use_fbar && a.fbar_psi == b.fbar_psi && a.fbar_fused_kernel == b.fbar_fused_kernel &&
         a.fbar_scheme == b.fbar_scheme && a.use_fem == b.use_fem;
}
bool operator==(const GeometrySpec& a, const GeometrySpec& b) {
  return a.object == b.object && a.operation == b.operation && a.span == b.span && a.offset == b.offset &&
         a.radius == b.radius && a.axis == b.axis && a.rotate == b.rotate && a.fulcrum == b.fulcrum &&
         a.array == b.array && a.spacing == b.spacing && a.file == b.file && a.padding == b.padding &&
         a.scaling_factor == b.scaling_factor && a.use_froude_scaling == b.use_froude_scaling &&
         a.has_attributes == b.has_attributes && a.input_attribs == b.input_attribs &&
         a.track_particle_id == b.track_particle_id;
}
bool operator==(const BodySpec& a, const BodySpec& b) {
  return a.gpu == b.gpu && a.model == b.model && a.velocity == b.velocity && a.initial_state == b.initial_state &&
         a.partition_start == b.partition_start &&
         a.partition_end == b.partition_end && a.track_particle_id == b.track_particle_id &&
         a.output_attribs == b.output_attribs && a.output_exterior_only == b.output_exterior_only &&
         a.exterior_threshold == b.exterior_threshold && a.track_attribs == b.track_attribs &&
         a.target_attribs == b.target_attribs && a.material == b.material && a.algorithm == b.algorithm &&
         a.geometry == b.geometry && a.mesh == b.mesh;
}
bool operator==(const BoundarySpec& a, const BoundarySpec& b) {
  return a.object == b.object && a.contact == b.contact && a.domain_start == b.domain_start &&
         a.domain_end == b.domain_end && a.time == b.time && a.friction_static == b.friction_static &&
         a.friction_dynamic == b.friction_dynamic && a.velocity == b.velocity && a.file == b.file &&
         a.output_frequency == b.output_frequency && a.array == b.array && a.spacing == b.spacing &&
         a.bathymetry == b.bathymetry && a.use_custom_bathymetry == b.use_custom_bathymetry &&
         a.angular_velocity == b.angular_velocity &&
         (a.angular_velocity == Real3{0.0, 0.0, 0.0} || a.rotation_center == b.rotation_center);  // a centre acts when it turns
}
bool operator==(const GridSensorSpec& a, const GridSensorSpec& b) {
  return a.name == b.name && a.toggle == b.toggle && a.attribute == b.attribute && a.operation == b.operation &&
         a.direction == b.direction &&
         a.direction_sign == b.direction_sign && a.output_frequency == b.output_frequency &&
         a.domain_start == b.domain_start && a.domain_end == b.domain_end;
}
bool operator==(const GridFieldSpec& a, const GridFieldSpec& b) {
  return a.name == b.name && a.toggle == b.toggle && a.domain_start == b.domain_start && a.domain_end == b.domain_end &&
         a.output_frequency == b.output_frequency && a.attributes == b.attributes && a.blocks == b.blocks;
}
bool operator==(const ParticleSensorSpec& a, const ParticleSensorSpec& b) {
  return a.name == b.name && a.toggle == b.toggle && a.attribute == b.attribute && a.operation == b.operation &&
         a.output_frequency == b.output_frequency && a.domain_start == b.domain_start && a.domain_end == b.domain_end;
}
bool operator==(const MeshEntrySpec& a, const MeshEntrySpec& b) {
  return a.file_vertices == b.file_vertices && a.file_elements == b.file_elements && a.file == b.file &&
         a.offset == b.offset && a.velocity == b.velocity && a.gpu == b.gpu && a.law == b.law &&
         a.fbar_elements == b.fbar_elements && a.rho == b.rho && a.youngs_modulus == b.youngs_modulus &&
         a.poisson_ratio == b.poisson_ratio && a.ppc == b.ppc && a.use_fem == b.use_fem &&
         a.use_asflip == b.use_asflip && a.alpha == b.alpha && a.beta_min == b.beta_min && a.beta_max == b.beta_max &&
         a.fbar_ratio == b.fbar_ratio && a.fbar_fused_kernel == b.fbar_fused_kernel &&
         a.output_attribs == b.output_attribs && a.track_attribs == b.track_attribs &&
         a.track_particle_id == b.track_particle_id && a.summary == b.summary;
}
bool operator==(const Scene& a, const Scene& b) {
  return a.simulation == b.simulation && a.bodies == b.bodies && a.boundaries == b.boundaries &&
         a.grid_sensors == b.grid_sensors && a.particle_sensors == b.particle_sensors &&
         a.grid_fields == b.grid_fields && a.meshes == b.meshes &&
         a.wrapper == b.wrapper;
}

}  // namespace fbar
