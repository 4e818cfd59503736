// The CPU engine over several ranks (cpu_engine.h; comm/slab_partition.h): shared and halo blocks, particle
// migration, slabs and rebalancing.
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
        if (pore_) put(send.back(), grid_.pore[gb]);
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
  std::vector<PoreBlock> own_pore;
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
      if (pore_) {
        own_pore.push_back(grid_.pore[gb]);
        std::memset(&grid_.pore[gb], 0, sizeof(PoreBlock));
      }
    }
  }
  auto add = [](TG* into, const TG* from, int count) {
    for (int k = 0; k < count; ++k) into[k] += from[k];
  };
  auto add_block = [&](int gb, const GridBlock* g, const AsflipBlock* a, const FbarBlock* f, const PoreBlock* w) {
    if (f) {
      add(&grid_.fbar[gb].sums[0][0], &f->sums[0][0], 2 * 64);
      return;
    }
    add(grid_.blocks[gb].mass, g->mass, 64);
    add(&grid_.blocks[gb].momentum[0][0], &g->momentum[0][0], 3 * 64);
    if (asflip_) add(&grid_.asflip[gb].old_velocity[0][0], &a->old_velocity[0][0], 3 * 64);
    if (pore_) add(grid_.pore[gb].volume, w->volume, 5 * 64);  // the five channels: one array
  };
  for (int q = 0; q < n; ++q) {
    if (q == r) {
      for (std::size_t i = 0; i < blocks.size(); ++i)
        add_block(blocks[i], fbar_sums ? nullptr : &own_grid[i], asflip_ && !fbar_sums ? &own_asflip[i] : nullptr,
                  fbar_sums ? &own_fbar[i] : nullptr, pore_ && !fbar_sums ? &own_pore[i] : nullptr);
      continue;
    }
    const std::size_t peer = static_cast<std::size_t>(q < r ? q : q - 1);
    const comm::Bytes& in = received[peer];
    std::size_t at = 0;
    for (int gb : shared_[static_cast<std::size_t>(q)]) {
      if (fbar_sums) {
        const FbarBlock f = take<FbarBlock>(in, at);
        add_block(gb, nullptr, nullptr, &f, nullptr);
      } else {
        const GridBlock g = take<GridBlock>(in, at);
        AsflipBlock a{};
        if (asflip_) a = take<AsflipBlock>(in, at);
        PoreBlock w{};
        if (pore_) w = take<PoreBlock>(in, at);
        add_block(gb, &g, &a, nullptr, &w);
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
        if (pore_) put(send[i], grid_.pore[gb]);
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
        PoreBlock w{};
        if (pore_) w = take<PoreBlock>(in, at);
        if (it == grid_.index.end()) continue;
        GridBlock& mine = grid_.blocks[it->second];
        add(mine.mass, g.mass, 64);
        add(&mine.momentum[0][0], &g.momentum[0][0], 3 * 64);
        if (asflip_) add(&grid_.asflip[it->second].old_velocity[0][0], &a.old_velocity[0][0], 3 * 64);
        if (pore_) add(grid_.pore[it->second].volume, w.volume, 5 * 64);
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
          if (body.fbar_nodal) body.jbar[w] = body.jbar[p];
          ++w;
        }
        body.id.resize(w);
        body.x.resize(w);
        body.v.resize(w);
        body.C.resize(w);
        body.mass.resize(w);
        body.volume.resize(w);
        mb.state.resize(w);
        if (body.fbar_nodal) body.jbar.resize(w);
      },
      body.material);
  resize_scratch(body);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::resize_scratch(Body& body) {
  body.x_next.resize(body.x.size());
  body.v_next.resize(body.x.size());
  body.C_next.resize(body.x.size());
  if (body.fbar_nodal) body.jbar_next.resize(body.x.size());
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
    // Per peer: this body's particle count, then their records (ID, x, v, C, mass, V0, material state, nodal
    // F-bar's 1 - JBar).
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
            if (body.fbar_nodal) put(out, body.jbar[p]);
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
              if (body.fbar_nodal) body.jbar.push_back(take<T>(received[i], at[i]));
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
  // Placed bodies are a preload of their rank (comm/placement.h placed_work): whole on their home, or everywhere
  // while the scene is still replicated.
  std::vector<long long> placed(bodies_.size(), 0);
  for (std::size_t b = 0; b < bodies_.size(); ++b)
    if (bodies_[b].home >= 0) placed[b] = static_cast<long long>(bodies_[b].x.size());
  if (!replicated) transport_->allreduce_sum(placed.data(), static_cast<int>(placed.size()));
  slabs_ = comm::choose_slabs(planes, ranks(), 1, comm::placed_work(scene_, ranks(), placed));
}

template class CpuEngine<double, double>;
template class CpuEngine<float, float>;
template class CpuEngine<double, float>;

}  // namespace fbar
