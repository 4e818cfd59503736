// F-bar's pass over a body's particles before its G2P2G (kernels of the GPU engine): the cell scheme's cell sums
// (physics/transfer.cuh) and the nodal scheme's node sums (physics/fbar_nodal.cuh), into the grid's F-bar channel
// set (grid_channels.h FbarSums), one CUDA block per particle block like g2p2g; the node sums also give the nodes'
// volume to the Volume and JBar grid sensors on their sample steps. The node sums add 54 integers per particle into
// a block's shared copy, each 64-bit integer as two native 32-bit shared atomics (sm_90 runs 64-bit shared atomics
// as compare-and-swap loops: g2p2g_kernel.cuh, "Fixed-point arena"), then add the copy to the grid.
#pragma once

#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "physics/fbar_nodal.cuh"
#include "physics/transfer.cuh"

namespace fbar {

/// F-bar's cell sums of one body (transfer.cuh): per particle, V0 (1 - J) and V0 of the state at the start of the
/// step added to the particle's cell, cell c stored at node c. Launched per body between the grid update and its
/// G2P2G, into a zeroed buffer; one CUDA block per particle block, like g2p2g.
template <typename M, typename T, typename TG>
struct FbarCellSumsParams {
  typename ParticleLayout<M, T>::Buffer in;  ///< particles of this step (storage order)
  LayoutView layout;                         ///< this step's layout
  BlockHashTableView table;
  FbarSums<TG> sums;                         ///< target (zeroed on blocks [0, block count))
  double quantum;                            ///< [m^3] their quantum (fixed_quantum of V0)
  T volume;                                  ///< [m^3] reference volume per particle
  T inv_dx;                                  ///< [1/m]
  StepStats* stats;
};

template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kParticleBlockThreads) fbar_cell_sums(FbarCellSumsParams<M, T, TG> p) {
  __shared__ int arena_blocks[8];
  const int block = blockIdx.x;
  const int count = p.layout.count[block];
  if (count == 0) return;
  const Vec3i origin = p.table.block_coords(block);
  g2p2g_detail::find_arena_blocks(p.table, block, origin, arena_blocks, p.stats);
  __syncthreads();
  const int first_slot = p.layout.bin_offset[block] * 32;
  for (int t = threadIdx.x; t < ((count + 31) / 32) * 32; t += blockDim.x) {
    const int src = p.layout.src[first_slot + t];
    if (src < 0) continue;
    const ParticleRecord<M, T> in = load_particle<M, T>(p.in, src);
    const QuadraticBspline<T> s = quadratic_bspline_inv(in.x, p.inv_dx);
    const int c0 = min(max(s.base[0] - 4 * origin[0], 0), 5), c1 = min(max(s.base[1] - 4 * origin[1], 0), 5),
              c2 = min(max(s.base[2] - 4 * origin[2], 0), 5);
    const Vec3i cell = fbar_cell_offset(in.x, p.inv_dx, s.base);
    const int a = c0 + cell[0], b = c1 + cell[1], c = c2 + cell[2];
    const int nb = arena_blocks[g2p2g_detail::arena_neighbour(a, b, c)];
    if (nb < 0) continue;  // counted by find_arena_blocks
    const int node = g2p2g_detail::arena_node_in_block(a, b, c);
    const double per_unit = 1.0 / p.quantum;
    p.sums.add(nb, 0, node, static_cast<double>(p.volume * one_minus_volume_ratio<M>(in.state)) * per_unit);
    p.sums.add(nb, 1, node, static_cast<double>(p.volume) * per_unit);
  }
}


/// What a particle's node sums carry besides w V: its 1 - JBar as stored (nodal F-bar, fused), advanced by its own
/// volume change over the step (nodal F-bar, split), or its own 1 - J (a Volume or JBar grid sensor, a body
/// without nodal F-bar).
enum class FbarNodeValue { Stored, Advanced, OwnJ };

/// Node sums of one body (physics/fbar_nodal.cuh): per particle, w V s and w V (V = V0 J of the state at the start
/// of the step, s = 1 - JBar as `value` says) on its 27 nodes. Launched per body into a zeroed buffer: by nodal
/// F-bar between the grid update and the body's G2P2G, by a Volume or JBar grid sensor before its sample (every
/// body into one buffer, in one quantum); one CUDA block per particle block.
template <typename M, typename T, typename TG>
struct FbarNodeSumsParams {
  typename ParticleLayout<M, T>::Buffer in;  ///< particles of this step (storage order)
  LayoutView layout;                         ///< this step's layout
  BlockHashTableView table;
  FbarSums<TG> sums;                         ///< target (zeroed on blocks [0, block count))
  double quantum;                            ///< [m^3] their quantum (fixed_quantum of the largest V0 summed)
  const T* jbar;                             ///< (storage slot) 1 - JBar (Stored, Advanced)
  FbarNodeValue value;
  typename GridLayout<TG>::VelocityBuffer velocity;  ///< Advanced: this step's grid velocities
  T volume;                                  ///< [m^3] reference volume per particle
  const T* vertex_volume;                    ///< (ID) [m^3] a mesh's lumped vertex volumes, or nullptr
  T dt, dx, inv_dx, d_inv;                   ///< [s], [m], [1/m], [1/m^2]
  StepStats* stats;
};

