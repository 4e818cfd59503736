// Validation: a load cell on the wall of a hydrostatic tank reads the hydrostatic force.
//
// Problem: the hydrostatic JFluid column of hydrostatic_column_case.h (H = 0.1 m, rho0 = 1800 kg/m^3, K = 1e6 Pa,
// gamma 7, slip Walls), started in its exact compressible equilibrium, width w = 4 cells along x and 2 along z. A
// grid sensor (direction X+, Sum) around the +x wall's nodes reads the force the water exerts on that wall:
//   F = w_z * int_0^H p(d) dd  ~ w_z rho0 g H^2 / 2   (the Tait p(d) of the case; 0.06 % above rho0 g H^2 / 2).
// BoundaryForce is m (v* - v) / dt at the wall nodes: the impulse the slip projection removes, per step; Force
// (ClaymoreUW's) is p / dt, the P2G momentum over dt. Along the wall's normal, where the wall holds the node, the two
// are the same number (v_x = 0 after the projection and g_x = 0), and both are checked. At
// equilibrium it equals the MLS internal force the particles put on those nodes, which for a pressure quadratic in
// depth is the exact face load (the discrete-equilibrium argument of test_hydrostatic_column.cpp), except for the
// free-surface row whose stencil is truncated. Measured (double): -0.016 % at dx = 0.01, -0.0039 % at 0.005 (second
// order: the surface row's imbalance, a fraction of rho0 g dx / 4 over a cell, against a load growing as H^2).
// Tolerance 0.1 % at both (6x the coarse value; an O(dx) error of the method, >= 1 % here, or a wrong force sign or
// scale fails it), with the error falling on refinement. The reading of a rest state must be steady (spread 0.1 %).
// The floor's load cell (BoundaryForce, Y-) must carry the whole weight m g (every particle's weight reaches the floor
// at rest; Force would leave out the weight of the floor nodes' own mass, which gravity adds after P2G).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "hydrostatic_column_case.h"
#include "io/sensor_recorder.h"
#include "validation_support.h"

