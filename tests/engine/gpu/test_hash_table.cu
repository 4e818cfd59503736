// GPU hash table: concurrent inserts (with duplicates) against std::unordered_map, finds, overflow and growth.
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <random>
#include <set>
#include <unordered_map>
#include <vector>

#include "gpu_test_support.h"
#include "engine/gpu/hash_table.cuh"

namespace fbar {
namespace {

__global__ void insert_keys(BlockHashTableView table, const unsigned long long* keys, int n, int* index,
                            int* inserted_count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  bool inserted = false;
  index[i] = table.insert(keys[i], inserted);
  if (inserted) atomicAdd(inserted_count, 1);
}

__global__ void find_keys(BlockHashTableView table, const unsigned long long* keys, int n, int* index) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) index[i] = table.find(keys[i]);
}

/// find_arena of every (block, neighbour) of `blocks` (index 8 i + n).
__global__ void find_arena_all(BlockHashTableView table, const int* blocks, int n, int* index) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= 8 * n) return;
  const int block = blocks[i / 8];
  index[i] = table.find_arena(block, table.block_coords(block), i % 8);
}

struct Keys {
  std::vector<unsigned long long> keys;  // with repeats, shuffled
  std::vector<unsigned long long> absent;
};

Keys random_keys(int distinct, int repeats, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> coord(-300, 300);
  std::set<unsigned long long> unique;
  while (static_cast<int>(unique.size()) < distinct) unique.insert(BlockKey::pack(coord(rng), coord(rng), coord(rng)));
  Keys k;
  for (unsigned long long key : unique)
    for (int r = 0; r < repeats; ++r) k.keys.push_back(key);
  std::shuffle(k.keys.begin(), k.keys.end(), rng);
  while (k.absent.size() < 1000) {
    const unsigned long long key = BlockKey::pack(coord(rng) + 1000, coord(rng), coord(rng));
    if (!unique.count(key)) k.absent.push_back(key);
  }
  return k;
}

template <typename V>
V* to_device(const std::vector<V>& v) {
  V* d = nullptr;
  FBAR_CUDA_CHECK(cudaMalloc(&d, sizeof(V) * std::max<std::size_t>(v.size(), 1)));
  FBAR_CUDA_CHECK(cudaMemcpy(d, v.data(), sizeof(V) * v.size(), cudaMemcpyHostToDevice));
  return d;
}

/// Runs the inserts and checks them against a std::unordered_map built from the same keys.
void insert_and_check(BlockHashTable& table, const std::vector<unsigned long long>& keys, int expected_distinct) {
  const int n = static_cast<int>(keys.size());
  unsigned long long* d_keys = to_device(keys);
  int *d_index = nullptr, *d_inserted = nullptr;
  FBAR_CUDA_CHECK(cudaMalloc(&d_index, sizeof(int) * n));
  FBAR_CUDA_CHECK(cudaMalloc(&d_inserted, sizeof(int)));
  FBAR_CUDA_CHECK(cudaMemset(d_inserted, 0, sizeof(int)));
  insert_keys<<<(n + 255) / 256, 256>>>(table.view(), d_keys, n, d_index, d_inserted);
  FBAR_CUDA_CHECK(cudaGetLastError());
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  std::vector<int> index(n);
  int inserted = 0;
  TableCounters counters{};
  FBAR_CUDA_CHECK(cudaMemcpy(index.data(), d_index, sizeof(int) * n, cudaMemcpyDeviceToHost));
  FBAR_CUDA_CHECK(cudaMemcpy(&inserted, d_inserted, sizeof(int), cudaMemcpyDeviceToHost));
  FBAR_CUDA_CHECK(cudaMemcpy(&counters, table.counters(), sizeof(counters), cudaMemcpyDeviceToHost));
  EXPECT_EQ(counters.overflow, 0);
  EXPECT_EQ(counters.block_count, expected_distinct);
  // Every key maps to one index; distinct keys to distinct indices in [0, block_count); coords round-trip.
  std::unordered_map<unsigned long long, int> reference;
  std::set<int> used;
  for (int i = 0; i < n; ++i) {
    ASSERT_GE(index[i], 0);
    ASSERT_LT(index[i], counters.block_count);
    const auto [it, fresh] = reference.try_emplace(keys[i], index[i]);
    if (fresh) {
      EXPECT_TRUE(used.insert(index[i]).second) << "two keys share block index " << index[i];
    } else {
      EXPECT_EQ(it->second, index[i]) << "one key got two indices";
    }
  }
  std::vector<int> coords(3 * counters.block_count);
  FBAR_CUDA_CHECK(cudaMemcpy(coords.data(), table.view().coords, sizeof(int) * coords.size(), cudaMemcpyDeviceToHost));
  for (const auto& [key, idx] : reference) {
    const Vec3i c = BlockKey::unpack(key);
    EXPECT_EQ(coords[3 * idx + 0], c[0]);
    EXPECT_EQ(coords[3 * idx + 1], c[1]);
    EXPECT_EQ(coords[3 * idx + 2], c[2]);
  }
  cudaFree(d_keys);
  cudaFree(d_index);
  cudaFree(d_inserted);
}

