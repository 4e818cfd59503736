// Grid fields (scene "grid-fields", physics/grid_fields.h, io/grid_field_recorder.h) on the CPU engine: a field's
// nodes against the grid sensors of the same box and step, the frame built from nodes (order, attributes, blocks),
// and the run loop's files on 1 and 2 ranks (the same bytes) with the time series ParaView opens.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "cpu/decomposition_scenes.h"
#include "engine/check_report.h"
#include "engine/cpu/cpu_engine.h"
#include "engine/engine_api.h"
#include "io/checkpoint.h"
#include "io/grid_field_recorder.h"
#include "scene/output_specs.h"
#include "../physics/physics_test_support.h"
#include "run_support.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;
using test::grid_sensor_spec;

GridFieldSpec field(Real3 lo, Real3 hi, std::vector<std::string> attributes, bool blocks = false) {
  GridFieldSpec f;
  f.domain_start = lo;
  f.domain_end = hi;
  f.attributes = std::move(attributes);
  f.output_frequency = 100.0;
  f.blocks = blocks;
  return f;
}

/// Dataset `name` of an .h5 frame as doubles (row-major), with its row count.
std::vector<double> read_h5(const fs::path& path, const char* name, hsize_t& rows) {
  std::vector<double> values;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(file, 0) << path;
  const hid_t set = H5Dopen2(file, name, H5P_DEFAULT);
  EXPECT_GE(set, 0) << name;
  const hid_t space = H5Dget_space(set);
  std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  hsize_t n = 1;
  for (hsize_t d : dims) n *= d;
  rows = dims.empty() ? 0 : dims[0];
  values.resize(n);
  if (n) H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
  H5Sclose(space);
  H5Dclose(set);
  H5Fclose(file);
  return values;
}

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// A field's nodes are the grid sensors' nodes: over the same box and step, their count is Mass's Count, and their
/// mass, x momentum, y force (p / dt) and boundary force sum to the sensors' Sums, their volume (a field reading
/// Volume) to the Volume sensor's; a blocks field holds at least the box's mass. The dam break, every step for 30 steps (the water reaches the right wall, the floor holds it).
TEST(GridFields, NodesAreTheGridSensorsNodes) {
  Scene scene = test::dam_break(false);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const Real3 lo{0.0, 0.0, 0.0}, hi{0.64, 0.1, 0.2};  // the floor's layer
  engine.set_grid_fields({field(lo, hi, {"Mass", "Momentum", "Force"}), field(lo, hi, {"Mass"}, true)});
  engine.set_grid_sensors({grid_sensor_spec("Mass", SensorOperation::Count, lo, hi),
                           grid_sensor_spec("Mass", SensorOperation::Sum, lo, hi),
                           grid_sensor_spec("Momentum", SensorOperation::Sum, lo, hi, {1, 0, 0}),
                           grid_sensor_spec("Force", SensorOperation::Sum, lo, hi, {0, 1, 0}),
                           grid_sensor_spec("BoundaryForce", SensorOperation::Sum, lo, hi, {0, 1, 0})});
  for (int step = 0; step < 30; ++step) {
    engine.set_grid_sample(0);
    engine.set_grid_field_sample(step % 2 == 0 ? 3u : 1u);  // the blocks field every other step
    const double dt = 2e-4;
    ASSERT_TRUE(engine.step(dt).ok);
    const std::vector<SensorAccum> s = engine.grid_samples(1);
    const GridFieldSample f = engine.grid_field_sample(0);
    EXPECT_EQ(f.dt, dt);
    EXPECT_EQ(static_cast<double>(f.nodes.size()), sensor_result(SensorOperation::Count, s[0])) << "step " << step;
    double m = 0.0, px = 0.0, fy = 0.0, by = 0.0;
    for (const GridFieldNode& n : f.nodes) {
      m += n.m;
      px += n.p[0];
      fy += n.p[1] / f.dt;
      by += n.boundary[1];
      EXPECT_EQ(n.volume, 0.0) << "no field reads Volume: the step sums none";
    }
    const double mass = sensor_result(SensorOperation::Sum, s[1]);
    EXPECT_NEAR(m, mass, 1e-12 * mass) << "step " << step;
    EXPECT_NEAR(px, sensor_result(SensorOperation::Sum, s[2]), 1e-9 * mass);
    EXPECT_NEAR(fy, sensor_result(SensorOperation::Sum, s[3]), 1e-9 * mass / dt);
    EXPECT_NEAR(by, sensor_result(SensorOperation::Sum, s[4]), 1e-9 * mass / dt);
    if (step % 2 == 0) {
      const io::ParticleFrame blocks = grid_field_frame(field(lo, hi, {"Mass"}, true), engine.grid_field_sample(1).nodes,
                                                        scene.simulation.dx, dt);
      const auto& bm = std::get<std::vector<float>>(blocks.find("Mass")->values);
      double sum = 0.0;
      for (float v : bm) sum += v;
      // The blocks field's box is the whole blocks the box touches (y up to 0.14 m): at least the box's mass.
      EXPECT_GE(sum, mass * (1.0 - 1e-6)) << "step " << step;
    }
  }
  // A field reading Volume has the step sum it: the nodes' volume sums to the Volume sensor's.
  engine.set_grid_fields({field(lo, hi, {"Volume", "JBar"})});
  engine.set_grid_sensors({grid_sensor_spec("Volume", SensorOperation::Sum, lo, hi)});
  engine.set_grid_field_sample(1u);
  engine.set_grid_sample(0);
  ASSERT_TRUE(engine.step(2e-4).ok);
  double volume = 0.0;
  for (const GridFieldNode& n : engine.grid_field_sample(0).nodes) volume += n.volume;
  const double sensor = sensor_result(SensorOperation::Sum, engine.grid_samples(1)[0]);
  EXPECT_GT(sensor, 0.0);
  EXPECT_NEAR(volume, sensor, 1e-12 * sensor);
}

