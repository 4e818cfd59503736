// The run loop of every engine (CPU reference, GPU; later every rank of a multi-GPU run): frames every 1/fps,
// progress lines, the stop request (stop_request.h) and the failure report, written once.
//
// What it asks of an engine (CpuEngine<T, TG> and GpuEngine<T, TG> provide it; run_detail::check_run_engine names a
// missing member at compile time):
//   double time(), next_dt(), last_dt();  long long steps();  int body_count();  std::size_t particle_count();
//   StepReport step_toward(double t_end, double t_following)
//                                               one step of at most next_dt() that lands on t_end exactly when it
//                                               reaches it; t_following: where the next step heads then
//   void set_frame_capture(bool)                the next step lands on a frame time (the GPU then writes the frame's
//                                               attributes on the device during that step; the CPU needs nothing)
//   void submit_frame(int body, const std::filesystem::path&, io::AsyncWriter&)
//                                               queues the body's frame of the current state
//   double output_wait_seconds()                time the loop spent waiting for the writer thread
//   std::string resource_note()                 appended to progress lines ("" or e.g. device memory and peak)
//   void set_grid_sensors(specs)                the grid sensors (io/sensor_recorder.h) a sampling step evaluates
//   void set_grid_sample(int slot)              the next step starts at a sample time: its grid update writes
//                                               every sensor's reduction into `slot` (-1: no sample)
//   std::vector<SensorAccum> grid_samples(n)    this rank's values of slots [0, n)
//   void set_grid_fields(specs)                 the grid fields (io/grid_field_recorder.h) a sampling step records
//   void set_grid_field_sample(unsigned mask)   the next step starts at a sample time of the fields in `mask`: its
//                                               grid update records their nodes (0: none)
//   GridFieldSample grid_field_sample(int i)    this rank's nodes of field i's last sample, with its step's dt
//   void set_particle_sensors(specs)            the particle sensors sample_particles() evaluates
//   void keep_particle_inputs(bool)             the next step's end state will be sampled (the GPU then records
//                                               each particle's v and C in that step; the CPU needs nothing)
//   void sample_particles(int slot)             reduces the current particle state into `slot`
//   std::vector<SensorAccum> particle_samples(n) this rank's values of particle slots [0, n)
//   void set_tracker(int body, TrackerSet)      the particles of a body whose attributes track() reads by ID
//   void track(int body, values, present)       the tracked particles this rank holds, now
//   io::Checkpoint checkpoint()                 this rank's state (collective; io/checkpoint.h)
//   bool checkpoint_ready()                     checkpoint() can be taken now (the GPU engine needs the particles'
//                                               v and C, which it records only on the steps asked to)
//   void keep_checkpoint_inputs(bool)           the next step records what checkpoint() needs
//   bool rebalance_due()                        decomposed runs: the particles per rank drifted apart (the same
//                                               answer on every rank); the step landing on the next frame then
//                                               keeps the checkpoint inputs
//   bool rebalance_if_drifted()                 after a frame's output (collective): new slabs when still due
//                                               (the CPU engine rebalances within its steps: false for both)
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <iostream>
#include <filesystem>
#include <limits>
#include <memory>
#include <ostream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "comm/placement.h"
#include "engine/engine_api.h"
#include "engine/engine_common.h"
#include "engine/run_constants.h"
#include "engine/stop_request.h"
#include "io/checkpoint.h"
#include "io/frame_series.h"
#include "io/grid_field_recorder.h"
#include "io/sensor_recorder.h"
#include "scene/scene.h"

namespace fbar {

namespace run_detail {

/// hh:mm:ss, or --:--:-- when unknown.
inline std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--:--";
  const long long s = static_cast<long long>(seconds + 0.5);
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%02lld:%02lld:%02lld", s / 3600, (s / 60) % 60, s % 60);
  return buf;
}

/// A time or a count as %.6g prints it.
inline std::string format_number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", x);
  return buf;
}

/// 0.123 -> "12.3 %".
inline std::string format_percent(double fraction) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g %%", 100.0 * fraction);
  return buf;
}

}  // namespace run_detail

