// Micro-benchmark: ways to accumulate P2G contributions into a shared-memory arena on the running GPU.
//
// The fused G2P2G kernel scatters 27 nodes x 4 channels per particle into an 8x8x8-node arena with shared float
// atomics. On sm_90 (nvcc 13.0) `atomicAdd(float*)` on shared memory compiles to a compare-and-swap loop
// (LDS, FADD, ATOMS.CAST.SPIN, branch): every add is a dependent chain of two shared-memory round trips, and lanes
// of one warp that hit the same address retry. This program times the same scatter pattern with:
//   cas       atomicAdd on shared memory (what the compiler emits)
//   cas4      one hand-written CAS loop for the 4 channels of a node (4 chains in flight per retry round)
//   cluster   red.shared::cluster.add.f32 on the block's own shared memory (distributed shared memory path)
//   generic   red.add.f32 through a generic address of shared memory
//   fixed     32-bit fixed-point adds (native integer shared atomics), an upper bound for comparison
// for three lane patterns: every lane in its own cell, pairs of lanes per cell (the lattice sampling order), and
// 8 lanes per cell (cell-sorted bins). It checks each variant's sums against the cas variant and prints a table.
//   shared_atomics [--blocks=20000] [--reps=7]
#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#define CHECK(x)                                                                                   \
  do {                                                                                             \
    cudaError_t e_ = (x);                                                                          \
    if (e_ != cudaSuccess) {                                                                       \
      std::fprintf(stderr, "%s:%d %s: %s\n", __FILE__, __LINE__, #x, cudaGetErrorString(e_));      \
      std::exit(2);                                                                                \
    }                                                                                              \
  } while (0)

namespace {

constexpr int kThreads = 128;
constexpr int kPlane = 68;            // padded x-plane of the arena (as in g2p2g_kernel.cuh)
constexpr int kStorage = 8 * kPlane;  // words per channel
constexpr int kBinsPerWarp = 4;       // 16 bins (512 particles) per block, as at 8 ppc

enum Variant { kCas, kCas4, kCluster, kGeneric, kFixed, kReduce, kFixed64, kVariants };
const char* kNames[kVariants] = {"cas", "cas4", "cluster", "generic", "fixed", "reduce", "fixed64"};
enum Pattern { kDistinct, kPairs, kEight, kPatterns };
const char* kPatternNames[kPatterns] = {"1 lane/cell", "2 lanes/cell", "8 lanes/cell"};

__device__ __forceinline__ unsigned hash(unsigned x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

__device__ __forceinline__ void add_cas4(float* base, int stride, float v0, float v1, float v2, float v3) {
  float* a[4] = {base, base + stride, base + 2 * stride, base + 3 * stride};
  float v[4] = {v0, v1, v2, v3};
  int old[4];
#pragma unroll
  for (int c = 0; c < 4; ++c) old[c] = __float_as_int(*reinterpret_cast<volatile float*>(a[c]));
  unsigned pending = 0xf;
  while (pending) {
#pragma unroll
    for (int c = 0; c < 4; ++c) {
      if (pending & (1u << c)) {
        const int seen = atomicCAS(reinterpret_cast<int*>(a[c]), old[c], __float_as_int(__int_as_float(old[c]) + v[c]));
        if (seen == old[c]) pending &= ~(1u << c);
        old[c] = seen;
      }
    }
  }
}

__device__ __forceinline__ void red_cluster(float* p, float v) {
  unsigned local = static_cast<unsigned>(__cvta_generic_to_shared(p));
  unsigned rank, remote;
  asm volatile("mov.u32 %0, %%cluster_ctarank;" : "=r"(rank));
  asm volatile("mapa.shared::cluster.u32 %0, %1, %2;" : "=r"(remote) : "r"(local), "r"(rank));
  asm volatile("red.relaxed.cluster.shared::cluster.add.f32 [%0], %1;" ::"r"(remote), "f"(v) : "memory");
}

__device__ __forceinline__ void red_generic(float* p, float v) {
  asm volatile("red.relaxed.gpu.add.f32 [%0], %1;" ::"l"(p), "f"(v) : "memory");
}

template <int kVariant>
__global__ void __launch_bounds__(kThreads) scatter(int pattern, double* block_sums) {
  __shared__ float arena[4][kStorage];
  for (int i = threadIdx.x; i < 4 * kStorage; i += kThreads) (&arena[0][0])[i] = 0.f;
  __syncthreads();
  const int lane = threadIdx.x % 32, warp = threadIdx.x / 32;
  for (int bin = 0; bin < kBinsPerWarp; ++bin) {
    // The particle's cell in [1, 4]^3 (stencil base in the arena), shared by `group` consecutive lanes.
    const int group = pattern == kDistinct ? 1 : pattern == kPairs ? 2 : 8;
    const unsigned h = hash(blockIdx.x * 4096u + warp * 64u + bin * 32u + lane / group);
    const int l0 = 1 + (h & 3), l1 = 1 + ((h >> 2) & 3), l2 = 1 + ((h >> 4) & 3);
    const float fx = (hash(h + lane) & 1023) * (1.f / 1024.f);
    const float m = 1.f + fx, px = 0.5f - fx, py = 0.25f * fx, pz = -0.125f;
    // reduce: lanes of one cell form a contiguous run; its head sums the run with shfl_down steps, then adds.
    const unsigned peers = __match_any_sync(0xffffffffu, (l0 * 8 + l1) * 8 + l2);
    const int seg_last = 31 - __clz(peers), seg_first = __ffs(peers) - 1;
    const int run = __reduce_max_sync(0xffffffffu, __popc(peers));
    const bool head = lane == seg_first;
    auto seg_sum = [&](float v) {
      for (int d = 1; d < run; d <<= 1) {
        const float t = __shfl_down_sync(0xffffffffu, v, d);
        if (lane + d <= seg_last) v += t;
      }
      return v;
    };
    for (int i = 0; i < 3; ++i) {
      const float wi = i == 0 ? 0.5f * (1.5f - fx) : i == 1 ? 0.75f - (fx - 1.f) * (fx - 1.f) : 0.5f * fx * fx;
#pragma unroll
      for (int j = 0; j < 3; ++j) {
#pragma unroll
        for (int k = 0; k < 3; ++k) {
          const float w = wi * (j == 1 ? 0.75f : 0.125f) * (k == 1 ? 0.75f : 0.125f);
          const int a = (l0 + i) * kPlane + (l1 + j) * 8 + (l2 + k);
          const float c0 = w * m, c1 = w * (px + 0.1f * i), c2 = w * (py - 0.1f * j), c3 = w * (pz + 0.1f * k);
          if constexpr (kVariant == kCas) {
            atomicAdd(&arena[0][a], c0);
            atomicAdd(&arena[1][a], c1);
            atomicAdd(&arena[2][a], c2);
            atomicAdd(&arena[3][a], c3);
          } else if constexpr (kVariant == kCas4) {
            add_cas4(&arena[0][a], kStorage, c0, c1, c2, c3);
          } else if constexpr (kVariant == kCluster) {
            red_cluster(&arena[0][a], c0);
            red_cluster(&arena[1][a], c1);
            red_cluster(&arena[2][a], c2);
            red_cluster(&arena[3][a], c3);
          } else if constexpr (kVariant == kGeneric) {
            red_generic(&arena[0][a], c0);
            red_generic(&arena[1][a], c1);
            red_generic(&arena[2][a], c2);
            red_generic(&arena[3][a], c3);
          } else if constexpr (kVariant == kReduce) {
            const float s0 = seg_sum(c0), s1 = seg_sum(c1), s2 = seg_sum(c2), s3 = seg_sum(c3);
            if (head) {
              atomicAdd(&arena[0][a], s0);
              atomicAdd(&arena[1][a], s1);
              atomicAdd(&arena[2][a], s2);
              atomicAdd(&arena[3][a], s3);
            }
          } else if constexpr (kVariant == kFixed64) {
            unsigned long long* la = reinterpret_cast<unsigned long long*>(&arena[0][0]);
            atomicAdd(&la[a], static_cast<unsigned long long>(__float2ll_rn(c0 * 1048576.f)));
            atomicAdd(&la[kStorage / 2 + (a >> 1)], static_cast<unsigned long long>(__float2ll_rn(c1 * 1048576.f)));
          } else {
            int* ia = reinterpret_cast<int*>(&arena[0][0]);
            atomicAdd(&ia[a], __float2int_rn(c0 * 1048576.f));
            atomicAdd(&ia[kStorage + a], __float2int_rn(c1 * 1048576.f));
            atomicAdd(&ia[2 * kStorage + a], __float2int_rn(c2 * 1048576.f));
            atomicAdd(&ia[3 * kStorage + a], __float2int_rn(c3 * 1048576.f));
          }
        }
      }
    }
  }
  __syncthreads();
  if (threadIdx.x < 4) {
    double s = 0.0;
    for (int n = 0; n < kStorage; ++n) {
      const float v = arena[threadIdx.x][n];
      s += kVariant == kFixed64 ? 0.0 : kVariant == kFixed ? static_cast<double>(__float_as_int(v)) / 1048576.0 : static_cast<double>(v);
    }
    block_sums[blockIdx.x * 4 + threadIdx.x] = s;
  }
}

using Kernel = void (*)(int, double*);
const Kernel kKernels[kVariants] = {scatter<kCas>, scatter<kCas4>, scatter<kCluster>, scatter<kGeneric>,
                                    scatter<kFixed>, scatter<kReduce>, scatter<kFixed64>};

}  // namespace

int main(int argc, char** argv) {
  int blocks = 20000, reps = 7;
  for (int i = 1; i < argc; ++i) {
    if (!std::strncmp(argv[i], "--blocks=", 9)) blocks = std::atoi(argv[i] + 9);
    if (!std::strncmp(argv[i], "--reps=", 7)) reps = std::atoi(argv[i] + 7);
  }
  cudaDeviceProp prop{};
  CHECK(cudaGetDeviceProperties(&prop, 0));
  std::printf("device: %s; %d blocks x %d particles, 108 adds each\n", prop.name, blocks, kThreads * kBinsPerWarp);
  double* sums = nullptr;
  CHECK(cudaMalloc(&sums, sizeof(double) * blocks * 4));
  std::vector<double> host(blocks * 4), ref(blocks * 4);
  cudaEvent_t e0, e1;
  CHECK(cudaEventCreate(&e0));
  CHECK(cudaEventCreate(&e1));
  std::printf("%-14s %-8s %10s %14s %12s\n", "pattern", "variant", "ms", "adds/ns", "max rel err");
  for (int pattern = 0; pattern < kPatterns; ++pattern) {
    for (int v = 0; v < kVariants; ++v) {
      std::vector<float> ms;
      for (int r = 0; r < reps; ++r) {
        CHECK(cudaEventRecord(e0));
        kKernels[v]<<<blocks, kThreads>>>(pattern, sums);
        CHECK(cudaGetLastError());
        CHECK(cudaEventRecord(e1));
        CHECK(cudaEventSynchronize(e1));
        float t = 0.f;
        CHECK(cudaEventElapsedTime(&t, e0, e1));
        ms.push_back(t);
      }
      std::sort(ms.begin(), ms.end());
      CHECK(cudaMemcpy(host.data(), sums, sizeof(double) * host.size(), cudaMemcpyDeviceToHost));
      if (v == kCas) ref = host;
      double err = 0.0;
      for (std::size_t i = 0; i < host.size(); ++i)
        err = std::max(err, std::fabs(host[i] - ref[i]) / std::max(1e-6, std::fabs(ref[i])));
      const double adds = static_cast<double>(blocks) * kThreads * kBinsPerWarp * 108.0;
      std::printf("%-14s %-8s %10.3f %14.2f %12.2e\n", kPatternNames[pattern], kNames[v], ms[ms.size() / 2],
                  adds / (ms[ms.size() / 2] * 1e6), err);
    }
  }
  return 0;
}
