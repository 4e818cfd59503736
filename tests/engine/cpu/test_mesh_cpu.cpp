// FEM bodies on the CPU engine (physics/fem.cuh, engine/cpu/cpu_mesh.cpp): the lumped mass, free flight, the coupling
// with particles, the element failure report, the frames with their .vtk connectivity, checkpoints, and a parsed
// scene's mesh turned into a body.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "../../physics/physics_test_support.h"
#include "../run_support.h"
#include "engine/cpu/cpu_engine.h"
#include "geometry/tet_mesh.h"
#include "io/checkpoint.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

namespace fs = std::filesystem;
using test::r3;

/// A scene of one mesh: the box [lo, hi] in cubes, FixedCorotated E 1e6 Pa, nu 0.3, rho 1000.
Scene mesh_scene(Real3 domain, double dx, Real3 gravity, Vec3d lo, Vec3d hi, Vec3i cells, Real3 velocity = r3(0, 0, 0)) {
  Scene scene = test::empty_scene(domain, dx, gravity);
  MeshEntrySpec& m = test::add_elastic_mesh(scene, box_tet_mesh(lo, hi, cells), 1000.0, 1e6, 0.3);
  m.velocity = velocity;
  m.output_attribs = {"ID", "J", "Velocity_X"};
  append_mesh_bodies(scene);
  return scene;
}

// The vertices carry the elements' lumped volumes: the body's mass is rho V exactly, whatever the mesh, and P2G puts
// all of it on the grid.
TEST(MeshCpu, LumpedMassIsTheMeshMass) {
  const Scene scene = mesh_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0), Vec3d{{0.3, 0.3, 0.3}}, Vec3d{{0.5, 0.4, 0.45}}, Vec3i{{4, 3, 5}});
  CpuEngine<double> engine(scene);
  const double mass = 1000.0 * 0.2 * 0.1 * 0.15;
  EXPECT_NEAR(engine.total_mass(), mass, 1e-13 * mass);
  ASSERT_TRUE(engine.step().ok);
  EXPECT_NEAR(engine.grid_mass(), mass, 1e-12 * mass);
  EXPECT_EQ(engine.particle_count(0), (5u * 4u * 6u));
}

// A mesh thrown without gravity translates rigidly: momentum kept to round-off, no strain (the elements' energy
// stays at round-off), every vertex moved by v t.
TEST(MeshCpu, FreeFlightIsARigidTranslation) {
  const Scene scene = mesh_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0), Vec3d{{0.3, 0.3, 0.3}}, Vec3d{{0.5, 0.4, 0.45}},
                                 Vec3i{{4, 2, 3}}, r3(0.5, -0.2, 0.1));
  CpuEngine<double> engine(scene);
  const std::vector<Vec3d> x0 = engine.positions(0);
  const Vec3d p0 = engine.total_momentum();
  for (int s = 0; s < 40; ++s) ASSERT_TRUE(engine.step().ok);
  const Vec3d p = engine.total_momentum();
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(p[a], p0[a], 1e-12 * norm(p0));
  EXPECT_LT(engine.elastic_energy(), 1e-20 * engine.kinetic_energy() + 1e-24);
  const Vec3d v{{0.5, -0.2, 0.1}};
  for (std::size_t i = 0; i < x0.size(); ++i)
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(engine.positions(0)[i][a], x0[i][a] + v[a] * engine.time(), 1e-12);
}

// A stretched bar springs back: the elements' force moves the vertices, the energy goes from kinetic to elastic and
// back (symplectic Euler keeps the total below its start), and the momentum of the symmetric start stays zero.
TEST(MeshCpu, StretchedBarSpringsBack) {
  Scene scene = mesh_scene(r3(1, 0.4, 0.4), 0.04, r3(0, 0, 0), Vec3d{{0.2, 0.16, 0.16}}, Vec3d{{0.6, 0.24, 0.24}},
                           Vec3i{{20, 4, 4}});
  CpuEngine<double> engine(scene);
  engine.set_velocities(0, [](const Vec3d& x) { return Vec3d{{0.5 * (x[0] - 0.4), 0, 0}}; });  // stretching
  const double e0 = engine.kinetic_energy() + engine.elastic_energy();
  double e_max = e0, elastic_max = 0, momentum = 0, length_max = 0;
  for (int s = 0; s < 300; ++s) {
    ASSERT_TRUE(engine.step().ok);
    e_max = std::max(e_max, engine.kinetic_energy() + engine.elastic_energy());
    elastic_max = std::max(elastic_max, engine.elastic_energy());
    momentum = std::max(momentum, std::fabs(engine.total_momentum()[0]));
    double lo = 1e9, hi = -1e9;
    for (const Vec3d& x : engine.positions(0)) lo = std::min(lo, x[0]), hi = std::max(hi, x[0]);
    length_max = std::max(length_max, hi - lo);
  }
  EXPECT_GT(elastic_max, 0.5 * e0);  // the kinetic energy went into the elements
  EXPECT_LT(e_max, 1.02 * e0);
  EXPECT_LT(momentum, 1e-12 * engine.total_mass() * 0.1);
  EXPECT_GT(length_max, 0.4 * 1.001);  // it stretched, then came back (elastic_max)
}

