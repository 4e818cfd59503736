// Kernels of a decomposed GPU run (comm/slab_partition.h): the halo blocks two ranks share and the particles that
// move from one rank to another.
//
// Halo: rank r and rank r + 1 both scatter into the grid blocks of plane cuts[r + 1]. Both hold the union of their
// blocks of that plane (insert_halo_blocks), listed in the same order (sorted keys) so that a message is the
// blocks' scalars in list order: pack_halo copies them out, add_halo adds the neighbour's in (a + b here, b + a
// there: the same sums, bit for bit). A delta exchange (the impulse rescaled after the sums were taken) adds the
// neighbour's new values minus the sums both already hold: (mine + theirs) - saved, the same on both sides.
// Migration: G2P2G marks a particle whose next particle block another rank owns (ParticleDest kEmigrant, the side
// in rank); pack_emigrants copies its record (stored scalars and ID, the ASFLIP velocity, the recorded v and C) into
// the message for that side; unpack_immigrants appends the records a neighbour sent behind the slots G2P2G wrote.
// A message has a fixed size that every rank knows (MigrantMessage): a header with each body's count, then each
// body's area of `capacity` records. The counts travel inside the message, so no rank waits for the host to learn
// them before the exchange; the host reads them with the step's one readback (record_migrant_counts).
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "MnSystem/Cuda/device_array.cuh"
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/kernels/kernel_common.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "engine/gpu/partition_domain.h"

namespace fbar {

inline constexpr int kHaloThreads = 256;

/// out[k, i] = buffer[index[k], i] for the n listed blocks of `scalars` scalars each.
template <typename TG>
__global__ void __launch_bounds__(kHaloThreads)
    pack_halo(const TG* buffer, int scalars, const int* index, int n, TG* out) {
  const long long t = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= static_cast<long long>(n) * scalars) return;
  const int k = static_cast<int>(t / scalars), i = static_cast<int>(t % scalars);
  out[t] = buffer[static_cast<std::size_t>(index[k]) * scalars + i];
}

/// buffer[index[k], i] = buffer + in (saved == nullptr), or (buffer + in) - saved (a delta exchange).
template <typename TG>
__global__ void __launch_bounds__(kHaloThreads)
    add_halo(TG* buffer, int scalars, const int* index, int n, const TG* in, const TG* saved) {
  const long long t = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= static_cast<long long>(n) * scalars) return;
  const int k = static_cast<int>(t / scalars), i = static_cast<int>(t % scalars);
  TG& v = buffer[static_cast<std::size_t>(index[k]) * scalars + i];
  const TG sum = v + in[t];
  v = saved ? sum - saved[t] : sum;
}

/// Host side: pack_halo of n listed blocks on `stream` (nothing for n = 0); every halo, shared-block and saved-sum copy
/// of the decomposition goes through here.
template <typename TG>
inline void launch_pack_halo(const TG* buffer, int scalars, const int* index, int n, TG* out, cudaStream_t stream) {
  if (n <= 0) return;
  pack_halo<TG><<<cuda::grid_for(static_cast<long long>(n) * scalars, kHaloThreads), kHaloThreads, 0, stream>>>(
      buffer, scalars, index, n, out);
  cuda::check_launch("pack_halo");
}
/// Host side: add_halo of n listed blocks on `stream` (nothing for n = 0).
template <typename TG>
inline void launch_add_halo(TG* buffer, int scalars, const int* index, int n, const TG* in, const TG* saved,
                            cudaStream_t stream) {
  if (n <= 0) return;
  add_halo<TG><<<cuda::grid_for(static_cast<long long>(n) * scalars, kHaloThreads), kHaloThreads, 0, stream>>>(
      buffer, scalars, index, n, in, saved);
  cuda::check_launch("add_halo");
}

/// One buffer of a halo or shared-block exchange: its blocks' bytes, and whether they are fixed-point words
/// (FixedGridBuffer: added as integers, exact and order-free) rather than TG scalars.
struct HaloBuffer {
  std::byte* data;
  std::size_t block_bytes;
  bool fixed = false;
};

