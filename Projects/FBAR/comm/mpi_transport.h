// One rank per MPI process (mpirun, srun): the Transport of a batch job (transport.h). Built when CMake finds MPI
// (FBAR_HAS_MPI); the halo and migration payloads of a GPU run go through NCCL (device_transport.h), sized and
// agreed here.
#pragma once

#include "comm/transport.h"

namespace fbar::comm {

/// True when an MPI launcher started this process (Open MPI, MPICH / Hydra, PMIx, Slurm's srun with a world size
/// above 1 in the environment). fbar then runs one rank per process.
bool launched_by_mpi();

#ifdef FBAR_HAS_MPI
class MpiTransport final : public Transport {
 public:
  /// Initialises MPI unless someone has (MPI_THREAD_FUNNELED: only the run loop's thread calls MPI) and
  /// finalises it on destruction if it did.
  MpiTransport();
  ~MpiTransport() override;
  MpiTransport(const MpiTransport&) = delete;
  MpiTransport& operator=(const MpiTransport&) = delete;

  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void allreduce_sum(double* values, int count) override;
  void allreduce_sum(long long* values, int count) override;
  void allreduce_max(double* values, int count) override;
  void allreduce_min(double* values, int count) override;
  void allreduce_min(long long* values, int count) override;
  std::vector<Bytes> exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) override;
  std::vector<Bytes> allgather(const Bytes& mine) override;
  void barrier() override;
  void abort(int code) override;

 private:
  int rank_ = 0, size_ = 1;
  bool finalize_ = false;
};
#endif

}  // namespace fbar::comm
