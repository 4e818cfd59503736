// Helpers of the validation tests: build reference-problem Scenes in code and reduce time series (SI units).
//
// Conventions of the CPU engine these helpers rely on (boundary.cuh, geometry.h):
//  * A Walls boundary acts on ClaymoreUW's nodes (boundary.cuh): the face's node plane F and every node outside it
//    (the planes 1.5 dx or more outside are held still). Two planes matter for a body against the wall:
//      F - dx/2  the ZERO-VELOCITY plane. The first free node plane F + dx has its quadratic B-spline support
//                starting there, so the grid velocity's normal component vanishes IDENTICALLY below it. A body
//                placed against it gives every free node a complete support: a fluid at rest is in exact discrete
//                equilibrium. But its first particle layer (at F - dx/4 with 2 particles per cell) puts 97 % of its
//                normal-direction weight on wall nodes: its normal strain is frozen and its pressure barely reaches
//                a free node. Such a layer behaves as part of the wall: under a stress-free start it never takes
//                its share of the load (-82 % pressure in the bottom row of the hydrostatic column), and a fluid
//                layer along a vertical wall stands on its own pressure instead of draining (the dam break's back
//                wall keeps a one-particle film at full height).
//      F         the LAST WALL NODE plane, the box face itself: material filling the box to its faces, as scenes
//                written for ClaymoreUW place it. The first particle layer (F + dx/4) puts 28 % of its weight on the
//                free node F + dx, enough to drain and load normally (dam-break residual height follows the data),
//                but the node F + dx lacks the half cell [F - dx/2, F] of its support, and a fluid's bottom cell
//                carries about +10 % excess pressure at every resolution (+11 % at rest from an equilibrium start,
//                +9.5 % after a stress-free start).
//    These are limitations of node-layer walls with C1 quadratic B-splines (the boundary treatment decides spatial
//    convergence near walls: Steffen, Wallstedt, Guilkey, Kirby & Berzins 2008, CMES 31(2)), measured and reported
//    in docs/validation.md. Each test names the placement it uses and why; wall_box() takes the planes of the
//    material faces and the placement, and returns the Walls box. Its faces always fall on node planes.
//  * A Walls box far away along an axis never acts along it: thin slabs (2D problems in 3D) use one box whose
//    faces along the slab's thin axis are active and whose other faces lie outside the domain.
//  * Bodies are sampled on the grid-aligned sub-lattice x_i = (i + 1/2) dx / n per axis (ppc = n^3), so a box whose
//    faces lie on node planes or half-way between them holds exactly n particles per cell along each axis.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <vector>

#include "scene/scene.h"

