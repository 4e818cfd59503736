// The run loop of every engine (CPU reference, GPU; later every rank of a multi-GPU run): frames every 1/fps,
// progress lines, the stop request (stop_request.h) and the failure report, written once.
//
// What it asks of an engine (CpuEngine<T, TG> and GpuEngine<T, TG> provide it):
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
#include <utility>
#include <vector>

#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "comm/placement.h"
#include "engine/engine_api.h"
#include "engine/run_constants.h"
#include "engine/stop_request.h"
#include "io/checkpoint.h"
#include "io/frame_series.h"
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

/// 0.123 -> "12.3 %".
inline std::string format_percent(double fraction) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g %%", 100.0 * fraction);
  return buf;
}

}  // namespace run_detail

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
  RunResult result;
  const SimulationSpec& sim = scene.simulation;
  comm::Transport* transport = options.transport;
  const int rank = transport ? transport->rank() : 0;
  const bool decomposed = transport && transport->size() > 1;
  const bool talk = !options.quiet && rank == 0;  // every rank runs the loop; rank 0 speaks for them
  std::filesystem::create_directories(sim.save_path);
  const std::string suffix = sim.save_suffix;
  io::frame_format(suffix);  // throws for a suffix without a writer before anything runs
  // One frame may wait while one is written: the engines' frame buffers bound the rest, so memory stays flat however
  // slow the disk (the GPU engine downloads into one pinned buffer per body; the CPU engine builds its frame here).
  io::AsyncWriter writer(1);
  const std::vector<int> homes = comm::body_ranks(scene, transport ? transport->size() : 1);  // bodies[].gpu
  auto write_frame = [&](int frame) {
    for (int b = 0; b < engine.body_count(); ++b) {
      const BodySpec& spec = scene.bodies[b];
      if (homes[b] >= 0 && homes[b] != rank) continue;  // a placed body: its rank's file only (dev[gpu])
      // A decomposed body is written by every rank, its particles in the rank's file (ClaymoreUW's dev[d] names).
      const int device = decomposed ? rank : std::max(spec.gpu, 0);  // "all" on one rank: dev[0]
      engine.submit_frame(b, io::frame_file_path(sim.save_path, spec.model, device, frame, suffix), writer);
    }
    result.frames_written = frame;
  };
  const double t0 = resume ? resume->start_time : engine.time();
  const double t_end = t0 + sim.frames / sim.fps;
  // .h5 frames: rank 0 keeps frames.xdmf (io/frame_series.h), every frame of every rank as one time series. Its
  // writer thread adds a frame once the frame's files of every rank are complete (after its own frame's files, which
  // it writes first); finish() adds the last ones once every rank has closed its writer.
  std::unique_ptr<io::FrameSeries> series;
  if (rank == 0 && suffix == ".h5") {
    const int ranks = transport ? transport->size() : 1;
    std::vector<std::vector<std::pair<int, int>>> files(static_cast<std::size_t>(engine.body_count()));
    for (int b = 0; b < engine.body_count(); ++b) {  // the (model, device) of each file write_frame() names
      const BodySpec& spec = scene.bodies[b];
      if (!decomposed) files[b].emplace_back(spec.model, std::max(spec.gpu, 0));
      else if (homes[b] >= 0) files[b].emplace_back(spec.model, homes[b]);
      else
        for (int r = 0; r < ranks; ++r) files[b].emplace_back(spec.model, r);
    }
    series = std::make_unique<io::FrameSeries>(sim.save_path, std::move(files), suffix);
  }
  auto add_to_series = [&](int frame) {
    if (!series) return;
    series->expect(frame, t0 + frame / sim.fps);
    writer.submit_job([s = series.get()] { s->update(); });
  };
  SensorRecorder sensors(scene, transport, t0, t_end, resume);
  engine.set_grid_sensors(sensors.grid_sensors());
  engine.set_grid_sample(-1);
  engine.set_particle_sensors(sensors.particle_sensors());
  auto flush_sensors = [&] {  // a collective; ranks agree on what is pending
    if (sensors.grid_pending() > 0) sensors.flush_grid(engine.grid_samples(sensors.grid_pending()));
    if (sensors.particle_pending() > 0) sensors.flush_particles(engine.particle_samples(sensors.particle_pending()));
  };
  TrackerRecorder trackers(scene, transport, resume);
  for (const BodyTracker& t : trackers.trackers()) engine.set_tracker(t.body, t.set);
  auto record_trackers = [&] {  // at every frame (ClaymoreUW's rate), a collective
    std::vector<double> values, present;
    for (std::size_t k = 0; k < trackers.trackers().size(); ++k) {
      engine.track(trackers.trackers()[k].body, values, present);
      trackers.record(k, engine.time(), values, present);
    }
  };
  // Particle sensors read the state a step lands on (or the initial state).
  auto sample_particles_at = [&](double t) {
    const int slot = sensors.particle_slot_for(t);
    if (slot < 0) return;
    engine.sample_particles(slot);
    sensors.particle_taken(t);
  };
  // A checkpoint of every rank's state (collective: the engine's state is taken now; each rank's writer thread
  // writes its file while the run goes on, after the frames queued before it; rank 0 records its CSVs' lengths).
  auto checkpoint = [&](const std::filesystem::path& path, const std::string& reason) {
    flush_sensors();
    auto c = std::make_shared<io::Checkpoint>(engine.checkpoint());
    c->reason = reason;
    c->start_time = t0;
    c->frame = result.frames_written;
    c->particle_sample_due = sensors.particle_untaken_at(engine.time());
    if (rank == 0) {
      sensors.file_sizes(c->csv);
      trackers.file_sizes(c->csv);
    }
    writer.submit_job([c, path] { io::write_checkpoint(path, *c); });
    if (rank == 0) result.checkpoint = path.string();
  };
  const std::filesystem::path save_dir(sim.save_path);
  auto step_checkpoint_path = [&] { return io::checkpoint_step_path(save_dir, engine.steps(), rank); };
  auto frame_checkpoint_due = [&](int frame) {
    return sim.checkpoint_every > 0 && frame % sim.checkpoint_every == 0;
  };
  auto finish = [&] {
    result.steps = engine.steps();
    result.end_time = engine.time();
    flush_sensors();  // the samples taken so far, also when the run stops early
    // The frames already queued are written (and a writer error is thrown) before we return; every rank then meets
    // the others (a writer error is thrown after that), so that rank 0 finds every rank's last frames for frames.xdmf.
    std::exception_ptr write_error;
    try {
      writer.close();
    } catch (...) {
      write_error = std::current_exception();
    }
    if (decomposed) transport->barrier();
    if (write_error) std::rethrow_exception(write_error);
    if (series) {
      series->update();
      for (const auto& [frame, file] : series->missing())
        std::cerr << "fbar: warning: " << series->path().string() << " leaves out frame " << frame << ": " << file
                  << " is not in " << sim.save_path
                  << (decomposed ? " (every rank must write to a folder rank 0 can read)" : "") << '\n';
    }
    return result;
  };

  if (talk) log << engine_line << '\n';
  const ViscousBound viscous = viscous_step_bound(scene);
  if (viscous.dt < resolved_default_dt(sim) && talk)
    log << "fbar: note: the explicit viscous bound of body " << viscous.body << " limits every step to "
        << viscous.dt << " s (CFL x rho x dx^2 / (3 x viscosity); default_dt " << resolved_default_dt(sim)
        << " s)\n";
  int first_frame = 1;
  if (resume) {  // the restart's own state was written (and sampled, unless still due) by the run that made it
    first_frame = resume->frame + 1;
    result.frames_written = resume->frame;
    if (series) {  // the frames the first run wrote stay in the series
      for (int f = 0; f <= resume->frame; ++f) series->expect(f, t0 + f / sim.fps);
      series->update();
    }
    result.restarted_from_frame = resume->frame;
    sample_particles_at(engine.time());  // only when the checkpoint says that sample was still due (its run's end)
    if (talk)
      log << "fbar: restarted from a checkpoint at t = " << engine.time() << " s, step " << engine.steps()
          << " (frame " << resume->frame << " written; " << resume->reason << ")\n";
    if (first_frame > sim.frames && rank == 0)
      std::cerr << "fbar: warning: --restart: the checkpoint is at frame " << resume->frame
                << " and the scene asks for " << sim.frames << " frames: nothing to run (raise frames or --frames)\n";
  } else {
    write_frame(0);
    add_to_series(0);
    sample_particles_at(t0);
    record_trackers();
  }

  const auto wall_start = std::chrono::steady_clock::now();
  const long long first_step = engine.steps();
  const double first_time = engine.time();
  // The particles of every rank and their imbalance, max / mean - 1 (a collective: every rank calls it at the same
  // points, rank 0 prints).
  struct Count {
    std::size_t particles;
    double imbalance;
  };
  auto all_particles = [&]() -> Count {
    const auto mine = static_cast<long long>(engine.particle_count());
    if (!decomposed) return {static_cast<std::size_t>(mine), 0.0};
    const long long total = transport->sum(mine);
    const double most = transport->max(static_cast<double>(mine));
    const double mean = static_cast<double>(total) / transport->size();
    return {static_cast<std::size_t>(total), mean > 0 ? most / mean - 1.0 : 0.0};
  };
  auto line = [&](const std::string& head, Count count) {
    const std::size_t particles = count.particles;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
    const double done = engine.time() - first_time;
    const double eta = done > 0 ? elapsed * (t_end - engine.time()) / done : -1.0;
    const long long stepped = engine.steps() - first_step;  // by this process (a restart starts at its step)
    const double ms_per_step = stepped > 0 ? 1e3 * elapsed / static_cast<double>(stepped) : 0.0;
    const std::string note = engine.resource_note();
    char text[512];
    std::snprintf(text, sizeof(text), "%s  t = %.6g s  dt = %.3g s  steps = %lld  particles = %zu  %.3g ms/step  ETA %s"
                  "  (output wait %.3g s%s%s)\n", head.c_str(), engine.time(), engine.last_dt(), engine.steps(),
                  particles, ms_per_step, run_detail::format_duration(eta).c_str(),
                  engine.output_wait_seconds(), note.empty() ? "" : "; ", note.c_str());
    log << text;
    if (decomposed)
      log << "  particles per rank: imbalance " << run_detail::format_percent(count.imbalance) << " (max / mean - 1)\n";
    log << std::flush;
  };

  // Where a step starting at `start` heads: the next sample time, or the frame time `target` (a sample time within
  // the tolerance of it counts as the frame time).
  auto head_for = [&](double start, double target) {
    const double sample = sensors.next_time_after(start);
    return sample < target - sensors.tolerance() ? sample : target;
  };
  long long steps_logged = engine.steps();
  bool stop_step = false;  // a signal came and the engine needs one more (recording) step before its checkpoint
  for (int frame = first_frame; frame <= sim.frames; ++frame) {
    const double target = t0 + frame / sim.fps;
    while (engine.time() < target) {
      int signal = stop_signal();
      if (decomposed) signal = static_cast<int>(transport->max(static_cast<double>(signal)));  // all stop together
      if (signal != 0 && !engine.checkpoint_ready() && !stop_step) {
        stop_step = true;  // the same on every rank (checkpoint_ready() follows the steps every rank took)
      } else if (signal != 0) {
        result.stop_signal = signal;
        result.exit_code = 128 + signal;
        checkpoint(step_checkpoint_path(), signal_name(signal));
        char text[512];
        std::snprintf(text, sizeof(text),
                      "stopped by %s at step %lld, t = %.6g s; the last frame written is %d; checkpoint %s "
                      "(fbar --restart=%s continues the run)",
                      signal_name(signal), engine.steps(), engine.time(), result.frames_written,
                      result.checkpoint.c_str(), result.checkpoint.c_str());
        result.message = text;
        return finish();
      }
      // Steps start on every sensor sample time; the one starting there samples the grid.
      const double start = engine.time();
      const double step_target = head_for(start, target);
      const int slot = sensors.grid_slot_for(start);
      engine.set_grid_sample(slot);
      // The step that may land on a particle sample time keeps what the particle sensors read (the last two steps
      // before it: the CPU engine may split what remains in two).
      engine.keep_particle_inputs(
          (sensors.particle_due(step_target) || (trackers.reads_velocity() && step_target == target)) &&
          engine.time() + 2.0 * engine.next_dt() >= step_target);
      // The step that lands on the frame time writes the frame (on the device, for the GPU engine).
      const bool lands = step_target == target && engine.time() + engine.next_dt() >= target;
      engine.set_frame_capture(lands);
      engine.keep_checkpoint_inputs(stop_step || (lands && (frame_checkpoint_due(frame) || engine.rebalance_due())));
      // Where the step after a landing heads: the next sample or frame time (the GPU fixes that step's dt now).
      const double following = step_target < target          ? head_for(step_target, target)
                                : frame < sim.frames ? head_for(step_target, t0 + (frame + 1) / sim.fps)
                                                     : std::numeric_limits<double>::infinity();
      const StepReport r = engine.step_toward(step_target, following);
      if (!r.ok) {
        engine.set_frame_capture(false);
        engine.set_grid_sample(-1);
        engine.keep_checkpoint_inputs(false);
        result.exit_code = 2;
        result.message = r.message();  // the caller reports it (cli.cpp prints it to stderr)
        if (engine.checkpoint_ready()) {  // the state before the failed step
          checkpoint(step_checkpoint_path(), "failure");
          result.message += "\ncheckpoint of the state before the failed step: " + result.checkpoint;
        } else {
          result.message += "\nno checkpoint of this state (the GPU engine had not recorded the particles' "
                            "velocities)" +
                            (result.checkpoint.empty() ? std::string()
                                                       : "; the last checkpoint is " + result.checkpoint);
        }
        return finish();
      }
      if (slot >= 0) sensors.grid_taken(start);
      sample_particles_at(engine.time());
      if (sim.info_rate > 0 && !options.quiet && engine.steps() - steps_logged >= sim.info_rate &&
          engine.time() < target) {  // the same decision on every rank
        steps_logged = engine.steps();
        const Count count = all_particles();
        if (talk) line("step " + std::to_string(engine.steps()), count);
      }
    }
    engine.set_frame_capture(false);
    engine.set_grid_sample(-1);
    engine.keep_checkpoint_inputs(false);
    write_frame(frame);
    add_to_series(frame);
    flush_sensors();
    record_trackers();
    if (frame_checkpoint_due(frame)) {
      if (!engine.checkpoint_ready())
        throw std::logic_error("the step landing on frame " + std::to_string(frame) +
                               " did not record what its checkpoint needs");
      checkpoint(io::checkpoint_frame_path(save_dir, frame, rank), "frame");
    }
    if (engine.rebalance_due()) {  // the same on every rank
      writer.flush();  // the frames' host buffers belong to the engine that is built again
      engine.rebalance_if_drifted();
    }
    if (!options.quiet) {
      const Count count = all_particles();
      if (talk) line("frame " + std::to_string(frame) + "/" + std::to_string(sim.frames), count);
    }
    steps_logged = engine.steps();
  }
  return finish();
}

}  // namespace fbar
