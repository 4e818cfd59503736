// How ranks (one per GPU, or CPU-engine ranks) exchange data: three transports of one interface (comm::Transport,
// Library/MnSystem/Comm/transport_interface.h).
//
//   LocalTransport    one rank; every collective is the identity (a run without decomposition)
//   ThreadTransport   N ranks as N threads of one process, through shared mailboxes (the workstation mode's host
//                     side, and CPU-engine tests of 2 and 3 ranks without a launcher)
//   MpiTransport      one rank per MPI process (mpirun / srun), MPI_COMM_WORLD (comm/mpi_transport.h; built when
//                     MPI is found)
//
// Collectives are called by every rank in the same order (as in MPI). Results of the reductions are the same on
// every rank, bit for bit: ThreadTransport and MpiTransport both reduce in rank order.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "MnSystem/Comm/transport_interface.h"

namespace fbar::comm {

/// One rank.
class LocalTransport final : public Transport {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  void allreduce_sum(double*, int) override {}
  void allreduce_sum(long long*, int) override {}
  void allreduce_max(double*, int) override {}
  void allreduce_min(double*, int) override {}
  void allreduce_min(long long*, int) override {}
  std::vector<Bytes> exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) override;
  std::vector<Bytes> allgather(const Bytes& mine) override { return {mine}; }
  void barrier() override {}
};

/// The shared state of N ThreadTransports (one per thread): make_thread_transports(n) builds them.
class ThreadHub;

class ThreadTransport final : public Transport {
 public:
  ThreadTransport(std::shared_ptr<ThreadHub> hub, int rank);
  int rank() const override { return rank_; }
  int size() const override;
  void allreduce_sum(double* values, int count) override;
  void allreduce_sum(long long* values, int count) override;
  void allreduce_max(double* values, int count) override;
  void allreduce_min(double* values, int count) override;
  void allreduce_min(long long* values, int count) override;
  std::vector<Bytes> exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) override;
  std::vector<Bytes> allgather(const Bytes& mine) override;
  void barrier() override;
  /// The other ranks' collectives throw std::runtime_error from now on (no rank waits for this one forever).
  void abort(int code) override;

 private:
  std::shared_ptr<ThreadHub> hub_;
  int rank_;
};

/// n transports sharing one hub; give transports[r] to the thread of rank r.
std::vector<std::unique_ptr<Transport>> make_thread_transports(int n);

}  // namespace fbar::comm
