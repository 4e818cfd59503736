// Scene front end: defaults, aliases, validation messages, unknown keys, model ids, Froude scaling (the writer's round
// trip and ClaymoreUW's tolerances: test_scene_write.cpp).
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

TEST(SceneParse, DefaultsAreClaymoreUWs) {
  const Scene s = parse(R"({"bodies": [{"material": {}, "geometry": [{"object": "Box"}]}]})");
  const SimulationSpec& sim = s.simulation;
  EXPECT_EQ(sim.domain, (Real3{1, 1, 1}));
  EXPECT_EQ(sim.dx, 0.1);
  EXPECT_EQ(sim.default_dt, 0.1 / 100.0);  // dx / 100 when absent
  EXPECT_EQ(sim.gravity, (Real3{0, -9.81, 0}));
  EXPECT_EQ(sim.time, 0.0);
  EXPECT_EQ(sim.fps, 60.0);
  EXPECT_EQ(sim.frames, 60);
  EXPECT_EQ(sim.save_path, "./");
  EXPECT_EQ(sim.save_suffix, ".bgeo");
  EXPECT_FALSE(sim.particles_output_exterior_only);
  EXPECT_EQ(sim.froude_scaling, 1.0);
  EXPECT_EQ(sim.precision, Precision::Single);
  EXPECT_EQ(sim.on_failure, OnFailure::Stop);
  ASSERT_EQ(s.bodies.size(), 1u);
  const BodySpec& b = s.bodies[0];
  EXPECT_EQ(b.gpu, 0);
  EXPECT_EQ(b.model, 0);
  EXPECT_EQ(b.velocity, (Real3{0, 0, 0}));
  EXPECT_EQ(b.partition_start, (Real3{-kInf, -kInf, -kInf}));
  EXPECT_EQ(b.partition_end, (Real3{kInf, kInf, kInf}));
  EXPECT_EQ(b.output_attribs, std::vector<std::string>{"ID"});
  EXPECT_EQ(b.material.law, Constitutive::JFluid);
  EXPECT_EQ(b.material.ppc, 8.0);
  EXPECT_EQ(b.material.cfl, 0.5);
  EXPECT_EQ(b.material.rho, 1000.0);
  EXPECT_EQ(b.material.bulk_modulus, 2e7);
  EXPECT_EQ(b.material.gamma, 7.1);
  EXPECT_EQ(b.material.viscosity, 1e-3);
  EXPECT_TRUE(b.algorithm.use_asflip);
  EXPECT_EQ(b.algorithm.asflip_alpha, 0.0);
  EXPECT_TRUE(b.algorithm.use_fbar);
  EXPECT_EQ(b.algorithm.fbar_psi, 0.0);
  EXPECT_FALSE(b.algorithm.use_fem);
  ASSERT_EQ(b.geometry.size(), 1u);
  EXPECT_EQ(b.geometry[0].operation, GeometryOperation::Add);
  EXPECT_EQ(b.geometry[0].span, (Real3{1, 1, 1}));
  EXPECT_EQ(b.geometry[0].array, (Int3{1, 1, 1}));
  EXPECT_TRUE(b.geometry[0].use_froude_scaling);
}

TEST(SceneParse, ElasticAndPlasticDefaults) {
  const Scene s = parse(scene_with(body(R"({"constitutive": "FixedCorotated"})") + "," +
                                   body(R"({"constitutive": "NACC"})") + "," + body(R"({"constitutive": "Sand"})")),
                        false);
  EXPECT_EQ(s.bodies[0].material.youngs_modulus, 1e7);
  EXPECT_EQ(s.bodies[0].material.poisson_ratio, 0.2);
  EXPECT_EQ(s.bodies[1].material.friction_angle, 30.0);
  EXPECT_EQ(s.bodies[1].material.xi, 0.8);
  EXPECT_EQ(s.bodies[1].material.beta, 0.5);
  EXPECT_TRUE(s.bodies[1].material.hardening);
  EXPECT_EQ(s.bodies[2].material.law, Constitutive::DruckerPrager);
  EXPECT_EQ(s.bodies[2].material.cohesion, 0.0);
  EXPECT_TRUE(s.bodies[2].material.vol_correction);
}

TEST(SceneParse, MaterialAliasesAreCaseInsensitive) {
  const std::vector<std::pair<const char*, Constitutive>> cases = {
      {"JFluid", Constitutive::JFluid},          {"Water", Constitutive::JFluid},
      {"fluid", Constitutive::JFluid},           {"J-Fluid", Constitutive::JFluid},
      {"FixedCorotated", Constitutive::FixedCorotated}, {"Fixed-Corotated", Constitutive::FixedCorotated},
      {"fixed_corotated", Constitutive::FixedCorotated}, {"NeoHookean", Constitutive::NeoHookean},
      {"Neo-Hookean", Constitutive::NeoHookean},  {"DruckerPrager", Constitutive::DruckerPrager},
      {"Drucker-Prager", Constitutive::DruckerPrager}, {"SAND", Constitutive::DruckerPrager},
      {"NACC", Constitutive::NACC},              {"CamClay", Constitutive::NACC},
      {"Cam-Clay", Constitutive::NACC},           {"cam clay", Constitutive::NACC}};
  for (const auto& [name, law] : cases) {
    const Scene s = parse(scene_with(body(std::string(R"({"constitutive": ")") + name + "\"}")), false);
    EXPECT_EQ(s.bodies[0].material.law, law) << name;
  }
}

TEST(SceneParse, ClaymoreUWLayoutAliases) {
  // models / grid-boundaries / targets, partition{} and output{} objects, ppc and CFL in algorithm,
  // constitutive on the body, output_freq, scaling, lower-case object names and contact aliases.
  const std::string json = R"({
    "simulation": {"domain": [2, 1, 1], "default_dx": 0.05},
    "models": [{
      "partition": {"gpu": 1, "model": 0, "partition_start": [0, 0, 0], "partition_end": [1, 1, 1]},
      "constitutive": "Water",
      "material": {"rho": 998},
      "algorithm": {"ppc": 27, "CFL": 0.4, "use_ASFLIP": false},
      "output": {"output_attribs": ["ID", "DefGrad_Determinant", "velocity_x"]},
      "geometry": [{"object": "sphere", "radius": 0.1, "offset": [0.2, 0.2, 0.2]}],
    }],
    "grid-boundaries": [{"object": "Wall", "contact": "roller", "domain_start": [0, 0, 0], "domain_end": [2, 1, 1]},
                        {"object": "OSU Paddle", "contact": "Separable", "domain_start": [0, 0, 0],
                         "domain_end": [0.1, 1, 1], "file": "data/paddle_motion.csv", "output_freq": 120}],
    "targets": [{"attribute": "Elevation", "operation": "Maximum", "output_freq": 30,
                 "domain_start": [1, 0, 0], "domain_end": [1, 1, 0.1]}]
  })";
  ParseOptions o;
  o.check_supported = false;
  o.data_dir = FBAR_SCENE_TEST_DIR;
  const Scene s = parse_scene_string(json, o);
  const BodySpec& b = s.bodies[0];
  EXPECT_EQ(b.gpu, 1);
  EXPECT_EQ(b.partition_end, (Real3{1, 1, 1}));
  EXPECT_EQ(b.material.law, Constitutive::JFluid);
  EXPECT_EQ(b.material.rho, 998.0);
  EXPECT_EQ(b.material.ppc, 27.0);
  EXPECT_EQ(b.material.cfl, 0.4);
  EXPECT_EQ(b.output_attribs, (std::vector<std::string>{"ID", "J", "Velocity_X"}));
  EXPECT_EQ(b.geometry[0].object, GeometryObject::Sphere);
  ASSERT_EQ(s.boundaries.size(), 2u);
  EXPECT_EQ(s.boundaries[0].object, BoundaryObject::Walls);
  EXPECT_EQ(s.boundaries[0].contact, Contact::Slip);
  EXPECT_EQ(s.boundaries[1].object, BoundaryObject::OSU_LWF_PADDLE);
  EXPECT_EQ(s.boundaries[1].output_frequency, 120.0);
  EXPECT_NE(s.boundaries[1].file.find("paddle_motion.csv"), std::string::npos);
  ASSERT_EQ(s.particle_sensors.size(), 1u);
  EXPECT_EQ(s.particle_sensors[0].attribute, "Position_Y");  // ClaymoreUW's wave-gauge "Elevation"
  EXPECT_EQ(s.particle_sensors[0].operation, SensorOperation::Max);
  EXPECT_EQ(s.particle_sensors[0].output_frequency, 30.0);
}

