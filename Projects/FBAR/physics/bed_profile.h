// A bed profile as the physics reads it: piecewise linear through points (x increasing), flat beyond its ends. The
// Bathymetry boundary (boundary.cuh), the bed bodies (geometry.cpp) and the facilities' beds (scene/facilities.h)
// evaluate it here.
#pragma once

#include "MnBase/Meta/config.h"

namespace fbar {

/// The piecewise-linear bed through n >= 2 points (x increasing; point k at px[k stride], py[k stride]), flat
/// beyond the ends, at x: its height; `i` is the segment that holds x (0 .. n-2, the end segment for an x outside)
/// and `on_segment` whether x lies strictly between the first and last point. Host and device (boundary.cuh's
/// Bathymetry, geometry.cpp's bed bodies).
template <typename T>
FBAR_HOST_DEVICE inline T bed_surface(const T* px, const T* py, int n, T x, int& i, bool& on_segment, int stride = 1) {
  i = 0;
  while (i + 2 < n && x >= px[(i + 1) * stride]) ++i;
  on_segment = x > px[0] && x < px[(n - 1) * stride];
  if (!on_segment) return x <= px[0] ? py[0] : py[(n - 1) * stride];
  const T x0 = px[i * stride], y0 = py[i * stride];
  return y0 + (x - x0) / (px[(i + 1) * stride] - x0) * (py[(i + 1) * stride] - y0);
}

}  // namespace fbar
