// Sensor schedules, reduction over ranks and CSV rows (sensor_recorder.h).
#include "io/sensor_recorder.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <system_error>

#include "MnSystem/IO/output_error.h"
#include "io/particle_frame.h"
#include "physics/constitutive_models.cuh"
#include "scene/scene_error.h"
#include "scene/scene_parse.h"

namespace fbar {

// ---------------------------------------------------------------------------------------------------------------
// Files

namespace {

/// A new CSV file with its header line, or (resume) the file of the run being continued, truncated to the length
/// the checkpoint recorded and opened for appending.
std::FILE* open_csv(const std::filesystem::path& path, const std::string& header, const char* what,
                    const io::Checkpoint* resume) {
  auto fail = [&] {
    return io::OutputError(std::string("cannot write ") + what + " file " + path.string() + ": " +
                              std::error_code(errno, std::generic_category()).message());
  };
  if (resume) {
    const std::string name = path.filename().string();
    long long recorded = -1;
    for (const auto& [file, bytes] : resume->csv)
      if (file == name) recorded = bytes;
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    if (recorded >= 0 && !ec && static_cast<long long>(size) >= recorded) {
      std::filesystem::resize_file(path, static_cast<std::uintmax_t>(recorded), ec);
      if (ec) throw io::OutputError(std::string("cannot truncate ") + what + " file " + path.string() + ": " + ec.message());
      std::FILE* f = std::fopen(path.c_str(), "a");
      if (!f) throw fail();
      return f;
    }
    std::cerr << "fbar: warning: " << path.string()
              << (recorded < 0 ? " was not written by the checkpointed run"
                               : ec ? " is missing" : " is shorter than when the checkpoint was written")
              << ": it starts again with the restart's rows only\n";
  }
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw fail();
  std::fprintf(f, "%s\n", header.c_str());
  return f;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Schedule

SensorRecorder::Schedule::~Schedule() {
  for (Output& o : outputs_)
    if (o.file) std::fclose(o.file);
}

void SensorRecorder::Schedule::add_sensor(double interval) {
  intervals_.push_back(interval);
  next_.push_back(0);
}

void SensorRecorder::Schedule::add_output(Output o, const std::string& header, bool writer,
                                          const io::Checkpoint* resume) {
  if (writer) o.file = open_csv(o.path, "Time [s]," + header, "sensor", resume);
  outputs_.push_back(o);
}

void SensorRecorder::Schedule::resume(double t, bool after) {
  for (std::size_t i = 0; i < sensors(); ++i) {
    long long k = 0;
    while (after ? sample_time(i, k) <= t + tolerance_ : sample_time(i, k) < t - tolerance_) ++k;
    next_[i] = k;
  }
}

void SensorRecorder::Schedule::file_sizes(std::vector<std::pair<std::string, long long>>& out) const {
  for (const Output& o : outputs_)
    if (o.file) {
      std::fflush(o.file);
      out.emplace_back(o.path.filename().string(), static_cast<long long>(std::ftell(o.file)));
    }
}

void SensorRecorder::Schedule::finish(double t0, double t_end, double tolerance, std::size_t values_per_slot) {
  t0_ = t0;
  t_end_ = t_end;
  tolerance_ = tolerance;
  values_per_slot_ = values_per_slot;
}

bool SensorRecorder::Schedule::due(std::size_t i, double t) const {
  const double ts = sample_time(i, next_[i]);
  return ts < t_end_ - tolerance_ && t >= ts - tolerance_;
}

bool SensorRecorder::Schedule::untaken_at(double t) const {
  for (std::size_t i = 0; i < sensors(); ++i)
    if (std::fabs(sample_time(i, next_[i]) - t) <= tolerance_) return true;
  return false;
}

double SensorRecorder::Schedule::next_time_after(double t) const {
  double next = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < sensors(); ++i) {
    long long k = next_[i];
    while (sample_time(i, k) <= t + tolerance_) ++k;
    const double ts = sample_time(i, k);
    if (ts < t_end_ - tolerance_) next = std::min(next, ts);
  }
  return next;
}

int SensorRecorder::Schedule::slot_for(double t) const {
  for (std::size_t i = 0; i < sensors(); ++i)
    if (due(i, t)) return pending();
  return -1;
}

void SensorRecorder::Schedule::taken(double t) {
  std::vector<char> due_now(sensors(), 0);
  bool any = false;
  double time = t;
  for (std::size_t i = 0; i < sensors(); ++i) {
    if (!due(i, t)) continue;
    // The time written is the sample time (t equals it up to the tolerance); every sample time up to t is consumed.
    if (!any) time = sample_time(i, next_[i]);
    any = true;
    due_now[i] = 1;
    while (sample_time(i, next_[i]) <= t + tolerance_) ++next_[i];
  }
  if (!any) throw std::logic_error("SensorRecorder: no sensor samples at this time");
  slot_times_.push_back(time);
  slot_due_.push_back(std::move(due_now));
}

void SensorRecorder::Schedule::flush(const std::vector<SensorAccum>& values, comm::Transport* transport) {
  const std::size_t count = slot_times_.size() * values_per_slot_;
  if (count == 0) {
    slot_times_.clear();
    slot_due_.clear();
    return;
  }
  if (values.size() < count) throw std::logic_error("SensorRecorder::flush: fewer values than pending samples");
  // The ranks' sums merge as integers (ExactSum's words): the same bits on any number of ranks.
  constexpr int kW = ExactSum::kWords;
  std::vector<long long> words(2 * kW * count);
  std::vector<double> sums(3 * count), maxima(count), minima(count);
  for (std::size_t k = 0; k < count; ++k) {
    for (int w = 0; w < kW; ++w) {
      words[2 * kW * k + w] = values[k].sum.word[w];
      words[2 * kW * k + kW + w] = values[k].sum_sq.word[w];
    }
    sums[3 * k + 0] = values[k].sum.special;
    sums[3 * k + 1] = values[k].sum_sq.special;
    sums[3 * k + 2] = values[k].count;
    maxima[k] = values[k].max;
    minima[k] = values[k].min;
  }
  if (transport && transport->size() > 1) {
    transport->allreduce_sum(words.data(), static_cast<int>(words.size()));
    transport->allreduce_sum(sums.data(), static_cast<int>(sums.size()));
    transport->allreduce_max(maxima.data(), static_cast<int>(maxima.size()));
    transport->allreduce_min(minima.data(), static_cast<int>(minima.size()));
  }
  for (std::size_t slot = 0; slot < slot_times_.size(); ++slot)
    for (Output& o : outputs_) {
      if (!slot_due_[slot][o.sensor] || !o.file) continue;
      const std::size_t k = slot * values_per_slot_ + o.value;
      SensorAccum a;
      for (int w = 0; w < kW; ++w) {
        a.sum.word[w] = words[2 * kW * k + w];
        a.sum_sq.word[w] = words[2 * kW * k + kW + w];
      }
      a.sum.special = sums[3 * k + 0];
      a.sum_sq.special = sums[3 * k + 1];
      a.count = sums[3 * k + 2];
      a.max = maxima[k];
      a.min = minima[k];
      std::fprintf(o.file, "%.12g,%.9g\n", slot_times_[slot], sensor_result(o.op, a));
    }
  for (Output& o : outputs_)
    if (o.file && std::fflush(o.file) != 0)
      throw io::OutputError("cannot write sensor file " + o.path.string() + ": " +
                               std::error_code(errno, std::generic_category()).message());
  slot_times_.clear();
  slot_due_.clear();
}

// ---------------------------------------------------------------------------------------------------------------
// SensorRecorder

SensorRecorder::SensorRecorder(const Scene& scene, comm::Transport* transport, double t0, double t_end,
                               const io::Checkpoint* resume)
    : transport_(transport) {
  const SimulationSpec& sim = scene.simulation;
  const bool writer = !transport || transport->rank() == 0;
  const std::filesystem::path dir(sim.save_path);
  double shortest = std::numeric_limits<double>::infinity();
  bool any = false;
  for (const GridSensorSpec& s : scene.grid_sensors) any = any || s.toggle;
  for (const ParticleSensorSpec& s : scene.particle_sensors) any = any || s.toggle;
  if (any && writer) std::filesystem::create_directories(dir);

  for (std::size_t i = 0; i < scene.grid_sensors.size(); ++i) {
    const GridSensorSpec& spec = scene.grid_sensors[i];
    if (!spec.toggle) continue;
    Schedule::Output o;
    o.sensor = grid_specs_.size();
    o.value = grid_specs_.size();
    o.op = spec.operation;
    o.path = dir / ("gridTarget[" + std::to_string(i) + "]_dev[0].csv");
    grid_.add_output(o, grid_sensor_column(spec), writer, resume);
    grid_.add_sensor(1.0 / spec.output_frequency);
    shortest = std::min(shortest, 1.0 / spec.output_frequency);
    grid_specs_.push_back(spec);
  }

  const std::size_t bodies = scene.bodies.size();
  std::size_t enabled = 0;
  for (const ParticleSensorSpec& spec : scene.particle_sensors) enabled += spec.toggle;
  for (std::size_t i = 0; i < scene.particle_sensors.size(); ++i) {
    const ParticleSensorSpec& spec = scene.particle_sensors[i];
    if (!spec.toggle) continue;
    const FrameColumn column = particle_attribute(spec).column;
    const std::size_t n = particle_specs_.size();
    for (std::size_t b = 0; b < bodies; ++b) {
      if (!material_has(scene.bodies[b].material.law, column.quantity)) continue;  // the body has no such quantity
      Schedule::Output o;
      o.sensor = n;
      o.value = b * enabled + n;
      o.op = spec.operation;
      o.path = dir / ("particleTarget[" + std::to_string(i) + "]_model[" + std::to_string(scene.bodies[b].model) +
                      "]_dev[0].csv");
      particle_.add_output(o, particle_sensor_column(spec), writer, resume);
    }
    particle_.add_sensor(1.0 / spec.output_frequency);
    shortest = std::min(shortest, 1.0 / spec.output_frequency);
    particle_specs_.push_back(spec);
  }
  tolerance_ = std::isfinite(shortest) ? 1e-9 * shortest : 0.0;
  grid_.finish(t0, t_end, tolerance_, grid_specs_.size());
  particle_.finish(t0, t_end, tolerance_, bodies * particle_specs_.size());
  if (resume) {
    grid_.resume(resume->time, false);
    particle_.resume(resume->time, !resume->particle_sample_due);
  }
}

SensorRecorder::~SensorRecorder() = default;


TrackerRecorder::TrackerRecorder(const Scene& scene, comm::Transport* transport, const io::Checkpoint* resume)
    : transport_(transport), trackers_(make_trackers(scene)), reads_velocity_(any_reads_velocity(trackers_)) {
  const bool writer = !transport || transport->rank() == 0;
  const std::filesystem::path dir(scene.simulation.save_path);
  for (const BodyTracker& t : trackers_) {
    paths_.push_back(dir / ("particleTrack_model[" + std::to_string(scene.bodies[t.body].model) + "]_dev[0].csv"));
    std::FILE* f = nullptr;
    if (writer) {
      std::filesystem::create_directories(dir);
      std::string header = "Time [s]";
      for (std::size_t a = 0; a < t.names.size(); ++a)
        for (long long id : t.ids)
          header += "," + t.names[a] + "[" + std::to_string(id) + "] [" + (t.units[a].empty() ? "-" : t.units[a]) + "]";
      f = open_csv(paths_.back(), header, "tracker", resume);
    }
    files_.push_back(f);
  }
}

void TrackerRecorder::file_sizes(std::vector<std::pair<std::string, long long>>& out) const {
  for (std::size_t k = 0; k < files_.size(); ++k)
    if (files_[k]) {
      std::fflush(files_[k]);
      out.emplace_back(paths_[k].filename().string(), static_cast<long long>(std::ftell(files_[k])));
    }
}

TrackerRecorder::~TrackerRecorder() {
  for (std::FILE* f : files_)
    if (f) std::fclose(f);
}

void TrackerRecorder::record(std::size_t k, double time, std::vector<double> values, std::vector<double> present) {
  const BodyTracker& t = trackers_[k];
  if (transport_ && transport_->size() > 1) {
    transport_->allreduce_sum(values.data(), static_cast<int>(values.size()));
    transport_->allreduce_sum(present.data(), static_cast<int>(present.size()));
  }
  // An ID on no rank is not a particle of the body (the parser warned: the body has fewer particles, and engines
  // never remove one): its columns read NaN. ClaymoreUW writes 0 for it.
  for (int i = 0; i < t.set.ids; ++i)
    if (present[i] > 1.0)
      throw std::runtime_error("bodies[" + std::to_string(t.body) + "].track_particle_id: particle ID " +
                               std::to_string(t.set.id[i]) + " is held by several ranks (an engine error)");
  std::FILE* f = files_[k];
  if (!f) return;
  std::fprintf(f, "%.12g", time);
  for (int a = 0; a < t.set.attribs; ++a)
    for (long long id : t.ids) {
      const int i = tracker_index(t.set, static_cast<int>(id));
      if (present[i] == 1.0) std::fprintf(f, ",%.9g", values[static_cast<std::size_t>(i) * t.set.attribs + a]);
      else std::fprintf(f, ",nan");
    }
  std::fprintf(f, "\n");
  if (std::fflush(f) != 0)
    throw io::OutputError("cannot write tracker file " + paths_[k].string() + ": " +
                             std::error_code(errno, std::generic_category()).message());
}

double SensorRecorder::next_time_after(double t) const {
  return std::min(grid_.next_time_after(t), particle_.next_time_after(t));
}

}  // namespace fbar
