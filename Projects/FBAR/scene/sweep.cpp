// Sweep files read and expanded into cases (sweep.h).
#include "scene/sweep.h"

#include <rapidjson/document.h>
#include <rapidjson/stringbuffer.h>
#include <rapidjson/writer.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <string_view>

namespace fbar {

namespace {

namespace fs = std::filesystem;
namespace rj = rapidjson;

constexpr unsigned kParseFlags =
    rj::kParseCommentsFlag | rj::kParseTrailingCommasFlag | rj::kParseNanAndInfFlag | rj::kParseFullPrecisionFlag;

std::string quote_text(std::string_view s) { return "\"" + std::string(s) + "\""; }

std::string json_text(const rj::Value& v) {
  rj::StringBuffer sb;
  rj::Writer<rj::StringBuffer, rj::UTF8<>, rj::UTF8<>, rj::CrtAllocator, rj::kWriteNanAndInfFlag> w(sb);
  v.Accept(w);
  return std::string(sb.GetString(), sb.GetSize());
}

/// What a value is, for messages: its JSON text, cut at 60 characters.
std::string shown(const rj::Value& v) {
  std::string t = json_text(v);
  return t.size() > 60 ? t.substr(0, 57) + "..." : t;
}

std::string number_text(double x) {
  rj::Value v(x);
  if (x == std::floor(x) && std::fabs(x) < 9.0e15) v.SetInt64(static_cast<int64_t>(x));
  return json_text(v);
}

std::string number_label(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

rj::Document parse_json(const std::string& text, const std::string& source) {
  rj::Document doc;
  doc.Parse<kParseFlags>(text.c_str(), text.size());
  if (doc.HasParseError())
    throw SceneError(source, "offset " + std::to_string(doc.GetErrorOffset()), "valid JSON");
  return doc;
}

void reject_unknown(const rj::Value& obj, const std::string& where, const std::vector<std::string_view>& known) {
  for (auto m = obj.MemberBegin(); m != obj.MemberEnd(); ++m) {
    const std::string_view key(m->name.GetString(), m->name.GetStringLength());
    if (std::find(known.begin(), known.end(), key) != known.end()) continue;
    std::string expected = "a key of " + (where.empty() ? std::string("a sweep file") : where);
    if (const std::string near = closest_key(key, known); !near.empty()) expected += " (did you mean " + quote_text(near) + "?)";
    throw SceneError(where.empty() ? std::string(key) : where + "." + std::string(key), "unknown key " + quote_text(key),
                     expected);
  }
}

double number_at(const rj::Value& v, const std::string& where, const std::string& expected) {
  if (!v.IsNumber() || !std::isfinite(v.GetDouble())) throw SceneError(where, shown(v), expected);
  return v.GetDouble();
}

/// [lo, hi] of a two-number array.
std::pair<double, double> pair_at(const rj::Value& v, const std::string& where, bool positive_second, bool ordered) {
  const std::string expected = std::string("an array of two numbers ") +
                               (positive_second ? "[mean, standard deviation > 0]" : "[low, high] with low <= high");
  if (!v.IsArray() || v.Size() != 2) throw SceneError(where, shown(v), expected);
  const double a = number_at(v[0], where + "[0]", "a number"), b = number_at(v[1], where + "[1]", "a number");
  if ((positive_second && !(b > 0.0)) || (ordered && !(a <= b))) throw SceneError(where, shown(v), expected);
  return {a, b};
}

/// One step of a path: an object key or an array index.
struct PathStep {
  std::string key;
  long long index = -1;  ///< >= 0: an array index
};

std::vector<PathStep> split_path(const std::string& path, const std::string& where) {
  std::vector<PathStep> steps;
  std::size_t i = 0;
  const std::string expected = "a JSON path into the scene such as \"bodies[0].material.E\" or \"simulation.gravity[1]\"";
  while (i < path.size()) {
    if (path[i] == '[') {
      const std::size_t close = path.find(']', i);
      if (close == std::string::npos || close == i + 1) throw SceneError(where, quote_text(path), expected);
      const std::string digits = path.substr(i + 1, close - i - 1);
      if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9)
        throw SceneError(where, quote_text(path), expected + " (an index is a non-negative integer)");
      steps.push_back({"", std::stoll(digits)});
      i = close + 1;
      if (i < path.size() && path[i] == '.') {
        ++i;
        if (i == path.size()) throw SceneError(where, quote_text(path), expected);
      }
      continue;
    }
    const std::size_t end = path.find_first_of(".[", i);
    const std::string key = path.substr(i, end == std::string::npos ? std::string::npos : end - i);
    if (key.empty()) throw SceneError(where, quote_text(path), expected);
    steps.push_back({key, -1});
    i = end == std::string::npos ? path.size() : end;
    if (i < path.size() && path[i] == '.') {
      ++i;
      if (i == path.size()) throw SceneError(where, quote_text(path), expected);
    }
  }
  if (steps.empty() || steps.front().index >= 0) throw SceneError(where, quote_text(path), expected);
  return steps;
}

/// Writes `value` at `path` in `doc`; the last key may be new. Returns "" or what went wrong.
std::string set_at_path(rj::Document& doc, const std::vector<PathStep>& steps, const rj::Value& value) {
  rj::Value* at = &doc;
  std::string walked;
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const PathStep& step = steps[s];
    const bool last = s + 1 == steps.size();
    if (step.index >= 0) {
      if (!at->IsArray())
        return walked + " is " + (at->IsObject() ? "an object" : "not an array") + ", not an array to index";
      if (step.index >= static_cast<long long>(at->Size()))
        return walked + " has " + std::to_string(at->Size()) + " entries (index " + std::to_string(step.index) +
               " is past its end)";
      at = &(*at)[static_cast<rj::SizeType>(step.index)];
      walked += "[" + std::to_string(step.index) + "]";
    } else {
      if (!at->IsObject()) return (walked.empty() ? std::string("the scene") : walked) + " is not an object";
      const std::string next = walked.empty() ? step.key : walked + "." + step.key;
      auto m = at->FindMember(step.key.c_str());
      if (m == at->MemberEnd()) {
        if (!last) return (walked.empty() ? std::string("the scene") : walked) + " has no key " + quote_text(step.key);
        at->AddMember(rj::Value(step.key.c_str(), doc.GetAllocator()), rj::Value(rj::kNullType), doc.GetAllocator());
        m = at->FindMember(step.key.c_str());
      }
      at = &m->value;
      walked = next;
    }
  }
  at->CopyFrom(value, doc.GetAllocator());
  return "";
}

/// 64-bit generator (splitmix64 seeding xoshiro256**): the same cases from the same seed on every platform, which
/// the standard library's distributions do not promise.
class Random {
 public:
  explicit Random(unsigned long long seed) {
    unsigned long long z = seed;
    for (auto& w : s_) {
      z += 0x9e3779b97f4a7c15ULL;
      unsigned long long x = z;
      x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
      x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
      w = x ^ (x >> 31);
    }
  }
  unsigned long long next() {
    const unsigned long long result = rotl(s_[1] * 5, 7) * 9, t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  ///< [0, 1)
  /// [0, n) without modulo bias.
  unsigned long long below(unsigned long long n) {
    const unsigned long long limit = std::numeric_limits<unsigned long long>::max() -
                                     std::numeric_limits<unsigned long long>::max() % n;
    unsigned long long x;
    do x = next(); while (x >= limit);
    return x % n;
  }

 private:
  static unsigned long long rotl(unsigned long long x, int k) { return (x << k) | (x >> (64 - k)); }
  unsigned long long s_[4];
};

std::string parameter_where(std::size_t p) { return "parameters[" + std::to_string(p) + "]"; }

SweepParameter read_parameter(const rj::Value& v, std::size_t p) {
  const std::string where = parameter_where(p);
  if (!v.IsObject()) throw SceneError(where, shown(v), "an object with \"name\" and \"path\"");
  reject_unknown(v, where, {"name", "path", "values", "labels", "range", "count", "uniform", "log_uniform", "normal",
                            "integer"});
  SweepParameter q;
  auto text = [&](const char* key) {
    const auto m = v.FindMember(key);
    if (m == v.MemberEnd()) throw SceneError(where + "." + key, "nothing", "a string (the key is required)");
    if (!m->value.IsString() || m->value.GetStringLength() == 0)
      throw SceneError(where + "." + key, shown(m->value), "a non-empty string");
    return std::string(m->value.GetString(), m->value.GetStringLength());
  };
  q.name = text("name");
  if (q.name.find_first_of(",\"\n\r") != std::string::npos)
    throw SceneError(where + ".name", quote_text(q.name), "a name without commas, quotes or line breaks (a table column)");
  q.path = text("path");
  split_path(q.path, where + ".path");
  int kinds = 0;
  if (const auto m = v.FindMember("values"); m != v.MemberEnd()) {
    ++kinds;
    q.kind = SweepParameter::Kind::Values;
    if (!m->value.IsArray() || m->value.Empty())
      throw SceneError(where + ".values", shown(m->value), "a non-empty array of the values the parameter takes");
    for (const auto& x : m->value.GetArray()) {
      q.values.push_back(json_text(x));
      q.labels.push_back(x.IsNumber() ? number_label(x.GetDouble())
                         : x.IsString() ? std::string(x.GetString(), x.GetStringLength())
                                        : "choice " + std::to_string(q.labels.size()));
    }
  }
  const std::pair<const char*, SweepParameter::Kind> ranges[] = {{"range", SweepParameter::Kind::Range},
                                                                 {"uniform", SweepParameter::Kind::Uniform},
                                                                 {"log_uniform", SweepParameter::Kind::LogUniform},
                                                                 {"normal", SweepParameter::Kind::Normal}};
  for (const auto& [key, kind] : ranges) {
    const auto m = v.FindMember(key);
    if (m == v.MemberEnd()) continue;
    ++kinds;
    q.kind = kind;
    std::tie(q.a, q.b) = pair_at(m->value, where + "." + key, kind == SweepParameter::Kind::Normal,
                                 kind != SweepParameter::Kind::Normal);
    if (kind == SweepParameter::Kind::LogUniform && !(q.a > 0.0))
      throw SceneError(where + ".log_uniform", shown(m->value), "[low, high] with 0 < low <= high");
  }
  if (kinds > 1)
    throw SceneError(where, "more than one of values, range, uniform, log_uniform and normal", "one of them");
  if (const auto m = v.FindMember("count"); m != v.MemberEnd()) {
    if (q.kind != SweepParameter::Kind::Range)
      throw SceneError(where + ".count", shown(m->value), "no count (count goes with \"range\")");
    if (!m->value.IsInt() || m->value.GetInt() < 1 || m->value.GetInt() > 100000)
      throw SceneError(where + ".count", shown(m->value), "an integer from 1 to 100000");
    q.count = m->value.GetInt();
  } else if (q.kind == SweepParameter::Kind::Range) {
    throw SceneError(where + ".count", "nothing", "the number of values from range[0] to range[1] (an integer >= 1)");
  }
  if (const auto m = v.FindMember("labels"); m != v.MemberEnd()) {
    if (q.kind != SweepParameter::Kind::Values)
      throw SceneError(where + ".labels", shown(m->value), "no labels (labels go with \"values\")");
    if (!m->value.IsArray() || m->value.Size() != q.values.size())
      throw SceneError(where + ".labels", shown(m->value),
                       "an array of " + std::to_string(q.values.size()) + " strings, one per value");
    for (rj::SizeType i = 0; i < m->value.Size(); ++i) {
      const auto& l = m->value[i];
      if (!l.IsString() || l.GetStringLength() == 0)
        throw SceneError(where + ".labels[" + std::to_string(i) + "]", shown(l), "a non-empty string");
      q.labels[i] = std::string(l.GetString(), l.GetStringLength());
    }
  }
  if (const auto m = v.FindMember("integer"); m != v.MemberEnd()) {
    if (!m->value.IsBool()) throw SceneError(where + ".integer", shown(m->value), "true or false");
    q.integer = m->value.GetBool();
  }
  return q;
}

/// A sampled or ranged value as written into the scene.
void put_number(const SweepParameter& q, double x, SweepCase& c) {
  if (q.integer) x = std::round(x);
  c.json.push_back(number_text(x));
  c.labels.push_back(number_label(x));
  c.numbers.push_back(x);
}

void put_choice(const SweepParameter& q, std::size_t k, SweepCase& c) {
  c.json.push_back(q.values[k]);
  c.labels.push_back(q.labels[k]);
  rj::Document d;
  d.Parse<kParseFlags>(q.values[k].c_str());
  c.numbers.push_back(d.IsNumber() ? d.GetDouble() : static_cast<double>(k));
}

/// u in [0, 1) mapped through the parameter's distribution.
void put_sample(const SweepParameter& q, double u, SweepCase& c) {
  switch (q.kind) {
    case SweepParameter::Kind::Values:
      put_choice(q, std::min(q.values.size() - 1, static_cast<std::size_t>(u * static_cast<double>(q.values.size()))), c);
      return;
    case SweepParameter::Kind::Uniform: put_number(q, q.a + u * (q.b - q.a), c); return;
    case SweepParameter::Kind::LogUniform:
      put_number(q, std::exp(std::log(q.a) + u * (std::log(q.b) - std::log(q.a))), c);
      return;
    case SweepParameter::Kind::Normal: {
      // The stratum's u is in [0, 1); 0 would be -infinity: take the smallest positive double's quantile instead.
      const double tiny = std::numeric_limits<double>::min();
      put_number(q, q.a + q.b * normal_quantile(std::clamp(u, tiny, 1.0 - 0x1.0p-53)), c);
      return;
    }
    default: return;
  }
}

void expand_factorial(Sweep& s) {
  std::vector<std::size_t> sizes;
  std::size_t total = 1;
  for (std::size_t p = 0; p < s.parameters.size(); ++p) {
    const SweepParameter& q = s.parameters[p];
    if (q.kind != SweepParameter::Kind::Values && q.kind != SweepParameter::Kind::Range)
      throw SceneError(parameter_where(p), quote_text(q.name),
                       "\"values\" or \"range\" with \"count\" for design \"factorial\" (a distribution is sampled: "
                       "design \"latin_hypercube\")");
    sizes.push_back(q.kind == SweepParameter::Kind::Values ? q.values.size() : static_cast<std::size_t>(q.count));
    total *= sizes.back();
    if (total > 100000) throw SceneError("parameters", std::to_string(total) + "+ cases", "at most 100000 cases");
  }
  for (std::size_t k = 0; k < total; ++k) {
    SweepCase c;
    c.id = static_cast<int>(k);
    // The first parameter varies slowest (case order reads like nested loops in the parameters' order).
    std::size_t rest = k, stride = total;
    for (std::size_t p = 0; p < s.parameters.size(); ++p) {
      const SweepParameter& q = s.parameters[p];
      stride /= sizes[p];
      const std::size_t i = rest / stride;
      rest %= stride;
      if (q.kind == SweepParameter::Kind::Values) put_choice(q, i, c);
      else put_number(q, q.count == 1 ? q.a : q.a + (q.b - q.a) * static_cast<double>(i) / (q.count - 1), c);
    }
    s.cases.push_back(std::move(c));
  }
}

void expand_latin_hypercube(Sweep& s) {
  for (std::size_t p = 0; p < s.parameters.size(); ++p)
    if (s.parameters[p].kind == SweepParameter::Kind::Range || s.parameters[p].kind == SweepParameter::Kind::Given)
      throw SceneError(parameter_where(p), quote_text(s.parameters[p].name),
                       "\"values\", \"uniform\", \"log_uniform\" or \"normal\" for design \"latin_hypercube\"");
  const std::size_t n = static_cast<std::size_t>(s.samples);
  Random random(s.seed);
  // Per parameter: a random permutation of the n strata, and a uniform position inside each.
  std::vector<std::vector<double>> u(s.parameters.size(), std::vector<double>(n));
  for (auto& column : u) {
    std::vector<std::size_t> strata(n);
    for (std::size_t i = 0; i < n; ++i) strata[i] = i;
    for (std::size_t i = n; i > 1; --i) std::swap(strata[i - 1], strata[random.below(i)]);
    for (std::size_t i = 0; i < n; ++i) column[i] = (static_cast<double>(strata[i]) + random.uniform()) / n;
  }
  for (std::size_t k = 0; k < n; ++k) {
    SweepCase c;
    c.id = static_cast<int>(k);
    for (std::size_t p = 0; p < s.parameters.size(); ++p) put_sample(s.parameters[p], u[p][k], c);
    s.cases.push_back(std::move(c));
  }
}

void read_given_cases(Sweep& s, const rj::Value& doc) {
  const auto m = doc.FindMember("cases");
  if (m == doc.MemberEnd() || !m->value.IsArray() || m->value.Empty())
    throw SceneError("cases", m == doc.MemberEnd() ? "nothing" : shown(m->value),
                     "a non-empty array of cases for design \"cases\", each {\"<parameter name>\": value, ...}");
  std::vector<std::string_view> names;
  for (const auto& q : s.parameters) names.emplace_back(q.name);
  for (rj::SizeType k = 0; k < m->value.Size(); ++k) {
    const rj::Value& given = m->value[k];
    const std::string where = "cases[" + std::to_string(k) + "]";
    if (!given.IsObject()) throw SceneError(where, shown(given), "an object naming every parameter's value");
    reject_unknown(given, where, names);
    SweepCase c;
    c.id = static_cast<int>(k);
    for (const auto& q : s.parameters) {
      const auto v = given.FindMember(q.name.c_str());
      if (v == given.MemberEnd()) throw SceneError(where + "." + q.name, "nothing", "the parameter's value");
      c.json.push_back(json_text(v->value));
      // A value that is one of the parameter's listed values takes its label.
      std::string label = v->value.IsNumber() ? number_label(v->value.GetDouble())
                          : v->value.IsString() ? std::string(v->value.GetString(), v->value.GetStringLength())
                                                : shown(v->value);
      double number = v->value.IsNumber() ? v->value.GetDouble() : std::nan("");
      for (std::size_t i = 0; i < q.values.size(); ++i)
        if (q.values[i] == c.json.back()) {
          label = q.labels[i];
          if (!v->value.IsNumber()) number = static_cast<double>(i);
        }
      c.labels.push_back(label);
      c.numbers.push_back(number);
    }
    s.cases.push_back(std::move(c));
  }
}

std::string read_text_file(const fs::path& path, const std::string& where) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(where, quote_text(path.string()), "a readable file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

}  // namespace

double normal_quantile(double u) {
  // Phi(x) = (1 + erf(x / sqrt 2)) / 2. A start from the logistic approximation, then Newton steps on
  // Phi(x) - u = 0 (derivative phi(x) = exp(-x^2 / 2) / sqrt(2 pi)), which converge quadratically for 0 < u < 1.
  if (!(u > 0.0 && u < 1.0)) return u <= 0.0 ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  double x = -std::log(1.0 / u - 1.0) / 1.702;
  for (int i = 0; i < 60; ++i) {
    // In the lower tail use erfc for accuracy: Phi(x) = erfc(-x / sqrt 2) / 2.
    const double phi_cdf = 0.5 * std::erfc(-x / std::sqrt(2.0));
    const double pdf = std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI);
    if (pdf == 0.0) break;
    const double step = (phi_cdf - u) / pdf;
    x -= std::clamp(step, -1.0, 1.0);
    if (std::fabs(step) < 1e-15 * std::max(1.0, std::fabs(x))) break;
  }
  return x;
}

std::string sweep_case_folder(int id) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "case_%04d", id);
  return buf;
}