/// What the run loop needs of an engine (the list above), checked when run_frames is instantiated: an engine that
/// lacks one member fails to compile with that member named.
namespace run_detail {
#define FBAR_ENGINE_NEEDS(trait, expression)                                      \
  template <class E, class = void>                                                \
  struct trait : std::false_type {};                                              \
  template <class E>                                                              \
  struct trait<E, std::void_t<decltype(expression)>> : std::true_type {};
template <class E>
E& engine_ref();
FBAR_ENGINE_NEEDS(HasClock, (double(engine_ref<E>().time()) + engine_ref<E>().next_dt() + engine_ref<E>().last_dt() +
                             static_cast<double>(engine_ref<E>().steps())))
FBAR_ENGINE_NEEDS(HasCounts, (engine_ref<E>().body_count() + engine_ref<E>().particle_count()))
FBAR_ENGINE_NEEDS(HasStepToward, (std::declval<StepReport&>() = engine_ref<E>().step_toward(1.0, 2.0)))
FBAR_ENGINE_NEEDS(HasFrames, (engine_ref<E>().set_frame_capture(true),
                              engine_ref<E>().submit_frame(0, std::filesystem::path(),
                                                           std::declval<io::AsyncWriter&>()),
                              double(engine_ref<E>().output_wait_seconds()),
                              std::string(engine_ref<E>().resource_note())))
FBAR_ENGINE_NEEDS(HasGridSensors, (engine_ref<E>().set_grid_sensors(std::declval<std::vector<GridSensorSpec>&>()),
                                   engine_ref<E>().set_grid_sample(0),
                                   std::vector<SensorAccum>(engine_ref<E>().grid_samples(1))))
FBAR_ENGINE_NEEDS(HasParticleSensors,
                  (engine_ref<E>().set_particle_sensors(std::declval<std::vector<ParticleSensorSpec>&>()),
                   engine_ref<E>().keep_particle_inputs(true), engine_ref<E>().sample_particles(0),
                   std::vector<SensorAccum>(engine_ref<E>().particle_samples(1))))
FBAR_ENGINE_NEEDS(HasGridFields, (engine_ref<E>().set_grid_fields(std::declval<std::vector<GridFieldSpec>&>()),
                                  engine_ref<E>().set_grid_field_sample(0u),
                                  GridFieldSample(engine_ref<E>().grid_field_sample(0))))
FBAR_ENGINE_NEEDS(HasTrackers, (engine_ref<E>().set_tracker(0, std::declval<const TrackerSet&>()),
                                engine_ref<E>().track(0, std::declval<std::vector<double>&>(),
                                                      std::declval<std::vector<double>&>())))
FBAR_ENGINE_NEEDS(HasCheckpoints, (io::Checkpoint(engine_ref<E>().checkpoint()),
                                   bool(engine_ref<E>().checkpoint_ready()), engine_ref<E>().keep_checkpoint_inputs(true),
                                   bool(engine_ref<E>().rebalance_due()), bool(engine_ref<E>().rebalance_if_drifted())))
#undef FBAR_ENGINE_NEEDS

template <class E>
constexpr bool check_run_engine() {
  static_assert(HasClock<E>::value, "run loop engine: needs time(), next_dt(), last_dt(), steps()");
  static_assert(HasCounts<E>::value, "run loop engine: needs body_count(), particle_count()");
  static_assert(HasStepToward<E>::value, "run loop engine: needs StepReport step_toward(double, double)");
  static_assert(HasFrames<E>::value,
                "run loop engine: needs set_frame_capture(bool), submit_frame(int, path, AsyncWriter&), "
                "output_wait_seconds(), resource_note()");
  static_assert(HasGridSensors<E>::value,
                "run loop engine: needs set_grid_sensors(specs), set_grid_sample(int), grid_samples(int)");
  static_assert(HasParticleSensors<E>::value,
                "run loop engine: needs set_particle_sensors(specs), keep_particle_inputs(bool), sample_particles(int), "
                "particle_samples(int)");
  static_assert(HasGridFields<E>::value,
                "run loop engine: needs set_grid_fields(specs), set_grid_field_sample(unsigned), grid_field_sample(int)");
  static_assert(HasTrackers<E>::value, "run loop engine: needs set_tracker(int, TrackerSet), track(int, values, present)");
  static_assert(HasCheckpoints<E>::value,
                "run loop engine: needs checkpoint(), checkpoint_ready(), keep_checkpoint_inputs(bool), "
                "rebalance_due(), rebalance_if_drifted()");
  return true;
}

}  // namespace run_detail

