// The scenes of the decomposition tests (CPU ranks: tests/engine/cpu/test_decomposition.cpp; GPU ranks:
// tests/engine/gpu/test_decomposition_gpu.cu and its MPI check), one definition for both engines.
#pragma once

#include <memory>

#include "../../physics/physics_test_support.h"
#include "geometry/tet_mesh.h"
#include "scene/scene_parse.h"

namespace fbar::test {

/// A water column (0.3 m wide along x, 0.2 m tall) collapsing in a 0.6 m tank: slabs along x, the water of the left
/// slabs flows across the cuts. `schemes`: also ASFLIP (alpha 0.9, beta 0 / 0.2) and F-bar (psi 1), whose grid
/// channels (v^n, the cell sums) cross the halo too.
inline Scene dam_break(bool schemes) {
  Scene scene = empty_scene(r3(0.64, 0.4, 0.2), 0.02, r3(0, -9.81, 0));
  BodySpec water = box_body(Constitutive::JFluid, r3(0.04, 0.04, 0.04), r3(0.3, 0.2, 0.12));
  water.material.bulk_modulus = 2e5;
  water.material.viscosity = 1e-3;
  if (schemes) {
    water.algorithm.use_asflip = true;
    water.algorithm.asflip_alpha = 0.9;
    water.algorithm.asflip_beta_min = 0.0;
    water.algorithm.asflip_beta_max = 0.2;
    water.algorithm.use_fbar = true;
    water.algorithm.fbar_psi = 1.0;
    water.algorithm.fbar_scheme = FbarScheme::Cell;
  }
  scene.bodies.push_back(water);
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = Contact::Slip;
  walls.domain_start = r3(0.04, 0.04, 0.04);  // the water's faces: it fills the tank's corner
  walls.domain_end = r3(0.60, 0.36, 0.16);
  scene.boundaries.push_back(walls);
  return scene;
}

/// An elastic FEM post (FixedCorotated tetrahedra, 0.06 x 0.12 x 0.06 m above the floor in cubes of 0.01 m, E 2e6
/// Pa, rho 1200 kg/m^3) in the dam break's tank, 1 cm from the water's face (their grid stencils overlap from the
/// start: the water pushes it at once), its foot clamped by a Sticky Box, on `gpu` (a mesh lives whole on its rank):
/// partition by method when the water is spread over the ranks.
inline Scene dam_break_with_post(int gpu) {
  Scene scene = dam_break(false);
  test::add_elastic_mesh(scene, box_tet_mesh(Vec3d{{0.35, 0.0, 0.07}}, Vec3d{{0.41, 0.16, 0.13}}, Vec3i{{6, 16, 6}}),
                         1200.0, 2e6, 0.3, gpu);
  BoundarySpec clamp;
  clamp.object = BoundaryObject::Box;
  clamp.contact = Contact::Sticky;
  clamp.domain_start = r3(0.33, 0.0, 0.05);
  clamp.domain_end = r3(0.43, 0.04, 0.15);
  scene.boundaries.push_back(clamp);
  return scene;
}

/// Makes `body` saturated soil (CoupledUP): a loose sand (E 2e6 Pa, nu 0.3, friction 30 deg, rho 2000 kg/m^3
/// saturated), its pore water (n 0.4, Kf 1e6 Pa so that the seepage step stays near the acoustic one, Kperm 1e-4 m/s)
/// carrying the overburden at the start. The decomposition and restart tests of saturated bodies use it.
inline void saturate(BodySpec& body) {
  MaterialSpec& m = body.material;
  m.law = Constitutive::CoupledUP;
  m.rho = 2000.0;
  m.youngs_modulus = 2e6;
  m.poisson_ratio = 0.3;
  m.friction_angle = 30.0;
  m.vol_correction = false;
  m.poro = 0.4;
  m.alpha1 = 1.0;
  m.Kf = 1e6;
  m.Ks = 1e12;
  m.Kperm = 1e-4;
  body.initial_state = InitialState::Hydrostatic;
}

/// ClaymoreUW users' load-cell check: water H = 0.2 m deep filling a Walls box [0, 0.2] x [0, 0.3] x
/// [0, D = 0.04] m to its faces (dx 0.01, JFluid rho 1000, K 5e5 Pa, started hydrostatic), with a Force load cell
/// against each x wall from outside, as scenes written for ClaymoreUW place them: [-0.05, 0] read X-, [0.2, 0.25]
/// read X+ (both boxes over every y and z). Each reads the wall's load rho g H^2 D / 2 = 7.848 N (kClaymoreTankLoad).
inline Scene claymore_tank(Contact contact = Contact::Separable) {
  Scene scene = empty_scene(r3(0.2, 0.3, 0.04), 0.01, r3(0, -9.81, 0));
  BodySpec water = box_body(Constitutive::JFluid, r3(0, 0, 0), r3(0.2, 0.2, 0.04));
  water.material.bulk_modulus = 5e5;  // c = 22 m/s: the GPU tests' fixed 2e-4 s steps are at CFL 0.45
  water.initial_state = InitialState::Hydrostatic;
  scene.bodies.push_back(water);
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = contact;
  walls.domain_start = r3(0, 0, 0);
  walls.domain_end = r3(0.2, 0.3, 0.04);
  scene.boundaries.push_back(walls);
  scene.grid_sensors = {grid_sensor_spec("Force", SensorOperation::Sum, r3(-0.05, -0.05, -0.05), r3(0, 0.35, 0.09),
                                         r3(1, 0, 0), -1),
                        grid_sensor_spec("Force", SensorOperation::Sum, r3(0.2, -0.05, -0.05), r3(0.25, 0.35, 0.09),
                                         r3(1, 0, 0), 1)};
  return scene;
}
constexpr double kClaymoreTankLoad = 1000.0 * 9.81 * 0.2 * 0.2 * 0.04 / 2;  ///< [N] rho g H^2 D / 2

/// A soft block (E 1e4 Pa) travelling at 2 m/s along x without gravity: every particle crosses one or more cuts.
/// `ranks` > 3 lengthens it (0.08 m, two GPU particle-block planes, per rank) so that every rank's slab is at least
/// two planes wide: on 4 ranks its particles cross three cuts.
inline Scene travelling_block(int ranks = 1) {
  Scene scene = empty_scene(r3(0.8, 0.2, 0.2), 0.01, r3(0, 0, 0));
  const double length = ranks > 3 ? 0.08 * ranks : 0.16;
  BodySpec block = box_body(Constitutive::FixedCorotated, r3(0.06, 0.06, 0.06), r3(length, 0.08, 0.08), r3(2, 0, 0));
  block.material.youngs_modulus = 1e4;
  scene.bodies.push_back(block);
  return scene;
}

/// ClaymoreUW's placement (bodies[].gpu): the dam break's water column whole on GPU 0 and a soft block (E 1e5 Pa,
/// rho 500) falling into it at 1 m/s whole on GPU 1, so that their grid blocks are shared by ranks that are not
/// slab neighbours. `mixed`: also a second, taller water column on the right spread over every rank by space
/// ("gpu": "all"); its slabs (along y, its tallest extent) cut through the other two bodies' blocks.
inline Scene placed_bodies(bool mixed) {
  Scene scene = dam_break(false);
  scene.bodies[0].gpu = 0;
  BodySpec block = box_body(Constitutive::FixedCorotated, r3(0.2, 0.26, 0.06), r3(0.08, 0.06, 0.08), r3(0, -1, 0));
  block.material.youngs_modulus = 1e5;
  block.material.rho = 500.0;
  block.gpu = 1;
  scene.bodies.push_back(block);
  if (mixed) {
    BodySpec right = box_body(Constitutive::JFluid, r3(0.44, 0.04, 0.04), r3(0.14, 0.28, 0.12));
    right.material.bulk_modulus = 2e5;
    right.material.viscosity = 1e-3;
    right.gpu = kAllGpus;
    right.model = 1;
    scene.bodies.push_back(right);
  }
  return scene;
}

}  // namespace fbar::test