TEST(SceneParse, KeysGivenTwiceMustAgree) {
  EXPECT_NE(error_of(scene_with(body(R"({"constitutive": "JFluid", "ppc": 8})", R"("algorithm": {"ppc": 27})"))).find(
                "bodies[0].algorithm.ppc: got 27; expected the same value as bodies[0].material.ppc (8)"),
            std::string::npos);
  // Agreeing values are fine.
  EXPECT_EQ(parse(scene_with(body(R"({"constitutive": "JFluid", "ppc": 8})", R"("algorithm": {"ppc": 8.0})")))
                .bodies[0]
                .material.ppc,
            8.0);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("gpu": 0, "partition": {"gpu": 1})"))).find("bodies[0].partition.gpu"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"bodies": [], "models": []})").find("either bodies or models"), std::string::npos);
}

TEST(SceneParse, MessagesNamePathValueExpectationAndUnit) {
  EXPECT_EQ(error_of(scene_with(body(R"({"constitutive": "FixedCorotated", "poisson_ratio": 0.5})"))),
            "bodies[0].material.poisson_ratio: got 0.5; expected a number in (-1, 0.5) [-]");
  EXPECT_EQ(error_of(scene_with(body(R"({"CFL": 0})"))), "bodies[0].material.CFL: got 0; expected a number in (0, 1] [-]");
  EXPECT_EQ(error_of(R"({"simulation": {"default_dx": -0.1}, "bodies": [)" + body() + "]}"),
            "simulation.default_dx: got -0.1; expected a number > 0 [m]");
  EXPECT_EQ(error_of(scene_with(body(R"({"ppc": 0})"))),
            "bodies[0].material.ppc: got 0; expected a number > 0 [particles/cell]");
  EXPECT_EQ(error_of(R"({"simulation": {"domain": [1, 1]}, "bodies": [)" + body() + "]}"),
            "simulation.domain: got [1,1]; expected an array of 3 numbers, each > 0 [m]");
  EXPECT_EQ(error_of(R"({"simulation": {"gravity": [0, "down", 0]}, "bodies": [)" + body() + "]}"),
            "simulation.gravity[1]: got \"down\"; expected a number [m/s^2]");
  EXPECT_EQ(error_of(R"({"simulation": {"frames": 10.5}, "bodies": [)" + body() + "]}"),
            "simulation.frames: got 10.5; expected an integer >= 1 [-]");
  EXPECT_EQ(error_of(scene_with(body(R"({"constitutive": "Jelly"})"))).rfind(
                "bodies[0].material.constitutive: got \"Jelly\"; expected one of JFluid, FixedCorotated, NeoHookean, "
                "DruckerPrager, NACC",
                0),
            0u);
}

TEST(SceneParse, SyntaxErrorsGiveLineAndColumn) {
  const std::string e = error_of("{\n  \"simulation\": {\n    \"fps\": 24,,\n  }\n}");
  EXPECT_EQ(e.rfind("(string):3:15: got \",\"", 0), 0u) << e;  // the second comma of `    "fps": 24,,`
  EXPECT_NE(e.find("expected valid JSON"), std::string::npos) << e;
  // Comments and trailing commas are accepted.
  EXPECT_NO_THROW(parse("// a comment\n{\"bodies\": [" + body() + ",], /* block */}"));
}

TEST(SceneParse, UnknownKeySuggestsClosestKnownKey) {
  const std::string json = scene_with(body(R"({"constitutive": "FixedCorotated", "poison_ratio": 0.3})"));
  const std::string e = error_of(json);
  EXPECT_NE(e.find("bodies[0].material.poison_ratio: got unknown key \"poison_ratio\""), std::string::npos) << e;
  EXPECT_NE(e.find("did you mean \"poisson_ratio\"?"), std::string::npos) << e;
  // With allow_unknown_keys it is a warning; the misspelt value is not used, and the warning says so.
  std::vector<std::string> warnings;
  const Scene s = parse(json, true, &warnings, true);
  EXPECT_EQ(s.bodies[0].material.poisson_ratio, 0.2);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("poison_ratio: ignored"), std::string::npos) << warnings[0];
  // HydroUQ's spelling poissons_ratio is read as poisson_ratio (ClaymoreUW ignores it and uses 0.2), with a warning.
  warnings.clear();
  const Scene h = parse(scene_with(body(R"({"constitutive": "FixedCorotated", "poissons_ratio": 0.3})")), true, &warnings);
  EXPECT_EQ(h.bodies[0].material.poisson_ratio, 0.3);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("bodies[0].material.poissons_ratio: read as poisson_ratio = 0.3"), std::string::npos)
      << warnings[0];
  EXPECT_NE(error_of(scene_with(body(R"({"constitutive": "FixedCorotated", "poissons_ratio": 0.3, "poisson_ratio": 0.25})")))
                .find("bodies[0].material.poissons_ratio: got 0.3; expected the value of poisson_ratio (0.25)"),
            std::string::npos);
  // A misspelt required key is reported as such, not as the required key missing.
  EXPECT_EQ(error_of(scene_with(R"({"materials": {}, "geometry": [{"object": "Box"}]})")),
            "bodies[0].materials: got unknown key \"materials\"; expected a key of bodies[] (did you mean \"material\"?)");
  // Top level and simulation too.
  EXPECT_NE(error_of(R"({"simulaton": {}, "bodies": [)" + body() + "]}").find("did you mean \"simulation\"?"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"simulation": {"default_Dx": 0.1}, "bodies": [)" + body() + "]}").find(
                "did you mean \"default_dx\"?"),
            std::string::npos);
}

TEST(SceneParse, ClosestKeyAndLevenshtein) {
  EXPECT_EQ(levenshtein_distance("kitten", "sitting"), 3u);
  EXPECT_EQ(levenshtein_distance("", "abc"), 3u);
  EXPECT_EQ(levenshtein_distance("abc", "abc"), 0u);
  EXPECT_EQ(closest_key("poissons_ratio", {"youngs_modulus", "poisson_ratio", "rho"}), "poisson_ratio");
  EXPECT_EQ(closest_key("cfl", {"CFL", "rho"}), "CFL");                    // case-insensitive
  EXPECT_EQ(closest_key("completely_different", {"CFL", "rho"}), "");      // too far: no suggestion
}

TEST(SceneParse, ParametersTheLawDoesNotReadAreWarnings) {
  // ClaymoreUW silently ignores a Young's modulus given to a fluid (HydroUQ writes every field of its material form);
  // here it is ignored with a warning naming the law's keys, and a key of another object likewise.
  std::vector<std::string> warnings;
  const Scene s = parse(scene_with(body(R"({"constitutive": "JFluid", "youngs_modulus": 1e6})")), true, &warnings);
  EXPECT_EQ(s.bodies[0].material.youngs_modulus, 1e7);  // the default: not used by JFluid, not set
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("bodies[0].material.youngs_modulus: 1000000 is ignored (no youngs_modulus for constitutive "
                             "JFluid (it reads bulk_modulus, gamma, viscosity, tension_cutoff))"),
            std::string::npos)
      << warnings[0];
  warnings.clear();
  parse(scene_with(R"({"material": {}, "geometry": [{"object": "Box", "radius": 0.1}]})"), true, &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("no radius for object Box"), std::string::npos) << warnings[0];
  // An unknown key stays an error.
  EXPECT_NE(error_of(scene_with(body(R"({"constitutive": "JFluid", "youngs_modulu": 1e6})"))).find("unknown key"),
            std::string::npos);
}

