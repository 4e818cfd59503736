#include "comm/placement.h"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <string>

namespace fbar::comm {

bool places_bodies(const Scene& scene) {
  std::set<int> named;
  for (const BodySpec& b : scene.bodies) named.insert(b.gpu);
  return named.size() > 1;
}

int ranks_asked(const Scene& scene) {
  if (!places_bodies(scene)) return 1;
  int most = 0;
  for (const BodySpec& b : scene.bodies) most = std::max(most, b.gpu);
  return most + 1;
}

std::vector<int> body_ranks(const Scene& scene, int ranks) {
  std::vector<int> out(scene.bodies.size(), kAllGpus);
  if (ranks <= 1 || !places_bodies(scene)) return out;
  for (std::size_t i = 0; i < scene.bodies.size(); ++i) {
    const int gpu = scene.bodies[i].gpu;
    if (gpu >= ranks)
      throw std::invalid_argument("bodies[" + std::to_string(i) + "].gpu: got " + std::to_string(gpu) +
                                  "; expected a GPU rank of this run, 0 to " + std::to_string(ranks - 1) +
                                  " (the scene places bodies on " + std::to_string(ranks_asked(scene)) +
                                  " GPUs: run it with --gpus=" + std::to_string(ranks_asked(scene)) +
                                  " or that many MPI ranks, or on one rank)");
    out[i] = gpu;
  }
  return out;
}

}  // namespace fbar::comm