namespace fbar::validation {

constexpr double kPi = 3.14159265358979323846;

inline Real3 r3(double x, double y, double z) { return Real3{x, y, z}; }

/// A scene without bodies or boundaries: domain [0, domain] [m], grid spacing dx [m], gravity [m/s^2], double
/// precision, step bounded by the CFL condition only (default_dt far above it).
inline Scene make_scene(Real3 domain, double dx, Real3 gravity) {
  Scene s;
  s.simulation.domain = domain;
  s.simulation.dx = dx;
  s.simulation.default_dt = 1.0;
  s.simulation.gravity = gravity;
  s.simulation.precision = Precision::Double;
  s.simulation.on_failure = OnFailure::Stop;  // a validation run must not repair itself silently
  return s;
}

/// An APIC / MLS-MPM body (no ASFLIP, no F-bar) without geometry, sampled at `ppc` particles per cell.
inline BodySpec make_body(Constitutive law, double rho, double ppc = 8.0, double cfl = 0.5) {
  BodySpec b;
  b.material.law = law;
  b.material.rho = rho;
  b.material.ppc = ppc;
  b.material.cfl = cfl;
  b.algorithm.use_asflip = false;
  b.algorithm.use_fbar = false;
  b.output_attribs = {"ID"};
  return b;
}

/// Transfer scheme of a run: APIC (alpha = beta = 0), PIC-FLIP blend (alpha), ASFLIP (alpha, beta_min, beta_max).
struct Scheme {
  const char* name;
  double alpha, beta_min, beta_max;
};
inline constexpr Scheme kApic{"APIC", 0, 0, 0};
/// The four schemes the validation tests and the study runner compare.
inline constexpr Scheme kTransferSchemes[] = {
    kApic, {"PIC-FLIP 0.95", 0.95, 0, 0}, {"FLIP", 1.0, 0, 0}, {"ASFLIP", 0.95, 0.0, 0.2}};

/// Runs a body with `scheme` (the ASFLIP keys; all zero is plain APIC, which needs no ASFLIP channels).
inline void set_scheme(BodySpec& body, const Scheme& scheme) {
  body.algorithm.use_asflip = true;
  body.algorithm.asflip_alpha = scheme.alpha;
  body.algorithm.asflip_beta_min = scheme.beta_min;
  body.algorithm.asflip_beta_max = scheme.beta_max;
}

/// A JFluid body: rho [kg/m^3], bulk modulus K [Pa], Tait exponent gamma [-], dynamic viscosity [Pa s].
inline BodySpec jfluid_body(double rho, double bulk_modulus, double gamma, double viscosity, double ppc = 8.0,
                            double cfl = 0.5) {
  BodySpec b = make_body(Constitutive::JFluid, rho, ppc, cfl);
  b.material.bulk_modulus = bulk_modulus;
  b.material.gamma = gamma;
  b.material.viscosity = viscosity;
  return b;
}

/// A FixedCorotated body: rho [kg/m^3], Young's modulus E [Pa], Poisson's ratio nu [-].
inline BodySpec fixed_corotated_body(double rho, double youngs_modulus, double poisson_ratio, double ppc = 8.0,
                                     double cfl = 0.5) {
  BodySpec b = make_body(Constitutive::FixedCorotated, rho, ppc, cfl);
  b.material.youngs_modulus = youngs_modulus;
  b.material.poisson_ratio = poisson_ratio;
  return b;
}

/// Adds the box [offset, offset + span] [m] to a body's geometry.
inline void add_box(BodySpec& body, Real3 offset, Real3 span) {
  GeometrySpec g;
  g.object = GeometryObject::Box;
  g.offset = offset;
  g.span = span;
  body.geometry.push_back(g);
}

/// Adds a cylinder of `radius` [m] along z from z0 to z0 + length, centred at (cx, cy) [m] (a disk of a slab).
inline void add_disk(BodySpec& body, double cx, double cy, double radius, double z0, double length) {
  GeometrySpec g;
  g.object = GeometryObject::Cylinder;
  g.axis = 2;
  g.radius = radius;
  g.offset = r3(cx - radius, cy - radius, z0);  // geometry.h: offset is the bounding box's min corner
  g.span = r3(2 * radius, 2 * radius, length);
  body.geometry.push_back(g);
}

/// Far enough to never act: a Walls face this far outside the domain has no grid node on or beyond it.
constexpr double kFar = 1e3;

/// Where a body's face sits relative to the Walls box that holds it (see the file comment).
enum class WallFit {
  ZeroVelocityPlane,  ///< material face at F - dx/2: exact resting equilibrium, frozen first particle layer
  LastWallNodePlane,  ///< material face at F (ClaymoreUW's scenes): draining first layer, ~+10 % bottom cell
};

/// Distance [m] from the box face F to the material face for a placement (inwards positive).
inline double wall_inset(WallFit fit, double dx) { return fit == WallFit::ZeroVelocityPlane ? -0.5 * dx : 0.0; }

/// True when c [m] lies on a grid node plane, k dx.
inline bool is_node_plane(double c, double dx) { return std::fabs(c / dx - std::round(c / dx)) < 1e-9; }

/// A Walls boundary holding material whose faces are the planes `lo` / `hi` [m], placed as `fit` says: the box is
/// wall_inset() outside them. Give -kFar / kFar for an axis the walls must not constrain. Throws
/// std::invalid_argument when a box face would not fall on a node plane (material faces at (k + 1/2) dx for
/// ZeroVelocityPlane, k dx for LastWallNodePlane).
inline BoundarySpec wall_box(Contact contact, Real3 lo, Real3 hi, double dx, WallFit fit) {
  BoundarySpec w;
  w.object = BoundaryObject::Walls;
  w.contact = contact;
  const double inset = wall_inset(fit, dx);
  for (int a = 0; a < 3; ++a) {
    const bool free_lo = lo[a] <= -kFar, free_hi = hi[a] >= kFar;
    w.domain_start[a] = free_lo ? -kFar : lo[a] - inset;
    w.domain_end[a] = free_hi ? kFar : hi[a] + inset;
    if ((!free_lo && !is_node_plane(w.domain_start[a], dx)) || (!free_hi && !is_node_plane(w.domain_end[a], dx)))
      throw std::invalid_argument("wall_box: the material faces do not put the Walls box faces on node planes");
  }
  return w;
}

// ------------------------------------------------------------------------------------------- time series

/// Times [s] where the sampled series v(t) changes sign, by linear interpolation between samples (a sample equal to 0
/// counts once). times and values have equal length.
inline std::vector<double> zero_crossings(const std::vector<double>& times, const std::vector<double>& values) {
  std::vector<double> out;
  for (std::size_t i = 1; i < times.size(); ++i) {
    const double a = values[i - 1], b = values[i];
    if ((a < 0.0 && b >= 0.0) || (a > 0.0 && b <= 0.0)) {
      const double s = a / (a - b);
      out.push_back(times[i - 1] + s * (times[i] - times[i - 1]));
    }
  }
  return out;
}

/// First time [s] at which the sampled series reaches `level` from below (linear interpolation); NaN if never.
inline double first_reach(const std::vector<double>& times, const std::vector<double>& values, double level) {
  if (!times.empty() && values[0] >= level) return times[0];
  for (std::size_t i = 1; i < times.size(); ++i)
    if (values[i - 1] < level && values[i] >= level)
      return times[i - 1] + (level - values[i - 1]) / (values[i] - values[i - 1]) * (times[i] - times[i - 1]);
  return std::numeric_limits<double>::quiet_NaN();
}

/// Linear interpolation of the table (xs ascending, ys) at x; clamped to the end values outside the table.
inline double interpolate(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  const std::size_t i = static_cast<std::size_t>(std::upper_bound(xs.begin(), xs.end(), x) - xs.begin());
  const double s = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys[i - 1] + s * (ys[i] - ys[i - 1]);
}

/// Wall-clock stopwatch for the runtimes the report quotes [s].
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace fbar::validation