TEST(SceneParse, AttributesAreCanonicalAndChecked) {
  const Scene s = parse(scene_with(body(R"({})", R"("output_attribs": ["DefGrad_Determinant", "pressure", "Mass"])")));
  EXPECT_EQ(s.bodies[0].output_attribs, (std::vector<std::string>{"J", "Pressure", "Mass"}));
  const std::string e = error_of(scene_with(body(R"({})", R"("output_attribs": ["ID", "Velocity_W"])")));
  EXPECT_NE(e.find("bodies[0].output_attribs[1]: got \"Velocity_W\""), std::string::npos) << e;
  EXPECT_NE(e.find("did you mean"), std::string::npos) << e;
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("output_attribs": ["J", "DefGrad_Determinant"])"))).find(
                "each attribute once"),
            std::string::npos);
}

TEST(SceneParse, ModelIdsAreAssignedInOrderPerGpu) {
  const Scene s = parse(scene_with(body() + "," + body(R"({})", R"("gpu": 1)") + "," + body() + "," +
                                   body(R"({})", R"("gpu": 1)")));
  EXPECT_EQ(s.bodies[0].model, 0);
  EXPECT_EQ(s.bodies[1].model, 0);
  EXPECT_EQ(s.bodies[2].model, 1);
  EXPECT_EQ(s.bodies[3].model, 1);
  // Explicit ids are kept; omitted ones fill the free ids in order.
  const Scene t = parse(scene_with(body(R"({})", R"("model": 1)") + "," + body()));
  EXPECT_EQ(t.bodies[0].model, 1);
  EXPECT_EQ(t.bodies[1].model, 0);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("model": 0)") + "," + body(R"({})", R"("model": 0)")))
                .find("bodies[1].model: got 0; expected a model id not used by another body on gpu 0 (bodies[0] has "
                      "model 0)"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("model": 2)"))).find("without gaps"), std::string::npos);
}

// bodies[].gpu "all" (spread over every GPU by space, comm/placement.h): its model id is taken on every GPU the scene
// names, because it writes model[m]_dev[d] on each.
TEST(SceneParse, GpuAllTakesItsModelIdOnEveryGpu) {
  const Scene s = parse(scene_with(body(R"({})", R"("gpu": 0)") + "," + body(R"({})", R"("gpu": 1)") + "," +
                                   body(R"({})", R"("gpu": "all")") + "," + body(R"({})", R"("gpu": 1)")));
  EXPECT_EQ(s.bodies[2].gpu, kAllGpus);
  EXPECT_EQ(s.bodies[0].model, 0);
  EXPECT_EQ(s.bodies[1].model, 0);
  EXPECT_EQ(s.bodies[2].model, 1);  // free on GPU 0 and on GPU 1
  EXPECT_EQ(s.bodies[3].model, 2);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("gpu": 1, "model": 0)") + "," +
                                body(R"({})", R"("gpu": "all", "model": 0)")))
                .find("bodies[1].model: got 0; expected a model id not used by another body on gpu 1 (bodies[0] has "
                      "model 0; a body on \"all\" GPUs takes its model id on every GPU)"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("gpu": "two")")))
                .find("bodies[0].gpu: got \"two\"; expected an integer >= 0 (the GPU that holds the whole body) or "
                      "\"all\""),
            std::string::npos);
}

TEST(SceneParse, CrossChecks) {
  EXPECT_NE(error_of(scene_with(body(), R"("boundaries": [{"object": "Walls", "domain_start": [0, 0, 0],
                                                          "domain_end": [1, 0, 1]}])"))
                .find("boundaries[0].domain_end[1]: got 0; expected a number > domain_start[1] (0): the box is empty"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("partition_start": [0.5, 0, 0], "partition_end": [0.4, 1, 1])")))
                .find("bodies[0].partition_end[0]: got 0.4; expected a number > partition_start[0] (0.5) [m]"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("algorithm": {"ASFLIP_beta_min": 0.5, "ASFLIP_beta_max": 0.1})")),
                     false)
                .find("bodies[0].algorithm.ASFLIP_beta_max: got 0.1; expected a number >= ASFLIP_beta_min (0.5)"),
            std::string::npos);
  // A cylinder needs its radius and a positive length along its axis.
  EXPECT_NE(error_of(scene_with(R"({"material": {}, "geometry": [{"object": "Cylinder", "axis": "Z"}]})"))
                .find("bodies[0].geometry[0].radius: got (missing)"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(R"({"material": {}, "geometry": [{"object": "Cylinder", "axis": "z", "radius": 0.1,
                                   "span": [0.2, 0.2, 0]}]})"))
                .find("bodies[0].geometry[0].span[2]: got 0; expected a number > 0 (the cylinder length along axis Z)"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(R"({"material": {}, "geometry": [{"object": "File", "file": "no/such/file.sdf"}]})"))
                .find("bodies[0].geometry[0].file: got \"no/such/file.sdf\"; expected an existing file"),
            std::string::npos);
}

// has_attributes: the names must set a particle's state, vectors and tensors whole, logJp only for a material that
// stores it, and a solid (.sdf) holds no values.
TEST(SceneParse, SeedAttributesAreChecked) {
  const std::string points = std::string(FBAR_SCENE_TEST_DIR) + "/data/points.csv";
  const auto with = [&](const std::string& attribs, const std::string& law = "JFluid",
                        const std::string& file = "") {
    return scene_with(R"({"material": {"constitutive": ")" + law + R"("}, "geometry": [{"object": "File", "file": ")" +
                      (file.empty() ? points : file) + R"(", "has_attributes": true, "input_attribs": )" + attribs +
                      "}]}");
  };
  EXPECT_NE(error_of(with(R"(["J", "Pressure"])"))
                .find("bodies[0].geometry[0].input_attribs[1]: got \"Pressure\"; expected an attribute that sets"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"(["Velocity_X", "Velocity_Y"])"))
                .find("bodies[0].geometry[0].input_attribs: got 2 of Velocity_X, Velocity_Y, Velocity_Z"),
            std::string::npos);
  EXPECT_NE(error_of(with(R"(["DefGrad_XX"])", "FixedCorotated")).find("all nine components"), std::string::npos);
  EXPECT_NE(error_of(with(R"(["logJp"])")).find("bodies[0].geometry[0].input_attribs[0]: got \"logJp\""),
            std::string::npos);
  EXPECT_NO_THROW(parse(with(R"(["logJp", "ID", "Mass"])", "DruckerPrager"), true));
  EXPECT_NE(error_of(with(R"(["J"])", "JFluid", std::string(FBAR_SCENE_TEST_DIR) + "/data/cube.sdf"))
                .find("bodies[0].geometry[0].has_attributes: got true"),
            std::string::npos);
}

// HydroUQ writes its wrapper keys at the top level: accepted as metadata, kept through the writer (run.json).
TEST(SceneParse, HydroUQWrapperKeysAreMetadata) {
  const Scene s = parse(R"({"Application": "MPM", "EventClassification": "Hydro", "type": "MPM", "subtype": "MPM",
                            "bodies": [{"material": {}, "geometry": [{"object": "Box"}]}]})");
  ASSERT_EQ(s.wrapper.size(), 4u);
  EXPECT_EQ(s.wrapper[0], (std::pair<std::string, std::string>{"Application", "MPM"}));
  EXPECT_EQ(s.wrapper[1], (std::pair<std::string, std::string>{"EventClassification", "Hydro"}));
  const std::string written = write_scene_json(s);
  EXPECT_NE(written.find("EventClassification"), std::string::npos) << written;
  EXPECT_NE(written.find("Hydro"), std::string::npos) << written;
  EXPECT_TRUE(parse(written) == s);
  EXPECT_NE(error_of(R"({"Application": 3, "bodies": [{"material": {}, "geometry": [{"object": "Box"}]}]})")
                .find("Application: got 3; expected a string (HydroUQ metadata)"),
            std::string::npos);
}

