// The exception of a file that could not be written (a full disk, a folder that vanished): its message names the
// file and the system's reason. The asynchronous writer rethrows a failed job as one, and the sensor files throw it,
// so that the run loop tells an output failure from the engine's own errors and says what is complete.
#pragma once

#include <stdexcept>

namespace fbar::io {

class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace fbar::io
