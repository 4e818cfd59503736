// GPU hash table from packed grid-block coordinates to active block indices (open addressing, linear probing).
//
// Claymore indexes blocks through a dense table over the whole domain (512 MB at 2^11 cells per axis); fbar sizes a
// real hash table from the scene instead: `slot_capacity` (a power of two, at least twice the block capacity, so the
// load factor stays <= 1/2 and probes stay short) slots of {key: u64, value: i32}. Keys pack the three block
// coordinates in 21 bits each with a bias of 2^20 (the CPU engine's packing: coordinates in [-2^20, 2^20)).
//
// Protocol (lock-free, insert-only between growths and compactions):
//   insert: atomicCAS claims an empty slot for the key; the winner takes the next block index with atomicAdd on
//           the block counter, records the block coordinates, and publishes the index with a release store. A thread
//           that finds the key already claimed spins (acquire loads) until the index is published; the publisher is
//           a thread past its CAS, so the wait is finite (independent thread scheduling, sm_70+).
//   find:   used only in launches after the inserting launch (kernel boundaries order memory), no spinning.
// Indices are dense [0, block_count) in insertion order and do not change as blocks are added, so grid buffers
// indexed by them stay valid (grow() keeps every index). renumber() is the one exception: the driver's grid
// compaction (MgspBenchmark::compact_grid) drops the blocks nothing uses any more between two steps and moves every
// per-block buffer with the table.
// Failure is never silent: an insert past the block capacity or after kMaxProbes slots sets a flag the host reads
// every step (TableStats), and the host grows the table before retrying the partition.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "MnSystem/Cuda/allocators.h"

namespace fbar {

/// Packing of block coordinates into 63-bit keys (same bias and widths as the CPU engine).
struct BlockKey {
  static constexpr int kBias = 1 << 20;
  static constexpr std::uint64_t kEmpty = ~std::uint64_t(0);  ///< never a packed key (bit 63 is always 0)

  FBAR_HOST_DEVICE static constexpr std::uint64_t pack(int x, int y, int z) {
    return (static_cast<std::uint64_t>(x + kBias) << 42) | (static_cast<std::uint64_t>(y + kBias) << 21) |
           static_cast<std::uint64_t>(z + kBias);
  }
  FBAR_HOST_DEVICE static constexpr Vec3i unpack(std::uint64_t key) {
    return Vec3i{{static_cast<int>((key >> 42) & 0x1fffff) - kBias, static_cast<int>((key >> 21) & 0x1fffff) - kBias,
                  static_cast<int>(key & 0x1fffff) - kBias}};
  }
  /// Key of neighbour n of the 2x2x2 arena that starts at block `origin`: the block + (n >> 2, (n >> 1) & 1, n & 1),
  /// so neighbour = (di * 2 + dj) * 2 + dk (G2P2G's arena, the footprint the partition activates, a mesh's stencil).
  FBAR_HOST_DEVICE static constexpr std::uint64_t arena_neighbour(const Vec3i& origin, int n) {
    return pack(origin[0] + (n >> 2), origin[1] + ((n >> 1) & 1), origin[2] + (n & 1));
  }
  /// Coordinates representable by pack() (a particle far outside the domain must not alias another block).
  FBAR_HOST_DEVICE static constexpr bool representable(int x, int y, int z) {
    return x >= -kBias && x < kBias && y >= -kBias && y < kBias && z >= -kBias && z < kBias;
  }
  /// splitmix64 finaliser: neighbouring blocks land far apart, so linear probing sees short clusters.
  FBAR_HOST_DEVICE static constexpr std::uint64_t hash(std::uint64_t k) {
    k ^= k >> 30;
    k *= 0xbf58476d1ce4e5b9ull;
    k ^= k >> 27;
    k *= 0x94d049bb133111ebull;
    k ^= k >> 31;
    return k;
  }
};

/// Device counters of the table, read by the host with the step's statistics.
struct TableCounters {
  int block_count;   ///< blocks inserted so far (indices [0, block_count))
  int overflow;      ///< inserts refused: block capacity reached or probe limit hit (grow and retry)
};

/// Kernel-side view of the table, passed by value (a handful of pointers and sizes).
struct BlockHashTableView {
  static constexpr int kMaxProbes = 128;