// The simulation keys HydroUQ writes (ClaymoreUW's loader reads none of them): each has a meaning, or an error or a
// warning that names it (user guide 2.1, difference 30).
// The values of ClaymoreUW's loader that fbar 0.1 refused (docs/claymore_compatibility.md): a boundary time in its
// three-element form, the grid-sensor operations addition / averages, a flat grid-sensor box (grown by one cell as
// ClaymoreUW grows it); refused with a reason: the CoupledUP grid channels in a scene without a CoupledUP body and the
// particle-sensor Subtract.
TEST(SceneParse, ClaymoreUWSensorAndBoundaryForms) {
  const std::string body = R"({"material": {"constitutive": "JFluid"}, "geometry": [{"object": "Box"}]})";
  std::vector<std::string> warnings;
  const Scene s = parse(scene_with(body, R"("boundaries": [{"object": "Walls", "contact": "Slip", "time": [0, 10, -1],
                                                           "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]},
                                                          {"object": "Walls", "contact": "Slip", "time": [1, 2, 5],
                                                           "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]}],
      "grid-sensors": [{"attribute": "Force", "operation": "addition", "domain_start": [0.1, 0.2, 0.1],
                        "domain_end": [0.3, 0.2, 0.4]},
                       {"attribute": "Mass", "operation": "Averages", "direction": "N/A",
                        "domain_start": [0.1, 0.2, 0.1], "domain_end": [0.3, 0.25, 0.4]}])"),
                        true, &warnings);
  ASSERT_EQ(s.boundaries.size(), 2u);
  EXPECT_EQ(s.boundaries[0].time[0], 0.0);
  EXPECT_EQ(s.boundaries[0].time[1], 10.0);
  EXPECT_EQ(s.boundaries[1].time[1], 2.0);
  ASSERT_EQ(warnings.size(), 1u);  // the third entry when it is not ClaymoreUW's -1
  EXPECT_NE(warnings[0].find("boundaries[1].time[2]: 5 is ignored"), std::string::npos) << warnings[0];
  ASSERT_EQ(s.grid_sensors.size(), 2u);
  EXPECT_EQ(s.grid_sensors[0].operation, SensorOperation::Sum);
  EXPECT_EQ(s.grid_sensors[1].operation, SensorOperation::Average);
  EXPECT_EQ(s.grid_sensors[0].domain_end[1], 0.2 + 0.05);  // flat in y: one cell (dx 0.05) thick
  EXPECT_EQ(s.grid_sensors[0].domain_end[0], 0.3);
  EXPECT_EQ(s.grid_sensors[1].domain_end[1], 0.25);
  EXPECT_NE(error_of(scene_with(body, R"("grid-sensors": [{"attribute": "masw", "direction": "N/A",
                                                          "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]}])"))
                .find("MassWater is the pore water of CoupledUP bodies, and the scene has none"),
            std::string::npos);
  const std::string soil = R"({"material": {"constitutive": "CoupledUP", "rho": 2000, "poro": 0.4, "Kf": 2.2e9,
                                            "Ks": 3.6e10, "Kperm": 1e-5}, "geometry": [{"object": "Box"}]})";
  const Scene saturated = parse(scene_with(soil, R"("grid-sensors": [{"attribute": "pore_pressure", "direction": "N/A",
                                                    "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]}])"));
  ASSERT_EQ(saturated.grid_sensors.size(), 1u);
  EXPECT_EQ(saturated.grid_sensors[0].attribute, "PorePressure");
  EXPECT_EQ(saturated.bodies[0].material.law, Constitutive::CoupledUP);
  EXPECT_EQ(saturated.bodies[0].material.rhow, 1000.0);   // ClaymoreUW's default
  EXPECT_EQ(saturated.bodies[0].material.alpha1, 1.0);    // ClaymoreUW's default
  EXPECT_NE(error_of(scene_with(body, R"("particle-sensors": [{"attribute": "Position_Y", "operation": "Subtract",
                                                              "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]}])"))
                .find("ClaymoreUW accepts Subtract and writes 0 for it"),
            std::string::npos);
  EXPECT_NE(error_of(scene_with(body, R"("boundaries": [{"object": "Walls", "time": [0, 1, 2, 3],
                                                         "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]}])"))
                .find("an array of 2 (or 3) numbers"),
            std::string::npos);
}

// ClaymoreUW's DKT scenes track particle 0 of every copy of a debris array: fbar takes local ID i as the i-th
// particle of copy 0 sampled alone, and finds the same point in each copy of the body (here 2 x 3 boxes).
TEST(SceneParse, GeometryTrackIdsFollowEveryArrayCopy) {
  const std::string json = R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05},
    "bodies": [{"material": {"constitutive": "FixedCorotated"}, "track_particle_id": [3],
                "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.2, 0.2, 0.2],
                              "array": [2, 3, 1], "spacing": [0.2, 0.15, 0], "track_particle_id": [0, 5]}]}]})";
  const Scene s = parse(json);
  const BodySpec& b = s.bodies[0];
  ASSERT_EQ(b.track_particle_id.size(), 1u + 2u * 6u);  // the body's own, then 2 local IDs x 6 copies
  EXPECT_EQ(b.track_particle_id[0], 3);
  EXPECT_TRUE(b.geometry[0].track_particle_id.empty());
  const std::vector<Vec3d> all = sample_body(b, s.simulation, 0);
  BodySpec one = b;
  one.geometry[0].array = Int3{1, 1, 1};
  const std::vector<Vec3d> copy0 = sample_body(one, s.simulation, 0);
  std::size_t k = 1;
  for (long long local : {0, 5})
    for (int a = 0; a < 2; ++a)
      for (int c = 0; c < 3; ++c) {
        const Vec3d expected = copy0[static_cast<std::size_t>(local)] + Vec3d{{0.2 * a, 0.15 * c, 0.0}};
        const Vec3d got = all[static_cast<std::size_t>(b.track_particle_id[k++])];
        for (int d = 0; d < 3; ++d) EXPECT_NEAR(got[d], expected[d], 1e-12) << "local " << local << " copy " << a << c;
      }
  // A local ID beyond one copy's particles names the count; a Subtract entry's IDs are the body's, with a warning.
  EXPECT_NE(error_of(R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05},
    "bodies": [{"material": {"constitutive": "FixedCorotated"},
                "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.2, 0.2, 0.2],
                              "array": [2, 1, 1], "spacing": [0.2, 0, 0], "track_particle_id": [64]}]}]})")
                .find("expected an ID below the 64 particles of one copy"),
            std::string::npos);
  std::vector<std::string> warnings;
  const Scene sub = parse(R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05},
    "bodies": [{"material": {"constitutive": "JFluid"},
                "geometry": [{"object": "Box", "span": [0.6, 0.3, 0.6], "offset": [0.1, 0.1, 0.1]},
                             {"object": "Sphere", "operation": "Subtract", "radius": 0.05, "offset": [0.2, 0.2, 0.2],
                              "array": [2, 1, 1], "spacing": [0.2, 0, 0], "track_particle_id": [7]}]}]})",
                          true, &warnings);
  EXPECT_EQ(sub.bodies[0].track_particle_id, (std::vector<long long>{7}));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("the entry adds no particles"), std::string::npos) << warnings[0];
}

