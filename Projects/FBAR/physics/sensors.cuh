// Grid sensors (load cells) and particle sensors (wave gauges), host and device: the value a node or a particle
// contributes to a sensor and the running reduction of one sample. Both engines evaluate grid_sensor_value() in their
// grid update, on the nodes they own, and particle sensors on their particles (frame_value() of physics/frame_columns.h,
// the formula frames use); the run loop reduces the ranks' SensorAccum (io/sensor_recorder.h) into one value per
// sensor and sample.
//
// What a node contributes (node of mass m > 0 whose position lies in [domain_start, domain_end], both ends included).
// p is the node's momentum as P2G left it (m v of the particles plus the impulse dt f_int of their stresses), before
// gravity and the boundary projections of the step; v* = p/m + dt g its velocity before the projections, v after them.
// ClaymoreUW's attributes read the P2G state, as ClaymoreUW's grid sensors do (mgmpm_kernels.cuh,
// retrieve_selected_grid_cells): a scene written for ClaymoreUW reads the same numbers.
//   Force          [N]     p / dt = m v + f_int: at nodes a wall holds at rest, the load the material puts on the wall
//                          (a wall pushed by water in +x reads positive along X); at free nodes it also counts the
//                          material's momentum over dt, which is large wherever it moves (ClaymoreUW's meaning).
//   Velocity       [m/s]   p / m
//   Momentum       [kg m/s] p
//   Mass           [kg]    m (no direction)
// fbar's own attributes read what the boundaries did:
//   BoundaryForce  [N]     m (v* - v) / dt: the force the material exerts on the boundaries at the node, i.e. minus
//                          the momentum change the boundary projections cause divided by dt (zero at nodes no
//                          boundary touches); gravity included. Along a wall's normal at its held nodes it equals Force.
//   Acceleration   [m/s^2] (v* - v) / dt: that force per unit node mass.
// The material's volume at the node (every body's particles, on the steps a sensor samples; ClaymoreUW's grid channels
// 7 and 8, mgmpm_kernels.cuh retrieve_selected_grid_cells):
//   Volume         [m^3]   sum_p w_ip V_p, V_p = V0_p J_p the particle's volume
//   JBar           [-]     the node's JBar: sum_p w_ip V_p JBar_p / sum_p w_ip V_p, the volume-weighted mean of its
//                          particles' JBar (nodal F-bar's stored JBar; J for the other bodies, as the JBar attribute)
// The pore water of saturated (CoupledUP) bodies, at nodes that carry some (other nodes add nothing to these):
//   MassWater      [kg]    sum_p w_ip n rhow V0_p (ClaymoreUW's masw)
//   PorePressure   [Pa]    the node's pore pressure p_i (volume-weighted mean of its particles'; 0 at drained nodes)
// A vector quantity is projected on the sensor's unit direction; a direction with a sign keeps only that side of the
// projection, as a magnitude (ClaymoreUW's X+ / X-): X+ gives max(q.x, 0), X- gives max(-q.x, 0).
#pragma once

#include <cmath>
#include <limits>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/frame_columns.h"

