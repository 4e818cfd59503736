// A boundary's motion from a file (ClaymoreUW's wave-maker series): rows "time [s], displacement along x [m],
// velocity along x [m/s]", no header (a first line that is not three numbers is taken as one), at the rate the
// scene gives as output_frequency [Hz]. Host only: the engines evaluate it once per step (RunConstants) and hand the
// moved boundary to apply_boundary().
//
// Froude scaling by a length factor s (simulation.froude_scaling) scales the file as the scene: times and
// velocities by s^0.5, displacements by s. Between rows the displacement and velocity are interpolated linearly;
// before the first row they are the first row's, after the last the last row's (the paddle holds its position).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fbar {

namespace motion_detail {
inline std::string g(double x) {
  std::ostringstream os;
  os << x;
  return os.str();
}
}  // namespace motion_detail

struct MotionPath {
  std::vector<double> t;  ///< [s] strictly increasing
  std::vector<double> d;  ///< [m] displacement along x
  std::vector<double> v;  ///< [m/s] velocity along x

  bool empty() const { return t.empty(); }

  /// Reads `file` (`where`: the JSON path for messages) and scales it by the Froude factor s. `rate` [Hz] is the
  /// scene's output_frequency (already Froude-scaled): the rows must be 1 / rate apart (1 % tolerance), or the
  /// scene and the file disagree on what the file holds. Throws std::invalid_argument naming path, line and value.
  static MotionPath load(const std::string& file, double froude_s, double rate, const std::string& where) {
    std::ifstream in(file);
    if (!in) throw std::invalid_argument(where + ": cannot read the motion file '" + file + "'");
    MotionPath m;
    std::string line;
    int number = 0;
    const double time_scale = std::sqrt(froude_s);
    while (std::getline(in, line)) {
      ++number;
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      std::replace(line.begin(), line.end(), ',', ' ');
      std::istringstream row(line);
      double a = 0, b = 0, c = 0;
      if (!(row >> a >> b >> c)) {
        if (number == 1) continue;  // a header row
        throw std::invalid_argument(where + ": line " + std::to_string(number) + " of '" + file +
                                    "': expected three numbers (time [s], displacement [m], velocity [m/s])");
      }
      a *= time_scale;
      if (!m.t.empty() && !(a > m.t.back()))
        throw std::invalid_argument(where + ": line " + std::to_string(number) + " of '" + file + "': time " +
                                    motion_detail::g(a) + " s is not after the previous row's");
      m.t.push_back(a);
      m.d.push_back(b * froude_s);
      m.v.push_back(c * time_scale);
    }
    if (m.t.size() < 2)
      throw std::invalid_argument(where + ": the motion file '" + file + "' holds fewer than two rows");
    const double spacing = (m.t.back() - m.t.front()) / static_cast<double>(m.t.size() - 1);
    if (rate > 0.0 && std::abs(spacing * rate - 1.0) > 0.01)
      throw std::invalid_argument(where + ": output_frequency " + motion_detail::g(rate) + " Hz, but the rows of '" +
                                  file + "' are " + motion_detail::g(1.0 / spacing) +
                                  " Hz apart (after Froude scaling): give the file's rate");
    return m;
  }

  /// Displacement [m] and velocity [m/s] at motion time tau [s] (linear between rows, held outside them).
  void at(double tau, double& displacement, double& velocity) const {
    if (tau <= t.front()) {
      displacement = d.front();
      velocity = v.front();
      return;
    }
    if (tau >= t.back()) {
      displacement = d.back();
      velocity = v.back();
      return;
    }
    const std::size_t i = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), tau) - t.begin()) - 1;
    const double w = (tau - t[i]) / (t[i + 1] - t[i]);
    displacement = d[i] + w * (d[i + 1] - d[i]);
    velocity = v[i] + w * (v[i + 1] - v[i]);
  }
};

}  // namespace fbar
