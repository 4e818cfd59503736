// The CPU reference engine (cpu_engine.h): construction, checkpoints, the initial state and the step (try,
// failure checks' verdict, commit, the retry policy, landing on a target time).
#include "engine/cpu/cpu_engine.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "MnBase/Math/bspline.h"
#include "comm/placement.h"
#include "scene/attributes.h"
#include "geometry/geometry.h"
#include "physics/grid_update.cuh"
#include "engine/hydrostatic.h"
#include "io/particle_frame.h"
#include "settings.h"
#include "physics/time_step.cuh"
#include "io/sensor_recorder.h"
#include "scene/scene_parse.h"
#include "physics/transfer.cuh"
#include "engine/cpu/cpu_engine_detail.h"

namespace fbar {

using namespace cpu_detail;


// ---------------------------------------------------------------------------------------------
// Construction

template <typename T, typename TG>
CpuEngine<T, TG>::CpuEngine(const Scene& scene) : scene_(scene), log_(&std::cerr) {
  std::vector<std::vector<Vec3d>> positions;
  std::vector<ParticleSeeds> seeds(scene.bodies.size());
  std::vector<Aabb> bounds(scene.bodies.size());
  for (std::size_t b = 0; b < scene.bodies.size(); ++b)
    positions.push_back(sample_body(scene.bodies[b], scene.simulation, static_cast<int>(b), &seeds[b], &bounds[b]));
  init(positions);
  apply_hydrostatic(bounds);
  apply_seeds(seeds);
}

template <typename T, typename TG>
CpuEngine<T, TG>::CpuEngine(const Scene& scene, const std::vector<std::vector<Vec3d>>& positions)
    : scene_(scene), log_(&std::cerr) {
  init(positions);
  std::vector<Aabb> bounds(scene.bodies.size());
  for (std::size_t b = 0; b < scene.bodies.size(); ++b)
    if (scene.bodies[b].initial_state == InitialState::Hydrostatic)
      bounds[b] = body_geometry_bounds(scene.bodies[b], scene.simulation, static_cast<int>(b));
  apply_hydrostatic(bounds);
}

template <typename T, typename TG>
CpuEngine<T, TG>::CpuEngine(const Scene& scene, comm::Transport& transport, double rebalance_threshold)
    : scene_(scene), transport_(&transport), rebalance_threshold_(rebalance_threshold), log_(&std::cerr) {
  std::vector<std::vector<Vec3d>> positions;
  std::vector<ParticleSeeds> seeds(scene.bodies.size());
  std::vector<Aabb> bounds(scene.bodies.size());
  for (std::size_t b = 0; b < scene.bodies.size(); ++b)
    positions.push_back(sample_body(scene.bodies[b], scene.simulation, static_cast<int>(b), &seeds[b], &bounds[b]));
  init(positions);
  apply_hydrostatic(bounds);
  apply_seeds(seeds);
  if (ranks() > 1) divide_replicated();  // every rank sampled every particle (deterministically)
}

template <typename T, typename TG>
void CpuEngine<T, TG>::divide_replicated() {
  // The slabs follow from the local counts, and each rank keeps the particles it owns.
  choose_slabs_now(true);
  for (Body& body : bodies_) {
    std::vector<int> owner(body.x.size());
    for (std::size_t p = 0; p < body.x.size(); ++p) owner[p] = owner_of(body, body.x[p]);
    keep_own_particles(body, owner);
  }
  measure_balance();
  chosen_imbalance_ = imbalance_;
}

template <typename T, typename TG>
CpuEngine<T, TG>::CpuEngine(const Scene& scene, const io::Checkpoint& cp, comm::Transport* transport,
                            double rebalance_threshold)
    : scene_(scene), rebalance_threshold_(rebalance_threshold), log_(&std::cerr) {
  if (transport) transport_ = transport;
  io::check_matches(cp, scene);
  std::vector<std::vector<Vec3d>> positions(cp.bodies.size());
  for (std::size_t b = 0; b < cp.bodies.size(); ++b) {
    const io::CheckpointBody& c = cp.bodies[b];
    positions[b].resize(c.particles());
    for (std::size_t p = 0; p < c.particles(); ++p) positions[b][p] = Vec3d{{c.x[3 * p], c.x[3 * p + 1], c.x[3 * p + 2]}};
  }
  init(positions);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const io::CheckpointBody& c = cp.bodies[b];
    Body& body = bodies_[b];
    const std::size_t n = c.particles();
    for (std::size_t p = 0; p < n; ++p) {
      body.id[p] = c.id[p];
      for (int a = 0; a < 3; ++a) body.v[p][a] = static_cast<T>(c.v[3 * p + a]);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) body.C[p](i, j) = static_cast<T>(c.C[9 * p + 3 * i + j]);
      body.mass[p] = static_cast<T>(c.mass[p]);
      body.volume[p] = static_cast<T>(c.volume[p]);
    }
    std::visit(
        [&](auto& mb) {
          using State = typename std::decay_t<decltype(mb.state)>::value_type;
          constexpr int S = static_cast<int>(sizeof(State) / sizeof(T));
          const std::size_t W = static_cast<std::size_t>(c.state_scalars);  // S (+ 1 with nodal F-bar: check_matches)
          for (std::size_t p = 0; p < n; ++p) {
            T v[S];
            for (int i = 0; i < S; ++i) v[i] = static_cast<T>(c.state[W * p + i]);
            std::memcpy(&mb.state[p], v, sizeof(State));
            if (body.fbar_nodal) body.jbar[p] = static_cast<T>(c.state[W * p + S]);
          }
        },
        body.material);
    body.max_wave_speed = c.max_wave_speed;
  }
  time_ = cp.time;
  steps_ = cp.steps;
  last_dt_ = cp.last_dt;
  max_grid_speed_ = cp.max_grid_speed;
  retry_.scale = cp.dt_scale;
  retry_.clean_steps = cp.clean_steps;
  if (ranks() > 1) {
    // (one slab when only placed bodies have particles: comm/placement.h)
    if (cp.ranks == ranks() && cp.rank == rank() && cp.slab_cuts.size() >= 2) {
      slabs_.axis = cp.slab_axis;  // this rank's own particles, in their slot order
      slabs_.cuts = cp.slab_cuts;
      measure_balance();
      chosen_imbalance_ = cp.chosen_imbalance;
    } else {  // every rank holds every particle (the merged set): divide them as at start
      if (cp.ranks != 1)
        throw std::invalid_argument("--restart: a checkpoint of rank " + std::to_string(cp.rank) + " of " +
                                    std::to_string(cp.ranks) + " given to rank " + std::to_string(rank()) + " of " +
                                    std::to_string(ranks()));
      divide_replicated();
    }
  } else if (cp.ranks != 1) {
    throw std::invalid_argument("--restart: a checkpoint of rank " + std::to_string(cp.rank) + " of " +
                                std::to_string(cp.ranks) + " given to a one-rank run (merge the set first)");
  }
}

