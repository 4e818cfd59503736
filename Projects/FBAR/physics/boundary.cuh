// Grid boundary projections, host/device: a boundary is a shape (which nodes it holds, and the normal n there,
// pointing out of the boundary into the material), a contact law and a velocity; both engines call apply_boundary()
// on grid node velocities after v = p/m + dt g (grid_update.cuh), while its time window [t_begin, t_end] contains
// the time t at the start of the step.
//
// Contact (scene "contact"), on the velocity relative to the boundary's, v_rel = v - v_b:
//   Sticky     v_rel = 0 at the boundary nodes.
//   Slip       the normal component is removed:                v_rel <- v_rel - (v_rel.n) n
//   Separable  only a normal component INTO the boundary is:    v_rel <- v_rel - min(v_rel.n, 0) n
// Coulomb friction (friction_dynamic mu_d, friction_static mu_s; Slip and Separable, as on the grid in Stomakhin et
// al. 2013): when the node pushes into the boundary (v_rel.n < 0) the tangential v_t is removed if
// |v_t| <= mu_s |v_rel.n| and otherwise shortened by mu_d |v_rel.n|, so the friction impulse is mu_d x the normal one.
//
// Shapes (ClaymoreUW's, from domain_start = lo and domain_end = hi; "keeps out": material stays outside):
//   Walls     keeps the material INSIDE the box [lo, hi] (the simulation domain when both are 0), on ClaymoreUW's
//             nodes (mgmpm_kernels.cuh, grid update, Walls): along each axis a node belongs to the low wall when
//             x_i <= lo and to the high wall when x_i >= hi, i.e. the face node plane and the planes outside it.
//             Sticky: every component of v_rel is removed there. Slip and Separable: the contact law acts along the
//             wall's normal (per axis, in turn for a node in several walls), and nodes 1.5 dx or more outside a face
//             (x_i <= lo - 1.5 dx, x_i >= hi + 1.5 dx) are held (v_rel = 0), so material that crossed the face stops.
//             Material may therefore fill the box to its faces; the outermost particles can cross a face by up to
//             half a cell (kDomainMarginCells lets them stand outside simulation.domain).
//   Box       keeps out of [lo, hi] (ClaymoreUW's nodes: inside, faces included); every node inside is projected with
//             the outward normal of the nearest face (on an edge the first axis of x, y, z wins a tie; ClaymoreUW
//             favours x too but leaves y-z edge nodes free). ClaymoreUW holds a Slip or Separable box's core (nodes
//             0.99 dx or more inside every face): fbar does not, since held nodes a cell inside a face drag material
//             sliding along it (a Slip box used as a symmetry plane stops being one).
//   Sphere    keeps out of the ball of center (lo + hi) / 2 and radius (hi_x - lo_x) / 2; n radial.
//   Cylinder  keeps out of the cylinder along y from lo_y to hi_y, axis at the box's center in x and z, radius
//             (hi_x - lo_x) / 2; n radial, or +-y at the nearer cap (ClaymoreUW has no caps: material on top sank in).
//   Floor     every node inside [lo, hi] is projected with n = +y.
//   Plane     the line from (lo_x, lo_y) to (hi_x, hi_y), infinite in z, for lo_x <= x < hi_x: nodes below it (and,
//             when it slopes, up to kBedLayerCells cells above it) are projected with its normal
//             (-dy, dx) / |(dx, dy)| (pointing up for a line drawn left to right).
//   HalfSpace keeps the material on the left of the line from (lo_x, lo_y) to (hi_x, hi_y), extended without end
//             in x and y, for lo_z <= z <= hi_z: nodes on the line or right of it are projected with its normal
//             (-dy, dx) / |(dx, dy)| (no band: a plate or a gate, not a bed). Not a scene object: facility pieces
//             (the USGS gate's slanted plate and doors) are built from it.
//   Velocity  every node inside [lo, hi] takes the boundary's velocity (contact and friction do not apply).
//   Bathymetry  keeps the material above the bed y_s(x): the piecewise-linear profile through its `bathymetry`
//             points (flat beyond the first and last), over all z; nodes at or below it (and, within a cell of a
//             sloped segment, up to kBedLayerCells cells above it) are projected with the normal of their segment (BoundaryProfiles
//             holds the points).
//   Piston    a wave maker: every node inside [lo, hi] is projected with n = +x (its face is the +x face at hi_x;
//             the material is in front of it). Moved by a motion file or `velocity` like any boundary.
//   Pump      drives the flow inside [lo, hi]: along each axis where the pump's velocity u_a is not 0, a node slower
//             than u_a in u_a's direction takes u_a (a faster node keeps its speed); contact does not apply and the
//             pump does not move (its velocity is the flow's).
// Facility objects (OSU flume and basin, USGS flume, WASIRF, Waseda harbour) are built from these shapes on the host
// (scene/facilities.h expand_boundary); nothing facility-specific reaches this file.
// A moving boundary (velocity v_b != 0) translates by v_b (t - t_begin): boundary_at() gives it at time t; one with a
// motion file (physics/motion_path.h) by the file's displacement along x, with the file's velocity. One with an
// angular velocity omega also turns, by |omega| (t - t_begin) about omega's axis through its rotation centre (which
// translates with it): the surface's velocity at a node is v_b + omega x (x - centre), the contact and friction act
// on the velocity relative to it, and a Velocity box gives its nodes that velocity (apply_boundary).
// `array` [nx, ny, nz] with `spacing` repeats a boundary nx x ny x nz times (boundary_array()).
#pragma once

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/bed_profile.h"
#include "physics/boundary_spec.h"