/// grid_field_frame: nodes in index order whatever order they come in, positions index * dx, each attribute's
/// formula; a blocks field's point per block at its centre with its nodes' sums.
TEST(GridFields, FrameOrdersNodesAndComputesTheAttributes) {
  const double dx = 0.1, dt = 0.01;
  auto node = [](int i, int j, int k, double m, double px) {
    GridFieldNode n{};
    n.index[0] = i, n.index[1] = j, n.index[2] = k;
    n.m = m;
    n.p[0] = px, n.p[1] = 0.0, n.p[2] = -m;
    n.boundary[0] = 0.0, n.boundary[1] = 2.0 * m, n.boundary[2] = 0.0;
    n.volume = 1e-3 * m;
    n.volume_jbar = 1e-5 * m;  // 1 - JBar = 0.01
    n.water = 0.0, n.pore = 0.0;
    return n;
  };
  const std::vector<GridFieldNode> nodes = {node(5, 0, 0, 2.0, 1.0), node(1, 2, 3, 1.0, 4.0), node(1, 2, 1, 4.0, 2.0)};
  const GridFieldSpec spec = field({0, 0, 0}, {1, 1, 1}, {"Mass", "Velocity", "Force", "BoundaryForce", "JBar"});
  const io::ParticleFrame f = grid_field_frame(spec, nodes, dx, dt);
  ASSERT_EQ(f.size(), 3u);
  const auto& x = std::get<std::vector<Vec3d>>(f.positions);
  EXPECT_EQ(x[0], (Vec3d{{0.1, 0.2, 0.1}}));  // (1, 2, 1) first, then (1, 2, 3), then (5, 0, 0)
  EXPECT_EQ(x[1], (Vec3d{{0.1, 0.2, 0.30000000000000004}}));
  EXPECT_EQ(x[2], (Vec3d{{0.5, 0.0, 0.0}}));
  const auto& m = std::get<std::vector<float>>(f.find("Mass")->values);
  EXPECT_EQ(m, (std::vector<float>{4.0f, 1.0f, 2.0f}));
  const auto& v = std::get<std::vector<float>>(f.find("Velocity")->values);
  EXPECT_FLOAT_EQ(v[0], 0.5f);   // p_x / m of node (1, 2, 1)
  EXPECT_FLOAT_EQ(v[2], -1.0f);  // p_z / m
  const auto& force = std::get<std::vector<float>>(f.find("Force")->values);
  EXPECT_FLOAT_EQ(force[3], 400.0f);  // p_x / dt of node (1, 2, 3)
  EXPECT_EQ(f.find("Force")->width, 3);
  EXPECT_EQ(f.find("Force")->unit, "N");
  const auto& b = std::get<std::vector<float>>(f.find("BoundaryForce")->values);
  EXPECT_FLOAT_EQ(b[1], 8.0f);
  const auto& jbar = std::get<std::vector<float>>(f.find("JBar")->values);
  EXPECT_FLOAT_EQ(jbar[0], 0.99f);
  // Blocks: (1, 2, 1) and (1, 2, 3) share block (0, 0, 0); (5, 0, 0) is in block (1, 0, 0).
  const GridFieldSpec per_block = field({0, 0, 0}, {1, 1, 1}, {"Mass", "Momentum", "Velocity"}, true);
  const io::ParticleFrame g = grid_field_frame(per_block, nodes, dx, dt);
  ASSERT_EQ(g.size(), 2u);
  const auto& xb = std::get<std::vector<Vec3d>>(g.positions);
  EXPECT_NEAR(xb[0][0], 0.15, 1e-15);
  EXPECT_NEAR(xb[1][0], 0.55, 1e-15);
  const auto& mb = std::get<std::vector<float>>(g.find("Mass")->values);
  EXPECT_EQ(mb, (std::vector<float>{5.0f, 2.0f}));
  const auto& pb = std::get<std::vector<float>>(g.find("Momentum")->values);
  EXPECT_FLOAT_EQ(pb[0], 6.0f);
  const auto& vb = std::get<std::vector<float>>(g.find("Velocity")->values);
  EXPECT_FLOAT_EQ(vb[0], 6.0f / 5.0f);  // the block's momentum over its mass
}

