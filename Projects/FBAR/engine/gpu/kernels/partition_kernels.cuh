// Partition kernels: next layout from the recorded (block, rank) of every particle, block activation, impulse fix.
//
// After G2P2G (which inserted every particle's next block and counted it), per body:
//   activate_footprint   each block with particles inserts its 7 +x/+y/+z neighbours (the 2x2x2 arena of G2P2G)
//   blocks_to_bins       ceil(count / 32) per block, then an exclusive scan (CUB) gives the bin offsets
//   finalize_layout      total bins (and an overflow flag when the bins do not fit) into the step statistics
//   scatter_src          src_next[offset(block) * 32 + rank] = slot: the gather indices of the next G2P2G
//   pad_src              the unused lanes of each block's last bin get -1
// All O(blocks) or O(particles) with coalesced reads; the only scattered writes are the 4-byte src indices.
#pragma once

#include <cuda_runtime.h>

#include "MnBase/Math/bspline.h"
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/kernels/kernel_common.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "engine/gpu/partition_domain.h"
#include "physics/transfer.cuh"

namespace fbar {

inline constexpr int kPartitionThreads = 256;

/// Records (block, rank) for particles at slots [first, slots) of `bins` from their positions (initial partition,
/// the repeat of a partition after the table grew, particles received from another rank). valid: the slot holds a
/// particle when valid[slot] >= 0 (nullptr: when slot < particles). A particle whose block lies outside `slab` is
/// marked kEmigrant (a repeat after it was sent), as G2P2G marks it. blocks (a restart's flat upload, or nullptr):
/// the block coordinates of each slot's particle (3 per slot) instead of its position's, so that the restart's P2G
/// groups the particles as the checkpointed run's last one did (io::CheckpointBody::p2g_block).
template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kPartitionThreads)
    dest_from_positions(typename ParticleLayout<M, T>::Buffer bins, const int* valid, int particles, int first,
                        int slots, T inv_dx, SlabBounds slab, BlockHashTableView table, int* next_count,
                        ParticleDest* dest, GridSums<TG> grid_a, GridSums<TG> grid_b, BodyStepStats* body_stats,
                        const int* blocks = nullptr) {
  const int slot = first + blockIdx.x * blockDim.x + threadIdx.x;  // whole warps run: claim_block_rank is collective
  const bool in_range = slot < slots;
  const bool active = in_range && (valid ? valid[slot] >= 0 : slot < particles);
  bool has_key = false;
  int emigrant = -1;
  std::uint64_t key = 0;
  if (active) {
    const ParticleRecord<M, T> p = load_particle<M, T>(bins, slot);
    const QuadraticBspline<T> s = quadratic_bspline_inv(p.x, inv_dx);
    const int b0 = blocks ? blocks[3 * static_cast<std::size_t>(slot)] : floor_div4(s.base[0] - 1);
    const int b1 = blocks ? blocks[3 * static_cast<std::size_t>(slot) + 1] : floor_div4(s.base[1] - 1);
    const int b2 = blocks ? blocks[3 * static_cast<std::size_t>(slot) + 2] : floor_div4(s.base[2] - 1);
    if (all_finite(p.x) && BlockKey::representable(b0, b1, b2)) {
      if (slab.owns(b0, b1, b2)) {
        has_key = true;
        key = BlockKey::pack(b0, b1, b2);
      } else {
        emigrant = slab.side(b0, b1, b2);
      }
    } else {
      atomicAdd(&body_stats->failures[kFailLeftDomain], 1);
      atomicMin(&body_stats->first_id[kFailLeftDomain], p.id);
    }
  }
  const ParticleDest d = g2p2g_detail::claim_block_rank<TG>(has_key, key, table, next_count, grid_a, grid_b);
  if (active) dest[slot] = emigrant >= 0 ? ParticleDest{kEmigrant, emigrant} : d;
}

/// Every block holding particles of the body activates the other 7 blocks of its 2x2x2 arena. Through the arena
/// cache (BlockHashTableView::insert_arena): a block that keeps its particles reads its 32 cached bytes and looks
/// nothing up.
template <typename T>
__global__ void __launch_bounds__(kPartitionThreads)
    activate_footprint(const int* count, int block_limit, BlockHashTableView table, GridSums<T> grid_a,
                       GridSums<T> grid_b) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= block_limit || b >= table.counters->block_count || count[b] == 0) return;
  const Vec3i c = table.block_coords(b);
  for (int n = 1; n < 8; ++n) {
    bool inserted = false;
    const int index = table.insert_arena(b, c, n, inserted);
    if (inserted) {
      grid_a.zero_block(index);
      grid_b.zero_block(index);
    }
  }
}

/// bins[b] = ceil(count[b] / 32) for b < capacity, bins[capacity] = 0 (so the scan's last entry is the total).
static __global__ void __launch_bounds__(kPartitionThreads) blocks_to_bins(const int* count, int* bins, int capacity) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b < capacity) bins[b] = (count[b] + 31) / 32;
  if (b == capacity) bins[b] = 0;
}