/// The run loop of run_frames (below): its set-up, one step, a frame's end, the stops and the run's end, by name.
/// Every rank of a decomposed run runs one in step with the others; rank 0 speaks for them.
template <class Engine>
class RunLoop {
  static_assert(run_detail::check_run_engine<Engine>());

 public:
  RunLoop(Engine& engine, const Scene& scene, const RunOptions& options, std::ostream& log,
          const io::Checkpoint* resume)
      : engine_(engine),
        scene_(scene),
        sim_(scene.simulation),
        options_(options),
        log_(log),
        resume_(resume),
        transport_(options.transport),
        rank_(transport_ ? transport_->rank() : 0),
        decomposed_(transport_ && transport_->size() > 1),
        talk_(!options.quiet && rank_ == 0),
        suffix_(prepared_suffix(sim_)),
        homes_(comm::body_ranks(scene, transport_ ? transport_->size() : 1)),  // bodies[].gpu
        t0_(resume ? resume->start_time : engine.time()),
        t_end_(t0_ + sim_.frames / sim_.fps),
        series_(make_series()),
        writer_(1),
        sensors_(scene, transport_, t0_, t_end_, resume),
        fields_(scene, transport_, t0_, t_end_, resume),
        trackers_(scene, transport_, resume),
        save_dir_(sim_.save_path) {
    engine_.set_grid_sensors(sensors_.grid_sensors());
    engine_.set_grid_sample(-1);
    engine_.set_particle_sensors(sensors_.particle_sensors());
    engine_.set_grid_fields(fields_.fields());
    engine_.set_grid_field_sample(0);
    for (const BodyTracker& t : trackers_.trackers()) engine_.set_tracker(t.body, t.set);
  }

  /// The whole run: the start (or the restart), every frame, the end.
  RunResult run(const std::string& engine_line) {
    const int first_frame = start(engine_line);
    wall_start_ = std::chrono::steady_clock::now();
    first_step_ = engine_.steps();
    first_time_ = engine_.time();
    steps_logged_ = engine_.steps();
    try {
      for (int frame = first_frame; frame <= sim_.frames; ++frame) {
        const double target = t0_ + frame / sim_.fps;
        while (engine_.time() < target)
          if (!step(frame, target)) return finish();
        end_frame(frame);
      }
      return finish();
    } catch (const io::OutputError& e) {
      return output_failure(e);
    }
  }

 private:
  /// The particles of every rank and their imbalance, max / mean - 1.
  struct Count {
    std::size_t particles;
    double imbalance;
  };

  /// The save folder made and the frame suffix checked (a suffix without a writer throws before anything runs).
  static std::string prepared_suffix(const SimulationSpec& sim) {
    std::filesystem::create_directories(sim.save_path);
    io::frame_format(sim.save_suffix);
    return sim.save_suffix;
  }

  /// .h5 frames: rank 0 keeps frames.xdmf (io/frame_series.h), every frame of every rank as one time series. Its
  /// writer thread adds a frame once the frame's files of every rank are complete; finish() adds the last ones once
  /// every rank has closed its writer.
  std::unique_ptr<io::FrameSeries> make_series() const {
    if (rank_ != 0 || suffix_ != ".h5") return nullptr;
    const int ranks = transport_ ? transport_->size() : 1;
    std::vector<std::vector<std::pair<int, int>>> files(static_cast<std::size_t>(engine_.body_count()));
    for (int b = 0; b < engine_.body_count(); ++b) {  // the (model, device) of each file write_frame() names
      const BodySpec& spec = scene_.bodies[b];
      if (!decomposed_) files[b].emplace_back(spec.model, std::max(spec.gpu, 0));
      else if (homes_[b] >= 0) files[b].emplace_back(spec.model, homes_[b]);
      else
        for (int r = 0; r < ranks; ++r) files[b].emplace_back(spec.model, r);
    }
    return std::make_unique<io::FrameSeries>(sim_.save_path, std::move(files), suffix_);
  }

