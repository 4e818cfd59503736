// File geometry (geometry_files.h): SDF solids against the analytic shapes they describe, point files in every
// format with placement, arrays, rotation and later operations, bed bodies (Bathymetry, OSU LWF / TWB) against their
// profiles, and errors that name the file and the line.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "MnSystem/IO/particle_io.h"
#include "geometry/geometry.h"
#include "geometry/geometry_files.h"
#include "scene/facilities.h"
#include "scene/scene_error.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() /
                     ("fbar_geometry_files_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
                      ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(d);
  return d;
}

SimulationSpec make_sim(double dx, Real3 domain = {1.0, 1.0, 1.0}) {
  SimulationSpec s;
  s.dx = dx;
  s.domain = domain;
  return s;
}

BodySpec make_body(std::vector<GeometrySpec> geometry, double ppc = 8) {
  BodySpec b;
  b.geometry = std::move(geometry);
  b.material.ppc = ppc;
  return b;
}

GeometrySpec file_entry(const fs::path& path, Real3 offset = {0, 0, 0}) {
  GeometrySpec g;
  g.object = GeometryObject::File;
  g.file = path.string();
  g.offset = offset;
  return g;
}

/// Writes an SDFGen file of the exact distance to a sphere of radius r whose bounding box's min corner is at grid
/// index `padding`: value(i, j, k) = |(i, j, k) - padding - r/h| h - r, on n = 2 r / h + 2 padding + 1 points.
fs::path write_sphere_sdf(const fs::path& dir, double r, double h, int padding) {
  const int n = static_cast<int>(std::lround(2.0 * r / h)) + 2 * padding + 1;
  const fs::path path = dir / "sphere.sdf";
  std::ofstream out(path);
  out << n << " " << n << " " << n << "\n-1 -1 -1\n" << h << "\n";
  const double c = padding + r / h;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        out << (std::sqrt((i - c) * (i - c) + (j - c) * (j - c) + (k - c) * (k - c)) * h - r) << (i + 1 < n ? " " : "\n");
  return path;
}

using Key = std::tuple<long long, long long, long long>;
std::set<Key> keys_of(const std::vector<Vec3d>& pts, double h) {
  std::set<Key> k;
  for (const Vec3d& p : pts)
    k.insert({std::llround(p[0] / h * 2), std::llround(p[1] / h * 2), std::llround(p[2] / h * 2)});
  return k;
}

// An SDF of a sphere samples the same body as the analytic Sphere: the same lattice points except within the
// interpolation error of the surface (trilinear interpolation of |x| - r is off by at most h_sdf^2 / (8 r) per
// axis... bounded here by h_sdf / 4), and every point of the difference lies within that shell.
TEST(FileGeometry, SdfSphereSamplesTheAnalyticSphere) {
  const fs::path dir = temp_dir();
  const double r = 0.2, h_sdf = 0.01, dx = 0.02;
  const Real3 offset{0.3, 0.25, 0.35};
  for (int padding : {1, 3}) {
    GeometrySpec sdf = file_entry(write_sphere_sdf(dir, r, h_sdf, padding), offset);
    sdf.padding = padding;
    GeometrySpec ball;
    ball.object = GeometryObject::Sphere;
    ball.offset = offset;
    ball.radius = r;
    const SimulationSpec sim = make_sim(dx);
    const std::vector<Vec3d> a = sample_body(make_body({sdf}), sim, 0);
    const std::vector<Vec3d> b = sample_body(make_body({ball}), sim, 0);
    const double h = dx / 2;
    const std::set<Key> ka = keys_of(a, h), kb = keys_of(b, h);
    const Vec3d centre{{offset[0] + r, offset[1] + r, offset[2] + r}};
    std::size_t differ = 0;
    for (const auto* pair : {&ka, &kb}) {
      const std::set<Key>& other = pair == &ka ? kb : ka;
      for (const Key& k : *pair) {
        if (other.count(k)) continue;
        ++differ;
        const Vec3d p{{std::get<0>(k) * h / 2, std::get<1>(k) * h / 2, std::get<2>(k) * h / 2}};
        EXPECT_NEAR(norm(p - centre), r, h_sdf / 4) << "padding " << padding;
      }
    }
    EXPECT_LT(static_cast<double>(differ), 0.01 * b.size()) << "padding " << padding;
    EXPECT_NEAR(static_cast<double>(a.size()), static_cast<double>(b.size()), 0.01 * b.size());
  }
}

