// The element pass of a mesh body on the GPU (physics/fem.cuh; the CPU engine's cpu_mesh.cpp does the same sums in
// the same order). The fused G2P2G computes a step's G2P and the next step's P2G in one pass, before the elements'
// forces at the new positions exist; the force impulse is linear and separable, so after the G2P2G of a mesh body:
//   1. mesh_index_vertices   over the slots the G2P2G wrote: each vertex's new position and slot, by ID, and
//                            whether its new stencil lies in its particle block's arena (else its G2P2G failed the
//                            try by CFL and the vertex gives no impulse: the nodes may not exist);
//   2. mesh_element_pass     per element: F = Ds Dm^-1 and J (an inverted element fails the try, counted with the
//                            element's number), and without F-bar its nodal forces H = [f1 f2 f3];
//      mesh_vertex_volume_ratio, mesh_fbar_elements (use_FBAR): each vertex's V0-weighted mean J, then each
//                            element's F-bar gradient and forces;
//   3. mesh_vertex_pass      per vertex, its elements in CSR order (no atomics: the same bits every run): its state
//                            (the V0-weighted mean gradient) into the bins, its force for the next step, the wave speed,
//                            and the impulse w_ip f dt_next added to the next grid's momentum at the vertex's stencil
//                            (nodes of the arena the G2P2G flushed into, so their blocks exist); on a frame step the
//                            vertex's frame entry (v and C from aux: a mesh body always records them).
// mesh_rescale_impulse adds w_ip f (dt - dt_p2g) when a try's dt differs from the one the grid's impulse used.
#pragma once

#include <cuda_runtime.h>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/vec.h"
#include "engine/gpu/grid_buffer.cuh"
#include "engine/gpu/hash_table.cuh"
#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/kernels/kernel_common.cuh"
#include "engine/gpu/particle_buffer.cuh"
#include "physics/constitutive_models.cuh"
#include "physics/fem.cuh"

namespace fbar {

inline constexpr int kFemThreads = 256;

/// A mesh body's device arrays (MgspBenchmark::MeshDevice owns them).
template <typename T>
struct MeshView {
  const TetElement<T>* elements = nullptr;
  int element_count = 0;
  const int* vertex_start = nullptr;     ///< (vertex + 1) CSR offsets
  const int* vertex_elements = nullptr;  ///< corners 4 e + k
  int vertex_count = 0;
  Vec3<T>* x = nullptr;                  ///< (vertex) positions the G2P2G wrote [m]
  int* slot = nullptr;                   ///< (vertex) their slot in the bins it wrote; -1 - slot: left its arena
  Mat3<T>* F = nullptr;                  ///< (element) the gradient its stress uses
  T* J = nullptr;                        ///< (element) det F (F-bar only)
  T* vertex_J = nullptr;                 ///< (vertex) V0-weighted mean J (F-bar only)
  Mat3<T>* H = nullptr;                  ///< (element) nodal forces [f1 f2 f3] [N] (use_FEM)
  T fbar_psi = T(0);                     ///< use_FBAR's blend, 0: plain tetrahedra
  bool forces = false;                   ///< use_FEM: the elements exert forces
};

/// The grid block indices of the 2x2x2 blocks from `lo` (table look-ups; -1 where missing).
FBAR_DEVICE FBAR_FORCE_INLINE void fem_stencil_blocks(const BlockHashTableView& table, const Vec3i& lo, int (&blocks)[8]) {
  for (int n = 0; n < 8; ++n)
    blocks[n] = table.find(BlockKey::arena_neighbour(lo, n));
}

/// Adds w_ip * impulse to the momentum of the 27 stencil nodes of x in the grid's quantum (their blocks found in the
/// table; a missing one is an internal error).
template <typename T, typename TG>
FBAR_DEVICE void fem_add_impulse(const BlockHashTableView& table, const GridSums<TG>& grid, const GridQuantum* quantum,
                                 const Vec3<T>& x, T inv_dx, const Vec3<T>& impulse, StepStats* stats) {
  const double per_unit = 1.0 / quantum->momentum;
  const QuadraticBspline<T> w = quadratic_bspline_inv(x, inv_dx);
  const Vec3i lo{{floor_div4(w.base[0]), floor_div4(w.base[1]), floor_div4(w.base[2])}};
  int blocks[8];
  fem_stencil_blocks(table, lo, blocks);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        const int n0 = w.base[0] + i, n1 = w.base[1] + j, n2 = w.base[2] + k;
        const int nb = blocks[((floor_div4(n0) - lo[0]) * 2 + (floor_div4(n1) - lo[1])) * 2 + (floor_div4(n2) - lo[2])];
        if (nb < 0) {
          atomicAdd(&stats->internal_error, 1);
          continue;
        }
        const int node = ((n0 & 3) * 4 + (n1 & 3)) * 4 + (n2 & 3);
        const T wt = w.w[0][i] * w.w[1][j] * w.w[2][k];
        for (int a = 0; a < 3; ++a)
          grid.add(nb, kSumMomentum + a, node, static_cast<double>(wt * impulse[a]) * per_unit);
      }
}