  /// The engine line, the diffusive bound's note, and frame 0 with its samples (or, restarted, what the first run
  /// wrote). Returns the first frame to run.
  int start(const std::string& engine_line) {
    if (talk_) log_ << engine_line << '\n';
    const DiffusiveBound bound = diffusive_step_bound(scene_);
    if (bound.dt < resolved_default_dt(sim_) && talk_)
      log_ << "fbar: note: the explicit " << (bound.seepage ? "seepage" : "viscous") << " bound of body "
           << bound.body << " limits every step to " << bound.dt << " s (" << bound.formula() << "; default_dt "
           << resolved_default_dt(sim_) << " s)\n";
    if (!resume_) {
      write_frame(0);
      sample_particles_at(t0_);
      record_trackers();
      return 1;
    }
    // The restart's own state was written (and sampled, unless still due) by the run that made it.
    result_.frames_written = resume_->frame;
    if (series_) {  // the frames the first run wrote stay in the series
      for (int f = 0; f <= resume_->frame; ++f) series_->expect(f, t0_ + f / sim_.fps);
      series_->update();
    }
    result_.restarted_from_frame = resume_->frame;
    sample_particles_at(engine_.time());  // only when the checkpoint says that sample was still due (its run's end)
    if (talk_)
      log_ << "fbar: restarted from a checkpoint at t = " << engine_.time() << " s, step " << engine_.steps()
           << " (frame " << resume_->frame << " written; " << resume_->reason << ")\n";
    if (resume_->frame + 1 > sim_.frames && rank_ == 0)
      std::cerr << "fbar: warning: --restart: the checkpoint is at frame " << resume_->frame
                << " and the scene asks for " << sim_.frames << " frames: nothing to run (raise frames or --frames)\n";
    return resume_->frame + 1;
  }

  /// One step toward the frame time `target` (or the sample time before it), after the stop request is agreed on.
  /// Returns false when the run stops here (a signal or a failure the engine does not repair).
  bool step(int frame, double target) {
    int signal = stop_signal();
    if (decomposed_) signal = static_cast<int>(transport_->max(static_cast<double>(signal)));  // all stop together
    if (signal != 0 && !engine_.checkpoint_ready() && !stop_step_) {
      stop_step_ = true;  // the same on every rank (checkpoint_ready() follows the steps every rank took)
    } else if (signal != 0) {
      stop_on_signal(signal);
      return false;
    }
    // Steps start on every sensor sample time; the one starting there samples the grid.
    const double start = engine_.time();
    const double step_target = head_for(start, target);
    const int slot = sensors_.grid_slot_for(start);
    engine_.set_grid_sample(slot);
    const unsigned fields = fields_.due_mask(start);  // the grid fields sampling at this step's start
    engine_.set_grid_field_sample(fields);
    // The step that may land on a particle sample time keeps what the particle sensors read (the last two steps
    // before it: the CPU engine may split what remains in two).
    engine_.keep_particle_inputs(
        (sensors_.particle_due(step_target) || (trackers_.reads_velocity() && step_target == target)) &&
        engine_.time() + 2.0 * engine_.next_dt() >= step_target);
    // The step that lands on the frame time writes the frame (on the device, for the GPU engine).
    const bool lands = step_target == target && engine_.time() + engine_.next_dt() >= target;
    engine_.set_frame_capture(lands);
    engine_.keep_checkpoint_inputs(stop_step_ ||
                                   (lands && (frame_checkpoint_due(frame) || engine_.rebalance_due())));
    // Where the step after a landing heads: the next sample or frame time (the GPU fixes that step's dt now).
    const double following = step_target < target    ? head_for(step_target, target)
                             : frame < sim_.frames ? head_for(step_target, t0_ + (frame + 1) / sim_.fps)
                                                   : std::numeric_limits<double>::infinity();
    const StepReport r = engine_.step_toward(step_target, following);
    if (!r.ok) {
      stop_on_failure(r);
      return false;
    }
    if (slot >= 0) sensors_.grid_taken(start);
    if (fields != 0) {  // a collective: every rank has the same mask
      for (std::size_t i = 0; i < fields_.fields().size(); ++i)
        if (fields >> i & 1u) {
          GridFieldSample s = engine_.grid_field_sample(static_cast<int>(i));
          fields_.record(i, start, s.dt, std::move(s.nodes), writer_);
        }
      fields_.taken(start);
      engine_.set_grid_field_sample(0);
    }
    sample_particles_at(engine_.time());
    if (sim_.info_rate > 0 && !options_.quiet && engine_.steps() - steps_logged_ >= sim_.info_rate &&
        engine_.time() < target) {  // the same decision on every rank
      steps_logged_ = engine_.steps();
      const Count count = all_particles();
      if (talk_) progress_line("step " + std::to_string(engine_.steps()), count);
    }
    return true;
  }

