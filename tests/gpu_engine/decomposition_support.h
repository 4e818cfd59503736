// Scenes and per-rank runs shared by the GPU decomposition test (threads) and its MPI check (one process per rank).
#pragma once

#include <cuda_runtime.h>

#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "comm/device_transport.h"
#include "comm/slab_partition.h"
#include "comm/transport.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"

namespace fbar::test {

inline Real3 r3(double x, double y, double z) { return Real3{x, y, z}; }

inline BodySpec box_body(Constitutive law, Real3 offset, Real3 span, Real3 velocity) {
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

inline Scene empty_scene(Real3 domain, double dx, Real3 gravity) {
  Scene s;
  s.simulation.domain = domain;
  s.simulation.dx = dx;
  s.simulation.default_dt = 1.0;
  s.simulation.gravity = gravity;
  s.simulation.precision = Precision::Double;
  return s;
}

/// The water column of the CPU decomposition test (tests/physics/test_decomposition.cpp): 0.3 x 0.2 m collapsing
/// in a 0.6 m tank; slabs along x, the water of the left slabs flows across the cuts. `schemes`: ASFLIP and F-bar,
/// whose grid channels (transported momentum, cell sums) cross the halo too.
inline Scene dam_break(bool schemes) {
  Scene scene = empty_scene(r3(0.64, 0.4, 0.2), 0.02, r3(0, -9.81, 0));
  BodySpec water = box_body(Constitutive::JFluid, r3(0.04, 0.04, 0.04), r3(0.3, 0.2, 0.12), r3(0, 0, 0));
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

/// A soft block (E 1e4 Pa) travelling at 2 m/s along x without gravity: every particle crosses the cuts, and the
/// first rank ends with no particle at all; a second, still block keeps a second body on the way.
inline Scene travelling_block() {
  Scene scene = empty_scene(r3(0.8, 0.2, 0.2), 0.01, r3(0, 0, 0));
  BodySpec block = box_body(Constitutive::FixedCorotated, r3(0.06, 0.06, 0.06), r3(0.16, 0.08, 0.08), r3(2, 0, 0));
  block.material.youngs_modulus = 1e4;
  scene.bodies.push_back(block);
  return scene;
}

struct ParticleState {
  Vec3d x, v;
};
using StateById = std::map<std::pair<int, int>, ParticleState>;

struct RunResult {
  StateById states;
  std::vector<double> mass;  ///< per body, per particle [kg]
  std::string error;
  double time = 0.0;
  long long steps = 0;
  long long migrated = 0;
  std::size_t halo_blocks = 0;
  bool always_owned = true;
};

/// One rank: `steps` CFL steps on CUDA device `gpu`, then every particle it holds. host: null for a run without
/// decomposition; nccl: NCCL between the ranks (each on its own GPU), else peer copies between threads.
inline RunResult run_rank(const Scene& scene, comm::Transport* host, int steps, int gpu = 0, bool nccl = false) {
  RunResult out;
  try {
    FBAR_CUDA_CHECK(cudaSetDevice(gpu));
    std::unique_ptr<comm::DeviceTransport> device;
    GpuEngineOptions options;
    if (host) {
      device = nccl ? comm::make_nccl_transport(*host) : comm::make_thread_device_transport(*host);
      options.ranks = host;
      options.device_ranks = device.get();
    }
    GpuEngine<double> engine(scene, options);
    engine.set_log(nullptr);
    engine.set_record_velocities(true);
    for (int s = 0; s < steps; ++s) {
      const StepReport r = engine.step();
      if (!r.ok) {
        out.error = r.message();
        return out;
      }
      out.halo_blocks = std::max(out.halo_blocks, engine.halo_blocks());
    }
    out.time = engine.time();
    out.steps = engine.steps();
    out.migrated = engine.migrated();
    const comm::SlabPartition& slabs = engine.slabs();
    const double inv_dx = 1.0 / scene.simulation.dx;
    for (int b = 0; b < engine.body_count(); ++b) {
      out.mass.push_back(engine.particle_mass(b));
      const ParticleSnapshot<double> s = engine.snapshot(b);
      for (std::size_t p = 0; p < s.x.size(); ++p) {
        if (!s.present.empty() && !s.present[p]) continue;
        out.states[{b, static_cast<int>(p)}] = {s.x[p], s.v[p]};
        // The GPU engine's particle block: floor((base - 1) / 4), base = floor(x / dx - 0.5).
        const double x = s.x[p][slabs.axis];
        const int block = static_cast<int>(std::floor((std::floor(x * inv_dx - 0.5) - 1.0) / 4.0));
        if (slabs.owner(block) != engine.rank()) out.always_owned = false;
      }
    }
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  return out;
}


// Tolerances. The GPU sums P2G contributions with atomics in arrival order, and its fixed-point P2G arena rounds
// each contribution to a quantum proportional to the largest particle momentum of the rank (kernels/
// g2p2g_kernel.cuh): so two runs on ONE rank already differ in the last bits of a node's sums, and a decomposed
// run rounds with each rank's own quantum and adds the neighbour's halo sums as one more term. What is compared is
// "the same run up to summation order and rounding". Measured on an H100 (double, 2 and 3 ranks, 120 steps):
// dam breaks max |dx| 3.3e-16 m, |dv| 4.4e-15 m/s, momentum 5.8e-16; the travelling block (a body edge with
// light nodes sets the grid speed, so dt) |dx| 4.9e-13 m, |dv| 5.8e-15 m/s, time 2.3e-12 relative. The bounds
// leave a factor of 20 or more.
constexpr double kPositionTolerance = 1e-11;  // [m]
constexpr double kVelocityTolerance = 1e-12;  // [m/s]
constexpr double kMomentumTolerance = 1e-14;  // [-] of sum m |v|
constexpr double kTimeTolerance = 1e-10;      // [-] relative

}  // namespace fbar::test