// scaling_factor scales the solid about its offset: twice the size holds 8 times the particles (within the
// lattice's surface error), and its bounding box starts at the offset.
TEST(FileGeometry, SdfScalingFactorScalesAboutTheOffset) {
  const fs::path dir = temp_dir();
  const fs::path path = write_sphere_sdf(dir, 0.1, 0.01, 1);
  const SimulationSpec sim = make_sim(0.02);
  GeometrySpec one = file_entry(path, {0.2, 0.2, 0.2});
  GeometrySpec two = one;
  two.scaling_factor = 2.0;
  const std::vector<Vec3d> a = sample_body(make_body({one}), sim, 0);
  const std::vector<Vec3d> b = sample_body(make_body({two}), sim, 0);
  EXPECT_NEAR(static_cast<double>(b.size()) / a.size(), 8.0, 0.4);
  double lo = 1e9;
  for (const Vec3d& p : b) lo = std::min(lo, p[0]);
  EXPECT_NEAR(lo, 0.2, 0.02);  // the first lattice plane inside the sphere of radius 0.2 starting at 0.2
}

// Point files: every format reads the same points; offset + scaling_factor * p, array copies, rotation about the
// fulcrum, the partition clip and a later Subtract all apply; the order is the file's.
TEST(FileGeometry, PointFilesInEveryFormatArePlacedLikeShapes) {
  const fs::path dir = temp_dir();
  const std::vector<Vec3d> pts = {Vec3d{{0.0, 0.0, 0.0}}, Vec3d{{0.1, 0.0, 0.0}}, Vec3d{{0.0, 0.2, 0.05}},
                                  Vec3d{{0.05, 0.05, 0.1}}};
  {
    std::ofstream csv(dir / "p.csv");
    csv << "Position_X [m],Position_Y [m],Position_Z [m],J\n";
    for (const Vec3d& p : pts) csv << p[0] << "," << p[1] << "," << p[2] << ",1\n";
    std::ofstream plain(dir / "plain.csv");  // ClaymoreUW's: no header, x, y, z first
    for (const Vec3d& p : pts) plain << p[0] << "," << p[1] << "," << p[2] << ",7,8\n";
    std::ofstream pos(dir / "p.pos");
    pos << "# x y z\n";
    for (const Vec3d& p : pts) pos << p[0] << " \t" << p[1] << " " << p[2] << "\n";
  }
  io::ParticleFrame frame;
  frame.positions = std::vector<Vec3d>(pts.begin(), pts.end());
  io::write_bgeo(dir / "p.bgeo", frame);
  io::write_h5(dir / "p.h5", frame);
  for (const char* name : {"p.csv", "plain.csv", "p.pos", "p.bgeo", "p.h5"}) {
    const std::vector<Vec3d> read = read_point_file((dir / name).string());
    ASSERT_EQ(read.size(), pts.size()) << name;
    for (std::size_t i = 0; i < pts.size(); ++i)
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(read[i][a], pts[i][a], 1e-7) << name << " point " << i;
  }

  const SimulationSpec sim = make_sim(0.05);
  GeometrySpec g = file_entry(dir / "p.pos", {0.2, 0.3, 0.4});
  g.scaling_factor = 2.0;
  std::vector<Vec3d> out = sample_body(make_body({g}), sim, 0);
  ASSERT_EQ(out.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(out[i][a], g.offset[a] + 2.0 * pts[i][a], 1e-12);

  g.array = {2, 1, 1};
  g.spacing = {0.3, 0, 0};
  g.rotate = {0, 0, 90};  // about z through the fulcrum: (x, y) -> (f_x - (y - f_y), f_y + (x - f_x))
  g.fulcrum = {0.5, 0.5, 0.5};
  out = sample_body(make_body({g}), sim, 0);
  ASSERT_EQ(out.size(), 8u);
  for (std::size_t c = 0; c < 2; ++c)
    for (std::size_t i = 0; i < 4; ++i) {
      const Vec3d local{{0.2 + 2.0 * pts[i][0] + 0.3 * c, 0.3 + 2.0 * pts[i][1], 0.4 + 2.0 * pts[i][2]}};
      const Vec3d& p = out[c * 4 + i];
      EXPECT_NEAR(p[0], 0.5 - (local[1] - 0.5), 1e-12);
      EXPECT_NEAR(p[1], 0.5 + (local[0] - 0.5), 1e-12);
      EXPECT_NEAR(p[2], local[2], 1e-12);
    }

  // A later Subtract removes the points inside it; the partition clip is half-open like the lattice's.
  GeometrySpec plain = file_entry(dir / "plain.csv", {0.2, 0.3, 0.4});
  GeometrySpec cut;
  cut.object = GeometryObject::Box;
  cut.operation = GeometryOperation::Subtract;
  cut.offset = {0.15, 0.25, 0.35};
  cut.span = {0.1, 0.1, 0.1};  // holds the first point only (the fourth, (0.25, 0.35, 0.5), is above z = 0.45)
  BodySpec body = make_body({plain, cut});
  out = sample_body(body, sim, 0);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_NEAR(out[0][0], 0.3, 1e-12);
  body.partition_end = {1.0, 0.5, 1.0};  // drops y = 0.5 (half-open), keeps y = 0.35
  out = sample_body(body, sim, 0);
  EXPECT_EQ(out.size(), 2u);
  // Points and a solid in one body: the lattice first, then the file's points.
  GeometrySpec box;
  box.object = GeometryObject::Box;
  box.offset = {0.6, 0.6, 0.6};
  box.span = {0.1, 0.1, 0.1};
  out = sample_body(make_body({box, plain}), sim, 0);
  ASSERT_EQ(out.size(), 8u * 8u + 4u);
  EXPECT_NEAR(out.back()[1], 0.3 + 0.05, 1e-12);
  // The counts the GPU engine sizes its buffers from agree with the sampling, point chunks included.
  const BodySampler sampler(make_body({box, plain}), sim, 0);
  const SampleCount count = sampler.count(sim.dx);
  EXPECT_EQ(count.particles, 68);
  long long per_plane = 0;
  for (long long n : count.per_plane) per_plane += n;
  EXPECT_EQ(per_plane, 68);
  EXPECT_EQ(static_cast<long long>(count.per_plane.size()), sampler.planes());
}

// has_attributes: named values come with the positions from a .csv header, a .bgeo and an .h5, whatever their order
// in the file; a missing name is an error that lists what the file holds.
TEST(FileGeometry, AttributesAreReadByNameInEveryFormat) {
  const fs::path dir = temp_dir();
  io::ParticleFrame frame;
  frame.positions = std::vector<Vec3d>{Vec3d{{0.1, 0.2, 0.3}}, Vec3d{{0.4, 0.5, 0.6}}, Vec3d{{0.7, 0.8, 0.9}}};
  frame.add("ID", 1, std::vector<std::int32_t>{0, 1, 2});
  frame.add("Velocity_X", 1, std::vector<float>{1.5f, -2.0f, 0.25f}, "m/s");
  frame.add("J", 1, std::vector<float>{0.99f, 1.0f, 1.01f});
  frame.add("DefGrad_Determinant_FBAR", 1, std::vector<float>{0.98f, 0.97f, 0.96f});
  io::write_bgeo(dir / "a.bgeo", frame);
  io::write_h5(dir / "a.h5", frame);
  io::write_csv(dir / "a.csv", frame);
  const std::vector<std::string> names = {"J", "ID", "Velocity_X", "JBar"};
  const std::vector<std::string> aliases = {"DefGrad_Determinant", "", "", "DefGrad_Determinant_FBAR"};
  for (const char* name : {"a.bgeo", "a.h5", "a.csv"}) {
    std::vector<double> values;
    const std::vector<Vec3d> x = read_point_file((dir / name).string(), names, aliases, values);
    ASSERT_EQ(x.size(), 3u) << name;
    ASSERT_EQ(values.size(), 12u) << name;
    for (std::size_t p = 0; p < 3; ++p) {
      EXPECT_FLOAT_EQ(static_cast<float>(values[4 * p + 0]), std::get<0>(frame.attributes[2].values)[p]) << name;
      EXPECT_EQ(values[4 * p + 1], static_cast<double>(p)) << name;
      EXPECT_FLOAT_EQ(static_cast<float>(values[4 * p + 2]), std::get<0>(frame.attributes[1].values)[p]) << name;
      EXPECT_FLOAT_EQ(static_cast<float>(values[4 * p + 3]), std::get<0>(frame.attributes[3].values)[p]) << name;
    }
    std::vector<double> none;
    try {
      read_point_file((dir / name).string(), {"logJp"}, {""}, none);
      ADD_FAILURE() << name << ": a missing attribute was accepted";
    } catch (const std::runtime_error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("named logJp"), std::string::npos) << m;
      EXPECT_NE(m.find("Velocity_X"), std::string::npos) << m;  // what the file holds
    }
  }
  {
    std::ofstream plain(dir / "plain.csv");
    plain << "0.1,0.2,0.3,1\n";
    std::ofstream pos(dir / "p.pos");
    pos << "0.1 0.2 0.3\n";
  }
  std::vector<double> v;
  EXPECT_THROW(read_point_file((dir / "plain.csv").string(), {"J"}, {""}, v), std::runtime_error);  // no header
  EXPECT_THROW(read_point_file((dir / "p.pos").string(), {"J"}, {""}, v), std::runtime_error);
}

