// Reads a scene JSON into the resolved Scene: syntax, types, ranges, aliases, unknown keys, defaults, cross-checks.
//
// Conventions of this file:
//  * Every value is read through one typed reader (read_number, read_real3, read_enum, ...) that throws SceneError
//    with the JSON path, the value as written, the expectation and the unit ("-" for dimensionless numbers).
//  * Every JSON object is wrapped in an ObjectReader that records which keys were consumed; what is left at
//    finish() is an unknown key (closest known key suggested) or a key the chosen law / object does not use.
//    Both are errors, or warnings with ParseOptions::allow_unknown_keys (the value is then ignored).
//  * Keys ClaymoreUW accepts in two places (bodies[].partition{} / output{} vs flat, ppc and CFL in material or
//    algorithm, constitutive on the body or in material) may be given in either place; given in both, they must
//    agree.
//  * Values are validated as the user wrote them (unscaled); Froude scaling is applied last.
//  * The parts live in scene_parse_bodies.cpp (bodies[]) and scene_parse_objects.cpp (boundaries and sensors); what
//    they share, in scene_parse_detail.h. This file reads simulation{} and the document, and holds the public API.
#include "scene/scene_parse.h"

#include "scene/scene_parse_detail.h"

#include <algorithm>
#include <memory>
#include <set>
#include <sstream>

#include "geometry/tet_mesh.h"

