// The CPU reference engine against its walls: obstacles, separable and sticky contact, inclines, pistons (constant
// and from a motion file), bathymetry beds, still water on a slope.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "scene/scene_parse.h"
#include "../../physics/physics_test_support.h"
#include "scene/facilities.h"

namespace fbar {
namespace {

using test::box_body;
using test::empty_scene;
using test::r3;
// A Sticky Box turning at omega = 1 rad/s about z through the centre of the elastic block it holds (the box 2 dx
// wider than the block on every side, no gravity): the block turns with it as a rigid body. After 0.5 s every
// particle has turned by 0.5 rad about the centre (each particle's angle within 1 %) and kept its distance from the
// axis (0.5 % of the block's half-width), and the block's angular momentum about z is I omega (2 %).
TEST(Boundary, TurningStickyBoxTurnsTheBlockItHolds) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.04, r3(0, 0, 0));
  BodySpec block = box_body(Constitutive::FixedCorotated, r3(0.38, 0.38, 0.38), r3(0.24, 0.24, 0.24));
  block.material.youngs_modulus = 1e5;
  scene.bodies.push_back(block);
  BoundarySpec box;
  box.object = BoundaryObject::Box;
  box.contact = Contact::Sticky;
  box.domain_start = {0.30, 0.30, 0.30};
  box.domain_end = {0.70, 0.70, 0.70};
  box.angular_velocity = {0.0, 0.0, 1.0};
  box.rotation_center = {0.5, 0.5, 0.5};
  scene.boundaries.push_back(box);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const std::vector<Vec3d> x0 = engine.positions(0);
  ASSERT_TRUE(engine.advance_to(0.5).ok);
  const std::vector<Vec3d> x1 = engine.positions(0);
  double worst_angle = 0.0, worst_radius = 0.0, lz = 0.0, inertia = 0.0;
  for (std::size_t i = 0; i < x0.size(); ++i) {
    const double a0 = std::atan2(x0[i][1] - 0.5, x0[i][0] - 0.5), a1 = std::atan2(x1[i][1] - 0.5, x1[i][0] - 0.5);
    const double r0 = std::hypot(x0[i][0] - 0.5, x0[i][1] - 0.5), r1 = std::hypot(x1[i][0] - 0.5, x1[i][1] - 0.5);
    worst_angle = std::max(worst_angle, std::fabs(std::remainder(a1 - a0, 2.0 * std::acos(-1.0)) - 0.5));
    worst_radius = std::max(worst_radius, std::fabs(r1 - r0));
    const double m = engine.masses(0)[i];
    const Vec3d& v = engine.velocities(0)[i];
    lz += m * ((x1[i][0] - 0.5) * v[1] - (x1[i][1] - 0.5) * v[0]);
    inertia += m * r1 * r1;
  }
  std::printf("[measured] turning sticky box: worst angle error %.2e rad of 0.5, worst radius change %.2e m, "
              "L_z / (I omega) %.4f\n", worst_angle, worst_radius, lz / inertia);
  EXPECT_LT(worst_angle, 0.005);
  EXPECT_LT(worst_radius, 0.005 * 0.12);
  EXPECT_NEAR(lz / inertia, 1.0, 0.02);
}