namespace fbar {
namespace {

using namespace hydrostatic_case;
using validation::r3;

/// w_z * int_0^H p(d) dd by Simpson's rule (p smooth: 2000 intervals are exact to 1e-12).
double exact_wall_force(double depth_width) {
  const int n = 2000;
  const double h = kH / n;
  double s = hydrostatic_pressure(0.0) + hydrostatic_pressure(kH);
  for (int i = 1; i < n; ++i) s += (i % 2 ? 4.0 : 2.0) * hydrostatic_pressure(i * h);
  return depth_width * s * h / 3.0;
}

struct LoadCellResult {
  double wall_mean = 0.0, wall_exact = 0.0, wall_claymore_mean = 0.0;
  double wall_spread = 0.0;  // (max - min) / exact over the samples
  double floor_mean = 0.0, weight = 0.0;
  bool ok = false;
};

LoadCellResult run_tank(double dx) {
  LoadCellResult out;
  const double wx = 4 * dx, wz = 2 * dx;
  const validation::WallFit fit = validation::WallFit::ZeroVelocityPlane;
  const double x0 = dx + validation::wall_inset(fit, dx), y0 = x0, z0 = x0;
  Scene scene = validation::make_scene(r3(x0 + wx + 2 * dx, y0 + kH + 3 * dx, z0 + wz + 2 * dx), dx, r3(0, -kG, 0));
  scene.simulation.precision = Precision::Double;
  BodySpec column = validation::jfluid_body(kRho, kK, kGamma, 0.0);
  validation::add_box(column, r3(x0, y0, z0), r3(wx, kH, wz));
  scene.bodies.push_back(column);
  const BoundarySpec walls =
      validation::wall_box(Contact::Slip, r3(x0, y0, z0), r3(x0 + wx, validation::kFar, z0 + wz), dx, fit);
  scene.boundaries.push_back(walls);

  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const double surface = y0 + kH;
  engine.set_volume_ratios(0, [&](const Vec3d& x) { return volume_ratio(hydrostatic_pressure(surface - x[1])); });

  // Wall nodes: on the +x face's node plane and outside it (boundary.cuh); the box takes every node from the face
  // outwards, at every height and depth. The floor: nodes on or below the bottom face.
  const double face_x = walls.domain_end[0], face_y = walls.domain_start[1];
  GridSensorSpec wall;
  wall.attribute = "BoundaryForce";
  wall.operation = SensorOperation::Sum;
  wall.direction = r3(1, 0, 0);
  wall.direction_sign = 1;
  wall.domain_start = r3(face_x - 0.5 * dx, -1.0, -1.0);
  wall.domain_end = r3(10.0, 10.0, 10.0);
  GridSensorSpec floor = wall;
  floor.direction = r3(0, 1, 0);
  floor.direction_sign = -1;
  floor.domain_start = r3(-1.0, -1.0, -1.0);
  floor.domain_end = r3(10.0, face_y + 0.5 * dx, 10.0);
  GridSensorSpec wall_claymore = wall;
  wall_claymore.attribute = "Force";
  engine.set_grid_sensors({wall, floor, wall_claymore});

  out.wall_exact = exact_wall_force(wz);
  out.weight = engine.total_mass() * kG;
  double lo = 1e300, hi = -1e300;
  int samples = 0;
  while (engine.time() < 0.1) {
    engine.set_grid_sample(0);
    const StepReport r = engine.step();
    if (!r.ok) {
      ADD_FAILURE() << r.message();
      return out;
    }
    const std::vector<SensorAccum> s = engine.grid_samples(1);
    const double f = sensor_result(SensorOperation::Sum, s[0]);
    out.wall_mean += f;
    out.wall_claymore_mean += sensor_result(SensorOperation::Sum, s[2]);
    out.floor_mean += sensor_result(SensorOperation::Sum, s[1]);
    lo = std::min(lo, f);
    hi = std::max(hi, f);
    ++samples;
  }
  out.wall_mean /= samples;
  out.wall_claymore_mean /= samples;
  out.floor_mean /= samples;
  out.wall_spread = (hi - lo) / out.wall_exact;
  out.ok = true;
  return out;
}

TEST(LoadCell, HydrostaticTankWallReadsRhoGHSquaredOverTwo) {
  const LoadCellResult coarse = run_tank(0.01);
  const LoadCellResult fine = run_tank(0.005);
  ASSERT_TRUE(coarse.ok && fine.ok);
  for (const LoadCellResult* r : {&coarse, &fine}) {
    const double err = (r->wall_mean - r->wall_exact) / r->wall_exact;
    std::printf("wall force %.6g N, exact %.6g N (rho g H^2/2 x w: %.6g N), error %+.3g %%, spread %.2g %%; "
                "floor %.6g N, weight %.6g N (relative difference %.2g)\n",
                r->wall_mean, r->wall_exact, kRho * kG * kH * kH / 2 * (r == &coarse ? 0.02 : 0.01), 100 * err,
                100 * r->wall_spread, r->floor_mean, r->weight, r->floor_mean / r->weight - 1.0);
    EXPECT_LE(std::fabs(err), 1e-3);
    EXPECT_NEAR(r->wall_claymore_mean, r->wall_mean, 1e-9 * r->wall_exact);  // the same number on a held wall node
    EXPECT_LE(r->wall_spread, 1e-3);  // a rest state: the reading is steady
    EXPECT_NEAR(r->floor_mean, r->weight, 1e-6 * r->weight);  // measured 2e-8: every weight reaches the floor
  }
  EXPECT_LT(std::fabs(fine.wall_mean / fine.wall_exact - 1.0), std::fabs(coarse.wall_mean / coarse.wall_exact - 1.0));
}

}  // namespace
}  // namespace fbar
