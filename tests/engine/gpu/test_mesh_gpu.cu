// FEM bodies on the GPU engine (kernels/fem_kernels.cuh) against the CPU reference engine (engine/cpu/cpu_mesh.cpp):
// the same vertices by ID after the same steps (plain and F-bar tetrahedra, APIC and ASFLIP, a try's dt changed
// after the grid held the impulse of another), the lumped mass, the element failure report, frames of the element
// states, and a checkpoint that continues bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "../../physics/physics_test_support.h"
#include "engine/cpu/cpu_engine.h"
#include "engine/gpu/gpu_engine.h"
#include "geometry/tet_mesh.h"
#include "gpu_test_support.h"
#include "io/checkpoint.h"
#include "io/frame_series.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

using test::r3;

/// An elastic mesh (FixedCorotated cubes of 6 tetrahedra) falling onto a particle block on a Sticky floor: the
/// vertices meet the particles on the grid within the first steps. fbar_elements: ClaymoreUW's Tetrahedron_FBar;
/// asflip: the mesh's vertices move by ASFLIP (alpha 0.5).
Scene mesh_on_block(bool fbar_elements, bool asflip) {
  Scene scene = test::empty_scene(r3(0.4, 0.4, 0.24), 0.02, r3(0, -9.81, 0));
  BodySpec block = test::box_body(Constitutive::FixedCorotated, r3(0.04, 0.04, 0.04), r3(0.32, 0.1, 0.16));
  block.material.youngs_modulus = 2e6;
  scene.bodies.push_back(block);
  MeshEntrySpec& m = test::add_elastic_mesh(scene, box_tet_mesh(Vec3d{{0.14, 0.145, 0.06}}, Vec3d{{0.26, 0.205, 0.18}},
                                                                 Vec3i{{6, 3, 6}}),
                                            800.0, 2e5, 0.3);
  m.fbar_elements = fbar_elements;
  m.output_attribs = {"ID", "J", "Velocity_X", "Pressure"};
  m.velocity = r3(0.0, -0.5, 0.0);
  m.use_asflip = asflip;
  m.alpha = asflip ? 0.5 : 0.0;
  append_mesh_bodies(scene);  // the mesh's body from the entry again
  BoundarySpec floor;
  floor.object = BoundaryObject::Walls;
  floor.contact = Contact::Sticky;
  floor.domain_start = r3(0.04, 0.04, 0.04);
  floor.domain_end = r3(0.36, 0.36, 0.2);
  scene.boundaries.push_back(floor);
  return scene;
}

struct Difference {
  double x = 0.0, v = 0.0, F = 0.0;
};

/// Runs both engines `steps` steps of the CPU engine's CFL dt (every third step at 0.6 of it, which makes the GPU
/// rescale the impulse its grid already holds) and compares every body by ID.
template <typename T>
Difference run_both(const Scene& scene, int steps) {
  const auto positions = test::sample_scene(scene);
  CpuEngine<T> cpu(scene, positions);
  GpuEngine<T> gpu(scene, positions);
  gpu.set_record_velocities(true);
  cpu.set_log(nullptr);
  gpu.set_log(nullptr);
  for (int s = 0; s < steps; ++s) {
    const double dt = cpu.next_dt() * (s % 3 == 2 ? 0.6 : 1.0);
    const StepReport rc = cpu.step(dt);
    const StepReport rg = gpu.step(dt);
    EXPECT_TRUE(rc.ok) << rc.message();
    EXPECT_TRUE(rg.ok) << rg.message();
    if (!rc.ok || !rg.ok) return {1e9, 1e9, 1e9};
  }
  Difference d;
  for (int b = 0; b < gpu.body_count(); ++b) {
    const ParticleSnapshot<T> g = gpu.snapshot(b);
    EXPECT_EQ(g.x.size(), cpu.positions(b).size());
    d.x = test::worst(d.x, test::max_diff(g.x, cpu.positions(b)));
    d.v = test::worst(d.v, test::max_diff(g.v, cpu.velocities(b)));
    const std::vector<Mat3<T>> F = cpu.deformation_gradients(b);
    for (std::size_t p = 0; p < F.size() && p < g.F.size(); ++p)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          d.F = test::worst(d.F, std::fabs(static_cast<double>(g.F[p](i, j)) - static_cast<double>(F[p](i, j))));
  }
  return d;
}

// A scene of one FEM mesh and no particle body (tests/scenes/good/mesh_only_post.json: the post clamped at its foot,
// swaying under its own weight): the GPU engine runs it as the CPU engine does, to the double tolerances below.
TEST(GpuMesh, MeshOnlySceneMatchesTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene =
      parse_scene_file(std::string(FBAR_SOURCE_DIR) + "/tests/scenes/good/mesh_only_post.json", ParseOptions{});
  ASSERT_EQ(scene.bodies.size(), 1u);
  ASSERT_EQ(scene.bodies[0].mesh, 0);
  const Difference d = run_both<double>(scene, 60);
  std::printf("[ GPU mesh ] a mesh alone: 60 steps, |dx| %.3g m, |dv| %.3g m/s, |dF| %.3g\n", d.x, d.v, d.F);
  EXPECT_LT(d.x, 1e-12);
  EXPECT_LT(d.v, 1e-12);
  EXPECT_LT(d.F, 1e-12);
}

