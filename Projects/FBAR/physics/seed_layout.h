// The values a seeded particle carries (a point file's attributes, geometry/particle_seed.h), in world units and NaN
// where the file gave nothing: [0, 3) velocity [m/s], [3, 12) deformation gradient (row-major), 12 J, 13 logJp.
// The materials read a seed through these offsets (constitutive_models.cuh material_seeded_state).
#pragma once

namespace fbar {

inline constexpr int kSeedScalars = 14;
inline constexpr int kSeedVelocity = 0;
inline constexpr int kSeedDefGrad = 3;
inline constexpr int kSeedJ = 12;
inline constexpr int kSeedLogJp = 13;

}  // namespace fbar
