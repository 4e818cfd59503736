// ThreadDeviceTransport and NcclTransport (device_transport.h); without the CUDA toolkit only nccl_available().
#include "comm/device_transport.h"

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(FBAR_HAS_CUDA)
#include <cuda_runtime.h>
#endif
#if defined(FBAR_HAS_NCCL)
#include <nccl.h>
#endif

namespace fbar::comm {

bool nccl_available() {
#if defined(FBAR_HAS_NCCL)
  return true;
#else
  return false;
#endif
}

#if defined(FBAR_HAS_CUDA)

namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("device transport: ") + what + ": " + cudaGetErrorString(e));
}

template <typename V>
void put(Bytes& out, const V& v) {
  const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
  out.insert(out.end(), b, b + sizeof(V));
}
template <typename V>
V take(const Bytes& in, std::size_t& at) {
  if (at + sizeof(V) > in.size()) throw std::logic_error("device transport: a truncated control message");
  V v;
  std::memcpy(&v, in.data() + at, sizeof(V));
  at += sizeof(V);
  return v;
}

/// Ranks as threads: each rank publishes (device, event after its packing, its send buffers) through the host
/// transport; the receiver waits on the sender's event and copies; the sender waits on the receivers' events
/// before its stream may touch the send buffers again. Events are process-wide handles, so threads may share them.
class ThreadDeviceTransport final : public DeviceTransport {
 public:
  explicit ThreadDeviceTransport(Transport& host) : host_(host) {
    check(cudaGetDevice(&device_), "cudaGetDevice");
    check(cudaEventCreateWithFlags(&ready_, cudaEventDisableTiming), "cudaEventCreate");
    check(cudaEventCreateWithFlags(&done_, cudaEventDisableTiming), "cudaEventCreate");
  }
  ~ThreadDeviceTransport() override {
    cudaEventDestroy(ready_);
    cudaEventDestroy(done_);
  }
  int rank() const override { return host_.rank(); }
  int size() const override { return host_.size(); }
  std::string describe() const override { return "peer copies between the threads of one process"; }

  void exchange(const std::vector<Message>& messages, cudaStream_t stream) override {
    check(cudaEventRecord(ready_, stream), "cudaEventRecord");
    Bytes mine;
    put(mine, device_);
    put(mine, reinterpret_cast<std::uintptr_t>(ready_));
    put(mine, static_cast<std::uint64_t>(messages.size()));
    for (const Message& m : messages) {
      put(mine, m.peer);
      put(mine, reinterpret_cast<std::uintptr_t>(m.send));
      put(mine, static_cast<std::uint64_t>(m.send_bytes));
    }
    const std::vector<Bytes> all = host_.allgather(mine);
    // Several messages between two ranks in one call pair up in order (as NCCL's grouped sends and receives do): my
    // k-th message with rank p receives p's k-th message to me.
    std::vector<int> seen(all.size(), 0);
    for (const Message& m : messages) {
      const int kth = seen.at(static_cast<std::size_t>(m.peer))++;
      if (m.recv_bytes == 0) continue;
      std::size_t at = 0;
      const Bytes& theirs = all.at(static_cast<std::size_t>(m.peer));
      const int device = take<int>(theirs, at);
      const auto event = reinterpret_cast<cudaEvent_t>(take<std::uintptr_t>(theirs, at));
      const auto n = take<std::uint64_t>(theirs, at);
      bool found = false;
      for (std::uint64_t i = 0, match = 0; i < n && !found; ++i) {
        const int to = take<int>(theirs, at);
        const auto ptr = reinterpret_cast<const void*>(take<std::uintptr_t>(theirs, at));
        const auto bytes = take<std::uint64_t>(theirs, at);
        if (to != rank() || static_cast<int>(match++) != kth) continue;
        if (bytes != m.recv_bytes)
          throw std::logic_error("device transport: rank " + std::to_string(m.peer) + " sends " +
                                 std::to_string(bytes) + " bytes, rank " + std::to_string(rank()) + " expects " +
                                 std::to_string(m.recv_bytes));
        check(cudaStreamWaitEvent(stream, event, 0), "cudaStreamWaitEvent");
        check(cudaMemcpyPeerAsync(m.recv, device_, ptr, device, bytes, stream), "cudaMemcpyPeerAsync");
        found = true;
      }
      if (!found)
        throw std::logic_error("device transport: rank " + std::to_string(m.peer) + " sends nothing to rank " +
                               std::to_string(rank()));
    }
    check(cudaEventRecord(done_, stream), "cudaEventRecord");
    Bytes done;
    put(done, reinterpret_cast<std::uintptr_t>(done_));
    const std::vector<Bytes> finished = host_.allgather(done);
    for (const Message& m : messages) {
      if (m.send_bytes == 0) continue;
      std::size_t at = 0;
      const auto event = reinterpret_cast<cudaEvent_t>(take<std::uintptr_t>(finished.at(static_cast<std::size_t>(m.peer)), at));
      check(cudaStreamWaitEvent(stream, event, 0), "cudaStreamWaitEvent");
    }
    host_.barrier();  // nobody records its events again before every wait above was queued
  }

