// Grid-sensor schedule, reduction over ranks and CSV rows (sensor_recorder.h).
#include "io/sensor_recorder.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <system_error>

namespace fbar {

namespace {

GridSensorQuantity quantity_of(const std::string& attribute) {
  if (attribute == "Force") return GridSensorQuantity::Force;
  if (attribute == "Acceleration") return GridSensorQuantity::Acceleration;
  if (attribute == "Momentum") return GridSensorQuantity::Momentum;
  if (attribute == "Velocity") return GridSensorQuantity::Velocity;
  if (attribute == "Mass") return GridSensorQuantity::Mass;
  // Volume and JBar are refused before a run (scene_support.cpp): the grid holds no volume channel.
  throw std::invalid_argument("grid sensor attribute \"" + attribute + "\" has no grid quantity in this release");
}

const char* unit_of(GridSensorQuantity q) {
  switch (q) {
    case GridSensorQuantity::Force: return "N";
    case GridSensorQuantity::Acceleration: return "m/s^2";
    case GridSensorQuantity::Momentum: return "kg m/s";
    case GridSensorQuantity::Velocity: return "m/s";
    case GridSensorQuantity::Mass: return "kg";
  }
  return "-";
}

}  // namespace

template <typename T>
GridSensorParams<T> make_grid_sensor_params(const GridSensorSpec& spec) {
  GridSensorParams<T> p;
  p.quantity = quantity_of(spec.attribute);
  p.sign = spec.direction_sign;
  for (int a = 0; a < 3; ++a) {
    p.direction[a] = static_cast<T>(spec.direction[a]);
    p.lo[a] = static_cast<T>(spec.domain_start[a]);
    p.hi[a] = static_cast<T>(spec.domain_end[a]);
  }
  return p;
}
template GridSensorParams<float> make_grid_sensor_params<float>(const GridSensorSpec&);
template GridSensorParams<double> make_grid_sensor_params<double>(const GridSensorSpec&);

double sensor_result(SensorOperation op, const SensorAccum& a) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  switch (op) {
    case SensorOperation::Sum: return a.sum;
    case SensorOperation::Count: return a.count;
    case SensorOperation::Max: return a.count > 0 ? a.max : nan;
    case SensorOperation::Min: return a.count > 0 ? a.min : nan;
    case SensorOperation::Average: return a.count > 0 ? a.sum / a.count : nan;
    case SensorOperation::Variance:
    case SensorOperation::STDEV: {
      if (!(a.count > 0)) return nan;
      const double mean = a.sum / a.count;
      const double variance = std::max(0.0, a.sum_sq / a.count - mean * mean);  // population variance
      return op == SensorOperation::Variance ? variance : std::sqrt(variance);
    }
  }
  return nan;
}

std::string grid_sensor_column(const GridSensorSpec& spec) {
  if (spec.operation == SensorOperation::Count) return "Count [-]";
  const char* unit = unit_of(quantity_of(spec.attribute));
  if (spec.operation == SensorOperation::Variance) return spec.attribute + " variance [(" + unit + ")^2]";
  return spec.attribute + " [" + unit + "]";
}

SensorRecorder::SensorRecorder(const Scene& scene, comm::Transport* transport, double t0, double t_end)
    : transport_(transport), t0_(t0), t_end_(t_end) {
  const SimulationSpec& sim = scene.simulation;
  const bool writer = !transport || transport->rank() == 0;
  double shortest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < scene.grid_sensors.size(); ++i) {
    const GridSensorSpec& spec = scene.grid_sensors[i];
    if (!spec.toggle) continue;
    quantity_of(spec.attribute);  // throws for what the grid cannot measure
    Sensor s;
    s.scene_index = i;
    s.interval = 1.0 / spec.output_frequency;
    s.path = std::filesystem::path(sim.save_path) / ("gridTarget[" + std::to_string(i) + "]_dev[0].csv");
    shortest = std::min(shortest, s.interval);
    // Slots between two flushes: each sensor samples at most ceil(frame interval / its interval) + 1 times in one.
    capacity_ += static_cast<int>(std::ceil((1.0 / sim.fps) / s.interval)) + 1;
    if (writer) {
      std::filesystem::create_directories(sim.save_path);
      s.file = std::fopen(s.path.c_str(), "w");
      if (!s.file)
        throw std::runtime_error("cannot write grid sensor file " + s.path.string() + ": " +
                                 std::error_code(errno, std::generic_category()).message());
      std::fprintf(s.file, "Time [s],%s\n", grid_sensor_column(spec).c_str());
    }
    specs_.push_back(spec);
    grid_.push_back(s);
  }
  tolerance_ = std::isfinite(shortest) ? 1e-9 * shortest : 0.0;
}

