// The scene reader's boundaries[], grid-sensors[] and particle-sensors[] entries (scene_parse.cpp gives the
// conventions).
#include "scene/scene_parse_detail.h"

namespace fbar::scene_json {

namespace {

// ---------------------------------------------------------------------------------------------------------------
// boundaries[], grid-sensors[], particle-sensors[]
// ---------------------------------------------------------------------------------------------------------------


/// domain_start / domain_end (both required); `strict` (boundaries): end > start per axis, an error otherwise.
/// A sensor's box (`ctx` given) may be inverted (end < start on some axis): ClaymoreUW runs such a scene with a
/// sensor that holds nothing, so fbar keeps the box (it contains nothing), and warns once naming the first axis.
std::pair<Real3, Real3> read_region(ObjectReader& o, bool strict, const Context* ctx = nullptr) {
  const rj::Value* s = o.get("domain_start");
  const rj::Value* e = o.get("domain_end");
  if (!s) o.missing("domain_start", "an array of 3 numbers", "m");
  if (!e) o.missing("domain_end", "an array of 3 numbers", "m");
  const Real3 start = read_real3(*s, o.sub("domain_start"), kAny, "m");
  const Real3 end = read_real3(*e, o.sub("domain_end"), kAny, "m");
  std::vector<int> inverted;
  for (int d = 0; d < 3; ++d)
    if (strict ? !(end[d] > start[d]) : !(end[d] >= start[d])) {
      if (strict || !ctx)
        throw SceneError(index_path(o.sub("domain_end"), d), num_text(end[d]),
                         std::string("a number ") + (strict ? ">" : ">=") + " domain_start[" + std::to_string(d) +
                             "] (" + num_text(start[d]) + "): the box is empty; swap the two values or correct them",
                         "m");
      inverted.push_back(d);
    }
  if (!inverted.empty()) {
    const int d = inverted.front();
    std::string also;
    for (std::size_t k = 1; k < inverted.size(); ++k) also += (also.empty() ? "" : ", ") + std::to_string(inverted[k]);
    ctx->warn(index_path(o.sub("domain_end"), d) + ": " + num_text(end[d]) + " m is below domain_start[" +
              std::to_string(d) + "] (" + num_text(start[d]) + " m)" +
              (also.empty() ? std::string() : " (and on axis " + also + ")") +
              ": the sensor's box holds nothing. ClaymoreUW runs the scene with this empty sensor; fbar runs it too "
              "and writes the sensor's file with 0 for Sum and Count and NaN for Max, Min, Average, Variance and "
              "STDEV (undefined on no values)");
  }
  return {start, end};
}

/// ClaymoreUW's "type" label on boundaries ("grid") and sensors ("grid" / "particles"): accepted when it matches.
/// Returns the object's "name" ("" when absent).
std::string read_type_label(ObjectReader& o, const char* expected) {
  if (auto* x = o.get("type")) {
    const std::string t = read_string(*x, o.sub("type"), expected);
    if (lower(t) != expected) throw SceneError(o.sub("type"), json_text(*x), in_quotes(expected) + " (or no type)");
  }
  if (auto* x = o.get("name")) return read_string(*x, o.sub("name"));
  return "";
}

}  // namespace

BoundarySpec parse_boundary(const rj::Value& v, const std::string& path, const Context& ctx) {
  BoundarySpec b;
  ObjectReader o(v, path, kBoundaryKeys, ctx, "boundaries[]");
  if (auto* x = o.get("object")) b.object = read_enum(*x, o.sub("object"), kBoundaryObjects);
  else b.object = BoundaryObject::Box;  // ClaymoreUW's default
  if (auto* x = o.get("contact")) b.contact = read_enum(*x, o.sub("contact"), kContacts);
  if (b.object == BoundaryObject::Plane) {
    // A Plane is the line from (start_x, start_y) to (end_x, end_y): it may descend (end_y < start_y); z is unused.
    const rj::Value* st = o.get("domain_start");
    const rj::Value* en = o.get("domain_end");
    if (!st) o.missing("domain_start", "an array of 3 numbers (the line's first point in x, y)", "m");
    if (!en) o.missing("domain_end", "an array of 3 numbers (the line's last point in x, y)", "m");
    b.domain_start = read_real3(*st, o.sub("domain_start"), kAny, "m");
    b.domain_end = read_real3(*en, o.sub("domain_end"), kAny, "m");
    if (!(b.domain_end[0] > b.domain_start[0]))
      throw SceneError(index_path(o.sub("domain_end"), 0), num_text(b.domain_end[0]),
                       "a number > domain_start[0] (" + num_text(b.domain_start[0]) + "): a Plane runs along +x", "m");
  } else {
    std::tie(b.domain_start, b.domain_end) = read_region(o, true);
  }
  if (auto* x = o.get("time")) {
    // ClaymoreUW writes [start, end, -1] (its third element is deprecated and unused); [start, end] is fbar's.
    if (x->IsArray() && x->Size() == 3) {
      const std::string third = index_path(o.sub("time"), 2);
      const double flag = read_number((*x)[2], third, kAny, "-");
      if (flag != -1.0) ctx.warn(third + ": " + num_text(flag) + " is ignored (ClaymoreUW's deprecated third entry)");
    }
    const auto t = read_reals<2>(*x, o.sub("time"), kAny, "s", true, true);
    if (std::isinf(t[0])) throw SceneError(index_path(o.sub("time"), 0), num_text(t[0]), "a finite number", "s");
    if (!(t[1] > t[0]))
      throw SceneError(index_path(o.sub("time"), 1), num_text(t[1]), "a number > time[0] (" + num_text(t[0]) + ")", "s");
    b.time = {t[0], t[1]};
  }
  if (auto* x = o.get("friction_static")) b.friction_static = read_number(*x, o.sub("friction_static"), kNonNegative, "-");
  // ClaymoreUW: the dynamic coefficient defaults to the static one.
  b.friction_dynamic = b.friction_static;
  if (auto* x = o.get("friction_dynamic")) b.friction_dynamic = read_number(*x, o.sub("friction_dynamic"), kNonNegative, "-");
  const rj::Value* velocity = o.get("velocity");
  const rj::Value* file = o.get("file");
  if (velocity && file)
    throw SceneError(o.sub("file"), json_text(*file), "either velocity (constant) or file (motion), not both");
  if (velocity) b.velocity = read_real3(*velocity, o.sub("velocity"), kAny, "m/s");
  if (file) {
    b.file = ctx.resolve_file(*file, o.sub("file"));
    auto f = o.get_any({"output_frequency", "output_freq"});
    if (!f) o.missing("output_frequency", "the sampling rate of the motion file, a number > 0", "Hz");
    b.output_frequency = read_number(*f.value, f.path, kPositive, "Hz");
  }
  // fbar's rotation: about rotation_center (default: the box's centre), at angular_velocity from time[0].
  for (int a = 0; a < 3; ++a) b.rotation_center[a] = 0.5 * (b.domain_start[a] + b.domain_end[a]);
  if (auto* x = o.get("angular_velocity")) b.angular_velocity = read_real3(*x, o.sub("angular_velocity"), kAny, "rad/s");
  if (auto* x = o.get("rotation_center")) b.rotation_center = read_real3(*x, o.sub("rotation_center"), kAny, "m");
  if (b.angular_velocity != Real3{0.0, 0.0, 0.0} &&
      (b.object == BoundaryObject::Pump || b.object == BoundaryObject::WASIRF_PUMP))
    throw SceneError(o.sub("angular_velocity"), json_text(*o.get("angular_velocity")),
                     "[0, 0, 0]: a pump drives a flow and does not turn", "rad/s");
  if (auto* x = o.get("array")) b.array = read_int3(*x, o.sub("array"), at_least(1));
  if (auto* x = o.get("spacing")) b.spacing = read_real3(*x, o.sub("spacing"), kAny, "m");

  const bool has_bathymetry = b.object == BoundaryObject::Bathymetry || b.object == BoundaryObject::OSU_LWF_RAMP ||
                              b.object == BoundaryObject::OSU_TWB_RAMP || b.object == BoundaryObject::USGS_RAMP;
  if (has_bathymetry) {
    if (auto* x = o.get("use_custom_bathymetry")) b.use_custom_bathymetry = read_bool(*x, o.sub("use_custom_bathymetry"));
    if (auto* x = o.get("bathymetry")) b.bathymetry = read_bed_points(*x, o.sub("bathymetry"));
    if (b.object == BoundaryObject::Bathymetry && b.bathymetry.size() < 2)  // ClaymoreUW: silently nothing
      throw SceneError(o.sub("bathymetry"), b.bathymetry.empty() ? "(missing)" : "1 point",
                       "at least 2 [x, y] points: a Bathymetry boundary is the bed through them", "m");
    if (b.use_custom_bathymetry && b.bathymetry.size() < 2)
      throw SceneError(o.sub("bathymetry"), b.bathymetry.empty() ? "(missing)" : "1 point",
                       "at least 2 [x, y] points when use_custom_bathymetry is true", "m");
  }
  if ((b.object == BoundaryObject::Pump || b.object == BoundaryObject::WASIRF_PUMP) &&
      b.velocity == Real3{0.0, 0.0, 0.0})
    throw SceneError(o.sub("velocity"), o.get("velocity") ? "[0, 0, 0]" : "(missing)",
                     "the flow velocity the pump drives, not zero", "m/s");
  read_type_label(o, "grid");
  const std::string object_name = to_string(b.object);
  // A key of another object (a motion file's rate without a file, a radius on a Box) is ignored with a warning,
  // as ClaymoreUW ignores it.
  o.finish(
      [&](std::string_view key) {
        if (key == "output_frequency" || key == "output_freq")
          return std::string("no ") + std::string(key) + " without a motion file";
        return "no " + std::string(key) + " for object " + object_name;
      },
      true);
  return b;
}

GridSensorSpec parse_grid_sensor(const rj::Value& v, const std::string& path, const Context& ctx) {
  GridSensorSpec s;
  ObjectReader o(v, path, kGridSensorKeys, ctx, "grid-sensors[]");
  if (const rj::Value* a = o.get("attribute"))  // ClaymoreUW's default: Force
    s.attribute = read_enum(*a, o.sub("attribute"), kGridSensorAttributes);
  if (auto* x = o.get("operation")) s.operation = read_enum(*x, o.sub("operation"), kGridSensorOperations);
  if (auto* x = o.get("direction")) {
    const std::string dp = o.sub("direction");
    if (x->IsArray()) {
      Real3 d = read_real3(*x, dp, kAny, "-");
      const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (!(n > 0.0)) throw SceneError(dp, json_text(*x), "a non-zero vector of 3 numbers, or X, X+, X-, Y, Y+, Y-, Z, Z+, Z-");
      // A vector already of unit length is kept bit for bit (so a written scene reads back identically).
      if (std::fabs(n - 1.0) > 4.0 * std::numeric_limits<double>::epsilon())
        for (double& c : d) c /= n;
      s.direction = d;
      s.direction_sign = 0;
    } else {
      const char* choices = "one of X, X+, X-, Y, Y+, Y-, Z, Z+, Z-, or a vector of 3 numbers";
      const std::string t = read_string(*x, dp, choices);
      const std::string u = lower(t);
      const bool scalar = s.attribute == "Mass" || s.attribute == "Volume" || s.attribute == "JBar" ||
                          s.attribute == "MassWater" || s.attribute == "PorePressure";
      if (u == "n/a") {  // ClaymoreUW's "no direction", meaningful for a scalar attribute only
        if (!scalar)
          throw SceneError(dp, json_text(*x), std::string(choices) + " (attribute " + s.attribute + " is a vector)");
      } else {
        if (u.empty() || u.size() > 2 || (u[0] != 'x' && u[0] != 'y' && u[0] != 'z') ||
            (u.size() == 2 && u[1] != '+' && u[1] != '-'))
          throw SceneError(dp, json_text(*x), choices);
        s.direction = {0.0, 0.0, 0.0};
        s.direction[u[0] - 'x'] = 1.0;
        s.direction_sign = u.size() == 1 ? 0 : (u[1] == '+' ? 1 : -1);
      }
    }
  }
  if (auto f = o.get_any({"output_frequency", "output_freq"}))
    s.output_frequency = read_number(*f.value, f.path, kPositive, "Hz");
  std::tie(s.domain_start, s.domain_end) = read_region(o, false, &ctx);
  s.name = read_type_label(o, "grid");
  if (auto* x = o.get("toggle")) s.toggle = read_bool(*x, o.sub("toggle"));
  o.finish();
  return s;
}

GridFieldSpec parse_grid_field(const rj::Value& v, const std::string& path, const Context& ctx) {
  GridFieldSpec f;
  ObjectReader o(v, path, kGridFieldKeys, ctx, "grid-fields[]");
  if (const rj::Value* a = o.get("attributes")) {
    const std::string ap = o.sub("attributes");
    if (!a->IsArray() || a->Empty())
      throw SceneError(ap, json_text(*a), "a non-empty array of grid attributes (Mass, Velocity, Momentum, Force, "
                                          "BoundaryForce, Volume, JBar, MassWater, PorePressure)");
    for (rj::SizeType i = 0; i < a->Size(); ++i) {
      const std::string name = read_enum((*a)[i], index_path(ap, i), kGridFieldAttributes);
      if (std::find(f.attributes.begin(), f.attributes.end(), name) != f.attributes.end())
        throw SceneError(index_path(ap, i), json_text((*a)[i]), "an attribute not listed before (each once)");
      f.attributes.push_back(name);
    }
  }
  if (auto x = o.get_any({"output_frequency", "output_freq"}))
    f.output_frequency = read_number(*x.value, x.path, kPositive, "Hz");
  std::tie(f.domain_start, f.domain_end) = read_region(o, false, &ctx);
  if (auto* x = o.get("blocks")) f.blocks = read_bool(*x, o.sub("blocks"));
  if (auto* x = o.get("name")) f.name = read_string(*x, o.sub("name"));
  if (auto* x = o.get("toggle")) f.toggle = read_bool(*x, o.sub("toggle"));
  o.finish();
  return f;
}

ParticleSensorSpec parse_particle_sensor(const rj::Value& v, const std::string& path, const Context& ctx,
                                         bool& attribute_given) {
  ParticleSensorSpec s;
  ObjectReader o(v, path, kParticleSensorKeys, ctx, "particle-sensors[]");
  if (const rj::Value* a = o.get("attribute"))  // ClaymoreUW's default: Position_Y (its target_attribs default)
    s.attribute = read_attribute(*a, o.sub("attribute"), true);
  if (auto* x = o.get("operation")) {
    if (x->IsString() && fold(x->GetString()) == "subtract")  // ClaymoreUW accepts it and writes 0: no reduction
      throw SceneError(o.sub("operation"), json_text(*x),
                       "one of Sum, Max, Min, Count, Average, STDEV, Variance (ClaymoreUW accepts Subtract and writes "
                       "0 for it: it reduces nothing)");
    s.operation = read_enum(*x, o.sub("operation"), kParticleSensorOperations);
  }
  if (auto f = o.get_any({"output_frequency", "output_freq"}))
    s.output_frequency = read_number(*f.value, f.path, kPositive, "Hz");
  std::tie(s.domain_start, s.domain_end) = read_region(o, false, &ctx);
  s.name = read_type_label(o, "particles");
  if (auto* x = o.get("toggle")) s.toggle = read_bool(*x, o.sub("toggle"));
  if (auto* x = o.get("direction"))  // HydroUQ writes it; a particle sensor aggregates a scalar
    ctx.warn(o.sub("direction") + ": " + json_text(*x) +
             " is ignored (a particle sensor aggregates the scalar attribute; ClaymoreUW ignores it too)");
  attribute_given = o.has("attribute");
  o.finish();
  return s;
}

}  // namespace fbar::scene_json
