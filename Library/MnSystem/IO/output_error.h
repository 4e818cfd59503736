// The exception of a file that could not be written (a full disk, a folder that vanished): its message names the
// file and the system's reason. The asynchronous writer rethrows a failed job as one, and the sensor files throw it,
// so that the run loop tells an output failure from the engine's own errors and says what is complete.
#pragma once

#include <stdexcept>
#include <string>

namespace fbar::io {

class OutputError : public std::runtime_error {
 public:
  /// `failure`: the file and the system's reason. `repeated`: an earlier job's failure reported again (what()
  /// then says so; failure() stays the original text, which the run loop puts in its one report).
  explicit OutputError(const std::string& failure, bool repeated = false)
      : std::runtime_error(repeated ? "an earlier output job failed: " + failure : failure), failure_(failure) {}
  const std::string& failure() const { return failure_; }

 private:
  std::string failure_;
};

}  // namespace fbar::io
