// What both engines share and neither owns: the step report and its failure kinds, the halve-and-recover retry
// policy of on_failure = reduce_dt (DtRetryPolicy) and the landing of a step on a target time (plan_step_toward).
// The CPU engine (engine/cpu), the GPU engine (engine/gpu) and the run loop (engine/run_loop.h) read them here, so
// neither engine includes the other (docs/developer_guide.md "Layers").
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace fbar {

/// What a failed check found.
enum class FailureKind {
  NonFinite,     ///< NaN or Inf in a particle's position, velocity, affine matrix or material state
  CflViolation,  ///< a particle moved more than one cell along an axis in one step
  LeftDomain,    ///< a particle's new position lies outside [0, simulation.domain]
  Inverted,      ///< a particle's volume ratio J <= 0: collapsed or turned inside out (no state means anything there)
};
/// How many FailureKind values there are (the per-kind counters).
inline constexpr int kFailureKinds = 4;
const char* to_string(FailureKind kind);

/// One failed check of one body in one step.
struct FailureReport {
  FailureKind kind = FailureKind::NonFinite;
  int body = 0;                   ///< index in scene.bodies
  long long step = 0;             ///< 1-based index of the step that failed (steps() + 1 when it was attempted)
  double time = 0.0;              ///< [s] simulated time at the start of that step
  double dt = 0.0;                ///< [s] the step size that failed
  long long count = 0;            ///< particles of the body that failed this check
  long long first_particle = -1;  ///< smallest failing particle index (ID) of the body; element index when `elements`
  bool elements = false;          ///< the count is of a mesh body's elements (Inverted: an element turned inside out)
  /// "body 0: 12 particles moved more than one cell in one step (CFL violation) at step 345, t = 0.1234 s,
  ///  dt = 1e-4 s (first: particle 17)".
  std::string describe() const;
};

/// Outcome of step() / advance_to().
struct StepReport {
  bool ok = true;
  double dt = 0.0;                      ///< [s] size of the (last) committed step; of the failed try when !ok
  int retries = 0;                      ///< dt halvings in this step (on_failure = reduce_dt)
  long long steps = 0;                  ///< steps committed by this call
  std::vector<FailureReport> failures;  ///< the checks that failed in the last try (empty when ok)
  std::vector<FailureReport> retried;   ///< failures that were repaired by halving dt (reduce_dt)
  /// All failures, one line each (empty when ok).
  std::string message() const;
  /// Adds the report of a later step of the same call (advance_to): steps, retries and repaired failures summed,
  /// dt and failures the later one's. Returns r.ok.
  bool absorb(StepReport r);
};

/// on_failure = reduce_dt: a failed step is retried from the unchanged state with dt / 2, up to kMaxStepRetries
/// times (dt / 2^8 at most); the halving persists and is undone (x 2) after kRecoverSteps clean steps.
inline constexpr int kMaxStepRetries = 8;
inline constexpr int kRecoverSteps = 100;

/// The state of that policy, one per engine (checkpoints keep both fields): what both engines do after a try.
struct DtRetryPolicy {
  double scale = 1.0;   ///< the persisting halving factor of CFL steps (1, 1/2, 1/4, ...)
  int clean_steps = 0;  ///< clean CFL steps since the last halving or recovery

  /// After a committed step: a CFL step counts towards undoing one halving.
  void committed(bool cfl_step);
  /// After a failed try with these failures: when `mode` is reduce_dt and report.retries < kMaxStepRetries, logs
  /// each failure (when `log`), adds them to report.retried, halves dt (and the scale, for a CFL step) and returns
  /// true: retry from the unchanged state. Otherwise returns false with report and dt untouched.
  bool retry(OnFailure mode, const std::vector<FailureReport>& failures, bool cfl_step, double& dt,
             StepReport& report, std::ostream* log);
};

/// The next step toward a target time (both engines' step_toward): the CFL step `dt_cfl`, shortened to land on
/// `t_end` when it reaches it (`last`), or half the remaining time when a full step would leave a sliver (two equal
/// steps). Throws std::runtime_error when the step is below the resolution of the clock at `time`.
struct StepPlan {
  double dt = 0.0;    ///< [s]
  bool last = false;  ///< the step lands on t_end: the engine sets its clock to t_end exactly when it commits

  /// After the planned step (report r): a step that landed whole (ok, last, not shortened by a retry) sets `clock` to
  /// t_end exactly, not t_end +- round-off.
  void land(double& clock, double t_end, const StepReport& r) const {
    if (r.ok && last && r.retries == 0) clock = t_end;
  }
};
StepPlan plan_step_toward(double time, double t_end, double dt_cfl);

/// What an engine checks of body `index` before it samples it (both engines; the release policy refuses these
/// earlier for scenes read from files): a law the engines implement, "particles" bodies, use_FEM only on a mesh's
/// body, output attributes the law has, a positive ppc. Throws std::invalid_argument naming the key; `engine`
/// ("CPU engine", "GPU engine") goes into the message.
void check_engine_body(const BodySpec& spec, int index, const std::string& engine);


}  // namespace fbar