namespace fbar {

enum class GridSensorQuantity : int {
  Force, Acceleration, Momentum, Velocity, Mass, BoundaryForce, MassWater, PorePressure, Volume, JBar
};

/// Whether a sensor reads the nodes' volume sums (engines sum them on the steps such a sensor samples).
FBAR_HOST_DEVICE inline bool grid_sensor_reads_volume(GridSensorQuantity q) {
  return q == GridSensorQuantity::Volume || q == GridSensorQuantity::JBar;
}

/// One grid sensor as the grid update sees it (trivially copyable; built by make_grid_sensor_params).
template <typename T>
struct GridSensorParams {
  GridSensorQuantity quantity = GridSensorQuantity::Mass;
  Vec3<T> direction{};  ///< unit vector (vector quantities)
  int sign = 0;         ///< +1: positive side only, -1: negative side only (as a magnitude), 0: signed projection
  Vec3<T> lo{};         ///< [m] box, inclusive
  Vec3<T> hi{};         ///< [m]
};

/// The grid sensors of one grid update (a kernel parameter).
template <typename T>
struct GridSensorSet {
  static constexpr int kMax = 16;
  int count = 0;
  GridSensorParams<T> s[kMax];
};

/// One particle sensor: the attribute it reduces (a frame column) and its box.
template <typename T>
struct ParticleSensorParams {
  FrameColumn column;
  Vec3<T> lo{};  ///< [m] box, inclusive
  Vec3<T> hi{};
};

/// Whether a particle sensor's attribute reads the particle's velocity or velocity gradient (the stress of a rate
/// law does): the GPU engine then records v and C on the steps that end on its sample times.
FBAR_HOST_DEVICE inline bool particle_sensor_reads_velocity(const FrameColumn& c) {
  return c.quantity == FrameQuantity::Velocity || c.quantity == FrameQuantity::VelocityMagnitude ||
         frame_quantity_reads_stress(c.quantity);
}

template <typename T>
struct ParticleSensorSet {
  static constexpr int kMax = 16;
  int count = 0;
  ParticleSensorParams<T> s[kMax];
};

/// The particles one body's tracker follows (bodies[].track_particle_id, track_attribs): IDs sorted ascending and
/// the attributes read of each. Particles keep their ID through bin reordering and migration between ranks, so a
/// kernel finds them by ID wherever they are.
struct TrackerSet {
  static constexpr int kMaxIds = 64;      ///< ClaymoreUW's limit
  static constexpr int kMaxAttribs = 16;
  int ids = 0;
  int id[kMaxIds];
  int attribs = 0;
  FrameColumn column[kMaxAttribs];
};

/// Index of `id` in the tracker's sorted IDs, or -1.
FBAR_HOST_DEVICE inline int tracker_index(const TrackerSet& t, int id) {
  int lo = 0, hi = t.ids - 1;
  while (lo <= hi) {
    const int mid = (lo + hi) / 2;
    if (t.id[mid] == id) return mid;
    if (t.id[mid] < id) lo = mid + 1;
    else hi = mid - 1;
  }
  return -1;
}

/// An order-free sum of doubles: each value rounded to a multiple of 2^-100 and added as an integer, held in six
/// signed 64-bit words of 32-bit chunks (word k weighs 2^(32 k - 100); a value adds a chunk of magnitude below 2^32
/// to each word, with its sign, so no word carries: 2^31 values fit). Any order of additions and
/// merges, on one thread, several CUDA blocks or several ranks, gives the same words, so the same value() bits.
/// Resolution 2^-100 ~ 7.9e-31, range 2^123 ~ 1e37 (a sensor's sums: forces, masses, pressures, their squares).
/// Non-finite values are summed apart as doubles (inf, -inf and NaN add order-free too) and win.
struct ExactSum {
  static constexpr int kWords = 6;
  static constexpr int kLowBit = -100;
  long long word[kWords] = {0, 0, 0, 0, 0, 0};
  double special = 0.0;  ///< the sum of the non-finite values (0: none)

  FBAR_HOST_DEVICE void add(double v) {
    if (!(v - v == 0.0)) {  // inf or NaN
      special += v;
      return;
    }
    // |v| / 2^-100 as an integer, cut into 32-bit chunks from the top; every step is exact (the magnitude has at most
    // 53 significant bits and each step removes the top ones), and the sign goes onto every chunk (signed words).
    const long long sign = v < 0.0 ? -1 : 1;
    double r = rint(ldexp(fabs(v), -kLowBit));
    for (int k = kWords - 1; k > 0; --k) {
      const double chunk = floor(ldexp(r, -32 * k));
      r -= ldexp(chunk, 32 * k);  // in [0, 2^(32 k))
      word[k] += sign * static_cast<long long>(chunk);
    }
    word[0] += sign * static_cast<long long>(r);
  }
  FBAR_HOST_DEVICE void merge(const ExactSum& o) {
    for (int k = 0; k < kWords; ++k) word[k] += o.word[k];
    special += o.special;
  }
  /// The sum, rounded (the words added from the top: a fixed order).
  FBAR_HOST_DEVICE double value() const {
    if (special != 0.0 || special != special) return special;
    double s = 0.0;
    for (int k = kWords - 1; k >= 0; --k) s += ldexp(static_cast<double>(word[k]), 32 * k + kLowBit);
    return s;
  }
};

/// Running reduction of one sensor's values in one sample: Sum, Count, Average, STDEV, Max and Min follow from it.
/// Order-free (ExactSum; count, max and min are): a sample's bits do not depend on the order the nodes or particles
/// are visited in, nor on how many ranks share them.
struct SensorAccum {
  ExactSum sum;
  ExactSum sum_sq;
  double count = 0.0;
  double max = -std::numeric_limits<double>::infinity();
  double min = std::numeric_limits<double>::infinity();

