// Linear tetrahedral finite elements coupled to MPM through the grid (host and device formulas, no storage).
//
// ClaymoreUW's coupling (its g2p2v / v2fem2v / v2p2g kernels), which both engines follow: a mesh's vertices are
// particles of their own body. Each step
//   1. P2G    each vertex gives its nodes w_ip m_v and w_ip (m_v v_v + m_v C_v (x_i - x_v) + dt f_v): mass and APIC
//             momentum like a particle, no MLS stress; the elements' internal force f_v enters as an impulse
//   2. grid   the common grid update (gravity, boundaries): vertices, particles and other meshes meet here
//   3. G2P    each vertex takes v, C and x from the grid like a particle (ASFLIP when the mesh asks for it)
//   4. forces from the new vertex positions, per element e with rest edges Dm = [X1-X0, X2-X0, X3-X0]:
//               F_e = Ds Dm^-1  (Ds the current edges),   P_e = tau(F_e) F_e^-T   (the element's law),
//               [f1 f2 f3] = -V0_e P_e Dm^-T,   f0 = -(f1 + f2 + f3)
//             summed at the vertices for the next step's P2G (the force of the committed positions).
// Vertex masses lump the elements: m_v = rho sum_e V0_e / 4 over the elements holding v (ClaymoreUW's), so the
// mesh carries its exact mass rho V whatever the mesh; the vertex's reference volume is that lumped volume.
// use_FBAR (ClaymoreUW's Tetrahedron_FBar, against volumetric locking of linear tetrahedra): each vertex averages
// its elements' J weighted by V0_e, each element takes the mean of its four vertices' averages, Jbar, and its stress
// from Fbar = (Jbar_mix / J)^(1/3) F with Jbar_mix = (1 - psi) J + psi Jbar (psi = meshes[].FBAR_ratio; ClaymoreUW
// reads FBAR_ratio and uses psi = 1: fbar's default is the same when use_FBAR is given without a ratio). The element's
// force is then -V0 tau(Fbar) Fbar^-T Dm^-T, the plain element's formula at Fbar: not the energy-consistent F-bar
// force (-V0 (J / Jbar) tau(Fbar) F^-T Dm^-T), from which it differs by a factor that is 1 where J = Jbar.
// A vertex's state (its frames, sensors and wave speed) is the V0-weighted mean of the gradients its elements' stresses
// use (F, or the F-bar elements' gradient): the stress a frame shows at a vertex is the mean of its elements'.
// Time step: an element of smallest height h (3 V / largest face area, at rest) bounds dt by CFL h / c_p beside the
// grid's CFL dx / (c_p + |v|) (explicit FEM; run_constants.h body_element_step_bound): a mesh squeezed to a
// fraction of its rest heights needs a smaller CFL number.
#pragma once

#include <cmath>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// One tetrahedron at rest: its vertices (indices into the mesh body's particles), Dm^-1 and V0.
template <typename T>
struct TetElement {
  int v[4];
  Mat3<T> Dm_inv;  ///< [1/m] inverse of the rest edge matrix [X1-X0, X2-X0, X3-X0]
  T volume;        ///< [m^3] rest volume V0 (> 0: the scene refuses inverted elements)
};

/// Edge matrix [x1-x0, x2-x0, x3-x0] (columns) [m].
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> tet_edges(const Vec3<T>& x0, const Vec3<T>& x1, const Vec3<T>& x2,
                                             const Vec3<T>& x3) {
  Mat3<T> D;
  for (int a = 0; a < 3; ++a) {
    D.m[a][0] = x1[a] - x0[a];
    D.m[a][1] = x2[a] - x0[a];
    D.m[a][2] = x3[a] - x0[a];
  }
  return D;
}

/// Deformation gradient F = Ds Dm^-1 of an element from its current vertex positions [-].
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> tet_deformation_gradient(const TetElement<T>& e, const Vec3<T>& x0, const Vec3<T>& x1,
                                                            const Vec3<T>& x2, const Vec3<T>& x3) {
  return tet_edges(x0, x1, x2, x3) * e.Dm_inv;
}

/// The F-bar element's gradient: F scaled to the volume ratio (1 - psi) J + psi Jbar (file comment).
template <typename T>
FBAR_HOST_DEVICE inline Mat3<T> tet_fbar_gradient(const Mat3<T>& F, T J, T Jbar, T psi) {
  using std::cbrt;
  const T mix = (T(1) - psi) * J + psi * Jbar;
  return F * cbrt(mix / J);
}

/// The element's nodal forces H = [f1 f2 f3] = -V0 tau F^-T Dm^-T [N] from its Kirchhoff stress tau = P F^T (f0 is
/// -(f1 + f2 + f3)). F^-T through the cofactor: F^-T = cof(F) / J.
template <typename T>
FBAR_HOST_DEVICE constexpr Mat3<T> tet_nodal_forces(const TetElement<T>& e, const Mat3<T>& kirchhoff, const Mat3<T>& F) {
  const Mat3<T> F_inv_T = cofactor(F) / determinant(F);
  return (kirchhoff * F_inv_T) * transpose(e.Dm_inv) * (-e.volume);
}

/// Smallest height of a tetrahedron: 3 V / (largest face area) [m] (the explicit FEM step's length).
template <typename T>
FBAR_HOST_DEVICE inline T tet_min_height(const Vec3<T>& x0, const Vec3<T>& x1, const Vec3<T>& x2, const Vec3<T>& x3) {
  using std::abs;
  const T six_v = abs(dot(x1 - x0, cross(x2 - x0, x3 - x0)));
  const T a0 = norm(cross(x2 - x1, x3 - x1));  // twice the area of the face opposite vertex 0
  const T a1 = norm(cross(x2 - x0, x3 - x0));
  const T a2 = norm(cross(x1 - x0, x3 - x0));
  const T a3 = norm(cross(x1 - x0, x2 - x0));
  T a = a0 > a1 ? a0 : a1;
  a = a > a2 ? a : a2;
  a = a > a3 ? a : a3;
  return six_v / a;  // 3 V / (a / 2) = 6 V / a
}

}  // namespace fbar
