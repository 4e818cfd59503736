// The GPU engine at scale, on small scenes: the memory plan is the allocation, a scene that does not fit is refused
// before anything is allocated, batched sampling uploads the same particles as a whole-body sample, and the frame
// a capture step writes on the device equals the frame built on the host from a snapshot of the same state.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"
#include "../cpu/decomposition_scenes.h"
#include "engine/grid_channels.h"
#include "engine/memory_plan.h"
#include "io/particle_frame.h"

namespace fbar {
namespace {

Scene frame_scene(Constitutive law, Precision precision) {
  Scene s = test::small_scene(law, precision);
  s.bodies[0].output_attribs = {"ID", "Position_Y", "Velocity_X", "Velocity_Magnitude", "J", "Pressure",
                                "VonMisesStress", "StressCauchy_XY", "Mass", "Volume", "StressCauchy_1",
                                "StressCauchy_Invariant2"};
  // Derived from F (device principal values: SVD and symmetric eigen-solves in the capture kernel).
  if (law != Constitutive::JFluid)
    for (const char* a : {"DefGrad_YY", "DefGrad_1", "DefGrad_Invariant3", "StressPK1_XY", "StressPK1_3", "StressPK2_YY",
                          "StressPK2_Invariant1", "StrainSmall_XX", "StrainSmall_2", "VonMisesStrain"})
      s.bodies[0].output_attribs.push_back(a);
  return s;
}

// device_bytes() after construction is the plan's total (the plan is computed from the same counts the engine
// uses; only the CUB scan scratch is estimated): within 0.5 %, with and without frames, single and double.
TEST(GpuMemory, PlanIsTheAllocation) {
  FBAR_REQUIRE_DEVICE();
  for (bool frames : {false, true}) {
    GpuEngineOptions o;
    o.frames = frames;
    GpuEngine<float> single(frame_scene(Constitutive::JFluid, Precision::Single), o);
    const double ps = static_cast<double>(single.memory_plan().total());
    EXPECT_NEAR(static_cast<double>(single.device_bytes()), ps, 0.005 * ps) << "frames " << frames;
    GpuEngine<double> dbl(frame_scene(Constitutive::FixedCorotated, Precision::Double), o);
    const double pd = static_cast<double>(dbl.memory_plan().total());
    EXPECT_NEAR(static_cast<double>(dbl.device_bytes()), pd, 0.005 * pd) << "frames " << frames;
    // Frames cost exactly N (3 sizeof(T) + 4 columns) bytes: every attribute but ID is a float column.
    const std::size_t columns = frame_scene(Constitutive::JFluid, Precision::Single).bodies[0].output_attribs.size() - 1;
    if (frames)
      EXPECT_EQ(single.memory_plan().frames, single.particle_count() * (3 * sizeof(float) + 4 * columns));
  }
  // The peak stays the start while nothing grows.
  GpuEngine<float> e(frame_scene(Constitutive::JFluid, Precision::Single));
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(e.step().ok);
  EXPECT_EQ(e.peak_device_bytes(), e.device_bytes());
}

// The grid's channel sets are what their declarations say (engine/grid_channels.h): the engine's channel buffers
// hold exactly capacity x grid_channel_block_bytes() for the sets the scene needs, at every precision, with ASFLIP,
// F-bar and a saturated body, and the capacity is the plan's. A set allocated without being declared, or declared
// without being allocated, fails this.
template <typename T, typename TG>
void expect_declared_grid(Precision precision) {
  for (int feature = 0; feature < 4; ++feature) {
    Scene s = test::small_scene(feature == 3 ? Constitutive::CoupledUP : Constitutive::FixedCorotated, precision);
    BodySpec& b = s.bodies[0];
    GridFeatures f;
    if (feature == 1) {
      b.algorithm.use_asflip = true;
      b.algorithm.asflip_alpha = 1.0;
      f.asflip = true;
    }
    if (feature == 2) {
      b.algorithm.use_fbar = true;
      b.algorithm.fbar_psi = 0.5;
      f.fbar = true;
    }
    if (feature == 3) {
      test::saturate(b);
      f.pore = true;
    }
    GpuEngine<T, TG> e(s);
    EXPECT_EQ(e.grid_block_capacity(), e.memory_plan().block_capacity) << "feature " << feature;
    EXPECT_EQ(e.grid_channel_bytes(),
              static_cast<std::size_t>(e.grid_block_capacity()) * grid_channel_block_bytes(precision, f))
        << "feature " << feature;
    for (int i = 0; i < 3; ++i) ASSERT_TRUE(e.step().ok) << "feature " << feature;
  }
}
TEST(GpuMemory, GridChannelsAreTheirDeclarations) {
  FBAR_REQUIRE_DEVICE();
  expect_declared_grid<float, float>(Precision::Single);
  expect_declared_grid<double, double>(Precision::Double);
  expect_declared_grid<double, float>(Precision::Mixed);
}

// A device that is too small: refused in the constructor, naming what would fit, before any allocation.
TEST(GpuMemory, RefusesWhatDoesNotFit) {
  FBAR_REQUIRE_DEVICE();
  GpuEngineOptions o;
  o.memory_limit = 1 << 20;  // 1 MiB "free"
  try {
    GpuEngine<float> e(frame_scene(Constitutive::JFluid, Precision::Single), o);
    FAIL() << "expected a refusal";
  } catch (const cuda::OutOfMemory& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("does not fit"), std::string::npos) << m;
    EXPECT_NE(m.find("default_dx"), std::string::npos) << m;
    EXPECT_NE(m.find("ppc"), std::string::npos) << m;
    EXPECT_NE(m.find("GPUs"), std::string::npos) << m;
  }
}

// Batches of 100 particles (a remainder carried across batches) give the very particles of one whole sample.
TEST(GpuMemory, BatchedSamplingEqualsWholeSample) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = frame_scene(Constitutive::FixedCorotated, Precision::Double);
  GpuEngineOptions small;
  small.sample_batch = 100;
  GpuEngine<double> batched(scene, small);
  GpuEngine<double> whole(scene, test::sample_scene(scene));
  const ParticleSnapshot<double> a = batched.snapshot(0), b = whole.snapshot(0);
  ASSERT_EQ(a.x.size(), b.x.size());
  for (std::size_t p = 0; p < a.x.size(); ++p)
    for (int d = 0; d < 3; ++d) ASSERT_EQ(a.x[p][d], b.x[p][d]) << "particle " << p;
  for (int s = 0; s < 5; ++s) {
    ASSERT_TRUE(batched.step(1e-3).ok);
    ASSERT_TRUE(whole.step(1e-3).ok);
  }
  // Then the runs agree to the summation order of the grid's global atomics (not bitwise between two GPU runs).
  const ParticleSnapshot<double> c = batched.snapshot(0), d = whole.snapshot(0);
  for (std::size_t p = 0; p < c.x.size(); ++p)
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(c.x[p][k], d.x[p][k], 1e-12) << "particle " << p;
}

