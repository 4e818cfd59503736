// Transports (comm/transport.h): reductions give the same value on every rank, exchanges deliver pairwise, and
// allgather returns every rank's buffer in rank order: ThreadTransport with 1-4 threads, MpiTransport under mpirun.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "comm/mpi_transport.h"
#include "comm/transport.h"

namespace fbar::comm {
namespace {

Bytes text(const std::string& s) { return Bytes(s.begin(), s.end()); }
std::string text(const Bytes& b) { return std::string(b.begin(), b.end()); }

/// What every transport must do; returns failures as strings (gtest assertions are not thread-safe on all builds).
std::vector<std::string> exercise(Transport& t) {
  std::vector<std::string> errors;
  auto expect = [&](bool ok, const std::string& what) {
    if (!ok) errors.push_back("rank " + std::to_string(t.rank()) + ": " + what);
  };
  const int r = t.rank(), n = t.size();
  // Reductions: 0.1 * (r + 1) summed in rank order is the same double everywhere; min / max exact.
  double values[2] = {0.1 * (r + 1), -static_cast<double>(r)};
  t.allreduce_sum(values, 2);
  double expected = 0.0;
  for (int k = 0; k < n; ++k) expected = k == 0 ? 0.1 : expected + 0.1 * (k + 1);
  expect(values[0] == expected, "sum " + std::to_string(values[0]));
  expect(values[1] == -0.5 * n * (n - 1), "sum of -r");
  expect(t.max(static_cast<double>(r)) == n - 1, "max");
  expect(t.min(static_cast<double>(r) + 2.5) == 2.5, "min");
  expect(t.min(static_cast<long long>(100 - r)) == 100 - (n - 1), "min long long");
  expect(t.sum(static_cast<long long>(r + 1)) == static_cast<long long>(n) * (n + 1) / 2, "sum long long");
  // Exchange with both neighbours on a ring (a pairwise pattern), one empty message among them.
  if (n > 1) {
    std::vector<int> peers;
    std::vector<Bytes> send;
    const int up = (r + 1) % n, down = (r + n - 1) % n;
    peers.push_back(up);
    send.push_back(text("from " + std::to_string(r) + " to " + std::to_string(up)));
    if (down != up) {
      peers.push_back(down);
      send.push_back(r == 0 ? Bytes{} : text("from " + std::to_string(r) + " to " + std::to_string(down)));
    }
    const std::vector<Bytes> got = t.exchange(peers, send);
    expect(got.size() == peers.size(), "one message per peer");
    for (std::size_t i = 0; i < got.size(); ++i) {
      const int p = peers[i];
      // Rank 0 sends an empty buffer to its down neighbour n - 1 when that is not also its up neighbour (n > 2).
      const std::string want = p == 0 && n > 2 && r == n - 1 ? "" : "from " + std::to_string(p) + " to " +
                                                                       std::to_string(r);
      expect(text(got[i]) == want, "got '" + text(got[i]) + "' from " + std::to_string(p));
    }
  }
  // Allgather: rank order, sizes differ per rank.
  const std::vector<Bytes> all = t.allgather(text(std::string(static_cast<std::size_t>(r), 'x') + std::to_string(r)));
  expect(static_cast<int>(all.size()) == n, "allgather size");
  for (int k = 0; k < static_cast<int>(all.size()); ++k)
    expect(text(all[k]) == std::string(static_cast<std::size_t>(k), 'x') + std::to_string(k), "allgather " +
                                                                                               std::to_string(k));
  t.barrier();
  return errors;
}

TEST(ThreadTransport, EveryCollectiveWithOneToFourRanks) {
  for (int n = 1; n <= 4; ++n) {
    std::vector<std::unique_ptr<Transport>> transports = make_thread_transports(n);
    std::vector<std::vector<std::string>> errors(n);
    std::vector<std::thread> threads;
    for (int r = 0; r < n; ++r) threads.emplace_back([&, r] { errors[r] = exercise(*transports[r]); });
    for (auto& th : threads) th.join();
    for (int r = 0; r < n; ++r)
      for (const std::string& e : errors[r]) ADD_FAILURE() << n << " ranks: " << e;
  }
}

TEST(LocalTransport, IsOneRank) {
  LocalTransport t;
  const std::vector<std::string> errors = exercise(t);
  for (const std::string& e : errors) ADD_FAILURE() << e;
}

#ifdef FBAR_HAS_MPI
TEST(MpiTransport, EveryCollectiveUnderMpirun) {
  const char* expected = std::getenv("FBAR_EXPECT_MPI_RANKS");
  if (!expected) GTEST_SKIP() << "not started by the Transport.Mpi3Ranks test (mpirun -np 3)";
  MpiTransport t;
  ASSERT_EQ(t.size(), std::atoi(expected));
  EXPECT_TRUE(launched_by_mpi());
  const std::vector<std::string> errors = exercise(t);
  for (const std::string& e : errors) ADD_FAILURE() << e;
}
#endif

}  // namespace
}  // namespace fbar::comm
