// summarize_scene() (particle counts, wave speeds, dt, memory estimates) and run_guarded(); run_cpu() is the CPU
// engine's (engine/cpu/cpu_run.cpp), run_gpu() the GPU engine's (engine/gpu/gpu_engine.cu).
#include "engine/engine_api.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "MnSystem/IO/async_writer.h"
#include "physics/constitutive_models.cuh"
#include "engine/run_constants.h"
#include "geometry/geometry.h"
#include "engine/grid_channels.h"
#include "engine/memory_plan.h"
#include "io/particle_frame.h"
#include "io/sensor_recorder.h"
#include "scene/scene_error.h"
#include "scene/scene_parse.h"
#include "physics/time_step.cuh"

namespace fbar {
namespace {

/// Material facts the summary needs, also for laws no engine implements yet (so `--check` still answers).
struct MaterialFacts {
  double wave_speed;   ///< [m/s] at rest
  int stored_scalars;  ///< per particle in a GPU bin (position + state)
};

MaterialFacts material_facts(const MaterialSpec& m) {
  MaterialFacts facts{0.0, 0};
  const bool known = visit_material(m.law, [&](auto mt) {
    using M = decltype(mt);
    facts.wave_speed = M::wave_speed(M::template make_params<double>(m), M::template reference_state<double>());
    facts.stored_scalars = M::kStoredScalars;
  });
  if (!known) {
    // The plastic laws not in MaterialTypes yet: p-wave speed sqrt((lambda + 2 mu) / rho); bins
    // store position + F + log Jp.
    const LameParameters l = lame_parameters(m.youngs_modulus, m.poisson_ratio);
    const double mu = l.mu, lambda = l.lambda;
    facts.wave_speed = std::sqrt((lambda + 2.0 * mu) / m.rho);
    facts.stored_scalars = 13;
  }
  return facts;
}

/// Bytes of one particle scalar and one grid scalar for a precision, on both engines: single stores and accumulates
/// in float; double in double; mixed keeps the particle state in double and the grid in float (ClaymoreUW's choice;
/// GpuEngine<double, float>, CpuEngine<double, float>).
std::size_t particle_scalar_bytes(Precision p) { return p == Precision::Single ? 4 : 8; }

/// A mesh's part of its body's summary: elements, quality, the lumped vertex volume, the element step bound and the
/// engines' bytes for the elements (physics/fem.cuh).
void summarize_mesh(BodySummary& s, const Scene& scene, const BodySpec& body) {
  const MeshEntrySpec& entry = scene.meshes.at(static_cast<std::size_t>(body.mesh));
  const TetMeshStats& f = entry.stats;
  s.mesh = true;
  s.elements = static_cast<long long>(f.elements);
  s.min_quality = f.min_quality;
  s.min_height = f.min_height;
  s.particle_volume = f.volume / static_cast<double>(std::max<std::size_t>(1, f.vertices));
  s.particle_mass = body.material.rho * s.particle_volume;
  // Per element: TetElement (4 ints, Dm^-1, V0), 4 CSR corners, the pass's F, J and forces H; per vertex: the CSR
  // start and the forces twice.
  const std::size_t t = particle_scalar_bytes(scene.simulation.precision);
  s.mesh_bytes = f.elements * (16 + 10 * t + 16 + 19 * t) + f.vertices * (4 + 6 * t);
  s.gpu_mesh_bytes = mesh_device_bytes(scene.simulation.precision, f.elements, f.vertices, entry.fbar_elements,
                                       body.algorithm.use_fem);
  s.dt_bound = min_time_step(s.dt_bound, body_element_step_bound(scene, body));  // run_constants.h
}

/// H200 particle-steps per second of one law's APIC step at 16M particles, single, double and mixed precision
/// (kGpuRateRecord: the benchmark's dam break for JFluid, its falling block for the other laws); `basis` says which
/// row. A law not measured takes FixedCorotated's (an SVD per particle and step, as most laws do).
struct LawThroughput {
  double single, dbl, mixed;
  const char* basis;
};
LawThroughput law_throughput(Constitutive law) {
  switch (law) {
    case Constitutive::JFluid: return {1.03e10, 5.07e9, 7.42e9, "JFluid"};
    case Constitutive::FixedCorotated: return {9.25e9, 4.36e9, 6.51e9, "FixedCorotated"};
    case Constitutive::NeoHookean: return {1.02e10, 5.04e9, 7.55e9, "NeoHookean"};
    case Constitutive::DruckerPrager: return {4.90e9, 1.86e9, 2.16e9, "DruckerPrager"};
    case Constitutive::NACC: return {6.34e9, 2.62e9, 2.92e9, "NACC"};
    case Constitutive::Hencky: return {7.39e9, 2.96e9, 3.79e9, "Hencky"};
    case Constitutive::VonMises: return {5.10e9, 1.90e9, 2.18e9, "VonMises"};
    case Constitutive::CoupledUP: return {2.72e9, 1.11e9, 1.33e9, "CoupledUP"};
    default: return {9.25e9, 4.36e9, 6.51e9, "FixedCorotated's (not measured for this law)"};
  }
}
/// A step with PIC-FLIP / FLIP / ASFLIP, and one with F-bar, against an APIC step (the JFluid dam break of
/// kGpuRateRecord), single, double and mixed.
constexpr double kAsflipStep[3] = {1.93, 1.91, 1.81};
constexpr double kFbarStep[3] = {1.20, 1.14, 1.21};
/// A step with the nodal F-bar (fused) against one with the cell F-bar, single precision, 16M particles
/// (docs/benchmarks/2026-12-04-h200-nodal-fbar-cost.md: 6.052 / 1.855 ms); the other precisions were not measured.
constexpr double kNodalFbarStep = 3.26;

/// A body's particle-steps per second on the GPU (law_throughput with the scheme's factors) and what it comes from.
double body_throughput(Constitutive law_name, Precision precision, bool asflip, bool fbar, bool nodal,
                       std::string& basis) {
  const LawThroughput law = law_throughput(law_name);
  const int p = precision == Precision::Single ? 0 : precision == Precision::Double ? 1 : 2;
  double rate = p == 0 ? law.single : p == 1 ? law.dbl : law.mixed;
  basis = std::string(law.basis) + ", " + to_string(precision);
  char factor[48];
  if (asflip) {
    rate /= kAsflipStep[p];
    std::snprintf(factor, sizeof(factor), ", ASFLIP x %.3g", kAsflipStep[p]);
    basis += factor;
  }
  if (fbar) {
    rate /= kFbarStep[p];
    std::snprintf(factor, sizeof(factor), ", F-bar x %.3g", kFbarStep[p]);
    basis += factor;
    if (nodal) {
      rate /= kNodalFbarStep;
      std::snprintf(factor, sizeof(factor), ", nodal x %.3g", kNodalFbarStep);
      basis += factor;
    }
  }
  return rate;
}

}  // namespace

HostFrameBytes host_frame_bytes(std::size_t n, std::size_t t, int columns, int attributes, const std::string& suffix,
                                bool exterior, std::size_t frame_host_bytes, bool mesh) {
  // GPU engine (frame_output.cuh submit_frame): the frame comes down whole into its pinned buffer when it fits
  // frame_host_bytes (a .bgeo without the filter as its packed records), else a piece at a time; the writer reads
  // io::FrameStream::piece points at a time (particle_io.h FrameReader: with the filter, a scratch copy of each
  // piece, one bit per point and two maps over the occupied cubes), a .bgeo serialises each piece's records.
  constexpr std::size_t kPiece = io::kFramePiecePoints;
  const std::size_t whole = n * (3 * t + 4 * static_cast<std::size_t>(columns));
  const std::size_t attrs = static_cast<std::size_t>(attributes);
  const std::size_t record = 16 + 4 * attrs;
  const bool bgeo = suffix == ".bgeo";
  HostFrameBytes f;
  const bool streamed = !mesh && whole > frame_host_bytes;
  f.pinned = streamed ? std::min(frame_host_bytes, kPiece * 3 * t) : bgeo && !exterior && !mesh ? n * record : whole;
  const std::size_t piece = std::min(n, kPiece);
  f.writer = piece * (3 * t + 4 * attrs) * (exterior ? 2 : 1) + (bgeo ? piece * record : 0);
  if (exterior) f.writer += n / 8 + n / 16;  // the bits, and the cube maps (~80 B per cube of >= 128 points)
  if (mesh) f.writer += n * (3 * t + 4 * attrs);  // a mesh's frame is built whole (its .vtk)
  return f;
}

HostCheckpointBytes host_checkpoint_bytes(std::size_t n, std::size_t slots, std::size_t t, int stored_scalars,
                                          std::size_t frame_host_bytes, bool mesh) {
  // GPU engine (sensors_checkpoints.cuh checkpoint): each body gathered in ID order (its stored scalars and v, C),
  // copied into the checkpoint's arrays (doubles: ID, x, v, C, mass, volume, state; the P2G block of each particle:
  // ID and 3 coordinates), the P2G record of every slot and a block per ID while it is read; the writer narrows
  // each array to float for a single-precision file. A body whose copy by ID exceeds frame_host_bytes (not a mesh)
  // is streamed: one range of IDs (as many rows as frame_host_bytes holds, at most 2^20) in pinned memory kept
  // until the file is written, one dataset's rows of that range in doubles (C: 9) and the writer's narrowed copy,
  // and the table's block coordinates (12 B per block, at most one block per bin of 32 slots).
  const std::size_t state = static_cast<std::size_t>(stored_scalars - 3);
  const std::size_t by_id = n * (static_cast<std::size_t>(stored_scalars) + 12) * t;
  HostCheckpointBytes c;
  c.streamed = checkpoint_streamed(n, stored_scalars, t, frame_host_bytes, mesh);
  if (c.streamed) {
    const std::size_t ids = checkpoint_range_ids(n, stored_scalars, t, frame_host_bytes);
    c.kept = ids * checkpoint_range_bytes(stored_scalars, t);
    c.transient = ids * 9 * (8 + 8) + slots / 32 * 12;
    return c;
  }
  c.kept = n * (8 + 8 * (3 + 3 + 9 + 1 + 1 + state) + 8 + 12);
  c.transient = std::max(by_id, slots * 8 + n * 4) + n * 9 * 4;
  return c;
}

namespace {

/// Float columns of a body's frame on the GPU and (attributes) its attribute count; a list the run refuses still
/// counts its bytes.
int gpu_frame_columns(const BodySpec& body, int index, int& attributes) {
  try {
    const std::vector<FrameAttributeSpec> attrs = frame_attributes(body, index, "GPU engine");
    attributes = static_cast<int>(attrs.size());
    return frame_float_columns(attrs);
  } catch (const std::invalid_argument&) {
    attributes = static_cast<int>(body.output_attribs.size());
    return attributes;
  }
}

/// One body's frames (columns >= 0: the run writes frames) and checkpoint in the summary's host memory.
void add_host_output_bytes(SceneSummary& summary, std::size_t& checkpoint_kept, std::size_t& checkpoint_transient,
                           const SimulationSpec& sim,
                           const BodySpec& body, long long particles, long long slots, int stored_scalars,
                           int columns, int attributes, std::size_t frame_host_bytes, bool mesh) {
  const std::size_t n = static_cast<std::size_t>(particles), t = particle_scalar_bytes(sim.precision);
  if (columns >= 0) {
    const HostFrameBytes f = host_frame_bytes(n, t, columns, attributes, sim.save_suffix,
                                              sim.particles_output_exterior_only || body.output_exterior_only,
                                              frame_host_bytes, mesh);
    summary.host_frame_pinned_bytes += f.pinned;
    summary.host_frame_writer_bytes = std::max(summary.host_frame_writer_bytes, f.writer);
  }
  const HostCheckpointBytes c =
      host_checkpoint_bytes(n, static_cast<std::size_t>(slots), t, stored_scalars, frame_host_bytes, mesh);
  checkpoint_kept += c.kept;
  summary.host_checkpoint_streamed = summary.host_checkpoint_streamed || c.streamed;
  checkpoint_transient = std::max(checkpoint_transient, c.transient);
}

/// The run's host memory from its parts: the set-up's, or the frames' and checkpoints' after it. The set-up's
/// memory is given back before the first frame (sampling allocates on the calling thread only and the run calls
/// malloc_trim: gpu_engine.cu run_with; docs/benchmarks/2026-12-02-h200-host-memory.md). The frames' writer and a
/// streamed checkpoint's reading are jobs of one writer thread, one after the other (a copied checkpoint is taken
/// while the frames are written).
/// Without checkpoint_every only a stop (SIGTERM, a failure) writes a checkpoint, and the report says what it adds.
void finish_host_run_bytes(SceneSummary& summary, std::size_t checkpoint_kept, std::size_t checkpoint_transient,
                           const SimulationSpec& sim) {
  summary.host_checkpoint_bytes = checkpoint_kept + checkpoint_transient;
  summary.checkpoints = sim.checkpoint_every > 0;
  const std::size_t writer =
      !summary.checkpoints              ? summary.host_frame_writer_bytes
      : summary.host_checkpoint_streamed ? checkpoint_kept + std::max(summary.host_frame_writer_bytes, checkpoint_transient)
                                         : summary.host_frame_writer_bytes + summary.host_checkpoint_bytes;
  summary.host_run_bytes =
      kHostProgramBytes + std::max(summary.host_setup_bytes, summary.host_frame_pinned_bytes + writer);
}

}  // namespace

SceneSummary summarize_scene(const Scene& scene, const SummaryOptions& options) {
  const SimulationSpec& sim = scene.simulation;
  SceneSummary summary;
  summary.dt = resolved_default_dt(sim);
  const double dx = sim.dx;

  int max_gpu = -1;
  bool several_ranks = false;  // a body spread ("all") or placed beyond GPU 0: the run is decomposed
  for (const BodySpec& b : scene.bodies) {  // "all": GPU 0's estimate
    max_gpu = std::max(max_gpu, std::max(b.gpu, 0));
    several_ranks = several_ranks || b.gpu != 0;
  }
  // Every body's particle blocks (their 2x2x2 footprints are the grid blocks, per GPU and for the CPU engine).
  std::vector<SampleCount> counts;
  std::vector<std::vector<BodyMemoryInput>> gpu_inputs(max_gpu + 1);
  std::size_t cpu_particle_bytes = 0;
  bool asflip = false, fbar = false, pore = false;  // some body uses ASFLIP / F-bar / pore water: grid channels
  std::size_t checkpoint_kept = 0;                  // every body's part of a checkpoint until it is written
  std::size_t checkpoint_transient = 0;             // the largest body's gather while a checkpoint is taken
  // v and C kept for particle sensors, trackers or checkpoints (on the steps landing on their times)
  const bool record = sensors_read_velocity(scene) || sim.checkpoint_every > 0;
  for (std::size_t i = 0; i < scene.bodies.size(); ++i) {
    const BodySpec& body = scene.bodies[i];
    const MaterialSpec& m = body.material;
    // Counted, not stored: --check and the memory plan cost no host memory per particle.
    const std::shared_ptr<const TetMesh> mesh = body.mesh >= 0 ? scene.meshes.at(static_cast<std::size_t>(body.mesh)).mesh : nullptr;
    counts.push_back(mesh ? count_points(mesh->vertices, dx) : BodySampler(body, sim, static_cast<int>(i)).count(dx));
    const SampleCount& count = counts.back();
    const MaterialFacts facts = material_facts(m);
    BodySummary s;
    s.particles = count.particles;
    s.particle_volume = dx * dx * dx / m.ppc;
    s.particle_mass = m.rho * s.particle_volume;
    s.wave_speed = facts.wave_speed;
    const double v0 = std::sqrt(body.velocity[0] * body.velocity[0] + body.velocity[1] * body.velocity[1] +
                                body.velocity[2] * body.velocity[2]);
    s.dt_bound = cfl_time_step(m.cfl, dx, facts.wave_speed, v0);
    if (mesh)
      summarize_mesh(s, scene, body);
    s.viscous_dt = body_viscous_step_bound(body, dx);
    s.seepage_dt = body_seepage_step_bound(body, dx);
    summary.dt = min_time_step(min_time_step(min_time_step(summary.dt, s.dt_bound), s.viscous_dt), s.seepage_dt);
    // Float columns of the body's frame on the GPU (-1: no frames); a list the run refuses still counts its bytes.
    int frame_attrs = 0;
    const int frame_columns = options.frames ? gpu_frame_columns(body, static_cast<int>(i), frame_attrs) : -1;
    {
      // The GPU engine's bytes per particle (before the bins' headroom and empty lanes) and the time of its step.
      const std::size_t t = particle_scalar_bytes(sim.precision);
      const bool asflip_body = body.algorithm.asflip_active();
      const bool fbar_body = body.algorithm.fbar_blend() != 0.0;
      s.stored_scalars = facts.stored_scalars;
      s.record_bytes = particle_record_bytes(facts.stored_scalars, t);
      std::size_t bytes = 2 * s.record_bytes + 16;  // two bin sets; partition: src of both layouts and the destination
      s.gpu_bytes_detail = "2 bins x " + std::to_string(s.record_bytes) + " B (" + std::to_string(facts.stored_scalars) +
                           " scalars of " + std::to_string(t) + " B + ID) + 16 B partition";
      if (asflip_body) {
        bytes += 6 * t;
        s.gpu_bytes_detail += " + " + std::to_string(6 * t) + " B ASFLIP velocities";
      }
      if (body.algorithm.fbar_nodal() && !mesh) {
        bytes += 2 * t;
        s.gpu_bytes_detail += " + " + std::to_string(2 * t) + " B nodal F-bar's JBar";
      }
      if (record || mesh) {  // a mesh's vertices always record them
        bytes += 12 * t;
        s.gpu_bytes_detail += " + " + std::to_string(12 * t) + " B recorded v and C";
      }
      if (frame_columns >= 0) {
        const std::size_t frame = 3 * t + 4 * static_cast<std::size_t>(frame_columns);
        bytes += frame;
        s.gpu_bytes_detail += " + " + std::to_string(frame) + " B frame (" + std::to_string(frame_columns) + " columns)";
      }
      s.gpu_bytes_per_particle = bytes;
      s.throughput = body_throughput(m.law, sim.precision, asflip_body, fbar_body, body.algorithm.fbar_nodal(),
                                     s.throughput_basis);
      s.gpu_ms_per_step = 1e3 * static_cast<double>(count.particles) / s.throughput;
      summary.gpu_ms_per_step += s.gpu_ms_per_step;
    }
    summary.bodies.push_back(s);

    BodyMemoryInput in;
    in.particles = count.particles;
    in.bins_needed = bins_needed(count);
    in.stored_scalars = facts.stored_scalars;
    in.asflip = body.algorithm.asflip_active();
    in.fbar = body.algorithm.fbar_blend() != 0.0;
    in.fbar_nodal = body.algorithm.fbar_nodal() && !mesh;
    in.pore = material_has_pore_fluid(body.material.law);
    in.record = record || mesh;
    in.mesh_bytes = s.gpu_mesh_bytes;
    if (frame_columns >= 0) in.frame_columns = frame_columns;
    asflip = asflip || in.asflip;
    fbar = fbar || in.fbar;
    pore = pore || in.pore;
    gpu_inputs[std::max(body.gpu, 0)].push_back(in);
    // GPU set-up: one batch of sampled positions (double, written at their counted offsets; on several ranks each
    // also holds the part of the batch it keeps), its bin records, and the block counts.
    const std::size_t batch = static_cast<std::size_t>(std::min(count.particles, kSampleBatchParticles));
    const std::size_t position_copies = several_ranks ? 2 : 1;
    summary.host_setup_bytes =
        std::max(summary.host_setup_bytes,
                 batch * (position_copies * 24 +
                          particle_record_bytes(facts.stored_scalars, particle_scalar_bytes(sim.precision))) +
                     count.blocks.size() * (sizeof(BlockCount) + 8 * 16));
    add_host_output_bytes(summary, checkpoint_kept, checkpoint_transient, sim, body, count.particles, in.bins_needed * 32,
                          facts.stored_scalars + (in.fbar_nodal ? 1 : 0), frame_columns, frame_attrs, options.frame_host_bytes, mesh != nullptr);

    // CPU engine: x, v, their next copies (4 x 3), C and its next copy (2 x 9), mass, volume (2), state twice, in
    // the particle scalar type, plus order / block index / key scratch (16 bytes).
    const std::size_t state_scalars =
        static_cast<std::size_t>(facts.stored_scalars - 3) + (body.algorithm.fbar_nodal() ? 1 : 0);  // + 1 - JBar
    cpu_particle_bytes += static_cast<std::size_t>(count.particles) *
                          ((12 + 18 + 2 + 2 * state_scalars) * particle_scalar_bytes(sim.precision) + 16);
  }

  summary.gpu_ms_per_step += kGpuStepOverheadMs + kGpuBodyOverheadMs * static_cast<double>(summary.bodies.size());
  // The grid channel sets each body's P2G sums into (grid_channels.h); a Volume or JBar grid sensor or field has
  // every body sum its volume into the F-bar sums on the steps it samples.
  const bool node_volume = scene_reads_node_volume(scene);
  const GridFeatures scene_grid{asflip, fbar, pore, node_volume};
  for (std::size_t i = 0; i < summary.bodies.size(); ++i) {
    const BodySpec& body = scene.bodies[i];
    const GridFeatures own{body.algorithm.asflip_active(), body.algorithm.fbar_blend() != 0.0,
                           material_has_pore_fluid(body.material.law), node_volume};
    summary.bodies[i].grid_channels = grid_channels_of_body(own, scene_grid);
  }

  finish_host_run_bytes(summary, checkpoint_kept, checkpoint_transient, sim);

  // CPU grid: the channel sets it keeps (grid_channels.h cpu_grid_channels) x 64 nodes per block in the grid scalar
  // type, coordinates and a hash-map entry.
  const std::size_t cpu_channels = static_cast<std::size_t>(cpu_grid_channels(scene_grid));
  std::vector<const SampleCount*> all;
  for (const SampleCount& c : counts) all.push_back(&c);
  summary.cpu_bytes = cpu_particle_bytes + static_cast<std::size_t>(footprint_blocks(all)) *
                                               (cpu_channels * 64 * grid_scalar_bytes(sim.precision) + 12 + 48);

  // GPU: the engine's own plan (memory_plan.h), per GPU.
  summary.gpu_bytes.assign(max_gpu + 1, 0);
  for (int g = 0; g <= max_gpu; ++g) {
    std::vector<const SampleCount*> on_gpu;
    for (std::size_t i = 0; i < counts.size(); ++i)
      if (std::max(scene.bodies[i].gpu, 0) == g) on_gpu.push_back(&counts[i]);
    summary.gpu_plans.push_back(
        plan_device_memory(sim.precision, footprint_blocks(on_gpu), gpu_inputs[g], node_volume));
    summary.gpu_plans.back().small += sensor_device_bytes(scene) + grid_field_device_bytes(scene);
    summary.gpu_bytes[g] = summary.gpu_plans.back().total();
  }
  return summary;
}

long long scene_work_particles(const Scene& scene, long long cap) {
  long long total = 0;
  for (std::size_t i = 0; i < scene.bodies.size() && total < cap; ++i) {
    const BodySpec& body = scene.bodies[i];
    if (body.mesh >= 0) {
      const TetMeshStats& m = scene.meshes.at(static_cast<std::size_t>(body.mesh)).stats;
      total += static_cast<long long>(m.vertices) + 5 * static_cast<long long>(m.elements);
      continue;
    }
    try {
      const BodySampler sampler(body, scene.simulation, static_cast<int>(i));
      if (sampler.candidates() > 64e6) return std::max(cap, total);
      total += sampler.count(scene.simulation.dx).particles;
    } catch (const std::exception&) {
      return std::max(cap, total);
    }
  }
  return total;
}

RunResult run_guarded(const std::function<RunResult()>& run) {
  RunResult result;
  result.from_exception = true;  // for every return below
  try {
    return run();
  } catch (const SceneError& e) {
    result.exit_code = 1;
    result.message = e.what();
  } catch (const std::invalid_argument& e) {
    result.exit_code = 1;
    result.message = e.what();
  } catch (const std::exception& e) {
    result.exit_code = 2;
    result.message = e.what();
  }
  return result;
}

}  // namespace fbar