namespace fbar {

enum class BoundaryShape : int { Walls, Box, Sphere, Cylinder, Floor, Plane, HalfSpace, Velocity, Bathymetry, Piston, Pump };

/// The points of every Bathymetry boundary of a run, one table (a boundary holds its first point and count).
template <typename T>
struct BoundaryProfiles {
  static constexpr int kMax = 128;  ///< points over all Bathymetry boundaries (ClaymoreUW: 32 per boundary)
  int count = 0;
  T x[kMax];  ///< [m] strictly increasing within a boundary
  T y[kMax];  ///< [m] surface height at x
};

/// A boundary as kernels see it (trivially copyable; built on the host by make_boundary_params).
template <typename T>
struct BoundaryParams {
  BoundaryShape shape;
  Contact contact;
  Vec3<T> lo;          ///< [m] box min corner (at time t_begin)
  Vec3<T> hi;          ///< [m] box max corner
  Vec3<T> velocity;    ///< [m/s] v_b: the boundary moves with it, and contact acts on v - v_b
  T layer;             ///< [m] Walls: nodes this far or farther outside a face are held (1.5 dx); sloped beds: band
  T dx;                ///< [m] grid spacing (a node within dx / 128 of a face, bed or line lies on it)
  T friction_static;   ///< [-] mu_s
  T friction_dynamic;  ///< [-] mu_d
  double t_begin;      ///< [s] active window (double: compared with the simulation clock)
  double t_end;        ///< [s]
  int profile_first;   ///< Bathymetry: its first point in BoundaryProfiles
  int profile_count;   ///< Bathymetry: its number of points (>= 2)
  bool rotates;        ///< it turns: omega != 0
  Vec3<T> omega;       ///< [rad/s] angular velocity
  Vec3<T> pivot;       ///< [m] the point it turns about (at t_begin; boundary_at moves it with the boundary)
  Mat3<T> rotation;    ///< the rotation since t_begin (boundary_at sets it; the identity at t_begin)
};

/// The rotation by angle |omega| t about omega's axis (Rodrigues), in double, converted to T.
template <typename T>
FBAR_HOST_DEVICE inline Mat3<T> rotation_of(const Vec3<T>& omega, double t) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const double w[3] = {static_cast<double>(omega[0]), static_cast<double>(omega[1]), static_cast<double>(omega[2])};
  const double rate = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  Mat3<T> r{};
  for (int i = 0; i < 3; ++i) r.m[i][i] = T(1);
  if (!(rate > 0.0) || t <= 0.0) return r;
  const double k[3] = {w[0] / rate, w[1] / rate, w[2] / rate}, angle = rate * t;
  const double c = cos(angle), s = sin(angle);
  const double K[3][3] = {{0.0, -k[2], k[1]}, {k[2], 0.0, -k[0]}, {-k[1], k[0], 0.0}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)  // R = I + sin K + (1 - cos) K^2, K^2 = k k^T - I
      r.m[i][j] = static_cast<T>((i == j ? c : 0.0) + s * K[i][j] + (1.0 - c) * k[i] * k[j]);
  return r;
}

