// Stability regression: a small stability sweep on the CPU engine must have no silent blow-up.
// The cases and how a run is classed: stability_case.h; the full maps: tools/study/run_study.py --problem stability
// and docs/validation.md ("Stability maps").
#include <gtest/gtest.h>

#include <cstdio>

#include "stability_case.h"

namespace fbar {
namespace {

using namespace stability_case;

void report(const char* what, const StabilityResult& r) {
  std::printf("%-44s %-8s energy gain %+.4f, %lld steps, %.2f s  %s\n", what, to_string(r.state), r.energy_gain,
              r.steps, r.seconds, r.message.c_str());
}

// The splash with lone particles at the CFL numbers a scene may ask for (0.5, ClaymoreUW's usual, and 1, the most)
// must be stable for APIC and FLIP: before the acoustic cap of physics/time_step.cuh, CFL 1 blew the lone particles
// up silently. Steps forced past fbar's bound (2 and 6 times its step, code only) and a fluid too soft for its flow
// (c0 = half the front speed) may fail, but never silently.
TEST(Stability, SplashWithLoneParticlesNeverFailsSilently) {
  for (const validation::Scheme& scheme : {validation::kTransferSchemes[0], validation::kTransferSchemes[2]}) {
    for (double cfl : {0.5, 1.0}) {
      SplashSetup s;
      s.scheme = scheme;
      s.cfl = cfl;
      const StabilityResult r = run_splash<double>(s);
      report((std::string("splash ") + scheme.name + ", CFL " + std::to_string(cfl)).c_str(), r);
      EXPECT_EQ(r.state, State::Stable) << scheme.name << " CFL " << cfl << ": " << r.message;
    }
    for (double f : {2.0, 6.0}) {
      SplashSetup s;
      s.scheme = scheme;
      s.dt_factor = f;
      const StabilityResult r = run_splash<double>(s);
      report((std::string("splash ") + scheme.name + ", dt x " + std::to_string(f)).c_str(), r);
      EXPECT_NE(r.state, State::Silent) << scheme.name << " dt x " << f << ": " << r.message;
    }
    SplashSetup soft;
    soft.scheme = scheme;
    soft.stiffness = 0.5;
    const StabilityResult r = run_splash<double>(soft);
    report((std::string("splash ") + scheme.name + ", c0 = front speed / 2").c_str(), r);
    EXPECT_NE(r.state, State::Silent) << scheme.name << " soft: " << r.message;
  }
}

// The bouncing block near incompressibility, with and without F-bar: fbar's step follows the p-wave speed, so every
// run is stable (locking is an accuracy matter, tests/validation/test_fbar_locking.cpp).
TEST(Stability, NearlyIncompressibleBlockIsStable) {
  for (double psi : {0.0, 1.0})
    for (double nu : {0.3, 0.49}) {
      BlockSetup b;
      b.poisson = nu;
      b.fbar_psi = psi;
      const StabilityResult r = run_block<double>(b);
      report(("block nu " + std::to_string(nu) + ", F-bar " + std::to_string(psi)).c_str(), r);
      EXPECT_EQ(r.state, State::Stable) << "nu " << nu << ", F-bar " << psi << ": " << r.message;
    }
}

}  // namespace
}  // namespace fbar
