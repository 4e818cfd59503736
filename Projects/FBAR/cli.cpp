// The fbar command line: options, scene loading and validation, --check report, and a run with its run.json.
#include "cli.h"

#include <rapidjson/document.h>
#include <rapidjson/writer.h>
#include <rapidjson/stringbuffer.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "MnSystem/Cuda/device_query.h"
#include "engine/engine_api.h"
#include "comm/device_transport.h"
#include "comm/mpi_transport.h"
#include "comm/placement.h"
#include "engine/stop_request.h"
#include "engine/memory_plan.h"
#include "scene/scene_parse.h"
#include "engine/check_report.h"
#include "run_record.h"
#include "sweep_run.h"
#include "physics/constitutive_models.cuh"

#ifndef FBAR_VERSION
#define FBAR_VERSION "unknown"
#endif

namespace fbar {

namespace {

namespace fs = std::filesystem;
namespace rj = rapidjson;


/// Why a program has no GPU engine, for its messages: a build without the CUDA toolkit, or (with it) a program
/// that links the front end alone (the CLI tests).
#if defined(FBAR_HAS_CUDA)
constexpr const char* kNoGpuEngineWhy = "";
#else
constexpr const char* kNoGpuEngineWhy = "; fbar was configured without the CUDA toolkit";
#endif

/// A command-line mistake (exit 1).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct CliOptions {
  std::string file = "scene.json";
  bool check = false;
  Backend backend = Backend::Auto;
  std::optional<std::string> output;
  std::optional<int> frames;
  bool quiet = false;
  int gpus = 1;  ///< GPU ranks of one process (threads); under mpirun each process is one rank
  bool halo_overlap = false;  ///< --halo-overlap=on: GPU ranks overlap the halo sums with G2P2G
  bool keep_gpus = false;     ///< --keep-gpus: --gpus=N runs N ranks even for a scene too small to gain from them
  std::size_t frame_buffer = kFrameHostBytes;  ///< --frame-buffer=MiB: host memory of one body's frame download [B]
  bool allow_unknown_keys = false;
  std::string data_dir;
  std::string restart;  ///< --restart=FILE: a checkpoint to continue from
  std::string sweep;    ///< --sweep=FILE: run a sweep (sweep_run.h) instead of one scene
  int jobs = 0;         ///< --jobs=N: a sweep's cases at once per GPU
  std::vector<int> cases;  ///< --cases=LIST: a sweep's cases to run
  bool gather = false;
  bool retry_failed = false;
  bool gpus_given = false;
  bool file_given = false;  ///< a scene file named on the command line
  bool version = false;
  bool help = false;
};

const char* kHelp =
    "usage: fbar [options] [scene.json]\n"
    "\n"
    "Runs a material point method scene (docs/user_guide.md). Without a file, runs ./scene.json.\n"
    "\n"
    "options:\n"
    "  -f FILE, --file=FILE    scene file (also the first positional argument; default: scene.json)\n"
    "  --check                 validate the scene, print it resolved with units, particle counts per body,\n"
    "                          the time step and memory estimates (CPU and per GPU); do not simulate\n"
    "  --backend=auto|gpu|cpu  engine: auto (default) uses the GPU engine when the build has one and a CUDA\n"
    "                          device it has code for is present, otherwise the CPU reference engine (with a\n"
    "                          warning that says why)\n"
    "  --output=DIR            write frames and run.json to DIR (overrides simulation.save_path; created if missing)\n"
    "  --frames=N              number of frames to simulate (overrides simulation.frames; N >= 1)\n"
    "  --quiet                 no progress lines (warnings and errors are still printed)\n"
    "  --gpus=N                decompose the scene over N GPU ranks of this process, one thread per rank on\n"
    "                          GPU (rank mod visible GPUs), NCCL between them (default 1; more ranks than GPUs\n"
    "                          share them through host-ordered peer copies: for testing). Under mpirun / srun\n"
    "                          each process is one rank on its node's GPU (local rank mod visible GPUs). A scene\n"
    "                          below 2000000 particles (a mesh element counting as 5) steps faster on one GPU:\n"
    "                          --gpus=N runs it on one (with a note), unless it places bodies on GPUs\n"
    "  --keep-gpus             --gpus=N runs N ranks whatever the scene's size (tests, measurements)\n"
    "  --halo-overlap=on|off   GPU ranks: run G2P2G on the particle blocks next to the cuts first and the rest\n"
    "                          while the halo sums travel (default off: between GPUs of one node the sums are\n"
    "                          faster than the overlap costs; on can pay between nodes on slow links)\n"
    "  --frame-buffer=MiB      GPU engine: host memory one body's frame or checkpoint download may take\n"
    "                          (default 1024); a larger frame is streamed to its file a piece at a time (the\n"
    "                          next frame's capture waits until it is written), a larger checkpoint a range of\n"
    "                          particle IDs at a time (the run waits until it is written)\n"
    "  --allow-unknown-keys    unknown keys (a misspelling, a key the object does not have) are warnings, not\n"
    "                          errors (keys the chosen law or object does not use are warnings already)\n"
    "  --data-dir=DIR          where geometry and motion files are looked up first (then $AssetDirPath, the\n"
    "                          scene's folder and the source tree's Data/)\n"
    "  --restart=FILE          continue the run from a checkpoint (checkpoint_frame[f]_dev[0].h5 or\n"
    "                          checkpoint_step[s]_dev[0].h5 in the run's output; the other ranks' files are found\n"
    "                          by their dev[d]): frames, sensor and tracker rows continue as if never stopped\n"
    "  --sweep=FILE            run a sweep: the cases of FILE (a scene and the parameters that vary,\n"
    "                          docs/user_guide.md §10), each in its folder, several at once on each GPU where\n"
    "                          memory allows, over --gpus=N GPUs (default: every visible one) or one per MPI\n"
    "                          rank or Slurm array task; completed cases are skipped and stopped ones resumed\n"
    "                          from their checkpoints; then one table of every case's sensors. With --check:\n"
    "                          every case checked and listed with its particles, memory and time\n"
    "  --jobs=N                --sweep: cases at once per GPU (default: as many as memory and cores allow; on\n"
    "                          the CPU engine 1)\n"
    "  --cases=LIST            --sweep: only these cases (\"0,3,5-9\")\n"
    "  --gather                --sweep: only gather the cases' sensors into the tables (after a job array)\n"
    "  --retry-failed          --sweep: run failed cases again (by default they are reported and skipped)\n"
    "  --version               print the version and exit\n"
    "  -h, --help              print this help and exit\n"
    "\n"
    "exit codes: 0 success, 1 invalid scene, input file or option, 2 run-time failure (NaN, CFL violation,\n"
    "capacity, device or output error); messages go to stderr as `fbar: error: ...`. SIGINT (Ctrl-C) or SIGTERM\n"
    "stops the run after the step in progress, writes a checkpoint (--restart continues from it) and run.json\n"
    "(status \"interrupted\") and exits with 128 + the signal number (130, 143); a second signal ends the process\n"
    "at once (a SIGTERM repeated within 2 s counts as the same one).\n";

const std::vector<std::string_view> kLongOptions = {"--file",   "--check",  "--backend",           "--output",
                                                    "--frames", "--quiet",  "--allow-unknown-keys", "--data-dir",
                                                    "--version", "--help",  "--gpus", "--restart", "--halo-overlap",
                                                    "--keep-gpus", "--frame-buffer", "--sweep", "--jobs",
                                                    "--cases", "--gather", "--retry-failed"};

/// "0,3,5-9" as case numbers.
std::vector<int> parse_case_list(const std::string& v) {
  std::vector<int> out;
  std::size_t i = 0;
  const std::string expected = "--cases: got '" + v + "'; expected case numbers such as 0,3,5-9";
  while (i < v.size()) {
    const std::size_t end = v.find(',', i);
    const std::string item = v.substr(i, end == std::string::npos ? std::string::npos : end - i);
    const std::size_t dash = item.find('-');
    auto number = [&](const std::string& t) {
      if (t.empty() || t.size() > 7 || t.find_first_not_of("0123456789") != std::string::npos) throw UsageError(expected);
      return std::stoi(t);
    };
    const int lo = number(dash == std::string::npos ? item : item.substr(0, dash));
    const int hi = dash == std::string::npos ? lo : number(item.substr(dash + 1));
    if (hi < lo || hi - lo > 1000000) throw UsageError(expected);
    for (int k = lo; k <= hi; ++k) out.push_back(k);
    if (end == std::string::npos) break;
    i = end + 1;
    if (i == v.size()) throw UsageError(expected);
  }
  if (out.empty()) throw UsageError(expected);
  return out;
}

CliOptions parse_arguments(int argc, char** argv) {
  CliOptions o;
  auto set_file = [&](const std::string& f) {
    if (o.file_given) throw UsageError("more than one scene file given ('" + o.file + "' and '" + f + "')");
    if (f.empty()) throw UsageError("empty scene file name");
    o.file = f;
    o.file_given = true;
  };
  bool options_done = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (options_done || arg.empty() || arg[0] != '-' || arg == "-") {
      set_file(arg);
      continue;
    }
    if (arg == "--") {
      options_done = true;
      continue;
    }
    // --name=value or --name value (for options that take one).
    std::string name = arg, value;
    bool has_value = false;
    if (const auto eq = arg.find('='); eq != std::string::npos && arg.rfind("--", 0) == 0) {
      name = arg.substr(0, eq);
      value = arg.substr(eq + 1);
      has_value = true;
    }
    auto take_value = [&]() -> std::string {
      if (has_value) return value;
      if (i + 1 >= argc) throw UsageError("option " + name + " needs a value");
      return argv[++i];
    };
    auto no_value = [&]() {
      if (has_value) throw UsageError("option " + name + " takes no value");
    };
    if (name == "-f" || name == "--file") {
      set_file(take_value());
    } else if (name == "--check") {
      no_value();
      o.check = true;
    } else if (name == "--backend") {
      const std::string b = take_value();
      if (b == "auto") o.backend = Backend::Auto;
      else if (b == "gpu") o.backend = Backend::Gpu;
      else if (b == "cpu") o.backend = Backend::Cpu;
      else throw UsageError("--backend: got '" + b + "'; expected auto, gpu or cpu");
    } else if (name == "--output") {
      o.output = take_value();
      if (o.output->empty()) throw UsageError("--output: expected a directory");
    } else if (name == "--frames") {
      const std::string v = take_value();
      std::size_t used = 0;
      long long n = 0;
      try {
        n = std::stoll(v, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != v.size() || v.empty() || n < 1 || n > 2147483647)
        throw UsageError("--frames: got '" + v + "'; expected an integer >= 1");
      o.frames = static_cast<int>(n);
    } else if (name == "--quiet") {
      no_value();
      o.quiet = true;
    } else if (name == "--gpus") {
      const std::string v = take_value();
      std::size_t used = 0;
      long long n = 0;
      try {
        n = std::stoll(v, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != v.size() || v.empty() || n < 1 || n > 1024)
        throw UsageError("--gpus: got '" + v + "'; expected an integer from 1 to 1024");
      o.gpus = static_cast<int>(n);
      o.gpus_given = true;
    } else if (name == "--sweep") {
      o.sweep = take_value();
      if (o.sweep.empty()) throw UsageError("--sweep: expected a sweep file");
    } else if (name == "--jobs") {
      const std::string v = take_value();
      if (v.empty() || v.size() > 4 || v.find_first_not_of("0123456789") != std::string::npos || std::stoi(v) < 1)
        throw UsageError("--jobs: got '" + v + "'; expected an integer from 1 to 9999");
      o.jobs = std::stoi(v);
    } else if (name == "--cases") {
      o.cases = parse_case_list(take_value());
    } else if (name == "--gather") {
      no_value();
      o.gather = true;
    } else if (name == "--retry-failed") {
      no_value();
      o.retry_failed = true;
    } else if (name == "--keep-gpus") {
      no_value();
      o.keep_gpus = true;
    } else if (name == "--halo-overlap") {
      const std::string v = take_value();
      if (v != "on" && v != "off") throw UsageError("--halo-overlap: got '" + v + "'; expected on or off");
      o.halo_overlap = v == "on";
    } else if (name == "--frame-buffer") {
      const std::string v = take_value();
      std::size_t used = 0;
      double mib = 0.0;
      try {
        mib = std::stod(v, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != v.size() || v.empty() || !(mib >= 0.001 && mib <= 1048576.0))
        throw UsageError("--frame-buffer: got '" + v + "'; expected a size in MiB from 0.001 to 1048576");
      o.frame_buffer = static_cast<std::size_t>(mib * 1048576.0);
    } else if (name == "--allow-unknown-keys") {
      no_value();
      o.allow_unknown_keys = true;
    } else if (name == "--data-dir") {
      o.data_dir = take_value();
    } else if (name == "--restart") {
      o.restart = take_value();
      if (o.restart.empty()) throw UsageError("--restart: expected a checkpoint file");
    } else if (name == "--version") {
      no_value();
      o.version = true;
    } else if (name == "-h" || name == "--help") {
      no_value();
      o.help = true;
    } else {
      std::string message = "unknown option '" + name + "'";
      const std::string near = closest_key(name, kLongOptions);
      if (!near.empty()) message += "; did you mean '" + near + "'?";
      throw UsageError(message);
    }
  }
  return o;
}

/// fbar --check: the scene's report with, when a device is present, its free memory and whether the plan fits.
int check_scene(const CliOptions& o, const Scene& scene, const EngineSet& engines) {
  SummaryOptions summary_options;
  summary_options.frame_host_bytes = o.frame_buffer;
  SceneSummary summary = summarize_scene(scene, summary_options);
  // With a device present: its free memory, and whether the plan fits (a run that does not fit is refused).
  const int devices = cuda::device_count();
  for (std::size_t g = 0; devices > 0 && g < summary.gpu_plans.size(); ++g) {
    if (static_cast<int>(g) >= devices) {
      summary.device_notes.push_back("GPU " + std::to_string(g) + ": not present on this machine (" +
                                     std::to_string(devices) + " CUDA devices)");
      continue;
    }
    std::size_t free_bytes = 0, total_bytes = 0;
    cuda::device_memory(static_cast<int>(g), free_bytes, total_bytes);
    cuda::DeviceInfo info;
    cuda::device_info(static_cast<int>(g), info);
    const std::string fit = memory_fit_message(summary.gpu_plans[g], free_bytes, total_bytes, scene,
                                               "GPU " + std::to_string(g));
    summary.device_notes.push_back("GPU " + std::to_string(g) + " (" + info.name + "): " +
                                   format_bytes(static_cast<double>(free_bytes)) + " free of " +
                                   format_bytes(static_cast<double>(total_bytes)) + "; " +
                                   (fit.empty() ? std::string("the scene fits") : "DOES NOT FIT: " + fit));
  }
  if (engines.run_gpu == nullptr)
    summary.device_notes.push_back(std::string("no GPU engine in this build") + kNoGpuEngineWhy +
                                   ": device memory not checked");
  else if (devices == 0)
    summary.device_notes.push_back("no CUDA device on this machine: free memory not checked");
  for (int g = 0; engines.run_gpu != nullptr && engines.gpu_fit != nullptr && g < devices; ++g) {
    const GpuCodeFit fit = engines.gpu_fit(g);
    if (!fit.runs || fit.jit) summary.device_notes.push_back(fit.message);
  }
  std::cout << "fbar " << FBAR_VERSION << ": scene " << o.file << " is valid\n";
  print_scene_report(std::cout, scene, summary);
  return kExitOk;
}

/// --gpus=N: one thread per GPU rank (rank r on GPU r % devices); a rank that ends by an exception releases the
/// others from their collectives. The result is rank 0's, or that of the first rank that failed on its own.
RunResult run_thread_ranks(const Scene& scene, const RunOptions& options, const EngineSet& engines, int ranks,
                           int devices, bool shared_gpus) {
  // One thread per GPU rank; a rank that ends by an exception releases the others from their collectives.
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(ranks);
  std::vector<RunResult> results(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      RunOptions mine = options;
      mine.transport = hosts[static_cast<std::size_t>(r)].get();
      mine.gpu = r % devices;
      mine.shared_gpus = shared_gpus;
      RunResult& out = results[static_cast<std::size_t>(r)];
      out = engines.run_gpu(scene, mine);
      if (out.from_exception) mine.transport->abort(out.exit_code);
    });
  for (std::thread& t : threads) t.join();
  RunResult result = results[0];
  for (int r = 0; r < ranks; ++r)  // the first rank that failed on its own explains the stop
    if (results[static_cast<std::size_t>(r)].from_exception &&
        results[static_cast<std::size_t>(r)].message.find("another rank") == std::string::npos) {
      result = results[static_cast<std::size_t>(r)];
      result.message = "rank " + std::to_string(r) + ": " + result.message;
      break;
    }
  return result;
}

/// An environment variable's integer value: the first of `names` that is set, otherwise `fallback`.
int env_int(const std::vector<const char*>& names, int fallback) {
  for (const char* n : names)
    if (const char* v = std::getenv(n)) return std::atoi(v);
  return fallback;
}
/// Where MPI launchers (Open MPI, Slurm, MPICH / Intel MPI) put a process's rank on its node.
const std::vector<const char*> kLocalRankVariables = {"OMPI_COMM_WORLD_LOCAL_RANK", "SLURM_LOCALID",
                                                      "MPI_LOCALRANKID"};

/// The engine of a run: --backend=gpu needs the GPU engine, a device and code for it; auto takes the GPU engine when
/// all three are there. False: --backend=gpu cannot be met (the error is printed).
bool choose_gpu_engine(const CliOptions& o, const EngineSet& engines, bool& gpu) {
  gpu = false;
  if (o.backend == Backend::Cpu) return true;
  // Why the GPU engine cannot run here ("" when it can): no engine, no device, or no code for a device it would use.
  std::string why;
  if (engines.run_gpu == nullptr) {
    if (o.backend == Backend::Gpu) {
      std::cerr << "fbar: error: --backend=gpu: the GPU engine is not available in this build (fbar "
                << FBAR_VERSION << " has the CPU reference engine only" << kNoGpuEngineWhy << "; use --backend=cpu "
                << "or auto)\n";
      return false;
    }
    std::cerr << "fbar: warning: no GPU engine in this build; running on the CPU reference engine (--backend=cpu "
                 "silences this" << kNoGpuEngineWhy << ")\n";
    return true;
  }
  const int devices = cuda::device_count();
  if (devices == 0) {
    why = cuda::no_device_reason();
  } else if (engines.gpu_fit != nullptr) {
    // The devices this process would use (the check loads a kernel there, which makes the device's context): 0 ..
    // --gpus-1 (rank r on GPU r mod devices), or under a launcher its node-local rank's GPU.
    int first = 0, used = std::min(o.gpus, devices);
    if (comm::launched_by_mpi()) {
      first = env_int(kLocalRankVariables, 0) % devices;
      used = 1;
    }
    for (int d = first; d < first + used && why.empty(); ++d) {
      const GpuCodeFit fit = engines.gpu_fit(d);
      if (!fit.runs) why = fit.message;
      else if (fit.jit && d == first) std::cerr << "fbar: note: " << fit.message << '\n';
    }
  }
  if (why.empty()) {
    gpu = true;
    return true;
  }
  if (o.backend == Backend::Gpu) {
    std::cerr << "fbar: error: --backend=gpu: " << why << " (use --backend=cpu or auto)\n";
    return false;
  }
  std::cerr << "fbar: warning: " << why << "; running on the CPU reference engine (--backend=cpu silences this)\n";
  return true;
}

/// fbar --sweep=FILE: the sweep's options from the command line's, the engine chosen as for one scene.
int sweep(const CliOptions& o, const std::vector<std::string>& command_line, const EngineSet& engines) {
  if (o.file_given) throw UsageError("--sweep runs the sweep's scene: give no scene file with it");
  SweepOptions s;
  s.file = o.sweep;
  s.check = o.check;
  s.gather = o.gather;
  s.retry_failed = o.retry_failed;
  s.quiet = o.quiet;
  s.gpus = o.gpus_given ? o.gpus : 0;
  s.jobs = o.jobs;
  s.cases = o.cases;
  s.output = o.output;
  s.frames = o.frames;
  s.frame_buffer = o.frame_buffer;
  s.allow_unknown_keys = o.allow_unknown_keys;
  s.data_dir = o.data_dir;
  s.local_rank = env_int(kLocalRankVariables, 0);
  if (!o.check && !o.gather && !choose_gpu_engine(o, engines, s.gpu)) return kExitRuntime;
  return run_sweep(s, engines, command_line);
}

int run(const CliOptions& o, const std::vector<std::string>& command_line, const EngineSet& engines) {
  if (!o.sweep.empty()) return sweep(o, command_line, engines);
  if (o.jobs > 0 || !o.cases.empty() || o.gather || o.retry_failed)
    throw UsageError("--jobs, --cases, --gather and --retry-failed go with --sweep");
  std::vector<std::string> warnings;
  ParseOptions parse;
  parse.allow_unknown_keys = o.allow_unknown_keys;
  parse.data_dir = o.data_dir;
  parse.warnings = &warnings;
  Scene scene = parse_scene_file(o.file, parse);
  for (const auto& w : warnings) std::cerr << "fbar: warning: " << w << '\n';
  if (o.frames) scene.simulation.frames = *o.frames;
  if (o.output) scene.simulation.save_path = *o.output;

  if (o.check) return check_scene(o, scene, engines);

  bool gpu = false;
  if (!choose_gpu_engine(o, engines, gpu)) return kExitRuntime;
  // Ranks: under mpirun / srun one per process (MPI); otherwise one, or --gpus=N GPU ranks as threads of this process.
  // Either engine decomposes the scene over them.
  std::unique_ptr<comm::Transport> transport;
  if (comm::launched_by_mpi()) {
#ifdef FBAR_HAS_MPI
    transport = std::make_unique<comm::MpiTransport>();
#else
    std::cerr << "fbar: error: started by an MPI launcher, but this build has no MPI (install an MPI development "
                 "package, e.g. libopenmpi-dev, and configure again)\n";
    return kExitRuntime;
#endif
  }
  const int mpi_ranks = transport ? transport->size() : 1;
  const int rank = transport ? transport->rank() : 0;
  int gpus = o.gpus;
  if (gpus > 1 && (mpi_ranks > 1 || !gpu)) {
    if (rank == 0)
      std::cerr << "fbar: error: --gpus=" << gpus
                << (mpi_ranks > 1 ? ": under an MPI launcher every process is one GPU rank (drop --gpus)"
                                  : ": the scene runs on the CPU reference engine (use --backend=gpu on a machine "
                                    "with a CUDA device)")
                << '\n';
    return kExitInput;
  }
  const int devices = gpu ? cuda::device_count() : 0;
  int local_gpu = -1;
  if (gpu && mpi_ranks > 1) {  // one MPI rank per GPU of its node, NCCL between them
    const int local_rank = env_int(kLocalRankVariables, rank);
    const int local_size =
        env_int({"OMPI_COMM_WORLD_LOCAL_SIZE", "SLURM_NTASKS_PER_NODE", "MPI_LOCALNRANKS"}, mpi_ranks);
    std::string why;
    if (!comm::nccl_available()) why = "this build has no NCCL (install it and configure again)";
    else if (local_size > devices)
      why = std::to_string(local_size) + " ranks on this node and " + std::to_string(devices) +
            " visible GPUs: start one rank per GPU (or --backend=cpu)";
    if (!why.empty()) {
      if (rank == 0) std::cerr << "fbar: error: " << mpi_ranks << " MPI ranks on the GPU engine: " << why << '\n';
      return kExitInput;
    }
    local_gpu = local_rank % devices;
  }
  // A scene too small to gain from several GPUs runs on one (kMultiGpuMinParticles); under an MPI launcher the
  // ranks are the launcher's: rank 0 says so.
  if (gpu && (gpus > 1 || mpi_ranks > 1) && !o.keep_gpus && comm::ranks_asked(scene) <= 1 && rank == 0) {
    const long long work = scene_work_particles(scene, kMultiGpuMinParticles);
    if (work < kMultiGpuMinParticles) {
      const std::string asked = mpi_ranks > 1 ? std::to_string(mpi_ranks) + " MPI ranks" : "--gpus=" + std::to_string(gpus);
      std::cerr << "fbar: note: " << asked << ": the scene has " << work
                << " particles (a mesh element counted as 5); below " << kMultiGpuMinParticles
                << " one GPU steps faster than several (docs/user_guide.md \"Several ranks\"): "
                << (mpi_ranks > 1 ? "start one rank (mpirun -np 1) for the fastest run"
                                  : "running on one GPU (--keep-gpus runs " + std::to_string(gpus) + " ranks)")
                << '\n';
      if (mpi_ranks == 1) gpus = 1;
    }
  }
  const bool thread_ranks = gpu && gpus > 1;
  const bool shared_gpus = thread_ranks && gpus > devices;
  if (thread_ranks && !shared_gpus && !comm::nccl_available()) {
    std::cerr << "fbar: error: --gpus=" << gpus << ": this build has no NCCL (install it and configure again)\n";
    return kExitInput;
  }
  if (shared_gpus)
    std::cerr << "fbar: warning: --gpus=" << gpus << " with " << devices
              << " visible GPU(s): ranks share GPUs and exchange through the host (for testing; slower than one "
                 "rank per GPU)\n";
  const int ranks = thread_ranks ? gpus : mpi_ranks;
  try {
    (void)comm::body_ranks(scene, ranks);  // a body placed on a GPU this run does not have: the scene's error
  } catch (const std::invalid_argument& e) {
    if (rank == 0) std::cerr << "fbar: error: " << e.what() << '\n';
    return kExitInput;
  }

  const fs::path out_dir(scene.simulation.save_path);
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir)) {
    std::cerr << "fbar: error: cannot create output directory '" << out_dir.string() << "': " << ec.message() << '\n';
    return kExitRuntime;
  }