// Double precision: the engines differ only by the order of the grid sums (the GPU's fixed-point arena and its
// atomic flush, its atomic element impulses): positions, velocities and vertex states to 1e-12. The vertex states
// (the elements' gradients) and the velocities show that the element pass, its impulse and its rescaling are the
// CPU engine's.
TEST(GpuMesh, MatchesTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  struct Case {
    const char* name;
    bool fbar, asflip;
  };
  for (const Case c : {Case{"plain tetrahedra, APIC", false, false}, Case{"F-bar tetrahedra, APIC", true, false},
                       Case{"plain tetrahedra, ASFLIP", false, true}}) {
    SCOPED_TRACE(c.name);
    const Difference d = run_both<double>(mesh_on_block(c.fbar, c.asflip), 60);
    std::printf("[ GPU mesh ] %s: 60 steps, |dx| %.3g m, |dv| %.3g m/s, |dF| %.3g\n", c.name, d.x, d.v, d.F);
    EXPECT_LT(d.x, 1e-12);
    EXPECT_LT(d.v, 1e-12);
    EXPECT_LT(d.F, 1e-12);
  }
}

// Single precision: the two engines agree within the fixed single-precision budget of the scene tests
// (test_scenes_gpu.cu: 1e-4 m/s; a soft mesh of E 2e5 Pa amplifies float's rounding little).
TEST(GpuMesh, MatchesTheCpuEngineInSinglePrecision) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = mesh_on_block(true, false);
  scene.simulation.precision = Precision::Single;
  const Difference d = run_both<float>(scene, 60);
  std::printf("[ GPU mesh ] single: 60 steps, |dx| %.3g m, |dv| %.3g m/s, |dF| %.3g\n", d.x, d.v, d.F);
  EXPECT_LT(d.x, 5e-6);
  EXPECT_LT(d.v, 1e-4);
  EXPECT_LT(d.F, 1e-4);
}

// The vertices carry the elements' lumped volumes: the body's mass is rho V, and the grid holds all of it.
TEST(GpuMesh, LumpedMassIsTheMeshMass) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = test::empty_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0));
  test::add_elastic_mesh(scene, box_tet_mesh(Vec3d{{0.3, 0.3, 0.3}}, Vec3d{{0.5, 0.4, 0.45}}, Vec3i{{4, 3, 5}}), 1000.0,
                         1e6, 0.3);
  GpuEngine<double> engine(scene);
  const double mass = 1000.0 * 0.2 * 0.1 * 0.15;
  EXPECT_NEAR(engine.total_mass(), mass, 1e-13 * mass);
  ASSERT_TRUE(engine.step().ok);
  EXPECT_NEAR(engine.grid_mass(), mass, 1e-12 * mass);
  EXPECT_EQ(engine.particle_count(0), 5u * 4u * 6u);
}

// A mesh thrown without gravity translates rigidly: no strain (the elements' energy at round-off), every vertex moved
// by v t.
TEST(GpuMesh, FreeFlightIsARigidTranslation) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = test::empty_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0));
  MeshEntrySpec& m = test::add_elastic_mesh(
      scene, box_tet_mesh(Vec3d{{0.3, 0.3, 0.3}}, Vec3d{{0.5, 0.4, 0.45}}, Vec3i{{4, 2, 3}}), 1000.0, 1e6, 0.3);
  m.velocity = r3(0.5, -0.2, 0.1);
  append_mesh_bodies(scene);
  GpuEngine<double> engine(scene);
  engine.set_record_velocities(true);
  const std::vector<Vec3d> x0 = engine.snapshot(0).x;
  for (int s = 0; s < 40; ++s) ASSERT_TRUE(engine.step().ok);
  EXPECT_LT(engine.elastic_energy(), 1e-20);
  const std::vector<Vec3d> x = engine.snapshot(0).x;
  const Vec3d v{{0.5, -0.2, 0.1}};
  for (std::size_t i = 0; i < x0.size(); ++i)
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(x[i][a], x0[i][a] + v[a] * engine.time(), 1e-12);
}

