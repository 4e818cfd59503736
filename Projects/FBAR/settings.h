// True compile-time choices of fbar (everything scene-dependent is sized at run time from the scene).
#pragma once

namespace fbar::settings {

/// Grid block side in nodes: 4x4x4 blocks (Claymore's choice; a block is the unit of sparsity and hashing).
inline constexpr int kBlockSide = 4;
inline constexpr int kBlockNodes = kBlockSide * kBlockSide * kBlockSide;

/// Particles per bin: one warp processes one bin (AoSoA layout, 32 lanes).
inline constexpr int kBinSize = 32;

/// Quadratic B-spline support: 3 nodes per axis.
inline constexpr int kSplineSupport = 3;

/// Shared-memory arena side in nodes for the fused G2P2G kernel: 2x2x2 blocks (off-by-2 around the particle block).
inline constexpr int kArenaSide = 2 * kBlockSide;

}  // namespace fbar::settings
