// The CPU reference engine (cpu_engine.h): partition, P2G, grid update, G2P, checks, totals and frames.
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

namespace fbar {
namespace {

constexpr int kBlockSide = settings::kBlockSide;
static_assert(kBlockSide == 4, "the block packing below assumes 4x4x4 blocks");
/// A particle block's stencils span nodes 0..5 (base 0..3 inside the block, + 0..2) along each axis.
constexpr int kArenaSide = kBlockSide + 2;
constexpr int kArenaNodes = kArenaSide * kArenaSide * kArenaSide;

/// Below these sizes a loop runs on one thread: a parallel region costs microseconds (far more when the cores are
/// shared), more than a few blocks of work.
constexpr int kMinParallelParticles = 4096;
constexpr int kMinParallelBlocks = 4;

constexpr int arena_index(int a, int b, int c) { return (a * kArenaSide + b) * kArenaSide + c; }
constexpr int block_node(int i, int j, int k) { return (i * kBlockSide + j) * kBlockSide + k; }
/// Which of the 2x2x2 grid blocks of a particle block an arena node (a, b, c) falls in, and where.
constexpr int arena_neighbour(int a, int b, int c) { return ((a >> 2) * 2 + (b >> 2)) * 2 + (c >> 2); }
constexpr int arena_node_in_block(int a, int b, int c) { return block_node(a & 3, b & 3, c & 3); }

/// Floor division by 4 (arithmetic shift: defined for negatives by every compiler fbar supports, and by C++20).
inline int block_of_node(int node) { return node >> 2; }
inline Vec3i block_of_node(const Vec3i& node) {
  return Vec3i{{block_of_node(node[0]), block_of_node(node[1]), block_of_node(node[2])}};
}

/// 21 bits per axis, offset by 2^20: block coordinates in [-2^20, 2^20) (4 million cells each way).
constexpr int kKeyBias = 1 << 20;
inline std::uint64_t pack_block(const Vec3i& b) {
  return (static_cast<std::uint64_t>(b[0] + kKeyBias) << 42) | (static_cast<std::uint64_t>(b[1] + kKeyBias) << 21) |
         static_cast<std::uint64_t>(b[2] + kKeyBias);
}
/// Parity colour 0..7: blocks of one colour are >= 2 blocks apart along some axis, so their 2x2x2 footprints are
/// disjoint.
inline int colour_of(const Vec3i& b) { return (b[0] & 1) | ((b[1] & 1) << 1) | ((b[2] & 1) << 2); }

const char* law_name(Constitutive law) {
  const char* name = "?";
  visit_material(law, [&](auto m) { name = decltype(m)::kJsonName; });
  return name;
}

/// Every scalar of a trivially copyable state made of T is finite.
template <typename T, typename S>
bool state_is_finite(const S& s) {
  static_assert(std::is_trivially_copyable_v<S> && sizeof(S) % sizeof(T) == 0, "state must be made of T");
  T values[sizeof(S) / sizeof(T)];
  std::memcpy(values, &s, sizeof(S));
  for (const T v : values)
    if (!std::isfinite(v)) return false;
  return true;
}

std::string format_g(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace

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
          constexpr int S = static_cast<int>(sizeof(State) / sizeof(T));  // = c.state_scalars (check_matches)
          for (std::size_t p = 0; p < n; ++p) {
            T v[S];
            for (int i = 0; i < S; ++i) v[i] = static_cast<T>(c.state[static_cast<std::size_t>(S) * p + i]);
            std::memcpy(&mb.state[p], v, sizeof(State));
          }
        },
        body.material);
    body.max_wave_speed = c.max_wave_speed;
  }
  time_ = cp.time;
  steps_ = cp.steps;
  last_dt_ = cp.last_dt;
  max_grid_speed_ = cp.max_grid_speed;
  dt_scale_ = cp.dt_scale;
  clean_steps_ = cp.clean_steps;
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
  c.dt_scale = dt_scale_;
  c.clean_steps = clean_steps_;
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
          out.state_scalars = S;
          out.state.resize(static_cast<std::size_t>(S) * n);
          for (std::size_t p = 0; p < n; ++p) {
            T v[S];
            std::memcpy(v, &mb.state[p], sizeof(State));
            for (int i = 0; i < S; ++i) out.state[static_cast<std::size_t>(S) * p + i] = static_cast<double>(v[i]);
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
    const std::string where = "bodies[" + std::to_string(b) + "]";
    const MaterialSpec& mat = spec.material;
    if (material_index(mat.law) < 0)
      throw std::invalid_argument(where + ".material.constitutive: " + law_name(mat.law) +
                                  " is not implemented by the CPU engine (implemented: " + supported_material_names() +
                                  ")");
    if (mat.type != "particles")
      throw std::invalid_argument(where + ".material.type: \"" + mat.type + "\" bodies are not implemented");
    const AlgorithmSpec& alg = spec.algorithm;
    if (alg.use_fem) throw std::invalid_argument(where + ".algorithm.use_FEM: not implemented by the CPU engine");
    for (const std::string& name : spec.output_attribs) {
      const std::string canonical = canonical_attribute(name);
      if (canonical.empty() || !engine_supports_attribute(mat.law, canonical))
        throw std::invalid_argument(where + ".output_attribs: " + name + " is not available for a " +
                                    law_name(mat.law) + " body");
    }
    if (!(mat.ppc > 0.0)) throw std::invalid_argument(where + ".material.ppc: must be positive");

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
      mb.next_state.resize(n);
      body.max_wave_speed = static_cast<double>(M::wave_speed(mb.params, M::template reference_state<T>()));
      body.material = std::move(mb);
    });
  }
  max_grid_speed_ = max_speed;
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
            max_grid_speed_ = std::max(max_grid_speed_, static_cast<double>(norm(body.v[p])));
            body.max_wave_speed = std::max(body.max_wave_speed, static_cast<double>(M::wave_speed(mb.params, mb.state[p])));
          }
        },
        body.material);
  }
}

// ---------------------------------------------------------------------------------------------
// Partition: particle blocks per body, active grid blocks for all bodies

template <typename T, typename TG>
void CpuEngine<T, TG>::build_partition() {
  grid_.index.clear();
  grid_.coords.clear();
  std::unordered_map<std::uint64_t, int> block_of_key;
  for (Body& body : bodies_) {
    Partition& part = body.partition;
    const int n = static_cast<int>(body.x.size());
    part.particle_block.resize(n);
    std::vector<std::uint64_t>& keys = part.particle_key;
    keys.resize(n);
#pragma omp parallel for schedule(static) if (n >= kMinParallelParticles)
    for (int p = 0; p < n; ++p) keys[p] = pack_block(block_of_node(quadratic_bspline_inv(body.x[p], k_.inv_dx).base));

    // Serial, in particle order: block numbering and the counting sort below are then deterministic. Sampled
    // bodies come in lattice order, so consecutive particles mostly share a block and skip the hash lookup.
    block_of_key.clear();
    part.block_keys.clear();
    part.block_coords.clear();
    std::uint64_t last_key = 0;
    int last_block = -1;
    for (int p = 0; p < n; ++p) {
      if (last_block < 0 || keys[p] != last_key) {
        const auto [it, inserted] = block_of_key.try_emplace(keys[p], static_cast<int>(part.block_keys.size()));
        if (inserted) {
          part.block_keys.push_back(keys[p]);
          part.block_coords.push_back(block_of_node(quadratic_bspline_inv(body.x[p], k_.inv_dx).base));
        }
        last_key = keys[p];
        last_block = it->second;
      }
      part.particle_block[p] = last_block;
    }
    const int nb = static_cast<int>(part.block_keys.size());
    part.block_start.assign(nb + 1, 0);
    for (int p = 0; p < n; ++p) ++part.block_start[part.particle_block[p] + 1];
    for (int b = 0; b < nb; ++b) part.block_start[b + 1] += part.block_start[b];
    part.order.resize(n);
    {
      std::vector<int> fill(part.block_start.begin(), part.block_start.end() - 1);
      for (int p = 0; p < n; ++p) part.order[fill[part.particle_block[p]]++] = p;
    }
    for (auto& list : part.colour_blocks) list.clear();
    for (int b = 0; b < nb; ++b) part.colour_blocks[colour_of(part.block_coords[b])].push_back(b);
    part.largest_colour = 0;
    for (const auto& list : part.colour_blocks)
      part.largest_colour = std::max(part.largest_colour, static_cast<int>(list.size()));

    // Grid blocks: each particle block's 2x2x2 footprint.
    part.grid_blocks.resize(nb);
    for (int b = 0; b < nb; ++b) {
      const Vec3i& c = part.block_coords[b];
      for (int di = 0; di < 2; ++di)
        for (int dj = 0; dj < 2; ++dj)
          for (int dk = 0; dk < 2; ++dk) {
            const Vec3i g{{c[0] + di, c[1] + dj, c[2] + dk}};
            const auto [it, inserted] = grid_.index.try_emplace(pack_block(g), static_cast<int>(grid_.coords.size()));
            if (inserted) grid_.coords.push_back(g);
            part.grid_blocks[b][(di * 2 + dj) * 2 + dk] = it->second;
          }
    }
  }
  grid_.blocks.resize(grid_.coords.size());
  if (asflip_) grid_.asflip.resize(grid_.coords.size());
  if (fbar_) grid_.fbar.resize(grid_.coords.size());
  partition_valid_ = true;
}

