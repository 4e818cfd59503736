// MpiTransport (mpi_transport.h).
#include "comm/mpi_transport.h"

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#ifdef FBAR_HAS_MPI
#include <mpi.h>
#endif

namespace fbar::comm {

bool launched_by_mpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS"}) {
    const char* v = std::getenv(name);
    if (v && std::atoi(v) >= 1) return true;
  }
  return false;
}

#ifdef FBAR_HAS_MPI
namespace {
void check(int code, const char* what) {
  if (code == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(code, text, &length);
  throw std::runtime_error(std::string("MPI error in ") + what + ": " + std::string(text, length));
}
}  // namespace

MpiTransport::MpiTransport() {
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized) {
    int provided = 0;
    check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
    finalize_ = true;
  }
  // Errors come back as codes (thrown as exceptions with the message), not as an abort of every rank.
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiTransport::~MpiTransport() {
  if (!finalize_) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

void MpiTransport::allreduce_sum(double* v, int n) {
  check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD), "MPI_Allreduce");
}
void MpiTransport::allreduce_sum(long long* v, int n) {
  check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD), "MPI_Allreduce");
}
void MpiTransport::allreduce_max(double* v, int n) {
  check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
}
void MpiTransport::allreduce_min(double* v, int n) {
  check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD), "MPI_Allreduce");
}
void MpiTransport::allreduce_min(long long* v, int n) {
  check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_LONG_LONG, MPI_MIN, MPI_COMM_WORLD), "MPI_Allreduce");
}

std::vector<Bytes> MpiTransport::exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) {
  if (peers.size() != send.size()) throw std::logic_error("MpiTransport::exchange: one buffer per peer");
  const int n = static_cast<int>(peers.size());
  std::vector<unsigned long long> out_size(n), in_size(n);
  std::vector<MPI_Request> requests;
  requests.reserve(2 * static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    out_size[i] = send[i].size();
    requests.emplace_back();
    check(MPI_Irecv(&in_size[i], 1, MPI_UNSIGNED_LONG_LONG, peers[i], 1, MPI_COMM_WORLD, &requests.back()), "MPI_Irecv");
    requests.emplace_back();
    check(MPI_Isend(&out_size[i], 1, MPI_UNSIGNED_LONG_LONG, peers[i], 1, MPI_COMM_WORLD, &requests.back()),
          "MPI_Isend");
  }
  check(MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  std::vector<Bytes> received(n);
  requests.clear();
  for (int i = 0; i < n; ++i) {
    received[i].resize(in_size[i]);
    // Counts above 2^31 bytes would need MPI 4's large-count calls; halo planes and migrations are far smaller.
    if (in_size[i] > 0x7fffffffULL || out_size[i] > 0x7fffffffULL)
      throw std::runtime_error("MpiTransport::exchange: a message of 2 GiB or more");
    if (in_size[i] > 0) {
      requests.emplace_back();
      check(MPI_Irecv(received[i].data(), static_cast<int>(in_size[i]), MPI_BYTE, peers[i], 2, MPI_COMM_WORLD,
                      &requests.back()),
            "MPI_Irecv");
    }
    if (out_size[i] > 0) {
      requests.emplace_back();
      check(MPI_Isend(send[i].data(), static_cast<int>(out_size[i]), MPI_BYTE, peers[i], 2, MPI_COMM_WORLD,
                      &requests.back()),
            "MPI_Isend");
    }
  }
  check(MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  return received;
}

std::vector<Bytes> MpiTransport::allgather(const Bytes& mine) {
  // In rounds that keep every MPI count an int (at most 1 GiB per rank): a rebalance gathers every rank's particles.
  const int n = size_;
  const std::size_t kRound = std::min<std::size_t>(std::size_t(1) << 30, static_cast<std::size_t>(INT_MAX) / n);
  long long my_size = static_cast<long long>(mine.size());
  std::vector<long long> sizes(n);
  check(MPI_Allgather(&my_size, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, MPI_COMM_WORLD), "MPI_Allgather");
  std::vector<Bytes> out(n);
  long long most = 0;
  for (int r = 0; r < n; ++r) {
    out[r].resize(static_cast<std::size_t>(sizes[r]));
    most = std::max(most, sizes[r]);
  }
  std::vector<int> counts(n), offsets(n);
  Bytes round;
  for (std::size_t start = 0; start < static_cast<std::size_t>(most) || start == 0; start += kRound) {
    int total = 0;
    for (int r = 0; r < n; ++r) {
      const auto size = static_cast<std::size_t>(sizes[r]);
      counts[r] = static_cast<int>(start < size ? std::min(kRound, size - start) : 0);
      offsets[r] = total;
      total += counts[r];
    }
    round.resize(static_cast<std::size_t>(std::max(total, 1)));
    const int mine_now = counts[rank_];
    check(MPI_Allgatherv(mine_now ? mine.data() + start : nullptr, mine_now, MPI_BYTE, round.data(), counts.data(),
                         offsets.data(), MPI_BYTE, MPI_COMM_WORLD),
          "MPI_Allgatherv");
    for (int r = 0; r < n; ++r)
      if (counts[r]) std::memcpy(out[r].data() + start, round.data() + offsets[r], static_cast<std::size_t>(counts[r]));
    if (most == 0) break;
  }
  return out;
}

void MpiTransport::barrier() { check(MPI_Barrier(MPI_COMM_WORLD), "MPI_Barrier"); }
void MpiTransport::abort(int code) { MPI_Abort(MPI_COMM_WORLD, code); }
#endif

}  // namespace fbar::comm
