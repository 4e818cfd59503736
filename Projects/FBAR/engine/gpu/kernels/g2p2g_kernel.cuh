// The fused G2P2G kernel (Wang et al. 2020): one template for every material, one CUDA block per particle block.
//
// Off-by-2 (the arena a particle block needs). A particle at x has the stencil base node base = floor(x/dx - 0.5)
// (per axis) and touches nodes base .. base + 2 in G2P. The CFL check guarantees a move of at most one cell, so
// the new base' lies in [base - 1, base + 1] and P2G touches nodes base - 1 .. base + 3. A block-aligned arena of
// nodes [4B, 4B + 8) (2x2x2 grid blocks starting at block B) holds all of them iff 4B <= base - 1 and
// base + 3 <= 4B + 7, i.e. base - 1 in [4B, 4B + 3]: B = floor((base - 1) / 4). That is the particle block of the
// particle (partition_domain.h). In the arena the G2P stencil starts at l = base - 4B in [1, 4] and the P2G
// stencil at l' = base' - 4B in [0, 5]; the kernel checks l' and counts a violation (never writes outside).
//
// Per CUDA block (particle block b, 8x8x8-node arena):
//   1. look up the 8 grid blocks of the arena, load the velocities of its inner 6x6x6 nodes into shared memory
//      (arena_v);
//   2. each warp takes bins of the block: read particles through the layout (fused reorder), G2P (v, C),
//      advection, state update (material advance), checks (NaN/Inf, left domain, CFL), store the particle in
//      layout order, stress (material kirchhoff_stress with the new C), P2G into arena_p with shared atomics,
//      record the particle's next block and rank (hash-table insert deduplicated per warp);
//   3. add arena_p into the next grid's fixed-point sums with global integer atomics (nodes no particle touched are
//      skipped; grid_buffer.cuh "Order-free grid sums").
// The P2G impulse uses the next step's dt (read from the device: compute_next_dt ran before this kernel), so the
// next grid holds exactly what the CPU engine's P2G of the next step computes.
// initial (a run-time flag of the same instantiation a step launches): the P2G of the initial state (v = initial
// velocity, C = 0 or a restart's, no motion): how the driver starts. Launched twice: first with bound_only (each
// particle's P2G bound measured, nothing written but the maxima), then into the arena with that bound, like every
// other launch. One instantiation for both, so that a restart's P2G runs the machine code of the step it replaces:
// a kernel of its own (it was one) sums the same particles differently in the last bit where the compiler
// contracts a multiply and an add in one and not in the other, and a restart then leaves the uninterrupted run.
//
// Fixed-point arena. On sm_90 a shared-memory float or double atomicAdd is a
// compare-and-swap loop (LDS, FADD, ATOMS.CAST.SPIN, branch; tools/benchmark/shared_atomics.cu): 108 of them per
// particle were ~90 % of this kernel. 32-bit integer shared atomics are native (ATOMS.ADD), 3.6x faster on the same
// scatter, so the arena accumulates integers in units of a per-block quantum q (FixedArena: int32 for float, int64
// as two 32-bit words with a carry for double, since 64-bit shared atomics are CAS loops too) and the flush adds
// sum x q into the grid. The quantum makes overflow impossible: a node's sum is bounded by
// sum_p w_ip |c_p| <= 0.75^3 count B, with count the block's particles and B a bound on every contribution per unit
// weight (mass: m_p; momentum: p2g_momentum_bound of every particle), so q = 0.75^3 count B / R keeps every sum,
// rounding included, inside the integer (R = 2^31 - 2^24 or 2^63 - 2^40; the int32 arena counts a block as 512
// particles at least, so that one contribution is at most 2^22 units and one FFMA rounds it: FixedArena::add_product).
// The momentum bound B is the previous
// try's measured maximum times kP2GHeadroom; a particle above it flags the try (StepStats::p2g_range) and the driver
// repeats the step with the bound it just measured, which then holds for every particle. Rounding: |error| <= q/2
// per contribution, about 1e-7 B (float) or 2e-16 B (double) at 512 particles per block: the size of the
// floating-point round-off of the same sums. Summation is order-independent within a block; the flush converts a
// block's integers to the grid's quanta (one rounding per node and block) and adds integers there too, so the whole
// P2G is order-free: the bound B and the grid's quanta are the same on every rank (reduced over the ranks with the
// wave speeds, compute_next_dt), so 1, 2 or 4 GPUs give the same sums.
#pragma once

#include <cuda_runtime.h>

#include <climits>
#include <type_traits>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "physics/constitutive_models.cuh"
#include "physics/frame_columns.h"
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/kernels/kernel_common.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "engine/gpu/partition_domain.h"
#include "settings.h"
#include "physics/seepage.cuh"
#include "physics/transfer.cuh"
#include "physics/fbar_nodal.cuh"