/// launch_add_halo in the buffer's arithmetic: `block_scalars`, `in` and `saved` count TG scalars; a fixed-point
/// buffer's words are added as 64-bit integers (a float add would not even copy their bits: denormals flush).
template <typename TG>
inline void launch_add_halo_as(const HaloBuffer& b, int block_scalars, const int* index, int n, const TG* in,
                               const TG* saved, cudaStream_t stream) {
  if (b.fixed) {
    using W = unsigned long long;
    constexpr int kPer = static_cast<int>(sizeof(W) / sizeof(TG));
    launch_add_halo(reinterpret_cast<W*>(b.data), block_scalars / kPer, index, n, reinterpret_cast<const W*>(in),
                    reinterpret_cast<const W*>(saved), stream);
  } else {
    launch_add_halo(reinterpret_cast<TG*>(b.data), block_scalars, index, n, in, saved, stream);
  }
}

/// Keys of the table blocks [first, block count) that lie in the halo planes (plane[0]: shared with rank - 1,
/// plane[1]: with rank + 1; INT_MIN when there is no such neighbour), appended to keys[side] (at most `capacity`
/// each; count[side] counts them all, so the host can tell an overflow).
static __global__ void __launch_bounds__(kHaloThreads)
    collect_halo_blocks(BlockHashTableView table, int first, int axis, int plane_lo, int plane_hi,
                        unsigned long long* keys_lo, unsigned long long* keys_hi, int capacity, int* count) {
  const int b = first + blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= table.counters->block_count || b >= table.block_capacity) return;
  const Vec3i c = table.block_coords(b);
  const int along = c[axis];
  for (int side = 0; side < 2; ++side) {
    if (along != (side == 0 ? plane_lo : plane_hi)) continue;
    const int k = atomicAdd(&count[side], 1);
    if (k < capacity) (side == 0 ? keys_lo : keys_hi)[k] = BlockKey::pack(c[0], c[1], c[2]);
  }
}

// Placed bodies (comm/placement.h): a grid block may be held by any set of ranks. Each rank lists the blocks it
// shares with each other rank (sorted keys, the same list on both), and the union of those lists. A sum starts every
// shared block from zero (or from the saved sums, a delta exchange) and adds each holder's contribution in rank order,
// its own at its place: the same bits on every holder however many there are.

/// Keys of every table block [first, block count) (all are candidates for sharing), at most `capacity` into keys;
/// *count counts them all.
static __global__ void __launch_bounds__(kHaloThreads)
    collect_new_blocks(BlockHashTableView table, int first, unsigned long long* keys, int capacity, int* count) {
  const int b = first + blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= table.counters->block_count || b >= table.block_capacity) return;
  const Vec3i c = table.block_coords(b);
  const int k = atomicAdd(count, 1);
  if (k < capacity) keys[k] = BlockKey::pack(c[0], c[1], c[2]);
}

/// buffer[index[k], i] = saved[k, i] (a delta exchange's start), or 0.
template <typename TG>
__global__ void __launch_bounds__(kHaloThreads)
    start_shared(TG* buffer, int scalars, const int* index, int n, const TG* saved) {
  const long long t = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= static_cast<long long>(n) * scalars) return;
  const int k = static_cast<int>(t / scalars), i = static_cast<int>(t % scalars);
  buffer[static_cast<std::size_t>(index[k]) * scalars + i] = saved ? saved[t] : TG(0);
}

/// buffer[index[k], i] += in[k, i] - saved[upos[k], i] (a delta exchange: saved in the union's order, upos: the
/// union position of list entry k; nullptr: k itself), or += in[k, i].
template <typename TG>
__global__ void __launch_bounds__(kHaloThreads)
    add_shared(TG* buffer, int scalars, const int* index, int n, const TG* in, const TG* saved, const int* upos) {
  const long long t = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= static_cast<long long>(n) * scalars) return;
  const int k = static_cast<int>(t / scalars), i = static_cast<int>(t % scalars);
  TG& v = buffer[static_cast<std::size_t>(index[k]) * scalars + i];
  if (saved) {
    const int u = upos ? upos[k] : k;
    v += in[t] - saved[static_cast<std::size_t>(u) * scalars + i];
  } else {
    v += in[t];
  }
}

