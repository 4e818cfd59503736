// Particle attribute names (output_attribs, track_attribs, target_attribs, particle-sensors).
//
// The canonical names are those of docs/user_guide.md §4.2; aliases map onto them. Which attributes a body can
// produce depends on its material and on the engine: see attribute_supported().
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <utility>

namespace fbar {

inline constexpr std::array<std::string_view, 92> kParticleAttributeNames = {
    "ID",
    "Mass",
    "Volume",
    "Position_X",
    "Position_Y",
    "Position_Z",
    "Velocity_X",
    "Velocity_Y",
    "Velocity_Z",
    "Velocity_Magnitude",
    "DefGrad_XX",
    "DefGrad_XY",
    "DefGrad_XZ",
    "DefGrad_YX",
    "DefGrad_YY",
    "DefGrad_YZ",
    "DefGrad_ZX",
    "DefGrad_ZY",
    "DefGrad_ZZ",
    "J",
    "JBar",
    "StressCauchy_XX",
    "StressCauchy_XY",
    "StressCauchy_XZ",
    "StressCauchy_YX",
    "StressCauchy_YY",
    "StressCauchy_YZ",
    "StressCauchy_ZX",
    "StressCauchy_ZY",
    "StressCauchy_ZZ",
    "Pressure",
    "VonMisesStress",
    "DefGrad_Invariant1",
    "DefGrad_Invariant2",
    "DefGrad_Invariant3",
    "DefGrad_1",
    "DefGrad_2",
    "DefGrad_3",
    "StressCauchy_Invariant1",
    "StressCauchy_Invariant2",
    "StressCauchy_Invariant3",
    "StressCauchy_1",
    "StressCauchy_2",
    "StressCauchy_3",
    "StressPK1_XX",
    "StressPK1_XY",
    "StressPK1_XZ",
    "StressPK1_YX",
    "StressPK1_YY",
    "StressPK1_YZ",
    "StressPK1_ZX",
    "StressPK1_ZY",
    "StressPK1_ZZ",
    "StressPK1_Invariant1",
    "StressPK1_Invariant2",
    "StressPK1_Invariant3",
    "StressPK1_1",
    "StressPK1_2",
    "StressPK1_3",
    "StressPK2_XX",
    "StressPK2_XY",
    "StressPK2_XZ",
    "StressPK2_YX",
    "StressPK2_YY",
    "StressPK2_YZ",
    "StressPK2_ZX",
    "StressPK2_ZY",
    "StressPK2_ZZ",
    "StressPK2_Invariant1",
    "StressPK2_Invariant2",
    "StressPK2_Invariant3",
    "StressPK2_1",
    "StressPK2_2",
    "StressPK2_3",
    "StrainSmall_XX",
    "StrainSmall_XY",
    "StrainSmall_XZ",
    "StrainSmall_YX",
    "StrainSmall_YY",
    "StrainSmall_YZ",
    "StrainSmall_ZX",
    "StrainSmall_ZY",
    "StrainSmall_ZZ",
    "StrainSmall_Invariant1",
    "StrainSmall_Invariant2",
    "StrainSmall_Invariant3",
    "StrainSmall_1",
    "StrainSmall_2",
    "StrainSmall_3",
    "VonMisesStrain",
    "PorePressure",
    "logJp",
};

/// Alias -> canonical name.
inline constexpr std::array<std::pair<std::string_view, std::string_view>, 4> kParticleAttributeAliases = {{
    {"DefGrad_Determinant", "J"},
    {"DefGrad_Determinant_FBAR", "JBar"},
    {"Dilation", "StrainSmall_Invariant1"},
    {"StrainSmall_Determinant", "StrainSmall_Invariant3"},
}};

/// Canonical name of an attribute or alias; empty when the name is unknown.
inline std::string canonical_attribute(std::string_view name) {
  for (const auto& a : kParticleAttributeAliases)
    if (a.first == name) return std::string(a.second);
  for (const auto& n : kParticleAttributeNames)
    if (n == name) return std::string(n);
  return {};
}

}  // namespace fbar
