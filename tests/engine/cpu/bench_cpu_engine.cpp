// Throughput of the CPU reference engine: particle-steps per second on a dam-break-like scene (water column + walls).
// Usage: bench_cpu_engine [dx=0.01] [steps=50] [law=JFluid|FixedCorotated] [precision=double|single]
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "engine/cpu/cpu_engine.h"

namespace {

template <typename T>
int run(const fbar::Scene& scene, int steps) {
  fbar::CpuEngine<T> engine(scene);
  engine.set_log(nullptr);
  engine.step();  // warm-up: first partition, page faults
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < steps; ++s) {
    const fbar::StepReport r = engine.step();
    if (!r.ok) {
      std::printf("failure: %s\n", r.message().c_str());
      return 2;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double n = static_cast<double>(engine.particle_count());
  std::printf(
      "%zu particles, %zu grid blocks, %d threads, %d steps in %.3f s: %.3g particle-steps/s (%.3g us per "
      "particle-step per thread), t = %.4g s, dt = %.3g s\n",
      engine.particle_count(), engine.active_grid_blocks(), omp_get_max_threads(), steps, seconds, n * steps / seconds,
      seconds * omp_get_max_threads() / (n * steps) * 1e6, engine.time(), engine.last_dt());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const double dx = argc > 1 ? std::atof(argv[1]) : 0.01;
  const int steps = argc > 2 ? std::atoi(argv[2]) : 50;
  const std::string law = argc > 3 ? argv[3] : "JFluid";
  const std::string precision = argc > 4 ? argv[4] : "double";

  fbar::Scene scene;
  scene.simulation.domain = {1.6, 0.8, 0.4};
  scene.simulation.dx = dx;
  scene.simulation.default_dt = 1e-3;
  fbar::BodySpec body;
  body.material.law = law == "FixedCorotated" ? fbar::Constitutive::FixedCorotated : fbar::Constitutive::JFluid;
  body.material.rho = 1000;
  body.material.bulk_modulus = 2e6;
  body.material.gamma = 7.0;
  body.material.youngs_modulus = 1e6;
  body.material.poisson_ratio = 0.3;
  body.algorithm.use_asflip = false;
  body.algorithm.use_fbar = false;
  fbar::GeometrySpec g;
  g.span = {0.4, 0.6, 0.3};
  g.offset = {0.05, 0.05, 0.05};
  body.geometry.push_back(g);
  scene.bodies.push_back(body);
  fbar::BoundarySpec walls;
  walls.contact = fbar::Contact::Separable;
  scene.boundaries.push_back(walls);
  return precision == "single" ? run<float>(scene, steps) : run<double>(scene, steps);
}
