// The CPU engine's output (cpu_engine.h): frames, sensors and trackers, particle access for tests, totals and
// memory.
#include "engine/cpu/cpu_engine.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "MnBase/Math/bspline.h"
#include "comm/placement.h"
#include "scene/attributes.h"
#include "geometry/geometry.h"
#include "physics/grid_update.cuh"
#include "engine/hydrostatic.h"
#include "io/particle_frame.h"
#include "settings.h"
#include "physics/time_step.cuh"
#include "io/sensor_recorder.h"
#include "scene/scene_parse.h"
#include "physics/transfer.cuh"
#include "engine/cpu/cpu_engine_detail.h"

namespace fbar {

using namespace cpu_detail;

template <typename T, typename TG>
void CpuEngine<T, TG>::submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer) {
  io::ParticleFrame f = frame(body);
  f.exterior = exterior_filter(scene_, body);
  if (const int m = body_at(body).spec.mesh; m >= 0) {  // with the elements: a .vtk beside the frame (particle_io.h)
    const std::shared_ptr<const TetMesh>& mesh = scene_.meshes[static_cast<std::size_t>(m)].mesh;
    f.tetrahedra = std::shared_ptr<const std::vector<std::array<int, 4>>>(mesh, &mesh->elements);
  }
  const auto t0 = std::chrono::steady_clock::now();
  writer.submit(path, std::move(f));
  output_wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_grid_sensors(const std::vector<GridSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(GridSensorSet<TG>::kMax))
    throw std::invalid_argument("grid-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(GridSensorSet<TG>::kMax) + " per run");
  grid_sensors_ = GridSensorSet<TG>{};
  for (const GridSensorSpec& spec : sensors)
    grid_sensors_.s[grid_sensors_.count++] = make_grid_sensor_params<TG>(spec, static_cast<double>(k_.dx));
  node_volume_ = false;
  for (int i = 0; i < grid_sensors_.count; ++i)
    node_volume_ = node_volume_ || grid_sensor_reads_volume(grid_sensors_.s[i].quantity);
  grid_samples_.clear();
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_grid_fields(const std::vector<GridFieldSpec>& fields) {
  if (fields.size() > static_cast<std::size_t>(GridFieldSet<TG>::kMax))
    throw std::invalid_argument("grid-fields: " + std::to_string(fields.size()) + " enabled fields; at most " +
                                std::to_string(GridFieldSet<TG>::kMax) + " per run");
  grid_fields_ = GridFieldSet<TG>{};
  for (const GridFieldSpec& spec : fields)
    grid_fields_.f[grid_fields_.count++] = make_grid_field_params<TG>(spec, static_cast<double>(k_.dx));
  field_samples_.assign(fields.size(), GridFieldSample{});
}

template <typename T, typename TG>
GridFieldSample CpuEngine<T, TG>::grid_field_sample(int field) const {
  if (field < 0 || field >= static_cast<int>(field_samples_.size()))
    throw std::logic_error("CpuEngine::grid_field_sample: no grid field " + std::to_string(field));
  return field_samples_[static_cast<std::size_t>(field)];
}

template <typename T, typename TG>
std::vector<SensorAccum> CpuEngine<T, TG>::grid_samples(int slots) const {
  const std::size_t n = static_cast<std::size_t>(slots) * grid_sensors_.count;
  if (grid_samples_.size() < n) throw std::logic_error("CpuEngine::grid_samples: fewer slots were sampled");
  return std::vector<SensorAccum>(grid_samples_.begin(), grid_samples_.begin() + static_cast<std::ptrdiff_t>(n));
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors) {
  if (sensors.size() > static_cast<std::size_t>(ParticleSensorSet<T>::kMax))
    throw std::invalid_argument("particle-sensors: " + std::to_string(sensors.size()) + " enabled sensors; at most " +
                                std::to_string(ParticleSensorSet<T>::kMax) + " per run");
  particle_sensors_ = ParticleSensorSet<T>{};
  for (const ParticleSensorSpec& spec : sensors)
    particle_sensors_.s[particle_sensors_.count++] = make_particle_sensor_params<T>(spec);
  particle_samples_.clear();
}

template <typename T, typename TG>
template <class Accept, class Fn>
void CpuEngine<T, TG>::each_particle_input(const Body& b, bool sigma, const Accept& accept, const Fn& fn) const {
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < b.x.size(); ++p)  // slot order: a fixed order on each rank
          if (accept(p))
            fn(p, particle_frame_inputs<M, T>(b.x[p], b.v[p], b.C[p], mb.state[p], mb.params, b.mass[p], b.volume[p],
                                              sigma, b.fbar_nodal, b.fbar_nodal ? b.jbar[p] : T(0)));
      },
      b.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::sample_particles(int slot) {
  const int n = particle_sensors_.count;
  if (n == 0) return;
  const std::size_t first = static_cast<std::size_t>(slot) * bodies_.size() * n;
  if (particle_samples_.size() < first + bodies_.size() * n) particle_samples_.resize(first + bodies_.size() * n);
  bool sigma = false;
  for (int i = 0; i < n; ++i) sigma = sigma || frame_quantity_reads_stress(particle_sensors_.s[i].column.quantity);
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    SensorAccum* acc = &particle_samples_[first + b * n];
    for (int i = 0; i < n; ++i) acc[i] = SensorAccum{};
    const Body& body = bodies_[b];
    auto in_some_box = [&](std::size_t p) {
      for (int i = 0; i < n; ++i)
        if (sensor_box_contains(particle_sensors_.s[i].lo, particle_sensors_.s[i].hi, body.x[p])) return true;
      return false;
    };
    each_particle_input(body, sigma, in_some_box, [&](std::size_t, const FrameInputs<T>& in) {
      for (int i = 0; i < n; ++i) {
        const ParticleSensorParams<T>& s = particle_sensors_.s[i];
        if (sensor_box_contains(s.lo, s.hi, in.x)) acc[i].add(static_cast<double>(frame_value(s.column, in)));
      }
    });
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_tracker(int body, const TrackerSet& set) {
  body_at(body);
  trackers_.resize(bodies_.size());
  trackers_[body] = set;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::track(int body, std::vector<double>& values, std::vector<double>& present) const {
  const Body& b = body_at(body);
  const TrackerSet empty{};
  const TrackerSet& t = static_cast<std::size_t>(body) < trackers_.size() ? trackers_[body] : empty;
  values.assign(static_cast<std::size_t>(t.ids) * t.attribs, 0.0);
  present.assign(t.ids, 0.0);
  if (t.ids == 0) return;
  auto index = [&](std::size_t p) {
    return b.id[p] <= std::numeric_limits<int>::max() ? tracker_index(t, static_cast<int>(b.id[p])) : -1;
  };
  // Only the tracked particles' inputs are computed (a few of a whole body).
  each_particle_input(b, true, [&](std::size_t p) { return index(p) >= 0; },
                      [&](std::size_t p, const FrameInputs<T>& in) {
                        const int i = index(p);
                        present[i] = 1.0;
                        for (int a = 0; a < t.attribs; ++a)
                          values[static_cast<std::size_t>(i) * t.attribs + a] =
                              static_cast<double>(frame_value(t.column[a], in));
                      });
}

template <typename T, typename TG>
std::vector<SensorAccum> CpuEngine<T, TG>::particle_samples(int slots) const {
  const std::size_t n = static_cast<std::size_t>(slots) * bodies_.size() * particle_sensors_.count;
  if (particle_samples_.size() < n) throw std::logic_error("CpuEngine::particle_samples: fewer slots were sampled");
  return std::vector<SensorAccum>(particle_samples_.begin(), particle_samples_.begin() + static_cast<std::ptrdiff_t>(n));
}

template <typename T, typename TG>
std::string CpuEngine<T, TG>::resource_note() const {
  std::string note = std::to_string(omp_get_max_threads()) + " threads";
  if (ranks() > 1)
    note += "; " + std::to_string(ranks()) + " ranks, rank " + std::to_string(rank()) + " holds " +
            std::to_string(particle_count()) + " particles, imbalance " + format_g(100.0 * imbalance_) + " %, " +
            std::to_string(migrated_) + " migrated from it, " + std::to_string(rebalances_) + " rebalances";
  return note;
}

// ---------------------------------------------------------------------------------------------
// Particle access

template <typename T, typename TG>
const typename CpuEngine<T, TG>::Body& CpuEngine<T, TG>::body_at(int body) const {
  if (body < 0 || body >= body_count()) throw std::out_of_range("CpuEngine: no body " + std::to_string(body));
  return bodies_[body];
}
template <typename T, typename TG>
typename CpuEngine<T, TG>::Body& CpuEngine<T, TG>::body_at(int body) {
  if (body < 0 || body >= body_count()) throw std::out_of_range("CpuEngine: no body " + std::to_string(body));
  return bodies_[body];
}

template <typename T, typename TG>
std::size_t CpuEngine<T, TG>::particle_count(int body) const {
  return body_at(body).x.size();
}
template <typename T, typename TG>
std::size_t CpuEngine<T, TG>::particle_count() const {
  std::size_t n = 0;
  for (const Body& b : bodies_) n += b.x.size();
  return n;
}
template <typename T, typename TG>
Constitutive CpuEngine<T, TG>::law(int body) const {
  return body_at(body).spec.material.law;
}
template <typename T, typename TG>
const std::vector<std::int64_t>& CpuEngine<T, TG>::ids(int body) const {
  return body_at(body).id;
}
template <typename T, typename TG>
const std::vector<Vec3<T>>& CpuEngine<T, TG>::positions(int body) const {
  return body_at(body).x;
}
template <typename T, typename TG>
const std::vector<Vec3<T>>& CpuEngine<T, TG>::velocities(int body) const {
  return body_at(body).v;
}
template <typename T, typename TG>
const std::vector<Mat3<T>>& CpuEngine<T, TG>::affine(int body) const {
  return body_at(body).C;
}
template <typename T, typename TG>
const std::vector<T>& CpuEngine<T, TG>::masses(int body) const {
  return body_at(body).mass;
}
template <typename T, typename TG>
const std::vector<T>& CpuEngine<T, TG>::volumes(int body) const {
  return body_at(body).volume;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::volume_ratios(int body) const {
  const Body& b = body_at(body);
  std::vector<T> J(b.x.size());
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < J.size(); ++p) J[p] = M::volume_ratio(mb.state[p]);
      },
      b.material);
  return J;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::jbar_ratios(int body) const {
  const Body& b = body_at(body);
  if (!b.fbar_nodal) return volume_ratios(body);
  std::vector<T> J(b.jbar.size());
  for (std::size_t p = 0; p < J.size(); ++p) J[p] = T(1) - b.jbar[p];
  return J;
}

template <typename T, typename TG>
std::vector<Mat3<T>> CpuEngine<T, TG>::deformation_gradients(int body) const {
  const Body& b = body_at(body);
  std::vector<Mat3T> F;
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.deformation_gradient) {
          F.reserve(mb.state.size());
          for (const auto& s : mb.state) F.push_back(s.F);
        } else {
          throw std::invalid_argument(std::string("CpuEngine: body ") + std::to_string(body) + " (" + M::kJsonName +
                                      ") stores no deformation gradient");
        }
      },
      b.material);
  return F;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::plastic_log_volumes(int body) const {
  const Body& b = body_at(body);
  std::vector<T> l;
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.log_jp) {
          l.reserve(mb.state.size());
          for (const auto& s : mb.state) l.push_back(s.logJp);
        } else {
          throw std::invalid_argument(std::string("CpuEngine: body ") + std::to_string(body) + " (" + M::kJsonName +
                                      ") stores no logJp");
        }
      },
      b.material);
  return l;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::pore_pressures(int body) const {
  const Body& b = body_at(body);
  std::vector<T> l;
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.pore_pressure) {
          l.reserve(mb.state.size());
          for (const auto& s : mb.state) l.push_back(s.pore_pressure);
        } else {
          throw std::invalid_argument(std::string("CpuEngine: body ") + std::to_string(body) + " (" + M::kJsonName +
                                      ") stores no pore pressure");
        }
      },
      b.material);
  return l;
}

