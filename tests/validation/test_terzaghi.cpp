// Validation: Terzaghi's one-dimensional consolidation of a saturated column under its own weight, on the
// CPU engine (the problem, the reference, the measured errors and the tolerances: terzaghi_case.h).
#include <gtest/gtest.h>

#include "engine/cpu/cpu_engine.h"
#include "terzaghi_case.h"

namespace fbar {
namespace {

TEST(Terzaghi, SelfWeightConsolidationFollowsTheSeries) {
  terzaghi::expect_follows_the_series<CpuEngine<double>>("CPU engine");
}

}  // namespace
}  // namespace fbar
