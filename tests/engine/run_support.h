// Scenes through the run loop in tests: run_cpu on several ranks (threads), and a log that asks the run to stop at a
// known point, as a signal arriving then would.
#pragma once

#include <memory>
#include <streambuf>
#include <string>
#include <thread>
#include <vector>

#include "comm/transport.h"
#include "engine/engine_api.h"
#include "engine/stop_request.h"
#include "scene/scene.h"

namespace fbar::test {

/// run_cpu or run_gpu.
using RunFn = RunResult (*)(const Scene&, const RunOptions&);

/// `run` of `scene` on `ranks` ranks (threads; one rank: no transport; GPU ranks share the visible GPUs by peer
/// copies), continuing from the checkpoint `restart` when it is not empty, logging to `log` (nullptr: quiet); every
/// rank's result.
inline std::vector<RunResult> run_ranks_with(RunFn run, const Scene& scene, int ranks, const std::string& restart = "",
                                             std::ostream* log = nullptr) {
  std::vector<std::unique_ptr<comm::Transport>> transports = comm::make_thread_transports(ranks);
  std::vector<RunResult> results(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      RunOptions o;
      o.quiet = log == nullptr;
      o.log = log;
      o.transport = ranks > 1 ? transports[static_cast<std::size_t>(r)].get() : nullptr;
      o.shared_gpus = true;  // read by run_gpu only
      o.restart = restart;
      results[static_cast<std::size_t>(r)] = run(scene, o);
    });
  for (auto& t : threads) t.join();
  return results;
}

/// run_ranks_with(run_cpu, ...).
inline std::vector<RunResult> run_cpu_ranks(const Scene& scene, int ranks, const std::string& restart = "",
                                            std::ostream* log = nullptr) {
  return run_ranks_with(run_cpu, scene, ranks, restart, log);
}

/// A log (std::ostream over it) that records a stop request for `signal` when a line starting with `prefix` is
/// written, e.g. "frame 1/": the run loop then stops at its next step, deterministically.
class StopWhenLogged : public std::streambuf {
 public:
  StopWhenLogged(std::string prefix, int signal) : prefix_(std::move(prefix)), signal_(signal) {}
  const std::string& text() const { return text_; }

 protected:
  int overflow(int c) override {
    if (c == traits_type::eof()) return 0;
    text_.push_back(static_cast<char>(c));
    if (c == '\n') {
      if (line_.rfind(prefix_, 0) == 0) request_stop(signal_);
      line_.clear();
    } else {
      line_.push_back(static_cast<char>(c));
    }
    return c;
  }

 private:
  std::string prefix_, line_, text_;
  int signal_;
};

}  // namespace fbar::test