namespace fbar {

using namespace scene_json;

namespace {

// ---------------------------------------------------------------------------------------------------------------
// simulation
// ---------------------------------------------------------------------------------------------------------------

struct SimulationRead {
  SimulationSpec spec;
  bool default_dt_given = false;
  std::optional<double> cfl;  ///< simulation.cfl (HydroUQ): the CFL number of every body that gives none
};

/// The simulation keys HydroUQ writes and ClaymoreUW's loader does not read (user guide 2.1 and difference 30).
void read_hydrouq_simulation(ObjectReader& o, SimulationRead& out, const Context& ctx) {
  SimulationSpec& s = out.spec;
  if (auto* x = o.get("initial_time")) {  // HydroUQ writes it beside `time`, the same value
    const double t = read_number(*x, o.sub("initial_time"), kAny, "s");
    if (o.has("time") && t != s.time)
      throw SceneError(o.sub("initial_time"), json_text(*x),
                       "the value of simulation.time (" + num_text(s.time) + " s): both name the start time");
    s.time = t;
  }
  if (auto* x = o.get("cfl")) out.cfl = read_number(*x, o.sub("cfl"), Range{0.0, 1.0, true, false}, "-");
  if (auto* x = o.get("time_integration")) {
    const std::string t = read_string(*x, o.sub("time_integration"), "\"Explicit\"");
    if (fold(t) != "explicit")
      throw SceneError(o.sub("time_integration"), json_text(*x),
                       "\"Explicit\" (fbar, like ClaymoreUW, integrates explicitly in time)");
  }
  if (auto* x = o.get("mirror_domain")) {
    const std::string p = o.sub("mirror_domain");
    const std::string expected = "false, or [false, false, false]: mirrored domains are not implemented (ClaymoreUW "
                                 "reads no mirror_domain either)";
    bool any = false;
    if (x->IsBool()) {
      any = x->GetBool();
    } else if (x->IsArray() && x->Size() == 3) {
      for (rj::SizeType i = 0; i < 3; ++i) {
        if (!(*x)[i].IsBool()) throw SceneError(index_path(p, i), json_text((*x)[i]), "true or false");
        any = any || (*x)[i].GetBool();
      }
    } else {
      throw SceneError(p, json_text(*x), expected);
    }
    if (any) throw SceneError(p, json_text(*x), expected);
  }
  if (auto* x = o.get("use_froude_scaling")) {
    if (!read_bool(*x, o.sub("use_froude_scaling")) && s.froude_scaling != 1.0 && !s.froude_scaling_applied) {
      ctx.warn("simulation.froude_scaling: " + num_text(s.froude_scaling) +
               " is not applied because simulation.use_froude_scaling is false (ClaymoreUW does not read "
               "use_froude_scaling and would apply it)");
      s.froude_scaling = 1.0;
    }
  }
  if (auto* x = o.get("froude_time_ratio")) {
    const double r = read_number(*x, o.sub("froude_time_ratio"), kPositive, "s/s");
    const double expected = std::sqrt(s.froude_scaling);
    if (!s.froude_scaling_applied && std::abs(r - expected) > 1e-3 * expected)
      ctx.warn("simulation.froude_time_ratio: " + num_text(r) + " is not used: Froude similitude fixes the time ratio "
               "at sqrt(froude_scaling) = " + num_text(expected) + " s/s, which fbar applies");
  }
  if (auto* x = o.get("use_cauchy_scaling"))
    s.cauchy_scaling = read_bool(*x, o.sub("use_cauchy_scaling")) ? CauchyScaling::On : CauchyScaling::Off;
  if (auto* x = o.get("cauchy_bulk_ratio")) {
    s.cauchy_bulk_ratio = read_number(*x, o.sub("cauchy_bulk_ratio"), kPositive, "Pa/Pa");
    if (s.cauchy_scaling != CauchyScaling::On && s.cauchy_bulk_ratio != 1.0)
      ctx.warn("simulation.cauchy_bulk_ratio: " + num_text(s.cauchy_bulk_ratio) +
               " is not applied because simulation.use_cauchy_scaling is not true");
    if (s.cauchy_scaling != CauchyScaling::On) s.cauchy_bulk_ratio = 1.0;
  }
  if (auto* x = o.get("duration")) {  // ClaymoreUW runs frames / fps; HydroUQ writes the duration it meant
    const double d = read_number(*x, o.sub("duration"), kPositive, "s");
    if (!o.has("frames")) {
      s.frames = std::max(1, static_cast<int>(std::ceil(d * s.fps - 1e-9)));
    } else if (std::abs(s.frames / s.fps - d) > 0.5 / s.fps) {
      ctx.warn("simulation.duration: " + num_text(d) + " s is not used: frames / fps = " + std::to_string(s.frames) +
               " / " + num_text(s.fps) + " = " + num_text(s.frames / s.fps) + " s sets the run's length (as in "
               "ClaymoreUW); leave frames out to run the duration");
    }
  }
}

SimulationRead parse_simulation(const rj::Value* v, const Context& ctx) {
  SimulationRead out;
  SimulationSpec& s = out.spec;
  if (!v) return out;
  ObjectReader o(*v, "simulation", kSimulationKeys, ctx, "simulation");
  if (auto* x = o.get("domain")) s.domain = read_real3(*x, o.sub("domain"), kPositive, "m");
  if (auto* x = o.get("default_dx")) s.dx = read_number(*x, o.sub("default_dx"), kPositive, "m");
  if (auto* x = o.get("default_dt")) {
    s.default_dt = read_number(*x, o.sub("default_dt"), kPositive, "s");
    out.default_dt_given = true;
  }
  if (auto* x = o.get("gravity")) s.gravity = read_real3(*x, o.sub("gravity"), kAny, "m/s^2");
  if (auto* x = o.get("time")) s.time = read_number(*x, o.sub("time"), kAny, "s");
  if (auto* x = o.get("fps")) s.fps = read_number(*x, o.sub("fps"), kPositive, "1/s");
  if (auto* x = o.get("frames")) s.frames = read_int(*x, o.sub("frames"), at_least(1), "-");
  if (auto* x = o.get("save_path")) {
    s.save_path = read_string(*x, o.sub("save_path"), "a directory path (a string)");
    if (s.save_path.empty()) throw SceneError(o.sub("save_path"), json_text(*x), "a non-empty directory path");
  }
  if (auto* x = o.get("save_suffix")) {
    const std::string suffix = read_string(*x, o.sub("save_suffix"), "one of .bgeo, .geo, .csv, .h5");
    std::vector<std::string> choices(kSaveSuffixes.begin(), kSaveSuffixes.end());
    if (std::find(choices.begin(), choices.end(), lower(suffix)) == choices.end())
      throw SceneError(o.sub("save_suffix"), json_text(*x), "one of " + join(choices));
    s.save_suffix = lower(suffix);
  }
  if (auto* x = o.get("particles_output_exterior_only"))
    s.particles_output_exterior_only = read_bool(*x, o.sub("particles_output_exterior_only"));
  if (auto* x = o.get("froude_scaling")) s.froude_scaling = read_number(*x, o.sub("froude_scaling"), kPositive, "-");
  if (auto* x = o.get("froude_scaling_applied"))
    s.froude_scaling_applied = read_bool(*x, o.sub("froude_scaling_applied"));
  if (auto* x = o.get("info_rate")) s.info_rate = read_int(*x, o.sub("info_rate"), kNonNegative, "steps");
  if (auto* x = o.get("checkpoint_every"))
    s.checkpoint_every = read_int(*x, o.sub("checkpoint_every"), kNonNegative, "frames");
  if (auto* x = o.get("precision")) s.precision = read_enum(*x, o.sub("precision"), kPrecisions);
  if (auto* x = o.get("on_failure")) s.on_failure = read_enum(*x, o.sub("on_failure"), kOnFailure);
  if (auto* x = o.get("seed")) {
    if (!x->IsUint64()) throw SceneError(o.sub("seed"), json_text(*x), "an integer in [0, 2^64)");
    s.seed = x->GetUint64();
  }
  if (auto* x = o.get("gpuid")) {
    read_int(*x, o.sub("gpuid"), kNonNegative);
    ctx.warn("simulation.gpuid: ignored (ClaymoreUW ignores it too; GPUs are chosen per body with bodies[].gpu)");
  }
  read_hydrouq_simulation(o, out, ctx);
  o.finish();
  return out;
}

// ---------------------------------------------------------------------------------------------------------------
// The document
// ---------------------------------------------------------------------------------------------------------------

// ClaymoreUW keeps one output frequency per kind of sensor, the last one read (mgsp_benchmark.cuh host_gt_freq,
// host_pt_freq), and writes every sensor of that kind at it; fbar writes each sensor at its own. Said once per kind.
template <typename Sensors>
void warn_claymoreuw_sensor_frequencies(const Sensors& sensors, const char* kind, const Context& ctx) {
  if (sensors.size() < 2) return;
  const double last = sensors.back().output_frequency;
  std::size_t differ = 0;
  for (const auto& s : sensors) differ += s.output_frequency != last ? 1 : 0;
  if (differ == 0) return;
  ctx.warn(std::string(kind) + "[].output_frequency: " + std::to_string(differ) + " of the " +
           std::to_string(sensors.size()) + " sensors ask for another rate than the last one's (" + num_text(last) +
           " Hz, " + kind + "[" + std::to_string(sensors.size() - 1) + "]). ClaymoreUW writes every " +
           (std::string(kind) == "grid-sensors" ? "grid" : "particle") + " sensor at the last one's rate; fbar " +
           "writes each at its own");
}


/// Assigns omitted model ids in order per GPU and checks that each GPU's ids are 0..n-1 without duplicates. A body
/// with "gpu": "all" writes model[m]_dev[d] on every GPU d, so its model id counts on every GPU the scene names.
void assign_models(std::vector<BodyRead>& bodies, const std::string& bodies_key) {
  std::set<int> gpus{0};  // every GPU the scene names (an "all" body alone: GPU 0)
  for (const BodyRead& b : bodies)
    if (b.spec.gpu != kAllGpus) gpus.insert(b.spec.gpu);
  auto on = [&](const BodyRead& b) { return b.spec.gpu == kAllGpus ? gpus : std::set<int>{b.spec.gpu}; };
  auto gpu_text = [](int gpu) { return gpu == kAllGpus ? std::string("\"all\"") : std::to_string(gpu); };
  std::map<int, std::set<int>> taken;  // gpu -> explicit model ids
  std::map<std::pair<int, int>, std::size_t> owner;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const BodyRead& b = bodies[i];
    if (!b.model_given) continue;
    for (int g : on(b)) {
      const auto key = std::make_pair(g, b.spec.model);
      const auto it = owner.find(key);
      if (it != owner.end())
        throw SceneError(b.model_path, std::to_string(b.spec.model),
                         "a model id not used by another body on gpu " + std::to_string(g) + " (" +
                             index_path(bodies_key, it->second) + " has model " + std::to_string(b.spec.model) +
                             (b.spec.gpu == kAllGpus || bodies[it->second].spec.gpu == kAllGpus
                                  ? "; a body on \"all\" GPUs takes its model id on every GPU"
                                  : "") +
                             ")");
      owner[key] = i;
      taken[g].insert(b.spec.model);
    }
  }
  for (BodyRead& b : bodies) {
    if (b.model_given) continue;
    auto free_everywhere = [&](int m) {
      for (int g : on(b))
        if (taken[g].count(m)) return false;
      return true;
    };
    int m = 0;
    while (!free_everywhere(m)) ++m;
    b.spec.model = m;
    for (int g : on(b)) taken[g].insert(m);
  }
  // Engines index a GPU's models 0..n-1 (ClaymoreUW requires it too).
  for (const BodyRead& b : bodies)
    for (int g : on(b)) {
      const int n = static_cast<int>(taken[g].size());
      if (b.spec.model >= n)
        throw SceneError(b.model_path, std::to_string(b.spec.model),
                         "model ids on gpu " + std::to_string(g) + " to be 0.." + std::to_string(n - 1) +
                             " without gaps (omit model to number bodies in order; the body's gpu is " +
                             gpu_text(b.spec.gpu) + ")");
    }
}

/// One entry of "meshes" (ClaymoreUW's keys with their meanings; MeshEntrySpec): the mesh of file_vertices +
/// file_elements (ClaymoreUW's CSV pair) or of a Gmsh .msh named by file (fbar's; ClaymoreUW reads and ignores file),
/// placed at offset [m], checked (geometry/tet_mesh.h) against the domain; the material and scheme keys in range.
/// `vertex_scale`: the file's coordinates are multiplied by it before the offset is added (a written, already
/// Froude-scaled scene: its offset is scaled, its mesh files never are).
MeshEntrySpec read_mesh_entry(const rj::Value& v, const std::string& path, const Context& ctx, const Real3& domain,
                              double vertex_scale) {
  MeshEntrySpec spec;
  ObjectReader o(v, path, kMeshKeys, ctx, "meshes[]");
  const rj::Value* vertices = o.get("file_vertices");
  const rj::Value* elements = o.get("file_elements");
  const rj::Value* file = o.get("file");
  if (auto* x = o.get("gpu")) spec.gpu = read_int(*x, o.sub("gpu"), kNonNegative);
  if (auto* x = o.get("constitutive")) {
    const std::string law = read_string(*x, o.sub("constitutive"));
    if (law == "Meshed" || law == "FixedCorotated") spec.law = Constitutive::FixedCorotated;
    else if (law == "NeoHookean") spec.law = Constitutive::NeoHookean;
    else
      throw SceneError(o.sub("constitutive"), json_text(*x),
                       "\"Meshed\" (ClaymoreUW's FixedCorotated tetrahedra), \"FixedCorotated\" or \"NeoHookean\"");
  }
  if (auto* x = o.get("rho")) spec.rho = read_number(*x, o.sub("rho"), kPositive, "kg/m^3");
  if (auto* x = o.get("youngs_modulus")) spec.youngs_modulus = read_number(*x, o.sub("youngs_modulus"), kPositive, "Pa");
  if (auto* x = o.get("poisson_ratio"))
    spec.poisson_ratio = read_number(*x, o.sub("poisson_ratio"), Range{-1.0, 0.5, true, true}, "-");
  if (auto* x = o.get("ppc")) spec.ppc = read_number(*x, o.sub("ppc"), kPositive, "particles per cell");
  if (auto* x = o.get("velocity")) spec.velocity = read_real3(*x, o.sub("velocity"), kAny, "m/s");
  if (auto* x = o.get("use_FEM")) spec.use_fem = read_bool(*x, o.sub("use_FEM"));
  if (auto* x = o.get("use_ASFLIP")) spec.use_asflip = read_bool(*x, o.sub("use_ASFLIP"));
  if (auto* x = o.get("alpha")) spec.alpha = read_number(*x, o.sub("alpha"), kUnit, "-");
  if (auto* x = o.get("beta_min")) spec.beta_min = read_number(*x, o.sub("beta_min"), kUnit, "-");
  if (auto* x = o.get("beta_max")) spec.beta_max = read_number(*x, o.sub("beta_max"), kUnit, "-");
  if (spec.beta_max < spec.beta_min)
    throw SceneError(o.sub("beta_max"), num_text(spec.beta_max), "a number >= beta_min (" + num_text(spec.beta_min) + ")",
                     "-");
  if (auto* x = o.get("use_FBAR")) spec.fbar_elements = read_bool(*x, o.sub("use_FBAR"));
  if (auto* x = o.get("FBAR_ratio")) spec.fbar_ratio = read_number(*x, o.sub("FBAR_ratio"), kUnit, "-");
  if (auto* x = o.get("FBAR_fused_kernel")) spec.fbar_fused_kernel = read_bool(*x, o.sub("FBAR_fused_kernel"));
  if (auto* x = o.get("output_attribs")) spec.output_attribs = read_attribute_list(*x, o.sub("output_attribs"));
  if (auto* x = o.get("track_attribs")) spec.track_attribs = read_attribute_list(*x, o.sub("track_attribs"));
  if (auto* x = o.get("track_particle_id"))
    spec.track_particle_id = read_integer_array(*x, o.sub("track_particle_id"), kNonNegative);
  TetMesh mesh;
  std::string source_key;
  std::string source;
  try {
    if (vertices || elements) {
      if (!vertices) throw SceneError(path + ".file_vertices", "(missing)", "the vertex file of file_elements' mesh");
      if (!elements) throw SceneError(path + ".file_elements", "(missing)", "the element file of file_vertices' mesh");
      spec.file_vertices = ctx.resolve_file(*vertices, path + ".file_vertices");
      spec.file_elements = ctx.resolve_file(*elements, path + ".file_elements");
      source_key = path + ".file_elements";
      source = json_text(*elements);
      mesh = read_tet_mesh_csv(spec.file_vertices, spec.file_elements);
    } else if (file && file->IsString() && fs::path(file->GetString()).extension() == ".msh") {
      source_key = path + ".file";
      source = json_text(*file);
      spec.file = ctx.resolve_file(*file, path + ".file");
      mesh = read_gmsh_msh41(spec.file);
    } else {
      throw SceneError(path + ".file_vertices", "(missing)",
                       "file_vertices and file_elements (ClaymoreUW's CSV pair), or a Gmsh .msh file in file");
    }
  } catch (const SceneError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw SceneError(source_key, source, std::string("a readable tetrahedral mesh (") + e.what() + ")");
  }
  for (std::size_t i = 0; i < spec.track_particle_id.size(); ++i)  // trackers follow vertices by number
    if (spec.track_particle_id[i] >= static_cast<long long>(mesh.vertices.size()))
      throw SceneError(path + ".track_particle_id[" + std::to_string(i) + "]", std::to_string(spec.track_particle_id[i]),
                       "a vertex number of the mesh, 0 to " + std::to_string(mesh.vertices.size() - 1));
  spec.file_mesh = std::make_shared<const TetMesh>(mesh);  // as the files hold it (Froude scaling places it again)
  if (vertex_scale != 1.0)
    for (Vec3d& x : mesh.vertices) x *= vertex_scale;
  TetMeshStats s;
  try {
    s = check_tet_mesh(mesh, "the mesh");
  } catch (const std::runtime_error& e) {
    throw SceneError(source_key, source, std::string("a valid tetrahedral mesh; ") + e.what());
  }
  Vec3d offset = Vec3d::zero();
  const rj::Value* given_offset = o.get("offset");
  if (given_offset) {
    spec.offset = read_real3(*given_offset, path + ".offset", kAny, "m");
    offset = Vec3d{{spec.offset[0], spec.offset[1], spec.offset[2]}};
  }
  const VertexOutside out_of_domain =
      vertex_outside(mesh, offset, Vec3d::zero(), Vec3d{{domain[0], domain[1], domain[2]}});
  if (out_of_domain.vertex >= 0) {
    const Vec3d x = mesh.vertices[static_cast<std::size_t>(out_of_domain.vertex)] + offset;
    const int a = out_of_domain.axis;
    std::ostringstream got;
    got << "vertex " << out_of_domain.vertex << " at (" << x[0] << ", " << x[1] << ", " << x[2] << ") m";
    throw SceneError(given_offset ? path + ".offset" : source_key, got.str(),
                     "every vertex, placed at offset, inside the domain [0, " + num_text(domain[a]) + "] along " +
                         std::string(1, "xyz"[a]),
                     "m");
  }
  spec.stats = s;
  spec.summary = describe(s);
  for (Vec3d& x : mesh.vertices) x += offset;
  spec.mesh = std::make_shared<const TetMesh>(std::move(mesh));
  o.finish();
  return spec;
}

}  // namespace

