// Transfer formulas (APIC/MLS-MPM moments, conservation), grid update, boundary projections and the time-step bound.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "engine/run_constants.h"
#include "physics/boundary.cuh"
#include "physics/constitutive_models.cuh"
#include "physics/grid_update.cuh"
#include "physics/motion_path.h"
#include "physics_test_support.h"
#include "physics/time_step.cuh"
#include "physics/transfer.cuh"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

using test::kEps;

// ------------------------------------------------------------------------------------------------ transfers

// Quadratic B-spline moments behind every conservation property: sum w = 1, sum w (x_i - x_p) = 0 and
// sum w (x_i - x_p)(x_i - x_p)^T = dx^2/4 I = D_p, i.e. D_p^-1 = 4/dx^2 for any dx (it must follow dx).
// Each sum has 27 terms of size <= dx^k: tolerance 64 eps dx^k.
TEST(Transfer, BsplineMomentsGiveApicInertia) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double dx : {0.01, 1.0, 7.3}) {
    for (int n = 0; n < 100; ++n) {
      const Vec3d x{{u(rng) * 40 * dx, u(rng) * 40 * dx, u(rng) * 40 * dx}};
      const QuadraticBspline<double> s = quadratic_bspline(x, dx);
      double w_sum = 0;
      Vec3d first = Vec3d::zero();
      Mat3d second = Mat3d::zero();
      for_each_stencil_node(s, dx, [&](int, int, int, double w, const Vec3d& d) {
        w_sum += w;
        first += d * w;
        second += outer(d, d) * w;
      });
      EXPECT_NEAR(w_sum, 1.0, 64 * kEps);
      EXPECT_LE(max_abs(first), 64 * kEps * dx);
      EXPECT_LE(max_abs(second - Mat3d::identity() / apic_inertia_inverse(dx)), 64 * kEps * dx * dx);
    }
  }
}

// One particle's P2G: node masses sum to m, node momenta to m v (the affine and stress terms cancel by the first
// moment), node angular momentum sum x_i x m_i v_i to the APIC particle angular momentum (transfer.cuh).
TEST(Transfer, P2GConservesMassMomentumAngularMomentum) {
  const double dx = 0.05, dt = 1e-3, mass = 0.3, vol = 2e-4;
  const Vec3d x{{0.4123, 0.2871, 0.6502}};
  const Vec3d v{{1.5, -0.25, 0.75}};
  const Mat3d C{{{0.5, -2.0, 1.0}, {3.0, 0.25, -1.5}, {0.75, 2.5, -0.5}}};
  const Mat3d tau_sym{{{1e5, 2e4, -3e4}, {2e4, -5e4, 1e4}, {-3e4, 1e4, 7e4}}};
  const P2GParticle<double> q = mls_p2g_particle(mass, vol, v, C, tau_sym, dt, apic_inertia_inverse(dx));
  const QuadraticBspline<double> s = quadratic_bspline(x, dx);
  double m_sum = 0;
  Vec3d p_sum = Vec3d::zero(), L_sum = Vec3d::zero();
  for_each_stencil_node(s, dx, [&](int i, int j, int k, double w, const Vec3d& d) {
    const Vec3d xi{{(s.base[0] + i) * dx, (s.base[1] + j) * dx, (s.base[2] + k) * dx}};
    const Vec3d mv = p2g_node_momentum(q, w, d);
    m_sum += w * q.mass;
    p_sum += mv;
    L_sum += cross(xi, mv);
  });
  EXPECT_NEAR(m_sum, mass, 16 * kEps * mass);
  // Force term magnitude dt V D^-1 |tau| dx ~ 1e-3 * 2e-4 * 1600 * 1e5 * 0.05 = 1.6: its sum cancels to round-off.
  EXPECT_LE(max_abs(p_sum - v * mass), 1e-14 * 10);
  // The stress part of the angular momentum vanishes because tau is symmetric (no internal torque).
  const Vec3d L_ref = apic_angular_momentum(mass, x, v, C, dx);
  EXPECT_LE(max_abs(L_sum - L_ref), 1e-14 * 10);
}

// The fixed-point P2G of the GPU engine sizes its quantum from p2g_momentum_bound: every component of every node
// momentum must lie within w b (random particles, payloads and dx; the bound is exact up to round-off, 1e-12).
// It must also be attained within the triangle inequality's slack: for an affine row of one sign the bound is
// reached at the stencil corner, so the largest |component| / w over the 27 nodes is at least b / 3.
TEST(Transfer, P2GMomentumBoundCoversEveryNode) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double dx : {0.01, 0.5, 4.0}) {
    for (int n = 0; n < 200; ++n) {
      P2GParticle<double> q;
      q.mass = 1.0 + u(rng) * 0.5;
      q.momentum = Vec3d{{u(rng), u(rng), u(rng)}} * 3.0;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) q.affine(r, c) = u(rng) * 50.0 / dx;
      const double b = p2g_momentum_bound(q, dx);
      const Vec3d x{{(10 + u(rng)) * dx, (20 + u(rng)) * dx, (30 + u(rng)) * dx}};
      const QuadraticBspline<double> s = quadratic_bspline(x, dx);
      double largest = 0.0;
      for_each_stencil_node(s, dx, [&](int, int, int, double w, const Vec3d& d) {
        const Vec3d mv = p2g_node_momentum(q, w, d);
        EXPECT_LE(max_abs(mv), w * b * (1 + 1e-12));
        largest = std::max(largest, max_abs(mv) / w);
      });
      EXPECT_GE(largest, b / 3.0);
    }
  }
}

// APIC reproduces affine velocity fields exactly: a grid holding v_i = v0 + A x_i gives v_p = v0 + A x_p and C_p = A.
TEST(Transfer, G2PReproducesAffineField) {
  for (double dx : {0.02, 3.0}) {
    const Vec3d v0{{0.3, -1.2, 2.0}};
    const Mat3d A{{{1.0, -0.5, 0.25}, {2.0, 0.1, -3.0}, {0.5, 0.75, -1.0}}};
    const Vec3d x{{17.37 * dx, 4.51 * dx, 9.99 * dx}};
    const QuadraticBspline<double> s = quadratic_bspline(x, dx);
    G2PSum<double> sum;
    for_each_stencil_node(s, dx, [&](int i, int j, int k, double w, const Vec3d& d) {
      const Vec3d xi{{(s.base[0] + i) * dx, (s.base[1] + j) * dx, (s.base[2] + k) * dx}};
      sum.add(w, v0 + A * xi, d);
    });
    const double scale = max_abs(A) * 20 * dx + norm(v0);  // velocity magnitude on the stencil
    EXPECT_LE(max_abs(sum.velocity() - (v0 + A * x)), 64 * kEps * scale);
    EXPECT_LE(max_abs(sum.affine(apic_inertia_inverse(dx)) - A), 64 * kEps * scale / dx);
  }
  EXPECT_EQ(advect(Vec3d{{1, 2, 3}}, Vec3d{{4, 5, 6}}, 0.5), (Vec3d{{3, 4.5, 6}}));
}

