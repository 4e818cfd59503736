// Grid buffers of the GPU engine: a run-time number of 4x4x4-node blocks, channels of 64 nodes inside a block.
//
// The buffers share the block indexing of the hash table (hash_table.cuh). What P2G sums is fixed point
// (FixedGridBuffer, "Order-free grid sums" below); what the grid update writes is TG (Library structurals):
//   GridBuffer<T>          mass + momentum (4 fixed-point channels): what P2G accumulates. Double-buffered by the
//                          driver: G2P2G of step n reads the velocities of step n and scatters into the other buffer.
//   TransportedBuffer<T>   ASFLIP's transported momentum (3 fixed-point channels), double-buffered like GridBuffer.
//   FbarSumBuffer<T>       F-bar's cell sums (2 fixed-point channels, transfer.cuh), only when a body uses F-bar.
//   PoreSumBuffer<T>       the seepage sums of saturated bodies (5 fixed-point channels, physics/seepage.cuh), and
//   GridPoreBuffer<T>      the node values the grid update writes from them (5 channels of T), only when a body is
//                          saturated (CoupledUP).
//   GridVelocityBuffer<T>  velocity (3 channels): what the grid update writes and G2P reads. Keeping it apart from
//                          the momentum leaves the P2G sums of step n intact until step n commits, which is what
//                          a retried step (on_failure = reduce_dt) and a changed dt need (see mgsp_benchmark.cuh).
// Byte layout of block b of a structural buffer (channel c, node (i, j, k) = 16 i + 4 j + k), T = float:
//   b * 768 + c * 256 + node * 4     (velocity x/y/z c = 0..2)
// so a warp reading one channel of 32 consecutive nodes reads 128 contiguous bytes; a fixed-point buffer's words
// follow FixedGrid's index (below).
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <utility>

#include "MnBase/Memory/structural_instance.h"
#include "MnBase/Meta/placeholder.h"
#include "MnSystem/Cuda/allocators.h"
#include "MnSystem/Cuda/device_array.cuh"
#include "engine/grid_channels.h"
#include "engine/gpu/block_access.cuh"
#include "settings.h"

namespace fbar {

/// Named channels of the structural buffers (placeholder indices of the block structural).
inline constexpr auto grid_velocity_x = placeholder::_0;  ///< [m/s] (velocity buffer)
inline constexpr auto grid_velocity_y = placeholder::_1;
inline constexpr auto grid_velocity_z = placeholder::_2;
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
  /// (channel, node) values of one block of a GridStorage::Value set with C channels.
  template <typename Seq>
  struct ValueBlockOf;
  template <std::size_t... I>
  struct ValueBlockOf<std::index_sequence<I...>> {
    template <std::size_t>
    using channel = scalar_;
    using type = structural<structural_type::dense, block_domain, soa, channel<I>...>;
  };
  template <int C>
  using value_block_ = typename ValueBlockOf<std::make_index_sequence<C>>::type;
  /// (channel, node) velocity of one block (and ASFLIP's v^n: the same channels).
  using velocity_block_ = value_block_<grid_set(GridSet::Velocity).channels>;
  /// (channel, node) seepage node values of one block, allocated only when a body is saturated.
  using pore_block_ = value_block_<grid_set(GridSet::PoreValues).channels>;
  using velocity_buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, velocity_block_>;
  using pore_buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, pore_block_>;
  using VelocityBuffer = structural_instance<velocity_buffer_>;
  using PoreBuffer = structural_instance<pore_buffer_>;

  static_assert(velocity_block_::size == grid_set_block_bytes(grid_set(GridSet::Velocity), sizeof(T)),
                "a velocity block: kGridSets");
  static_assert(grid_set(GridSet::OldVelocity).channels == grid_set(GridSet::Velocity).channels,
                "ASFLIP's v^n has the velocity's channels");
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
    // Done before the engine's non-blocking streams use the blocks (they do not wait for the legacy stream).
    FBAR_CUDA_CHECK(cudaStreamSynchronize(cudaStreamLegacy));
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
  std::byte* data() const { return reinterpret_cast<std::byte*>(instance_.data()); }
  std::size_t bytes() const { return instance_ ? instance_.size_bytes() : 0; }
  int capacity() const { return static_cast<int>(instance_.capacity()); }

 private:
  Instance instance_{};
};

