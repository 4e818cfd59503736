// The scenes of the decomposition tests (CPU ranks: tests/physics/test_decomposition.cpp; GPU ranks:
// tests/gpu_engine/test_decomposition_gpu.cu and its MPI check), one definition for both engines.
#pragma once

#include "physics_test_support.h"

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
  }
  scene.bodies.push_back(water);
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = Contact::Slip;
  walls.domain_start = r3(0.02, 0.02, 0.02);
  walls.domain_end = r3(0.62, 0.38, 0.18);
  scene.boundaries.push_back(walls);
  return scene;
}

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