static __global__ void finalize_layout(const int* bin_offset, int capacity, int bin_capacity, BodyStepStats* body_stats,
                                StepStats* stats, const TableCounters* counters) {
  const int total = bin_offset[capacity];
  body_stats->total_bins = total;
  if (total > bin_capacity) atomicAdd(&stats->bin_overflow, 1);
  stats->block_count = counters->block_count;
  stats->table_overflow = counters->overflow;
}

/// Slots one thread of scatter_src places (kPartitionThreads apart, so each pass is coalesced).
inline constexpr int kScatterSlotsPerThread = 8;

/// src_next[offset(block) * 32 + rank] = slot for every particle of the previous layout: slots whose dest names a
/// block (a G2P2G wrote every slot of its bins: kNoParticle marks the padding), or, with `valid`, only slots with
/// valid[slot] >= 0 (dest written for those alone: the partition from positions), or with `particles` >= 0 only
/// slots below it (the flat upload). Launch cuda::grid_for(slots, kPartitionThreads * kScatterSlotsPerThread).
static __global__ void __launch_bounds__(kPartitionThreads)
    scatter_src(const ParticleDest* dest, const int* valid, int particles, int slots, const int* bin_offset,
                int* src_next, int bin_capacity, BodyStepStats* body_stats) {
  const int first = blockIdx.x * (kPartitionThreads * kScatterSlotsPerThread) + threadIdx.x;
  int placed = 0;
#pragma unroll
  for (int k = 0; k < kScatterSlotsPerThread; ++k) {
    const int slot = first + k * kPartitionThreads;
    if (slot >= slots) break;
    if (valid ? valid[slot] < 0 : (particles >= 0 && slot >= particles)) continue;
    const ParticleDest d = dest[slot];
    if (d.block < 0) continue;
    const long long target = static_cast<long long>(bin_offset[d.block]) * 32 + d.rank;
    if (target < static_cast<long long>(bin_capacity) * 32) {
      src_next[target] = slot;
      ++placed;
    }
  }
  // One atomic per CUDA block of 2,048 slots: same-address atomics serialise in L2.
  __shared__ int warp_placed[kPartitionThreads / 32];
  placed = warp_sum(placed);
  if (threadIdx.x % 32 == 0) warp_placed[threadIdx.x / 32] = placed;
  __syncthreads();
  if (threadIdx.x == 0) {
    int block_placed = 0;
    for (int w = 0; w < kPartitionThreads / 32; ++w) block_placed += warp_placed[w];
    if (block_placed) atomicAdd(&body_stats->particles, block_placed);
  }
}

/// Lanes past the last particle of each block's last bin get src = -1.
static __global__ void __launch_bounds__(kPartitionThreads)
    pad_src(const int* count, const int* bin_offset, int capacity, int* src_next, int bin_capacity) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= capacity) return;
  const int c = count[b];
  if (c % 32 == 0) return;
  const int bin = bin_offset[b] + c / 32;
  if (bin >= bin_capacity) return;
  for (int lane = c % 32; lane < 32; ++lane) src_next[bin * 32 + lane] = -1;
}

// Grid compaction (MgspBenchmark::compact_grid, between two steps): the blocks a layout's particles use (their
// particle blocks and 2x2x2 arenas) and the listed halo blocks are kept, in the order of their keys, the others
// dropped; the table, the current grid sums and each layout are moved to the new indices.

/// live[b] = 1 for every block of the layout holding particles and the other 7 blocks of its arena.
static __global__ void __launch_bounds__(kPartitionThreads)
    mark_live_blocks(const int* count, int block_count, BlockHashTableView table, int* live) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= block_count || count[b] == 0) return;
  live[b] = 1;
  const Vec3i c = table.block_coords(b);
  for (int n = 1; n < 8; ++n) {
    const int index = table.find_arena(b, c, n);
    if (index >= 0) live[index] = 1;  // the footprint activation inserted it: always found
  }
}

/// live[index[i]] = 1 for a list of table blocks (a decomposed run's halo).
static __global__ void __launch_bounds__(kPartitionThreads) mark_listed_blocks(const int* index, int n, int* live) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n && index[i] >= 0) live[index[i]] = 1;
}

/// The kept blocks' keys and old indices, packed at their position among the kept (position: exclusive scan of live).
static __global__ void __launch_bounds__(kPartitionThreads)
    pack_kept_blocks(const int* live, const int* position, int block_count, BlockHashTableView table,
                     unsigned long long* keys, int* old_index) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= block_count || !live[b]) return;
  const Vec3i c = table.block_coords(b);
  keys[position[b]] = BlockKey::pack(c[0], c[1], c[2]);
  old_index[position[b]] = b;
}

/// new_index[old_of_new[i]] = i (new_index holds -1 for the dropped blocks beforehand).
static __global__ void __launch_bounds__(kPartitionThreads)
    invert_block_order(const int* old_of_new, int kept, int* new_index) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < kept) new_index[old_of_new[i]] = i;
}