// ---------------------------------------------------------------------------------------------
// P2G

template <typename T, typename TG>
void CpuEngine<T, TG>::p2g(Body& body, T dt) {
  const Partition& part = body.partition;
  const T dx = k_.dx, inv_dx = k_.inv_dx, d_inv = k_.d_inv;
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        const auto params = mb.params;
        const auto& state = mb.state;
#pragma omp parallel if (part.largest_colour >= kMinParallelBlocks)
        {
          // (channel, node) private arena of one particle block: mass, momentum x, y, z; summed in the grid scalar
          // type (float in mixed precision, like the GPU engine's arena and grid).
          TG arena_m[kArenaNodes];
          TG arena_p[3][kArenaNodes];
          TG arena_q[3][kArenaNodes];  // ASFLIP: the momentum without the stress impulse, m (v + C (x_i - x_p))
          for (int colour = 0; colour < 8; ++colour) {
            const std::vector<int>& list = part.colour_blocks[colour];
            const int count = static_cast<int>(list.size());
        // The implicit barrier at the end of each `omp for` keeps the colours in order.
#pragma omp for schedule(dynamic, 1)
            for (int li = 0; li < count; ++li) {
              const int pb = list[li];
              const Vec3i& origin = part.block_coords[pb];
              std::fill(arena_m, arena_m + kArenaNodes, TG(0));
              for (auto& ch : arena_p) std::fill(ch, ch + kArenaNodes, TG(0));
              if (asflip_)
                for (auto& ch : arena_q) std::fill(ch, ch + kArenaNodes, TG(0));
              for (int q = part.block_start[pb]; q < part.block_start[pb + 1]; ++q) {
                const int p = part.order[q];
                const QuadraticBspline<T> s = quadratic_bspline_inv(body.x[p], inv_dx);
                const int l0 = s.base[0] - origin[0] * kBlockSide;
                const int l1 = s.base[1] - origin[1] * kBlockSide;
                const int l2 = s.base[2] - origin[2] * kBlockSide;
                const StressResult<T> stress = M::kirchhoff_stress(params, state[p], body.C[p]);
                P2GParticle<T> payload =
                    mls_p2g_particle(body.mass[p], body.volume[p], body.v[p], body.C[p], stress.kirchhoff, dt, d_inv);
                if (!body.force.empty()) payload.momentum += body.force[p] * dt;  // set_particle_forces
                for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                  const int a = arena_index(l0 + i, l1 + j, l2 + k);
                  const Vec3T mv = p2g_node_momentum(payload, w, xixp);
                  arena_m[a] += static_cast<TG>(w * payload.mass);
                  arena_p[0][a] += static_cast<TG>(mv[0]);
                  arena_p[1][a] += static_cast<TG>(mv[1]);
                  arena_p[2][a] += static_cast<TG>(mv[2]);
                });
                // Every body transports momentum into v^n when any body uses ASFLIP: v^n = sum / (all bodies' mass).
                if (asflip_) {
                  const P2GParticle<T> transported =
                      mls_p2g_particle(body.mass[p], body.volume[p], body.v[p], body.C[p], Mat3T::zero(), dt, d_inv);
                  for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                    const int a = arena_index(l0 + i, l1 + j, l2 + k);
                    const Vec3T mv = p2g_node_momentum(transported, w, xixp);
                    for (int d = 0; d < 3; ++d) arena_q[d][a] += static_cast<TG>(mv[d]);
                  });
                }
              }
              // Add the arena to the (up to 8) grid blocks it overlaps; no other block of this colour touches them.
              const std::array<int, 8>& targets = part.grid_blocks[pb];
              for (int a = 0; a < kArenaSide; ++a)
                for (int b = 0; b < kArenaSide; ++b)
                  for (int c = 0; c < kArenaSide; ++c) {
                    const int ai = arena_index(a, b, c);
                    if (arena_m[ai] == TG(0)) continue;  // untouched node (zero weight everywhere)
                    const int gb = targets[arena_neighbour(a, b, c)];
                    GridBlock& g = grid_.blocks[gb];
                    const int node = arena_node_in_block(a, b, c);
                    g.mass[node] += arena_m[ai];
                    g.momentum[0][node] += arena_p[0][ai];
                    g.momentum[1][node] += arena_p[1][ai];
                    g.momentum[2][node] += arena_p[2][ai];
                    if (asflip_)
                      for (int d = 0; d < 3; ++d) grid_.asflip[gb].old_velocity[d][node] += arena_q[d][ai];
                  }
            }
          }
        }
      },
      body.material);
}

// ---------------------------------------------------------------------------------------------
// Grid update