namespace fbar {

static_assert(settings::kBinSize == 32, "one warp processes one bin: lane = particle");
static_assert(settings::kArenaSide == 8 && settings::kBlockSide == 4, "the arena is 2x2x2 blocks of 4x4x4 nodes");

/// Threads of a G2P2G CUDA block (one particle block) over a grid of TG: float grids 2 warps, so that 12 blocks are
/// resident per SM (float JFluid: 80 registers, 12 x 17.5 KB of shared memory) and while some set up or flush their
/// arena others run particles (4 warps, 6 blocks per SM, took 1.7 % longer for JFluid and 4.8 % for FixedCorotated:
/// tools/benchmark/NOTES.md, v13); double grids 4 warps, where the int64 arena's 35 KB per block allow 6 blocks per
/// SM and 2 warps would halve the resident warps (double JFluid took 11 % longer).
template <typename TG>
inline constexpr int kG2P2GThreads = sizeof(TG) == sizeof(float) ? 64 : 128;
/// Threads of the other passes with one CUDA block per particle block (F-bar's cell sums, the seepage sums).
inline constexpr int kParticleBlockThreads = 128;
inline constexpr int kArenaSide = settings::kArenaSide;  ///< nodes per axis of the shared arena (2 grid blocks)
inline constexpr int kArenaNodes = kArenaSide * kArenaSide * kArenaSide;
/// Shared-memory stride of one x-plane of the arena: 64 nodes + 4. Unpadded, nodes one x apart are 64 words apart
/// (the same bank), so lanes of one bin in cells that differ only in x hit one bank; +4 shifts each plane by 4
/// banks. Storage per channel: 8 x 68 words.
inline constexpr int kArenaPlane = kArenaSide * kArenaSide + 4;
inline constexpr int kArenaStorage = kArenaSide * kArenaPlane;
/// Scalars written per slot when velocities are recorded: v (3) then C row-major (9).
inline constexpr int kAuxScalars = 12;
/// Fixed-point arena: headroom of the momentum bound over the previous try's maximum, and the largest weight of a
/// quadratic B-spline stencil node (0.75^3).
inline constexpr double kP2GHeadroom = 2.0;
inline constexpr double kMaxNodeWeight = 0.421875;

/// A body's output frame on the device (ID order), written by the G2P2G of the step that lands on a frame time and
/// by capture_frame_state before the first step: positions in T, then one float per attribute (frame_columns.h).
template <typename T>
struct FrameCapture {
  T* x = nullptr;            ///< (ID, 3) [m], nullptr: this launch captures nothing
  float* columns = nullptr;  ///< (column, ID)
  int particles = 0;         ///< entries of x and of each column
  /// A decomposed rank's directory (nullptr: one GPU, entry = ID): bit id % 32 of id_bits[id / 32] is set when the
  /// rank holds particle id, id_offset[w] counts the set bits of the words before w; the entry of particle id is
  /// its rank among the rank's IDs, so a rank's frame is in ID order and as long as its particle count.
  const unsigned* id_bits = nullptr;
  const int* id_offset = nullptr;
  int column_count = 0;
  bool sigma = false;        ///< some column reads the Cauchy stress
  FrameColumn column[kMaxFrameColumns];
};

/// A body's particle mass and reference volume: one value for every particle, or (a mesh body: physics/fem.cuh) the
/// lumped value of each vertex by ID.
template <typename T>
struct ParticleMeasures {
  T mass = T(0);                      ///< [kg] every particle's (a mesh: the largest vertex mass, the P2G quantum's bound)
  T volume = T(0);                    ///< [m^3]
  const T* vertex_mass = nullptr;     ///< (ID) [kg], or nullptr
  const T* vertex_volume = nullptr;   ///< (ID) [m^3], or nullptr
  FBAR_HOST_DEVICE T mass_of(int id) const { return vertex_mass ? vertex_mass[id] : mass; }
  FBAR_HOST_DEVICE T volume_of(int id) const { return vertex_volume ? vertex_volume[id] : volume; }
};

/// Writes particle `id`'s frame entry from its new state (out of line: only capture steps pay its registers).
template <typename M, typename T>
__device__ __noinline__ void capture_particle(const FrameCapture<T>& cap, int id, const Vec3<T>& x, const Vec3<T>& v,
                                              const Mat3<T>& C, const material_state_t<M, T>& s,
                                              const material_params_t<M, T>& material, T mass, T volume,
                                              bool nodal = false, T one_minus_jbar = T(0)) {
  if (cap.id_bits) {
    if (id < 0) return;
    id = cap.id_offset[id >> 5] + __popc(cap.id_bits[id >> 5] & ((1u << (id & 31)) - 1u));
  }
  if (id < 0 || id >= cap.particles) return;
  const FrameInputs<T> in =
      particle_frame_inputs<M, T>(x, v, C, s, material, mass, volume, cap.sigma, nodal, one_minus_jbar);
  const std::size_t i = static_cast<std::size_t>(id);
  cap.x[3 * i + 0] = x[0];
  cap.x[3 * i + 1] = x[1];
  cap.x[3 * i + 2] = x[2];
  for (int c = 0; c < cap.column_count; ++c)
    cap.columns[static_cast<std::size_t>(c) * cap.particles + i] = static_cast<float>(frame_value(cap.column[c], in));
}

template <typename M, typename T, typename TG>
struct G2P2GParams {
  using Bins = typename ParticleLayout<M, T>::Buffer;
  Bins in;                   ///< particles of this step (storage order)
  Bins out;                  ///< particles of the next step, written in this layout's order
  LayoutView layout;         ///< this step's layout
  /// Decomposed runs: CUDA block k runs the particle block layout.order[order_first + k] (one pass of the halo-first
  /// G2P2G); one GPU: order_first < 0 and CUDA block k runs table block k.
  int order_first;
  int* next_count;           ///< (block) particles per block of the next layout (zeroed before)
  ParticleDest* dest;        ///< (slot) next block and rank of each particle
  BlockHashTableView table;
  typename GridLayout<TG>::VelocityBuffer velocity;  ///< grid velocities of this step
  GridSums<TG> grid_next;               ///< P2G target (zeroed on blocks [0, block count))
  GridSums<TG> grid_this;               ///< this step's P2G sums: a new block is zeroed here as well
  const GridQuantum* quantum_next;      ///< the quanta of grid_next (compute_next_dt)
  bool initial;                         ///< the initial (or a restart's) P2G: v and C from initial_v / initial_C
  bool bound_only;                      ///< initial: measure the P2G bound only (nothing else is written)
  T* aux;                    ///< (slot, kAuxScalars) v and C, or nullptr
  FrameCapture<T> capture;   ///< this body's frame (capture.x != nullptr on a frame step; nullptr in a kCapture
                             ///< launch: none written, a restart's P2G after a frame step)
  /// ASFLIP (transfer.cuh). Every body adds its transported momentum m (v + C (x_i - x_p)) to `transported_next`
  /// when any body uses ASFLIP (non-null); a body that uses it also reads v^n (`old_velocity`) and its particles'
  /// velocities (`particle_v_in` at the storage slot, `particle_v_out` at the layout slot; 3 scalars per slot).
  TransportedSums<TG> transported_next;
  typename GridLayout<TG>::VelocityBuffer old_velocity;
  const T* particle_v_in;
  T* particle_v_out;
  bool asflip;                ///< this body uses PIC-FLIP / ASFLIP
  AsflipParams<T> asflip_params;
  FbarSums<TG> fbar_sums;    ///< F-bar cell sums of this body (fbar_cell_sums), when fbar_psi > 0
  double fbar_quantum;       ///< [m^3] their quantum
  T fbar_psi;                ///< [-] F-bar: the fraction of J pulled to its cell's mean per step, 0: off (transfer.cuh)
  /// Nodal F-bar (physics/fbar_nodal.cuh): fbar_sums holds this body's node sums (fbar_node_sums) instead of cell
  /// sums; the particles' 1 - JBar beside the bins (jbar_in at the storage slot, jbar_out at the layout slot).
  bool fbar_nodal = false;
  bool fbar_fused = false;
  const T* jbar_in = nullptr;
  T* jbar_out = nullptr;
  /// Saturated bodies (IsPoreFluid): the grid's h_i and r_i after the grid update (seepage_sums, then
  /// update_grid_velocity_query_max), read by G2P's seepage (physics/seepage.cuh); gravity for the head's datum.
  typename GridLayout<TG>::PoreBuffer pore;
  Vec3<T> gravity;           ///< [m/s^2]
  material_params_t<M, T> material;
  T mass;                    ///< [kg] per particle (a mesh body: the largest vertex mass, bounding the P2G quantum)
  T volume;                  ///< [m^3] reference volume per particle
  /// A mesh body (physics/fem.cuh; the kMesh launches): each vertex's lumped mass by ID, and its
  /// P2G carries no MLS stress (the elements' force impulse follows, kernels/fem_kernels.cuh); nullptr otherwise.
  const T* vertex_mass;
  Vec3<T> initial_velocity;  ///< [m/s] (initial)
  const T* initial_v;        ///< (particle ID, 3) per-particle initial velocities [m/s] (initial), or nullptr
  const T* initial_C;        ///< (particle ID, 9) per-particle APIC C [1/s] (initial; a restart), or nullptr: 0
  T dt;                      ///< [s] this step
  T dx, inv_dx, d_inv;       ///< [m], [1/m], [1/m^2]
  Vec3<T> domain;            ///< [m]
  const double* dt_next;     ///< [s] impulse dt of the P2G (device, from compute_next_dt)
  StepStats* stats;
  BodyStepStats* body_stats;
  SlabBounds slab;           ///< the particle blocks this rank owns: a particle leaving them is an emigrant
  int* emigrant_slots;       ///< decomposed runs: the slots of this try's emigrants (body_stats->emigrant_list
                             ///< counts them all; at most emigrant_capacity stored); nullptr on one GPU
  int emigrant_capacity;
  unsigned long long* wave_speed;  ///< (this body) bits of the largest wave speed of the new state
  const unsigned long long* p2g_bound_in;  ///< (this body) bits of the momentum bound B of the last try [kg m/s]
  unsigned long long* p2g_bound_out;       ///< (this body) bits of the largest p2g_momentum_bound of this try
};

/// Dynamic shared memory of a g2p2g launch [bytes]: the P2G arena of 4 channels, or 7 when transported momentum
/// is summed (ASFLIP), in the grid scalar type TG.
template <typename TG>
constexpr std::size_t g2p2g_arena_bytes(bool transported) {
  return static_cast<std::size_t>(transported ? 7 : 4) * kArenaStorage * sizeof(TG);
}

namespace g2p2g_detail {

/// One arena node's grid velocity, padded to 4 scalars so G2P reads a node with one 16-byte (float) or two
/// 16-byte (double) shared loads instead of three scalar loads.
template <typename T>
struct alignas(4 * sizeof(T)) ArenaVelocity {
  T x, y, z, pad;
};

/// Integer view of the arena's (channel, node) sums for the fixed-point P2G. kRange: the magnitude a node's sum may
/// use; the rounding of up to 2^24 (float) or 2^40 (double) contributions stays inside the integer.
template <typename T>
struct FixedArena;
template <>
struct FixedArena<float> {
  static constexpr double kRange = 2147483648.0 - 16777216.0;  // 2^31 - 2^24
  unsigned* words;                                               // (channel, node): int32
  int channels;                                                  // 4, or 7 with ASFLIP's transported momentum
  /// units: in the particle scalar type (float, or double in mixed precision: rounded once, to the integer).
  template <typename U>
  FBAR_DEVICE FBAR_FORCE_INLINE void add(int ch, int a, U units) const {
    int v;
    if constexpr (std::is_same_v<U, double>) v = __double2int_rn(units);
    else v = __float2int_rn(units);
    atomicAdd(reinterpret_cast<int*>(words) + ch * kArenaStorage + a, v);
  }
  /// Blocks count as kMinCount particles at least in their quantum (g2p2g's span), so that one contribution, at most
  /// 0.75^3 B / q = kRange / max(count, kMinCount) units, stays within 2^22: add_product can then round x y to the
  /// integer with one FFMA instead of a multiply and an F2I (a quarter-rate instruction).
  static constexpr int kMinCount = 512;
  /// Adds round(x y) units (|x y| < 2^22): fma(x, y, 1.5 2^23) is the float nearest x y + 1.5 2^23, whose bits are
  /// those of 1.5 2^23 plus the nearest integer to x y (a double: 1.5 2^52, whose low 32 bits are 0).
  template <typename U>
  FBAR_DEVICE FBAR_FORCE_INLINE void add_product(int ch, int a, U x, U y) const {
    int v;
    if constexpr (std::is_same_v<U, double>)
      v = static_cast<int>(static_cast<unsigned>(static_cast<unsigned long long>(
          __double_as_longlong(__fma_rn(x, y, 6755399441055744.0)))));
    else
      v = __float_as_int(__fmaf_rn(x, y, 12582912.0f)) - 0x4B400000;
    atomicAdd(reinterpret_cast<int*>(words) + ch * kArenaStorage + a, v);
  }
  FBAR_DEVICE FBAR_FORCE_INLINE float units(int ch, int a) const {
    return static_cast<float>(static_cast<int>(words[ch * kArenaStorage + a]));
  }
  FBAR_DEVICE FBAR_FORCE_INLINE double exact(int ch, int a) const {  ///< the sum, exactly
    return static_cast<double>(static_cast<int>(words[ch * kArenaStorage + a]));
  }
};
template <>
struct FixedArena<double> {
  static constexpr double kRange = 9223372036854775808.0 - 1099511627776.0;  // 2^63 - 2^40
  unsigned* words;  // (half, channel, node): low then high 32 bits of an int64
  int channels;     // 4, or 7 with ASFLIP's transported momentum
  /// 64-bit add from two native 32-bit ones: a low word that wraps carries exactly once into the high word, so the
  /// pair holds the exact sum modulo 2^64 whatever the interleaving.
  static constexpr int kMinCount = 1;  ///< the quantum follows the block's count (FixedArena<float>::kMinCount)
  FBAR_DEVICE FBAR_FORCE_INLINE void add_product(int ch, int a, double x, double y) const { add(ch, a, x * y); }
  FBAR_DEVICE FBAR_FORCE_INLINE void add(int ch, int a, double units) const {
    const long long v = __double2ll_rn(units);
    const unsigned lo = static_cast<unsigned>(v), hi = static_cast<unsigned>(static_cast<unsigned long long>(v) >> 32);
    const unsigned old = atomicAdd(words + ch * kArenaStorage + a, lo);
    atomicAdd(words + (channels + ch) * kArenaStorage + a, hi + (old + lo < old ? 1u : 0u));
  }
  FBAR_DEVICE FBAR_FORCE_INLINE double units(int ch, int a) const {
    const unsigned long long bits = (static_cast<unsigned long long>(words[(channels + ch) * kArenaStorage + a]) << 32) |
                                    words[ch * kArenaStorage + a];
    return static_cast<double>(static_cast<long long>(bits));
  }
  FBAR_DEVICE FBAR_FORCE_INLINE double exact(int ch, int a) const { return units(ch, a); }  ///< rounded to 53 bits
};

/// Shared-memory index of arena node (a, b, c) (x-planes padded, see kArenaPlane).
FBAR_DEVICE FBAR_FORCE_INLINE int arena_index(int a, int b, int c) { return a * kArenaPlane + b * kArenaSide + c; }
/// Which of the arena's 2x2x2 grid blocks holds arena node (a, b, c) (neighbour = (di * 2 + dj) * 2 + dk), and the
/// node's index inside that block.
FBAR_DEVICE FBAR_FORCE_INLINE int arena_neighbour(int a, int b, int c) {
  return ((a >> 2) * 2 + (b >> 2)) * 2 + (c >> 2);
}
FBAR_DEVICE FBAR_FORCE_INLINE int arena_node_in_block(int a, int b, int c) {
  return ((a & 3) * 4 + (b & 3)) * 4 + (c & 3);
}

/// Threads 0..7 of the CUDA block: the hash-table index of each of the arena's 2x2x2 grid blocks of table block
/// `block` at `origin` (from the table's arena cache after a block's first lookup), -1 and an internal error when
/// one is missing. The caller synchronises.
FBAR_DEVICE FBAR_FORCE_INLINE void find_arena_blocks(const BlockHashTableView& table, int block, const Vec3i& origin,
                                                     int* arena_blocks, StepStats* stats) {
  if (threadIdx.x < 8) {
    const int found = table.find_arena(block, origin, static_cast<int>(threadIdx.x));
    arena_blocks[threadIdx.x] = found;
    if (found < 0) atomicAdd(&stats->internal_error, 1);
  }
}

/// The grid velocities G2P reads into shared memory (zero in a missing block): the arena's inner 6x6x6 nodes, 1..6
/// on each axis, where the G2P stencils of the block's particles lie (they start at l = base - 4B in [1, 4]; the
/// arena's outer nodes 0 and 7 only receive the P2G of particles that moved). The outer nodes are not written.
/// The caller synchronises before and after.
template <typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void load_arena_velocities(const typename GridLayout<TG>::VelocityBuffer& velocity,
                                                         const int* arena_blocks, ArenaVelocity<TG>* arena_v) {
  constexpr int kThreads = kG2P2GThreads<TG>;
  constexpr int kInner = 6 * 6 * 6;
  // Unrolled: a thread's loads of all its nodes are in flight together.
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int r = 0; r < (kInner + kThreads - 1) / kThreads; ++r) {
    const int i = static_cast<int>(threadIdx.x) + r * kThreads;
    if (i >= kInner) break;
    const int a = 1 + i / 36, bc = i - (a - 1) * 36, b = 1 + bc / 6, c = 1 + bc - (b - 1) * 6;
    const int nb = arena_blocks[arena_neighbour(a, b, c)];
    const int node = arena_node_in_block(a, b, c);
    TG vx = TG(0), vy = TG(0), vz = TG(0);
    if (nb >= 0) {
      vx = block_val(velocity, grid_velocity_x, nb, node);
      vy = block_val(velocity, grid_velocity_y, nb, node);
      vz = block_val(velocity, grid_velocity_z, nb, node);
    }
    arena_v[arena_index(a, b, c)] = ArenaVelocity<TG>{vx, vy, vz, TG(0)};
  }
}

/// transfer.cuh's for_each_stencil_node with the 27 nodes unrolled: the same weights in the same order
/// (w0 w1, then x w2), so the stencil arrays stay in registers (the rolled loop put them in local memory).
template <typename T, typename F>
FBAR_DEVICE FBAR_FORCE_INLINE void for_each_stencil_node_unrolled(const QuadraticBspline<T>& s, T dx, F&& f) {
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < 3; ++i)
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
    for (int j = 0; j < 3; ++j) {
      const T wij = s.w[0][i] * s.w[1][j];
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
      for (int k = 0; k < 3; ++k) f(i, j, k, wij * s.w[2][k], s.node_offset(i, j, k, dx));
    }
}