/// The boundary at time t [s]: translated by velocity (t - t_begin) (itself when it does not move).
template <typename T>
FBAR_HOST_DEVICE inline BoundaryParams<T> boundary_at(const BoundaryParams<T>& b, double t) {
  BoundaryParams<T> m = b;
  if (b.shape == BoundaryShape::Pump) return m;  // its velocity is the flow's, not its own
  const double since = t - b.t_begin;
  if (since > 0.0)
    for (int a = 0; a < 3; ++a) {
      const T shift = static_cast<T>(static_cast<double>(b.velocity[a]) * since);
      m.lo[a] += shift;
      m.hi[a] += shift;
      m.pivot[a] += shift;
    }
  if (b.rotates) m.rotation = rotation_of(b.omega, since);
  return m;
}

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

/// Contact on the velocity relative to the boundary's.
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> project_moving(const BoundaryParams<T>& b, const Vec3<T>& v, const Vec3<T>& n) {
  return project_contact(b, v - b.velocity, n) + b.velocity;
}

/// The unit normal, in the x-y plane, to the left of the line from (lo_x, lo_y) to (hi_x, hi_y) (Plane, HalfSpace).
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> line_normal(const BoundaryParams<T>& b) {
  const T ex = b.hi[0] - b.lo[0], ey = b.hi[1] - b.lo[1];
  const T length = sqrt(ex * ex + ey * ey);
  Vec3<T> n = Vec3<T>::zero();
  n[0] = -ey / length;
  n[1] = ex / length;
  return n;
}

/// Walls: the domain's faces (or the box's): nodes on a face keep out of it; nodes within the layer behind it are
/// held at the wall's velocity (as Sticky ones). Part of apply_boundary (snap: its dx / 128).
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> apply_walls(const BoundaryParams<T>& b, const Vec3<T>& x_node, Vec3<T> v, T snap) {
  using std::fabs;
  using std::sqrt;
  bool on_face = false, held = false;
  for (int a = 0; a < 3; ++a) {
    const T below = b.lo[a] - x_node[a], above = x_node[a] - b.hi[a];  // >= 0: on or outside that face
    on_face = on_face || below >= -snap || above >= -snap;
    held = held || below >= b.layer - snap || above >= b.layer - snap;
  }
  if (!on_face) return v;
  if (held || b.contact == Contact::Sticky) return b.velocity;
  for (int a = 0; a < 3; ++a) {
    Vec3<T> n = Vec3<T>::zero();
    if (b.lo[a] - x_node[a] >= -snap) {
      n[a] = T(1);
      v = project_moving(b, v, n);
    }
    if (x_node[a] - b.hi[a] >= -snap) {
      n[a] = T(-1);
      v = project_moving(b, v, n);
    }
  }
  return v;
}

/// Cylinder along y: nodes inside keep out through the nearest of its side, top and bottom. Part of apply_boundary (snap: its dx / 128).
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> apply_cylinder(const BoundaryParams<T>& b, const Vec3<T>& x_node, Vec3<T> v, T snap) {
  using std::fabs;
  using std::sqrt;
  if (x_node[1] < b.lo[1] - snap || x_node[1] > b.hi[1] + snap) return v;
  const T radius = (b.hi[0] - b.lo[0]) * T(0.5);
  const T dx = x_node[0] - (b.lo[0] + b.hi[0]) * T(0.5);
  const T dz = x_node[2] - (b.lo[2] + b.hi[2]) * T(0.5);
  const T r = sqrt(dx * dx + dz * dz);
  if (r > radius) return v;
  Vec3<T> n = Vec3<T>::zero();
  const T to_side = radius - r, to_bottom = x_node[1] - b.lo[1], to_top = b.hi[1] - x_node[1];
  if (to_top <= to_side && to_top <= to_bottom) {
    n[1] = T(1);
  } else if (to_bottom <= to_side) {
    n[1] = T(-1);
  } else if (r > T(0)) {
    n[0] = dx / r;
    n[2] = dz / r;
  } else {
    n[0] = T(1);
  }
  return project_moving(b, v, n);
}