template <typename T, typename TG>
double CpuEngine<T, TG>::update_grid(TG dt) {
  using Vec3G = Vec3<TG>;
  std::vector<BoundaryParams<TG>> active;
  for (std::size_t i = 0; i < kg_.boundaries.size(); ++i)
    if (boundary_active(kg_.boundaries[i], time_)) active.push_back(kg_.boundary_at_time(i, time_));
  const int nblocks = static_cast<int>(grid_.blocks.size());
  std::vector<double> block_mass(nblocks);
  // Grid sensors: each block's reduction apart, merged in block order below (independent of the thread count).
  const int sensors = grid_sample_slot_ >= 0 ? grid_sensors_.count : 0;
  std::vector<SensorAccum> block_sensors(static_cast<std::size_t>(nblocks) * sensors);
  TG max_speed_sq = TG(0);
#pragma omp parallel for schedule(static) reduction(max : max_speed_sq) if (nblocks >= kMinParallelBlocks)
  for (int gb = 0; gb < nblocks; ++gb) {
    GridBlock& g = grid_.blocks[gb];
    const Vec3i& c = grid_.coords[gb];
    // A halo block is held by two ranks: its nodes count (mass, sensors) on the rank owning its plane.
    // With placed bodies: on the lowest rank holding it (find_shared_blocks).
    const bool owned = ranks() == 1 || (placed_ ? counted_[static_cast<std::size_t>(gb)] != 0
                                                : slabs_.owner(c[0], c[1], c[2]) == rank());
    double mass_sum = 0.0;
    for (int i = 0; i < kBlockSide; ++i)
      for (int j = 0; j < kBlockSide; ++j)
        for (int k = 0; k < kBlockSide; ++k) {
          const int node = block_node(i, j, k);
          const TG m = g.mass[node];
          mass_sum += static_cast<double>(m);
          const Vec3G momentum{{g.momentum[0][node], g.momentum[1][node], g.momentum[2][node]}};
          if (asflip_) {  // v^n = transported momentum / m (P2G accumulated it in old_velocity)
            TG(&old)[3][64] = grid_.asflip[gb].old_velocity;
            const Vec3G transported{{old[0][node], old[1][node], old[2][node]}};
            const Vec3G v_old = grid_node_velocity(m, transported, Vec3G::zero(), dt);
            for (int a = 0; a < 3; ++a) old[a][node] = v_old[a];
          }
          Vec3G v = grid_node_velocity(m, momentum, kg_.gravity, dt);
          if (m > TG(0)) {
            const Vec3G x_node{{static_cast<TG>(c[0] * kBlockSide + i) * kg_.dx,
                                static_cast<TG>(c[1] * kBlockSide + j) * kg_.dx,
                                static_cast<TG>(c[2] * kBlockSide + k) * kg_.dx}};
            const Vec3G v_free = v;
            for (const BoundaryParams<TG>& b : active) v = apply_boundary(b, x_node, v, &kg_.profiles);
            if (sensors > 0 && owned)
              accumulate_grid_sensors(grid_sensors_, x_node, GridNodeSample<TG>{m, momentum, v_free, v, dt},
                                      &block_sensors[static_cast<std::size_t>(gb) * sensors]);
          }
          g.momentum[0][node] = v[0];
          g.momentum[1][node] = v[1];
          g.momentum[2][node] = v[2];
          max_speed_sq = std::max(max_speed_sq, dot(v, v));
        }
    block_mass[gb] = owned ? mass_sum : 0.0;
  }
  if (sensors > 0) {
    const std::size_t first = static_cast<std::size_t>(grid_sample_slot_) * sensors;
    if (grid_samples_.size() < first + sensors) grid_samples_.resize(first + sensors);
    for (int i = 0; i < sensors; ++i) {
      SensorAccum total;
      for (int gb = 0; gb < nblocks; ++gb) total.merge(block_sensors[static_cast<std::size_t>(gb) * sensors + i]);
      grid_samples_[first + i] = total;
    }
  }
  grid_mass_ = 0.0;
  for (double m : block_mass) grid_mass_ += m;
  if (ranks() > 1) grid_mass_ = transport_->sum(grid_mass_);
  return std::sqrt(static_cast<double>(max_speed_sq));
}

// ---------------------------------------------------------------------------------------------
// F-bar: the body's cell sums of V0 (1 - J) and V0 at the start of the step (transfer.cuh, fbar_velocity_gradient)

template <typename T, typename TG>
void CpuEngine<T, TG>::fbar_cell_sums(Body& body) {
  const int nblocks = static_cast<int>(grid_.blocks.size());
#pragma omp parallel for schedule(static) if (nblocks >= kMinParallelBlocks)
  for (int gb = 0; gb < nblocks; ++gb)
    for (auto& ch : grid_.fbar[gb].sums) std::fill(ch, ch + 64, TG(0));
  const Partition& part = body.partition;
  const T inv_dx = k_.inv_dx;
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        const auto& state = mb.state;
#pragma omp parallel if (part.largest_colour >= kMinParallelBlocks)
        {
          T arena_sum[2][kArenaNodes];  // (sum, cell) the block's deposits: V0 (1 - J), V0 (cell i at node i)
          for (int colour = 0; colour < 8; ++colour) {
            const std::vector<int>& list = part.colour_blocks[colour];
            const int count = static_cast<int>(list.size());
#pragma omp for schedule(dynamic, 1)
            for (int li = 0; li < count; ++li) {
              const int pb = list[li];
              const std::array<int, 8>& blocks = part.grid_blocks[pb];
              for (auto& ch : arena_sum) std::fill(ch, ch + kArenaNodes, T(0));
              const Vec3i& origin = part.block_coords[pb];
              for (int q = part.block_start[pb]; q < part.block_start[pb + 1]; ++q) {
                const int p = part.order[q];
                const QuadraticBspline<T> s = quadratic_bspline_inv(body.x[p], inv_dx);
                const Vec3i cell = fbar_cell_offset(body.x[p], inv_dx, s.base);
                const int a = arena_index(s.base[0] - origin[0] * kBlockSide + cell[0],
                                          s.base[1] - origin[1] * kBlockSide + cell[1],
                                          s.base[2] - origin[2] * kBlockSide + cell[2]);
                const T V0 = body.volume[p];
                arena_sum[0][a] += V0 * one_minus_volume_ratio<M>(state[p]);
                arena_sum[1][a] += V0;
              }
              // The same colour discipline as P2G: no other block of this colour touches these grid blocks.
              for (int a = 0; a < kArenaSide; ++a)
                for (int b = 0; b < kArenaSide; ++b)
                  for (int c = 0; c < kArenaSide; ++c) {
                    const int ai = arena_index(a, b, c);
                    if (arena_sum[1][ai] == T(0)) continue;
                    FbarBlock& g = grid_.fbar[blocks[arena_neighbour(a, b, c)]];
                    const int node = arena_node_in_block(a, b, c);
                    g.sums[0][node] += static_cast<TG>(arena_sum[0][ai]);
                    g.sums[1][node] += static_cast<TG>(arena_sum[1][ai]);
                  }
            }
          }
        }
      },
      body.material);
}

// ---------------------------------------------------------------------------------------------
// G2P with failure checks