  /// The frame's output once a step landed on it: frame files, sensor rows, trackers, a due checkpoint, a due
  /// rebalance and the progress line.
  void end_frame(int frame) {
    engine_.set_frame_capture(false);
    engine_.set_grid_sample(-1);
    engine_.set_grid_field_sample(0);
    engine_.keep_checkpoint_inputs(false);
    write_frame(frame);
    flush_sensors();
    record_trackers();
    if (frame_checkpoint_due(frame)) {
      if (!engine_.checkpoint_ready())
        throw std::logic_error("the step landing on frame " + std::to_string(frame) +
                               " did not record what its checkpoint needs");
      checkpoint(io::checkpoint_frame_path(save_dir_, frame, rank_), "frame");
    }
    if (engine_.rebalance_due()) {  // the same on every rank
      writer_.flush();  // the frames' host buffers belong to the engine that is built again
      engine_.rebalance_if_drifted();
    }
    if (!options_.quiet) {
      const Count count = all_particles();
      if (talk_) progress_line("frame " + std::to_string(frame) + "/" + std::to_string(sim_.frames), count);
    }
    steps_logged_ = engine_.steps();
  }

  /// A stop request (SIGINT / SIGTERM) agreed on by every rank: a checkpoint of this state, exit code 128 + signal.
  void stop_on_signal(int signal) {
    result_.stop_signal = signal;
    result_.exit_code = 128 + signal;
    checkpoint(step_checkpoint_path(), signal_name(signal));
    char text[512];
    std::snprintf(text, sizeof(text),
                  "stopped by %s at step %lld, t = %.6g s; the last frame written is %d; checkpoint %s "
                  "(fbar --restart=%s continues the run)",
                  signal_name(signal), engine_.steps(), engine_.time(), result_.frames_written,
                  result_.checkpoint.c_str(), result_.checkpoint.c_str());
    result_.message = text;
  }

  /// A failure the engine did not repair: exit code 2, its report, and a checkpoint of the state before the step
  /// when the engine can take one.
  void stop_on_failure(const StepReport& r) {
    engine_.set_frame_capture(false);
    engine_.set_grid_sample(-1);
    engine_.keep_checkpoint_inputs(false);
    result_.exit_code = 2;
    result_.message = r.message();  // the caller reports it (cli.cpp prints it to stderr)
    if (engine_.checkpoint_ready()) {  // the state before the failed step
      checkpoint(step_checkpoint_path(), "failure");
      result_.message += "\ncheckpoint of the state before the failed step: " + result_.checkpoint;
    } else {
      result_.message += "\nno checkpoint of this state (the GPU engine had not recorded the particles' "
                         "velocities)" +
                         (result_.checkpoint.empty() ? std::string() : "; the last checkpoint is " + result_.checkpoint);
    }
  }

