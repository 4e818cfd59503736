// Quadratic B-spline weights and gradients for MLS-MPM / APIC particle-grid transfers (host and device).
//
// Grid convention: node (i, j, k) sits at (i, j, k) * dx, positions are measured from the grid origin in metres,
// dx is the grid spacing in metres. A particle at x interacts with the 3x3x3 nodes base + (0..2, 0..2, 0..2):
//     base_a = floor(x_a / dx - 0.5),   fx_a = x_a / dx - base_a  in [0.5, 1.5)   (a = x, y, z),
// and the 1D quadratic B-spline N(r) evaluated at the node distances r = fx - (0, 1, 2) gives
//     w0 = 0.5 (1.5 - fx)^2,   w1 = 0.75 - (fx - 1)^2,   w2 = 0.5 (fx - 0.5)^2,
//     dw_n / dx_a = (dN / dfx) / dx:   dw0 = (fx - 1.5) / dx,   dw1 = -2 (fx - 1) / dx,   dw2 = (fx - 0.5) / dx.
// The 3D weight is the tensor product w_ijk = w[0][i] w[1][j] w[2][k] (dimensionless); its gradient with respect to
// the particle position is in 1/m. Near the half-cell boundaries fx may leave [0.5, 1.5) by one ulp; the stencil
// stays valid there: the three polynomials sum to 1 (derivatives to 0) and reproduce linear fields for every fx,
// and the node that leaves the support has a weight of order ulp^2.
//
// APIC / MLS-MPM (Jiang et al. 2015, Hu et al. 2018): for quadratic B-splines the inertia-like tensor is
// D_p = dx^2 / 4 I, so the affine velocity is C_p = D_p^-1 sum_i w_ip v_i (x_i - x_p)^T with D_p^-1 = 4 / dx^2.
// It must follow dx (Claymore's unscaled constant only holds for dx = 1).
#pragma once

#include <cmath>

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// Quadratic B-spline stencil of one particle: base node, per-axis weights and their x-derivatives.
/// Index layout: w[axis][node], axis 0..2 = x, y, z, node 0..2 = base + 0, 1, 2 along that axis.
template <typename T>
struct QuadraticBspline {
  Vec3i base;    ///< lowest node index of the 3x3x3 stencil
  Vec3<T> frac;  ///< fx = x / dx - base per axis, in [0.5, 1.5) (dimensionless)
  T w[3][3];     ///< 1D weights, dimensionless
  T dw[3][3];    ///< d w[axis][node] / d x_axis, in 1/m

  /// 3D weight of stencil node (i, j, k), each in 0..2.
  FBAR_HOST_DEVICE constexpr T weight(int i, int j, int k) const { return w[0][i] * w[1][j] * w[2][k]; }

  /// Gradient of the 3D weight of node (i, j, k) with respect to the particle position (1/m). The gradient with
  /// respect to the node position is its negative.
  FBAR_HOST_DEVICE constexpr Vec3<T> gradient(int i, int j, int k) const {
    return Vec3<T>{{dw[0][i] * w[1][j] * w[2][k], w[0][i] * dw[1][j] * w[2][k], w[0][i] * w[1][j] * dw[2][k]}};
  }

  /// x_node - x_particle along one axis for the stencil's node n on that axis, in metres: (n - frac[axis]) * dx.
  FBAR_HOST_DEVICE constexpr T axis_offset(int axis, int n, T dx) const { return (T(n) - frac[axis]) * dx; }

  /// x_node - x_particle for stencil node (i, j, k), in metres: ((i, j, k) - frac) * dx.
  FBAR_HOST_DEVICE constexpr Vec3<T> node_offset(int i, int j, int k, T dx) const {
    return Vec3<T>{{axis_offset(0, i, dx), axis_offset(1, j, dx), axis_offset(2, k, dx)}};
  }
};

namespace bspline_detail {

/// x * y rounded once, never fused with a following add. The base index and fx must both come from the same
/// rounded x / dx: if nvcc contracted x * inv_dx - 0.5 into an FMA, a particle exactly on a cell face could get a
/// different base on the GPU than on the CPU (both valid, but the two engines must agree).
FBAR_HOST_DEVICE FBAR_FORCE_INLINE float mul_rounded(float x, float y) {
#if FBAR_IN_DEVICE_CODE
  return __fmul_rn(x, y);
#else
  return x * y;  // host builds target x86-64 without -mfma: no contraction
#endif
}
FBAR_HOST_DEVICE FBAR_FORCE_INLINE double mul_rounded(double x, double y) {
#if FBAR_IN_DEVICE_CODE
  return __dmul_rn(x, y);
#else
  return x * y;
#endif
}

}  // namespace bspline_detail

/// Stencil of the particle at x (m) on a grid of spacing dx (m), given as its reciprocal inv_dx = 1/dx (1/m) so
/// that kernels divide once per launch, not per particle.
template <typename T>
FBAR_HOST_DEVICE inline QuadraticBspline<T> quadratic_bspline_inv(const Vec3<T>& x, T inv_dx) {
  using std::floor;
  QuadraticBspline<T> s{};
  for (int a = 0; a < 3; ++a) {
    const T xi = bspline_detail::mul_rounded(x[a], inv_dx);
    const T b = floor(xi - T(0.5));
    const T fx = xi - b;
    s.base[a] = static_cast<int>(b);
    s.frac[a] = fx;
    const T d0 = T(1.5) - fx;  // distance (in cells) to node 0, beyond the particle: N(r) = 0.5 (1.5 - |r|)^2
    const T d1 = fx - T(1);    // signed distance to node 1:                         N(r) = 0.75 - r^2
    const T d2 = fx - T(0.5);  // 1.5 - distance to node 2:                          N(r) = 0.5 (1.5 - |r|)^2
    s.w[a][0] = T(0.5) * d0 * d0;
    s.w[a][1] = T(0.75) - d1 * d1;
    s.w[a][2] = T(0.5) * d2 * d2;
    s.dw[a][0] = -d0 * inv_dx;
    s.dw[a][1] = T(-2) * d1 * inv_dx;
    s.dw[a][2] = d2 * inv_dx;
  }
  return s;
}

/// Stencil of the particle at x (m) on a grid of spacing dx (m).
template <typename T>
FBAR_HOST_DEVICE inline QuadraticBspline<T> quadratic_bspline(const Vec3<T>& x, T dx) {
  return quadratic_bspline_inv(x, T(1) / dx);
}

/// APIC / MLS-MPM inverse inertia D_p^-1 = 4 / dx^2 for quadratic B-splines (1/m^2).
template <typename T>
FBAR_HOST_DEVICE constexpr T apic_inertia_inverse(T dx) {
  return T(4) / (dx * dx);
}

}  // namespace fbar
