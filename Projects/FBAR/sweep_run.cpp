// fbar --sweep=FILE (sweep_run.h): check every case, pack the cases on the GPUs, resume, gather.
#include "sweep_run.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <unistd.h>

#include "MnSystem/Cuda/device_query.h"
#include "comm/mpi_transport.h"
#include "comm/placement.h"
#include "engine/engine_api.h"
#include "engine/memory_plan.h"
#include "engine/run_loop.h"
#include "engine/stop_request.h"
#include "io/sweep_table.h"
#include "run_record.h"
#include "scene/scene_parse.h"
#include "scene/sweep.h"

namespace fbar {

namespace {

namespace fs = std::filesystem;

/// One case as checked: its scene and what it costs.
struct CasePlan {
  const SweepCase* c = nullptr;
  Scene scene;
  long long particles = 0;
  std::size_t gpu_bytes = 0;   ///< the GPU engine's plan on its one GPU
  double est_steps = 0.0;      ///< simulated time / the first time step
  double est_gpu_s = 0.0;      ///< [s] on a kGpuRateDevice, alone
  double weight = 0.0;         ///< the share of the sweep's work (progress and ETA)
};

std::string count_text(long long n) {
  std::string s = std::to_string(n);
  for (int i = static_cast<int>(s.size()) - 3; i > 0; i -= 3) s.insert(static_cast<std::size_t>(i), ",");
  return s;
}

/// Which share of the cases this process runs: MPI rank r of n, a Slurm array task, or all.
struct Share {
  int index = 0, count = 1;
  std::string what;  ///< "MPI rank 1 of 4", "Slurm array task 2 of 8", ""
};

Share job_share(comm::Transport* mpi) {
  Share s;
  if (mpi != nullptr && mpi->size() > 1) {
    s.index = mpi->rank();
    s.count = mpi->size();
    s.what = "MPI rank " + std::to_string(s.index) + " of " + std::to_string(s.count);
    return s;
  }
  const char* id = std::getenv("SLURM_ARRAY_TASK_ID");
  const char* count = std::getenv("SLURM_ARRAY_TASK_COUNT");
  if (id != nullptr && count != nullptr && std::atoi(count) > 1) {
    // The task's position in the array ("--array=0-30:2" has a step of 2).
    const char* min = std::getenv("SLURM_ARRAY_TASK_MIN");
    const char* step = std::getenv("SLURM_ARRAY_TASK_STEP");
    s.index = (std::atoi(id) - (min ? std::atoi(min) : 0)) / std::max(1, step ? std::atoi(step) : 1);
    s.count = std::atoi(count);
    s.what = "Slurm array task " + std::to_string(s.index) + " of " + std::to_string(s.count);
  }
  return s;
}

/// The newest checkpoint in a case's folder (checkpoint_frame[f]_dev[0].h5 or checkpoint_step[s]_dev[0].h5), or "".
std::string newest_checkpoint(const fs::path& folder) {
  static const std::regex name(R"(checkpoint_(frame|step)\[\d+\]_dev\[0\]\.h5)");
  std::string best;
  fs::file_time_type best_time{};
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    if (!e.is_regular_file() || !std::regex_match(e.path().filename().string(), name)) continue;
    const auto t = fs::last_write_time(e.path(), ec);
    if (best.empty() || t > best_time) {
      best = e.path().string();
      best_time = t;
    }
  }
  return best;
}

/// The cases' values as written in the sweep's folder (sweep.json): a folder that holds another sweep is refused.
std::string manifest_text(const Sweep& sweep) {
  std::ostringstream m;
  m << "{\n  \"parameters\": [";
  for (std::size_t p = 0; p < sweep.parameters.size(); ++p)
    m << (p ? ", " : "") << "{\"name\": \"" << sweep.parameters[p].name << "\", \"path\": \"" << sweep.parameters[p].path
      << "\"}";
  m << "],\n  \"cases\": [\n";
  for (std::size_t k = 0; k < sweep.cases.size(); ++k) {
    const SweepCase& c = sweep.cases[k];
    m << "    {\"case\": " << c.id << ", \"values\": [";
    for (std::size_t p = 0; p < c.json.size(); ++p) m << (p ? ", " : "") << c.json[p];
    m << "]}" << (k + 1 < sweep.cases.size() ? "," : "") << "\n";
  }
  m << "  ]\n}\n";
  return m.str();
}

/// A place cases run: one GPU (device >= 0) or the CPU engine (device -1), with its slots and memory.
struct Place {
  int device = -1;
  std::string name;
  int slots = 1;
  int running = 0;
  std::size_t budget = 0;  ///< [B] kSweepMemoryShare of the free memory at the start (0: not limited)
  std::size_t planned = 0; ///< [B] the running cases' plans
};

struct Outcome {
  int case_index = 0;
  RunResult result;
  double wall_s = 0.0;
};

class SweepRunner {
 public:
  SweepRunner(const SweepOptions& o, const EngineSet& engines, const std::vector<std::string>& command_line,
              const Sweep& sweep)
      : o_(o), engines_(engines), command_line_(command_line), sweep_(sweep) {}