// The seeds of a placed file: velocities turn with the entry's rotation and scale with Froude (s^0.5), F turns as
// R F R^T, and they follow their particles through the partition clip and the array copies.
TEST(FileGeometry, SeedsFollowRotationFroudeScalingAndClipping) {
  const fs::path dir = temp_dir();
  {
    std::ofstream csv(dir / "s.csv");
    csv << "Position_X,Position_Y,Position_Z,Velocity_X,Velocity_Y,Velocity_Z,DefGrad_XX,DefGrad_XY,DefGrad_XZ,"
           "DefGrad_YX,DefGrad_YY,DefGrad_YZ,DefGrad_ZX,DefGrad_ZY,DefGrad_ZZ,logJp\n";
    csv << "0,0,0, 1,0,0, 2,0,0, 0,1,0, 0,0,1, -0.1\n";
    csv << "0.1,0,0, 0,3,0, 1,0,0, 0,1,0, 0,0,1, -0.2\n";
  }
  SimulationSpec sim = make_sim(0.05);
  sim.froude_scaling = 4.0;
  GeometrySpec g = file_entry(dir / "s.csv", {0.2, 0.2, 0.2});
  g.has_attributes = true;
  g.input_attribs = {"Velocity_X", "Velocity_Y", "Velocity_Z", "DefGrad_XX", "DefGrad_XY", "DefGrad_XZ",
                     "DefGrad_YX", "DefGrad_YY", "DefGrad_YZ", "DefGrad_ZX", "DefGrad_ZY", "DefGrad_ZZ", "logJp"};
  g.rotate = {0, 0, 90};
  g.fulcrum = {0.2, 0.2, 0.2};
  g.array = {1, 1, 2};
  g.spacing = {0, 0, 0.3};
  BodySpec body = make_body({g});
  ParticleSeeds seeds;
  std::vector<Vec3d> x = sample_body(body, sim, 0, &seeds);
  ASSERT_EQ(x.size(), 4u);
  ASSERT_EQ(seeds.size(), 4u);
  EXPECT_EQ(seeds.first, 0);
  for (std::size_t c = 0; c < 2; ++c) {
    const double* a = seeds.at(2 * c);      // v (1, 0, 0) -> R v = (0, 1, 0), x 2 (Froude 4)
    const double* b = seeds.at(2 * c + 1);  // v (0, 3, 0) -> (-3, 0, 0) x 2
    EXPECT_NEAR(a[kSeedVelocity + 0], 0.0, 1e-12);
    EXPECT_NEAR(a[kSeedVelocity + 1], 2.0, 1e-12);
    EXPECT_NEAR(b[kSeedVelocity + 0], -6.0, 1e-12);
    EXPECT_NEAR(b[kSeedVelocity + 1], 0.0, 1e-12);
    EXPECT_NEAR(a[kSeedDefGrad + 0], 1.0, 1e-12);  // diag(2, 1, 1) -> diag(1, 2, 1)
    EXPECT_NEAR(a[kSeedDefGrad + 4], 2.0, 1e-12);
    EXPECT_NEAR(a[kSeedDefGrad + 1], 0.0, 1e-12);
    EXPECT_EQ(a[kSeedLogJp], -0.1);
    EXPECT_EQ(b[kSeedLogJp], -0.2);
    EXPECT_TRUE(std::isnan(a[kSeedJ]));
  }
  // The clip drops the second point of each copy (rotated to y = 0.2 + 0.1 = 0.3 >= 0.25); its seed goes with it.
  body.partition_end = {1.0, 0.25, 1.0};
  x = sample_body(body, sim, 0, &seeds);
  ASSERT_EQ(x.size(), 2u);
  ASSERT_EQ(seeds.size(), 2u);
  EXPECT_EQ(seeds.at(0)[kSeedLogJp], -0.1);
  EXPECT_EQ(seeds.at(1)[kSeedLogJp], -0.1);
  // After a sampled solid, the seeded particles are the last ones: `first` counts the lattice's.
  GeometrySpec box;
  box.object = GeometryObject::Box;
  box.offset = {0.6, 0.6, 0.6};
  box.span = {0.1, 0.1, 0.1};
  x = sample_body(make_body({box, g}), sim, 0, &seeds);
  EXPECT_EQ(seeds.first, 64);
  EXPECT_EQ(seeds.size(), 4u);
  EXPECT_EQ(x.size(), 68u);
  // An inverted particle (J <= 0: ClaymoreUW writes such points into its own frames, and its breaking wave's frame
  // 20 holds them) is dropped, and the shape says which and how many; the other particles keep their seeds.
  {
    std::ofstream csv(dir / "bad.csv");
    csv << "Position_X,Position_Y,Position_Z,J\n0.1,0.1,0.1,1\n0.2,0.2,0.2,-0.5\n0.3,0.3,0.3,0.9\n";
  }
  GeometrySpec bad = file_entry(dir / "bad.csv");
  bad.has_attributes = true;
  bad.input_attribs = {"J"};
  x = sample_body(make_body({bad}), make_sim(0.05), 0, &seeds);
  ASSERT_EQ(x.size(), 2u);
  ASSERT_EQ(seeds.size(), 2u);
  EXPECT_EQ(seeds.at(0)[kSeedJ], 1.0);
  EXPECT_EQ(seeds.at(1)[kSeedJ], 0.9);
  EXPECT_DOUBLE_EQ(x[1][0], 0.3);
  const BodyDrops drops = body_drops(make_body({bad}), make_sim(0.05), 0);
  ASSERT_EQ(drops.file_notes.size(), 1u);
  EXPECT_EQ(drops.file_notes[0].dropped, 1u);
  EXPECT_EQ(drops.file_notes[0].read, 3u);
  EXPECT_EQ(drops.file_notes[0].first, "point 1: J = -0.5");
}

