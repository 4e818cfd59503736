// plan_device_memory(): the GPU engine's capacities and buffer sizes from a scene's counts (memory_plan.h).
#include "engine/memory_plan.h"

#include "engine/grid_channels.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <sstream>
#include <unordered_set>

namespace fbar {
namespace {

std::size_t particle_scalar_bytes(Precision p) { return p == Precision::Single ? 4 : 8; }

/// Hash-table slots for a block capacity: the next power of two >= 2 x capacity, at least 1024 (hash_table.cuh).
std::size_t table_slots(long long capacity) {
  std::size_t p = 1024;
  while (p < 2 * static_cast<std::size_t>(capacity)) p <<= 1;
  return p;
}

/// Grid bytes at a block capacity (everything indexed by block, bodies' partition arrays excluded): the table and
/// every channel set the scene carries (grid_channels.h).
std::size_t grid_bytes(long long capacity, Precision precision, GridFeatures features) {
  const std::size_t c = static_cast<std::size_t>(capacity);
  // keys, values, coordinates, the arena cache (8 indices a block), counters
  const std::size_t bytes = table_slots(capacity) * (8 + 4) + c * 3 * 4 + c * 8 * 4 + 8;
  return bytes + c * grid_channel_block_bytes(precision, features);
}

/// The largest one copy of a channel set the scene carries, per block (alive beside its bigger copy while the
/// grid grows).
std::size_t largest_grid_set_block_bytes(Precision precision, GridFeatures features) {
  std::size_t largest = 0;
  for (const GridSetDecl& d : kGridSets)
    if (features.has(d.need)) largest = std::max(largest, grid_set_block_bytes(d, grid_scalar_bytes(precision)));
  return largest;
}

/// Per-block partition arrays of one body (partition_domain.h): count and bin offset of two layouts, bins per
/// block (one GPU: a decomposed rank with overlap_halo adds its two block lists, 8 bytes per block).
std::size_t partition_block_bytes(long long capacity) {
  const std::size_t c = static_cast<std::size_t>(capacity);
  return c * (2 * 2 * 4 + 4);
}

}  // namespace

long long bins_needed(const SampleCount& count) {
  long long bins = 0;
  for (const BlockCount& c : count.blocks) bins += (c.particles + 31) / 32;
  return bins;
}

long long footprint_blocks(const std::vector<const SampleCount*>& counts) {
  // Keys pack the coordinates in 21 bits each with a bias of 2^20 (hash_table.cuh BlockKey's packing).
  auto pack = [](long long x, long long y, long long z) {
    constexpr long long bias = 1 << 20;
    return (static_cast<std::uint64_t>(x + bias) << 42) | (static_cast<std::uint64_t>(y + bias) << 21) |
           static_cast<std::uint64_t>(z + bias);
  };
  std::unordered_set<std::uint64_t> blocks;
  for (const SampleCount* count : counts)
    for (const BlockCount& c : count->blocks)
      for (int n = 0; n < 8; ++n) blocks.insert(pack(c.bx + (n >> 2), c.by + ((n >> 1) & 1), c.bz + (n & 1)));
  return static_cast<long long>(blocks.size());
}

std::size_t particle_record_bytes(int stored_scalars, std::size_t scalar_bytes) {
  const std::size_t raw = static_cast<std::size_t>(stored_scalars) * scalar_bytes + 4;
  return (raw + scalar_bytes - 1) / scalar_bytes * scalar_bytes;
}

long long DeviceMemoryPlan::total_particles() const {
  long long n = 0;
  for (long long p : particles) n += p;
  return n;
}

DeviceMemoryPlan plan_device_memory(Precision precision, long long footprint_blocks,
                                    const std::vector<BodyMemoryInput>& bodies, bool node_volume) {
  DeviceMemoryPlan plan;
  plan.precision = precision;
  plan.footprint_blocks = footprint_blocks;
  plan.block_capacity = std::max<long long>(1024, 2 * footprint_blocks);
  GridFeatures features;
  features.node_volume = node_volume;
  for (const BodyMemoryInput& b : bodies) {
    features.asflip = features.asflip || b.asflip;
    features.fbar = features.fbar || b.fbar;
    features.pore = features.pore || b.pore;
  }
  const std::size_t t = particle_scalar_bytes(precision);
  plan.grid = grid_bytes(plan.block_capacity, precision, features);
  const std::size_t grid_largest =
      static_cast<std::size_t>(plan.block_capacity) * largest_grid_set_block_bytes(precision, features);
  // Doubling: the bigger arrays, and one old array alive during its copy.
  plan.grid_growth = grid_bytes(2 * plan.block_capacity, precision, features) - plan.grid + grid_largest;
  for (const BodyMemoryInput& b : bodies) {
    const long long flat = (b.particles + 31) / 32;
    long long bins = std::max<long long>(64, std::max(flat, b.bins_needed * 3 / 2 + 16));
    bins = std::min(bins, std::max(flat, DeviceLimits::kMaxSlots / 32));  // headroom never past the slot limit
    plan.bin_capacity.push_back(bins);
    plan.particles.push_back(b.particles);
    const std::size_t slots = static_cast<std::size_t>(bins) * 32;
    const std::size_t record = particle_record_bytes(b.stored_scalars, t);
    std::size_t particle = 2 * slots * record;
    if (b.asflip) particle += 2 * slots * 3 * t;
    if (b.fbar_nodal) particle += 2 * slots * t;  // nodal F-bar's 1 - JBar beside both bin buffers
    if (b.record) particle += slots * 12 * t;  // v and C (kAuxScalars), one copy
    if (b.checkpoints) particle += slots * 8;  // the ID and block of each slot's last P2G (a checkpoint's grouping)
    plan.particles_bytes += particle;
    const std::size_t per_slot = slots * (2 * 4 + 8);
    plan.partition += partition_block_bytes(plan.block_capacity) + per_slot;
    plan.grid_growth += partition_block_bytes(plan.block_capacity);
    // Growth by half: the new buffers, and one src array of the old size alive during its copy.
    plan.bins_growth += (particle + per_slot) / 2 + slots * 4;
    plan.meshes += b.mesh_bytes;
    if (b.frame_columns >= 0)
      plan.frames += static_cast<std::size_t>(b.particles) * (3 * t + 4 * static_cast<std::size_t>(b.frame_columns));
  }
  // Step statistics (a few hundred bytes per body), wave speeds and P2G bounds, the CUB scan's scratch for
  // capacity + 1 integers (a tile descriptor per 2^11 items and a little fixed space).
  plan.small = 4096 + bodies.size() * 256 + (static_cast<std::size_t>(plan.block_capacity) / 2048 + 2) * 16 + 1024;
  return plan;
}

std::size_t mesh_device_bytes(Precision precision, std::size_t elements, std::size_t vertices, bool fbar, bool forces) {
  const std::size_t t = particle_scalar_bytes(precision);
  return elements * ((16 + 10 * t) + 16 + 9 * t + (forces ? 9 * t : 0) + (fbar ? t : 0)) +
         vertices * (4 + 4 + 2 * t + 3 * t + 6 * t + (fbar ? t : 0)) + 4;
}

std::string format_bytes(double bytes) {
  char buf[48];
  if (bytes >= 1024.0 * 1024.0 * 1024.0)
    std::snprintf(buf, sizeof(buf), "%.2f GiB", bytes / (1024.0 * 1024.0 * 1024.0));
  else if (bytes >= 1024.0 * 1024.0)
    std::snprintf(buf, sizeof(buf), "%.1f MiB", bytes / (1024.0 * 1024.0));
  else
    std::snprintf(buf, sizeof(buf), "%.0f KiB", bytes / 1024.0);
  return buf;
}

std::string memory_fit_message(const DeviceMemoryPlan& plan, std::size_t free_bytes, std::size_t total_bytes,
                               const Scene& scene, const std::string& where) {
  const double need = static_cast<double>(plan.total());
  const double have = static_cast<double>(free_bytes);
  if (need <= have) return {};
  // Memory is nearly proportional to the particle count: N ~ ppc / dx^3.
  const double ratio = need / std::max(have, 1.0);
  std::ostringstream os;
  os << where << ": the scene needs " << format_bytes(need) << " of device memory for "
     << plan.total_particles() << " particles, but " << format_bytes(have) << " of " << format_bytes(static_cast<double>(total_bytes))
     << " are free. What would fit: simulation.default_dx " << scene.simulation.dx << " -> "
     << scene.simulation.dx * std::cbrt(ratio * 1.05) << " m (coarser)";
  double ppc = 0.0;
  for (const BodySpec& b : scene.bodies) ppc = std::max(ppc, b.material.ppc);
  if (ppc > 1.0) os << ", or material.ppc " << ppc << " -> " << std::max(1.0, std::floor(ppc / (ratio * 1.05)));
  os << ", or " << static_cast<int>(std::ceil(ratio * 1.05))
     << " GPUs of this size (--gpus=N, or one MPI rank per GPU: every body is spread over them by space)";
  return os.str();
}

}  // namespace fbar
