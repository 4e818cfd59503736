// The experimental facilities that ClaymoreUW's scenes name, as data: bed profiles (x along the flume from the
// wave-maker's neutral position, y above the flume floor, metres at full scale) that Bathymetry boundaries and
// water-body geometry share, so that a body of water sits exactly on the bed that holds it. Nothing here reaches a
// kernel: boundary.cuh and geometry.cpp turn these points into the generic Bathymetry profile and CSG solid.
//
// Sources and what is approximate (user guide §2.7, "Facility objects"):
//  * OSU Large Wave Flume (LWF, Oregon State University, 104 m x 3.7 m x 4.6 m): ClaymoreUW's own bed table (the
//    OSU_LWF_RAMP grid kernel, mgmpm_kernels.cuh L2413-2462, and make_OSU_LWF, read_scene_input.h L688-718), which
//    scenes written for ClaymoreUW place their structures and gauges on: from the wave maker's neutral position,
//    0.225 m (a raised slab) flat to 17.925 m (a break at 14.275 m kept as a point), 1:11.86 up to 1.15 m at 28.9 m,
//    1:24.375 up to 1.75 m at 43.525 m, flat to 80.1 m, 1:12.25 up to 2.35 m at 87.45 m, flat beyond; flat at
//    0.225 m before the neutral position. It lies 0.2 to 0.23 m above the published stations (1:12 up to 3 ft at
//    28.9 m, 1:24 up to 5 ft, 1:12 up to 7 ft). The boundary puts the neutral position 2 m (x s) after domain_start
//    (ClaymoreUW: x = 2 m, whatever domain_start says), the water body 0.1 m (x s) after its offset (as ClaymoreUW).
//  * OSU Tsunami Wave Basin (TWB, 48.8 m x 26.5 m x 2.1 m): flat to 11.3 m, 1:20 up to 1.0 m at 31.3 m, flat to
//    41.3 m (ClaymoreUW's tables); flat beyond (ClaymoreUW drops to 0 after 41.3 m, behind the basin's end wall).
//  * USGS debris-flow flume (H.J. Andrews, 95 m long, 2 m wide): the flume bed is flat (y = 0) to 80 m in the flume's
//    own frame (tilt it with gravity), then the run-out pad bends up: 1:5.675 to 81.25 m, 1:2.747 to 82.5 m, then
//    1:1.732 (ClaymoreUW's tables; its 1.25 / 5.675 m step is not Froude-scaled there, which fbar corrects). fbar
//    ends the last slope at 100 m (a profile is flat beyond its last point).
#pragma once

#include <array>
#include <vector>

#include "physics/bed_profile.h"
#include "scene/scene.h"

namespace fbar {

using BedPoints = std::vector<std::array<double, 2>>;

inline BedPoints osu_lwf_bathymetry() {
  return {{0.0, 0.225},   {14.275, 0.225}, {17.925, 0.225}, {28.9, 1.15},
          {43.525, 1.75}, {80.1, 1.75},    {87.45, 2.35}};
}

/// Where the LWF bed's origin (the wave maker's neutral position) lies, at full scale [m]: 2 m after the boundary's
/// domain_start (ClaymoreUW's OSU_LWF_RAMP kernel: x = 2 m), 0.1 m after the water body's offset (make_OSU_LWF).
constexpr double kOsuLwfNeutralFromBoundary = 2.0;
constexpr double kOsuLwfNeutralFromWater = 0.1;

inline BedPoints osu_twb_bathymetry() { return {{0.0, 0.0}, {11.3, 0.0}, {31.3, 1.0}, {41.3, 1.0}}; }

inline BedPoints usgs_ramp_bathymetry() {
  const double y1 = 1.25 / 5.675, y2 = y1 + 1.25 / 2.747;
  return {{0.0, 0.0}, {80.0, 0.0}, {81.25, y1}, {82.5, y2}, {100.0, y2 + 17.5 / 1.732}};
}

/// A facility bed scaled by the Froude factor s and placed with its origin at (x0, y0).
inline BedPoints place_bed(BedPoints bed, double s, double x0, double y0) {
  for (auto& p : bed) {
    p[0] = x0 + p[0] * s;
    p[1] = y0 + p[1] * s;
  }
  return bed;
}

/// Height of the bed through `bed` (at least two points) at x.
inline double bed_height(const BedPoints& bed, double x) {
  int i;
  bool on_segment;
  return bed_surface(&bed[0][0], &bed[0][1], static_cast<int>(bed.size()), x, i, on_segment, 2);
}

/// The generic boundaries (Walls, Box, ..., Bathymetry, Piston, Pump) a boundary entry stands for: a generic object
/// is itself; a facility object (OSU_LWF_RAMP, OSU_LWF_PADDLE, OSU_TWB_RAMP, OSU_TWB_PADDLE, USGS_RAMP, USGS_GATE,
/// WASIRF_PUMP, TOKYO_HARBOR) becomes the generic pieces that build it, placed by its domain_start / domain_end and
/// Froude-scaled by `sim` (user guide §2.7 lists each). The pieces keep the entry's contact, friction, time window,
/// velocity, motion file and array; the engines see only generic shapes.
std::vector<BoundarySpec> expand_boundary(const BoundarySpec& spec, const SimulationSpec& sim);

}  // namespace fbar