  void allreduce_max(double* values, int count, cudaStream_t stream) override {
    std::vector<double> host(static_cast<std::size_t>(count));
    check(cudaMemcpyAsync(host.data(), values, sizeof(double) * host.size(), cudaMemcpyDeviceToHost, stream), "copy");
    check(cudaStreamSynchronize(stream), "cudaStreamSynchronize");
    host_.allreduce_max(host.data(), count);
    check(cudaMemcpyAsync(values, host.data(), sizeof(double) * host.size(), cudaMemcpyHostToDevice, stream), "copy");
    check(cudaStreamSynchronize(stream), "cudaStreamSynchronize");  // `host` leaves scope
  }

 private:
  Transport& host_;
  int device_ = 0;
  cudaEvent_t ready_ = nullptr;
  cudaEvent_t done_ = nullptr;
};

#if defined(FBAR_HAS_NCCL)
void check_nccl(ncclResult_t r, const char* what) {
  if (r != ncclSuccess) throw std::runtime_error(std::string("NCCL ") + what + ": " + ncclGetErrorString(r));
}

class NcclTransport final : public DeviceTransport {
 public:
  explicit NcclTransport(Transport& host) : rank_(host.rank()), size_(host.size()) {
    ncclUniqueId id{};
    if (rank_ == 0) check_nccl(ncclGetUniqueId(&id), "ncclGetUniqueId");
    Bytes mine(sizeof(id));
    std::memcpy(mine.data(), &id, sizeof(id));
    const std::vector<Bytes> all = host.allgather(mine);
    std::memcpy(&id, all.at(0).data(), sizeof(id));
    check_nccl(ncclCommInitRank(&comm_, size_, id, rank_), "ncclCommInitRank");
  }
  ~NcclTransport() override {
    if (comm_) ncclCommDestroy(comm_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  std::string describe() const override {
    int v = 0;
    ncclGetVersion(&v);
    return "NCCL " + std::to_string(v / 10000) + "." + std::to_string(v / 100 % 100) + "." + std::to_string(v % 100);
  }
  void exchange(const std::vector<Message>& messages, cudaStream_t stream) override {
    check_nccl(ncclGroupStart(), "ncclGroupStart");
    for (const Message& m : messages) {
      if (m.send_bytes) check_nccl(ncclSend(m.send, m.send_bytes, ncclChar, m.peer, comm_, stream), "ncclSend");
      if (m.recv_bytes) check_nccl(ncclRecv(m.recv, m.recv_bytes, ncclChar, m.peer, comm_, stream), "ncclRecv");
    }
    check_nccl(ncclGroupEnd(), "ncclGroupEnd");
  }
  void allreduce_max(double* values, int count, cudaStream_t stream) override {
    check_nccl(ncclAllReduce(values, values, static_cast<std::size_t>(count), ncclFloat64, ncclMax, comm_, stream),
               "ncclAllReduce");
  }

 private:
  int rank_, size_;
  ncclComm_t comm_ = nullptr;
};
#endif

}  // namespace

std::unique_ptr<DeviceTransport> make_thread_device_transport(Transport& host) {
  return std::make_unique<ThreadDeviceTransport>(host);
}

std::unique_ptr<DeviceTransport> make_nccl_transport(Transport& host) {
#if defined(FBAR_HAS_NCCL)
  return std::make_unique<NcclTransport>(host);
#else
  (void)host;
  throw std::runtime_error("this fbar was built without NCCL (install NCCL and rebuild; docs/user_guide.md)");
#endif
}

#endif  // FBAR_HAS_CUDA

}  // namespace fbar::comm
