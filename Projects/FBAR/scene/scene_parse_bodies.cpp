// The scene reader's bodies[] (scene_parse.cpp gives the conventions): material, algorithm, geometry and the
// body's own keys.
#include "scene/scene_parse_detail.h"

namespace fbar::scene_json {

namespace {

// ---------------------------------------------------------------------------------------------------------------
// bodies[]
// ---------------------------------------------------------------------------------------------------------------

MaterialSpec parse_material(ObjectReader& body, ObjectReader* algorithm, const Context& ctx) {
  MaterialSpec m;
  const rj::Value* v = body.get("material");
  if (!v) body.missing("material", "an object with constitutive and its parameters");
  ObjectReader o(*v, body.sub("material"), kMaterialKeys, ctx, "bodies[].material");

  const auto law = read_either<Constitutive>(o, &body, "constitutive", [](const rj::Value& x, const std::string& p) {
    return read_enum(x, p, kLaws);
  });
  m.law = law.value_or(Constitutive::JFluid);  // ClaymoreUW's default
  const auto type = read_either<std::string>(o, &body, "type", [](const rj::Value& x, const std::string& p) {
    const std::string t = lower(read_string(x, p, "\"particles\" or \"mesh\""));
    if (t != "particles" && t != "mesh") throw SceneError(p, json_text(x), "\"particles\" or \"mesh\"");
    return t;
  });
  if (type) m.type = *type;

  auto number = [](const Range& r, const char* unit) {
    return [r, unit](const rj::Value& x, const std::string& p) { return read_number(x, p, r, unit); };
  };
  if (auto ppc = read_either<double>(o, algorithm, "ppc", number(kPositive, "particles/cell"))) m.ppc = *ppc;
  if (auto cfl = read_either<double>(o, algorithm, "CFL", number(Range{0.0, 1.0, true, false}, "-"))) m.cfl = *cfl;
  if (auto* x = o.get("rho")) m.rho = read_number(*x, o.sub("rho"), kPositive, "kg/m^3");
  if (auto* x = o.get("material_preset")) read_string(*x, o.sub("material_preset"), "a string (HydroUQ's label)");

  // The parameters the law reads (its kParameters: type and range checked); finish() reports any other one given.
  std::vector<std::string> used_names;
  for_each_material_parameter(m.law, [&](const MaterialParameter& p) {
    used_names.emplace_back(p.key);
    const rj::Value* x = o.get(p.key);
    if (!x) return;
    if (p.is_flag())
      m.*(p.flag) = read_bool(*x, o.sub(p.key));
    else
      m.*(p.number) = read_number(*x, o.sub(p.key), Range{p.range.lo, p.range.hi, p.range.lo_open, p.range.hi_open},
                                  p.unit);
  });
  if (auto* x = o.get("poissons_ratio")) {  // HydroUQ writes this spelling; ClaymoreUW reads only poisson_ratio
    const bool used = std::find(used_names.begin(), used_names.end(), "poisson_ratio") != used_names.end();
    if (!used) {
      ctx.warn(o.sub("poissons_ratio") + ": " + json_text(*x) + " is ignored (no poisson_ratio for constitutive " +
               to_string(m.law) + ")");
    } else {
      const double nu = read_number(*x, o.sub("poissons_ratio"), Range{-1.0, 0.5, true, true}, "-");
      if (o.has("poisson_ratio") && nu != m.poisson_ratio)
        throw SceneError(o.sub("poissons_ratio"), json_text(*x),
                         "the value of poisson_ratio (" + num_text(m.poisson_ratio) + "), or only one of the two");
      if (!o.has("poisson_ratio"))
        ctx.warn(o.sub("poissons_ratio") + ": read as poisson_ratio = " + num_text(nu) +
                 " (HydroUQ's spelling; ClaymoreUW does not read it and uses its default 0.2)");
      m.poisson_ratio = nu;
    }
  }
  // Rules across parameters (e.g. DruckerPrager's logJp0 needs the volume correction).
  visit_material(m.law, [&](auto law) {
    const ParameterProblem problem = material_check<decltype(law)>(m);
    if (problem.key == nullptr) return;
    std::string value;
    for_each_material_parameter(m.law, [&](const MaterialParameter& p) {
      if (std::string_view(p.key) == problem.key) value = p.is_flag() ? (m.*(p.flag) ? "true" : "false") : num_text(m.*(p.number));
    });
    throw SceneError(o.sub(problem.key), value, problem.expected);
  });

  const std::string law_name = to_string(m.law);
  // A parameter of another law is ignored with a warning: ClaymoreUW's scenes carry them (HydroUQ writes every
  // field of its material form) and ClaymoreUW ignores them silently.
  o.finish(
      [&](std::string_view key) {
        return "no " + std::string(key) + " for constitutive " + law_name + " (it reads " + join(used_names) + ")";
      },
      true);
  return m;
}

AlgorithmSpec parse_algorithm(ObjectReader* o) {
  AlgorithmSpec a;
  if (!o) return a;
  if (auto* x = o->get("type")) {
    a.type = lower(read_string(*x, o->sub("type"), "\"particles\" or \"mesh\""));
    if (a.type != "particles" && a.type != "mesh") throw SceneError(o->sub("type"), json_text(*x), "\"particles\" or \"mesh\"");
  }
  if (auto* x = o->get("use_ASFLIP")) a.use_asflip = read_bool(*x, o->sub("use_ASFLIP"));
  if (auto* x = o->get("ASFLIP_alpha")) a.asflip_alpha = read_number(*x, o->sub("ASFLIP_alpha"), kUnit, "-");
  if (auto* x = o->get("ASFLIP_beta_min")) a.asflip_beta_min = read_number(*x, o->sub("ASFLIP_beta_min"), kUnit, "-");
  if (auto* x = o->get("ASFLIP_beta_max")) a.asflip_beta_max = read_number(*x, o->sub("ASFLIP_beta_max"), kUnit, "-");
  if (a.asflip_beta_min > a.asflip_beta_max)
    throw SceneError(o->sub("ASFLIP_beta_max"), num_text(a.asflip_beta_max),
                     "a number >= ASFLIP_beta_min (" + num_text(a.asflip_beta_min) + ")", "-");
  if (auto* x = o->get("use_FBAR")) a.use_fbar = read_bool(*x, o->sub("use_FBAR"));
  if (auto* x = o->get("FBAR_psi")) a.fbar_psi = read_number(*x, o->sub("FBAR_psi"), kUnit, "-");
  if (auto* x = o->get("FBAR_fused_kernel")) a.fbar_fused_kernel = read_bool(*x, o->sub("FBAR_fused_kernel"));
  if (auto* x = o->get("FBAR_scheme")) a.fbar_scheme = read_enum(*x, o->sub("FBAR_scheme"), kFbarSchemes);
  if (auto* x = o->get("use_FEM")) a.use_fem = read_bool(*x, o->sub("use_FEM"));
  return a;
}


GeometrySpec parse_geometry(const rj::Value& v, const std::string& path, const Context& ctx) {
  GeometrySpec g;
  ObjectReader o(v, path, kGeometryKeys, ctx, "bodies[].geometry[]");
  const rj::Value* obj = o.get("object");
  if (!obj) o.missing("object", enum_choices(kGeometryObjects));
  g.object = read_enum(*obj, o.sub("object"), kGeometryObjects);
  if (auto* x = o.get("operation")) g.operation = read_enum(*x, o.sub("operation"), kGeometryOperations);

  const bool is_file = g.object == GeometryObject::File;
  const bool is_round = g.object == GeometryObject::Sphere || g.object == GeometryObject::Cylinder;

  // Keys of every object.
  if (auto* x = o.get("offset")) g.offset = read_real3(*x, o.sub("offset"), kAny, "m");
  if (auto* x = o.get("rotate")) g.rotate = read_real3(*x, o.sub("rotate"), kAny, "deg");
  if (auto* x = o.get("fulcrum")) g.fulcrum = read_real3(*x, o.sub("fulcrum"), kAny, "m");
  if (auto* x = o.get("array")) g.array = read_int3(*x, o.sub("array"), at_least(1));
  if (auto* x = o.get("spacing")) g.spacing = read_real3(*x, o.sub("spacing"), kAny, "m");
  if (auto* x = o.get("use_froude_scaling")) g.use_froude_scaling = read_bool(*x, o.sub("use_froude_scaling"));
  // HydroUQ's switches (ClaymoreUW reads neither and always applies array and rotate): false drops them.
  if (auto* x = o.get("apply_array"); x && !read_bool(*x, o.sub("apply_array")) && g.array != Int3{1, 1, 1}) {
    ctx.warn(o.sub("array") + ": not applied because apply_array is false (ClaymoreUW would apply it)");
    g.array = Int3{1, 1, 1};
  }
  if (auto* x = o.get("apply_rotation"); x && !read_bool(*x, o.sub("apply_rotation")) && g.rotate != Real3{0, 0, 0}) {
    ctx.warn(o.sub("rotate") + ": not applied because apply_rotation is false (ClaymoreUW would apply it)");
    g.rotate = Real3{0, 0, 0};
  }
  if (auto* x = o.get("track_particle_id"))
    g.track_particle_id = read_integer_array(*x, o.sub("track_particle_id"), kNonNegative);

  // Shape keys.
  Real3 sphere_span{};  // checked against the radius only: a sphere is offset + radius
  const bool is_bed = g.object == GeometryObject::Bathymetry || g.object == GeometryObject::OsuLwf ||
                      g.object == GeometryObject::OsuTwb;
  if (g.object == GeometryObject::Box || is_bed) {
    if (auto* x = o.get("span")) g.span = read_real3(*x, o.sub("span"), kPositive, "m");
  }
  if (is_bed) {
    // Read for Bathymetry too (ClaymoreUW's scenes set it there), where the points are always used.
    if (auto* x = o.get("use_custom_bathymetry")) g.use_custom_bathymetry = read_bool(*x, o.sub("use_custom_bathymetry"));
    if (auto* x = o.get("bathymetry")) g.bathymetry = read_bed_points(*x, o.sub("bathymetry"));
    if (g.object == GeometryObject::Bathymetry && g.bathymetry.size() < 2)
      throw SceneError(o.sub("bathymetry"), g.bathymetry.empty() ? "(missing)" : "1 point",
                       "at least 2 [x, y] points: a Bathymetry body is the water above the bed through them", "m");
    if (g.object != GeometryObject::Bathymetry && g.use_custom_bathymetry && g.bathymetry.size() < 2)
      throw SceneError(o.sub("bathymetry"), g.bathymetry.empty() ? "(missing)" : "1 point",
                       "at least 2 [x, y] points when use_custom_bathymetry is true", "m");
    if (g.object != GeometryObject::Bathymetry && !g.use_custom_bathymetry && !g.bathymetry.empty())
      throw SceneError(o.sub("use_custom_bathymetry"), "false",
                       "true when bathymetry points are given (they replace the facility's bed only then)");
  }
  if (g.object == GeometryObject::Sphere) {
    // ClaymoreUW clips a sphere to the box [offset, offset + span]; fbar samples the whole sphere. Both agree when
    // span >= 2 radius; a smaller span (a clipped sphere) is refused below rather than silently sampled whole.
    if (auto* x = o.get("span")) sphere_span = read_real3(*x, o.sub("span"), kAny, "m");
  }
  if (g.object == GeometryObject::Cylinder) {
    const rj::Value* axis = o.get("axis");
    const rj::Value* long_axis = o.get("long_axis");
    if (axis) g.axis = read_enum(*axis, o.sub("axis"), kAxes);
    if (long_axis) {
      // ClaymoreUW reads only `axis` (read_scene_input.h L2307); HydroUQ scenes may carry long_axis beside it.
      const int la = read_enum(*long_axis, o.sub("long_axis"), kAxes);
      if (!axis) {
        g.axis = la;
      } else if (la != g.axis) {
        throw SceneError(o.sub("long_axis"), json_text(*long_axis),
                         std::string("the same axis as axis (") + json_text(*axis) +
                             "), or only one of them: ClaymoreUW would use axis and ignore long_axis");
      } else {
        ctx.warn(o.sub("long_axis") + ": " + json_text(*long_axis) + " is redundant: ClaymoreUW ignores long_axis and "
                 "reads axis; fbar checks that the two agree and uses axis (" + json_text(*axis) + ")");
      }
    }
    if (auto* x = o.get("span")) {
      // Only span[axis] (the length) is used; the cross-section comes from radius.
      g.span = read_real3(*x, o.sub("span"), kNonNegative, "m");
      if (!(g.span[g.axis] > 0.0))
        throw SceneError(index_path(o.sub("span"), g.axis), num_text(g.span[g.axis]),
                         std::string("a number > 0 (the cylinder length along axis ") + axis_name(g.axis) + ")", "m");
    }
    if (auto* x = o.get("length")) {  // the length along the axis; ClaymoreUW takes it from span
      const double length = read_number(*x, o.sub("length"), kPositive, "m");
      if (!o.has("span"))
        g.span[g.axis] = length;
      else if (length != g.span[g.axis])
        ctx.warn(o.sub("length") + ": " + num_text(length) + " m is not used: span[" + std::to_string(g.axis) +
                 "] = " + num_text(g.span[g.axis]) + " m is the cylinder's length (as in ClaymoreUW)");
    }
  }
  if (is_round) {
    const rj::Value* x = o.get("radius");
    if (!x) o.missing("radius", std::string("a number > 0 for object ") + to_string(g.object), "m");
    g.radius = read_number(*x, o.sub("radius"), kPositive, "m");
    if (o.get("span")) {
      // The cross-section axes of a cylinder (all three for a sphere) must hold the whole circle: ClaymoreUW would
      // clip the shape to [offset, offset + span], which fbar expresses as an Intersection with a Box instead.
      for (int d = 0; d < 3; ++d) {
        if (g.object == GeometryObject::Cylinder && d == g.axis) continue;
        const double span_d = g.object == GeometryObject::Sphere ? sphere_span[d] : g.span[d];
        // A cylinder's cross-section span of 0 means "not given" (fbar writes it so); only a clip is refused.
        if (g.object == GeometryObject::Cylinder && span_d == 0.0) continue;
        if (span_d < 2.0 * g.radius * (1.0 - 1e-12))
          throw SceneError(index_path(o.sub("span"), d), num_text(span_d),
                           "a number >= 2 * radius = " + num_text(2.0 * g.radius) +
                               " (ClaymoreUW clips the shape to [offset, offset + span]; in fbar add an Intersection "
                               "with a Box for a clipped " + to_string(g.object) + ")",
                           "m");
      }
    }
  }
  if (is_file) {
    const rj::Value* x = o.get("file");
    if (!x) o.missing("file", "a file path for object File");
    g.file = ctx.resolve_file(*x, o.sub("file"));
    if (auto* p = o.get("padding")) g.padding = read_int(*p, o.sub("padding"), at_least(1), "cells");
    if (auto f = o.get_any({"scaling_factor", "scaling"})) g.scaling_factor = read_number(*f.value, f.path, kPositive, "-");
    if (auto* h = o.get("has_attributes")) g.has_attributes = read_bool(*h, o.sub("has_attributes"));
    if (auto* a = o.get("input_attribs")) g.input_attribs = read_attribute_list(*a, o.sub("input_attribs"));
    if (g.has_attributes && g.input_attribs.empty())
      throw SceneError(o.sub("input_attribs"), "(missing or empty)",
                       "the attribute names to read from the file when has_attributes is true");
    if (g.has_attributes && geometry_file_kind(g.file) == GeometryFileKind::Sdf)
      throw SceneError(o.sub("has_attributes"), "true", "false for an .sdf file (a solid holds no particle values; "
                                                        "has_attributes reads .csv, .bgeo and .h5 point files)");
    if (g.has_attributes) check_seed_attributes(g.input_attribs, o.sub("input_attribs"));
    if (!g.has_attributes && !g.input_attribs.empty())  // ClaymoreUW reads them and then zeroes them
      ctx.warn(o.sub("input_attribs") + ": ignored (has_attributes is false: only positions are read)");
    if (g.padding != 1 && geometry_file_kind(g.file) != GeometryFileKind::Sdf)
      throw SceneError(o.sub("padding"), std::to_string(g.padding), "no padding for a point file (it places an .sdf)",
                       "cells");
  }
  const std::string object_name = to_string(g.object);
  // A key of another object (a radius on a Box, a region on a Bathymetry body) is ignored with a warning, as
  // ClaymoreUW ignores it.
  o.finish([&](std::string_view key) { return "no " + std::string(key) + " for object " + object_name; }, true);
  return g;
}

}  // namespace

BodyRead parse_body(const rj::Value& v, const std::string& path, const Context& ctx) {
  BodyRead out;
  BodySpec& b = out.spec;
  ObjectReader o(v, path, kBodyKeys, ctx, "bodies[]");

  std::optional<ObjectReader> partition, output, algorithm;
  if (auto* x = o.get("partition")) partition.emplace(*x, o.sub("partition"), kPartitionKeys, ctx, "bodies[].partition");
  if (auto* x = o.get("output")) output.emplace(*x, o.sub("output"), kOutputKeys, ctx, "bodies[].output");
  if (auto* x = o.get("algorithm")) algorithm.emplace(*x, o.sub("algorithm"), kAlgorithmKeys, ctx, "bodies[].algorithm");
  ObjectReader* part = partition ? &*partition : nullptr;
  ObjectReader* outp = output ? &*output : nullptr;
  ObjectReader* algo = algorithm ? &*algorithm : nullptr;

  auto id_reader = [](const rj::Value& x, const std::string& p) { return read_int(x, p, kNonNegative); };
  auto gpu_reader = [](const rj::Value& x, const std::string& p) {
    if (x.IsString() && std::string_view(x.GetString()) == "all") return kAllGpus;
    if (x.IsString())
      throw SceneError(p, json_text(x),
                       "an integer >= 0 (the GPU that holds the whole body) or \"all\" (the body spread over every "
                       "GPU by space)");
    return read_int(x, p, kNonNegative);
  };
  if (auto gpu = read_either<int>(o, part, "gpu", gpu_reader)) b.gpu = *gpu;
  if (auto model = read_either<int>(o, part, "model", id_reader)) {
    b.model = *model;
    out.model_given = true;
  }
  out.model_path = (part && part->has("model")) ? part->sub("model") : o.sub("model");
  auto point = [](const rj::Value& x, const std::string& p) { return read_real3(x, p, kAny, "m", true); };
  if (auto ps = read_either<Real3>(o, part, "partition_start", point)) b.partition_start = *ps;
  if (auto pe = read_either<Real3>(o, part, "partition_end", point)) b.partition_end = *pe;
  for (int d = 0; d < 3; ++d)
    if (!(b.partition_end[d] > b.partition_start[d]))
      throw SceneError(index_path(part && part->has("partition_end") ? part->sub("partition_end") : o.sub("partition_end"), d),
                       num_text(b.partition_end[d]),
                       "a number > partition_start[" + std::to_string(d) + "] (" + num_text(b.partition_start[d]) + ")",
                       "m");
  if (auto* x = o.get("velocity")) b.velocity = read_real3(*x, o.sub("velocity"), kAny, "m/s");

  auto ids = [](const rj::Value& x, const std::string& p) { return read_integer_array(x, p, kNonNegative); };
  if (auto t = read_either<std::vector<long long>>(o, outp, "track_particle_id", ids)) b.track_particle_id = *t;
  auto attribs = [](const rj::Value& x, const std::string& p) { return read_attribute_list(x, p); };
  if (auto a = read_either<std::vector<std::string>>(o, outp, "output_attribs", attribs)) b.output_attribs = *a;
  if (outp && outp->get("attribs")) {  // ClaymoreUW's newer spelling, output: {attribs: [...]}
    const std::vector<std::string> a = attribs(*outp->get("attribs"), outp->sub("attribs"));
    if ((o.get("output_attribs") || outp->get("output_attribs")) && a != b.output_attribs)
      ctx.warn(o.sub("output_attribs") + ": ignored: " + outp->sub("attribs") +
               " (ClaymoreUW's newer key) is given too and differs; the frames hold output.attribs");
    b.output_attribs = a;
  }
  if (outp) {
    if (auto* x = outp->get("exterior_only")) b.output_exterior_only = read_bool(*x, outp->sub("exterior_only"));
    if (auto* x = outp->get("exterior_threshold"))
      b.exterior_threshold = read_number(*x, outp->sub("exterior_threshold"), kNonNegative, "particles per block");
  }
  if (auto a = read_either<std::vector<std::string>>(o, outp, "track_attribs", attribs)) b.track_attribs = *a;
  auto targets = [](const rj::Value& x, const std::string& p) {  // what the particle sensors aggregate
    require_array(x, p, "an array of one particle attribute name");
    if (x.Size() > 1)
      throw SceneError(p, std::to_string(x.Size()) + " attributes",
                       "one attribute (the particle sensors aggregate one; ClaymoreUW uses only the first too)");
    std::vector<std::string> names;
    for (rj::SizeType i = 0; i < x.Size(); ++i) names.push_back(read_attribute(x[i], index_path(p, i), true));
    return names;
  };
  if (auto a = read_either<std::vector<std::string>>(o, outp, "target_attribs", targets)) b.target_attribs = *a;
  // ClaymoreUW's newer spelling: "trackers": {"ids": [...], "attribs": [...]}.
  if (auto* x = o.get("trackers")) {
    ObjectReader tr(*x, o.sub("trackers"), kTrackerKeys, ctx, "bodies[].trackers");
    // The newer keys win over track_particle_id / track_attribs (a warning when both are given and differ).
    if (auto* ids_value = tr.get("ids")) {
      const std::vector<long long> t = ids(*ids_value, tr.sub("ids"));
      if (!b.track_particle_id.empty() && t != b.track_particle_id)
        ctx.warn(o.sub("track_particle_id") + ": ignored: " + tr.sub("ids") +
                 " (ClaymoreUW's newer key) is given too and differs; fbar tracks trackers.ids");
      b.track_particle_id = t;
    }
    if (auto* a = tr.get("attribs")) {
      const std::vector<std::string> t = attribs(*a, tr.sub("attribs"));
      if (!b.track_attribs.empty() && t != b.track_attribs)
        ctx.warn(o.sub("track_attribs") + ": ignored: " + tr.sub("attribs") +
                 " (ClaymoreUW's newer key) is given too and differs; fbar records trackers.attribs");
      b.track_attribs = t;
    }
    tr.finish();
  }

  b.material = parse_material(o, algo, ctx);
  if (auto* x = o.get("initial_state")) {
    b.initial_state = read_enum(*x, o.sub("initial_state"), kInitialStates);
    if (b.initial_state == InitialState::Hydrostatic && !material_has_hydrostatic_state(b.material.law))
      throw SceneError(o.sub("initial_state"), json_text(*x),
                       std::string("\"rest\" for constitutive ") + to_string(b.material.law) +
                           " (a hydrostatic initial state sets a fluid's pressure: JFluid)");
  }
  const rj::Value* material = o.get("material");
  out.cfl_given = (material->IsObject() && material->HasMember("CFL")) || (algo && algo->has("CFL"));
  b.algorithm = parse_algorithm(algo);

  const rj::Value* geo = o.get("geometry");
  if (!geo) o.missing("geometry", "a non-empty array of geometry objects (Box, Sphere, Cylinder, File)");
  require_array(*geo, o.sub("geometry"), "a non-empty array of geometry objects (Box, Sphere, Cylinder, File)");
  if (geo->Size() == 0)
    throw SceneError(o.sub("geometry"), "[]", "a non-empty array of geometry objects (Box, Sphere, Cylinder, File)");
  for (rj::SizeType i = 0; i < geo->Size(); ++i)
    b.geometry.push_back(parse_geometry((*geo)[i], index_path(o.sub("geometry"), i), ctx));
  if (b.initial_state == InitialState::Hydrostatic)
    for (std::size_t i = 0; i < b.geometry.size(); ++i)
      if (b.geometry[i].has_attributes)
        throw SceneError(o.sub("initial_state"), "\"hydrostatic\"",
                         "\"rest\": geometry[" + std::to_string(i) +
                             "] has_attributes seeds the body's states from its file (a body starts either from a "
                             "file's states or hydrostatic)");
  // ClaymoreUW appends a geometry entry's track_particle_id to the body's, shifted by the particles of each array
  // copy before it; without copies the IDs are the body's own (with copies: resolve_copy_track_ids, after scaling).
  for (GeometrySpec& g : b.geometry) {
    if (g.track_particle_id.empty() || g.array != Int3{1, 1, 1}) continue;
    for (long long id : g.track_particle_id)
      if (std::find(b.track_particle_id.begin(), b.track_particle_id.end(), id) == b.track_particle_id.end())
        b.track_particle_id.push_back(id);
    g.track_particle_id.clear();
  }

  // Labels that HydroUQ / ClaymoreUW scenes carry; they have no effect on the simulation.
  if (auto* x = o.get("name")) read_string(*x, o.sub("name"));
  if (auto* x = o.get("color")) read_string(*x, o.sub("color"));

  if (algo) algo->finish();
  if (part) part->finish();
  if (outp) outp->finish();
  o.finish();
  return out;
}

}  // namespace fbar::scene_json
