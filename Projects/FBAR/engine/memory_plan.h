// Device memory of the GPU engine, planned before anything is allocated: one function that both the engine (to size
// its buffers) and `fbar --check` (to report and refuse) use, so the estimate is the allocation.
//
// What one device holds (GpuEngine<T, TG>; mgsp_benchmark.cuh allocates exactly these):
//   per grid block of capacity   hash table (2 slots of key u64 + value i32, power of two), block coordinates,
//                                the cached indices of its 2x2x2 arena (8 x i32), the channel sets the scene
//                                carries as engine/grid_channels.h declares them (two P2G grids of 4 channels x 64
//                                nodes, the grid velocity, ASFLIP's, F-bar's and the seepage channels), and
//                                per body the partition's per-block arrays (counts and bin offsets of two layouts,
//                                bins per block, halo tag: 21 B)
//   per particle slot of a body  two particle buffers (the fused G2P2G reads one and writes the other), ASFLIP's
//                                particle velocities beside both, the partition's src of two layouts and dest (16 B)
//   per particle of a body       its output frame on the device when frames are written (position in the particle
//                                scalar type and one float per output attribute, ID order)
// Capacities: grid blocks 2 x the blocks the particles' 2x2x2 footprints cover at start (at least 1024); bins
// 1.5 x (+16) what the particle blocks need at start (at least 64 and the flat upload). Both grow at run time when a
// scene outgrows them (the engine logs it; the plan reports what one growth costs).
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include "geometry/geometry.h"
#include "scene/scene.h"