// ------------------------------------------------------------------------------------------------ grid update

TEST(GridUpdate, VelocityFromMomentumPlusGravity) {
  const Vec3d g{{0, -9.81, 0}};
  EXPECT_EQ(grid_node_velocity(0.0, Vec3d{{1, 2, 3}}, g, 0.1), Vec3d::zero());  // empty node
  const Vec3d v = grid_node_velocity(2.0, Vec3d{{1, 2, 3}}, g, 0.1);
  EXPECT_DOUBLE_EQ(v[0], 0.5);
  EXPECT_DOUBLE_EQ(v[1], 1.0 + (-9.81 * 0.1));  // the same operations as the formula: exact
  EXPECT_DOUBLE_EQ(v[2], 1.5);
}

// ------------------------------------------------------------------------------------------------ boundaries

SimulationSpec unit_sim(double dx) {
  SimulationSpec s;
  s.domain = {1.0, 2.0, 1.0};
  s.dx = dx;
  return s;
}

BoundaryParams<double> make(BoundaryObject object, Contact contact, Real3 lo = {0, 0, 0}, Real3 hi = {0, 0, 0},
                            double dx = 0.1) {
  BoundarySpec spec;
  spec.object = object;
  spec.contact = contact;
  spec.domain_start = lo;
  spec.domain_end = hi;
  BoundaryParams<double> b{};
  std::string error;
  EXPECT_TRUE(make_boundary_params(spec, unit_sim(dx).dx, unit_sim(dx).domain, b, error)) << error;
  return b;
}

const Vec3d kV{{0.3, -0.7, 0.2}};

// Walls act on ClaymoreUW's nodes (mgmpm_kernels.cuh, grid update, Walls): x <= lo or x >= hi along an axis.
TEST(Boundary, WallsAreTheDomainByDefaultOnTheFaceNodesAndOutside) {
  const auto b = make(BoundaryObject::Walls, Contact::Sticky);
  EXPECT_EQ(b.hi, (Vec3d{{1.0, 2.0, 1.0}}));
  // Sticky: the face's node plane (0) and everything outside it are held; one cell in (dx) is free.
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.0, 1.0, 0.5}}, kV), Vec3d::zero());
  EXPECT_EQ(apply_boundary(b, Vec3d{{-0.1, 1.0, 0.5}}, kV), Vec3d::zero());
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.1, 1.0, 0.5}}, kV), kV);
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.5, 2.0, 0.5}}, kV), Vec3d::zero());  // high y face
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.5, 1.9, 0.5}}, kV), kV);
  // A node position a round-off below the face still lies on it (snap: dx / 128).
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.5, 2.0 - 1e-6, 0.5}}, kV), Vec3d::zero());
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.5, 2.0 - 0.01, 0.5}}, kV), kV);
}

TEST(Boundary, WallsSlipRemovesNormalSeparableOnlyInward) {
  const auto slip = make(BoundaryObject::Walls, Contact::Slip);
  const auto sep = make(BoundaryObject::Walls, Contact::Separable);
  const Vec3d floor_node{{0.5, 0.0, 0.5}}, ceiling_node{{0.5, 2.0, 0.5}};
  // Floor, moving down (into the wall): both remove v_y.
  EXPECT_EQ(apply_boundary(slip, floor_node, kV), (Vec3d{{0.3, 0.0, 0.2}}));
  EXPECT_EQ(apply_boundary(sep, floor_node, kV), (Vec3d{{0.3, 0.0, 0.2}}));
  // Floor, moving up (away): slip still removes v_y, separable lets it go.
  const Vec3d up{{0.3, 0.7, 0.2}};
  EXPECT_EQ(apply_boundary(slip, floor_node, up), (Vec3d{{0.3, 0.0, 0.2}}));
  EXPECT_EQ(apply_boundary(sep, floor_node, up), up);
  // Ceiling: "into the wall" is +y.
  EXPECT_EQ(apply_boundary(sep, ceiling_node, up), (Vec3d{{0.3, 0.0, 0.2}}));
  EXPECT_EQ(apply_boundary(sep, ceiling_node, kV), kV);
  // Corner (x low, y low): both normals removed.
  const Vec3d into_corner{{-0.3, -0.7, 0.2}};
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.0, 0.0, 0.5}}, into_corner), (Vec3d{{0.0, 0.0, 0.2}}));
  // One cell inside the face the node is free; one cell outside it is still a normal-only node.
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.1, 0.5}}, kV), kV);
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, -0.1, 0.5}}, kV), (Vec3d{{0.3, 0.0, 0.2}}));
  // 1.5 dx or more outside a face every component is held, for Slip and Separable alike.
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, -0.2, 0.5}}, kV), Vec3d::zero());
  EXPECT_EQ(apply_boundary(sep, Vec3d{{0.5, -0.2, 0.5}}, up), Vec3d::zero());
  EXPECT_EQ(apply_boundary(sep, Vec3d{{1.15, 1.0, 0.5}}, kV), Vec3d::zero());
}

TEST(Boundary, WallsUseTheirOwnBox) {
  const auto b = make(BoundaryObject::Walls, Contact::Slip, {0.2, 0.2, 0.2}, {0.8, 1.6, 0.8});
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.2, 1.0, 0.5}}, kV), (Vec3d{{0.0, -0.7, 0.2}}));  // on the x face
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.3, 1.0, 0.5}}, kV), kV);                          // 0.1 inside it
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.5, 1.0, 0.5}}, kV), kV);
}

// Particles may stand up to kDomainMarginCells cells outside simulation.domain (material fills Walls to the faces).
TEST(Boundary, DomainMarginOfEightCells) {
  const Vec3d domain{{1.0, 2.0, 1.0}};
  EXPECT_TRUE(inside_domain(Vec3d{{-0.79, 1.0, 0.5}}, domain, 0.1));
  EXPECT_TRUE(inside_domain(Vec3d{{0.5, 2.79, 0.5}}, domain, 0.1));
  EXPECT_FALSE(inside_domain(Vec3d{{-0.81, 1.0, 0.5}}, domain, 0.1));
  EXPECT_FALSE(inside_domain(Vec3d{{0.5, 1.0, 1.81}}, domain, 0.1));
}