/// Order-free grid sums. Every addition into a grid block's sums (the flush of a G2P2G arena, the mesh and rescaled
/// impulses, the halo and shared-block sums of a decomposed run) adds integers in units of a quantum per channel
/// kind (GridQuantum), so the sum is the same bits whatever order the additions come in: the same scene, build and
/// rank count give the same grid, and the grid does not depend on how many ranks summed it (docs/developer_guide.md
/// "Repeatable runs").
///   float grids:  one int64 word per value, quantum B 2^-40: B is a bound on one particle's contribution per unit
///                 weight, so a node may take 2^63 / (0.42 x 2^40) ~ 2e7 particles before the word overflows;
///                 the G2P2G flush converts a block's integer sum in float (rounded to 24 bits: the float grid's
///                 own precision, as a float atomic rounds), so the grid's quantum (4.5e-13 B) costs nothing.
///   double grids: two int64 words per value, hi 2^32 + lo with 0 <= lo < 2^32 per addition, each word summed on
///                 its own (no carry: the low word takes 2^31 additions before it could overflow, a node takes at
///                 most 8 per flush), quantum B 2^-60: range 2^95 q = 3e10 B, rounding 4.3e-19 B (the double arena's
///                 quantum is 2.3e-17 B at 512 particles per block).
/// Word (block, word, channel, node) = block * kBlockWords + (word * C + channel) * 64 + node: a warp reading one
/// channel of 32 nodes reads 256 contiguous bytes.
template <typename TG>
struct FixedSumFormat;
template <>
struct FixedSumFormat<float> {
  static constexpr int kWords = 1;
  static constexpr int kFractionBits = 40;
};
template <>
struct FixedSumFormat<double> {
  static constexpr int kWords = 2;
  static constexpr int kFractionBits = 60;
};

/// The quanta of one grid's sums: [kg] and [kg m/s] per unit (compute_next_dt writes them before the P2G).
struct GridQuantum {
  double mass = 0.0;
  double momentum = 0.0;
};

/// A device view of C channels of fixed-point sums per node (FixedSumFormat<TG>).
template <typename TG, int C>
struct FixedGrid {
  static constexpr int kChannels = C;
  static constexpr int kWords = FixedSumFormat<TG>::kWords;
  static constexpr std::size_t kBlockWords = static_cast<std::size_t>(kWords) * C * 64;
  unsigned long long* words = nullptr;

  FBAR_HOST_DEVICE explicit operator bool() const { return words != nullptr; }
  FBAR_HOST_DEVICE unsigned long long* word(int block, int word_index, int channel, int node) const {
    return words + static_cast<std::size_t>(block) * kBlockWords + (word_index * C + channel) * 64 + node;
  }
#if defined(__CUDACC__)
  /// Adds `units` (any real: rounded to the nearest integer here) to the sum. Order-free.
  __device__ __forceinline__ void add(int block, int channel, int node, double units) const {
    if constexpr (kWords == 1) {
      const long long v = __double2ll_rn(units);
      if (v != 0) atomicAdd(word(block, 0, channel, node), static_cast<unsigned long long>(v));
    } else {
      const double r = rint(units);
      if (r == 0.0) return;
      const double hi = floor(r * 0x1p-32);  // exact: r is an integer of at most 53 significant bits
      const double lo = r - hi * 0x1p32;     // in [0, 2^32), exact
      if (lo != 0.0) atomicAdd(word(block, 0, channel, node), static_cast<unsigned long long>(lo));
      if (hi != 0.0) atomicAdd(word(block, 1, channel, node), static_cast<unsigned long long>(__double2ll_rn(hi)));
    }
  }
  /// The same from a float (float grids: the arena's flush converts in float, the sums' own precision).
  __device__ __forceinline__ void add(int block, int channel, int node, float units) const {
    static_assert(kWords == 1, "float units go into a float grid's one-word sums");
    const long long v = __float2ll_rn(units);
    if (v != 0) atomicAdd(word(block, 0, channel, node), static_cast<unsigned long long>(v));
  }
#endif
  /// The sum in units (rounded to double).
  FBAR_HOST_DEVICE double units(int block, int channel, int node) const {
    if constexpr (kWords == 1) {
      return static_cast<double>(static_cast<long long>(*word(block, 0, channel, node)));
    } else {
      return static_cast<double>(static_cast<long long>(*word(block, 1, channel, node))) * 0x1p32 +
             static_cast<double>(*word(block, 0, channel, node));
    }
  }
  /// Zeroes block `block` (one thread: a block the table just created).
  FBAR_HOST_DEVICE void zero_block(int block) const {
    unsigned long long* w = words + static_cast<std::size_t>(block) * kBlockWords;
    for (std::size_t i = 0; i < kBlockWords; ++i) w[i] = 0ull;
  }
};

/// The owner of a FixedGrid's words: a run-time number of blocks.
template <typename TG, int C>
class FixedGridBuffer {
 public:
  using View = FixedGrid<TG, C>;
  static constexpr std::size_t kBlockBytes = View::kBlockWords * sizeof(unsigned long long);