  unsigned long long* keys;  ///< (slot) packed key or BlockKey::kEmpty
  int* values;               ///< (slot) block index, -1 until published
  int* coords;               ///< (block, axis) block coordinates, 3 ints per block
  TableCounters* counters;
  std::uint32_t slot_mask;   ///< slot_capacity - 1 (a power of two)
  int block_capacity;        ///< most blocks the grid buffers can hold
  /// (block, neighbour) a cache of each block's 2x2x2 arena (the block itself and its +x/+y/+z neighbours,
  /// neighbour = (di * 2 + dj) * 2 + dk): the index once a kernel has looked it up, -1 before. Valid while
  /// indices do not change (growth keeps them and the cache, renumber() renumbers the cache, clear() resets both).
  int* arena = nullptr;

  /// Index of neighbour n of block `block` (at `origin`) of its arena, -1 when absent: from the cache, else looked up
  /// and cached. For launches after the inserting one (as find).
  FBAR_DEVICE int find_arena(int block, const Vec3i& origin, int n) const {
    int index = arena[8 * block + n];
    if (index < 0) {
      index = find(BlockKey::arena_neighbour(origin, n));
      if (index >= 0) arena[8 * block + n] = index;  // another CUDA block may write the same value: benign
    }
    return index;
  }

  /// As find_arena, inserting the neighbour when the table lacks it (`inserted`: this call created it). -1 (and the
  /// overflow counter raised) as insert.
  FBAR_DEVICE int insert_arena(int block, const Vec3i& origin, int n, bool& inserted) const {
    inserted = false;
    int index = arena[8 * block + n];
    if (index < 0) {
      index = insert(BlockKey::arena_neighbour(origin, n), inserted);
      if (index >= 0) arena[8 * block + n] = index;
    }
    return index;
  }

  /// Index of the block `key`, or -1 when it is not in the table. For launches after the inserting one.
  FBAR_DEVICE int find(std::uint64_t key) const {
    std::uint32_t slot = static_cast<std::uint32_t>(BlockKey::hash(key)) & slot_mask;
    for (int probe = 0; probe < kMaxProbes; ++probe) {
      const unsigned long long k = keys[slot];
      if (k == key) return values[slot];
      if (k == BlockKey::kEmpty) return -1;
      slot = (slot + 1) & slot_mask;
    }
    return -1;
  }

  /// Index of block `key`, inserting it when absent; `inserted` says whether this call created it. -1 (and the
  /// overflow counter raised) when the block capacity or the probe limit is exceeded.
  FBAR_DEVICE int insert(std::uint64_t key, bool& inserted) const {
    inserted = false;
    std::uint32_t slot = static_cast<std::uint32_t>(BlockKey::hash(key)) & slot_mask;
    for (int probe = 0; probe < kMaxProbes; ++probe) {
      unsigned long long k = keys[slot];
      if (k == BlockKey::kEmpty) k = atomicCAS(&keys[slot], BlockKey::kEmpty, static_cast<unsigned long long>(key));
      if (k == BlockKey::kEmpty) {  // this thread claimed the slot
        const int index = atomicAdd(&counters->block_count, 1);
        if (index >= block_capacity) {
          atomicAdd(&counters->overflow, 1);
          // Publish -2: finders stop spinning and report overflow too; the host rebuilds from scratch on growth.
          atomicExch(&values[slot], -2);
          return -1;
        }
        const Vec3i c = BlockKey::unpack(key);
        coords[3 * index + 0] = c[0];
        coords[3 * index + 1] = c[1];
        coords[3 * index + 2] = c[2];
        __threadfence();
        atomicExch(&values[slot], index);
        inserted = true;
        return index;
      }
      if (k == key) {  // claimed by someone else: wait for the published index
        // A volatile load (L2), not an atomic: many warps look up the same hot block every step.
        int v;
        do {
          v = *static_cast<volatile int*>(&values[slot]);
        } while (v == -1);
        if (v < 0) {
          atomicAdd(&counters->overflow, 1);
          return -1;
        }
        return v;
      }
      slot = (slot + 1) & slot_mask;
    }
    atomicAdd(&counters->overflow, 1);
    return -1;
  }

