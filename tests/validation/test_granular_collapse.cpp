// Validation: planar granular column collapse against Lube et al. 2005 (VALIDATION.md experiment 2), DruckerPrager.
//
// Setup (the MPM set-up GeoTaichi uses for this benchmark): a column L0 = 2 m wide and H0 = 1 m high (aspect ratio
// a = H0 / L0 = 0.5) against a smooth back wall on a rough floor; rho 2700 kg/m^3, E 20 MPa, nu 0.2, friction angle
// 33 deg, no cohesion; dx = 0.05 m, 2 x 2 particles per cell in the plane (8 ppc in a slab one cell thick between
// slip walls: plane strain), gravity 9.81 m/s^2, released at rest.
// Lube et al. 2005 (planar, quasi-2D channel): runout (L_inf - L0) / L0 = 1.2 a for a < 2.3, and for small a the
// top of the column does not move: H_inf = H0. At a = 0.5: runout 0.6 (L_inf = 3.2 m), with an experimental scatter
// of about +-20 % about the fit (at a = 2 the data span 2.4 to 3.6 about the fits' 2.4 / 3.0).
// What is asserted: H_inf = H0 within 5 % (one dx), the deposit at rest (kinetic energy below 1e-4 of the potential
// energy released), and the runout bracketed by the two floors this release has. The experiments' floor is rough
// but lets the grains slide with Coulomb friction, which fbar's boundaries do not implement yet (friction_static is
// refused): a no-slip (Sticky) floor stops the bottom cell layer, a frictionless (Slip) floor lets the pile spread
// past the domain. Measured (CPU, double, 3 s): Sticky floor runout 0.285 (Lube 0.6: outside the band, short),
// H_inf / H0 0.999; Slip floor: the front leaves the 5 m domain at t = 1.57 s (runout > 1.5). The runout check
// against Lube's band is therefore left to the frictional floor (docs/validation.md lists it as open); here the
// Sticky floor must give a runout in (0, 0.6], short of Lube's fit, as a no-slip base must.
// Runout is the 99th-percentile particle distance from the back wall (VALIDATION.md), so a few saltating particles
// do not set it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace {

using validation::r3;

constexpr double kL0 = 2.0, kH0 = 1.0, kDx = 0.05;
constexpr double kRho = 2700.0;

TEST(GranularCollapse, RunoutAndHeightAgainstLube) {
  validation::Stopwatch clock;
  const auto fit = validation::WallFit::LastWallNodePlane;
  const double x0 = kDx + validation::wall_inset(fit, kDx), y0 = x0, z0 = x0;
  Scene scene = validation::make_scene(r3(x0 + 5.0, y0 + kH0 + 4 * kDx, z0 + 2.5 * kDx), kDx, r3(0, -9.81, 0));
  BodySpec sand = validation::make_body(Constitutive::DruckerPrager, kRho);
  sand.material.youngs_modulus = 20e6;
  sand.material.poisson_ratio = 0.2;
  sand.material.friction_angle = 33.0;
  sand.material.cohesion = 0.0;
  validation::add_box(sand, r3(x0, y0, z0), r3(kL0, kH0, kDx));
  scene.bodies.push_back(sand);
  const double far = validation::kFar;
  scene.boundaries.push_back(validation::wall_box(Contact::Sticky, r3(-far, y0, -far), r3(far, far, far), kDx, fit));
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(x0, -far, -far), r3(far, far, far), kDx, fit));
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(-far, -far, z0), r3(far, far, z0 + kDx), kDx, fit));

  CpuEngine<double> engine(scene);
  double potential0 = 0;
  for (std::size_t p = 0; p < engine.particle_count(0); ++p)
    potential0 += engine.masses(0)[p] * 9.81 * (engine.positions(0)[p][1] - y0);
  const StepReport r = engine.advance_to(3.0);
  ASSERT_TRUE(r.ok) << r.message();
  double potential = 0;
  std::vector<double> reach, height;
  for (std::size_t p = 0; p < engine.particle_count(0); ++p) {
    const Vec3d& x = engine.positions(0)[p];
    potential += engine.masses(0)[p] * 9.81 * (x[1] - y0);
    reach.push_back(x[0] - x0);
    height.push_back(x[1] - y0);
  }
  std::sort(reach.begin(), reach.end());
  std::sort(height.begin(), height.end());
  const double L_inf = reach[static_cast<std::size_t>(0.99 * (reach.size() - 1))];
  // The top surface: particle centres sit dx/4 below it (2 per cell), so the height is the top centre + dx/4.
  const double H_inf = height.back() + 0.25 * kDx;
  const double runout = (L_inf - kL0) / kL0;
  const double released = potential0 - potential;
  std::printf("granular collapse a = 0.5 (DruckerPrager phi 33 deg): %zu particles, %lld steps, %.1f s wall\n",
              engine.particle_count(0), engine.steps(), clock.seconds());
  std::printf("  runout (L_inf - L0)/L0 = %.3f (Lube 1.2 a = 0.600, band 0.48..0.72; Sticky floor); H_inf/H0 = %.3f (1); "
              "kinetic/released %.2g\n",
              runout, H_inf / kH0, engine.kinetic_energy() / released);
  EXPECT_GT(runout, 0.0);
  EXPECT_LE(runout, 0.6);
  EXPECT_NEAR(H_inf, kH0, 0.05 * kH0);
  EXPECT_GT(released, 0.0);
  EXPECT_LE(engine.kinetic_energy(), 1e-4 * released);
}

}  // namespace
}  // namespace fbar
