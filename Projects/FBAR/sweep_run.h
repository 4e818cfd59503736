// fbar --sweep=FILE (docs/user_guide.md §10): every case of a sweep checked, then run on the GPUs (or the CPU) this
// job has, several at once where memory allows, resumed where a stopped sweep left off, and gathered into one table.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "cli.h"
#include "scene/scene.h"

namespace fbar {

struct SweepOptions {
  std::string file;                    ///< the sweep file
  bool check = false;                  ///< list the cases with their particles, memory and time; run nothing
  bool gather = false;                 ///< only gather the cases' files into the tables
  bool retry_failed = false;           ///< run failed cases again (by default a failed case is reported, not rerun)
  bool quiet = false;                  ///< no progress lines (each case's own lines go to its log.txt)
  bool gpu = false;                    ///< the GPU engine (chosen by the command line); otherwise the CPU engine
  int gpus = 0;                        ///< GPUs of this process to use (0: every visible one)
  int jobs = 0;                        ///< cases at once per GPU (CPU engine: at once); 0: as many as fit
  int local_rank = 0;                  ///< under an MPI launcher: this process's rank on its node (its GPU)
  std::vector<int> cases;              ///< --cases: only these (empty: all)
  std::optional<std::string> output;   ///< --output: the sweep's folder
  std::optional<int> frames;           ///< --frames for every case
  std::size_t frame_buffer = 0;        ///< --frame-buffer [B]
  bool allow_unknown_keys = false;
  std::string data_dir;
};

/// Cases at once on one GPU when --jobs is not given: at most this many (each case's thread waits on its GPU
/// with one CPU core) and at most the cores per GPU less one.
inline constexpr int kSweepMaxJobsPerGpu = 16;
/// Share of a GPU's free memory the cases running on it may plan to take together.
inline constexpr double kSweepMemoryShare = 0.9;

/// Runs (or checks, or gathers) the sweep; returns the exit code: 0 when every case of this job completed, 1 for a
/// bad sweep file or case scene (no case runs), 2 when a case failed (the others still ran), 128 + signal when
/// stopped. Under mpirun / srun each rank runs every size-th case on its GPU; in a Slurm job array each task runs
/// every SLURM_ARRAY_TASK_COUNT-th case, and `fbar --sweep=FILE --gather` gathers after the array.
int run_sweep(const SweepOptions& options, const EngineSet& engines, const std::vector<std::string>& command_line);

}  // namespace fbar