/// Bathymetry: nodes at or below the bed profile (within the band above a sloped stretch) keep out along the normal of
/// their segment. Part of apply_boundary (snap: its dx / 128).
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> apply_bathymetry(const BoundaryParams<T>& b, const Vec3<T>& x_node, Vec3<T> v, T snap,
                                                 const BoundaryProfiles<T>* profiles) {
  using std::fabs;
  using std::sqrt;
  if (!profiles || b.profile_count < 2) return v;
  // The segment over x (the first / last one extended flat beyond the ends), its height and normal.
  const T* px = profiles->x + b.profile_first;
  const T* py = profiles->y + b.profile_first;
  const int last = b.profile_count - 1;
  int i;
  bool on_segment;
  // A node within dx / 128 of a breakpoint stands on it (the segment right of it, the same in both precisions).
  T xn = x_node[0];
  T surface = bed_surface(px, py, b.profile_count, xn, i, on_segment);
  const int near = (i + 1 <= last && fabs(xn - px[i + 1]) <= snap) ? i + 1 : (fabs(xn - px[i]) <= snap ? i : -1);
  if (near >= 0 && xn != px[near]) {
    xn = px[near];
    surface = bed_surface(px, py, b.profile_count, xn, i, on_segment);
  }
  T ex = T(1), ey = T(0);
  if (on_segment) {
    ex = px[i + 1] - px[i];
    ey = py[i + 1] - py[i];
  }
  // Within b.layer (kBedLayerCells) of a sloped segment the bed holds a band of nodes up to b.layer above it; a
  // flat stretch, aligned with the grid, needs none. The segments reaching into [x - layer, x + layer] are the
  // ones next to segment i: scanned outwards from it. A segment that ends within dx / 128 of layer away does
  // not reach the node (one answer in both precisions).
  bool sloped = false;
  for (int j = i; j >= 0 && !sloped && px[j + 1] > xn - b.layer + snap; --j)
    sloped = py[j + 1] != py[j] && px[j] < xn + b.layer - snap;
  for (int j = i + 1; j < last && !sloped && px[j] < xn + b.layer - snap; ++j) sloped = py[j + 1] != py[j];
  if (x_node[1] > surface + (sloped ? b.layer : T(0)) + snap) return v;  // above the bed: the material's side
  const T length = sqrt(ex * ex + ey * ey);
  Vec3<T> n = Vec3<T>::zero();
  n[0] = -ey / length;
  n[1] = ex / length;
  return project_moving(b, v, n);
}