  /// A frame, sensor, tracker or checkpoint file could not be written (a full disk, a folder that vanished): one
  /// message naming the file, the system's reason and what is complete (the last frame whose files were all
  /// written, the last checkpoint written whole). It ends this rank's run as an exception would (from_exception:
  /// several MPI ranks are stopped together by the command line), without waiting for the others.
  RunResult output_failure(const io::OutputError& e) {
    try {
      writer_.close();  // the remaining jobs are skipped; it throws the error again
    } catch (const io::OutputError&) {
    }
    const std::size_t done = writer_.completed();
    int frame = resume_ ? resume_->frame : -1;
    for (const auto& [jobs, f] : frame_marks_)
      if (jobs <= done) frame = f;
    std::string checkpoint = resume_ && !options_.restart.empty() ? options_.restart : std::string();
    for (const auto& [jobs, path] : checkpoint_marks_)
      if (jobs <= done) checkpoint = path;
    RunResult r = result_;
    r.exit_code = 2;
    r.from_exception = true;
    r.steps = engine_.steps();
    r.end_time = engine_.time();
    r.frames_written = frame;
    r.checkpoint = rank_ == 0 ? checkpoint : std::string();
    const std::string& what = e.failure();
    r.message = "output failed at step " + std::to_string(engine_.steps()) + ", t = " +
                run_detail::format_number(engine_.time()) + " s: " + what + ". Complete: " +
                (frame >= 0 ? "frames 0 to " + std::to_string(frame) + " (t = " +
                                  run_detail::format_number(t0_ + frame / sim_.fps) + " s)"
                            : std::string("no frame")) +
                ", " + (checkpoint.empty() ? std::string("no checkpoint") : "the checkpoint " + checkpoint) +
                "; the sensor files up to the failure. Free space in " + sim_.save_path +
                (checkpoint.empty() ? " and run again" : " and continue with --restart=" + checkpoint);
    return r;
  }

  /// Every body's frame of the current state, and its place in frames.xdmf.
  void write_frame(int frame) {
    for (int b = 0; b < engine_.body_count(); ++b) {
      const BodySpec& spec = scene_.bodies[b];
      if (homes_[b] >= 0 && homes_[b] != rank_) continue;  // a placed body: its rank's file only (dev[gpu])
      // A decomposed body is written by every rank, its particles in the rank's file (ClaymoreUW's dev[d] names).
      const int device = decomposed_ ? rank_ : std::max(spec.gpu, 0);  // "all" on one rank: dev[0]
      engine_.submit_frame(b, io::frame_file_path(sim_.save_path, spec.model, device, frame, suffix_), writer_);
    }
    result_.frames_written = frame;
    if (series_) {
      series_->expect(frame, t0_ + frame / sim_.fps);
      writer_.submit_job([s = series_.get()] { s->update(); });
    }
    frame_marks_.emplace_back(writer_.submitted(), frame);  // complete once the writer has done that many jobs
  }

  /// The sensors' pending samples to their files (a collective; ranks agree on what is pending).
  void flush_sensors() {
    if (sensors_.grid_pending() > 0) sensors_.flush_grid(engine_.grid_samples(sensors_.grid_pending()));
    if (sensors_.particle_pending() > 0)
      sensors_.flush_particles(engine_.particle_samples(sensors_.particle_pending()));
  }

  /// Every tracker's row, at every frame (ClaymoreUW's rate); a collective.
  void record_trackers() {
    std::vector<double> values, present;
    for (std::size_t k = 0; k < trackers_.trackers().size(); ++k) {
      engine_.track(trackers_.trackers()[k].body, values, present);
      trackers_.record(k, engine_.time(), values, present);
    }
  }

  /// Particle sensors read the state a step lands on (or the initial state).
  void sample_particles_at(double t) {
    const int slot = sensors_.particle_slot_for(t);
    if (slot < 0) return;
    engine_.sample_particles(slot);
    sensors_.particle_taken(t);
  }

