// Prints the resolved scene with units, particle counts, time steps and memory estimates (`fbar --check`).
#include "engine/check_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <string>

#include "MnSystem/IO/frame_size.h"
#include "engine/memory_plan.h"
#include "io/grid_field_recorder.h"
#include "io/particle_frame.h"
#include "scene/scene_parse.h"

#include "physics/constitutive_models.cuh"

namespace fbar {

namespace {

std::string num(double x) {
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  std::ostringstream os;
  os << std::setprecision(10) << x;
  return os.str();
}
template <std::size_t N>
std::string vec(const std::array<double, N>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < N; ++i) s += (i ? ", " : "") + num(v[i]);
  return s + "]";
}
std::string ivec(const Int3& v) {
  return "[" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) + "]";
}
std::string list(const std::vector<std::string>& v) {
  if (v.empty()) return "(none)";
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + v[i];
  return s;
}
std::string bytes(std::size_t b) { return format_bytes(static_cast<double>(b)); }
const char* yes_no(bool b) { return b ? "true" : "false"; }

void row(std::ostream& os, const std::string& key, const std::string& value) {
  os << "  " << std::left << std::setw(32) << key << value << '\n';
}

std::string material_line(const MaterialSpec& m) {
  std::string s = std::string(to_string(m.law)) + " (" + m.type + "): ppc " + num(m.ppc) + ", CFL " + num(m.cfl) +
                  ", rho " + num(m.rho) + " kg/m^3";
  for_each_material_parameter(m.law, [&](const MaterialParameter& p) {
    s += std::string(", ") + p.key + " ";
    if (p.is_flag())
      s += yes_no(m.*(p.flag));
    else if (!std::isfinite(m.*(p.number)))
      s += "none";  // an absent optional parameter (tension_cutoff)
    else
      s += num(m.*(p.number)) + (std::string_view(p.unit) == "-" ? "" : std::string(" ") + p.unit);
  });
  return s;
}

/// A mesh's rows of its body's section (the rest is the body's).
void print_mesh_rows(std::ostream& os, const BodySummary& bs) {
  row(os, "mesh", std::to_string(bs.particles) + " vertices, " + std::to_string(bs.elements) +
                      " tetrahedra, smallest quality " + num(bs.min_quality) + ", smallest height " +
                      num(bs.min_height) + " m; elements " + bytes(bs.gpu_mesh_bytes) + " on its GPU, " +
                      bytes(bs.mesh_bytes) + " on the CPU engine, besides the vertices");
}

/// Whether several GPUs pay for the scene (kMultiGpuMinParticles; scene_work_particles' measure: a mesh element
/// counts as 5 particles).
void print_gpu_ranks_row(std::ostream& os, const SceneSummary& summary) {
  long long work = 0;
  for (const BodySummary& bs : summary.bodies) work += bs.particles + (bs.mesh ? 5 * bs.elements : 0);
  const std::string limit = std::to_string(kMultiGpuMinParticles);
  row(os, "GPU ranks",
      work < kMultiGpuMinParticles
          ? "one: below " + limit + " particles one GPU steps faster than several (" + std::to_string(work) +
                " here); fbar --gpus=N runs it on one GPU unless bodies are placed (--keep-gpus keeps N), and "
                "under mpirun one rank is fastest"
          : "several pay from " + limit + " particles (" + std::to_string(work) + " here)");
}

