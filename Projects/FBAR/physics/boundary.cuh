// Grid boundary projections: Walls (faces of a box that holds the material) and Box (an obstacle), host/device.
//
// A boundary acts on grid node velocities after v = p/m + dt g (grid_update.cuh), while its time window
// [t_begin, t_end] contains the time t at the start of the step. Contact (scene "contact"):
//   Sticky     v = 0 at the boundary nodes.
//   Slip       the normal component is removed:             v <- v - (v.n) n
//   Separable  only a normal component INTO the wall is removed:  v <- v - min(v.n, 0) n
// n is the unit normal pointing out of the wall into the material. With friction (friction_dynamic mu_d,
// friction_static mu_s, Slip/Separable only; Coulomb law on the grid as in Stomakhin et al. 2013), when the node
// pushes into the wall (v.n < 0) the tangential velocity v_t is removed if |v_t| <= mu_s |v.n| and otherwise
// shortened by mu_d |v.n|.
//
// Walls: the box [lo, hi] (the boundary's domain_start/domain_end, or the simulation domain when those are left at
// 0) keeps the material inside. Along each axis a node belongs to the low wall when x_i - lo < 1.5 dx and to the
// high wall when hi - x_i < 1.5 dx: the face node plane and the first plane inside it, i.e. a one-cell wall layer
// at each face (ClaymoreUW's walls are a layer of cells at the domain boundary). Particles then settle about one
// cell inside the face and their stencils never leave [lo - dx, hi + dx]. A node in several walls (edges, corners)
// gets each wall's projection in turn (x, then y, then z).
// Box: the obstacle [lo, hi] (closed) from domain_start to domain_end. Nodes inside it are projected with the
// outward normal of the nearest face (ties: lowest axis, low face first); material may not enter.
#pragma once

#include <cmath>
#include <string>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "scene/scene.h"

namespace fbar {

enum class BoundaryShape : int { Walls, Box };

/// A boundary as kernels see it (trivially copyable; built on the host by make_boundary_params).
template <typename T>
struct BoundaryParams {
  BoundaryShape shape;
  Contact contact;
  Vec3<T> lo;          ///< [m] box min corner
  Vec3<T> hi;          ///< [m] box max corner
  T layer;             ///< [m] Walls: nodes closer than this to a face are wall nodes (1.5 dx)
  T friction_static;   ///< [-] mu_s
  T friction_dynamic;  ///< [-] mu_d
  double t_begin;      ///< [s] active window (double: compared with the simulation clock)
  double t_end;        ///< [s]
};

/// Is the boundary active for the step that starts at time t [s]?
template <typename T>
FBAR_HOST_DEVICE constexpr bool boundary_active(const BoundaryParams<T>& b, double t) {
  return t >= b.t_begin && t <= b.t_end;
}

/// Projects v against a wall with unit normal n (pointing into the material) for the given contact law.
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> project_contact(const BoundaryParams<T>& b, const Vec3<T>& v, const Vec3<T>& n) {
  using std::sqrt;
  if (b.contact == Contact::Sticky) return Vec3<T>::zero();
  const T vn = dot(v, n);
  if (b.contact == Contact::Separable && vn >= T(0)) return v;  // leaving the wall: untouched
  Vec3<T> vt = v - n * vn;
  if (vn < T(0) && (b.friction_static > T(0) || b.friction_dynamic > T(0))) {
    const T vt_norm = sqrt(dot(vt, vt));
    const T push = -vn;
    if (vt_norm <= b.friction_static * push) {
      vt = Vec3<T>::zero();
    } else if (vt_norm > T(0)) {
      const T shrink = vt_norm - b.friction_dynamic * push;
      vt = shrink > T(0) ? vt * (shrink / vt_norm) : Vec3<T>::zero();
    }
  }
  return vt;
}

/// The velocity of the grid node at x_node [m] after this boundary (assumed active).
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> apply_boundary(const BoundaryParams<T>& b, const Vec3<T>& x_node, Vec3<T> v) {
  if (b.shape == BoundaryShape::Walls) {
    for (int a = 0; a < 3; ++a) {
      Vec3<T> n = Vec3<T>::zero();
      if (x_node[a] - b.lo[a] < b.layer) {
        n[a] = T(1);
        v = project_contact(b, v, n);
      }
      if (b.hi[a] - x_node[a] < b.layer) {
        n[a] = T(-1);
        v = project_contact(b, v, n);
      }
    }
    return v;
  }
  // Box obstacle.
  for (int a = 0; a < 3; ++a)
    if (x_node[a] < b.lo[a] || x_node[a] > b.hi[a]) return v;  // outside: untouched
  int axis = 0;
  T sign = T(-1);
  T nearest = x_node[0] - b.lo[0];
  for (int a = 0; a < 3; ++a) {
    const T to_lo = x_node[a] - b.lo[a];
    const T to_hi = b.hi[a] - x_node[a];
    if (to_lo < nearest) nearest = to_lo, axis = a, sign = T(-1);
    if (to_hi < nearest) nearest = to_hi, axis = a, sign = T(1);
  }
  Vec3<T> n = Vec3<T>::zero();
  n[axis] = sign;
  return project_contact(b, v, n);
}

/// Builds the kernel parameters of a boundary on the host. Returns false and an explanation in `error` for a
/// boundary the engines do not implement yet (other objects, moving boundaries, arrays), never ignoring a key.
template <typename T>
inline bool make_boundary_params(const BoundarySpec& spec, const SimulationSpec& sim, BoundaryParams<T>& out,
                                 std::string& error) {
  if (spec.object != BoundaryObject::Walls && spec.object != BoundaryObject::Box) {
    error = "only the Walls and Box boundary objects are implemented";
    return false;
  }
  if (spec.velocity[0] != 0.0 || spec.velocity[1] != 0.0 || spec.velocity[2] != 0.0 || !spec.file.empty()) {
    error = "moving boundaries (velocity, motion file) are not implemented";
    return false;
  }
  if (spec.array[0] != 1 || spec.array[1] != 1 || spec.array[2] != 1) {
    error = "boundary arrays (array != [1,1,1]) are not implemented";
    return false;
  }
  bool has_box = true;
  for (int a = 0; a < 3; ++a) has_box = has_box && spec.domain_end[a] > spec.domain_start[a];
  if (spec.object == BoundaryObject::Box && !has_box) {
    error = "a Box boundary needs domain_end > domain_start in every axis";
    return false;
  }
  out.shape = spec.object == BoundaryObject::Walls ? BoundaryShape::Walls : BoundaryShape::Box;
  out.contact = spec.contact;
  for (int a = 0; a < 3; ++a) {
    out.lo[a] = static_cast<T>(has_box ? spec.domain_start[a] : 0.0);
    out.hi[a] = static_cast<T>(has_box ? spec.domain_end[a] : sim.domain[a]);
  }
  out.layer = static_cast<T>(1.5 * sim.dx);
  out.friction_static = static_cast<T>(spec.friction_static);
  out.friction_dynamic = static_cast<T>(spec.friction_dynamic);
  out.t_begin = spec.time[0];
  out.t_end = spec.time[1];
  return true;
}

}  // namespace fbar
