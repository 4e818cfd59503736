// One body's output frame from its particle state, for both engines: attribute names, units and formulas in one place.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnSystem/IO/particle_io.h"
#include "attributes.h"
#include "materials/material_common.cuh"
#include "scene.h"

namespace fbar {

/// Row/column of a tensor attribute suffix "XX".."ZZ" after `prefix`; false when the name has no such suffix.
inline bool tensor_component(std::string_view name, std::string_view prefix, int& row, int& col) {
  if (name.size() != prefix.size() + 2 || name.substr(0, prefix.size()) != prefix) return false;
  row = name[prefix.size()] - 'X';
  col = name[prefix.size() + 1] - 'X';
  return row >= 0 && row < 3 && col >= 0 && col < 3;
}

/// What a frame reads of one body, particles in ID order (slot p = particle ID p). The per-particle arrays that
/// cost work to produce (J, F, Cauchy stress) are asked for only when an attribute needs them, once each.
template <typename T>
struct FrameSource {
  const std::vector<Vec3<T>>* x = nullptr;       ///< [m]
  const std::vector<Vec3<T>>* v = nullptr;       ///< [m/s]
  std::function<T(std::size_t)> mass;            ///< [kg] of particle p
  std::function<T(std::size_t)> volume0;         ///< [m^3] reference volume of particle p
  std::function<std::vector<T>()> J;             ///< [-]
  std::function<std::vector<Mat3<T>>()> F;       ///< [-] (materials that store F)
  std::function<std::vector<Mat3<T>>()> sigma;   ///< [Pa] Cauchy stress
  std::function<std::vector<T>()> logJp;         ///< [-] plastic state (materials with kOutputs.log_jp)
};

/// The frame of `spec.output_attribs` (canonical names; an alias and its name count once). `engine` names the
/// engine in the error for an attribute it cannot produce (the release policy refuses those before a run).
template <typename T>
io::ParticleFrame build_frame(const BodySpec& spec, int body, const FrameSource<T>& src, const std::string& engine) {
  const std::size_t n = src.x->size();
  io::ParticleFrame f;
  if constexpr (std::is_same_v<T, double>) {
    f.positions = *src.x;
  } else {
    f.positions = std::vector<Vec3f>(src.x->begin(), src.x->end());
  }
  std::vector<T> J;
  std::vector<Mat3<T>> F, sigma;
  auto scalar = [&](const std::string& name, const std::string& unit, auto&& value_of) {
    std::vector<float> values(n);
    for (std::size_t p = 0; p < n; ++p) values[p] = static_cast<float>(value_of(p));
    f.add(name, 1, std::move(values), unit);
  };
  for (const std::string& requested : spec.output_attribs) {
    const std::string name = canonical_attribute(requested);
    if (f.find(name)) continue;  // listed twice (e.g. an alias and its canonical name)
    int row = 0, col = 0;
    if (name == "ID") {
      std::vector<std::int32_t> ids(n);
      for (std::size_t p = 0; p < n; ++p) ids[p] = static_cast<std::int32_t>(p);
      f.add(name, 1, std::move(ids));
    } else if (name == "Mass") {
      scalar(name, "kg", src.mass);
    } else if (name == "Volume") {  // current volume V0 J
      if (J.empty()) J = src.J();
      scalar(name, "m^3", [&](std::size_t p) { return src.volume0(p) * J[p]; });
    } else if (name.rfind("Position_", 0) == 0) {
      const int a = name.back() - 'X';
      scalar(name, "m", [&](std::size_t p) { return (*src.x)[p][a]; });
    } else if (name == "Velocity_Magnitude") {
      scalar(name, "m/s", [&](std::size_t p) { return norm((*src.v)[p]); });
    } else if (name.rfind("Velocity_", 0) == 0) {
      const int a = name.back() - 'X';
      scalar(name, "m/s", [&](std::size_t p) { return (*src.v)[p][a]; });
    } else if (name == "J") {
      if (J.empty()) J = src.J();
      scalar(name, "", [&](std::size_t p) { return J[p]; });
    } else if (name == "logJp") {
      const std::vector<T> l = src.logJp();
      scalar(name, "", [&](std::size_t p) { return l[p]; });
    } else if (tensor_component(name, "DefGrad_", row, col)) {
      if (F.empty()) F = src.F();
      scalar(name, "", [&](std::size_t p) { return F[p](row, col); });
    } else if (name == "Pressure" || name == "VonMisesStress" || tensor_component(name, "StressCauchy_", row, col)) {
      if (sigma.empty()) sigma = src.sigma();
      if (name == "Pressure")
        scalar(name, "Pa", [&](std::size_t p) { return mean_pressure(sigma[p]); });
      else if (name == "VonMisesStress")
        scalar(name, "Pa", [&](std::size_t p) { return von_mises_stress(sigma[p]); });
      else
        scalar(name, "Pa", [&](std::size_t p) { return sigma[p](row, col); });
    } else {
      throw std::invalid_argument("bodies[" + std::to_string(body) + "].output_attribs: " + requested +
                                  " is not available on the " + engine);
    }
  }
  return f;
}

}  // namespace fbar
