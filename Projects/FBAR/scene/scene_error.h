// Errors in scene input: every one names the JSON path, the offending value, what was expected and the unit.
#pragma once

#include <stdexcept>
#include <string>

namespace fbar {

/// Thrown for an invalid scene (exit code 1). what() is the full, user-facing message:
///   "<path>: got <value>; expected <expected> [<unit>]"
class SceneError : public std::runtime_error {
 public:
  SceneError(std::string path, std::string value, std::string expected, std::string unit = {})
      : std::runtime_error(format(path, value, expected, unit)),
        path_(std::move(path)), value_(std::move(value)), expected_(std::move(expected)), unit_(std::move(unit)) {}

  const std::string& path() const { return path_; }
  const std::string& value() const { return value_; }
  const std::string& expected() const { return expected_; }
  const std::string& unit() const { return unit_; }

 private:
  static std::string format(const std::string& path, const std::string& value, const std::string& expected,
                            const std::string& unit) {
    std::string s = path + ": got " + value + "; expected " + expected;
    if (!unit.empty()) s += " [" + unit + "]";
    return s;
  }
  std::string path_, value_, expected_, unit_;
};

}  // namespace fbar
