// Tests of particle frame files: bgeo bytes against the classic format, round trips, geo/csv text, async writer.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <future>
#include <limits>
#include <random>
#include <sstream>
#include <thread>

#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"

namespace fbar::io {
namespace {

namespace fs = std::filesystem;

/// A fresh directory per test, removed afterwards.
class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("fbar_io_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::uint32_t bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

/// Two particles with an int, a vector and a float attribute; values chosen with short exact binary forms.
ParticleFrame small_frame() {
  ParticleFrame f;
  f.positions = std::vector<Vec3f>{Vec3f{{0.5f, 0.25f, 0.125f}}, Vec3f{{1.0f, 2.0f, 3.0f}}};
  f.add("ID", 1, std::vector<std::int32_t>{7, 8});
  f.add("Velocity", 3, std::vector<float>{1.0f, -2.5f, 3.0f, 0.1f, 0.0f, 0.0f}, "m/s");
  f.add("J", 1, std::vector<float>{1.0f, 0.5f});
  return f;
}

void append_be32(std::string& s, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) s.push_back(static_cast<char>((v >> shift) & 0xff));
}
void append_be16(std::string& s, std::uint16_t v) {
  s.push_back(static_cast<char>(v >> 8));
  s.push_back(static_cast<char>(v & 0xff));
}

TEST(FrameNames, ClaymoreUwPattern) {
  EXPECT_EQ(frame_file_name(0, 0, 12, ".bgeo"), "model[0]_dev[0]_frame[12].bgeo");
  EXPECT_EQ(frame_file_name(3, 1, 0, ".csv"), "model[3]_dev[1]_frame[0].csv");
  EXPECT_EQ(frame_file_path("out/run", 1, 2, 345, ".geo"), fs::path("out/run/model[1]_dev[2]_frame[345].geo"));
  EXPECT_EQ(frame_format(".bgeo"), FrameFormat::Bgeo);
  EXPECT_EQ(frame_format(".geo"), FrameFormat::Geo);
  EXPECT_EQ(frame_format(".csv"), FrameFormat::Csv);
  EXPECT_EQ(frame_format(".h5"), FrameFormat::H5);
  EXPECT_THROW(frame_format(".vtk"), std::invalid_argument);
}

// The expected file is assembled here byte by byte from the classic bgeo description (partio BGEO.cpp), with
// IEEE-754 bit patterns written out by hand: 1.0f = 0x3f800000, 0.5f = 0x3f000000, -2.5f = 0xc0200000, ...
TEST_F(IoTest, BgeoBytesFollowTheClassicFormat) {
  const fs::path path = dir_ / "small.bgeo";
  write_bgeo(path, small_frame());
  std::string want;
  want += "BgeoV";
  append_be32(want, 5);  // version
  append_be32(want, 2);  // nPoints
  append_be32(want, 0);  // nPrims
  append_be32(want, 0);  // nPointGroups
  append_be32(want, 0);  // nPrimGroups
  append_be32(want, 3);  // nPointAttrib
  append_be32(want, 0);  // nVertexAttrib
  append_be32(want, 0);  // nPrimAttrib
  append_be32(want, 0);  // nAttrib
  ASSERT_EQ(want.size(), 41u);
  append_be16(want, 2), want += "ID", append_be16(want, 1), append_be32(want, 1), append_be32(want, 0);
  append_be16(want, 8), want += "Velocity", append_be16(want, 3), append_be32(want, 5);
  for (int i = 0; i < 3; ++i) append_be32(want, 0);
  append_be16(want, 1), want += "J", append_be16(want, 1), append_be32(want, 0), append_be32(want, 0);
  // point 0: P = (0.5, 0.25, 0.125, 1), ID 7, v = (1, -2.5, 3), J = 1
  for (std::uint32_t u : {0x3f000000u, 0x3e800000u, 0x3e000000u, 0x3f800000u, 7u, 0x3f800000u, 0xc0200000u,
                          0x40400000u, 0x3f800000u})
    append_be32(want, u);
  // point 1: P = (1, 2, 3, 1), ID 8, v = (0.1f, 0, 0), J = 0.5
  for (std::uint32_t u : {0x3f800000u, 0x40000000u, 0x40400000u, 0x3f800000u, 8u, 0x3dcccccdu, 0u, 0u, 0x3f000000u})
    append_be32(want, u);
  want.push_back('\x00');
  want.push_back('\xff');
  const std::string got = slurp(path);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) ASSERT_EQ(got[i], want[i]) << "byte " << i;
  EXPECT_FALSE(fs::exists(dir_ / "small.bgeo.part"));
}

TEST_F(IoTest, BgeoRoundTripIsBitExact) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u(-1e3f, 1e3f);
  const std::size_t n = 5000;
  ParticleFrame f;
  std::vector<Vec3d> x(n);
  std::vector<float> vel(3 * n), mass(n);
  std::vector<std::int32_t> id(n);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = Vec3d{{std::ldexp(double(u(rng)), -3), double(u(rng)), 1.0 + 1e-9 * i}};  // doubles: rounded to float
    for (int c = 0; c < 3; ++c) vel[3 * i + c] = u(rng);
    mass[i] = u(rng);
    id[i] = static_cast<std::int32_t>(i) - 17;
  }
  // Awkward values survive too: signed zero, denormal, infinity, extremes.
  vel[0] = -0.0f;
  vel[1] = std::numeric_limits<float>::denorm_min();
  vel[2] = std::numeric_limits<float>::infinity();
  mass[0] = std::numeric_limits<float>::max();
  id[1] = std::numeric_limits<std::int32_t>::min();
  id[2] = std::numeric_limits<std::int32_t>::max();
  f.positions = x;
  f.add("Velocity", 3, vel, "m/s");
  f.add("ID", 1, id);
  f.add("Mass", 1, mass, "kg");
  const fs::path path = dir_ / "round.bgeo";
  write_bgeo(path, f);
  const ParticleFrame r = read_bgeo(path);
  ASSERT_EQ(r.size(), n);
  ASSERT_FALSE(r.double_precision());
  ASSERT_EQ(r.attributes.size(), 3u);
  EXPECT_EQ(r.attributes[0].name, "Velocity");
  EXPECT_EQ(r.attributes[0].width, 3);
  EXPECT_EQ(r.attributes[0].type(), AttributeType::Float);
  EXPECT_EQ(r.attributes[1].name, "ID");
  EXPECT_EQ(r.attributes[1].type(), AttributeType::Int);
  EXPECT_EQ(r.attributes[2].name, "Mass");
  const auto& rx = std::get<0>(r.positions);
  for (std::size_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) ASSERT_EQ(bits(rx[i][d]), bits(static_cast<float>(x[i][d]))) << i;
  for (std::size_t i = 0; i < 3 * n; ++i) ASSERT_EQ(bits(r.attributes[0].floats()[i]), bits(vel[i])) << i;
  EXPECT_EQ(r.attributes[1].ints(), id);
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(bits(r.attributes[2].floats()[i]), bits(mass[i])) << i;
  // Size: 41-byte header + dictionary + n * (4 + 3 + 1 + 1) words + 2 extra markers.
  const std::size_t dict = (2 + 8 + 2 + 4 + 12) + (2 + 2 + 2 + 4 + 4) + (2 + 4 + 2 + 4 + 4);
  EXPECT_EQ(fs::file_size(path), 41 + dict + n * 9 * 4 + 2);
}