/// G2P's velocity and affine sums, v = sum_i w v_i and B = sum_i w v_i (x_i - x_p)^T (transfer.cuh's G2PSum), with
/// the sums over k done first per (i, j) column of nodes: S = sum_k w_k v, Z = sum_k w_k d_k v (6 multiply-adds per
/// node), then v += w_i w_j S, B += (w_i w_j S) (d_i, d_j, 0)^T + w_i w_j Z e_z^T (12 per column), 10 a node instead
/// of 3 multiplies, 3 adds and 9 multiply-adds (the compiler may not re-associate them). Same sums, other rounding
/// (a few ulps of |v|). Arena: the stencil's first node at (c0, c1, c2).
template <typename T, typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void g2p_sums_by_column(const QuadraticBspline<T>& s, T dx, const ArenaVelocity<TG>* arena,
                                                      int c0, int c1, int c2, Vec3<T>& v, Mat3<T>& B) {
  T d[3][3];  // x_i - x_p per axis and node
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int a = 0; a < 3; ++a)
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
    for (int n = 0; n < 3; ++n) d[a][n] = s.axis_offset(a, n, dx);
  v = Vec3<T>::zero();
  B = Mat3<T>::zero();
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < 3; ++i)
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
    for (int j = 0; j < 3; ++j) {
      Vec3<T> sk = Vec3<T>::zero(), zk = Vec3<T>::zero();
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
      for (int k = 0; k < 3; ++k) {
        const ArenaVelocity<TG> n = arena[arena_index(c0 + i, c1 + j, c2 + k)];
        const Vec3<T> vn{{static_cast<T>(n.x), static_cast<T>(n.y), static_cast<T>(n.z)}};
        sk += vn * s.w[2][k];
        zk += vn * (s.w[2][k] * d[2][k]);
      }
      const T wij = s.w[0][i] * s.w[1][j];
      const Vec3<T> ws = sk * wij;
      v += ws;
      for (int r = 0; r < 3; ++r) {
        B(r, 0) += ws[r] * d[0][i];
        B(r, 1) += ws[r] * d[1][j];
        B(r, 2) += zk[r] * wij;
      }
    }
}