/// The velocity of the grid node at x_node [m] after this boundary at rest in its own frame (apply_boundary turns
/// a rotating one into it).
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> apply_boundary_unrotated(const BoundaryParams<T>& b, const Vec3<T>& x_node, Vec3<T> v,
                                                         const BoundaryProfiles<T>* profiles) {
  using std::fabs;
  using std::sqrt;
  // A node within dx / 128 of a face, a bed or a line lies on it, whatever the round-off of its position and of the
  // scene's numbers (6 x 0.02 against 0.02 + 0.1 decided a flat bed's node row differently in float and double).
  const T snap = b.dx * T(1.0 / 128);
  const auto inside_box = [&] {
    for (int a = 0; a < 3; ++a)
      if (x_node[a] < b.lo[a] - snap || x_node[a] > b.hi[a] + snap) return false;
    return true;
  };
  switch (b.shape) {
    case BoundaryShape::Walls:
      return apply_walls(b, x_node, v, snap);
    case BoundaryShape::Box: {
      if (!inside_box()) return v;
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
      return project_moving(b, v, n);
    }
    case BoundaryShape::Sphere: {
      const T radius = (b.hi[0] - b.lo[0]) * T(0.5);
      const Vec3<T> d = x_node - (b.lo + b.hi) * T(0.5);
      const T r = sqrt(dot(d, d));
      if (r > radius) return v;
      Vec3<T> n = Vec3<T>::zero();
      if (r > T(0))
        n = d * (T(1) / r);
      else
        n[1] = T(1);  // the center: straight up
      return project_moving(b, v, n);
    }
    case BoundaryShape::Cylinder:
      return apply_cylinder(b, x_node, v, snap);
    case BoundaryShape::Floor: {
      if (!inside_box()) return v;
      Vec3<T> n = Vec3<T>::zero();
      n[1] = T(1);
      return project_moving(b, v, n);
    }
    case BoundaryShape::Plane: {
      if (x_node[0] < b.lo[0] - snap || x_node[0] >= b.hi[0] - snap) return v;
      const Vec3<T> n = line_normal(b);
      const T side = (x_node[0] - b.lo[0]) * n[0] + (x_node[1] - b.lo[1]) * n[1];
      const bool sloped = b.hi[1] != b.lo[1];
      if (side > (sloped ? b.layer : T(0)) + snap) return v;  // above the line (and its band, kBedLayerCells)
      return project_moving(b, v, n);
    }
    case BoundaryShape::HalfSpace: {
      if (x_node[2] < b.lo[2] - snap || x_node[2] > b.hi[2] + snap) return v;
      const Vec3<T> n = line_normal(b);
      const T side = (x_node[0] - b.lo[0]) * n[0] + (x_node[1] - b.lo[1]) * n[1];
      if (side > snap) return v;  // the material's side
      return project_moving(b, v, n);
    }
    case BoundaryShape::Velocity:
      return inside_box() ? b.velocity : v;
    case BoundaryShape::Piston: {
      if (!inside_box()) return v;
      Vec3<T> n = Vec3<T>::zero();
      n[0] = T(1);
      return project_moving(b, v, n);
    }
    case BoundaryShape::Pump: {
      if (!inside_box()) return v;
      for (int a = 0; a < 3; ++a) {
        const T u = b.velocity[a];
        if (u > T(0) && v[a] < u) v[a] = u;
        if (u < T(0) && v[a] > u) v[a] = u;
      }
      return v;
    }
    case BoundaryShape::Bathymetry:
      return apply_bathymetry(b, x_node, v, snap, profiles);
  }
  return v;
}

/// The velocity of the grid node at x_node [m] after this boundary (assumed active; give boundary_at(b, t)). A
/// boundary that turns is its shape at t_begin's orientation, turned by `rotation` about `pivot`: the node is taken
/// into that frame, the contact acts there on the velocity relative to the surface's, v_b + omega x (x - pivot), and
/// the result is turned back.
template <typename T>
FBAR_HOST_DEVICE inline Vec3<T> apply_boundary(const BoundaryParams<T>& b, const Vec3<T>& x_node, Vec3<T> v,
                                               const BoundaryProfiles<T>* profiles = nullptr) {
  if (!b.rotates) return apply_boundary_unrotated(b, x_node, v, profiles);
  const Vec3<T> r = x_node - b.pivot;
  const Vec3<T> surface = b.velocity + cross(b.omega, r);
  const Mat3<T> back = transpose(b.rotation);
  BoundaryParams<T> still = b;
  still.velocity = Vec3<T>::zero();
  const Vec3<T> relative = back * (v - surface);
  const Vec3<T> out = apply_boundary_unrotated(still, b.pivot + back * r, relative, profiles);
  bool untouched = true;  // a node the boundary does not act on keeps its velocity exactly (no round trip)
  for (int a = 0; a < 3; ++a) untouched = untouched && out[a] == relative[a];
  return untouched ? v : b.rotation * out + surface;
}

