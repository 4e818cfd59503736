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
#include "scene/scene_parse.h"

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

namespace fbar {

namespace rj = rapidjson;
namespace fs = std::filesystem;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------------------------
// Text helpers
// ---------------------------------------------------------------------------------------------------------------

/// Compact JSON text of a value, shortened for messages.
std::string writer_text(const rj::Value& v) {
  rj::StringBuffer sb;
  rj::Writer<rj::StringBuffer, rj::UTF8<>, rj::UTF8<>, rj::CrtAllocator, rj::kWriteNanAndInfFlag> w(sb);
  v.Accept(w);
  std::string s = sb.GetString();
  if (s.size() > 80) s = s.substr(0, 77) + "...";
  return s;
}

/// A number for messages: integers without ".0" (1e6 -> 1000000), others in shortest round-trip form.
std::string num_text(double x) {
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  if (x == std::floor(x) && std::fabs(x) < 1e15) {
    std::ostringstream os;
    os << static_cast<long long>(x);
    return os.str();
  }
  return writer_text(rj::Value(x));
}

/// A JSON value as the user wrote it (up to number spelling), for the "got ..." part of messages.
std::string json_text(const rj::Value& v) {
  if (v.IsNumber() && !v.IsInt64()) return num_text(v.GetDouble());
  return writer_text(v);
}

std::string in_quotes(std::string_view s) { return "\"" + std::string(s) + "\""; }

std::string lower(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

/// Enum matching key: lower case without spaces, '_' and '-' ("Drucker-Prager" == "drucker_prager").
std::string fold(std::string_view s) {
  std::string r;
  for (char c : s)
    if (c != ' ' && c != '_' && c != '-') r += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

std::string join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string r;
  for (std::size_t i = 0; i < items.size(); ++i) r += (i ? sep : "") + items[i];
  return r;
}

std::string sub_path(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}
std::string index_path(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

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
const Range kAny{};
const Range kPositive{0.0, kInf, true, false};
const Range kNonNegative{0.0, kInf, false, false};
const Range kUnit{0.0, 1.0, false, false};
Range at_least(double lo) { return Range{lo, kInf, false, false}; }

/// "an array of 3 numbers" or "an array of 3 numbers, each > 0".
std::string each(const Range& r, const std::string& noun) {
  const std::string bound = r.describe("");
  return bound.empty() ? noun : noun + ", each" + bound;
}

double read_number(const rj::Value& v, const std::string& path, const Range& r, const char* unit,
                   bool allow_inf = false) {
  if (!v.IsNumber()) throw SceneError(path, json_text(v), r.describe("a number"), unit);
  const double x = v.GetDouble();
  if (std::isnan(x) || (std::isinf(x) && !allow_inf)) throw SceneError(path, json_text(v), r.describe("a finite number"), unit);
  if (!r.contains(x)) throw SceneError(path, json_text(v), r.describe("a number"), unit);
  return x;
}

long long read_integer(const rj::Value& v, const std::string& path, const Range& r, const char* unit = "") {
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

int read_int(const rj::Value& v, const std::string& path, const Range& r, const char* unit = "") {
  const long long x = read_integer(v, path, r, unit);
  if (x < std::numeric_limits<int>::min() || x > std::numeric_limits<int>::max())
    throw SceneError(path, json_text(v), "an integer in [-2147483648, 2147483647]", unit);
  return static_cast<int>(x);
}

bool read_bool(const rj::Value& v, const std::string& path) {
  if (!v.IsBool()) throw SceneError(path, json_text(v), "true or false");
  return v.GetBool();
}

std::string read_string(const rj::Value& v, const std::string& path, const char* what = "a string") {
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
Real3 read_real3(const rj::Value& v, const std::string& path, const Range& r, const char* unit, bool allow_inf = false) {
  return read_reals<3>(v, path, r, unit, allow_inf);
}

Int3 read_int3(const rj::Value& v, const std::string& path, const Range& r) {
  if (!v.IsArray() || v.Size() != 3) throw SceneError(path, json_text(v), each(r, "an array of 3 integers"));
  Int3 out{};
  for (rj::SizeType i = 0; i < 3; ++i) out[i] = read_int(v[i], index_path(path, i), r);
  return out;
}

std::vector<long long> read_integer_array(const rj::Value& v, const std::string& path, const Range& r) {
  if (!v.IsArray()) throw SceneError(path, json_text(v), each(r, "an array of integers"));
  std::vector<long long> out;
  for (rj::SizeType i = 0; i < v.Size(); ++i) out.push_back(read_integer(v[i], index_path(path, i), r));
  return out;
}

const rj::Value& require_array(const rj::Value& v, const std::string& path, const char* what) {
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
std::vector<EnumName<Constitutive>> material_names() {
  std::vector<EnumName<Constitutive>> laws;
  for_each_material([&](auto m) {
    using M = decltype(m);
    EnumName<Constitutive> e{M::kLaw, {M::kJsonName}};
    for_each_material_alias<M>([&](const char* a) { e.names.push_back(a); });
    laws.push_back(std::move(e));
  });
  return laws;
}
const std::vector<EnumName<Constitutive>> kLaws = material_names();
const std::vector<EnumName<Precision>> kPrecisions = {
    {Precision::Single, {"single"}}, {Precision::Double, {"double"}}, {Precision::Mixed, {"mixed"}}};
const std::vector<EnumName<OnFailure>> kOnFailure = {{OnFailure::Stop, {"stop"}},
                                                     {OnFailure::ReduceDt, {"reduce_dt"}}};
const std::vector<EnumName<InitialState>> kInitialStates = {{InitialState::Rest, {"rest"}},
                                                            {InitialState::Hydrostatic, {"hydrostatic"}}};
const std::vector<EnumName<GeometryObject>> kGeometryObjects = {{GeometryObject::Box, {"Box", "Cube"}},
                                                                {GeometryObject::Sphere, {"Sphere", "Ball"}},
                                                                {GeometryObject::Cylinder, {"Cylinder"}},
                                                                {GeometryObject::File, {"File"}},
                                                                {GeometryObject::Bathymetry, {"Bathymetry"}},
                                                                {GeometryObject::OsuLwf, {"OSU LWF", "OSU_LWF_WATER"}},
                                                                {GeometryObject::OsuTwb, {"OSU TWB", "OSU_TWB_WATER"}}};
const std::vector<EnumName<GeometryOperation>> kGeometryOperations = {
    {GeometryOperation::Add, {"Add"}},
    {GeometryOperation::Subtract, {"Subtract"}},
    {GeometryOperation::Union, {"Union"}},
    {GeometryOperation::Intersection, {"Intersection", "Intersect"}},
    {GeometryOperation::Difference, {"Difference"}}};
const std::vector<EnumName<int>> kAxes = {{0, {"X"}}, {1, {"Y"}}, {2, {"Z"}}};
const std::vector<EnumName<BoundaryObject>> kBoundaryObjects = {
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
const std::vector<EnumName<Contact>> kContacts = {
    {Contact::Sticky, {"Sticky", "Stick", "Rigid", "No-Slip", "Fixed", "Fix"}},
    {Contact::Slip, {"Slip", "Roller"}},
    {Contact::Separable, {"Separable", "Seperable", "Separate", "Separatable"}},
};
const std::vector<EnumName<SensorOperation>> kGridSensorOperations = {
    {SensorOperation::Sum, {"Sum", "Add", "Addition"}},
    {SensorOperation::Max, {"Max", "Maximum"}},
    {SensorOperation::Min, {"Min", "Minimum"}},
    {SensorOperation::Count, {"Count"}},
    {SensorOperation::Average, {"Average", "Averages", "Mean"}},
    {SensorOperation::STDEV, {"STDEV", "Standard Deviation"}},
};
const std::vector<EnumName<SensorOperation>> kParticleSensorOperations = {
    {SensorOperation::Sum, {"Sum", "Add"}},
    {SensorOperation::Max, {"Max", "Maximum"}},
    {SensorOperation::Min, {"Min", "Minimum"}},
    {SensorOperation::Count, {"Count"}},
    {SensorOperation::Average, {"Average", "Mean"}},
    {SensorOperation::STDEV, {"STDEV", "Standard Deviation"}},
    {SensorOperation::Variance, {"Variance"}},
};
const std::vector<EnumName<std::string>> kGridSensorAttributes = {
    {"Force", {"Force"}},       {"BoundaryForce", {"BoundaryForce"}}, {"Acceleration", {"Acceleration"}},
    {"Momentum", {"Momentum"}},
    {"Velocity", {"Velocity"}}, {"Mass", {"Mass"}},                 {"Volume", {"Volume"}},
    {"JBar", {"JBar", "J Bar"}},
    // ClaymoreUW's CoupledUP grid channels (refused: scene_support.cpp)
    {"MassWater", {"MassWater", "masw"}},       {"PorePressure", {"PorePressure", "pore_pressure"}},
};
const std::vector<const char*> kSaveSuffixes = {".bgeo", ".geo", ".csv", ".h5"};

// ---------------------------------------------------------------------------------------------------------------
// Known keys per object (for unknown-key detection and the closest-key suggestion)
// ---------------------------------------------------------------------------------------------------------------

using Keys = std::vector<std::string_view>;
const Keys kTopKeys = {"simulation", "bodies",           "models",  "boundaries", "grid-boundaries",
                       "grid-sensors", "particle-sensors", "targets", "meshes",
                       "Application",  "EventClassification", "type", "subtype"};
/// HydroUQ's wrapper keys at the top level: metadata (Scene::wrapper), in this order.
const char* const kWrapperKeys[] = {"Application", "EventClassification", "type", "subtype"};
const Keys kSimulationKeys = {"domain",      "default_dx",  "default_dt", "gravity",
                              "time",        "fps",         "frames",     "save_path",
                              "save_suffix", "particles_output_exterior_only",
                              "froude_scaling", "froude_scaling_applied", "info_rate", "checkpoint_every", "precision",
                              "on_failure",  "seed",        "gpuid",
                              // HydroUQ's (ClaymoreUW's loader does not read them; fbar gives each a meaning)
                              "initial_time", "duration", "cfl", "time_integration", "mirror_domain",
                              "use_froude_scaling", "froude_time_ratio", "use_cauchy_scaling", "cauchy_bulk_ratio"};
const Keys kBodyKeys = {"gpu",           "model",          "velocity",     "partition_start", "partition_end",
                        "partition",     "output",         "track_particle_id", "output_attribs", "track_attribs",
                        "target_attribs", "material",      "algorithm",    "geometry",        "constitutive",
                        "type",          "name",           "color",         "trackers",       "initial_state"};
const Keys kTrackerKeys = {"ids", "attribs"};
const Keys kPartitionKeys = {"gpu", "model", "partition_start", "partition_end"};
const Keys kOutputKeys = {"output_attribs", "attribs",         "track_attribs",     "target_attribs",
                           "track_particle_id", "exterior_only", "exterior_threshold"};
/// Keys of bodies[].material: the common ones, then every material's parameters (kParameters).
Keys material_keys() {
  // material_preset: HydroUQ's label of the form it filled in; poissons_ratio: HydroUQ's spelling of poisson_ratio.
  // rhow, alpha1, poro, Kf, Ks, Kperm: ClaymoreUW's CoupledUP parameters (that law is refused by name; on another
  // law they are ignored with a warning, as any parameter the law does not read).
  Keys keys = {"type", "constitutive", "ppc", "CFL", "rho", "material_preset", "poissons_ratio",
               "rhow", "alpha1", "poro", "Kf", "Ks", "Kperm"};
  for_each_material([&](auto m) {
    for (const MaterialParameter& p : decltype(m)::kParameters)
      if (std::find(keys.begin(), keys.end(), std::string_view(p.key)) == keys.end()) keys.push_back(p.key);
  });
  return keys;
}
const Keys kMaterialKeys = material_keys();
const Keys kAlgorithmKeys = {"type",     "ppc",      "CFL",           "use_ASFLIP",        "ASFLIP_alpha",
                             "ASFLIP_beta_min", "ASFLIP_beta_max", "use_FBAR", "FBAR_psi", "FBAR_fused_kernel",
                             "use_FEM"};
const Keys kGeometryKeys = {"object",   "operation", "span",           "offset",         "radius",
                            "axis",     "rotate",    "fulcrum",        "array",          "spacing",
                            "file",     "padding",   "scaling_factor", "scaling",        "use_froude_scaling",
                            "has_attributes", "input_attribs", "track_particle_id", "bathymetry",
                            "use_custom_bathymetry",
                            // HydroUQ's / ClaymoreUW scenes': switches of array and rotate, a cylinder's length and
                            // long axis; a region some scenes give a Bathymetry body (read by no ClaymoreUW code)
                            "apply_array", "apply_rotation", "length", "long_axis", "domain_start", "domain_end"};
const Keys kBoundaryKeys = {"object",   "contact",  "domain_start",   "domain_end",  "time",
                            "friction_static", "friction_dynamic", "velocity", "file", "output_frequency",
                            "output_freq", "array", "spacing",        "bathymetry",  "use_custom_bathymetry",
                            "type",     "name"};
const Keys kGridSensorKeys = {"attribute",   "operation",  "direction", "output_frequency", "output_freq",
                              "domain_start", "domain_end", "type",      "name",             "toggle"};
const Keys kParticleSensorKeys = {"attribute",    "operation",  "output_frequency", "output_freq",
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
std::string read_attribute(const rj::Value& v, const std::string& path, bool allow_elevation = false) {
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
void check_seed_attributes(const std::vector<std::string>& names, const std::string& path) {
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

std::vector<std::string> read_attribute_list(const rj::Value& v, const std::string& path) {
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
// bodies[]
// ---------------------------------------------------------------------------------------------------------------

MaterialSpec parse_material(ObjectReader& body, ObjectReader* algorithm, const Context& ctx) {
  MaterialSpec m;
  const rj::Value* v = body.get("material");
  if (!v) body.missing("material", "an object with constitutive and its parameters");
  ObjectReader o(*v, body.sub("material"), kMaterialKeys, ctx, "bodies[].material");

  const auto law = read_either<Constitutive>(o, &body, "constitutive", [](const rj::Value& x, const std::string& p) {
    // ClaymoreUW's coupled u-p soil (its names; "undrained" it parses and then rejects): refused by name.
    if (x.IsString()) {
      const std::string f = fold(x.GetString());
      if (f == "coupledup" || f == "coupled" || f == "up" || f == "undrained")
        throw SceneError(p, json_text(x),
                         "a law this release implements (" + supported_material_names() +
                             "); ClaymoreUW's CoupledUP (saturated soil with pore pressure: rhow, alpha1, poro, Kf, "
                             "Ks, Kperm) is not supported yet in this release");
    }
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
  if (auto* x = o->get("use_FEM")) a.use_fem = read_bool(*x, o->sub("use_FEM"));
  return a;
}

/// A bed profile [[x, y], ...] [m], x strictly increasing.
std::vector<std::array<double, 2>> read_bed_points(const rj::Value& x, const std::string& bp) {
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

struct BodyRead {
  BodySpec spec;
  bool model_given = false;
  bool cfl_given = false;  ///< material.CFL or algorithm.CFL (else simulation.cfl applies when given)
  std::string model_path;
};

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

// ---------------------------------------------------------------------------------------------------------------
// boundaries[], grid-sensors[], particle-sensors[]
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

// ---------------------------------------------------------------------------------------------------------------
// The document
// ---------------------------------------------------------------------------------------------------------------

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

  std::string bodies_path = "bodies";
  const rj::Value* bodies = optional_array(root, {"bodies", "models"}, bodies_path, "a non-empty array of bodies");
  if (!bodies) root.missing("bodies", "a non-empty array of bodies");
  if (bodies->Size() == 0) throw SceneError(bodies_path, "[]", "a non-empty array of bodies");
  std::vector<BodyRead> read;
  for (rj::SizeType i = 0; i < bodies->Size(); ++i) read.push_back(parse_body((*bodies)[i], index_path(bodies_path, i), ctx));
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
  warn_claymoreuw_sensor_frequencies(scene.grid_sensors, "grid-sensors", ctx);
  warn_claymoreuw_sensor_frequencies(scene.particle_sensors, "particle-sensors", ctx);
  // FEM meshes: their keys are defined by a later release; only their presence is recorded (check_supported).
  if (auto* a = optional_array(root, {"meshes"}, path, "an array of mesh objects")) scene.mesh_count = static_cast<int>(a->Size());
  for (const char* k : kWrapperKeys)
    if (auto* v = root.get(k)) scene.wrapper.emplace_back(k, read_string(*v, k, "a string (HydroUQ metadata)"));
  root.finish();

  apply_froude_scaling(scene);
  // ClaymoreUW's default step is dx / 100 (of the scaled dx: the default is a property of the grid).
  if (!sim.default_dt_given) scene.simulation.default_dt = scene.simulation.dx / 100.0;
  resolve_copy_track_ids(scene, ctx);  // samples the bodies that list IDs per array copy (at scale)
  audit_bodies(scene, ctx);
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
  return parse_text(json, "(string)", options, fs::path());
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
