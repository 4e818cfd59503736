// Grid-field schedules, the ranks' nodes gathered and the files (grid_field_recorder.h).
#include "io/grid_field_recorder.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <tuple>

#include "MnSystem/IO/h5_frame.h"
#include "MnSystem/IO/particle_io.h"

namespace fbar {

namespace {

std::string shortest(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, r.ptr);
}

struct AttributeInfo {
  const char* name;
  int width;
  const char* unit;
};
constexpr AttributeInfo kAttributes[] = {
    {"Mass", 1, "kg"},          {"Velocity", 3, "m/s"}, {"Momentum", 3, "kg m/s"}, {"Force", 3, "N"},
    {"BoundaryForce", 3, "N"},  {"Volume", 1, "m^3"},   {"JBar", 1, "-"},          {"MassWater", 1, "kg"},
    {"PorePressure", 1, "Pa"},
};

const AttributeInfo& attribute_info(const std::string& name) {
  for (const AttributeInfo& a : kAttributes)
    if (name == a.name) return a;
  throw std::invalid_argument("grid field attribute \"" + name + "\" is not a grid quantity");
}

/// The values of attribute `name` of one point (a node, or a block's sums; `wet`: its nodes carrying pore water).
void point_values(const std::string& name, const GridFieldNode& n, double dt, int wet, float* out) {
  if (name == "Mass") {
    out[0] = static_cast<float>(n.m);
  } else if (name == "Velocity") {
    for (int d = 0; d < 3; ++d) out[d] = static_cast<float>(n.m > 0.0 ? n.p[d] / n.m : 0.0);
  } else if (name == "Momentum") {
    for (int d = 0; d < 3; ++d) out[d] = static_cast<float>(n.p[d]);
  } else if (name == "Force") {
    for (int d = 0; d < 3; ++d) out[d] = static_cast<float>(n.p[d] / dt);
  } else if (name == "BoundaryForce") {
    for (int d = 0; d < 3; ++d) out[d] = static_cast<float>(n.boundary[d]);
  } else if (name == "Volume") {
    out[0] = static_cast<float>(n.volume);
  } else if (name == "JBar") {
    out[0] = static_cast<float>(n.volume > 0.0 ? 1.0 - n.volume_jbar / n.volume : 0.0);
  } else if (name == "MassWater") {
    out[0] = static_cast<float>(n.water);
  } else if (name == "PorePressure") {
    out[0] = static_cast<float>(wet > 0 ? n.pore / wet : 0.0);
  } else {
    throw std::invalid_argument("grid field attribute \"" + name + "\" is not a grid quantity");
  }
}

bool index_less(const GridFieldNode& a, const GridFieldNode& b) {
  return std::tie(a.index[0], a.index[1], a.index[2]) < std::tie(b.index[0], b.index[1], b.index[2]);
}

int floor_div4(int i) { return i >= 0 ? i / 4 : -((-i + 3) / 4); }

/// The grid content (Topology, Geometry, Attributes) of a sample's .h5 as write_h5 describes it in its .xdmf.
std::string grid_content(const io::ParticleFrame& f, const std::string& file) {
  const std::size_t n = f.size();
  std::string x = "     <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + std::to_string(n) +
                  "\" NodesPerElement=\"1\"/>\n";
  x += "     <Geometry GeometryType=\"XYZ\">\n      " + io::h5_detail::data_item(n, 3, false, 8, file, "Position") +
       "\n     </Geometry>\n";
  for (const io::FrameAttribute& a : f.attributes) {
    const char* kind = a.width == 1 ? "Scalar" : a.width == 3 ? "Vector" : "Matrix";
    x += "     <Attribute Name=\"" + a.name + "\" AttributeType=\"" + kind + "\" Center=\"Node\">\n      " +
         io::h5_detail::data_item(n, a.width, false, 4, file, a.name) + "\n     </Attribute>\n";
  }
  return x;
}

/// The grid content of a sample's .xdmf on disk (a restart's earlier samples), re-indented; "" when unreadable.
std::string grid_content_of_file(const std::filesystem::path& xdmf) {
  std::ifstream in(xdmf, std::ios::binary);
  if (!in) return "";
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t topo = text.find("<Topology ");
  const std::size_t end = text.rfind("  </Grid>");
  if (topo == std::string::npos || end == std::string::npos || end < topo) return "";
  std::string out, line;
  const std::string body = text.substr(topo, end - topo);
  std::size_t start = 0;
  while (start < body.size()) {
    std::size_t nl = body.find('\n', start);
    if (nl == std::string::npos) nl = body.size();
    line = body.substr(start, nl - start);
    const std::size_t first = line.find_first_not_of(' ');
    if (first != std::string::npos) out += std::string(line.find("<DataItem") == first ? 6 : 5, ' ') + line.substr(first) + "\n";
    start = nl + 1;
  }
  return out;
}

}  // namespace