std::string sweep_case_label(const Sweep& sweep, const SweepCase& c) {
  std::string s;
  for (std::size_t p = 0; p < sweep.parameters.size(); ++p)
    s += (p ? ", " : "") + sweep.parameters[p].name + "=" + c.labels[p];
  return s;
}

std::string sweep_case_scene_json(const Sweep& sweep, const SweepCase& c, const std::string& save_path) {
  rj::Document doc = parse_json(sweep.scene_json, sweep.scene_file.empty() ? sweep.source + ": scene" : sweep.scene_file);
  const std::string who = "sweep case " + std::to_string(c.id) + " (" + sweep_case_label(sweep, c) + ")";
  for (std::size_t p = 0; p < sweep.parameters.size(); ++p) {
    const SweepParameter& q = sweep.parameters[p];
    rj::Document value;
    value.Parse<kParseFlags>(c.json[p].c_str());
    const std::string why = set_at_path(doc, split_path(q.path, parameter_where(p) + ".path"), value);
    if (!why.empty())
      throw SceneError(sweep.source + ": " + parameter_where(p) + ".path", quote_text(q.path),
                       "a path that leads through the scene (" + who + ": " + why + ")");
  }
  rj::Value save(save_path.c_str(), doc.GetAllocator());
  if (!doc.HasMember("simulation")) doc.AddMember("simulation", rj::Value(rj::kObjectType), doc.GetAllocator());
  rj::Value& sim = doc["simulation"];
  if (!sim.IsObject()) throw SceneError(sweep.source + ": scene.simulation", shown(sim), "an object");
  if (sim.HasMember("save_path")) sim["save_path"] = save;
  else sim.AddMember("save_path", save, doc.GetAllocator());
  return indent_json(json_text(doc));
}