/// flags[index[k]] = 1 for the n listed blocks.
/// add_shared of n listed blocks in the buffer's arithmetic (launch_add_halo_as).
template <typename TG>
inline void launch_add_shared_as(const HaloBuffer& b, int block_scalars, const int* index, int n, const TG* in,
                                 const TG* saved, const int* upos, cudaStream_t stream) {
  if (n <= 0) return;
  if (b.fixed) {
    using W = unsigned long long;
    constexpr int kPer = static_cast<int>(sizeof(W) / sizeof(TG));
    const int scalars = block_scalars / kPer;
    add_shared<W><<<cuda::grid_for(static_cast<long long>(n) * scalars, kHaloThreads), kHaloThreads, 0, stream>>>(
        reinterpret_cast<W*>(b.data), scalars, index, n, reinterpret_cast<const W*>(in),
        reinterpret_cast<const W*>(saved), upos);
  } else {
    add_shared<TG><<<cuda::grid_for(static_cast<long long>(n) * block_scalars, kHaloThreads), kHaloThreads, 0, stream>>>(
        reinterpret_cast<TG*>(b.data), block_scalars, index, n, in, saved, upos);
  }
  cuda::check_launch("add_shared");
}

static __global__ void __launch_bounds__(kHaloThreads) mark_blocks(const int* index, int n, unsigned char* flags) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n) flags[index[k]] = 1;
}

/// The blocks of a layout that have particles, listed for the halo-first G2P2G (partition_domain.h): a particle
/// block in plane `first_lo` (the lowest plane of the slab, when there is a lower neighbour) or `first_hi` (the
/// highest, when there is an upper one) scatters into a shared grid plane (its arena is blocks B .. B + 1), so it
/// goes to the front of `order`; every other block with particles to the back. counters[0] / [1] count them (H, I).
/// The order within each part is that of the atomics: it does not matter (each block is a CUDA block of its own).
static __global__ void __launch_bounds__(kHaloThreads)
    list_particle_blocks(const int* count, int capacity, BlockHashTableView table, int axis, int first_lo,
                         int first_hi, int* order, int* counters) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= capacity || count[b] == 0) return;
  const int along = table.block_coords(b)[axis];
  if (along == first_lo || along == first_hi)
    order[atomicAdd(&counters[0], 1)] = b;
  else
    order[capacity - 1 - atomicAdd(&counters[1], 1)] = b;
}

/// Inserts the listed blocks (zeroed in both grids when new) and writes their table indices (-1: overflow).
template <typename TG>
__global__ void __launch_bounds__(kHaloThreads)
    insert_halo_blocks(BlockHashTableView table, const unsigned long long* keys, int n, int* index,
                       GridSums<TG> grid_a, GridSums<TG> grid_b) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  bool inserted = false;
  const int b = table.insert(keys[k], inserted);
  if (inserted) {
    grid_a.zero_block(b);
    grid_b.zero_block(b);
  }
  index[k] = b;
}

/// Bytes of one migrating particle's record: its stored scalars and ID, then 3 ASFLIP velocity scalars, then the
/// recorded v and C (each when present).
template <typename M, typename T>
constexpr std::size_t migrant_bytes(bool asflip, bool aux, bool jbar = false) {
  return sizeof(ParticleRecord<M, T>) + sizeof(T) * ((asflip ? 3 : 0) + (aux ? kAuxScalars : 0) + (jbar ? 1 : 0));
}

/// The layout of one side's migration message, the same on every rank: a header of one int per body (that body's
/// emigrants to this side, all of them counted even past `capacity`), padded to kHeaderBytes, then body b's area of
/// `capacity` records of `widest` bytes at header + b x capacity x widest.
struct MigrantMessage {
  static constexpr std::size_t kHeaderBytes = 256;  ///< room for 64 bodies' counts (DtParams::kMaxBodies)
  std::size_t widest = 0;                           ///< bytes of the largest body's record
  int capacity = 0;                                 ///< records per body
  int bodies = 0;
  FBAR_HOST_DEVICE std::size_t bytes() const {
    return kHeaderBytes + widest * static_cast<std::size_t>(capacity) * static_cast<std::size_t>(bodies);
  }
  FBAR_HOST_DEVICE std::size_t area(int body) const {
    return kHeaderBytes + widest * static_cast<std::size_t>(capacity) * static_cast<std::size_t>(body);
  }
};