// A Box obstacle under a falling block: no particle enters it. Its top face is y = 0.3 (a node plane); a particle's
// stencil reaches the obstacle's nodes only below y = 0.3 + 1.5 dx, so the lowest particle must get below that
// (contact happened) and stay above 0.3 (nothing entered), checked after every step. The block is elastic
// (E 1e6 Pa) and Sticky contact is not adhesive (the ball test below): it does not come to rest but bounces
// (measured: v_cm,y -1.59 m/s at the first impact, +1.33 m/s after it, restitution 0.84; at t = 0.5 s it is near the
// top of its second bounce). Asserted for the bounce: the centre of mass reverses (rebound > 0) and leaves no faster
// than it arrived (restitution <= 1: a wall that only zeroes node velocities cannot add energy; budget 0).
TEST(Boundary, FallingBlockBouncesOnBoxObstacleAndNeverEntersIt) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.4, 0.4, 0.4), r3(0.1, 0.1, 0.1), r3(0, -1, 0)));
  BoundarySpec box;
  box.object = BoundaryObject::Box;
  box.contact = Contact::Sticky;
  box.domain_start = {0.2, 0.1, 0.2};
  box.domain_end = {0.8, 0.3, 0.8};
  scene.boundaries.push_back(box);
  CpuEngine<double> engine(scene);
  double y_min = 1.0, v_in = 0.0, v_out = 0.0;  // impact: most negative v_cm,y before it first turns upward
  bool rebounding = false;
  while (engine.time() < 0.25) {  // the first bounce: impact at 0.065 s, apex at 0.21 s
    ASSERT_TRUE(engine.step().ok);
    for (const Vec3d& x : engine.positions(0)) y_min = std::min(y_min, x[1]);
    double m = 0, p = 0;
    for (std::size_t i = 0; i < engine.particle_count(0); ++i)
      m += engine.masses(0)[i], p += engine.masses(0)[i] * engine.velocities(0)[i][1];
    const double v_cm = p / m;
    rebounding = rebounding || v_cm > 0;
    if (!rebounding) v_in = std::min(v_in, v_cm);
    else v_out = std::max(v_out, v_cm);
  }
  std::printf("[measured] block on box obstacle: lowest particle y = %.5f m (top face 0.3); v_cm,y %.4f m/s at the "
              "impact, %.4f m/s after it (restitution %.3f)\n", y_min, v_in, v_out, v_out / -v_in);
  EXPECT_GT(y_min, 0.3);
  EXPECT_LT(y_min, 0.3 + 1.5 * 0.02);
  EXPECT_GT(v_out, 0.0) << "no rebound";
  EXPECT_LE(v_out, -v_in) << "the block left faster than it arrived";
}

// A ball thrown obliquely at a wall (no gravity; an elastic FixedCorotated sphere of radius 0.1 m, E 1e5 Pa, at
// 1 m/s into the wall and 0.5 m/s along it). Separable contact removes only the velocity into the wall: the ball
// rebounds, leaves the wall's node layer and keeps its velocity along the wall. Sticky contact holds the wall's nodes
// at rest: the contact stops the ball's motion along the wall where it touches. A rigid ball whose contact point
// stops leaves rolling with 5/7 of its velocity along the wall; the elastic ball keeps less (measured: 0.51). Neither
// law is adhesive: an elastic ball rebounds from both (the grid nodes of the wall are held, the particles are not
// glued to them), which the normal velocity after the impact shows (measured: 0.96 and 0.97 of the impact speed).
TEST(Boundary, BallLeavesASeparableWallAndStopsSlidingAtAStickyOne) {
  const double dx = 0.02, wall = 0.1, vn = 1.0, vt = 0.5;
  for (Contact contact : {Contact::Separable, Contact::Sticky}) {
    Scene scene = empty_scene(r3(0.6, 1.0, 0.4), dx, r3(0, 0, 0));
    BodySpec ball = box_body(Constitutive::FixedCorotated, r3(0.2, 0.1, 0.1), r3(0.2, 0.2, 0.2), r3(-vn, vt, 0));
    ball.geometry[0].object = GeometryObject::Sphere;
    ball.geometry[0].radius = 0.1;
    ball.material.youngs_modulus = 1e5;
    scene.bodies.push_back(ball);
    BoundarySpec walls;
    walls.object = BoundaryObject::Walls;
    walls.contact = contact;
    walls.domain_start = r3(wall, 0.0, 0.0);
    walls.domain_end = r3(0.6, 1.0, 0.4);
    scene.boundaries.push_back(walls);
    CpuEngine<double> engine(scene);
    engine.set_log(nullptr);
    auto mean_v = [&] {
      double m = 0;
      Vec3d p = Vec3d::zero();
      for (std::size_t i = 0; i < engine.particle_count(0); ++i) {
        m += engine.masses(0)[i];
        p = p + engine.velocities(0)[i] * engine.masses(0)[i];
      }
      return p * (1.0 / m);
    };
    auto x_min = [&] {
      double x = 1.0;
      for (const Vec3d& q : engine.positions(0)) x = std::min(x, q[0]);
      return x;
    };
    double touched = 1.0;
    const double t_end = 0.3;  // the impact is over by 0.2 s; the ball reaches the far wall after 0.4 s
    while (engine.time() < t_end) {
      ASSERT_TRUE(engine.step().ok);
      touched = std::min(touched, x_min());
    }
    const Vec3d v = mean_v();
    const double gap = x_min() - wall;
    std::printf("[measured] ball at a %s wall: closest approach %.4f m from the face; at %.1f s mean v = (%.3f, %.3f) "
                "m/s (thrown at (%.1f, %.1f)), gap %.4f m\n",
                contact == Contact::Separable ? "Separable" : "Sticky", touched - wall, t_end, v[0], v[1], -vn, vt, gap);
    EXPECT_LT(touched - wall, 2 * dx) << "the ball never reached the wall";
    // Rebound: an elastic sphere at v / c = 0.1 (c = sqrt(E / rho) = 10 m/s) on a rigid wall keeps nearly all of its
    // normal velocity; the loss is the energy left ringing in the ball and APIC's dissipation over a contact resolved
    // by ~2 cells. Budget: 10 % of the normal velocity (19 % of the normal kinetic energy); no gain (energy).
    // Measured 0.959 (Separable), 0.972 (Sticky). The old bound, 0.5, had no budget.
    EXPECT_GT(v[0], 0.9 * vn) << "no rebound, or too much lost in it";
    EXPECT_LE(v[0], vn) << "the wall added energy";
    EXPECT_GT(gap, 2 * dx) << "the ball did not leave the wall";
    if (contact == Contact::Separable)
      EXPECT_NEAR(v[1], vt, 0.05 * vt) << "a frictionless wall changed the velocity along it";
    else
      EXPECT_LT(v[1], 5.0 / 7.0 * vt) << "a Sticky wall let the ball slide on";
  }
}