std::string algorithm_line(const AlgorithmSpec& a) {
  const bool asflip = a.asflip_active();
  const bool fbar = a.fbar_blend() != 0.0;
  // The scheme that runs (transfer.cuh): beta > 0 is ASFLIP, alpha = 1 without beta FLIP, 0 < alpha < 1 the blend.
  const bool beta = a.asflip_beta_min != 0.0 || a.asflip_beta_max != 0.0;
  std::string s = !asflip ? "APIC" : beta ? "ASFLIP" : a.asflip_alpha == 1.0 ? "FLIP" : "PIC-FLIP";
  if (fbar) s += a.fbar_nodal() ? (a.fbar_fused_kernel ? " + nodal F-bar (fused)" : " + nodal F-bar (split)")
                                : " + F-bar";
  if (a.use_fem) s += " + FEM";
  return s + " (use_ASFLIP " + yes_no(a.use_asflip) + ", ASFLIP_alpha " + num(a.asflip_alpha) + ", ASFLIP_beta " +
         num(a.asflip_beta_min) + ".." + num(a.asflip_beta_max) + ", use_FBAR " + yes_no(a.use_fbar) + ", FBAR_psi " +
         num(a.fbar_psi) + ", FBAR_fused_kernel " + yes_no(a.fbar_fused_kernel) +
         ", FBAR_scheme " + (a.fbar_scheme == FbarScheme::Nodal ? "nodal" : "cell") + ", use_FEM " + yes_no(a.use_fem) + ")";
}

std::string geometry_line(const GeometrySpec& g) {
  std::string s = std::string(to_string(g.operation)) + " " + to_string(g.object) + ":";
  switch (g.object) {
    case GeometryObject::Box: s += " span " + vec(g.span) + " m,"; break;
    case GeometryObject::Sphere: s += " radius " + num(g.radius) + " m,"; break;
    case GeometryObject::Cylinder:
      s += " radius " + num(g.radius) + " m, length " + num(g.span[g.axis]) + " m along " + axis_name(g.axis) + ",";
      break;
    case GeometryObject::File:
      s += " file " + g.file + ", padding " + std::to_string(g.padding) + ", scaling_factor " + num(g.scaling_factor) + ",";
      break;
    case GeometryObject::Bathymetry:
    case GeometryObject::OsuLwf:
    case GeometryObject::OsuTwb:
      s += " span " + vec(g.span) + " m above " +
           (g.bathymetry.empty() ? std::string("the facility's bed")
                                 : std::to_string(g.bathymetry.size()) + " bed points") + ",";
      break;
  }
  s += " offset " + vec(g.offset) + " m";
  if (g.rotate != Real3{0.0, 0.0, 0.0}) s += ", rotate " + vec(g.rotate) + " deg about " + vec(g.fulcrum) + " m";
  if (g.array != Int3{1, 1, 1}) s += ", array " + ivec(g.array) + " spaced " + vec(g.spacing) + " m";
  if (!g.use_froude_scaling) s += ", not Froude-scaled";
  return s;
}

/// "1.2 MiB (1258291 B)": bytes on disk, the exact figure too (the text formats' figures are estimates all the same).
std::string disk(double b) {
  return format_bytes(b) + " (" + std::to_string(static_cast<long long>(std::llround(b))) + " B)";
}

/// One frame file of body `body` holding all its particles, in the scene's save_suffix: the attributes of
/// output_attribs as the engines write them (ID int32, the rest float32 of width 1), positions in the run's precision.
io::FrameFileSize body_frame_size(const Scene& scene, int body, long long particles) {
  io::FrameLayout layout;
  layout.double_positions = scene.simulation.precision != Precision::Single;
  for (const FrameAttributeSpec& a : frame_attributes(scene.bodies[static_cast<std::size_t>(body)], body, "engines"))
    layout.attributes.push_back({a.name, 1, a.column.quantity == FrameQuantity::Id, a.unit});
  return io::frame_file_size(io::frame_format(scene.simulation.save_suffix),
                             static_cast<std::size_t>(std::max<long long>(particles, 0)), layout);
}

bool exterior_only(const Scene& scene, int body) {
  return scene.simulation.particles_output_exterior_only ||
         scene.bodies[static_cast<std::size_t>(body)].output_exterior_only;
}