std::vector<int> find_all(const BlockHashTable& table, const std::vector<unsigned long long>& keys) {
  const int n = static_cast<int>(keys.size());
  unsigned long long* d_keys = to_device(keys);
  int* d_index = nullptr;
  FBAR_CUDA_CHECK(cudaMalloc(&d_index, sizeof(int) * n));
  find_keys<<<(n + 255) / 256, 256>>>(table.view(), d_keys, n, d_index);
  FBAR_CUDA_CHECK(cudaGetLastError());
  std::vector<int> index(n);
  FBAR_CUDA_CHECK(cudaMemcpy(index.data(), d_index, sizeof(int) * n, cudaMemcpyDeviceToHost));
  cudaFree(d_keys);
  cudaFree(d_index);
  return index;
}

TEST(GpuHashTable, PackRoundTripsAndKeepsTheEmptyKeyFree) {
  for (const Vec3i c : {Vec3i{{0, 0, 0}}, Vec3i{{-1, 2, -3}}, Vec3i{{(1 << 20) - 1, -(1 << 20), 5}}}) {
    const std::uint64_t k = BlockKey::pack(c[0], c[1], c[2]);
    EXPECT_NE(k, BlockKey::kEmpty);
    EXPECT_EQ(BlockKey::unpack(k)[0], c[0]);
    EXPECT_EQ(BlockKey::unpack(k)[1], c[1]);
    EXPECT_EQ(BlockKey::unpack(k)[2], c[2]);
  }
}

TEST(GpuHashTable, ConcurrentInsertsMatchUnorderedMap) {
  FBAR_REQUIRE_DEVICE();
  const Keys k = random_keys(20000, 4, 1);  // 80000 concurrent inserts, each key by 4 threads
  BlockHashTable table;
  table.allocate(20000, nullptr);
  insert_and_check(table, k.keys, 20000);
  const std::vector<int> absent = find_all(table, k.absent);
  for (int v : absent) EXPECT_EQ(v, -1);
  // find() after the inserting launch returns the inserted index.
  const std::vector<int> again = find_all(table, k.keys);
  const std::vector<int> again2 = find_all(table, k.keys);
  EXPECT_EQ(again, again2);
  for (int v : again) EXPECT_GE(v, 0);
}

TEST(GpuHashTable, OverflowIsCountedAndGrowthKeepsIndices) {
  FBAR_REQUIRE_DEVICE();
  const Keys k = random_keys(3000, 1, 2);
  BlockHashTable table;
  table.allocate(1000, nullptr);  // room for 1000 of 3000 blocks
  const std::vector<unsigned long long> first(k.keys.begin(), k.keys.begin() + 900);
  insert_and_check(table, first, 900);
  const std::vector<int> before = find_all(table, first);
  // 2100 more keys into room for 100: refused inserts must be counted, never silently dropped.
  {
    const std::vector<unsigned long long> rest(k.keys.begin() + 900, k.keys.end());
    unsigned long long* d_keys = to_device(rest);
    int *d_index = nullptr, *d_inserted = nullptr;
    FBAR_CUDA_CHECK(cudaMalloc(&d_index, sizeof(int) * rest.size()));
    FBAR_CUDA_CHECK(cudaMalloc(&d_inserted, sizeof(int)));
    FBAR_CUDA_CHECK(cudaMemset(d_inserted, 0, sizeof(int)));
    insert_keys<<<(static_cast<int>(rest.size()) + 255) / 256, 256>>>(table.view(), d_keys, static_cast<int>(rest.size()),
                                                                      d_index, d_inserted);
    FBAR_CUDA_CHECK(cudaGetLastError());
    FBAR_CUDA_CHECK(cudaDeviceSynchronize());
    TableCounters c{};
    FBAR_CUDA_CHECK(cudaMemcpy(&c, table.counters(), sizeof(c), cudaMemcpyDeviceToHost));
    EXPECT_EQ(c.overflow, 2000);
    cudaFree(d_keys);
    cudaFree(d_index);
    cudaFree(d_inserted);
  }
  table.grow(4000, nullptr);
  TableCounters c{};
  FBAR_CUDA_CHECK(cudaMemcpy(&c, table.counters(), sizeof(c), cudaMemcpyDeviceToHost));
  EXPECT_EQ(c.overflow, 0);
  EXPECT_EQ(c.block_count, 1000);
  EXPECT_EQ(find_all(table, first), before) << "growth changed block indices";
  // Now all 3000 fit; the ones already present keep their index.
  insert_and_check(table, k.keys, 3000);
  EXPECT_EQ(find_all(table, first), before);
}

