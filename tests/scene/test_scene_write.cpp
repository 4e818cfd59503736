// Scene front end: the writer's round trip (shipped scenes, every feature, meshes, scenes built in code) and
// ClaymoreUW's tolerances (cylinder axes, resume files, sensor frequencies, inverted boxes, dropped particles, asset
// lookup, nearly cubic ppc). Defaults, aliases, validation and Froude scaling: test_scene_parse.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "geometry/geometry.h"
#include "scene/scene_parse.h"
#include "scene_parse_test_support.h"

namespace fbar {
namespace {

using namespace scene_test;

/// parse(write(scene)) == scene, and writing again gives the same text.
void expect_round_trip(const Scene& scene) {
  const std::string text = write_scene_json(scene);
  ParseOptions o;
  o.check_supported = false;
  Scene again;
  try {
    again = parse_scene_string(text, o);
  } catch (const SceneError& e) {
    FAIL() << e.what() << "\n" << text;
  }
  EXPECT_TRUE(again == scene) << text;
  EXPECT_EQ(write_scene_json(again), text);
  EXPECT_EQ(write_scene_json(again, false), write_scene_json(scene, false));
}

TEST(SceneWrite, RoundTripOfTheShippedScenes) {
  for (const char* f : {"scenes/dam_break_3d.json", "scenes/elastic_block_drop.json", "scenes/two_disks.json",
                        "Projects/FBAR/scene.json", "tests/scenes/good/claymoreuw_layout.json",
                        "tests/scenes/good/csg_two_gpus.json", "tests/scenes/good/froude_scaled_block.json",
                        "tests/scenes/good/models_alias.json", "tests/scenes/good/tiny_fluid.json",
                        "tests/scenes/good/hydrouq_keys.json", "tests/scenes/good/decomposed_boundaries.json"}) {
    SCOPED_TRACE(f);
    const Scene s = parse_scene_file(std::string(FBAR_SOURCE_DIR) + "/" + f, ParseOptions{});
    expect_round_trip(s);
  }
}

TEST(SceneWrite, RoundTripOfEveryFeature) {
  // Every law, geometry object, operation, boundary object family, sensor kind, with Froude scaling applied.
  const std::string json = R"({
    "simulation": {"domain": [3, 2, 1], "default_dx": 0.02, "gravity": [0.1, -9.80665, 0], "time": 0.25,
                   "fps": 24, "frames": 7, "save_path": "out/x", "save_suffix": ".csv", "froude_scaling": 0.3,
                   "info_rate": 10, "precision": "mixed", "on_failure": "reduce_dt", "seed": 18446744073709551615,
                   "particles_output_exterior_only": true},
    "bodies": [
      {"gpu": 1, "material": {"constitutive": "NACC", "youngs_modulus": 3.3e6, "poisson_ratio": -0.1,
                              "friction_angle": 41.5, "xi": 0.7, "beta": 0.3, "logJp0": -0.01, "hardeningOn": false},
       "algorithm": {"use_ASFLIP": true, "ASFLIP_alpha": 0.995, "ASFLIP_beta_min": 0.01, "ASFLIP_beta_max": 0.2,
                     "use_FBAR": true, "FBAR_psi": 0.98, "FBAR_fused_kernel": true},
       "velocity": [0.1, 0.2, 0.3], "partition_start": [0.1, 0.1, 0.1],
       "track_particle_id": [0, 5], "track_attribs": ["Position_X"], "target_attribs": ["Velocity_Y"],
       "output_attribs": ["ID", "logJp", "StressPK2_1"],
       "geometry": [{"object": "Cylinder", "axis": "Y", "radius": 0.15, "span": [0, 0.5, 0],
                     "offset": [0.3, 0.2, 0.1], "rotate": [10, 20, 30], "fulcrum": [0.4, 0.4, 0.4],
                     "array": [2, 1, 3], "spacing": [0.4, 0, 0.3]},
                    {"object": "File", "operation": "Union", "file": "data/points.csv",
                     "scaling": 1.5, "has_attributes": true,
                     "input_attribs": ["Velocity_X", "Velocity_Y", "Velocity_Z", "J"],
                     "use_froude_scaling": false},
                    {"object": "File", "operation": "Subtract", "file": "data/cube.sdf", "padding": 2,
                     "scaling_factor": 0.5},
                    {"object": "Bathymetry", "span": [1, 0.5, 0.2], "bathymetry": [[0, 0.1], [1, 0.3]]},
                    {"object": "OSU LWF", "operation": "Intersection", "span": [2, 1, 1], "offset": [0.1, 0, 0]},
                    {"object": "OSU TWB", "span": [2, 1, 1], "use_custom_bathymetry": true,
                     "bathymetry": [[0, 0], [2, 0.2]]}]},
      {"gpu": 1, "model": 0, "material": {"constitutive": "DruckerPrager", "friction_angle": 35, "cohesion": 0.01,
                                          "SandVolCorrection": false, "ppc": 27},
       "partition_end": [2, 2, 2],
       "geometry": [{"object": "Sphere", "radius": 0.1, "offset": [1, 1, 0.5]},
                    {"object": "Box", "operation": "Intersection", "span": [0.1, 0.3, 0.3], "offset": [1, 1, 0.5]},
                    {"object": "Box", "operation": "Difference", "span": [0.05, 0.05, 0.05], "offset": [1, 1, 0.5]}]},
      {"material": {"constitutive": "NeoHookean", "type": "mesh"}, "algorithm": {"type": "mesh", "use_FEM": true},
       "geometry": [{"object": "Box", "operation": "Subtract"}]},
      {"initial_state": "hydrostatic", "material": {"constitutive": "JFluid", "tension_cutoff": 1500},
       "geometry": [{"object": "Box", "span": [0.5, 0.4, 0.3], "offset": [0.2, 0.2, 0.2]}]}],
    "boundaries": [
      {"object": "OSU_LWF_RAMP", "contact": "Slip", "domain_start": [0, 0, 0], "domain_end": [3, 2, 1],
       "use_custom_bathymetry": true, "bathymetry": [[0, 0.1], [1.5, 0.2], [3, 0.6]], "friction_static": 0.2},
      {"object": "OSU Paddle", "domain_start": [0, 0, 0], "domain_end": [0.1, 2, 1],
       "file": "data/paddle_motion.csv", "output_frequency": 100, "time": [0, 9]},
      {"object": "Box", "contact": "Separable", "domain_start": [1, 0, 0], "domain_end": [1.1, 0.3, 0.1],
       "array": [3, 1, 2], "spacing": [0.2, 0, 0.3], "velocity": [0, 0, -0.5], "friction_dynamic": 0.1}],
    "grid-sensors": [
      {"attribute": "Force", "operation": "Sum", "direction": "Z-", "output_frequency": 200,
       "domain_start": [1, 0, 0], "domain_end": [1.1, 0.3, 0.1]},
      {"attribute": "velocity", "operation": "STDEV", "direction": [1, 1, 0], "domain_start": [1, 0, 0],
       "domain_end": [1, 0.3, 0.1]}],
    "particle-sensors": [{"attribute": "Pressure", "operation": "Variance", "domain_start": [0, 0, 0],
                          "domain_end": [3, 2, 1]}]
  })";
  ParseOptions o;
  o.check_supported = false;
  o.data_dir = FBAR_SCENE_TEST_DIR;
  const Scene s = parse_scene_string(json, o);
  EXPECT_EQ(s.bodies[1].model, 0);
  EXPECT_EQ(s.bodies[0].model, 1);  // assigned after the explicit id 0 on gpu 1
  EXPECT_DOUBLE_EQ(s.grid_sensors[1].direction[0], std::sqrt(0.5));
  expect_round_trip(s);
}