// A point file can only be added: it holds no volume that could be subtracted or intersected.
TEST(FileGeometry, ErrorsNameTheFileAndTheLine) {
  const fs::path dir = temp_dir();
  const SimulationSpec sim = make_sim(0.05);
  auto error_of = [&](const GeometrySpec& g) -> std::pair<std::string, std::string> {
    try {
      GeometrySpec box;
      box.object = GeometryObject::Box;
      box.offset = {0.1, 0.1, 0.1};
      box.span = {0.2, 0.2, 0.2};
      sample_body(make_body({box, g}), sim, 0);
    } catch (const SceneError& e) {
      return {e.path(), e.what()};
    }
    ADD_FAILURE() << "no SceneError";
    return {};
  };
  { std::ofstream(dir / "bad.csv") << "0.1,0.2,0.3\n0.1,zero,0.3\n"; }
  auto [path, what] = error_of(file_entry(dir / "bad.csv"));
  EXPECT_EQ(path, "bodies[0].geometry[1].file");
  EXPECT_NE(what.find("line 2: expected a finite number, got \"zero\""), std::string::npos) << what;
  { std::ofstream(dir / "short.sdf") << "2 2 2\n0 0 0\n0.1\n-1 -1 -1\n"; }
  std::tie(path, what) = error_of(file_entry(dir / "short.sdf"));
  EXPECT_NE(what.find("holds 3 of the 8 values"), std::string::npos) << what;
  { std::ofstream(dir / "two.csv") << "0.1,0.2\n"; }
  std::tie(path, what) = error_of(file_entry(dir / "two.csv"));
  EXPECT_NE(what.find("line 1: expected at least 3 values (x, y, z), got 2"), std::string::npos) << what;
  { std::ofstream(dir / "ok.csv") << "0.1,0.2,0.3\n"; }
  GeometrySpec sub = file_entry(dir / "ok.csv");
  sub.operation = GeometryOperation::Subtract;
  std::tie(path, what) = error_of(sub);
  EXPECT_EQ(path, "bodies[0].geometry[1].operation");
  { std::ofstream(dir / "empty.pos") << "# nothing\n"; }
  std::tie(path, what) = error_of(file_entry(dir / "empty.pos"));
  EXPECT_NE(what.find("holds no points"), std::string::npos) << what;
  std::tie(path, what) = error_of(file_entry(dir / "missing.h5"));
  EXPECT_EQ(path, "bodies[0].geometry[1].file");
}