// Coulomb friction on the grid (boundary.cuh, project_contact): a block on a floor with gravity tilted by theta is a
// block on an incline. Each floor node loses mu_d times the normal velocity it pushes into the wall from its
// tangential velocity, so the friction impulse is mu_d times the floor's normal impulse, M g cos(theta) dt per step
// once the block rests on it: the block slides with a = g (sin theta - mu_d cos theta) when tan theta > mu_s and
// sticks (v = 0) otherwise. Stiff block (E 1e7 Pa), 8 ppc, dx 0.01 m; the mean velocity of the block after it has
// settled (from t = 0.05 s, the first 0.05 s carry the landing) is compared with the rigid-body answer.
// Measured: the velocity gained over 0.15 s is within 0.14 % of the rigid block's (frictionless: exact), and the
// sticking block moves by 0.004 m/s (elastic ringing). Tolerances: 1 % of the sliding velocity gained, 2 % of
// g sin(theta) t for the sticking case.
struct InclineCase {
  double theta_deg, mu_s, mu_d;
  Contact contact;
};
double incline_velocity(const InclineCase& c, double t) {
  const double g = 9.81, th = c.theta_deg * M_PI / 180.0;
  if (std::tan(th) <= c.mu_s) return 0.0;
  return g * (std::sin(th) - c.mu_d * std::cos(th)) * t;
}
class Incline : public ::testing::TestWithParam<InclineCase> {};
TEST_P(Incline, SlidesOrSticksAsTheRigidBlock) {
  const InclineCase c = GetParam();
  const double g = 9.81, th = c.theta_deg * M_PI / 180.0, dx = 0.01;
  Scene scene = empty_scene(r3(0.6, 0.2, 0.2), dx, r3(g * std::sin(th), -g * std::cos(th), 0));
  BodySpec block = box_body(Constitutive::FixedCorotated, r3(0.05, 0.03, 0.06), r3(0.1, 0.04, 0.08));
  block.material.youngs_modulus = 1e7;
  scene.bodies.push_back(block);
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = c.contact;
  walls.friction_static = c.mu_s;
  walls.friction_dynamic = c.mu_d;
  walls.domain_start = r3(0.0, 0.025, 0.0);  // the floor face at y = 0.025: particles start just above it
  walls.domain_end = r3(0.6, 0.2, 0.2);
  scene.boundaries.push_back(walls);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  auto mean_vx = [&] {
    double m = 0, p = 0;
    for (std::size_t i = 0; i < engine.particle_count(0); ++i) {
      m += engine.masses(0)[i];
      p += engine.masses(0)[i] * engine.velocities(0)[i][0];
    }
    return p / m;
  };
  const double t0 = 0.05, t1 = 0.2;
  ASSERT_TRUE(engine.advance_to(t0).ok);
  const double v0 = mean_vx();
  ASSERT_TRUE(engine.advance_to(t1).ok);
  const double v1 = mean_vx();
  const double expected = incline_velocity(c, t1) - incline_velocity(c, t0);
  std::printf("[measured] incline %.0f deg, mu_s %.2f, mu_d %.2f: dv %.5f m/s over %.2f s (rigid block %.5f)\n",
              c.theta_deg, c.mu_s, c.mu_d, v1 - v0, t1 - t0, expected);
  if (expected == 0.0) {
    EXPECT_LT(std::abs(v1 - v0), 0.02 * g * std::sin(th) * (t1 - t0));
  } else {
    EXPECT_NEAR(v1 - v0, expected, 0.01 * expected);
  }
}
INSTANTIATE_TEST_SUITE_P(Boundary, Incline,
                         ::testing::Values(InclineCase{30, 0.0, 0.0, Contact::Slip},
                                           InclineCase{30, 0.3, 0.3, Contact::Slip},
                                           InclineCase{30, 0.3, 0.2, Contact::Separable},
                                           InclineCase{20, 0.5, 0.4, Contact::Slip}));