void append_mesh_bodies(Scene& scene) {
  scene.bodies.erase(std::remove_if(scene.bodies.begin(), scene.bodies.end(), [](const BodySpec& b) { return b.mesh >= 0; }),
                     scene.bodies.end());
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    MeshEntrySpec& e = scene.meshes[m];
    if (e.mesh && e.stats.elements == 0) e.stats = check_tet_mesh(*e.mesh, "meshes[" + std::to_string(m) + "]");
    BodySpec b;
    b.mesh = static_cast<int>(m);
    b.tet_mesh = e.mesh;
    b.gpu = e.gpu;
    // Not a particle body's model (a body spread over N ranks writes model[m]_dev[r] for every rank r), nor an
    // earlier mesh's on the same GPU.
    std::set<int> used;
    for (const BodySpec& o : scene.bodies)
      if (o.mesh < 0 || o.gpu == e.gpu) used.insert(o.model);
    while (used.count(b.model)) ++b.model;
    b.velocity = e.velocity;
    b.output_attribs = e.output_attribs;
    b.track_attribs = e.track_attribs;
    b.track_particle_id = e.track_particle_id;
    b.material.law = e.law;
    b.material.rho = e.rho;
    b.material.youngs_modulus = e.youngs_modulus;
    b.material.poisson_ratio = e.poisson_ratio;
    b.material.ppc = e.ppc;
    b.algorithm.use_asflip = e.use_asflip;
    b.algorithm.asflip_alpha = e.alpha;
    b.algorithm.asflip_beta_min = e.beta_min;
    b.algorithm.asflip_beta_max = e.beta_max;
    b.algorithm.use_fbar = false;  // use_FBAR is the elements' (physics/fem.cuh)
    b.algorithm.use_fem = e.use_fem;  // the elements exert forces
    scene.bodies.push_back(std::move(b));
  }
}