  FBAR_HOST_DEVICE void add(double v) {
    sum.add(v);
    sum_sq.add(v * v);
    count += 1.0;
    max = v > max ? v : max;
    min = v < min ? v : min;
  }
  FBAR_HOST_DEVICE void merge(const SensorAccum& o) {
    sum.merge(o.sum);
    sum_sq.merge(o.sum_sq);
    count += o.count;
    max = o.max > max ? o.max : max;
    min = o.min < min ? o.min : min;
  }
};

template <typename T>
FBAR_HOST_DEVICE inline bool sensor_box_contains(const Vec3<T>& lo, const Vec3<T>& hi, const Vec3<T>& x) {
  return x[0] >= lo[0] && x[0] <= hi[0] && x[1] >= lo[1] && x[1] <= hi[1] && x[2] >= lo[2] && x[2] <= hi[2];
}

/// A vector quantity seen by a sensor: its projection on the direction, one-sided when sign != 0.
template <typename T>
FBAR_HOST_DEVICE inline T sensor_projection(const GridSensorParams<T>& s, const Vec3<T>& q) {
  const T p = dot(q, s.direction);
  if (s.sign > 0) return p > T(0) ? p : T(0);
  if (s.sign < 0) return p < T(0) ? -p : T(0);
  return p;
}

/// What a grid sensor reads of one node: its mass, its P2G momentum and its velocity before and after the boundary
/// projections of a step of dt.
template <typename T>
struct GridNodeSample {
  T m;             ///< [kg] mass (> 0)
  Vec3<T> p;       ///< [kg m/s] momentum from P2G (m v + dt f_int), before gravity and boundaries
  Vec3<T> v_free;  ///< [m/s] v* = p/m + dt g
  Vec3<T> v;       ///< [m/s] after the boundary projections
  T dt;            ///< [s]
  T water_mass = T(0);     ///< [kg] pore water at the node (0: none, the pore sensors skip the node)
  T pore_pressure = T(0);  ///< [Pa] the node's pore pressure
  T volume = T(0);         ///< [m^3] sum_p w_ip V_p (summed only when a Volume or JBar sensor samples)
  T volume_jbar = T(0);    ///< [m^3] sum_p w_ip V_p (1 - JBar_p)
};

/// What a node (mass m > 0 inside the sensor's box) contributes.
template <typename T>
FBAR_HOST_DEVICE inline T grid_sensor_value(const GridSensorParams<T>& s, const GridNodeSample<T>& n) {
  switch (s.quantity) {
    case GridSensorQuantity::Force: return sensor_projection(s, n.p / n.dt);
    case GridSensorQuantity::BoundaryForce: return sensor_projection(s, (n.v_free - n.v) * (n.m / n.dt));
    case GridSensorQuantity::Acceleration: return sensor_projection(s, (n.v_free - n.v) / n.dt);
    case GridSensorQuantity::Momentum: return sensor_projection(s, n.p);
    case GridSensorQuantity::Velocity: return sensor_projection(s, n.p / n.m);
    case GridSensorQuantity::Mass: return n.m;
    case GridSensorQuantity::MassWater: return n.water_mass;
    case GridSensorQuantity::PorePressure: return n.pore_pressure;
    case GridSensorQuantity::Volume: return n.volume;
    case GridSensorQuantity::JBar: return T(1) - n.volume_jbar / n.volume;
  }
  return T(0);
}

/// Whether sensor s reads a node (mass > 0): every node, but the pore sensors only nodes that carry pore water and
/// the volume sensors only nodes with volume (a node of mass has some).
template <typename T>
FBAR_HOST_DEVICE inline bool grid_sensor_reads(const GridSensorParams<T>& s, const GridNodeSample<T>& n) {
  const bool pore = s.quantity == GridSensorQuantity::MassWater || s.quantity == GridSensorQuantity::PorePressure;
  if (grid_sensor_reads_volume(s.quantity)) return n.volume > T(0);
  return !pore || n.water_mass > T(0);
}

/// Adds a node at x to every sensor of `set` whose box holds it.
template <typename T>
FBAR_HOST_DEVICE inline void accumulate_grid_sensors(const GridSensorSet<T>& set, const Vec3<T>& x,
                                                     const GridNodeSample<T>& n, SensorAccum* acc) {
  for (int i = 0; i < set.count; ++i)
    if (grid_sensor_reads(set.s[i], n) && sensor_box_contains(set.s[i].lo, set.s[i].hi, x))
      acc[i].add(static_cast<double>(grid_sensor_value(set.s[i], n)));
}

}  // namespace fbar