  /// A checkpoint of every rank's state (collective: the engine's state is taken now; each rank's writer thread
  /// writes its file while the run goes on, after the frames queued before it, or before the next step when a body
  /// is read from the engine as it is written; rank 0 records its CSVs' lengths).
  void checkpoint(const std::filesystem::path& path, const std::string& reason) {
    flush_sensors();
    auto c = std::make_shared<io::Checkpoint>(engine_.checkpoint());
    c->reason = reason;
    c->start_time = t0_;
    c->frame = result_.frames_written;
    c->particle_sample_due = sensors_.particle_untaken_at(engine_.time());
    if (rank_ == 0) {
      sensors_.file_sizes(c->csv);
      trackers_.file_sizes(c->csv);
    }
    writer_.submit_job([c, path] { io::write_checkpoint(path, *c); });
    checkpoint_marks_.emplace_back(writer_.submitted(), path.string());
    if (rank_ == 0) result_.checkpoint = path.string();
    // A streamed body (io::Checkpoint::streamed) is read from the engine while the file is written: the run waits
    // for it before the next step changes that state.
    if (!c->streamed.empty()) writer_.flush();
  }
  std::filesystem::path step_checkpoint_path() const {
    return io::checkpoint_step_path(save_dir_, engine_.steps(), rank_);
  }
  bool frame_checkpoint_due(int frame) const { return sim_.checkpoint_every > 0 && frame % sim_.checkpoint_every == 0; }

  /// Where a step starting at `start` heads: the next sample time, or the frame time `target` (a sample time within
  /// the tolerance of it counts as the frame time).
  double head_for(double start, double target) const {
    const double sensor = sensors_.next_time_after(start), field = fields_.next_time_after(start);
    if (sensor < target - sensors_.tolerance() && sensor <= field) return sensor;
    return field < target - fields_.tolerance() ? field : target;
  }

  /// A collective: every rank calls it at the same points, rank 0 prints.
  Count all_particles() {
    const auto mine = static_cast<long long>(engine_.particle_count());
    if (!decomposed_) return {static_cast<std::size_t>(mine), 0.0};
    const long long total = transport_->sum(mine);
    const double most = transport_->max(static_cast<double>(mine));
    const double mean = static_cast<double>(total) / transport_->size();
    return {static_cast<std::size_t>(total), mean > 0 ? most / mean - 1.0 : 0.0};
  }