// An element turned inside out is a failure naming the body, the count of elements and the first one.
TEST(MeshCpu, InvertedElementIsReportedByElement) {
  const Scene scene = mesh_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0), Vec3d{{0.4, 0.4, 0.4}}, Vec3d{{0.6, 0.6, 0.6}},
                                 Vec3i{{4, 4, 4}});
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  // Squash the cube through itself along z in one step: z - 0.5 becomes -2 (z - 0.5).
  const double dt = 1e-3;
  engine.set_velocities(0, [&](const Vec3d& x) { return Vec3d{{0, 0, -3.0 * (x[2] - 0.5) / dt}}; });
  const StepReport r = engine.step(dt);
  ASSERT_FALSE(r.ok);
  const std::string m = r.message();
  EXPECT_NE(m.find(" elements volume ratio J <= 0"), std::string::npos) << m;
  EXPECT_NE(m.find("(first: element "), std::string::npos) << m;
}

// A mesh falls onto an elastic particle block and comes to rest on it: the two bodies meet on the grid (momentum
// exchanged, no interpenetration beyond a cell).
TEST(MeshCpu, MeshRestsOnAParticleBlock) {
  Scene scene = mesh_scene(r3(0.4, 0.4, 0.24), 0.02, r3(0, -9.81, 0), Vec3d{{0.14, 0.2, 0.06}},
                           Vec3d{{0.26, 0.26, 0.18}}, Vec3i{{6, 3, 6}});
  scene.meshes[0].youngs_modulus = 2e5;
  BodySpec block = test::box_body(Constitutive::FixedCorotated, r3(0.04, 0.04, 0.04), r3(0.32, 0.1, 0.16));
  block.material.youngs_modulus = 2e6;
  scene.bodies.insert(scene.bodies.begin(), block);
  append_mesh_bodies(scene);  // the mesh's body after the particle bodies again
  ASSERT_EQ(scene.bodies.size(), 2u);
  ASSERT_EQ(scene.bodies[1].mesh, 0);
  BoundarySpec floor;
  floor.object = BoundaryObject::Walls;
  floor.contact = Contact::Sticky;
  floor.domain_start = r3(0.04, 0.04, 0.04);
  floor.domain_end = r3(0.36, 0.36, 0.2);
  scene.boundaries.push_back(floor);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  const StepReport r = engine.advance_to(0.5);
  ASSERT_TRUE(r.ok) << r.message();
  double lowest = 1e9, speed = 0;
  for (std::size_t i = 0; i < engine.positions(1).size(); ++i) {
    lowest = std::min(lowest, engine.positions(1)[i][1]);
    speed = std::max(speed, norm(engine.velocities(1)[i]));
  }
  // The block's top is at 0.14 m (it settles by rho g h^2 / (2 E) ~ 2.5e-5 m); the mesh's bottom rests within a cell
  // above it (grid contact acts at a cell's distance) and never goes through.
  EXPECT_GT(lowest, 0.14 - 0.01);
  EXPECT_LT(lowest, 0.14 + 0.03);
  EXPECT_LT(speed, 0.05) << "the mesh is still moving";
}