/// Grid nodes up to this many cells above a sloped bed (Bathymetry segments and Plane lines that are not
/// horizontal) belong to it; material resting on a slope therefore sits up to a cell higher. Without the band, nodes
/// just above a slope that the water's pressure pushes into the bed's staircase are free, and still water on a Slip
/// 1:5 slope grows an up-slope current at the bed (0.4 m/s in 2 s at dx = 0.1 m); with it the water stays at rest
/// (below 0.01 m/s; tests/engine/cpu/test_cpu_engine.cpp Boundary.StillWaterOnASlopeStaysStill). ClaymoreUW's bed
/// band also reaches one cell above the bed.
constexpr double kBedLayerCells = 1.0;

/// Particles may stand up to this many cells outside simulation.domain before they count as having left it, as in
/// ClaymoreUW, whose grid starts 8 cells before the domain's origin (settings.cuh g_offset): Walls on the domain's
/// faces hold material with their face node plane and the planes outside it (ClaymoreUW's nodes), so the outermost
/// particles can cross a face by up to half a cell, and scenes anchor bodies in boundaries below the domain (ClaymoreUW's
/// YIELD scene clamps a plate's foot in a Sticky Box 1 to 3 cells below the floor).
constexpr double kDomainMarginCells = 8.0;

/// Is the particle position x [m] inside simulation.domain [0, domain] widened by kDomainMarginCells cells of dx?
/// Whether boundary b acts on the node at x_node at all (some velocity, or its opposite, comes out changed): the
/// node's walls hold water as well as material (seepage.cuh: a held node is never drained).
template <typename T>
FBAR_HOST_DEVICE inline bool boundary_holds(const BoundaryParams<T>& b, const Vec3<T>& x_node,
                                            const BoundaryProfiles<T>* profiles = nullptr) {
  const Vec3<T> probe{{T(0.5), T(1), T(0.75)}};
  for (int sign = -1; sign <= 1; sign += 2) {
    const Vec3<T> v = probe * T(sign);
    const Vec3<T> out = apply_boundary(b, x_node, v, profiles);
    if (out[0] != v[0] || out[1] != v[1] || out[2] != v[2]) return true;
  }
  return false;
}

template <typename T>
FBAR_HOST_DEVICE inline bool inside_domain(const Vec3<T>& x, const Vec3<T>& domain, T dx) {
  const T margin = static_cast<T>(kDomainMarginCells) * dx;
  bool inside = true;
  for (int a = 0; a < 3; ++a) inside = inside && x[a] >= -margin && x[a] <= domain[a] + margin;
  return inside;
}

/// The copies of a boundary that `array` [nx, ny, nz] and `spacing` [m] ask for (ClaymoreUW's boundary arrays):
/// copy (i, j, k) is translated by (i sx, j sy, k sz), in i-major order; [1, 1, 1] gives the boundary itself.
template <typename T>
inline std::vector<BoundaryParams<T>> boundary_array(const BoundaryParams<T>& b, const BoundarySpec& spec) {
  std::vector<BoundaryParams<T>> out;
  for (int i = 0; i < spec.array[0]; ++i)
    for (int j = 0; j < spec.array[1]; ++j)
      for (int k = 0; k < spec.array[2]; ++k) {
        BoundaryParams<T> c = b;
        const int n[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          const T shift = static_cast<T>(n[a] * spec.spacing[a]);
          c.lo[a] += shift;
          c.hi[a] += shift;
          c.pivot[a] += shift;  // each copy turns about its own centre
        }
        out.push_back(c);
      }
  return out;
}

