// The worked example of docs/developer_guide.md, "Adding a material": the guide's code is the tree's code, its JSON
// scene parses and runs, and the example law (materials/hencky.cuh) passes the tests every law needs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "physics/constitutive_models.cuh"
#include "engine/cpu/cpu_engine.h"
#include "physics_test_support.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

using test::kEps;

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Fenced blocks of one language in the section of `markdown` that starts with `heading` (up to the next "## ").
std::vector<std::string> fenced_blocks(const std::string& markdown, const std::string& heading,
                                       const std::string& language) {
  std::vector<std::string> blocks;
  const std::size_t start = markdown.find(heading);
  if (start == std::string::npos) return blocks;
  const std::size_t end = markdown.find("\n## ", start + heading.size());
  const std::string section = markdown.substr(start, end == std::string::npos ? std::string::npos : end - start);
  const std::string open = "```" + language + "\n";
  std::size_t at = 0;
  while ((at = section.find(open, at)) != std::string::npos) {
    const std::size_t body = at + open.size();
    const std::size_t close = section.find("\n```", body);
    if (close == std::string::npos) break;
    blocks.push_back(section.substr(body, close - body + 1));
    at = close + 4;
  }
  return blocks;
}

const std::string kSource = FBAR_SOURCE_DIR;

TEST(MaterialGuide, EveryCodeBlockIsTheTreesCode) {
  const std::string guide = read_text(kSource + "/docs/developer_guide.md");
  ASSERT_FALSE(guide.empty()) << "docs/developer_guide.md not found under " << kSource;
  const std::vector<std::string> blocks = fenced_blocks(guide, "## Adding a material", "cpp");
  ASSERT_GE(blocks.size(), 5u) << "the guide's worked example lost its code";
  const std::vector<std::string> sources = {read_text(kSource + "/Projects/FBAR/physics/materials/hencky.cuh"),
                                            read_text(kSource + "/Projects/FBAR/physics/material_spec.h"),
                                            read_text(kSource + "/Projects/FBAR/physics/constitutive_models.cuh")};
  for (const std::string& block : blocks) {
    const bool found = std::any_of(sources.begin(), sources.end(),
                                   [&](const std::string& s) { return s.find(block) != std::string::npos; });
    EXPECT_TRUE(found) << "this block of the guide is not in materials/hencky.cuh, material_spec.h or "
                          "constitutive_models.cuh:\n"
                       << block;
  }
  // The guide's include line names the header.
  EXPECT_NE(guide.find("#include \"physics/materials/hencky.cuh\""), std::string::npos);
  EXPECT_NE(sources[2].find("#include \"physics/materials/hencky.cuh\""), std::string::npos);
}

TEST(MaterialGuide, JsonSceneParsesAndRunsOnTheCpuEngine) {
  const std::string guide = read_text(kSource + "/docs/developer_guide.md");
  const std::vector<std::string> scenes = fenced_blocks(guide, "## Adding a material", "json");
  ASSERT_EQ(scenes.size(), 1u);
  const Scene scene = parse_scene_string(scenes[0], ParseOptions{});
  ASSERT_EQ(scene.bodies.size(), 1u);
  const MaterialSpec& m = scene.bodies[0].material;
  EXPECT_EQ(m.law, Constitutive::Hencky);
  EXPECT_EQ(m.youngs_modulus, 1e5);
  EXPECT_EQ(m.poisson_ratio, 0.3);
  // The alias and the range check come from the type.
  std::string alias = scenes[0];
  alias.replace(alias.find("\"Hencky\""), 8, "\"HenckyElastic\"");
  EXPECT_EQ(parse_scene_string(alias, ParseOptions{}).bodies[0].material.law, Constitutive::Hencky);
  std::string bad = scenes[0];
  bad.replace(bad.find("0.3}"), 3, "0.5");
  try {
    parse_scene_string(bad, ParseOptions{});
    ADD_FAILURE() << "poisson_ratio 0.5 was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("bodies[0].material.poisson_ratio"), std::string::npos) << e.what();
  }
  // The block falls 0.02 s from rest (20 steps of 1 ms, CFL 0.23 at c_p = 11.6 m/s): symplectic Euler moves it by
  // exactly g t^2 / 2 + g t dt / 2 (no wall within reach, a uniform velocity field has C = 0 and F stays I).
  CpuEngine<double> engine(scene);
  auto mean_y = [&] {
    double s = 0;
    for (const auto& x : engine.positions(0)) s += x[1];
    return s / engine.positions(0).size();
  };
  const double y0 = mean_y(), dt = 1e-3;
  for (int n = 0; n < 20; ++n) ASSERT_TRUE(engine.step(dt).ok);
  const double t = engine.time();
  EXPECT_NEAR(y0 - mean_y(), 0.5 * 9.81 * t * t + 0.5 * 9.81 * t * dt, 1e-12);
  for (const double J : engine.volume_ratios(0)) EXPECT_NEAR(J, 1.0, 1e-12);
}

MaterialSpec hencky_spec(double E, double nu, double rho) {
  MaterialSpec m;
  m.law = Constitutive::Hencky;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  m.rho = rho;
  return m;
}

