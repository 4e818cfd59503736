// The fused G2P2G kernel (Wang et al. 2020): one template for every material, one CUDA block per particle block.
//
// Off-by-2 (the arena a particle block needs). A particle at x has the stencil base node base = floor(x/dx - 0.5)
// (per axis) and touches nodes base .. base + 2 in G2P. The CFL check guarantees a move of at most one cell, so
// the new base' lies in [base - 1, base + 1] and P2G touches nodes base - 1 .. base + 3. A block-aligned arena of
// nodes [4B, 4B + 8) (2x2x2 grid blocks starting at block B) holds all of them iff 4B <= base - 1 and
// base + 3 <= 4B + 7, i.e. base - 1 in [4B, 4B + 3]: B = floor((base - 1) / 4). That is the particle block of the
// particle (partition_domain.h). In the arena the G2P stencil starts at l = base - 4B in [1, 4] and the P2G
// stencil at l' = base' - 4B in [0, 5]; the kernel checks l' and counts a violation (never writes outside).
//
// Per CUDA block (particle block b, 8x8x8-node arena):
//   1. look up the 8 grid blocks of the arena, load their velocities into shared memory (arena_v);
//   2. each warp takes bins of the block: read particles through the layout (fused reorder), G2P (v, C),
//      advection, state update (material advance), checks (NaN/Inf, left domain, CFL), store the particle in
//      layout order, stress (material kirchhoff_stress with the new C), P2G into arena_p with shared atomics,
//      record the particle's next block and rank (hash-table insert deduplicated per warp);
//   3. add arena_p into the next grid with global atomics (nodes no particle touched are skipped).
// The P2G impulse uses the next step's dt (read from the device: compute_next_dt ran before this kernel), so the
// next grid holds exactly what the CPU engine's P2G of the next step computes.
// kInitial: the P2G of the initial state (v = initial velocity, C = 0, no motion): how the driver starts.
#pragma once

#include <cuda_runtime.h>

#include <climits>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "constitutive_models.cuh"
#include "grid_buffer.cuh"
#include "hash_table.cuh"
#include "kernels/kernel_common.cuh"
#include "particle_buffer.cuh"
#include "partition_domain.h"
#include "settings.h"
#include "transfer.cuh"

