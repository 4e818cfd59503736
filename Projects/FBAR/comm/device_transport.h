// How the ranks of a decomposed GPU run move device memory: halo blocks and migrating particles (grouped
// point-to-point messages on the rank's stream) and the inputs of the time step (a reduction of device values).
//
//   NcclTransport          NCCL (grouped ncclSend / ncclRecv, ncclAllReduce): one code path inside a node and across
//                          nodes; the communicator's id is shared through the host Transport (MPI or threads).
//                          Built when NCCL is found (FBAR_HAS_NCCL).
//   ThreadDeviceTransport  ranks as threads of one process: cudaMemcpyPeerAsync between the ranks' buffers, ordered
//                          by CUDA events that the ranks exchange through their host ThreadTransport. It also runs
//                          several ranks on ONE GPU, which NCCL refuses ("duplicate GPU"): the tests of the
//                          decomposition logic on a one-GPU machine.
//
// Like the host Transport, every rank calls every operation in the same order. Messages are paired: when rank a
// sends b bytes to rank c, rank c receives exactly b bytes from rank a in the same call.
//
// A build without the CUDA toolkit (FBAR_HAS_CUDA undefined) has no device transport: only nccl_available().
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "comm/transport.h"

#if defined(FBAR_HAS_CUDA)
#include <cuda_runtime_api.h>
#endif

namespace fbar::comm {

/// Whether this build has NCCL (never without the CUDA toolkit).
bool nccl_available();

#if defined(FBAR_HAS_CUDA)

class DeviceTransport {
 public:
  struct Message {
    int peer = -1;
    const void* send = nullptr;  ///< device bytes for `peer` (may be empty)
    std::size_t send_bytes = 0;
    void* recv = nullptr;        ///< device bytes from `peer`
    std::size_t recv_bytes = 0;
  };
  virtual ~DeviceTransport() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Every message's send and receive, grouped, ordered after the work queued on `stream` before the call; the
  /// received bytes are ready for work queued on `stream` after it.
  virtual void exchange(const std::vector<Message>& messages, cudaStream_t stream) = 0;
  /// values[i] = max over ranks of values[i] (device doubles, in place, on `stream`).
  virtual void allreduce_max(double* values, int count, cudaStream_t stream) = 0;
  virtual std::string describe() const = 0;  ///< "NCCL 2.28.9" / "peer copies (threads)" for logs
};

/// The device transport of rank `host.rank()` as a thread of this process: every rank of `host` (a ThreadTransport,
/// one per thread) must create one, on its thread, with its CUDA device current.
std::unique_ptr<DeviceTransport> make_thread_device_transport(Transport& host);

/// An NCCL communicator over the ranks of `host` (MPI ranks or threads), on the current CUDA device; rank 0 makes
/// the id and `host` shares it. Collective over `host`. Throws std::runtime_error without NCCL or on its failure.
std::unique_ptr<DeviceTransport> make_nccl_transport(Transport& host);

#endif  // FBAR_HAS_CUDA

}  // namespace fbar::comm
