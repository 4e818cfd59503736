// Seepage P2G of the GPU engine: the five seepage channels of a saturated body (CoupledUP; physics/seepage.cuh)
// from the particles' state at the start of the step, the CPU engine's P2G of the same channels.
//
// Why a kernel of its own and not five more channels of the fused G2P2G's arena: the grid update of step n needs the
// sums of state n, which is what G2P2G's P2G half produces for step n + 1, so the fused kernel could carry them; but
// a retried or rescaled step (on_failure = reduce_dt, a new dt) must see them again, and the grid update replaces
// them in place with the nodes' h_i, r_i and p_i. Summed at the start of every try from bins[cur] (unchanged until
// the step commits), they need no second buffer, no rescale and no bookkeeping across tries, and bodies without
// pore water pay nothing: the G2P2G arena, its shared memory and its occupancy stay those of the other laws. The
// price is one more read of a saturated body's particles per step (the benchmark's CoupledUP row measures it).
//
// One CUDA block per particle block, as fbar_cell_sums, over the 8x8x8 arena of nodes around the block, in fixed point
// as the G2P2G's P2G (g2p2g_kernel.cuh, "Fixed-point arena"): on sm_90 a shared float atomic is a compare-and-swap
// loop, 135 of them per particle (27 nodes x 5 channels); measured on an H200 at 16M particles, the float arena took
// 4.2 ms a step, as long as the whole G2P2G. Two passes over the block's particles: the first bounds each channel's
// contribution per unit weight (B_c, reduced over the block), which sets the channel's quantum q_c =
// 0.75^3 count B_c / R so that no node's sum can leave the integer (R: FixedArena<TG>::kRange); the second adds
// each contribution in units of q_c with native integer atomics (int32 for float, int64 as two words for double),
// and one thread per arena node adds its sums into the grid's fixed-point seepage sums (grid_buffer.cuh "Order-free
// grid sums") in units of Q_c = B_c 2^-F, B_c the channel's bound over every saturated body (and rank): a first
// launch (bounds_only) measures it, so the sums are order-free end to end. Rounding: q_c / 2 per contribution, about
// 1e-7 B_c (float) or 2e-16 B_c (double): float's and double's own rounding of such sums. Bounds per unit weight
// (|x_i - x_p| <= 1.5 dx per axis): volume V, head V (|h| + 1.5 dx |grad h|_1), inflow V D^-1 1.5 dx |q|_1, water
// n rhow V0, density V rhow.
#pragma once

#include <cuda_runtime.h>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "engine/gpu/partition_domain.h"
#include "physics/constitutive_models.cuh"
#include "physics/seepage.cuh"

