// Grid update kernels: v = p/m + dt g with the shared boundary projections, max |v| for the next dt, and the dt.
#pragma once

#include <cuda_runtime.h>

#include "MnBase/Math/vec.h"
#include "physics/boundary.cuh"
#include "engine/gpu/grid_buffer.cuh"
#include "physics/grid_update.cuh"
#include "physics/seepage.cuh"
#include "physics/grid_fields.h"
#include "physics/sensors.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/kernels/kernel_common.cuh"
#include "physics/time_step.cuh"

namespace fbar {

/// Boundaries a grid update applies (those active at the step's start time), by value.
template <typename T>
struct BoundarySet {
  static constexpr int kMax = 32;  ///< a kernel parameter with the profiles: 6-7 KiB (CUDA 12.1+: up to 32 KiB)
  int count;
  BoundaryParams<T> b[kMax];
  BoundaryProfiles<T> profiles;  ///< the points of the Bathymetry boundaries
};

/// A node's mass [kg] and momentum [kg m/s] from fixed-point sums (grid_buffer.cuh) and their quanta.
template <typename T>
FBAR_DEVICE FBAR_FORCE_INLINE T sum_mass(const GridSums<T>& g, const GridQuantum& q, int block, int node) {
  return static_cast<T>(g.units(block, kSumMass, node) * q.mass);
}
template <typename T, int C>
FBAR_DEVICE FBAR_FORCE_INLINE Vec3<T> sum_momentum(const FixedGrid<T, C>& g, const GridQuantum& q, int block, int node) {
  constexpr int first = C == 4 ? kSumMomentum : 0;
  return Vec3<T>{{static_cast<T>(g.units(block, first, node) * q.momentum),
                  static_cast<T>(g.units(block, first + 1, node) * q.momentum),
                  static_cast<T>(g.units(block, first + 2, node) * q.momentum)}};
}

template <typename T>
struct GridUpdateParams {
  GridSums<T> grid;                                 ///< P2G sums of this step (read only: kept for a retry)
  const GridQuantum* quantum;                       ///< their quanta
  typename GridLayout<T>::VelocityBuffer velocity;  ///< written: node velocities
  /// ASFLIP (when a body uses it, else null): the transported momentum the P2G summed apart (read), and v^n =
  /// transported / m (written), what G2P's FLIP increment needs (transfer.cuh).
  TransportedSums<T> transported;
  typename GridLayout<T>::VelocityBuffer old_velocity;
  /// Saturated bodies (else null): the seepage sums (seepage_sums, fixed point in the quanta of their bounds), and
  /// the node values written from them: the sums, replaced at every node with mass by the node's head h_i, inflow
  /// r_i and pore pressure p_i (seepage_node; grid_buffer.cuh names the channels).
  PoreSums<T> pore_sums;
  const unsigned long long* pore_bound;
  typename GridLayout<T>::PoreBuffer pore;
  const int* coords;                                ///< (block, axis) block coordinates (hash table)
  int block_count;
  T dt;         ///< [s]
  T dx;         ///< [m]
  Vec3<T> gravity;
  BoundarySet<T> boundaries;
  StepStats* stats;
};

inline constexpr int kGridUpdateThreads = 256;  ///< 4 blocks of 64 nodes per CUDA block

/// One thread per node; velocity = grid_node_velocity + boundary projections (exactly the CPU engine's order).
template <typename T>
__global__ void __launch_bounds__(kGridUpdateThreads) update_grid_velocity_query_max(GridUpdateParams<T> p) {
  const int block = blockIdx.x * (kGridUpdateThreads / 64) + threadIdx.x / 64;
  const int node = threadIdx.x % 64;
  double speed_sq = 0.0;
  if (block < p.block_count) {
    const GridQuantum q = *p.quantum;
    const T m = sum_mass(p.grid, q, block, node);
    const Vec3<T> momentum = sum_momentum(p.grid, q, block, node);
    Vec3<T> v = grid_node_velocity(m, momentum, p.gravity, p.dt);
    T pore[5] = {T(0), T(0), T(0), T(0), T(0)};
    if (p.pore)
      for (int c = 0; c < 5; ++c)
        pore[c] = static_cast<T>(p.pore_sums.units(block, c, node) * pore_quantum<T>(p.pore_bound[c]));
    if (p.old_velocity) {
      const Vec3<T> transported = sum_momentum(p.transported, q, block, node);
      const Vec3<T> v_old = grid_node_velocity(m, transported, Vec3<T>::zero(), p.dt);
      block_val(p.old_velocity, grid_velocity_x, block, node) = v_old[0];
      block_val(p.old_velocity, grid_velocity_y, block, node) = v_old[1];
      block_val(p.old_velocity, grid_velocity_z, block, node) = v_old[2];
    }
    if (m > T(0)) {
      const int i = node / 16, j = (node / 4) % 4, k = node % 4;
      const Vec3<T> x_node{{static_cast<T>(p.coords[3 * block + 0] * 4 + i) * p.dx,
                            static_cast<T>(p.coords[3 * block + 1] * 4 + j) * p.dx,
                            static_cast<T>(p.coords[3 * block + 2] * 4 + k) * p.dx}};
      for (int b = 0; b < p.boundaries.count; ++b)
        v = apply_boundary(p.boundaries.b[b], x_node, v, &p.boundaries.profiles);
      if (p.pore) {
        const auto held = [&] {  // some active boundary acts on the node: its water is held, never drained
          for (int b = 0; b < p.boundaries.count; ++b)
            if (boundary_holds(p.boundaries.b[b], x_node, &p.boundaries.profiles)) return true;
          return false;
        };
        const SeepageNode<T> n = seepage_node(pore[0], pore[1], pore[2], pore[4], x_node, p.gravity, held,
                                              p.dx * p.dx * p.dx);
        pore[1] = n.head;
        pore[2] = n.inflow;
        pore[4] = n.pressure;
      }
    }
    if (p.pore) {
      block_val(p.pore, grid_pore_volume, block, node) = pore[0];
      block_val(p.pore, grid_pore_head, block, node) = pore[1];
      block_val(p.pore, grid_pore_inflow, block, node) = pore[2];
      block_val(p.pore, grid_pore_water, block, node) = pore[3];
      block_val(p.pore, grid_pore_density, block, node) = pore[4];
    }
    block_val(p.velocity, grid_velocity_x, block, node) = v[0];
    block_val(p.velocity, grid_velocity_y, block, node) = v[1];
    block_val(p.velocity, grid_velocity_z, block, node) = v[2];
    speed_sq = static_cast<double>(dot(v, v));
  }
  // Warp max, then one atomic per CUDA block (a NaN never wins fmax, but a NaN velocity also NaNs its particles,
  // which the G2P2G checks count). One atomic per warp on this one address serialised in L2: half of this kernel's
  // 71 us at 31k blocks on an H200.
  __shared__ double warp_speed_sq[kGridUpdateThreads / 32];
  speed_sq = warp_max(speed_sq);
  if (threadIdx.x % 32 == 0) warp_speed_sq[threadIdx.x / 32] = speed_sq;
  __syncthreads();
  if (threadIdx.x == 0) {
    for (int w = 1; w < kGridUpdateThreads / 32; ++w) speed_sq = fmax(speed_sq, warp_speed_sq[w]);
    if (speed_sq > 0.0) atomic_max_nonneg(&p.stats->max_speed_sq, speed_sq);
  }
}

/// The grid sensors of a sampling step (physics/sensors.cuh), evaluated after the grid update from the same P2G sums
/// (v* = p/m + dt g again, bit for bit the update's) and the velocities it wrote, on the nodes this rank owns.
template <typename T>
struct GridSensorSampleParams {
  GridSums<T> grid;                                 ///< P2G sums of the step
  const GridQuantum* quantum;                       ///< their quanta
  typename GridLayout<T>::VelocityBuffer velocity;  ///< node velocities after the boundary projections
  typename GridLayout<T>::PoreBuffer pore;  ///< saturated bodies: water mass and p_i after the grid update (or null)
  /// A Volume or JBar sensor: every body's sum w V (1 - JBar) and sum w V (channels 0, 1) in units of volume_quantum
  /// (words null: no sensor reads them).
  FbarSums<T> volume{};
  double volume_quantum = 0.0;
  const int* coords;
  int block_count;
  T dt;
  T dx;
  Vec3<T> gravity;
  SlabBounds slab;
  /// Placed bodies: per table block, 1 when a lower rank also holds it (its nodes count there); null: the slab rule.
  const unsigned char* not_counted;
  GridSensorSet<T> sensors;
  SensorAccum* partials;  ///< (sensor, CUDA block) partial reductions
};

inline constexpr int kSensorThreads = 256;
inline constexpr int kSensorBlocks = 512;  ///< CUDA blocks per sensor at most (grid-stride beyond; sensor_device_bytes)

/// Reduces a block's SensorAccum onto thread 0 (warp shuffles, then the warps' results through shared memory), as
/// 8-byte words (SensorAccum has initializers: __shared__ cannot hold one; its sums merge order-free anyway).
FBAR_DEVICE inline SensorAccum block_reduce_sensor(SensorAccum a) {
  constexpr int kWords = static_cast<int>(sizeof(SensorAccum) / sizeof(long long));
  static_assert(sizeof(SensorAccum) == kWords * sizeof(long long), "SensorAccum is whole 8-byte words");
  __shared__ long long warps[kSensorThreads / 32][kWords];
  for (int offset = 16; offset > 0; offset /= 2) {
    long long mine[kWords], theirs[kWords];
    memcpy(mine, &a, sizeof(a));
    for (int k = 0; k < kWords; ++k) theirs[k] = __shfl_down_sync(0xffffffffu, mine[k], offset);
    SensorAccum o;
    memcpy(&o, theirs, sizeof(o));
    a.merge(o);
  }
  if (threadIdx.x % 32 == 0) memcpy(warps[threadIdx.x / 32], &a, sizeof(a));
  __syncthreads();
  if (threadIdx.x == 0)
    for (int w = 1; w < kSensorThreads / 32; ++w) {
      SensorAccum o;
      memcpy(&o, warps[w], sizeof(o));
      a.merge(o);
    }
  return a;
}

/// Node (block, node) as the sensors and fields read it: false when this rank does not count it, it has no mass, or
/// its block misses the box [lo, hi]; otherwise its position and sample.
template <typename T>
FBAR_DEVICE inline bool grid_node_sample(const GridSensorSampleParams<T>& p, const GridQuantum& q, int block, int node,
                                         const Vec3<T>& lo, const Vec3<T>& hi, Vec3<T>& x_node, int (&index)[3],
                                         GridNodeSample<T>& sample) {
  const int c0 = p.coords[3 * block], c1 = p.coords[3 * block + 1], c2 = p.coords[3 * block + 2];
  if (p.not_counted ? p.not_counted[block] != 0 : !p.slab.owns(c0, c1, c2)) return false;
  const int c[3] = {c0, c1, c2};
  bool overlaps = true;
  for (int d = 0; d < 3; ++d)
    overlaps = overlaps && static_cast<T>(c[d] * 4 + 3) * p.dx >= lo[d] && static_cast<T>(c[d] * 4) * p.dx <= hi[d];
  if (!overlaps) return false;
  const T m = sum_mass(p.grid, q, block, node);
  if (!(m > T(0))) return false;
  const int i = node / 16, j = (node / 4) % 4, k = node % 4;
  index[0] = c0 * 4 + i;
  index[1] = c1 * 4 + j;
  index[2] = c2 * 4 + k;
  x_node = Vec3<T>{{static_cast<T>(index[0]) * p.dx, static_cast<T>(index[1]) * p.dx, static_cast<T>(index[2]) * p.dx}};
  if (!sensor_box_contains(lo, hi, x_node)) return false;
  const Vec3<T> momentum = sum_momentum(p.grid, q, block, node);
  const Vec3<T> v_free = grid_node_velocity(m, momentum, p.gravity, p.dt);
  const Vec3<T> v{{block_val(p.velocity, grid_velocity_x, block, node), block_val(p.velocity, grid_velocity_y, block, node),
                   block_val(p.velocity, grid_velocity_z, block, node)}};
  sample = GridNodeSample<T>{m, momentum, v_free, v, p.dt};
  if (p.pore) {
    sample.water_mass = block_val(p.pore, grid_pore_water, block, node);
    sample.pore_pressure = block_val(p.pore, grid_pore_density, block, node);
  }
  if (p.volume.words) {
    sample.volume = static_cast<T>(p.volume.units(block, 1, node) * p.volume_quantum);
    sample.volume_jbar = static_cast<T>(p.volume.units(block, 0, node) * p.volume_quantum);
  }
  return true;
}

/// blockIdx.y = sensor; a grid-stride loop over the nodes (blocks whose extent misses the sensor's box are skipped
/// before any node is read), one partial per CUDA block. Fixed order: the sums are reproducible bit for bit.
template <typename T>
__global__ void __launch_bounds__(kSensorThreads) sample_grid_sensors(GridSensorSampleParams<T> p) {
  const GridSensorParams<T>& g = p.sensors.s[blockIdx.y];
  SensorAccum a;
  const GridQuantum q = *p.quantum;
  const long long nodes = static_cast<long long>(p.block_count) * 64;
  for (long long idx = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x; idx < nodes;
       idx += static_cast<long long>(gridDim.x) * blockDim.x) {
    Vec3<T> x_node;
    int index[3];
    GridNodeSample<T> sample;
    if (!grid_node_sample(p, q, static_cast<int>(idx / 64), static_cast<int>(idx % 64), g.lo, g.hi, x_node, index, sample))
      continue;
    if (!grid_sensor_reads(g, sample)) continue;  // the CPU engine's rule (accumulate_grid_sensors)
    a.add(static_cast<double>(grid_sensor_value(g, sample)));
  }
  a = block_reduce_sensor(a);
  if (threadIdx.x == 0) p.partials[static_cast<std::size_t>(blockIdx.y) * gridDim.x + blockIdx.x] = a;
}

/// One grid field's nodes (physics/grid_fields.h): every node this rank counts inside the box, in any order (the
/// recorder orders them by index); *count ends as their number (at most `capacity`, the box's node count).
template <typename T>
__global__ void __launch_bounds__(kSensorThreads)
    collect_grid_field(GridSensorSampleParams<T> p, GridFieldParams<T> f, GridFieldNode* out, int capacity, int* count) {
  const GridQuantum q = *p.quantum;
  const long long nodes = static_cast<long long>(p.block_count) * 64;
  for (long long idx = static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x; idx < nodes;
       idx += static_cast<long long>(gridDim.x) * blockDim.x) {
    Vec3<T> x_node;
    int index[3];
    GridNodeSample<T> sample;
    if (!grid_node_sample(p, q, static_cast<int>(idx / 64), static_cast<int>(idx % 64), f.lo, f.hi, x_node, index, sample))
      continue;
    const int at = atomicAdd(count, 1);
    if (at < capacity) out[at] = grid_field_node(index, sample);
  }
}

/// out[sensor] = the sensor's partials merged in CUDA-block order (one thread per sensor: at most kSensorBlocks).
static __global__ void merge_sensor_partials(const SensorAccum* partials, int per_sensor, int sensors, SensorAccum* out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= sensors) return;
  SensorAccum a;
  for (int b = 0; b < per_sensor; ++b) a.merge(partials[static_cast<std::size_t>(s) * per_sensor + b]);
  out[s] = a;
}