// A moving boundary: a Separable Box piston at v_p = 0.5 m/s (no gravity) reaches an elastic block at rest. A rigid
// wall of infinite mass hitting a free elastic body leaves it with a mean velocity between v_p (the piston keeps
// pushing: the block cannot be slower) and 2 v_p (a perfectly elastic rebound), and Separable contact lets it leave;
// no particle may get behind the piston's face. Measured: 0.758 m/s (a partly elastic impact, the block ringing).
// A piston wave maker displaces water: a tank 0.06 m wide with water h0 = 0.1 m deep between the piston face
// (x = 0.12 m) and the far wall (x = 0.58 m); the Piston moves at vp = 0.25 m/s for T = 0.4 s. The water is nearly
// incompressible (JFluid, K = 1e6 Pa: rho g h0 / K = 1e-3), so at T the water above the initial level holds the volume
// the face swept through the water, W h0 vp T, however the wave shapes the surface. Measured as the part of each
// particle's cube (side (V0 J)^(1/3); none above the level at the start) that lies above the level. The grid resolves
// where the face meets the water to within half a cell, so the tolerance is W h0 dx / 2 (5 % of the swept volume
// here; measured: 1.0 % less, the particles at the face reaching up to 0.43 dx into the piston's last node layer). No
// particle gets a cell behind the face.
TEST(Boundary, PistonDisplacesItsSweptVolumeOfWater) {
  const double dx = 0.01, vp = 0.25, T = 0.4, floor = 0.02, h0 = 0.1, width = 0.06, face0 = 0.12;
  Scene scene = empty_scene(r3(0.6, 0.3, 0.1), dx, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(face0, floor, 0.02), r3(0.58 - face0, h0, width)));
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = Contact::Separable;
  walls.domain_start = r3(0.02, floor, 0.02);
  walls.domain_end = r3(0.58, 0.28, 0.02 + width);
  scene.boundaries.push_back(walls);
  BoundarySpec piston;
  piston.object = BoundaryObject::Piston;
  piston.contact = Contact::Separable;
  piston.domain_start = r3(0.0, 0.0, 0.0);
  piston.domain_end = r3(face0, 0.3, 0.1);
  piston.velocity = r3(vp, 0, 0);
  scene.boundaries.push_back(piston);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const double level = floor + h0;
  auto volume_above = [&] {
    double v = 0.0;
    const auto& x = engine.positions(0);
    const auto& v0 = engine.volumes(0);
    const auto J = engine.volume_ratios(0);
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double vol = v0[i] * J[i], side = std::cbrt(vol);
      v += vol * std::clamp((x[i][1] + side / 2 - level) / side, 0.0, 1.0);
    }
    return v;
  };
  const double at_start = volume_above();
  double deepest = 0.0;  // [m] how far a particle got behind the piston's face
  while (engine.time() < T) {
    ASSERT_TRUE(engine.advance_to(std::min(T, engine.time() + 0.01)).ok);
    const double face = face0 + vp * engine.time();
    for (const Vec3d& x : engine.positions(0)) deepest = std::max(deepest, face - x[0]);
  }
  const double swept = width * h0 * vp * T, above = volume_above();
  std::printf("[measured] piston at %.2f m/s for %.1f s: water above the initial level %.4g m^3 (at the start %.3g), "
              "swept volume %.4g m^3 (ratio %.4f); deepest particle %.4f m behind the face\n",
              vp, T, above, at_start, swept, above / swept, deepest);
  EXPECT_LT(std::abs(at_start), 1e-3 * swept);
  EXPECT_NEAR(above, swept, width * h0 * dx / 2);
  EXPECT_LT(deepest, dx);
}

