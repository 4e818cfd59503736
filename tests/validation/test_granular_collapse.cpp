// Validation: planar granular column collapse against Lube et al. 2005 (docs/validation.md), DruckerPrager.
// The problem, its reference and the run are in granular_collapse_case.h; the test here runs it on the CPU engine.
#include <gtest/gtest.h>

#include "granular_collapse_case.h"

namespace fbar {
namespace {

using namespace granular_case;

TEST(GranularCollapse, RunoutAndHeightAgainstLube) {
  expect_granular_within_lube(run_granular_collapse("CPU engine"));
}

}  // namespace
}  // namespace fbar