namespace fbar {

/// Size limits of one device (docs/user_guide.md, "Limits").
struct DeviceLimits {
  /// Particle slots per body and device (bins x 32: particles plus the empty lanes of partly filled bins, headroom
  /// included; slot indices and particle IDs are 32-bit signed integers). Headroom is clamped to it, so a body may
  /// hold up to kMaxSlots slots of particles (about 2.0e9 particles of a compact 8 ppc body).
  static constexpr long long kMaxSlots = 2147483647LL;
  /// Grid blocks per device (block indices are 32-bit signed; the hash table has 2 x capacity slots, a power of two
  /// below 2^32).
  static constexpr long long kMaxBlocks = 1LL << 30;
  /// Bodies per device (the time-step kernel's table, grid_update_kernels.cuh DtParams::kMaxBodies).
  static constexpr int kMaxBodies = 64;
};

/// One body's inputs to the plan.
struct BodyMemoryInput {
  long long particles = 0;
  long long bins_needed = 0;     ///< sum over particle blocks of ceil(count / 32) at start
  int stored_scalars = 0;        ///< per particle in a bin: position (3) + the material's state
  bool asflip = false;           ///< PIC-FLIP / ASFLIP (particle velocities, transported grid momentum)
  bool fbar = false;             ///< F-bar (cell or node sums)
  bool fbar_nodal = false;       ///< nodal F-bar: 1 - JBar per slot beside both bin buffers
  bool pore = false;             ///< saturated (CoupledUP): the grid's seepage channels
  int frame_columns = -1;        ///< float attributes of its output frame, -1: no frames on the device
  bool record = false;           ///< v and C per particle slot (12 scalars: a particle sensor reads velocities)
  bool checkpoints = false;      ///< the ID and block of each slot's last P2G, for checkpoints (8 B a slot)
  std::size_t mesh_bytes = 0;    ///< a mesh body on this device: its elements (mesh_device_bytes)
};

/// The plan for one device. Every figure in bytes unless named otherwise.
struct DeviceMemoryPlan {
  Precision precision = Precision::Single;
  long long footprint_blocks = 0;  ///< grid blocks the particles' 2x2x2 footprints cover at start
  long long block_capacity = 0;
  std::vector<long long> bin_capacity;   ///< per body
  std::vector<long long> particles;      ///< per body
  std::size_t grid = 0;        ///< hash table, P2G grids, velocity, ASFLIP, F-bar and seepage channels
  std::size_t partition = 0;   ///< per-block and per-slot partition arrays of every body
  std::size_t particles_bytes = 0;  ///< particle buffers (both), ASFLIP particle velocities, recorded v and C
  std::size_t frames = 0;      ///< output frames kept on the device for the asynchronous download
  std::size_t small = 0;       ///< step statistics, scan scratch, per-body reductions
  std::size_t meshes = 0;      ///< mesh bodies' elements and vertex arrays (kernels/fem_kernels.cuh)
  std::size_t total() const { return grid + partition + particles_bytes + frames + small + meshes; }
  std::size_t grid_growth = 0;  ///< more device memory when the grid blocks double (transient copy included)
  std::size_t bins_growth = 0;  ///< more when every body's bins grow by half (transient copy included)
  long long total_particles() const;
};

/// Particles sampled and uploaded per batch by the GPU engine's set-up (host memory is O(batch), not O(N)).
inline constexpr long long kSampleBatchParticles = 1LL << 23;

/// Host memory one body's frame download may take before the GPU engine streams the frame (--frame-buffer).
inline constexpr std::size_t kFrameHostBytes = std::size_t(1) << 30;

/// GPU checkpoints (sensors_checkpoints.cuh) and --check's plan of them: whether a body of n particles with
/// stored_scalars scalars of scalar_bytes each is read from the device a range of IDs at a time (its copy by ID,
/// the stored scalars with v and C, exceeds frame_host_bytes; a mesh never is), and the IDs of a range (as many rows
/// and held-ID marks as frame_host_bytes holds, at most 2^20, at most n).
inline bool checkpoint_streamed(std::size_t n, int stored_scalars, std::size_t scalar_bytes,
                                std::size_t frame_host_bytes, bool mesh) {
  return !mesh && n > 0 && n * (static_cast<std::size_t>(stored_scalars) + 12) * scalar_bytes > frame_host_bytes;
}
inline std::size_t checkpoint_range_bytes(int stored_scalars, std::size_t scalar_bytes) {
  return (static_cast<std::size_t>(stored_scalars) + 12) * scalar_bytes + sizeof(int);
}
inline std::size_t checkpoint_range_ids(std::size_t n, int stored_scalars, std::size_t scalar_bytes,
                                        std::size_t frame_host_bytes) {
  const std::size_t ids = frame_host_bytes / checkpoint_range_bytes(stored_scalars, scalar_bytes);
  return std::max<std::size_t>(1, std::min({ids, std::size_t{1} << 20, n}));
}

/// CUDA context and runtime memory not in the plan (measured on an H100 with CUDA 13: 0.5-0.6 GiB).
inline constexpr std::size_t kCudaContextBytes = std::size_t(600) << 20;

/// Bytes of one particle in a bin: stored scalars and the 32-bit ID, padded to the scalar's alignment.
std::size_t particle_record_bytes(int stored_scalars, std::size_t scalar_bytes);

/// Bins of 32 the particle blocks of a count need: sum of ceil(count / 32).
long long bins_needed(const SampleCount& count);

/// Device bytes of a mesh body's elements and per-vertex arrays besides its bins (the GPU engine's MeshDevice): per
/// element its rest shape (4 indices, Dm^-1, V0), 4 CSR corners, F and (use_FEM) the forces H, (F-bar) J; per vertex
/// the CSR start, its slot, lumped mass and volume, position and two forces, (F-bar) its mean J.
std::size_t mesh_device_bytes(Precision precision, std::size_t elements, std::size_t vertices, bool fbar, bool forces);

/// Grid blocks covered by the 2x2x2 footprints (blocks B .. B + 1 per axis) of every particle block of `counts`.
long long footprint_blocks(const std::vector<const SampleCount*>& counts);

/// Grid-block and bin capacities and the bytes of every buffer (see the file comment). node_volume: a grid sensor
/// reads Volume or JBar (the grid carries the F-bar sums for it).
DeviceMemoryPlan plan_device_memory(Precision precision, long long footprint_blocks,
                                    const std::vector<BodyMemoryInput>& bodies, bool node_volume = false);

/// Empty when the plan fits `free_bytes` (with the context reserve already taken out of free_bytes by the caller,
/// or not: `free_bytes` is what cudaMemGetInfo reports before the engine allocates); otherwise a message that says
/// by how much it does not fit and what would (a coarser dx, fewer ppc, more GPUs), for `where` ("GPU 0").
std::string memory_fit_message(const DeviceMemoryPlan& plan, std::size_t free_bytes, std::size_t total_bytes,
                               const Scene& scene, const std::string& where);

/// "12.3 GiB" style.
std::string format_bytes(double bytes);

}  // namespace fbar