  FBAR_DEVICE Vec3i block_coords(int index) const {
    return Vec3i{{coords[3 * index + 0], coords[3 * index + 1], coords[3 * index + 2]}};
  }
};

namespace hash_table_detail {

static __global__ void reset_slots(unsigned long long* keys, int* values, std::uint32_t slots) {
  const std::uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < slots) {
    keys[i] = BlockKey::kEmpty;
    values[i] = -1;
  }
}

/// Re-inserts every published entry of an old table into a new one keeping its block index.
static __global__ void rehash_slots(const unsigned long long* old_keys, const int* old_values, std::uint32_t old_slots,
                             BlockHashTableView table) {
  const std::uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= old_slots) return;
  const unsigned long long key = old_keys[i];
  const int value = old_values[i];
  if (key == BlockKey::kEmpty || value < 0) return;
  std::uint32_t slot = static_cast<std::uint32_t>(BlockKey::hash(key)) & table.slot_mask;
  for (int probe = 0; probe <= static_cast<int>(table.slot_mask); ++probe) {
    if (atomicCAS(&table.keys[slot], BlockKey::kEmpty, key) == BlockKey::kEmpty) {
      table.values[slot] = value;
      return;
    }
    slot = (slot + 1) & table.slot_mask;
  }
  atomicAdd(&table.counters->overflow, 1);
}

/// Compaction (BlockHashTable::renumber): new block i is old block old_of_new[i]; its coordinates and its arena
/// cache (a neighbour that was dropped: -1) into coords_out and arena_out.
static __global__ void renumber_blocks(BlockHashTableView table, const int* old_of_new, const int* new_index, int kept,
                                       int* coords_out, int* arena_out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= kept) return;
  const int old = old_of_new[i];
  for (int a = 0; a < 3; ++a) coords_out[3 * i + a] = table.coords[3 * old + a];
  for (int n = 0; n < 8; ++n) {
    const int v = table.arena[8 * old + n];
    arena_out[8 * i + n] = v >= 0 ? new_index[v] : -1;
  }
}

/// Compaction: the keys of blocks [0, kept) (from their coordinates) into the emptied slots, each with its index.
static __global__ void insert_renumbered(BlockHashTableView table, int kept) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= kept) return;
  const Vec3i c = table.block_coords(i);
  const unsigned long long key = BlockKey::pack(c[0], c[1], c[2]);
  std::uint32_t slot = static_cast<std::uint32_t>(BlockKey::hash(key)) & table.slot_mask;
  for (int probe = 0; probe <= static_cast<int>(table.slot_mask); ++probe) {
    if (atomicCAS(&table.keys[slot], BlockKey::kEmpty, key) == BlockKey::kEmpty) {
      table.values[slot] = i;
      return;
    }
    slot = (slot + 1) & table.slot_mask;
  }
  atomicAdd(&table.counters->overflow, 1);
}

static __global__ void set_block_count(TableCounters* counters, int count) {
  counters->block_count = count;
  counters->overflow = 0;
}

/// After a growth: blocks whose insert overflowed were never recorded; the count restarts at the old capacity.
static __global__ void clamp_block_count(TableCounters* counters, int old_capacity) {
  if (counters->block_count > old_capacity) counters->block_count = old_capacity;
}

inline std::uint32_t next_pow2(std::size_t n) {
  std::uint32_t p = 1024;
  while (p < n) p <<= 1;
  return p;
}

}  // namespace hash_table_detail

/// Owner of the table's device memory (one per device state object; no globals).
class BlockHashTable {
 public:
  BlockHashTable() = default;
  BlockHashTable(const BlockHashTable&) = delete;
  BlockHashTable& operator=(const BlockHashTable&) = delete;
  ~BlockHashTable() { release(); }