// An element turned inside out is a failure naming the body, the count of elements and the first one.
TEST(GpuMesh, InvertedElementIsReportedByElement) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = test::empty_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0));
  test::add_elastic_mesh(scene, box_tet_mesh(Vec3d{{0.4, 0.4, 0.4}}, Vec3d{{0.6, 0.6, 0.6}}, Vec3i{{4, 4, 4}}), 1000.0,
                         1e6, 0.3);
  scene.simulation.on_failure = OnFailure::Stop;
  const double dt = 1e-3;
  GpuEngineOptions options;
  std::vector<Vec3d> v;
  for (const Vec3d& x : scene.meshes[0].mesh->vertices) v.push_back(Vec3d{{0, 0, -3.0 * (x[2] - 0.5) / dt}});
  options.initial_velocities = {v};
  GpuEngine<double> engine(scene, options);
  engine.set_log(nullptr);
  const StepReport r = engine.step(dt);
  ASSERT_FALSE(r.ok);
  const std::string message = r.message();
  EXPECT_NE(message.find(" elements volume ratio J <= 0"), std::string::npos) << message;
  EXPECT_NE(message.find("(first: element "), std::string::npos) << message;
}

// A mesh body's frame as the device captures it holds the states its elements gave the vertices at the step's new
// positions (the element pass writes the entry, not the G2P2G): the written .bgeo equals the host-built frame of the
// same state (positions, J, velocity, pressure), and the .vtk of the tetrahedra lies beside it.
TEST(GpuMesh, FramesHoldTheElementStates) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = mesh_on_block(false, false);
  GpuEngineOptions options;
  options.frames = true;
  GpuEngine<double> engine(scene, options);
  engine.set_log(nullptr);
  engine.set_record_velocities(true);  // frame(): the host-built reference reads the recorded v and C
  for (int s = 0; s < 31; ++s) {
    engine.set_frame_capture(s == 30);
    ASSERT_TRUE(engine.step().ok);
  }
  const auto file = std::filesystem::temp_directory_path() / "fbar_gpu_mesh_frame.bgeo";
  io::AsyncWriter writer(1);
  engine.submit_frame(1, file, writer);
  writer.close();
  const io::ParticleFrame reference = engine.frame(1), written = io::read_bgeo(file);
  ASSERT_EQ(written.size(), reference.size());
  double dx = 0.0;
  for (std::size_t p = 0; p < written.size(); ++p) dx = std::max(dx, max_abs(written.position(p) - reference.position(p)));
  EXPECT_LT(dx, 1e-6);
  double strain = 0.0;
  for (const char* name : {"J", "Velocity_X", "Pressure"}) {
    const io::FrameAttribute *a = reference.find(name), *w = written.find(name);
    ASSERT_TRUE(a && w) << name;
    const auto &av = std::get<std::vector<float>>(a->values), &wv = std::get<std::vector<float>>(w->values);
    ASSERT_EQ(av.size(), wv.size());
    double scale = 1e-30, err = 0.0;
    for (std::size_t p = 0; p < av.size(); ++p) {
      scale = test::worst(scale, std::fabs(static_cast<double>(av[p])));
      err = test::worst(err, std::fabs(static_cast<double>(av[p]) - static_cast<double>(wv[p])));
      if (std::string(name) == "J") strain = test::worst(strain, std::fabs(static_cast<double>(av[p]) - 1.0));
    }
    EXPECT_LE(err, 1e-5 * scale) << name;
  }
  EXPECT_GT(strain, 1e-6);  // the mesh is strained: the comparison of J means something
  auto vtk = file;
  vtk.replace_extension(".vtk");
  EXPECT_TRUE(std::filesystem::exists(vtk)) << "the tetrahedra beside the frame";
  std::filesystem::remove(file);
  std::filesystem::remove(vtk);
}

// A checkpoint of a mesh scene continues on the GPU as the uninterrupted run: the element forces follow from the
// positions (the restart's first grid is a fresh P2G, its atomic sums in another order: as close as two runs).
TEST(GpuMesh, CheckpointContinuesTheRun) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = mesh_on_block(true, false);
  GpuEngine<double> a(scene);
  a.set_log(nullptr);
  for (int s = 0; s < 21; ++s) {
    a.keep_checkpoint_inputs(s == 20);
    ASSERT_TRUE(a.step().ok);
  }
  ASSERT_TRUE(a.checkpoint_ready());
  const io::Checkpoint c = a.checkpoint();
  a.keep_checkpoint_inputs(false);
  GpuEngineOptions options;
  options.restart = &c;
  GpuEngine<double> b(scene, options);
  b.set_log(nullptr);
  EXPECT_EQ(b.next_dt(), a.next_dt());
  a.set_record_velocities(true);
  b.set_record_velocities(true);
  for (int s = 0; s < 20; ++s) {
    ASSERT_TRUE(a.step().ok);
    ASSERT_TRUE(b.step().ok);
  }
  double dx = 0.0, dv = 0.0;
  for (int body = 0; body < a.body_count(); ++body) {
    dx = test::worst(dx, test::max_diff(a.snapshot(body).x, b.snapshot(body).x));
    dv = test::worst(dv, test::max_diff(a.snapshot(body).v, b.snapshot(body).v));
  }
  std::printf("[ GPU mesh ] restart: 20 steps on, |dx| %.3g m, |dv| %.3g m/s\n", dx, dv);
  EXPECT_LT(dx, 1e-13);
  EXPECT_LT(dv, 1e-11);
}

}  // namespace
}  // namespace fbar