struct PistonBlockResult {
  double v_ratio = 0;  ///< v_cm / v_p of the block at t = 0.4 s
  double kept = 0;     ///< energy the block holds / work the piston did
  double v_bound = 0;  ///< the energy bound on v_cm, / v_p
  double deepest = 0;  ///< [m] how far a particle got behind the piston's face
  double dx = 0;
};

/// A FixedCorotated block (0.08 m, E = 1e6 Pa) at rest, hit by a Separable Box piston moving at 0.5 m/s.
PistonBlockResult piston_block(double dx) {
  const double vp = 0.5;
  Scene scene = empty_scene(r3(0.6, 0.2, 0.2), dx, r3(0, 0, 0));
  BodySpec block = box_body(Constitutive::FixedCorotated, r3(0.15, 0.06, 0.06), r3(0.08, 0.08, 0.08));
  block.material.youngs_modulus = 1e6;
  scene.bodies.push_back(block);
  BoundarySpec piston;
  piston.object = BoundaryObject::Box;
  piston.contact = Contact::Separable;
  piston.domain_start = r3(0.02, 0.02, 0.02);
  piston.domain_end = r3(0.10, 0.18, 0.18);
  piston.velocity = r3(vp, 0, 0);
  scene.boundaries.push_back(piston);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  PistonBlockResult r;
  r.dx = dx;
  while (engine.time() < 0.4) {
    EXPECT_TRUE(engine.step().ok);
    const double face = 0.10 + vp * engine.time();
    for (const Vec3d& x : engine.positions(0)) r.deepest = std::max(r.deepest, face - x[0]);
  }
  double m = 0, p = 0;
  for (std::size_t i = 0; i < engine.particle_count(0); ++i) {
    m += engine.masses(0)[i];
    p += engine.masses(0)[i] * engine.velocities(0)[i][0];
  }
  const double v_cm = p / m, work = vp * m * v_cm;
  const double energy = engine.kinetic_energy() + engine.elastic_energy();
  const double internal = energy - 0.5 * m * v_cm * v_cm;
  r.v_ratio = v_cm / vp;
  r.kept = energy / work;
  r.v_bound = (vp + std::sqrt(std::max(0.0, vp * vp - 2 * internal / m))) / vp;
  std::printf("[measured] piston at %.2f m/s, dx %.3g m: block mean velocity %.4f v_p at t = 0.4 s, deepest %.4f m "
              "behind the face; block energy %.4f of the piston's work, v_cm bound %.4f v_p\n",
              vp, dx, r.v_ratio, r.deepest, r.kept, r.v_bound);
  return r;
}

// Energy balance of the impact: the piston's only force on the block gave it the impulse m v_cm (it started at rest)
// while moving at v_p, so it did the work W = v_p m v_cm; the block holds E = kinetic + elastic energy (its
// translation and its ringing), the rest was dissipated (APIC, the wall's node projection): E <= W, budget 0 beyond
// time-integration round-off (1e-3 W). Equivalently v_cm <= v_p + sqrt(v_p^2 - 2 E_internal / m) < 2 v_p. Lower
// bound: once separated no force acts, and a block slower than the piston would be caught again: v_cm >= v_p.
// Between the bounds the answer is not converged, and not monotone under refinement either: the elastic limit (a
// bar hit by a rigid wall leaves at 2 v_p, nothing ringing) is where a falling transfer dissipation would lead, but
// measured the block keeps 0.949 of the work (1.899 v_p) at dx 0.02 m and 0.765 (1.516 v_p) at dx 0.01 m. The
// piston's face crosses a node plane every dx / v_p and each crossing sets a node's velocity at once; that the
// finer grid loses more is an open finding, so both resolutions are held to the bounds only.
TEST(Boundary, MovingPistonPushesABlock) {
  for (const PistonBlockResult& r : {piston_block(0.02), piston_block(0.01)}) {
    SCOPED_TRACE(testing::Message() << "dx " << r.dx);
    EXPECT_GE(r.v_ratio, 1.0);
    EXPECT_LE(r.kept, 1 + 1e-3);
    EXPECT_LE(r.v_ratio, r.v_bound * (1 + 1e-3));
    EXPECT_LT(r.deepest, r.dx);
  }
}

