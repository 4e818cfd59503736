// Particle buffers of the GPU engine: per body, bins of 32 particles (AoSoA), the bin layout derived from the material.
//
// A bin is attribute-major: for each stored scalar an array of 32 lanes, then the 32 particle IDs:
//     bin b: | x[32] | y[32] | z[32] | state_0[32] ... state_{S-4}[32] | id[32] |        (S = M::kStoredScalars)
// built with the Library structurals (a dense node of 32 lanes, SoA, inside a dynamic node of bins, AoS), so a
// warp reading one attribute of its bin reads 128 contiguous bytes (float). The state scalars are the bytes of
// M::State<T> in member order (JFluid: 1 - J; FixedCorotated: F row-major), so adding a material adds its bin.
// Bytes per particle: JFluid float 4 x 4 + 4 (ID) = 20, FixedCorotated float 12 x 4 + 4 = 52 (double: 40, 104,
// the ID padded to the 8-byte element alignment).
// Mass and reference volume are per body (every particle of a body is sampled with the same volume).
// Particle IDs travel with the particles through every reorder, so output and comparisons are by ID.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <utility>

#include "MnBase/Math/vec.h"
#include "MnBase/Memory/structural_instance.h"
#include "MnBase/Meta/config.h"
#include "MnBase/Meta/placeholder.h"
#include "MnSystem/Cuda/allocators.h"
#include "engine/gpu/block_access.cuh"
#include "physics/constitutive_models.cuh"
#include "settings.h"

namespace fbar {

namespace particle_detail {
template <typename X, std::size_t>
using repeat = X;

template <typename T, typename Seq>
struct bin_of;
template <typename T, std::size_t... Is>
struct bin_of<T, std::index_sequence<Is...>> {
  using soa = decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact,
                        attrib_layout::soa>;
  /// (attribute, lane): the stored scalars, then the particle ID.
  using type = structural<structural_type::dense, domain<int, settings::kBinSize>, soa,
                          repeat<structural_entity<T>, Is>..., i32_>;
};
}  // namespace particle_detail

/// Bin layout of material M in precision T.
template <typename M, typename T>
struct ParticleLayout {
  static constexpr int kScalars = M::kStoredScalars;  ///< position (3) + state
  static constexpr int kStateScalars = kScalars - 3;
  using State = material_state_t<M, T>;
  static_assert(sizeof(State) == sizeof(T) * kStateScalars,
                "the material State<T> must consist of exactly kStoredScalars - 3 scalars of T");
  using bin_ = typename particle_detail::bin_of<T, std::make_index_sequence<kScalars>>::type;
  using aos = decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact,
                        attrib_layout::aos>;
  using buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, aos, bin_>;
  using Buffer = structural_instance<buffer_>;
  static constexpr auto id_attrib = placeholder::index_t<kScalars>{};
  static constexpr std::size_t kBinBytes = bin_::size;
  /// A bin is 32 C-struct elements {T x S, int32 id} (structural.h rule 1): double pads the ID to 8 bytes.
  static constexpr std::size_t kParticleBytes =
      (kScalars * sizeof(T) + sizeof(std::int32_t) + alignof(T) - 1) / alignof(T) * alignof(T);
  static_assert(kBinBytes == settings::kBinSize * kParticleBytes,
                "a bin holds exactly the stored scalars and the ID of 32 particles");
};

/// One particle as a kernel holds it in registers.
template <typename M, typename T>
struct ParticleRecord {
  Vec3<T> x;                         ///< [m]
  material_state_t<M, T> state;
  int id;
};

namespace particle_detail {
template <typename M, typename T, std::size_t... Is>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void load_scalars(const typename ParticleLayout<M, T>::Buffer& buf, int bin, int lane,
                                                     T (&v)[sizeof...(Is)], std::index_sequence<Is...>) {
  ((v[Is] = block_val(buf, placeholder::index_t<static_cast<placeholder::placeholder_type>(Is)>{}, bin, lane)), ...);
}
template <typename M, typename T, std::size_t... Is>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void store_scalars(const typename ParticleLayout<M, T>::Buffer& buf, int bin,
                                                      int lane, const T (&v)[sizeof...(Is)], std::index_sequence<Is...>) {
  ((block_val(buf, placeholder::index_t<static_cast<placeholder::placeholder_type>(Is)>{}, bin, lane) = v[Is]), ...);
}
}  // namespace particle_detail

/// Reads particle `slot` (bin slot / 32, lane slot % 32) of a buffer.
template <typename M, typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE ParticleRecord<M, T> load_particle(const typename ParticleLayout<M, T>::Buffer& buf,
                                                                     int slot) {
  using L = ParticleLayout<M, T>;
  const int bin = slot / settings::kBinSize;
  const int lane = slot % settings::kBinSize;
  T v[L::kScalars];
  particle_detail::load_scalars<M, T>(buf, bin, lane, v, std::make_index_sequence<L::kScalars>{});
  ParticleRecord<M, T> p;
  p.x = Vec3<T>{{v[0], v[1], v[2]}};
  // Element-wise with constant indices after unrolling (a memcpy would put the state in local memory).
  T* state = reinterpret_cast<T*>(&p.state);
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < L::kStateScalars; ++i) state[i] = v[3 + i];
  p.id = block_val(buf, L::id_attrib, bin, lane);
  return p;
}

