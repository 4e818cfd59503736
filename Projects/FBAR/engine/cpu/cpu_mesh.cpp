// The CPU engine's FEM bodies (cpu_engine.h MeshPart; the coupling in physics/fem.cuh): the elements built from a
// mesh at start, and the element pass after each try's G2P (vertex forces and states from the new positions).
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "engine/cpu/cpu_engine.h"
#include "engine/cpu/cpu_engine_detail.h"
#include "engine/mesh_elements.h"

namespace fbar {

using namespace cpu_detail;

template <typename T, typename TG>
void CpuEngine<T, TG>::init_mesh(Body& body) {
  const MeshEntrySpec& entry = scene_.meshes.at(static_cast<std::size_t>(body.spec.mesh));
  const TetMesh& mesh = *entry.mesh;
  MeshPart& part = body.mesh;
  part.fbar_psi = entry.fbar_elements ? static_cast<T>(entry.fbar_ratio) : T(0);
  const std::size_t nv = mesh.vertices.size();
  // Every vertex, or none: a rank restarted from its own checkpoint holds no vertex of a mesh placed elsewhere.
  const bool held = !body.x.empty();
  if (held && body.x.size() != nv)
    throw std::invalid_argument("meshes[" + std::to_string(body.spec.mesh) + "]: " + std::to_string(body.x.size()) +
                                " vertex positions for a mesh of " + std::to_string(nv) + " vertices");
  MeshElements<T> built = mesh_elements<T>(mesh);  // rest shapes from the mesh file, not from the particle positions
  part.elements = std::move(built.elements);
  part.vertex_start = std::move(built.vertex_start);
  part.vertex_elements = std::move(built.vertex_elements);
  const std::vector<double>& lumped = built.lumped_volume;
  const double rho = body.spec.material.rho;
  if (!held) return;  // its elements only (the rank holding the mesh steps it)
  for (std::size_t v = 0; v < nv; ++v) {
    body.volume[v] = static_cast<T>(lumped[v]);
    body.mass[v] = static_cast<T>(rho * lumped[v]);  // a vertex in no element carries no mass (the parser warned)
  }
  part.force.assign(nv, Vec3T::zero());
  part.force_next.assign(nv, Vec3T::zero());
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (kMeshLaw<M, T>) {
          const MeshPassResult r = mesh_pass<M>(body, mb.params, body.x, part.force, mb.state);
          if (r.inverted > 0)
            throw std::invalid_argument("meshes[" + std::to_string(body.spec.mesh) + "]: element " +
                                        std::to_string(r.first_inverted) + " is inverted at the start");
          body.max_wave_speed = std::max(body.max_wave_speed, r.max_wave_speed);
        } else {
          throw std::invalid_argument("meshes[" + std::to_string(body.spec.mesh) + "].constitutive: " +
                                      std::string(M::kJsonName) + " is not an element law (FixedCorotated, NeoHookean)");
        }
      },
      body.material);
}

template <typename T, typename TG>
long long CpuEngine<T, TG>::element_gradients(const Body& body, const std::vector<Vec3T>& x, std::vector<Mat3T>& F,
                                              long long& first_inverted) const {
  const MeshPart& part = body.mesh;
  const int ne = static_cast<int>(part.elements.size());
  const int nv = static_cast<int>(x.size());
  F.resize(static_cast<std::size_t>(ne));
  std::vector<T> J(static_cast<std::size_t>(ne));
  long long inverted = 0, first = std::numeric_limits<long long>::max();
#pragma omp parallel for schedule(static) reduction(+ : inverted) reduction(min : first) if (ne >= kMinParallelParticles)
  for (int e = 0; e < ne; ++e) {
    const TetElement<T>& el = part.elements[static_cast<std::size_t>(e)];
    F[static_cast<std::size_t>(e)] = tet_deformation_gradient(el, x[el.v[0]], x[el.v[1]], x[el.v[2]], x[el.v[3]]);
    J[static_cast<std::size_t>(e)] = determinant(F[static_cast<std::size_t>(e)]);
    if (!(J[static_cast<std::size_t>(e)] > T(0))) {
      ++inverted;
      first = std::min(first, static_cast<long long>(e));
    }
  }
  first_inverted = inverted > 0 ? first : -1;
  if (inverted > 0 || part.fbar_psi == T(0)) return inverted;
  // F-bar elements: each vertex's V0-weighted mean of its elements' J (in element order), then each element's
  // gradient scaled to the blend of its J and the mean of its four vertices' (physics/fem.cuh).
  std::vector<T> vertex_J(static_cast<std::size_t>(nv));
#pragma omp parallel for schedule(static) if (nv >= kMinParallelParticles)
  for (int v = 0; v < nv; ++v) {
    T sum_J = T(0), sum_V = T(0);
    for (int c = part.vertex_start[static_cast<std::size_t>(v)]; c < part.vertex_start[static_cast<std::size_t>(v) + 1]; ++c) {
      const int e = part.vertex_elements[static_cast<std::size_t>(c)] / 4;
      const T V = part.elements[static_cast<std::size_t>(e)].volume;
      sum_J += J[static_cast<std::size_t>(e)] * V;
      sum_V += V;
    }
    vertex_J[static_cast<std::size_t>(v)] = sum_V > T(0) ? sum_J / sum_V : T(1);
  }
#pragma omp parallel for schedule(static) if (ne >= kMinParallelParticles)
  for (int e = 0; e < ne; ++e) {
    const TetElement<T>& el = part.elements[static_cast<std::size_t>(e)];
    const T Jbar = T(0.25) * (vertex_J[el.v[0]] + vertex_J[el.v[1]] + vertex_J[el.v[2]] + vertex_J[el.v[3]]);
    F[static_cast<std::size_t>(e)] = tet_fbar_gradient(F[static_cast<std::size_t>(e)], J[static_cast<std::size_t>(e)],
                                                       Jbar, part.fbar_psi);
  }
  return 0;
}

