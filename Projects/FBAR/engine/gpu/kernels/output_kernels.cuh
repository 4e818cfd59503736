// Output kernels: gather a body's particles into ID order (positions, state, velocity, affine C) for frames/tests.
#pragma once

#include <cuda_runtime.h>

#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/kernels/grid_update_kernels.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "engine/gpu/partition_domain.h"

namespace fbar {

inline constexpr int kOutputThreads = 256;

/// The particles with IDs first .. first + count - 1 (every ID: first 0, count `particles`) in ID order:
/// out[(id - first) * (S + kAuxScalars) + ...] = x (3), state, then 1 - JBar when jbar != nullptr (nodal F-bar: S
/// counts it), then v (3) and C (9) when aux != nullptr
/// (else 0), and held[id - first] = id when held != nullptr (which IDs a rank holds). One thread per slot of the
/// current layout; particles are read through src (storage order); an ID outside 0 .. particles - 1 counts in
/// `missing`.
template <typename M, typename T>
__global__ void __launch_bounds__(kOutputThreads)
    gather_by_id(typename ParticleLayout<M, T>::Buffer bins, const int* src, int slots, const T* aux, int particles,
                 int first, int count, T* out, int* held, int* missing, const T* jbar) {
  constexpr int kStored = ParticleLayout<M, T>::kScalars;
  const int S = kStored + (jbar ? 1 : 0);
  const int W = S + kAuxScalars;
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int s = src[slot];
  if (s < 0) return;
  const ParticleRecord<M, T> p = load_particle<M, T>(bins, s);
  if (p.id < 0 || p.id >= particles) {
    atomicAdd(missing, 1);
    return;
  }
  if (p.id < first || p.id - first >= count) return;
  if (held) held[p.id - first] = p.id;
  T* o = out + static_cast<std::size_t>(p.id - first) * W;
  o[0] = p.x[0];
  o[1] = p.x[1];
  o[2] = p.x[2];
  memcpy(o + 3, &p.state, sizeof(p.state));
  if (jbar) o[kStored] = jbar[s];
  for (int i = 0; i < kAuxScalars; ++i) o[S + i] = aux ? aux[static_cast<std::size_t>(s) * kAuxScalars + i] : T(0);
}

/// What a checkpoint keeps of a G2P2G's grouping (io::CheckpointBody::p2g_block): for slot s of `layout` (the
/// layout that G2P2G read; its particle was written to `written` at slot s), out[2 s] = the particle's ID and
/// out[2 s + 1] = the table index of the block it was summed from; (-1, -1) for an empty lane. One CUDA block per
/// table block (a block's particles fill the first `count` slots of its bins).
template <typename M, typename T>
__global__ void __launch_bounds__(kOutputThreads)
    record_p2g_blocks(typename ParticleLayout<M, T>::Buffer written, LayoutView layout, int slots, int* out) {
  const int block = static_cast<int>(blockIdx.x);
  const int count = layout.count[block];
  if (count == 0) return;
  const int first = layout.bin_offset[block] * 32;
  const int end = first + ((count + 31) / 32) * 32;
  for (int slot = first + static_cast<int>(threadIdx.x); slot < end && slot < slots; slot += kOutputThreads) {
    const bool active = layout.src[slot] >= 0;
    out[2 * static_cast<std::size_t>(slot)] =
        active ? block_val(written, ParticleLayout<M, T>::id_attrib, slot / settings::kBinSize, slot % settings::kBinSize)
               : -1;
    out[2 * static_cast<std::size_t>(slot) + 1] = active ? block : -1;
  }
}

/// A streamed checkpoint's grouping of the particles with IDs first .. first + count - 1, from record_p2g_blocks'
/// `record` (slots pairs of ID and table block): block_of[id - first] = the table block (-1 beforehand: not summed
/// by this rank). A recorded ID outside 0 .. particles - 1, a block outside 0 .. blocks - 1 or an ID recorded twice
/// counts in `errors`.
/// (Not a template: defined once, in output_kernels.cu.)
__global__ void p2g_blocks_by_id(const int* record, int slots, int particles, int blocks, int first, int count,
                                 int* block_of, int* errors);

/// The frame of the state before the first step (v = the body's initial velocity, or each particle's from v_by_id
/// (3 per ID) when a seed gave them; C = 0): one thread per slot of the current layout, particles read through src.
template <typename M, typename T>
__global__ void __launch_bounds__(kOutputThreads)
    capture_frame_state(typename ParticleLayout<M, T>::Buffer bins, const int* src, int slots, FrameCapture<T> capture,
                        Vec3<T> velocity, const T* v_by_id, material_params_t<M, T> material, ParticleMeasures<T> measures,
                        const T* jbar) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int s = src[slot];
  if (s < 0) return;
  const ParticleRecord<M, T> p = load_particle<M, T>(bins, s);
  Vec3<T> v = velocity;
  if (v_by_id && p.id >= 0) {
    const T* q = v_by_id + 3 * static_cast<std::size_t>(p.id);
    v = Vec3<T>{{q[0], q[1], q[2]}};
  }
  capture_particle<M, T>(capture, p.id, p.x, v, Mat3<T>::zero(), p.state, material, measures.mass_of(p.id),
                         measures.volume_of(p.id), jbar != nullptr, jbar ? jbar[s] : T(0));
}

