// Particle state read from a point file (bodies[].geometry[] object File with has_attributes: true): ClaymoreUW's way
// of resuming a body from a frame, matched here by attribute name (ClaymoreUW matches by list position).
//
// A seeded particle carries kSeedScalars values in world units, NaN where the file gave nothing:
//   [0, 3)   velocity [m/s]            Velocity_X/_Y/_Z (NaN: the body's `velocity`)
//   [3, 12)  deformation gradient [-]  DefGrad_XX..ZZ, row-major (all nine or none)
//   12       J [-]                     J, or JBar when J is not listed (F-bar recomputes JBar each step)
//   13       logJp [-]                 logJp (materials that store it: NACC, DruckerPrager)
// ID is accepted and not stored (a body's particles are numbered in sampling order, and a frame fbar writes is in ID
// order, so its IDs come back); Mass and Volume are accepted and not used (a particle's mass and volume follow from
// the body's rho, ppc and default_dx). Every other attribute is refused by the scene checks (seed_slot() < -1).
// The state a seed gives each material: constitutive_models.cuh, material_seeded_state().
#pragma once

#include <cmath>
#include <limits>
#include <string_view>
#include <vector>

#include "physics/seed_layout.h"

namespace fbar {

/// seed_slot() of an attribute that is read and not stored (ID, Mass, Volume).
inline constexpr int kSeedIgnored = -1;
/// seed_slot() of an attribute that cannot seed a particle.
inline constexpr int kSeedRefused = -2;

/// Where a canonical attribute name (scene/attributes.h) goes in a seed, kSeedIgnored or kSeedRefused. JBar maps to
/// kSeedJ (used when J is not listed).
inline int seed_slot(std::string_view name) {
  static constexpr std::string_view kDefGrad[9] = {"DefGrad_XX", "DefGrad_XY", "DefGrad_XZ",
                                                   "DefGrad_YX", "DefGrad_YY", "DefGrad_YZ",
                                                   "DefGrad_ZX", "DefGrad_ZY", "DefGrad_ZZ"};
  if (name == "Velocity_X") return kSeedVelocity;
  if (name == "Velocity_Y") return kSeedVelocity + 1;
  if (name == "Velocity_Z") return kSeedVelocity + 2;
  for (int k = 0; k < 9; ++k)
    if (name == kDefGrad[k]) return kSeedDefGrad + k;
  if (name == "J" || name == "JBar") return kSeedJ;
  if (name == "logJp") return kSeedLogJp;
  if (name == "ID" || name == "Mass" || name == "Volume") return kSeedIgnored;
  return kSeedRefused;
}

/// The attributes that may seed a particle, for error messages.
inline const char* seed_attribute_names() {
  return "Velocity_X, Velocity_Y, Velocity_Z, DefGrad_XX..DefGrad_ZZ (all nine), J, JBar, logJp (and ID, Mass, "
         "Volume, which are read and not used)";
}

/// The seeded particles of one body: its point-file particles, which follow the lattice-sampled ones in ID order.
struct ParticleSeeds {
  long long first = 0;          ///< ID of the first seeded particle
  std::vector<double> values;   ///< kSeedScalars per particle, in ID order (NaN: not given)

  std::size_t size() const { return values.size() / kSeedScalars; }
  bool empty() const { return values.empty(); }
  const double* at(std::size_t i) const { return values.data() + kSeedScalars * i; }
};

inline double seed_unset() { return std::numeric_limits<double>::quiet_NaN(); }

}  // namespace fbar