/// The dam break through the run loop with a field over the tank's right part (.h5) and one switched off before a blocks
/// field: sample files at 100 Hz named by the field's index, the time series listing them, and 2 ranks writing one
/// rank's nodes (the CPU engine's halo sums differ from one rank's by their summation order: values to 1e-9).
fs::path run_with_fields(int ranks) {
  Scene scene = test::dam_break(false);
  scene.simulation.fps = 50.0;
  scene.simulation.frames = 3;
  scene.simulation.save_suffix = ".h5";
  scene.simulation.save_path = (fs::path(::testing::TempDir()) / ("fbar_grid_fields_" + std::to_string(ranks))).string();
  fs::remove_all(scene.simulation.save_path);
  GridFieldSpec wall = field({0.25, 0.0, 0.0}, {0.64, 0.4, 0.2}, {"Mass", "Force", "BoundaryForce", "Volume"});
  GridFieldSpec off = wall;
  off.toggle = false;
  GridFieldSpec blocks = field({0.0, 0.0, 0.0}, {0.64, 0.4, 0.2}, {"Mass", "Momentum"}, true);
  blocks.output_frequency = 50.0;  // the frame rate
  scene.grid_fields = {wall, off, blocks};
  for (const RunResult& r : test::run_cpu_ranks(scene, ranks)) EXPECT_EQ(r.exit_code, 0) << r.message;
  return scene.simulation.save_path;
}