// A rotated entry turns its whole array about the fulcrum: copy (a, b, c) lies R (a, b, c) x spacing from copy 0.
// At 90 degrees about z the shifted points are lattice points (exact); at 30 degrees the world lattice does not turn
// with the copies, and each copy's particle is the nearest, within half a lattice diagonal (sqrt(3)/2 x 0.025 m).
TEST(SceneParse, GeometryTrackIdsFollowARotatedArray) {
  for (const double angle : {90.0, 30.0}) {
    const std::string json = R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05},
      "bodies": [{"material": {"constitutive": "FixedCorotated"},
                  "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.5, 0.2, 0.3],
                                "rotate": [0, 0, )" + std::to_string(angle) + R"(], "fulcrum": [0.5, 0.2, 0.3],
                                "array": [3, 1, 1], "spacing": [0.2, 0, 0], "track_particle_id": [0, 21]}]}]})";
    const Scene s = parse(json);
    const BodySpec& b = s.bodies[0];
    ASSERT_EQ(b.track_particle_id.size(), 2u * 3u) << angle;
    const std::vector<Vec3d> all = sample_body(b, s.simulation, 0);
    BodySpec one = b;
    one.geometry[0].array = Int3{1, 1, 1};
    const std::vector<Vec3d> copy0 = sample_body(one, s.simulation, 0);
    const double c = std::cos(angle * M_PI / 180.0), sn = std::sin(angle * M_PI / 180.0);
    const double tolerance = angle == 90.0 ? 1e-12 : 0.5 * std::sqrt(3.0) * 0.025;
    std::size_t k = 0;
    for (long long local : {0, 21})
      for (int a = 0; a < 3; ++a) {
        const Vec3d expected = copy0[static_cast<std::size_t>(local)] + Vec3d{{0.2 * a * c, 0.2 * a * sn, 0.0}};
        const Vec3d got = all[static_cast<std::size_t>(b.track_particle_id[k++])];
        double d2 = 0;
        for (int d = 0; d < 3; ++d) d2 += (got[d] - expected[d]) * (got[d] - expected[d]);
        EXPECT_LE(std::sqrt(d2), tolerance) << "angle " << angle << " local " << local << " copy " << a;
      }
  }
}

TEST(SceneParse, HydroUQSimulationKeys) {
  auto scene = [](const std::string& sim) {
    return R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05, )" + sim +
           R"(}, "bodies": [{"material": {"constitutive": "JFluid"}, "geometry": [{"object": "Box"}]},
                            {"material": {"constitutive": "JFluid", "CFL": 0.7}, "geometry": [{"object": "Box"}]}]})";
  };
  std::vector<std::string> warnings;
  const Scene s = parse(scene(R"("time": 0.5, "initial_time": 0.5, "cfl": 0.4, "time_integration": "Explicit",
                                 "mirror_domain": [false, false, false], "fps": 10, "duration": 2.05,
                                 "use_froude_scaling": true, "froude_scaling": 1, "froude_time_ratio": 1,
                                 "use_cauchy_scaling": false, "cauchy_bulk_ratio": 1)"),
                        true, &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  EXPECT_EQ(s.simulation.time, 0.5);
  EXPECT_EQ(s.bodies[0].material.cfl, 0.4);  // simulation.cfl for a body that gives none
  EXPECT_EQ(s.bodies[1].material.cfl, 0.7);  // its own CFL wins
  EXPECT_EQ(s.simulation.frames, 21);        // duration without frames: ceil(2.05 s x 10 fps)
  EXPECT_EQ(s.simulation.cauchy_scaling, CauchyScaling::Off);

  // Warnings: a duration frames / fps contradicts, a Froude factor switched off, a time ratio Froude does not allow,
  // a Cauchy ratio without use_cauchy_scaling.
  warnings.clear();
  const Scene w = parse(scene(R"("fps": 10, "frames": 5, "duration": 2, "froude_scaling": 4, "use_froude_scaling": false,
                                 "froude_time_ratio": 3, "cauchy_bulk_ratio": 2)"),
                        true, &warnings);
  ASSERT_EQ(warnings.size(), 4u);
  EXPECT_NE(warnings[0].find("simulation.froude_scaling: 4 is not applied because simulation.use_froude_scaling is false"),
            std::string::npos) << warnings[0];
  EXPECT_NE(warnings[1].find("simulation.froude_time_ratio: 3 is not used"), std::string::npos) << warnings[1];
  EXPECT_NE(warnings[2].find("simulation.cauchy_bulk_ratio: 2 is not applied"), std::string::npos) << warnings[2];
  EXPECT_NE(warnings[3].find("simulation.duration: 2 s is not used: frames / fps = 5 / 10 = 0.5 s"), std::string::npos)
      << warnings[3];
  EXPECT_EQ(w.simulation.froude_scaling, 1.0);
  EXPECT_EQ(w.simulation.domain, (Real3{1, 1, 1}));
  EXPECT_EQ(w.simulation.frames, 5);

  // Errors name the key, the value and what fbar expects.
  EXPECT_NE(error_of(scene(R"("time_integration": "Implicit")"))
                .find(R"(simulation.time_integration: got "Implicit"; expected "Explicit")"),
            std::string::npos);
  EXPECT_NE(error_of(scene(R"("mirror_domain": [true, false, false])"))
                .find("simulation.mirror_domain: got [true,false,false]; expected false, or [false, false, false]: "
                      "mirrored domains are not implemented"),
            std::string::npos);
  EXPECT_NE(error_of(scene(R"("time": 0, "initial_time": 1)"))
                .find("simulation.initial_time: got 1; expected the value of simulation.time (0 s)"),
            std::string::npos);
  EXPECT_NE(error_of(scene(R"("cfl": 1.5)")).find("simulation.cfl: got 1.5"), std::string::npos);
  EXPECT_NE(error_of(scene(R"("cauchy_bulk_ratio": 0)")).find("simulation.cauchy_bulk_ratio: got 0; expected a number > 0"),
            std::string::npos);
}

// Cauchy similitude: with use_cauchy_scaling the materials' stresses and moduli scale by cauchy_bulk_ratio c (also
// at froude_scaling 1) and viscosities by c s^0.5; false keeps them as written (ClaymoreUW) while lengths still
// scale; absent, c = s (difference 14). The resolved scene reads back unchanged (applied once).
TEST(SceneParse, CauchyScalingScalesStressesByTheRatio) {
  auto scene = [](const std::string& sim) {
    return R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05, )" + sim +
           R"(}, "bodies": [{"material": {"constitutive": "JFluid", "bulk_modulus": 1e6, "viscosity": 0.01},
                             "geometry": [{"object": "Box"}]},
                            {"material": {"constitutive": "VonMises", "youngs_modulus": 1e7,
                                          "tensile_yield_strength": 1e5}, "geometry": [{"object": "Box"}]}]})";
  };
  const Scene on = parse(scene(R"("froude_scaling": 4, "use_cauchy_scaling": true, "cauchy_bulk_ratio": 2)"));
  EXPECT_EQ(on.bodies[0].material.bulk_modulus, 2e6);
  EXPECT_DOUBLE_EQ(on.bodies[0].material.viscosity, 0.01 * 2 * 2);  // c s^0.5
  EXPECT_EQ(on.bodies[1].material.youngs_modulus, 2e7);
  EXPECT_EQ(on.bodies[1].material.tensile_yield_strength, 2e5);
  EXPECT_EQ(on.simulation.domain, (Real3{4, 4, 4}));
  EXPECT_TRUE(parse(write_scene_json(on)) == on);

  const Scene at_one = parse(scene(R"("use_cauchy_scaling": true, "cauchy_bulk_ratio": 3)"));
  EXPECT_EQ(at_one.bodies[0].material.bulk_modulus, 3e6);
  EXPECT_EQ(at_one.simulation.domain, (Real3{1, 1, 1}));
  EXPECT_TRUE(at_one.simulation.froude_scaling_applied);
  EXPECT_TRUE(parse(write_scene_json(at_one)) == at_one);

  const Scene off = parse(scene(R"("froude_scaling": 4, "use_cauchy_scaling": false)"));
  EXPECT_EQ(off.bodies[0].material.bulk_modulus, 1e6);
  EXPECT_EQ(off.bodies[0].material.viscosity, 0.01);
  EXPECT_EQ(off.simulation.domain, (Real3{4, 4, 4}));
  EXPECT_TRUE(parse(write_scene_json(off)) == off);

  const Scene absent = parse(scene(R"("froude_scaling": 4)"));
  EXPECT_EQ(absent.bodies[0].material.bulk_modulus, 4e6);
  EXPECT_DOUBLE_EQ(absent.bodies[0].material.viscosity, 0.08);
}

