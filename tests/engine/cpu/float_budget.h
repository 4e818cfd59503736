// The shipped scenes and the single-precision velocity budget of each after 30 steps from rest, shared by the CPU
// engine's float-vs-double test (test_scenes_cpu.cpp) and the GPU-vs-CPU scene test (tests/engine/gpu/test_scenes_gpu.cu).
//
// Float rounding of positions and velocities over 30 steps of the shipped scenes leaves |dv| of 1e-7 to 1e-5 m/s;
// 1e-4 m/s is the budget. Four scenes amplify rounding through their physics, and get 4x the float-vs-double
// difference measured for that mechanism: a cohesionless DruckerPrager column released from rest sits at the cone's
// apex, where rounding decides whether a particle is in tension (projected to the tip) or not (granular_collapse.json:
// 1.3e-3 m/s), and a nu = 0.499 block turns the rounding of J into pressure through lambda = 166 E
// (incompressible_block.json: 1.7e-4 m/s). The saturated column of saturated_collapse.json starts with its pore water
// carrying the overburden, so every particle's skeleton starts at zero effective stress, at the same apex
// (3.1e-4 m/s). An FEM mesh turns the rounding of its vertex positions into strain: one float ulp of a position
// near x = 1 m (6e-8 m) over an element edge of 0.02 m is a strain of 3e-6, 15 Pa at E = 5 MPa, 6e-3 N on a vertex
// of 6 g: up to 1 m/s^2 of noise, 2.8e-3 m/s over the 30 steps' 2.8 ms (fem_post_dam_break.json: 6.3e-4 m/s
// measured at the post's vertices). A larger difference anywhere else means that float and double took
// different branches somewhere (a node on a boundary in one precision and off it in the other): a defect, not noise.
#pragma once

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

namespace fbar::test {

/// Every scene in scenes/ (sorted) and the default scene Projects/FBAR/scene.json.
inline std::vector<std::filesystem::path> shipped_scene_files() {
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(fs::path(FBAR_SOURCE_DIR) / "scenes"))
    if (e.path().extension() == ".json") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  files.push_back(fs::path(FBAR_SOURCE_DIR) / "Projects" / "FBAR" / "scene.json");
  return files;
}

inline double float_velocity_budget(const std::string& scene_file_name) {
  if (scene_file_name == "granular_collapse.json") return 4 * 1.3e-3;
  if (scene_file_name == "incompressible_block.json") return 4 * 1.7e-4;
  if (scene_file_name == "saturated_collapse.json") return 4 * 3.1e-4;
  if (scene_file_name == "fem_post_dam_break.json") return 4 * 6.3e-4;
  return 1e-4;
}

/// The single-precision pore-pressure budget of a scene with saturated bodies, relative to its largest |p|: float
/// rounding of the pressure itself is 1e-7 of it; at the apex of saturated_collapse.json's skeleton (above) the
/// particles that the rounding projects or not change J by a step's strain, and the pore water turns that into
/// pressure through M (measured float vs double on the CPU engine after 30 steps: 84 Pa of 12.0 kPa, 7.0e-3 of |p|max; budget 4x).
inline double float_pore_pressure_budget(const std::string& scene_file_name) {
  if (scene_file_name == "saturated_collapse.json") return 4 * 7.0e-3;
  return 1e-5;
}

}  // namespace fbar::test