namespace fbar {

static_assert(settings::kBinSize == 32, "one warp processes one bin: lane = particle");
static_assert(settings::kArenaSide == 8 && settings::kBlockSide == 4, "the arena is 2x2x2 blocks of 4x4x4 nodes");

inline constexpr int kG2P2GThreads = 128;                 ///< 4 warps per particle block
inline constexpr int kArenaSide = settings::kArenaSide;  ///< nodes per axis of the shared arena (2 grid blocks)
inline constexpr int kArenaNodes = kArenaSide * kArenaSide * kArenaSide;
/// Shared-memory stride of one x-plane of the arena: 64 nodes + 4. Unpadded, nodes one x apart are 64 words apart
/// (the same bank), so lanes of one bin in cells that differ only in x hit one bank; +4 shifts each plane by 4
/// banks. Storage per channel: 8 x 68 words.
inline constexpr int kArenaPlane = kArenaSide * kArenaSide + 4;
inline constexpr int kArenaStorage = kArenaSide * kArenaPlane;
/// Scalars written per slot when velocities are recorded: v (3) then C row-major (9).
inline constexpr int kAuxScalars = 12;

template <typename M, typename T>
struct G2P2GParams {
  using Bins = typename ParticleLayout<M, T>::Buffer;
  Bins in;                   ///< particles of this step (storage order)
  Bins out;                  ///< particles of the next step, written in this layout's order
  LayoutView layout;         ///< this step's layout
  int* next_count;           ///< (block) particles per block of the next layout (zeroed before)
  ParticleDest* dest;        ///< (slot) next block and rank of each particle
  BlockHashTableView table;
  typename GridLayout<T>::VelocityBuffer velocity;  ///< grid velocities of this step
  typename GridLayout<T>::Buffer grid_next;         ///< P2G target (zeroed on blocks [0, block count))
  typename GridLayout<T>::Buffer grid_this;         ///< this step's P2G sums: a new block is zeroed here as well
  T* aux;                    ///< (slot, kAuxScalars) v and C, or nullptr
  material_params_t<M, T> material;
  T mass;                    ///< [kg] per particle
  T volume;                  ///< [m^3] reference volume per particle
  Vec3<T> initial_velocity;  ///< [m/s] (kInitial)
  T dt;                      ///< [s] this step
  T dx, inv_dx, d_inv;       ///< [m], [1/m], [1/m^2]
  Vec3<T> domain;            ///< [m]
  const double* dt_next;     ///< [s] impulse dt of the P2G (device, from compute_next_dt)
  StepStats* stats;
  BodyStepStats* body_stats;
  unsigned long long* wave_speed;  ///< (this body) bits of the largest wave speed of the new state
};

namespace g2p2g_detail {

/// One arena node's grid velocity, padded to 4 scalars so G2P reads a node with one 16-byte (float) or two
/// 16-byte (double) shared loads instead of three scalar loads.
template <typename T>
struct alignas(4 * sizeof(T)) ArenaVelocity {
  T x, y, z, pad;
};

/// Shared-memory index of arena node (a, b, c) (x-planes padded, see kArenaPlane).
FBAR_DEVICE FBAR_FORCE_INLINE int arena_index(int a, int b, int c) { return a * kArenaPlane + b * kArenaSide + c; }

/// Zeroes block `index` of a grid buffer (one thread, a new block: rare).
template <typename T>
FBAR_DEVICE void zero_block(const typename GridLayout<T>::Buffer& grid, int index) {
  for (int n = 0; n < 64; ++n) {
    block_val(grid, grid_mass, index, n) = T(0);
    block_val(grid, grid_momentum_x, index, n) = T(0);
    block_val(grid, grid_momentum_y, index, n) = T(0);
    block_val(grid, grid_momentum_z, index, n) = T(0);
  }
}

/// transfer.cuh's for_each_stencil_node with the 27 nodes unrolled: the same weights in the same order
/// (w0 w1, then x w2), so the stencil arrays stay in registers (the rolled loop put them in local memory).
template <typename T, typename F>
FBAR_DEVICE FBAR_FORCE_INLINE void for_each_stencil_node_unrolled(const QuadraticBspline<T>& s, T dx, F&& f) {
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < 3; ++i)
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
    for (int j = 0; j < 3; ++j) {
      const T wij = s.w[0][i] * s.w[1][j];
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
      for (int k = 0; k < 3; ++k) f(i, j, k, wij * s.w[2][k], s.node_offset(i, j, k, dx));
    }
}

template <typename T, int N, typename State>
FBAR_DEVICE FBAR_FORCE_INLINE bool state_finite(const State& state) {
  const T* s = reinterpret_cast<const T*>(&state);
  bool ok = true;
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < N; ++i) ok = ok && isfinite(s[i]);
  return ok;
}

/// Warp-cooperative: every lane with has_key inserts/finds its block once per distinct key (one leader per key),
/// reserves ranks for all lanes sharing it and returns {block, rank}; {-1, -1} for lanes without a key or when the
/// table overflowed. grid_a/grid_b: new blocks are zeroed there. Must be called by all 32 lanes.
template <typename T>
FBAR_DEVICE ParticleDest claim_block_rank(bool has_key, std::uint64_t key, const BlockHashTableView& table,
                                          int* next_count, const typename GridLayout<T>::Buffer& grid_a,
                                          const typename GridLayout<T>::Buffer& grid_b) {
  ParticleDest d{-1, -1};
  const unsigned keyed = __ballot_sync(0xffffffffu, has_key);
  if (has_key) {
    const unsigned peers = __match_any_sync(keyed, static_cast<unsigned long long>(key));
    const int leader = __ffs(peers) - 1;
    const int lane = threadIdx.x % 32;
    int index = -1, base = 0;
    if (lane == leader) {
      bool inserted = false;
      index = table.insert(key, inserted);
      if (inserted) {
        zero_block<T>(grid_a, index);
        zero_block<T>(grid_b, index);
      }
      if (index >= 0) base = atomicAdd(&next_count[index], __popc(peers));
    }
    index = __shfl_sync(peers, index, leader);
    base = __shfl_sync(peers, base, leader);
    if (index >= 0) d = ParticleDest{index, base + __popc(peers & lanemask_lt())};
  }
  return d;
}

}  // namespace g2p2g_detail