// target_attribs (ClaymoreUW: what its particle sensors aggregate) is the attribute of sensors that give none; a
// sensor's own attribute wins, with a warning when the bodies' differs; more than one entry is an error.
TEST(SceneParse, TargetAttribsChooseTheParticleSensorsAttribute) {
  const std::string sensor = R"("particle-sensors": [{"domain_start": [0, 0, 0], "domain_end": [1, 1, 1]},
                                                     {"attribute": "Velocity_X", "domain_start": [0, 0, 0],
                                                      "domain_end": [1, 1, 1]}])";
  std::vector<std::string> warnings;
  const Scene s = parse(scene_with(body(R"({})", R"("target_attribs": ["Velocity_Y"])"), sensor), true, &warnings);
  EXPECT_EQ(s.particle_sensors[0].attribute, "Velocity_Y");
  EXPECT_EQ(s.particle_sensors[1].attribute, "Velocity_X");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("particle-sensors[1].attribute: Velocity_X is aggregated; the bodies' target_attribs "
                             "(Velocity_Y)"),
            std::string::npos)
      << warnings[0];
  EXPECT_NE(error_of(scene_with(body(R"({})", R"("target_attribs": ["Velocity_Y", "Position_Y"])"), sensor))
                .find("bodies[0].target_attribs: got 2 attributes; expected one attribute"),
            std::string::npos);
}

// grid-fields (fbar's): defaults (Mass, Velocity, Force at the frame rate), Froude scaling of the box and the rate,
// a round trip through the scene writer, and the errors naming the path.
TEST(SceneParse, GridFields) {
  const Scene s = parse(scene_with(body(), R"("grid-fields": [
      {"domain_start": [0.5, 0, 0], "domain_end": [0.6, 1, 1]},
      {"attributes": ["Volume", "J Bar", "BoundaryForce"], "output_frequency": 200, "blocks": true,
       "domain_start": [0, 0, 0], "domain_end": [1, 1, 1], "name": "tank", "toggle": false}])"));
  ASSERT_EQ(s.grid_fields.size(), 2u);
  EXPECT_EQ(s.grid_fields[0].attributes, (std::vector<std::string>{"Mass", "Velocity", "Force"}));
  EXPECT_EQ(s.grid_fields[0].output_frequency, s.simulation.fps);
  EXPECT_FALSE(s.grid_fields[0].blocks);
  EXPECT_EQ(s.grid_fields[1].attributes, (std::vector<std::string>{"Volume", "JBar", "BoundaryForce"}));
  EXPECT_EQ(s.grid_fields[1].output_frequency, 200.0);
  EXPECT_TRUE(s.grid_fields[1].blocks);
  EXPECT_FALSE(s.grid_fields[1].toggle);
  EXPECT_EQ(s.grid_fields[1].name, "tank");
  const Scene again = parse_scene_string(write_scene_json(s), ParseOptions{});
  EXPECT_TRUE(again.grid_fields == s.grid_fields) << write_scene_json(s);
  // Froude scaling (s = 4): the box x 4, the rate x 1/2.
  const Scene scaled = parse(R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05, "froude_scaling": 4},
      "bodies": [)" + body() + R"(], "grid-fields": [{"output_frequency": 100, "domain_start": [0.1, 0, 0],
      "domain_end": [0.2, 1, 1]}]})");
  EXPECT_EQ(scaled.grid_fields[0].domain_end[0], 0.8);
  EXPECT_EQ(scaled.grid_fields[0].output_frequency, 50.0);
  const auto field = [](const std::string& keys) {
    return scene_with(body(), R"("grid-fields": [{)" + keys + R"(, "domain_start": [0, 0, 0], "domain_end": [1, 1, 1]}])");
  };
  EXPECT_EQ(error_of(field(R"("attributes": [])")).rfind("grid-fields[0].attributes: got []; expected a non-empty array", 0), 0u);
  EXPECT_EQ(error_of(field(R"("attributes": ["Pressure"])")).rfind("grid-fields[0].attributes[0]: got \"Pressure\"", 0), 0u);
  EXPECT_EQ(error_of(field(R"("attributes": ["Mass", "Mass"])")).rfind("grid-fields[0].attributes[1]", 0), 0u);
  EXPECT_EQ(error_of(field(R"("output_frequency": 0)")).rfind("grid-fields[0].output_frequency: got 0", 0), 0u);
  EXPECT_EQ(error_of(field(R"("attributes": ["PorePressure"])")).rfind("grid-fields[0].attributes[0]: got \"PorePressure\"", 0), 0u);
  EXPECT_EQ(error_of(field(R"("bloks": true)")).rfind("grid-fields[0].bloks", 0), 0u);
}

// A boundary's rotation (fbar's angular_velocity, rotation_center): the centre defaults to the box's, both survive
// the scene writer, Froude scaling scales them as a frequency and a length, and a pump does not turn.
TEST(SceneParse, BoundaryRotation) {
  const Scene s = parse(scene_with(body(), R"("boundaries": [{"object": "Box", "contact": "Slip",
      "domain_start": [0.2, 0.2, 0.2], "domain_end": [0.4, 0.6, 0.4], "angular_velocity": [0, 0, 3]},
      {"object": "Cylinder", "domain_start": [0.6, 0, 0.6], "domain_end": [0.8, 0.5, 0.8],
       "angular_velocity": [0, 1, 0], "rotation_center": [0.7, 0, 0.7]}])"));
  ASSERT_EQ(s.boundaries.size(), 2u);
  EXPECT_EQ(s.boundaries[0].angular_velocity, (Real3{0.0, 0.0, 3.0}));
  EXPECT_EQ(s.boundaries[0].rotation_center, (Real3{0.30000000000000004, 0.4, 0.30000000000000004}));
  EXPECT_EQ(s.boundaries[1].rotation_center, (Real3{0.7, 0.0, 0.7}));
  const Scene again = parse_scene_string(write_scene_json(s), ParseOptions{});
  EXPECT_TRUE(again.boundaries == s.boundaries) << write_scene_json(s);
  const Scene scaled = parse(R"({"simulation": {"domain": [1, 1, 1], "default_dx": 0.05, "froude_scaling": 4},
      "bodies": [)" + body() + R"(], "boundaries": [{"object": "Box", "domain_start": [0.1, 0.1, 0.1],
      "domain_end": [0.2, 0.2, 0.2], "angular_velocity": [0, 0, 2], "rotation_center": [0.1, 0.1, 0.1]}]})");
  EXPECT_EQ(scaled.boundaries[0].angular_velocity[2], 1.0);
  EXPECT_EQ(scaled.boundaries[0].rotation_center[0], 0.4);
  EXPECT_EQ(error_of(scene_with(body(), R"("boundaries": [{"object": "Pump", "velocity": [1, 0, 0],
      "domain_start": [0, 0, 0], "domain_end": [1, 1, 1], "angular_velocity": [0, 1, 0]}])"))
                .rfind("boundaries[0].angular_velocity: got [0,1,0]", 0),
            0u);
}

