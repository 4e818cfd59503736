// ClaymoreUW's resume in tests (CPU and GPU): the water + plastic block scene's state written as .bgeo frames, and
// the scene whose bodies are seeded from them (File geometry with has_attributes).
#pragma once

#include <filesystem>
#include <string>

#include "MnSystem/IO/particle_io.h"
#include "../physics/physics_test_support.h"
#include "scene/scene.h"

namespace fbar::test {

/// Output attributes that carry a body's state: velocity and J for the water (body 0); velocity, logJp and F for
/// the plastic block (body 1).
inline void output_state_attributes(Scene& scene) {
  scene.bodies[0].output_attribs = {"ID", "Velocity_X", "Velocity_Y", "Velocity_Z", "J"};
  scene.bodies[1].output_attribs = {"ID", "Velocity_X", "Velocity_Y", "Velocity_Z", "logJp"};
  for (const char* c : {"XX", "XY", "XZ", "YX", "YY", "YZ", "ZX", "ZY", "ZZ"})
    scene.bodies[1].output_attribs.push_back(std::string("DefGrad_") + c);
}

/// The .bgeo frame of body k in `dir`.
inline std::filesystem::path resume_frame(const std::filesystem::path& dir, std::size_t k) {
  return dir / ("body" + std::to_string(k) + ".bgeo");
}

/// Writes every body's frame of `run` (an engine of `scene`) to `dir` and returns `scene` with each body read back
/// from its frame: File geometry, has_attributes with the body's output_attribs, body velocity 0 (the file's
/// velocities replace it).
template <typename Engine>
Scene seeded_from_frames(const Scene& scene, const Engine& run, const std::filesystem::path& dir) {
  Scene seeded = scene;
  for (std::size_t k = 0; k < scene.bodies.size(); ++k) {
    io::write_bgeo(resume_frame(dir, k), run.frame(static_cast<int>(k)));
    GeometrySpec g;
    g.object = GeometryObject::File;
    g.file = resume_frame(dir, k).string();
    g.has_attributes = true;
    g.input_attribs = scene.bodies[k].output_attribs;
    seeded.bodies[k].geometry = {g};
    seeded.bodies[k].velocity = r3(0, 0, 0);
  }
  return seeded;
}

}  // namespace fbar::test