/// The report's boundaries[], grid-sensors[] and particle-sensors[] sections.
void print_boundaries_and_sensors(std::ostream& os, const Scene& scene) {
  for (std::size_t i = 0; i < scene.boundaries.size(); ++i) {
    const BoundarySpec& b = scene.boundaries[i];
    os << "boundaries[" << i << "]  " << to_string(b.object) << ", " << to_string(b.contact) << '\n';
    row(os, "domain", vec(b.domain_start) + " .. " + vec(b.domain_end) + " m");
    row(os, "time", "[" + num(b.time[0]) + ", " + num(b.time[1]) + ") s");
    row(os, "friction", "static " + num(b.friction_static) + ", dynamic " + num(b.friction_dynamic));
    if (b.file.empty()) row(os, "velocity", vec(b.velocity) + " m/s");
    else row(os, "motion file", b.file + " sampled at " + num(b.output_frequency) + " Hz");
    if (b.angular_velocity != Real3{0.0, 0.0, 0.0})
      row(os, "rotation", vec(b.angular_velocity) + " rad/s about " + vec(b.rotation_center) + " m (at time[0])");
    if (b.array != Int3{1, 1, 1}) row(os, "array", ivec(b.array) + " spaced " + vec(b.spacing) + " m");
    if (!b.bathymetry.empty()) row(os, "bathymetry", std::to_string(b.bathymetry.size()) + " points");
  }
  if (scene.boundaries.empty()) os << "boundaries  none (particles leaving the domain are reported)\n";
  for (std::size_t i = 0; i < scene.grid_sensors.size(); ++i) {
    const GridSensorSpec& g = scene.grid_sensors[i];
    os << "grid-sensors[" << i << "]  " << (g.name.empty() ? "" : "\"" + g.name + "\": ") << to_string(g.operation)
       << " of " << g.attribute << " along " << vec(g.direction)
       << (g.direction_sign > 0 ? " (positive part)" : g.direction_sign < 0 ? " (negative part)" : "") << " at "
       << num(g.output_frequency) << " Hz in " << vec(g.domain_start) << " .. " << vec(g.domain_end) << " m"
       << (g.toggle ? " -> gridTarget[" + std::to_string(i) + "]_dev[0].csv" : " (off)") << "\n";
  }
  for (std::size_t i = 0; i < scene.grid_fields.size(); ++i) {
    const GridFieldSpec& f = scene.grid_fields[i];
    std::string attributes;
    for (const std::string& a : f.attributes) attributes += (attributes.empty() ? "" : ", ") + a;
    os << "grid-fields[" << i << "]  " << (f.name.empty() ? "" : "\"" + f.name + "\": ") << attributes
       << (f.blocks ? " per grid block" : " per node") << " at " << num(f.output_frequency) << " Hz in "
       << vec(f.domain_start) << " .. " << vec(f.domain_end) << " m"
       << (f.toggle ? " -> " + grid_field_file_name(i, 0, scene.simulation.save_suffix) + ", ..." : " (off)") << "\n";
  }
  for (std::size_t i = 0; i < scene.particle_sensors.size(); ++i) {
    const ParticleSensorSpec& p = scene.particle_sensors[i];
    os << "particle-sensors[" << i << "]  " << (p.name.empty() ? "" : "\"" + p.name + "\": ")
       << to_string(p.operation) << " of " << p.attribute << " at " << num(p.output_frequency) << " Hz in "
       << vec(p.domain_start) << " .. " << vec(p.domain_end) << " m"
       << (p.toggle ? " -> particleTarget[" + std::to_string(i) + "]_model[m]_dev[0].csv per body" : " (off)") << "\n";
  }
}