namespace {

const rj::Value* optional_array(ObjectReader& root, std::initializer_list<std::string_view> keys, std::string& path,
                                const char* what) {
  auto f = root.get_any(keys);
  if (!f) return nullptr;
  path = f.path;
  return &require_array(*f.value, f.path, what);
}

/// ClaymoreUW's geometry-level track_particle_id on an entry with array copies: it tracks local particle i of every
/// copy. fbar samples a body as one solid on the global lattice, so its IDs run over the whole body: local ID i is
/// the i-th particle of the entry's copy 0 sampled alone (same lattice, partition and seed), and copy (a, b, c)
/// contributes the body's particle at that point shifted by (a, b, c) x spacing (the nearest within half a lattice
/// step). A rotated entry turns its whole array about its fulcrum, so copy (a, b, c) sits R (a, b, c) x spacing from
/// copy 0; the world lattice does not turn with it, so the copy's particle is the nearest within half a lattice
/// diagonal (sqrt(3)/2 steps). An entry that adds no particles (Subtract, Intersection, Difference) lists the body's
/// own IDs (a warning says so).
void resolve_copy_track_ids(Scene& scene, const Context& ctx) {
  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    BodySpec& b = scene.bodies[bi];
    const std::string bp = "bodies[" + std::to_string(bi) + "]";
    bool pending = false;
    for (const GeometrySpec& g : b.geometry)
      pending = pending || !g.track_particle_id.empty();
    if (!pending) continue;
    auto add_id = [&](long long id) {
      if (std::find(b.track_particle_id.begin(), b.track_particle_id.end(), id) == b.track_particle_id.end())
        b.track_particle_id.push_back(id);
    };
    const std::vector<Vec3d> all = sample_body(b, scene.simulation, static_cast<int>(bi));
    const double dx = scene.simulation.dx;
    const double step = dx / std::cbrt(b.material.ppc);  // the lattice step (jitter: the mean spacing)
    // The body's particles by cell, for the nearest-particle lookups.
    std::map<std::array<long long, 3>, std::vector<long long>> cells;
    auto cell_of = [&](const Vec3d& x) {
      return std::array<long long, 3>{static_cast<long long>(std::floor(x[0] / dx)),
                                      static_cast<long long>(std::floor(x[1] / dx)),
                                      static_cast<long long>(std::floor(x[2] / dx))};
    };
    for (std::size_t id = 0; id < all.size(); ++id) cells[cell_of(all[id])].push_back(static_cast<long long>(id));
    auto nearest = [&](const Vec3d& x, double radius_in_steps) -> long long {
      const auto c = cell_of(x);
      long long best = -1;
      double best_d2 = radius_in_steps * radius_in_steps * step * step;
      for (long long i = -1; i <= 1; ++i)
        for (long long j = -1; j <= 1; ++j)
          for (long long k = -1; k <= 1; ++k) {
            const auto it = cells.find({c[0] + i, c[1] + j, c[2] + k});
            if (it == cells.end()) continue;
            for (long long id : it->second) {
              double d2 = 0.0;
              for (int a = 0; a < 3; ++a) d2 += (all[id][a] - x[a]) * (all[id][a] - x[a]);
              if (d2 <= best_d2) {
                best_d2 = d2;
                best = id;
              }
            }
          }
      return best;
    };
    for (std::size_t gi = 0; gi < b.geometry.size(); ++gi) {
      GeometrySpec& g = b.geometry[gi];
      if (g.track_particle_id.empty()) continue;
      const std::string gp = bp + ".geometry[" + std::to_string(gi) + "].track_particle_id";
      if (g.operation != GeometryOperation::Add && g.operation != GeometryOperation::Union) {
        ctx.warn(gp + ": the entry adds no particles, so its IDs are taken as the body's (ClaymoreUW shifts them by "
                 "the body's particle count for each copy)");
        for (long long id : g.track_particle_id) add_id(id);
        g.track_particle_id.clear();
        continue;
      }
      BodySpec alone = b;
      alone.geometry = {g};
      alone.geometry[0].array = Int3{1, 1, 1};
      alone.geometry[0].track_particle_id.clear();
      const std::vector<Vec3d> first = sample_body(alone, scene.simulation, static_cast<int>(bi));
      const bool rotated = g.rotate != Real3{0.0, 0.0, 0.0};
      const Mat3<double> rot = euler_xyz(g.rotate);
      const double radius = rotated ? 0.5 * std::sqrt(3.0) + 1e-9 : 0.5;  // lattice steps
      for (long long local : g.track_particle_id) {
        if (local >= static_cast<long long>(first.size()))
          throw SceneError(gp, std::to_string(local),
                           "an ID below the " + std::to_string(first.size()) + " particles of one copy of the entry");
        for (int a = 0; a < g.array[0]; ++a)
          for (int c = 0; c < g.array[1]; ++c)
            for (int d = 0; d < g.array[2]; ++d) {
              const Vec3d shift{{a * g.spacing[0], c * g.spacing[1], d * g.spacing[2]}};
              const Vec3d at = first[static_cast<std::size_t>(local)] + (rotated ? rot * shift : shift);
              const long long id = nearest(at, radius);
              if (id < 0)
                throw SceneError(gp, std::to_string(local),
                                 "an ID of a particle every copy keeps (copy [" + std::to_string(a) + ", " +
                                     std::to_string(c) + ", " + std::to_string(d) + "] has no particle at [" +
                                     num_text(at[0]) + ", " + num_text(at[1]) + ", " + num_text(at[2]) +
                                     "]: a later entry or the partition removed it)");
              add_id(id);
            }
      }
      g.track_particle_id.clear();
    }
  }
}