Scene sweep_case_scene(const Sweep& sweep, const SweepCase& c, const std::string& save_path,
                       const ParseOptions& options) {
  const std::string text = sweep_case_scene_json(sweep, c, save_path);
  ParseOptions mine = options;
  mine.scene_dir = sweep.scene_dir;
  try {
    return parse_scene_string(text, mine);
  } catch (const SceneError& e) {
    throw SceneError("sweep case " + std::to_string(c.id) + " (" + sweep_case_label(sweep, c) + "): " + e.path(),
                     e.value(), e.expected(), e.unit());
  }
}

Sweep parse_sweep_string(const std::string& json, const std::string& dir, const std::string& source) {
  rj::Document doc = parse_json(json, source);
  if (!doc.IsObject()) throw SceneError(source, shown(doc), "a sweep: an object with \"scene\" and \"parameters\"");
  reject_unknown(doc, "", {"scene", "output", "design", "samples", "seed", "parameters", "cases"});
  Sweep s;
  s.source = source;
  const fs::path base = dir.empty() ? fs::current_path() : fs::path(dir);
  const auto scene = doc.FindMember("scene");
  if (scene == doc.MemberEnd()) throw SceneError("scene", "nothing", "the base scene: a file name or a scene object");
  if (scene->value.IsString()) {
    const fs::path file = base / scene->value.GetString();
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) throw SceneError("scene", quote_text(file.string()), "an existing scene file");
    s.scene_file = file.string();
    s.scene_json = read_text_file(file, "scene");
    s.scene_dir = fs::absolute(file, ec).parent_path().string();
  } else if (scene->value.IsObject()) {
    s.scene_json = json_text(scene->value);
    s.scene_dir = fs::absolute(base).string();
  } else {
    throw SceneError("scene", shown(scene->value), "a scene file name or a scene object");
  }
  if (const auto m = doc.FindMember("output"); m != doc.MemberEnd()) {
    if (!m->value.IsString() || m->value.GetStringLength() == 0)
      throw SceneError("output", shown(m->value), "a folder name");
    s.output = (base / m->value.GetString()).lexically_normal().string();
  } else {
    std::string stem = fs::path(source).filename().string();
    if (stem.size() > 5 && stem.substr(stem.size() - 5) == ".json") stem.resize(stem.size() - 5);
    s.output = (base / (stem.empty() || source == "(sweep)" ? std::string("sweep") : stem)).string();
  }
  if (const auto m = doc.FindMember("design"); m != doc.MemberEnd()) {
    const std::string d = m->value.IsString() ? m->value.GetString() : "";
    if (d == "factorial") s.design = SweepDesign::Factorial;
    else if (d == "cases") s.design = SweepDesign::Cases;
    else if (d == "latin_hypercube") s.design = SweepDesign::LatinHypercube;
    else throw SceneError("design", shown(m->value), "\"factorial\", \"cases\" or \"latin_hypercube\"");
  }
  const auto samples = doc.FindMember("samples");
  const auto seed = doc.FindMember("seed");
  if (s.design == SweepDesign::LatinHypercube) {
    if (samples == doc.MemberEnd() || !samples->value.IsInt() || samples->value.GetInt() < 1 ||
        samples->value.GetInt() > 100000)
      throw SceneError("samples", samples == doc.MemberEnd() ? "nothing" : shown(samples->value),
                       "the number of cases, an integer from 1 to 100000");
    s.samples = samples->value.GetInt();
    if (seed != doc.MemberEnd()) {
      if (!seed->value.IsUint64()) throw SceneError("seed", shown(seed->value), "a non-negative integer");
      s.seed = seed->value.GetUint64();
    }
  } else {
    if (samples != doc.MemberEnd())
      throw SceneError("samples", shown(samples->value), "no samples (they go with design \"latin_hypercube\")");
    if (seed != doc.MemberEnd())
      throw SceneError("seed", shown(seed->value), "no seed (it goes with design \"latin_hypercube\")");
  }
  const auto params = doc.FindMember("parameters");
  if (params == doc.MemberEnd() || !params->value.IsArray() || params->value.Empty())
    throw SceneError("parameters", params == doc.MemberEnd() ? "nothing" : shown(params->value),
                     "a non-empty array of parameters, each {\"name\", \"path\", values}");
  std::set<std::string> names, paths;
  for (rj::SizeType p = 0; p < params->value.Size(); ++p) {
    SweepParameter q = read_parameter(params->value[p], p);
    if (!names.insert(q.name).second)
      throw SceneError(parameter_where(p) + ".name", quote_text(q.name), "a name no other parameter has");
    if (!paths.insert(q.path).second)
      throw SceneError(parameter_where(p) + ".path", quote_text(q.path), "a path no other parameter has");
    s.parameters.push_back(std::move(q));
  }
  if (s.design != SweepDesign::Cases && doc.HasMember("cases"))
    throw SceneError("cases", shown(doc["cases"]), "no cases (they go with design \"cases\")");
  switch (s.design) {
    case SweepDesign::Factorial: expand_factorial(s); break;
    case SweepDesign::LatinHypercube: expand_latin_hypercube(s); break;
    case SweepDesign::Cases: read_given_cases(s, doc); break;
  }
  // Every case's paths lead through the scene (sweep_case_scene_json throws naming the case and parameter).
  for (const SweepCase& c : s.cases) (void)sweep_case_scene_json(s, c, "./");
  return s;
}

Sweep parse_sweep_file(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw SceneError("--sweep", quote_text(path), "an existing sweep file");
  const std::string text = read_text_file(path, "--sweep");
  try {
    return parse_sweep_string(text, fs::absolute(path, ec).parent_path().string(), path);
  } catch (const SceneError& e) {
    if (e.path().rfind(path, 0) == 0) throw;
    throw SceneError(path + ": " + e.path(), e.value(), e.expected(), e.unit());
  }
}

}  // namespace fbar