  void progress_line(const std::string& head, Count count) {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start_).count();
    const double done = engine_.time() - first_time_;
    const double eta = done > 0 ? elapsed * (t_end_ - engine_.time()) / done : -1.0;
    const long long stepped = engine_.steps() - first_step_;  // by this process (a restart starts at its step)
    const double ms_per_step = stepped > 0 ? 1e3 * elapsed / static_cast<double>(stepped) : 0.0;
    const std::string note = engine_.resource_note();
    char text[512];
    std::snprintf(text, sizeof(text), "%s  t = %.6g s  dt = %.3g s  steps = %lld  particles = %zu  %.4g ms/step  ETA %s"
                  "  (output wait %.3g s%s%s)\n", head.c_str(), engine_.time(), engine_.last_dt(), engine_.steps(),
                  count.particles, ms_per_step, run_detail::format_duration(eta).c_str(),
                  engine_.output_wait_seconds(), note.empty() ? "" : "; ", note.c_str());
    log_ << text;
    if (decomposed_)
      log_ << "  particles per rank: imbalance " << run_detail::format_percent(count.imbalance) << " (max / mean - 1)\n";
    log_ << std::flush;
  }

  /// The run's end, also when it stops early: the samples taken so far, the frames already queued written (a writer
  /// error is thrown after every rank has met the others, so that rank 0 finds every rank's last frames for
  /// frames.xdmf), and the result.
  RunResult finish() {
    result_.steps = engine_.steps();
    result_.end_time = engine_.time();
    flush_sensors();
    std::exception_ptr write_error;
    try {
      writer_.close();
    } catch (...) {
      write_error = std::current_exception();
    }
    if (decomposed_) transport_->barrier();
    if (write_error) std::rethrow_exception(write_error);
    if (series_) {
      series_->update();
      for (const auto& [frame, file] : series_->missing())
        std::cerr << "fbar: warning: " << series_->path().string() << " leaves out frame " << frame << ": " << file
                  << " is not in " << sim_.save_path
                  << (decomposed_ ? " (every rank must write to a folder rank 0 can read)" : "") << '\n';
    }
    return result_;
  }

  Engine& engine_;
  const Scene& scene_;
  const SimulationSpec& sim_;
  const RunOptions& options_;
  std::ostream& log_;
  const io::Checkpoint* resume_;
  comm::Transport* transport_;
  const int rank_;
  const bool decomposed_;
  const bool talk_;  ///< rank 0 of a run that is not quiet: every rank runs the loop, rank 0 speaks for them
  const std::string suffix_;
  const std::vector<int> homes_;  ///< per body: its rank (bodies[].gpu) or kAllGpus
  const double t0_, t_end_;
  std::unique_ptr<io::FrameSeries> series_;  ///< before writer_: the writer's jobs end before the series goes
  /// One frame may wait while one is written: the engines' frame buffers bound the rest, so memory stays flat however
  /// slow the disk (the GPU engine downloads into one pinned buffer per body; the CPU engine builds its frame here).
  io::AsyncWriter writer_;
  SensorRecorder sensors_;
  GridFieldRecorder fields_;
  TrackerRecorder trackers_;
  const std::filesystem::path save_dir_;
  RunResult result_;
  /// The writer's submitted() after each frame's and each checkpoint's jobs: complete once completed() reaches it.
  std::vector<std::pair<std::size_t, int>> frame_marks_;
  std::vector<std::pair<std::size_t, std::string>> checkpoint_marks_;
  std::chrono::steady_clock::time_point wall_start_{};
  long long first_step_ = 0, steps_logged_ = 0;
  double first_time_ = 0.0;
  bool stop_step_ = false;  ///< a signal came and the engine needs one more (recording) step before its checkpoint
};

/// Runs `engine` (constructed from `scene`) for simulation.frames frames, writing frame 0 (the initial state) and
/// every frame to simulation.save_path (model[m]_dev[d]_frame[f].suffix), and the sensors' CSVs (steps start and
/// end on every sample time; rows are written at each frame), with a progress line per frame and, when
/// simulation.info_rate > 0, every info_rate steps. `engine_line` is logged first (which engine, particles, set-up).
/// With several ranks (options.transport) every rank runs this loop in step with the others: the engine agrees on
/// dt and failures, the loop on a stop request; each rank writes its particles (model[m]_dev[rank]_frame[f]) and
/// rank 0 logs. With .h5 frames rank 0 also keeps frames.xdmf, all of them as one time series (io/frame_series.h).
/// Stops at the first failure the engine does not repair (exit code 2, the engine's report: body, step, time) and
/// at a stop request (exit code 128 + signal, at the next step boundary). Throws what the engine or the writer
/// throws (run_guarded turns it into an exit code).
/// Checkpoints (io/checkpoint.h): every simulation.checkpoint_every frames (checkpoint_frame[f]_dev[d].h5), and when
/// the run stops on a signal or a failure (checkpoint_step[s]_dev[d].h5, the state before the failed step). The GPU
/// engine records the particles' v and C for them: on the step landing on a checkpoint frame, and on a signal one
/// more step (the signal's checkpoint follows it); after a failure it writes one only when the step before had
/// recorded them (the report names the last checkpoint otherwise).
/// resume: the checkpoint the engine was built from (--restart): frames continue after resume->frame at the first
/// run's frame times, the sensor and tracker files are continued, nothing is written for the restart's own state.
template <class Engine>
RunResult run_frames(Engine& engine, const Scene& scene, const RunOptions& options, std::ostream& log,
                     const std::string& engine_line, const io::Checkpoint* resume = nullptr) {
  return RunLoop<Engine>(engine, scene, options, log, resume).run(engine_line);
}

}  // namespace fbar