/// Counts every body's particles and what its clips drop, and warns (once per body and kind) where a ClaymoreUW
/// scene relies on a silent tolerance: geometry outside the partition (ClaymoreUW drops it without a word,
/// read_scene_input.h L324-330), particles more than kDomainMarginCells cells outside simulation.domain (those
/// within the margin are kept without a word, as ClaymoreUW keeps them in its grid's 8-cell margin, settings.cuh
/// g_offset; its grid ends there), and tracked IDs that name no particle (ClaymoreUW writes 0.0 for them every
/// frame; fbar writes NaN).
void audit_bodies(const Scene& scene, const Context& ctx) {
  const SimulationSpec& sim = scene.simulation;
  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    const BodySpec& b = scene.bodies[bi];
    const std::string bp = "bodies[" + std::to_string(bi) + "]";
    BodyDrops drops;
    try {
      drops = body_drops(b, sim, static_cast<int>(bi));
    } catch (const std::exception&) {
      continue;  // a body that cannot be sampled (a file's content, no particle) fails where it is sampled
    }
    for (const BodyShape::FileSeedNotes& note : drops.file_notes) {
      const std::string at = bp + ".geometry[" + std::to_string(note.entry) + "].file: \"" + b.geometry[note.entry].file + "\"";
      if (!std::isnan(note.one_minus_j_median))
        ctx.warn(at + ": its J column holds 1 - J, as ClaymoreUW writes it (median " + num_text(note.one_minus_j_median) +
                 "); fbar reads J = 1 - value, as ClaymoreUW reads it back. fbar's own frames hold J");
      if (note.dropped > 0)
        ctx.warn(at + ": " + std::to_string(note.dropped) + " of its " + std::to_string(note.read) +
                 " particles are inverted (J or det DefGrad <= 0; first: " + note.first +
                 ") and are dropped. ClaymoreUW keeps such particles (its JFluid pressure pow(J, -gamma) is not a "
                 "number there)");
    }
    if (!drops.partition_counted)
      ctx.warn(bp + ".partition_start/partition_end: the geometry outside [" + num_text(b.partition_start[0]) + ", " +
               num_text(b.partition_start[1]) + ", " + num_text(b.partition_start[2]) + "] .. [" +
               num_text(b.partition_end[0]) + ", " + num_text(b.partition_end[1]) + ", " +
               num_text(b.partition_end[2]) + "] m is dropped (not counted: the unclipped geometry is too large); "
               "ClaymoreUW drops it too, without a word");
    else if (drops.outside_partition > 0)
      ctx.warn(bp + ".partition_start/partition_end: " + std::to_string(drops.outside_partition) + " of the " +
               std::to_string(drops.outside_partition + drops.particles + drops.outside_domain) +
               " particles of the body's geometry lie outside [" + num_text(b.partition_start[0]) + ", " +
               num_text(b.partition_start[1]) + ", " + num_text(b.partition_start[2]) + "] .. [" +
               num_text(b.partition_end[0]) + ", " + num_text(b.partition_end[1]) + ", " +
               num_text(b.partition_end[2]) + "] m and are dropped; ClaymoreUW drops them too, without a word");
    if (drops.outside_domain > 0)
      ctx.warn(bp + ".geometry: " + std::to_string(drops.outside_domain) + " of the body's " +
               std::to_string(drops.outside_domain + drops.particles) + " particles lie more than " +
               num_text(kDomainMarginCells) + " cells (" + num_text(kDomainMarginCells * sim.dx) +
               " m) outside simulation.domain [0, " + num_text(sim.domain[0]) + "] x [0, " + num_text(sim.domain[1]) +
               "] x [0, " + num_text(sim.domain[2]) + "] m and are dropped (" + std::to_string(drops.particles) +
               " remain); particles may stand within that margin (ClaymoreUW's grid margin, whose grid ends there)");
    std::vector<std::size_t> bad;
    for (std::size_t k = 0; k < b.track_particle_id.size(); ++k)
      if (b.track_particle_id[k] >= drops.particles) bad.push_back(k);
    if (!bad.empty()) {
      std::string more;
      for (std::size_t k = 1; k < bad.size(); ++k)
        more += (more.empty() ? "" : ", ") + std::to_string(b.track_particle_id[bad[k]]);
      ctx.warn(bp + ".track_particle_id[" + std::to_string(bad.front()) + "]: " +
               std::to_string(b.track_particle_id[bad.front()]) +
               (more.empty() ? std::string() : " (and " + more + ")") + " is not the ID of one of the body's " +
               std::to_string(drops.particles) + " particles (0 .. " + std::to_string(drops.particles - 1) +
               ", in sampling order); ClaymoreUW matches no particle and writes 0.0 for it every frame; fbar writes "
               "NaN in its columns of particleTrack_model[" + std::to_string(b.model) + "]_dev[0].csv");
    }
  }
}