std::vector<int> find_arena_all(const BlockHashTable& table, const std::vector<int>& blocks) {
  const int n = static_cast<int>(blocks.size());
  int* d_blocks = to_device(blocks);
  int* d_index = nullptr;
  FBAR_CUDA_CHECK(cudaMalloc(&d_index, sizeof(int) * 8 * n));
  find_arena_all<<<(8 * n + 255) / 256, 256>>>(table.view(), d_blocks, n, d_index);
  FBAR_CUDA_CHECK(cudaGetLastError());
  std::vector<int> index(8 * n);
  FBAR_CUDA_CHECK(cudaMemcpy(index.data(), d_index, sizeof(int) * index.size(), cudaMemcpyDeviceToHost));
  cudaFree(d_blocks);
  cudaFree(d_index);
  return index;
}

std::vector<int> arena_cache(const BlockHashTable& table, int blocks) {
  std::vector<int> cache(8 * static_cast<std::size_t>(blocks));
  FBAR_CUDA_CHECK(cudaMemcpy(cache.data(), table.view().arena, sizeof(int) * cache.size(), cudaMemcpyDeviceToHost));
  return cache;
}

// The arena cache (BlockHashTableView::find_arena, which G2P2G's set-up reads) against find(): the same index from
// the lookup and from the cache, -1 (and nothing cached) for a neighbour that is absent, kept by growth, reset by
// clear() (where the indices are handed out again).
TEST(GpuHashTable, ArenaCacheAgreesWithFindAndLivesAsLongAsTheIndices) {
  FBAR_REQUIRE_DEVICE();
  // Blocks of a 6 x 5 x 4 box, so that the +x/+y/+z neighbours of its last layers are absent.
  std::vector<unsigned long long> keys;
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 5; ++y)
      for (int z = 0; z < 4; ++z) keys.push_back(BlockKey::pack(x - 3, y, z + 7));
  BlockHashTable table;
  table.allocate(200, nullptr);
  insert_and_check(table, keys, static_cast<int>(keys.size()));
  const std::vector<int> index = find_all(table, keys);
  std::vector<unsigned long long> neighbour_keys;
  for (unsigned long long key : keys) {
    const Vec3i c = BlockKey::unpack(key);
    for (int n = 0; n < 8; ++n) neighbour_keys.push_back(BlockKey::arena_neighbour(c, n));
  }
  const std::vector<int> expected = find_all(table, neighbour_keys);
  int absent = 0;
  for (int v : expected) absent += v < 0;
  ASSERT_GT(absent, 0);
  const int n = static_cast<int>(keys.size());
  EXPECT_EQ(find_arena_all(table, index), expected);  // looked up, then cached
  std::vector<int> cache = arena_cache(table, n);
  for (int i = 0; i < 8 * n; ++i) EXPECT_EQ(cache[8 * static_cast<std::size_t>(index[i / 8]) + i % 8], expected[i]);
  EXPECT_EQ(find_arena_all(table, index), expected);  // from the cache
  table.grow(400, nullptr);
  EXPECT_EQ(arena_cache(table, n), cache) << "growth lost the cache";
  EXPECT_EQ(find_arena_all(table, index), expected);
  table.clear(nullptr);
  for (int v : arena_cache(table, n)) EXPECT_EQ(v, -1) << "clear() kept a cached index";
}

}  // namespace
}  // namespace fbar
