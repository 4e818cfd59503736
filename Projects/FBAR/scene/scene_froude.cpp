// Froude similitude: scales a whole resolved scene by the length factor s = simulation.froude_scaling.
//
// Froude similitude keeps Fr = U / sqrt(g L) fixed with gravity and density unchanged, so with lengths x s:
//   length            x s        domain, default_dx, geometry span / offset / radius / spacing / fulcrum, mesh
//                                vertices and offset,
//                                partition_start / partition_end, boundary domain / spacing / bathymetry points,
//                                sensor domains; a File geometry's scaling_factor (its linear size)
//   time              x s^0.5    simulation.time, default_dt (when given), boundary time windows
//   velocity          x s^0.5    body and mesh initial velocity, boundary velocity
//   frequency         x s^-0.5   fps, sensor and grid-field output_frequency, motion-file output_frequency
//                                (frames is unchanged, so the simulated duration frames / fps scales as s^0.5)
//   mass              x s^3      (no scene key: particle mass follows from rho and the scaled particle volume)
//   stress, modulus   x c        bulk_modulus, youngs_modulus (meshes' too), VonMises strengths (froude_power 1): c = s by
//                                default (Cauchy similitude at equal density, so the elastic wave speed
//                                sqrt(E / rho) scales like a Froude velocity); c = cauchy_bulk_ratio when
//                                use_cauchy_scaling is true (even at s = 1); use_cauchy_scaling false keeps every
//                                material parameter as written (ClaymoreUW's behaviour)
//   dynamic viscosity x c s^0.5  stress x time (s^1.5 by default)
//   unchanged                    density, gravity, dimensionless parameters (gamma, poisson_ratio, CFL, ppc,
//                                friction angles and coefficients, cohesion (a log-strain), logJp0, beta, xi,
//                                ASFLIP / F-bar ratios), angles (rotate), counts (frames, array, info_rate)
// A geometry entry with use_froude_scaling false keeps its lengths as written (ClaymoreUW uses this for particle
// files that were produced at the target scale already). Motion-file contents are scaled by their loader
// (positions x s, times and velocities x s^0.5) from simulation.froude_scaling.
#include <cmath>
#include <memory>
#include <sstream>

#include "scene/scene_parse.h"

#include "physics/constitutive_models.cuh"
#include "scene/scene_error.h"

namespace fbar {

namespace {

void scale3(Real3& v, double k) {
  for (double& c : v) c *= k;  // infinity (an open partition bound) stays infinite
}

}  // namespace

void apply_froude_scaling(Scene& scene) {
  SimulationSpec& sim = scene.simulation;
  const double s = sim.froude_scaling;
  // The stress ratio c of the materials (SimulationSpec::cauchy_scaling); 0: leave them as written.
  const double c = sim.cauchy_scaling == CauchyScaling::Off  ? 0.0
                   : sim.cauchy_scaling == CauchyScaling::On ? sim.cauchy_bulk_ratio
                                                             : s;
  if (sim.froude_scaling_applied || (s == 1.0 && (c == 1.0 || c == 0.0))) return;  // identity: nothing to record
  sim.froude_scaling_applied = true;
  const double length = s;
  const double time = std::sqrt(s);
  const double velocity = std::sqrt(s);
  const double frequency = 1.0 / std::sqrt(s);

  scale3(sim.domain, length);
  sim.dx *= length;
  sim.default_dt *= time;  // 0 (absent) stays 0 and is resolved to dx / 100 afterwards
  sim.time *= time;
  sim.fps *= frequency;

  for (BodySpec& b : scene.bodies) {
    scale3(b.velocity, velocity);
    scale3(b.partition_start, length);
    scale3(b.partition_end, length);
    // Only the parameters the law reads (MaterialParameter::froude_power: stress 1, viscosity 1.5), stresses by c
    // and viscosities by c s^0.5: the others keep their defaults (the written scene omits them).
    if (c > 0.0)
      for_each_material_parameter(b.material.law, [&](const MaterialParameter& p) {
        if (!p.is_flag() && p.froude_power != 0.0) b.material.*(p.number) *= c * std::pow(s, p.froude_power - 1.0);
      });
    for (GeometrySpec& g : b.geometry) {
      if (!g.use_froude_scaling) continue;
      scale3(g.offset, length);
      scale3(g.spacing, length);
      scale3(g.fulcrum, length);
      switch (g.object) {  // shape sizes the object uses
        case GeometryObject::Box: scale3(g.span, length); break;
        case GeometryObject::Sphere: g.radius *= length; break;
        case GeometryObject::Cylinder:
          scale3(g.span, length);
          g.radius *= length;
          break;
        case GeometryObject::File: g.scaling_factor *= length; break;
        case GeometryObject::Bathymetry:
        case GeometryObject::OsuLwf:
        case GeometryObject::OsuTwb:
          scale3(g.span, length);  // a facility's own bed is scaled where it is placed (geometry.cpp)
          for (auto& p : g.bathymetry) {
            p[0] *= length;
            p[1] *= length;
          }
          break;
      }
    }
  }
  // FEM meshes like bodies: the vertices (placed at offset) and the offset as lengths, the velocity, the elements'
  // Young's modulus as a stress (ClaymoreUW scales none of them).
  for (MeshEntrySpec& m : scene.meshes) {
    scale3(m.offset, length);
    scale3(m.velocity, velocity);
    if (c > 0.0) m.youngs_modulus *= c;
    if (m.mesh) {
      // The file's vertices x s + the scaled offset: the operations a re-read of the written scene does, so both
      // give the same bits (read_mesh_entry). A mesh built in code without its file's copy is scaled as placed.
      const Vec3d offset{{m.offset[0], m.offset[1], m.offset[2]}};
      TetMesh unplaced = m.file_mesh ? *m.file_mesh : *m.mesh;
      for (Vec3d& x : unplaced.vertices) x *= length;
      m.stats = check_tet_mesh(unplaced, "meshes[]");  // what the re-read measures: the scaled file mesh
      m.summary = describe(m.stats);
      TetMesh placed = unplaced;
      if (m.file_mesh)
        for (Vec3d& x : placed.vertices) x += offset;
      m.mesh = std::make_shared<const TetMesh>(std::move(placed));
    }
  }
  bool mesh_bodies = false;  // appended already (a scene built in code): their keys come from the entries again
  for (const BodySpec& b : scene.bodies) mesh_bodies = mesh_bodies || b.mesh >= 0;
  if (mesh_bodies) append_mesh_bodies(scene);
  for (BoundarySpec& b : scene.boundaries) {
    scale3(b.domain_start, length);
    scale3(b.domain_end, length);
    scale3(b.spacing, length);
    scale3(b.velocity, velocity);
    scale3(b.rotation_center, length);
    scale3(b.angular_velocity, frequency);
    for (double& t : b.time) t *= time;
    b.output_frequency *= frequency;
    for (auto& p : b.bathymetry) {
      p[0] *= length;
      p[1] *= length;
    }
  }
  for (GridSensorSpec& g : scene.grid_sensors) {
    scale3(g.domain_start, length);
    scale3(g.domain_end, length);
    g.output_frequency *= frequency;
  }
  for (ParticleSensorSpec& p : scene.particle_sensors) {
    scale3(p.domain_start, length);
    scale3(p.domain_end, length);
    p.output_frequency *= frequency;
  }
  for (GridFieldSpec& f : scene.grid_fields) {
    scale3(f.domain_start, length);
    scale3(f.domain_end, length);
    f.output_frequency *= frequency;
  }
}

}  // namespace fbar