TEST(Boundary, BoxObstacleNearestFaceNormal) {
  const auto slip = make(BoundaryObject::Box, Contact::Slip, {0.4, 0.0, 0.4}, {0.6, 0.5, 0.6});
  const auto sep = make(BoundaryObject::Box, Contact::Separable, {0.4, 0.0, 0.4}, {0.6, 0.5, 0.6});
  const auto stick = make(BoundaryObject::Box, Contact::Sticky, {0.4, 0.0, 0.4}, {0.6, 0.5, 0.6});
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.3, 0.2, 0.5}}, kV), kV);                          // outside
  EXPECT_EQ(apply_boundary(stick, Vec3d{{0.5, 0.2, 0.5}}, kV), Vec3d::zero());              // inside
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.48, 0.5}}, kV), (Vec3d{{0.3, 0.0, 0.2}}));   // top face nearest
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.41, 0.2, 0.5}}, kV), (Vec3d{{0.0, -0.7, 0.2}}));  // x-low face nearest
  // No held core (ClaymoreUW holds nodes 0.99 dx inside every face): a deep node keeps its tangential velocity.
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.2, 0.5}}, kV), (Vec3d{{0.0, -0.7, 0.2}}));  // x-low face nearest (tie)
  // Separable at the top face: falling (into the box) is stopped, rising is free.
  EXPECT_EQ(apply_boundary(sep, Vec3d{{0.5, 0.48, 0.5}}, kV), (Vec3d{{0.3, 0.0, 0.2}}));
  const Vec3d up{{0.3, 0.7, 0.2}};
  EXPECT_EQ(apply_boundary(sep, Vec3d{{0.5, 0.48, 0.5}}, up), up);
  // x-low face: moving +x is into the box.
  EXPECT_EQ(apply_boundary(sep, Vec3d{{0.41, 0.2, 0.5}}, kV), (Vec3d{{0.0, -0.7, 0.2}}));
  EXPECT_EQ(apply_boundary(sep, Vec3d{{0.41, 0.2, 0.5}}, -kV), -kV);
}

// Coulomb friction on the grid: |v_t| <= mu_s |v_n| sticks, otherwise |v_t| shrinks by mu_d |v_n|.
TEST(Boundary, CoulombFriction) {
  BoundarySpec spec;
  spec.object = BoundaryObject::Walls;
  spec.contact = Contact::Slip;
  spec.friction_static = 0.5;
  spec.friction_dynamic = 0.2;
  BoundaryParams<double> b{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
  const Vec3d floor_node{{0.5, 0.0, 0.5}};  // on the floor's face
  // v_n = -1 (into the floor), |v_t| = 0.4 <= 0.5: sticks.
  EXPECT_EQ(apply_boundary(b, floor_node, Vec3d{{0.4, -1.0, 0.0}}), Vec3d::zero());
  // |v_t| = 2 > 0.5: slides with |v_t| = 2 - 0.2 = 1.8 in the same direction.
  const Vec3d v = apply_boundary(b, floor_node, Vec3d{{1.2, -1.0, 1.6}});
  EXPECT_NEAR(v[0], 1.2 * 0.9, 4 * kEps);
  EXPECT_EQ(v[1], 0.0);
  EXPECT_NEAR(v[2], 1.6 * 0.9, 4 * kEps);
  // Leaving the floor: no normal force, no friction (slip still removes v_n).
  EXPECT_EQ(apply_boundary(b, floor_node, Vec3d{{0.4, 1.0, 0.0}}), (Vec3d{{0.4, 0.0, 0.0}}));
}

TEST(Boundary, TimeWindowAndUnsupportedObjects) {
  BoundarySpec spec;
  spec.time = {0.5, 1.5};
  BoundaryParams<double> b{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
  EXPECT_FALSE(boundary_active(b, 0.49));
  EXPECT_TRUE(boundary_active(b, 0.5));
  EXPECT_TRUE(boundary_active(b, 1.5));
  EXPECT_FALSE(boundary_active(b, 1.51));
  spec.object = BoundaryObject::USGS_GATE;
  EXPECT_FALSE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
  EXPECT_NE(error.find("expand_boundary"), std::string::npos) << error;
  spec.object = BoundaryObject::Box;  // without extents
  EXPECT_FALSE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
}

// Sphere (ClaymoreUW: center = box midpoint, radius = half the x extent): inside nodes get the radial normal.
TEST(Boundary, SphereKeepsOutWithRadialNormal) {
  const auto slip = make(BoundaryObject::Sphere, Contact::Slip, {0.3, 0.3, 0.3}, {0.7, 0.7, 0.7});
  const auto stick = make(BoundaryObject::Sphere, Contact::Sticky, {0.3, 0.3, 0.3}, {0.7, 0.7, 0.7});
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.75, 0.5}}, kV), kV);  // above the ball (r = 0.25 > 0.2)
  EXPECT_EQ(apply_boundary(stick, Vec3d{{0.5, 0.6, 0.5}}, kV), Vec3d::zero());
  // On top (n = +y): falling is stopped, the tangential part kept.
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.65, 0.5}}, kV), (Vec3d{{0.3, 0.0, 0.2}}));
  // On the +x side at 45 degrees in x-y: the normal (1, 1, 0)/sqrt(2) component is removed.
  const double h = 0.1;
  const Vec3d v = apply_boundary(slip, Vec3d{{0.5 + h, 0.5 + h, 0.5}}, Vec3d{{-1.0, -1.0, 0.5}});
  EXPECT_NEAR(v[0], 0.0, 1e-15);
  EXPECT_NEAR(v[1], 0.0, 1e-15);
  EXPECT_EQ(v[2], 0.5);
}

// Cylinder (ClaymoreUW: along y from start_y to end_y, axis at the box center in x and z, radius half the x
// extent), with caps: a node near the top gets +y, one near the side the radial normal.
TEST(Boundary, CylinderAlongYWithCaps) {
  const auto slip = make(BoundaryObject::Cylinder, Contact::Slip, {0.4, 0.0, 0.4}, {0.6, 0.5, 0.6});
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.55, 0.5}}, kV), kV);                         // above
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.62, 0.2, 0.5}}, kV), kV);                         // beside
  EXPECT_EQ(apply_boundary(slip, Vec3d{{0.5, 0.48, 0.5}}, kV), (Vec3d{{0.3, 0.0, 0.2}}));  // under the top cap
  const Vec3d side = apply_boundary(slip, Vec3d{{0.59, 0.25, 0.5}}, kV);                    // near the +x side
  EXPECT_NEAR(side[0], 0.0, 1e-15);
  EXPECT_EQ(side[1], -0.7);
  EXPECT_EQ(side[2], 0.2);
}

