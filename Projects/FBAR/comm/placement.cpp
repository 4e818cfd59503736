#include "comm/placement.h"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <string>

namespace fbar::comm {

std::vector<long long> placed_work(const Scene& scene, int ranks, const std::vector<long long>& body_particles) {
  std::vector<long long> work(static_cast<std::size_t>(std::max(ranks, 1)), 0);
  const std::vector<int> homes = body_ranks(scene, ranks);
  for (std::size_t i = 0; i < scene.bodies.size() && i < body_particles.size(); ++i) {
    if (homes[i] < 0) continue;
    long long w = body_particles[i];
    if (const int m = scene.bodies[i].mesh; m >= 0)
      w += 5 * static_cast<long long>(scene.meshes.at(static_cast<std::size_t>(m)).stats.elements);
    work[static_cast<std::size_t>(homes[i])] += w;
  }
  return work;
}

bool places_bodies(const Scene& scene) {
  std::set<int> named;
  for (const BodySpec& b : scene.bodies)
    if (b.mesh < 0) named.insert(b.gpu);
  return named.size() > 1;
}

int ranks_asked(const Scene& scene) {
  const bool particles_placed = places_bodies(scene);
  int most = 0;
  for (const BodySpec& b : scene.bodies)
    if (b.mesh >= 0 || particles_placed) most = std::max(most, b.gpu);
  return most + 1;
}

std::vector<int> body_ranks(const Scene& scene, int ranks) {
  std::vector<int> out(scene.bodies.size(), kAllGpus);
  if (ranks <= 1) return out;
  const bool particles_placed = places_bodies(scene);
  for (std::size_t i = 0; i < scene.bodies.size(); ++i) {
    const BodySpec& b = scene.bodies[i];
    if (b.mesh < 0 && !particles_placed) continue;
    if (b.gpu >= ranks)
      throw std::invalid_argument((b.mesh >= 0 ? "meshes[" + std::to_string(b.mesh) + "]" : "bodies[" + std::to_string(i) + "]") +
                                  ".gpu: got " + std::to_string(b.gpu) + "; expected a GPU rank of this run, 0 to " +
                                  std::to_string(ranks - 1) + " (the scene places bodies on " +
                                  std::to_string(ranks_asked(scene)) + " GPUs: run it with --gpus=" +
                                  std::to_string(ranks_asked(scene)) + " or that many MPI ranks, or on one rank)");
    out[i] = b.gpu;
  }
  return out;
}

}  // namespace fbar::comm
