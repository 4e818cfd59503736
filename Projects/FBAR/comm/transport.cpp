// LocalTransport and ThreadTransport (transport.h).
#include "comm/transport.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace fbar::comm {

std::vector<Bytes> LocalTransport::exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) {
  if (!peers.empty()) throw std::logic_error("LocalTransport::exchange: a single rank has no peers");
  (void)send;
  return {};
}

/// Mailboxes and a generation-counting barrier. A collective: every rank deposits, waits at the barrier, reads,
/// waits again (so no rank deposits the next collective's data before everyone has read this one's).
class ThreadHub {
 public:
  explicit ThreadHub(int n) : n_(n), slots_(static_cast<std::size_t>(n)), mail_(static_cast<std::size_t>(n * n)) {}
  int size() const { return n_; }

  void barrier() {
    std::unique_lock<std::mutex> lock(mutex_);
    if (aborted_) throw std::runtime_error(kAborted);
    const long long generation = generation_;
    if (++waiting_ == n_) {
      waiting_ = 0;
      ++generation_;
      cv_.notify_all();
    } else {
      cv_.wait(lock, [&] { return generation_ != generation || aborted_; });
      if (generation_ == generation) throw std::runtime_error(kAborted);
    }
  }
  /// Another rank ended by an exception: every rank waiting in (or entering) a collective throws instead.
  void abort() {
    std::lock_guard<std::mutex> lock(mutex_);
    aborted_ = true;
    cv_.notify_all();
  }
  static constexpr const char* kAborted = "another rank of this process stopped with an error";
  Bytes& slot(int rank) { return slots_[static_cast<std::size_t>(rank)]; }
  Bytes& mail(int from, int to) { return mail_[static_cast<std::size_t>(from * n_ + to)]; }

 private:
  int n_;
  std::mutex mutex_;
  std::condition_variable cv_;
  int waiting_ = 0;
  long long generation_ = 0;
  bool aborted_ = false;
  std::vector<Bytes> slots_;  // (rank) this collective's contribution
  std::vector<Bytes> mail_;   // (from, to) this exchange's message
};

namespace {

template <typename V>
Bytes to_bytes(const V* values, int count) {
  Bytes b(static_cast<std::size_t>(count) * sizeof(V));
  if (count > 0) std::memcpy(b.data(), values, b.size());
  return b;
}

/// Reduces every rank's slot in rank order into `values` (the same order, so the same result, on every rank).
template <typename V, typename Op>
void reduce_slots(ThreadHub& hub, int rank, V* values, int count, Op op) {
  hub.slot(rank) = to_bytes(values, count);
  hub.barrier();
  std::vector<V> result(static_cast<std::size_t>(count));
  for (int r = 0; r < hub.size(); ++r) {
    const Bytes& b = hub.slot(r);
    if (b.size() != result.size() * sizeof(V))
      throw std::logic_error("ThreadTransport: ranks passed different counts to a reduction");
    for (int i = 0; i < count; ++i) {
      V v;
      std::memcpy(&v, b.data() + static_cast<std::size_t>(i) * sizeof(V), sizeof(V));
      result[static_cast<std::size_t>(i)] = r == 0 ? v : op(result[static_cast<std::size_t>(i)], v);
    }
  }
  hub.barrier();
  std::copy(result.begin(), result.end(), values);
}

}  // namespace

ThreadTransport::ThreadTransport(std::shared_ptr<ThreadHub> hub, int rank) : hub_(std::move(hub)), rank_(rank) {}
int ThreadTransport::size() const { return hub_->size(); }

void ThreadTransport::allreduce_sum(double* v, int n) {
  reduce_slots(*hub_, rank_, v, n, [](double a, double b) { return a + b; });
}
void ThreadTransport::allreduce_sum(long long* v, int n) {
  reduce_slots(*hub_, rank_, v, n, [](long long a, long long b) { return a + b; });
}
void ThreadTransport::allreduce_max(double* v, int n) {
  reduce_slots(*hub_, rank_, v, n, [](double a, double b) { return b > a ? b : a; });
}
void ThreadTransport::allreduce_min(double* v, int n) {
  reduce_slots(*hub_, rank_, v, n, [](double a, double b) { return b < a ? b : a; });
}
void ThreadTransport::allreduce_min(long long* v, int n) {
  reduce_slots(*hub_, rank_, v, n, [](long long a, long long b) { return b < a ? b : a; });
}

std::vector<Bytes> ThreadTransport::exchange(const std::vector<int>& peers, const std::vector<Bytes>& send) {
  if (peers.size() != send.size()) throw std::logic_error("ThreadTransport::exchange: one buffer per peer");
  for (std::size_t i = 0; i < peers.size(); ++i) {
    if (peers[i] < 0 || peers[i] >= size() || peers[i] == rank_)
      throw std::logic_error("ThreadTransport::exchange: bad peer " + std::to_string(peers[i]));
    hub_->mail(rank_, peers[i]) = send[i];
  }
  hub_->barrier();
  std::vector<Bytes> received;
  for (int peer : peers) received.push_back(std::move(hub_->mail(peer, rank_)));
  hub_->barrier();
  return received;
}

std::vector<Bytes> ThreadTransport::allgather(const Bytes& mine) {
  hub_->slot(rank_) = mine;
  hub_->barrier();
  std::vector<Bytes> all;
  for (int r = 0; r < size(); ++r) all.push_back(hub_->slot(r));
  hub_->barrier();
  return all;
}

void ThreadTransport::barrier() { hub_->barrier(); }
void ThreadTransport::abort(int) { hub_->abort(); }

std::vector<std::unique_ptr<Transport>> make_thread_transports(int n) {
  if (n < 1) throw std::invalid_argument("make_thread_transports: at least one rank");
  auto hub = std::make_shared<ThreadHub>(n);
  std::vector<std::unique_ptr<Transport>> t;
  for (int r = 0; r < n; ++r) t.push_back(std::make_unique<ThreadTransport>(hub, r));
  return t;
}

}  // namespace fbar::comm