  /// One case's scene, checked, and what it costs (throws SceneError naming the case).
  CasePlan plan_case(const SweepCase& c, const SummaryOptions& summary_options, std::vector<std::string>& warnings) const {
    ParseOptions parse;
    parse.allow_unknown_keys = o_.allow_unknown_keys;
    parse.data_dir = o_.data_dir;
    parse.warnings = &warnings;
    CasePlan p;
    p.c = &c;
    p.scene = sweep_case_scene(sweep_, c, io::sweep_case_path(sweep_, c.id).string(), parse);
    if (o_.frames) p.scene.simulation.frames = *o_.frames;
    if (comm::ranks_asked(p.scene) > 1)
      throw SceneError("sweep case " + std::to_string(c.id) + " (" + sweep_case_label(sweep_, c) + "): bodies[].gpu",
                       "bodies on " + std::to_string(comm::ranks_asked(p.scene)) + " GPUs",
                       "every body on GPU 0 (a sweep runs each case on one GPU)");
    const SceneSummary s = summarize_scene(p.scene, summary_options);
    for (const BodySummary& b : s.bodies) p.particles += b.particles;
    p.gpu_bytes = s.gpu_bytes.empty() ? 0 : s.gpu_bytes[0];
    const double duration = p.scene.simulation.frames / p.scene.simulation.fps;
    p.est_steps = s.dt > 0.0 ? std::ceil(duration / s.dt) : 0.0;
    p.est_gpu_s = p.est_steps * s.gpu_ms_per_step * 1e-3;
    p.weight = std::max(1.0, p.est_steps * static_cast<double>(std::max(1LL, p.particles)));
    return p;
  }

