// Decomposition with placed bodies (bodies[].gpu, comm/placement.h): the blocks any set of ranks holds, listed
// per peer and summed in rank order. Part of MgspBenchmark.
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

/// rebuild_shared, step 4: the table indices of the changed peer lists (every key is in the table here: found, not
/// inserted), the union of all lists and each entry's place in it. Returns whether any list changed.
template <typename T, typename TG>
bool MgspBenchmark<T, TG>::index_shared_lists(const std::vector<bool>& changed) {
  using Key = unsigned long long;
  bool any = false;
  const int r = rank(), n = ranks();
  // Every changed list's lookups are queued, then one synchronisation (the keys stay alive until it).
  std::vector<cuda::DeviceArray<Key>> keys(static_cast<std::size_t>(n));
  for (int q = 0; q < n; ++q) {
    if (!changed[q]) continue;
    any = true;
    SharedPeer& peer = dec_.shared[q];
    const int count = static_cast<int>(peer.keys.size());
    keys[q].allocate(peer.keys.size());
    peer.index.allocate(peer.keys.size());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(keys[q].get(), peer.keys.data(), sizeof(Key) * peer.keys.size(),
                                    cudaMemcpyHostToDevice, stream_));
    insert_halo_blocks<TG><<<cuda::grid_for(count, kHaloThreads), kHaloThreads, 0, stream_>>>(
        table_.view(), keys[q].get(), count, peer.index.get(), grid_sums(0).view(), grid_sums(1).view());
    cuda::check_launch("insert_halo_blocks");
    peer.blocks.resize(peer.keys.size());
    FBAR_CUDA_CHECK(cudaMemcpyAsync(peer.blocks.data(), peer.index.get(), sizeof(int) * peer.blocks.size(),
                                    cudaMemcpyDeviceToHost, stream_));
  }
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  for (int q = 0; q < n; ++q)
    if (changed[q])
      for (int b : dec_.shared[q].blocks)
        if (b < 0)
          throw std::logic_error("GpuEngine: a shared block is missing from this rank's table (rank " +
                                 std::to_string(r) + ", peer " + std::to_string(q) + ")");
  if (any) {
    std::vector<int> all;
    for (int q = 0; q < n; ++q) all.insert(all.end(), dec_.shared[q].blocks.begin(), dec_.shared[q].blocks.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    dec_.union_blocks = std::move(all);
    dec_.union_index.allocate(std::max<std::size_t>(dec_.union_blocks.size(), 1));
    if (!dec_.union_blocks.empty())
      FBAR_CUDA_CHECK(cudaMemcpyAsync(dec_.union_index.get(), dec_.union_blocks.data(), sizeof(int) * dec_.union_blocks.size(),
                                      cudaMemcpyHostToDevice, stream_));
    std::vector<std::vector<int>> positions(static_cast<std::size_t>(n));  // host sources of the copies below
    for (int q = 0; q < n; ++q) {
      SharedPeer& peer = dec_.shared[q];
      if (q == r || peer.blocks.empty()) continue;
      std::vector<int>& upos = positions[q];
      upos.resize(peer.blocks.size());
      for (std::size_t k = 0; k < upos.size(); ++k)
        upos[k] = static_cast<int>(std::lower_bound(dec_.union_blocks.begin(), dec_.union_blocks.end(), peer.blocks[k]) -
                                   dec_.union_blocks.begin());
      peer.upos.allocate(upos.size());
      FBAR_CUDA_CHECK(cudaMemcpyAsync(peer.upos.get(), upos.data(), sizeof(int) * upos.size(), cudaMemcpyHostToDevice,
                                      stream_));
    }
    FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // the positions are host temporaries
  }
  return any;
}