/// Builds the kernel parameters of a generic boundary (expand_boundary() turns facility objects into generic ones)
/// on the host (dx [m] the grid spacing, domain [m] its extent); a Bathymetry's points go to BoundaryProfiles (RunConstants). Returns false and an explanation in
/// `error` for a facility object or a boundary without the extents it needs, never ignoring a key. Arrays: boundary_array();
/// motion files: MotionPath (RunConstants::boundary_at_time).
template <typename T>
inline bool make_boundary_params(const BoundarySpec& spec, double dx, const std::array<double, 3>& domain,
                                 BoundaryParams<T>& out, std::string& error) {
  switch (spec.object) {
    case BoundaryObject::Walls: out.shape = BoundaryShape::Walls; break;
    case BoundaryObject::Box: out.shape = BoundaryShape::Box; break;
    case BoundaryObject::Sphere: out.shape = BoundaryShape::Sphere; break;
    case BoundaryObject::Cylinder: out.shape = BoundaryShape::Cylinder; break;
    case BoundaryObject::Floor: out.shape = BoundaryShape::Floor; break;
    case BoundaryObject::Plane: out.shape = BoundaryShape::Plane; break;
    case BoundaryObject::HalfSpace: out.shape = BoundaryShape::HalfSpace; break;
    case BoundaryObject::Velocity: out.shape = BoundaryShape::Velocity; break;
    case BoundaryObject::Bathymetry: out.shape = BoundaryShape::Bathymetry; break;
    case BoundaryObject::Piston: out.shape = BoundaryShape::Piston; break;
    case BoundaryObject::Pump: out.shape = BoundaryShape::Pump; break;
    default:
      error = "a facility object stands for generic pieces: expand it with expand_boundary() (scene/facilities.h) "
              "first";
      return false;
  }
  out.profile_first = 0;
  out.profile_count = 0;
  if (spec.object == BoundaryObject::Bathymetry && spec.bathymetry.size() < 2) {
    error = "a Bathymetry boundary needs at least two bathymetry points [[x, y], ...]";
    return false;
  }
  bool has_box = true;
  for (int a = 0; a < 3; ++a) has_box = has_box && spec.domain_end[a] > spec.domain_start[a];
  if (spec.object == BoundaryObject::Bathymetry) {
    has_box = false;  // the profile spans the domain; domain_start / domain_end are not used
  } else if (spec.object == BoundaryObject::Plane) {
    has_box = spec.domain_end[0] > spec.domain_start[0];  // a line in x, y (it may descend)
    if (!has_box) {
      error = "a Plane needs domain_end[0] > domain_start[0]";
      return false;
    }
  } else if (spec.object == BoundaryObject::HalfSpace) {
    has_box = spec.domain_end[2] >= spec.domain_start[2] &&
              (spec.domain_end[0] != spec.domain_start[0] || spec.domain_end[1] != spec.domain_start[1]);
    if (!has_box) {
      error = "a HalfSpace needs two distinct points in x, y and domain_end[2] >= domain_start[2]";
      return false;
    }
  } else if (spec.object != BoundaryObject::Walls && !has_box) {
    error = "this boundary object needs domain_end > domain_start in every axis";
    return false;
  }
  out.contact = spec.contact;
  for (int a = 0; a < 3; ++a) {
    out.lo[a] = static_cast<T>(has_box ? spec.domain_start[a] : 0.0);
    out.hi[a] = static_cast<T>(has_box ? spec.domain_end[a] : domain[a]);
    out.velocity[a] = static_cast<T>(spec.velocity[a]);
  }
  out.layer = static_cast<T>(1.5 * dx);
  out.dx = static_cast<T>(dx);
  if (spec.object == BoundaryObject::Bathymetry || spec.object == BoundaryObject::Plane)
    out.layer = static_cast<T>(kBedLayerCells * dx);
  out.friction_static = static_cast<T>(spec.friction_static);
  out.friction_dynamic = static_cast<T>(spec.friction_dynamic);
  out.t_begin = spec.time[0];
  out.t_end = spec.time[1];
  out.rotates = spec.angular_velocity != std::array<double, 3>{0.0, 0.0, 0.0};
  for (int a = 0; a < 3; ++a) {
    out.omega[a] = static_cast<T>(spec.angular_velocity[a]);
    out.pivot[a] = static_cast<T>(spec.rotation_center[a]);
  }
  out.rotation = rotation_of(out.omega, 0.0);
  if (out.rotates && out.shape == BoundaryShape::Pump) {
    error = "a Pump drives a flow and does not turn (angular_velocity must be 0)";
    return false;
  }
  return true;
}

}  // namespace fbar
