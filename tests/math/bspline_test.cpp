// Tests for MnBase/Math/bspline.h: the reproducing properties of quadratic B-spline weights that MLS-MPM relies on.
//
// Properties (exact in real arithmetic for the quadratic B-spline, Steffen et al. 2008; Jiang et al. 2015):
//   partition of unity     sum_i w_ip = 1
//   linear completeness    sum_i w_ip x_i = x_p                 (so APIC/MLS transfers conserve affine motion)
//   gradient sums          sum_i grad w_ip = 0
//   gradient completeness  sum_i (x_i - x_p) (grad w_ip)^T = I  (the gradient of a linear field is exact)
//   D_p                    sum_i w_ip (x_i - x_p)(x_i - x_p)^T = dx^2 / 4 I  (so D_p^-1 = 4 / dx^2)
// Tolerances: the properties are polynomial identities in fx, so evaluated with the computed fx they hold to the
// rounding of 27 triple products (64 eps). Against the exact node positions x_i the rounding of fx = x / dx - base
// (~eps |x / dx|) enters too: 64 eps (1 + |x / dx|). Positions span +-300 cells around the origin.
#include "MnBase/Math/bspline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace fbar {
namespace {

template <typename T>
class BsplineTyped : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(BsplineTyped, Scalars);

/// Positions to test for a given dx: random, exactly on nodes, exactly on cell faces (half-way between nodes,
/// where the base index jumps), and one ulp either side of those.
template <typename T>
std::vector<Vec3<T>> probe_positions(T dx, std::mt19937_64& rng) {
  std::vector<Vec3<T>> xs;
  std::uniform_real_distribution<double> u(-300.0, 300.0);  // in cells
  for (int n = 0; n < 2000; ++n) xs.push_back(Vec3<T>{{T(u(rng) * dx), T(u(rng) * dx), T(u(rng) * dx)}});
  for (int i = -5; i <= 5; ++i) {
    const T node = T(i) * dx, face = (T(i) + T(0.5)) * dx;
    for (T p : {node, face}) {
      const T lo = std::nextafter(p, -std::numeric_limits<T>::infinity());
      const T hi = std::nextafter(p, std::numeric_limits<T>::infinity());
      xs.push_back(Vec3<T>{{p, lo, hi}});
      xs.push_back(Vec3<T>{{hi, p, lo}});
    }
  }
  return xs;
}

TYPED_TEST(BsplineTyped, ReproducingProperties) {
  using T = TypeParam;
  const double eps = std::numeric_limits<T>::epsilon();
  std::mt19937_64 rng(8);
  double worst_unity = 0, worst_linear = 0, worst_grad_sum = 0, worst_grad_linear = 0, worst_inertia = 0;
  for (T dx : {T(1), T(0.01), T(0.0625), T(0.37), T(2.5)}) {
    const T inv_d = apic_inertia_inverse(dx);
    for (const Vec3<T>& xp : probe_positions(dx, rng)) {
      SCOPED_TRACE(::testing::Message() << "dx = " << dx << ", x = (" << xp[0] << ", " << xp[1] << ", " << xp[2]
                                        << ")");
      const QuadraticBspline<T> s = quadratic_bspline(xp, dx);
      double cells = 0;  // max |x / dx|: the rounding of fx scales with it
      for (int a = 0; a < 3; ++a) {
        const double exact = double(xp[a]) / double(dx);
        cells = std::max(cells, std::abs(exact));
        // fx stays in [0.5, 1.5) and base + fx = x / dx, both up to the rounding of x / dx (at a face either base
        // is correct: the weights are continuous there).
        EXPECT_GE(s.frac[a], 0.5 - 4 * eps * (1 + cells));
        EXPECT_LT(s.frac[a], 1.5 + 4 * eps * (1 + cells));
        EXPECT_NEAR(double(s.base[a]) + double(s.frac[a]), exact, 4 * eps * (1 + cells)) << "axis " << a;
      }
      // The sums below are identities in fx (they hold for any fx, e.g. sum_n w_n (n - fx) = 0), so only the 27-term
      // summation rounds: 64 eps. Completeness against the exact node positions also sees the rounding of fx itself.
      const double tol = 64 * eps;
      const double tol_x = 64 * eps * (1 + cells);

      double sum_w = 0;
      Vec3d sum_wx = Vec3d::zero(), sum_grad = Vec3d::zero();
      Mat3d grad_linear = Mat3d::zero(), inertia = Mat3d::zero();
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          for (int k = 0; k < 3; ++k) {
            const double w = s.weight(i, j, k);
            const Vec3d g = s.gradient(i, j, k).template cast<double>();
            const Vec3d dxi = s.node_offset(i, j, k, dx).template cast<double>();  // x_i - x_p
            // Node position computed exactly from the integer index (double), to test completeness in x_i itself.
            const Vec3d xi{{double(s.base[0] + i) * dx, double(s.base[1] + j) * dx, double(s.base[2] + k) * dx}};
            sum_w += w;
            sum_wx += w * xi;
            sum_grad += g;
            grad_linear += outer(dxi, g);
            inertia += w * outer(dxi, dxi);
          }
      const double unity = std::abs(sum_w - 1.0);
      const double linear = max_abs(sum_wx - xp.template cast<double>()) / double(dx);  // in cells
      const double grad_sum = max_abs(sum_grad) * double(dx);                           // dimensionless
      const double grad_linear_err = max_abs(grad_linear - Mat3d::identity());
      const double inertia_err = max_abs(inertia * double(inv_d) - Mat3d::identity());  // D_p^-1 D_p = I
      EXPECT_LE(unity, tol);
      EXPECT_LE(linear, tol_x);
      EXPECT_LE(grad_sum, tol);
      EXPECT_LE(grad_linear_err, tol);
      EXPECT_LE(inertia_err, tol);
      worst_unity = std::max(worst_unity, unity);
      worst_linear = std::max(worst_linear, linear);
      worst_grad_sum = std::max(worst_grad_sum, grad_sum);
      worst_grad_linear = std::max(worst_grad_linear, grad_linear_err);
      worst_inertia = std::max(worst_inertia, inertia_err);
      if (::testing::Test::HasFailure()) return;
    }
  }
  std::printf(
      "[ worst    ] bspline %s: |sum w - 1| %.3g  |sum w x_i - x_p|/dx %.3g  |sum grad w| dx %.3g  "
      "|sum (x_i-x_p) grad w^T - I| %.3g  |D^-1 D - I| %.3g\n",
      sizeof(T) == 4 ? "float" : "double", worst_unity, worst_linear, worst_grad_sum, worst_grad_linear, worst_inertia);
}

TYPED_TEST(BsplineTyped, KnownValuesAtNodeAndFace) {
  // On a node (fx = 1): weights (1/8, 3/4, 1/8), derivatives (-1/2, 0, 1/2) / dx. On a face (x / dx = n + 1/2, so
  // fx = 0.5): weights (1/2, 1/2, 0), derivatives (-1, 1, 0) / dx. All exactly representable.
  using T = TypeParam;
  for (T dx : {T(1), T(0.25), T(4)}) {
    const QuadraticBspline<T> node = quadratic_bspline(Vec3<T>{{T(3) * dx, T(-2) * dx, T(0)}}, dx);
    EXPECT_EQ(node.base, (Vec3i{{2, -3, -1}}));
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(node.w[a][0], T(0.125));
      EXPECT_EQ(node.w[a][1], T(0.75));
      EXPECT_EQ(node.w[a][2], T(0.125));
      EXPECT_EQ(node.dw[a][0], T(-0.5) / dx);
      EXPECT_EQ(node.dw[a][1], T(0));
      EXPECT_EQ(node.dw[a][2], T(0.5) / dx);
    }
    const QuadraticBspline<T> face = quadratic_bspline(Vec3<T>{{T(3.5) * dx, T(-0.5) * dx, T(0.5) * dx}}, dx);
    EXPECT_EQ(face.base, (Vec3i{{3, -1, 0}}));
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(face.w[a][0], T(0.5));
      EXPECT_EQ(face.w[a][1], T(0.5));
      EXPECT_EQ(face.w[a][2], T(0));
      EXPECT_EQ(face.dw[a][0], T(-1) / dx);
      EXPECT_EQ(face.dw[a][1], T(1) / dx);
      EXPECT_EQ(face.dw[a][2], T(0));
    }
  }
}