// Floor: every node in its box gets n = +y. Plane: the line from (lo_x, lo_y) to (hi_x, hi_y), nodes below it.
TEST(Boundary, FloorAndDescendingPlane) {
  const auto floor = make(BoundaryObject::Floor, Contact::Separable, {0.0, 0.0, 0.0}, {1.0, 0.1, 1.0});
  EXPECT_EQ(apply_boundary(floor, Vec3d{{0.5, 0.05, 0.5}}, kV), (Vec3d{{0.3, 0.0, 0.2}}));
  EXPECT_EQ(apply_boundary(floor, Vec3d{{0.5, 0.15, 0.5}}, kV), kV);
  // A 45-degree ramp descending from (0, 1) to (1, 0): normal (1, 1)/sqrt(2).
  const auto ramp = make(BoundaryObject::Plane, Contact::Slip, {0.0, 1.0, 0.0}, {1.0, 0.0, 1.0});
  EXPECT_EQ(apply_boundary(ramp, Vec3d{{0.5, 0.65, 0.5}}, kV), kV);  // above the line and its one-cell band
  // Within the band (0.07 above the line, dx = 0.1): moving into the ramp, its normal part is removed.
  EXPECT_FALSE(apply_boundary(ramp, Vec3d{{0.5, 0.6, 0.5}}, kV) == kV);
  const Vec3d v = apply_boundary(ramp, Vec3d{{0.5, 0.4, 0.5}}, Vec3d{{-1.0, -1.0, 0.3}});
  EXPECT_NEAR(v[0], 0.0, 1e-15);
  EXPECT_NEAR(v[1], 0.0, 1e-15);
  EXPECT_EQ(v[2], 0.3);
  EXPECT_EQ(apply_boundary(ramp, Vec3d{{1.0, -0.5, 0.5}}, kV), kV);  // beyond its x range [0, 1)
}

// Boundary arrays (ClaymoreUW's array / spacing): copies translated by (i sx, j sy, k sz).
TEST(Boundary, ArraysRepeatTheObject) {
  BoundarySpec spec;
  spec.object = BoundaryObject::Cylinder;
  spec.contact = Contact::Sticky;
  spec.domain_start = {0.1, 0.0, 0.1};
  spec.domain_end = {0.2, 0.5, 0.2};
  spec.array = {3, 1, 2};
  spec.spacing = {0.3, 0.0, 0.4};
  BoundaryParams<double> b{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error)) << error;
  const std::vector<BoundaryParams<double>> copies = boundary_array(b, spec);
  ASSERT_EQ(copies.size(), 6u);
  EXPECT_NEAR(copies[5].lo[0], 0.1 + 2 * 0.3, 1e-15);  // (i, k) = (2, 1)
  EXPECT_NEAR(copies[5].lo[2], 0.1 + 0.4, 1e-15);
  EXPECT_EQ(copies[5].lo[1], 0.0);
  // The third column along x holds the node at its axis; the first one does not.
  const Vec3d node{{0.75, 0.2, 0.55}};
  EXPECT_EQ(apply_boundary(copies[5], node, kV), Vec3d::zero());
  EXPECT_EQ(apply_boundary(copies[0], node, kV), kV);
}

// Bathymetry: the bed through its points (flat beyond the ends), material above, the segment's normal below it.
TEST(Boundary, BathymetryFollowsItsProfile) {
  BoundarySpec spec;
  spec.object = BoundaryObject::Bathymetry;
  spec.contact = Contact::Slip;
  spec.bathymetry = {{0.2, 0.1}, {0.6, 0.3}, {0.8, 0.3}};  // flat, a 1:2 slope up, flat
  BoundaryParams<double> b{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error)) << error;
  BoundaryProfiles<double> profiles;
  b.profile_first = 0;
  b.profile_count = 3;
  for (int i = 0; i < 3; ++i) {
    profiles.x[i] = spec.bathymetry[static_cast<std::size_t>(i)][0];
    profiles.y[i] = spec.bathymetry[static_cast<std::size_t>(i)][1];
  }
  profiles.count = 3;
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.1, 0.15, 0.5}}, kV, &profiles), kV);  // above the flat start
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.1, 0.05, 0.5}}, kV, &profiles), (Vec3d{{0.3, 0.0, 0.2}}));
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.4, 0.32, 0.5}}, kV, &profiles), kV);  // a cell above the slope (bed 0.2)
  EXPECT_FALSE(apply_boundary(b, Vec3d{{0.4, 0.25, 0.5}}, kV, &profiles) == kV);  // in its band (dx = 0.1)
  // Below the slope: moving along +x runs into it; the component along its normal (-1, 2)/sqrt(5) is removed:
  // (2, 0) - (-2/sqrt(5)) (-1, 2)/sqrt(5) = (1.6, 0.8), along the slope.
  const Vec3d v = apply_boundary(b, Vec3d{{0.4, 0.15, 0.5}}, Vec3d{{2.0, 0.0, 0.3}}, &profiles);
  EXPECT_NEAR(v[0], 1.6, 1e-15);
  EXPECT_NEAR(v[1], 0.8, 1e-15);
  EXPECT_EQ(v[2], 0.3);
  EXPECT_EQ(apply_boundary(b, Vec3d{{0.9, 0.35, 0.5}}, kV, &profiles), kV);   // above the flat end
  spec.bathymetry.resize(1);
  EXPECT_FALSE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
}

// The OSU Large Wave Flume bed (OSU_LWF_RAMP without custom points): ClaymoreUW's bed table (its OSU_LWF_RAMP grid
// kernel: 0.225 m up to 16.275 m, 1.15 m at 30.9 m, 1.75 m from 45.525 m to 82.1 m, 2.35 m from 89.45 m, with the
// wave maker's neutral position at x = 2 m), placed 2 m (x s) after domain_start (x, y) and Froude-scaled.
TEST(Boundary, OsuLwfRampIsTheFlumeBed) {
  for (const double s : {1.0, 0.1}) {
    Scene scene;
    scene.simulation.dx = 0.05 * s;
    scene.simulation.domain = {100.0 * s + 2.0, 5.0, 1.0};
    scene.simulation.froude_scaling = s;
    BoundarySpec ramp;
    ramp.object = BoundaryObject::OSU_LWF_RAMP;
    ramp.contact = Contact::Slip;
    ramp.domain_start = {1.0, 0.5, 0.0};
    ramp.domain_end = {100.0 * s + 1.0, 4.0, 1.0};
    scene.boundaries.push_back(ramp);
    const RunConstants<double> k(scene, "test");
    ASSERT_EQ(k.boundaries.size(), 1u);
    const BoundaryParams<double>& b = k.boundaries[0];
    // (x from domain_start at full scale, bed height) as ClaymoreUW's kernel has them for domain_start 0: flat
    // 0.225 m before and after the wave maker (x = 2 m), 1:11.86 to 1.15 m at 30.9 m, 1:24.375 to 1.75 m at
    // 45.525 m, 1:12.25 from 82.1 m to 2.35 m at 89.45 m. A node 1 mm below the bed is projected, one that is more
    // than a cell above it (the band over slopes, kBedLayerCells) is not.
    for (const auto& [x, y] : std::vector<std::pair<double, double>>{{0.5, 0.225},
                                                                     {12.0, 0.225},
                                                                     {18.0, 0.225},
                                                                     {30.9, 1.15},
                                                                     {38.2125, 1.15 + 0.6 / 2},
                                                                     {60.0, 1.75},
                                                                     {85.775, 1.75 + 0.6 / 2},
                                                                     {97.0, 2.35}}) {
      const double xs = 1.0 + x * s, ys = 0.5 + y * s;
      EXPECT_EQ(apply_boundary(b, Vec3d{{xs, ys + scene.simulation.dx + 1e-3 * s, 0.5}}, kV, &k.profiles), kV)
          << s << " " << x;
      EXPECT_FALSE(apply_boundary(b, Vec3d{{xs, ys - 1e-3 * s, 0.5}}, kV, &k.profiles) == kV) << s << " " << x;
    }
  }
}

