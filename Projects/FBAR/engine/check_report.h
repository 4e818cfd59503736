// Human-readable report of a resolved scene with units (what `fbar --check` prints).
#pragma once

#include <iosfwd>

#include "engine/engine_api.h"
#include "scene/scene.h"

namespace fbar {

/// Every simulation key; per body its law and parameters, algorithm, geometry, particle count, wave speed and
/// time-step bound; boundaries and sensors; then the step and the memory estimates of `summary`.
void print_scene_report(std::ostream& os, const Scene& scene, const SceneSummary& summary);

}  // namespace fbar