// A frame of a million points: serialised by several threads in two chunks (records of 36 bytes, ~32 MiB per chunk),
// read back exactly, point for point.
TEST_F(IoTest, BgeoLargeFrameRoundTripsAcrossChunksAndThreads) {
  const std::size_t n = 1000003;
  ParticleFrame f;
  std::vector<Vec3d> x(n);
  std::vector<std::int32_t> id(n);
  std::vector<float> v(3 * n), p(n);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = Vec3d{{0.001 * i, -0.5 * i, 1.0 / (i + 1.0)}};
    id[i] = static_cast<std::int32_t>(n - i);
    for (int c = 0; c < 3; ++c) v[3 * i + c] = static_cast<float>(i) * (c - 1.5f);
    p[i] = std::sqrt(static_cast<float>(i));
  }
  f.positions = x;
  f.add("ID", 1, id);
  f.add("Velocity", 3, v, "m/s");
  f.add("Pressure", 1, p, "Pa");
  write_bgeo(dir_ / "big.bgeo", f);
  EXPECT_EQ(fs::file_size(dir_ / "big.bgeo"), 41 + (2 + 2 + 2 + 4 + 4) + (2 + 8 + 2 + 4 + 12) + (2 + 8 + 2 + 4 + 4) +
                                                  n * 36 + 2);
  const ParticleFrame r = read_bgeo(dir_ / "big.bgeo");
  ASSERT_EQ(r.size(), n);
  const auto& rid = r.find("ID")->ints();
  const auto& rv = r.find("Velocity")->floats();
  const auto& rp = r.find("Pressure")->floats();
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) ASSERT_EQ(r.position(i)[c], static_cast<double>(static_cast<float>(x[i][c]))) << i;
    ASSERT_EQ(rid[i], id[i]) << i;
    ASSERT_EQ(rp[i], p[i]) << i;
    for (int c = 0; c < 3; ++c) ASSERT_EQ(rv[3 * i + c], v[3 * i + c]) << i;
  }
}

