// run.json (run_record.h).
#include "run_record.h"

#include <rapidjson/document.h>
#include <rapidjson/stringbuffer.h>
#include <rapidjson/writer.h>

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <system_error>

#include "engine/stop_request.h"
#include "scene/scene_parse.h"

#ifndef FBAR_VERSION
#define FBAR_VERSION "unknown"
#endif

namespace fbar {

namespace fs = std::filesystem;
namespace rj = rapidjson;

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string run_json_text(const Scene& scene, const std::vector<std::string>& command_line, const std::string& started,
                          double wall_s, const RunResult& result, bool gpu, int ranks, bool running) {
  rj::Document doc(rj::kObjectType);
  auto& a = doc.GetAllocator();
  auto str = [&](const std::string& s) { return rj::Value(s.c_str(), static_cast<rj::SizeType>(s.size()), a); };
  doc.AddMember("fbar_version", str(FBAR_VERSION), a);
  doc.AddMember("backend", str(gpu ? "gpu" : "cpu"), a);
  doc.AddMember("engine", str(gpu ? "GPU engine (device 0)" : "CPU reference engine"), a);
  doc.AddMember("precision", str(to_string(scene.simulation.precision)), a);
  doc.AddMember("ranks", ranks, a);
  rj::Value cmd(rj::kArrayType);
  for (const auto& c : command_line) cmd.PushBack(str(c), a);
  doc.AddMember("command_line", cmd, a);
  std::error_code ec;
  doc.AddMember("scene_file", str(scene.source_path.empty() ? "" : fs::absolute(scene.source_path, ec).string()), a);
  doc.AddMember("started_utc", str(started), a);
  doc.AddMember("wall_time_s", wall_s, a);
  doc.AddMember("steps", static_cast<int64_t>(result.steps), a);
  doc.AddMember("end_time_s", result.end_time, a);
  doc.AddMember("frames_written", result.frames_written, a);
  doc.AddMember("status", str(running                     ? "running"
                              : result.exit_code == kExitOk ? "completed"
                              : result.stop_signal != 0    ? "interrupted"
                                                           : "failed"),
                a);
  if (result.stop_signal != 0) doc.AddMember("signal", str(signal_name(result.stop_signal)), a);
  if (!result.checkpoint.empty()) doc.AddMember("checkpoint", str(result.checkpoint), a);
  if (result.restarted_from_frame >= 0) doc.AddMember("restarted_from_frame", result.restarted_from_frame, a);
  doc.AddMember("exit_code", result.exit_code, a);
  doc.AddMember("message", str(result.message), a);
  rj::Document resolved(&a);
  resolved.Parse<rj::kParseNanAndInfFlag | rj::kParseFullPrecisionFlag>(write_scene_json(scene, false).c_str());
  doc.AddMember("scene", rj::Value(resolved, a), a);

  rj::StringBuffer sb;
  rj::Writer<rj::StringBuffer, rj::UTF8<>, rj::UTF8<>, rj::CrtAllocator, rj::kWriteNanAndInfFlag> w(sb);
  doc.Accept(w);
  return indent_json(std::string_view(sb.GetString(), sb.GetSize()));
}

bool RunJson::start(const fs::path& path, const std::string& text, std::string& error) {
  path_ = path;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return failed(error, errno);
  const std::string room(kReserve, ' ');
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() &&
                  std::fwrite(room.data(), 1, room.size(), f) == room.size() && std::fflush(f) == 0;
  const int err = errno;
  if (std::fclose(f) != 0 || !ok) return failed(error, ok ? errno : err);
  return true;
}

bool RunJson::finish(const std::string& text, std::string& error) {
  std::FILE* f = std::fopen(path_.c_str(), "r+b");
  if (!f) f = std::fopen(path_.c_str(), "wb");  // removed during the run
  if (!f) return failed(error, errno);
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && std::fflush(f) == 0 &&
                  ftruncate(fileno(f), static_cast<off_t>(text.size())) == 0;
  const int err = errno;
  if (std::fclose(f) != 0 || !ok) return failed(error, ok ? errno : err);
  return true;
}

bool RunJson::failed(std::string& error, int err) const {
  error = "cannot write " + path_.string() + ": " + std::error_code(err, std::generic_category()).message();
  return false;
}

bool finish_run_json(RunJson& run_json, const std::string& final_record, RunResult& result) {
  std::string json_error;
  if (!run_json.finish(final_record, json_error)) {
    // The run's own message first; then why its record could not be kept (run.json then holds the start's record).
    if (result.exit_code == kExitOk) result.exit_code = kExitRuntime;
    result.message = (result.message.empty() ? std::string() : result.message + "; ") + json_error +
                     " (it holds the record written when the run started, status \"running\")";
    return false;
  }
  return true;
}

int report_run(RunJson& run_json, const std::string& final_record, RunResult result) {
  const bool json_written = finish_run_json(run_json, final_record, result);
  if (result.stop_signal != 0)
    std::cerr << "fbar: " << result.message << (json_written ? "; run.json written" : "") << "\n";
  else if (result.exit_code != kExitOk)
    std::cerr << "fbar: error: " << (result.message.empty() ? "the run failed" : result.message) << '\n';
  return result.exit_code;
}

}  // namespace fbar
