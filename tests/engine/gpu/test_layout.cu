// Byte layout of the GPU engine's structures, written by kernels and checked on the host: particle bins (AoSoA,
// attribute-major lanes, ID last) per material and precision, and the grid's fixed-point sums (channels of 64
// nodes, order-free).
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "gpu_test_support.h"
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/particle_buffer.cuh"

namespace fbar {
namespace {

/// A distinct, exactly representable value per (slot, scalar).
FBAR_HOST_DEVICE constexpr double tag(int slot, int scalar) { return slot * 16 + scalar + 0.5; }

template <typename M, typename T>
__global__ void write_particles(typename ParticleLayout<M, T>::Buffer bins, int n) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= n) return;
  ParticleRecord<M, T> p;
  p.x = Vec3<T>{{T(tag(slot, 0)), T(tag(slot, 1)), T(tag(slot, 2))}};
  T* s = reinterpret_cast<T*>(&p.state);
  for (int i = 0; i < ParticleLayout<M, T>::kStateScalars; ++i) s[i] = T(tag(slot, 3 + i));
  p.id = 1000 + slot;
  store_particle<M, T>(bins, slot, p);
}

template <typename M, typename T>
void check_bins() {
  using L = ParticleLayout<M, T>;
  const int bins = 3, n = bins * 32 - 5;
  auto buffer = ParticleBuffer<M, T>();
  buffer.allocate(bins);
  FBAR_CUDA_CHECK(cudaMemset(buffer.instance().data(), 0xff, buffer.bytes()));
  write_particles<M, T><<<1, 128>>>(buffer.instance(), n);
  FBAR_CUDA_CHECK(cudaGetLastError());
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  std::vector<std::byte> host(buffer.bytes());
  FBAR_CUDA_CHECK(cudaMemcpy(host.data(), buffer.instance().data(), host.size(), cudaMemcpyDeviceToHost));
  ASSERT_EQ(host.size(), bins * L::kBinBytes);
  for (int slot = 0; slot < n; ++slot) {
    const int bin = slot / 32, lane = slot % 32;
    const std::byte* b = host.data() + bin * L::kBinBytes;
    // (attribute, lane): scalar a of lane l at a * 32 * sizeof(T) + l * sizeof(T), then the IDs.
    for (int a = 0; a < L::kScalars; ++a) {
      T v;
      std::memcpy(&v, b + (a * 32 + lane) * sizeof(T), sizeof(T));
      EXPECT_EQ(v, T(tag(slot, a))) << "slot " << slot << " scalar " << a;
    }
    std::int32_t id;
    std::memcpy(&id, b + L::kScalars * 32 * sizeof(T) + lane * 4, 4);
    EXPECT_EQ(id, 1000 + slot);
  }
}

TEST(GpuLayout, JFluidBinsFloat) {
  FBAR_REQUIRE_DEVICE();
  static_assert(ParticleLayout<JFluid, float>::kBinBytes == 32 * 20, "JFluid float: 4 scalars + ID");
  check_bins<JFluid, float>();
}
TEST(GpuLayout, JFluidBinsDouble) {
  FBAR_REQUIRE_DEVICE();
  static_assert(ParticleLayout<JFluid, double>::kBinBytes == 32 * 40, "JFluid double: 4 scalars + padded ID");
  check_bins<JFluid, double>();
}
TEST(GpuLayout, FixedCorotatedBinsFloat) {
  FBAR_REQUIRE_DEVICE();
  static_assert(ParticleLayout<FixedCorotated, float>::kBinBytes == 32 * 52, "FixedCorotated float: 12 + ID");
  check_bins<FixedCorotated, float>();
}
TEST(GpuLayout, FixedCorotatedBinsDouble) {
  FBAR_REQUIRE_DEVICE();
  check_bins<FixedCorotated, double>();
}

/// Adds, for every (block, channel, node), the contributions k = 0 .. kTerms - 1 of value(b, c, n, k) in units,
/// thread t taking contribution (t + shift) % kTerms: a different shift is a different order of the same additions.
inline constexpr int kTerms = 96;
FBAR_HOST_DEVICE inline double term(int b, int c, int n, int k) {
  // Mixed signs and magnitudes (1e-3 .. 1e9 units, non-integers): rounding happens in every addition.
  const double m = ((b * 7 + c * 3 + n + k * 13) % 17 - 8) * 0.37;
  return m * (k % 5 == 0 ? 1.0e9 : k % 3 == 0 ? 1.0e3 : 1.0e-3) + 0.25 * k;
}
template <typename T>
__global__ void add_terms(GridSums<T> grid, int shift) {
  const int b = blockIdx.x, k = (threadIdx.x + shift) % kTerms;
  for (int c = 0; c < 4; ++c)
    for (int n = 0; n < 64; ++n) grid.add(b, c, n, term(b, c, n, k));
}

/// Fixed-point grid sums (grid_buffer.cuh): word (block, word, channel, node) at the documented index, the same words
/// whatever the order of the additions, and each sum equal to the rounded terms' exact sum.
template <typename T>
void check_grid() {
  constexpr int kBlocks = 5;
  using View = typename GridBuffer<T>::View;
  static_assert(GridBuffer<T>::kBlockBytes == 4 * 64 * 8 * FixedSumFormat<T>::kWords, "4 channels x 64 nodes");
  std::vector<std::vector<unsigned long long>> words;
  for (int shift : {0, 37, 95}) {
    GridBuffer<T> grid;
    grid.allocate(kBlocks);
    add_terms<T><<<kBlocks, kTerms>>>(grid.view(), shift);
    FBAR_CUDA_CHECK(cudaGetLastError());
    FBAR_CUDA_CHECK(cudaDeviceSynchronize());
    std::vector<unsigned long long> host(grid.bytes() / 8);
    ASSERT_EQ(host.size(), kBlocks * View::kBlockWords);
    FBAR_CUDA_CHECK(cudaMemcpy(host.data(), grid.data(), grid.bytes(), cudaMemcpyDeviceToHost));
    words.push_back(host);
  }
  EXPECT_EQ(words[0], words[1]) << "the order of the additions changed the sums";
  EXPECT_EQ(words[0], words[2]) << "the order of the additions changed the sums";
  const View view{words[0].data()};
  for (int b = 0; b < kBlocks; ++b)
    for (int c = 0; c < 4; ++c)
      for (int n = 0; n < 64; ++n) {
        long long exact = 0;  // the sum of the rounded terms, computed apart
        for (int k = 0; k < kTerms; ++k) exact += std::llrint(term(b, c, n, k));
        EXPECT_EQ(view.units(b, c, n), static_cast<double>(exact)) << b << " " << c << " " << n;
        if constexpr (FixedSumFormat<T>::kWords == 1)
          EXPECT_EQ(static_cast<long long>(words[0][b * View::kBlockWords + c * 64 + n]), exact);
      }
}

TEST(GpuLayout, GridSumsFloat) {
  FBAR_REQUIRE_DEVICE();
  check_grid<float>();
}
TEST(GpuLayout, GridSumsDouble) {
  FBAR_REQUIRE_DEVICE();
  check_grid<double>();
}

}  // namespace
}  // namespace fbar