std::string grid_field_file_name(std::size_t field, long long sample, const std::string& suffix) {
  return "gridField[" + std::to_string(field) + "]_frame[" + std::to_string(sample) + "]" + suffix;
}

std::string grid_field_series_name(std::size_t field) { return "gridField[" + std::to_string(field) + "].xdmf"; }

io::ParticleFrame grid_field_frame(const GridFieldSpec& spec, std::vector<GridFieldNode> nodes, double dx, double dt) {
  std::vector<int> wet;  // per point: nodes carrying pore water (a block's PorePressure is their mean)
  std::sort(nodes.begin(), nodes.end(), index_less);  // one order whatever the ranks' and threads': the same bytes
  if (spec.blocks) {  // one point per grid block: its nodes' sums
    std::map<std::tuple<int, int, int>, std::pair<GridFieldNode, int>> blocks;
    for (const GridFieldNode& n : nodes) {
      const auto key = std::make_tuple(floor_div4(n.index[0]), floor_div4(n.index[1]), floor_div4(n.index[2]));
      auto [it, inserted] = blocks.try_emplace(key);
      GridFieldNode& b = it->second.first;
      if (inserted) {
        b = GridFieldNode{};
        b.index[0] = std::get<0>(key);
        b.index[1] = std::get<1>(key);
        b.index[2] = std::get<2>(key);
        b.m = b.volume = b.volume_jbar = b.water = b.pore = 0.0;
        for (int d = 0; d < 3; ++d) b.p[d] = b.boundary[d] = 0.0;
      }
      b.m += n.m;
      for (int d = 0; d < 3; ++d) b.p[d] += n.p[d], b.boundary[d] += n.boundary[d];
      b.volume += n.volume;
      b.volume_jbar += n.volume_jbar;
      b.water += n.water;
      if (n.water > 0.0) b.pore += n.pore, ++it->second.second;
    }
    nodes.clear();
    for (const auto& [key, b] : blocks) {
      nodes.push_back(b.first);
      wet.push_back(b.second);
    }
  } else {
    for (const GridFieldNode& n : nodes) wet.push_back(n.water > 0.0 ? 1 : 0);
  }
  io::ParticleFrame f;
  std::vector<Vec3d> x(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i)
    for (int d = 0; d < 3; ++d)  // a block's point: its centre, node 1.5 of the block
      x[i][d] = (spec.blocks ? 4.0 * nodes[i].index[d] + 1.5 : static_cast<double>(nodes[i].index[d])) * dx;
  f.positions = std::move(x);
  for (const std::string& name : spec.attributes) {
    const AttributeInfo& a = attribute_info(name);
    std::vector<float> values(nodes.size() * static_cast<std::size_t>(a.width));
    for (std::size_t i = 0; i < nodes.size(); ++i) point_values(name, nodes[i], dt, wet[i], &values[i * a.width]);
    f.add(a.name, a.width, std::move(values), a.unit);
  }
  return f;
}

GridFieldRecorder::GridFieldRecorder(const Scene& scene, comm::Transport* transport, double t0, double t_end,
                                     const io::Checkpoint* resume)
    : transport_(transport),
      dir_(scene.simulation.save_path),
      suffix_(scene.simulation.save_suffix),
      dx_(scene.simulation.dx),
      t0_(t0),
      t_end_(t_end) {
  double shortest_interval = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < scene.grid_fields.size(); ++i) {
    const GridFieldSpec& f = scene.grid_fields[i];
    if (!f.toggle) continue;
    specs_.push_back(f);
    index_.push_back(i);
    intervals_.push_back(1.0 / f.output_frequency);
    shortest_interval = std::min(shortest_interval, intervals_.back());
  }
  if (specs_.size() > static_cast<std::size_t>(GridFieldSet<double>::kMax))
    throw std::invalid_argument("grid-fields: " + std::to_string(specs_.size()) + " enabled fields; at most " +
                                std::to_string(GridFieldSet<double>::kMax));
  tolerance_ = std::isfinite(shortest_interval) ? 1e-9 * shortest_interval : 0.0;
  next_.assign(specs_.size(), 0);
  series_.resize(specs_.size());
  const bool writer = !transport_ || transport_->rank() == 0;
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (!resume) continue;
    long long k = 0;
    while (sample_time(i, k) < resume->time - tolerance_) ++k;  // the step starting at resume->time takes its sample
    next_[i] = k;
    if (!writer || suffix_ != ".h5") continue;
    for (long long j = 0; j < k; ++j) {  // the series keeps the first run's samples
      std::filesystem::path xdmf = dir_ / grid_field_file_name(index_[i], j, suffix_);
      xdmf.replace_extension(".xdmf");
      const std::string grid = grid_content_of_file(xdmf);
      if (!grid.empty() && grid.find("NumberOfElements=\"0\"") == std::string::npos)
        series_[i].push_back({sample_time(i, j), grid});
    }
  }
}