/// Per-body inputs of the time-step bound.
struct DtBody {
  double cfl;
  double rest_wave_speed;  ///< [m/s] floor of the body's wave speed (the speed at rest)
};

struct DtParams {
  static constexpr int kMaxBodies = 64;
  int body_count;
  DtBody bodies[kMaxBodies];
  const unsigned long long* wave_speed;  ///< (body) bits of the largest wave speed of the current state [m/s]
  double default_dt;                     ///< [s]
  double dx;                             ///< [m]
  double scale;                          ///< reduce_dt factor (1 when no step was repeated lately)
  double fixed_dt;                       ///< > 0: the next step's dt is given (step(dt)); else the CFL bound
  double t_next;                         ///< [s] time at the start of the next step
  double t_target;                       ///< [s] the next step is shortened to land here (inf: no target)
  StepStats* stats;
  /// The quanta of the grid the next P2G sums into (grid_buffer.cuh "Order-free grid sums"), or nullptr: mass
  /// M 2^-F, momentum max(headroom max_b B_b, M dx / dt) 2^-F, with M the largest particle (vertex) mass of any
  /// body, B_b the P2G bounds this try's G2P2G reads (p2g_bound, bound_count bodies) and dx / dt the speed no
  /// particle passes without failing the CFL check (a floor: a grid whose particles are at rest still takes the
  /// elements' impulses).
  GridQuantum* quantum;
  unsigned long long* p2g_bound;  ///< (body) bits of B_b; decomposed: replaced by the maximum over the ranks
  int bound_count;
  double mass_bound;              ///< [kg] M
  double headroom;                ///< kP2GHeadroom
  int fraction_bits;              ///< F: FixedSumFormat<TG>::kFractionBits
  /// Decomposed runs: the largest grid speed (bits of |v|^2), each body's wave speed, then each body's P2G bound,
  /// reduced over the ranks in one message (gather_dt_inputs); read instead of stats->max_speed_sq, wave_speed and
  /// p2g_bound, and the speed is written back to stats. nullptr: one GPU.
  const unsigned long long* reduced;
};