namespace fbar {

template <typename M, typename T, typename TG>
struct SeepageSumsParams {
  typename ParticleLayout<M, T>::Buffer in;  ///< particles of this step (storage order)
  LayoutView layout;                         ///< this step's layout
  BlockHashTableView table;
  PoreSums<TG> sums;                         ///< target (zeroed on blocks [0, block count) before)
  /// (channel) bits of B_c over every saturated body: bounds_only launches raise them (zeroed before the first),
  /// the others read them
  unsigned long long* bound;
  bool bounds_only;
  material_params_t<M, T> material;
  T volume;              ///< [m^3] reference volume per particle
  T dx, inv_dx, d_inv;   ///< [m], [1/m], [1/m^2]
  Vec3<T> gravity;       ///< [m/s^2]
  StepStats* stats;
};

inline constexpr int kSeepageChannels = 5;

template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kParticleBlockThreads) seepage_sums(SeepageSumsParams<M, T, TG> p) {
  static_assert(IsPoreFluid<M>::value, "seepage_sums runs for saturated materials only");
  using g2p2g_detail::arena_index;
  using Fixed = g2p2g_detail::FixedArena<TG>;
  constexpr int kWords = (sizeof(TG) == 8 ? 2 : 1) * kSeepageChannels * kArenaStorage;
  // (channel, node) integer sums (double: (half, channel, node)): volume, head, inflow, water, density.
  __shared__ unsigned arena_words[kWords];
  __shared__ int arena_blocks[8];
  __shared__ unsigned long long block_bound[kSeepageChannels];  // bits of each channel's B_c (non-negative doubles)
  const int block = blockIdx.x;
  const int count = p.layout.count[block];
  if (count == 0) return;  // uniform per CUDA block
  const Vec3i origin = p.table.block_coords(block);
  g2p2g_detail::find_arena_blocks(p.table, block, origin, arena_blocks, p.stats);
  for (int i = threadIdx.x; i < kWords; i += blockDim.x) arena_words[i] = 0u;
  if (threadIdx.x < kSeepageChannels) block_bound[threadIdx.x] = 0ull;
  __syncthreads();
  const T rhow = M::water_density(p.material);
  const T water = M::water_mass(p.material, p.volume);
  const T reach = T(1.5) * p.dx;  // the largest |x_i - x_p| per axis over a stencil
  const int first_slot = p.layout.bin_offset[block] * 32;
  const int slots = ((count + 31) / 32) * 32;
  // What one particle deposits, before the stencil: its volume, head, Darcy flux and head gradient.
  struct Source {
    QuadraticBspline<T> s;
    T volume, head;
    Vec3<T> flux, head_gradient;
  };
  const auto source_of = [&](const ParticleRecord<M, T>& in) {
    return Source{quadratic_bspline_inv(in.x, p.inv_dx), p.volume * M::volume_ratio(in.state),
                  M::pore_pressure(in.state) - rhow * dot(p.gravity, in.x), M::seepage(p.material, in.state),
                  M::head_gradient(in.state)};
  };
  // Pass 1: the channels' bounds per unit weight.
  double bound[kSeepageChannels] = {0.0, 0.0, 0.0, 0.0, 0.0};
  for (int t = threadIdx.x; t < slots; t += blockDim.x) {
    const int src = p.layout.src[first_slot + t];
    if (src < 0) continue;
    const Source q = source_of(load_particle<M, T>(p.in, src));
    const T l1_gradient = fabs(q.head_gradient[0]) + fabs(q.head_gradient[1]) + fabs(q.head_gradient[2]);
    const T l1_flux = fabs(q.flux[0]) + fabs(q.flux[1]) + fabs(q.flux[2]);
    bound[0] = fmax(bound[0], static_cast<double>(q.volume));
    bound[1] = fmax(bound[1], static_cast<double>(q.volume * (fabs(q.head) + reach * l1_gradient)));
    bound[2] = fmax(bound[2], static_cast<double>(q.volume * p.d_inv * reach * l1_flux));
    bound[3] = fmax(bound[3], static_cast<double>(water));
    bound[4] = fmax(bound[4], static_cast<double>(q.volume * rhow));
  }
  for (int c = 0; c < kSeepageChannels; ++c) {
    const double b = warp_max(bound[c]);
    if (threadIdx.x % 32 == 0 && b > 0.0) atomic_max_nonneg(&block_bound[c], b);
  }
  __syncthreads();
  if (p.bounds_only) {
    if (threadIdx.x < kSeepageChannels && block_bound[threadIdx.x] != 0ull)
      atomicMax(&p.bound[threadIdx.x], block_bound[threadIdx.x]);
    return;
  }
  // The channels' quanta [their units] and inverses (a channel with B_c = 0, e.g. no flow, adds nothing).
  T quantum[kSeepageChannels], inverse[kSeepageChannels];
  const double span = kMaxNodeWeight * count / Fixed::kRange;
  for (int c = 0; c < kSeepageChannels; ++c) {
    const double b = __longlong_as_double(static_cast<long long>(block_bound[c]));
    quantum[c] = static_cast<T>(b * span);
    inverse[c] = b > 0.0 ? static_cast<T>(1.0 / (b * span)) : T(0);
  }
  // Pass 2: the contributions in units of the quanta.
  const Fixed fixed{arena_words, kSeepageChannels};
  for (int t = threadIdx.x; t < slots; t += blockDim.x) {
    const int src = p.layout.src[first_slot + t];
    if (src < 0) continue;
    const ParticleRecord<M, T> in = load_particle<M, T>(p.in, src);
    const Source q = source_of(in);
    // The G2P stencil of a particle of this block starts at 1..4 in the arena (g2p2g_kernel.cuh, "Off-by-2").
    const int l0 = q.s.base[0] - 4 * origin[0], l1 = q.s.base[1] - 4 * origin[1], l2 = q.s.base[2] - 4 * origin[2];
    if (l0 < 0 || l0 > 5 || l1 < 0 || l1 > 5 || l2 < 0 || l2 > 5) {
      atomicAdd(&p.stats->internal_error, 1);  // a particle outside its block's arena: never expected
      continue;
    }
    g2p2g_detail::for_each_stencil_node_unrolled(q.s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
      const int a = arena_index(l0 + i, l1 + j, l2 + k);
      const SeepageDeposit<T> d =
          seepage_deposit(w, xixp, p.d_inv, q.volume, q.head + dot(q.head_gradient, xixp), q.flux, water, rhow);
      fixed.add(0, a, d.volume * inverse[0]);
      fixed.add(1, a, d.head * inverse[1]);
      fixed.add(2, a, d.inflow * inverse[2]);
      fixed.add(3, a, d.water * inverse[3]);
      fixed.add(4, a, d.density * inverse[4]);
    });
  }
  __syncthreads();
  double to_grid[kSeepageChannels];  // q_c / Q_c
  for (int c = 0; c < kSeepageChannels; ++c) {
    const double global = pore_quantum<TG>(p.bound[c]);
    to_grid[c] = global > 0.0 ? static_cast<double>(quantum[c]) / global : 0.0;
  }
  for (int i = threadIdx.x; i < kArenaNodes; i += blockDim.x) {
    const int a = i >> 6, b = (i >> 3) & 7, c = i & 7;
    const int ai = arena_index(a, b, c);
    if (fixed.exact(0, ai) == 0.0) continue;  // no particle's stencil covers this node
    const int nb = arena_blocks[g2p2g_detail::arena_neighbour(a, b, c)];
    if (nb < 0) continue;  // counted by find_arena_blocks
    const int node = g2p2g_detail::arena_node_in_block(a, b, c);
    for (int ch = 0; ch < kSeepageChannels; ++ch) p.sums.add(nb, ch, node, fixed.exact(ch, ai) * to_grid[ch]);
  }
}

}  // namespace fbar
