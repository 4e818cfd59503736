// Partition of one body on one device: which particle block every particle is in, and where its bin lives.
//
// A "layout" is the bin order G2P2G walks: particles grouped by particle block (the grid block B with
// B = floor((base - 1) / 4), base = floor(x/dx - 0.5) the stencil base node; see kernels/g2p2g_kernel.cuh for the
// off-by-2 derivation), each block owning ceil(count / 32) consecutive bins. Per block index of the hash table:
//   count[b]       particles of the body in block b
//   bin_offset[b]  first bin of block b (exclusive scan of ceil(count / 32); bin_offset[capacity] = total bins)
// per slot (bin * 32 + lane) of the layout:
//   src[slot]      where the particle is stored now (slot of the buffer written by the previous G2P2G), -1 = empty
// Claymore's fused reorder: G2P2G reads its particles through src (a gather that stays mostly within a few old
// bins) and writes them in layout order, so the reorder costs no pass of its own. While it runs it records, per
// slot, the particle's next block and its rank there (dest), which the partition kernels turn into the next
// layout's src. Layouts are double-buffered so a failed step can be repeated from the untouched one.
// Decomposed runs with the halo overlap (ordered domains) also list, per layout, the blocks that have particles, halo particle blocks first:
//   order[0, H)                 the blocks whose P2G reaches a grid plane shared with a neighbour (G2P2G runs them
//                               first, so the halo exchange overlaps the rest)
//   order[capacity - I, capacity)  the other I blocks with particles
// (the counts H and I come back with the step's statistics; one-GPU runs have no order arrays and launch over every
// table block).
#pragma once

#include <cuda_runtime.h>

#include <cstddef>

#include "MnSystem/Cuda/device_query.h"

namespace fbar {

/// The next block and the rank inside it that G2P2G records for the particle at a layout slot.
struct ParticleDest {
  int block;  ///< hash-table block index, -1 when the particle failed a check or the table overflowed,
              ///< kEmigrant when another rank owns its next block (rank: 0 the lower neighbour, 1 the upper)
  int rank;   ///< 0-based rank among the block's particles (arbitrary order: atomic arrival)
};
inline constexpr int kEmigrant = -2;
/// ParticleDest::block of a G2P2G lane without a particle (the padding of a block's last bin): the partition needs no
/// other record of which slots hold particles.
inline constexpr int kNoParticle = -3;

/// Device arrays of one layout, as kernels see them (passed by value).
struct LayoutView {
  int* count;       ///< (block) particles per block
  int* bin_offset;  ///< (block + 1) first bin of each block
  int* src;         ///< (slot) storage slot of the particle, -1 for an empty lane
  int* order;       ///< (block) halo particle blocks from the front, the others from the back; nullptr: not listed
};

/// Owner of a body's partition arrays (two layouts, dest, scan scratch; block lists when ordered).
class PartitionDomain {
 public:
  PartitionDomain() = default;
  PartitionDomain(const PartitionDomain&) = delete;
  PartitionDomain& operator=(const PartitionDomain&) = delete;
  ~PartitionDomain() { release(); }

  /// Sizes the per-block arrays for `blocks` blocks and the per-slot arrays for `bins` bins (contents lost);
  /// ordered: with the block lists of a decomposed run.
  void allocate(int blocks, int bins, bool ordered = false) {
    release();
    ordered_ = ordered;
    block_capacity_ = blocks;
    bin_capacity_ = bins;
    for (int l = 0; l < 2; ++l) {
      count_[l] = static_cast<int*>(cuda::device_malloc(sizeof(int) * blocks, "partition arrays"));
      bin_offset_[l] = static_cast<int*>(cuda::device_malloc(sizeof(int) * (blocks + 1), "partition arrays"));
      src_[l] = static_cast<int*>(cuda::device_malloc(sizeof(int) * slots(), "partition arrays"));
      FBAR_CUDA_CHECK(cudaMemset(src_[l], 0xff, sizeof(int) * slots()));  // -1: empty (growth copies all slots)
      FBAR_CUDA_CHECK(cudaMemset(count_[l], 0, sizeof(int) * blocks));
      FBAR_CUDA_CHECK(cudaMemset(bin_offset_[l], 0, sizeof(int) * (blocks + 1)));
    }
    dest_ = static_cast<ParticleDest*>(cuda::device_malloc(sizeof(ParticleDest) * slots(), "partition arrays"));
    FBAR_CUDA_CHECK(cudaMemset(dest_, 0xff, sizeof(ParticleDest) * slots()));  // block -1: no destination
    bins_per_block_ = static_cast<int*>(cuda::device_malloc(sizeof(int) * (blocks + 1), "partition arrays"));
    allocate_order(blocks);
    // The memsets above ran on the legacy stream, which the engine's non-blocking streams do not wait for: done
    // before anything is queued after them (with other runs on the device they may otherwise land later).
    FBAR_CUDA_CHECK(cudaStreamSynchronize(cudaStreamLegacy));
  }

