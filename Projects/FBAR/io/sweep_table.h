// A sweep's cases gathered into one table (docs/user_guide.md §10.3): every case's sensor and tracker files read back
// and written, with the case's parameters, as one long table, a summary per case and a list of the cases.
//
// Files, in the sweep's folder:
//   sweep_cases.csv    case, each parameter (its label), status, steps, end time, wall time, message
//   sweep_table.csv    case, each parameter, sensor, quantity, time, value: one row per sample of every column of
//                      every gridTarget*, particleTarget* and particleTrack* file of a completed case (the values
//                      as the case's file writes them)
//   sweep_summary.csv  case, each parameter, sensor, quantity, samples, peak (the value of largest magnitude), its
//                      time, mean, impulse (the trapezoidal integral over time): one row per column of each file
//   sweep_table.h5     the same three tables as HDF5 datasets (groups cases, table, summary; parameters as numbers:
//                      a number's value, a choice's index), for numpy, MATLAB and ParaView users
// A sensor is named by its file name without ".csv" ("gridTarget[0]_dev[0]"), a quantity by its column's header
// ("Force_x [N]").
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "scene/sweep.h"

namespace fbar::io {

/// How a case went, from the run.json in its folder.
struct SweepCaseRecord {
  int id = 0;
  std::string status = "not run";  ///< "completed", "failed", "interrupted", "running" (stopped hard), "not run"
  std::string message;
  std::string checkpoint;          ///< run.json's last checkpoint (an interrupted run), or empty
  long long steps = 0;
  double end_time = 0.0;           ///< [s]
  double wall_s = 0.0;             ///< [s]
};

/// A CSV field: quoted, its quotes doubled, when it holds a comma, a quote or a line break.
std::string csv_field(const std::string& s);

/// <sweep.output>/case_<kkkk>.
std::filesystem::path sweep_case_path(const Sweep& sweep, int id);

/// Reads case `id`'s run.json; "not run" when there is none, "running" with a message when it cannot be read.
SweepCaseRecord read_sweep_case(const Sweep& sweep, int id);

struct SweepGathered {
  int completed = 0;       ///< cases whose files were gathered
  long long rows = 0;      ///< rows of sweep_table.csv
  std::vector<std::filesystem::path> files;
};

/// Writes the four files from every case's folder (the completed cases' sensors; every case in sweep_cases.csv).
/// Throws std::runtime_error naming the file it cannot read or write.
SweepGathered gather_sweep(const Sweep& sweep);

}  // namespace fbar::io