  const std::string started = utc_now();
  const auto t0 = std::chrono::steady_clock::now();
  RunOptions ro;
  ro.quiet = o.quiet;
  ro.halo_overlap = o.halo_overlap;
  ro.frame_host_bytes = o.frame_buffer;
  if (!o.restart.empty()) {
    std::error_code exists_ec;
    if (!fs::is_regular_file(o.restart, exists_ec)) {
      if (rank == 0) std::cerr << "fbar: error: --restart: " << o.restart << ": no such file\n";
      return kExitInput;
    }
    ro.restart = o.restart;
  }
  // The first record, once nothing refuses the run any more: a folder that takes no file fails here, not after it.
  RunJson run_json;
  if (rank == 0) {
    std::string error;
    if (!run_json.start(out_dir / "run.json", run_json_text(scene, command_line, started, 0.0, RunResult{}, gpu, ranks, true),
                        error)) {
      std::cerr << "fbar: error: " << error << " (the output folder, simulation.save_path or --output)\n";
      return kExitRuntime;
    }
  }
  ro.log = &std::cout;
  ro.transport = transport.get();
  RunResult result;
  {
    // SIGINT / SIGTERM stop the run at the next step boundary; run.json below then says so (stop_request.h).
    const StopSignals stop_signals;
    if (thread_ranks) {
      result = run_thread_ranks(scene, ro, engines, ranks, devices, shared_gpus);
    } else {
      ro.gpu = local_gpu;
      result = gpu ? engines.run_gpu(scene, ro) : run_cpu(scene, ro);
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The ranks agree on steps, failures and stops (the engine and the run loop reduce them); an exception (a CUDA or
  // output error, a message from another rank cut short) may be one rank's alone: it ends the job, so that no rank
  // waits for the others forever.
  if (mpi_ranks > 1 && result.from_exception) {
    std::cerr << "fbar: error: rank " << rank << ": " << result.message << '\n';
    transport->abort(result.exit_code);
  }
  if (rank != 0) return result.exit_code;  // rank 0 writes run.json and the report
  return report_run(run_json, run_json_text(scene, command_line, started, wall_s, result, gpu, ranks, false), result);
}

}  // namespace

int cli_main(int argc, char** argv, const EngineSet& engines) {
  std::vector<std::string> command_line(argv, argv + argc);
  CliOptions options;
  try {
    options = parse_arguments(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << "fbar: error: " << e.what() << " (see fbar --help)\n";
    return kExitInput;
  }
  if (options.help) {
    std::cout << kHelp;
    return kExitOk;
  }
  if (options.version) {
    std::cout << "fbar " << FBAR_VERSION
              << (engines.run_gpu ? " (GPU engine and CPU reference engine)\n"
                                  : " (CPU reference engine; the GPU engine is not available in this build)\n");
    return kExitOk;
  }
  try {
    return run(options, command_line, engines);
  } catch (const UsageError& e) {
    std::cerr << "fbar: error: " << e.what() << " (see fbar --help)\n";
    return kExitInput;
  } catch (const SceneError& e) {
    std::cerr << "fbar: error: " << e.what() << '\n';
    return kExitInput;
  } catch (const std::exception& e) {
    std::cerr << "fbar: error: " << e.what() << '\n';
    return kExitRuntime;
  }
}

}  // namespace fbar
