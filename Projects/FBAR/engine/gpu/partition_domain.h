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
// halo_tag (per block) is reserved for the multi-GPU partition (0 = interior); single-GPU runs leave it 0.
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

/// Device arrays of one layout, as kernels see them (passed by value).
struct LayoutView {
  int* count;       ///< (block) particles per block
  int* bin_offset;  ///< (block + 1) first bin of each block
  int* src;         ///< (slot) storage slot of the particle, -1 for an empty lane
};

/// Owner of a body's partition arrays (two layouts, dest, scan scratch, halo tags).
class PartitionDomain {
 public:
  PartitionDomain() = default;
  PartitionDomain(const PartitionDomain&) = delete;
  PartitionDomain& operator=(const PartitionDomain&) = delete;
  ~PartitionDomain() { release(); }

  /// Sizes the per-block arrays for `blocks` blocks and the per-slot arrays for `bins` bins (contents lost).
  void allocate(int blocks, int bins) {
    release();
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
    bins_per_block_ = static_cast<int*>(cuda::device_malloc(sizeof(int) * (blocks + 1), "partition arrays"));
    halo_tag_ = static_cast<unsigned char*>(cuda::device_malloc(blocks, "partition arrays"));
    FBAR_CUDA_CHECK(cudaMemset(halo_tag_, 0, blocks));
  }

  /// Grows the per-block arrays keeping layout `keep` (counts and offsets of blocks [0, old capacity)).
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
    cudaFree(halo_tag_);
    bins_per_block_ = static_cast<int*>(cuda::device_malloc(sizeof(int) * (blocks + 1), "partition arrays"));
    halo_tag_ = static_cast<unsigned char*>(cuda::device_malloc(blocks, "partition arrays"));
    FBAR_CUDA_CHECK(cudaMemsetAsync(halo_tag_, 0, blocks, stream));
    block_capacity_ = blocks;
  }

  /// Grows the per-slot arrays: src of layout `keep` is kept, the other src and dest are reallocated empty.
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
    bin_capacity_ = bins;
  }

  LayoutView layout(int l) const { return LayoutView{count_[l], bin_offset_[l], src_[l]}; }
  ParticleDest* dest() const { return dest_; }
  int* bins_per_block() const { return bins_per_block_; }
  unsigned char* halo_tag() const { return halo_tag_; }
  int block_capacity() const { return block_capacity_; }
  int bin_capacity() const { return bin_capacity_; }
  std::size_t slots() const { return static_cast<std::size_t>(bin_capacity_) * 32; }
  std::size_t bytes() const {
    return static_cast<std::size_t>(block_capacity_) * (2 * 2 * sizeof(int) + sizeof(int) + 1) +
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
    if (halo_tag_) cudaFree(halo_tag_);
    dest_ = nullptr;
    bins_per_block_ = nullptr;
    halo_tag_ = nullptr;
  }

  int* count_[2] = {nullptr, nullptr};
  int* bin_offset_[2] = {nullptr, nullptr};
  int* src_[2] = {nullptr, nullptr};
  ParticleDest* dest_ = nullptr;
  int* bins_per_block_ = nullptr;
  unsigned char* halo_tag_ = nullptr;
  int block_capacity_ = 0;
  int bin_capacity_ = 0;
};

}  // namespace fbar
