// Output attribute names as the physics knows them: which quantity and column a name selects, its unit, and whether
// a material has it. Frames, particle sensors, trackers and the release policy (scene/scene_support.cpp) ask here,
// so that a name means one thing everywhere.
#pragma once

#include <string>
#include <string_view>

#include "physics/constitutive_models.cuh"
#include "physics/frame_columns.h"

namespace fbar {

/// Row/column of a tensor attribute suffix "XX".."ZZ" after `prefix`; false when the name has no such suffix.
inline bool tensor_component(std::string_view name, std::string_view prefix, int& row, int& col) {
  if (name.size() != prefix.size() + 2 || name.substr(0, prefix.size()) != prefix) return false;
  row = name[prefix.size()] - 'X';
  col = name[prefix.size() + 1] - 'X';
  return row >= 0 && row < 3 && col >= 0 && col < 3;
}

/// One requested attribute with its file name and unit.
struct FrameAttributeSpec {
  std::string name;
  std::string unit;
  FrameColumn column;
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
  // JBar: the volume ratio the stress sees, nodal F-bar's JBar (physics/fbar_nodal.cuh); the cell scheme pulls the
  // particle's own J toward its cell's mean (transfer.cuh), and without nodal F-bar JBar is J.
  if (name == "J") return set(FrameQuantity::J, "");
  if (name == "JBar") return set(FrameQuantity::JBar, "");
  if (name == "logJp") return set(FrameQuantity::LogJp, "");
  if (name == "PorePressure") return set(FrameQuantity::PorePressure, "Pa");
  if (name == "Pressure") return set(FrameQuantity::Pressure, "Pa");
  if (name == "VonMisesStress") return set(FrameQuantity::VonMises, "Pa");
  if (name == "VonMisesStrain") return set(FrameQuantity::VonMisesStrain, "");
  if (tensor_attribute(name, "DefGrad_", row, col)) return set(FrameQuantity::DefGrad, "", row, col);
  if (tensor_attribute(name, "StressCauchy_", row, col)) return set(FrameQuantity::Stress, "Pa", row, col);
  if (tensor_attribute(name, "StressPK1_", row, col)) return set(FrameQuantity::StressPK1, "Pa", row, col);
  if (tensor_attribute(name, "StressPK2_", row, col)) return set(FrameQuantity::StressPK2, "Pa", row, col);
  if (tensor_attribute(name, "StrainSmall_", row, col)) return set(FrameQuantity::StrainSmall, "", row, col);
  return false;
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
  if (q == FrameQuantity::PorePressure) return outputs.pore_pressure;
  return true;
}

/// Whether a body of material `law` can output the attribute of canonical name `name` (attributes.h) on either
/// engine: a name frames can hold, of a quantity the law has.
inline bool material_supports_attribute(Constitutive law, std::string_view name) {
  FrameAttributeSpec a;
  return material_index(law) >= 0 && resolve_frame_attribute(std::string(name), a) &&
         material_has(law, a.column.quantity);
}

}  // namespace fbar
