// Sweep files (Projects/FBAR/scene/sweep.h): designs expanded into cases, values written at their paths, sampled
// designs stratified and repeatable, and every mistake named by its JSON path.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "scene/scene_parse.h"
#include "scene/sweep.h"

namespace fbar {
namespace {

/// A base scene small enough to parse quickly: one water box in walls.
const char* kBase = R"({
  "simulation": {"domain": [0.4, 0.4, 0.4], "default_dx": 0.05, "default_dt": 1e-3, "fps": 100, "frames": 2,
                 "save_path": "./out", "save_suffix": ".csv"},
  "bodies": [{"material": {"constitutive": "JFluid", "ppc": 8, "CFL": 0.5, "rho": 1000, "bulk_modulus": 2e5,
                           "gamma": 7.1, "viscosity": 0.001},
              "algorithm": {"use_ASFLIP": false, "use_FBAR": false},
              "geometry": [{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.15, 0.1, 0.15]}]}],
  "boundaries": [{"object": "Walls", "contact": "Separable", "domain_start": [0.05, 0.05, 0.05],
                  "domain_end": [0.35, 0.35, 0.35]}]
})";

std::string sweep_text(const std::string& rest) { return std::string("{\"scene\": ") + kBase + ", " + rest + "}"; }

Sweep parse(const std::string& rest) { return parse_sweep_string(sweep_text(rest), ".", "test.sweep.json"); }

/// The SceneError message of parsing `rest`, or "" when it parses.
std::string error_of(const std::string& rest) {
  try {
    (void)parse(rest);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

// Factorial: every combination, the first parameter varying slowest; a range's ends are its values; the values land
// at their paths in the case's scene, which parses to them.
TEST(Sweep, FactorialCoversEveryCombinationInOrder) {
  const Sweep s = parse(R"("parameters": [
      {"name": "rho", "path": "bodies[0].material.rho", "values": [900, 1000, 1100]},
      {"name": "x", "path": "bodies[0].geometry[0].offset[0]", "range": [0.1, 0.2], "count": 2}])");
  ASSERT_EQ(s.cases.size(), 6u);
  const double rho[] = {900, 900, 1000, 1000, 1100, 1100}, x[] = {0.1, 0.2, 0.1, 0.2, 0.1, 0.2};
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(s.cases[k].id, static_cast<int>(k));
    EXPECT_EQ(s.cases[k].numbers[0], rho[k]) << k;
    EXPECT_DOUBLE_EQ(s.cases[k].numbers[1], x[k]) << k;
    const Scene scene = sweep_case_scene(s, s.cases[k], "out/case", ParseOptions{});
    EXPECT_EQ(scene.bodies[0].material.rho, rho[k]) << k;
    EXPECT_DOUBLE_EQ(scene.bodies[0].geometry[0].offset[0], x[k]) << k;
    EXPECT_EQ(scene.simulation.save_path, "out/case");
  }
  EXPECT_EQ(sweep_case_label(s, s.cases[3]), "rho=1000, x=0.2");
  EXPECT_EQ(sweep_case_folder(3), "case_0003");
}

// A whole JSON value (an array of geometry entries) is a choice; tables show its label and its index.
TEST(Sweep, ChoicesOfWholeValuesCarryLabels) {
  const Sweep s = parse(R"("parameters": [{"name": "shape", "path": "bodies[0].geometry", "labels": ["box", "sphere"],
      "values": [[{"object": "Box", "span": [0.1, 0.1, 0.1], "offset": [0.15, 0.1, 0.15]}],
                 [{"object": "Sphere", "radius": 0.05, "offset": [0.2, 0.15, 0.2]}]]}])");
  ASSERT_EQ(s.cases.size(), 2u);
  EXPECT_EQ(s.cases[1].labels[0], "sphere");
  EXPECT_EQ(s.cases[1].numbers[0], 1.0);
  const Scene scene = sweep_case_scene(s, s.cases[1], "o", ParseOptions{});
  ASSERT_EQ(scene.bodies[0].geometry.size(), 1u);
  EXPECT_EQ(scene.bodies[0].geometry[0].radius, 0.05);
}

