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
#include "scene/attributes.h"
#include "physics/frame_columns.h"
#include "physics/constitutive_models.cuh"
#include "physics/materials/material_common.cuh"
#include "scene/scene.h"

namespace fbar {

/// Row/column of a tensor attribute suffix "XX".."ZZ" after `prefix`; false when the name has no such suffix.
inline bool tensor_component(std::string_view name, std::string_view prefix, int& row, int& col) {
  if (name.size() != prefix.size() + 2 || name.substr(0, prefix.size()) != prefix) return false;
  row = name[prefix.size()] - 'X';
  col = name[prefix.size() + 1] - 'X';
  return row >= 0 && row < 3 && col >= 0 && col < 3;
}

/// What a frame reads of one body: particles in ID order (slot p = particle ID p) unless `id` gives each slot's ID
/// (a rank of a decomposed run holds some particles, in any order). The per-particle arrays that
/// cost work to produce (J, F, Cauchy stress) are asked for only when an attribute needs them, once each.
template <typename T>
struct FrameSource {
  const std::vector<Vec3<T>>* x = nullptr;       ///< [m]
  const std::vector<Vec3<T>>* v = nullptr;       ///< [m/s]
  const std::vector<std::int64_t>* id = nullptr; ///< particle ID of each slot; nullptr: the slot index
  std::function<T(std::size_t)> mass;            ///< [kg] of particle p
  std::function<T(std::size_t)> volume0;         ///< [m^3] reference volume of particle p
  std::function<std::vector<T>()> J;             ///< [-]
  std::function<std::vector<Mat3<T>>()> F;       ///< [-] (materials that store F)
  std::function<std::vector<Mat3<T>>()> sigma;   ///< [Pa] Cauchy stress
  std::function<std::vector<T>()> logJp;         ///< [-] plastic state (materials with kOutputs.log_jp)
};

/// One requested attribute with its file name and unit.
struct FrameAttributeSpec {
  std::string name;
  std::string unit;
  FrameColumn column;
};

/// Which inputs a list of attributes reads.
struct FrameNeeds {
  bool J = false, F = false, sigma = false, logJp = false, velocity = false;
};

/// The column of a tensor attribute "<prefix>XX".."ZZ", "<prefix>Invariant1..3" or "<prefix>1..3".
inline bool tensor_attribute(std::string_view name, std::string_view prefix, int& row, int& col) {
  if (tensor_component(name, prefix, row, col)) return true;
  if (name.substr(0, prefix.size()) != prefix) return false;
  const std::string_view rest = name.substr(prefix.size());
  if (rest.size() == 10 && rest.substr(0, 9) == "Invariant" && rest[9] >= '1' && rest[9] <= '3') {
    row = kTensorInvariant;
    col = rest[9] - '1';
    return true;
  }
  if (rest.size() == 1 && rest[0] >= '1' && rest[0] <= '3') {
    row = kTensorPrincipal;
    col = rest[0] - '1';
    return true;
  }
  return false;
}

/// The column and unit of a canonical attribute name (attributes.h); false for a name frames cannot hold.
inline bool resolve_frame_attribute(const std::string& name, FrameAttributeSpec& a) {
  a.name = name;
  int row = 0, col = 0;
  auto set = [&](FrameQuantity q, const char* unit, int r = 0, int c = 0) {
    a.column = FrameColumn{q, r, c};
    a.unit = unit;
    return true;
  };
  if (name == "ID") return set(FrameQuantity::Id, "");
  if (name == "Mass") return set(FrameQuantity::Mass, "kg");
  if (name == "Volume") return set(FrameQuantity::Volume, "m^3");
  if (name.rfind("Position_", 0) == 0) return set(FrameQuantity::Position, "m", name.back() - 'X');
  if (name == "Velocity_Magnitude") return set(FrameQuantity::VelocityMagnitude, "m/s");
  if (name.rfind("Velocity_", 0) == 0) return set(FrameQuantity::Velocity, "m/s", name.back() - 'X');
  // JBar: both engines' F-bar pulls the particle's J toward its cell's mean every step (transfer.cuh), so the J
  // they store is ClaymoreUW's JBar (without F-bar, J itself).
  if (name == "J" || name == "JBar") return set(FrameQuantity::J, "");
  if (name == "logJp") return set(FrameQuantity::LogJp, "");
  if (name == "Pressure") return set(FrameQuantity::Pressure, "Pa");
  if (name == "VonMisesStress") return set(FrameQuantity::VonMises, "Pa");
  if (name == "VonMisesStrain") return set(FrameQuantity::VonMisesStrain, "");
  if (tensor_attribute(name, "DefGrad_", row, col)) return set(FrameQuantity::DefGrad, "", row, col);
  if (tensor_attribute(name, "StressCauchy_", row, col)) return set(FrameQuantity::Stress, "Pa", row, col);
  if (tensor_attribute(name, "StressPK1_", row, col)) return set(FrameQuantity::StressPK1, "Pa", row, col);
  if (tensor_attribute(name, "StressPK2_", row, col)) return set(FrameQuantity::StressPK2, "Pa", row, col);
  if (tensor_attribute(name, "StrainSmall_", row, col)) return set(FrameQuantity::StrainSmall, "", row, col);
  return false;  // PorePressure: no engine keeps it per particle
}

/// Whether a quantity reads the deformation gradient F (a material that stores F has it).
inline bool frame_quantity_reads_F(FrameQuantity q) {
  return q == FrameQuantity::DefGrad || q == FrameQuantity::StressPK1 || q == FrameQuantity::StressPK2 ||
         q == FrameQuantity::StrainSmall || q == FrameQuantity::VonMisesStrain;
}

/// Whether a body of material `law` has quantity q: the F-derived ones need a law that stores F, logJp a plastic law
/// (frames, particle sensors, trackers and the release policy ask this one function).
inline bool material_has(Constitutive law, FrameQuantity q) {
  MaterialOutputs outputs{false, false};
  visit_material(law, [&](auto m) { outputs = decltype(m)::kOutputs; });
  if (frame_quantity_reads_F(q)) return outputs.deformation_gradient;
  if (q == FrameQuantity::LogJp) return outputs.log_jp;
  return true;
}

/// `spec.output_attribs` resolved in order (canonical names; an alias and its name count once). Throws
/// std::invalid_argument naming bodies[body].output_attribs for a name no engine produces.
inline std::vector<FrameAttributeSpec> frame_attributes(const BodySpec& spec, int body, const std::string& engine) {
  std::vector<FrameAttributeSpec> out;
  for (const std::string& requested : spec.output_attribs) {
    const std::string name = canonical_attribute(requested);
    bool seen = false;
    for (const auto& a : out) seen = seen || a.name == name;
    if (seen) continue;  // listed twice (e.g. an alias and its canonical name)
    FrameAttributeSpec a;
    if (!resolve_frame_attribute(name, a))
      throw std::invalid_argument("bodies[" + std::to_string(body) + "].output_attribs: " + requested +
                                  " is not available on the " + engine);
    out.push_back(a);
  }
  return out;
}

inline FrameNeeds frame_needs(const std::vector<FrameAttributeSpec>& attributes) {
  FrameNeeds n;
  for (const auto& a : attributes) n.sigma = n.sigma || frame_quantity_reads_stress(a.column.quantity);
  for (const auto& a : attributes) switch (a.column.quantity) {
      case FrameQuantity::Volume:
      case FrameQuantity::J: n.J = true; break;
      case FrameQuantity::LogJp: n.logJp = true; break;
      case FrameQuantity::DefGrad:
      case FrameQuantity::StrainSmall:
      case FrameQuantity::VonMisesStrain: n.F = true; break;
      case FrameQuantity::StressPK1:
      case FrameQuantity::StressPK2: n.F = n.J = true; break;
      case FrameQuantity::Velocity:
      case FrameQuantity::VelocityMagnitude: n.velocity = true; break;
      default: break;
    }
  return n;
}

/// Float columns of a body's frame (every attribute but ID, which is the particle's index in ID order).
inline int frame_float_columns(const std::vector<FrameAttributeSpec>& attributes) {
  int n = 0;
  for (const auto& a : attributes) n += a.column.quantity != FrameQuantity::Id;
  return n;
}

/// The frame of `spec.output_attribs` (canonical names; an alias and its name count once). `engine` names the
/// engine in the error for an attribute it cannot produce (the release policy refuses those before a run).
/// The surface-only filter of body `body` (io::ExteriorFilter): on when simulation.particles_output_exterior_only or
/// bodies[].output.exterior_only is true; cubes of one grid block (4 dx); bodies[].output.exterior_threshold
/// particles of the body per block (ClaymoreUW's 128 by default).
inline io::ExteriorFilter exterior_filter(const Scene& scene, int body) {
  const BodySpec& spec = scene.bodies[static_cast<std::size_t>(body)];
  if (!scene.simulation.particles_output_exterior_only && !spec.output_exterior_only) return {};
  return io::ExteriorFilter{4.0 * scene.simulation.dx, spec.exterior_threshold};
}

template <typename T>
io::ParticleFrame build_frame(const BodySpec& spec, int body, const FrameSource<T>& src, const std::string& engine) {
  const std::size_t n = src.x->size();
  io::ParticleFrame f;
  if constexpr (std::is_same_v<T, double>) {
    f.positions = *src.x;
  } else {
    f.positions = std::vector<Vec3f>(src.x->begin(), src.x->end());
  }
  const std::vector<FrameAttributeSpec> attributes = frame_attributes(spec, body, engine);
  const FrameNeeds needs = frame_needs(attributes);
  std::vector<T> J, logJp;
  std::vector<Mat3<T>> F, sigma;
  if (needs.J) J = src.J();
  if (needs.F) F = src.F();
  if (needs.sigma) sigma = src.sigma();
  if (needs.logJp) logJp = src.logJp();
  for (const FrameAttributeSpec& a : attributes) {
    if (a.column.quantity == FrameQuantity::Id) {
      std::vector<std::int32_t> ids(n);
      for (std::size_t p = 0; p < n; ++p) ids[p] = static_cast<std::int32_t>(src.id ? (*src.id)[p] : p);
      f.add(a.name, 1, std::move(ids));
      continue;
    }
    std::vector<float> values(n);
    for (std::size_t p = 0; p < n; ++p) {
      FrameInputs<T> in{};
      in.x = (*src.x)[p];
      if (src.v) in.v = (*src.v)[p];
      in.mass = src.mass(p);
      in.volume0 = src.volume0(p);
      if (needs.J) in.J = J[p];
      if (needs.logJp) in.logJp = logJp[p];
      if (needs.F) in.F = F[p];
      if (needs.sigma) in.sigma = sigma[p];
      values[p] = static_cast<float>(frame_value(a.column, in));
    }
    f.add(a.name, 1, std::move(values), a.unit);
  }
  return f;
}

}  // namespace fbar