// meshes[] (FEM bodies): each entry's files are read and checked at parse, resolved, and survive a round trip with the
// offset, Froude-scaled or not.
TEST(SceneWrite, RoundTripOfMeshEntries) {
  const std::string json = R"({
    "simulation": {"domain": [1, 1, 1], "default_dx": 0.05},
    "bodies": [{"material": {"constitutive": "JFluid"},
                "geometry": [{"object": "Box", "span": [0.2, 0.2, 0.2], "offset": [0.5, 0.5, 0.5]}]}],
    "meshes": [{"gpu": 1, "constitutive": "Meshed", "file": "ignored, as ClaymoreUW ignores it",
                "file_vertices": "../scenes/bad/mesh_cube_vertices.csv", "file_elements": "../scenes/bad/mesh_cube_elements.csv",
                "offset": [0.2, 0.1, 0.3], "velocity": [0, -1, 0], "rho": 1100, "youngs_modulus": 2e6,
                "poisson_ratio": 0.35, "ppc": 8, "use_FEM": true, "use_ASFLIP": true, "alpha": 0.9, "beta_min": 0,
                "beta_max": 0.2, "use_FBAR": true, "FBAR_ratio": 0.5, "FBAR_fused_kernel": false,
                "output_attribs": ["ID", "Position_X"], "track_attribs": ["Position_Y"], "track_particle_id": [3]},
               {"constitutive": "NeoHookean", "file": "../scenes/bad/mesh_two_tetrahedra.msh", "offset": [0.5, 0.5, 0.5]}]
  })";
  ParseOptions o;
  o.check_supported = false;
  o.data_dir = FBAR_SCENE_TEST_DIR;
  const Scene s = parse_scene_string(json, o);
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(s.meshes[0].summary.rfind("8 vertices, 6 tetrahedra, volume 0.001 m^3", 0), 0u) << s.meshes[0].summary;
  EXPECT_TRUE(s.meshes[0].file.empty());
  EXPECT_EQ(s.meshes[1].summary.rfind("5 vertices, 2 tetrahedra", 0), 0u) << s.meshes[1].summary;
  EXPECT_TRUE(std::filesystem::path(s.meshes[1].file).is_absolute()) << s.meshes[1].file;
  EXPECT_EQ(s.meshes[1].offset, (Real3{0.5, 0.5, 0.5}));
  EXPECT_EQ(s.meshes[0].gpu, 1);
  EXPECT_EQ(s.meshes[0].law, Constitutive::FixedCorotated);  // "Meshed": ClaymoreUW's FixedCorotated tetrahedra
  EXPECT_EQ(s.meshes[1].law, Constitutive::NeoHookean);
  EXPECT_TRUE(s.meshes[0].fbar_elements);
  EXPECT_DOUBLE_EQ(s.meshes[0].youngs_modulus, 2e6);
  EXPECT_DOUBLE_EQ(s.meshes[0].beta_max, 0.2);
  EXPECT_EQ(s.meshes[0].track_particle_id, (std::vector<long long>{3}));
  EXPECT_EQ(s.meshes[1].output_attribs, (std::vector<std::string>{"ID"}));  // the default
  expect_round_trip(s);
  // Keys in range, a law for tetrahedra, no unknown key; each error names its key.
  auto mesh_error = [&](const std::string& from, const std::string& to) {
    std::string bad = json;
    bad.replace(bad.find(from), from.size(), to);
    try {
      parse_scene_string(bad, o);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(mesh_error("\"poisson_ratio\": 0.35", "\"poisson_ratio\": 0.5"),
            "meshes[0].poisson_ratio: got 0.5; expected a number in (-1, 0.5) [-]");
  EXPECT_EQ(mesh_error("\"constitutive\": \"NeoHookean\"", "\"constitutive\": \"JFluid\""),
            "meshes[1].constitutive: got \"JFluid\"; expected \"Meshed\" (ClaymoreUW's FixedCorotated tetrahedra), "
            "\"FixedCorotated\" or \"NeoHookean\"");
  EXPECT_NE(mesh_error("\"FBAR_fused_kernel\"", "\"FBAR_fused_kernels\"").find("meshes[0].FBAR_fused_kernels"),
            std::string::npos);
  // Froude scaling (x 2): the vertices and the offset as lengths, the velocity by sqrt 2, the modulus by 2 (Cauchy
  // similitude); the written scene reads back the same (its mesh files are unscaled, its offset scaled).
  std::string scaled = json;
  scaled.replace(scaled.find("\"default_dx\": 0.05"), 18, "\"default_dx\": 0.05, \"froude_scaling\": 2");
  scaled.replace(scaled.find("\"domain\": [1, 1, 1]"), 19, "\"domain\": [0.5, 0.5, 0.5]");
  scaled.replace(scaled.find("\"offset\": [0.5, 0.5, 0.5]}]}"), 28, "\"offset\": [0.2, 0.2, 0.2]}]}");
  scaled.replace(scaled.find("\"offset\": [0.5, 0.5, 0.5]}]"), 27, "\"offset\": [0.3, 0.3, 0.3]}]");
  const Scene f = parse_scene_string(scaled, o);
  EXPECT_EQ(f.meshes[0].offset, (Real3{0.4, 0.2, 0.6}));
  EXPECT_DOUBLE_EQ(f.meshes[0].velocity[1], -std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(f.meshes[0].youngs_modulus, 4e6);
  EXPECT_DOUBLE_EQ(f.meshes[0].mesh->vertices[1][0], 2 * s.meshes[0].mesh->vertices[1][0] - 2 * 0.2 + 0.4);
  EXPECT_EQ(f.meshes[0].summary.rfind("8 vertices, 6 tetrahedra, volume 0.008 m^3", 0), 0u) << f.meshes[0].summary;
  ASSERT_EQ(f.bodies.size(), 3u);
  EXPECT_EQ(f.bodies[1].tet_mesh, f.meshes[0].mesh);
  expect_round_trip(f);
}

TEST(SceneWrite, RoundTripOfASceneBuiltInCode) {
  Scene s;
  s.simulation.dx = 0.03;
  s.simulation.default_dt = 2e-4;
  s.simulation.frames = 3;
  BodySpec b;
  b.material.law = Constitutive::FixedCorotated;
  b.material.youngs_modulus = 5e5;
  b.material.poisson_ratio = 0.33;
  b.partition_end = {kInf, 0.7, kInf};  // partly open: written as Infinity, which the reader accepts here
  GeometrySpec g;
  g.object = GeometryObject::Sphere;
  g.radius = 0.2;
  b.geometry.push_back(g);
  s.bodies.push_back(b);
  BoundarySpec w;
  w.domain_end = {1, 1, 1};
  w.time = {0.5, kInf};
  s.boundaries.push_back(w);
  expect_round_trip(s);
}


// ---------------------------------------------------------------------------------------------------------------
// ClaymoreUW's silent tolerances that its HEAD scenes rely on: each runs with exactly one warning that
// names the key, what ClaymoreUW does and what fbar does.

/// The warnings that contain `needle`.
std::vector<std::string> with(const std::vector<std::string>& warnings, const std::string& needle) {
  std::vector<std::string> out;
  for (const std::string& w : warnings)
    if (w.find(needle) != std::string::npos) out.push_back(w);
  return out;
}

// ClaymoreUW's YIELD scene gives a cylinder both axis and long_axis ("Z"); ClaymoreUW reads axis only.
TEST(ClaymoreUWTolerances, CylinderAxisAndLongAxis) {
  auto cylinder = [](const std::string& keys) {
    return scene_with(R"({"material": {}, "geometry": [{"object": "Cylinder", "radius": 0.1, "span": [0.2, 0.2, 0.2],
                         "offset": [0.3, 0.3, 0.3], )" + keys + "}]}");
  };
  std::vector<std::string> warnings;
  Scene s = parse(cylinder(R"("axis": "Z", "long_axis": "Z")"), true, &warnings);
  EXPECT_EQ(s.bodies[0].geometry[0].axis, 2);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], "bodies[0].geometry[0].long_axis: \"Z\" is redundant: ClaymoreUW ignores long_axis and reads "
                         "axis; fbar checks that the two agree and uses axis (\"Z\")");
  // Disagreeing: an error that says which one ClaymoreUW would use.
  EXPECT_NE(error_of(cylinder(R"("axis": "Y", "long_axis": "Z")"))
                .find("bodies[0].geometry[0].long_axis: got \"Z\"; expected the same axis as axis (\"Y\"), or only one "
                      "of them: ClaymoreUW would use axis and ignore long_axis"),
            std::string::npos);
  // long_axis alone is fbar's alias of axis, without a warning.
  warnings.clear();
  s = parse(cylinder(R"("long_axis": "Y")"), true, &warnings);
  EXPECT_EQ(s.bodies[0].geometry[0].axis, 1);
  EXPECT_TRUE(warnings.empty());
  // An unknown key beside them stays an error.
  EXPECT_NE(error_of(cylinder(R"("axis": "Z", "long_axes": "Z")")).find("long_axes"), std::string::npos);
}

