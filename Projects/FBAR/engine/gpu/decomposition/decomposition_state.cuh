// What a decomposed GPU rank keeps besides the one-GPU state (GpuEngineOptions::ranks; comm/slab_partition.h): the
// transports, its slab, the halo with each neighbour, the migration's message sizes and counts, and, for placed bodies
// (bodies[].gpu, comm/placement.h), the blocks shared with each rank. MgspBenchmark holds one (dec_); the code that
// uses it is in this folder (slabs.cuh, halo.cuh, shared_blocks.cuh, migration.cuh). One GPU: null transports, the
// slab all of space, nothing else used.
#pragma once

#include <cuda_runtime.h>

#include <array>
#include <cstddef>
#include <unordered_set>
#include <vector>

#include "MnSystem/Cuda/device_array.cuh"
#include "comm/device_transport.h"
#include "comm/slab_partition.h"
#include "comm/transport.h"
#include "engine/gpu/kernels/kernel_common.cuh"

namespace fbar {

/// The halo with the lower (0) and upper (1) neighbour: the union of both ranks' blocks of the shared plane.
template <typename TG>
struct HaloSide {
  int peer = -1;                              ///< -1: no neighbour on this side
  int plane = 0;                              ///< grid-block coordinate of the shared plane along the axis
  std::vector<unsigned long long> keys;       ///< sorted union (the same list on both ranks)
  cuda::DeviceArray<int> index;        ///< table index of each key here
  cuda::DeviceArray<TG> send, recv;    ///< message buffers (every exchanged buffer's blocks, in turn)
  cuda::DeviceArray<TG> saved[2];      ///< grid[g]'s summed halo blocks (delta exchanges)
  cuda::DeviceArray<unsigned long long> fresh;  ///< new local halo keys of the last collect_halo
  cuda::DeviceArray<std::byte> migrants_out, migrants_in;
};

/// Placed bodies: the blocks this rank shares with one other rank.
template <typename TG>
struct SharedPeer {
  std::vector<unsigned long long> keys;       ///< blocks both ranks hold, sorted (the same list on both)
  std::vector<int> blocks;                    ///< their table indices here
  cuda::DeviceArray<int> index, upos;  ///< the same on the device; upos: each entry's union position
  cuda::DeviceArray<TG> send, recv;
};

template <typename TG>
struct DecompositionState {
  comm::Transport* host = nullptr;
  comm::DeviceTransport* device = nullptr;
  comm::SlabPartition slabs;
  SlabBounds slab;
  cudaStream_t halo_stream = nullptr;  ///< the halo sums overlapping the interior G2P2G (highest priority)
  cudaEvent_t halo_ready = nullptr, halo_done = nullptr;  ///< halo blocks scattered / summed
  cudaEvent_t halo_events[2] = {};  ///< kernel timing: the halo stream's sums start / end
  std::array<HaloSide<TG>, 2> halo;
  int halo_scanned = 0;                        ///< table blocks already looked at for the halo planes
  int halo_fresh_capacity = 0;
  /// Records per body and side in a migration message (MigrantMessage): the same on every rank, grown (by all
  /// ranks at once, after agree_on_try) when a step sent more than half of it; a step that sent more is repeated.
  int migrant_capacity = 512;     ///< options_.migrant_capacity at start
  long long migration_repeats = 0;  ///< tries repeated because migrants overflowed the messages
  /// agree_on_try: the most particles one rank sent one side for one body (or half its emigrant list); a message
  /// overflowed when it is above migrant_capacity
  int migrant_most = 0;
  long long migrated = 0;
  long long pending_migrated = 0;
  bool halo_grew = false;  ///< agree_on_try: some rank has new halo blocks (every rank then calls rebuild_halo)
  double most_rank_particles = 0.0;  ///< agree_on_try: the most particles any rank holds after the last step

  cuda::DeviceArray<unsigned long long> dt_inputs_d;  ///< gather_dt_inputs: one reduction over the ranks

  // Placed bodies (bodies[].gpu, comm/placement.h): any set of ranks may hold a block; the sums go over these lists
  // (shared_exchange) instead of the neighbour planes, and halo[0].fresh collects every new table block.
  std::vector<int> homes;  ///< per body: the rank holding it whole, or kAllGpus (spread by space); empty: one GPU
  bool placed = false;     ///< some body is placed
  std::vector<SharedPeer<TG>> shared;                                   ///< per rank (this rank's entry unused)
  std::vector<std::unordered_set<unsigned long long>> rank_keys;    ///< every rank's table keys so far
  std::vector<int> union_blocks;                                    ///< every shared block once, ascending
  cuda::DeviceArray<int> union_index;
  cuda::DeviceArray<TG> union_own, union_saved[2];          ///< this rank's part; grid[g]'s summed values
  cuda::DeviceArray<unsigned char> not_counted;              ///< per table block (sensors count it once)
};

}  // namespace fbar