  /// Checks every case (throws SceneError naming the first case in order that fails).
  void plan() {
    const auto t0 = std::chrono::steady_clock::now();
    SummaryOptions summary_options;
    if (o_.frame_buffer > 0) summary_options.frame_host_bytes = o_.frame_buffer;
    // Cases are checked and counted on every core (a case's count is serial, one thread each); the first case in
    // case order that fails is reported, and warnings are kept in case order.
    const std::size_t n = sweep_.cases.size();
    plans_.assign(n, CasePlan{});
    std::vector<std::vector<std::string>> warnings(n);
    std::vector<std::exception_ptr> errors(n);
    std::atomic<std::size_t> next{0};
    const std::size_t threads = std::min<std::size_t>(n, std::max(1u, std::thread::hardware_concurrency()));
    const int cores_each = std::max(1, static_cast<int>(std::max(1u, std::thread::hardware_concurrency()) / threads));
    const int main_threads = omp_get_max_threads();
    auto work = [&] {
      omp_set_num_threads(cores_each);  // one case on every core, or a core to each of many
      for (std::size_t k = next++; k < n; k = next++) {
        try {
          plans_[k] = plan_case(sweep_.cases[k], summary_options, warnings[k]);
        } catch (...) {
          errors[k] = std::current_exception();
        }
      }
    };
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work);
    work();
    for (std::thread& t : pool) t.join();
    omp_set_num_threads(main_threads);
    for (const std::exception_ptr& e : errors)
      if (e) std::rethrow_exception(e);
    // One warning of each text, for the whole sweep (every case repeats its base scene's).
    std::set<std::string> seen;
    for (const auto& list : warnings)
      for (const auto& w : list)
        if (seen.insert(w).second) std::cerr << "fbar: warning: " << w << '\n';
    plan_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  int check(const Share& share) const {
    std::cout << "fbar: sweep " << o_.file << " is valid: " << plans_.size() << " cases, folder " << sweep_.output
              << "\n\n";
    std::size_t label_width = 10;
    for (const CasePlan& p : plans_) label_width = std::max(label_width, sweep_case_label(sweep_, *p.c).size());
    std::cout << std::left << std::setw(6) << "case" << std::setw(static_cast<int>(label_width) + 2) << "parameters"
              << std::right << std::setw(13) << "particles" << std::setw(13) << "GPU memory" << std::setw(12)
              << "steps" << std::setw(16) << "GPU time (" << kGpuRateDevice << ")  status\n";
    double total_s = 0.0;
    long long total_particles = 0;
    std::size_t peak_bytes = 0;
    for (const CasePlan& p : plans_) {
      const io::SweepCaseRecord r = io::read_sweep_case(sweep_, p.c->id);
      std::cout << std::left << std::setw(6) << p.c->id << std::setw(static_cast<int>(label_width) + 2)
                << sweep_case_label(sweep_, *p.c) << std::right << std::setw(13) << count_text(p.particles)
                << std::setw(13) << format_bytes(static_cast<double>(p.gpu_bytes)) << std::setw(12)
                << count_text(static_cast<long long>(p.est_steps)) << std::setw(16) << run_detail::format_duration(p.est_gpu_s)
                << "  " << r.status << (runs_here(share, p) ? "" : " (another task's)") << "\n";
      total_s += p.est_gpu_s;
      total_particles += p.particles;
      peak_bytes = std::max(peak_bytes, p.gpu_bytes);
    }
    std::cout << "\ntotal: " << plans_.size() << " cases, " << count_text(total_particles) << " particles, about "
              << run_detail::format_duration(total_s) << " of one " << kGpuRateDevice << " one case at a time (" << kGpuRateRecord
              << "); the largest case plans " << format_bytes(static_cast<double>(peak_bytes)) << "\n";
    const int devices = cuda::device_count();
    for (int d = 0; d < devices; ++d) {
      std::size_t free_bytes = 0, total_bytes = 0;
      cuda::device_memory(d, free_bytes, total_bytes);
      const std::size_t budget = static_cast<std::size_t>(kSweepMemoryShare * static_cast<double>(free_bytes));
      std::cout << "GPU " << d << ": " << format_bytes(static_cast<double>(free_bytes)) << " free; "
                << (peak_bytes > budget ? "the largest case DOES NOT FIT"
                                        : "up to " + std::to_string(std::min<std::size_t>(
                                                         auto_slots(devices),
                                                         peak_bytes ? budget / peak_bytes : kSweepMaxJobsPerGpu)) +
                                              " of the largest cases at once")
                << "\n";
    }
    if (devices == 0) std::cout << "no CUDA device on this machine: the cases would run on the CPU engine\n";
    if (!share.what.empty()) std::cout << share.what << ": runs every " << share.count << "th case from " << share.index << "\n";
    return kExitOk;
  }