SensorRecorder::~SensorRecorder() {
  for (Sensor& s : grid_)
    if (s.file) std::fclose(s.file);
}

bool SensorRecorder::due(const Sensor& s, double t) const {
  const double ts = sample_time(s, s.next);
  return ts < t_end_ - tolerance_ && t >= ts - tolerance_;
}

double SensorRecorder::next_time() const {
  double next = std::numeric_limits<double>::infinity();
  for (const Sensor& s : grid_) {
    const double ts = sample_time(s, s.next);
    if (ts < t_end_ - tolerance_) next = std::min(next, ts);
  }
  return next;
}

double SensorRecorder::next_time_after(double t) const {
  double next = std::numeric_limits<double>::infinity();
  for (const Sensor& s : grid_) {
    long long k = s.next;
    while (sample_time(s, k) <= t + tolerance_) ++k;
    const double ts = sample_time(s, k);
    if (ts < t_end_ - tolerance_) next = std::min(next, ts);
  }
  return next;
}

int SensorRecorder::slot_for(double t) const {
  for (const Sensor& s : grid_)
    if (due(s, t)) return static_cast<int>(slots_.size());
  return -1;
}

void SensorRecorder::taken(double t) {
  Slot slot;
  slot.due.assign(grid_.size(), 0);
  bool any = false;
  for (std::size_t i = 0; i < grid_.size(); ++i) {
    Sensor& s = grid_[i];
    if (!due(s, t)) continue;
    // The time written is the sample time (t equals it up to the tolerance), and every sample time the step
    // covered is consumed (none is: steps start on each).
    if (!any) slot.time = sample_time(s, s.next);
    any = true;
    slot.due[i] = 1;
    while (sample_time(s, s.next) <= t + tolerance_) ++s.next;
  }
  if (!any) throw std::logic_error("SensorRecorder::taken: no sensor samples at this time");
  if (static_cast<int>(slots_.size()) >= capacity_)
    throw std::logic_error("SensorRecorder: more samples than slots between two flushes");
  slots_.push_back(std::move(slot));
}

void SensorRecorder::flush(const std::vector<SensorAccum>& values) {
  const std::size_t n = grid_.size();
  const std::size_t count = slots_.size() * n;
  if (values.size() < count) throw std::logic_error("SensorRecorder::flush: fewer values than pending samples");
  if (count == 0) return;
  std::vector<double> sums(3 * count), maxima(count), minima(count);
  for (std::size_t k = 0; k < count; ++k) {
    sums[3 * k + 0] = values[k].sum;
    sums[3 * k + 1] = values[k].sum_sq;
    sums[3 * k + 2] = values[k].count;
    maxima[k] = values[k].max;
    minima[k] = values[k].min;
  }
  if (transport_ && transport_->size() > 1) {
    transport_->allreduce_sum(sums.data(), static_cast<int>(sums.size()));
    transport_->allreduce_max(maxima.data(), static_cast<int>(maxima.size()));
    transport_->allreduce_min(minima.data(), static_cast<int>(minima.size()));
  }
  for (std::size_t slot = 0; slot < slots_.size(); ++slot)
    for (std::size_t i = 0; i < n; ++i) {
      Sensor& s = grid_[i];
      if (!slots_[slot].due[i] || !s.file) continue;
      const std::size_t k = slot * n + i;
      SensorAccum a;
      a.sum = sums[3 * k + 0];
      a.sum_sq = sums[3 * k + 1];
      a.count = sums[3 * k + 2];
      a.max = maxima[k];
      a.min = minima[k];
      const double v = sensor_result(specs_[i].operation, a);
      std::fprintf(s.file, "%.12g,%.9g\n", slots_[slot].time, v);
    }
  for (Sensor& s : grid_)
    if (s.file && std::fflush(s.file) != 0)
      throw std::runtime_error("cannot write grid sensor file " + s.path.string() + ": " +
                               std::error_code(errno, std::generic_category()).message());
  slots_.clear();
}

}  // namespace fbar
