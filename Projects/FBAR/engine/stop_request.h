// A run asked to stop by a signal (SIGINT from Ctrl-C, SIGTERM from a batch system's time limit or `kill`).
//
// While a StopSignals object lives, the first SIGINT or SIGTERM only records the signal; the run loop sees it at
// the next step boundary, writes a checkpoint there (run_loop.h) and stops, and the command line writes run.json
// (status "interrupted") and exits with 128 + the signal number, as a shell reports a process ended by that
// signal. A second signal ends the process at once (by that signal), except a SIGTERM repeated within 2 s of the
// first: senders repeat it (coreutils `timeout` signals the process and then its group; srun forwards it to every
// task), and that is still the first request.
#pragma once

namespace fbar {

/// The signal that asked the run to stop (SIGINT, SIGTERM), or 0.
int stop_signal();

/// Records a stop request as the handler does (tests; a rank told to stop by another rank).
void request_stop(int signal);

/// Forgets a recorded request (a new run in the same process).
void clear_stop_request();

/// Forgets an earlier request, installs the SIGINT / SIGTERM handlers for its lifetime, restores the previous ones
/// after.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  void (*previous_int_)(int);
  void (*previous_term_)(int);
};

/// "SIGINT", "SIGTERM", or "signal N".
const char* signal_name(int signal);

}  // namespace fbar