// A key the scene leaves out (a default) may be the path's last step.
TEST(Sweep, PathMayEndInAKeyTheSceneOmits) {
  const Sweep s = parse(R"("parameters": [{"name": "cfl", "path": "simulation.cfl", "values": [0.3]}])");
  const std::string text = sweep_case_scene_json(s, s.cases[0], "o");
  EXPECT_NE(text.find("\"cfl\": 0.3"), std::string::npos) << text;
}

// Latin hypercube: n samples put exactly one value in each of the n equal strata of every parameter's range (the
// design's defining property), the same seed gives the same cases and another seed others; log_uniform strata are
// equal in log, a choice's strata map onto its values in equal shares.
TEST(Sweep, LatinHypercubeStratifiesEveryParameter) {
  const std::string rest = R"("design": "latin_hypercube", "samples": 40, "seed": 7, "parameters": [
      {"name": "mu", "path": "boundaries[0].friction_static", "uniform": [0.1, 0.5]},
      {"name": "E", "path": "bodies[0].material.bulk_modulus", "log_uniform": [1e5, 1e7]},
      {"name": "rho", "path": "bodies[0].material.rho", "values": [900, 1000, 1100, 1200]}])";
  const Sweep s = parse(rest);
  ASSERT_EQ(s.cases.size(), 40u);
  std::set<int> mu_strata, e_strata;
  int rho_count[4] = {0, 0, 0, 0};
  for (const SweepCase& c : s.cases) {
    const double mu = c.numbers[0], e = c.numbers[1];
    ASSERT_GE(mu, 0.1);
    ASSERT_LT(mu, 0.5);
    mu_strata.insert(static_cast<int>(std::floor((mu - 0.1) / 0.4 * 40)));
    e_strata.insert(static_cast<int>(std::floor((std::log10(e) - 5.0) / 2.0 * 40)));
    ++rho_count[static_cast<int>(c.numbers[2] / 100.0 + 0.5) - 9];
  }
  EXPECT_EQ(mu_strata.size(), 40u);
  EXPECT_EQ(e_strata.size(), 40u);
  // The strata are paired at random: the rank correlation of two parameters is near 0 (its spread for 40 random
  // pairs is 1 / sqrt(39) = 0.16; strata paired in order would give 1).
  std::vector<std::pair<double, double>> pairs;
  for (const SweepCase& c : s.cases) pairs.emplace_back(c.numbers[0], c.numbers[1]);
  std::vector<double> rank_mu(40), rank_e(40);
  for (std::size_t i = 0; i < 40; ++i)
    for (std::size_t j = 0; j < 40; ++j) {
      rank_mu[i] += pairs[j].first < pairs[i].first;
      rank_e[i] += pairs[j].second < pairs[i].second;
    }
  double d2 = 0.0;
  for (std::size_t i = 0; i < 40; ++i) d2 += (rank_mu[i] - rank_e[i]) * (rank_mu[i] - rank_e[i]);
  const double spearman = 1.0 - 6.0 * d2 / (40.0 * (40.0 * 40.0 - 1.0));
  EXPECT_LT(std::fabs(spearman), 0.5) << spearman;
  for (int n : rho_count) EXPECT_EQ(n, 10);
  const Sweep again = parse(rest);
  for (std::size_t k = 0; k < 40; ++k) EXPECT_EQ(again.cases[k].json, s.cases[k].json) << k;
  std::string other = rest;
  other.replace(other.find("\"seed\": 7"), 9, "\"seed\": 8");
  EXPECT_NE(parse(other).cases[0].json, s.cases[0].json);
}

// Normal parameters: the quantile function against tabulated values of the standard normal distribution.
TEST(Sweep, NormalQuantileMatchesTables) {
  EXPECT_NEAR(normal_quantile(0.5), 0.0, 1e-15);
  EXPECT_NEAR(normal_quantile(0.975), 1.959963984540054, 1e-12);
  EXPECT_NEAR(normal_quantile(0.8413447460685429), 1.0, 1e-12);
  EXPECT_NEAR(normal_quantile(1e-10), -6.361340902404056, 1e-9);
  EXPECT_NEAR(normal_quantile(0.025), -1.959963984540054, 1e-12);
  const Sweep s = parse(R"("design": "latin_hypercube", "samples": 1000, "seed": 1,
      "parameters": [{"name": "rho", "path": "bodies[0].material.rho", "normal": [1000, 20]}])");
  double mean = 0.0;
  for (const SweepCase& c : s.cases) mean += c.numbers[0] / 1000.0;
  EXPECT_NEAR(mean, 1000.0, 0.5);  // a stratified sample's mean: far within 20 / sqrt(1000) = 0.63 of the truth
}