template <typename T, typename TG>
template <typename M, typename States>
typename CpuEngine<T, TG>::MeshPassResult CpuEngine<T, TG>::mesh_pass(const Body& body,
                                                                     const material_params_t<M, T>& params,
                                                                     const std::vector<Vec3T>& x,
                                                                     std::vector<Vec3T>& force, States& states) const {
  static_assert(kMeshLaw<M, T>, "mesh elements need a law whose state is F");
  const MeshPart& part = body.mesh;
  const int ne = static_cast<int>(part.elements.size());
  const int nv = static_cast<int>(x.size());
  MeshPassResult result;
  if (nv == 0) return result;  // the mesh lives on another rank
  std::vector<Mat3T> F;
  long long first = -1;
  const long long inverted = element_gradients(body, x, F, first);
  result.inverted = inverted;
  result.first_inverted = first;
  if (inverted > 0) return result;  // the try fails; nothing below means anything
  const auto each_corner = [&](int v, auto&& fn) {
    for (int c = part.vertex_start[static_cast<std::size_t>(v)]; c < part.vertex_start[static_cast<std::size_t>(v) + 1]; ++c)
      fn(part.vertex_elements[static_cast<std::size_t>(c)]);
  };

  // Element forces H = [f1 f2 f3] (f0 = -(f1 + f2 + f3)) from the gradient the element's stress uses.
  const bool forces = body.spec.algorithm.use_fem;  // meshes[].use_FEM: the elements exert forces
  std::vector<Mat3T> H(forces ? static_cast<std::size_t>(ne) : 0);
  if (forces) {
#pragma omp parallel for schedule(static) if (ne >= kMinParallelParticles)
    for (int e = 0; e < ne; ++e) {
      const Mat3T& Fe = F[static_cast<std::size_t>(e)];
      const StressResult<T> stress = M::kirchhoff_stress(params, material_state_t<M, T>{Fe}, Mat3T::zero());
      H[static_cast<std::size_t>(e)] = tet_nodal_forces(part.elements[static_cast<std::size_t>(e)], stress.kirchhoff, Fe);
    }
  }
  // Per vertex, in element order (deterministic): its state, the V0-weighted mean of those gradients (so a vertex's
  // stress is the mean of what its elements use), and the sum of its elements' forces.
  force.resize(static_cast<std::size_t>(nv));
  T max_wave = T(0);
  long long nonfinite = 0, first_nonfinite = std::numeric_limits<long long>::max();
#pragma omp parallel for schedule(static) reduction(max : max_wave) reduction(+ : nonfinite) \
    reduction(min : first_nonfinite) if (nv >= kMinParallelParticles)
  for (int v = 0; v < nv; ++v) {
    Mat3T sum_F = Mat3T::zero();
    T sum_V = T(0);
    Vec3T f = Vec3T::zero();
    each_corner(v, [&](int corner) {
      const int e = corner / 4, k = corner % 4;
      const T V = part.elements[static_cast<std::size_t>(e)].volume;
      sum_F += F[static_cast<std::size_t>(e)] * V;
      sum_V += V;
      if (forces) {
        const Mat3T& h = H[static_cast<std::size_t>(e)];
        for (int a = 0; a < 3; ++a) f[a] += k == 0 ? -(h(a, 0) + h(a, 1) + h(a, 2)) : h(a, k - 1);
      }
    });
    const material_state_t<M, T> s{sum_V > T(0) ? sum_F / sum_V : Mat3T::identity()};
    states[static_cast<std::size_t>(v)] = s;
    force[static_cast<std::size_t>(v)] = f;
    if (!all_finite(f) || !state_is_finite<T>(s)) {
      ++nonfinite;
      first_nonfinite = std::min(first_nonfinite, static_cast<long long>(body.id[static_cast<std::size_t>(v)]));
    }
    max_wave = std::max(max_wave, M::wave_speed(params, s));
  }
  result.max_wave_speed = static_cast<double>(max_wave);
  result.nonfinite = nonfinite;
  result.first_nonfinite = nonfinite > 0 ? first_nonfinite : -1;
  return result;
}

template <typename T, typename TG>
typename CpuEngine<T, TG>::MeshPassResult CpuEngine<T, TG>::mesh_after_g2p(Body& body) {
  MeshPassResult r;
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (kMeshLaw<M, T>) r = mesh_pass<M>(body, mb.params, body.x_next, body.mesh.force_next, mb.next_state);
      },
      body.material);
  return r;
}

template <typename T, typename TG>
double CpuEngine<T, TG>::mesh_elastic_energy(const Body& body) const {
  double e = 0.0;
  if (body.x.empty()) return e;  // the mesh lives on another rank
  std::vector<Mat3T> F;
  long long first = -1;
  element_gradients(body, body.x, F, first);  // the gradients the stresses use (F-bar's when use_FBAR)
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (kMeshLaw<M, T>)
          for (std::size_t k = 0; k < F.size(); ++k)
            e += static_cast<double>(body.mesh.elements[k].volume) *
                 static_cast<double>(M::energy_density(mb.params, material_state_t<M, T>{F[k]}));
      },
      body.material);
  return e;
}

template class CpuEngine<double, double>;
template class CpuEngine<float, float>;
template class CpuEngine<double, float>;

}  // namespace fbar