/// P2G of one particle's momentum into arena channels ch .. ch + 2 (and, kMass, its mass into channel 0), all
/// in the block's quanta: node (i, j, k) gets w (p + A (x_i - x_p)) with p + A (x_i - x_p) built up per axis
/// (p + A_x d_i per i, + A_y d_j per (i, j), + A_z d_k per node: 3 adds and 3 multiplies per node instead of 3
/// multiplies and 9 multiply-adds). The weight is transfer.cuh's (w_i w_j) w_k, so the mass is added exactly as
/// before; the momentum is rounded otherwise (a few ulps). Arena: the stencil's first node at (l0, l1, l2).
template <bool kMass, typename T, typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void p2g_add_factored(const QuadraticBspline<T>& w, T dx, const FixedArena<TG>& fixed,
                                                    int l0, int l1, int l2, T mass, const Vec3<T>& p,
                                                    const Mat3<T>& A, int ch) {
  Vec3<T> az[3];  // A_z d_k
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int k = 0; k < 3; ++k) {
    const T d = w.axis_offset(2, k, dx);
    az[k] = Vec3<T>{{A(0, 2) * d, A(1, 2) * d, A(2, 2) * d}};
  }
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < 3; ++i) {
    const T wi = w.w[0][i];
    const T dxi = w.axis_offset(0, i, dx);
    const Vec3<T> pi{{p[0] + A(0, 0) * dxi, p[1] + A(1, 0) * dxi, p[2] + A(2, 0) * dxi}};
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
    for (int j = 0; j < 3; ++j) {
      const T dyj = w.axis_offset(1, j, dx);
      const Vec3<T> pij{{pi[0] + A(0, 1) * dyj, pi[1] + A(1, 1) * dyj, pi[2] + A(2, 1) * dyj}};
      const T wij = wi * w.w[1][j];
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
      for (int k = 0; k < 3; ++k) {
        const T wt = wij * w.w[2][k];
        const int a = arena_index(l0 + i, l1 + j, l2 + k);
        if constexpr (kMass) fixed.add_product(0, a, wt, mass);
        fixed.add_product(ch, a, pij[0] + az[k][0], wt);
        fixed.add_product(ch + 1, a, pij[1] + az[k][1], wt);
        fixed.add_product(ch + 2, a, pij[2] + az[k][2], wt);
      }
    }
  }
}

template <typename T, int N, typename State>
FBAR_DEVICE FBAR_FORCE_INLINE bool state_finite(const State& state) {
  const T* s = reinterpret_cast<const T*>(&state);
  bool ok = true;
#if FBAR_IN_DEVICE_CODE
#pragma unroll
#endif
  for (int i = 0; i < N; ++i) ok = ok && isfinite(s[i]);
  return ok;
}

/// Warp-cooperative: every lane with has_key inserts/finds its block once per distinct key (one leader per key),
/// reserves ranks for all lanes sharing it and returns {block, rank}; {-1, -1} for lanes without a key or when the
/// table overflowed. grid_a/grid_b: new blocks are zeroed there. Must be called by all 32 lanes, converged.
/// own_key / own_index: a block known to be in the table (g2p2g: the particle block itself), which needs no lookup.
/// The common case (every keyed lane has one key) skips the lane matching; the leader's index and rank base reach
/// the other lanes by full-warp shuffles after the leader's branch has reconverged (a shuffle inside the branch,
/// masked to the peers, compiled to a collective loop that every bin of every G2P2G paid).
template <typename T>
FBAR_DEVICE ParticleDest claim_block_rank(bool has_key, std::uint64_t key, const BlockHashTableView& table,
                                          int* next_count, const GridSums<T>& grid_a, const GridSums<T>& grid_b,
                                          std::uint64_t own_key = BlockKey::kEmpty, int own_index = -1) {
  constexpr unsigned kFull = 0xffffffffu;
  const unsigned keyed = __ballot_sync(kFull, has_key);
  if (keyed == 0) return ParticleDest{-1, -1};
  const std::uint64_t k = has_key ? key : BlockKey::kEmpty;
  const std::uint64_t first_key = __shfl_sync(kFull, k, __ffs(keyed) - 1);
  const unsigned peers = __all_sync(kFull, !has_key || k == first_key)
                             ? keyed
                             : __match_any_sync(kFull, static_cast<unsigned long long>(k));
  const int lane = threadIdx.x % 32;
  const int leader = has_key ? __ffs(peers) - 1 : lane;
  int index = -1, base = 0;
  if (has_key && lane == leader) {
    if (k == own_key) {
      index = own_index;
    } else {
      bool inserted = false;
      index = table.insert(k, inserted);
      if (inserted) {
        grid_a.zero_block(index);
        grid_b.zero_block(index);
      }
    }
    if (index >= 0) base = atomicAdd(&next_count[index], __popc(peers));
  }
  index = __shfl_sync(kFull, index, leader);
  base = __shfl_sync(kFull, base, leader);
  if (!has_key || index < 0) return ParticleDest{-1, -1};
  return ParticleDest{index, base + __popc(peers & lanemask_lt())};
}

