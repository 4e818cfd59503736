// The CPU engine's transfers (cpu_engine.h): the partition into particle and grid blocks, P2G, the grid update,
// the F-bar cell sums and G2P with the failure checks.
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
#include "physics/seepage.cuh"
#include "physics/transfer.cuh"
#include "physics/fbar_nodal.cuh"
#include "engine/cpu/cpu_engine_detail.h"

namespace fbar {

using namespace cpu_detail;

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
  if (fbar_ || node_volume_) grid_.fbar.resize(grid_.coords.size());
  if (pore_) grid_.pore.resize(grid_.coords.size());
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
          TG arena_w[5][kArenaNodes];  // saturated bodies: the seepage channels (PoreBlock, seepage.cuh)
          constexpr bool pore = IsPoreFluid<M>::value;
          const bool mesh = body.is_mesh();
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
              if constexpr (pore)
                for (auto& ch : arena_w) std::fill(ch, ch + kArenaNodes, TG(0));
              for (int q = part.block_start[pb]; q < part.block_start[pb + 1]; ++q) {
                const int p = part.order[q];
                const QuadraticBspline<T> s = quadratic_bspline_inv(body.x[p], inv_dx);
                const int l0 = s.base[0] - origin[0] * kBlockSide;
                const int l1 = s.base[1] - origin[1] * kBlockSide;
                const int l2 = s.base[2] - origin[2] * kBlockSide;
                // A mesh vertex carries no MLS stress: its elements' force enters as an impulse (physics/fem.cuh).
                const Mat3T tau =
                    mesh ? Mat3T::zero()
                         : M::kirchhoff_stress(params, body.fbar_nodal ? fbar_stress_state<M>(params, state[p], body.jbar[p])
                                                                       : state[p],
                                               body.C[p])
                               .kirchhoff;
                P2GParticle<T> payload = mls_p2g_particle(body.mass[p], body.volume[p], body.v[p], body.C[p], tau, dt, d_inv);
                if (mesh) payload.momentum += body.mesh.force[p] * dt;
                if (!body.force.empty()) payload.momentum += body.force[p] * dt;  // set_particle_forces
                for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                  const int a = arena_index(l0 + i, l1 + j, l2 + k);
                  const Vec3T mv = p2g_node_momentum(payload, w, xixp);
                  arena_m[a] += static_cast<TG>(w * payload.mass);
                  arena_p[0][a] += static_cast<TG>(mv[0]);
                  arena_p[1][a] += static_cast<TG>(mv[1]);
                  arena_p[2][a] += static_cast<TG>(mv[2]);
                });
                if constexpr (pore) {
                  const T V = body.volume[p] * M::volume_ratio(state[p]);
                  const T rhow = M::water_density(params);
                  const T head = M::pore_pressure(state[p]) - rhow * dot(k_.gravity, body.x[p]);
                  const Vec3T flux = M::seepage(params, state[p]);
                  const Vec3T head_gradient = M::head_gradient(state[p]);
                  const T water = M::water_mass(params, body.volume[p]);
                  for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                    const int a = arena_index(l0 + i, l1 + j, l2 + k);
                    const SeepageDeposit<T> d =
                        seepage_deposit(w, xixp, d_inv, V, head + dot(head_gradient, xixp), flux, water, rhow);
                    arena_w[0][a] += static_cast<TG>(d.volume);
                    arena_w[1][a] += static_cast<TG>(d.head);
                    arena_w[2][a] += static_cast<TG>(d.inflow);
                    arena_w[3][a] += static_cast<TG>(d.water);
                    arena_w[4][a] += static_cast<TG>(d.density);
                  });
                }
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
                    if constexpr (pore) {
                      PoreBlock& w = grid_.pore[gb];
                      w.volume[node] += arena_w[0][ai];
                      w.head[node] += arena_w[1][ai];
                      w.inflow[node] += arena_w[2][ai];
                      w.water[node] += arena_w[3][ai];
                      w.density[node] += arena_w[4][ai];
                    }
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
  // Grid fields: each block's nodes apart (field, node), concatenated in block order below.
  const bool fields = grid_fields_.mask != 0;
  const bool volume = (sensors > 0 && node_volume_) || grid_fields_.reads_volume();
  std::vector<std::vector<std::pair<int, GridFieldNode>>> block_fields(fields ? nblocks : 0);
  TG max_speed_sq = TG(0);
  const TG full_volume = kg_.dx * kg_.dx * kg_.dx;  // a node's volume when material surrounds it (seepage)
  const auto holds = [&](const Vec3G& x) {  // some active boundary acts on the node (seepage: never drained)
    for (const BoundaryParams<TG>& b : active)
      if (boundary_holds(b, x, &kg_.profiles)) return true;
    return false;
  };
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
            GridNodeSample<TG> sample{m, momentum, v_free, v, dt};
            if (pore_) {
              PoreBlock& w = grid_.pore[gb];
              const SeepageNode<TG> n = seepage_node(w.volume[node], w.head[node], w.inflow[node], w.density[node],
                                                     x_node, kg_.gravity, [&] { return holds(x_node); }, full_volume);
              sample.water_mass = w.water[node];
              sample.pore_pressure = n.pressure;
              w.head[node] = n.head;
              w.inflow[node] = n.inflow;
            }
            if (volume) {
              sample.volume = grid_.fbar[gb].sums[1][node];
              sample.volume_jbar = grid_.fbar[gb].sums[0][node];
            }
            if (sensors > 0 && owned)
              accumulate_grid_sensors(grid_sensors_, x_node, sample, &block_sensors[static_cast<std::size_t>(gb) * sensors]);
            if (fields && owned) {
              const int index[3] = {c[0] * kBlockSide + i, c[1] * kBlockSide + j, c[2] * kBlockSide + k};
              for (int f = 0; f < grid_fields_.count; ++f)
                if ((grid_fields_.mask >> f & 1u) && grid_field_contains(grid_fields_.f[f], x_node))
                  block_fields[gb].emplace_back(f, grid_field_node(index, sample));
            }
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
  if (fields) {  // each field's nodes in block order (the recorder orders them by node index)
    for (int f = 0; f < grid_fields_.count; ++f)
      if (grid_fields_.mask >> f & 1u) field_samples_[static_cast<std::size_t>(f)] = GridFieldSample{static_cast<double>(dt), {}};
    for (const auto& list : block_fields)
      for (const auto& [f, node] : list) field_samples_[static_cast<std::size_t>(f)].nodes.push_back(node);
  }
  grid_mass_ = 0.0;
  for (double m : block_mass) grid_mass_ += m;
  if (ranks() > 1) grid_mass_ = transport_->sum(grid_mass_);
  return std::sqrt(static_cast<double>(max_speed_sq));
}

