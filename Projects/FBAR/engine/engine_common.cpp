// What both engines share (engine_common.h): the step report's text and the attributes a material can give.
#include "engine/engine_common.h"

#include <algorithm>
#include <cstdio>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string>

#include "physics/frame_attributes.h"
#include "scene/attributes.h"
#include "physics/constitutive_models.cuh"

namespace fbar {
namespace {

std::string format_g(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace

const char* to_string(FailureKind kind) {
  switch (kind) {
    case FailureKind::NonFinite:
      return "NaN/Inf in the particle state";
    case FailureKind::CflViolation:
      return "moved more than one cell in one step (CFL violation)";
    case FailureKind::LeftDomain:
      return "left the domain";
    case FailureKind::Inverted:
      return "volume ratio J <= 0 (collapsed or inverted: the step outran the material's stability)";
  }
  return "?";
}

std::string FailureReport::describe() const {
  std::ostringstream s;
  const char* what = elements ? " element" : " particle";
  s << "body " << body << ": " << count << what << (count == 1 ? " " : "s ") << to_string(kind) << " at step " << step
    << ", t = " << format_g(time) << " s, dt = " << format_g(dt) << " s (first:" << what << " " << first_particle << ")";
  return s.str();
}

bool StepReport::absorb(StepReport r) {
  steps += r.steps;
  retries += r.retries;
  retried.insert(retried.end(), r.retried.begin(), r.retried.end());
  dt = r.dt;
  if (!r.ok) {
    ok = false;
    failures = std::move(r.failures);
  }
  return r.ok;
}

std::string StepReport::message() const {
  std::string m;
  for (const FailureReport& f : failures) m += (m.empty() ? "" : "\n") + f.describe();
  return m;
}

void DtRetryPolicy::committed(bool cfl_step) {
  if (cfl_step && scale < 1.0 && ++clean_steps >= kRecoverSteps) {
    scale = std::min(1.0, 2.0 * scale);
    clean_steps = 0;
  }
}

bool DtRetryPolicy::retry(OnFailure mode, const std::vector<FailureReport>& failures, bool cfl_step, double& dt,
                          StepReport& report, std::ostream* log) {
  if (mode != OnFailure::ReduceDt || report.retries >= kMaxStepRetries) return false;
  if (log)
    for (const FailureReport& f : failures)
      *log << "fbar: " << f.describe() << "; retrying the step with dt = " << format_g(dt / 2) << " s\n";
  report.retried.insert(report.retried.end(), failures.begin(), failures.end());
  ++report.retries;
  dt *= 0.5;
  if (cfl_step) {
    scale *= 0.5;
    clean_steps = 0;
  }
  return true;
}

StepPlan plan_step_toward(double time, double t_end, double dt_cfl) {
  const double remaining = t_end - time;
  StepPlan plan{dt_cfl, dt_cfl >= remaining};
  if (plan.last)
    plan.dt = remaining;
  else if (2.0 * dt_cfl > remaining)
    plan.dt = 0.5 * remaining;  // two equal steps rather than a full one and a sliver
  if (!(time + plan.dt > time))
    throw std::runtime_error("advance_to: the time step " + format_g(plan.dt) +
                             " s is below the resolution of the clock at t = " + format_g(time) + " s");
  return plan;
}

void check_engine_body(const BodySpec& spec, int index, const std::string& engine) {
  const std::string where =
      spec.mesh >= 0 ? "meshes[" + std::to_string(spec.mesh) + "]" : "bodies[" + std::to_string(index) + "]";
  const MaterialSpec& mat = spec.material;
  const char* law = "?";
  visit_material(mat.law, [&](auto m) { law = decltype(m)::kJsonName; });
  if (material_index(mat.law) < 0)
    throw std::invalid_argument(where + ".material.constitutive: " + law + " is not implemented by the " + engine +
                                " (implemented: " + supported_material_names() + ")");
  if (mat.type != "particles")
    throw std::invalid_argument(where + ".material.type: \"" + mat.type + "\" bodies are not implemented");
  if (spec.algorithm.use_fem && spec.mesh < 0)
    throw std::invalid_argument(where + ".algorithm.use_FEM: not implemented by the " + engine);
  for (const std::string& name : spec.output_attribs) {
    const std::string canonical = canonical_attribute(name);
    if (canonical.empty() || !material_supports_attribute(mat.law, canonical))
      throw std::invalid_argument(where + ".output_attribs: " + name + " is not available for a " + law + " body");
  }
  if (!(mat.ppc > 0.0)) throw std::invalid_argument(where + ".material.ppc: must be positive");
}

}  // namespace fbar