/// Writes particle `slot` of a buffer.
template <typename M, typename T>
FBAR_HOST_DEVICE FBAR_FORCE_INLINE void store_particle(const typename ParticleLayout<M, T>::Buffer& buf, int slot,
                                                       const ParticleRecord<M, T>& p) {
  using L = ParticleLayout<M, T>;
  const int bin = slot / settings::kBinSize;
  const int lane = slot % settings::kBinSize;
  T v[L::kScalars];
  v[0] = p.x[0];
  v[1] = p.x[1];
  v[2] = p.x[2];
  const T* state = reinterpret_cast<const T*>(&p.state);
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < L::kStateScalars; ++i) v[3 + i] = state[i];
  particle_detail::store_scalars<M, T>(buf, bin, lane, v, std::make_index_sequence<L::kScalars>{});
  block_val(buf, L::id_attrib, bin, lane) = p.id;
}

/// Owner of one body's bins (device memory); the driver keeps two (the fused G2P2G reads one, writes the other).
template <typename M, typename T>
class ParticleBuffer {
 public:
  using Layout = ParticleLayout<M, T>;
  using Buffer = typename Layout::Buffer;

  ParticleBuffer() = default;
  ParticleBuffer(const ParticleBuffer&) = delete;
  ParticleBuffer& operator=(const ParticleBuffer&) = delete;
  ParticleBuffer(ParticleBuffer&& o) noexcept : buffer_(o.buffer_) { o.buffer_ = Buffer{}; }
  ~ParticleBuffer() {
    if (buffer_) cudaFree(buffer_.data());
  }

  /// (Re)allocates for `bins` bins; the contents are not kept.
  void allocate(int bins) {
    if (buffer_) buffer_.deallocate(cuda::DeviceAllocator{});
    buffer_ = spawn<typename Layout::buffer_>(cuda::DeviceAllocator{}, static_cast<std::size_t>(bins));
  }
  /// Grows to `bins` bins keeping the first `keep_bins` (a stream-ordered copy, then a sync before the old frees).
  void grow_keeping(int bins, int keep_bins, cudaStream_t s) {
    Buffer bigger = spawn<typename Layout::buffer_>(cuda::DeviceAllocator{}, static_cast<std::size_t>(bins));
    const std::size_t keep = Layout::kBinBytes * static_cast<std::size_t>(keep_bins);
    if (buffer_ && keep > 0)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(bigger.data(), buffer_.data(), keep, cudaMemcpyDeviceToDevice, s));
    FBAR_CUDA_CHECK(cudaStreamSynchronize(s));
    if (buffer_) buffer_.deallocate(cuda::DeviceAllocator{});
    buffer_ = bigger;
  }
  Buffer instance() const { return buffer_; }
  int bin_capacity() const { return static_cast<int>(buffer_.capacity()); }
  std::size_t bytes() const { return buffer_ ? buffer_.size_bytes() : 0; }

 private:
  Buffer buffer_{};
};

}  // namespace fbar
