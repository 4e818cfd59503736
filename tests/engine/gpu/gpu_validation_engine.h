// CpuEngine's query interface over the GPU engine, so that the validation cases of tests/validation (*_case.h,
// templated on the engine) run unchanged on the GPU: every query reads one snapshot of the body (cached until the
// next step), velocities are recorded every step, masses are the engine's per particle (a mesh's lumped vertex masses,
// one value for every particle of another body) and volumes its per-body constant. Per-particle initial velocities
// (set_velocities) are handed to the GPU engine's constructor, which therefore runs at the first query after them.
#pragma once

#include <functional>
#include <ostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <vector>

#include "MnBase/Math/vec.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"
#include "scene/scene.h"

namespace fbar::test {

template <typename T>
class GpuValidationEngine {
 public:
  explicit GpuValidationEngine(const Scene& scene)
      : scene_(scene), positions_(sample_scene(scene)), cache_(scene.bodies.size()) {}

  /// As CpuEngine::set_velocities, before the first step or query only.
  void set_velocities(int body, const std::function<Vec3d(const Vec3d&)>& velocity_of_position) {
    if (engine_) throw std::logic_error("GpuValidationEngine: set_velocities after the engine started");
    options_.initial_velocities.resize(scene_.bodies.size());
    std::vector<Vec3d>& v = options_.initial_velocities[body];
    v.clear();
    for (const Vec3d& x : positions_[body]) v.push_back(velocity_of_position(x));
  }
  /// Not available on the GPU engine: the cases call it only for starts the GPU tests do not run.
  void set_volume_ratios(int, const std::function<double(const Vec3d&)>&, bool = true) {
    throw std::logic_error("GpuValidationEngine: set_volume_ratios is a CPU engine feature");
  }

  StepReport step() { return changed(engine().step()); }
  StepReport step(double dt) { return changed(engine().step(dt)); }
  StepReport advance_to(double t_end) { return changed(engine().advance_to(t_end)); }
  StepReport step_toward(double t_end) { return changed(engine().step_toward(t_end)); }
  /// As CpuEngine::set_log (nullptr: silent), before or after the engine started.
  void set_log(std::ostream* log) {
    log_ = log;
    log_set_ = true;
    if (engine_) engine_->set_log(log);
  }
  double next_dt() { return engine().next_dt(); }
  double time() { return engine().time(); }
  long long steps() { return engine().steps(); }
  double last_dt() { return engine().last_dt(); }

  std::size_t particle_count(int body) { return engine().particle_count(body); }
  const std::vector<Vec3<T>>& positions(int body) { return snapshot(body).x; }
  const std::vector<Vec3<T>>& velocities(int body) { return snapshot(body).v; }
  std::vector<T> masses(int body) {
    const std::vector<double> m = engine().particle_masses(body);  // a mesh's lumped vertex masses
    return std::vector<T>(m.begin(), m.end());
  }
  std::vector<T> volumes(int body) {
    return std::vector<T>(particle_count(body), static_cast<T>(engine().particle_volume(body)));
  }
  std::vector<T> volume_ratios(int body) { return snapshot(body).J; }
  std::vector<Mat3<T>> deformation_gradients(int body) { return snapshot(body).F; }
  std::vector<T> plastic_log_volumes(int body) { return snapshot(body).logJp; }
  std::vector<T> pore_pressures(int body) { return snapshot(body).pore_pressure; }
  std::vector<Mat3<T>> cauchy_stresses(int body) { return snapshot(body).sigma; }
  std::vector<T> pressures(int body) {
    const ParticleSnapshot<T>& s = snapshot(body);
    std::vector<T> p(s.sigma.size());
    for (std::size_t i = 0; i < p.size(); ++i) p[i] = -(s.sigma[i](0, 0) + s.sigma[i](1, 1) + s.sigma[i](2, 2)) / T(3);
    return p;
  }

  double total_mass() { return engine().total_mass(); }
  Vec3d total_momentum() {
    Vec3d sum = Vec3d::zero();
    for (int b = 0; b < engine().body_count(); ++b) {
      const std::vector<double> m = engine().particle_masses(b);
      for (std::size_t p = 0; p < velocities(b).size(); ++p) sum += velocities(b)[p].template cast<double>() * m[p];
    }
    return sum;
  }
  double kinetic_energy() {
    double e = 0.0;
    for (int b = 0; b < engine().body_count(); ++b) {
      const std::vector<double> m = engine().particle_masses(b);
      for (std::size_t p = 0; p < velocities(b).size(); ++p)
        e += 0.5 * m[p] * static_cast<double>(dot(velocities(b)[p], velocities(b)[p]));
    }
    return e;
  }
  /// Grid sensors, as CpuEngine (the GPU engine's own interface).
  void set_grid_sensors(const std::vector<GridSensorSpec>& sensors) { engine().set_grid_sensors(sensors); }
  void set_grid_sample(int slot) { engine().set_grid_sample(slot); }
  std::vector<SensorAccum> grid_samples(int slots) { return engine().grid_samples(slots); }
  double elastic_energy() { return engine().elastic_energy(); }

 private:
  GpuEngine<T>& engine() {
    if (!engine_) {
      engine_ = std::make_unique<GpuEngine<T>>(scene_, positions_, options_);
      engine_->set_record_velocities(true);
      if (log_set_) engine_->set_log(log_);
    }
    return *engine_;
  }
  StepReport changed(StepReport r) {
    for (auto& c : cache_) c.reset();
    return r;
  }
  const ParticleSnapshot<T>& snapshot(int body) {
    if (!cache_[body]) cache_[body] = engine().snapshot(body);
    return *cache_[body];
  }

  Scene scene_;
  std::vector<std::vector<Vec3d>> positions_;
  GpuEngineOptions options_;
  std::ostream* log_ = nullptr;
  bool log_set_ = false;
  std::unique_ptr<GpuEngine<T>> engine_;
  std::vector<std::optional<ParticleSnapshot<T>>> cache_;
};

}  // namespace fbar::test