/// 1. Each vertex's position and slot from the bins the G2P2G wrote (slots [0, slots) of the layout it wrote in;
/// src: that layout's, the slot of each in `before`, the bins it read; negative entries are empty slots). A vertex
/// whose new stencil base left its particle block's arena (base - 1 - 4 B in [0, 5] per axis, B that block: the
/// G2P2G counted it a CFL failure) gets slot -1 - slot.
template <typename M, typename T>
__global__ void __launch_bounds__(kFemThreads)
    mesh_index_vertices(typename ParticleLayout<M, T>::Buffer bins, typename ParticleLayout<M, T>::Buffer before,
                        const int* src, int slots, T inv_dx, MeshView<T> mesh) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots || src[slot] < 0) return;
  const ParticleRecord<M, T> r = load_particle<M, T>(bins, slot);
  if (r.id < 0 || r.id >= mesh.vertex_count) return;
  const QuadraticBspline<T> was = quadratic_bspline_inv(load_particle<M, T>(before, src[slot]).x, inv_dx);
  const QuadraticBspline<T> now = quadratic_bspline_inv(r.x, inv_dx);
  bool inside = true;
  for (int a = 0; a < 3; ++a) {
    const int l = now.base[a] - 4 * floor_div4(was.base[a] - 1);
    inside = inside && l >= 0 && l <= 5 && all_finite(r.x);
  }
  mesh.x[r.id] = r.x;
  mesh.slot[r.id] = inside ? slot : -1 - slot;
}

/// 2. Per element: F and J from the new positions; an inverted one counted (first: the smallest element number).
/// Plain tetrahedra (psi = 0) also take their forces here.
template <typename M, typename T>
__global__ void __launch_bounds__(kFemThreads)
    mesh_element_pass(MeshView<T> mesh, material_params_t<M, T> params, BodyStepStats* body_stats) {
  const int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e >= mesh.element_count) return;
  const TetElement<T> el = mesh.elements[e];
  const Mat3<T> F = tet_deformation_gradient(el, mesh.x[el.v[0]], mesh.x[el.v[1]], mesh.x[el.v[2]], mesh.x[el.v[3]]);
  const T J = determinant(F);
  mesh.F[e] = F;
  if (!(J > T(0))) {
    atomicAdd(&body_stats->failures[kFailInverted], 1);
    atomicMin(&body_stats->first_id[kFailInverted], e);
    return;
  }
  if (mesh.fbar_psi != T(0)) {
    mesh.J[e] = J;
  } else if (mesh.forces) {
    mesh.H[e] = tet_nodal_forces(el, M::kirchhoff_stress(params, material_state_t<M, T>{F}, Mat3<T>::zero()).kirchhoff, F);
  }
}

/// F-bar: each vertex's V0-weighted mean of its elements' J, in element order. Skipped (as the CPU engine) when an
/// element inverted: the try fails.
template <typename T>
__global__ void __launch_bounds__(kFemThreads) mesh_vertex_volume_ratio(MeshView<T> mesh, const BodyStepStats* body_stats) {
  const int v = blockIdx.x * blockDim.x + threadIdx.x;
  if (v >= mesh.vertex_count || body_stats->failures[kFailInverted] > 0) return;
  T sum_J = T(0), sum_V = T(0);
  for (int c = mesh.vertex_start[v]; c < mesh.vertex_start[v + 1]; ++c) {
    const int e = mesh.vertex_elements[c] / 4;
    const T V = mesh.elements[e].volume;
    sum_J += mesh.J[e] * V;
    sum_V += V;
  }
  mesh.vertex_J[v] = sum_V > T(0) ? sum_J / sum_V : T(1);
}

/// F-bar: each element's gradient scaled to the blend of its J and its vertices' mean, and its forces at it.
template <typename M, typename T>
__global__ void __launch_bounds__(kFemThreads)
    mesh_fbar_elements(MeshView<T> mesh, material_params_t<M, T> params, const BodyStepStats* body_stats) {
  const int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e >= mesh.element_count || body_stats->failures[kFailInverted] > 0) return;
  const TetElement<T> el = mesh.elements[e];
  const T Jbar =
      T(0.25) * (mesh.vertex_J[el.v[0]] + mesh.vertex_J[el.v[1]] + mesh.vertex_J[el.v[2]] + mesh.vertex_J[el.v[3]]);
  const Mat3<T> F = tet_fbar_gradient(mesh.F[e], mesh.J[e], Jbar, mesh.fbar_psi);
  mesh.F[e] = F;
  if (mesh.forces)
    mesh.H[e] = tet_nodal_forces(el, M::kirchhoff_stress(params, material_state_t<M, T>{F}, Mat3<T>::zero()).kirchhoff, F);
}