/// Particle sensors (physics/sensors.cuh) of one body: blockIdx.y = sensor, a grid-stride loop over the slots of the
/// current layout, one partial per CUDA block (merge_sensor_partials adds them in order: reproducible sums). v and C
/// come from aux (the step that landed here recorded them), or are the initial velocity and 0 before the first step.
template <typename M, typename T>
__global__ void __launch_bounds__(kSensorThreads)
    sample_particle_sensors(typename ParticleLayout<M, T>::Buffer bins, const int* src, int slots, const T* aux,
                            Vec3<T> v0, material_params_t<M, T> material, ParticleMeasures<T> measures, ParticleSensorSet<T> sensors,
                            SensorAccum* partials, const T* jbar) {
  const ParticleSensorParams<T>& g = sensors.s[blockIdx.y];
  const bool sigma = frame_quantity_reads_stress(g.column.quantity);
  SensorAccum a;
  for (int slot = blockIdx.x * blockDim.x + threadIdx.x; slot < slots; slot += gridDim.x * blockDim.x) {
    const int s = src[slot];
    if (s < 0) continue;
    const ParticleRecord<M, T> p = load_particle<M, T>(bins, s);
    if (!sensor_box_contains(g.lo, g.hi, p.x)) continue;
    Vec3<T> v = v0;
    Mat3<T> C = Mat3<T>::zero();
    if (aux) {
      const T* r = aux + static_cast<std::size_t>(s) * kAuxScalars;
      v = Vec3<T>{{r[0], r[1], r[2]}};
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) C(i, j) = r[3 + 3 * i + j];
    }
    const FrameInputs<T> in = particle_frame_inputs<M, T>(p.x, v, C, p.state, material, measures.mass_of(p.id),
                                                          measures.volume_of(p.id), sigma, jbar != nullptr,
                                                          jbar ? jbar[s] : T(0));
    a.add(static_cast<double>(frame_value(g.column, in)));
  }
  a = block_reduce_sensor(a);
  if (threadIdx.x == 0) partials[static_cast<std::size_t>(blockIdx.y) * gridDim.x + blockIdx.x] = a;
}

/// A tracker's particles (TrackerSet, found by ID): one thread per slot of the current layout; the particle with a
/// tracked ID writes its attributes (values[i * attribs + a], i its index in the sorted IDs) and present[i] = 1.
template <typename M, typename T>
__global__ void __launch_bounds__(kOutputThreads)
    track_particles(typename ParticleLayout<M, T>::Buffer bins, const int* src, int slots, const T* aux, Vec3<T> v0,
                    material_params_t<M, T> material, ParticleMeasures<T> measures, TrackerSet t, double* values, double* present,
                    const T* jbar) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int s = src[slot];
  if (s < 0) return;
  const ParticleRecord<M, T> p = load_particle<M, T>(bins, s);
  const int i = tracker_index(t, p.id);
  if (i < 0) return;
  Vec3<T> v = v0;
  Mat3<T> C = Mat3<T>::zero();
  if (aux) {
    const T* r = aux + static_cast<std::size_t>(s) * kAuxScalars;
    v = Vec3<T>{{r[0], r[1], r[2]}};
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) C(a, b) = r[3 + 3 * a + b];
  }
  const FrameInputs<T> in = particle_frame_inputs<M, T>(p.x, v, C, p.state, material, measures.mass_of(p.id),
                                                        measures.volume_of(p.id), true, jbar != nullptr,
                                                        jbar ? jbar[s] : T(0));
  for (int a = 0; a < t.attribs; ++a) values[i * t.attribs + a] = static_cast<double>(frame_value(t.column[a], in));
  present[i] = 1.0;
}