  void allocate(int block_capacity) {
    words_.allocate(View::kBlockWords * static_cast<std::size_t>(block_capacity));  // zeroed
    capacity_ = block_capacity;
  }
  /// New capacity keeping blocks [0, keep_blocks).
  void grow(int block_capacity, int keep_blocks, cudaStream_t stream) {
    cuda::DeviceArray<unsigned long long> bigger;
    bigger.allocate(View::kBlockWords * static_cast<std::size_t>(block_capacity));  // zeroed
    if (words_.size() && keep_blocks > 0)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.get(), words_.get(), kBlockBytes * keep_blocks, cudaMemcpyDeviceToDevice,
                                      stream));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream));
    words_.swap(bigger);
    capacity_ = block_capacity;
  }
  /// Zeroes blocks [begin, end).
  void clear(int begin, int end, cudaStream_t stream) {
    if (end > begin)
      FBAR_CUDA_CHECK(cudaMemsetAsync(words_.get() + View::kBlockWords * begin, 0, kBlockBytes * (end - begin), stream));
  }
  View view() const { return View{words_.get()}; }
  std::byte* data() const { return reinterpret_cast<std::byte*>(words_.get()); }
  std::size_t bytes() const { return words_.bytes(); }
  int capacity() const { return capacity_; }

 private:
  cuda::DeviceArray<unsigned long long> words_;
  int capacity_ = 0;
};

/// The grid's P2G sums (mass, momentum x, y, z) and ASFLIP's transported momentum (x, y, z), in fixed point.
template <typename TG>
using GridSums = FixedGrid<TG, grid_set(GridSet::Sums).channels>;
template <typename TG>
using TransportedSums = FixedGrid<TG, grid_set(GridSet::Transported).channels>;
template <typename TG>
using GridBuffer = FixedGridBuffer<TG, grid_set(GridSet::Sums).channels>;
template <typename TG>
using TransportedBuffer = FixedGridBuffer<TG, grid_set(GridSet::Transported).channels>;
/// F-bar's cell sums (channels 0, 1: volume x compression and volume, kGridSets), in fixed point with the quantum
/// fixed_quantum(V0) of the body whose sums they hold.
template <typename TG>
using FbarSums = FixedGrid<TG, grid_set(GridSet::FbarSums).channels>;
template <typename TG>
using FbarSumBuffer = FixedGridBuffer<TG, grid_set(GridSet::FbarSums).channels>;
/// The seepage channels' sums (grid_pore_volume .. grid_pore_density: channels 0..4, kernels/seepage_kernels.cuh)
/// in fixed point, channel c in units of pore_quantum(B_c); the grid update writes the node values into the
/// GridPoreBuffer that G2P and the sensors read.
template <typename TG>
using PoreSums = FixedGrid<TG, grid_set(GridSet::PoreSums).channels>;
template <typename TG>
using PoreSumBuffer = FixedGridBuffer<TG, grid_set(GridSet::PoreSums).channels>;
/// The quantum of a channel whose contributions per unit weight are bounded by `bound`: bound 2^-F (FixedSumFormat).
template <typename TG>
FBAR_HOST_DEVICE inline double fixed_quantum(double bound) {
  return ldexp(bound, -FixedSumFormat<TG>::kFractionBits);
}
/// The quantum of a seepage channel from the bits of its bound B_c (a non-negative double).
template <typename TG>
FBAR_HOST_DEVICE inline double pore_quantum(unsigned long long bound_bits) {
  double b;
  memcpy(&b, &bound_bits, sizeof(b));
  return fixed_quantum<TG>(b);
}

/// Channels of GridSums (mass, momentum) and of TransportedSums (momentum).
inline constexpr int kSumMass = 0;
inline constexpr int kSumMomentum = 1;  ///< x; y, z follow
// The kernels' channel indices above are kGridSets' channel order (engine/grid_channels.h).
static_assert(kSumMass == 0 && kSumMomentum + 3 == grid_set(GridSet::Sums).channels, "P2G sums: kGridSets");
static_assert(decltype(grid_velocity_x)::value == 0 && decltype(grid_velocity_z)::value + 1 ==
                  static_cast<unsigned>(grid_set(GridSet::Velocity).channels), "velocity: kGridSets");
static_assert(decltype(grid_pore_volume)::value == 0 &&
                  decltype(grid_pore_density)::value + 1 == static_cast<unsigned>(grid_set(GridSet::PoreValues).channels) &&
                  grid_set(GridSet::PoreSums).channels == grid_set(GridSet::PoreValues).channels,
              "seepage channels: kGridSets");
template <typename T>
using GridVelocityBuffer = BlockBuffer<typename GridLayout<T>::velocity_block_>;
template <typename T>
using GridPoreBuffer = BlockBuffer<typename GridLayout<T>::pore_block_>;

}  // namespace fbar