template <typename M, typename T, bool kInitial>
__global__ void __launch_bounds__(kG2P2GThreads) g2p2g(G2P2GParams<M, T> p) {
  using State = material_state_t<M, T>;
  constexpr int kStateScalars = ParticleLayout<M, T>::kStateScalars;
  // (x, y, z) grid velocities of the 8x8x8-node arena (vx, vy, vz, pad per node), index arena_index(x, y, z) =
  // 68 x + 8 y + z.
  __shared__ g2p2g_detail::ArenaVelocity<T> arena_v[kArenaStorage];
  // (channel, x, y, z) P2G sums: mass, momentum x, y, z; same indexing.
  __shared__ T arena_p[4][kArenaStorage];
  // (neighbour) hash-table index of the arena's 2x2x2 grid blocks, neighbour = (di * 2 + dj) * 2 + dk.
  __shared__ int arena_blocks[8];

  const int block = blockIdx.x;
  const int count = p.layout.count[block];
  if (count == 0) return;  // uniform per CUDA block: a stale or footprint-only block
  const Vec3i origin = p.table.block_coords(block);
  if (threadIdx.x < 8) {
    const int di = threadIdx.x >> 2, dj = (threadIdx.x >> 1) & 1, dk = threadIdx.x & 1;
    const int found = p.table.find(BlockKey::pack(origin[0] + di, origin[1] + dj, origin[2] + dk));
    arena_blocks[threadIdx.x] = found;
    if (found < 0) atomicAdd(&p.stats->internal_error, 1);
  }
  for (int i = threadIdx.x; i < 4 * kArenaStorage; i += blockDim.x) (&arena_p[0][0])[i] = T(0);
  __syncthreads();
  if constexpr (!kInitial) {
    for (int i = threadIdx.x; i < kArenaNodes; i += blockDim.x) {
      const int a = i >> 6, b = (i >> 3) & 7, c = i & 7;
      const int nb = arena_blocks[((a >> 2) * 2 + (b >> 2)) * 2 + (c >> 2)];
      const int node = ((a & 3) * 4 + (b & 3)) * 4 + (c & 3);
      T vx = T(0), vy = T(0), vz = T(0);
      if (nb >= 0) {
        vx = block_val(p.velocity, grid_velocity_x, nb, node);
        vy = block_val(p.velocity, grid_velocity_y, nb, node);
        vz = block_val(p.velocity, grid_velocity_z, nb, node);
      }
      arena_v[g2p2g_detail::arena_index(a, b, c)] = g2p2g_detail::ArenaVelocity<T>{vx, vy, vz, T(0)};
    }
    __syncthreads();
  }

  const T dt_next = static_cast<T>(*p.dt_next);
  const int lane = threadIdx.x % 32;
  const int warp = threadIdx.x / 32;
  const int bins = (count + 31) / 32;
  const int first_bin = p.layout.bin_offset[block];
  double wave_max = 0.0;
  for (int bin = warp; bin < bins; bin += kG2P2GThreads / 32) {
    const int slot = (first_bin + bin) * 32 + lane;
    const int src = p.layout.src[slot];
    const bool active = src >= 0;
    int failed = -1;
    bool has_key = false;
    std::uint64_t key = 0;
    int id = INT_MAX;
    if (active) {
      const ParticleRecord<M, T> in = load_particle<M, T>(p.in, src);
      id = in.id;
      Vec3<T> v, x_new;
      Mat3<T> C;
      State state_new;
      if constexpr (kInitial) {
        v = p.initial_velocity;
        C = Mat3<T>::zero();
        x_new = in.x;
        state_new = in.state;
      } else {
        const QuadraticBspline<T> s = quadratic_bspline_inv(in.x, p.inv_dx);
        const int l0 = s.base[0] - 4 * origin[0], l1 = s.base[1] - 4 * origin[1], l2 = s.base[2] - 4 * origin[2];
        if (l0 < 0 || l0 > 5 || l1 < 0 || l1 > 5 || l2 < 0 || l2 > 5) {
          atomicAdd(&p.stats->internal_error, 1);  // a particle outside its block's arena: never expected
        }
        const int c0 = min(max(l0, 0), 5), c1 = min(max(l1, 0), 5), c2 = min(max(l2, 0), 5);
        G2PSum<T> sum;
        g2p2g_detail::for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
          const int a = g2p2g_detail::arena_index(c0 + i, c1 + j, c2 + k);
          const g2p2g_detail::ArenaVelocity<T> node_v = arena_v[a];
          sum.add(w, Vec3<T>{{node_v.x, node_v.y, node_v.z}}, xixp);
        });
        v = sum.velocity();
        C = sum.affine(p.d_inv);
        x_new = advect(in.x, v, p.dt);
        state_new = M::advance(in.state, C, p.dt);
        // Checks, in the CPU engine's order: non-finite, left the domain, moved more than a cell.
        if (!(all_finite(x_new) && all_finite(v) && all_finite(C) &&
              g2p2g_detail::state_finite<T, kStateScalars>(state_new))) {
          failed = kFailNonFinite;
        } else {
          bool inside = true;
          for (int a = 0; a < 3; ++a) inside = inside && x_new[a] >= T(0) && x_new[a] <= p.domain[a];
          if (!inside)
            failed = kFailLeftDomain;
          else if (max_abs(x_new - in.x) > p.dx)
            failed = kFailCfl;
        }
      }
      ParticleRecord<M, T> out{x_new, state_new, in.id};
      store_particle<M, T>(p.out, slot, out);
      if (p.aux != nullptr) {
        T* a = p.aux + static_cast<std::size_t>(slot) * kAuxScalars;
        a[0] = v[0];
        a[1] = v[1];
        a[2] = v[2];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) a[3 + 3 * r + c] = C(r, c);
      }
      if (failed < 0) {
        const QuadraticBspline<T> s = quadratic_bspline_inv(x_new, p.inv_dx);
        const int l0 = s.base[0] - 4 * origin[0], l1 = s.base[1] - 4 * origin[1], l2 = s.base[2] - 4 * origin[2];
        if (l0 < 0 || l0 > 5 || l1 < 0 || l1 > 5 || l2 < 0 || l2 > 5) {
          failed = kFailCfl;  // left the arena (rounding at exactly one cell): same meaning, never written
        } else {
          wave_max = fmax(wave_max, static_cast<double>(M::wave_speed(p.material, state_new)));
          const StressResult<T> stress = M::kirchhoff_stress(p.material, state_new, C);
          const P2GParticle<T> payload =
              mls_p2g_particle(p.mass, p.volume, v, C, stress.kirchhoff, dt_next, p.d_inv);
          auto scatter = [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
            const int a = g2p2g_detail::arena_index(l0 + i, l1 + j, l2 + k);
            const Vec3<T> mv = p2g_node_momentum(payload, w, xixp);
            atomicAdd(&arena_p[0][a], w * payload.mass);
            atomicAdd(&arena_p[1][a], mv[0]);
            atomicAdd(&arena_p[2][a], mv[1]);
            atomicAdd(&arena_p[3][a], mv[2]);
          };
          g2p2g_detail::for_each_stencil_node_unrolled(s, p.dx, scatter);
          const int b0 = floor_div4(s.base[0] - 1), b1 = floor_div4(s.base[1] - 1), b2 = floor_div4(s.base[2] - 1);
          if (BlockKey::representable(b0, b1, b2)) {
            has_key = true;
            key = BlockKey::pack(b0, b1, b2);
          } else {
            failed = kFailLeftDomain;
          }
        }
      }
    }
    // Failure counts: one atomic per warp and kind; the smallest failing ID for the report.
    for (int kind = 0; kind < kFailKinds; ++kind) {
      const unsigned mask = __ballot_sync(0xffffffffu, failed == kind);
      if (mask != 0) {
        if (lane == __ffs(mask) - 1) atomicAdd(&p.body_stats->failures[kind], __popc(mask));
        if (failed == kind) atomicMin(&p.body_stats->first_id[kind], id);
      }
    }
    const ParticleDest d =
        g2p2g_detail::claim_block_rank<T>(has_key, key, p.table, p.next_count, p.grid_next, p.grid_this);
    if (active) p.dest[slot] = d;
  }
  wave_max = warp_max(wave_max);
  if (lane == 0 && wave_max > 0.0) atomic_max_nonneg(p.wave_speed, wave_max);

  __syncthreads();
  // Flush: one thread per arena node; atomics into the (up to 8) grid blocks of the next grid.
  for (int i = threadIdx.x; i < kArenaNodes; i += blockDim.x) {
    const int a = i >> 6, b = (i >> 3) & 7, c = i & 7;
    const int ai = g2p2g_detail::arena_index(a, b, c);
    const T m = arena_p[0][ai];
    if (m == T(0)) continue;  // no particle's stencil covers this node
    const int nb = arena_blocks[((a >> 2) * 2 + (b >> 2)) * 2 + (c >> 2)];
    if (nb < 0) continue;  // counted above as an internal error
    const int node = ((a & 3) * 4 + (b & 3)) * 4 + (c & 3);
    atomicAdd(&block_val(p.grid_next, grid_mass, nb, node), m);
    atomicAdd(&block_val(p.grid_next, grid_momentum_x, nb, node), arena_p[1][ai]);
    atomicAdd(&block_val(p.grid_next, grid_momentum_y, nb, node), arena_p[2][ai]);
    atomicAdd(&block_val(p.grid_next, grid_momentum_z, nb, node), arena_p[3][ai]);
  }
}

}  // namespace fbar
