// The scene front end: reads a scene JSON (docs/user_guide.md §2) into the resolved Scene, validates it, writes it back.
//
// Reading applies, in this order: syntax (RapidJSON, with // comments and trailing commas allowed), every key's
// type / range / array length / enum value (ClaymoreUW's aliases accepted), unknown keys (error naming the closest
// known key, or a warning with allow_unknown_keys), defaults, cross-checks (model ids, attribute names, domains,
// file existence), Froude scaling, and finally the release policy check_supported(). Every problem throws
// SceneError naming the JSON path, the value, what was expected and the unit.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "scene/scene.h"
#include "scene/scene_error.h"

namespace fbar {

struct ParseOptions {
  /// Unknown keys (and parameters the chosen law or object does not use) become warnings instead of errors.
  bool allow_unknown_keys = false;
  /// Where geometry and motion files are looked up first (--data-dir); then $AssetDirPath, the scene file's folder
  /// and <source>/Data.
  std::string data_dir;
  /// Receives warnings (one line each, without a "warning:" prefix); nullptr drops them.
  std::vector<std::string>* warnings = nullptr;
  /// Apply check_supported() after parsing. Tests of parsing unsupported features turn it off.
  bool check_supported = true;
  /// parse_scene_string: the folder the scene's relative files resolve against after data_dir and $AssetDirPath
  /// (a sweep case: its base scene's folder); empty: the working directory.
  std::string scene_dir;
};

/// Reads and resolves a scene file. Throws SceneError (missing / unreadable file, syntax, invalid values).
Scene parse_scene_file(const std::string& path, const ParseOptions& options);

/// Reads and resolves a scene held in a string (source_path stays empty; relative files resolve against data_dir,
/// $AssetDirPath and the working directory).
Scene parse_scene_string(const std::string& json, const ParseOptions& options);

/// The release policy: what this build's engine (the CPU reference engine) can run. Throws SceneError whose
/// expected text says "not supported yet in this release" and names the key, for the first feature it cannot run.
/// Later releases delete lines here and nowhere else.
void check_supported(const Scene& scene);

/// One body per meshes[] entry, appended after the particle bodies (BodySpec::mesh = its index): gpu, velocity,
/// output and tracking from the entry; material law, rho, E, nu and ppc from it, type "particles" (the vertices are
/// particles to every part of fbar but the engines' stress, physics/fem.cuh); ASFLIP from use_ASFLIP, alpha and
/// beta_min/max; use_FEM from use_FEM; no particle F-bar (use_FBAR is the elements'). Its model number is the first
/// one that no particle body uses and no earlier mesh on its GPU (its frames model[m]_dev[gpu] then never share a name:
/// a spread body writes model[m]_dev[r] on every rank r; ClaymoreUW puts a mesh in model 0 of its GPU, which a
/// particle body there would overwrite).
/// Bodies already appended are replaced; an entry's mesh is measured (MeshEntrySpec::stats) when nobody did. The parser
/// calls it; so do programs that build a scene in code.
void append_mesh_bodies(Scene& scene);

/// Applies Froude similitude with factor s = scene.simulation.froude_scaling to every field, the materials' stresses
/// by the Cauchy ratio of simulation.cauchy_scaling (see the definition for the exponent of each quantity), and
/// sets simulation.froude_scaling_applied. No-op when already applied or when nothing would change.
void apply_froude_scaling(Scene& scene);

/// The resolved scene as a JSON document (every key, canonical names, SI units, froude_scaling_applied true when
/// scaled). parse_scene_string(write_scene_json(s)) == s for every scene the parser produces. Open (infinite)
/// partition bounds and the default always-active boundary time window are omitted; a partly infinite one (only
/// from a scene built in code) is written as Infinity, which the reader accepts only there.
std::string write_scene_json(const Scene& scene, bool pretty = true);

/// Indents compact JSON (two spaces per level; arrays of scalars stay on one line). Used for run.json too.
std::string indent_json(std::string_view compact);

/// Closest of `candidates` to `key` by case-insensitive Levenshtein distance; empty when none is reasonably close
/// (distance greater than max(2, |key| / 2)).
std::string closest_key(std::string_view key, const std::vector<std::string_view>& candidates);
std::size_t levenshtein_distance(std::string_view a, std::string_view b);

// Canonical names (the spelling write_scene_json uses and --check prints).
const char* to_string(Precision p);
/// The precision as run logs state it: "single", "double", or "mixed: particles double, grid single".
const char* precision_description(Precision p);
const char* to_string(OnFailure f);
const char* to_string(InitialState s);
const char* to_string(Backend b);
const char* to_string(Constitutive c);
const char* to_string(GeometryObject o);
const char* to_string(GeometryOperation o);
const char* to_string(BoundaryObject o);
const char* to_string(Contact c);
const char* to_string(SensorOperation o);
/// "X" / "Y" / "Z" for 0 / 1 / 2.
const char* axis_name(int axis);

// Field-by-field equality of the resolved model (source_path and data_dir are provenance and are not compared).
bool operator==(const SimulationSpec& a, const SimulationSpec& b);
bool operator==(const MeshEntrySpec& a, const MeshEntrySpec& b);
bool operator==(const MaterialSpec& a, const MaterialSpec& b);
bool operator==(const AlgorithmSpec& a, const AlgorithmSpec& b);
bool operator==(const GeometrySpec& a, const GeometrySpec& b);
bool operator==(const BodySpec& a, const BodySpec& b);
bool operator==(const BoundarySpec& a, const BoundarySpec& b);
bool operator==(const GridSensorSpec& a, const GridSensorSpec& b);
bool operator==(const ParticleSensorSpec& a, const ParticleSensorSpec& b);
bool operator==(const GridFieldSpec& a, const GridFieldSpec& b);
bool operator==(const Scene& a, const Scene& b);
inline bool operator!=(const Scene& a, const Scene& b) { return !(a == b); }

}  // namespace fbar