// ClaymoreUW writes 1 - J under the name J (its ResumeCheckpoint scene reads its Create run's frame 20: a median of
// about 1e-4) and reads the column back as 1 - J: fbar does the same for such a file and says so; its own frames
// hold J. A particle that is inverted either way (J <= 0) is dropped, with the count and the first one.
TEST(ClaymoreUWTolerances, ResumeFilesWithOneMinusJAndInvertedParticles) {
  const std::filesystem::path file = std::filesystem::temp_directory_path() / "fbar_resume_j.csv";
  const auto warnings_for = [&](const std::string& rows) {
    {
      std::ofstream csv(file);
      csv << "Position_X,Position_Y,Position_Z,J,Velocity_X,Velocity_Y,Velocity_Z\n" << rows;
    }
    std::vector<std::string> warnings;
    parse(scene_with(R"({"material": {}, "geometry": [{"object": "File", "file": ")" + file.string() +
                     R"(", "has_attributes": true, "input_attribs": ["J", "Velocity_X", "Velocity_Y", "Velocity_Z"]}]})"),
          true, &warnings);
    return warnings;
  };
  const std::string at = "bodies[0].geometry[0].file: \"" + file.string() + "\": ";
  // ClaymoreUW's column: 1 - J, one particle crushed (1 - J = 1.2, J = -0.2).
  std::vector<std::string> w = warnings_for("0.1,0.1,0.1,0.0001,0,0,0\n0.2,0.2,0.2,-0.000008,0,0,0\n"
                                            "0.3,0.3,0.3,0.0002,0,0,0\n0.4,0.4,0.4,1.2,0,0,0\n");
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0], at + "its J column holds 1 - J, as ClaymoreUW writes it (median 0.0002); fbar reads J = 1 - value, "
                       "as ClaymoreUW reads it back. fbar's own frames hold J");
  EXPECT_EQ(w[1], at + "1 of its 4 particles are inverted (J or det DefGrad <= 0; first: point 3: J = -0.2) and are "
                       "dropped. ClaymoreUW keeps such particles (its JFluid pressure pow(J, -gamma) is not a number "
                       "there)");
  // fbar's column: J, two inverted.
  w = warnings_for("0.1,0.1,0.1,1,0,0,0\n0.2,0.2,0.2,0.98,0,0,0\n0.3,0.3,0.3,-0.000008,0,0,0\n0.4,0.4,0.4,0,0,0,0\n");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].rfind(at + "2 of its 4 particles are inverted (J or det DefGrad <= 0; first: point 2: J = -8e-06)", 0), 0u)
      << w[0];
  // A healthy J column: nothing said.
  EXPECT_TRUE(warnings_for("0.1,0.1,0.1,1,0,0,0\n0.2,0.2,0.2,0.999,0,0,0\n").empty());
  std::filesystem::remove(file);
}