TEST_F(IoTest, BgeoEmptyFrame) {
  ParticleFrame f;
  f.positions = std::vector<Vec3f>{};
  f.add("ID", 1, std::vector<std::int32_t>{});
  write_bgeo(dir_ / "empty.bgeo", f);
  const ParticleFrame r = read_bgeo(dir_ / "empty.bgeo");
  EXPECT_EQ(r.size(), 0u);
  ASSERT_EQ(r.attributes.size(), 1u);
  EXPECT_EQ(r.attributes[0].name, "ID");
}

TEST_F(IoTest, BgeoReaderRejectsBadFiles) {
  const fs::path good = dir_ / "good.bgeo";
  write_bgeo(good, small_frame());
  const std::string bytes = slurp(good);
  auto write_raw = [&](const std::string& name, const std::string& data) {
    std::ofstream(dir_ / name, std::ios::binary) << data;
    return dir_ / name;
  };
  auto message = [](const fs::path& p) {
    try {
      read_bgeo(p);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string bad_magic = bytes;
  bad_magic[0] = 'X';
  EXPECT_NE(message(write_raw("magic.bgeo", bad_magic)).find("magic.bgeo: not a classic bgeo"), std::string::npos);
  std::string v4 = bytes;
  v4[8] = 4;
  EXPECT_NE(message(write_raw("v4.bgeo", v4)).find("version 4"), std::string::npos);
  EXPECT_NE(message(write_raw("short.bgeo", bytes.substr(0, bytes.size() - 7))).find("ends early"),
            std::string::npos);
  EXPECT_NE(message(write_raw("tail.bgeo", bytes + "x")).find("unexpected bytes"), std::string::npos);
  EXPECT_NE(message(write_raw("new.bgeo", std::string("\x7fNSJ", 4) + bytes.substr(4))).find("new-style"),
            std::string::npos);
  EXPECT_NE(message(dir_ / "missing.bgeo").find("cannot open"), std::string::npos);
}

TEST_F(IoTest, GeoTextMatchesTheClassicLayout) {
  write_geo(dir_ / "small.geo", small_frame());
  EXPECT_EQ(slurp(dir_ / "small.geo"),
            "PGEOMETRY V5\n"
            "NPoints 2 NPrims 1\n"
            "NPointGroups 0 NPrimGroups 0\n"
            "NPointAttrib 3 NVertexAttrib 0 NPrimAttrib 1 NAttrib 0\n"
            "PointAttrib\n"
            "ID 1 int 0\n"
            "Velocity 3 vector 0 0 0\n"
            "J 1 float 0\n"
            "0.5 0.25 0.125 1 (7\t1 -2.5 3\t1)\n"
            "1 2 3 1 (8\t0.1 0 0\t0.5)\n"
            "PrimitiveAttrib\n"
            "generator 1 index 1 papi\n"
            "Part 2 0 1 [0]\n"
            "beginExtra\n"
            "endExtra\n");
}

// Text output uses the shortest representation that parses back to the same value: no precision is lost.
TEST_F(IoTest, TextNumbersRoundTrip) {
  ParticleFrame f;
  const double xd = 0.1 + 1e-17 * 3;  // needs 17 significant digits
  const float vf = std::nextafter(0.1f, 1.0f);
  f.positions = std::vector<Vec3d>{Vec3d{{xd, 1.0 / 3.0, -2e-300}}};
  f.add("V", 1, std::vector<float>{vf});
  write_csv(dir_ / "p.csv", f);
  std::istringstream in(slurp(dir_ / "p.csv"));
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_EQ(header, "Position_X [m],Position_Y [m],Position_Z [m],V");
  std::vector<std::string> cells;
  std::stringstream rs(row);
  for (std::string c; std::getline(rs, c, ',');) cells.push_back(c);
  ASSERT_EQ(cells.size(), 4u);
  EXPECT_EQ(std::strtod(cells[0].c_str(), nullptr), xd);
  EXPECT_EQ(std::strtod(cells[1].c_str(), nullptr), 1.0 / 3.0);
  EXPECT_EQ(std::strtod(cells[2].c_str(), nullptr), -2e-300);
  EXPECT_EQ(std::strtof(cells[3].c_str(), nullptr), vf);
}

TEST_F(IoTest, CsvHeaderNamesAndUnits) {
  write_csv(dir_ / "small.csv", small_frame());
  EXPECT_EQ(slurp(dir_ / "small.csv"),
            "Position_X [m],Position_Y [m],Position_Z [m],ID,Velocity_X [m/s],Velocity_Y [m/s],Velocity_Z [m/s],J\n"
            "0.5,0.25,0.125,7,1,-2.5,3,1\n"
            "1,2,3,8,0.1,0,0,0.5\n");
}

TEST_F(IoTest, WriteFrameDispatchesOnSuffix) {
  const ParticleFrame f = small_frame();
  write_frame(dir_ / "a.bgeo", f);
  write_frame(dir_ / "a.geo", f);
  write_frame(dir_ / "a.csv", f);
  EXPECT_EQ(slurp(dir_ / "a.bgeo").substr(0, 5), "BgeoV");
  EXPECT_EQ(slurp(dir_ / "a.geo").substr(0, 12), "PGEOMETRY V5");
  EXPECT_EQ(slurp(dir_ / "a.csv").substr(0, 14), "Position_X [m]");
  write_frame(dir_ / "a.h5", f);
  EXPECT_EQ(slurp(dir_ / "a.h5").substr(1, 3), "HDF");
  EXPECT_TRUE(fs::exists(dir_ / "a.xdmf"));
  EXPECT_THROW(write_frame(dir_ / "a.vtk", f), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "a.vtk"));
}

/// Reads dataset `name` of an HDF5 file as doubles, with its dimensions and "unit" attribute (HDF5 C API).
struct H5Data {
  std::vector<double> values;
  std::vector<hsize_t> dims;
  std::string unit;
};
H5Data read_h5(const fs::path& path, const char* name) {
  H5Data d;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(file, 0);
  const hid_t set = H5Dopen2(file, name, H5P_DEFAULT);
  EXPECT_GE(set, 0) << name;
  const hid_t space = H5Dget_space(set);
  d.dims.resize(H5Sget_simple_extent_ndims(space));
  H5Sget_simple_extent_dims(space, d.dims.data(), nullptr);
  hsize_t n = 1;
  for (hsize_t x : d.dims) n *= x;
  d.values.resize(n);
  if (n) H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, d.values.data());
  if (H5Aexists(set, "unit") > 0) {
    const hid_t attr = H5Aopen(set, "unit", H5P_DEFAULT);
    const hid_t type = H5Aget_type(attr);
    std::string s(H5Tget_size(type), '\0');
    H5Aread(attr, type, s.data());
    d.unit = s;
    H5Tclose(type);
    H5Aclose(attr);
  }
  H5Sclose(space);
  H5Dclose(set);
  H5Fclose(file);
  return d;
}

