// A sweep's cases gathered into one table (sweep_table.h).
#include "io/sweep_table.h"

#include <rapidjson/document.h>

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include "MnSystem/IO/h5_frame.h"

namespace fbar::io {

namespace {

namespace fs = std::filesystem;
namespace rj = rapidjson;
using h5_detail::Handle;

/// A message on one line: its line breaks as "; " (one case, one line of sweep_cases.csv).
std::string one_line(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '\r') continue;
    if (c == '\n') out += "; ";
    else out += c;
  }
  return out;
}

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r') {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

/// One sensor or tracker file of a case: its header and its rows as written.
struct SensorFile {
  std::string sensor;                             ///< file name without .csv
  std::vector<std::string> header;                ///< "Time [s]", then one per quantity
  std::vector<std::vector<std::string>> rows;     ///< the fields as written
};

bool is_sensor_file(const std::string& name) {
  if (name.size() < 5 || name.substr(name.size() - 4) != ".csv") return false;
  for (const char* prefix : {"gridTarget[", "particleTarget[", "particleTrack_"})
    if (name.rfind(prefix, 0) == 0) return true;
  return false;
}

std::vector<SensorFile> read_sensor_files(const fs::path& folder) {
  std::vector<fs::path> paths;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec))
    if (e.is_regular_file() && is_sensor_file(e.path().filename().string())) paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  std::vector<SensorFile> files;
  for (const fs::path& p : paths) {
    std::ifstream in(p);
    if (!in) throw std::runtime_error("sweep: cannot read " + p.string());
    SensorFile f;
    f.sensor = p.stem().string();
    std::string line;
    if (!std::getline(in, line)) continue;  // an empty file (a run stopped before its first row)
    f.header = split_csv_line(line);
    while (std::getline(in, line)) {
      if (line.empty() || line == "\r") continue;
      std::vector<std::string> fields = split_csv_line(line);
      if (fields.size() != f.header.size())
        throw std::runtime_error("sweep: " + p.string() + ": a row of " + std::to_string(fields.size()) +
                                 " fields under a header of " + std::to_string(f.header.size()));
      f.rows.push_back(std::move(fields));
    }
    files.push_back(std::move(f));
  }
  return files;
}

double to_number(const std::string& s) {
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);
  return end == s.c_str() ? std::nan("") : x;
}

struct Summary {
  long long samples = 0;
  double peak = std::nan(""), peak_time = std::nan(""), mean = std::nan(""), impulse = 0.0;
};

/// Peak (largest magnitude), mean and trapezoidal impulse of one column; nan samples (an empty sensor box) skipped.
Summary summarize(const std::vector<double>& t, const std::vector<double>& v) {
  Summary s;
  double sum = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) continue;
    ++s.samples;
    sum += v[i];
    if (!(std::fabs(v[i]) <= std::fabs(s.peak))) {
      s.peak = v[i];
      s.peak_time = t[i];
    }
    if (i > 0 && std::isfinite(v[i - 1])) s.impulse += 0.5 * (v[i] + v[i - 1]) * (t[i] - t[i - 1]);
  }
  if (s.samples > 0) s.mean = sum / static_cast<double>(s.samples);
  return s;
}

std::string number(double x) {
  if (std::isnan(x)) return "nan";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

// ------------------------------------------------------------------------------------------------ HDF5
void write_numbers(hid_t group, const std::string& name, hid_t type, std::size_t n, const void* data,
                   const std::string& file) {
  h5_detail::write_dataset_pieces(group, name, type, n, 1, "", file,
                                  [&](const auto& emit) { emit(n, data); });
}

void write_strings(hid_t group, const std::string& name, const std::vector<std::string>& v, const std::string& file) {
  std::size_t width = 1;
  for (const auto& s : v) width = std::max(width, s.size() + 1);
  std::vector<char> packed(v.size() * width, '\0');
  for (std::size_t i = 0; i < v.size(); ++i) std::copy(v[i].begin(), v[i].end(), packed.begin() + i * width);
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose, "make a string type");
  H5Tset_size(type.get(), width);
  write_numbers(group, name, type.get(), v.size(), packed.data(), file);
}

Handle group_in(hid_t file, const char* name, const std::string& where) {
  const Handle gcpl = h5_detail::untimed(H5P_GROUP_CREATE, where);
  return Handle(H5Gcreate2(file, name, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose,
                std::string("create group ") + name + " in " + where);
}

}  // namespace

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