  /// Allocates for `block_capacity` blocks (slots: next power of two >= 2 x capacity) and empties the table.
  void allocate(int block_capacity, cudaStream_t stream) {
    release();
    block_capacity_ = block_capacity;
    slots_ = hash_table_detail::next_pow2(2 * static_cast<std::size_t>(block_capacity));
    allocate_arrays(stream);
    clear(stream);
  }

  /// Removes every block (counters to 0, every slot empty).
  void clear(cudaStream_t stream) {
    hash_table_detail::reset_slots<<<(slots_ + 255) / 256, 256, 0, stream>>>(keys_, values_, slots_);
    FBAR_CUDA_CHECK(cudaGetLastError());
    FBAR_CUDA_CHECK(cudaMemsetAsync(counters_, 0, sizeof(TableCounters), stream));
    FBAR_CUDA_CHECK(cudaMemsetAsync(arena_, 0xff, arena_bytes(block_capacity_), stream));
  }

  /// Grows to `block_capacity` blocks keeping every key and block index (and the block counter). The overflow
  /// counter is reset; the caller redoes the inserts that overflowed.
  void grow(int block_capacity, cudaStream_t stream) {
    unsigned long long* old_keys = keys_;
    int* old_values = values_;
    int* old_coords = coords_;
    int* old_arena = arena_;
    TableCounters* old_counters = counters_;
    const std::uint32_t old_slots = slots_;
    const int old_capacity = block_capacity_;
    block_capacity_ = block_capacity;
    slots_ = hash_table_detail::next_pow2(2 * static_cast<std::size_t>(block_capacity));
    allocate_arrays(stream);
    hash_table_detail::reset_slots<<<(slots_ + 255) / 256, 256, 0, stream>>>(keys_, values_, slots_);
    FBAR_CUDA_CHECK(cudaGetLastError());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(coords_, old_coords, sizeof(int) * 3 * static_cast<std::size_t>(old_capacity),
                                    cudaMemcpyDeviceToDevice, stream));
    FBAR_CUDA_CHECK(cudaMemcpyAsync(arena_, old_arena, arena_bytes(old_capacity), cudaMemcpyDeviceToDevice, stream));
    FBAR_CUDA_CHECK(cudaMemcpyAsync(counters_, old_counters, sizeof(TableCounters), cudaMemcpyDeviceToDevice, stream));
    FBAR_CUDA_CHECK(cudaMemsetAsync(&counters_->overflow, 0, sizeof(int), stream));
    hash_table_detail::clamp_block_count<<<1, 1, 0, stream>>>(counters_, old_capacity);
    FBAR_CUDA_CHECK(cudaGetLastError());
    hash_table_detail::rehash_slots<<<(old_slots + 255) / 256, 256, 0, stream>>>(old_keys, old_values, old_slots,
                                                                                 view());
    FBAR_CUDA_CHECK(cudaGetLastError());
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream));
    cuda::DeviceAllocator device;
    device.deallocate(old_keys, 0);
    device.deallocate(old_values, 0);
    device.deallocate(old_coords, 0);
    device.deallocate(old_arena, 0);
    device.deallocate(old_counters, 0);
  }

  /// Compaction: keeps the `kept` blocks old_of_new[0, kept) (old indices) as blocks [0, kept), in that order;
  /// new_index: (old block, of old_count) its new index or -1 (dropped). Coordinates and arena caches follow (a
  /// cached neighbour that was dropped is looked up again when needed); the slots are rebuilt. scratch: 11 ints per
  /// kept block. The caller moves every per-block buffer alike.
  void renumber(const int* old_of_new, const int* new_index, int kept, int old_count, int* scratch,
                cudaStream_t stream) {
    int* coords_out = scratch;
    int* arena_out = scratch + 3 * static_cast<std::size_t>(kept);
    const int threads = 256;
    if (kept > 0) {
      hash_table_detail::renumber_blocks<<<(kept + threads - 1) / threads, threads, 0, stream>>>(
          view(), old_of_new, new_index, kept, coords_out, arena_out);
      FBAR_CUDA_CHECK(cudaGetLastError());
      FBAR_CUDA_CHECK(cudaMemcpyAsync(coords_, coords_out, sizeof(int) * 3 * static_cast<std::size_t>(kept),
                                      cudaMemcpyDeviceToDevice, stream));
      FBAR_CUDA_CHECK(cudaMemcpyAsync(arena_, arena_out, arena_bytes(kept), cudaMemcpyDeviceToDevice, stream));
    }
    if (old_count > kept)
      FBAR_CUDA_CHECK(cudaMemsetAsync(arena_ + 8 * static_cast<std::size_t>(kept), 0xff,
                                      arena_bytes(old_count) - arena_bytes(kept), stream));
    hash_table_detail::reset_slots<<<(slots_ + 255) / 256, 256, 0, stream>>>(keys_, values_, slots_);
    FBAR_CUDA_CHECK(cudaGetLastError());
    hash_table_detail::set_block_count<<<1, 1, 0, stream>>>(counters_, kept);
    FBAR_CUDA_CHECK(cudaGetLastError());
    if (kept > 0) {
      hash_table_detail::insert_renumbered<<<(kept + threads - 1) / threads, threads, 0, stream>>>(view(), kept);
      FBAR_CUDA_CHECK(cudaGetLastError());
    }
  }

  BlockHashTableView view() const {
    return BlockHashTableView{keys_, values_, coords_, counters_, slots_ - 1, block_capacity_, arena_};
  }
  int block_capacity() const { return block_capacity_; }
  std::uint32_t slot_capacity() const { return slots_; }
  TableCounters* counters() const { return counters_; }
  std::size_t bytes() const {
    return static_cast<std::size_t>(slots_) * (sizeof(unsigned long long) + sizeof(int)) +
           static_cast<std::size_t>(block_capacity_) * 3 * sizeof(int) + arena_bytes(block_capacity_) +
           sizeof(TableCounters);
  }

 private:
  static std::size_t arena_bytes(int block_capacity) {
    return sizeof(int) * 8 * static_cast<std::size_t>(block_capacity);
  }
  /// The arrays for block_capacity_ and slots_, their initial contents set on `stream`: grow() copies the old
  /// contents on the same stream after them (a memset on the legacy stream is not ordered with a non-blocking
  /// stream: with other runs' work on the device it could land after the copy and erase it).
  void allocate_arrays(cudaStream_t stream) {
    cuda::DeviceAllocator device;
    arena_ = static_cast<int*>(device.allocate(arena_bytes(block_capacity_)));
    FBAR_CUDA_CHECK(cudaMemsetAsync(arena_, 0xff, arena_bytes(block_capacity_), stream));  // no index cached
    keys_ = static_cast<unsigned long long*>(device.allocate(sizeof(unsigned long long) * slots_));
    values_ = static_cast<int*>(device.allocate(sizeof(int) * slots_));
    coords_ = static_cast<int*>(device.allocate(sizeof(int) * 3 * static_cast<std::size_t>(block_capacity_)));
    counters_ = static_cast<TableCounters*>(device.allocate(sizeof(TableCounters)));
    // Coordinates of blocks not inserted yet are never read, but growth copies the whole array: keep it defined.
    FBAR_CUDA_CHECK(cudaMemsetAsync(coords_, 0, sizeof(int) * 3 * static_cast<std::size_t>(block_capacity_), stream));
  }
  void release() {
    cuda::DeviceAllocator device;
    if (keys_) {
      // Destructors must not throw: ignore failures at teardown (the context may be gone).
      cudaFree(keys_);
      cudaFree(values_);
      cudaFree(coords_);
      cudaFree(arena_);
      cudaFree(counters_);
    }
    (void)device;
    keys_ = nullptr;
    values_ = nullptr;
    coords_ = nullptr;
    arena_ = nullptr;
    counters_ = nullptr;
  }

  unsigned long long* keys_ = nullptr;
  int* values_ = nullptr;
  int* coords_ = nullptr;
  int* arena_ = nullptr;  ///< (block, neighbour) BlockHashTableView::arena
  TableCounters* counters_ = nullptr;
  std::uint32_t slots_ = 0;
  int block_capacity_ = 0;
};

}  // namespace fbar