TEST(SceneParse, ReleasePolicyRejectsWhatTheEngineCannotRun) {
  struct Case {
    std::string json;
    std::string path;
  };
  const std::vector<Case> cases = {
      {scene_with(body(R"({})", R"("algorithm": {"use_FEM": true})")), "bodies[0].algorithm.use_FEM"},
  };
  for (const Case& c : cases) {
    const std::string e = error_of(c.json);
    EXPECT_EQ(e.rfind(c.path + ": got", 0), 0u) << e;
    EXPECT_NE(e.find("is not supported yet in this release"), std::string::npos) << e;
    // The same scene is valid input: it parses with the policy switched off.
    EXPECT_NO_THROW(parse(c.json, false)) << c.json;
  }
  // An attribute fbar writes for other laws is an error that names the law (also the release's check: the scene
  // parses with it off).
  const std::string logjp = scene_with(body(R"({})", R"("output_attribs": ["logJp"])"));
  const std::string e = error_of(logjp);
  EXPECT_EQ(e.rfind("bodies[0].output_attribs[0]: got", 0), 0u) << e;
  EXPECT_NE(e.find("for JFluid (a JFluid body has no such quantity in its state)"), std::string::npos) << e;
  EXPECT_NO_THROW(parse(logjp, false)) << logjp;
  // Volume and JBar grid sensors run (the F-bar sums hold the nodes' volume on their sample steps).
  EXPECT_NO_THROW(parse(scene_with(body(), R"("grid-sensors": [{"attribute": "Volume", "domain_start": [0,0,0],
                                              "domain_end": [1,1,1]}, {"attribute": "J Bar", "direction": "N/A",
                                              "domain_start": [0,0,0], "domain_end": [1,1,1]}])")));
  // ASFLIP and F-bar switched on with zero ratios are APIC, which this release runs.
  EXPECT_NO_THROW(parse(scene_with(body(R"({})", R"("algorithm": {"use_ASFLIP": true, "use_FBAR": true})"))));
  EXPECT_NO_THROW(parse(scene_with(body(R"({"constitutive": "FixedCorotated"})"),
                                   R"("boundaries": [{"object": "Walls", "contact": "Sticky", "time": [0, 1],
                                      "domain_start": [0,0,0], "domain_end": [1,1,1]}])")));
}

// Froude similitude with s = 4: lengths x4, times and velocities x2, frequencies /2, moduli x4, viscosity x8,
// density, gravity, angles and dimensionless numbers unchanged. Each scaled value is one multiplication by an
// exactly representable factor (4, 2, 0.5, 8), so it is the correctly rounded product: compared with
// EXPECT_DOUBLE_EQ against the product written out.
// Trackers: ClaymoreUW's two spellings (track_particle_id / track_attribs, and the trackers object), not both; an
// attribute the body's material lacks and too many IDs are errors naming the key.
TEST(SceneParse, TrackersInEitherSpelling) {
  const Scene a = parse(scene_with(body(R"({})", R"("track_particle_id": [3, 1], "track_attribs": ["Velocity_X"])")));
  const Scene b = parse(scene_with(body(R"({})", R"("trackers": {"ids": [3, 1], "attribs": ["Velocity_X"]})")));
  EXPECT_EQ(a.bodies[0].track_particle_id, (std::vector<long long>{3, 1}));
  EXPECT_EQ(b.bodies[0].track_particle_id, a.bodies[0].track_particle_id);
  EXPECT_EQ(b.bodies[0].track_attribs, a.bodies[0].track_attribs);
  // Both spellings (ClaymoreUW's scene.json has both, different): the newer trackers wins, with a warning.
  std::vector<std::string> warnings;
  const Scene both = parse(scene_with(body(R"({})", R"("track_particle_id": [1], "trackers": {"ids": [2]})")), true,
                           &warnings);
  EXPECT_EQ(both.bodies[0].track_particle_id, (std::vector<long long>{2}));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("bodies[0].track_particle_id: ignored: bodies[0].trackers.ids"), std::string::npos)
      << warnings[0];
  // The same for output.attribs and output_attribs.
  warnings.clear();
  const Scene out = parse(scene_with(body(R"({})", R"("output_attribs": ["Pressure"], "output": {"attribs": ["J"]})")),
                          true, &warnings);
  EXPECT_EQ(out.bodies[0].output_attribs, (std::vector<std::string>{"J"}));
  ASSERT_EQ(warnings.size(), 1u);
  // A geometry entry's IDs (without array copies) join the body's, as in ClaymoreUW.
  const Scene geo = parse(scene_with(R"({"material": {}, "track_particle_id": [3],
                                         "geometry": [{"object": "Box", "track_particle_id": [0, 3]}]})"));
  EXPECT_EQ(geo.bodies[0].track_particle_id, (std::vector<long long>{3, 0}));
  EXPECT_TRUE(geo.bodies[0].geometry[0].track_particle_id.empty());
  EXPECT_EQ(error_of(scene_with(body(R"({})", R"("track_particle_id": [1], "track_attribs": ["DefGrad_XX"])")))
                .rfind("bodies[0].track_attribs[0]", 0),
            0u);  // JFluid stores no F
  std::string many = "[";
  for (int i = 0; i < 65; ++i) many += (i ? "," : "") + std::to_string(i);
  EXPECT_EQ(error_of(scene_with(body(R"({})", R"("track_particle_id": )" + many + "]"))).rfind("bodies[0].track_particle_id", 0),
            0u);
  EXPECT_EQ(error_of(scene_with(body(R"({})", R"("track_attribs": ["J"])"))).rfind("bodies[0].track_attribs", 0), 0u);
}

// ClaymoreUW's output object: attribs (its newer name of output_attribs), exterior_only and exterior_threshold.
TEST(SceneParse, OutputObjectAttribsAndExterior) {
  const Scene s = parse(scene_with(body(R"({})", R"("output": {"attribs": ["ID", "Pressure"], "exterior_threshold": 0.5})")));
  EXPECT_EQ(s.bodies[0].output_attribs, (std::vector<std::string>{"ID", "Pressure"}));
  EXPECT_EQ(s.bodies[0].exterior_threshold, 0.5);
  std::vector<std::string> warnings;  // both, different: the newer output.attribs is written, with a warning
  const Scene both =
      parse(scene_with(body(R"({})", R"("output_attribs": ["ID"], "output": {"attribs": ["Mass"]})")), true, &warnings);
  EXPECT_EQ(both.bodies[0].output_attribs, (std::vector<std::string>{"Mass"}));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("bodies[0].output_attribs: ignored: bodies[0].output.attribs (ClaymoreUW's newer key)"),
            std::string::npos)
      << warnings[0];
  const Scene ext = parse(scene_with(body(R"({})", R"("output": {"exterior_only": true})")));
  EXPECT_TRUE(ext.bodies[0].output_exterior_only);
  EXPECT_EQ(ext.bodies[0].exterior_threshold, 128.0);  // ClaymoreUW's cutoff
  const std::string negative = error_of(scene_with(body(R"({})", R"("output": {"exterior_threshold": -1})")));
  EXPECT_EQ(negative.rfind("bodies[0].output.exterior_threshold: got -1", 0), 0u) << negative;
}

