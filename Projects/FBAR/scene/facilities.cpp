// Facility boundary objects as generic pieces (facilities.h).
#include "scene/facilities.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fbar {

std::vector<BoundarySpec> expand_boundary(const BoundarySpec& spec, const SimulationSpec& sim) {
  const double s = sim.froude_scaling;
  const double time_scale = std::sqrt(s);  // Froude: times and velocities scale with s^0.5
  const Real3& lo = spec.domain_start;
  const Real3& hi = spec.domain_end;
  BoundarySpec g = spec;
  const bool custom = spec.use_custom_bathymetry && spec.bathymetry.size() >= 2;
  switch (spec.object) {
    case BoundaryObject::OSU_LWF_RAMP:
    case BoundaryObject::OSU_TWB_RAMP:
    case BoundaryObject::USGS_RAMP: {
      // The facility's bed with its origin at domain_start (x, y), the LWF's 2 m (x s) further along x (its wave
      // maker's neutral position), unless custom points replace it.
      g.object = BoundaryObject::Bathymetry;
      if (!custom) {
        const bool lwf = spec.object == BoundaryObject::OSU_LWF_RAMP;
        const BedPoints bed = lwf                                           ? osu_lwf_bathymetry()
                              : spec.object == BoundaryObject::OSU_TWB_RAMP ? osu_twb_bathymetry()
                                                                            : usgs_ramp_bathymetry();
        g.bathymetry = place_bed(bed, s, lo[0] + (lwf ? kOsuLwfNeutralFromBoundary * s : 0.0), lo[1]);
      }
      return {g};
    }
    case BoundaryObject::OSU_LWF_PADDLE:
    case BoundaryObject::OSU_TWB_PADDLE:
      // A piston-type wave maker: its face is the box's +x face at domain_end[0] (the neutral position), moved along
      // x by the motion file (or `velocity`).
      g.object = BoundaryObject::Piston;
      return {g};
    case BoundaryObject::WASIRF_PUMP:
      g.object = BoundaryObject::Pump;
      return {g};
    case BoundaryObject::TOKYO_HARBOR: {
      // The Waseda harbour's quay: a solid block (apron) from x = lo_x + 4.45 m to hi_x, from the floor lo_y up to
      // 0.255 m, over the box's z range; material keeps out of it (its top and its quay face).
      g.object = BoundaryObject::Box;
      g.domain_start = {lo[0] + 4.45 * s, lo[1] - 2.0 * sim.dx, lo[2]};
      g.domain_end = {hi[0], lo[1] + 0.255 * s, hi[2]};
      return {g};
    }
    case BoundaryObject::USGS_GATE: {
      // The USGS flume's head gate as ClaymoreUW builds it (mgmpm_kernels.cuh:2193-2225): a plate through the
      // flume's bed at x = 4.7 m (x s) from domain_start, leaning back 60 degrees from the bed over the material
      // (its normal (-cos 30, -sin 30, 0) points upstream), closed over every z until 1 s (x s^0.5) of simulation
      // time; then two doors open from z = 4 m (x s) from domain_start, sliding apart 1 m (x s) each until 2 s
      // (x s^0.5), when the gate is gone. Only inside the entry's time window.
      constexpr double kCos30 = 0.86602540378443864676, kSin30 = 0.5;
      const double t_open = 1.0 * time_scale, t_gone = 2.0 * time_scale;
      const double speed = 1.0 * s / (t_gone - t_open);  // 1 m (x s) in 1 s (x s^0.5)
      const double base_x = lo[0] + 4.7 * s, base_y = lo[1], zc = lo[2] + 4.0 * s;
      double reach = 0.0;  // every z of the grid: the domain's largest extent beyond each side
      for (const double d : sim.domain) reach = std::max(reach, std::abs(d));
      reach += std::abs(lo[2]) + 4.0 * s;
      BoundarySpec plate = spec;
      plate.object = BoundaryObject::HalfSpace;
      plate.velocity = {0.0, 0.0, 0.0};
      // The line from the base up the plate: its left (upstream, under the plate) holds the material.
      plate.domain_start = {base_x, base_y, zc - reach};
      plate.domain_end = {base_x - kSin30 * s, base_y + kCos30 * s, zc + reach};
      const double before_open = std::nextafter(t_open, -std::numeric_limits<double>::infinity());
      const double before_gone = std::nextafter(t_gone, -std::numeric_limits<double>::infinity());
      std::vector<BoundarySpec> pieces;
      BoundarySpec closed = plate;
      closed.time = {spec.time[0], std::min(before_open, spec.time[1])};
      if (closed.time[1] >= closed.time[0]) pieces.push_back(closed);
      for (int side = 0; side < 2; ++side) {
        BoundarySpec d = plate;
        d.time = {std::max(t_open, spec.time[0]), std::min(before_gone, spec.time[1])};
        if (d.time[1] < d.time[0]) continue;
        const double opened = speed * (d.time[0] - t_open);  // each door's travel when it starts acting
        if (side == 0) d.domain_end[2] = zc - opened;
        else d.domain_start[2] = zc + opened;
        d.velocity = {0.0, 0.0, side == 0 ? -speed : speed};
        pieces.push_back(d);
      }
      return pieces;
    }
    default:
      return {spec};
  }
}

}  // namespace fbar