// A moving boundary translates by v_b (t - t_begin), and contact acts on the velocity relative to it: a Sticky
// box carries its nodes along, a Separable one pushes what is in front of it.
TEST(Boundary, MovingBoundaryTranslatesAndActsOnRelativeVelocity) {
  BoundarySpec spec;
  spec.object = BoundaryObject::Box;
  spec.contact = Contact::Separable;
  spec.domain_start = {0.0, 0.0, 0.0};
  spec.domain_end = {0.2, 1.0, 1.0};
  spec.velocity = {0.5, 0.0, 0.0};
  spec.time = {1.0, 10.0};
  BoundaryParams<double> b{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error)) << error;
  const BoundaryParams<double> at3 = boundary_at(b, 3.0);  // moved 1 m along x
  EXPECT_NEAR(at3.lo[0], 1.0, 1e-15);
  EXPECT_NEAR(at3.hi[0], 1.2, 1e-15);
  EXPECT_EQ(boundary_at(b, 0.5).lo[0], 0.0);  // before its window: where it starts
  const Vec3d node{{1.19, 0.5, 0.5}};         // just behind its +x face
  // At rest in front of the piston: pushed to the piston's speed along x.
  EXPECT_EQ(apply_boundary(at3, node, Vec3d::zero()), (Vec3d{{0.5, 0.0, 0.0}}));
  // Faster than the piston, away from it: untouched.
  EXPECT_EQ(apply_boundary(at3, node, Vec3d{{0.8, 0.1, 0.0}}), (Vec3d{{0.8, 0.1, 0.0}}));
  spec.contact = Contact::Sticky;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
  EXPECT_EQ(apply_boundary(boundary_at(b, 3.0), node, kV), (Vec3d{{0.5, 0.0, 0.0}}));
  // A Velocity region imposes its velocity.
  spec.object = BoundaryObject::Velocity;
  spec.velocity = {0.0, 0.0, -2.0};
  spec.time = {0.0, 10.0};
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.1).dx, unit_sim(0.1).domain, b, error));
  EXPECT_EQ(apply_boundary(boundary_at(b, 0.0), Vec3d{{0.1, 0.5, 0.5}}, kV), (Vec3d{{0.0, 0.0, -2.0}}));
}

// A turning boundary (angular_velocity about rotation_center): its shape at t_begin's orientation turned by
// |omega| (t - t_begin); a Sticky node inside takes the surface's velocity omega x r (+ v_b), a node inside the
// unturned box but outside the turned one is left alone, Slip removes the normal part of the velocity relative to
// the turning surface, and the centre translates with the boundary.
TEST(Boundary, TurningBoxActsWhereItIsWithItsSurfaceVelocity) {
  BoundarySpec spec;
  spec.object = BoundaryObject::Box;
  spec.contact = Contact::Sticky;
  spec.domain_start = {0.4, 0.4, 0.4};
  spec.domain_end = {0.6, 0.6, 0.6};
  spec.angular_velocity = {0.0, 0.0, 2.0};  // rad/s about z
  spec.rotation_center = {0.5, 0.5, 0.5};
  spec.time = {1.0, 10.0};
  BoundaryParams<double> b{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.01).dx, unit_sim(0.01).domain, b, error)) << error;
  const double t = 1.0 + std::acos(-1.0) / 8.0;  // 45 degrees after t_begin
  const BoundaryParams<double> at = boundary_at(b, t);
  EXPECT_NEAR(at.rotation.m[0][0], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(at.rotation.m[1][0], std::sqrt(0.5), 1e-15);  // x turns towards y
  const Vec3d corner{{0.63, 0.5, 0.5}};  // beyond the unturned +x face, inside the turned box (its corner)
  const Vec3d omega_r{{0.0, 2.0 * 0.13, 0.0}};
  const Vec3d v = apply_boundary(at, corner, kV);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(v[a], omega_r[a], 1e-12) << a;
  const Vec3d cut{{0.595, 0.595, 0.5}};  // inside the unturned box, outside the turned one
  EXPECT_EQ(apply_boundary(at, cut, kV), kV);
  // At t_begin it has not turned: the same node is outside.
  EXPECT_EQ(apply_boundary(boundary_at(b, 1.0), corner, kV), kV);
  // Slip on the turned +x face (normal n = (1, 1, 0) / sqrt 2): a node at rest just inside it, off the diagonal
  // (box-frame offset (0.099, 0.05) from the centre), where the surface moves into the material at
  // (omega x r) . n = -2 x 0.05 m/s, is pushed along n with the surface and keeps its (zero) tangential velocity.
  spec.contact = Contact::Slip;
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.01).dx, unit_sim(0.01).domain, b, error)) << error;
  const double c45 = std::sqrt(0.5);
  const Vec3d n{{c45, c45, 0.0}}, tangent{{-c45, c45, 0.0}};
  const Vec3d face = Vec3d{{0.5, 0.5, 0.5}} + n * 0.099 + tangent * 0.05;
  const Vec3d w = apply_boundary(boundary_at(b, t), face, Vec3d::zero());
  EXPECT_NEAR(dot(w, n), -0.1, 1e-12);
  EXPECT_NEAR(dot(w, tangent), 0.0, 1e-12);
  EXPECT_NEAR(w[2], 0.0, 1e-12);
  // Translating as well: the centre moves with the boundary.
  spec.velocity = {0.1, 0.0, 0.0};
  ASSERT_TRUE(make_boundary_params(spec, unit_sim(0.01).dx, unit_sim(0.01).domain, b, error)) << error;
  EXPECT_NEAR(boundary_at(b, 3.0).pivot[0], 0.7, 1e-15);
  // A pump does not turn.
  spec.object = BoundaryObject::Pump;
  EXPECT_FALSE(make_boundary_params(spec, unit_sim(0.01).dx, unit_sim(0.01).domain, b, error));
  EXPECT_NE(error.find("does not turn"), std::string::npos) << error;
}

