// What the parts of the CPU engine share (engine/cpu/cpu_engine*.cpp only): block and arena arithmetic, the
// parallel thresholds, and small helpers.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <type_traits>

#include "MnBase/Math/vec.h"
#include "physics/constitutive_models.cuh"
#include "settings.h"

namespace fbar::cpu_detail {

constexpr int kBlockSide = settings::kBlockSide;
static_assert(kBlockSide == 4, "the block packing below assumes 4x4x4 blocks");
/// A particle block's stencils span nodes 0..5 (base 0..3 inside the block, + 0..2) along each axis.
constexpr int kArenaSide = kBlockSide + 2;
constexpr int kArenaNodes = kArenaSide * kArenaSide * kArenaSide;

/// Below these sizes a loop runs on one thread: a parallel region costs microseconds (far more when the cores are
/// shared), more than a few blocks of work.
constexpr int kMinParallelParticles = 4096;
constexpr int kMinParallelBlocks = 4;

constexpr int arena_index(int a, int b, int c) { return (a * kArenaSide + b) * kArenaSide + c; }
constexpr int block_node(int i, int j, int k) { return (i * kBlockSide + j) * kBlockSide + k; }
/// Which of the 2x2x2 grid blocks of a particle block an arena node (a, b, c) falls in, and where.
constexpr int arena_neighbour(int a, int b, int c) { return ((a >> 2) * 2 + (b >> 2)) * 2 + (c >> 2); }
constexpr int arena_node_in_block(int a, int b, int c) { return block_node(a & 3, b & 3, c & 3); }

/// Floor division by 4 (arithmetic shift: defined for negatives by every compiler fbar supports, and by C++20).
inline int block_of_node(int node) { return node >> 2; }
inline Vec3i block_of_node(const Vec3i& node) {
  return Vec3i{{block_of_node(node[0]), block_of_node(node[1]), block_of_node(node[2])}};
}

/// 21 bits per axis, offset by 2^20: block coordinates in [-2^20, 2^20) (4 million cells each way).
constexpr int kKeyBias = 1 << 20;
inline std::uint64_t pack_block(const Vec3i& b) {
  return (static_cast<std::uint64_t>(b[0] + kKeyBias) << 42) | (static_cast<std::uint64_t>(b[1] + kKeyBias) << 21) |
         static_cast<std::uint64_t>(b[2] + kKeyBias);
}
/// Parity colour 0..7: blocks of one colour are >= 2 blocks apart along some axis, so their 2x2x2 footprints are
/// disjoint.
inline int colour_of(const Vec3i& b) { return (b[0] & 1) | ((b[1] & 1) << 1) | ((b[2] & 1) << 2); }

/// Every scalar of a trivially copyable state made of T is finite.
template <typename T, typename S>
bool state_is_finite(const S& s) {
  static_assert(std::is_trivially_copyable_v<S> && sizeof(S) % sizeof(T) == 0, "state must be made of T");
  T values[sizeof(S) / sizeof(T)];
  std::memcpy(values, &s, sizeof(S));
  for (const T v : values)
    if (!std::isfinite(v)) return false;
  return true;
}

inline std::string format_g(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace fbar::cpu_detail
