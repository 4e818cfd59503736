// Byte layout of the GPU engine's structures, written by kernels and checked on the host: particle bins (AoSoA,
// attribute-major lanes, ID last) per material and precision, and the grid blocks (SoA channels of 64 nodes).
#include <gtest/gtest.h>

#include <cuda_runtime.h>

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

template <typename T>
__global__ void write_grid(typename GridLayout<T>::Buffer grid) {
  const int b = blockIdx.x, node = threadIdx.x;
  const auto g = grid.ch(placeholder::_0, b);
  g.val_1d(grid_mass, node) = T(tag(b * 64 + node, 0));
  g.val_1d(grid_momentum_x, node) = T(tag(b * 64 + node, 1));
  g.val_1d(grid_momentum_y, node) = T(tag(b * 64 + node, 2));
  g.val_1d(grid_momentum_z, node) = T(tag(b * 64 + node, 3));
}

template <typename T>
void check_grid() {
  GridBuffer<T> grid;
  grid.allocate(5);
  write_grid<T><<<5, 64>>>(grid.instance());
  FBAR_CUDA_CHECK(cudaGetLastError());
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  std::vector<std::byte> host(grid.bytes());
  FBAR_CUDA_CHECK(cudaMemcpy(host.data(), grid.instance().data(), host.size(), cudaMemcpyDeviceToHost));
  ASSERT_EQ(host.size(), 5 * 4 * 64 * sizeof(T));
  for (int b = 0; b < 5; ++b)
    for (int c = 0; c < 4; ++c)
      for (int node = 0; node < 64; ++node) {
        T v;
        std::memcpy(&v, host.data() + ((b * 4 + c) * 64 + node) * sizeof(T), sizeof(T));
        EXPECT_EQ(v, T(tag(b * 64 + node, c)));
      }
}

TEST(GpuLayout, GridBlocksFloat) {
  FBAR_REQUIRE_DEVICE();
  check_grid<float>();
}
TEST(GpuLayout, GridBlocksDouble) {
  FBAR_REQUIRE_DEVICE();
  check_grid<double>();
}

}  // namespace
}  // namespace fbar