// Frames of a mesh body: the vertices as a particle frame and, beside it, a .vtk of the tetrahedra that ParaView
// opens (header, point and cell counts, point data of the attributes).
TEST(MeshCpu, FramesCarryTheConnectivity) {
  const fs::path dir = fs::temp_directory_path() / "fbar_mesh_frames";
  fs::remove_all(dir);
  Scene scene = mesh_scene(r3(1, 1, 1), 0.05, r3(0, -9.81, 0), Vec3d{{0.3, 0.3, 0.3}}, Vec3d{{0.5, 0.4, 0.45}},
                           Vec3i{{2, 1, 1}});
  scene.simulation.save_path = dir.string();
  scene.simulation.save_suffix = ".bgeo";
  scene.simulation.fps = 100;
  scene.simulation.frames = 1;
  const std::vector<RunResult> r = test::run_cpu_ranks(scene, 1);
  ASSERT_EQ(r[0].exit_code, 0) << r[0].message;
  for (int f : {0, 1}) {
    const fs::path bgeo = dir / ("model[0]_dev[0]_frame[" + std::to_string(f) + "].bgeo");
    const fs::path vtk = dir / ("model[0]_dev[0]_frame[" + std::to_string(f) + "].vtk");
    ASSERT_TRUE(fs::exists(bgeo)) << bgeo;
    ASSERT_TRUE(fs::exists(vtk)) << vtk;
    std::ifstream in(vtk, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text.rfind("# vtk DataFile Version 3.0\n", 0), 0u);
    EXPECT_NE(text.find("POINTS 12 double\n"), std::string::npos);
    EXPECT_NE(text.find("CELLS 12 60\n"), std::string::npos);
    EXPECT_NE(text.find("CELL_TYPES 12\n"), std::string::npos);
    EXPECT_NE(text.find("POINT_DATA 12\n"), std::string::npos);
    EXPECT_NE(text.find("SCALARS ID int 1\n"), std::string::npos);
    EXPECT_NE(text.find("SCALARS J float 1\n"), std::string::npos);
    EXPECT_NE(text.find("SCALARS Velocity_X float 1\n"), std::string::npos);
  }
  fs::remove_all(dir);
}

// A checkpoint of a mesh scene continues bit for bit: the element forces follow from the positions.
TEST(MeshCpu, CheckpointContinuesBitForBit) {
  Scene scene = mesh_scene(r3(0.6, 0.6, 0.6), 0.04, r3(0, -9.81, 0), Vec3d{{0.2, 0.2, 0.2}}, Vec3d{{0.36, 0.3, 0.3}},
                           Vec3i{{8, 5, 5}}, r3(0.3, 0.1, 0));
  CpuEngine<double> a(scene);
  for (int s = 0; s < 20; ++s) ASSERT_TRUE(a.step().ok);
  const io::Checkpoint c = a.checkpoint();
  CpuEngine<double> b(scene, c);
  for (int s = 0; s < 20; ++s) {
    ASSERT_TRUE(a.step().ok);
    ASSERT_TRUE(b.step().ok);
  }
  ASSERT_EQ(a.positions(0).size(), b.positions(0).size());
  for (std::size_t i = 0; i < a.positions(0).size(); ++i)
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(a.positions(0)[i][k], b.positions(0)[i][k]);
      EXPECT_EQ(a.velocities(0)[i][k], b.velocities(0)[i][k]);
    }
}

