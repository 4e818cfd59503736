// Facility boundary objects as generic pieces (facilities.h).
#include "scene/facilities.h"

#include <algorithm>
#include <cmath>

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
      // The USGS flume's head gate: the box [lo, hi] split at its z-centre into two doors. Closed from time[0] for
      // 1 s (x s^0.5), then each door slides away from the centre at 1 m/s (x s^0.5) for 1 s (x s^0.5), then gone.
      const double t0 = spec.time[0], t_open = t0 + 1.0 * time_scale, t_gone = t0 + 2.0 * time_scale;
      const double zc = 0.5 * (lo[2] + hi[2]), speed = 1.0 * time_scale;
      // Closed: one box (two boxes would meet at a seam where a node sees the seam as its nearest face).
      BoundarySpec closed = spec;
      closed.object = BoundaryObject::Box;
      closed.velocity = {0.0, 0.0, 0.0};
      closed.time = {t0, std::min(t_open, spec.time[1])};
      std::vector<BoundarySpec> doors{closed};
      for (int side = 0; side < 2; ++side) {
        BoundarySpec d = closed;
        if (side == 0) d.domain_end[2] = zc;
        else d.domain_start[2] = zc;
        d.time = {t_open, std::min(t_gone, spec.time[1])};
        d.velocity = {0.0, 0.0, side == 0 ? -speed : speed};
        if (d.time[1] > d.time[0]) doors.push_back(d);
      }
      return doors;
    }
    default:
      return {spec};
  }
}

}  // namespace fbar