// Motion files (physics/motion_path.h): rows time, displacement, velocity; linear between rows, held outside them;
// Froude scaling by s: times and velocities x sqrt(s), displacements x s; the scene's rate must match the rows.
TEST(MotionPath, InterpolatesHoldsScalesAndChecks) {
  const std::string file = ::testing::TempDir() + "fbar_motion_test.csv";
  {
    std::ofstream out(file);
    out << "time,displacement,velocity\n0.0,0.0,0.0\n0.5,0.1,0.4\n1.0,0.3,0.4\n";
  }
  const MotionPath m = MotionPath::load(file, 1.0, 2.0, "boundaries[0].file");
  double d = 0, v = 0;
  m.at(0.25, d, v);
  EXPECT_DOUBLE_EQ(d, 0.05);
  EXPECT_DOUBLE_EQ(v, 0.2);
  m.at(-1.0, d, v);
  EXPECT_EQ(d, 0.0);
  m.at(7.0, d, v);  // after the last row: held
  EXPECT_EQ(d, 0.3);
  EXPECT_EQ(v, 0.4);
  const MotionPath f = MotionPath::load(file, 4.0, 1.0, "boundaries[0].file");  // s = 4: rows 1 s apart
  EXPECT_DOUBLE_EQ(f.t[1], 1.0);
  EXPECT_DOUBLE_EQ(f.d[2], 1.2);
  EXPECT_DOUBLE_EQ(f.v[1], 0.8);
  try {
    MotionPath::load(file, 1.0, 120.0, "boundaries[0].file");
    FAIL() << "a rate that does not match the rows must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("are 2 Hz apart"), std::string::npos) << e.what();
  }
  {
    std::ofstream out(file);
    out << "0,0,0\n0.5,0.1\n";
  }
  EXPECT_THROW(MotionPath::load(file, 1.0, 2.0, "boundaries[0].file"), std::invalid_argument);
  std::remove(file.c_str());
}

// ------------------------------------------------------------------------------------------------ time step

TEST(TimeStep, CflBound) {
  // dt = CFL dx / (c + |v|max): 0.5 * 0.01 / (100 + 0) = 5e-5 s; with |v|max = 25: 4e-5 s.
  EXPECT_DOUBLE_EQ(cfl_time_step(0.5, 0.01, 100.0, 0.0), 5e-5);
  EXPECT_DOUBLE_EQ(cfl_time_step(0.5, 0.01, 100.0, 25.0), 4e-5);
  // CFL above 0.5: the acoustic part stays at c dt / dx = 0.5 (a lone particle's limit is 1 / sqrt(3)); CFL 1 gives
  // 1e-4 s by the flow bound and 5e-5 s by the cap. Fast flow still binds below the cap: |v| = 150 -> 4e-5 s.
  EXPECT_DOUBLE_EQ(cfl_time_step(1.0, 0.01, 100.0, 0.0), 5e-5);
  EXPECT_DOUBLE_EQ(cfl_time_step(1.0, 0.01, 100.0, 150.0), 4e-5);
  EXPECT_DOUBLE_EQ(cfl_time_step(0.9, 0.01, 0.0, 10.0), 9e-4);  // no wave speed: the flow bound alone
  EXPECT_DOUBLE_EQ(min_time_step(1e-4, 4e-5), 4e-5);
  EXPECT_DOUBLE_EQ(min_time_step(1e-5, 4e-5), 1e-5);
  EXPECT_DOUBLE_EQ(min_time_step(1e-5, std::numeric_limits<double>::quiet_NaN()), 1e-5);
  SimulationSpec sim;
  sim.dx = 0.02;
  sim.default_dt = 0.0;
  EXPECT_DOUBLE_EQ(resolved_default_dt(sim), 2e-4);  // absent: dx / 100 (SCHEMA.md)
  sim.default_dt = 3e-4;
  EXPECT_DOUBLE_EQ(resolved_default_dt(sim), 3e-4);
}

}  // namespace
}  // namespace fbar

