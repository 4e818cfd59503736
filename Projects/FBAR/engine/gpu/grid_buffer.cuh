// Grid buffers of the GPU engine: a run-time number of 4x4x4-node blocks, SoA inside a block (Library structurals).
//
// Two kinds of buffer share the block indexing of the hash table (hash_table.cuh):
//   GridBuffer<T>          mass + momentum (4 channels): what P2G accumulates. Double-buffered by the driver:
//                          G2P2G of step n reads the velocities of step n and scatters into the other buffer.
//   GridFbarBuffer<T>      F-bar's cell sums (2 channels, transfer.cuh), only when a body uses F-bar.
//   GridPoreBuffer<T>      the seepage channels of saturated bodies (5 channels, physics/seepage.cuh), only when a
//                          body is saturated (CoupledUP): P2G sums, then the grid update's node values in place.
//   GridVelocityBuffer<T>  velocity (3 channels): what the grid update writes and G2P reads. Keeping it apart from
//                          the momentum leaves the P2G sums of step n intact until step n commits, which is what
//                          a retried step (on_failure = reduce_dt) and a changed dt need (see mgsp_benchmark.cuh).
// Byte layout of block b (channel c, node (i, j, k) = 16 i + 4 j + k), T = float:
//   b * 1024 + c * 256 + node * 4     (mass c = 0, momentum x/y/z c = 1..3; velocity buffer: 768 B per block)
// so a warp reading one channel of 32 consecutive nodes reads 128 contiguous bytes.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <cstddef>

#include "MnBase/Memory/structural_instance.h"
#include "MnBase/Meta/placeholder.h"
#include "MnSystem/Cuda/allocators.h"
#include "engine/gpu/block_access.cuh"
#include "settings.h"

namespace fbar {

/// Named grid channels (placeholder indices of the block structural).
inline constexpr auto grid_mass = placeholder::_0;        ///< [kg]
inline constexpr auto grid_momentum_x = placeholder::_1;  ///< [kg m/s]
inline constexpr auto grid_momentum_y = placeholder::_2;
inline constexpr auto grid_momentum_z = placeholder::_3;
inline constexpr auto grid_velocity_x = placeholder::_0;  ///< [m/s] (velocity buffer)
inline constexpr auto grid_velocity_y = placeholder::_1;
inline constexpr auto grid_velocity_z = placeholder::_2;
inline constexpr auto grid_fbar_compression = placeholder::_0;  ///< [m^3] F-bar cell sum of V0 (1 - J) (cell at node)
inline constexpr auto grid_fbar_volume = placeholder::_1;       ///< [m^3] F-bar cell sum of V0
// Seepage channels (physics/seepage.cuh): what the seepage P2G sums, and what the grid update leaves in their place.
inline constexpr auto grid_pore_volume = placeholder::_0;   ///< [m^3] sum w V
inline constexpr auto grid_pore_head = placeholder::_1;     ///< [Pa m^3] sum w V (h + grad h . (x_i - x_p)); then h_i [Pa]
inline constexpr auto grid_pore_inflow = placeholder::_2;   ///< [m^3/s] sum V q . grad w; then r_i [1/s]
inline constexpr auto grid_pore_water = placeholder::_3;    ///< [kg] sum w n rhow V0 (MassWater)
inline constexpr auto grid_pore_density = placeholder::_4;  ///< [kg] sum w V rhow; then p_i [Pa] (PorePressure)

template <typename T>
struct GridLayout {
  static_assert(settings::kBlockSide == 4, "grid blocks are 4x4x4 nodes");
  using scalar_ = structural_entity<T>;
  using soa = decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact,
                        attrib_layout::soa>;
  using block_domain = domain<int, 4, 4, 4>;
  /// (channel, node) mass and momentum of one block.
  using block_ = structural<structural_type::dense, block_domain, soa, scalar_, scalar_, scalar_, scalar_>;
  /// (channel, node) velocity of one block.
  using velocity_block_ = structural<structural_type::dense, block_domain, soa, scalar_, scalar_, scalar_>;
  /// (channel, cell) F-bar's cell sums of one block (transfer.cuh), allocated only when a body uses F-bar.
  using fbar_block_ = structural<structural_type::dense, block_domain, soa, scalar_, scalar_>;
  /// (channel, node) seepage channels of one block, allocated only when a body is saturated.
  using pore_block_ = structural<structural_type::dense, block_domain, soa, scalar_, scalar_, scalar_, scalar_, scalar_>;
  using buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, block_>;
  using fbar_buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, fbar_block_>;
  using velocity_buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, velocity_block_>;
  using pore_buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, pore_block_>;
  using Buffer = structural_instance<buffer_>;
  using VelocityBuffer = structural_instance<velocity_buffer_>;
  using FbarBuffer = structural_instance<fbar_buffer_>;
  using PoreBuffer = structural_instance<pore_buffer_>;

