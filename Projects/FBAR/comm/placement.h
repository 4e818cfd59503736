// Which bodies are placed whole on one rank (ClaymoreUW's bodies[].gpu) and which are spread over the ranks by space.
//
// fbar spreads every body over the ranks by space (comm/slab_partition.h) unless the scene places bodies the way
// ClaymoreUW does: when its bodies name more than one GPU (`"gpu": 0` and `"gpu": 1`, or an integer and "all"),
// each body with an integer `gpu` lives whole on that rank (it never migrates; partition_start / partition_end clip
// it, so one geometry can be cut into pieces on several GPUs as in ClaymoreUW) and each body with `"gpu": "all"` is
// spread by space. Placed bodies interact with everything else through a general halo: every grid block held by
// several ranks is summed over all of them (CpuEngine::exchange_halo, MgspBenchmark::rebuild_halo).
#pragma once

#include <vector>

#include "scene/scene.h"

namespace fbar::comm {

/// Whether the scene places its particle bodies on GPUs (they name more than one GPU, "all" counting as one). A mesh
/// (FEM body) is always placed whole on its meshes[].gpu: its elements join vertices of one rank.
bool places_bodies(const Scene& scene);

/// The ranks a placing scene asks for (the largest `gpu` of a placed body or mesh + 1); 1 for a scene that places
/// nothing.
int ranks_asked(const Scene& scene);

/// Per body, the rank that holds it whole, or kAllGpus (-1) for a body spread by space. Every body is spread on one
/// rank; particle bodies are spread when the scene does not place them; meshes are always placed. Throws std::invalid_argument naming bodies[i].gpu when a body names
/// a GPU the run does not have.
std::vector<int> body_ranks(const Scene& scene, int ranks);

/// Per rank, the work of the bodies placed whole on it (body_ranks), for choose_slabs' preload: a body's particles
/// (body_particles[i], every rank's), a mesh's vertices and 5 per element (its element pass costs 0.57 ns an
/// element-step against 0.11 ns a particle-step: docs/benchmarks/2026-11-28-h200x2-fem.md). All zero when nothing is
/// placed.
std::vector<long long> placed_work(const Scene& scene, int ranks, const std::vector<long long>& body_particles);

}  // namespace fbar::comm
