// run.json, the record of a run (docs/user_guide.md §4.1): written when a run starts and rewritten when it ends, by
// the command line (cli.cpp) and by each case of a sweep (sweep_run.cpp).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "engine/engine_api.h"
#include "scene/scene.h"

namespace fbar {

inline constexpr int kExitOk = 0;
inline constexpr int kExitInput = 1;    ///< invalid scene, input file or command line
inline constexpr int kExitRuntime = 2;  ///< run-time failure (NaN, CFL, capacity, device, output)

/// The time now, "2026-12-04T01:02:03Z".
std::string utc_now();

/// run.json's text: the resolved scene and how the run went (running: the record written at the start).
std::string run_json_text(const Scene& scene, const std::vector<std::string>& command_line, const std::string& started,
                          double wall_s, const RunResult& result, bool gpu, int ranks, bool running);

/// run.json is written when the run starts (status "running") with room reserved after the text (trailing
/// whitespace, which JSON allows), and rewritten in place at the end: a disk that fills up during the run still
/// takes the final record, which overwrites blocks the file already holds.
class RunJson {
 public:
  static constexpr std::size_t kReserve = 64 * 1024;  ///< [bytes] beyond the first record (the final one's message)

  /// The first record; false (with `error`) when it cannot be written.
  bool start(const std::filesystem::path& path, const std::string& text, std::string& error);
  /// The final record over the first, the file cut to its length; false (with `error`) when it cannot be written.
  bool finish(const std::string& text, std::string& error);

 private:
  bool failed(std::string& error, int err) const;
  std::filesystem::path path_;
};

/// The final record written (true); when it cannot be, `result` says why after the run's own message (exit code 2).
bool finish_run_json(RunJson& run_json, const std::string& final_record, RunResult& result);

/// The run's end on rank 0: finish_run_json and the run's message on stderr. Returns the exit code.
int report_run(RunJson& run_json, const std::string& final_record, RunResult result);

}  // namespace fbar