template <typename T, typename TG>
std::vector<Mat3<T>> CpuEngine<T, TG>::cauchy_stresses(int body) const {
  const Body& b = body_at(body);
  std::vector<Mat3T> sigma(b.x.size());
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        const int n = static_cast<int>(sigma.size());
#pragma omp parallel for schedule(static) if (n >= kMinParallelParticles)
        for (int p = 0; p < n; ++p)
          sigma[p] = cauchy_stress(M::kirchhoff_stress(
              mb.params, b.fbar_nodal ? fbar_stress_state<M>(mb.params, mb.state[p], b.jbar[p]) : mb.state[p], b.C[p]));
      },
      b.material);
  return sigma;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::pressures(int body) const {
  const std::vector<Mat3T> sigma = cauchy_stresses(body);
  std::vector<T> p(sigma.size());
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = mean_pressure(sigma[i]);
  return p;
}

template <typename T, typename TG>
std::vector<T> CpuEngine<T, TG>::wave_speeds(int body) const {
  const Body& b = body_at(body);
  std::vector<T> c(b.x.size());
  std::visit(
      [&](const auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        for (std::size_t p = 0; p < c.size(); ++p) c[p] = M::wave_speed(mb.params, mb.state[p]);
      },
      b.material);
  return c;
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_velocities(int body, const std::function<Vec3d(const Vec3d&)>& velocity_of_position) {
  Body& b = body_at(body);
  for (std::size_t p = 0; p < b.x.size(); ++p) {
    b.v[p] = velocity_of_position(b.x[p].template cast<double>()).template cast<T>();
    max_grid_speed_ = std::max(max_grid_speed_, static_cast<double>(norm(b.v[p])));
  }
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_volume_ratios(int body, const std::function<double(const Vec3d&)>& J_of_position,
                                     bool rescale_mass) {
  Body& b = body_at(body);
  const SimulationSpec& sim = scene_.simulation;
  const double current_volume = sim.dx * sim.dx * sim.dx / b.spec.material.ppc;
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (std::is_same_v<M, JFluid>) {
          double c_max = 0.0;
          for (std::size_t p = 0; p < b.x.size(); ++p) {
            const double J = J_of_position(b.x[p].template cast<double>());
            if (!(J > 0.0) || !std::isfinite(J))
              throw std::invalid_argument("CpuEngine::set_volume_ratios: J must be positive and finite");
            mb.state[p] = M::template state_with_J<T>(static_cast<T>(J));
            if (rescale_mass) {
              b.volume[p] = static_cast<T>(current_volume / J);
              b.mass[p] = static_cast<T>(b.spec.material.rho * current_volume / J);
            }
            c_max = std::max(c_max, static_cast<double>(M::wave_speed(mb.params, mb.state[p])));
          }
          b.max_wave_speed = std::max(b.max_wave_speed, c_max);
        } else {
          throw std::invalid_argument(std::string("CpuEngine::set_volume_ratios: body ") + std::to_string(body) + " (" +
                                      M::kJsonName + ") does not store J");
        }
      },
      b.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_deformation_gradients(int body, const std::function<Mat3d(const Vec3d&)>& F_of_position) {
  Body& b = body_at(body);
  std::visit(
      [&](auto& mb) {
        using M = typename std::decay_t<decltype(mb)>::material_type;
        if constexpr (M::kOutputs.deformation_gradient) {
          for (std::size_t p = 0; p < b.x.size(); ++p)
            mb.state[p].F = F_of_position(b.x[p].template cast<double>()).template cast<T>();
        } else {
          throw std::invalid_argument(std::string("CpuEngine::set_deformation_gradients: body ") +
                                      std::to_string(body) + " (" + M::kJsonName + ") does not store F");
        }
      },
      b.material);
}

template <typename T, typename TG>
void CpuEngine<T, TG>::set_particle_forces(int body, ParticleForce force) {
  if (force && ranks() > 1)
    throw std::invalid_argument("CpuEngine::set_particle_forces: one rank only (the forces do not migrate)");
  Body& b = body_at(body);
  b.force_of = std::move(force);
  b.force.clear();
}

// ---------------------------------------------------------------------------------------------
// Totals

template <typename T, typename TG>
double CpuEngine<T, TG>::total_mass() const {
  double m = 0.0;
  for (const Body& b : bodies_)
    for (const T mp : b.mass) m += static_cast<double>(mp);
  return m;
}

template <typename T, typename TG>
Vec3d CpuEngine<T, TG>::total_momentum() const {
  Vec3d P = Vec3d::zero();
  for (const Body& b : bodies_)
    for (std::size_t p = 0; p < b.x.size(); ++p) P += b.v[p].template cast<double>() * static_cast<double>(b.mass[p]);
  return P;
}

template <typename T, typename TG>
Vec3d CpuEngine<T, TG>::angular_momentum() const {
  Vec3d L = Vec3d::zero();
  const double dx = scene_.simulation.dx;
  for (const Body& b : bodies_)
    for (std::size_t p = 0; p < b.x.size(); ++p)
      L += apic_angular_momentum(static_cast<double>(b.mass[p]), b.x[p].template cast<double>(),
                                 b.v[p].template cast<double>(), b.C[p].template cast<double>(), dx);
  return L;
}

template <typename T, typename TG>
double CpuEngine<T, TG>::kinetic_energy() const {
  double e = 0.0;
  for (const Body& b : bodies_)
    for (std::size_t p = 0; p < b.x.size(); ++p) {
      const Vec3d v = b.v[p].template cast<double>();
      e += 0.5 * static_cast<double>(b.mass[p]) * dot(v, v);
    }
  return e;
}

template <typename T, typename TG>
double CpuEngine<T, TG>::elastic_energy() const {
  double e = 0.0;
  for (const Body& b : bodies_)
    if (b.is_mesh())
      e += mesh_elastic_energy(b);  // the elements' energy (the vertex states are their means)
    else
      std::visit(
        [&](const auto& mb) {
          using M = typename std::decay_t<decltype(mb)>::material_type;
          for (std::size_t p = 0; p < b.x.size(); ++p)
            e += static_cast<double>(b.volume[p]) * static_cast<double>(M::energy_density(mb.params, mb.state[p]));
        },
        b.material);
  return e;
}

// ---------------------------------------------------------------------------------------------
// Output

template <typename T, typename TG>
io::ParticleFrame CpuEngine<T, TG>::frame(int body) const {
  const Body& b = body_at(body);
  FrameSource<T> src;
  src.x = &b.x;
  src.v = &b.v;
  src.id = &b.id;
  src.mass = [&](std::size_t p) { return b.mass[p]; };
  src.volume0 = [&](std::size_t p) { return b.volume[p]; };
  src.J = [&] { return volume_ratios(body); };
  src.jbar = [&] { return jbar_ratios(body); };
  src.F = [&] { return deformation_gradients(body); };
  src.sigma = [&] { return cauchy_stresses(body); };
  src.logJp = [&] { return plastic_log_volumes(body); };
  src.pore_pressure = [&] { return pore_pressures(body); };
  return build_frame(b.spec, body, src, "CPU engine");
}

template <typename T, typename TG>
std::size_t CpuEngine<T, TG>::memory_bytes() const {
  std::size_t bytes = 0;
  for (const Body& b : bodies_) {
    bytes += (b.x.capacity() + b.v.capacity() + b.x_next.capacity() + b.v_next.capacity()) * sizeof(Vec3T);
    bytes += (b.C.capacity() + b.C_next.capacity()) * sizeof(Mat3T);
    bytes += (b.mass.capacity() + b.volume.capacity()) * sizeof(T) + b.id.capacity() * sizeof(std::int64_t);
    std::visit([&](const auto& mb) { bytes += (mb.state.capacity() + mb.next_state.capacity()) * sizeof(mb.state[0]); },
               b.material);
    const Partition& part = b.partition;
    bytes += part.order.capacity() * sizeof(int) + part.particle_block.capacity() * sizeof(int) +
             part.particle_key.capacity() * sizeof(std::uint64_t) +
             part.grid_blocks.capacity() * sizeof(std::array<int, 8>) +
             part.block_keys.capacity() * (sizeof(std::uint64_t) + sizeof(Vec3i) + 2 * sizeof(int));
  }
  bytes += grid_.blocks.capacity() * sizeof(GridBlock) + grid_.coords.capacity() * sizeof(Vec3i) +
           grid_.asflip.capacity() * sizeof(AsflipBlock) + grid_.fbar.capacity() * sizeof(FbarBlock);
  bytes += grid_.index.size() * (sizeof(std::uint64_t) + sizeof(int) + 2 * sizeof(void*));
  return bytes;
}

template class CpuEngine<double, double>;
template class CpuEngine<float, float>;
template class CpuEngine<double, float>;

}  // namespace fbar