TEST(GridFields, RunLoopWritesSamplesAndTheirSeriesAndRanksAgree) {
  const fs::path one = run_with_fields(1), two = run_with_fields(2);
  // 0.06 s at 100 Hz: samples 0..5; at 50 Hz: 0..2 (the end time is not sampled: no step starts there).
  // Sample k of a field in both runs: the same nodes (positions), the same masses to summation order.
  const auto same_nodes = [&](const std::string& name) {
    ASSERT_TRUE(fs::exists(one / name)) << name;
    ASSERT_TRUE(fs::exists(two / name)) << name;
    hsize_t r1 = 0, r2 = 0;
    EXPECT_TRUE(read_h5(one / name, "Position", r1) == read_h5(two / name, "Position", r2)) << name;
    const std::vector<double> m1 = read_h5(one / name, "Mass", r1), m2 = read_h5(two / name, "Mass", r2);
    ASSERT_EQ(m1.size(), m2.size()) << name;
    for (std::size_t i = 0; i < m1.size(); ++i) EXPECT_NEAR(m1[i], m2[i], 1e-9 * (1.0 + m1[i])) << name << " node " << i;
  };
  for (int k = 0; k < 6; ++k) same_nodes("gridField[0]_frame[" + std::to_string(k) + "].h5");
  EXPECT_FALSE(fs::exists(one / "gridField[0]_frame[6].h5"));
  EXPECT_FALSE(fs::exists(one / "gridField[1]_frame[0].h5")) << "switched off";
  for (int k = 0; k < 3; ++k) same_nodes("gridField[2]_frame[" + std::to_string(k) + "].h5");
  EXPECT_FALSE(fs::exists(one / "gridField[2]_frame[3].h5"));
  const std::string series = bytes_of(one / "gridField[0].xdmf");
  EXPECT_TRUE(series == bytes_of(two / "gridField[0].xdmf"));
  const std::regex time(R"re(<Time Value="([^"]+)"/>)re");
  std::vector<double> times;
  for (auto it = std::sregex_iterator(series.begin(), series.end(), time); it != std::sregex_iterator(); ++it)
    times.push_back(std::stod((*it)[1]));
  ASSERT_EQ(times.size(), 6u);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(times[k], k / 100.0, 1e-12);
  EXPECT_NE(series.find("gridField[0]_frame[5].h5:/Force"), std::string::npos);
  EXPECT_NE(series.find("CollectionType=\"Temporal\""), std::string::npos);
  // The right field's frame: the nodes of mass at x >= 0.25 m (the column's front half), read back in order, each
  // with its volume.
  hsize_t rows = 0, volume_rows = 0;
  const std::vector<double> x = read_h5(one / "gridField[0]_frame[5].h5", "Position", rows);
  ASSERT_GT(rows, 0u);
  for (hsize_t i = 0; i < rows; ++i) {
    EXPECT_GE(x[3 * i], 0.25 - 1e-9);
    if (i > 0) {
      EXPECT_LE(x[3 * (i - 1)], x[3 * i]) << "nodes in index order";
    }
  }
  const std::vector<double> volume = read_h5(one / "gridField[0]_frame[5].h5", "Volume", volume_rows);
  EXPECT_EQ(volume_rows, rows);
  for (double v : volume) EXPECT_GT(v, 0.0) << "every node of mass has volume";
  const std::vector<double> bm = read_h5(one / "gridField[2]_frame[2].h5", "Mass", rows);
  double mass = 0.0;
  for (double m : bm) mass += m;
  EXPECT_NEAR(mass, 1000.0 * 0.3 * 0.2 * 0.12, 1e-3) << "the blocks over the whole tank hold the water's mass";
}

/// --check lists the fields and counts their device records in the GPU memory plan (104 bytes per node of the box);
/// a field reading Volume makes the grid carry the F-bar sums for it (the "grid channels" row).
TEST(GridFields, CheckListsThemAndCountsTheirMemory) {
  Scene scene = test::dam_break(false);
  const SceneSummary plain = summarize_scene(scene);
  GridFieldSpec f = field({0.0, 0.0, 0.0}, {0.2, 0.1, 0.04}, {"Mass", "Volume"});  // 11 x 6 x 3 nodes at dx 0.02
  scene.grid_fields = {f};
  const SceneSummary with = summarize_scene(scene);
  EXPECT_EQ(grid_field_device_bytes(scene), 11u * 6u * 3u * sizeof(GridFieldNode) + sizeof(int));
  EXPECT_EQ(with.gpu_plans.at(0).small - plain.gpu_plans.at(0).small, grid_field_device_bytes(scene));
  EXPECT_EQ(with.bodies.at(0).grid_channels, "mass, momentum (4) + F-bar / node volume sums (2)");
  std::ostringstream os;
  print_scene_report(os, scene, with);
  EXPECT_NE(os.str().find("grid-fields[0]  Mass, Volume per node at 100 Hz"), std::string::npos) << os.str();
  EXPECT_NE(os.str().find("-> gridField[0]_frame[0].bgeo"), std::string::npos) << os.str();
}

/// A restart from frame 1's checkpoint (t = 0.02 s) into a copy of the run's files up to it: the samples from 0.02 s on
/// are written again with the uninterrupted run's bytes (the CPU engine continues bit for bit), and the series lists
/// the first run's samples with the restart's.
TEST(GridFields, ARestartContinuesTheSamplesAndTheSeries) {
  Scene scene = test::dam_break(false);
  scene.simulation.fps = 50.0;
  scene.simulation.frames = 3;
  scene.simulation.save_suffix = ".h5";
  scene.simulation.checkpoint_every = 1;
  const fs::path a = fs::path(::testing::TempDir()) / "fbar_grid_fields_restart_a";
  const fs::path b = fs::path(::testing::TempDir()) / "fbar_grid_fields_restart_b";
  fs::remove_all(a);
  fs::remove_all(b);
  scene.simulation.save_path = a.string();
  scene.grid_fields = {field({0.0, 0.0, 0.0}, {0.64, 0.4, 0.2}, {"Mass", "Velocity", "Force"})};
  for (const RunResult& r : test::run_cpu_ranks(scene, 1)) ASSERT_EQ(r.exit_code, 0) << r.message;
  fs::copy(a, b, fs::copy_options::recursive);
  for (int k = 2; k < 6; ++k) {  // the samples at and after the checkpoint's time, and the series
    fs::remove(b / ("gridField[0]_frame[" + std::to_string(k) + "].h5"));
    fs::remove(b / ("gridField[0]_frame[" + std::to_string(k) + "].xdmf"));
  }
  fs::remove(b / "gridField[0].xdmf");
  scene.simulation.save_path = b.string();
  const fs::path checkpoint = io::checkpoint_frame_path(b, 1, 0);
  ASSERT_TRUE(fs::exists(checkpoint));
  for (const RunResult& r : test::run_cpu_ranks(scene, 1, checkpoint.string())) ASSERT_EQ(r.exit_code, 0) << r.message;
  for (int k = 0; k < 6; ++k) {
    const std::string name = "gridField[0]_frame[" + std::to_string(k) + "].h5";
    ASSERT_TRUE(fs::exists(b / name)) << name;
    EXPECT_TRUE(bytes_of(a / name) == bytes_of(b / name)) << name << ": the restart's sample differs from the run's";
  }
  EXPECT_TRUE(bytes_of(a / "gridField[0].xdmf") == bytes_of(b / "gridField[0].xdmf"))
      << bytes_of(a / "gridField[0].xdmf") << "\n---\n" << bytes_of(b / "gridField[0].xdmf");
}

}  // namespace
}  // namespace fbar