fs::path sweep_case_path(const Sweep& sweep, int id) { return fs::path(sweep.output) / sweep_case_folder(id); }

SweepCaseRecord read_sweep_case(const Sweep& sweep, int id) {
  SweepCaseRecord r;
  r.id = id;
  const fs::path path = sweep_case_path(sweep, id) / "run.json";
  std::ifstream in(path, std::ios::binary);
  if (!in) return r;
  std::ostringstream text;
  text << in.rdbuf();
  rj::Document doc;
  doc.Parse<rj::kParseNanAndInfFlag>(text.str().c_str());
  if (doc.HasParseError() || !doc.IsObject() || !doc.HasMember("status") || !doc["status"].IsString()) {
    r.status = "running";
    r.message = path.string() + " cannot be read (the run was stopped while writing it?)";
    return r;
  }
  r.status = doc["status"].GetString();
  if (doc.HasMember("message") && doc["message"].IsString()) r.message = doc["message"].GetString();
  if (doc.HasMember("checkpoint") && doc["checkpoint"].IsString()) r.checkpoint = doc["checkpoint"].GetString();
  if (doc.HasMember("steps") && doc["steps"].IsInt64()) r.steps = doc["steps"].GetInt64();
  if (doc.HasMember("end_time_s") && doc["end_time_s"].IsNumber()) r.end_time = doc["end_time_s"].GetDouble();
  if (doc.HasMember("wall_time_s") && doc["wall_time_s"].IsNumber()) r.wall_s = doc["wall_time_s"].GetDouble();
  return r;
}

