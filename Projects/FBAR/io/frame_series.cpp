// frames.xdmf (frame_series.h).
#include "io/frame_series.h"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "MnSystem/IO/particle_io.h"

namespace fbar::io {

namespace {

std::string shortest(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, r.ptr);
}

/// The whole file, or false when it cannot be read.
bool read_text(const std::filesystem::path& path, std::string& text) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return static_cast<bool>(in) || in.eof();
}

/// From one frame file's .xdmf (h5_frame.h's layout): its particle count and the lines of its grid's content
/// (Topology, Geometry, Attributes), each indented by `indent` more. False when the file is not such an .xdmf.
bool grid_content(const std::string& xdmf, const std::string& indent, long long& particles, std::string& content) {
  if (xdmf.find("</Xdmf>") == std::string::npos) return false;
  const std::size_t topo = xdmf.find("<Topology ");
  const std::size_t end = xdmf.rfind("</Grid>");
  if (topo == std::string::npos || end == std::string::npos || end < topo) return false;
  const std::string key = "NumberOfElements=\"";
  const std::size_t count = xdmf.find(key, topo);
  if (count == std::string::npos) return false;
  particles = std::stoll(xdmf.substr(count + key.size(), 20));
  const std::size_t first = xdmf.rfind('\n', topo) + 1;  // the line of <Topology
  const std::size_t last = xdmf.rfind('\n', end) + 1;    // the line of </Grid>
  content.clear();
  std::istringstream lines(xdmf.substr(first, last - first));
  for (std::string line; std::getline(lines, line);) content += indent + line + "\n";
  return true;
}

}  // namespace

FrameSeries::FrameSeries(std::filesystem::path dir, std::vector<std::vector<std::pair<int, int>>> body_files,
                         std::string suffix)
    : dir_(std::move(dir)), body_files_(std::move(body_files)), suffix_(std::move(suffix)) {}

void FrameSeries::expect(int frame, double time) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& f : done_)
    if (f.frame == frame) return;
  for (const auto& p : pending_)
    if (p.first == frame) return;
  pending_.emplace_back(frame, time);
}

std::string FrameSeries::frame_xml(int frame, double time, std::string& missing) const {
  std::string bodies;
  for (std::size_t b = 0; b < body_files_.size(); ++b) {
    std::string grids;
    for (const auto& [model, device] : body_files_[b]) {
      const std::filesystem::path h5 = frame_file_path(dir_, model, device, frame, suffix_);
      std::filesystem::path xdmf = h5;
      xdmf.replace_extension(".xdmf");
      std::string text, content;
      long long particles = 0;
      std::error_code ec;
      if (!std::filesystem::exists(h5, ec) || !read_text(xdmf, text) ||
          !grid_content(text, "   ", particles, content)) {
        missing = xdmf.filename().string();
        return {};
      }
      if (particles == 0) continue;  // an empty rank of the body
      grids += "     <Grid Name=\"model[" + std::to_string(model) + "]_dev[" + std::to_string(device) +
               "]\" GridType=\"Uniform\">\n" + content + "     </Grid>\n";
    }
    if (grids.empty()) continue;
    bodies += "    <Grid Name=\"bodies[" + std::to_string(b) +
              "]\" GridType=\"Collection\" CollectionType=\"Spatial\">\n" + grids + "    </Grid>\n";
  }
  return "   <Grid Name=\"frame[" + std::to_string(frame) +
         "]\" GridType=\"Collection\" CollectionType=\"Spatial\">\n    <Time Value=\"" + shortest(time) + "\"/>\n" +
         bodies + "   </Grid>\n";
}

int FrameSeries::update() {
  std::lock_guard<std::mutex> lock(mutex_);
  int added = 0;
  for (auto it = pending_.begin(); it != pending_.end();) {
    std::string missing;
    std::string xml = frame_xml(it->first, it->second, missing);
    if (xml.empty()) {
      ++it;
      continue;
    }
    done_.push_back(Frame{it->first, it->second, std::move(xml)});
    it = pending_.erase(it);
    ++added;
  }
  if (added > 0) {
    std::sort(done_.begin(), done_.end(), [](const Frame& a, const Frame& b) { return a.frame < b.frame; });
    write();
  }
  return added;
}

void FrameSeries::write() const {
  std::string x =
      "<?xml version=\"1.0\" ?>\n"
      "<!-- fbar: every frame of this run (ParaView: open this file; the frames' .h5 files stay next to it) -->\n"
      "<Xdmf Version=\"3.0\">\n <Domain>\n"
      "  <Grid Name=\"frames\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const Frame& f : done_) x += f.xml;
  x += "  </Grid>\n </Domain>\n</Xdmf>\n";
  detail::AtomicFile out(path());
  out.buffer() = std::move(x);
  out.commit();
}

std::vector<std::pair<int, std::string>> FrameSeries::missing() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::pair<int, std::string>> out;
  for (const auto& [frame, time] : pending_) {
    std::string what;
    if (frame_xml(frame, time, what).empty()) out.emplace_back(frame, what);
  }
  return out;
}

int FrameSeries::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(done_.size());
}

}  // namespace fbar::io