// Given cases: each names every parameter; a value equal to a listed one takes its label; integer rounds samples.
TEST(Sweep, GivenCasesAndIntegers) {
  const Sweep s = parse(R"("design": "cases", "parameters": [
      {"name": "rho", "path": "bodies[0].material.rho", "values": [1000, 1025], "labels": ["fresh", "sea"]},
      {"name": "ppc", "path": "bodies[0].material.ppc"}],
      "cases": [{"rho": 1025, "ppc": 8}, {"rho": 990, "ppc": 27}])");
  ASSERT_EQ(s.cases.size(), 2u);
  EXPECT_EQ(s.cases[0].labels[0], "sea");
  EXPECT_EQ(s.cases[1].labels[0], "990");
  const Sweep i = parse(R"("design": "latin_hypercube", "samples": 5, "parameters": [
      {"name": "ppc", "path": "bodies[0].material.ppc", "uniform": [1, 27], "integer": true}])");
  for (const SweepCase& c : i.cases) {
    EXPECT_EQ(c.numbers[0], std::round(c.numbers[0]));
    EXPECT_EQ(c.json[0].find('.'), std::string::npos) << c.json[0];
  }
}

// Mistakes: each names the sweep file's JSON path (or the case and the scene's path), the value and what was expected.
TEST(Sweep, MistakesNameTheirPath) {
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[3].material.rho", "values": [1]}])")
                .find("parameters[0].path: got \"bodies[3].material.rho\"; expected a path that leads through the scene "
                      "(sweep case 0 (x=1): bodies has 1 entries (index 3 is past its end))"),
            std::string::npos)
      << error_of(R"("parameters": [{"name": "x", "path": "bodies[3].material.rho", "values": [1]}])");
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[0].materal.rho", "values": [1]}])")
                .find("bodies[0] has no key \"materal\""),
            std::string::npos);
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[0].material.rho", "valeus": [1]}])")
                .find("parameters[0].valeus: got unknown key \"valeus\"; expected a key of parameters[0] (did you mean "
                      "\"values\"?)"),
            std::string::npos);
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[0].material.rho", "uniform": [1, 2]}])")
                .find("for design \"factorial\""),
            std::string::npos);
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[0].material.rho", "range": [1, 2]}])")
                .find("parameters[0].count: got nothing"),
            std::string::npos);
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[0].material.rho", "range": [2, 1], "count": 2}])")
                .find("parameters[0].range: got [2,1]; expected an array of two numbers [low, high] with low <= high"),
            std::string::npos);
  EXPECT_NE(error_of(R"("design": "latin_hypercube", "parameters": [{"name": "x", "path": "a", "uniform": [1, 2]}])")
                .find("samples: got nothing"),
            std::string::npos);
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "bodies[0].material.rho", "values": [1]},
                                       {"name": "x", "path": "simulation.fps", "values": [1]}])")
                .find("parameters[1].name: got \"x\"; expected a name no other parameter has"),
            std::string::npos);
  EXPECT_NE(error_of(R"("design": "cases", "parameters": [{"name": "x", "path": "simulation.fps"}],
                        "cases": [{"y": 3}])")
                .find("cases[0].y: got unknown key \"y\""),
            std::string::npos);
  EXPECT_NE(error_of(R"("parameters": [{"name": "x", "path": "simulation..fps", "values": [1]}])")
                .find("parameters[0].path: got \"simulation..fps\"; expected a JSON path"),
            std::string::npos);
  // A value the scene refuses: the case, its values and the scene's own message.
  const Sweep s = parse(R"("parameters": [{"name": "rho", "path": "bodies[0].material.rho", "values": [1000, -5]}])");
  try {
    (void)sweep_case_scene(s, s.cases[1], "o", ParseOptions{});
    FAIL() << "rho = -5 was accepted";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("sweep case 1 (rho=-5): bodies[0].material.rho: got -5", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace fbar
