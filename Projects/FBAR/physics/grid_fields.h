// Grid fields (scene "grid-fields"): the grid's node values inside a box, taken by the step that starts at a sample
// time from the same P2G state and grid update the grid sensors read (physics/sensors.cuh GridNodeSample), on the
// nodes the rank owns (a halo node once). Both engines record one GridFieldNode per node of mass > 0 inside a
// field's box; io/grid_field_recorder.h gathers the ranks' nodes, orders them by node index and writes the frame.
//
// What each attribute is (per node; a `blocks` field sums its nodes per grid block):
//   Mass          [kg]      m
//   Velocity      [m/s]     p / m (the P2G velocity, before gravity and the boundaries; the grid sensors' Velocity)
//   Momentum      [kg m/s]  p
//   Force         [N]       p / dt (ClaymoreUW's grid Force: the load the material puts on a wall at held nodes)
//   BoundaryForce [N]       m (v* - v) / dt (the force the material exerts on the boundaries at the node)
//   Volume        [m^3]     sum_p w_ip V_p
//   JBar          [-]       1 - sum_p w_ip V_p (1 - JBar_p) / Volume (the node's volume-weighted JBar)
//   MassWater     [kg]      the pore water's mass at the node (saturated bodies; 0 elsewhere)
//   PorePressure  [Pa]      the node's pore pressure (saturated bodies; 0 elsewhere)
// A block's point is its centre (node 1.5 of the block on each axis); its Mass, Momentum, Force, BoundaryForce,
// Volume and MassWater are its nodes' sums, its Velocity the sum of p over the sum of m, its JBar from the summed
// volumes, its PorePressure the mean over its nodes that carry pore water.
#pragma once

#include <cstdint>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/sensors.cuh"

namespace fbar {

/// One node of a grid field, as an engine records it (plain data: ranks exchange it as bytes).
struct GridFieldNode {
  std::int32_t index[3];  ///< the node's grid index (position index * dx)
  std::int32_t pad = 0;
  double m;               ///< [kg]
  double p[3];            ///< [kg m/s] P2G momentum
  double boundary[3];     ///< [N] m (v* - v) / dt
  double volume;          ///< [m^3] sum w V (0 unless the field reads Volume or JBar)
  double volume_jbar;     ///< [m^3] sum w V (1 - JBar)
  double water;           ///< [kg]
  double pore;            ///< [Pa]
};

/// What an engine hands the run loop of one field's sample: this rank's nodes and the sampled step's dt [s].
struct GridFieldSample {
  double dt = 0.0;
  std::vector<GridFieldNode> nodes;
};

/// A field's box as the engines test it, in the grid scalar type (both ends included, widened by dx / 128 as the
/// grid sensors' boxes are: make_grid_field_params).
template <typename T>
struct GridFieldParams {
  Vec3<T> lo{};
  Vec3<T> hi{};
  bool volume = false;  ///< reads Volume or JBar: the step sums the nodes' volume first
};

/// The fields of one step (at most kMax, a kernel parameter): `mask` bit i set when field i samples this step.
template <typename T>
struct GridFieldSet {
  static constexpr int kMax = 16;
  int count = 0;
  unsigned mask = 0;
  GridFieldParams<T> f[kMax];
  /// Some field sampled this step reads the nodes' volume.
  FBAR_HOST_DEVICE bool reads_volume() const {
    for (int i = 0; i < count; ++i)
      if ((mask >> i & 1u) && f[i].volume) return true;
    return false;
  }
};

/// Whether field f's box holds the node at x.
template <typename T>
FBAR_HOST_DEVICE inline bool grid_field_contains(const GridFieldParams<T>& f, const Vec3<T>& x) {
  return sensor_box_contains(f.lo, f.hi, x);
}

/// The record of a node (grid index c) of the sample `n`.
template <typename T>
FBAR_HOST_DEVICE inline GridFieldNode grid_field_node(const int c[3], const GridNodeSample<T>& n) {
  GridFieldNode r;
  for (int d = 0; d < 3; ++d) {
    r.index[d] = c[d];
    r.p[d] = static_cast<double>(n.p[d]);
    r.boundary[d] = static_cast<double>((n.v_free[d] - n.v[d]) * (n.m / n.dt));
  }
  r.pad = 0;
  r.m = static_cast<double>(n.m);
  r.volume = static_cast<double>(n.volume);
  r.volume_jbar = static_cast<double>(n.volume_jbar);
  r.water = static_cast<double>(n.water_mass);
  r.pore = static_cast<double>(n.pore_pressure);
  return r;
}

}  // namespace fbar