/// A decomposed rank's ID directory (FrameCapture::id_bits): sets the bit of every particle of the layout.
template <typename M, typename T>
__global__ void __launch_bounds__(kOutputThreads)
    mark_ids(typename ParticleLayout<M, T>::Buffer bins, const int* src, int slots, unsigned* bits) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int s = src[slot];
  if (s < 0) return;
  const int id = load_particle<M, T>(bins, s).id;
  atomicOr(&bits[id >> 5], 1u << (id & 31));
}

/// counts[w] = set bits of bits[w] for w < words, counts[words] = 0 (an exclusive scan then gives the offsets).
static __global__ void __launch_bounds__(kOutputThreads) count_id_bits(const unsigned* bits, int words, int* counts) {
  const int w = blockIdx.x * blockDim.x + threadIdx.x;
  if (w < words) counts[w] = __popc(bits[w]);
  if (w == words) counts[w] = 0;
}

/// What pack_bgeo_records reads: a captured frame (FrameCapture's x and columns, and its ID directory) and, per
/// attribute of the file in order, the capture column it comes from or -1 for the particle ID.
template <typename T>
struct BgeoPack {
  const T* x = nullptr;              ///< (entry, 3) [m]
  const float* columns = nullptr;    ///< (column, entry), column c at c x stride
  std::size_t stride = 0;
  int entries = 0;                   ///< records to write
  const unsigned* id_bits = nullptr; ///< nullptr: entry = ID
  const int* id_offset = nullptr;    ///< (words + 1) exclusive prefix counts of id_bits
  int words = 0;
  int attributes = 0;
  int source[kMaxFrameColumns + 1];  ///< capture column of attribute a, or -1: the ID
};

/// The ID of entry `e` of a decomposed rank's frame: the word whose prefix count range holds e (binary search),
/// then the (e - offset)-th set bit of that word.
__device__ inline int bgeo_entry_id(const unsigned* bits, const int* offset, int words, int e) {
  int lo = 0, hi = words;  // the last word w with offset[w] <= e
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    if (offset[mid] <= e) lo = mid;
    else hi = mid;
  }
  unsigned m = bits[lo];
  for (int k = e - offset[lo]; k > 0; --k) m &= m - 1;
  return 32 * lo + __ffs(m) - 1;
}

/// A frame's bgeo point records (io::write_bgeo's layout: x, y, z, w = 1 as big-endian float32, then every
/// attribute as big-endian float32 or int32), written as 4-byte words straight into `out` (pinned host memory is
/// fine: consecutive threads write consecutive words). A grid-stride loop: a few blocks keep PCIe busy without
/// taking the SMs from the step.
template <typename T>
__global__ void __launch_bounds__(kOutputThreads) pack_bgeo_records(BgeoPack<T> p, unsigned* out) {
  const int words_per_record = 4 + p.attributes;
  const std::size_t total = static_cast<std::size_t>(p.entries) * words_per_record;
  for (std::size_t g = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x; g < total;
       g += static_cast<std::size_t>(gridDim.x) * blockDim.x) {
    const int e = static_cast<int>(g / words_per_record);
    const int w = static_cast<int>(g - static_cast<std::size_t>(e) * words_per_record);
    unsigned v;
    if (w < 3) {
      v = __float_as_uint(static_cast<float>(p.x[3 * static_cast<std::size_t>(e) + w]));
    } else if (w == 3) {
      v = __float_as_uint(1.0f);
    } else {
      const int c = p.source[w - 4];
      if (c >= 0)
        v = __float_as_uint(p.columns[static_cast<std::size_t>(c) * p.stride + e]);
      else
        v = static_cast<unsigned>(p.id_bits ? bgeo_entry_id(p.id_bits, p.id_offset, p.words, e) : e);
    }
    out[g] = __byte_perm(v, 0, 0x0123);  // big-endian
  }
}

}  // namespace fbar
