// GPU tests for structural instances: kernels write and read the SPGrid through val / val_1d on the device.
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <cstddef>
#include <cstring>
#include <vector>

#include "spgrid_example.h"
#include "MnBase/Memory/structural_instance.h"
#include "MnSystem/Cuda/allocators.h"
#include "MnSystem/Cuda/device_query.h"

namespace fbar {
namespace {

using namespace placeholder;
using test::grid_buffer_;
using test::spgrid_byte_offset;
using Grid = structural_instance<grid_buffer_>;

/// A distinct, exactly representable value per (block, channel, node): at most 4 * 64 * 64 < 2^24.
FBAR_HOST_DEVICE constexpr float node_value(unsigned b, unsigned c, unsigned cell) {
  return static_cast<float>((b * 4 + c) * 64 + cell);
}

// Launch shape of every SPGrid kernel: one CUDA block per grid block, one thread per node (64).
__global__ void write_through_val(Grid grid) {
  const unsigned b = blockIdx.x, cell = threadIdx.x;
  const int x = cell / 16, y = cell / 4 % 4, z = cell % 4;
  const auto block = grid.ch(_0, b);
  block.val(_0, x, y, z) = node_value(b, 0, cell);
  block.val(_1, x, y, z) = node_value(b, 1, cell);
  block.val(_2, x, y, z) = node_value(b, 2, cell);
  block.val(_3, x, y, z) = node_value(b, 3, cell);
}

// out is (block, channel, node), 64 floats per channel.
__global__ void read_through_val_1d(Grid grid, float* out) {
  const unsigned b = blockIdx.x, cell = threadIdx.x;
  const auto block = grid.ch(_0, b);
  float* o = out + b * 4 * 64 + cell;
  o[0 * 64] = block.val_1d(_0, cell);
  o[1 * 64] = block.val_1d(_1, cell);
  o[2 * 64] = block.val_1d(_2, cell);
  o[3 * 64] = block.val_1d(_3, cell);
}

void check_launch() {
  FBAR_CUDA_CHECK(cudaGetLastError());
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
}

template <typename F, std::size_t... Cs>
void for_each_channel(F& f, std::index_sequence<Cs...>) {
  (f(index_t<static_cast<attrib_index>(Cs)>{}), ...);
}

TEST(StructuralGpu, SpgridKernelWritesLandAtTheHostComputedOffsets) {
  if (cuda::device_count() == 0) GTEST_SKIP() << cuda::no_device_reason();

  cuda::DeviceAllocator device;
  const unsigned capacity = 13;  // a run-time block count, not a power of two
  Grid grid = spawn<grid_buffer_>(device, capacity);
  ASSERT_EQ(grid.size_bytes(), capacity * test::spgrid_block_bytes);
  FBAR_CUDA_CHECK(cudaMemset(grid.data(), 0xff, grid.size_bytes()));  // NaN pattern: a missed write shows

  write_through_val<<<capacity, 64>>>(grid);
  check_launch();

  std::vector<std::byte> bytes(grid.size_bytes());
  FBAR_CUDA_CHECK(cudaMemcpy(bytes.data(), grid.data(), bytes.size(), cudaMemcpyDeviceToHost));

  // The same structure viewed on the host computes the offsets; 13 * 4 * 64 floats cover every byte.
  const Grid host_view{bytes.data(), capacity};
  for (unsigned b = 0; b < capacity; ++b) {
    auto check = [&](auto c) {
      for (unsigned cell = 0; cell < 64; ++cell) {
        const int x = cell / 16, y = cell / 4 % 4, z = cell % 4;
        const std::byte* p = reinterpret_cast<const std::byte*>(&host_view.ch(_0, b).val(c, x, y, z));
        const std::size_t offset = static_cast<std::size_t>(p - bytes.data());
        ASSERT_EQ(offset, spgrid_byte_offset(b, c, x, y, z));
        float v;
        std::memcpy(&v, bytes.data() + offset, sizeof v);
        EXPECT_EQ(v, node_value(b, c, cell)) << "block " << b << " channel " << c << " node " << cell;
      }
    };
    for_each_channel(check, std::make_index_sequence<4>{});
  }

  float* out = nullptr;
  FBAR_CUDA_CHECK(cudaMalloc(&out, capacity * 4 * 64 * sizeof(float)));
  read_through_val_1d<<<capacity, 64>>>(grid, out);
  check_launch();
  std::vector<float> read(capacity * 4 * 64);
  FBAR_CUDA_CHECK(cudaMemcpy(read.data(), out, read.size() * sizeof(float), cudaMemcpyDeviceToHost));
  for (unsigned b = 0; b < capacity; ++b)
    for (unsigned c = 0; c < 4; ++c)
      for (unsigned cell = 0; cell < 64; ++cell) EXPECT_EQ(read[(b * 4 + c) * 64 + cell], node_value(b, c, cell));

  FBAR_CUDA_CHECK(cudaFree(out));
  grid.deallocate(device);
}

// {f32, f64} SoA under a dynamic node: the double array starts at round_up(4 * capacity, 8). A layout that
// ignored the run-time capacity or alignment would fault (misaligned f64) or overlap the float array.
using soa = test::spgrid_decorator;
using particles_ = structural<structural_type::dynamic, dynamic_domain<int>, soa, f32_, f64_>;
using Particles = structural_instance<particles_>;

__global__ void write_particles(Particles p) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= p.capacity()) return;
  p.val(_0, i) = static_cast<float>(i);
  p.val(_1, i) = -static_cast<double>(i) - 0.5;
}

TEST(StructuralGpu, DynamicSoAUsesTheRunTimeCapacityOnTheDevice) {
  if (cuda::device_count() == 0) GTEST_SKIP() << cuda::no_device_reason();

  cuda::DeviceAllocator device;
  for (unsigned capacity : {5u, 1000u, 4099u}) {
    Particles p = spawn<particles_>(device, capacity);
    write_particles<<<(capacity + 127) / 128, 128>>>(p);
    check_launch();
    std::vector<std::byte> bytes(p.size_bytes());
    FBAR_CUDA_CHECK(cudaMemcpy(bytes.data(), p.data(), bytes.size(), cudaMemcpyDeviceToHost));
    const Particles host_view{bytes.data(), capacity};
    EXPECT_EQ(reinterpret_cast<std::byte*>(&host_view.val(_1, 0)) - bytes.data(),
              static_cast<std::ptrdiff_t>((capacity * 4 + 7) / 8 * 8));
    for (unsigned i = 0; i < capacity; ++i) {
      EXPECT_EQ(host_view.val_1d(_0, i), static_cast<float>(i));
      EXPECT_EQ(host_view.val_1d(_1, i), -static_cast<double>(i) - 0.5);
    }
    p.deallocate(device);
  }
}

}  // namespace
}  // namespace fbar