/// Copies the emigrants G2P2G listed (list[0 .. min(*listed, list_capacity)): slots of `bins` whose dest is
/// kEmigrant) into the message of their side (at most `capacity` records each; count_lo / count_hi, the body's ints
/// in the two headers, count them all).
template <typename M, typename T>
__global__ void __launch_bounds__(kHaloThreads)
    pack_emigrants(typename ParticleLayout<M, T>::Buffer bins, const int* list, const int* listed, int list_capacity,
                   const ParticleDest* dest, const T* particle_v, const T* aux, std::byte* out_lo, std::byte* out_hi,
                   int capacity, int* count_lo, int* count_hi, const T* jbar) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= list_capacity || i >= *listed) return;
  const int slot = list[i];
  const ParticleDest d = dest[slot];
  if (d.block != kEmigrant) return;
  const int k = atomicAdd(d.rank == 0 ? count_lo : count_hi, 1);
  if (k >= capacity) return;
  const std::size_t bytes = migrant_bytes<M, T>(particle_v != nullptr, aux != nullptr, jbar != nullptr);
  std::byte* o = (d.rank == 0 ? out_lo : out_hi) + bytes * static_cast<std::size_t>(k);
  const ParticleRecord<M, T> p = load_particle<M, T>(bins, slot);
  memcpy(o, &p, sizeof(p));
  o += sizeof(p);
  if (particle_v) {
    memcpy(o, particle_v + 3 * static_cast<std::size_t>(slot), 3 * sizeof(T));
    o += 3 * sizeof(T);
  }
  if (aux) {
    memcpy(o, aux + kAuxScalars * static_cast<std::size_t>(slot), kAuxScalars * sizeof(T));
    o += kAuxScalars * sizeof(T);
  }
  if (jbar) memcpy(o, jbar + slot, sizeof(T));
}

/// Writes the n = min(*count, capacity) received records to slots first .. first + n - 1 of `bins` (and of
/// particle_v / aux) and marks them valid (valid[slot] = slot) for the partition; slots first + n .. first +
/// capacity - 1 are marked empty (-1). The count is read on the device: the host learns it with the step's readback.
template <typename M, typename T>
__global__ void __launch_bounds__(kHaloThreads)
    unpack_immigrants(typename ParticleLayout<M, T>::Buffer bins, int first, const std::byte* in, const int* count,
                      int capacity, T* particle_v, T* aux, int* valid, T* jbar) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= capacity) return;
  const int slot = first + k;
  if (k >= *count) {  // past the records sent (a count past the capacity is an overflow: the step is repeated)
    valid[slot] = -1;
    return;
  }
  const std::size_t bytes = migrant_bytes<M, T>(particle_v != nullptr, aux != nullptr, jbar != nullptr);
  const std::byte* r = in + bytes * static_cast<std::size_t>(k);
  ParticleRecord<M, T> p;
  memcpy(&p, r, sizeof(p));
  r += sizeof(p);
  store_particle<M, T>(bins, slot, p);
  if (particle_v) {
    memcpy(particle_v + 3 * static_cast<std::size_t>(slot), r, 3 * sizeof(T));
    r += 3 * sizeof(T);
  }
  if (aux) {
    memcpy(aux + kAuxScalars * static_cast<std::size_t>(slot), r, kAuxScalars * sizeof(T));
    r += kAuxScalars * sizeof(T);
  }
  if (jbar) memcpy(jbar + slot, r, sizeof(T));
  valid[slot] = slot;
}

/// The step's migration counts for the host: body b's emigrants to each side (the headers of the outgoing messages)
/// and immigrants from each side (the received headers; nullptr: no neighbour there), into its BodyStepStats.
static __global__ void record_migrant_counts(int bodies, const int* out_lo, const int* out_hi, const int* in_lo,
                                             const int* in_hi, BodyStepStats* body_stats) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= bodies) return;
  body_stats[b].emigrants[0] = out_lo[b];
  body_stats[b].emigrants[1] = out_hi[b];
  body_stats[b].immigrants[0] = in_lo ? in_lo[b] : 0;
  body_stats[b].immigrants[1] = in_hi ? in_hi[b] : 0;
}

}  // namespace fbar
