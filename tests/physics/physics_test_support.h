// Helpers for the physics tests: seeded random tensors and a small scene builder for the CPU engine.
#pragma once

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "MnBase/Math/vec.h"
#include "geometry/tet_mesh.h"
#include "scene/scene.h"
#include "scene/scene_parse.h"

namespace fbar::test {

/// Rotation by `angle` [rad] about the unit `axis` (Rodrigues).
inline Mat3d rotation(const Vec3d& axis_in, double angle) {
  const Vec3d a = axis_in / norm(axis_in);
  const double c = std::cos(angle), s = std::sin(angle);
  Mat3d K{{{0, -a[2], a[1]}, {a[2], 0, -a[0]}, {-a[1], a[0], 0}}};
  return Mat3d::identity() + K * s + (K * K) * (1.0 - c);
}

inline Mat3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 2.0 * 3.14159265358979323846);
  return rotation(Vec3d{{n(rng), n(rng), n(rng)}}, u(rng));
}

/// F = I + e A with A uniform in [-1, 1]^9 (det > 0 for e < 1/3).
inline Mat3d random_deformation(std::mt19937_64& rng, double e) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Mat3d F = Mat3d::identity();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) F(i, j) += e * u(rng);
  return F;
}

inline Real3 r3(double x, double y, double z) { return Real3{x, y, z}; }

/// A box body of `law` sampled at 8 ppc (2x2x2 lattice per cell).
inline BodySpec box_body(Constitutive law, Real3 offset, Real3 span, Real3 velocity = r3(0, 0, 0)) {
  BodySpec b;
  b.material.law = law;
  b.material.ppc = 8.0;
  b.material.cfl = 0.5;
  b.material.rho = 1000.0;
  b.material.youngs_modulus = 1e6;
  b.material.poisson_ratio = 0.3;
  b.material.bulk_modulus = 1e6;
  b.material.gamma = 7.0;
  b.material.viscosity = 0.0;
  b.algorithm.use_asflip = false;
  b.algorithm.use_fbar = false;
  b.velocity = velocity;
  GeometrySpec g;
  g.object = GeometryObject::Box;
  g.span = span;
  g.offset = offset;
  b.geometry.push_back(g);
  b.output_attribs = {"ID"};
  return b;
}

/// A scene with no boundaries and the given gravity; default_dt large so only explicit dt or the CFL bound acts.
inline Scene empty_scene(Real3 domain, double dx, Real3 gravity) {
  Scene s;
  s.simulation.domain = domain;
  s.simulation.dx = dx;
  s.simulation.default_dt = 1.0;
  s.simulation.gravity = gravity;
  s.simulation.precision = Precision::Double;
  return s;
}

/// A grid sensor (load cell) of `attribute` reduced by `op` over the box [lo, hi] along `direction` (sign: +1 / -1
/// the positive / negative side only, 0 signed).
inline GridSensorSpec grid_sensor_spec(const std::string& attribute, SensorOperation op, Real3 lo, Real3 hi,
                                       Real3 direction = r3(1, 0, 0), int sign = 0) {
  GridSensorSpec s;
  s.attribute = attribute;
  s.operation = op;
  s.domain_start = lo;
  s.domain_end = hi;
  s.direction = direction;
  s.direction_sign = sign;
  return s;
}

/// A particle sensor of `attribute` (a canonical frame attribute name) reduced by `op` over the box [lo, hi].
inline ParticleSensorSpec particle_sensor_spec(const std::string& attribute, SensorOperation op, Real3 lo, Real3 hi) {
  ParticleSensorSpec s;
  s.attribute = attribute;
  s.operation = op;
  s.domain_start = lo;
  s.domain_end = hi;
  return s;
}

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr float kEpsF = std::numeric_limits<float>::epsilon();

/// Adds a mesh of FixedCorotated tetrahedra (rho [kg/m^3], E [Pa], nu) to `scene` as an FEM body (use_FEM, APIC
/// vertices, on `gpu`, frames of "ID") and appends its body (append_mesh_bodies); returns the entry to adjust (call
/// append_mesh_bodies again after changing what the body copies: gpu, velocity, law, rho, E, nu, outputs, scheme).
inline MeshEntrySpec& add_elastic_mesh(Scene& scene, TetMesh mesh, double rho, double youngs_modulus,
                                       double poisson_ratio, int gpu = 0) {
  MeshEntrySpec m;
  m.law = Constitutive::FixedCorotated;
  m.rho = rho;
  m.youngs_modulus = youngs_modulus;
  m.poisson_ratio = poisson_ratio;
  m.use_fem = true;
  m.use_asflip = false;
  m.gpu = gpu;
  m.output_attribs = {"ID"};
  m.mesh = std::make_shared<const TetMesh>(std::move(mesh));
  scene.meshes.push_back(std::move(m));
  append_mesh_bodies(scene);
  return scene.meshes.back();
}

}  // namespace fbar::test