template <typename T, typename TG>
void CpuEngine<T, TG>::g2p(int body_index, Body& body, T dt, TryResult& result) {
  const Partition& part = body.partition;
  const T dx = k_.dx, inv_dx = k_.inv_dx, d_inv = k_.d_inv;
  const Vec3T domain = k_.domain;
  const int nb = static_cast<int>(part.block_keys.size());
  long long count[kFailureKinds] = {};
  long long first[kFailureKinds];
  std::fill(first, first + kFailureKinds, std::numeric_limits<long long>::max());
  double max_wave = 0.0;
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        const auto params = mb.params;
        const auto& state = mb.state;
        auto& next_state = mb.next_state;
        const bool fbar = body.fbar_psi != T(0);
#pragma omp parallel if (nb >= kMinParallelBlocks)
        {
          T arena_v[3][kArenaNodes];      // (component, node) grid velocities around one particle block
          T arena_v_old[3][kArenaNodes];  // (component, node) ASFLIP's v^n, when the body uses it
          T arena_fbar[2][kArenaNodes];   // (sum, node) F-bar's cell sums, when the body uses it
          long long my_count[kFailureKinds] = {};
          long long my_first[kFailureKinds];
          std::copy(first, first + kFailureKinds, my_first);
          T my_wave = T(0);
#pragma omp for schedule(dynamic, 1)
          for (int pb = 0; pb < nb; ++pb) {
            const std::array<int, 8>& sources = part.grid_blocks[pb];
            for (int a = 0; a < kArenaSide; ++a)
              for (int b = 0; b < kArenaSide; ++b)
                for (int c = 0; c < kArenaSide; ++c) {
                  const int gb = sources[arena_neighbour(a, b, c)];
                  const GridBlock& g = grid_.blocks[gb];
                  const int node = arena_node_in_block(a, b, c);
                  const int ai = arena_index(a, b, c);
                  arena_v[0][ai] = g.momentum[0][node];
                  arena_v[1][ai] = g.momentum[1][node];
                  arena_v[2][ai] = g.momentum[2][node];
                  if (body.asflip)
                    for (int d = 0; d < 3; ++d) arena_v_old[d][ai] = grid_.asflip[gb].old_velocity[d][node];
                  if (fbar)
                    for (int d = 0; d < 2; ++d) arena_fbar[d][ai] = grid_.fbar[gb].sums[d][node];
                }
            const Vec3i& origin = part.block_coords[pb];
            for (int q = part.block_start[pb]; q < part.block_start[pb + 1]; ++q) {
              const int p = part.order[q];
              const Vec3T x = body.x[p];
              const QuadraticBspline<T> s = quadratic_bspline_inv(x, inv_dx);
              const int l0 = s.base[0] - origin[0] * kBlockSide;
              const int l1 = s.base[1] - origin[1] * kBlockSide;
              const int l2 = s.base[2] - origin[2] * kBlockSide;
              G2PSum<T> sum;
              G2POldSum<T> old;
              T cell_compression = T(0);  // F-bar's 1 - Jbar of the particle's cell
              for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                const int a = arena_index(l0 + i, l1 + j, l2 + k);
                sum.add(w, Vec3T{{arena_v[0][a], arena_v[1][a], arena_v[2][a]}}, xixp);
                if (body.asflip) old.add(w, Vec3T{{arena_v_old[0][a], arena_v_old[1][a], arena_v_old[2][a]}});
              });
              if (fbar) {
                const Vec3i cell = fbar_cell_offset(x, inv_dx, s.base);
                const int a = arena_index(l0 + cell[0], l1 + cell[1], l2 + cell[2]);
                cell_compression = fbar_cell_compression(arena_fbar[0][a], arena_fbar[1][a]);
              }
              Vec3T v = sum.velocity();
              const Mat3T C = sum.affine(d_inv);
              const auto s_new = M::advance(
                  params, state[p],
                  fbar ? fbar_velocity_gradient(C, one_minus_volume_ratio<M>(state[p]), cell_compression, body.fbar_psi, dt)
                       : C,
                  dt);
              Vec3T x_new;
              if (body.asflip) {
                const AsflipUpdate<T> u =
                    asflip_update(body.asflip_params, body.v[p], v, old.v, M::volume_ratio(s_new), dt);
                v = u.v;
                x_new = x + u.move;
              } else {
                x_new = advect(x, v, dt);
              }
              body.x_next[p] = x_new;
              body.v_next[p] = v;
              body.C_next[p] = C;
              next_state[p] = s_new;

              const bool finite = all_finite(x_new) && all_finite(v) && all_finite(C) && state_is_finite<T>(s_new);
              int failed = -1;
              if (!finite) {
                failed = static_cast<int>(FailureKind::NonFinite);
              } else if (!(M::volume_ratio(s_new) > T(0))) {
                failed = static_cast<int>(FailureKind::Inverted);
              } else {
                if (!inside_domain(x_new, domain, dx))
                  failed = static_cast<int>(FailureKind::LeftDomain);
                else if (max_abs(x_new - x) > dx)
                  failed = static_cast<int>(FailureKind::CflViolation);
                else
                  my_wave = std::max(my_wave, M::wave_speed(params, s_new));
              }
              if (failed >= 0) {
                ++my_count[failed];
                my_first[failed] = std::min<long long>(my_first[failed], body.id[p]);
              }
            }
          }