/// What the threads of one g2p2g CUDA block share: the arena in shared memory (grid velocities, the P2G sums as
/// integers, the hash-table indices of its 2x2x2 grid blocks), the particle block's origin, the fixed-point quanta
/// of this block's P2G [kg], [kg m/s] with their inverses and the bound every particle must meet, and the factors
/// from this block's quanta to the grid's (q / Q).
template <typename T, typename TG>
struct BlockArena {
  const ArenaVelocity<TG>* velocity;
  FixedArena<TG> fixed;
  const int* blocks;
  Vec3i origin;
  int channels;  ///< 4, or 7 with the transported momentum (ASFLIP)
  T dt_next;
  T q_mass, inv_q_mass, q_momentum, inv_q_momentum, limit;
  double to_grid_mass, to_grid_momentum;
};

/// One lane's particle between its G2P and its P2G: the new state, velocity and affine matrix, the check that
/// failed (-1: none), and where the particle goes next (its block key on this rank, or the neighbour that owns it).
template <typename M, typename T>
struct LaneParticle {
  Vec3<T> v, x_new;
  Mat3<T> C;
  material_state_t<M, T> state;
  T jbar = T(0);  ///< nodal F-bar: 1 - JBar after the step
  int failed = -1;
  int emigrant = -1;  ///< 0 / 1: the lower / upper neighbour owns the particle's next block
  bool has_key = false;
  std::uint64_t key = 0;
};

/// G2P of one particle from the arena's velocities: v, C, advection, the material update (with F-bar's cell mean
/// and ASFLIP's increment when the body uses them) and the checks, in the CPU engine's order: non-finite, inverted,
/// left the domain, moved more than a cell. The initial P2G instead starts from the initial (or a restart's) v, C.
template <typename M, typename T, typename TG, bool kMayAsflip, bool kMesh>
FBAR_DEVICE FBAR_FORCE_INLINE void g2p_particle(const G2P2GParams<M, T, TG>& p, const BlockArena<T, TG>& arena,
                                                const ParticleRecord<M, T>& in, int src, LaneParticle<M, T>& out) {
  constexpr int kStateScalars = ParticleLayout<M, T>::kStateScalars;
  if (p.initial) {
    const std::size_t i = 3 * static_cast<std::size_t>(in.id);  // by ID: a rank uploads a subset of the IDs
    out.v = p.initial_v ? Vec3<T>{{p.initial_v[i], p.initial_v[i + 1], p.initial_v[i + 2]}} : p.initial_velocity;
    out.C = Mat3<T>::zero();
    if (p.initial_C) {
      const T* c = p.initial_C + 9 * static_cast<std::size_t>(in.id);
      for (int r = 0; r < 3; ++r)
        for (int cc = 0; cc < 3; ++cc) out.C(r, cc) = c[3 * r + cc];
    }
    out.x_new = in.x;
    out.state = in.state;
    if (p.fbar_nodal) out.jbar = p.jbar_in[src];
    return;
  }
  const QuadraticBspline<T> s = quadratic_bspline_inv(in.x, p.inv_dx);
  const Vec3i& origin = arena.origin;
  const int l0 = s.base[0] - 4 * origin[0], l1 = s.base[1] - 4 * origin[1], l2 = s.base[2] - 4 * origin[2];
  if (l0 < 0 || l0 > 5 || l1 < 0 || l1 > 5 || l2 < 0 || l2 > 5) {
    atomicAdd(&p.stats->internal_error, 1);  // a particle outside its block's arena: never expected
  }
  const int c0 = min(max(l0, 0), 5), c1 = min(max(l1, 0), 5), c2 = min(max(l2, 0), 5);
  if constexpr (std::is_same_v<T, float>) {
    Mat3<T> B;
    g2p_sums_by_column<T, TG>(s, p.dx, arena.velocity, c0, c1, c2, out.v, B);
    out.C = B * p.d_inv;  // G2PSum::affine
  } else {  // double particles: the column sums' extra registers cost more than their instructions save
    G2PSum<T> sum;
    for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
      const ArenaVelocity<TG> node_v = arena.velocity[arena_index(c0 + i, c1 + j, c2 + k)];
      sum.add(w, Vec3<T>{{static_cast<T>(node_v.x), static_cast<T>(node_v.y), static_cast<T>(node_v.z)}}, xixp);
    });
    out.v = sum.velocity();
    out.C = sum.affine(p.d_inv);
  }
  if (!(kMayAsflip && p.asflip)) out.x_new = advect(in.x, out.v, p.dt);
  if constexpr (kMesh) {
    out.state = in.state;  // a vertex's state is its elements' (the element pass sets it from the new positions)
  } else if (p.fbar_nodal) {  // nodal F-bar: the nodes' 1 - JBar gathered, blended (physics/fbar_nodal.cuh)
    T gathered = T(0);
    const double q = p.fbar_quantum;
    for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>&) {
      const int a = c0 + i, b = c1 + j, c = c2 + k;
      const int nb = arena.blocks[arena_neighbour(a, b, c)];
      if (nb < 0) return;  // counted as an internal error when the arena was set up
      const int node = arena_node_in_block(a, b, c);
      gathered += w * fbar_node_value(static_cast<T>(p.fbar_sums.units(nb, 0, node) * q),
                                      static_cast<T>(p.fbar_sums.units(nb, 1, node) * q), p.fbar_fused);
    });
    const NodalFbar<T> nf = nodal_fbar<M>(in.state, out.C, gathered, p.fbar_fused, p.fbar_psi, p.dt);
    out.state = M::advance(p.material, in.state, nf.C_state, p.dt);
    out.jbar = nf.s;
  } else if (p.fbar_psi != T(0)) {  // F-bar: J is pulled toward its cell's mean, then advanced (transfer.cuh)
    const Vec3i cell = fbar_cell_offset(in.x, p.inv_dx, s.base);
    const int a = c0 + cell[0], b = c1 + cell[1], c = c2 + cell[2];
    const int nb = arena.blocks[arena_neighbour(a, b, c)];
    const int node = arena_node_in_block(a, b, c);
    const T one_minus_J = one_minus_volume_ratio<M>(in.state);
    const T cell_mean = nb < 0 ? one_minus_J
                               : fbar_cell_compression(
                                     static_cast<T>(p.fbar_sums.units(nb, 0, node) * p.fbar_quantum),
                                     static_cast<T>(p.fbar_sums.units(nb, 1, node) * p.fbar_quantum));
    out.state = M::advance(p.material, in.state,
                           fbar_velocity_gradient(out.C, one_minus_J, cell_mean, p.fbar_psi, p.dt), p.dt);
  } else {
    out.state = M::advance(p.material, in.state, out.C, p.dt);
  }
  if constexpr (IsPoreFluid<M>::value) {  // the pore water's flow from the grid's heads (physics/seepage.cuh)
    SeepageSum<T> seep;
    for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>& xixp) {
      const int a = c0 + i, b = c1 + j, c = c2 + k;
      const int nb = arena.blocks[arena_neighbour(a, b, c)];
      if (nb < 0) return;  // counted as an internal error when the arena was set up
      const int node = arena_node_in_block(a, b, c);
      seep.add(w, xixp, static_cast<T>(block_val(p.pore, grid_pore_head, nb, node)),
               static_cast<T>(block_val(p.pore, grid_pore_inflow, nb, node)));
    });
    out.state = M::seep(p.material, out.state, seep.inflow, seep.head_gradient(p.d_inv),
                        seep.head + M::water_density(p.material) * dot(p.gravity, in.x),
                        M::pore_pressure(out.state) - M::pore_pressure(in.state), p.dt);
  }
  if (kMayAsflip && p.asflip) {  // FLIP increment from v^n at the stencil, the particle's own velocity
    G2POldSum<T> old;
    for_each_stencil_node_unrolled(s, p.dx, [&](int i, int j, int k, T w, const Vec3<T>&) {
      const int a = c0 + i, b = c1 + j, c = c2 + k;
      const int nb = arena.blocks[arena_neighbour(a, b, c)];
      if (nb < 0) return;
      const int node = arena_node_in_block(a, b, c);
      old.add(w, Vec3<T>{{static_cast<T>(block_val(p.old_velocity, grid_velocity_x, nb, node)),
                          static_cast<T>(block_val(p.old_velocity, grid_velocity_y, nb, node)),
                          static_cast<T>(block_val(p.old_velocity, grid_velocity_z, nb, node))}});
    });
    const T* vp = p.particle_v_in + static_cast<std::size_t>(src) * 3;
    // Nodal F-bar: the expansion test reads JBar, as ClaymoreUW's does.
    const AsflipUpdate<T> u = asflip_update(p.asflip_params, Vec3<T>{{vp[0], vp[1], vp[2]}}, out.v, old.v,
                                            p.fbar_nodal ? T(1) - out.jbar : M::volume_ratio(out.state), p.dt);
    out.v = u.v;
    out.x_new = in.x + u.move;
  }
  if (!(all_finite(out.x_new) && all_finite(out.v) && all_finite(out.C) &&
        state_finite<T, kStateScalars>(out.state))) {
    out.failed = kFailNonFinite;
  } else if (!kMesh && !(M::volume_ratio(out.state) > T(0))) {  // a mesh's elements: the element pass
    out.failed = kFailInverted;
  } else {
    if (!inside_domain(out.x_new, p.domain, p.dx))
      out.failed = kFailLeftDomain;
    else if (max_abs(out.x_new - in.x) > p.dx)
      out.failed = kFailCfl;
  }
}

