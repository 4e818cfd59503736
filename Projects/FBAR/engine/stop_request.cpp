// Stop requests by SIGINT / SIGTERM (stop_request.h).
#include "engine/stop_request.h"

#include <atomic>
#include <csignal>

namespace fbar {
namespace {

// Lock-free, so the handler may store into it (a std::sig_atomic_t would do for one thread; the run loop may run on
// another thread than the one the signal is delivered to).
std::atomic<int> g_stop_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free atomic");

extern "C" void on_stop_signal(int signal) {
  g_stop_signal.store(signal, std::memory_order_relaxed);
  // A second Ctrl-C ends the process at once. SIGTERM stays graceful: senders repeat it (coreutils `timeout` signals
  // the process and then its group, Slurm may forward it twice) and follow it with SIGKILL after their grace time.
  if (signal == SIGINT) std::signal(SIGINT, SIG_DFL);
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