// A piston driven by a motion file (displacement 0.5 t, velocity 0.5 m/s, 100 Hz rows) moves exactly as the
// constant-velocity piston: the two runs agree to round-off in every particle.
TEST(Boundary, MotionFilePistonEqualsConstantVelocity) {
  const std::string file = ::testing::TempDir() + "fbar_piston_motion.csv";
  {
    std::ofstream out(file);
    out.precision(17);
    for (int i = 0; i <= 100; ++i) out << 0.01 * i << "," << 0.005 * i << ",0.5\n";
  }
  Scene scene = empty_scene(r3(0.6, 0.2, 0.2), 0.02, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.14, 0.04, 0.04), r3(0.12, 0.12, 0.12)));
  BoundarySpec piston;
  piston.object = BoundaryObject::Box;
  piston.contact = Contact::Separable;
  piston.domain_start = r3(0.02, 0.02, 0.02);
  piston.domain_end = r3(0.10, 0.18, 0.18);
  piston.velocity = r3(0.5, 0, 0);
  Scene constant = scene;
  constant.boundaries.push_back(piston);
  piston.velocity = r3(0, 0, 0);
  piston.file = file;
  piston.output_frequency = 100;
  scene.boundaries.push_back(piston);
  CpuEngine<double> a(constant), b(scene);
  a.set_log(nullptr);
  b.set_log(nullptr);
  for (int s = 0; s < 250; ++s) {  // 0.1 s: the piston face travels from 0.10 m to 0.15 m, into the water
    ASSERT_TRUE(a.step(4e-4).ok);
    ASSERT_TRUE(b.step(4e-4).ok);
  }
  double diff = 0, moved = 0;
  for (std::size_t p = 0; p < a.particle_count(0); ++p) {
    diff = std::max(diff, max_abs(a.positions(0)[p] - b.positions(0)[p]));
    moved = std::max(moved, a.velocities(0)[p][0]);
  }
  EXPECT_GT(moved, 0.3);  // the piston reached the water and pushed it
  EXPECT_LT(diff, 1e-12);
  std::remove(file.c_str());
}

// A Bathymetry bed holds material as a floor does: a block dropped onto a flat bed at y = 0.1 m comes to rest on it
// (lowest particle within one cell above the bed, never below it), and on a 1:1 slope rising to +x a frictionless
// block is pushed back down it (its x velocity turns negative).
TEST(Boundary, BathymetryBedHoldsAndDeflects) {
  Scene scene = empty_scene(r3(1, 0.6, 0.3), 0.02, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.2, 0.2, 0.1), r3(0.1, 0.1, 0.1)));
  BoundarySpec bed;
  bed.object = BoundaryObject::Bathymetry;
  bed.contact = Contact::Separable;
  bed.bathymetry = {{0.0, 0.1}, {1.0, 0.1}};
  bed.domain_start = r3(0, 0, 0);
  bed.domain_end = r3(1, 0.6, 0.3);
  scene.boundaries.push_back(bed);
  {
    CpuEngine<double> engine(scene);
    engine.set_log(nullptr);
    double y_min = 1.0;
    while (engine.time() < 0.4) {
      ASSERT_TRUE(engine.step().ok);
      for (const Vec3d& x : engine.positions(0)) y_min = std::min(y_min, x[1]);
    }
    EXPECT_GT(y_min, 0.1);
    EXPECT_LT(y_min, 0.1 + 0.02 + 1e-9);
  }
  scene.bodies[0] = box_body(Constitutive::FixedCorotated, r3(0.45, 0.3, 0.1), r3(0.1, 0.1, 0.1));
  scene.boundaries[0].bathymetry = {{0.0, 0.0}, {0.4, 0.0}, {0.8, 0.4}, {1.0, 0.4}};  // 45 degrees up from x = 0.4
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  ASSERT_TRUE(engine.advance_to(0.3).ok);
  double m = 0, p = 0;
  for (std::size_t i = 0; i < engine.particle_count(0); ++i) {
    m += engine.masses(0)[i];
    p += engine.masses(0)[i] * engine.velocities(0)[i][0];
  }
  EXPECT_LT(p / m, -0.1) << "the slope must send the block back towards -x";
}