/// A 64-bit integer add into shared memory from two native 32-bit ones (sm_90 runs 64-bit shared atomics as
/// compare-and-swap loops): a low word that wraps carries exactly once into the high word, so the pair holds the
/// exact sum modulo 2^64 whatever the interleaving (FixedArena<double> of g2p2g_kernel.cuh).
FBAR_DEVICE FBAR_FORCE_INLINE void add_shared_int64(unsigned* lo_word, unsigned* hi_word, long long v) {
  const unsigned lo = static_cast<unsigned>(v), hi = static_cast<unsigned>(static_cast<unsigned long long>(v) >> 32);
  const unsigned old = lo != 0u ? atomicAdd(lo_word, lo) : 0u;
  const unsigned carry = old + lo < old ? 1u : 0u;
  if (hi + carry != 0u) atomicAdd(hi_word, hi + carry);
}

/// One fixed-point contribution into a block's shared copy of the sums: the words FixedGrid::add would add to the
/// grid (the same rounding), so that the flush adds the same integers the particles would have added one by one.
/// `lo` indexes the low halves of a value's words (word w at lo + w * stride), `hi` their high halves.
template <typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void add_shared_units(unsigned* lo, unsigned* hi, int stride, double units) {
  if constexpr (FixedSumFormat<TG>::kWords == 1) {
    const long long v = __double2ll_rn(units);
    if (v != 0) add_shared_int64(lo, hi, v);
  } else {
    const double r = rint(units);
    if (r == 0.0) return;
    const double h = floor(r * 0x1p-32);
    const double l = r - h * 0x1p32;
    if (l != 0.0) add_shared_int64(lo, hi, static_cast<long long>(l));
    if (h != 0.0) add_shared_int64(lo + stride, hi + stride, __double2ll_rn(h));
  }
}

template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kParticleBlockThreads) fbar_node_sums(FbarNodeSumsParams<M, T, TG> p) {
  constexpr int kWords = FixedSumFormat<TG>::kWords;
  constexpr int kSlots = 2 * kArenaNodes;  // (channel, arena node)
  constexpr int kHalf = kWords * kSlots;   // the high halves follow the low ones
  // The block's sums over its 2x2x2 grid blocks (word, channel, node a * 64 + b * 8 + c) as 64-bit integers in two
  // 32-bit halves, integer adds: order-free.
  __shared__ unsigned acc[2 * kHalf];
  __shared__ int arena_blocks[8];
  const int block = blockIdx.x;
  const int count = p.layout.count[block];
  if (count == 0) return;
  for (int i = threadIdx.x; i < 2 * kHalf; i += blockDim.x) acc[i] = 0u;
  const Vec3i origin = p.table.block_coords(block);
  g2p2g_detail::find_arena_blocks(p.table, block, origin, arena_blocks, p.stats);
  __syncthreads();
  const int first_slot = p.layout.bin_offset[block] * 32;
  const double per_unit = 1.0 / p.quantum;
  const auto node_of = [](int a, int b, int c) { return (a * kArenaSide + b) * kArenaSide + c; };
  for (int t = threadIdx.x; t < ((count + 31) / 32) * 32; t += blockDim.x) {
    const int src = p.layout.src[first_slot + t];
    if (src < 0) continue;
    const ParticleRecord<M, T> in = load_particle<M, T>(p.in, src);
    const QuadraticBspline<T> s = quadratic_bspline_inv(in.x, p.inv_dx);
    const int c0 = min(max(s.base[0] - 4 * origin[0], 0), 5), c1 = min(max(s.base[1] - 4 * origin[1], 0), 5),
              c2 = min(max(s.base[2] - 4 * origin[2], 0), 5);
    const T V = (p.vertex_volume ? p.vertex_volume[in.id] : p.volume) * M::volume_ratio(in.state);
    T value = p.value == FbarNodeValue::OwnJ ? one_minus_volume_ratio<M>(in.state) : p.jbar[src];
    if (p.value == FbarNodeValue::Advanced) {
      G2PSum<T> sum;
      g2p2g_detail::for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
        const int a = c0 + i, b = c1 + j, c = c2 + k;
        const int nb = arena_blocks[g2p2g_detail::arena_neighbour(a, b, c)];
        if (nb < 0) return;  // counted by find_arena_blocks
        const int node = g2p2g_detail::arena_node_in_block(a, b, c);
        sum.add(w, Vec3<T>{{static_cast<T>(block_val(p.velocity, grid_velocity_x, nb, node)),
                            static_cast<T>(block_val(p.velocity, grid_velocity_y, nb, node)),
                            static_cast<T>(block_val(p.velocity, grid_velocity_z, nb, node))}},
                xixp);
      });
      value = fbar_advance_one_minus_J(value, fbar_volume_increment<M>(sum.affine(p.d_inv), p.dt));
    }
    g2p2g_detail::for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>&) {
      const int n = node_of(c0 + i, c1 + j, c2 + k);
      add_shared_units<TG>(acc + n, acc + kHalf + n, kSlots, static_cast<double>(w * V * value) * per_unit);
      add_shared_units<TG>(acc + kArenaNodes + n, acc + kHalf + kArenaNodes + n, kSlots,
                           static_cast<double>(w * V) * per_unit);
    });
  }
  __syncthreads();
  for (int i = threadIdx.x; i < kSlots; i += blockDim.x) {
    const int channel = i / kArenaNodes, n = i % kArenaNodes;
    const int a = n / (kArenaSide * kArenaSide), b = (n / kArenaSide) % kArenaSide, c = n % kArenaSide;
    const int nb = arena_blocks[g2p2g_detail::arena_neighbour(a, b, c)];
    if (nb < 0) continue;
    const int node = g2p2g_detail::arena_node_in_block(a, b, c);
    for (int w = 0; w < kWords; ++w) {
      const unsigned long long v = (static_cast<unsigned long long>(acc[kHalf + w * kSlots + i]) << 32) | acc[w * kSlots + i];
      if (v != 0ull) atomicAdd(p.sums.word(nb, w, channel, node), v);
    }
  }
}

}  // namespace fbar