#pragma omp critical(fbar_cpu_g2p_reduce)
          {
            for (int k = 0; k < kFailureKinds; ++k) {
              count[k] += my_count[k];
              first[k] = std::min(first[k], my_first[k]);
            }
            max_wave = std::max(max_wave, static_cast<double>(my_wave));
          }
        }
        // Never below the wave speed at rest (a fluid in slight tension would otherwise loosen the bound).
        max_wave = std::max(max_wave, static_cast<double>(M::wave_speed(params, M::template reference_state<T>())));
      },
      body.material);

  result.max_wave_speed[body_index] = max_wave;
  for (int k = 0; k < kFailureKinds; ++k) {
    result.count[body_index][k] = count[k];
    result.first[body_index][k] = first[k];
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::reduce_try(TryResult& result, double dt) {
  const int nb = static_cast<int>(bodies_.size());
  if (ranks() > 1) {
    result.max_grid_speed = transport_->max(result.max_grid_speed);
    transport_->allreduce_max(result.max_wave_speed.data(), nb);
    std::vector<long long> counts, firsts;
    for (int b = 0; b < nb; ++b)
      for (int k = 0; k < kFailureKinds; ++k) {
        counts.push_back(result.count[b][k]);
        firsts.push_back(result.first[b][k]);
      }
    transport_->allreduce_sum(counts.data(), static_cast<int>(counts.size()));
    transport_->allreduce_min(firsts.data(), static_cast<int>(firsts.size()));
    for (int b = 0; b < nb; ++b)
      for (int k = 0; k < kFailureKinds; ++k) {
        result.count[b][k] = counts[static_cast<std::size_t>(kFailureKinds * b + k)];
        result.first[b][k] = firsts[static_cast<std::size_t>(kFailureKinds * b + k)];
      }
  }
  for (int b = 0; b < nb; ++b)
    for (int k = 0; k < kFailureKinds; ++k) {
      if (result.count[b][k] == 0) continue;
      FailureReport f;
      f.kind = static_cast<FailureKind>(k);
      f.body = b;
      f.step = steps_ + 1;
      f.time = time_;
      f.dt = dt;
      f.count = result.count[b][k];
      f.first_particle = result.first[b][k];
      result.failures.push_back(f);
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
  result.max_grid_speed = update_grid(static_cast<TG>(dt_in));
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    if (bodies_[b].fbar_psi != T(0)) {
      fbar_cell_sums(bodies_[b]);  // F-bar averages within one body
      if (ranks() > 1) exchange_halo(true);
    }
    g2p(static_cast<int>(b), bodies_[b], dt, result);
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
  for (const Body& body : bodies_)
    bound = min_time_step(
        bound, cfl_time_step(body.spec.material.cfl, scene_.simulation.dx, body.max_wave_speed, max_grid_speed_));
  return bound * dt_scale_;
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
      if (cfl_dt && dt_scale_ < 1.0 && ++clean_steps_ >= kRecoverSteps) {
        dt_scale_ = std::min(1.0, 2.0 * dt_scale_);
        clean_steps_ = 0;
      }
      return report;
    }
    if (scene_.simulation.on_failure == OnFailure::ReduceDt && report.retries < kMaxStepRetries) {
      if (log_)
        for (const FailureReport& f : result.failures)
          *log_ << "fbar: " << f.describe() << "; retrying the step with dt = " << format_g(dt / 2) << " s\n";
      report.retried.insert(report.retried.end(), result.failures.begin(), result.failures.end());
      ++report.retries;
      dt *= 0.5;
      if (cfl_dt) {
        dt_scale_ *= 0.5;
        clean_steps_ = 0;
      }
      continue;
    }
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
  if (r.ok && plan.last && r.retries == 0) time_ = t_end;  // land on the target exactly, not t_end +- round-off
  return r;
}

template <typename T, typename TG>
StepReport CpuEngine<T, TG>::advance_to(double t_end) {
  StepReport total;
  while (time_ < t_end && total.absorb(step_toward(t_end))) {
  }
  return total;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer) {
  io::ParticleFrame f = frame(body);
  f.exterior = exterior_filter(scene_, body);
  const auto t0 = std::chrono::steady_clock::now();
  writer.submit(path, std::move(f));
  output_wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_grid_sensors(const std::vector<GridSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(GridSensorSet<TG>::kMax))
    throw std::invalid_argument("grid-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(GridSensorSet<TG>::kMax) + " per run");
  grid_sensors_ = GridSensorSet<TG>{};
  for (const GridSensorSpec& spec : sensors)
    grid_sensors_.s[grid_sensors_.count++] = make_grid_sensor_params<TG>(spec, static_cast<double>(k_.dx));
  grid_samples_.clear();
}

template <typename T, typename TG>
std::vector<SensorAccum> CpuEngine<T, TG>::grid_samples(int slots) const {
  const std::size_t n = static_cast<std::size_t>(slots) * grid_sensors_.count;
  if (grid_samples_.size() < n) throw std::logic_error("CpuEngine::grid_samples: fewer slots were sampled");
  return std::vector<SensorAccum>(grid_samples_.begin(), grid_samples_.begin() + static_cast<std::ptrdiff_t>(n));
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(ParticleSensorSet<T>::kMax))
    throw std::invalid_argument("particle-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(ParticleSensorSet<T>::kMax) + " per run");
  particle_sensors_ = ParticleSensorSet<T>{};
  for (const ParticleSensorSpec& spec : sensors)
    particle_sensors_.s[particle_sensors_.count++] = make_particle_sensor_params<T>(spec);
  particle_samples_.clear();
}

template <typename T, typename TG>
template <class Accept, class Fn>
void CpuEngine<T, TG>::each_particle_input(const Body& b, bool sigma, const Accept& accept, const Fn& fn) const {
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < b.x.size(); ++p)  // slot order: a fixed order on each rank
          if (accept(p))
            fn(p, particle_frame_inputs<M, T>(b.x[p], b.v[p], b.C[p], mb.state[p], mb.params, b.mass[p], b.volume[p],
                                              sigma));
      },
      b.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::sample_particles(int slot) {
  const int n = particle_sensors_.count;
  if (n == 0) return;
  const std::size_t first = static_cast<std::size_t>(slot) * bodies_.size() * n;
  if (particle_samples_.size() < first + bodies_.size() * n) particle_samples_.resize(first + bodies_.size() * n);
  bool sigma = false;
  for (int i = 0; i < n; ++i) sigma = sigma || frame_quantity_reads_stress(particle_sensors_.s[i].column.quantity);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    SensorAccum* acc = &particle_samples_[first + b * n];
    for (int i = 0; i < n; ++i) acc[i] = SensorAccum{};
    const Body& body = bodies_[b];
    auto in_some_box = [&](std::size_t p) {
      for (int i = 0; i < n; ++i)
        if (sensor_box_contains(particle_sensors_.s[i].lo, particle_sensors_.s[i].hi, body.x[p])) return true;
      return false;
    };
    each_particle_input(body, sigma, in_some_box, [&](std::size_t, const FrameInputs<T>& in) {
      for (int i = 0; i < n; ++i) {
        const ParticleSensorParams<T>& s = particle_sensors_.s[i];
        if (sensor_box_contains(s.lo, s.hi, in.x)) acc[i].add(static_cast<double>(frame_value(s.column, in)));
      }
    });
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_tracker(int body, const TrackerSet& set) {
  body_at(body);
  trackers_.resize(bodies_.size());
  trackers_[body] = set;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::track(int body, std::vector<double>& values, std::vector<double>& present) const {
  const Body& b = body_at(body);
  const TrackerSet empty{};
  const TrackerSet& t = static_cast<std::size_t>(body) < trackers_.size() ? trackers_[body] : empty;
  values.assign(static_cast<std::size_t>(t.ids) * t.attribs, 0.0);
  present.assign(t.ids, 0.0);
  if (t.ids == 0) return;
  auto index = [&](std::size_t p) {
    return b.id[p] <= std::numeric_limits<int>::max() ? tracker_index(t, static_cast<int>(b.id[p])) : -1;
  };
  // Only the tracked particles' inputs are computed (a few of a whole body).
  each_particle_input(b, true, [&](std::size_t p) { return index(p) >= 0; },
                      [&](std::size_t p, const FrameInputs<T>& in) {
                        const int i = index(p);
                        present[i] = 1.0;
                        for (int a = 0; a < t.attribs; ++a)
                          values[static_cast<std::size_t>(i) * t.attribs + a] =
                              static_cast<double>(frame_value(t.column[a], in));
                      });
}

template <typename T, typename TG>
std::vector<SensorAccum> CpuEngine<T, TG>::particle_samples(int slots) const {
  const std::size_t n = static_cast<std::size_t>(slots) * bodies_.size() * particle_sensors_.count;
  if (particle_samples_.size() < n) throw std::logic_error("CpuEngine::particle_samples: fewer slots were sampled");
  return std::vector<SensorAccum>(particle_samples_.begin(), particle_samples_.begin() + static_cast<std::ptrdiff_t>(n));
}

template <typename T, typename TG>
std::string CpuEngine<T, TG>::resource_note() const {
  std::string note = std::to_string(omp_get_max_threads()) + " threads";
  if (ranks() > 1)
    note += "; " + std::to_string(ranks()) + " ranks, rank " + std::to_string(rank()) + " holds " +
            std::to_string(particle_count()) + " particles, imbalance " + format_g(100.0 * imbalance_) + " %, " +
            std::to_string(migrated_) + " migrated from it, " + std::to_string(rebalances_) + " rebalances";
  return note;
}

// ---------------------------------------------------------------------------------------------
// Particle access

template <typename T, typename TG>
const typename CpuEngine<T, TG>::Body& CpuEngine<T, TG>::body_at(int body) const {
  if (body < 0 || body >= body_count()) throw std::out_of_range("CpuEngine: no body " + std::to_string(body));
  return bodies_[body];
}
template <typename T, typename TG>
typename CpuEngine<T, TG>::Body& CpuEngine<T, TG>::body_at(int body) {
  if (body < 0 || body >= body_count()) throw std::out_of_range("CpuEngine: no body " + std::to_string(body));
  return bodies_[body];
}

template <typename T, typename TG>
std::size_t CpuEngine<T, TG>::particle_count(int body) const {
  return body_at(body).x.size();
}
template <typename T, typename TG>
std::size_t CpuEngine<T, TG>::particle_count() const {
  std::size_t n = 0;
  for (const Body& b : bodies_) n += b.x.size();
  return n;
}
template <typename T, typename TG>
Constitutive CpuEngine<T, TG>::law(int body) const {
  return body_at(body).spec.material.law;
}
template <typename T, typename TG>
const std::vector<std::int64_t>& CpuEngine<T, TG>::ids(int body) const {
  return body_at(body).id;
}
template <typename T, typename TG>
const std::vector<Vec3<T>>& CpuEngine<T, TG>::positions(int body) const {
  return body_at(body).x;
}
template <typename T, typename TG>
const std::vector<Vec3<T>>& CpuEngine<T, TG>::velocities(int body) const {
  return body_at(body).v;
}
template <typename T, typename TG>
const std::vector<Mat3<T>>& CpuEngine<T, TG>::affine(int body) const {
  return body_at(body).C;
}
template <typename T, typename TG>
const std::vector<T>& CpuEngine<T, TG>::masses(int body) const {
  return body_at(body).mass;
}
template <typename T, typename TG>
const std::vector<T>& CpuEngine<T, TG>::volumes(int body) const {
  return body_at(body).volume;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::volume_ratios(int body) const {
  const Body& b = body_at(body);
  std::vector<T> J(b.x.size());
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < J.size(); ++p) J[p] = M::volume_ratio(mb.state[p]);
      },
      b.material);
  return J;
}

template <typename T, typename TG>
std::vector<Mat3<T>> CpuEngine<T, TG>::deformation_gradients(int body) const {
  const Body& b = body_at(body);
  std::vector<Mat3T> F;
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.deformation_gradient) {
          F.reserve(mb.state.size());
          for (const auto& s : mb.state) F.push_back(s.F);
        } else {
          throw std::invalid_argument(std::string("CpuEngine: body ") + std::to_string(body) + " (" + M::kJsonName +
                                      ") stores no deformation gradient");
        }
      },
      b.material);
  return F;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::plastic_log_volumes(int body) const {
  const Body& b = body_at(body);
  std::vector<T> l;
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.log_jp) {
          l.reserve(mb.state.size());
          for (const auto& s : mb.state) l.push_back(s.logJp);
        } else {
          throw std::invalid_argument(std::string("CpuEngine: body ") + std::to_string(body) + " (" + M::kJsonName +
                                      ") stores no logJp");
        }
      },
      b.material);
  return l;
}

