// engine_common.h: the step-landing rule and the retry policy both engines use, the step report's bookkeeping.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "engine/engine_common.h"

namespace fbar {
namespace {

// A CFL step that reaches the target is shortened to land on it; one that would leave less than a step is halved
// (two equal steps, not a full one and a sliver); any other is kept.
TEST(PlanStepToward, LandsHalvesOrKeeps) {
  StepPlan p = plan_step_toward(1.0, 1.25, 0.5);
  EXPECT_TRUE(p.last);
  EXPECT_EQ(p.dt, 0.25);
  p = plan_step_toward(1.0, 1.3, 0.2);  // 0.2 then a 0.1 sliver: two steps of 0.15 instead
  EXPECT_FALSE(p.last);
  EXPECT_DOUBLE_EQ(p.dt, 0.15);
  p = plan_step_toward(1.0, 2.0, 0.2);
  EXPECT_FALSE(p.last);
  EXPECT_EQ(p.dt, 0.2);
  p = plan_step_toward(0.0, 0.2, 0.2);  // exactly one step: it lands
  EXPECT_TRUE(p.last);
  EXPECT_EQ(p.dt, 0.2);
}

// A step the clock cannot represent (t + dt == t) is an error that names the step and the time, in both engines
// (the GPU engine's copy of the rule used to miss this check); landing on the next representable time is not.
TEST(PlanStepToward, BelowTheClockResolutionIsAnError) {
  const double t = 1e6;  // one ulp of t is 1.2e-10 s: a CFL step of 1e-12 s does not move the clock
  try {
    plan_step_toward(t, 2e6, 1e-12);
    ADD_FAILURE() << "a step below the clock's resolution was planned";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("below the resolution of the clock at t = 1e+06 s"), std::string::npos)
        << e.what();
  }
  const StepPlan ulp = plan_step_toward(t, std::nextafter(t, 2e6), 1e-3);
  EXPECT_TRUE(ulp.last);
  EXPECT_GT(t + ulp.dt, t);
}

// StepPlan::land: only a whole landing step (ok, planned as the last, no retry shortened it) sets the clock to t_end.
TEST(PlanStepToward, OnlyAWholeLandingSetsTheClock) {
  const StepPlan last = plan_step_toward(1.0, 1.25, 0.5);
  StepReport ok;
  double clock = 1.0 + 0.25 + 1e-17;
  last.land(clock, 1.25, ok);
  EXPECT_EQ(clock, 1.25);
  StepReport retried;
  retried.retries = 1;  // the step was halved: it ends short of t_end
  clock = 1.125;
  last.land(clock, 1.25, retried);
  EXPECT_EQ(clock, 1.125);
  StepReport failed;
  failed.ok = false;
  clock = 1.0;
  last.land(clock, 1.25, failed);
  EXPECT_EQ(clock, 1.0);
  const StepPlan middle = plan_step_toward(1.0, 2.0, 0.2);
  clock = 1.2;
  middle.land(clock, 2.0, ok);
  EXPECT_EQ(clock, 1.2);
}

// check_engine_body: both engines refuse what they cannot run with the key, the value and the engine named.
TEST(CheckEngineBody, NamesTheKeyAndTheEngine) {
  BodySpec body;
  body.material.law = Constitutive::JFluid;
  EXPECT_NO_THROW(check_engine_body(body, 0, "GPU engine"));
  auto message = [](const BodySpec& b) {
    try {
      check_engine_body(b, 2, "CPU engine");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  BodySpec logjp = body;
  logjp.output_attribs = {"logJp"};
  EXPECT_EQ(message(logjp), "bodies[2].output_attribs: logJp is not available for a JFluid body");
  BodySpec fem = body;
  fem.algorithm.use_fem = true;
  EXPECT_EQ(message(fem), "bodies[2].algorithm.use_FEM: not implemented by the CPU engine");
  BodySpec mesh = body;
  mesh.material.type = "mesh";
  EXPECT_EQ(message(mesh), "bodies[2].material.type: \"mesh\" bodies are not implemented");
  BodySpec empty = body;
  empty.material.ppc = 0.0;
  EXPECT_EQ(message(empty), "bodies[2].material.ppc: must be positive");
}

// A saturated (CoupledUP) body runs on both engines with its PorePressure attribute; a law without pore water has no
// such attribute on either.
TEST(CheckEngineBody, SaturatedBodiesRunOnBothEngines) {
  BodySpec soil;
  soil.material.law = Constitutive::CoupledUP;
  soil.material.poro = 0.4;
  soil.output_attribs = {"ID", "PorePressure"};
  EXPECT_NO_THROW(check_engine_body(soil, 0, "CPU engine"));
  EXPECT_NO_THROW(check_engine_body(soil, 1, "GPU engine"));
  BodySpec water;
  water.output_attribs = {"PorePressure"};
  EXPECT_THROW(check_engine_body(water, 0, "CPU engine"), std::invalid_argument);  // JFluid has no pore water
  EXPECT_THROW(check_engine_body(water, 0, "GPU engine"), std::invalid_argument);
}

// absorb(): steps, retries and repaired failures add up over the steps of one advance_to; dt and the failures are
// the last step's.
TEST(StepReportAbsorb, SumsStepsAndKeepsTheLastFailure) {
  StepReport total;
  StepReport a;
  a.steps = 1;
  a.dt = 0.1;
  a.retries = 1;
  a.retried.push_back(FailureReport{FailureKind::CflViolation, 0, 1, 0.0, 0.2, 3, 7});
  EXPECT_TRUE(total.absorb(a));
  StepReport b;
  b.ok = false;
  b.dt = 0.05;
  b.failures.push_back(FailureReport{FailureKind::NonFinite, 1, 2, 0.1, 0.05, 1, 4});
  EXPECT_FALSE(total.absorb(b));
  EXPECT_FALSE(total.ok);
  EXPECT_EQ(total.steps, 1);
  EXPECT_EQ(total.retries, 1);
  EXPECT_EQ(total.dt, 0.05);
  ASSERT_EQ(total.retried.size(), 1u);
  ASSERT_EQ(total.failures.size(), 1u);
  EXPECT_EQ(total.message(),
            "body 1: 1 particle NaN/Inf in the particle state at step 2, t = 0.1 s, dt = 0.05 s (first: particle 4)");
}

// reduce_dt: a failed try is retried with dt / 2 up to kMaxStepRetries times, each failure logged and kept in the
// report; a CFL step's halving persists in the scale, which doubles back after kRecoverSteps clean CFL steps. A fixed
// dt (step(dt)) leaves the scale alone; on_failure = stop never retries.
TEST(DtRetryPolicy, HalvesPersistsAndRecovers) {
  const std::vector<FailureReport> failures{FailureReport{FailureKind::CflViolation, 0, 5, 1.0, 0.1, 2, 9}};
  DtRetryPolicy policy;
  StepReport report;
  double dt = 0.1;
  std::ostringstream log;
  EXPECT_FALSE(policy.retry(OnFailure::Stop, failures, true, dt, report, &log));
  EXPECT_EQ(dt, 0.1);
  EXPECT_EQ(report.retries, 0);
  ASSERT_TRUE(policy.retry(OnFailure::ReduceDt, failures, true, dt, report, &log));
  EXPECT_EQ(dt, 0.05);
  EXPECT_EQ(policy.scale, 0.5);
  EXPECT_EQ(report.retries, 1);
  ASSERT_EQ(report.retried.size(), 1u);
  EXPECT_NE(log.str().find("retrying the step with dt = 0.05 s"), std::string::npos) << log.str();
  for (int k = 1; k < kMaxStepRetries; ++k)
    EXPECT_TRUE(policy.retry(OnFailure::ReduceDt, failures, true, dt, report, nullptr));
  EXPECT_EQ(report.retries, kMaxStepRetries);
  EXPECT_FALSE(policy.retry(OnFailure::ReduceDt, failures, true, dt, report, nullptr));  // dt / 2^8 at most
  EXPECT_DOUBLE_EQ(dt, 0.1 / 256);
  EXPECT_DOUBLE_EQ(policy.scale, 1.0 / 256);
  for (int k = 0; k < kRecoverSteps - 1; ++k) policy.committed(true);
  EXPECT_DOUBLE_EQ(policy.scale, 1.0 / 256);
  policy.committed(false);  // a fixed-dt step does not count
  EXPECT_DOUBLE_EQ(policy.scale, 1.0 / 256);
  policy.committed(true);
  EXPECT_DOUBLE_EQ(policy.scale, 1.0 / 128);
  EXPECT_EQ(policy.clean_steps, 0);
  DtRetryPolicy fixed;
  StepReport r2;
  double dt2 = 0.2;
  ASSERT_TRUE(fixed.retry(OnFailure::ReduceDt, failures, false, dt2, r2, nullptr));
  EXPECT_EQ(dt2, 0.1);
  EXPECT_EQ(fixed.scale, 1.0);
}

}  // namespace
}  // namespace fbar