/// rebuild_shared, step 5: the just-created blocks take their summed values (grid[summed_grid]) from their lowest
/// earlier holder, whose values every earlier holder shares (sync_out / sync_in: the keys this rank sends to and
/// receives from each rank); then the summed values of the whole union are kept for a delta exchange.
template <typename T, typename TG>
void MgspBenchmark<T, TG>::sync_new_shared_blocks(int summed_grid,
                                                  const std::vector<std::vector<unsigned long long>>& sync_out,
                                                  const std::vector<std::vector<unsigned long long>>& sync_in) {
  using Key = unsigned long long;
  const int r = rank(), n = ranks();
  constexpr int kScalars = static_cast<int>(GridBuffer<TG>::kBlockBytes / sizeof(TG));
  TG* grid = reinterpret_cast<TG*>(grid_sums(summed_grid).data());
  std::unordered_map<Key, int> where;
  for (int q = 0; q < n; ++q)
    for (std::size_t k = 0; k < dec_.shared[q].keys.size(); ++k) where[dec_.shared[q].keys[k]] = dec_.shared[q].blocks[k];
  auto indices = [&](const std::vector<Key>& keys) {
    std::vector<int> out;
    for (Key k : keys) {
      const auto it = where.find(k);
      if (it == where.end()) throw std::logic_error("GpuEngine: a block to synchronise is not shared");
      out.push_back(it->second);
    }
    return out;
  };
  std::vector<cuda::DeviceArray<int>> out_index(static_cast<std::size_t>(n)), in_index(static_cast<std::size_t>(n));
  std::vector<cuda::DeviceArray<TG>> out_values(static_cast<std::size_t>(n)), in_values(static_cast<std::size_t>(n));
  // The host index lists live until the synchronisation at the end (their copies are queued, not waited for).
  std::vector<std::vector<int>> out_idx(static_cast<std::size_t>(n)), in_idx(static_cast<std::size_t>(n));
  std::vector<comm::DeviceTransport::Message> messages;
  for (int q = 0; q < n; ++q) {
    if (q == r || (sync_out[q].empty() && sync_in[q].empty())) continue;
    comm::DeviceTransport::Message m;
    m.peer = q;
    if (!sync_out[q].empty()) {
      const std::vector<int>& idx = out_idx[q] = indices(sync_out[q]);
      out_index[q].allocate(idx.size());
      out_values[q].allocate(idx.size() * kScalars);
      FBAR_CUDA_CHECK(cudaMemcpyAsync(out_index[q].get(), idx.data(), sizeof(int) * idx.size(), cudaMemcpyHostToDevice,
                                      stream_));
      const int count = static_cast<int>(idx.size());
      launch_pack_halo(grid, kScalars, out_index[q].get(), count, out_values[q].get(), stream_);
      m.send = out_values[q].get();
      m.send_bytes = sizeof(TG) * idx.size() * kScalars;
    }
    if (!sync_in[q].empty()) {
      const std::vector<int>& idx = in_idx[q] = indices(sync_in[q]);
      in_index[q].allocate(idx.size());
      in_values[q].allocate(idx.size() * kScalars);
      FBAR_CUDA_CHECK(cudaMemcpyAsync(in_index[q].get(), idx.data(), sizeof(int) * idx.size(), cudaMemcpyHostToDevice,
                                      stream_));
      m.recv = in_values[q].get();
      m.recv_bytes = sizeof(TG) * idx.size() * kScalars;
    }
    messages.push_back(m);
  }
  dec_.device->exchange(messages, stream_);
  for (int q = 0; q < n; ++q) {
    if (sync_in[q].empty()) continue;
    const int count = static_cast<int>(sync_in[q].size());  // a new block is zero here: adding sets it
    launch_add_halo_as<TG>(grid_halo(summed_grid), kScalars, in_index[q].get(), count, in_values[q].get(),
                           static_cast<const TG*>(nullptr), stream_);
  }
  const std::size_t count = dec_.union_blocks.size() * kScalars;
  for (int g = 0; g < 2; ++g)
    if (dec_.union_saved[g].size() < count) dec_.union_saved[g].allocate(count);  // the other grid: saved at its sum
  if (!dec_.union_blocks.empty()) {
    launch_pack_halo(grid, kScalars, dec_.union_index.get(), static_cast<int>(dec_.union_blocks.size()),
                     dec_.union_saved[summed_grid].get(), stream_);
  }
  FBAR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // the message buffers and index lists are freed on return
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::rebuild_shared(int summed_grid, const std::vector<unsigned long long>& fresh_here) {
  using Key = unsigned long long;
  const int r = rank(), n = ranks();
  // 1. Every rank's new keys (table blocks are never removed: a rank's keys only grow).
  std::vector<std::vector<Key>> fresh(static_cast<std::size_t>(n));
  {
    comm::Bytes packed(sizeof(Key) * fresh_here.size());
    if (!packed.empty()) std::memcpy(packed.data(), fresh_here.data(), packed.size());
    const std::vector<comm::Bytes> all = dec_.host->allgather(packed);
    for (int q = 0; q < n; ++q) {
      fresh[q].resize(all[q].size() / sizeof(Key));
      if (!fresh[q].empty()) std::memcpy(fresh[q].data(), all[q].data(), all[q].size());
      std::sort(fresh[q].begin(), fresh[q].end());
    }
  }
  // 2. Before the new keys join: a new block's lowest earlier holder (-1: nobody held it, its sums are zero
  // everywhere). It sends grid[summed_grid]'s values of the block to the ranks that have just created it.
  auto earliest = [&](Key k) {
    for (int q = 0; q < n; ++q)
      if (dec_.rank_keys[q].count(k)) return q;
    return -1;
  };
  std::vector<std::vector<Key>> sync_out(static_cast<std::size_t>(n)), sync_in(static_cast<std::size_t>(n));
  for (int q = 0; q < n; ++q) {
    if (q == r) continue;
    for (Key k : fresh[q])
      if (earliest(k) == r) sync_out[q].push_back(k);
  }
  for (Key k : fresh[r]) {
    const int d = earliest(k);
    if (d >= 0) sync_in[d].push_back(k);
  }
  // 3. New entries of each peer's list: a block both ranks now hold that one of them has just created.
  std::vector<bool> changed(static_cast<std::size_t>(n), false);
  for (int q = 0; q < n; ++q) {
    if (q == r) continue;
    std::vector<Key> added;
    for (Key k : fresh[r])
      if (dec_.rank_keys[q].count(k) || std::binary_search(fresh[q].begin(), fresh[q].end(), k)) added.push_back(k);
    for (Key k : fresh[q])
      if (dec_.rank_keys[r].count(k)) added.push_back(k);
    if (added.empty()) continue;
    SharedPeer& peer = dec_.shared[q];
    peer.keys.insert(peer.keys.end(), added.begin(), added.end());
    std::sort(peer.keys.begin(), peer.keys.end());
    peer.keys.erase(std::unique(peer.keys.begin(), peer.keys.end()), peer.keys.end());
    changed[q] = true;
  }
  for (int q = 0; q < n; ++q) dec_.rank_keys[q].insert(fresh[q].begin(), fresh[q].end());
  // 4. Table indices of the changed lists, the union and each entry's place in it.
  const bool any = index_shared_lists(changed);
  if (any || dec_.not_counted.size() < static_cast<std::size_t>(block_capacity_)) mark_not_counted();
  // 5. The just-created blocks take their summed values from their lowest earlier holder.
  if (summed_grid >= 0) sync_new_shared_blocks(summed_grid, sync_out, sync_in);
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::shared_exchange(const BlockBuffers& buffers, int grid,
                                           bool delta, cudaStream_t stream) {
  const int r = rank(), n = ranks();
  const int held = static_cast<int>(dec_.union_blocks.size());
  if (held == 0) {  // nothing shared here (no rank has a message for this one): still a collective for the others
    dec_.device->exchange({}, stream);
    return;
  }
  std::size_t per_block = 0;
  for (const HaloBuffer& b : buffers) per_block += b.block_bytes / sizeof(TG);
  // 1. Each peer's blocks out, theirs in.
  std::vector<comm::DeviceTransport::Message> messages;
  for (int q = 0; q < n; ++q) {
    SharedPeer& peer = dec_.shared[q];
    if (q == r || peer.blocks.empty()) continue;
    const int count = static_cast<int>(peer.blocks.size());
    const std::size_t scalars = static_cast<std::size_t>(count) * per_block;
    if (peer.send.size() < scalars) {
      peer.send.allocate(scalars);
      peer.recv.allocate(scalars);
    }
    std::size_t offset = 0;
    for (const HaloBuffer& b : buffers) {
      const int block_scalars = static_cast<int>(b.block_bytes / sizeof(TG));
      launch_pack_halo(reinterpret_cast<const TG*>(b.data), block_scalars, peer.index.get(), count,
                       peer.send.get() + offset, stream);
      offset += static_cast<std::size_t>(count) * block_scalars;
    }
    comm::DeviceTransport::Message m;
    m.peer = q;
    m.send = peer.send.get();
    m.recv = peer.recv.get();
    m.send_bytes = m.recv_bytes = scalars * sizeof(TG);
    messages.push_back(m);
  }
  // 2. This rank's own part of every shared block (before the exchange returns: the sums below overwrite it).
  const std::size_t own = static_cast<std::size_t>(held) * per_block;
  if (dec_.union_own.size() < own) dec_.union_own.allocate(own);
  {
    std::size_t offset = 0;
    for (const HaloBuffer& b : buffers) {
      const int block_scalars = static_cast<int>(b.block_bytes / sizeof(TG));
      launch_pack_halo(reinterpret_cast<const TG*>(b.data), block_scalars, dec_.union_index.get(), held,
                       dec_.union_own.get() + offset, stream);
      offset += static_cast<std::size_t>(held) * block_scalars;
    }
  }
  dec_.device->exchange(messages, stream);
  // 3. Every holder: from zero (a delta exchange: from the saved sums, adding each part minus them), each rank's part
  // in rank order.
  std::size_t offset = 0, own_offset = 0;
  bool first = true;
  for (const HaloBuffer& b : buffers) {
    const int block_scalars = static_cast<int>(b.block_bytes / sizeof(TG));
    TG* target = reinterpret_cast<TG*>(b.data);
    const bool use_saved = first && delta;
    if (use_saved && dec_.union_saved[grid].size() < static_cast<std::size_t>(held) * block_scalars)
      throw std::logic_error("GpuEngine: a delta exchange before any sum");
    const TG* saved = use_saved ? dec_.union_saved[grid].get() : nullptr;
    const long long all = static_cast<long long>(held) * block_scalars;
    start_shared<TG><<<cuda::grid_for(all, kHaloThreads), kHaloThreads, 0, stream>>>(
        target, block_scalars, dec_.union_index.get(), held, saved);
    cuda::check_launch("start_shared");
    for (int q = 0; q < n; ++q) {
      if (q == r) {
        launch_add_shared_as<TG>(b, block_scalars, dec_.union_index.get(), held, dec_.union_own.get() + own_offset,
                                 saved, nullptr, stream);
        continue;
      }
      SharedPeer& peer = dec_.shared[q];
      if (peer.blocks.empty()) continue;
      const int count = static_cast<int>(peer.blocks.size());
      launch_add_shared_as<TG>(b, block_scalars, peer.index.get(), count, peer.recv.get() + offset * count, saved,
                               peer.upos.get(), stream);
    }
    if (first && grid >= 0) {  // the sums every holder now has, for a later delta exchange
      if (dec_.union_saved[grid].size() < static_cast<std::size_t>(all)) dec_.union_saved[grid].allocate(all);
      launch_pack_halo(target, block_scalars, dec_.union_index.get(), held, dec_.union_saved[grid].get(), stream);
    }
    offset += static_cast<std::size_t>(block_scalars);
    own_offset += static_cast<std::size_t>(held) * block_scalars;
    first = false;
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::mark_not_counted() {
  dec_.not_counted.allocate(static_cast<std::size_t>(block_capacity_));
  FBAR_CUDA_CHECK(cudaMemsetAsync(dec_.not_counted.get(), 0, static_cast<std::size_t>(block_capacity_), stream_));
  for (int q = 0; q < rank(); ++q) {
    const SharedPeer& peer = dec_.shared[q];
    if (peer.blocks.empty()) continue;
    const int count = static_cast<int>(peer.blocks.size());
    mark_blocks<<<cuda::grid_for(count, kHaloThreads), kHaloThreads, 0, stream_>>>(peer.index.get(), count,
                                                                                       dec_.not_counted.get());
    cuda::check_launch("mark_blocks");
  }
}

}  // namespace fbar
