// Decomposition: the halo between neighbouring slabs (the blocks of a shared plane summed on both ranks), its
// exchange overlapping the interior G2P2G, and its rebuild when a rank has new blocks. Part of MgspBenchmark.
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
void MgspBenchmark<T, TG>::g2p2g_and_halo(T dt) {
  auto sums = [&](cudaStream_t s) {
    halo_exchange(step_halo_buffers(1 - gc_), 1 - gc_, false, s);
  };
  if (!options_.overlap_halo) {
    for (auto& b : bodies_) b->g2p2g(*this, false, dt);
    event_record(2);
    sums(stream_);
    return;
  }
  // The halo particle blocks of every body first: after them no launch of this step writes a block of a shared
  // plane (a particle block B scatters into blocks B .. B + 1 only). fbar_sums() holds one body's cell sums at a
  // time, so an F-bar body with another F-bar body after it runs its other blocks at once.
  int fbar_left = 0;
  for (const auto& b : bodies_) fbar_left += b->fbar_psi != T(0);
  std::vector<BodyBase*> rest;
  for (auto& b : bodies_) {
    b->g2p2g(*this, false, dt, G2P2GPass::Halo);
    if (b->fbar_psi != T(0) && --fbar_left > 0)
      b->g2p2g(*this, false, dt, G2P2GPass::Interior);
    else
      rest.push_back(b.get());
  }
  FBAR_CUDA_CHECK(cudaEventRecord(dec_.halo_ready, stream_));
  // The other blocks on the compute stream, queued before the exchange (a host-ordered transport may block in it).
  for (BodyBase* b : rest) b->g2p2g(*this, false, dt, G2P2GPass::Interior);
  event_record(2);
  FBAR_CUDA_CHECK(cudaStreamWaitEvent(dec_.halo_stream, dec_.halo_ready, 0));
  if (timing_) FBAR_CUDA_CHECK(cudaEventRecord(dec_.halo_events[0], dec_.halo_stream));
  sums(dec_.halo_stream);
  if (timing_) FBAR_CUDA_CHECK(cudaEventRecord(dec_.halo_events[1], dec_.halo_stream));
  FBAR_CUDA_CHECK(cudaEventRecord(dec_.halo_done, dec_.halo_stream));
  FBAR_CUDA_CHECK(cudaStreamWaitEvent(stream_, dec_.halo_done, 0));
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::halo_exchange(const BlockBuffers& buffers, int grid,
                                         bool delta, cudaStream_t stream) {
  if (!stream) stream = stream_;
  if (dec_.placed) {
    shared_exchange(buffers, grid, delta, stream);
    return;
  }
  dec_.device->exchange(pack_halo_messages(buffers, stream), stream);
  add_halo_messages(buffers, grid, delta, stream);
}

template <typename T, typename TG>
std::vector<comm::DeviceTransport::Message> MgspBenchmark<T, TG>::pack_halo_messages(const BlockBuffers& buffers,
                                                                                     cudaStream_t stream) {
  std::size_t per_block = 0;  // scalars of every listed buffer's block
  for (const HaloBuffer& b : buffers) per_block += b.block_bytes / sizeof(TG);
  std::vector<comm::DeviceTransport::Message> messages;
  for (HaloSide& h : dec_.halo) {
    if (h.peer < 0) continue;
    const int n = static_cast<int>(h.keys.size());
    const std::size_t scalars = static_cast<std::size_t>(n) * per_block;
    if (h.send.size() < scalars) {
      h.send.allocate(scalars);
      h.recv.allocate(scalars);
    }
    std::size_t offset = 0;
    for (const HaloBuffer& b : buffers) {
      const int block_scalars = static_cast<int>(b.block_bytes / sizeof(TG));
      launch_pack_halo(reinterpret_cast<const TG*>(b.data), block_scalars, h.index.get(), n, h.send.get() + offset, stream);
      offset += static_cast<std::size_t>(n) * block_scalars;
    }
    comm::DeviceTransport::Message m;
    m.peer = h.peer;
    m.send = h.send.get();
    m.recv = h.recv.get();
    m.send_bytes = m.recv_bytes = scalars * sizeof(TG);
    messages.push_back(m);
  }
  return messages;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::add_halo_messages(const BlockBuffers& buffers, int grid, bool delta, cudaStream_t stream) {
  const bool save = grid >= 0;
  for (HaloSide& h : dec_.halo) {
    if (h.peer < 0 || h.keys.empty()) continue;
    const int n = static_cast<int>(h.keys.size());
    std::size_t offset = 0;
    bool first = true;
    for (const HaloBuffer& b : buffers) {
      const int block_scalars = static_cast<int>(b.block_bytes / sizeof(TG));
      TG* target = reinterpret_cast<TG*>(b.data);
      const std::size_t count = static_cast<std::size_t>(n) * block_scalars;
      const bool saved = first && delta;
      if (saved && h.saved[grid].size() < count) throw std::logic_error("GpuEngine: a delta exchange before any sum");
      launch_add_halo_as<TG>(b, block_scalars, h.index.get(), n, h.recv.get() + offset,
                             saved ? h.saved[grid].get() : nullptr, stream);
      if (first && save) {  // the sums both ranks now hold, for a later delta exchange
        if (h.saved[grid].size() < count) h.saved[grid].allocate(count);
        launch_pack_halo(target, block_scalars, h.index.get(), n, h.saved[grid].get(), stream);
      }
      offset += count;
      first = false;
    }
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::collect_halo() {
  if (dec_.halo_fresh_capacity == 0) {
    dec_.halo_fresh_capacity = 1024;
    for (HaloSide& h : dec_.halo) h.fresh.allocate(static_cast<std::size_t>(dec_.halo_fresh_capacity));
  }
  const int limit = block_capacity_ - dec_.halo_scanned;
  if (limit <= 0) return;
  if (dec_.placed) {  // every new block may be shared with any rank
    collect_new_blocks<<<cuda::grid_for(limit, kHaloThreads), kHaloThreads, 0, stream_>>>(
        table_.view(), dec_.halo_scanned, dec_.halo[0].fresh.get(), dec_.halo_fresh_capacity, stats_d_->halo_new);
    cuda::check_launch("collect_new_blocks");
    return;
  }
  collect_halo_blocks<<<cuda::grid_for(limit, kHaloThreads), kHaloThreads, 0, stream_>>>(
      table_.view(), dec_.halo_scanned, dec_.slab.axis, dec_.halo[0].peer >= 0 ? dec_.halo[0].plane : INT_MIN,
      dec_.halo[1].peer >= 0 ? dec_.halo[1].plane : INT_MIN, dec_.halo[0].fresh.get(), dec_.halo[1].fresh.get(), dec_.halo_fresh_capacity,
      stats_d_->halo_new);
  cuda::check_launch("collect_halo_blocks");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::rebuild_halo(int summed_grid) {
  // 1. This rank's new keys per side (collected after the last partition; collected again when they overflowed).
  std::array<std::vector<unsigned long long>, 2> fresh;
  const int fresh_count[2] = {stats_->halo_new[0], stats_->halo_new[1]};
  if (std::max(fresh_count[0], fresh_count[1]) > dec_.halo_fresh_capacity) {
    while (dec_.halo_fresh_capacity < std::max(fresh_count[0], fresh_count[1])) dec_.halo_fresh_capacity *= 2;
    for (HaloSide& h : dec_.halo) h.fresh.allocate(static_cast<std::size_t>(dec_.halo_fresh_capacity));
    FBAR_CUDA_CHECK(cudaMemsetAsync(stats_d_->halo_new, 0, sizeof(stats_d_->halo_new), stream_));
    collect_halo();
  }
  for (int side = 0; side < 2; ++side) {
    fresh[side].resize(static_cast<std::size_t>(fresh_count[side]));
    if (fresh_count[side] > 0)
      FBAR_CUDA_CHECK(cudaMemcpyAsync(fresh[side].data(), dec_.halo[side].fresh.get(),
                                      sizeof(unsigned long long) * fresh[side].size(), cudaMemcpyDeviceToHost, stream_));
  }
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  dec_.halo_scanned = std::max(dec_.halo_scanned, std::min(stats_->block_count, block_capacity_));
  if (dec_.placed) {
    rebuild_shared(summed_grid, fresh[0]);
    return;
  }
  // 2. To the neighbours, and theirs back.
  std::vector<int> peers;
  std::vector<comm::Bytes> send;
  for (int side = 0; side < 2; ++side) {
    if (dec_.halo[side].peer < 0) continue;
    peers.push_back(dec_.halo[side].peer);
    const auto* b = reinterpret_cast<const std::uint8_t*>(fresh[side].data());
    send.emplace_back(b, b + sizeof(unsigned long long) * fresh[side].size());
  }
  const std::vector<comm::Bytes> received = dec_.host->exchange(peers, send);
  // 3. The union, sorted (the same list on both sides), inserted here where absent, and its table indices.
  std::size_t i = 0;
  for (int side = 0; side < 2; ++side) {
    HaloSide& h = dec_.halo[side];
    if (h.peer < 0) continue;
    const comm::Bytes& theirs = received[i++];
    std::vector<unsigned long long> all = h.keys;
    all.insert(all.end(), fresh[side].begin(), fresh[side].end());
    const std::size_t k = theirs.size() / sizeof(unsigned long long);
    const std::size_t at = all.size();
    all.resize(at + k);
    if (k) std::memcpy(all.data() + at, theirs.data(), theirs.size());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    if (all.size() == h.keys.size()) continue;
    h.keys = std::move(all);
    const int n = static_cast<int>(h.keys.size());
    cuda::DeviceArray<unsigned long long> keys;
    keys.allocate(h.keys.size());
    h.index.allocate(h.keys.size());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(keys.get(), h.keys.data(), sizeof(unsigned long long) * h.keys.size(),
                                    cudaMemcpyHostToDevice, stream_));
    for (;;) {
      insert_halo_blocks<TG><<<cuda::grid_for(n, kHaloThreads), kHaloThreads, 0, stream_>>>(
          table_.view(), keys.get(), n, h.index.get(), grid_sums(0).view(), grid_sums(1).view());
      cuda::check_launch("insert_halo_blocks");
      TableCounters c{};
      FBAR_CUDA_CHECK(cudaMemcpyAsync(&c, table_.counters(), sizeof(c), cudaMemcpyDeviceToHost, stream_));
      FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
      if (c.overflow == 0 && c.block_count <= block_capacity_) {
        block_count_ = std::max(block_count_, c.block_count);
        break;
      }
      grow_blocks(2 * block_capacity_);  // keeps every block; the inserts are repeated (existing ones are found)
    }
    // The summed values both ranks hold, in the new list's order (a block new to the list is zero on both sides:
    // it was created after the P2G that filled the grid), for a delta exchange before the next sum.
    constexpr int kScalars = static_cast<int>(GridBuffer<TG>::kBlockBytes / sizeof(TG));
    const std::size_t count = static_cast<std::size_t>(n) * kScalars;
    for (int g = 0; g < 2; ++g) h.saved[g].allocate(count);  // the other grid is summed (and saved) before its use
    if (summed_grid >= 0) {
      launch_pack_halo(reinterpret_cast<const TG*>(grid_sums(summed_grid).data()), kScalars, h.index.get(), n,
                       h.saved[summed_grid].get(), stream_);
    }
  }
  // Blocks inserted here are halo blocks already listed: not new for the next collect.
  dec_.halo_scanned = std::max(dec_.halo_scanned, block_count_);
}

}  // namespace fbar
