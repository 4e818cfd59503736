// Library/MnSystem/host_memory.h: this process's resident memory and its peak, as the GPU engine's log reports them.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstring>
#include <memory>

#include "MnSystem/host_memory.h"

namespace fbar {
namespace {

// Touching 256 MiB raises the resident memory by about that much and the peak with it; freeing it leaves the peak.
// Linux counts resident pages per thread in batches (up to 64 pages each before they reach the process's count), so
// the peak read later may lag a resident figure read earlier by that much: 1 MiB is allowed.
TEST(HostMemory, FollowsAnAllocationThatIsTouched) {
  const HostMemory before = host_memory();
  if (before.resident == 0) GTEST_SKIP() << "no /proc/self/status on this system: host memory is not read here";
  EXPECT_GE(before.peak, before.resident);
  constexpr std::size_t kBytes = std::size_t{256} << 20;
  HostMemory during;
  {
    std::unique_ptr<char[]> block(new char[kBytes]);
    std::memset(block.get(), 1, kBytes);
    during = host_memory();
    EXPECT_EQ(block[kBytes / 2], 1);
  }
  EXPECT_GE(during.resident, before.resident + kBytes * 9 / 10);
  EXPECT_LE(during.resident, before.resident + kBytes + (std::size_t{64} << 20));
  EXPECT_GE(during.peak, during.resident);
  EXPECT_GE(host_memory().peak + (std::size_t{1} << 20), during.resident);
}

}  // namespace
}  // namespace fbar
