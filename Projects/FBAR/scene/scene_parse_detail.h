// What the parts of the scene reader share (scene/scene_parse*.cpp only; the conventions are in scene_parse.cpp):
// text helpers, typed readers with their ranges, the enumerations and their aliases, the known keys per object, the
// parse context and the object reader, and the readers of the document's parts that live in other files.
#pragma once

#include <rapidjson/document.h>
#include <rapidjson/error/en.h>
#include <rapidjson/stringbuffer.h>
#include <rapidjson/writer.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "geometry/geometry.h"
#include "geometry/geometry_files.h"
#include "scene/attributes.h"
#include "physics/boundary.cuh"
#include "physics/constitutive_models.cuh"

#include "scene/scene_parse.h"

namespace fbar {
namespace rj = rapidjson;
}  // namespace fbar

namespace fbar::scene_json {

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------------------------
// Text helpers
// ---------------------------------------------------------------------------------------------------------------

/// Compact JSON text of a value, shortened for messages.
inline std::string writer_text(const rj::Value& v) {
  rj::StringBuffer sb;
  rj::Writer<rj::StringBuffer, rj::UTF8<>, rj::UTF8<>, rj::CrtAllocator, rj::kWriteNanAndInfFlag> w(sb);
  v.Accept(w);
  std::string s = sb.GetString();
  if (s.size() > 80) s = s.substr(0, 77) + "...";
  return s;
}

/// A number for messages: integers without ".0" (1e6 -> 1000000), others in shortest round-trip form.
inline std::string num_text(double x) {
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  if (x == std::floor(x) && std::fabs(x) < 1e15) {
    std::ostringstream os;
    os << static_cast<long long>(x);
    return os.str();
  }
  return writer_text(rj::Value(x));
}

/// A JSON value as the user wrote it (up to number spelling), for the "got ..." part of messages.
inline std::string json_text(const rj::Value& v) {
  if (v.IsNumber() && !v.IsInt64()) return num_text(v.GetDouble());
  return writer_text(v);
}

inline std::string in_quotes(std::string_view s) { return "\"" + std::string(s) + "\""; }

inline std::string lower(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

/// Enum matching key: lower case without spaces, '_' and '-' ("Drucker-Prager" == "drucker_prager").
inline std::string fold(std::string_view s) {
  std::string r;
  for (char c : s)
    if (c != ' ' && c != '_' && c != '-') r += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

inline std::string join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string r;
  for (std::size_t i = 0; i < items.size(); ++i) r += (i ? sep : "") + items[i];
  return r;
}

inline std::string sub_path(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}
inline std::string index_path(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

// ---------------------------------------------------------------------------------------------------------------
// Ranges and typed readers
// ---------------------------------------------------------------------------------------------------------------

/// A closed / open interval of admissible numbers with its wording for messages.
struct Range {
  double lo = -kInf, hi = kInf;
  bool lo_open = false, hi_open = false;

  bool contains(double x) const {
    if (lo_open ? !(x > lo) : !(x >= lo)) return false;
    if (hi_open ? !(x < hi) : !(x <= hi)) return false;
    return true;
  }
  std::string describe(const char* noun) const {
    const std::string n = noun;
    if (lo == -kInf && hi == kInf) return n;
    if (hi == kInf) return n + (lo_open ? " > " : " >= ") + num_text(lo);
    if (lo == -kInf) return n + (hi_open ? " < " : " <= ") + num_text(hi);
    return n + " in " + (lo_open ? "(" : "[") + num_text(lo) + ", " + num_text(hi) + (hi_open ? ")" : "]");
  }
};
inline const Range kAny{};
inline const Range kPositive{0.0, kInf, true, false};
inline const Range kNonNegative{0.0, kInf, false, false};
inline const Range kUnit{0.0, 1.0, false, false};
inline Range at_least(double lo) { return Range{lo, kInf, false, false}; }

/// "an array of 3 numbers" or "an array of 3 numbers, each > 0".
inline std::string each(const Range& r, const std::string& noun) {
  const std::string bound = r.describe("");
  return bound.empty() ? noun : noun + ", each" + bound;
}

inline double read_number(const rj::Value& v, const std::string& path, const Range& r, const char* unit,
                   bool allow_inf = false) {
  if (!v.IsNumber()) throw SceneError(path, json_text(v), r.describe("a number"), unit);
  const double x = v.GetDouble();
  if (std::isnan(x) || (std::isinf(x) && !allow_inf)) throw SceneError(path, json_text(v), r.describe("a finite number"), unit);
  if (!r.contains(x)) throw SceneError(path, json_text(v), r.describe("a number"), unit);
  return x;
}

inline long long read_integer(const rj::Value& v, const std::string& path, const Range& r, const char* unit = "") {
  bool ok = v.IsInt64();
  long long x = ok ? v.GetInt64() : 0;
  if (!ok && v.IsNumber()) {  // 8.0 is the integer 8 (ClaymoreUW scenes write counts as doubles)
    const double d = v.GetDouble();
    if (std::isfinite(d) && d == std::floor(d) && std::fabs(d) <= 9.007199254740992e15) {
      ok = true;
      x = static_cast<long long>(d);
    }
  }
  if (!ok || !r.contains(static_cast<double>(x))) throw SceneError(path, json_text(v), r.describe("an integer"), unit);
  return x;
}

inline int read_int(const rj::Value& v, const std::string& path, const Range& r, const char* unit = "") {
  const long long x = read_integer(v, path, r, unit);
  if (x < std::numeric_limits<int>::min() || x > std::numeric_limits<int>::max())
    throw SceneError(path, json_text(v), "an integer in [-2147483648, 2147483647]", unit);
  return static_cast<int>(x);
}

inline bool read_bool(const rj::Value& v, const std::string& path) {
  if (!v.IsBool()) throw SceneError(path, json_text(v), "true or false");
  return v.GetBool();
}

inline std::string read_string(const rj::Value& v, const std::string& path, const char* what = "a string") {
  if (!v.IsString()) throw SceneError(path, json_text(v), what);
  return std::string(v.GetString(), v.GetStringLength());
}

/// N numbers; `or_one_more`: N + 1 are accepted too (the caller reads the last one), and the message says so.
template <std::size_t N>
std::array<double, N> read_reals(const rj::Value& v, const std::string& path, const Range& r, const char* unit,
                                 bool allow_inf = false, bool or_one_more = false) {
  if (!v.IsArray() || (v.Size() != N && !(or_one_more && v.Size() == N + 1)))
    throw SceneError(path, json_text(v),
                     each(r, "an array of " + std::to_string(N) + (or_one_more ? " (or " + std::to_string(N + 1) + ")" : "") +
                                 " numbers"),
                     unit);
  std::array<double, N> out{};
  for (rj::SizeType i = 0; i < N; ++i) out[i] = read_number(v[i], index_path(path, i), r, unit, allow_inf);
  return out;
}
inline Real3 read_real3(const rj::Value& v, const std::string& path, const Range& r, const char* unit, bool allow_inf = false) {
  return read_reals<3>(v, path, r, unit, allow_inf);
}

inline Int3 read_int3(const rj::Value& v, const std::string& path, const Range& r) {
  if (!v.IsArray() || v.Size() != 3) throw SceneError(path, json_text(v), each(r, "an array of 3 integers"));
  Int3 out{};
  for (rj::SizeType i = 0; i < 3; ++i) out[i] = read_int(v[i], index_path(path, i), r);
  return out;
}

inline std::vector<long long> read_integer_array(const rj::Value& v, const std::string& path, const Range& r) {
  if (!v.IsArray()) throw SceneError(path, json_text(v), each(r, "an array of integers"));
  std::vector<long long> out;
  for (rj::SizeType i = 0; i < v.Size(); ++i) out.push_back(read_integer(v[i], index_path(path, i), r));
  return out;
}

inline const rj::Value& require_array(const rj::Value& v, const std::string& path, const char* what) {
  if (!v.IsArray()) throw SceneError(path, json_text(v), what);
  return v;
}

// ---------------------------------------------------------------------------------------------------------------
// Enumerations: canonical name first, then the aliases ClaymoreUW accepts (matched after fold()).
// ---------------------------------------------------------------------------------------------------------------

template <class E>
struct EnumName {
  E value;
  std::vector<const char*> names;  ///< names[0] is canonical
};

template <class E>
std::string enum_choices(const std::vector<EnumName<E>>& table) {
  std::vector<std::string> n;
  for (const auto& e : table) n.push_back(e.names[0]);
  return "one of " + join(n);
}

template <class E>
E read_enum(const rj::Value& v, const std::string& path, const std::vector<EnumName<E>>& table) {
  if (!v.IsString()) throw SceneError(path, json_text(v), enum_choices(table));
  const std::string key = fold(v.GetString());
  for (const auto& e : table)
    for (const char* n : e.names)
      if (fold(n) == key) return e.value;
  std::vector<std::string_view> all;
  for (const auto& e : table)
    for (const char* n : e.names) all.emplace_back(n);
  std::string expected = enum_choices(table);
  const std::string near = closest_key(v.GetString(), all);
  if (!near.empty()) expected += " (did you mean " + in_quotes(near) + "?)";
  throw SceneError(path, json_text(v), expected);
}

/// Every material's JSON name and aliases, from MaterialTypes (constitutive_models.cuh).
inline std::vector<EnumName<Constitutive>> material_names() {
  std::vector<EnumName<Constitutive>> laws;
  for_each_material([&](auto m) {
    using M = decltype(m);
    EnumName<Constitutive> e{M::kLaw, {M::kJsonName}};
    for_each_material_alias<M>([&](const char* a) { e.names.push_back(a); });
    laws.push_back(std::move(e));
  });
  return laws;
}
inline const std::vector<EnumName<Constitutive>> kLaws = material_names();
inline const std::vector<EnumName<Precision>> kPrecisions = {
    {Precision::Single, {"single"}}, {Precision::Double, {"double"}}, {Precision::Mixed, {"mixed"}}};
inline const std::vector<EnumName<OnFailure>> kOnFailure = {{OnFailure::Stop, {"stop"}},
                                                     {OnFailure::ReduceDt, {"reduce_dt"}}};
inline const std::vector<EnumName<InitialState>> kInitialStates = {{InitialState::Rest, {"rest"}},
                                                            {InitialState::Hydrostatic, {"hydrostatic"}}};
inline const std::vector<EnumName<GeometryObject>> kGeometryObjects = {{GeometryObject::Box, {"Box", "Cube"}},
                                                                {GeometryObject::Sphere, {"Sphere", "Ball"}},
                                                                {GeometryObject::Cylinder, {"Cylinder"}},
                                                                {GeometryObject::File, {"File"}},
                                                                {GeometryObject::Bathymetry, {"Bathymetry"}},
                                                                {GeometryObject::OsuLwf, {"OSU LWF", "OSU_LWF_WATER"}},
                                                                {GeometryObject::OsuTwb, {"OSU TWB", "OSU_TWB_WATER"}}};
inline const std::vector<EnumName<GeometryOperation>> kGeometryOperations = {
    {GeometryOperation::Add, {"Add"}},
    {GeometryOperation::Subtract, {"Subtract"}},
    {GeometryOperation::Union, {"Union"}},
    {GeometryOperation::Intersection, {"Intersection", "Intersect"}},
    {GeometryOperation::Difference, {"Difference"}}};
inline const std::vector<EnumName<int>> kAxes = {{0, {"X"}}, {1, {"Y"}}, {2, {"Z"}}};
inline const std::vector<EnumName<BoundaryObject>> kBoundaryObjects = {
    {BoundaryObject::Walls, {"Walls", "Wall"}},
    {BoundaryObject::Box, {"Box", "Cube"}},
    {BoundaryObject::Sphere, {"Sphere", "Ball"}},
    {BoundaryObject::Cylinder, {"Cylinder"}},
    {BoundaryObject::Plane, {"Plane", "Surface"}},
    {BoundaryObject::Floor, {"Floor"}},
    {BoundaryObject::Bathymetry, {"Bathymetry", "Bath"}},
    {BoundaryObject::Piston, {"Piston", "Paddle"}},
    {BoundaryObject::Pump, {"Pump"}},
    {BoundaryObject::Velocity, {"Velocity", "velocity_boundary"}},
    {BoundaryObject::OSU_LWF_RAMP, {"OSU_LWF_RAMP", "OSU LWF", "OSU Flume", "OSU LWF Bathymetry"}},
    {BoundaryObject::OSU_LWF_PADDLE, {"OSU_LWF_PADDLE", "OSU Paddle", "OSU LWF Piston", "OSU Wave Maker"}},
    {BoundaryObject::OSU_TWB_RAMP, {"OSU_TWB_RAMP", "OSU TWB", "OSU TWB Bathymetry"}},
    {BoundaryObject::OSU_TWB_PADDLE, {"OSU_TWB_PADDLE", "OSU TWB Piston", "OSU TWB Wave Maker", "OSU DWB Paddle"}},
    {BoundaryObject::USGS_RAMP, {"USGS_RAMP", "USGS Flume", "USGS DFF Ramp"}},
    {BoundaryObject::USGS_GATE, {"USGS_GATE", "USGS Gates", "USGS DFF Gate", "USGS DFF Gates"}},
    {BoundaryObject::WASIRF_PUMP, {"WASIRF_PUMP", "UW WASIRF Pump"}},
    {BoundaryObject::TOKYO_HARBOR, {"TOKYO_HARBOR", "WU TWB Harbor", "Waseda Harbor"}},
};
inline const std::vector<EnumName<FbarScheme>> kFbarSchemes = {
    {FbarScheme::Cell, {"cell"}},
    {FbarScheme::Nodal, {"nodal", "ClaymoreUW"}},
};
inline const std::vector<EnumName<Contact>> kContacts = {
    {Contact::Sticky, {"Sticky", "Stick", "Rigid", "No-Slip", "Fixed", "Fix"}},
    {Contact::Slip, {"Slip", "Roller"}},
    {Contact::Separable, {"Separable", "Seperable", "Separate", "Separatable"}},
};
inline const std::vector<EnumName<SensorOperation>> kGridSensorOperations = {
    {SensorOperation::Sum, {"Sum", "Add", "Addition"}},
    {SensorOperation::Max, {"Max", "Maximum"}},
    {SensorOperation::Min, {"Min", "Minimum"}},
    {SensorOperation::Count, {"Count"}},
    {SensorOperation::Average, {"Average", "Averages", "Mean"}},
    {SensorOperation::STDEV, {"STDEV", "Standard Deviation"}},
};
inline const std::vector<EnumName<SensorOperation>> kParticleSensorOperations = {
    {SensorOperation::Sum, {"Sum", "Add"}},
    {SensorOperation::Max, {"Max", "Maximum"}},
    {SensorOperation::Min, {"Min", "Minimum"}},
    {SensorOperation::Count, {"Count"}},
    {SensorOperation::Average, {"Average", "Mean"}},
    {SensorOperation::STDEV, {"STDEV", "Standard Deviation"}},
    {SensorOperation::Variance, {"Variance"}},
};
inline const std::vector<EnumName<std::string>> kGridSensorAttributes = {
    {"Force", {"Force"}},       {"BoundaryForce", {"BoundaryForce"}}, {"Acceleration", {"Acceleration"}},
    {"Momentum", {"Momentum"}},
    {"Velocity", {"Velocity"}}, {"Mass", {"Mass"}},                 {"Volume", {"Volume"}},
    {"JBar", {"JBar", "J Bar"}},
    // the pore water of CoupledUP bodies (seepage channels)
    {"MassWater", {"MassWater", "masw"}},       {"PorePressure", {"PorePressure", "pore_pressure"}},
};
inline const std::vector<EnumName<std::string>> kGridFieldAttributes = {
    {"Mass", {"Mass"}},       {"Velocity", {"Velocity"}}, {"Momentum", {"Momentum"}}, {"Force", {"Force"}},
    {"BoundaryForce", {"BoundaryForce"}}, {"Volume", {"Volume"}}, {"JBar", {"JBar", "J Bar"}},
    {"MassWater", {"MassWater", "masw"}}, {"PorePressure", {"PorePressure", "pore_pressure"}},
};
inline const std::vector<const char*> kSaveSuffixes = {".bgeo", ".geo", ".csv", ".h5"};

// ---------------------------------------------------------------------------------------------------------------
// Known keys per object (for unknown-key detection and the closest-key suggestion)
// ---------------------------------------------------------------------------------------------------------------

using Keys = std::vector<std::string_view>;
inline const Keys kTopKeys = {"simulation", "bodies",           "models",  "boundaries", "grid-boundaries",
                       "grid-sensors", "particle-sensors", "targets", "meshes", "grid-fields",
                       "Application",  "EventClassification", "type", "subtype"};
/// HydroUQ's wrapper keys at the top level: metadata (Scene::wrapper), in this order.
inline const char* const kWrapperKeys[] = {"Application", "EventClassification", "type", "subtype"};
inline const Keys kSimulationKeys = {"domain",      "default_dx",  "default_dt", "gravity",
                              "time",        "fps",         "frames",     "save_path",
                              "save_suffix", "particles_output_exterior_only",
                              "froude_scaling", "froude_scaling_applied", "info_rate", "checkpoint_every", "precision",
                              "on_failure",  "seed",        "gpuid",
                              // HydroUQ's (ClaymoreUW's loader does not read them; fbar gives each a meaning)
                              "initial_time", "duration", "cfl", "time_integration", "mirror_domain",
                              "use_froude_scaling", "froude_time_ratio", "use_cauchy_scaling", "cauchy_bulk_ratio"};
inline const Keys kBodyKeys = {"gpu",           "model",          "velocity",     "partition_start", "partition_end",
                        "partition",     "output",         "track_particle_id", "output_attribs", "track_attribs",
                        "target_attribs", "material",      "algorithm",    "geometry",        "constitutive",
                        "type",          "name",           "color",         "trackers",       "initial_state"};
inline const Keys kTrackerKeys = {"ids", "attribs"};
inline const Keys kMeshKeys = {"gpu",        "constitutive",  "file",     "file_vertices",     "file_elements",
                               "offset",     "velocity",      "rho",      "youngs_modulus",    "poisson_ratio",
                               "ppc",        "use_FEM",       "use_ASFLIP", "alpha",           "beta_min",
                               "beta_max",   "use_FBAR",      "FBAR_ratio", "FBAR_fused_kernel", "output_attribs",
                               "track_attribs", "track_particle_id"};
inline const Keys kPartitionKeys = {"gpu", "model", "partition_start", "partition_end"};
inline const Keys kOutputKeys = {"output_attribs", "attribs",         "track_attribs",     "target_attribs",
                           "track_particle_id", "exterior_only", "exterior_threshold"};
/// Keys of bodies[].material: the common ones, then every material's parameters (kParameters).
inline Keys material_keys() {
  // material_preset: HydroUQ's label of the form it filled in; poissons_ratio: HydroUQ's spelling of poisson_ratio.
  Keys keys = {"type", "constitutive", "ppc", "CFL", "rho", "material_preset", "poissons_ratio"};
  for_each_material([&](auto m) {
    for (const MaterialParameter& p : decltype(m)::kParameters)
      if (std::find(keys.begin(), keys.end(), std::string_view(p.key)) == keys.end()) keys.push_back(p.key);
  });
  return keys;
}
inline const Keys kMaterialKeys = material_keys();
inline const Keys kAlgorithmKeys = {"type",     "ppc",      "CFL",           "use_ASFLIP",        "ASFLIP_alpha",
                             "ASFLIP_beta_min", "ASFLIP_beta_max", "use_FBAR", "FBAR_psi", "FBAR_fused_kernel", "FBAR_scheme",
                             "use_FEM"};
inline const Keys kGeometryKeys = {"object",   "operation", "span",           "offset",         "radius",
                            "axis",     "rotate",    "fulcrum",        "array",          "spacing",
                            "file",     "padding",   "scaling_factor", "scaling",        "use_froude_scaling",
                            "has_attributes", "input_attribs", "track_particle_id", "bathymetry",
                            "use_custom_bathymetry",
                            // HydroUQ's / ClaymoreUW scenes': switches of array and rotate, a cylinder's length and
                            // long axis; a region some scenes give a Bathymetry body (read by no ClaymoreUW code)
                            "apply_array", "apply_rotation", "length", "long_axis", "domain_start", "domain_end"};
inline const Keys kBoundaryKeys = {"object",   "contact",  "domain_start",   "domain_end",  "time",
                            "friction_static", "friction_dynamic", "velocity", "file", "output_frequency",
                            "output_freq", "array", "spacing",        "bathymetry",  "use_custom_bathymetry",
                            "type",     "name", "angular_velocity", "rotation_center"};
inline const Keys kGridSensorKeys = {"attribute",   "operation",  "direction", "output_frequency", "output_freq",
                              "domain_start", "domain_end", "type",      "name",             "toggle"};
inline const Keys kGridFieldKeys = {"attributes", "output_frequency", "output_freq", "domain_start", "domain_end",
                                     "blocks", "name", "toggle"};
inline const Keys kParticleSensorKeys = {"attribute",    "operation",  "output_frequency", "output_freq",
                                  "domain_start", "domain_end", "type",             "name", "toggle", "direction"};


// ---------------------------------------------------------------------------------------------------------------
// Parse context and object reader
// ---------------------------------------------------------------------------------------------------------------

struct Context {
  const ParseOptions& options;
  std::vector<fs::path> search_dirs;  ///< where relative file names are looked up, in order

  void warn(const std::string& message) const {
    if (options.warnings) options.warnings->push_back(message);
  }
  /// An unknown or unused key: an error, or with allow_unknown_keys a warning (the value is then ignored).
  void reject_key(const std::string& path, const std::string& value, const std::string& expected) const {
    if (!options.allow_unknown_keys) throw SceneError(path, value, expected);
    warn(path + ": ignored (" + expected + ")");
  }

  /// Resolves a file name (the one lookup of every asset: geometry files, motion files). Search order (user guide
  /// §2.9 "Where files are found"): an absolute path as written; else the name as written under each search folder
  /// (--data-dir, $AssetDirPath, the scene's folder, fbar's Data/); else the file's own name in each of those folders
  /// and in their motion/ and geometry/ subfolders (where fbar ships ClaymoreUW's files). A name with folders found
  /// only by its file name is used with a warning. Throws naming every place looked at.
  std::string resolve_file(const rj::Value& v, const std::string& path) const {
    const std::string name = read_string(v, path, "a file path");
    if (name.empty()) throw SceneError(path, json_text(v), "a file path");
    const fs::path p(name);
    std::vector<std::string> tried;
    auto found = [](const fs::path& candidate) {
      std::error_code ec;
      return fs::is_regular_file(candidate, ec);
    };
    auto absolute = [](const fs::path& candidate) {
      std::error_code ec;
      return fs::absolute(candidate, ec).lexically_normal().string();
    };
    if (p.is_absolute()) {
      if (found(p)) return p.lexically_normal().string();
      tried.push_back(p.lexically_normal().string());
    } else {
      for (const auto& dir : search_dirs) {
        const fs::path candidate = dir / p;
        if (found(candidate)) return absolute(candidate);
        tried.push_back(absolute(candidate));
      }
    }
    // ClaymoreUW opens "./" + name from its working folder, so its scenes carry names like "..//x.csv" that only
    // hold there, or a bare name of a file fbar ships in Data/motion/ or Data/geometry/.
    const fs::path base = p.filename();
    if (base.empty()) throw SceneError(path, json_text(v), "an existing file (looked for " + join(tried, ", ") + ")");
    const bool bare = base == p;
    for (const auto& dir : search_dirs)
      for (const fs::path& sub : {fs::path(), fs::path("motion"), fs::path("geometry")}) {
        if (bare && sub.empty()) continue;  // looked at above
        const fs::path candidate = dir / sub / base;
        if (!found(candidate)) continue;
        const std::string at = absolute(candidate);
        if (!bare)
          warn(path + ": \"" + name + "\" is not found as written; using " + at +
               " (the same file name in a data folder)");
        return at;
      }
    tried.push_back(base.string() + (bare ? " in the motion/ and geometry/ subfolders of each of those folders"
                                          : " in each of those folders and their motion/ and geometry/ subfolders"));
    throw SceneError(path, json_text(v), "an existing file (looked for " + join(tried, ", ") + ")");
  }
};

/// Wraps one JSON object: hands out its members by key and reports, at finish(), the keys nobody consumed.
class ObjectReader {
 public:
  ObjectReader(const rj::Value& v, std::string path, const Keys& known, const Context& ctx, const char* what)
      : v_(v), path_(std::move(path)), known_(known), ctx_(ctx), what_(what) {
    if (!v.IsObject()) throw SceneError(path_.empty() ? "(top level)" : path_, json_text(v), std::string("an object (") + what + ")");
    used_.assign(v.MemberCount(), false);
    std::set<std::string> seen;
    for (auto m = v.MemberBegin(); m != v.MemberEnd(); ++m) {
      const std::string key(m->name.GetString(), m->name.GetStringLength());
      if (!seen.insert(key).second)
        throw SceneError(sub(key), json_text(m->value), "each key once per object (" + key + " is given twice)");
    }
  }

  const std::string& path() const { return path_; }
  std::string sub(std::string_view key) const { return sub_path(path_, key); }

  /// The member `key`, marked consumed; nullptr when absent.
  const rj::Value* get(std::string_view key) {
    std::size_t i = 0;
    for (auto m = v_.MemberBegin(); m != v_.MemberEnd(); ++m, ++i)
      if (std::string_view(m->name.GetString(), m->name.GetStringLength()) == key) {
        used_[i] = true;
        return &m->value;
      }
    return nullptr;
  }

  bool has(std::string_view key) const { return v_.HasMember(std::string(key).c_str()); }

  /// One of several alias keys (first is canonical); more than one given is an error.
  struct Found {
    const rj::Value* value = nullptr;
    std::string path;
    explicit operator bool() const { return value != nullptr; }
  };
  Found get_any(std::initializer_list<std::string_view> keys) {
    Found f;
    std::string first_key;
    for (std::string_view k : keys) {
      if (const rj::Value* v = get(k)) {
        if (f) throw SceneError(sub(k), json_text(*v), "either " + first_key + " or " + std::string(k) + ", not both (aliases)");
        f.value = v;
        f.path = sub(k);
        first_key = std::string(k);
      }
    }
    return f;
  }

  /// Throws for a required key that is absent. When an unconsumed unknown key is a likely misspelling of it
  /// ("materials" for "material"), that key is reported instead, with the suggestion.
  [[noreturn]] void missing(std::string_view key, const std::string& expected, const char* unit = "") const {
    std::size_t i = 0;
    for (auto m = v_.MemberBegin(); m != v_.MemberEnd(); ++m, ++i) {
      if (used_[i]) continue;
      const std::string name(m->name.GetString(), m->name.GetStringLength());
      if (std::find(known_.begin(), known_.end(), name) != known_.end()) continue;
      if (closest_key(name, {key}) == key)
        throw SceneError(sub(name), "unknown key " + in_quotes(name),
                         std::string("a key of ") + what_ + " (did you mean " + in_quotes(key) + "?)");
    }
    throw SceneError(sub(key), "(missing)", expected, unit);
  }

  /// Reports unconsumed members: known keys get `why_unused(key)`, unknown keys the closest known key. warn_unused:
  /// a known key this object does not use is a warning (ClaymoreUW ignores it silently), not an error.
  void finish(const std::function<std::string(std::string_view)>& why_unused = {}, bool warn_unused = false) {
    std::size_t i = 0;
    for (auto m = v_.MemberBegin(); m != v_.MemberEnd(); ++m, ++i) {
      if (used_[i]) continue;
      const std::string key(m->name.GetString(), m->name.GetStringLength());
      const bool known = std::find(known_.begin(), known_.end(), key) != known_.end();
      if (known && warn_unused) {
        ctx_.warn(sub(key) + ": " + json_text(m->value) + " is ignored (" +
                  (why_unused ? why_unused(key) : "no " + key + " here") + ")");
      } else if (known) {
        ctx_.reject_key(sub(key), json_text(m->value), why_unused ? why_unused(key) : "no " + key + " here");
      } else {
        std::string expected = std::string("a key of ") + what_;
        const std::string near = closest_key(key, known_);
        if (!near.empty()) expected += " (did you mean " + in_quotes(near) + "?)";
        ctx_.reject_key(sub(key), "unknown key " + in_quotes(key), expected);
      }
    }
  }

 private:
  const rj::Value& v_;
  std::string path_;
  const Keys& known_;
  const Context& ctx_;
  const char* what_;
  std::vector<bool> used_;
};

/// A key given both flat and in a sub-object (or in two sibling objects): read both, they must agree.
template <class T, class Read>
std::optional<T> read_either(ObjectReader& a, ObjectReader* b, std::string_view key, Read read,
                             std::string_view key_b = {}) {
  if (key_b.empty()) key_b = key;
  std::optional<T> va, vb;
  const rj::Value* ja = a.get(key);
  const rj::Value* jb = b ? b->get(key_b) : nullptr;
  if (ja) va = read(*ja, a.sub(key));
  if (jb) vb = read(*jb, b->sub(key_b));
  if (va && vb && !(*va == *vb))
    throw SceneError(b->sub(key_b), json_text(*jb),
                     "the same value as " + a.sub(key) + " (" + json_text(*ja) + "), or only one of the two");
  return va ? va : vb;
}

/// One particle attribute name, canonical (attributes.h); aliases and any letter case accepted.
inline std::string read_attribute(const rj::Value& v, const std::string& path, bool allow_elevation = false) {
  const std::string name = read_string(v, path, "a particle attribute name (a string)");
  std::string canonical = canonical_attribute(name);
  if (canonical.empty()) {  // case-insensitive second chance ("velocity_x")
    for (const auto& n : kParticleAttributeNames)
      if (lower(n) == lower(name)) canonical = std::string(n);
    for (const auto& a : kParticleAttributeAliases)
      if (lower(a.first) == lower(name)) canonical = std::string(a.second);
  }
  // ClaymoreUW's wave gauges (particle-sensors with attribute "Elevation", operation Max) measure Position_Y.
  if (canonical.empty() && allow_elevation && lower(name) == "elevation") canonical = "Position_Y";
  if (canonical.empty()) {
    Keys all(kParticleAttributeNames.begin(), kParticleAttributeNames.end());
    for (const auto& a : kParticleAttributeAliases) all.push_back(a.first);
    std::string expected = "a particle attribute name (user guide §4.2, e.g. ID, Position_X, Velocity_Magnitude, J, Pressure)";
    const std::string near = closest_key(name, all);
    if (!near.empty()) expected += "; did you mean " + in_quotes(near) + "?";
    throw SceneError(path, json_text(v), expected);
  }
  return canonical;
}

/// input_attribs of a File read with has_attributes: names that seed a particle (geometry/particle_seed.h), vectors
/// and tensors whole (a velocity with all three components, F with all nine).
inline void check_seed_attributes(const std::vector<std::string>& names, const std::string& path) {
  int velocity = 0, defgrad = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const int slot = seed_slot(names[i]);
    if (slot == kSeedRefused)
      throw SceneError(index_path(path, i), "\"" + names[i] + "\"",
                       std::string("an attribute that sets a particle's initial state: ") + seed_attribute_names());
    if (slot >= kSeedVelocity && slot < kSeedVelocity + 3) ++velocity;
    if (slot >= kSeedDefGrad && slot < kSeedDefGrad + 9) ++defgrad;
  }
  if (velocity != 0 && velocity != 3)
    throw SceneError(path, std::to_string(velocity) + " of Velocity_X, Velocity_Y, Velocity_Z",
                     "all three velocity components or none (the body's velocity gives the rest)");
  if (defgrad != 0 && defgrad != 9)
    throw SceneError(path, std::to_string(defgrad) + " of DefGrad_XX..DefGrad_ZZ",
                     "all nine components of the deformation gradient or none");
}

inline std::vector<std::string> read_attribute_list(const rj::Value& v, const std::string& path) {
  require_array(v, path, "an array of particle attribute names");
  std::vector<std::string> out;
  for (rj::SizeType i = 0; i < v.Size(); ++i) {
    const std::string ip = index_path(path, i);
    const std::string canonical = read_attribute(v[i], ip);
    if (std::find(out.begin(), out.end(), canonical) != out.end())
      throw SceneError(ip, json_text(v[i]), "each attribute once (" + canonical + " is already listed)");
    out.push_back(canonical);
  }
  return out;
}

/// bodies[].geometry[] and boundaries[] "Bathymetry" breakpoints.
/// A bed profile [[x, y], ...] [m], x strictly increasing.
inline std::vector<std::array<double, 2>> read_bed_points(const rj::Value& x, const std::string& bp) {
  std::vector<std::array<double, 2>> bed;
  require_array(x, bp, "an array of [x, y] points");
  for (rj::SizeType i = 0; i < x.Size(); ++i) {
    const auto pt = read_reals<2>(x[i], index_path(bp, i), kAny, "m");
    if (!bed.empty() && !(pt[0] > bed.back()[0]))
      throw SceneError(index_path(index_path(bp, i), 0), num_text(pt[0]),
                       "a number > the previous point's x (" + num_text(bed.back()[0]) + ")", "m");
    bed.push_back({pt[0], pt[1]});
  }
  return bed;
}

// ---------------------------------------------------------------------------------------------------------------
// The parts of the document read in their own files
// ---------------------------------------------------------------------------------------------------------------

/// One body as read (scene_parse_bodies.cpp), before the document assigns models and resolves tracked IDs.
struct BodyRead {
  BodySpec spec;
  bool model_given = false;
  bool cfl_given = false;  ///< material.CFL or algorithm.CFL (else simulation.cfl applies when given)
  std::string model_path;
};

BodyRead parse_body(const rj::Value& v, const std::string& path, const Context& ctx);
/// boundaries[], grid-sensors[] and particle-sensors[] entries (scene_parse_objects.cpp).
BoundarySpec parse_boundary(const rj::Value& v, const std::string& path, const Context& ctx);
GridSensorSpec parse_grid_sensor(const rj::Value& v, const std::string& path, const Context& ctx);
ParticleSensorSpec parse_particle_sensor(const rj::Value& v, const std::string& path, const Context& ctx,
                                         bool& attribute_given);
GridFieldSpec parse_grid_field(const rj::Value& v, const std::string& path, const Context& ctx);

}  // namespace fbar::scene_json
