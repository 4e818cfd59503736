// Sweeps (docs/user_guide.md §10): one scene and the parameters that vary, read from a sweep file and expanded into
// cases, each case the scene with its values written at their JSON paths.
//
// A sweep file is a JSON object:
//   "scene":      the base scene: a file (relative to the sweep file's folder) or the scene object itself
//   "output":     the sweep's folder, relative to the sweep file's (default: the sweep file's name without .json,
//                 beside it; --output overrides it, relative to the working directory); case k runs in
//                 <output>/case_<kkkk>/ (its frames, sensors, run.json, log.txt)
//   "design":     "factorial" (default: every combination of the parameters' values), "cases" (the listed "cases"),
//                 "latin_hypercube" ("samples" cases, each parameter's range cut in that many strata, one sample per
//                 stratum, strata paired at random from "seed")
//   "samples", "seed": the sampled design's size and its random seed (an integer; the same seed, the same cases)
//   "parameters": [{ "name", "path", one of: "values" [...], "range" [lo, hi] with "count", "uniform" [lo, hi],
//                 "log_uniform" [lo, hi], "normal" [mean, std]; optional "labels" [...], "integer" true }]
//   "cases":      design "cases": [{ "<name>": value, ... }], every parameter named in each
// A path names a value of the scene JSON as written in it: object keys and array indices, "bodies[2].geometry[0]
// .offset[0]", "simulation.gravity[1]"; its last key may be one the scene leaves out (a default). A value may be any
// JSON (a whole array of geometry entries to choose from): tables show its label.
#pragma once

#include <string>
#include <vector>

#include "scene/scene.h"
#include "scene/scene_parse.h"

namespace fbar {

enum class SweepDesign { Factorial, Cases, LatinHypercube };

/// One varied parameter: where it goes and the values it takes.
struct SweepParameter {
  enum class Kind { Values, Range, Uniform, LogUniform, Normal, Given };
  std::string name;  ///< its column in the sweep's tables
  std::string path;  ///< JSON path into the scene
  Kind kind = Kind::Given;
  std::vector<std::string> values;  ///< Values: each value's JSON text
  std::vector<std::string> labels;  ///< Values: each value's label (default: a number's text, "choice k" otherwise)
  double a = 0.0, b = 0.0;          ///< Range, Uniform, LogUniform: [a, b]; Normal: mean a, standard deviation b
  int count = 0;                    ///< Range: values from a to b, evenly spaced (count 1: a)
  bool integer = false;             ///< sampled values rounded to the nearest integer
};

/// One case: each parameter's value.
struct SweepCase {
  int id = 0;
  std::vector<std::string> json;    ///< per parameter: the JSON text written at its path
  std::vector<std::string> labels;  ///< per parameter: as tables show it
  std::vector<double> numbers;      ///< per parameter: the value when it is a number, else the choice's index
};

struct Sweep {
  std::string source;      ///< the sweep file (for messages)
  std::string scene_file;  ///< the base scene file, empty when inline
  std::string scene_json;  ///< the base scene's text
  std::string scene_dir;   ///< the folder the scene's relative files resolve against
  std::string output;      ///< the sweep's folder
  SweepDesign design = SweepDesign::Factorial;
  int samples = 0;
  unsigned long long seed = 0;
  std::vector<SweepParameter> parameters;
  std::vector<SweepCase> cases;
};

/// Reads a sweep file and expands its cases. Throws SceneError naming the sweep file's JSON path, the value and what
/// was expected (a path that does not name a value of the scene included: "parameters[1].path").
Sweep parse_sweep_file(const std::string& path);
/// The same from a string; `dir` stands for the sweep file's folder (relative scene and output paths).
Sweep parse_sweep_string(const std::string& json, const std::string& dir, const std::string& source = "(sweep)");

/// "case_0007".
std::string sweep_case_folder(int id);
/// "height=0.2, mu=0.3".
std::string sweep_case_label(const Sweep& sweep, const SweepCase& c);

/// The case's scene text: the base scene with each parameter's value at its path and simulation.save_path set to
/// `save_path` (canonical key order of the input kept). Throws SceneError naming the case and the parameter when a
/// path does not lead through the scene.
std::string sweep_case_scene_json(const Sweep& sweep, const SweepCase& c, const std::string& save_path);
/// The case's scene parsed and validated (relative files resolve against sweep.scene_dir). A SceneError names the
/// case: "sweep case 3 (height=0.2): bodies[0].material.E: got ...".
Scene sweep_case_scene(const Sweep& sweep, const SweepCase& c, const std::string& save_path,
                       const ParseOptions& options);

/// The standard normal quantile Phi^-1(u), 0 < u < 1 (Newton on erf to double precision).
double normal_quantile(double u);

}  // namespace fbar