Scene parse_document(const rj::Document& doc, Context& ctx) {
  Scene scene;
  ObjectReader root(doc, "", kTopKeys, ctx, "the scene (simulation, bodies, boundaries, grid-sensors, particle-sensors)");

  const SimulationRead sim = parse_simulation(root.get("simulation"), ctx);
  scene.simulation = sim.spec;

  // A scene of FEM meshes alone (a structure under its own weight) has no particle body: `bodies` may then be absent
  // or empty; a scene with neither is an error (naming bodies, or meshes when only that key is given).
  std::string bodies_path = "bodies", meshes_path = "meshes";
  const char* const kBodiesExpected = "a non-empty array of bodies (or of meshes)";
  const rj::Value* bodies = optional_array(root, {"bodies", "models"}, bodies_path, kBodiesExpected);
  const rj::Value* meshes = optional_array(root, {"meshes"}, meshes_path, "an array of mesh objects");
  const bool has_meshes = meshes && meshes->Size() > 0;
  if (!bodies && !has_meshes) {
    if (meshes) throw SceneError(meshes_path, "[]", "a non-empty array of meshes (or a non-empty array of bodies)");
    root.missing("bodies", kBodiesExpected);
  }
  if (bodies && bodies->Size() == 0 && !has_meshes) throw SceneError(bodies_path, "[]", kBodiesExpected);
  std::vector<BodyRead> read;
  if (bodies)
    for (rj::SizeType i = 0; i < bodies->Size(); ++i)
      read.push_back(parse_body((*bodies)[i], index_path(bodies_path, i), ctx));
  assign_models(read, bodies_path);
  for (auto& b : read) {
    if (sim.cfl && !b.cfl_given) b.spec.material.cfl = *sim.cfl;
    scene.bodies.push_back(std::move(b.spec));
  }

  std::string path;
  if (auto* a = optional_array(root, {"boundaries", "grid-boundaries"}, path, "an array of boundary objects"))
    for (rj::SizeType i = 0; i < a->Size(); ++i) scene.boundaries.push_back(parse_boundary((*a)[i], index_path(path, i), ctx));
  if (auto* a = optional_array(root, {"grid-sensors"}, path, "an array of grid-sensor objects"))
    for (rj::SizeType i = 0; i < a->Size(); ++i) {
      GridSensorSpec g = parse_grid_sensor((*a)[i], index_path(path, i), ctx);
      // ClaymoreUW grows a box of zero thickness along an axis by one cell, so that a plane of nodes is caught.
      for (int d = 0; d < 3; ++d)
        if (g.domain_end[d] == g.domain_start[d]) g.domain_end[d] += scene.simulation.dx;
      scene.grid_sensors.push_back(std::move(g));
    }
  if (auto* a = optional_array(root, {"particle-sensors", "targets"}, path, "an array of particle-sensor objects")) {
    // ClaymoreUW's particle sensors aggregate the bodies' target_attribs[0] (its default Position_Y) and read no
    // attribute of their own; fbar's read their attribute, and take the bodies' target_attribs when they give none.
    std::set<std::string> targets;
    for (const BodySpec& b : scene.bodies)
      if (!b.target_attribs.empty()) targets.insert(b.target_attribs.front());
    for (rj::SizeType i = 0; i < a->Size(); ++i) {
      bool given = false;
      ParticleSensorSpec sensor = parse_particle_sensor((*a)[i], index_path(path, i), ctx, given);
      const std::string at = index_path(path, i) + ".attribute";
      if (!given && targets.size() > 1)
        throw SceneError(at, "(missing)", "an attribute: the bodies' target_attribs differ (" + join(std::vector<std::string>(targets.begin(), targets.end())) + ")");
      if (!given && targets.size() == 1) sensor.attribute = *targets.begin();
      if (given && !targets.empty() && !targets.count(sensor.attribute))
        ctx.warn(at + ": " + sensor.attribute + " is aggregated; the bodies' target_attribs (" + join(std::vector<std::string>(targets.begin(), targets.end())) +
                 "), which ClaymoreUW's sensors aggregate instead, is not");
      scene.particle_sensors.push_back(std::move(sensor));
    }
  }
  if (auto* a = optional_array(root, {"grid-fields"}, path, "an array of grid-field objects"))
    for (rj::SizeType i = 0; i < a->Size(); ++i) {
      GridFieldSpec f = parse_grid_field((*a)[i], index_path(path, i), ctx);
      if (f.attributes.empty()) f.attributes = {"Mass", "Velocity", "Force"};
      if (f.output_frequency == 0.0) f.output_frequency = scene.simulation.fps;  // Froude-scaled below as fps is
      scene.grid_fields.push_back(std::move(f));
    }
  warn_claymoreuw_sensor_frequencies(scene.grid_sensors, "grid-sensors", ctx);
  warn_claymoreuw_sensor_frequencies(scene.particle_sensors, "particle-sensors", ctx);
  // FEM meshes: each entry's mesh files are read and checked now (a bad mesh is named by --check), and each becomes
  // a body after the particle bodies (append_mesh_bodies, below).
  if (meshes) {
    for (rj::SizeType i = 0; i < meshes->Size(); ++i)
      scene.meshes.push_back(read_mesh_entry((*meshes)[i], index_path(meshes_path, i), ctx, scene.simulation.domain,
                                             scene.simulation.froude_scaling_applied ? scene.simulation.froude_scaling : 1.0));
  }
  for (const char* k : kWrapperKeys)
    if (auto* v = root.get(k)) scene.wrapper.emplace_back(k, read_string(*v, k, "a string (HydroUQ metadata)"));
  root.finish();

  apply_froude_scaling(scene);
  // ClaymoreUW's default step is dx / 100 (of the scaled dx: the default is a property of the grid).
  if (!sim.default_dt_given) scene.simulation.default_dt = scene.simulation.dx / 100.0;
  resolve_copy_track_ids(scene, ctx);  // samples the bodies that list IDs per array copy (at scale)
  audit_bodies(scene, ctx);
  for (std::size_t m = 0; m < scene.meshes.size(); ++m)
    if (scene.meshes[m].mesh && !scene.meshes[m].use_fem)
      ctx.warn("meshes[" + std::to_string(m) + "].use_FEM: false: the elements exert no force (the vertices move with the "
               "grid, as in ClaymoreUW); set it true for an elastic body");
  append_mesh_bodies(scene);
  return scene;
}