/// The inputs of compute_next_dt of a decomposed rank, side by side for one reduction over the ranks: out[0] the
/// largest |v|^2 of the grid update, out[1 + b] body b's wave speed, out[1 + bodies + b] its P2G bound (all as bits
/// of non-negative doubles).
static __global__ void gather_dt_inputs(const StepStats* stats, const unsigned long long* wave_speed,
                                        const unsigned long long* p2g_bound, int bodies, unsigned long long* out) {
  const int i = threadIdx.x;
  if (i == 0) out[0] = stats->max_speed_sq;
  if (i < bodies) {
    out[1 + i] = wave_speed[i];
    out[1 + bodies + i] = p2g_bound[i];
  }
}

/// dt of the next step: min(default_dt, min_b CFL_b dx / (c_b + |v|max)) x scale, clamped to the target time.
static __global__ void compute_next_dt(DtParams p) {
  if (threadIdx.x != 0 || blockIdx.x != 0) return;
  if (p.reduced) p.stats->max_speed_sq = p.reduced[0];  // the host reads the largest speed over the ranks
  double dt;
  if (p.fixed_dt > 0.0) {
    dt = p.fixed_dt;
  } else {
    const unsigned long long* wave = p.reduced ? p.reduced + 1 : p.wave_speed;
    const double vmax = sqrt(__longlong_as_double(static_cast<long long>(p.stats->max_speed_sq)));
    dt = p.default_dt;
    for (int b = 0; b < p.body_count; ++b) {
      const double c = fmax(__longlong_as_double(static_cast<long long>(wave[b])), p.bodies[b].rest_wave_speed);
      dt = min_time_step(dt, cfl_time_step(p.bodies[b].cfl, p.dx, c, vmax));
    }
    dt *= p.scale;
  }
  // Land on the target; when one more step would leave a sliver, two equal steps share what remains (as the
  // host's step_toward), so no step is shorter than half of the CFL dt.
  const double remaining = p.t_target - p.t_next;
  if (remaining > 0.0 && dt >= remaining)
    dt = remaining;
  else if (remaining > 0.0 && 2.0 * dt > remaining)
    dt = 0.5 * remaining;
  p.stats->dt_next = dt;
  if (p.quantum) {
    double bound = 0.0;
    for (int b = 0; b < p.bound_count; ++b) {
      const unsigned long long bits = p.reduced ? p.reduced[1 + p.bound_count + b] : p.p2g_bound[b];
      if (p.reduced) p.p2g_bound[b] = bits;  // every rank's arena uses the same bound
      bound = fmax(bound, __longlong_as_double(static_cast<long long>(bits)));
    }
    const double momentum = fmax(p.headroom * bound, p.mass_bound * p.dx / dt);
    p.quantum->mass = ldexp(p.mass_bound, -p.fraction_bits);
    p.quantum->momentum = ldexp(momentum, -p.fraction_bits);
  }
}

}  // namespace fbar