// ---------------------------------------------------------------------------------------------
// F-bar: the body's cell sums of V0 (1 - J) and V0 at the start of the step (transfer.cuh, fbar_velocity_gradient)

template <typename T, typename TG>
void CpuEngine<T, TG>::clear_fbar_sums() {
  const int nblocks = static_cast<int>(grid_.blocks.size());
#pragma omp parallel for schedule(static) if (nblocks >= kMinParallelBlocks)
  for (int gb = 0; gb < nblocks; ++gb)
    for (auto& ch : grid_.fbar[gb].sums) std::fill(ch, ch + 64, TG(0));
}

template <typename T, typename TG>
void CpuEngine<T, TG>::add_fbar_arena(const std::array<int, 8>& blocks, const T* sums, const T* volumes) {
  for (int a = 0; a < kArenaSide; ++a)
    for (int b = 0; b < kArenaSide; ++b)
      for (int c = 0; c < kArenaSide; ++c) {
        const int ai = arena_index(a, b, c);
        if (volumes[ai] == T(0)) continue;  // no particle's volume reached the node
        FbarBlock& g = grid_.fbar[blocks[arena_neighbour(a, b, c)]];
        const int node = arena_node_in_block(a, b, c);
        g.sums[0][node] += static_cast<TG>(sums[ai]);
        g.sums[1][node] += static_cast<TG>(volumes[ai]);
      }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::fbar_cell_sums(Body& body) {
  clear_fbar_sums();
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
              add_fbar_arena(blocks, arena_sum[0], arena_sum[1]);  // the colour discipline of P2G: no other block of this colour
                                                  // touches these grid blocks
            }
          }
        }
      },
      body.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::fbar_node_sums(Body& body, T dt, bool volume_sensor) {
  if (!volume_sensor) clear_fbar_sums();
  const Partition& part = body.partition;
  const T dx = k_.dx, inv_dx = k_.inv_dx, d_inv = k_.d_inv;
  const bool split = !volume_sensor && !body.fbar_fused;
  const bool own_j = volume_sensor && !body.fbar_nodal;  // a volume sensor reads J of a body without nodal F-bar
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        const auto& state = mb.state;
#pragma omp parallel if (part.largest_colour >= kMinParallelBlocks)
        {
          T arena_sum[2][kArenaNodes];  // (sum, node) the block's deposits: w V s, w V
          T arena_v[3][kArenaNodes];    // split: the grid velocities around the block (each particle's C)
          for (int colour = 0; colour < 8; ++colour) {
            const std::vector<int>& list = part.colour_blocks[colour];
            const int count = static_cast<int>(list.size());
#pragma omp for schedule(dynamic, 1)
            for (int li = 0; li < count; ++li) {
              const int pb = list[li];
              const std::array<int, 8>& blocks = part.grid_blocks[pb];
              for (auto& ch : arena_sum) std::fill(ch, ch + kArenaNodes, T(0));
              if (split)
                for (int a = 0; a < kArenaSide; ++a)
                  for (int b = 0; b < kArenaSide; ++b)
                    for (int c = 0; c < kArenaSide; ++c) {
                      const GridBlock& g = grid_.blocks[blocks[arena_neighbour(a, b, c)]];
                      const int node = arena_node_in_block(a, b, c);
                      for (int d = 0; d < 3; ++d) arena_v[d][arena_index(a, b, c)] = g.momentum[d][node];
                    }
              const Vec3i& origin = part.block_coords[pb];
              for (int q = part.block_start[pb]; q < part.block_start[pb + 1]; ++q) {
                const int p = part.order[q];
                const QuadraticBspline<T> s = quadratic_bspline_inv(body.x[p], inv_dx);
                const int l0 = s.base[0] - origin[0] * kBlockSide;
                const int l1 = s.base[1] - origin[1] * kBlockSide;
                const int l2 = s.base[2] - origin[2] * kBlockSide;
                const T V = body.volume[p] * M::volume_ratio(state[p]);
                T value = own_j ? one_minus_volume_ratio<M>(state[p]) : body.jbar[p];  // fused: the stored 1 - JBar
                if (split) {  // 1 - JBar dJ: advanced by the particle's own increment over this step
                  G2PSum<T> sum;
                  for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                    const int a = arena_index(l0 + i, l1 + j, l2 + k);
                    sum.add(w, Vec3T{{arena_v[0][a], arena_v[1][a], arena_v[2][a]}}, xixp);
                  });
                  value = fbar_advance_one_minus_J(value, fbar_volume_increment<M>(sum.affine(d_inv), dt));
                }
                for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T&) {
                  const int a = arena_index(l0 + i, l1 + j, l2 + k);
                  arena_sum[0][a] += w * V * value;
                  arena_sum[1][a] += w * V;
                });
              }
              add_fbar_arena(blocks, arena_sum[0], arena_sum[1]);  // the colour discipline of P2G: no other block of this colour
                                                  // touches these grid blocks
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
        const bool nodal = fbar && body.fbar_nodal;
        const bool mesh = body.is_mesh();
