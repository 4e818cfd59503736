// A mesh's elements as both engines run them (physics/fem.cuh): the rest shapes, the lumped vertex masses and the
// CSR of each vertex's elements, built once on the host from the scene's TetMesh (double arithmetic, then cast).
#pragma once

#include <array>
#include <cstddef>
#include <type_traits>
#include <vector>

#include "MnBase/Math/vec.h"
#include "geometry/tet_mesh.h"
#include "physics/constitutive_models.cuh"
#include "physics/fem.cuh"

namespace fbar {

/// The laws whose state is F alone (FixedCorotated, NeoHookean): the elements' laws (meshes[].constitutive).
template <typename M, typename T>
constexpr bool kMeshLaw = std::is_same_v<material_state_t<M, T>, FixedCorotatedState<T>>;

template <typename T>
struct MeshElements {
  std::vector<TetElement<T>> elements;
  /// CSR: the corners (4 e + k) of vertex v are vertex_elements[vertex_start[v] .. vertex_start[v + 1]), in element
  /// order (the order the engines sum them in: bitwise independent of threads).
  std::vector<int> vertex_start, vertex_elements;
  /// (vertex) lumped rest volume sum_e V0_e / 4 [m^3] (double: the mass rho V of the body is exact). A vertex in no
  /// element has none (and no mass: the parser warned).
  std::vector<double> lumped_volume;
};

/// The elements of `mesh` (vertices placed, in metres): Dm^-1 and V0 from the rest positions in double.
template <typename T>
MeshElements<T> mesh_elements(const TetMesh& mesh) {
  MeshElements<T> out;
  const std::size_t nv = mesh.vertices.size();
  out.lumped_volume.assign(nv, 0.0);
  std::vector<int> count(nv + 1, 0);
  out.elements.reserve(mesh.elements.size());
  for (const std::array<int, 4>& e : mesh.elements) {
    const Vec3d& X0 = mesh.vertices[static_cast<std::size_t>(e[0])];
    const Mat3d Dm = tet_edges(X0, mesh.vertices[static_cast<std::size_t>(e[1])],
                               mesh.vertices[static_cast<std::size_t>(e[2])], mesh.vertices[static_cast<std::size_t>(e[3])]);
    const double V0 = determinant(Dm) / 6.0;  // > 0: check_tet_mesh refused inverted elements
    TetElement<T> el;
    for (int k = 0; k < 4; ++k) {
      el.v[k] = e[k];
      out.lumped_volume[static_cast<std::size_t>(e[k])] += V0 / 4.0;
      ++count[static_cast<std::size_t>(e[k]) + 1];
    }
    el.Dm_inv = inverse(Dm).template cast<T>();
    el.volume = static_cast<T>(V0);
    out.elements.push_back(el);
  }
  for (std::size_t v = 0; v < nv; ++v) count[v + 1] += count[v];
  out.vertex_start = count;
  out.vertex_elements.assign(static_cast<std::size_t>(count[nv]), 0);
  std::vector<int> fill(count.begin(), count.end() - 1);
  for (std::size_t e = 0; e < out.elements.size(); ++e)
    for (int k = 0; k < 4; ++k)
      out.vertex_elements[static_cast<std::size_t>(fill[static_cast<std::size_t>(out.elements[e].v[k])]++)] =
          static_cast<int>(4 * e + k);
  return out;
}

}  // namespace fbar