  /// Grows the per-block arrays keeping layout `keep` (counts and offsets of blocks [0, old capacity)). The block
  /// lists are not kept: list the kept layout again (the same counts give the same H and I).
  void grow_blocks(int blocks, int keep, cudaStream_t stream) {
    for (int l = 0; l < 2; ++l) {
      int* c = nullptr;
      int* o = nullptr;
      c = static_cast<int*>(cuda::device_malloc(sizeof(int) * blocks, "partition arrays"));
      o = static_cast<int*>(cuda::device_malloc(sizeof(int) * (blocks + 1), "partition arrays"));
      FBAR_CUDA_CHECK(cudaMemsetAsync(c, 0, sizeof(int) * blocks, stream));
      FBAR_CUDA_CHECK(cudaMemsetAsync(o, 0, sizeof(int) * (blocks + 1), stream));
      if (l == keep) {
        FBAR_CUDA_CHECK(cudaMemcpyAsync(c, count_[l], sizeof(int) * block_capacity_, cudaMemcpyDeviceToDevice, stream));
        FBAR_CUDA_CHECK(
            cudaMemcpyAsync(o, bin_offset_[l], sizeof(int) * block_capacity_, cudaMemcpyDeviceToDevice, stream));
      }
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream));
      cudaFree(count_[l]);
      cudaFree(bin_offset_[l]);
      count_[l] = c;
      bin_offset_[l] = o;
    }
    cudaFree(bins_per_block_);
    free_order();
    bins_per_block_ = static_cast<int*>(cuda::device_malloc(sizeof(int) * (blocks + 1), "partition arrays"));
    allocate_order(blocks);
    block_capacity_ = blocks;
  }

  /// Grows the per-slot arrays: src of layout `keep` is kept, the other src and dest are reallocated empty (dest:
  /// block -1, no destination).
  void grow_bins(int bins, int keep, cudaStream_t stream) {
    const std::size_t new_slots = static_cast<std::size_t>(bins) * 32;
    for (int l = 0; l < 2; ++l) {
      int* s = nullptr;
      s = static_cast<int*>(cuda::device_malloc(sizeof(int) * new_slots, "partition arrays"));
      FBAR_CUDA_CHECK(cudaMemsetAsync(s, 0xff, sizeof(int) * new_slots, stream));  // -1: empty
      if (l == keep)
        FBAR_CUDA_CHECK(cudaMemcpyAsync(s, src_[l], sizeof(int) * slots(), cudaMemcpyDeviceToDevice, stream));
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream));
      cudaFree(src_[l]);
      src_[l] = s;
    }
    cudaFree(dest_);
    dest_ = static_cast<ParticleDest*>(cuda::device_malloc(sizeof(ParticleDest) * new_slots, "partition arrays"));
    FBAR_CUDA_CHECK(cudaMemsetAsync(dest_, 0xff, sizeof(ParticleDest) * new_slots, stream));
    bin_capacity_ = bins;
  }

  LayoutView layout(int l) const { return LayoutView{count_[l], bin_offset_[l], src_[l], order_[l]}; }
  bool ordered() const { return ordered_; }
  int* list_counters() const { return list_counters_; }  ///< 2 device ints: scratch for listing a layout again
  ParticleDest* dest() const { return dest_; }
  int* bins_per_block() const { return bins_per_block_; }
  int block_capacity() const { return block_capacity_; }
  int bin_capacity() const { return bin_capacity_; }
  std::size_t slots() const { return static_cast<std::size_t>(bin_capacity_) * 32; }
  std::size_t bytes() const {
    return static_cast<std::size_t>(block_capacity_) * (2 * 2 * sizeof(int) + sizeof(int) + (ordered_ ? 2 * sizeof(int) : 0)) +
           slots() * (2 * sizeof(int) + sizeof(ParticleDest));
  }

 private:
  void release() {
    for (int l = 0; l < 2; ++l) {
      if (count_[l]) cudaFree(count_[l]);
      if (bin_offset_[l]) cudaFree(bin_offset_[l]);
      if (src_[l]) cudaFree(src_[l]);
      count_[l] = bin_offset_[l] = src_[l] = nullptr;
    }
    if (dest_) cudaFree(dest_);
    if (bins_per_block_) cudaFree(bins_per_block_);
    free_order();
    dest_ = nullptr;
    bins_per_block_ = nullptr;
  }
  void allocate_order(int blocks) {
    if (!ordered_) return;
    for (int l = 0; l < 2; ++l) order_[l] = static_cast<int*>(cuda::device_malloc(sizeof(int) * blocks, "partition arrays"));
    list_counters_ = static_cast<int*>(cuda::device_malloc(2 * sizeof(int), "partition arrays"));
  }
  void free_order() {
    for (int l = 0; l < 2; ++l) {
      if (order_[l]) cudaFree(order_[l]);
      order_[l] = nullptr;
    }
    if (list_counters_) cudaFree(list_counters_);
    list_counters_ = nullptr;
  }

  int* count_[2] = {nullptr, nullptr};
  int* bin_offset_[2] = {nullptr, nullptr};
  int* src_[2] = {nullptr, nullptr};
  ParticleDest* dest_ = nullptr;
  int* bins_per_block_ = nullptr;
  int* order_[2] = {nullptr, nullptr};
  int* list_counters_ = nullptr;
  bool ordered_ = false;
  int block_capacity_ = 0;
  int bin_capacity_ = 0;
};

}  // namespace fbar