  static constexpr std::size_t kBlockBytes = block_::element_storage_size * block_domain::extent;
  static_assert(block_::size == 4 * 64 * sizeof(T), "a grid block is 4 channels x 64 nodes, nothing else");
  static_assert(velocity_block_::size == 3 * 64 * sizeof(T), "a velocity block is 3 channels x 64 nodes");
};

/// Owner of one run-time sized buffer of blocks of structural `Node` (grid or velocity).
template <typename Node>
class BlockBuffer {
 public:
  using Instance = structural_instance<structural<structural_type::dynamic, dynamic_domain<int>,
                                                  typename GridLayout<float>::soa, Node>>;
  static constexpr std::size_t kBlockBytes = Node::size;

  BlockBuffer() = default;
  BlockBuffer(const BlockBuffer&) = delete;
  BlockBuffer& operator=(const BlockBuffer&) = delete;
  ~BlockBuffer() {
    if (instance_) cudaFree(instance_.data());  // no throw at teardown
  }

  void allocate(int block_capacity) {
    if (instance_) instance_.deallocate(cuda::DeviceAllocator{});
    instance_ = spawn<typename Instance::structural>(cuda::DeviceAllocator{}, static_cast<std::size_t>(block_capacity));
    // Defined from the start: growth copies blocks that may not have been written since (velocities of blocks the
    // last grid update did not cover).
    FBAR_CUDA_CHECK(cudaMemset(instance_.data(), 0, kBlockBytes * static_cast<std::size_t>(block_capacity)));
  }
  /// New capacity keeping blocks [0, keep_blocks) (a block is one contiguous range: the outer node is one element
  /// per block, so the copy is a single memcpy).
  void grow(int block_capacity, int keep_blocks, cudaStream_t stream) {
    Instance bigger =
        spawn<typename Instance::structural>(cuda::DeviceAllocator{}, static_cast<std::size_t>(block_capacity));
    if (instance_ && keep_blocks > 0)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.data(), instance_.data(), kBlockBytes * keep_blocks,
                                      cudaMemcpyDeviceToDevice, stream));
    const std::size_t kept = instance_ ? static_cast<std::size_t>(std::max(keep_blocks, 0)) : 0;
    FBAR_CUDA_CHECK(cudaMemsetAsync(bigger.data() + kBlockBytes * kept, 0,
                                    kBlockBytes * (static_cast<std::size_t>(block_capacity) - kept), stream));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream));
    if (instance_) instance_.deallocate(cuda::DeviceAllocator{});
    instance_ = bigger;
  }
  /// Zeroes blocks [begin, end).
  void clear(int begin, int end, cudaStream_t stream) {
    if (end > begin)
      FBAR_CUDA_CHECK(cudaMemsetAsync(instance_.data() + kBlockBytes * begin, 0, kBlockBytes * (end - begin), stream));
  }
  Instance instance() const { return instance_; }
  std::size_t bytes() const { return instance_ ? instance_.size_bytes() : 0; }
  int capacity() const { return static_cast<int>(instance_.capacity()); }

 private:
  Instance instance_{};
};

template <typename T>
using GridBuffer = BlockBuffer<typename GridLayout<T>::block_>;
template <typename T>
using GridVelocityBuffer = BlockBuffer<typename GridLayout<T>::velocity_block_>;
template <typename T>
using GridFbarBuffer = BlockBuffer<typename GridLayout<T>::fbar_block_>;
template <typename T>
using GridPoreBuffer = BlockBuffer<typename GridLayout<T>::pore_block_>;

}  // namespace fbar
