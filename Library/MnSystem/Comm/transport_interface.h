// The interface through which ranks (one per GPU, or CPU-engine ranks) exchange data: reductions in rank order, pairwise
// exchanges, gathers and barriers. The transports that implement it are the application's (Projects/FBAR/comm:
// threads of one process, MPI); code that only reduces or exchanges through a transport (the sensor recorder, the
// engines) includes this interface alone.
//
// Collectives are called by every rank in the same order (as in MPI). Results of the reductions are the same on
// every rank, bit for bit: every transport reduces in rank order.
#pragma once

#include <cstdint>
#include <vector>

namespace fbar::comm {

using Bytes = std::vector<std::uint8_t>;

class Transport {
 public:
  virtual ~Transport() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Element-wise over ranks, in place (every rank passes the same count).
  virtual void allreduce_sum(double* values, int count) = 0;
  virtual void allreduce_sum(long long* values, int count) = 0;
  virtual void allreduce_max(double* values, int count) = 0;
  virtual void allreduce_min(double* values, int count) = 0;
  virtual void allreduce_min(long long* values, int count) = 0;
  /// Sends send[i] to peers[i] and returns what peers[i] sent to this rank, for every i (pairwise: if a lists b,
  /// b lists a). Buffers may be empty.
  virtual std::vector<Bytes> exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) = 0;
  /// Every rank's buffer, in rank order, on every rank.
  virtual std::vector<Bytes> allgather(const Bytes& mine) = 0;
  virtual void barrier() = 0;
  /// Ends every rank's run after a failure only this rank saw (so no rank waits forever in a collective): MPI
  /// aborts the job with `code`; ranks of one process (threads, one rank) return and let the caller report.
  virtual void abort(int code) { (void)code; }

  double sum(double x) { allreduce_sum(&x, 1); return x; }
  long long sum(long long x) { allreduce_sum(&x, 1); return x; }
  double max(double x) { allreduce_max(&x, 1); return x; }
  double min(double x) { allreduce_min(&x, 1); return x; }
  long long min(long long x) { allreduce_min(&x, 1); return x; }
};

}  // namespace fbar::comm