// ClaymoreUW keeps one output frequency per kind of sensor (the last one read) and writes every sensor of that kind
// at it: its AVE scene's load cells (120 Hz) are written at its velocity meters' 2048 Hz. fbar writes each sensor at
// its own rate and says so once per kind; sensors that agree, or a single sensor, give no warning.
TEST(ClaymoreUWTolerances, SensorFrequenciesThatDifferAreNamed) {
  std::vector<std::string> warnings;
  const Scene s = parse(scene_with(body(), R"("grid-sensors": [
      {"attribute": "Force", "direction": "X+", "output_frequency": 120, "domain_start": [0, 0, 0], "domain_end": [0.1, 0.1, 0.1]},
      {"attribute": "Force", "direction": "X-", "output_frequency": 120, "domain_start": [0, 0, 0], "domain_end": [0.1, 0.1, 0.1]},
      {"attribute": "Velocity", "direction": "Y", "output_frequency": 2048, "domain_start": [0, 0, 0], "domain_end": [0.1, 0.1, 0.1]}],
      "particle-sensors": [
      {"attribute": "Position_Y", "operation": "Max", "output_frequency": 30, "domain_start": [0, 0, 0], "domain_end": [0.1, 0.1, 0.1]},
      {"attribute": "Position_Y", "operation": "Max", "output_frequency": 30, "domain_start": [0, 0, 0], "domain_end": [0.1, 0.1, 0.1]}])"),
                        true, &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], "grid-sensors[].output_frequency: 2 of the 3 sensors ask for another rate than the last one's "
                         "(2048 Hz, grid-sensors[2]). ClaymoreUW writes every grid sensor at the last one's rate; fbar "
                         "writes each at its own");
  ASSERT_EQ(s.grid_sensors.size(), 3u);
  EXPECT_EQ(s.grid_sensors[0].output_frequency, 120.0);  // kept: fbar samples each at its own rate
  EXPECT_EQ(s.grid_sensors[2].output_frequency, 2048.0);
  EXPECT_EQ(s.particle_sensors[1].output_frequency, 30.0);
}