namespace fbar {
namespace {

// transfer.cuh ASFLIP update (Fei et al. 2021): alpha = beta = 0 is APIC bit for bit; alpha = 1 is FLIP's velocity
// v_p + (v_pic - v_old); beta_max acts on dilated particles (J >= 1), beta_min on compressed ones.
TEST(Asflip, UpdateFormulas) {
  const Vec3d vp{{1.0, -2.0, 0.5}}, vpic{{0.8, -1.5, 0.25}}, vold{{0.9, -1.75, 0.375}};
  const double dt = 1e-3;
  const AsflipUpdate<double> apic = asflip_update(AsflipParams<double>{0, 0, 0}, vp, vpic, vold, 1.01, dt);
  EXPECT_EQ(apic.v, vpic);
  EXPECT_EQ(apic.move, vpic * dt);
  const AsflipUpdate<double> flip = asflip_update(AsflipParams<double>{1, 0, 0}, vp, vpic, vold, 0.99, dt);
  EXPECT_LE(max_abs(flip.v - (vp + (vpic - vold))), 4e-16);
  const AsflipParams<double> a{0.5, 0.1, 0.3};
  const AsflipUpdate<double> dilated = asflip_update(a, vp, vpic, vold, 1.0, dt);
  const AsflipUpdate<double> compressed = asflip_update(a, vp, vpic, vold, 0.999, dt);
  EXPECT_LE(max_abs(dilated.v - (vpic + (vp - vold) * 0.5)), 4e-16);
  EXPECT_LE(max_abs(dilated.move - (vpic + (vp - vold) * 0.3) * dt), 1e-18);
  EXPECT_LE(max_abs(compressed.move - (vpic + (vp - vold) * 0.1) * dt), 1e-18);
  // Uniform motion (v_p = v_old): every scheme moves with v_pic.
  const AsflipUpdate<double> uniform = asflip_update(a, vold, vpic, vold, 1.2, dt);
  EXPECT_EQ(uniform.v, vpic);
  EXPECT_EQ(uniform.move, vpic * dt);
}

// transfer.cuh F-bar: C' = C + kappa I. JFluid's exact update J (1 + dt tr C') must land on the line
// ((1 - psi) J + psi Jbar)(1 + dt tr C) to round-off, for any psi; the deviatoric part is C's; a particle at its
// cell's mean (or psi = 0) keeps C; the cell of a particle is base + 0 or 1 per axis; an empty cell has mean 0.
TEST(Fbar, VelocityGradientAndCell) {
  Mat3d C = Mat3d::zero();
  C(0, 0) = 0.3, C(0, 1) = -1.2, C(1, 0) = 0.4, C(1, 1) = -0.1, C(2, 2) = 0.7, C(2, 0) = 0.25;
  const double trC = 0.9, dt = 1e-4;
  const double one_minus_J = 2e-5, cell = -3e-5;  // J = 0.99998, Jbar = 1.00003
  for (const double psi : {0.0, 0.25, 0.96, 1.0}) {
    const Mat3d Cp = fbar_velocity_gradient(C, one_minus_J, cell, psi, dt);
    const double J_new = (1 - one_minus_J) * (1 + dt * (Cp(0, 0) + Cp(1, 1) + Cp(2, 2)));
    const double expected = ((1 - psi) * (1 - one_minus_J) + psi * (1 - cell)) * (1 + dt * trC);
    EXPECT_NEAR(J_new, expected, 1e-15) << psi;
    const Mat3d diff = Cp - C;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (a != b) {
          EXPECT_EQ(diff(a, b), 0.0) << psi << " " << a << b;
        }
    EXPECT_NEAR(diff(0, 0), diff(1, 1), 1e-15);
    EXPECT_NEAR(diff(1, 1), diff(2, 2), 1e-15);
  }
  EXPECT_EQ(max_abs(fbar_velocity_gradient(C, one_minus_J, one_minus_J, 1.0, dt) - C), 0.0);
  EXPECT_EQ(max_abs(fbar_velocity_gradient(C, one_minus_J, cell, 0.0, dt) - C), 0.0);
  // F-bar reads 1 - J through one_minus_volume_ratio: JFluid's stored value exactly (in float, 1 - (1 - u) would
  // keep 1e-7 only to the quantum of J near 1, 6e-8), every other law's 1 - volume_ratio.
  const JFluidState<float> fluid{1e-7f};
  EXPECT_EQ(one_minus_volume_ratio<JFluid>(fluid), 1e-7f);
  EXPECT_NE(1.0f - JFluid::volume_ratio(fluid), 1e-7f);
  FixedCorotatedState<double> solid{Mat3d::identity()};
  solid.F(0, 0) = 1.01;
  EXPECT_DOUBLE_EQ(one_minus_volume_ratio<FixedCorotated>(solid), 1.0 - FixedCorotated::volume_ratio(solid));
  EXPECT_EQ(fbar_cell_compression(0.0, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(fbar_cell_compression(3e-12, 2e-6), 1.5e-6);
  const double dx = 0.1;
  for (const double x : {0.05, 0.0999, 0.1, 0.149, 0.15, 0.1999, 1.234}) {
    const Vec3d p{{x, x + 0.04, x + 0.07}};
    const QuadraticBspline<double> s = quadratic_bspline_inv(p, 1.0 / dx);
    const Vec3i c = fbar_cell_offset(p, 1.0 / dx, s.base);
    for (int a = 0; a < 3; ++a) {
      EXPECT_TRUE(c[a] == 0 || c[a] == 1) << x;
      EXPECT_EQ(s.base[a] + c[a], static_cast<int>(std::floor(p[a] / dx))) << x;
    }
  }
}

}  // namespace
}  // namespace fbar

namespace fbar {
namespace {

/// The velocity of a node after every active boundary of a scene at time t (as both engines apply them).
Vec3d after_boundaries(const RunConstants<double>& k, const Vec3d& x, Vec3d v, double t) {
  for (std::size_t i = 0; i < k.boundaries.size(); ++i) {
    if (!boundary_active(k.boundaries[i], t)) continue;
    v = apply_boundary(k.boundary_at_time(i, t), x, v, &k.profiles);
  }
  return v;
}

Scene facility_scene(BoundaryObject object, Contact contact, Real3 lo, Real3 hi, double s = 1.0) {
  Scene scene;
  scene.simulation.dx = 0.05 * s;
  scene.simulation.domain = {100.0 * s, 10.0 * s, 10.0 * s};
  scene.simulation.froude_scaling = s;
  BoundarySpec b;
  b.object = object;
  b.contact = contact;
  b.domain_start = lo;
  b.domain_end = hi;
  scene.boundaries.push_back(b);
  return scene;
}

// A Piston (and the OSU paddles built on it) pushes along +x from its face: a Separable one brings slower nodes up
// to its speed and leaves faster ones; a Slip one sets the normal component and keeps the tangential ones.
TEST(FacilityBoundary, PaddlesArePistonsAlongX) {
  for (BoundaryObject paddle : {BoundaryObject::Piston, BoundaryObject::OSU_LWF_PADDLE, BoundaryObject::OSU_TWB_PADDLE}) {
    Scene scene = facility_scene(paddle, Contact::Separable, {0.0, 0.0, 0.0}, {1.0, 5.0, 5.0});
    scene.boundaries[0].velocity = {0.5, 0.0, 0.0};
    const RunConstants<double> k(scene, "test");
    ASSERT_EQ(k.boundaries.size(), 1u);
    const double t = 2.0;  // the face has moved to x = 2
    EXPECT_EQ(after_boundaries(k, Vec3d{{1.9, 1.0, 1.0}}, Vec3d{{0.1, -0.2, 0.3}}, t), (Vec3d{{0.5, -0.2, 0.3}}));
    EXPECT_EQ(after_boundaries(k, Vec3d{{1.9, 1.0, 1.0}}, Vec3d{{0.9, -0.2, 0.3}}, t), (Vec3d{{0.9, -0.2, 0.3}}));
    EXPECT_EQ(after_boundaries(k, Vec3d{{2.1, 1.0, 1.0}}, Vec3d{{0.1, -0.2, 0.3}}, t), (Vec3d{{0.1, -0.2, 0.3}}));
    scene.boundaries[0].contact = Contact::Slip;
    const RunConstants<double> slip(scene, "test");
    EXPECT_EQ(after_boundaries(slip, Vec3d{{1.9, 1.0, 1.0}}, Vec3d{{0.9, -0.2, 0.3}}, t), (Vec3d{{0.5, -0.2, 0.3}}));
  }
}

// The OSU TWB and USGS ramps are Bathymetry beds through the facility's stations, placed at domain_start and scaled.
TEST(FacilityBoundary, RampsFollowTheFacilityStations) {
  struct Case {
    BoundaryObject object;
    std::vector<std::pair<double, double>> stations;  // (x, bed height) at full scale
  };
  const std::vector<Case> cases = {
      {BoundaryObject::OSU_TWB_RAMP, {{5.0, 0.0}, {21.3, 0.5}, {31.3, 1.0}, {40.0, 1.0}}},
      {BoundaryObject::USGS_RAMP, {{50.0, 0.0}, {81.25, 1.25 / 5.675}, {82.5, 1.25 / 5.675 + 1.25 / 2.747},
                                   {90.0, 1.25 / 5.675 + 1.25 / 2.747 + 7.5 / 1.732}}}};
  for (const Case& c : cases)
    for (const double s : {1.0, 0.2}) {
      const Scene scene = facility_scene(c.object, Contact::Slip, {1.0 * s, 0.5 * s, 0.0}, {99.0 * s, 9.0 * s, 9.0 * s}, s);
      const RunConstants<double> k(scene, "test");
      for (const auto& [x, y] : c.stations) {
        const double xs = (1.0 + x) * s, ys = (0.5 + y) * s;
        EXPECT_EQ(after_boundaries(k, Vec3d{{xs, ys + scene.simulation.dx + 1e-3 * s, 1.0}}, kV, 0.0), kV)
            << to_string(c.object) << x;
        EXPECT_FALSE(after_boundaries(k, Vec3d{{xs, ys - 1e-3 * s, 1.0}}, kV, 0.0) == kV) << to_string(c.object) << x;
      }
    }
}

// The USGS gate against ClaymoreUW's rule, transcribed from mgmpm_kernels.cuh:2193-2225 (Separable, Froude scale 1,
// flume origin 0): a node with x >= 4.7 m or above the plate y = -tan 60 (x - 4.7) is in the gate; before 1 s every
// such node, from 1 s to 2 s those with z <= 4 - (t - 1) or z >= 4 + (t - 1), lose a velocity component into the
// plate's normal (-cos 30, -sin 30, 0); from 2 s nothing.
Vec3d claymore_usgs_gate(const Vec3d& x, Vec3d v, double t) {
  const double gate_y = -1.73205080757 * (x[0] - 4.7);
  if (!(x[0] >= 4.7 || x[1] >= gate_y) || t >= 2.0) return v;
  if (t >= 1.0 && x[2] > 4.0 - (t - 1.0) && x[2] < 4.0 + (t - 1.0)) return v;
  const Vec3d n{{-0.866025403784, -0.5, 0.0}};
  const double vn = dot(n, v);
  return vn < 0.0 ? v - n * vn : v;
}

// fbar's gate gives ClaymoreUW's velocities on every node above the flume bed (y >= 0) of a 3 m x 2.5 m x 3 m block
// around it, at times before, during and after the doors open; at Froude scale s it is the same gate with lengths
// x s and times x s^0.5 (ClaymoreUW's doors open at s m/s instead: the user guide's differences list).
TEST(FacilityBoundary, UsgsGateIsClaymoresSlantedPlateWithOpeningDoors) {
  const std::vector<Vec3d> probes = {Vec3d{{1.0, 0.2, 0.0}}, Vec3d{{-0.3, 0.8, 0.4}}, Vec3d{{0.6, -0.9, -0.2}},
                                     Vec3d{{-1.0, 0.0, 0.0}}};
  for (const double s : {1.0, 0.25}) {
    const double ts = std::sqrt(s);
    Scene scene = facility_scene(BoundaryObject::USGS_GATE, Contact::Separable, {0.0, 0.0, 0.0}, {10.0, 10.0, 10.0}, s);
    const RunConstants<double> k(scene, "test");
    int held = 0, free = 0;
    for (const double t : {0.0, 0.6, 0.99, 1.2, 1.55, 1.9, 2.0, 2.4})
      for (double x = 3.5125; x < 6.5; x += 0.125)
        for (double y = 0.0125; y < 2.5; y += 0.125)
          for (double z = 2.5125; z < 5.5; z += 0.125)
            for (const Vec3d& v : probes) {
              const Vec3d want = claymore_usgs_gate(Vec3d{{x, y, z}}, v, t);
              const Vec3d got = after_boundaries(k, Vec3d{{x * s, y * s, z * s}}, v * ts, t * ts) * (1.0 / ts);
              for (int a = 0; a < 3; ++a)
                ASSERT_NEAR(got[a], want[a], 1e-9) << "s " << s << " t " << t << " node " << x << " " << y << " " << z;
              (want == v ? free : held) += 1;
            }
    EXPECT_GT(held, 1000);  // the comparison saw both sides of the plate and of the doors
    EXPECT_GT(free, 1000);
  }
}

// The Waseda (Tokyo) harbour: an apron 0.255 m high from 4.45 m behind domain_start; a WASIRF pump drives its box.
TEST(FacilityBoundary, HarbourQuayAndPump) {
  const RunConstants<double> harbour(
      facility_scene(BoundaryObject::TOKYO_HARBOR, Contact::Slip, {1.0, 0.2, 0.0}, {9.0, 2.0, 4.0}), "test");
  const Vec3d down{{0.0, -1.0, 0.0}};
  EXPECT_EQ(after_boundaries(harbour, Vec3d{{6.0, 0.2 + 0.25, 1.0}}, down, 0.0), Vec3d::zero());  // on the apron
  EXPECT_EQ(after_boundaries(harbour, Vec3d{{6.0, 0.2 + 0.30, 1.0}}, down, 0.0), down);           // above it
  EXPECT_EQ(after_boundaries(harbour, Vec3d{{5.3, 0.2 + 0.1, 1.0}}, down, 0.0), down);            // in front
  // Just behind the quay face (its nearest face): a node moving into the quay loses that motion.
  EXPECT_EQ(after_boundaries(harbour, Vec3d{{5.46, 0.25, 1.0}}, Vec3d{{1.0, 0.0, 0.0}}, 0.0), Vec3d::zero());

  Scene pump = facility_scene(BoundaryObject::WASIRF_PUMP, Contact::Separable, {1.0, 0.0, 0.0}, {2.0, 1.0, 1.0});
  pump.boundaries[0].velocity = {0.8, 0.0, -0.2};
  const RunConstants<double> k(pump, "test");
  EXPECT_EQ(after_boundaries(k, Vec3d{{1.5, 0.5, 0.5}}, Vec3d{{0.1, 0.3, 0.0}}, 5.0), (Vec3d{{0.8, 0.3, -0.2}}));
  EXPECT_EQ(after_boundaries(k, Vec3d{{1.5, 0.5, 0.5}}, Vec3d{{1.2, 0.3, -0.5}}, 5.0), (Vec3d{{1.2, 0.3, -0.5}}));
  EXPECT_EQ(after_boundaries(k, Vec3d{{2.5, 0.5, 0.5}}, Vec3d{{0.1, 0.3, 0.0}}, 5.0), (Vec3d{{0.1, 0.3, 0.0}}));
}

}  // namespace
}  // namespace fbar
