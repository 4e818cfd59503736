// Shared helpers of the GPU engine tests: skip without a device, small scenes, error measures against the CPU engine.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "MnSystem/Cuda/device_query.h"
#include "comm/device_transport.h"
#include "geometry/geometry.h"
#include "scene/scene.h"

#define FBAR_REQUIRE_DEVICE()                                                   \
  do {                                                                          \
    if (::fbar::cuda::device_count() == 0) GTEST_SKIP() << ::fbar::cuda::no_device_reason(); \
  } while (0)

/// Tests of ranks on separate GPUs through NCCL: skip without NCCL in the build or with fewer than n GPUs visible.
#define FBAR_REQUIRE_GPUS(n)                                                                                     \
  do {                                                                                                           \
    FBAR_REQUIRE_DEVICE();                                                                                       \
    if (!::fbar::comm::nccl_available()) GTEST_SKIP() << "this build has no NCCL";                               \
    if (::fbar::test::visible_gpus() < (n))                                                                      \
      GTEST_SKIP() << "needs " << (n) << " GPUs, " << ::fbar::test::visible_gpus() << " visible";                \
  } while (0)

namespace fbar::test {

inline int visible_gpus() { return cuda::device_count(); }

/// A 1 m box, dx = 0.05, Walls a cell inside its faces ([0.05, 0.95] on each axis); one body: a 0.3 x 0.25 x 0.3 m
/// block (6 x 5 x 6 cells, 8 ppc = 1440 particles) whose bottom sits 0.04 m above the floor's face, moving at
/// `velocity`.
inline Scene small_scene(Constitutive law, Precision precision, Real3 velocity = {0.0, -2.0, 0.0}, bool walls = true) {
  Scene s;
  SimulationSpec& sim = s.simulation;
  sim.domain = {1.0, 1.0, 1.0};
  sim.dx = 0.05;
  sim.default_dt = 1e-3;
  sim.gravity = {0.0, -9.81, 0.0};
  sim.precision = precision;
  BodySpec body;
  body.material.law = law;
  body.material.ppc = 8;
  body.material.cfl = 0.5;
  body.material.rho = 1000;
  body.material.bulk_modulus = 2e6;
  body.material.gamma = 7.1;
  body.material.viscosity = 1e-3;
  body.material.youngs_modulus = 1e5;
  body.material.poisson_ratio = 0.3;
  body.material.tensile_yield_strength = 5e3;  // VonMises yields where the block lands (rho c_p v = 23 kPa)
  body.algorithm.use_asflip = false;
  body.algorithm.use_fbar = false;
  GeometrySpec box;
  box.object = GeometryObject::Box;
  box.span = {0.3, 0.25, 0.3};
  box.offset = {0.35, 0.09, 0.35};
  body.geometry.push_back(box);
  body.velocity = velocity;
  body.output_attribs = {"ID", "Position_X", "Velocity_Y", "J", "Pressure"};
  s.bodies.push_back(body);
  if (walls) {
    BoundarySpec w;
    w.object = BoundaryObject::Walls;
    w.contact = Contact::Slip;
    w.domain_start = {0.05, 0.05, 0.05};
    w.domain_end = {0.95, 0.95, 0.95};
    s.boundaries.push_back(w);
  }
  return s;
}

inline std::vector<std::vector<Vec3d>> sample_scene(const Scene& s) {
  std::vector<std::vector<Vec3d>> p;
  for (std::size_t b = 0; b < s.bodies.size(); ++b) p.push_back(sample_body(s.bodies[b], s.simulation, static_cast<int>(b)));
  return p;
}

/// The larger of two differences, NaN when either is (std::max(m, NaN) is m): accumulate maxima with it.
inline double worst(double a, double b) { return std::isnan(a) || std::isnan(b) ? std::numeric_limits<double>::quiet_NaN() : std::max(a, b); }

/// Largest component-wise |a - b| over the entries; NaN when any component of either side is NaN (std::max and
/// max_abs drop a NaN operand, so a NaN in a state would otherwise pass EXPECT_LE(max_diff, tol)), and infinity when
/// the sizes differ.
template <typename V>
double max_diff(const std::vector<V>& a, const std::vector<V>& b) {
  if (a.size() != b.size()) return std::numeric_limits<double>::infinity();
  double m = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    using S = typename V::value_type;  // Vec and Mat: a plain array of S
    const V d = a[i] - b[i];
    const S* c = reinterpret_cast<const S*>(&d);
    for (std::size_t k = 0; k < sizeof(V) / sizeof(S); ++k) m = worst(m, std::fabs(static_cast<double>(c[k])));
    if (std::isnan(m)) return m;
  }
  return m;
}
template <typename T>
double max_diff_scalar(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return std::numeric_limits<double>::infinity();
  double m = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    m = worst(m, std::fabs(static_cast<double>(a[i] - b[i])));
    if (std::isnan(m)) return m;
  }
  return m;
}

}  // namespace fbar::test