bool GridFieldRecorder::due(std::size_t i, double t) const {
  const double ts = sample_time(i, next_[i]);
  return ts < t_end_ - tolerance_ && std::fabs(t - ts) <= tolerance_;
}

double GridFieldRecorder::next_time_after(double t) const {
  double next = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    long long k = next_[i];
    while (sample_time(i, k) <= t + tolerance_) ++k;
    const double ts = sample_time(i, k);
    if (ts < t_end_ - tolerance_) next = std::min(next, ts);
  }
  return next;
}

unsigned GridFieldRecorder::due_mask(double t) const {
  unsigned mask = 0;
  for (std::size_t i = 0; i < specs_.size(); ++i)
    if (due(i, t)) mask |= 1u << i;
  return mask;
}

void GridFieldRecorder::taken(double t) {
  for (std::size_t i = 0; i < specs_.size(); ++i)
    if (due(i, t)) ++next_[i];
}

void GridFieldRecorder::record(std::size_t i, double t, double dt, std::vector<GridFieldNode> nodes,
                               io::AsyncWriter& writer) {
  if (transport_ && transport_->size() > 1) {  // every rank's nodes (disjoint: each rank's own), in rank order
    comm::Bytes mine(nodes.size() * sizeof(GridFieldNode));
    if (!nodes.empty()) std::memcpy(mine.data(), nodes.data(), mine.size());
    const std::vector<comm::Bytes> all = transport_->allgather(mine);
    nodes.clear();
    for (const comm::Bytes& b : all) {
      const std::size_t n = b.size() / sizeof(GridFieldNode);
      const std::size_t at = nodes.size();
      nodes.resize(at + n);
      if (n > 0) std::memcpy(nodes.data() + at, b.data(), n * sizeof(GridFieldNode));
    }
    if (transport_->rank() != 0) return;
  }
  const long long k = next_[i];
  io::ParticleFrame frame = grid_field_frame(specs_[i], std::move(nodes), dx_, dt);
  const std::string file = grid_field_file_name(index_[i], k, suffix_);
  // The series leaves out a sample without nodes (some readers refuse zero-sized datasets); its file is written.
  if (suffix_ == ".h5" && frame.size() > 0) series_[i].push_back({t, grid_content(frame, file)});
  writer.submit(dir_ / file, std::move(frame));
  if (suffix_ == ".h5") {  // after the sample's files (the writer runs its jobs in order)
    const std::filesystem::path path = dir_ / grid_field_series_name(index_[i]);
    std::string x =
        "<?xml version=\"1.0\" ?>\n"
        "<!-- fbar: every sample of grid field " + std::to_string(index_[i]) +
        " (ParaView: open this file; the samples' .h5 files stay next to it) -->\n"
        "<Xdmf Version=\"3.0\">\n <Domain>\n"
        "  <Grid Name=\"gridField[" + std::to_string(index_[i]) + "]\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (std::size_t s = 0; s < series_[i].size(); ++s)
      x += "   <Grid Name=\"sample\" GridType=\"Uniform\">\n    <Time Value=\"" + shortest(series_[i][s].time) +
           "\"/>\n" + series_[i][s].grid + "   </Grid>\n";
    x += "  </Grid>\n </Domain>\n</Xdmf>\n";
    writer.submit_job([path, x = std::move(x)] {
      io::detail::AtomicFile out(path);
      out.buffer() = x;
      out.commit();
    });
  }
}

}  // namespace fbar
