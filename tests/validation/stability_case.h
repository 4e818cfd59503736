// Stability maps: where the explicit scheme fails, and whether fbar says so.
//
// Each run is classed as
//   Stable    completed, and nothing impossible happened;
//   Detected  fbar stopped it with a report (StepReport not ok: NaN or Inf, a volume ratio J <= 0, a move of more
//             than a cell in a step, a particle outside the domain), which a scene run turns into exit code 2 and
//             its message;
//   Silent    completed without a report, yet something impossible happened: the total energy (kinetic + stored +
//             gravity, evaluated every 10 steps) rose above its start by more than 5 % of the problem's energy
//             scale (nothing in these problems supplies energy: the walls are fixed and the gravity is
//             conservative), or the energy became non-finite. A silent cell means a blow-up the detector missed.
//             (The first map found one: a lone particle whose step outran its stability bound collapsed to J <= 0
//             with a finite state and a NaN energy; the engines now report J <= 0, FailureKind::Inverted.)
//
// Problems (2D slabs one cell thick, CPU or GPU engine):
//  * Splash: a water column a = 0.1 m wide and 2a high collapses in a tank 3a long (Martin & Moyce's set-up, shorter)
//    and hits the far wall, which throws a splash up the wall. A second body of lone particles (12 particles, each
//    alone in its cell, 3 cells apart) flies at 3 times Ritter's front speed 2 sqrt(g a) towards the far wall and up:
//    isolated particles against a wall, the case where explicit MPM codes meet infinities. Energy scale: the column's
//    potential energy m g a plus the lone particles' kinetic energy. Run to T = t sqrt(2 g / a) = 4.
//    Parameters: the CFL number of both bodies (a scene's material.CFL, (0, 1]), the stiffness c0 / (2 sqrt(g a))
//    (the sound speed over the front speed), the scheme; and, for code only, a step forced to a multiple of fbar's
//    (dt_factor, CpuEngine::step(dt): not a scene's choice, and not checked against the bound).
//  * Block: an elastic block (FixedCorotated, E = 1e6 Pa, rho 1000) of 0.1 m falls 0.1 m onto a floor (Separable) and
//    bounces (to t = 0.3 s). Poisson's ratio nu from 0.3 to 0.499 (towards incompressibility the p-wave speed grows without bound;
//    fbar's step follows it), F-bar off or on, the scheme. Energy scale: m g (drop height + block height).
#pragma once

#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace stability_case {

using validation::r3;

enum class State { Stable, Detected, Silent };

inline const char* to_string(State s) {
  return s == State::Stable ? "stable" : s == State::Detected ? "detected" : "silent";
}

struct StabilityResult {
  State state = State::Stable;
  std::string message;       ///< the report of a detected failure; what was impossible for a silent one
  double energy_gain = 0;    ///< [-] largest E(t) - E(0) over the energy scale
  double energy_scale = 0;   ///< [J]
  long long steps = 0;
  std::size_t particles = 0;
  double simulated = 0;      ///< [s]
  double seconds = 0;        ///< [s] wall time
};

struct SplashSetup {
  validation::Scheme scheme = validation::kApic;
  double cfl = 0.5;         ///< [-] the bodies' CFL number (material.CFL)
  double dt_factor = 1.0;   ///< [-] each step is this multiple of the engine's step (1: the engine's own steps)
  double stiffness = 10.0;  ///< [-] c0 / (2 sqrt(g a))
  double cells = 8;         ///< cells per a
  bool lone_particles = true;
};

struct BlockSetup {
  validation::Scheme scheme = validation::kApic;
  double dt_factor = 1.0;
  double poisson = 0.3;
  double fbar_psi = 0.0;
  double cells = 8;  ///< cells per block edge
};

constexpr double kG = 9.81;
constexpr double kA = 0.1;  // [m] splash column width

/// Gravity potential energy sum m g y over the bodies [J].
template <class Engine>
double potential_energy(Engine& engine, int bodies) {
  double e = 0.0;
  for (int b = 0; b < bodies; ++b) {
    const auto& x = engine.positions(b);
    const auto m = engine.masses(b);
    for (std::size_t p = 0; p < x.size(); ++p) e += static_cast<double>(m[p]) * kG * static_cast<double>(x[p][1]);
  }
  return e;
}