/// What one particle writes besides the next P2G: its record in layout order, ASFLIP's velocity, the recorded v and
/// C (aux) and, in a capture launch, its frame columns.
template <typename M, typename T, typename TG, bool kMayAsflip, bool kCapture>
FBAR_DEVICE FBAR_FORCE_INLINE void store_particle_outputs(const G2P2GParams<M, T, TG>& p, int slot, int id,
                                                          const LaneParticle<M, T>& s) {
  ParticleRecord<M, T> out{s.x_new, s.state, id};
  store_particle<M, T>(p.out, slot, out);
  if (p.fbar_nodal) p.jbar_out[slot] = s.jbar;
  if (kMayAsflip && p.asflip) {
    T* vp = p.particle_v_out + static_cast<std::size_t>(slot) * 3;
    vp[0] = s.v[0];
    vp[1] = s.v[1];
    vp[2] = s.v[2];
  }
  if (p.aux != nullptr) {
    T* a = p.aux + static_cast<std::size_t>(slot) * kAuxScalars;
    a[0] = s.v[0];
    a[1] = s.v[1];
    a[2] = s.v[2];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a[3 + 3 * r + c] = s.C(r, c);
  }
  if constexpr (kCapture)
    if (p.capture.x)
      capture_particle<M, T>(p.capture, id, s.x_new, s.v, s.C, s.state, p.material, p.mass, p.volume, p.fbar_nodal,
                             s.jbar);
}

/// P2G of one particle that passed its checks: wave speed, stress, the MLS payload with the next step's impulse
/// into the arena (integers in the block's quanta), the momentum bound it needs, and its next block (key) or the
/// neighbour that owns it. measure_only (the initial launch's first pass): the bound and the wave speed only.
template <typename M, typename T, typename TG, bool kMayMesh>
FBAR_DEVICE FBAR_FORCE_INLINE void p2g_particle(const G2P2GParams<M, T, TG>& p, const BlockArena<T, TG>& arena,
                                                LaneParticle<M, T>& s, int id, double& wave_max, double& bound_max,
                                                bool& out_of_range, bool measure_only) {
  const QuadraticBspline<T> w = quadratic_bspline_inv(s.x_new, p.inv_dx);
  const Vec3i& origin = arena.origin;
  const int l0 = w.base[0] - 4 * origin[0], l1 = w.base[1] - 4 * origin[1], l2 = w.base[2] - 4 * origin[2];
  if (l0 < 0 || l0 > 5 || l1 < 0 || l1 > 5 || l2 < 0 || l2 > 5) {
    s.failed = kFailCfl;  // left the arena (rounding at exactly one cell): same meaning, never written
    return;
  }
  // Nodal F-bar: the state dilated to JBar is the one stressed (physics/fbar_nodal.cuh).
  const material_state_t<M, T> stressed = p.fbar_nodal ? fbar_stress_state<M>(p.material, s.state, s.jbar) : s.state;
  // The wave speed, or the key that orders states by it (evaluated once per block: reduce_block_maxima).
  if constexpr (material_detail::has_wave_speed_order<M>::value)
    wave_max = fmax(wave_max, static_cast<double>(M::wave_speed_order(p.material, stressed)));
  else
    wave_max = fmax(wave_max, static_cast<double>(M::wave_speed(p.material, stressed)));
  // A mesh vertex: its own mass and no MLS stress (physics/fem.cuh).
  const bool mesh = kMayMesh && p.vertex_mass != nullptr;
  const T mass = mesh ? p.vertex_mass[id] : p.mass;
  const Mat3<T> tau = mesh ? Mat3<T>::zero() : M::kirchhoff_stress(p.material, stressed, s.C).kirchhoff;
  const T dt_next = arena.dt_next;
  const P2GParticle<T> payload = mls_p2g_particle(mass, p.volume, s.v, s.C, tau, dt_next, p.d_inv);
  // ASFLIP: the momentum the particle carries, without the stress impulse (v^n of the next step).
  const bool transport = arena.channels == 7;
  const P2GParticle<T> carried =
      transport ? mls_p2g_particle(mass, p.volume, s.v, s.C, Mat3<T>::zero(), dt_next, p.d_inv) : P2GParticle<T>{};
  T b = p2g_momentum_bound(payload, p.dx);
  if (transport) b = fmax(b, p2g_momentum_bound(carried, p.dx));
  if (!isfinite(b)) {
    s.failed = kFailNonFinite;  // a finite state whose stress overflowed
  } else {
    bound_max = fmax(bound_max, static_cast<double>(b));
    if (measure_only) return;
    if (b > arena.limit) {
      out_of_range = true;  // this try is repeated with the measured bound
    } else {
      // The payload in quanta: the per-node products then need no scaling (4 multiplies fewer per node).
      p2g_add_factored<true, T, TG>(w, p.dx, arena.fixed, l0, l1, l2, payload.mass * arena.inv_q_mass,
                              payload.momentum * arena.inv_q_momentum, payload.affine * arena.inv_q_momentum, 1);
      if (transport)
        p2g_add_factored<false, T, TG>(w, p.dx, arena.fixed, l0, l1, l2, T(0), carried.momentum * arena.inv_q_momentum,
                                carried.affine * arena.inv_q_momentum, 4);
    }
  }
  const int b0 = floor_div4(w.base[0] - 1), b1 = floor_div4(w.base[1] - 1), b2 = floor_div4(w.base[2] - 1);
  if (!BlockKey::representable(b0, b1, b2)) {
    s.failed = kFailLeftDomain;
  } else if (p.slab.owns(b0, b1, b2)) {
    s.has_key = true;
    s.key = BlockKey::pack(b0, b1, b2);
  } else {
    s.emigrant = p.slab.side(b0, b1, b2);
  }
}

