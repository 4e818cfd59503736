// Decomposition: particles that leave a rank's slab go to its neighbour (packed by G2P2G's emigrant lists,
// appended behind the receiver's slots before the partition). Part of MgspBenchmark.
#pragma once

#include "engine/gpu/mgsp_benchmark.cuh"

namespace fbar {

template <typename T, typename TG>
void MgspBenchmark<T, TG>::migrate_particles() {
  MigrantMessage msg;
  dec_.device->exchange(pack_migrant_messages(msg), stream_);
  unpack_migrant_messages(msg);
}

template <typename T, typename TG>
std::vector<comm::DeviceTransport::Message> MgspBenchmark<T, TG>::pack_migrant_messages(MigrantMessage& msg) {
  // No host round trip: the messages have a size every rank knows (MigrantMessage), the counts travel in their
  // headers, and the host reads them with the step's one readback (settle_migration).
  static_assert(MigrantMessage::kHeaderBytes >= sizeof(int) * DtParams::kMaxBodies, "a count per body in the header");
  const int nb = body_count();
  msg = MigrantMessage{};
  msg.capacity = dec_.migrant_capacity;
  msg.bodies = nb;
  for (auto& b : bodies_) msg.widest = std::max(msg.widest, b->migrant_bytes(*this));
  const std::size_t bytes = msg.bytes();
  for (HaloSide& h : dec_.halo) {
    if (h.migrants_out.size() < bytes) h.migrants_out.allocate(bytes);
    if (h.peer >= 0 && h.migrants_in.size() < bytes) h.migrants_in.allocate(bytes);
  }
  // 1. Pack: each body into its area of both sides' messages, counted in the headers.
  for (HaloSide& h : dec_.halo)
    FBAR_CUDA_CHECK(cudaMemsetAsync(h.migrants_out.get(), 0, MigrantMessage::kHeaderBytes, stream_));
  auto header = [](cuda::DeviceArray<std::byte>& a) { return reinterpret_cast<int*>(a.get()); };
  for (auto& b : bodies_)
    b->pack_emigrants(*this, dec_.halo[0].migrants_out.get() + msg.area(b->index),
                      dec_.halo[1].migrants_out.get() + msg.area(b->index), msg.capacity,
                      header(dec_.halo[0].migrants_out) + b->index, header(dec_.halo[1].migrants_out) + b->index);
  // 2. The whole messages to the neighbours (the same size both ways).
  std::vector<comm::DeviceTransport::Message> messages;
  for (HaloSide& h : dec_.halo) {
    if (h.peer < 0) continue;
    comm::DeviceTransport::Message m;
    m.peer = h.peer;
    m.send = h.migrants_out.get();
    m.send_bytes = bytes;
    m.recv = h.migrants_in.get();
    m.recv_bytes = bytes;
    messages.push_back(m);
  }
  return messages;
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::unpack_migrant_messages(const MigrantMessage& msg) {
  const int nb = body_count();
  auto header = [](cuda::DeviceArray<std::byte>& a) { return reinterpret_cast<int*>(a.get()); };
  // 3. Immigrants behind the G2P2G's slots, `capacity` slots per neighbour (those past its count marked empty);
  // their (block, rank) before the partition.
  int sides = 0;
  for (const HaloSide& h : dec_.halo) sides += h.peer >= 0 ? 1 : 0;
  for (auto& bp : bodies_) {
    BodyBase& b = *bp;
    const int first = b.source_slots;
    const long long end = first + static_cast<long long>(sides) * msg.capacity;
    const long long room = 32LL * std::min(b.bins_capacity(1 - cur_), b.partition.bin_capacity());
    if (end > room) grow_for_arrivals(b, first, (end + 31) / 32);
    int slot = first;
    for (HaloSide& h : dec_.halo) {
      if (h.peer < 0) continue;
      b.unpack_immigrants(*this, slot, h.migrants_in.get() + msg.area(b.index), header(h.migrants_in) + b.index,
                          msg.capacity);
      slot += msg.capacity;
    }
    b.source_slots = slot;
    b.dest_from_positions(*this, 1 - cur_, b.partition.layout(cur_).src, first, slot);
  }
  record_migrant_counts<<<1, 64, 0, stream_>>>(
      nb, header(dec_.halo[0].migrants_out), header(dec_.halo[1].migrants_out),
      dec_.halo[0].peer >= 0 ? header(dec_.halo[0].migrants_in) : nullptr,
      dec_.halo[1].peer >= 0 ? header(dec_.halo[1].migrants_in) : nullptr, body_stats_d_);
  cuda::check_launch("record_migrant_counts");
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::settle_migration() {
  dec_.migrant_most = 0;
  for (auto& b : bodies_) {
    const BodyStepStats& s = body_stats_[b->index];
    int leaving = 0, arriving = 0;
    for (int side = 0; side < 2; ++side) {
      leaving += s.emigrants[side];
      arriving += s.immigrants[side];
      dec_.migrant_most = std::max({dec_.migrant_most, s.emigrants[side], s.immigrants[side]});
    }
    // G2P2G lists at most 2 x capacity emigrants (emigrant_slots): more, and half the list is above the capacity.
    dec_.migrant_most = std::max(dec_.migrant_most, (s.emigrant_list + 1) / 2);
    dec_.pending_migrated += leaving;
    b->pending_particles = b->particles - leaving + arriving;
  }
}

template <typename T, typename TG>
void MgspBenchmark<T, TG>::ensure_emigrant_lists() {
  if (!decomposed()) return;
  const std::size_t entries = 2 * static_cast<std::size_t>(dec_.migrant_capacity);
  for (auto& b : bodies_)
    if (b->emigrant_slots.size() != entries) b->emigrant_slots.allocate(entries);
}

}  // namespace fbar