// .h5: one dataset per quantity with its unit, positions in the frame's precision; the .xdmf names them all.
TEST_F(IoTest, H5DatasetsUnitsAndXdmf) {
  ParticleFrame f = small_frame();
  f.positions = std::vector<Vec3d>{Vec3d{{0.1, 0.2, 0.3}}, Vec3d{{1.0, 2.0, 3.0}}};  // double positions
  write_frame(dir_ / "f.h5", f);
  EXPECT_FALSE(fs::exists(dir_ / "f.h5.part"));
  const H5Data x = read_h5(dir_ / "f.h5", "Position");
  EXPECT_EQ(x.dims, (std::vector<hsize_t>{2, 3}));
  EXPECT_EQ(x.values, (std::vector<double>{0.1, 0.2, 0.3, 1.0, 2.0, 3.0}));  // exact: stored as float64
  EXPECT_EQ(x.unit, "m");
  const H5Data id = read_h5(dir_ / "f.h5", "ID");
  EXPECT_EQ(id.dims, (std::vector<hsize_t>{2}));
  EXPECT_EQ(id.values, (std::vector<double>{7, 8}));
  const H5Data v = read_h5(dir_ / "f.h5", "Velocity");
  EXPECT_EQ(v.dims, (std::vector<hsize_t>{2, 3}));
  EXPECT_EQ(v.values[1], -2.5);
  EXPECT_EQ(v.values[3], static_cast<double>(0.1f));
  EXPECT_EQ(v.unit, "m/s");
  EXPECT_EQ(read_h5(dir_ / "f.h5", "J").unit, "");
  const std::string xdmf = slurp(dir_ / "f.xdmf");
  EXPECT_NE(xdmf.find("TopologyType=\"Polyvertex\" NumberOfElements=\"2\""), std::string::npos) << xdmf;
  EXPECT_NE(xdmf.find("Precision=\"8\" Format=\"HDF\">f.h5:/Position"), std::string::npos) << xdmf;
  EXPECT_NE(xdmf.find("<Attribute Name=\"Velocity\" AttributeType=\"Vector\""), std::string::npos) << xdmf;
  EXPECT_NE(xdmf.find("Dimensions=\"2\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">f.h5:/ID"), std::string::npos);
  // An empty frame is a valid file too.
  ParticleFrame empty;
  empty.positions = std::vector<Vec3f>{};
  write_frame(dir_ / "e.h5", empty);
  EXPECT_EQ(read_h5(dir_ / "e.h5", "Position").dims, (std::vector<hsize_t>{0, 3}));
}

TEST_F(IoTest, InvalidFramesAreRefused) {
  auto refused = [&](ParticleFrame f) {
    EXPECT_THROW(write_bgeo(dir_ / "bad.bgeo", f), std::invalid_argument);
    EXPECT_FALSE(fs::exists(dir_ / "bad.bgeo"));
    EXPECT_FALSE(fs::exists(dir_ / "bad.bgeo.part"));
  };
  ParticleFrame f = small_frame();
  f.attributes[0].name = "Velocity X";  // space: Houdini cannot name it
  refused(f);
  f = small_frame();
  f.attributes[0].name = "P";
  refused(f);
  f = small_frame();
  f.attributes[2].name = "ID";  // duplicate
  refused(f);
  f = small_frame();
  std::get<0>(f.attributes[1].values).pop_back();  // 5 values for 2 particles of width 3
  refused(f);
}

TEST_F(IoTest, IoFailuresThrowWithThePath) {
  const fs::path path = dir_ / "no_such_dir" / "x.bgeo";
  try {
    write_bgeo(path, small_frame());
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_dir/x.bgeo.part"), std::string::npos) << e.what();
  }
}

// Every frame is written, in submission order: a job queued right after frame k runs after frame k is on disk
// and before frame k+1 is.
TEST_F(IoTest, AsyncWriterWritesAllFramesInOrder) {
  const int frames = 20;
  std::vector<int> order;  // touched only by the writer thread until flush() returns
  bool in_order = true;
  {
    AsyncWriter writer(3);
    for (int k = 0; k < frames; ++k) {
      ParticleFrame f;
      f.positions = std::vector<Vec3f>(100, Vec3f{{float(k), 0.0f, 0.0f}});
      f.add("ID", 1, std::vector<std::int32_t>(100, k));
      writer.submit(frame_file_path(dir_, 0, 0, k, ".bgeo"), std::move(f));
      writer.submit_job([&, k] {
        order.push_back(k);
        in_order = in_order && fs::exists(frame_file_path(dir_, 0, 0, k, ".bgeo")) &&
                   !fs::exists(frame_file_path(dir_, 0, 0, k + 1, ".bgeo"));
      });
    }
    writer.flush();
    EXPECT_EQ(writer.completed(), std::size_t(2 * frames));
    writer.close();
  }
  ASSERT_EQ(order.size(), std::size_t(frames));
  for (int k = 0; k < frames; ++k) EXPECT_EQ(order[k], k);
  EXPECT_TRUE(in_order);
  for (int k = 0; k < frames; ++k) {
    const ParticleFrame r = read_bgeo(frame_file_path(dir_, 0, 0, k, ".bgeo"));
    ASSERT_EQ(r.size(), 100u);
    EXPECT_EQ(r.find("ID")->ints()[99], k);
  }
}

// The destructor drains the queue: every frame submitted before it runs is written whole (not truncated, not another
// frame's data). Each frame carries its own index in every value, so a file written from the wrong frame, a partly
// written file or a missing one fails; 20000 particles a frame keep the queue non-empty when the destructor starts.
TEST_F(IoTest, AsyncWriterDestructorDrainsTheQueue) {
  constexpr int kFrames = 5;
  constexpr std::size_t kParticles = 20000;
  {
    AsyncWriter writer(8);
    for (int k = 0; k < kFrames; ++k) {
      ParticleFrame f;
      std::vector<Vec3f> x(kParticles);
      std::vector<std::int32_t> ids(kParticles);
      for (std::size_t i = 0; i < kParticles; ++i) {
        x[i] = Vec3f{{float(k), float(i), 0.5f}};
        ids[i] = static_cast<std::int32_t>(i) + 1000000 * k;
      }
      f.positions = std::move(x);
      f.add("ID", 1, std::move(ids));
      writer.submit(frame_file_path(dir_, 1, 0, k, ".bgeo"), std::move(f));
    }
  }
  for (int k = 0; k < kFrames; ++k) {
    const fs::path path = frame_file_path(dir_, 1, 0, k, ".bgeo");
    ASSERT_TRUE(fs::exists(path)) << k;
    const ParticleFrame r = read_bgeo(path);
    ASSERT_EQ(r.size(), kParticles) << k;
    ASSERT_NE(r.find("ID"), nullptr) << k;
    const auto& ids = r.find("ID")->ints();
    const auto& rx = std::get<0>(r.positions);
    std::size_t wrong = 0;
    for (std::size_t i = 0; i < kParticles; ++i)
      wrong += rx[i][0] != float(k) || rx[i][1] != float(i) || rx[i][2] != 0.5f ||
               ids[i] != static_cast<std::int32_t>(i) + 1000000 * k;
    EXPECT_EQ(wrong, 0u) << "frame " << k << ": values that are not the submitted frame's";
  }
}

TEST_F(IoTest, AsyncWriterReportsErrors) {
  AsyncWriter writer(4);
  const fs::path bad = dir_ / "missing" / "model[0]_dev[0]_frame[0].bgeo";
  writer.submit(bad, small_frame());
  std::atomic<bool> later_job_ran{false};
  try {
    writer.submit_job([&] { later_job_ran = true; });
  } catch (const std::runtime_error&) {
    // the failure may already be known: then the job is refused, which is fine too
  }
  try {
    writer.flush();
    FAIL() << "flush() did not report the failed write";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing/model[0]_dev[0]_frame[0].bgeo"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(later_job_ran);  // jobs after a failure are skipped
  // The writer stays failed: later calls keep saying so, with the original message.
  try {
    writer.submit(dir_ / "ok.bgeo", small_frame());
    FAIL() << "submit() after a failure was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("earlier output job failed"), std::string::npos) << e.what();
  }
  EXPECT_THROW(writer.close(), std::runtime_error);
  EXPECT_FALSE(fs::exists(dir_ / "ok.bgeo"));
}

// With max_pending = 1, a second waiting job makes submit() block until the worker takes one.
TEST_F(IoTest, AsyncWriterBoundsTheQueue) {
  AsyncWriter writer(1);
  std::promise<void> release;
  std::shared_future<void> gate = release.get_future().share();
  std::promise<void> started;
  writer.submit_job([gate, &started] {
    started.set_value();
    gate.wait();
  });
  started.get_future().wait();     // the worker holds job 1
  writer.submit_job([] {});        // job 2 waits in the queue (1 slot)
  std::atomic<bool> third_accepted{false};
  std::thread producer([&] {
    writer.submit_job([] {});      // must block: the queue is full
    third_accepted = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_FALSE(third_accepted);    // cannot pass early; on a slow machine it still holds
  release.set_value();
  producer.join();
  EXPECT_TRUE(third_accepted);
  writer.close();
  EXPECT_EQ(writer.completed(), 3u);
}

// Surface-only frames (ExteriorFilter): a 5 x 5 x 5 cube of 1 m blocks with 8 points each; threshold 7 keeps the 98
// blocks of its shell (each has an empty neighbour) and drops the 27 inner ones (every neighbour holds 8); attributes
// follow their points; threshold 8 keeps every point; a lone far point is always kept.
TEST_F(IoTest, ExteriorFilterKeepsTheSurfaceBlocks) {
  ParticleFrame f;
  std::vector<Vec3f> x;
  std::vector<std::int32_t> id;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      for (int k = 0; k < 10; ++k) {
        x.push_back(Vec3f{{0.25f + 0.5f * i, 0.25f + 0.5f * j, 0.25f + 0.5f * k}});
        id.push_back(static_cast<std::int32_t>(x.size() - 1));
      }
  x.push_back(Vec3f{{20.5f, 20.5f, 20.5f}});
  id.push_back(1000);
  f.positions = x;
  f.add("ID", 1, id);
  f.exterior = ExteriorFilter{1.0, 7.0};
  const ParticleFrame kept = exterior_points(f);
  EXPECT_FALSE(kept.exterior.on());
  ASSERT_EQ(kept.size(), 98u * 8u + 1u);
  const auto& ids = std::get<std::vector<std::int32_t>>(kept.attributes[0].values);
  for (std::size_t r = 0; r < kept.size(); ++r) {
    const Vec3d p = kept.position(r);
    EXPECT_EQ(p, x[static_cast<std::size_t>(ids[r])].cast<double>());  // the attribute follows its point
    bool shell = false;
    for (int a = 0; a < 3; ++a) shell = shell || p[a] < 1.0 || p[a] > 4.0;
    EXPECT_TRUE(shell) << p[0] << " " << p[1] << " " << p[2];
  }
  f.exterior.threshold = 8.0;
  EXPECT_EQ(exterior_points(f).size(), f.size());
  // write_frame applies it.
  f.exterior.threshold = 7.0;
  write_frame(dir_ / "surface.bgeo", f);
  EXPECT_EQ(read_bgeo(dir_ / "surface.bgeo").size(), 98u * 8u + 1u);
}


// A frame streamed in pieces (FrameStream) writes the bytes of the same frame read in one piece, in every format,
// with and without the exterior filter; each column of the source is read in increasing order within a pass and
// never more than a piece at a time, so a writer's host memory follows the piece, not the frame.
TEST_F(IoTest, StreamedFrameWritesTheBytesOfOnePiece) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const bool dbl : {false, true}) {
    const std::size_t n = 3001;
    ParticleFrame f;
    std::vector<Vec3d> xd(n);
    for (auto& x : xd)  // a slab thicker in x, so the filter keeps some blocks and drops others
      for (int a = 0; a < 3; ++a) x[a] = 0.3 * u(rng) * (a == 0 ? 2 : 1);
    if (dbl) {
      f.positions = xd;
    } else {
      std::vector<Vec3f> xf(n);
      for (std::size_t p = 0; p < n; ++p) xf[p] = xd[p].cast<float>();
      f.positions = xf;
    }
    std::vector<std::int32_t> id(n);
    std::vector<float> s1(n), v3(3 * n), w2(2 * n);
    for (std::size_t p = 0; p < n; ++p) {
      id[p] = static_cast<std::int32_t>(5 * p + 2);
      s1[p] = static_cast<float>(u(rng) - 0.5);
      for (int c = 0; c < 3; ++c) v3[3 * p + c] = static_cast<float>(u(rng));
      for (int c = 0; c < 2; ++c) w2[2 * p + c] = static_cast<float>(-u(rng));
    }
    f.add("ID", 1, id);
    f.add("Pressure", 1, s1, "Pa");
    f.add("Velocity", 3, v3, "m/s");
    f.add("Pair", 2, w2);
    for (const double threshold : {0.0, 6.0, 1e9}) {
      f.exterior = threshold > 0 ? ExteriorFilter{0.06, threshold} : ExteriorFilter{};
      for (const char* suffix : {".bgeo", ".geo", ".csv", ".h5"}) {
        const std::string tag = std::string(dbl ? "d" : "f") + std::to_string(static_cast<int>(threshold)) + suffix;
        write_frame(dir_ / ("whole" + tag), stream_of(f, n));
        FrameStream s = stream_of(f, 97);
        const auto positions = s.read_positions;
        const auto values = s.read_values;
        std::vector<std::size_t> next(f.attributes.size() + 1, 0);  // per column: positions, then attributes
        std::size_t largest = 0;
        bool ordered = true;
        auto seen = [&](std::size_t column, std::size_t first, std::size_t count) {
          if (first == 0) next[column] = 0;  // a new pass
          ordered = ordered && first >= next[column];
          next[column] = first + count;
          largest = std::max(largest, count);
        };
        s.read_positions = [&](std::size_t first, std::size_t count, void* out) {
          seen(0, first, count);
          positions(first, count, out);
        };
        s.read_values = [&](std::size_t a, std::size_t first, std::size_t count, void* out) {
          seen(a + 1, first, count);
          values(a, first, count, out);
        };
        write_frame(dir_ / ("pieces" + tag), s);
        EXPECT_TRUE(ordered) << tag;
        EXPECT_LE(largest, 97u) << tag;
        const std::string whole = slurp(dir_ / ("whole" + tag)), pieces = slurp(dir_ / ("pieces" + tag));
        EXPECT_GT(whole.size(), 100u) << tag;
        EXPECT_TRUE(whole == pieces) << tag << ": " << whole.size() << " vs " << pieces.size() << " bytes";
      }
      if (threshold == 6.0) {  // the filter drops some points and keeps others
        const std::size_t kept = exterior_points(f).size();
        EXPECT_GT(kept, 0u);
        EXPECT_LT(kept, n);
        EXPECT_EQ(read_bgeo(dir_ / (std::string("pieces") + (dbl ? "d" : "f") + "6.bgeo")).size(), kept);
      }
    }
  }
}

}  // namespace
}  // namespace fbar::io