#pragma omp parallel if (nb >= kMinParallelBlocks)
        {
          T arena_v[3][kArenaNodes];      // (component, node) grid velocities around one particle block
          T arena_v_old[3][kArenaNodes];  // (component, node) ASFLIP's v^n, when the body uses it
          T arena_fbar[2][kArenaNodes];   // (sum, node) F-bar's cell sums, when the body uses it
          T arena_w[2][kArenaNodes];      // saturated bodies: h_i and r_i (seepage.cuh)
          constexpr bool pore = IsPoreFluid<M>::value;
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
                  if constexpr (pore) {
                    const PoreBlock& w = grid_.pore[gb];
                    arena_w[0][ai] = w.head[node];
                    arena_w[1][ai] = w.inflow[node];
                  }
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
              SeepageSum<T> seep;
              T cell_compression = T(0);  // F-bar's 1 - Jbar of the particle's cell
              T gathered = T(0);          // nodal F-bar: sum_i w_ip s_i (fbar_nodal.cuh)
              for_each_stencil_node(s, dx, [&](int i, int j, int k, T w, const Vec3T& xixp) {
                const int a = arena_index(l0 + i, l1 + j, l2 + k);
                sum.add(w, Vec3T{{arena_v[0][a], arena_v[1][a], arena_v[2][a]}}, xixp);
                if (nodal) gathered += w * fbar_node_value(arena_fbar[0][a], arena_fbar[1][a], body.fbar_fused);
                if (body.asflip) old.add(w, Vec3T{{arena_v_old[0][a], arena_v_old[1][a], arena_v_old[2][a]}});
                if constexpr (pore) seep.add(w, xixp, arena_w[0][a], arena_w[1][a]);
              });
              if (fbar && !nodal) {
                const Vec3i cell = fbar_cell_offset(x, inv_dx, s.base);
                const int a = arena_index(l0 + cell[0], l1 + cell[1], l2 + cell[2]);
                cell_compression = fbar_cell_compression(arena_fbar[0][a], arena_fbar[1][a]);
              }
              Vec3T v = sum.velocity();
              const Mat3T C = sum.affine(d_inv);
              // A mesh vertex's state is its elements' (mesh_after_g2p sets it from the new positions).
              NodalFbar<T> nf{T(0), C};
              if (nodal) nf = nodal_fbar<M>(state[p], C, gathered, body.fbar_fused, body.fbar_psi, dt);
              const Mat3T C_state = nodal ? nf.C_state
                                    : fbar ? fbar_velocity_gradient(C, one_minus_volume_ratio<M>(state[p]),
                                                                    cell_compression, body.fbar_psi, dt)
                                           : C;
              auto s_new = mesh ? state[p] : M::advance(params, state[p], C_state, dt);
              if (nodal) body.jbar_next[p] = nf.s;
              if constexpr (pore)
                s_new = M::seep(params, s_new, seep.inflow, seep.head_gradient(d_inv),
                                seep.head + M::water_density(params) * dot(k_.gravity, x),
                                M::pore_pressure(s_new) - M::pore_pressure(state[p]), dt);
              Vec3T x_new;
              if (body.asflip) {
                // Nodal F-bar: ASFLIP's expansion test reads JBar, as ClaymoreUW's does.
                const AsflipUpdate<T> u = asflip_update(body.asflip_params, body.v[p], v, old.v,
                                                        nodal ? T(1) - nf.s : M::volume_ratio(s_new), dt);
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
              } else if (!mesh && !(M::volume_ratio(s_new) > T(0))) {  // a mesh's elements: mesh_after_g2p
                failed = static_cast<int>(FailureKind::Inverted);
              } else {
                if (!inside_domain(x_new, domain, dx))
                  failed = static_cast<int>(FailureKind::LeftDomain);
                else if (max_abs(x_new - x) > dx)
                  failed = static_cast<int>(FailureKind::CflViolation);
                else
                  my_wave = std::max(my_wave, M::wave_speed(params, nodal ? fbar_stress_state<M>(params, s_new, nf.s)
                                                                          : s_new));
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
      f.elements = bodies_[static_cast<std::size_t>(b)].is_mesh() && f.kind == FailureKind::Inverted;
      result.failures.push_back(f);
    }
}

template class CpuEngine<double, double>;
template class CpuEngine<float, float>;
template class CpuEngine<double, float>;

}  // namespace fbar