  int run(const Share& share, comm::Transport* mpi) {
    std::error_code ec;
    fs::create_directories(sweep_.output, ec);
    if (ec || !fs::is_directory(sweep_.output))
      throw SceneError("output", "\"" + sweep_.output + "\"", "a folder fbar can create (" + ec.message() + ")");
    // The folder's record of the sweep: rank 0 writes or compares it, the other ranks wait for its answer.
    const bool ranks = mpi != nullptr && mpi->size() > 1;
    long long manifest_ok = (!ranks || mpi->rank() == 0) ? (check_manifest() ? 1 : 0) : 1;
    if (ranks) mpi->allreduce_min(&manifest_ok, 1);
    if (manifest_ok == 0) return kExitInput;
    write_plan();
    // The cases this process runs, and how each starts: fresh, from a checkpoint, or not at all (done, failed).
    int done = 0, failed_before = 0;
    for (std::size_t i = 0; i < plans_.size(); ++i) {
      const CasePlan& p = plans_[i];
      if (!runs_here(share, p)) continue;
      const io::SweepCaseRecord r = io::read_sweep_case(sweep_, p.c->id);
      if (r.status == "completed") {
        ++done;
        continue;
      }
      if (r.status == "failed" && !o_.retry_failed) {
        ++failed_before;
        std::cerr << "fbar: sweep: case " << p.c->id << " (" << sweep_case_label(sweep_, *p.c) << ") failed before: "
                  << r.message << " (--retry-failed runs it again)\n";
        continue;
      }
      std::string restart;
      if (r.status == "interrupted" || r.status == "running") {
        restart = r.checkpoint;
        if (restart.empty() || !fs::is_regular_file(restart, ec))
          restart = newest_checkpoint(io::sweep_case_path(sweep_, p.c->id));
      }
      pending_.push_back({i, restart});
      pending_weight_ += p.weight;
    }
    // Largest first: the long cases start early and the short ones fill the gaps.
    std::stable_sort(pending_.begin(), pending_.end(),
                     [&](const Pending& a, const Pending& b) { return plans_[a.index].weight > plans_[b.index].weight; });
    make_places(ranks);
    if (places_.empty()) throw std::runtime_error("sweep: no GPU to run the cases on (--backend=cpu runs them on the CPU)");
    if (!o_.quiet) {
      std::cout << "fbar: sweep " << o_.file << ": " << pending_.size() << " cases to run";
      if (done > 0) std::cout << ", " << done << " completed before";
      if (failed_before > 0) std::cout << ", " << failed_before << " failed before";
      if (!share.what.empty()) std::cout << " (" << share.what << ")";
      std::cout << "; on";
      for (const Place& pl : places_) std::cout << " " << pl.name << " (" << pl.slots << " at once)";
      std::cout << "; each case's log: " << sweep_.output << "/case_*/log.txt" << std::endl;
    }
    const auto t_run = std::chrono::steady_clock::now();
    const int failed = schedule();
    const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_run).count();
    const int signal = stop_signal();
    if (signal != 0) {
      std::cerr << "fbar: sweep stopped by " << signal_name(signal) << ": " << completed_ << " cases completed, "
                << interrupted_ << " interrupted with a checkpoint; the same command resumes the sweep\n";
      return 128 + signal;
    }
    if (ranks) mpi->barrier();
    const bool gather_here = share.count == 1 || (ranks && mpi->rank() == 0);
    if (gather_here) {
      const auto t_gather = std::chrono::steady_clock::now();
      const io::SweepGathered g = io::gather_sweep(sweep_);
      const double gather_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_gather).count();
      if (!o_.quiet)
        std::cout << "fbar: sweep: " << g.completed << " of " << sweep_.cases.size() << " cases gathered, "
                  << count_text(g.rows) << " rows: " << (fs::path(sweep_.output) / "sweep_table.csv").string()
                  << ", sweep_summary.csv, sweep_cases.csv, sweep_table.h5; cases checked in " << std::fixed
                  << std::setprecision(2) << plan_s_ << " s, run in " << run_s << " s, gathered in " << gather_s
                  << " s" << std::defaultfloat << std::endl;
    } else if (mpi == nullptr && !o_.quiet) {
      std::cout << "fbar: sweep: " << share.what << " done; after every task: fbar --sweep=" << o_.file
                << " --gather" << std::endl;
    }
    return failed + failed_before > 0 ? kExitRuntime : kExitOk;
  }

 private:
  struct Pending {
    std::size_t index;
    std::string restart;
  };

  bool runs_here(const Share& share, const CasePlan& p) const {
    const int id = p.c->id;
    if (!o_.cases.empty() && std::find(o_.cases.begin(), o_.cases.end(), id) == o_.cases.end()) return false;
    return id % share.count == share.index;
  }

  int auto_slots(int devices) const {
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    return std::clamp(cores / std::max(1, devices) - 1, 1, kSweepMaxJobsPerGpu);
  }

  bool check_manifest() const {
    const fs::path path = fs::path(sweep_.output) / "sweep.json";
    const std::string text = manifest_text(sweep_);
    std::ifstream in(path, std::ios::binary);
    if (in) {
      std::ostringstream old;
      old << in.rdbuf();
      if (old.str() == text) return true;
      std::cerr << "fbar: error: " << path.string() << " holds another sweep (its parameters or cases differ from "
                << o_.file << "'s): give this sweep another output (--output or \"output\") or remove the folder\n";
      return false;
    }
    std::ofstream out(path, std::ios::binary);
    out << text;
    if (!out.flush()) {
      std::cerr << "fbar: error: cannot write " << path.string() << '\n';
      return false;
    }
    return true;
  }

  /// sweep_plan.csv: every case's particles, planned device memory and estimated steps and time (what --check
  /// prints), for scripts. Written whole and renamed: tasks of a job array write the same file.
  void write_plan() const {
    const fs::path path = fs::path(sweep_.output) / "sweep_plan.csv";
    const fs::path part = path.string() + ".part" + std::to_string(::getpid());
    {
      std::ofstream f(part, std::ios::binary);
      f << "case";
      for (const auto& q : sweep_.parameters) f << "," << q.name;
      f << ",particles,gpu_bytes,estimated_steps,estimated_gpu_time [s]\n";
      for (const CasePlan& p : plans_) {
        f << p.c->id;
        for (const auto& l : p.c->labels) f << "," << io::csv_field(l);
        f << "," << p.particles << "," << p.gpu_bytes << "," << static_cast<long long>(p.est_steps) << ","
          << p.est_gpu_s << "\n";
      }
    }
    std::error_code ec;
    fs::rename(part, path, ec);
  }

  void make_places(bool mpi_ranks) {
    if (!o_.gpu) {
      Place p;
      p.name = "the CPU engine";
      p.slots = std::max(1, o_.jobs);
      places_.push_back(p);
      return;
    }
    const int visible = cuda::device_count();
    std::vector<int> devices;
    if (mpi_ranks) {  // one rank per GPU of its node
      devices.push_back(o_.local_rank % std::max(1, visible));
    } else {
      const int n = o_.gpus > 0 ? std::min(o_.gpus, visible) : visible;
      for (int d = 0; d < n; ++d) devices.push_back(d);
    }
    for (int d : devices) {
      Place p;
      p.device = d;
      p.name = "GPU " + std::to_string(d);
      p.slots = o_.jobs > 0 ? o_.jobs : auto_slots(static_cast<int>(devices.size()));
      std::size_t free_bytes = 0, total_bytes = 0;
      cuda::device_memory(d, free_bytes, total_bytes);
      p.budget = static_cast<std::size_t>(kSweepMemoryShare * static_cast<double>(free_bytes));
      places_.push_back(p);
    }
  }

  /// Starts cases while slots and memory allow, until every case has run or a stop is requested; returns the
  /// number of cases that failed.
  int schedule() {
    const auto t0 = std::chrono::steady_clock::now();
    std::mutex m;
    std::condition_variable cv;
    std::vector<Outcome> finished;
    std::vector<std::thread> threads;
    std::vector<int> place_of(plans_.size(), -1);
    int running = 0, failed = 0;
    std::size_t next = 0;  // pending_ before next: started
    std::vector<bool> started(pending_.size(), false);
    const StopSignals stop_signals;  // one for the sweep: a signal stops every running case at its next step
    std::unique_lock<std::mutex> lock(m);
    for (;;) {
      // Start what fits: for each free slot, the largest case not started whose plan fits the place's memory (a
      // case larger than the whole budget runs alone, and its own check reports it).
      bool launched = true;
      while (stop_signal() == 0 && launched) {
        launched = false;
        for (std::size_t pl = 0; pl < places_.size(); ++pl) {
          Place& place = places_[pl];
          if (place.running >= place.slots) continue;
          for (std::size_t t = next; t < pending_.size(); ++t) {
            if (started[t]) continue;
            const CasePlan& p = plans_[pending_[t].index];
            const bool fits = place.budget == 0 || place.running == 0 || place.planned + p.gpu_bytes <= place.budget;
            if (!fits) continue;
            started[t] = true;
            while (next < pending_.size() && started[next]) ++next;
            place.running += 1;
            place.planned += p.gpu_bytes;
            place_of[pending_[t].index] = static_cast<int>(pl);
            ++running;
            threads.emplace_back([this, &m, &cv, &finished, t, device = place.device, slots = place.slots] {
              Outcome out = run_case(pending_[t].index, pending_[t].restart, device, slots);
              std::lock_guard<std::mutex> g(m);
              finished.push_back(std::move(out));
              cv.notify_all();
            });
            launched = true;
            break;
          }
        }
      }
      if (running == 0) break;
      cv.wait_for(lock, std::chrono::seconds(1), [&] { return !finished.empty(); });
      for (Outcome& out : finished) {
        --running;
        const CasePlan& p = plans_[static_cast<std::size_t>(out.case_index)];
        Place& place = places_[static_cast<std::size_t>(place_of[static_cast<std::size_t>(out.case_index)])];
        place.running -= 1;
        place.planned -= p.gpu_bytes;
        const std::string who = "case " + std::to_string(p.c->id) + " (" + sweep_case_label(sweep_, *p.c) + ")";
        if (out.result.exit_code == kExitOk) {
          ++completed_;
          ran_weight_ += p.weight;
        } else if (out.result.stop_signal != 0) {
          ++interrupted_;
        } else {
          ++failed;
          ran_weight_ += p.weight;
          std::cerr << "fbar: sweep: " << who << " failed: "
                    << (out.result.message.empty() ? "the run failed" : out.result.message) << '\n';
        }
        if (!o_.quiet && out.result.stop_signal == 0) {
          const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          const double left = pending_weight_ - ran_weight_;
          const double eta = ran_weight_ > 0 ? elapsed * left / ran_weight_ : NAN;
          std::cout << "fbar: sweep: " << who << (out.result.exit_code == kExitOk ? " completed" : " failed")
                    << " in " << run_detail::format_duration(out.wall_s) << "; " << completed_ + failed << " of " << pending_.size()
                    << " done (" << failed << " failed), " << running << " running, ETA " << run_detail::format_duration(eta)
                    << std::endl;
        }
      }
      finished.clear();
    }
    lock.unlock();
    for (std::thread& th : threads) th.join();
    return failed;
  }

  /// One case in its folder: scene.json, log.txt (its progress lines), run.json, and the run itself.
  Outcome run_case(std::size_t index, const std::string& restart, int device, int slots) {
    const CasePlan& p = plans_[index];
    Outcome out;
    out.case_index = static_cast<int>(index);
    const auto t0 = std::chrono::steady_clock::now();
    const fs::path folder = io::sweep_case_path(sweep_, p.c->id);
    std::error_code ec;
    fs::create_directories(folder, ec);
    // Each case's OpenMP work (sampling, the CPU engine) gets its share of the cores.
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    omp_set_num_threads(std::max(1, cores / std::max(1, slots)));
    std::ofstream log(folder / "log.txt", std::ios::app);
    {
      std::ofstream scene_file(folder / "scene.json", std::ios::binary);
      scene_file << sweep_case_scene_json(sweep_, *p.c, folder.string());
    }
    log << "fbar: sweep " << o_.file << ", case " << p.c->id << " (" << sweep_case_label(sweep_, *p.c) << ")"
        << (restart.empty() ? "" : ", restarted from " + restart) << ", on "
        << (device >= 0 ? "GPU " + std::to_string(device) : std::string("the CPU engine")) << ", " << utc_now()
        << std::endl;
    RunOptions ro;
    ro.quiet = false;
    ro.log = &log;
    ro.gpu = device;
    if (o_.frame_buffer > 0) ro.frame_host_bytes = o_.frame_buffer;
    ro.restart = restart;
    RunJson run_json;
    const std::string started = utc_now();
    std::string error;
    if (!run_json.start(folder / "run.json",
                        run_json_text(p.scene, command_line_, started, 0.0, RunResult{}, device >= 0, 1, true), error)) {
      out.result.exit_code = kExitRuntime;
      out.result.message = error;
      return out;
    }
    out.result = run_guarded([&] { return device >= 0 ? engines_.run_gpu(p.scene, ro) : run_cpu(p.scene, ro); });
    out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    finish_run_json(run_json, run_json_text(p.scene, command_line_, started, out.wall_s, out.result, device >= 0, 1, false),
                    out.result);
    if (!out.result.message.empty()) log << "fbar: " << out.result.message << std::endl;
    return out;
  }

  const SweepOptions& o_;
  const EngineSet& engines_;
  const std::vector<std::string>& command_line_;
  const Sweep& sweep_;
  std::vector<CasePlan> plans_;
  std::vector<Pending> pending_;
  std::vector<Place> places_;
  int completed_ = 0, interrupted_ = 0;
  double plan_s_ = 0.0;
  double pending_weight_ = 0.0, ran_weight_ = 0.0;  ///< the cases to run, and those run
};

}  // namespace