template <typename T>
void expect_frame_matches_snapshot(Constitutive law, Precision precision) {
  const Scene scene = frame_scene(law, precision);
  GpuEngineOptions o;
  o.frames = true;
  GpuEngine<T> gpu(scene, o);
  const auto dir = std::filesystem::temp_directory_path() / ("fbar_frames_" + std::to_string(static_cast<int>(law)));
  std::filesystem::create_directories(dir);
  io::AsyncWriter writer(1);
  gpu.set_record_velocities(true);  // the snapshot's v and C of the same step (the reference)
  gpu.submit_frame(0, dir / "f0.bgeo", writer);
  for (int s = 0; s < 6; ++s) {
    gpu.set_frame_capture(s == 5);
    ASSERT_TRUE(gpu.step(1e-3).ok);
  }
  gpu.submit_frame(0, dir / "f1.bgeo", writer);
  writer.close();
  const io::ParticleFrame reference = gpu.frame(0);  // host build_frame from the snapshot (aux v, C)
  const io::ParticleFrame written = io::read_bgeo(dir / "f1.bgeo");
  ASSERT_EQ(written.size(), reference.size());
  for (std::size_t p = 0; p < written.size(); ++p)
    for (int d = 0; d < 3; ++d)
      ASSERT_NEAR(written.position(p)[d], reference.position(p)[d], 1e-6) << "particle " << p;
  // Stress attributes: float rounding of the pressure (|sigma| ~ p) carries into the small deviatoric parts, so their
  // tolerance scales with the largest |pressure|.
  double pressure_scale = 0.0;
  if (const io::FrameAttribute* pr = reference.find("Pressure"))
    for (float v : std::get<std::vector<float>>(pr->values)) pressure_scale = test::worst(pressure_scale, std::fabs(double(v)));
  for (const io::FrameAttribute& a : reference.attributes) {
    const io::FrameAttribute* w = written.find(a.name);
    ASSERT_NE(w, nullptr) << a.name;
    if (a.name == "ID") {
      EXPECT_EQ(std::get<std::vector<std::int32_t>>(w->values), std::get<std::vector<std::int32_t>>(a.values));
      continue;
    }
    const auto& rv = std::get<std::vector<float>>(a.values);
    const auto& wv = std::get<std::vector<float>>(w->values);
    ASSERT_EQ(rv.size(), wv.size());
    double scale = 0.0, err = 0.0;
    for (std::size_t p = 0; p < rv.size(); ++p) {
      scale = test::worst(scale, std::fabs(static_cast<double>(rv[p])));
      err = test::worst(err, std::fabs(static_cast<double>(rv[p]) - static_cast<double>(wv[p])));
    }
    if (a.name == "VonMisesStress" || a.name.rfind("StressCauchy_", 0) == 0 || a.name.rfind("StressPK", 0) == 0)
      scale = std::max(scale, pressure_scale);
    if (a.name == "StressCauchy_Invariant2") scale = std::max(scale, pressure_scale * pressure_scale);
    // Strains of F ~ I: |eps| ~ 1e-3 here, F's float rounding is 6e-8 absolute: scale by |F| ~ 1.
    if (a.name.rfind("StrainSmall_", 0) == 0 || a.name == "VonMisesStrain") scale = std::max(scale, 1.0);
    // The same formula on the same state: equal up to rounding in T (float: 6e-8; FMA contraction differs between
    // the device and the host) and the float output: 1e-5 of the scale.
    EXPECT_LE(err, 1e-5 * std::max(scale, 1e-30) + 1e-30) << a.name << " scale " << scale;
  }
  // Frame 0 (before the first step) holds the sampled positions.
  const io::ParticleFrame first = io::read_bgeo(dir / "f0.bgeo");
  const auto positions = test::sample_scene(scene);
  ASSERT_EQ(first.size(), positions[0].size());
  for (std::size_t p = 0; p < first.size(); ++p)
    for (int d = 0; d < 3; ++d) ASSERT_NEAR(first.position(p)[d], positions[0][p][d], 1e-6);
}