TYPED_TEST(BsplineTyped, GradientMatchesFiniteDifference) {
  // Central difference of the 3D weight in x_p with step h: the weight is a polynomial of degree 2 per axis inside
  // one piece (fx in [0.6, 1.4], h = 1e-3 dx keeps the probe inside), so the central difference has no truncation
  // error; only round-off remains. Done in double; the T stencil is then compared with the double one.
  using T = TypeParam;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> cell(-50, 50);
  std::uniform_real_distribution<double> frac(0.6, 1.4);
  const T dx = T(0.3);
  const double h = 1e-3 * dx;
  // Round-off of the difference quotient: each weight carries the rounding of fx (~eps * 50 cells ~ 1e-14),
  // divided by the step 2e-3 cells gives ~1e-11 in units of 1/dx.
  const double tol = 1e-10;
  for (int n = 0; n < 200; ++n) {
    Vec3d xp{};
    for (int a = 0; a < 3; ++a) xp[a] = (std::floor(cell(rng)) + frac(rng)) * dx;
    const QuadraticBspline<double> s = quadratic_bspline(xp, double(dx));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) {
          const Vec3d g = s.gradient(i, j, k);
          for (int a = 0; a < 3; ++a) {
            Vec3d xm = xp, xq = xp;
            xm[a] -= h;
            xq[a] += h;
            const QuadraticBspline<double> sm = quadratic_bspline(xm, double(dx));
            const QuadraticBspline<double> sq = quadratic_bspline(xq, double(dx));
            ASSERT_EQ(sm.base, s.base);
            ASSERT_EQ(sq.base, s.base);
            const double fd = (sq.weight(i, j, k) - sm.weight(i, j, k)) / (xq[a] - xm[a]);
            EXPECT_NEAR(g[a], fd, tol / dx);
          }
        }
    // The same stencil in T agrees with the double one to T's precision: |dw/dfx| <= 1 times the rounding of
    // fx (x rounded to T, then x / dx: a few eps_T * 50 cells).
    const QuadraticBspline<T> st = quadratic_bspline(xp.cast<T>(), dx);
    for (int a = 0; a < 3; ++a)
      for (int m = 0; m < 3; ++m) EXPECT_NEAR(st.w[a][m], s.w[a][m], 8 * 51 * std::numeric_limits<T>::epsilon());
  }
}

TYPED_TEST(BsplineTyped, InertiaInverseFollowsDx) {
  using T = TypeParam;
  EXPECT_EQ(apic_inertia_inverse(T(1)), T(4));
  EXPECT_EQ(apic_inertia_inverse(T(0.5)), T(16));
  EXPECT_EQ(apic_inertia_inverse(T(0.01)), T(4) / (T(0.01) * T(0.01)));
}

}  // namespace
}  // namespace fbar
