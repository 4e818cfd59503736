// Benchmark scenes shared by fbar_benchmark and fbar_scaling (one definition of each case).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

#include "scene/scene.h"

namespace fbar::bench {

/// Water column (2k x 2k x k cells of an 8 ppc box) in a 4k x 3k x 1.5k-cell tank, or a solid block of the same
/// size dropped from mid-height at 1 m/s; tank_box: a JFluid box filling its tank but for a four-cell margin
/// (the scaling scene: dx 0.002 m, a 2 : 1.2 : 1 box, Separable walls).
inline Scene make_scene(const std::string& name, double millions, Precision precision) {
  const double cells = millions * 1e6 / 8.0;
  const bool tank_box = name == "tank_box";
  const int k = std::max(4, static_cast<int>(std::lround(std::cbrt(cells / 4.0))));
  const int kx = std::max(4, static_cast<int>(std::lround(std::cbrt(cells / 0.3))));  // tank_box: kx x 0.6kx x 0.5kx
  const double dx = tank_box ? 0.002 : 0.01;
  Scene s;
  SimulationSpec& sim = s.simulation;
  sim.dx = dx;
  sim.default_dt = 1e-3;
  sim.gravity = {0.0, -9.81, 0.0};
  sim.precision = precision;
  BodySpec body;
  GeometrySpec box;
  box.object = GeometryObject::Box;
  box.offset = {4 * dx, 4 * dx, 4 * dx};
  if (tank_box) {
    const int ky = std::max(4, static_cast<int>(std::lround(0.6 * kx))), kz = std::max(4, kx / 2);
    sim.domain = {(kx + 8) * dx, (ky + 8) * dx, (kz + 8) * dx};
    box.span = {kx * dx, ky * dx, kz * dx};
  } else {
    sim.domain = {(4 * k + 8) * dx, (3 * k + 8) * dx, (k + k / 2 + 8) * dx};
    box.span = {2 * k * dx, 2 * k * dx, k * dx};
  }
  body.material.ppc = 8;
  body.material.cfl = 0.5;
  body.material.rho = 1000;
  // nodal_dam_break / nodal_split_dam_break / nodal_block: fbar_dam_break and fbar_block with ClaymoreUW's nodal
  // F-bar (FBAR_scheme "nodal"; fused, split, split).
  const bool nodal = name == "nodal_dam_break" || name == "nodal_split_dam_break" || name == "nodal_block";
  if (nodal) {
    body.algorithm.fbar_scheme = FbarScheme::Nodal;
    body.algorithm.fbar_fused_kernel = name == "nodal_dam_break";
  }
  if (tank_box || name == "dam_break" || name == "fbar_dam_break" || name == "asflip_dam_break" ||
      name == "picflip_dam_break" || name == "flip_dam_break" || name == "nodal_dam_break" ||
      name == "nodal_split_dam_break") {
    body.material.law = Constitutive::JFluid;
    body.material.bulk_modulus = 2e6;
    body.material.gamma = 7.1;
    body.material.viscosity = 1e-3;
    if (name == "fbar_dam_break" || nodal) body.algorithm.fbar_psi = 1.0;
    if (name == "fbar_dam_break") body.algorithm.fbar_scheme = FbarScheme::Cell;
  } else {
    // falling_block: FixedCorotated; neo_block, sand_block, clay_block: the same block in NeoHookean,
    // DruckerPrager (phi 30 deg, volume correction) and NACC (phi 30 deg, consolidated: logJp0 = -0.3);
    // vonmises_block: VonMises (J2 in Hencky strain, sigma_y 100 kPa, no hardening);
    // saturated_block: sand_block's skeleton saturated (CoupledUP: n 0.4, Kf 1e7, Ks 2.2e7, Kperm 1e-5 m/s,
    // ClaymoreUW's defaults but the porosity, the pore water carrying the overburden at the start).
    body.material.law = name == "neo_block"    ? Constitutive::NeoHookean
                        : name == "sand_block" ? Constitutive::DruckerPrager
                        : name == "saturated_block" ? Constitutive::CoupledUP
                        : name == "clay_block" ? Constitutive::NACC
                        : name == "hencky_block" ? Constitutive::Hencky
                        : name == "vonmises_block" ? Constitutive::VonMises
                                               : Constitutive::FixedCorotated;
    if (body.material.law == Constitutive::VonMises) body.material.tensile_yield_strength = 1e5;
    if (name == "fbar_block" || nodal) body.algorithm.fbar_psi = 1.0;
    if (name == "fbar_block") body.algorithm.fbar_scheme = FbarScheme::Cell;
    body.material.youngs_modulus = 1e7;
    body.material.poisson_ratio = 0.3;
    body.material.friction_angle = 30.0;
    if (body.material.law == Constitutive::NACC) body.material.logJp0 = -0.3;
    if (body.material.law == Constitutive::CoupledUP) {
      body.material.poro = 0.4;
      body.material.Kf = 1e7;
      body.material.Ks = 2.2e7;
      body.material.Kperm = 1e-5;
      body.initial_state = InitialState::Hydrostatic;
    }
    box.offset = {(k + 4) * dx, (k / 2 + 4) * dx, (k / 4 + 4) * dx};
    body.velocity = {0.0, -1.0, 0.0};
  }
  body.algorithm.use_asflip = name == "asflip_dam_break" || name == "asflip_block" || name == "picflip_dam_break" ||
                              name == "flip_dam_break";
  if (body.algorithm.use_asflip) {  // ASFLIP (alpha 0.9, beta 0 / 0.2), PIC-FLIP blend 0.95, FLIP
    const bool blend = name == "picflip_dam_break" || name == "flip_dam_break";
    body.algorithm.asflip_alpha = name == "flip_dam_break" ? 1.0 : blend ? 0.95 : 0.9;
    body.algorithm.asflip_beta_min = 0.0;
    body.algorithm.asflip_beta_max = blend ? 0.0 : 0.2;
  }
  body.algorithm.use_fbar = body.algorithm.fbar_psi != 0.0;
  body.geometry.push_back(box);
  body.output_attribs = {"ID"};
  s.bodies.push_back(body);
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = tank_box ? Contact::Separable : Contact::Slip;
  walls.domain_start = {2 * dx, 2 * dx, 2 * dx};
  walls.domain_end = {sim.domain[0] - 2 * dx, sim.domain[1] - 2 * dx, sim.domain[2] - 2 * dx};
  s.boundaries.push_back(walls);
  return s;
}

}  // namespace fbar::bench