// A Bathymetry body is the water above its bed inside its box: the lattice count matches the analytic volume
// (the bed's mean height over the box) within the one-plane sampling error, and no particle lies below the bed.
TEST(FileGeometry, BathymetryBodyIsTheWaterAboveTheBed) {
  const SimulationSpec sim = make_sim(0.02, {2.0, 1.0, 1.0});
  GeometrySpec g;
  g.object = GeometryObject::Bathymetry;
  g.offset = {0.0, 0.0, 0.0};
  g.span = {2.0, 0.6, 0.2};
  g.bathymetry = {{0.5, 0.0}, {1.5, 0.4}};  // flat 0 before 0.5, 1:2.5 ramp, flat 0.4 after 1.5
  const std::vector<Vec3d> pts = sample_body(make_body({g}), sim, 0);
  for (const Vec3d& p : pts) ASSERT_GE(p[1], bed_height(g.bathymetry, p[0]));
  const double volume = 2.0 * 0.6 * 0.2 - 0.2 * (1.0 * 0.2 + 0.5 * 0.4);  // box minus bed (ramp triangle + flat)
  const double h = 0.01, per_point = h * h * h;
  EXPECT_NEAR(pts.size() * per_point, volume, 2.0 * 0.2 * h + 1e-9);  // one lattice spacing over the bed's length

  // The OSU LWF water sits on the flume's bed (ClaymoreUW's table, 0.225 m x s above the floor at the wave maker)
  // whose neutral position lies 0.1 m x s after the offset (ClaymoreUW's make_OSU_LWF), scaled by s.
  const double s = 1.0 / 20.0;
  SimulationSpec flume = make_sim(0.02, {5.0, 0.5, 0.2});
  flume.froude_scaling = s;
  GeometrySpec lwf;
  lwf.object = GeometryObject::OsuLwf;
  lwf.offset = {0.1, 0.05, 0.0};
  lwf.span = {4.8, 0.15, 0.2};
  const std::vector<Vec3d> water = sample_body(make_body({lwf}), flume, 0);
  const BedPoints bed = place_bed(osu_lwf_bathymetry(), s, 0.1 + 0.1 * s, 0.05);
  ASSERT_EQ(bed.front()[1], 0.05 + 0.225 * s);
  std::map<std::pair<long long, long long>, double> lowest;  // per lattice column: lowest particle above the bed
  for (const Vec3d& p : water) {
    ASSERT_GE(p[1], bed_height(bed, p[0])) << p[0];
    const auto key = std::make_pair(std::llround(p[0] / h), std::llround(p[2] / h));
    const double gap = p[1] - bed_height(bed, p[0]);
    auto it = lowest.find(key);
    if (it == lowest.end() || gap < it->second) lowest[key] = gap;
  }
  for (const auto& [column, gap] : lowest) EXPECT_LE(gap, h) << column.first;  // no gap under the water
  // 10 m x s after the neutral position the bed stands 0.225 m x s above the floor, on the plateau (60 m x s) 1.75 m
  // x s: the water columns are that much shorter than the span. Before the neutral position (x < 0.1 + 0.1 s) the
  // bed is flat at 0.225 m x s too: no water under it.
  std::size_t near_start = 0, past_ramp = 0;
  for (const Vec3d& p : water) {
    ASSERT_GE(p[1], 0.05 + 0.225 * s - 1e-12) << p[0];
    if (std::fabs(p[0] - (0.1 + 10.0 * s)) < 0.006) ++near_start;
    if (std::fabs(p[0] - (0.1 + 60.0 * s)) < 0.006) ++past_ramp;
  }
  ASSERT_GT(near_start, 0u);
  EXPECT_NEAR(static_cast<double>(past_ramp) / near_start, (0.15 - 1.75 * s) / (0.15 - 0.225 * s), 0.08);
}

}  // namespace
}  // namespace fbar