// ClaymoreUW's DKT_2D scene has a particle sensor with domain_end[0] < domain_start[0]: it runs, the box holds
// nothing. Grid sensors the same; a boundary box stays an error; a zero-length grid-sensor box grows by one cell.
TEST(ClaymoreUWTolerances, InvertedSensorBoxesRunEmpty) {
  std::vector<std::string> warnings;
  const Scene s = parse(scene_with(body(), R"("particle-sensors": [{"attribute": "Position_Y", "operation": "Max",
      "domain_start": [0.0099, 0, 0], "domain_end": [0.0011, 0.08, 0.0001]}],
      "grid-sensors": [{"attribute": "Mass", "domain_start": [0, 0.5, 0], "domain_end": [1, 0.2, 0.1]},
                       {"attribute": "Mass", "domain_start": [0.2, 0.2, 0.2], "domain_end": [0.2, 0.4, 0.4]}])"),
                        true, &warnings);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_EQ(warnings[0].rfind("grid-sensors[0].domain_end[1]: 0.2 m is below domain_start[1] (0.5 m): the sensor's box "
                              "holds nothing. ClaymoreUW runs the scene with this empty sensor; fbar runs it too and "
                              "writes the sensor's file with 0 for Sum and Count and NaN for Max",
                              0),
            0u)
      << warnings[0];
  EXPECT_EQ(warnings[1].rfind("particle-sensors[0].domain_end[0]: 0.0011 m is below domain_start[0] (0.0099 m)", 0), 0u)
      << warnings[1];
  ASSERT_EQ(s.particle_sensors.size(), 1u);
  EXPECT_EQ(s.particle_sensors[0].domain_start[0], 0.0099);  // kept as given: the box contains nothing
  EXPECT_EQ(s.particle_sensors[0].domain_end[0], 0.0011);
  EXPECT_EQ(s.grid_sensors[0].domain_end[1], 0.2);
  EXPECT_EQ(s.grid_sensors[1].domain_end[0], 0.2 + 0.05);  // zero length along x: one cell (dx 0.05), as ClaymoreUW
  EXPECT_EQ(s.grid_sensors[1].domain_end[1], 0.4);
  EXPECT_NE(error_of(scene_with(body(), R"("boundaries": [{"object": "Box", "domain_start": [0.5, 0, 0],
                                                          "domain_end": [0.2, 1, 1]}])"))
                .find("boundaries[0].domain_end[0]: got 0.2; expected a number > domain_start[0] (0.5)"),
            std::string::npos);
}

