// Stop requests by SIGINT / SIGTERM (stop_request.h).
#include "engine/stop_request.h"

#include <time.h>

#include <atomic>
#include <csignal>

namespace fbar {
namespace {

// Lock-free, so the handler may store into it (a std::sig_atomic_t would do for one thread; the run loop may run on
// another thread than the one the signal is delivered to).
std::atomic<int> g_stop_signal{0};
constexpr long long kRepeatWindowNs = 2000000000LL;
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free atomic");

// CLOCK_MONOTONIC of the first request [ns] (clock_gettime is async-signal-safe).
std::atomic<long long> g_first_ns{0};
static_assert(std::atomic<long long>::is_always_lock_free, "the signal handler needs a lock-free atomic");

long long monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<long long>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

extern "C" void on_stop_signal(int signal) {
  const long long now = monotonic_ns();
  const int first = g_stop_signal.load(std::memory_order_relaxed);
  if (first == 0) {
    g_first_ns.store(now, std::memory_order_relaxed);
    g_stop_signal.store(signal, std::memory_order_relaxed);
    return;
  }
  // A second signal ends the process at once, by that signal (the default action). A SIGTERM repeated within
  // kRepeatWindowNs of the first is the same request: senders repeat it (coreutils `timeout` signals the process and
  // then its group; srun forwards it to every task).
  if (signal == SIGTERM && first == SIGTERM && now - g_first_ns.load(std::memory_order_relaxed) < kRepeatWindowNs)
    return;
  std::signal(signal, SIG_DFL);
  std::raise(signal);
}

}  // namespace

int stop_signal() { return g_stop_signal.load(std::memory_order_relaxed); }
void request_stop(int signal) { g_stop_signal.store(signal, std::memory_order_relaxed); }
void clear_stop_request() { g_stop_signal.store(0, std::memory_order_relaxed); }

StopSignals::StopSignals() : previous_int_(SIG_DFL), previous_term_(SIG_DFL) {
  clear_stop_request();  // a request of an earlier run in this process does not stop this one
  previous_int_ = std::signal(SIGINT, on_stop_signal);
  previous_term_ = std::signal(SIGTERM, on_stop_signal);
}

StopSignals::~StopSignals() {
  std::signal(SIGINT, previous_int_ == SIG_ERR ? SIG_DFL : previous_int_);
  std::signal(SIGTERM, previous_term_ == SIG_ERR ? SIG_DFL : previous_term_);
}

const char* signal_name(int signal) {
  switch (signal) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    default: return "a signal";
  }
}

}  // namespace fbar