TEST(SceneParse, FroudeScalingScalesEveryQuantityByItsExponent) {
  const std::string json = R"({
    "simulation": {"domain": [2, 1, 0.5], "default_dx": 0.05, "default_dt": 1e-3, "time": 1.5, "fps": 60,
                   "frames": 10, "gravity": [0, -9.81, 0], "froude_scaling": 4},
    "bodies": [
      {"velocity": [1, -0.5, 0], "partition_start": [0.1, 0, 0], "partition_end": [1.9, 1, 0.5],
       "material": {"constitutive": "JFluid", "rho": 1000, "bulk_modulus": 2e6, "gamma": 7.1, "viscosity": 1e-3,
                    "CFL": 0.4},
       "geometry": [{"object": "Box", "span": [0.25, 0.5, 0.2], "offset": [0.1, 0.1, 0.1], "rotate": [0, 0, 30],
                     "fulcrum": [0.2, 0.3, 0.2], "array": [2, 1, 1], "spacing": [0.5, 0, 0]},
                    {"object": "Sphere", "operation": "Subtract", "radius": 0.05, "offset": [0.1, 0.1, 0.1]},
                    {"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [1, 0.1, 0.1],
                     "use_froude_scaling": false}]},
      {"material": {"constitutive": "FixedCorotated", "youngs_modulus": 1e6, "poisson_ratio": 0.3},
       "geometry": [{"object": "Cylinder", "radius": 0.1, "axis": "Y", "span": [0.2, 0.3, 0.2],
                     "offset": [1.2, 0.1, 0.1]}]}],
    "boundaries": [{"object": "Walls", "domain_start": [0.05, 0.05, 0.05], "domain_end": [1.95, 0.95, 0.45],
                    "time": [0.5, 2]}],
    "grid-sensors": [{"attribute": "Force", "direction": "X+", "output_frequency": 120,
                      "domain_start": [1, 0, 0], "domain_end": [1.1, 1, 0.5]}],
    "particle-sensors": [{"attribute": "Position_Y", "operation": "Max", "output_frequency": 30,
                          "domain_start": [1, 0, 0], "domain_end": [1.1, 1, 0.5]}]
  })";
  const Scene s = parse(json, false);
  const SimulationSpec& sim = s.simulation;
  EXPECT_TRUE(sim.froude_scaling_applied);
  EXPECT_EQ(sim.froude_scaling, 4.0);
  EXPECT_DOUBLE_EQ(sim.domain[0], 2 * 4.0);
  EXPECT_DOUBLE_EQ(sim.domain[2], 0.5 * 4.0);
  EXPECT_DOUBLE_EQ(sim.dx, 0.05 * 4.0);
  EXPECT_DOUBLE_EQ(sim.default_dt, 1e-3 * 2.0);
  EXPECT_DOUBLE_EQ(sim.time, 1.5 * 2.0);
  EXPECT_DOUBLE_EQ(sim.fps, 60 * 0.5);
  EXPECT_EQ(sim.frames, 10);  // duration frames / fps scales with the time factor through fps
  EXPECT_EQ(sim.gravity, (Real3{0, -9.81, 0}));

  const BodySpec& fluid = s.bodies[0];
  EXPECT_DOUBLE_EQ(fluid.velocity[0], 1 * 2.0);
  EXPECT_DOUBLE_EQ(fluid.velocity[1], -0.5 * 2.0);
  EXPECT_DOUBLE_EQ(fluid.partition_start[0], 0.1 * 4.0);
  EXPECT_DOUBLE_EQ(fluid.partition_end[0], 1.9 * 4.0);
  EXPECT_DOUBLE_EQ(fluid.material.bulk_modulus, 2e6 * 4.0);
  EXPECT_DOUBLE_EQ(fluid.material.viscosity, 1e-3 * 8.0);
  EXPECT_EQ(fluid.material.rho, 1000.0);
  EXPECT_EQ(fluid.material.gamma, 7.1);
  EXPECT_EQ(fluid.material.cfl, 0.4);
  const GeometrySpec& box = fluid.geometry[0];
  EXPECT_DOUBLE_EQ(box.span[1], 0.5 * 4.0);
  EXPECT_DOUBLE_EQ(box.offset[0], 0.1 * 4.0);
  EXPECT_DOUBLE_EQ(box.fulcrum[1], 0.3 * 4.0);
  EXPECT_DOUBLE_EQ(box.spacing[0], 0.5 * 4.0);
  EXPECT_EQ(box.rotate, (Real3{0, 0, 30}));
  EXPECT_EQ(box.array, (Int3{2, 1, 1}));
  EXPECT_DOUBLE_EQ(fluid.geometry[1].radius, 0.05 * 4.0);
  EXPECT_EQ(fluid.geometry[2].span, (Real3{0.1, 0.1, 0.1}));  // use_froude_scaling false: as written
  EXPECT_EQ(fluid.geometry[2].offset, (Real3{1, 0.1, 0.1}));

  const BodySpec& solid = s.bodies[1];
  EXPECT_DOUBLE_EQ(solid.material.youngs_modulus, 1e6 * 4.0);
  EXPECT_EQ(solid.material.poisson_ratio, 0.3);
  EXPECT_DOUBLE_EQ(solid.geometry[0].radius, 0.1 * 4.0);
  EXPECT_DOUBLE_EQ(solid.geometry[0].span[1], 0.3 * 4.0);
  EXPECT_EQ(solid.partition_end, (Real3{kInf, kInf, kInf}));  // open bounds stay open

  const BoundarySpec& walls = s.boundaries[0];
  EXPECT_DOUBLE_EQ(walls.domain_end[0], 1.95 * 4.0);
  EXPECT_DOUBLE_EQ(walls.time[0], 0.5 * 2.0);
  EXPECT_DOUBLE_EQ(walls.time[1], 2 * 2.0);
  EXPECT_DOUBLE_EQ(s.grid_sensors[0].output_frequency, 120 * 0.5);
  EXPECT_DOUBLE_EQ(s.grid_sensors[0].domain_end[0], 1.1 * 4.0);
  EXPECT_DOUBLE_EQ(s.particle_sensors[0].output_frequency, 30 * 0.5);

  // Similitude check: the Froude number of the fluid's p-wave speed, c / sqrt(g dx), is unchanged, since
  // c = sqrt(K / rho) scales by sqrt(4) and sqrt(g dx) by sqrt(4). Tolerance: a few ulps of the square roots.
  const Scene unscaled = parse(std::string(json).replace(json.find("\"froude_scaling\": 4"), 19, "\"froude_scaling\": 1"),
                               false);
  auto froude = [](const Scene& sc) {
    const MaterialSpec& m = sc.bodies[0].material;
    return std::sqrt(m.bulk_modulus / m.rho) / std::sqrt(9.81 * sc.simulation.dx);
  };
  EXPECT_NEAR(froude(s), froude(unscaled), 1e-12 * froude(unscaled));
  // The default step follows the scaled grid: dx / 100.
  const Scene no_dt = parse(R"({"simulation": {"default_dx": 0.05, "froude_scaling": 9}, "bodies": [)" + body() + "]}");
  EXPECT_DOUBLE_EQ(no_dt.simulation.default_dt, 0.05 * 9 / 100);
}

TEST(SceneParse, FroudeScalingIsAppliedOnce) {
  Scene s = parse(R"({"simulation": {"default_dx": 0.05, "froude_scaling": 4}, "bodies": [)" + body() + "]}");
  const double dx = s.simulation.dx;
  apply_froude_scaling(s);  // already applied: no-op
  EXPECT_EQ(s.simulation.dx, dx);
}

// bodies[].initial_state and JFluid's tension_cutoff (fbar's keys): read, defaults, and errors naming the key.
TEST(SceneParse, InitialStateAndTensionCutoff) {
  const Scene rest = parse(scene_with(body()));
  EXPECT_EQ(rest.bodies[0].initial_state, InitialState::Rest);
  EXPECT_TRUE(std::isinf(rest.bodies[0].material.tension_cutoff));
  const Scene h = parse(scene_with(body(R"({"constitutive": "JFluid", "tension_cutoff": 0})",
                                        R"("initial_state": "hydrostatic")")));
  EXPECT_EQ(h.bodies[0].initial_state, InitialState::Hydrostatic);
  EXPECT_EQ(h.bodies[0].material.tension_cutoff, 0.0);
  const std::string solid = error_of(scene_with(body(R"({"constitutive": "FixedCorotated"})",
                                                     R"("initial_state": "hydrostatic")")));
  EXPECT_NE(solid.find("bodies[0].initial_state"), std::string::npos) << solid;
  EXPECT_NE(solid.find("FixedCorotated"), std::string::npos) << solid;
  const std::string word = error_of(scene_with(body(R"({"constitutive": "JFluid"})", R"("initial_state": "still")")));
  EXPECT_NE(word.find("bodies[0].initial_state"), std::string::npos) << word;
  EXPECT_NE(word.find("hydrostatic"), std::string::npos) << word;
  const std::string negative = error_of(scene_with(body(R"({"constitutive": "JFluid", "tension_cutoff": -5})")));
  EXPECT_NE(negative.find("bodies[0].material.tension_cutoff"), std::string::npos) << negative;
  EXPECT_NE(negative.find("Pa"), std::string::npos) << negative;
}

}  // namespace
}  // namespace fbar