int run_sweep(const SweepOptions& options, const EngineSet& engines, const std::vector<std::string>& command_line) {
  Sweep sweep = parse_sweep_file(options.file);
  if (options.output) sweep.output = *options.output;
  for (int id : options.cases)
    if (id < 0 || id >= static_cast<int>(sweep.cases.size()))
      throw SceneError("--cases", std::to_string(id),
                       "case numbers from 0 to " + std::to_string(sweep.cases.size() - 1) + " (the sweep's cases)");
  if (options.gather) {
    const io::SweepGathered g = io::gather_sweep(sweep);
    std::cout << "fbar: sweep: " << g.completed << " of " << sweep.cases.size() << " cases gathered, "
              << count_text(g.rows) << " rows in " << (fs::path(sweep.output) / "sweep_table.csv").string() << "\n";
    return kExitOk;
  }
  SweepRunner runner(options, engines, command_line, sweep);
  runner.plan();
  std::unique_ptr<comm::Transport> mpi;
  if (comm::launched_by_mpi()) {
#ifdef FBAR_HAS_MPI
    mpi = std::make_unique<comm::MpiTransport>();
#endif
  }
  const Share share = job_share(mpi.get());
  if (options.check) return (mpi && mpi->rank() != 0) ? kExitOk : runner.check(share);
  return runner.run(share, mpi.get());
}

}  // namespace fbar