// ClaymoreUW's scene.json tracks IDs 100000.. of bodies with fewer particles; geometry outside the partition is
// dropped silently by ClaymoreUW; particles outside the domain (YIELD: below y = 0) it keeps in its grid's 8-cell
// margin, and so does fbar, without a word. The test scene shipped in tests/scenes/good has one of each, and
// particles beyond the margin: one warning each, with the counts.
TEST(ClaymoreUWTolerances, TrackedIdsPartitionAndDomainDropsWarnWithCounts) {
  std::vector<std::string> warnings;
  ParseOptions o;
  o.warnings = &warnings;
  const Scene s =
      parse_scene_file(std::string(FBAR_SCENE_TEST_DIR) + "/../scenes/good/claymoreuw_tolerances.json", o);
  ASSERT_EQ(warnings.size(), 6u);
  const auto ids = with(warnings, "track_particle_id");
  ASSERT_EQ(ids.size(), 1u);
  EXPECT_EQ(ids[0], "bodies[0].track_particle_id[1]: 100000 is not the ID of one of the body's 320 particles (0 .. 319, "
                    "in sampling order); ClaymoreUW matches no particle and writes 0.0 for it every frame; fbar writes "
                    "NaN in its columns of particleTrack_model[0]_dev[0].csv");
  const auto domain = with(warnings, "outside simulation.domain");
  ASSERT_EQ(domain.size(), 1u);
  EXPECT_EQ(domain[0], "bodies[0].geometry: 64 of the body's 384 particles lie more than 8 cells (0.4 m) outside "
                       "simulation.domain [0, 0.4] x [0, 0.4] x [0, 0.4] m and are dropped (320 remain); particles may "
                       "stand within that margin (ClaymoreUW's grid margin, whose grid ends there)");
  const auto partition = with(warnings, "partition_start/partition_end");
  ASSERT_EQ(partition.size(), 1u);
  EXPECT_EQ(partition[0], "bodies[1].partition_start/partition_end: 24 of the 48 particles of the body's geometry lie "
                          "outside [0, 0, 0] .. [0.25, 0.4, 0.4] m and are dropped; ClaymoreUW drops them too, without "
                          "a word");
  EXPECT_EQ(with(warnings, "long_axis").size(), 1u);
  EXPECT_EQ(with(warnings, "the sensor's box holds nothing").size(), 2u);
  // The counts the engines sample.
  // Body 0 keeps the 256 particles between y = -0.4 and 0 (the margin) and the 64 inside the domain.
  const std::vector<Vec3d> kept = sample_body(s.bodies[0], s.simulation, 0);
  EXPECT_EQ(kept.size(), 320u);
  EXPECT_EQ(std::count_if(kept.begin(), kept.end(), [](const Vec3d& p) { return p[1] < 0.0; }), 256);
  for (const Vec3d& p : kept) EXPECT_GE(p[1], -0.4) << p[1];
  EXPECT_EQ(sample_body(s.bodies[1], s.simulation, 1).size(), 24u);
  // IDs within the body: no warning.
  warnings.clear();
  parse(scene_with(body(R"({"constitutive": "JFluid"})", R"("track_particle_id": [0, 63])")), true, &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();
}

// Asset files (geometry and motion files) are found where ClaymoreUW users keep them and where fbar ships them:
// the name as written under the scene's folder, then the file's own name in each folder and its motion/ and
// geometry/ subfolders (fbar's Data/motion/ holds ClaymoreUW's wave-maker series).
TEST(ClaymoreUWTolerances, AssetFilesAreFoundInOneOrder) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(::testing::TempDir()) / "fbar_asset_lookup";
  fs::remove_all(root);
  fs::create_directories(root / "scenes");
  const fs::path shipped = fs::path(FBAR_SCENE_TEST_DIR) / ".." / ".." / "Data" / "motion" /
                           "wmdisp_hydro2sec_1200hz_smooth_14032023.csv";
  ASSERT_TRUE(fs::is_regular_file(shipped)) << shipped;
  fs::copy_file(shipped, root / "mine.csv");
  fs::copy_file(shipped, root / "scenes" / "near.csv");
  auto scene_file = [&](const std::string& file) {
    std::ofstream out(root / "scenes" / "scene.json");
    out << scene_with(body(), R"("boundaries": [{"object": "OSU Paddle", "domain_start": [0, 0, 0],
        "domain_end": [0.05, 1, 1], "time": [10, 20], "output_frequency": 1200, "file": ")" + file + R"("}])");
  };
  std::vector<std::string> warnings;
  ParseOptions o;
  o.warnings = &warnings;
  auto resolved = [&](const std::string& file) {
    warnings.clear();
    scene_file(file);
    return fs::path(parse_scene_file((root / "scenes" / "scene.json").string(), o).boundaries.at(0).file);
  };
  // A bare name of a file fbar ships: Data/motion/, without a warning.
  EXPECT_EQ(fs::canonical(resolved("wmdisp_hydro2sec_1200hz_smooth_14032023.csv")), fs::canonical(shipped));
  EXPECT_TRUE(warnings.empty());
  // ClaymoreUW's "..//name" relative to the scene's folder (the Create scene's form): found as written.
  EXPECT_EQ(fs::canonical(resolved("..//mine.csv")), fs::canonical(root / "mine.csv"));
  EXPECT_TRUE(warnings.empty());
  // A name with folders that do not hold it: its file name in a search folder, with one warning.
  EXPECT_EQ(fs::canonical(resolved("../elsewhere/near.csv")), fs::canonical(root / "scenes" / "near.csv"));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("boundaries[0].file: \"../elsewhere/near.csv\" is not found as written; using "),
            std::string::npos)
      << warnings[0];
  // Nowhere: the error names the file and every place looked at (ClaymoreUW's resume scene without its checkpoint).
  scene_file("../checkpoint/model[0]_dev[0]_frame[20].bgeo");
  try {
    parse_scene_file((root / "scenes" / "scene.json").string(), o);
    ADD_FAILURE() << "a missing file parsed";
  } catch (const SceneError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("boundaries[0].file: got \"../checkpoint/model[0]_dev[0]_frame[20].bgeo\"; expected an existing "
                        "file (looked for " + (root / "checkpoint" / "model[0]_dev[0]_frame[20].bgeo").string()),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("model[0]_dev[0]_frame[20].bgeo in each of those folders and their motion/ and geometry/ "
                        "subfolders"),
              std::string::npos)
        << what;
  }
}

// HydroUQ's ppc 27.000001 (ClaymoreUW's YIELD and DKT_2D scenes) samples ClaymoreUW's dx / 3 lattice: exactly 27
// particles per full cell.
TEST(ClaymoreUWTolerances, NearlyCubicPpcIsTheLattice) {
  const Scene s = parse(scene_with(body(R"({"constitutive": "JFluid", "ppc": 27.000001})")));
  EXPECT_EQ(sample_body(s.bodies[0], s.simulation, 0).size(), 4u * 4u * 4u * 27u);  // 0.2 m box, dx 0.05
}

}  // namespace
}  // namespace fbar