/// Block i of dst = block old_of_new[i] of src, for i < kept (words: 16-byte words per block).
static __global__ void __launch_bounds__(kPartitionThreads)
    gather_blocks(const uint4* src, uint4* dst, int words, const int* old_of_new, int kept) {
  const long long total = static_cast<long long>(kept) * words;
  for (long long w = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x; w < total;
       w += static_cast<long long>(gridDim.x) * blockDim.x) {
    const long long i = w / words;
    const int o = static_cast<int>(w - i * words);
    dst[w] = src[static_cast<long long>(old_of_new[i]) * words + o];
  }
}

/// A layout's per-block arrays at the new indices: count and the first bin each block had (for moving its bins).
static __global__ void __launch_bounds__(kPartitionThreads)
    gather_layout_blocks(const int* count, const int* bin_offset, const int* old_of_new, int kept, int* count_out,
                         int* old_bin_out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= kept) return;
  count_out[i] = count[old_of_new[i]];
  old_bin_out[i] = bin_offset[old_of_new[i]];
}

/// The bins of new block i (one warp a block): src_out's bins from bin_offset[i] = src's bins from old_bin[i].
static __global__ void __launch_bounds__(kPartitionThreads)
    move_block_bins(const int* src, int* src_out, const int* count, const int* bin_offset, const int* old_bin,
                    int kept) {
  const int i = blockIdx.x * (kPartitionThreads / 32) + threadIdx.x / 32;
  const int lane = threadIdx.x % 32;
  if (i >= kept) return;
  const int bins = (count[i] + 31) / 32;
  const long long to = static_cast<long long>(bin_offset[i]) * 32 + lane;
  const long long from = static_cast<long long>(old_bin[i]) * 32 + lane;
  for (int k = 0; k < bins; ++k) src_out[to + 32LL * k] = src[from + 32LL * k];
}

/// flags[b] = 1 for the blocks of a layout holding particles; flags[block_count] counts them once the caller has
/// run count_flags (diagnostics: GpuEngine::particle_blocks).
static __global__ void __launch_bounds__(kPartitionThreads)
    mark_particle_blocks(const int* count, int block_count, int* flags) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b < block_count && count[b] > 0) flags[b] = 1;
}
static __global__ void __launch_bounds__(kPartitionThreads) count_flags(int* flags, int n) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  const int set = __syncthreads_count(b < n && flags[b] != 0);
  if (threadIdx.x == 0 && set > 0) atomicAdd(&flags[n], set);
}

/// index[i] = new_index[index[i]] (a list of table blocks after a compaction).
static __global__ void __launch_bounds__(kPartitionThreads) renumber_list(int* index, int n, const int* new_index) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n && index[i] >= 0) index[i] = new_index[index[i]];
}

/// Rescales the P2G impulse of a grid: adds w (-ddt V0 D^-1 tau)(x_i - x_p) per node for every particle of the
/// layout, so a grid built with impulse dt_old holds the one of dt_old + ddt (a repeated step with a smaller dt,
/// or step(dt) with a new dt). The stress is evaluated with C = 0: exact for rate-independent materials; the
/// viscous part of a JFluid keeps its old dt (C is not stored between steps). Added in the grid's quantum.
template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kPartitionThreads)
    rescale_impulse(typename ParticleLayout<M, T>::Buffer bins, LayoutView layout, int slots,
                    material_params_t<M, T> material, T volume, T ddt, T dx, T inv_dx, T d_inv,
                    BlockHashTableView table, GridSums<TG> grid, const GridQuantum* quantum, StepStats* stats,
                    const T* jbar) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int src = layout.src[slot];
  if (src < 0) return;
  const ParticleRecord<M, T> p = load_particle<M, T>(bins, src);
  // Nodal F-bar (jbar: 1 - JBar by storage slot): the state its P2G stressed (physics/fbar_nodal.cuh).
  const StressResult<T> stress =
      M::kirchhoff_stress(material, jbar ? fbar_stress_state<M>(material, p.state, jbar[src]) : p.state, Mat3<T>::zero());
  const P2GParticle<T> payload =
      mls_p2g_particle(T(0), volume, Vec3<T>::zero(), Mat3<T>::zero(), stress.kirchhoff, ddt, d_inv);
  const QuadraticBspline<T> s = quadratic_bspline_inv(p.x, inv_dx);
  const double per_unit = 1.0 / quantum->momentum;
  for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
    const int nx = s.base[0] + i, ny = s.base[1] + j, nz = s.base[2] + k;
    const int b = table.find(BlockKey::pack(floor_div4(nx), floor_div4(ny), floor_div4(nz)));
    if (b < 0) {
      atomicAdd(&stats->internal_error, 1);
      return;
    }
    const int node = ((nx & 3) * 4 + (ny & 3)) * 4 + (nz & 3);
    const Vec3<T> mv = p2g_node_momentum(payload, w, xixp);
    for (int a = 0; a < 3; ++a) grid.add(b, kSumMomentum + a, node, static_cast<double>(mv[a]) * per_unit);
  });
}

}  // namespace fbar