SweepGathered gather_sweep(const Sweep& sweep) {
  SweepGathered g;
  const fs::path out(sweep.output);
  const std::size_t np = sweep.parameters.size();
  std::string parameter_header;
  for (const auto& q : sweep.parameters) parameter_header += "," + csv_field(q.name);
  auto open = [&](const char* name) {
    const fs::path p = out / name;
    auto f = std::make_unique<std::ofstream>(p, std::ios::binary);
    if (!*f) throw std::runtime_error("sweep: cannot write " + p.string());
    g.files.push_back(p);
    return f;
  };
  auto cases_csv = open("sweep_cases.csv");
  auto table_csv = open("sweep_table.csv");
  auto summary_csv = open("sweep_summary.csv");
  *cases_csv << "case" << parameter_header << ",status,steps,end_time [s],wall_time [s],message\n";
  *table_csv << "case" << parameter_header << ",sensor,quantity,time [s],value\n";
  *summary_csv << "case" << parameter_header << ",sensor,quantity,samples,peak,peak_time [s],mean,impulse [value s]\n";

  // Columns of the HDF5 file.
  std::vector<int> case_id;
  std::vector<std::string> case_status;
  std::vector<std::vector<double>> case_numbers(np);
  std::vector<std::vector<std::string>> case_labels(np);
  std::vector<std::string> series_sensor, series_quantity;
  std::map<std::pair<std::string, std::string>, int> series_index;
  std::vector<int> row_case, row_series, sum_case, sum_series;
  std::vector<double> row_time, row_value, sum_peak, sum_peak_time, sum_mean, sum_impulse;
  std::vector<long long> sum_samples;

  for (const SweepCase& c : sweep.cases) {
    const SweepCaseRecord r = read_sweep_case(sweep, c.id);
    std::string params;
    for (std::size_t p = 0; p < np; ++p) params += "," + csv_field(c.labels[p]);
    *cases_csv << c.id << params << "," << r.status << "," << r.steps << "," << number(r.end_time) << ","
               << number(r.wall_s) << "," << csv_field(one_line(r.message)) << "\n";
    case_id.push_back(c.id);
    case_status.push_back(r.status);
    for (std::size_t p = 0; p < np; ++p) {
      case_numbers[p].push_back(c.numbers[p]);
      case_labels[p].push_back(c.labels[p]);
    }
    if (r.status != "completed") continue;
    ++g.completed;
    for (const SensorFile& f : read_sensor_files(sweep_case_path(sweep, c.id))) {
      std::vector<double> t;
      for (const auto& row : f.rows) t.push_back(to_number(row[0]));
      for (std::size_t col = 1; col < f.header.size(); ++col) {
        const auto key = std::make_pair(f.sensor, f.header[col]);
        auto [it, added] = series_index.emplace(key, static_cast<int>(series_sensor.size()));
        if (added) {
          series_sensor.push_back(f.sensor);
          series_quantity.push_back(f.header[col]);
        }
        std::vector<double> v;
        for (const auto& row : f.rows) {
          *table_csv << c.id << params << "," << csv_field(f.sensor) << "," << csv_field(f.header[col]) << ","
                     << row[0] << "," << row[col] << "\n";
          v.push_back(to_number(row[col]));
          row_case.push_back(c.id);
          row_series.push_back(it->second);
          row_time.push_back(t[v.size() - 1]);
          row_value.push_back(v.back());
          ++g.rows;
        }
        const Summary s = summarize(t, v);
        *summary_csv << c.id << params << "," << csv_field(f.sensor) << "," << csv_field(f.header[col]) << ","
                     << s.samples << "," << number(s.peak) << "," << number(s.peak_time) << "," << number(s.mean)
                     << "," << number(s.impulse) << "\n";
        sum_case.push_back(c.id);
        sum_series.push_back(it->second);
        sum_samples.push_back(s.samples);
        sum_peak.push_back(s.peak);
        sum_peak_time.push_back(s.peak_time);
        sum_mean.push_back(s.mean);
        sum_impulse.push_back(s.impulse);
      }
    }
  }
  for (auto* f : {cases_csv.get(), table_csv.get(), summary_csv.get()}) {
    f->flush();
    if (!*f) throw std::runtime_error("sweep: cannot write the tables in " + out.string());
  }

  const fs::path h5 = out / "sweep_table.h5";
  const std::string where = h5.string();
  {
    std::lock_guard<std::mutex> lock(h5_detail::hdf5_mutex());
    h5_detail::Quiet quiet;
    const Handle fcpl = h5_detail::untimed(H5P_FILE_CREATE, where);
    Handle file(H5Fcreate(where.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose, "create " + where);
    {
      Handle cases = group_in(file.get(), "cases", where);
      write_numbers(cases.get(), "case", H5T_NATIVE_INT, case_id.size(), case_id.data(), where);
      write_strings(cases.get(), "status", case_status, where);
      for (std::size_t p = 0; p < np; ++p) {
        write_numbers(cases.get(), sweep.parameters[p].name, H5T_NATIVE_DOUBLE, case_numbers[p].size(),
                      case_numbers[p].data(), where);
        write_strings(cases.get(), sweep.parameters[p].name + " label", case_labels[p], where);
      }
    }
    {
      Handle table = group_in(file.get(), "table", where);
      write_strings(table.get(), "series sensor", series_sensor, where);
      write_strings(table.get(), "series quantity", series_quantity, where);
      write_numbers(table.get(), "case", H5T_NATIVE_INT, row_case.size(), row_case.data(), where);
      write_numbers(table.get(), "series", H5T_NATIVE_INT, row_series.size(), row_series.data(), where);
      write_numbers(table.get(), "time", H5T_NATIVE_DOUBLE, row_time.size(), row_time.data(), where);
      write_numbers(table.get(), "value", H5T_NATIVE_DOUBLE, row_value.size(), row_value.data(), where);
    }
    {
      Handle summary = group_in(file.get(), "summary", where);
      write_numbers(summary.get(), "case", H5T_NATIVE_INT, sum_case.size(), sum_case.data(), where);
      write_numbers(summary.get(), "series", H5T_NATIVE_INT, sum_series.size(), sum_series.data(), where);
      write_numbers(summary.get(), "samples", H5T_NATIVE_LLONG, sum_samples.size(), sum_samples.data(), where);
      write_numbers(summary.get(), "peak", H5T_NATIVE_DOUBLE, sum_peak.size(), sum_peak.data(), where);
      write_numbers(summary.get(), "peak time", H5T_NATIVE_DOUBLE, sum_peak_time.size(), sum_peak_time.data(), where);
      write_numbers(summary.get(), "mean", H5T_NATIVE_DOUBLE, sum_mean.size(), sum_mean.data(), where);
      write_numbers(summary.get(), "impulse", H5T_NATIVE_DOUBLE, sum_impulse.size(), sum_impulse.data(), where);
    }
    if (file.release() < 0) throw h5_detail::failure("close " + where);
  }
  g.files.push_back(h5);
  return g;
}

}  // namespace fbar::io