TEST(GpuFrames, CaptureEqualsSnapshotJFluidFloat) {
  FBAR_REQUIRE_DEVICE();
  expect_frame_matches_snapshot<float>(Constitutive::JFluid, Precision::Single);
}
TEST(GpuFrames, CaptureEqualsSnapshotFixedCorotatedDouble) {
  FBAR_REQUIRE_DEVICE();
  expect_frame_matches_snapshot<double>(Constitutive::FixedCorotated, Precision::Double);
}

// A frame must come from a capture step: submitting after a step that captured nothing is a programming error.
TEST(GpuFrames, RefusesAFrameThatWasNotCaptured) {
  FBAR_REQUIRE_DEVICE();
  GpuEngineOptions o;
  o.frames = true;
  GpuEngine<float> gpu(frame_scene(Constitutive::JFluid, Precision::Single), o);
  ASSERT_TRUE(gpu.step(1e-3).ok);
  io::AsyncWriter writer(1);
  EXPECT_THROW(gpu.submit_frame(0, std::filesystem::temp_directory_path() / "fbar_never.bgeo", writer),
               std::logic_error);
}

// A frame larger than GpuEngineOptions::frame_host_bytes is streamed from the device through a buffer of that size
// (here 4 KiB: hundreds of pieces) instead of coming down whole: the files hold the same bytes (two runs of a scene
// write the same bytes), in every format, with and without the exterior filter (threshold 0 drops the blocks
// surrounded by particles), in single and double precision; frame 1 is still being written from the device while
// the steps to frame 2 run, so frame 2's capture waits for it.
template <typename T>
void expect_streamed_frames_equal_whole(Precision precision) {
  for (const bool exterior : {false, true})
    for (const char* suffix : {".bgeo", ".geo", ".csv", ".h5"}) {
      Scene scene = frame_scene(Constitutive::FixedCorotated, precision);
      scene.simulation.dx = 0.02;
      scene.simulation.particles_output_exterior_only = exterior;
      scene.bodies[0].exterior_threshold = 0;
      std::vector<std::string> files[2];
      long long particles = 0;
      for (int streamed = 0; streamed < 2; ++streamed) {
        GpuEngineOptions o;
        o.frames = true;
        if (streamed) o.frame_host_bytes = 4096;
        GpuEngine<T> gpu(scene, o);
        particles = gpu.particle_count();
        const auto dir = std::filesystem::temp_directory_path() /
                         ("fbar_streamed_" + std::to_string(sizeof(T)) + "_" + std::to_string(streamed));
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
        {
          io::AsyncWriter writer(1);
          gpu.submit_frame(0, dir / (std::string("f0") + suffix), writer);
          for (int s = 0; s < 6; ++s) {
            gpu.set_frame_capture(s == 2 || s == 5);
            ASSERT_TRUE(gpu.step(1e-3).ok);
            if (s == 2) gpu.submit_frame(0, dir / (std::string("f1") + suffix), writer);
          }
          gpu.submit_frame(0, dir / (std::string("f2") + suffix), writer);
          writer.close();
        }
        for (const char* f : {"f0", "f1", "f2"}) {
          files[streamed].push_back(io::detail::read_whole_file(dir / (std::string(f) + suffix)));
          if (std::string(suffix) == ".h5") files[streamed].push_back(io::detail::read_whole_file(dir / (std::string(f) + ".xdmf")));
        }
        if (std::string(suffix) == ".bgeo") {
          const std::size_t written = io::read_bgeo(dir / "f2.bgeo").size();
          if (exterior) {
            EXPECT_LT(written, static_cast<std::size_t>(particles)) << "the filter drops the inner blocks";
            EXPECT_GT(written, 0u);
          } else {
            EXPECT_EQ(written, static_cast<std::size_t>(particles));
          }
        }
      }
      ASSERT_EQ(files[0].size(), files[1].size());
      for (std::size_t k = 0; k < files[0].size(); ++k) {
        EXPECT_GT(files[0][k].size(), 100u) << suffix << " file " << k;
        EXPECT_TRUE(files[0][k] == files[1][k]) << suffix << " exterior " << exterior << " file " << k << ": "
                                                << files[0][k].size() << " vs " << files[1][k].size() << " bytes";
      }
    }
}

TEST(GpuFrames, StreamedFramesWriteTheBytesOfWholeFramesSingle) {
  FBAR_REQUIRE_DEVICE();
  expect_streamed_frames_equal_whole<float>(Precision::Single);
}
TEST(GpuFrames, StreamedFramesWriteTheBytesOfWholeFramesDouble) {
  FBAR_REQUIRE_DEVICE();
  expect_streamed_frames_equal_whole<double>(Precision::Double);
}

}  // namespace
}  // namespace fbar