/// The GPU engine's host memory: the set-up's, and the whole run's (engine_api.cpp host_frame_bytes,
/// host_checkpoint_bytes).
void print_host_memory_rows(std::ostream& os, const SceneSummary& summary) {
  row(os, "host memory (set-up)", bytes(summary.host_setup_bytes) +
                                      " at most while sampling (bodies are sampled and uploaded in batches)");
  long long particles = 0;
  for (const BodySummary& b : summary.bodies) particles += b.particles;
  std::ostringstream per;
  per << std::fixed << std::setprecision(0)
      << static_cast<double>(summary.host_checkpoint_bytes) / static_cast<double>(std::max<long long>(1, particles));
  const std::string checkpoint =
      bytes(summary.host_checkpoint_bytes) + " while it is taken and written (" +
      (summary.host_checkpoint_streamed
           ? std::string("bodies above --frame-buffer are read from the device a range of IDs at a time, and the "
                         "run waits for the file)")
           : per.str() + " B per particle: every particle's state is copied to the host)");
  row(os, "host memory (run)",
      bytes(summary.host_run_bytes) + " at most on the GPU engine: " + bytes(kHostProgramBytes) +
          " program and CUDA runtime + the larger of the set-up (above: given back before the first frame) and "
          "frames " +
          bytes(summary.host_frame_pinned_bytes + summary.host_frame_writer_bytes) + " (pinned download buffers " +
          bytes(summary.host_frame_pinned_bytes) + ", frames above --frame-buffer stream a piece at a time; the "
          "writer " + bytes(summary.host_frame_writer_bytes) + ")" +
          (summary.checkpoints ? " + a checkpoint " + checkpoint
                               : "; a checkpoint on SIGTERM or a failure adds " + checkpoint));
}

}  // namespace