template <typename T, typename TG>
CpuEngine<T, TG>::~CpuEngine() = default;

template <typename T, typename TG>
io::Checkpoint CpuEngine<T, TG>::checkpoint() const {
  io::Checkpoint c;
  c.engine = "cpu";
  c.precision = to_string(scene_.simulation.precision);
  c.rank = rank();
  c.ranks = ranks();
  c.time = time_;
  c.steps = steps_;
  c.last_dt = last_dt_;
  c.next_dt = next_dt();
  c.max_grid_speed = max_grid_speed_;
  c.dt_scale = retry_.scale;
  c.clean_steps = retry_.clean_steps;
  if (ranks() > 1) {
    c.slab_axis = slabs_.axis;
    c.slab_cuts = slabs_.cuts;
    c.chosen_imbalance = chosen_imbalance_;
  }
  std::vector<long long> counts;
  for (const Body& body : bodies_) counts.push_back(static_cast<long long>(body.x.size()));
  if (!counts.empty()) transport_->allreduce_sum(counts.data(), static_cast<int>(counts.size()));
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& body = bodies_[b];
    io::CheckpointBody out;
    out.law = to_string(body.spec.material.law);
    out.global_particles = counts[b];
    out.max_wave_speed = body.max_wave_speed;
    const std::size_t n = body.x.size();
    out.id = body.id;
    out.x.resize(3 * n);
    out.v.resize(3 * n);
    out.C.resize(9 * n);
    out.mass.assign(body.mass.begin(), body.mass.end());
    out.volume.assign(body.volume.begin(), body.volume.end());
    for (std::size_t p = 0; p < n; ++p)
      for (int a = 0; a < 3; ++a) {
        out.x[3 * p + a] = static_cast<double>(body.x[p][a]);
        out.v[3 * p + a] = static_cast<double>(body.v[p][a]);
        for (int j = 0; j < 3; ++j) out.C[9 * p + 3 * a + j] = static_cast<double>(body.C[p](a, j));
      }
    std::visit(
        [&](const auto& mb) {
          using State = typename std::decay_t<decltype(mb.state)>::value_type;
          constexpr int S = static_cast<int>(sizeof(State) / sizeof(T));
          const std::size_t W = S + (body.fbar_nodal ? 1 : 0);  // nodal F-bar: 1 - JBar after the law's scalars
          out.state_scalars = static_cast<int>(W);
          out.state.resize(W * n);
          for (std::size_t p = 0; p < n; ++p) {
            T v[S];
            std::memcpy(v, &mb.state[p], sizeof(State));
            for (int i = 0; i < S; ++i) out.state[W * p + i] = static_cast<double>(v[i]);
            if (body.fbar_nodal) out.state[W * p + S] = static_cast<double>(body.jbar[p]);
          }
        },
        body.material);
    c.bodies.push_back(std::move(out));
  }
  return c;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::init(const std::vector<std::vector<Vec3d>>& positions) {
  const SimulationSpec& sim = scene_.simulation;
  k_ = RunConstants<T>(scene_, "CPU engine");
  kg_ = RunConstants<TG>(scene_, "CPU engine");
  slabs_ = comm::choose_slabs(comm::PlaneCounts{}, 1);  // all of space (a decomposed run chooses again)
  if (positions.size() != scene_.bodies.size())
    throw std::invalid_argument("CpuEngine: one position list per body expected");
  time_ = sim.time;

  double max_speed = 0.0;
  bodies_.resize(scene_.bodies.size());
  const std::vector<int> homes = comm::body_ranks(scene_, ranks());  // bodies[].gpu (comm/placement.h)
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    bodies_[b].home = homes[b];
    placed_ = placed_ || homes[b] >= 0;
  }
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b) {
    const BodySpec& spec = scene_.bodies[b];
    check_engine_body(spec, static_cast<int>(b), "CPU engine");
    const std::string where = body_path(scene_, b);
    const MaterialSpec& mat = spec.material;
    const AlgorithmSpec& alg = spec.algorithm;

    Body& body = bodies_[b];
    body.spec = spec;
    const std::size_t n = positions[b].size();
    const double volume = sim.dx * sim.dx * sim.dx / mat.ppc;
    const Vec3T v0{
        {static_cast<T>(spec.velocity[0]), static_cast<T>(spec.velocity[1]), static_cast<T>(spec.velocity[2])}};
    max_speed = std::max(max_speed, static_cast<double>(norm(v0)));
    body.id.resize(n);
    for (std::size_t p = 0; p < n; ++p) body.id[p] = static_cast<std::int64_t>(p);
    body.x.resize(n);
    const Vec3d domain{{sim.domain[0], sim.domain[1], sim.domain[2]}};
    for (std::size_t p = 0; p < n; ++p) {
      const Vec3d& q = positions[b][p];
      if (!inside_domain(q, domain, sim.dx))
        throw std::invalid_argument(where + ": particle " + std::to_string(p) + " lies outside the domain");
      body.x[p] = q.template cast<T>();
    }
    body.v.assign(n, v0);
    body.C.assign(n, Mat3T::zero());
    body.asflip = alg.asflip_active();
    body.asflip_params = AsflipParams<T>{static_cast<T>(alg.asflip_alpha), static_cast<T>(alg.asflip_beta_min),
                                         static_cast<T>(alg.asflip_beta_max)};
    asflip_ = asflip_ || body.asflip;
    body.fbar_psi = static_cast<T>(alg.fbar_blend());
    body.fbar_nodal = alg.fbar_nodal();
    body.fbar_fused = alg.fbar_fused_kernel;
    fbar_ = fbar_ || body.fbar_psi != T(0);
    body.mass.assign(n, static_cast<T>(mat.rho * volume));
    body.volume.assign(n, static_cast<T>(volume));
    body.x_next.resize(n);
    body.v_next.resize(n);
    body.C_next.resize(n);
    visit_material(mat.law, [&](auto m) {
      using M = decltype(m);
      MaterialBody<M> mb{M::template make_params<T>(mat), {}, {}};
      mb.state.assign(n, material_initial_state<M, T>(spec.material));
      pore_ = pore_ || IsPoreFluid<M>::value;
      mb.next_state.resize(n);
      body.max_wave_speed = static_cast<double>(M::wave_speed(mb.params, M::template reference_state<T>()));
      body.material = std::move(mb);
    });
    if (body.fbar_nodal) {
      body.jbar.resize(n);
      body.jbar_next.resize(n);
      init_jbar(body);
    }
    if (spec.mesh >= 0) init_mesh(body);
  }
  max_grid_speed_ = max_speed;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::init_jbar(Body& body) {
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < mb.state.size(); ++p) body.jbar[p] = one_minus_volume_ratio<M>(mb.state[p]);
      },
      body.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::apply_hydrostatic(const std::vector<Aabb>& bounds) {
  for (std::size_t b = 0; b < bodies_.size() && b < bounds.size(); ++b) {
    Body& body = bodies_[b];
    const HydrostaticProfile h = hydrostatic_profile(body.spec, scene_.simulation, bounds[b].lo, bounds[b].hi);
    if (!h.active) continue;
    std::visit(
        [&](auto& mb) {
          using M = typename std::decay_t<decltype(mb)>::material_type;
          for (std::size_t p = 0; p < body.x.size(); ++p) {
            mb.state[p] = material_hydrostatic_state<M, T>(mb.params, h.kirchhoff_pressure(body.x[p].template cast<double>()));
            body.max_wave_speed = std::max(body.max_wave_speed, static_cast<double>(M::wave_speed(mb.params, mb.state[p])));
          }
        },
        body.material);
    if (body.fbar_nodal) init_jbar(body);
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::apply_seeds(const std::vector<ParticleSeeds>& seeds) {
  for (std::size_t b = 0; b < bodies_.size() && b < seeds.size(); ++b) {
    const ParticleSeeds& seed = seeds[b];
    if (seed.empty()) continue;
    Body& body = bodies_[b];
    std::visit(
        [&](auto& mb) {
          using M = typename std::decay_t<decltype(mb)>::material_type;
          for (std::size_t i = 0; i < seed.size(); ++i) {
            const std::size_t p = static_cast<std::size_t>(seed.first) + i;  // slot = ID before any division
            const double* s = seed.at(i);
            if (!std::isnan(s[kSeedVelocity]))
              for (int a = 0; a < 3; ++a) body.v[p][a] = static_cast<T>(s[kSeedVelocity + a]);
            mb.state[p] = material_seeded_state<M, T>(mb.state[p], s);
            if (body.fbar_nodal) body.jbar[p] = one_minus_volume_ratio<M>(mb.state[p]);
            max_grid_speed_ = std::max(max_grid_speed_, static_cast<double>(norm(body.v[p])));
            body.max_wave_speed = std::max(body.max_wave_speed, static_cast<double>(M::wave_speed(mb.params, mb.state[p])));
          }
        },
        body.material);
  }
}

// ---------------------------------------------------------------------------------------------
// Step

template <typename T, typename TG>
typename CpuEngine<T, TG>::TryResult CpuEngine<T, TG>::try_step(double dt_in) {
  const T dt = static_cast<T>(dt_in);
  TryResult result;
  result.max_wave_speed.assign(bodies_.size(), 0.0);
  result.count.assign(bodies_.size(), {});
  result.first.assign(bodies_.size(), {});
  const int nblocks = static_cast<int>(grid_.blocks.size());
#pragma omp parallel for schedule(static) if (nblocks >= kMinParallelBlocks)
  for (int gb = 0; gb < nblocks; ++gb) {
    std::memset(&grid_.blocks[gb], 0, sizeof(GridBlock));
    if (asflip_) std::memset(&grid_.asflip[gb], 0, sizeof(AsflipBlock));
    if (pore_) std::memset(&grid_.pore[gb], 0, sizeof(PoreBlock));
  }
  for (Body& body : bodies_) {
    if (body.force_of) {
      body.force.resize(body.x.size());
      for (std::size_t p = 0; p < body.x.size(); ++p)
        body.force[p] = body.force_of(body.id[p], body.x[p].template cast<double>(), time_).template cast<T>();
    }
    p2g(body, dt);
  }
  if (ranks() > 1) exchange_halo(false);
  if ((node_volume_ && grid_sample_slot_ >= 0) || grid_fields_.reads_volume()) {
    // a Volume or JBar sensor or field samples: every body's volume on the nodes
    grid_.fbar.resize(grid_.blocks.size());
    clear_fbar_sums();
    for (Body& body : bodies_) fbar_node_sums(body, dt, true);
    if (ranks() > 1) exchange_halo(true);
  }
  result.max_grid_speed = update_grid(static_cast<TG>(dt_in));
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    if (bodies_[b].fbar_psi != T(0)) {  // F-bar averages within one body
      if (bodies_[b].fbar_nodal)
        fbar_node_sums(bodies_[b], dt);
      else
        fbar_cell_sums(bodies_[b]);
      if (ranks() > 1) exchange_halo(true);
    }
    g2p(static_cast<int>(b), bodies_[b], dt, result);
    if (bodies_[b].is_mesh()) {  // the elements at the new positions: next step's forces, the vertex states
      const MeshPassResult m = mesh_after_g2p(bodies_[b]);
      constexpr int kInverted = static_cast<int>(FailureKind::Inverted);
      result.count[b][kInverted] += m.inverted;
      if (m.inverted > 0) result.first[b][kInverted] = std::min(result.first[b][kInverted], m.first_inverted);
      result.max_wave_speed[b] = std::max(result.max_wave_speed[b], m.max_wave_speed);
      constexpr int kNonFinite = static_cast<int>(FailureKind::NonFinite);
      result.count[b][kNonFinite] += m.nonfinite;
      if (m.nonfinite > 0) result.first[b][kNonFinite] = std::min(result.first[b][kNonFinite], m.first_nonfinite);
    }
  }
  reduce_try(result, static_cast<double>(dt));  // the dt the step ran with (float in single precision)
  return result;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::commit(const TryResult& result, double dt) {
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    Body& body = bodies_[b];
    body.x.swap(body.x_next);
    body.v.swap(body.v_next);
    body.C.swap(body.C_next);
    std::visit([](auto& mb) { mb.state.swap(mb.next_state); }, body.material);
    body.jbar.swap(body.jbar_next);
    body.mesh.force.swap(body.mesh.force_next);
    body.max_wave_speed = result.max_wave_speed[b];
  }
  time_ += dt;
  ++steps_;
  last_dt_ = dt;
  max_grid_speed_ = result.max_grid_speed;
  partition_valid_ = false;
}

template <typename T, typename TG>
double CpuEngine<T, TG>::next_dt() const {
  double bound = k_.default_dt;
  for (const Body& body : bodies_)  // (a mesh's element bound is part of k_.default_dt: run_constants.h)
    bound = min_time_step(
        bound, cfl_time_step(body.spec.material.cfl, scene_.simulation.dx, body.max_wave_speed, max_grid_speed_));
  return bound * retry_.scale;
}

template <typename T, typename TG>
StepReport CpuEngine<T, TG>::step_impl(double dt, bool cfl_dt) {
  if (!(dt > 0.0) || !std::isfinite(dt)) throw std::invalid_argument("CpuEngine::step: dt must be positive");
  StepReport report;
  for (;;) {
    if (!partition_valid_) build_partition();
    TryResult result = try_step(dt);
    if (result.failures.empty()) {
      commit(result, dt);
      if (ranks() > 1) migrate();
      report.dt = dt;
      report.steps = 1;
      retry_.committed(cfl_dt);
      return report;
    }
    if (retry_.retry(scene_.simulation.on_failure, result.failures, cfl_dt, dt, report, log_)) continue;
    report.ok = false;
    report.dt = dt;
    report.failures = std::move(result.failures);
    return report;
  }
}

template <typename T, typename TG>
StepReport CpuEngine<T, TG>::step() {
  return step_impl(next_dt(), true);
}

template <typename T, typename TG>
StepReport CpuEngine<T, TG>::step(double dt) {
  return step_impl(dt, false);
}

template <typename T, typename TG>
StepReport CpuEngine<T, TG>::step_toward(double t_end) {
  const StepPlan plan = plan_step_toward(time_, t_end, next_dt());
  StepReport r = step_impl(plan.dt, true);
  plan.land(time_, t_end, r);
  return r;
}

template <typename T, typename TG>
StepReport CpuEngine<T, TG>::advance_to(double t_end) {
  StepReport total;
  while (time_ < t_end && total.absorb(step_toward(t_end))) {
  }
  return total;
}

template class CpuEngine<double, double>;
template class CpuEngine<float, float>;
template class CpuEngine<double, float>;

}  // namespace fbar