/// Failure counts of one warp: one atomic per warp and kind; the smallest failing ID for the report. All 32 lanes.
template <typename M, typename T, typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void count_failures(const G2P2GParams<M, T, TG>& p, int lane, int failed, int id) {
  if (!__any_sync(0xffffffffu, failed >= 0)) return;  // the common case: one vote
  for (int kind = 0; kind < kFailKinds; ++kind) {
    const unsigned mask = __ballot_sync(0xffffffffu, failed == kind);
    if (mask != 0) {
      if (lane == __ffs(mask) - 1) atomicAdd(&p.body_stats->failures[kind], __popc(mask));
      if (failed == kind) atomicMin(&p.body_stats->first_id[kind], id);
    }
  }
}

/// What a lane's wave-speed maximum starts from: no particle yet (a law with wave_speed_order reduces its keys, which
/// may be negative, and evaluates the wave speed of the block's largest).
inline constexpr double kNoWave = -1.0e300;

/// Per-body maxima of the wave speed (or its order key) and the P2G bound, and whether a particle exceeded the
/// bound: warp, then CUDA block (block_max, block_over: shared), then one global atomic per block (per-warp atomics
/// on one address serialise in L2). Every thread of the block.
template <typename M, typename T, typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void reduce_block_maxima(const G2P2GParams<M, T, TG>& p, double wave_max,
                                                       double bound_max, bool out_of_range,
                                                       double (*block_max)[kG2P2GThreads<TG> / 32], int& block_over) {
  const int lane = threadIdx.x % 32;
  const int warp = threadIdx.x / 32;
  wave_max = warp_max(wave_max);
  bound_max = warp_max(bound_max);
  const bool over = __any_sync(0xffffffffu, out_of_range);
  if (lane == 0) {
    block_max[0][warp] = wave_max;
    block_max[1][warp] = bound_max;
    if (over) block_over = 1;
  }
  __syncthreads();
  if (threadIdx.x == 0) {
    double wave = kNoWave, bound = 0.0;
    for (int w = 0; w < kG2P2GThreads<TG> / 32; ++w) {
      wave = fmax(wave, block_max[0][w]);
      bound = fmax(bound, block_max[1][w]);
    }
    if constexpr (material_detail::has_wave_speed_order<M>::value)  // the block's largest key, to its wave speed
      wave = wave > kNoWave ? static_cast<double>(M::wave_speed_at_order(p.material, static_cast<T>(wave))) : 0.0;
    if (wave > 0.0) atomic_max_nonneg(p.wave_speed, wave);
    if (bound > 0.0) atomic_max_nonneg(p.p2g_bound_out, bound);
    if (block_over) atomicAdd(&p.stats->p2g_range, 1);
  }
}

/// The arena's sums into the next grid: one thread per arena node, each channel's block integer converted to the
/// grid's quantum (q / Q, rounded to the nearest unit) and added with an integer atomic into the (up to 8) grid
/// blocks (nodes no particle's stencil covers are skipped). Every thread of the block, after the P2G.
template <typename M, typename T, typename TG>
FBAR_DEVICE FBAR_FORCE_INLINE void flush_arena(const G2P2GParams<M, T, TG>& p, const BlockArena<T, TG>& arena) {
  for (int i = threadIdx.x; i < kArenaNodes; i += blockDim.x) {
    const int a = i >> 6, b = (i >> 3) & 7, c = i & 7;
    const int ai = arena_index(a, b, c);
    // Float grids convert in float (the grid's own precision; the same bits on every run), double grids in double.
    using U = TG;
    const U mass_units = arena.fixed.units(0, ai);
    if (mass_units == U(0)) continue;  // no particle's stencil covers this node
    const int nb = arena.blocks[arena_neighbour(a, b, c)];
    if (nb < 0) continue;  // counted as an internal error when the arena was set up
    const int node = arena_node_in_block(a, b, c);
    const U to_mass = static_cast<U>(arena.to_grid_mass), to_momentum = static_cast<U>(arena.to_grid_momentum);
    p.grid_next.add(nb, kSumMass, node, mass_units * to_mass);
    for (int ch = 1; ch < 4; ++ch) p.grid_next.add(nb, ch, node, arena.fixed.units(ch, ai) * to_momentum);
    if (arena.channels == 7)
      for (int ch = 0; ch < 3; ++ch)
        p.transported_next.add(nb, ch, node, arena.fixed.units(4 + ch, ai) * to_momentum);
  }
}

}  // namespace g2p2g_detail