void print_scene_report(std::ostream& os, const Scene& scene, const SceneSummary& summary) {
  const SimulationSpec& s = scene.simulation;
  os << "simulation\n";
  row(os, "domain", vec(s.domain) + " m");
  row(os, "default_dx", num(s.dx) + " m");
  row(os, "default_dt", num(s.default_dt) + " s");
  row(os, "gravity", vec(s.gravity) + " m/s^2");
  row(os, "time", num(s.time) + " s");
  row(os, "fps", num(s.fps) + " 1/s");
  row(os, "frames", std::to_string(s.frames) + " (simulated time " + num(s.time) + " .. " +
                        num(s.time + s.frames / s.fps) + " s)");
  row(os, "save_path", s.save_path);
  row(os, "save_suffix", s.save_suffix);
  row(os, "particles_output_exterior_only", yes_no(s.particles_output_exterior_only));
  row(os, "froude_scaling", num(s.froude_scaling) + (s.froude_scaling != 1.0 ? " (applied to every value shown)" : ""));
  row(os, "info_rate", std::to_string(s.info_rate) + " steps" + (s.info_rate == 0 ? " (log once per frame)" : ""));
  row(os, "checkpoint_every", std::to_string(s.checkpoint_every) + " frames" +
                                  (s.checkpoint_every == 0 ? " (checkpoints only when a run stops early)" : ""));
  row(os, "precision", to_string(s.precision));
  row(os, "on_failure", to_string(s.on_failure));
  row(os, "seed", std::to_string(s.seed));

  long long total = 0;
  double frame_bytes = 0.0, frame_headers = 0.0;  // one frame of every body, one file each
  bool frame_exact = true, frame_at_most = false;
  for (std::size_t i = 0; i < scene.bodies.size(); ++i) {
    const BodySpec& b = scene.bodies[i];
    if (b.mesh >= 0)
      os << "meshes[" << b.mesh << "] (body " << i << ")  gpu " << b.gpu << ", model " << b.model << ": "
         << scene.meshes[static_cast<std::size_t>(b.mesh)].summary << '\n';
    else
      os << "bodies[" << i << "]  gpu " << (b.gpu == kAllGpus ? std::string("all") : std::to_string(b.gpu))
         << ", model " << b.model << '\n';
    row(os, "material", material_line(b.material));
    if (b.mesh >= 0) {
      const MeshEntrySpec& m = scene.meshes[static_cast<std::size_t>(b.mesh)];
      row(os, "algorithm", "vertices " + algorithm_line(b.algorithm) + "; elements: use_FBAR " +
                               yes_no(m.fbar_elements) +
                               (m.fbar_elements ? ", FBAR_ratio " + num(m.fbar_ratio) : std::string()));
    } else {
      row(os, "algorithm", algorithm_line(b.algorithm));
    }
    row(os, "velocity", vec(b.velocity) + " m/s");
    if (b.initial_state == InitialState::Hydrostatic)
      row(os, "initial_state", material_has_pore_fluid(b.material.law)
                                   ? "hydrostatic: the pore water carries rho g (depth below the top of the geometry)"
                                   : "hydrostatic: J p = rho g (depth below the top of the geometry)");
    row(os, "partition", vec(b.partition_start) + " .. " + vec(b.partition_end) + " m");
    for (std::size_t j = 0; j < b.geometry.size(); ++j)
      row(os, "geometry[" + std::to_string(j) + "]", geometry_line(b.geometry[j]));
    row(os, "output_attribs", list(b.output_attribs));
    if (!b.track_particle_id.empty() || !b.track_attribs.empty())
      row(os, "track", std::to_string(b.track_particle_id.size()) + " particle(s): " + list(b.track_attribs));
    if (!b.target_attribs.empty()) row(os, "target_attribs", list(b.target_attribs));
    if (i < summary.bodies.size()) {
      const BodySummary& bs = summary.bodies[i];
      total += bs.particles;
      if (bs.mesh) print_mesh_rows(os, bs);
      row(os, "particles", std::to_string(bs.particles) + (bs.mesh ? " vertices" : "") + " (volume " +
                               num(bs.particle_volume) + " m^3, mass " + num(bs.particle_mass) + " kg each" +
                               (bs.mesh ? " on average: the lumped element volumes" : "") + ")");
      row(os, "p-wave speed", num(bs.wave_speed) + " m/s");
      row(os, "time step bound",
          num(bs.dt_bound) + " s (min(CFL x dx / (wave speed + |velocity|), 0.5 x dx / wave speed" +
              (bs.mesh ? ", CFL x smallest element height / wave speed" : "") + "))");
      if (std::isfinite(bs.viscous_dt))
        row(os, "viscous bound", num(bs.viscous_dt) + " s (CFL x rho x dx^2 / (3 x viscosity), explicit viscosity)");
      if (std::isfinite(bs.seepage_dt))
        row(os, "seepage bound",
            num(bs.seepage_dt) + " s (CFL x dx^2 / (8 x kappa x M), explicit seepage; kappa = Kperm / (rhow g0), "
                                 "1/M = poro/Kf + (alpha1 - poro)/Ks)");
      {
        row(os, "GPU per particle", std::to_string(bs.gpu_bytes_per_particle) + " B: " + bs.gpu_bytes_detail);
        char cost[160];
        std::snprintf(cost, sizeof(cost), "%.3g ms per step on an %s (measured %s: %.3g particle-steps/s: ",
                      bs.gpu_ms_per_step, kGpuRateDevice, kGpuRateDate, bs.throughput);
        row(os, "GPU time", cost + bs.throughput_basis + ")");
      }
      row(os, "grid channels", bs.grid_channels);
      const int body = static_cast<int>(i);
      const io::FrameFileSize f = body_frame_size(scene, body, bs.particles);
      frame_bytes += f.bytes;
      frame_headers += f.headers;
      frame_exact = frame_exact && f.exact;
      const bool at_most = exterior_only(scene, body);
      frame_at_most = frame_at_most || at_most;
      char per[64];
      std::snprintf(per, sizeof(per), "%.4g", bs.particles > 0 ? f.data / static_cast<double>(bs.particles) : 0.0);
      row(os, "frame on disk",
          std::string(at_most ? "at most " : f.exact ? "" : "about ") + disk(f.bytes) +
              " per frame as " + s.save_suffix + " (" + std::to_string(bs.particles) + " particles x " + per +
              " B + " + std::to_string(std::llround(f.headers)) + " B of headers per file" +
              (at_most ? "; exterior_only writes fewer" : "") + ")");
    }
  }

  print_boundaries_and_sensors(os, scene);

  os << "summary\n";
  row(os, "particles", std::to_string(total) + " in " + std::to_string(scene.bodies.size()) + " body(ies)");
  print_gpu_ranks_row(os, summary);
  row(os, "time step", num(summary.dt) + " s (min of default_dt and every body's bounds)");
  const double steps_per_frame = summary.dt > 0.0 ? std::ceil(1.0 / (s.fps * summary.dt)) : 0.0;
  row(os, "steps", "about " + num(steps_per_frame) + " per frame, " + num(steps_per_frame * s.frames) + " in all");
  {
    char cost[256];
    const double per_simulated_s = summary.dt > 0.0 ? 1e-3 * summary.gpu_ms_per_step / summary.dt : 0.0;
    std::snprintf(cost, sizeof(cost),
                  "about %.3g ms per step on one %s (%.2g ms + %.2g ms per body + the bodies' particles), %.3g s "
                  "per simulated second at this time step (%s)",
                  summary.gpu_ms_per_step, kGpuRateDevice, kGpuStepOverheadMs, kGpuBodyOverheadMs, per_simulated_s,
                  kGpuRateRecord);
    row(os, "GPU time", cost);
  }
  {
    // Frames 0..frames are written (frame 0: the initial state); several ranks write a file each per body and frame.
    const double frames = static_cast<double>(s.frames) + 1.0;
    const std::string how = frame_at_most ? "at most " : frame_exact ? "" : "about ";
    row(os, "disk per frame",
        how + disk(frame_bytes) + " in " + s.save_suffix + " (every body, one file each; " +
            "a run on several ranks adds each further file's headers, " +
            std::to_string(std::llround(frame_headers)) + " B per rank and frame at most)");
    row(os, "disk for frames", how + bytes(static_cast<std::size_t>(frame_bytes * frames)) + " for the " +
                                   num(frames) + " frames 0.." + std::to_string(s.frames) + " in " + s.save_path +
                                   (s.save_suffix == ".h5" ? " (and frames.xdmf, the time series)" : ""));
  }
  row(os, "memory (CPU engine)", bytes(summary.cpu_bytes));
  for (std::size_t g = 0; g < summary.gpu_plans.size(); ++g) {
    const DeviceMemoryPlan& p = summary.gpu_plans[g];
    const std::string gpu = "GPU " + std::to_string(g);
    const double n = static_cast<double>(std::max<long long>(1, p.total_particles()));
    std::ostringstream per;
    per << std::fixed << std::setprecision(1) << static_cast<double>(p.total()) / n << " B per particle";
    row(os, "memory (" + gpu + ")",
        bytes(p.total()) + " for the whole run (" + per.str() + "; + about " + bytes(kCudaContextBytes) +
            " CUDA context): particles " + bytes(p.particles_bytes) + ", partition " + bytes(p.partition) + ", grid " +
            bytes(p.grid) + " (" + std::to_string(p.block_capacity) + " blocks of capacity for " +
            std::to_string(p.footprint_blocks) + " at start), frames " + bytes(p.frames) +
            (p.meshes > 0 ? ", mesh elements " + bytes(p.meshes) : std::string()));
    row(os, "growth (" + gpu + ")",
        "+" + bytes(p.grid_growth) + " if the active grid outgrows its capacity (blocks x2), +" +
            bytes(p.bins_growth) + " if the particle bins do (x1.5); logged when it happens");
  }
  print_host_memory_rows(os, summary);
  row(os, "limits (per GPU)", std::to_string(DeviceLimits::kMaxSlots) + " particle slots per body (particles and the "
                              "empty lanes of partly filled bins of 32), " + std::to_string(DeviceLimits::kMaxBlocks) +
                              " grid blocks, " + std::to_string(DeviceLimits::kMaxBodies) + " bodies");
  for (const std::string& line : summary.device_notes) row(os, "device", line);
}

}  // namespace fbar
