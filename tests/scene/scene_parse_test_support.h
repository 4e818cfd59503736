// What the scene reader's tests share: a body and a scene in JSON text, parsing with the test's options, and the
// message of a scene that must be refused.
#pragma once

#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "scene/scene_parse.h"

namespace fbar::scene_test {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// A body with the given material (JSON object text) and one 0.2 m box; `extra` adds body keys.
inline std::string body(const std::string& material = R"({"constitutive": "JFluid"})", const std::string& extra = "") {
  return R"({"material": )" + material +
         R"(, "geometry": [{"object": "Box", "span": [0.2, 0.2, 0.2], "offset": [0.1, 0.1, 0.1]}])" +
         (extra.empty() ? "" : ", " + extra) + "}";
}
inline std::string scene_with(const std::string& bodies, const std::string& rest = "") {
  return R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05}, "bodies": [)" + bodies + "]" +
         (rest.empty() ? "" : ", " + rest) + "}";
}

inline Scene parse(const std::string& json, bool check = true, std::vector<std::string>* warnings = nullptr,
            bool allow_unknown = false) {
  ParseOptions o;
  o.check_supported = check;
  o.warnings = warnings;
  o.allow_unknown_keys = allow_unknown;
  return parse_scene_string(json, o);
}

/// The SceneError message of parsing `json`; fails the test when it parses.
inline std::string error_of(const std::string& json, bool check = true) {
  try {
    parse(json, check);
  } catch (const SceneError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a SceneError for\n" << json;
  return {};
}

}  // namespace fbar::scene_test