// Hencky: F = diag(s, 1, 1) gives tau_11 = (lambda + 2 mu) log s, tau_22 = tau_33 =
// lambda log s, no shear. A diagonal SVD is exact; tolerance 16 eps (lambda + 2 mu) max(1, |log s|).
TEST(Hencky, UniaxialStretchMatchesClosedForm) {
  const auto p = Hencky::make_params<double>(hencky_spec(1e7, 0.3, 1000.0));
  for (const double s : {0.5, 0.9, 0.999, 1.0, 1.001, 1.2, 2.0}) {
    Mat3d F = Mat3d::identity();
    F(0, 0) = s;
    const StressResult<double> r = Hencky::kirchhoff_stress(p, {F}, Mat3d::zero());
    const double tol = 16 * kEps * (p.lambda + 2 * p.mu) * std::max(1.0, std::fabs(std::log(s)));
    EXPECT_NEAR(r.kirchhoff(0, 0), (p.lambda + 2 * p.mu) * std::log(s), tol) << s;
    EXPECT_NEAR(r.kirchhoff(1, 1), p.lambda * std::log(s), tol) << s;
    EXPECT_NEAR(r.kirchhoff(2, 2), p.lambda * std::log(s), tol) << s;
    EXPECT_NEAR(r.kirchhoff(0, 1), 0.0, tol);
    EXPECT_NEAR(r.J, s, 4 * kEps);
  }
}

// Objectivity: tau(R F) = R tau(F) R^T; a rotation carries no stress. Tolerance as FixedCorotated's (SVD accuracy).
TEST(Hencky, RotationInvariance) {
  const auto p = Hencky::make_params<double>(hencky_spec(5e6, 0.25, 2000.0));
  std::mt19937_64 rng(17);
  for (int n = 0; n < 200; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.3);
    const Mat3d R = test::random_rotation(rng);
    const Mat3d tau = Hencky::kirchhoff_stress(p, {F}, Mat3d::zero()).kirchhoff;
    const Mat3d tau_rot = Hencky::kirchhoff_stress(p, {R * F}, Mat3d::zero()).kirchhoff;
    EXPECT_LE(max_abs(tau_rot - R * tau * transpose(R)), 1e-13 * (p.lambda + 2 * p.mu));
  }
  const Mat3d R = test::rotation(Vec3d{{0.3, -1, 2}}, 2.1);
  EXPECT_LE(max_abs(Hencky::kirchhoff_stress(p, {R}, Mat3d::zero()).kirchhoff), 16 * kEps * p.lambda);
}

// The stress is the energy's derivative: P = tau F^-T = dpsi/dF (central differences, h = 1e-6: truncation and
// rounding as for FixedCorotated, tolerance 1e-8 E).
TEST(Hencky, StressIsEnergyDerivative) {
  const double E = 1e7;
  const auto p = Hencky::make_params<double>(hencky_spec(E, 0.3, 1000.0));
  std::mt19937_64 rng(5);
  for (int n = 0; n < 20; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.2);
    const Mat3d P = Hencky::kirchhoff_stress(p, {F}, Mat3d::zero()).kirchhoff * transpose(inverse(F));
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Mat3d Fp = F, Fm = F;
        Fp(i, j) += h;
        Fm(i, j) -= h;
        EXPECT_NEAR(P(i, j), (Hencky::energy_density(p, {Fp}) - Hencky::energy_density(p, {Fm})) / (2 * h),
                    1e-8 * E);
      }
  }
  EXPECT_EQ(Hencky::energy_density(p, Hencky::reference_state<double>()), 0.0);
}

// Small strains: Hooke's law, tau = lambda tr(eps) I + 2 mu eps with eps = sym(F) - I, to O(|eps|^2): a strain of
// 1e-5 leaves a difference below 10 |eps|^2 (lambda + 2 mu). Wave speed: the P-wave speed.
TEST(Hencky, SmallStrainIsHookesLawAndWaveSpeedIsPWaveSpeed) {
  const auto p = Hencky::make_params<double>(hencky_spec(2e8, 0.2, 2500.0));
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1e-5, 1e-5);
  for (int n = 0; n < 50; ++n) {
    Mat3d eps;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j <= i; ++j) eps(i, j) = eps(j, i) = u(rng);
    const Mat3d F = Mat3d::identity() + eps;
    const double tr = eps(0, 0) + eps(1, 1) + eps(2, 2);
    Mat3d hooke = eps * (2 * p.mu);
    for (int i = 0; i < 3; ++i) hooke(i, i) += p.lambda * tr;
    EXPECT_LE(max_abs(Hencky::kirchhoff_stress(p, {F}, Mat3d::zero()).kirchhoff - hooke),
              10 * 1e-10 * (p.lambda + 2 * p.mu));
  }
  EXPECT_NEAR(Hencky::wave_speed(p, Hencky::reference_state<double>()), std::sqrt((p.lambda + 2 * p.mu) / 2500.0),
              1e-12);
}

}  // namespace
}  // namespace fbar
