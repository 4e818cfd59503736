// This process's host memory as the system counts it: resident now and at most so far (Linux /proc/self/status
// VmRSS and VmHWM; 0 where the system has no such file). Linux batches its page counts per thread, so either figure
// may lag by some hundred KiB.
#pragma once

#include <cstddef>
#include <fstream>
#include <string>

namespace fbar {

struct HostMemory {
  std::size_t resident = 0;  ///< [bytes] VmRSS
  std::size_t peak = 0;      ///< [bytes] VmHWM: the most resident so far
};

inline HostMemory host_memory() {
  HostMemory m;
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);) {
    const bool rss = line.rfind("VmRSS:", 0) == 0, hwm = line.rfind("VmHWM:", 0) == 0;
    if (!rss && !hwm) continue;
    const std::size_t kib = std::stoull(line.substr(6));  // "   123456 kB"
    (rss ? m.resident : m.peak) = kib * 1024;
  }
  return m;
}

}  // namespace fbar