/// kTransport: the arena also sums the transported momentum (some body uses ASFLIP). A separate instantiation, so
/// that APIC scenes run a kernel without that code: with the ASFLIP code present behind run-time branches, APIC
/// steps in double took 5.03 / 7.09 ms (dam_break / falling_block, 16M particles, H100) against 3.33 / 4.83 ms
/// without (two runs, docs/benchmarks/2026-11-23-h100-asflip-arena.md). The initial P2G runs the instantiation a step would.
/// kCapture: this launch also writes the body's output frame (a separate instantiation: a run-time branch to the
/// capture call, even out of line, doubled the APIC kernel's time on an H100).
/// The phases (g2p2g_detail): arena set-up, then per bin g2p_particle, store_particle_outputs, p2g_particle and the
/// next block's claim, then reduce_block_maxima and flush_arena.
/// kMesh: a mesh body's vertices (physics/fem.cuh): the state kept, no inversion check, the vertex's mass and no
/// stress in P2G.
namespace g2p2g_detail {
/// One CUDA block of g2p2g / g2p2g_capped (below): one particle block's G2P2G.
template <typename M, typename T, typename TG, bool kTransport, bool kCapture, bool kMesh>
__device__ __forceinline__ void g2p2g_block(const G2P2GParams<M, T, TG>& p) {
  constexpr int kThreads = kG2P2GThreads<TG>;
  // The initial launch's first pass measures the bound the second one uses (nothing else is written).
  const bool measure = p.bound_only;
  // (x, y, z) grid velocities of the 8x8x8-node arena (vx, vy, vz, pad per node), index arena_index(x, y, z) =
  // 68 x + 8 y + z.
  __shared__ g2p2g_detail::ArenaVelocity<TG> arena_v[kArenaStorage];
  // (channel, x, y, z) P2G sums: mass, momentum x, y, z; same indexing, integers in units of q_mass, q_momentum
  // (FixedArena).
  // Dynamic shared memory (the launch gives g2p2g_arena_bytes): 4 channels, or 7 when a body uses ASFLIP (the
  // transported momentum x, y, z as channels 4..6, transfer.cuh); in double 7 channels take 30.5 KB, which with
  // arena_v stays inside the 48 KB a block may use without opting in.
  extern __shared__ __align__(16) unsigned char g2p2g_dynamic_shared[];
  TG* const arena_p = reinterpret_cast<TG*>(g2p2g_dynamic_shared);
  const int channels = kTransport ? 7 : 4;
  // A body that uses ASFLIP runs in a kTransport launch: only those carry its code.
  constexpr bool kMayAsflip = kTransport;
  // (neighbour) hash-table index of the arena's 2x2x2 grid blocks, neighbour = (di * 2 + dj) * 2 + dk.
  __shared__ int arena_blocks[8];
  // (quantity, warp) per-warp maxima of the wave speed and the P2G bound; whether a particle exceeded the bound.
  __shared__ double block_max[2][kThreads / 32];
  __shared__ int block_over;

  const int block = p.order_first >= 0 ? p.layout.order[p.order_first + static_cast<int>(blockIdx.x)]
                                       : static_cast<int>(blockIdx.x);
  const int count = p.layout.count[block];
  if (count == 0) return;  // uniform per CUDA block: a stale or footprint-only block
  const int lane = threadIdx.x % 32;
  const int warp = threadIdx.x / 32;
  const int bins = (count + 31) / 32;
  const int first_bin = p.layout.bin_offset[block];
  // Each warp reads the gather index of its next bin one bin ahead (the first one before the arena's set-up), so
  // that a bin waits for one global load (its particle) instead of two in a row (the index, then the particle).
  int src_ahead = warp < bins ? p.layout.src[(first_bin + warp) * 32 + lane] : -1;
  const Vec3i origin = p.table.block_coords(block);
  if (threadIdx.x == 0) block_over = 0;
  g2p2g_detail::find_arena_blocks(p.table, block, origin, arena_blocks, p.stats);
  {  // zero the P2G arena, 16 bytes a store (its size is a multiple of 16 bytes: 4 or 7 channels of 8 x 68 words)
    static_assert((kArenaStorage * sizeof(float)) % sizeof(uint4) == 0, "the arena is zeroed in 16-byte words");
    uint4* const words = reinterpret_cast<uint4*>(arena_p);
    const int n = channels * static_cast<int>(kArenaStorage * sizeof(TG) / sizeof(uint4));
    for (int i = threadIdx.x; i < n; i += kThreads) words[i] = make_uint4(0u, 0u, 0u, 0u);
  }

  // Fixed-point quanta of this block [kg], [kg m/s] and their inverses; limit: the bound every particle must meet.
  // (Before the barrier: the warps that do not look up the arena's blocks compute them while those loads run.)
  const double span =
      kMaxNodeWeight * max(count, g2p2g_detail::FixedArena<TG>::kMinCount) / g2p2g_detail::FixedArena<TG>::kRange;
  const double bound = kP2GHeadroom * __longlong_as_double(static_cast<long long>(*p.p2g_bound_in));
  const g2p2g_detail::FixedArena<TG> fixed{reinterpret_cast<unsigned*>(arena_p), channels};
  g2p2g_detail::BlockArena<T, TG> arena{arena_v, fixed, arena_blocks, origin, channels, static_cast<T>(*p.dt_next)};
  arena.q_mass = static_cast<T>(static_cast<double>(p.mass) * span);
  arena.inv_q_mass = T(1) / arena.q_mass;
  arena.q_momentum = static_cast<T>(bound * span);
  arena.inv_q_momentum = bound > 0.0 ? static_cast<T>(1.0 / (bound * span)) : T(0);
  arena.limit = static_cast<T>(bound);
  if (!measure) {
    const GridQuantum q = *p.quantum_next;
    arena.to_grid_mass = static_cast<double>(arena.q_mass) / q.mass;
    arena.to_grid_momentum = static_cast<double>(arena.q_momentum) / q.momentum;
  }
  __syncthreads();
  if (!p.initial) {  // uniform over the launch
    g2p2g_detail::load_arena_velocities<TG>(p.velocity, arena_blocks, arena_v);
    __syncthreads();
  }
  // The particle block's own key: its particles that stay claim their rank without a table lookup.
  const std::uint64_t own_key = BlockKey::pack(origin[0], origin[1], origin[2]);
  double bound_max = 0.0, wave_max = g2p2g_detail::kNoWave;
  bool out_of_range = false;
  for (int bin = warp; bin < bins; bin += kThreads / 32) {
    const int slot = (first_bin + bin) * 32 + lane;
    const int src = src_ahead;
    if (bin + kThreads / 32 < bins) src_ahead = p.layout.src[slot + kThreads];
    const bool active = src >= 0;
    g2p2g_detail::LaneParticle<M, T> s;
    int id = INT_MAX;
    if (active) {
      const ParticleRecord<M, T> in = load_particle<M, T>(p.in, src);
      id = in.id;
      g2p2g_detail::g2p_particle<M, T, TG, kMayAsflip, kMesh>(p, arena, in, src, s);
      if (!measure) g2p2g_detail::store_particle_outputs<M, T, TG, kMayAsflip, kCapture>(p, slot, in.id, s);
      if (s.failed < 0)
        g2p2g_detail::p2g_particle<M, T, TG, kMesh>(p, arena, s, in.id, wave_max, bound_max,
                                                                out_of_range, measure);
    }
    if (measure) continue;
    g2p2g_detail::count_failures(p, lane, s.failed, id);
    const ParticleDest d =
        g2p2g_detail::claim_block_rank<TG>(s.has_key, s.key, p.table, p.next_count, p.grid_next, p.grid_this,
                                           own_key, block);
    // Every lane of the bin (kNoParticle for the padding): scatter_src then reads no validity array.
    p.dest[slot] = !active ? ParticleDest{kNoParticle, 0} : s.emigrant >= 0 ? ParticleDest{kEmigrant, s.emigrant} : d;
    // The emigrants' slots, listed so that the migration reads those few instead of every slot's destination.
    if (active && s.emigrant >= 0 && p.emigrant_slots) {
      const int k = atomicAdd(&p.body_stats->emigrant_list, 1);
      if (k < p.emigrant_capacity) p.emigrant_slots[k] = slot;
    }
  }
  g2p2g_detail::reduce_block_maxima(p, wave_max, bound_max, out_of_range, block_max, block_over);
  if (!measure) g2p2g_detail::flush_arena<M, T, TG>(p, arena);
}
}  // namespace g2p2g_detail

template <typename M, typename T, typename TG, bool kTransport, bool kCapture = false, bool kMesh = false>
__global__ void __launch_bounds__(kG2P2GThreads<TG>) g2p2g(G2P2GParams<M, T, TG> p) {
  g2p2g_detail::g2p2g_block<M, T, TG, kTransport, kCapture, kMesh>(p);
}

/// Whether a G2P2G runs as g2p2g_capped: the compiler must leave room for kG2P2GCappedBlocks resident blocks per
/// SM. A double-particle JFluid step uses 124 registers without the initial P2G's run-time branch and 165 with it,
/// one block per SM fewer (double grid: 4 blocks of 128 threads instead of 3; mixed: 8 of 64 instead of 6) and 13 %
/// longer steps (docs/benchmarks/2026-12-02-h200-restart-kernel.md); capped, it keeps to 128 registers. Every other
/// launch keeps the plain bound (a minimum of 1 block is not the same: ptxas then takes up to 255 registers, which
/// made single-precision and FixedCorotated steps 19-28 % slower, same record).
template <typename M, typename T, typename TG, bool kTransport, bool kMesh>
inline constexpr bool kG2P2GCapped = std::is_same_v<M, JFluid> && sizeof(T) == sizeof(double) && !kTransport && !kMesh;
template <typename TG>
inline constexpr int kG2P2GCappedBlocks = sizeof(TG) == sizeof(double) ? 4 : 8;

template <typename M, typename T, typename TG, bool kTransport, bool kCapture = false, bool kMesh = false>
__global__ void __launch_bounds__(kG2P2GThreads<TG>, kG2P2GCappedBlocks<TG>) g2p2g_capped(G2P2GParams<M, T, TG> p) {
  g2p2g_detail::g2p2g_block<M, T, TG, kTransport, kCapture, kMesh>(p);
}

/// Launches the G2P2G of one body (g2p2g, or g2p2g_capped where kG2P2GCapped) over `blocks` particle blocks.
template <typename M, typename T, typename TG, bool kTransport, bool kCapture = false, bool kMesh = false>
void launch_g2p2g(const G2P2GParams<M, T, TG>& p, int blocks, std::size_t arena, cudaStream_t s) {
  if constexpr (kG2P2GCapped<M, T, TG, kTransport, kMesh>)
    g2p2g_capped<M, T, TG, kTransport, kCapture, kMesh><<<blocks, kG2P2GThreads<TG>, arena, s>>>(p);
  else
    g2p2g<M, T, TG, kTransport, kCapture, kMesh><<<blocks, kG2P2GThreads<TG>, arena, s>>>(p);
}

}  // namespace fbar