/// What the vertex pass reads and writes besides the mesh.
template <typename M, typename T, typename TG>
struct MeshVertexParams {
  MeshView<T> mesh;
  typename ParticleLayout<M, T>::Buffer bins;  ///< the bins the G2P2G wrote (states replaced at mesh.slot)
  material_params_t<M, T> params;
  Vec3<T>* force;                              ///< (vertex) the elements' force at these positions [N], written
  BlockHashTableView table;
  GridSums<TG> grid_next;                      ///< the next step's P2G sums (the impulse is added)
  const GridQuantum* quantum_next;             ///< their quanta
  const double* dt_next;                       ///< [s] that P2G's impulse dt (device)
  T inv_dx;
  const T* aux;                                ///< (slot, kAuxScalars) v and C the G2P2G recorded
  FrameCapture<T> capture;                     ///< capture.x != nullptr: a frame step
  ParticleMeasures<T> measures;
  StepStats* stats;
  BodyStepStats* body_stats;
  unsigned long long* wave_speed;              ///< (this body) bits of the largest wave speed of the new state
};

/// 3. Per vertex: state, force, checks, wave speed, impulse and frame entry (file comment).
template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kFemThreads) mesh_vertex_pass(MeshVertexParams<M, T, TG> p) {
  const int v = blockIdx.x * blockDim.x + threadIdx.x;
  double wave = 0.0;
  const bool skip = p.body_stats->failures[kFailInverted] > 0;  // the try fails; nothing below means anything
  if (v < p.mesh.vertex_count && !skip) {
    const MeshView<T>& m = p.mesh;
    Mat3<T> sum_F = Mat3<T>::zero();
    T sum_V = T(0);
    Vec3<T> f = Vec3<T>::zero();
    for (int c = m.vertex_start[v]; c < m.vertex_start[v + 1]; ++c) {
      const int corner = m.vertex_elements[c];
      const int e = corner / 4, k = corner % 4;
      const T V = m.elements[e].volume;
      sum_F += m.F[e] * V;
      sum_V += V;
      if (m.forces) {
        const Mat3<T> h = m.H[e];
        for (int a = 0; a < 3; ++a) f[a] += k == 0 ? -(h(a, 0) + h(a, 1) + h(a, 2)) : h(a, k - 1);
      }
    }
    const material_state_t<M, T> s{sum_V > T(0) ? sum_F / sum_V : Mat3<T>::identity()};
    const bool inside = m.slot[v] >= 0;  // else the try fails (CFL): no impulse, nodes may be missing
    const int slot = inside ? m.slot[v] : -1 - m.slot[v];
    ParticleRecord<M, T> r = load_particle<M, T>(p.bins, slot);
    r.state = s;
    store_particle<M, T>(p.bins, slot, r);
    p.force[v] = f;
    const bool finite = all_finite(f) && g2p2g_detail::state_finite<T, ParticleLayout<M, T>::kStateScalars>(s);
    if (!finite) {
      atomicAdd(&p.body_stats->failures[kFailNonFinite], 1);
      atomicMin(&p.body_stats->first_id[kFailNonFinite], v);
    } else {
      wave = static_cast<double>(M::wave_speed(p.params, s));
      if (inside && m.forces && (f[0] != T(0) || f[1] != T(0) || f[2] != T(0)))
        fem_add_impulse<T, TG>(p.table, p.grid_next, p.quantum_next, m.x[v], p.inv_dx, f * static_cast<T>(*p.dt_next),
                               p.stats);
    }
    if (p.capture.x) {
      const T* a = p.aux + static_cast<std::size_t>(slot) * kAuxScalars;
      Mat3<T> C;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) C(i, j) = a[3 + 3 * i + j];
      capture_particle<M, T>(p.capture, v, m.x[v], Vec3<T>{{a[0], a[1], a[2]}}, C, s, p.params, p.measures.mass_of(v),
                             p.measures.volume_of(v));
    }
  }
  wave = warp_max(wave);
  if (threadIdx.x % 32 == 0 && wave > 0.0) atomic_max_nonneg(p.wave_speed, wave);
}

/// The impulse of a changed dt: w_ip f (ddt) at each vertex of the current bins (storage read through src).
template <typename M, typename T, typename TG>
__global__ void __launch_bounds__(kFemThreads)
    mesh_rescale_impulse(typename ParticleLayout<M, T>::Buffer bins, const int* src, int slots, const Vec3<T>* force,
                         int vertex_count, T ddt, T inv_dx, BlockHashTableView table,
                         GridSums<TG> grid, const GridQuantum* quantum, StepStats* stats) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int s = src[slot];
  if (s < 0) return;
  const ParticleRecord<M, T> r = load_particle<M, T>(bins, s);
  if (r.id < 0 || r.id >= vertex_count) return;
  const Vec3<T> f = force[r.id];
  if (f[0] == T(0) && f[1] == T(0) && f[2] == T(0)) return;
  fem_add_impulse<T, TG>(table, grid, quantum, r.x, inv_dx, f * ddt, stats);
}

}  // namespace fbar
