// Pieces every GPU kernel family shares: the per-step statistics the host reads back, warp/atomic helpers.
#pragma once

#include <cuda_runtime.h>

#include <cstdint>

#include "MnBase/Meta/config.h"

namespace fbar {

/// Failure kinds counted on the device; the order matches FailureKind of the CPU engine (cpu_engine.h).
enum : int { kFailNonFinite = 0, kFailCfl = 1, kFailLeftDomain = 2, kFailInverted = 3, kFailKinds = 4 };

/// Per-body counters of one step try (zeroed before the try).
struct BodyStepStats {
  int failures[kFailKinds];  ///< particles failing each check
  int first_id[kFailKinds];  ///< smallest failing particle ID (INT_MAX when none)
  int total_bins;            ///< bins of the next layout (bin_offset[capacity])
  int particles;             ///< particles placed in the next layout
  int halo_blocks;           ///< decomposed runs: blocks of the next layout listed first (list_particle_blocks)
  int interior_blocks;       ///< decomposed runs: the other blocks with particles of the next layout
  int emigrants[2];          ///< decomposed runs: particles sent to the rank below / above (all, past the capacity too)
  int immigrants[2];         ///< decomposed runs: particles the rank below / above sent (as its header counts them)
  int emigrant_list;         ///< decomposed runs: emigrants G2P2G listed (all, past the list's capacity too)
};

/// The particle blocks a rank owns (comm/slab_partition.h): planes [lo, hi) along `axis`; one rank owns all.
struct SlabBounds {
  int axis = 0;
  int lo = -2147483647 - 1;
  int hi = 2147483647;
  FBAR_HOST_DEVICE int along(int b0, int b1, int b2) const { return axis == 0 ? b0 : axis == 1 ? b1 : b2; }
  FBAR_HOST_DEVICE bool owns(int b0, int b1, int b2) const {
    const int b = along(b0, b1, b2);
    return b >= lo && b < hi;
  }
  /// The neighbour a block outside the slab belongs to: 0 the lower (rank - 1), 1 the upper (rank + 1).
  FBAR_HOST_DEVICE int side(int b0, int b1, int b2) const { return along(b0, b1, b2) < lo ? 0 : 1; }
};

/// Whole-device counters of one step try; followed in memory by one BodyStepStats per body, so the host reads
/// everything it needs each step with one small copy.
struct StepStats {
  unsigned long long max_speed_sq;  ///< bits of a double: largest |v|^2 of the grid update [m^2/s^2]
  double dt_next;                   ///< [s] dt of the next step, used by this step's P2G impulse
  int bin_overflow;                 ///< a body's next layout needs more bins than allocated
  int internal_error;               ///< arena block missing / particle outside its block: an engine bug
  int block_count;                  ///< copy of the table's block count after the partition update
  int table_overflow;               ///< copy of the table's overflow counter
  int p2g_range;                    ///< particle blocks with a particle above the fixed-point P2G bound: repeat
  int halo_new[2];                  ///< decomposed runs: new table blocks in the halo plane shared with rank -/+ 1
};

/// atomicMax on a non-negative double stored as its bit pattern (IEEE order = integer order for x >= 0).
FBAR_DEVICE FBAR_FORCE_INLINE void atomic_max_nonneg(unsigned long long* bits, double value) {
  atomicMax(bits, static_cast<unsigned long long>(__double_as_longlong(value)));
}

FBAR_DEVICE FBAR_FORCE_INLINE double warp_max(double v) {
  for (int o = 16; o > 0; o >>= 1) v = fmax(v, __shfl_xor_sync(0xffffffffu, v, o));
  return v;
}

/// Sum over the 32 lanes of a full warp (every lane gets it): the warp-reduce instruction of compute capability 8.0
/// and newer, shuffles on 7.x.
FBAR_DEVICE FBAR_FORCE_INLINE int warp_sum(int v) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
  return __reduce_add_sync(0xffffffffu, v);
#else
  for (int o = 16; o > 0; o >>= 1) v += __shfl_xor_sync(0xffffffffu, v, o);
  return v;
#endif
}

FBAR_DEVICE FBAR_FORCE_INLINE unsigned lanemask_lt() {
  unsigned m;
  asm("mov.u32 %0, %%lanemask_lt;" : "=r"(m));
  return m;
}

/// Arithmetic-shift floor division by 4 (defined for negatives on every supported compiler).
FBAR_HOST_DEVICE FBAR_FORCE_INLINE int floor_div4(int n) { return n >> 2; }

}  // namespace fbar