// A parsed scene: the mesh becomes a body after the particle bodies, model number the first free one on its GPU,
// its keys carried over; written back, the scene reads the same.
TEST(MeshCpu, ParsedMeshBecomesABody) {
  const fs::path dir = fs::temp_directory_path() / "fbar_mesh_parse";
  fs::create_directories(dir);
  {
    std::ofstream v(dir / "v.csv"), e(dir / "e.csv");
    v << "0,0,0\n0.1,0,0\n0,0.1,0\n0,0,0.1\n";
    e << "1,2,3,4\n";
  }
  const std::string json = R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05},
    "bodies": [{"material": {"constitutive": "JFluid"}, "geometry": [{"object": "Box", "span": [0.2, 0.2, 0.2],
                "offset": [0.1, 0.1, 0.1]}]}],
    "meshes": [{"gpu": 0, "constitutive": "Meshed", "file_vertices": "v.csv", "file_elements": "e.csv",
                "offset": [0.5, 0.5, 0.5], "velocity": [1, 0, 0], "rho": 800, "youngs_modulus": 2e6,
                "poisson_ratio": 0.25, "use_FEM": true, "use_ASFLIP": true, "alpha": 0.5,
                "use_FBAR": true, "output_attribs": ["ID", "J", "Pressure"]}]})";
  ParseOptions o;
  o.data_dir = dir.string();
  const Scene scene = parse_scene_string(json, o);
  ASSERT_EQ(scene.bodies.size(), 2u);
  const BodySpec& b = scene.bodies[1];
  EXPECT_EQ(b.mesh, 0);
  EXPECT_EQ(b.gpu, 0);
  EXPECT_EQ(b.model, 1);  // model 0 of GPU 0 is the water's
  EXPECT_EQ(b.material.law, Constitutive::FixedCorotated);
  EXPECT_EQ(b.material.rho, 800.0);
  EXPECT_EQ(b.velocity, r3(1, 0, 0));
  EXPECT_TRUE(b.algorithm.asflip_active());
  EXPECT_EQ(b.algorithm.asflip_alpha, 0.5);
  EXPECT_FALSE(b.algorithm.use_fbar);  // use_FBAR is the elements'
  EXPECT_TRUE(scene.meshes[0].fbar_elements);
  EXPECT_EQ(scene.meshes[0].fbar_ratio, 1.0);  // ClaymoreUW's full average
  ASSERT_TRUE(scene.meshes[0].mesh);
  EXPECT_EQ(scene.meshes[0].mesh->vertices[1], (Vec3d{{0.6, 0.5, 0.5}}));
  EXPECT_EQ(b.output_attribs, (std::vector<std::string>{"ID", "J", "Pressure"}));
  check_supported(scene);  // the CPU engine runs it
  CpuEngine<double> engine(scene);
  EXPECT_EQ(engine.particle_count(1), 4u);
  EXPECT_NEAR(engine.total_mass() - engine.masses(0).size() * engine.masses(0)[0], 800.0 * 0.1 * 0.1 * 0.1 / 6, 1e-12);
  const Scene again = parse_scene_string(write_scene_json(scene), o);
  EXPECT_TRUE(again == scene);
  fs::remove_all(dir);
}

// A Gmsh mesh (MSH 4.1, fbar's `file`) of NeoHookean tetrahedra runs like a CSV one: the bad-scene corpus's two
// tetrahedra dropped onto a Sticky floor come to rest on it with their mass.
TEST(MeshCpu, GmshNeoHookeanMeshRuns) {
  const std::string json = R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05, "gravity": [0, -9.81, 0]},
    "bodies": [{"material": {"constitutive": "JFluid"}, "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1],
                "offset": [0.1, 0.1, 0.1]}]}],
    "boundaries": [{"object": "Walls", "contact": "Sticky", "domain_start": [0.05, 0.05, 0.05],
                    "domain_end": [0.95, 0.95, 0.95]}],
    "meshes": [{"constitutive": "NeoHookean", "file": "mesh_two_tetrahedra.msh", "offset": [0.5, 0.3, 0.5],
                "rho": 1000, "youngs_modulus": 1e6, "poisson_ratio": 0.3, "use_FEM": true}]})";
  ParseOptions o;
  o.data_dir = std::string(FBAR_SOURCE_DIR) + "/tests/scenes/bad";
  const Scene scene = parse_scene_string(json, o);
  ASSERT_EQ(scene.bodies.size(), 2u);
  EXPECT_EQ(scene.bodies[1].material.law, Constitutive::NeoHookean);
  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  double mesh_mass = 0, volume = 0;
  for (double m : engine.masses(1)) mesh_mass += m;
  const TetMesh& mesh = *scene.meshes[0].mesh;
  for (const auto& e : mesh.elements)
    volume += tet_volume(mesh.vertices[e[0]], mesh.vertices[e[1]], mesh.vertices[e[2]], mesh.vertices[e[3]]);
  EXPECT_NEAR(mesh_mass, 1000.0 * volume, 1e-12 * 1000.0 * volume);
  const StepReport r = engine.advance_to(0.4);
  ASSERT_TRUE(r.ok) << r.message();
  double lowest = 1e9, speed = 0;
  for (std::size_t i = 0; i < engine.positions(1).size(); ++i) {
    lowest = std::min(lowest, engine.positions(1)[i][1]);
    speed = std::max(speed, norm(engine.velocities(1)[i]));
  }
  EXPECT_LT(lowest, 0.05 + 0.05);  // fell from 0.3 m to the floor at 0.05 m (within a cell)
  EXPECT_GT(lowest, 0.05 - 0.01);
  EXPECT_LT(speed, 0.05);
}

}  // namespace
}  // namespace fbar