/// Steps `engine` to t_end with dt = dt_factor x the CFL step and classes the run.
template <class Engine>
StabilityResult run_and_class(Engine& engine, int bodies, double dt_factor, double t_end, double energy_scale) {
  const auto start = std::chrono::steady_clock::now();
  StabilityResult r;
  r.energy_scale = energy_scale;
  long long first_wrong = -1;  // the step at which the energy first rose past 5 % of its scale
  for (int b = 0; b < bodies; ++b) r.particles += engine.positions(b).size();
  auto energy = [&]() { return engine.kinetic_energy() + engine.elastic_energy() + potential_energy(engine, bodies); };
  const double e0 = energy();
  while (engine.time() < t_end) {
    const StepReport s = dt_factor == 1.0 ? engine.step()
                                          : engine.step(std::min(dt_factor * engine.next_dt(),
                                                                 t_end - engine.time() + 1e-15));
    ++r.steps;
    if (!s.ok) {
      r.state = State::Detected;
      r.message = s.message();
      if (first_wrong >= 0 && r.steps - first_wrong > 20) {
        r.state = State::Silent;
        r.message = "the energy rose by " + std::to_string(r.energy_gain) + " of its scale " +
                    std::to_string(r.steps - first_wrong) + " steps before the report: " + r.message;
      }
      break;
    }
    if (r.steps % 10 != 0 && engine.time() < t_end) continue;  // the energy every 10 steps (a GPU readback)
    const double e = energy();
    if (!std::isfinite(e)) {
      r.state = State::Silent;
      r.message = "the energy became non-finite without a report";
      break;
    }
    r.energy_gain = std::max(r.energy_gain, (e - e0) / energy_scale);
    if (first_wrong < 0 && r.energy_gain > 0.05) first_wrong = r.steps;
  }
  if (r.state == State::Stable && r.energy_gain > 0.05) {
    r.state = State::Silent;
    r.message = "the energy rose by " + std::to_string(r.energy_gain) + " of its scale without a report";
  }
  r.simulated = engine.time();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

/// The splash problem (see the file comment). T, TG: particle and grid scalars.
template <typename T, typename TG = T, class Engine = CpuEngine<T, TG>>
StabilityResult run_splash(const SplashSetup& setup) {
  const double dx = kA / setup.cells;
  const double x0 = 2 * dx, y0 = 2 * dx, z0 = 2 * dx;
  const double front = 2 * std::sqrt(kG * kA);  // Ritter's front speed
  const double c0 = setup.stiffness * front;
  Scene scene = validation::make_scene(r3(x0 + 3 * kA + 2 * dx, y0 + 4 * kA + 2 * dx, z0 + 3 * dx), dx, r3(0, -kG, 0));
  scene.simulation.precision = !std::is_same_v<T, TG>     ? Precision::Mixed
                               : std::is_same_v<T, float> ? Precision::Single
                                                          : Precision::Double;
  BodySpec column = validation::jfluid_body(1000.0, 1000.0 * c0 * c0, 7.0, 1e-3, 8.0, setup.cfl);
  validation::set_scheme(column, setup.scheme);
  validation::add_box(column, r3(x0, y0, z0), r3(kA, 2 * kA, dx));
  scene.bodies.push_back(column);
  int bodies = 1;
  if (setup.lone_particles) {
    // 12 particles, one per half-cell box on the particle lattice, 3 cells apart, above the column's right half.
    BodySpec spray = column;
    spray.geometry.clear();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 3; ++j)
        validation::add_box(spray, r3(x0 + 0.5 * kA + 3 * i * dx, y0 + 2 * kA + (2 + 3 * j) * dx, z0),
                            r3(0.5 * dx, 0.5 * dx, 0.5 * dx));
    spray.velocity = r3(3 * front, 1.5 * front, 0);
    scene.bodies.push_back(spray);
    bodies = 2;
  }
  scene.boundaries.push_back(validation::wall_box(Contact::Separable, r3(x0, y0, z0),
                                                  r3(x0 + 3 * kA, y0 + 4 * kA, z0 + dx), dx,
                                                  validation::WallFit::LastWallNodePlane));
  Engine engine(scene);
  const double m_column = 1000.0 * kA * 2 * kA * dx;
  const double m_spray = setup.lone_particles ? 12 * 1000.0 * dx * dx * dx / 8 : 0.0;
  const double scale = m_column * kG * kA + 0.5 * m_spray * (9 + 2.25) * front * front;
  return run_and_class(engine, bodies, setup.dt_factor, 4.0 / std::sqrt(2 * kG / kA), scale);
}

/// The bouncing block (see the file comment).
template <typename T, typename TG = T, class Engine = CpuEngine<T, TG>>
StabilityResult run_block(const BlockSetup& setup) {
  const double edge = 0.1, drop = 0.1;
  const double dx = edge / setup.cells;
  const double x0 = 2 * dx, y0 = 2 * dx, z0 = 2 * dx;
  Scene scene = validation::make_scene(r3(x0 + 3 * edge + 2 * dx, y0 + drop + 2 * edge, z0 + 3 * dx), dx,
                                       r3(0, -kG, 0));
  scene.simulation.precision = !std::is_same_v<T, TG>     ? Precision::Mixed
                               : std::is_same_v<T, float> ? Precision::Single
                                                          : Precision::Double;
  BodySpec block = validation::fixed_corotated_body(1000.0, 1e6, setup.poisson);
  validation::set_scheme(block, setup.scheme);
  block.algorithm.use_fbar = setup.fbar_psi != 0.0;
  block.algorithm.fbar_psi = setup.fbar_psi;
  block.algorithm.fbar_scheme = FbarScheme::Cell;  // the cell scheme's stability (the nodal one: test_fbar_locking.cpp)
  validation::add_box(block, r3(x0 + edge, y0 + drop, z0), r3(edge, edge, dx));
  scene.bodies.push_back(block);
  scene.boundaries.push_back(validation::wall_box(Contact::Separable, r3(x0, y0, z0),
                                                  r3(x0 + 3 * edge, validation::kFar, z0 + dx), dx,
                                                  validation::WallFit::LastWallNodePlane));
  Engine engine(scene);
  const double m = 1000.0 * edge * edge * dx;
  // Falls in 0.14 s, lands and bounces; 0.3 s in all.
  return run_and_class(engine, 1, setup.dt_factor, 0.3, m * kG * (drop + edge));
}

}  // namespace stability_case
}  // namespace fbar