// Still water on a frictionless (Slip) 1:5 slope stays at rest, for a Bathymetry bed and for a Plane ramp: the bed's
// band of nodes up to one cell above it (boundary.cuh kBedLayerCells) keeps the pressure on its staircase from driving
// an up-slope current at the bed (without the band: 0.17 m/s after 0.5 s here, growing to 0.4 m/s at 2 s).
TEST(Boundary, StillWaterOnASlopeStaysStill) {
  const std::vector<std::array<double, 2>> profile = {{0.2, 0.2}, {2.0, 0.2}, {5.0, 0.8}};
  for (const bool plane : {false, true}) {
    Scene scene = empty_scene(r3(6.0, 1.5, 0.5), 0.1, r3(0, -9.81, 0));
    scene.simulation.precision = Precision::Single;
    BodySpec water = box_body(Constitutive::JFluid, r3(0.2, 0.2, 0.1), r3(5.6, 0.8, 0.3));
    water.material.bulk_modulus = 2e7;
    water.geometry[0].object = GeometryObject::Bathymetry;
    water.geometry[0].bathymetry = profile;
    scene.bodies.push_back(water);
    BoundarySpec walls;
    walls.object = BoundaryObject::Walls;
    walls.contact = Contact::Slip;
    walls.domain_start = r3(0.2, 0.2, 0.2);  // the walls' faces a cell inside the water's box
    walls.domain_end = r3(5.8, 1.3, 0.3);
    scene.boundaries.push_back(walls);
    BoundarySpec bed;
    bed.contact = Contact::Slip;
    if (!plane) {
      bed.object = BoundaryObject::Bathymetry;
      bed.bathymetry = profile;
      bed.domain_end = r3(6.0, 1.5, 0.5);
      scene.boundaries.push_back(bed);
    } else {
      bed.object = BoundaryObject::Plane;
      bed.domain_start = r3(2.0, 0.2, 0.0);
      bed.domain_end = r3(5.0, 0.8, 0.5);
      scene.boundaries.push_back(bed);
      bed.object = BoundaryObject::Floor;  // the flats on either side
      bed.domain_start = r3(0.0, 0.0, 0.0);
      bed.domain_end = r3(2.0, 0.2, 0.5);
      scene.boundaries.push_back(bed);
      bed.domain_start = r3(5.0, 0.0, 0.0);
      bed.domain_end = r3(6.0, 0.8, 0.5);
      scene.boundaries.push_back(bed);
    }
    CpuEngine<float> engine(scene);
    engine.set_log(nullptr);
    ASSERT_TRUE(engine.advance_to(0.5).ok);
    double bed_layer = 0.0, count = 0.0, fastest = 0.0;
    for (std::size_t i = 0; i < engine.particle_count(0); ++i) {
      const auto& x = engine.positions(0)[i];
      const auto& v = engine.velocities(0)[i];
      fastest = std::max(fastest, static_cast<double>(norm(v)));
      const double y_bed = bed_height(profile, x[0]);
      if (x[0] > 2.5 && x[0] < 4.5 && x[1] < y_bed + 0.1) {
        bed_layer += v[0];
        count += 1.0;
      }
    }
    ASSERT_GT(count, 100.0);
    EXPECT_LT(std::fabs(bed_layer / count), 0.02) << (plane ? "Plane" : "Bathymetry") << ": mean x velocity at the bed";
    EXPECT_LT(fastest, 0.1) << (plane ? "Plane" : "Bathymetry");
  }
}

}  // namespace
}  // namespace fbar