template <typename T, typename TG>
std::vector<Mat3<T>> CpuEngine<T, TG>::cauchy_stresses(int body) const {
  const Body& b = body_at(body);
  std::vector<Mat3T> sigma(b.x.size());
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        const int n = static_cast<int>(sigma.size());
#pragma omp parallel for schedule(static) if (n >= kMinParallelParticles)
        for (int p = 0; p < n; ++p) sigma[p] = cauchy_stress(M::kirchhoff_stress(mb.params, mb.state[p], b.C[p]));
      },
      b.material);
  return sigma;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::pressures(int body) const {
  const std::vector<Mat3T> sigma = cauchy_stresses(body);
  std::vector<T> p(sigma.size());
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = mean_pressure(sigma[i]);
  return p;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::wave_speeds(int body) const {
  const Body& b = body_at(body);
  std::vector<T> c(b.x.size());
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < c.size(); ++p) c[p] = M::wave_speed(mb.params, mb.state[p]);
      },
      b.material);
  return c;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_velocities(int body, const std::function<Vec3d(const Vec3d&)>& velocity_of_position) {
  Body& b = body_at(body);
  for (std::size_t p = 0; p < b.x.size(); ++p) {
    b.v[p] = velocity_of_position(b.x[p].template cast<double>()).template cast<T>();
    max_grid_speed_ = std::max(max_grid_speed_, static_cast<double>(norm(b.v[p])));
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_volume_ratios(int body, const std::function<double(const Vec3d&)>& J_of_position,
                                     bool rescale_mass) {
  Body& b = body_at(body);
  const SimulationSpec& sim = scene_.simulation;
  const double current_volume = sim.dx * sim.dx * sim.dx / b.spec.material.ppc;
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (std::is_same_v<M, JFluid>) {
          double c_max = 0.0;
          for (std::size_t p = 0; p < b.x.size(); ++p) {
            const double J = J_of_position(b.x[p].template cast<double>());
            if (!(J > 0.0) || !std::isfinite(J))
              throw std::invalid_argument("CpuEngine::set_volume_ratios: J must be positive and finite");
            mb.state[p] = M::template state_with_J<T>(static_cast<T>(J));
            if (rescale_mass) {
              b.volume[p] = static_cast<T>(current_volume / J);
              b.mass[p] = static_cast<T>(b.spec.material.rho * current_volume / J);
            }
            c_max = std::max(c_max, static_cast<double>(M::wave_speed(mb.params, mb.state[p])));
          }
          b.max_wave_speed = std::max(b.max_wave_speed, c_max);
        } else {
          throw std::invalid_argument(std::string("CpuEngine::set_volume_ratios: body ") + std::to_string(body) + " (" +
                                      M::kJsonName + ") does not store J");
        }
      },
      b.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_deformation_gradients(int body, const std::function<Mat3d(const Vec3d&)>& F_of_position) {
  Body& b = body_at(body);
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.deformation_gradient) {
          for (std::size_t p = 0; p < b.x.size(); ++p)
            mb.state[p].F = F_of_position(b.x[p].template cast<double>()).template cast<T>();
        } else {
          throw std::invalid_argument(std::string("CpuEngine::set_deformation_gradients: body ") +
                                      std::to_string(body) + " (" + M::kJsonName + ") does not store F");
        }
      },
      b.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_particle_forces(int body, ParticleForce force) {
  if (force && ranks() > 1)
    throw std::invalid_argument("CpuEngine::set_particle_forces: one rank only (the forces do not migrate)");
  Body& b = body_at(body);
  b.force_of = std::move(force);
  b.force.clear();
}

// ---------------------------------------------------------------------------------------------
// Totals

template <typename T, typename TG>
double CpuEngine<T, TG>::total_mass() const {
  double m = 0.0;
  for (const Body& b : bodies_)
    for (const T mp : b.mass) m += static_cast<double>(mp);
  return m;
}

template <typename T, typename TG>
Vec3d CpuEngine<T, TG>::total_momentum() const {
  Vec3d P = Vec3d::zero();
  for (const Body& b : bodies_)
    for (std::size_t p = 0; p < b.x.size(); ++p) P += b.v[p].template cast<double>() * static_cast<double>(b.mass[p]);
  return P;
}

template <typename T, typename TG>
Vec3d CpuEngine<T, TG>::angular_momentum() const {
  Vec3d L = Vec3d::zero();
  const double dx = scene_.simulation.dx;
  for (const Body& b : bodies_)
    for (std::size_t p = 0; p < b.x.size(); ++p)
      L += apic_angular_momentum(static_cast<double>(b.mass[p]), b.x[p].template cast<double>(),
                                 b.v[p].template cast<double>(), b.C[p].template cast<double>(), dx);
  return L;
}

template <typename T, typename TG>
double CpuEngine<T, TG>::kinetic_energy() const {
  double e = 0.0;
  for (const Body& b : bodies_)
    for (std::size_t p = 0; p < b.x.size(); ++p) {
      const Vec3d v = b.v[p].template cast<double>();
      e += 0.5 * static_cast<double>(b.mass[p]) * dot(v, v);
    }
  return e;
}

template <typename T, typename TG>
double CpuEngine<T, TG>::elastic_energy() const {
  double e = 0.0;
  for (const Body& b : bodies_)
    std::visit(
        [&](const auto& mb) {
          using M = typename std::decay_t<decltype(mb)>::material_type;
          for (std::size_t p = 0; p < b.x.size(); ++p)
            e += static_cast<double>(b.volume[p]) * static_cast<double>(M::energy_density(mb.params, mb.state[p]));
        },
        b.material);
  return e;
}

// ---------------------------------------------------------------------------------------------
// Output

template <typename T, typename TG>
io::ParticleFrame CpuEngine<T, TG>::frame(int body) const {
  const Body& b = body_at(body);
  FrameSource<T> src;
  src.x = &b.x;
  src.v = &b.v;
  src.id = &b.id;
  src.mass = [&](std::size_t p) { return b.mass[p]; };
  src.volume0 = [&](std::size_t p) { return b.volume[p]; };
  src.J = [&] { return volume_ratios(body); };
  src.F = [&] { return deformation_gradients(body); };
  src.sigma = [&] { return cauchy_stresses(body); };
  src.logJp = [&] { return plastic_log_volumes(body); };
  return build_frame(b.spec, body, src, "CPU engine");
}

template <typename T, typename TG>
std::size_t CpuEngine<T, TG>::memory_bytes() const {
  std::size_t bytes = 0;
  for (const Body& b : bodies_) {
    bytes += (b.x.capacity() + b.v.capacity() + b.x_next.capacity() + b.v_next.capacity()) * sizeof(Vec3T);
    bytes += (b.C.capacity() + b.C_next.capacity()) * sizeof(Mat3T);
    bytes += (b.mass.capacity() + b.volume.capacity()) * sizeof(T) + b.id.capacity() * sizeof(std::int64_t);
    std::visit([&](const auto& mb) { bytes += (mb.state.capacity() + mb.next_state.capacity()) * sizeof(mb.state[0]); },
               b.material);
    const Partition& part = b.partition;
    bytes += part.order.capacity() * sizeof(int) + part.particle_block.capacity() * sizeof(int) +
             part.particle_key.capacity() * sizeof(std::uint64_t) +
             part.grid_blocks.capacity() * sizeof(std::array<int, 8>) +
             part.block_keys.capacity() * (sizeof(std::uint64_t) + sizeof(Vec3i) + 2 * sizeof(int));
  }
  bytes += grid_.blocks.capacity() * sizeof(GridBlock) + grid_.coords.capacity() * sizeof(Vec3i) +
           grid_.asflip.capacity() * sizeof(AsflipBlock) + grid_.fbar.capacity() * sizeof(FbarBlock);
  bytes += grid_.index.size() * (sizeof(std::uint64_t) + sizeof(int) + 2 * sizeof(void*));
  return bytes;
}

// ---------------------------------------------------------------------------------------------
// Decomposition over ranks (comm/slab_partition.h): halo planes, migration, slabs

namespace {

/// Appends the bytes of a trivially copyable value.
template <typename V>
void put(comm::Bytes& out, const V& v) {
  static_assert(std::is_trivially_copyable_v<V>);
  const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
  out.insert(out.end(), b, b + sizeof(V));
}
/// Reads a trivially copyable value at `at` and advances it.
template <typename V>
V take(const comm::Bytes& in, std::size_t& at) {
  static_assert(std::is_trivially_copyable_v<V>);
  if (at + sizeof(V) > in.size()) throw std::runtime_error("CpuEngine: a truncated message from another rank");
  V v;
  std::memcpy(&v, in.data() + at, sizeof(V));
  at += sizeof(V);
  return v;
}

}  // namespace

template <typename T, typename TG>
int CpuEngine<T, TG>::owner_of(const Body& body, const Vec3T& x) const {
  if (body.home >= 0) return body.home;
  const Vec3i b = block_of_node(quadratic_bspline_inv(x, k_.inv_dx).base);
  return slabs_.owner(b[0], b[1], b[2]);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::find_shared_blocks() {
  const int r = rank(), n = ranks();
  comm::Bytes mine(grid_.coords.size() * sizeof(std::uint64_t));
  for (std::size_t gb = 0; gb < grid_.coords.size(); ++gb) {
    const std::uint64_t key = pack_block(grid_.coords[gb]);
    std::memcpy(mine.data() + gb * sizeof(key), &key, sizeof(key));
  }
  const std::vector<comm::Bytes> all = transport_->allgather(mine);
  shared_.assign(static_cast<std::size_t>(n), {});
  counted_.assign(grid_.coords.size(), 1);
  for (int q = 0; q < n; ++q) {
    if (q == r) continue;
    const comm::Bytes& theirs = all[static_cast<std::size_t>(q)];
    std::vector<std::pair<std::uint64_t, int>> both;  // (key, this rank's block)
    for (std::size_t at = 0; at + sizeof(std::uint64_t) <= theirs.size(); at += sizeof(std::uint64_t)) {
      std::uint64_t key;
      std::memcpy(&key, theirs.data() + at, sizeof(key));
      const auto it = grid_.index.find(key);
      if (it != grid_.index.end()) both.emplace_back(key, it->second);
    }
    std::sort(both.begin(), both.end());  // key order: the same list on both ranks
    std::vector<int>& list = shared_[static_cast<std::size_t>(q)];
    for (const auto& [key, gb] : both) {
      list.push_back(gb);
      if (q < r) counted_[static_cast<std::size_t>(gb)] = 0;
    }
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::exchange_shared_blocks(bool fbar_sums) {
  const int r = rank(), n = ranks();
  if (!fbar_sums) find_shared_blocks();  // the F-bar sums follow the P2G sums of the same step: the same blocks
  std::vector<int> peers;
  std::vector<comm::Bytes> send;
  for (int q = 0; q < n; ++q) {
    if (q == r) continue;
    peers.push_back(q);
    send.emplace_back();
    for (int gb : shared_[static_cast<std::size_t>(q)]) {
      if (fbar_sums) {
        put(send.back(), grid_.fbar[gb]);
      } else {
        put(send.back(), grid_.blocks[gb]);
        if (asflip_) put(send.back(), grid_.asflip[gb]);
      }
    }
  }
  const std::vector<comm::Bytes> received = transport_->exchange(peers, send);
  // Every holder adds the contributions in rank order, its own at its place, from zero: the same bits on all of them
  // (a block of three ranks: (0 + a) + b) + c everywhere; a + b = b + a is not enough there).
  std::vector<int> blocks;  // every shared block once
  {
    std::vector<unsigned char> seen(grid_.coords.size(), 0);
    for (const std::vector<int>& list : shared_)
      for (int gb : list)
        if (!seen[static_cast<std::size_t>(gb)]++) blocks.push_back(gb);
  }
  std::vector<GridBlock> own_grid;
  std::vector<AsflipBlock> own_asflip;
  std::vector<FbarBlock> own_fbar;
  for (int gb : blocks) {
    if (fbar_sums) {
      own_fbar.push_back(grid_.fbar[gb]);
      std::memset(&grid_.fbar[gb], 0, sizeof(FbarBlock));
    } else {
      own_grid.push_back(grid_.blocks[gb]);
      std::memset(&grid_.blocks[gb], 0, sizeof(GridBlock));
      if (asflip_) {
        own_asflip.push_back(grid_.asflip[gb]);
        std::memset(&grid_.asflip[gb], 0, sizeof(AsflipBlock));
      }
    }
  }
  auto add = [](TG* into, const TG* from, int count) {
    for (int k = 0; k < count; ++k) into[k] += from[k];
  };
  auto add_block = [&](int gb, const GridBlock* g, const AsflipBlock* a, const FbarBlock* f) {
    if (f) {
      add(&grid_.fbar[gb].sums[0][0], &f->sums[0][0], 2 * 64);
      return;
    }
    add(grid_.blocks[gb].mass, g->mass, 64);
    add(&grid_.blocks[gb].momentum[0][0], &g->momentum[0][0], 3 * 64);
    if (asflip_) add(&grid_.asflip[gb].old_velocity[0][0], &a->old_velocity[0][0], 3 * 64);
  };
  for (int q = 0; q < n; ++q) {
    if (q == r) {
      for (std::size_t i = 0; i < blocks.size(); ++i)
        add_block(blocks[i], fbar_sums ? nullptr : &own_grid[i], asflip_ && !fbar_sums ? &own_asflip[i] : nullptr,
                  fbar_sums ? &own_fbar[i] : nullptr);
      continue;
    }
    const std::size_t peer = static_cast<std::size_t>(q < r ? q : q - 1);
    const comm::Bytes& in = received[peer];
    std::size_t at = 0;
    for (int gb : shared_[static_cast<std::size_t>(q)]) {
      if (fbar_sums) {
        const FbarBlock f = take<FbarBlock>(in, at);
        add_block(gb, nullptr, nullptr, &f);
      } else {
        const GridBlock g = take<GridBlock>(in, at);
        AsflipBlock a{};
        if (asflip_) a = take<AsflipBlock>(in, at);
        add_block(gb, &g, &a, nullptr);
      }
    }
    if (at != in.size()) throw std::runtime_error("CpuEngine: rank " + std::to_string(q) + " shares other blocks");
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::exchange_halo(bool fbar_sums) {
  if (placed_) {
    exchange_shared_blocks(fbar_sums);
    return;
  }
  const int r = rank(), n = ranks();
  std::vector<int> peers;
  std::vector<int> planes;
  if (r > 0) {
    peers.push_back(r - 1);
    planes.push_back(slabs_.halo_plane(r - 1));
  }
  if (r + 1 < n) {
    peers.push_back(r + 1);
    planes.push_back(slabs_.halo_plane(r));
  }
  const int axis = slabs_.axis;
  std::vector<comm::Bytes> send(peers.size());
  for (std::size_t i = 0; i < peers.size(); ++i)
    for (std::size_t gb = 0; gb < grid_.coords.size(); ++gb) {
      const Vec3i& c = grid_.coords[gb];
      if (c[axis] != planes[i]) continue;
      put(send[i], c);
      if (fbar_sums) {
        put(send[i], grid_.fbar[gb]);
      } else {
        put(send[i], grid_.blocks[gb]);
        if (asflip_) put(send[i], grid_.asflip[gb]);
      }
    }
  const std::vector<comm::Bytes> received = transport_->exchange(peers, send);
  // Add what the neighbour scattered into the blocks this rank holds (a + b here, b + a there: the same sums). A
  // block only the neighbour holds is none of this rank's particles' business.
  auto add = [](TG* into, const TG* from, int count) {
    for (int k = 0; k < count; ++k) into[k] += from[k];
  };
  for (const comm::Bytes& in : received) {
    std::size_t at = 0;
    while (at < in.size()) {
      const Vec3i c = take<Vec3i>(in, at);
      const auto it = grid_.index.find(pack_block(c));
      if (fbar_sums) {
        const FbarBlock f = take<FbarBlock>(in, at);
        if (it != grid_.index.end()) add(&grid_.fbar[it->second].sums[0][0], &f.sums[0][0], 2 * 64);
      } else {
        const GridBlock g = take<GridBlock>(in, at);
        AsflipBlock a{};
        if (asflip_) a = take<AsflipBlock>(in, at);
        if (it == grid_.index.end()) continue;
        GridBlock& mine = grid_.blocks[it->second];
        add(mine.mass, g.mass, 64);
        add(&mine.momentum[0][0], &g.momentum[0][0], 3 * 64);
        if (asflip_) add(&grid_.asflip[it->second].old_velocity[0][0], &a.old_velocity[0][0], 3 * 64);
      }
    }
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::keep_own_particles(Body& body, const std::vector<int>& owner) {
  const int r = rank();
  std::visit(
      [&](auto& mb) {
        std::size_t w = 0;
        for (std::size_t p = 0; p < owner.size(); ++p) {
          if (owner[p] != r) continue;
          body.id[w] = body.id[p];
          body.x[w] = body.x[p];
          body.v[w] = body.v[p];
          body.C[w] = body.C[p];
          body.mass[w] = body.mass[p];
          body.volume[w] = body.volume[p];
          mb.state[w] = mb.state[p];
          ++w;
        }
        body.id.resize(w);
        body.x.resize(w);
        body.v.resize(w);
        body.C.resize(w);
        body.mass.resize(w);
        body.volume.resize(w);
        mb.state.resize(w);
      },
      body.material);
  resize_scratch(body);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::resize_scratch(Body& body) {
  body.x_next.resize(body.x.size());
  body.v_next.resize(body.x.size());
  body.C_next.resize(body.x.size());
  std::visit([](auto& mb) { mb.next_state.resize(mb.state.size()); }, body.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::measure_balance() {
  std::vector<long long> per_rank(static_cast<std::size_t>(ranks()), 0);
  per_rank[static_cast<std::size_t>(rank())] = static_cast<long long>(particle_count());
  transport_->allreduce_sum(per_rank.data(), ranks());
  imbalance_ = comm::imbalance(per_rank);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::migrate() {
  const int r = rank(), n = ranks();
  std::vector<int> peers;
  for (int q = 0; q < n; ++q)
    if (q != r) peers.push_back(q);
  std::vector<comm::Bytes> send(peers.size());
  auto peer_index = [&](int q) { return q < r ? q : q - 1; };
  long long sent = 0;
  for (Body& body : bodies_) {
    const std::size_t count = body.x.size();
    std::vector<int> dest(count);
    for (std::size_t p = 0; p < count; ++p) dest[p] = owner_of(body, body.x[p]);
    // Per peer: this body's particle count, then their records (ID, x, v, C, mass, V0, material state).
    std::vector<std::uint64_t> per_peer(peers.size(), 0);
    for (std::size_t p = 0; p < count; ++p)
      if (dest[p] != r) ++per_peer[static_cast<std::size_t>(peer_index(dest[p]))];
    for (std::size_t i = 0; i < peers.size(); ++i) put(send[i], per_peer[i]);
    std::visit(
        [&](const auto& mb) {
          for (std::size_t p = 0; p < count; ++p) {
            if (dest[p] == r) continue;
            comm::Bytes& out = send[static_cast<std::size_t>(peer_index(dest[p]))];
            put(out, body.id[p]);
            put(out, body.x[p]);
            put(out, body.v[p]);
            put(out, body.C[p]);
            put(out, body.mass[p]);
            put(out, body.volume[p]);
            put(out, mb.state[p]);
            ++sent;
          }
        },
        body.material);
    keep_own_particles(body, dest);
  }
  const std::vector<comm::Bytes> received = transport_->exchange(peers, send);
  // Unpack in peer (rank) order, body by body: the slot order after a migration does not depend on timing.
  std::vector<std::size_t> at(received.size(), 0);
  for (Body& body : bodies_) {
    std::visit(
        [&](auto& mb) {
          using State = typename std::decay_t<decltype(mb.state)>::value_type;
          for (std::size_t i = 0; i < received.size(); ++i) {
            const auto k = take<std::uint64_t>(received[i], at[i]);
            for (std::uint64_t j = 0; j < k; ++j) {
              body.id.push_back(take<std::int64_t>(received[i], at[i]));
              body.x.push_back(take<Vec3T>(received[i], at[i]));
              body.v.push_back(take<Vec3T>(received[i], at[i]));
              body.C.push_back(take<Mat3T>(received[i], at[i]));
              body.mass.push_back(take<T>(received[i], at[i]));
              body.volume.push_back(take<T>(received[i], at[i]));
              mb.state.push_back(take<State>(received[i], at[i]));
              if (owner_of(body, body.x.back()) != r)
                throw std::runtime_error("particle " + std::to_string(body.id.back()) +
                                         " crossed a whole slab in one step (rank " + std::to_string(r) + ")");
            }
          }
        },
        body.material);
    resize_scratch(body);
  }
  migrated_ += sent;
  partition_valid_ = false;

  // Balance: the particles per rank, and new slabs when they drifted apart beyond the threshold.
  measure_balance();
  // New slabs when the counts drifted apart beyond the threshold, and beyond 1.5 x what whole block planes allowed
  // at the last choice (a body a few planes wide cannot be split evenly; choosing again would not help).
  if (rebalance_threshold_ > 0.0 && imbalance_ > rebalance_threshold_ && imbalance_ > 1.5 * chosen_imbalance_) {
    const comm::SlabPartition before = slabs_;
    const double drifted = imbalance_;
    choose_slabs_now(false);
    chosen_imbalance_ = drifted;  // unless the new cuts do better (below)
    if (slabs_.cuts != before.cuts) {
      ++rebalances_;
      migrate();  // to the new owners; sets imbalance_ (and cannot rebalance again: the cuts are the best ones)
      chosen_imbalance_ = imbalance_;
      if (log_ && r == 0)
        *log_ << "fbar: particles per rank drifted apart (imbalance " << format_g(100 * drifted) << " % > "
              << format_g(100 * rebalance_threshold_) << " %) at step " << steps_ << ": new " << slabs_.describe()
              << ", imbalance " << format_g(100 * imbalance_) << " %\n";
    }
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::choose_slabs_now(bool replicated) {
  // Particle-block bounds and the axis of the largest extent, over every rank.
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -std::numeric_limits<double>::infinity();
  }
  for (const Body& body : bodies_) {
    if (body.home >= 0) continue;  // placed bodies have no say in the slabs
    for (const Vec3T& x : body.x) {
      const Vec3i b = block_of_node(quadratic_bspline_inv(x, k_.inv_dx).base);
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], static_cast<double>(b[a]));
        hi[a] = std::max(hi[a], static_cast<double>(b[a]));
      }
    }
  }
  if (!replicated) {
    transport_->allreduce_min(lo, 3);
    transport_->allreduce_max(hi, 3);
  }
  comm::PlaneCounts planes;
  if (!(lo[0] <= hi[0])) {
    slabs_ = comm::choose_slabs(planes, 1);  // no particles anywhere: one slab
    return;
  }
  planes.axis = comm::longest_axis(lo, hi);
  planes.first = static_cast<int>(lo[planes.axis]);
  planes.counts.assign(static_cast<std::size_t>(hi[planes.axis] - lo[planes.axis]) + 1, 0);
  for (const Body& body : bodies_) {
    if (body.home >= 0) continue;
    for (const Vec3T& x : body.x) {
      const Vec3i b = block_of_node(quadratic_bspline_inv(x, k_.inv_dx).base);
      ++planes.counts[static_cast<std::size_t>(b[planes.axis] - planes.first)];
    }
  }
  if (!replicated) transport_->allreduce_sum(planes.counts.data(), static_cast<int>(planes.counts.size()));
  slabs_ = comm::choose_slabs(planes, ranks());
}

template class CpuEngine<double, double>;
template class CpuEngine<float, float>;
template class CpuEngine<double, float>;

}  // namespace fbar