/// 1-based line and column of a byte offset.
std::pair<std::size_t, std::size_t> line_column(const std::string& text, std::size_t offset) {
  std::size_t line = 1, col = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return {line, col};
}

Scene parse_text(const std::string& json, const std::string& source, const ParseOptions& options,
                 const fs::path& scene_dir) {
  rj::Document doc;
  // Comments and trailing commas are friendly; Infinity only appears where check-time rules allow it (partition
  // bounds, boundary time windows); full precision so that written scenes read back bit for bit.
  constexpr unsigned kFlags = rj::kParseCommentsFlag | rj::kParseTrailingCommasFlag | rj::kParseNanAndInfFlag |
                              rj::kParseFullPrecisionFlag;
  doc.Parse<kFlags>(json.c_str(), json.size());
  if (doc.HasParseError()) {
    const std::size_t at = doc.GetErrorOffset();
    const auto [line, col] = line_column(json, at);
    std::string near = json.substr(at, 20);
    const auto nl = near.find('\n');
    if (nl != std::string::npos) near = near.substr(0, nl);
    const bool line_break = at < json.size() && (json[at] == '\n' || json[at] == '\r');
    std::string reason = rj::GetParseError_En(doc.GetParseError());
    // RapidJSON reports a raw line break in a string (usually a missing closing quote) as an invalid escape.
    if (line_break && doc.GetParseError() == rj::kParseErrorStringEscapeInvalid)
      reason = "a line break inside a string: missing closing quotation mark?";
    throw SceneError(source + ":" + std::to_string(line) + ":" + std::to_string(col),
                     at >= json.size() ? "end of input" : line_break ? "a line break" : in_quotes(near),
                     "valid JSON (" + reason + ")");
  }

  Context ctx{options, {}};
  if (!options.data_dir.empty()) ctx.search_dirs.emplace_back(options.data_dir);
  if (const char* env = std::getenv("AssetDirPath"); env && *env) ctx.search_dirs.emplace_back(env);
  ctx.search_dirs.push_back(scene_dir.empty() ? fs::current_path() : scene_dir);
#ifdef FBAR_SOURCE_DIR
  ctx.search_dirs.push_back(fs::path(FBAR_SOURCE_DIR) / "Data");
#endif

  Scene scene = parse_document(doc, ctx);
  scene.source_path = source == "(string)" ? std::string() : source;
  scene.data_dir = ctx.search_dirs.front().string();
  if (options.check_supported) check_supported(scene);
  return scene;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Public API
// ---------------------------------------------------------------------------------------------------------------

std::size_t levenshtein_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t subst = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, subst});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string closest_key(std::string_view key, const std::vector<std::string_view>& candidates) {
  const std::string k = lower(key);
  std::string best;
  std::size_t best_d = std::numeric_limits<std::size_t>::max();
  for (std::string_view c : candidates) {
    const std::size_t d = levenshtein_distance(k, lower(c));
    if (d < best_d) {
      best_d = d;
      best = std::string(c);
    }
  }
  const std::size_t limit = std::max<std::size_t>(2, key.size() / 2);
  return best_d <= limit ? best : std::string();
}

Scene parse_scene_string(const std::string& json, const ParseOptions& options) {
  return parse_text(json, "(string)", options, fs::path(options.scene_dir));
}

Scene parse_scene_file(const std::string& path, const ParseOptions& options) {
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw SceneError("--file", in_quotes(path), "an existing scene file (no such file)");
  if (fs::is_directory(path, ec)) throw SceneError("--file", in_quotes(path), "a scene file, not a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError("--file", in_quotes(path), "a readable scene file (cannot open it)");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const fs::path dir = fs::absolute(fs::path(path), ec).parent_path();
  return parse_text(buffer.str(), path, options, dir);
}

}  // namespace fbar
