// The CPU reference engine against exact solutions: free fall, rigid translation, conservation, time steps, failure
// detection, the run summary and the API (its walls: test_cpu_boundaries.cpp).
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "engine/cpu/cpu_engine.h"
#include "scene/scene_parse.h"
#include "engine/check_report.h"
#include "engine/engine_api.h"
#include "../../physics/physics_test_support.h"
#include "scene/facilities.h"

namespace fbar {
namespace {

using test::box_body;
using test::empty_scene;
using test::kEps;
using test::r3;

Scene two_body_scene_for_summary() {
  Scene scene = empty_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.2, 0.2, 0.2), r3(0.2, 0.2, 0.2)));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.6, 0.6, 0.6), r3(0.2, 0.2, 0.2)));
  return scene;
}

// Free fall: symplectic Euler gives x_n = x0 + g t_n^2/2 + g t_n dt/2 exactly (no spatial error:
// a uniform velocity field is transferred exactly, the deformation stays I). Body far from every wall, fixed dt.
// Error budget: each step adds O(eps |x|) to x and O(eps |v|) to v; after n = 200 steps |x| <= 1 m, |v| <= 2 m/s:
// 2 n eps (|x| + t |v|) < 2e-13 m. Tolerance 1e-12 m; velocity 1e-12 m/s; |F - I| 1e-12; stress 1e-12 E.
/// (material, ASFLIP alpha, beta_min, beta_max, FBAR_psi): every law under APIC, and FLIP / ASFLIP / F-bar (uniform
/// motion is exact for any alpha, beta: the particle velocity equals the transported grid velocity; F-bar leaves a
/// uniform divergence unchanged: transfer.cuh).
struct FallCase {
  Constitutive law;
  double alpha, beta_min, beta_max;
  double psi = 0.0;
};
std::string fall_case_name(const ::testing::TestParamInfo<FallCase>& info) {
  const FallCase& c = info.param;
  std::string name = to_string(c.law);
  if (c.alpha != 0.0 || c.beta_min != 0.0 || c.beta_max != 0.0) name += c.beta_max != 0.0 ? "_ASFLIP" : "_PICFLIP";
  if (c.psi != 0.0) name += "_Fbar";
  return name;
}
class FreeFall : public ::testing::TestWithParam<FallCase> {};

TEST_P(FreeFall, MatchesSymplecticEulerExactly) {
  const FallCase c = GetParam();
  Scene scene = empty_scene(r3(1, 1, 1), 0.05, r3(0.5, -9.81, 0.25));
  scene.bodies.push_back(box_body(c.law, r3(0.4, 0.6, 0.4), r3(0.15, 0.1, 0.1), r3(0.1, 1.0, -0.2)));
  AlgorithmSpec& a = scene.bodies[0].algorithm;
  a.use_asflip = true;
  a.asflip_alpha = c.alpha;
  a.asflip_beta_min = c.beta_min;
  a.asflip_beta_max = c.beta_max;
  a.use_fbar = true;
  a.fbar_psi = c.psi;
  a.fbar_scheme = FbarScheme::Cell;
  scene.bodies[0].material.logJp0 = c.law == Constitutive::NACC ? -0.1 : 0.0;  // a clay with strength
  CpuEngine<double> engine(scene);
  const std::vector<Vec3d> x0 = engine.positions(0);
  const Vec3d v0{{0.1, 1.0, -0.2}}, g{{0.5, -9.81, 0.25}};
  const double dt = 1e-3;
  const int n = 200;
  for (int s = 0; s < n; ++s) ASSERT_TRUE(engine.step(dt).ok);
  const double t = n * dt;
  EXPECT_EQ(engine.steps(), n);
  EXPECT_NEAR(engine.time(), t, 1e-15);
  double x_err = 0, v_err = 0;
  for (std::size_t p = 0; p < x0.size(); ++p) {
    const Vec3d expected = x0[p] + v0 * t + g * (0.5 * t * t + 0.5 * t * dt);
    x_err = std::max(x_err, max_abs(engine.positions(0)[p] - expected));
    v_err = std::max(v_err, max_abs(engine.velocities(0)[p] - (v0 + g * t)));
  }
  EXPECT_LE(x_err, 1e-12) << "max position error " << x_err;
  EXPECT_LE(v_err, 1e-12) << "max velocity error " << v_err;
  for (const double J : engine.volume_ratios(0)) EXPECT_NEAR(J, 1.0, 1e-12);
  for (const Mat3d& s : engine.cauchy_stresses(0)) EXPECT_LE(max_abs(s), 1e-12 * 1e6);
  std::printf("free fall (%s, alpha %g, beta %g/%g, psi %g): max |x - exact| = %.3g m, max |v - exact| = %.3g m/s "
              "after %d steps\n",
              to_string(c.law), c.alpha, c.beta_min, c.beta_max, c.psi, x_err, v_err, n);
}

INSTANTIATE_TEST_SUITE_P(
    MaterialsAndSchemes, FreeFall,
    ::testing::Values(FallCase{Constitutive::JFluid, 0, 0, 0}, FallCase{Constitutive::FixedCorotated, 0, 0, 0},
                      FallCase{Constitutive::NeoHookean, 0, 0, 0}, FallCase{Constitutive::DruckerPrager, 0, 0, 0},
                      FallCase{Constitutive::NACC, 0, 0, 0}, FallCase{Constitutive::JFluid, 1, 0, 0},
                      FallCase{Constitutive::FixedCorotated, 0.95, 0, 0},
                      FallCase{Constitutive::DruckerPrager, 0.9, 0.05, 0.2},
                      FallCase{Constitutive::Hencky, 0, 0, 0}, FallCase{Constitutive::NeoHookean, 0, 0, 0, 1.0},
                      FallCase{Constitutive::JFluid, 0, 0, 0, 0.5}, FallCase{Constitutive::VonMises, 0, 0, 0}),
    fall_case_name);

// Uniform translation across many cells keeps v = v0, F = I, stress 0 to round-off. 15 cells
// travelled (0.3 m at dx = 0.02); the CFL step is taken (it must not matter). Same budget as above.
TEST(RigidTranslation, StaysUniformAcrossManyCells) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, 0, 0));
  const Vec3d v0{{1.0, -0.5, 0.25}};
  scene.bodies.push_back(
      box_body(Constitutive::FixedCorotated, r3(0.2, 0.5, 0.3), r3(0.1, 0.1, 0.1), r3(1.0, -0.5, 0.25)));
  CpuEngine<double> engine(scene);
  const std::vector<Vec3d> x0 = engine.positions(0);
  const StepReport r = engine.advance_to(0.3);
  ASSERT_TRUE(r.ok) << r.message();
  EXPECT_EQ(engine.time(), 0.3);  // lands on the target exactly
  double v_err = 0, x_err = 0, F_err = 0, s_max = 0;
  const auto F = engine.deformation_gradients(0);
  const auto sigma = engine.cauchy_stresses(0);
  for (std::size_t p = 0; p < x0.size(); ++p) {
    v_err = std::max(v_err, max_abs(engine.velocities(0)[p] - v0));
    x_err = std::max(x_err, max_abs(engine.positions(0)[p] - (x0[p] + v0 * 0.3)));
    F_err = std::max(F_err, max_abs(F[p] - Mat3d::identity()));
    s_max = std::max(s_max, max_abs(sigma[p]));
  }
  EXPECT_LE(v_err, 1e-12);
  EXPECT_LE(x_err, 1e-12);
  EXPECT_LE(F_err, 1e-12);
  EXPECT_LE(s_max, 1e-12 * 1e6);
  std::printf("rigid translation: %lld steps, |v - v0| %.3g m/s, |x - exact| %.3g m, |F - I| %.3g, |sigma| %.3g Pa\n",
              engine.steps(), v_err, x_err, F_err, s_max);
}

// Float engine: the same translation keeps v0 to float round-off (n eps_f |v| with n ~ 100 steps -> 1e-5 m/s).
TEST(RigidTranslation, SinglePrecision) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.2, 0.5, 0.3), r3(0.1, 0.1, 0.1), r3(1.0, -0.5, 0.25)));
  CpuEngine<float> engine(scene);
  ASSERT_TRUE(engine.advance_to(0.2).ok);
  for (const Vec3f& v : engine.velocities(0)) EXPECT_LE(max_abs(v - Vec3f{{1.0f, -0.5f, 0.25f}}), 1e-5f);
}

// Mass: particle masses never change (sum exactly constant) and P2G puts all of it on the grid (partition of unity,
// double sum of N terms: relative N eps). A colliding, bouncing scene with walls and gravity.
TEST(Conservation, MassExact) {
  Scene scene = empty_scene(r3(0.6, 0.6, 0.3), 0.02, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.05, 0.05, 0.05), r3(0.2, 0.3, 0.2)));
  scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.35, 0.3, 0.05), r3(0.1, 0.1, 0.1), r3(-1, 0, 0)));
  BoundarySpec walls;
  walls.contact = Contact::Separable;
  scene.boundaries.push_back(walls);
  CpuEngine<double> engine(scene);
  const double m0 = engine.total_mass();
  ASSERT_TRUE(engine.advance_to(0.05).ok);
  EXPECT_EQ(engine.total_mass(), m0);
  EXPECT_NEAR(engine.grid_mass(), m0, static_cast<double>(engine.particle_count()) * kEps * m0);
  std::printf("mass: %zu particles, %lld steps, |grid mass - particle mass| / mass = %.3g\n", engine.particle_count(),
              engine.steps(), std::fabs(engine.grid_mass() - m0) / m0);
}

// Momentum and angular momentum (APIC / MLS-MPM conserve both exactly): two elastic blocks
// of different density collide and spin, no gravity, no boundaries. Each step's sums are exact up to round-off of
// terms of size sum m |v| (momentum) and sum m |x||v| (angular momentum); over ~100 steps the drift stays below
// 1e-12 of those scales.
TEST(Conservation, MomentumAndAngularMomentumWithoutExternalForces) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, 0, 0));
  scene.bodies.push_back(
      box_body(Constitutive::FixedCorotated, r3(0.3, 0.4, 0.4), r3(0.12, 0.1, 0.1), r3(2.0, 0.3, 0)));
  BodySpec other = box_body(Constitutive::FixedCorotated, r3(0.46, 0.45, 0.42), r3(0.1, 0.1, 0.08), r3(-1.0, 0, 0.2));
  other.material.rho = 2500.0;
  scene.bodies.push_back(other);
  CpuEngine<double> engine(scene);
  // Add spin to body 0 so that angular momentum is exercised by C.
  engine.set_velocities(0, [](const Vec3d& x) {
    return Vec3d{{2.0 - 5.0 * (x[1] - 0.45), 0.3 + 5.0 * (x[0] - 0.36), 0.0}};
  });
  const Vec3d P0 = engine.total_momentum();
  const Vec3d L0 = engine.angular_momentum();
  const double E0 = engine.kinetic_energy() + engine.elastic_energy();
  double p_scale = 0, l_scale = 0;
  for (int b = 0; b < 2; ++b)
    for (std::size_t p = 0; p < engine.particle_count(b); ++p) {
      p_scale += engine.masses(b)[p] * norm(engine.velocities(b)[p]);
      l_scale += engine.masses(b)[p] * norm(engine.velocities(b)[p]) * norm(engine.positions(b)[p]);
    }
  ASSERT_TRUE(engine.advance_to(0.03).ok);
  const double dp = max_abs(engine.total_momentum() - P0) / p_scale;
  const double dl = max_abs(engine.angular_momentum() - L0) / l_scale;
  EXPECT_LE(dp, 1e-12);
  EXPECT_LE(dl, 1e-12);
  const double E1 = engine.kinetic_energy() + engine.elastic_energy();
  EXPECT_LE(E1, E0 * (1 + 1e-9));  // a collision dissipates (APIC), it never creates energy
  std::printf("momentum drift %.3g, angular momentum drift %.3g (relative), %lld steps, energy %.6g -> %.6g J\n", dp,
              dl, engine.steps(), E0, E1);
}

// Results do not depend on the number of threads (fixed summation order by colour / block / particle).
TEST(Determinism, BitwiseIndependentOfThreadCount) {
  auto run = [](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Scene scene = empty_scene(r3(0.6, 0.6, 0.3), 0.02, r3(0, -9.81, 0));
    scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.05, 0.05, 0.05), r3(0.2, 0.3, 0.2)));
    BoundarySpec walls;
    walls.contact = Contact::Slip;
    scene.boundaries.push_back(walls);
    CpuEngine<double> engine(scene);
    EXPECT_TRUE(engine.advance_to(0.02).ok);
    omp_set_num_threads(saved);
    return engine.positions(0);
  };
  const auto a = run(1);
  const auto b = run(3);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t p = 0; p < a.size(); ++p) ASSERT_EQ(a[p], b[p]) << "particle " << p;
}

// ------------------------------------------------------------------------------------------------ time step

// dt = min(default_dt, CFL dx / (c + |v|max)) with the p-wave speed (physics/time_step.cuh).
TEST(TimeStep, EngineUsesCflFormula) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.4, 0.4, 0.4), r3(0.1, 0.1, 0.1), r3(3, 0, 4)));
  CpuEngine<double> engine(scene);
  const double E = 1e6, nu = 0.3, rho = 1000;
  const double cp = std::sqrt(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu) * rho));
  EXPECT_NEAR(engine.next_dt(), 0.5 * 0.02 / (cp + 5.0), 1e-15);
  scene.simulation.default_dt = 1e-5;
  CpuEngine<double> capped(scene);
  EXPECT_EQ(capped.next_dt(), 1e-5);
  const SceneSummary summary = summarize_scene(scene);
  EXPECT_NEAR(summary.bodies[0].wave_speed, cp, 1e-12 * cp);
  EXPECT_NEAR(summary.bodies[0].dt_bound, 0.5 * 0.02 / (cp + 5.0), 1e-15);
  EXPECT_EQ(summary.dt, 1e-5);
  EXPECT_EQ(summary.bodies[0].particles, 5 * 5 * 5 * 8);
  EXPECT_EQ(summary.gpu_bytes.size(), 1u);
  EXPECT_GT(summary.gpu_bytes[0], 0u);
}

// A very viscous fluid (nu = 10 m^2/s): the explicit viscous bound CFL rho dx^2 / (3 mu) (time_step.cuh) caps the
// step of both engines (RunConstants) and of --check. Without it this cube, at dt = default_dt = 0.5 dx^2 / nu, loses
// stability silently: its velocities grow and the CFL step collapses towards zero (measured before the bound: 2e5
// steps for 0.01 s, no failure reported). With it, at CFL 1 (the largest allowed), the run reaches 0.05 s in t / bound
// steps and the kinetic energy stays below the initial one plus all the potential energy the cube can release.
TEST(TimeStep, ViscousBoundKeepsAVeryViscousFluidStable) {
  const double dx = 0.02, mu = 1e4, rho = 1000, g = 9.81;
  Scene scene = empty_scene(r3(0.4, 0.4, 0.4), dx, r3(0, -g, 0));
  BodySpec body = box_body(Constitutive::JFluid, r3(0.15, 0.1, 0.15), r3(0.1, 0.1, 0.1), r3(0.3, -1.0, 0.2));
  body.material.bulk_modulus = 2e5;
  body.material.viscosity = mu;
  body.material.cfl = 1.0;
  scene.bodies.push_back(body);
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = Contact::Separable;
  walls.domain_start = r3(0.05, 0.05, 0.05);
  walls.domain_end = r3(0.35, 0.35, 0.35);
  scene.boundaries.push_back(walls);
  scene.simulation.default_dt = 0.5 * dx * dx * rho / mu;
  const double bound = 1.0 * rho * dx * dx / (3.0 * mu);

  const SceneSummary summary = summarize_scene(scene);
  EXPECT_NEAR(summary.bodies[0].viscous_dt, bound, 1e-15 * bound);
  EXPECT_NEAR(summary.dt, bound, 1e-15 * bound);
  std::ostringstream report;
  print_scene_report(report, scene, summary);
  EXPECT_NE(report.str().find("viscous bound"), std::string::npos) << report.str();

  CpuEngine<double> engine(scene);
  engine.set_log(nullptr);
  EXPECT_LE(engine.next_dt(), bound * (1 + 1e-15));
  double mass = 0.0;
  for (double m : engine.masses(0)) mass += m;
  const double energy_cap = engine.kinetic_energy() + mass * g * 0.35;
  const double t_end = 0.05;
  const long long step_cap = static_cast<long long>(1.1 * t_end / bound) + 2;
  while (engine.time() < t_end && engine.steps() < step_cap) {
    const StepReport r = engine.step_toward(t_end);
    ASSERT_TRUE(r.ok) << r.message();
  }
  EXPECT_EQ(engine.time(), t_end) << "after " << engine.steps() << " steps";
  EXPECT_LT(engine.kinetic_energy(), energy_cap);

  // An inviscid body has no viscous bound.
  scene.bodies[0].material.viscosity = 0.0;
  EXPECT_TRUE(std::isinf(summarize_scene(scene).bodies[0].viscous_dt));
}

// --check names the scheme that runs: APIC, PIC-FLIP (0 < alpha < 1, beta 0), FLIP (alpha 1), ASFLIP (beta > 0),
// each with " + F-bar" when FBAR_psi > 0.
TEST(CheckReport, NamesTheTransferScheme) {
  struct Case {
    double alpha, beta_max, psi;
    const char* expected;
  };
  for (const Case& c : {Case{0, 0, 0, "APIC ("}, Case{0.95, 0, 0, "PIC-FLIP ("}, Case{1, 0, 0, "FLIP ("},
                        Case{0.95, 0.2, 0, "ASFLIP ("}, Case{0, 0, 1, "APIC + F-bar ("},
                        Case{0.9, 0.1, 0.5, "ASFLIP + F-bar ("}}) {
    Scene scene = empty_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0));
    scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.4, 0.4, 0.4), r3(0.1, 0.1, 0.1)));
    AlgorithmSpec& a = scene.bodies[0].algorithm;
    a.use_asflip = a.use_fbar = true;
    a.asflip_alpha = c.alpha;
    a.asflip_beta_max = c.beta_max;
    a.fbar_psi = c.psi;
    a.fbar_scheme = FbarScheme::Cell;
    std::ostringstream os;
    print_scene_report(os, scene, summarize_scene(scene));
    EXPECT_NE(os.str().find(std::string(" ") + c.expected + "use_ASFLIP"), std::string::npos) << c.expected << "\n"
                                                                                            << os.str();
  }
}

// A compressed JFluid has a faster sound speed, c^2 = (K/rho0) J^(1-gamma); the engine's dt follows it.
TEST(TimeStep, FollowsCompressedSoundSpeed) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.4, 0.4, 0.4), r3(0.1, 0.1, 0.1)));
  CpuEngine<double> engine(scene);
  const double c0 = std::sqrt(1e6 / 1000.0);
  EXPECT_NEAR(engine.next_dt(), 0.5 * 0.02 / c0, 1e-15);
  engine.set_volume_ratios(0, [](const Vec3d& x) { return x[0] < 0.45 ? 0.9 : 1.0; });
  const double c = c0 * std::sqrt(std::pow(0.9, 1 - 7.0));
  EXPECT_NEAR(engine.next_dt(), 0.5 * 0.02 / c, 1e-12 * 0.5 * 0.02 / c);
}

// A scene pays only for what it uses: ASFLIP adds particle velocities (GPU) and 3 + 3 grid channels per buffer set,
// F-bar 2 grid channels; the estimates grow by those and only when a body switches the scheme on, and the CPU
// estimate still brackets what the engine allocates.
TEST(Summary, MemoryEstimatesCountTheSchemes) {
  Scene scene = two_body_scene_for_summary();
  scene.simulation.precision = Precision::Double;
  const SceneSummary apic = summarize_scene(scene);
  Scene asflip = scene;
  asflip.bodies[0].algorithm.use_asflip = true;
  asflip.bodies[0].algorithm.asflip_alpha = 0.9;
  const SceneSummary with_asflip = summarize_scene(asflip);
  Scene fbar = scene;
  fbar.bodies[1].algorithm.use_fbar = true;
  fbar.bodies[1].algorithm.fbar_psi = 1.0;
  fbar.bodies[1].algorithm.fbar_scheme = FbarScheme::Cell;
  const SceneSummary with_fbar = summarize_scene(fbar);
  Scene off = scene;  // ratios given but the switches off: plain APIC, same memory
  off.bodies[0].algorithm.use_asflip = false;
  off.bodies[0].algorithm.asflip_alpha = 0.9;
  off.bodies[1].algorithm.use_fbar = false;
  off.bodies[1].algorithm.fbar_psi = 1.0;
  EXPECT_EQ(summarize_scene(off).gpu_bytes[0], apic.gpu_bytes[0]);
  EXPECT_EQ(summarize_scene(off).cpu_bytes, apic.cpu_bytes);
  EXPECT_GT(with_asflip.gpu_bytes[0], with_fbar.gpu_bytes[0]);
  EXPECT_GT(with_fbar.gpu_bytes[0], apic.gpu_bytes[0]);
  EXPECT_GT(with_asflip.cpu_bytes, with_fbar.cpu_bytes);
  EXPECT_GT(with_fbar.cpu_bytes, apic.cpu_bytes);
  for (const Scene* s : {&asflip, &fbar}) {
    CpuEngine<double> engine(*s);
    ASSERT_TRUE(engine.step().ok);
    const double estimate = static_cast<double>(summarize_scene(*s).cpu_bytes);
    EXPECT_GT(estimate, 0.5 * static_cast<double>(engine.memory_bytes()));
    EXPECT_LT(estimate, 2.0 * static_cast<double>(engine.memory_bytes()));
  }
}

// Memory estimates grow with precision (mixed: double particles, float grid, between the two) and are split by GPU
// id; the CPU estimates hold for the engine of each precision.
TEST(Summary, MemoryEstimatesPerGpu) {
  Scene scene = two_body_scene_for_summary();
  scene.bodies[1].gpu = 1;
  scene.simulation.precision = Precision::Single;
  const SceneSummary single = summarize_scene(scene);
  scene.simulation.precision = Precision::Mixed;
  const SceneSummary mixed = summarize_scene(scene);
  scene.simulation.precision = Precision::Double;
  const SceneSummary dbl = summarize_scene(scene);
  for (int g = 0; g < 2; ++g) {
    EXPECT_GT(mixed.gpu_bytes[g], single.gpu_bytes[g]);
    EXPECT_LT(mixed.gpu_bytes[g], dbl.gpu_bytes[g]);
  }
  std::size_t mixed_engine_bytes = 0;
  {
    Scene s = scene;
    s.simulation.precision = Precision::Single;
    CpuEngine<float> e(s);
    ASSERT_TRUE(e.step().ok);
    EXPECT_GT(static_cast<double>(single.cpu_bytes), 0.5 * static_cast<double>(e.memory_bytes()));
    EXPECT_LT(static_cast<double>(single.cpu_bytes), 2.0 * static_cast<double>(e.memory_bytes()));
    s.simulation.precision = Precision::Mixed;
    CpuEngine<double, float> m(s);
    ASSERT_TRUE(m.step().ok);
    EXPECT_GT(static_cast<double>(mixed.cpu_bytes), 0.5 * static_cast<double>(m.memory_bytes()));
    EXPECT_LT(static_cast<double>(mixed.cpu_bytes), 2.0 * static_cast<double>(m.memory_bytes()));
    mixed_engine_bytes = m.memory_bytes();
  }
  ASSERT_EQ(single.gpu_bytes.size(), 2u);
  EXPECT_GT(single.gpu_bytes[0], 0u);
  EXPECT_GT(single.gpu_bytes[1], 0u);
  EXPECT_GT(single.gpu_bytes[0], single.gpu_bytes[1]);  // FixedCorotated stores 12 scalars, JFluid 4
  EXPECT_GT(dbl.gpu_bytes[0], single.gpu_bytes[0]);
  EXPECT_GT(single.cpu_bytes, 0u);
  CpuEngine<double> engine(scene);
  ASSERT_TRUE(engine.step().ok);
  // The estimate counts what the engine allocates (within 2x: vector capacities, hash-map nodes).
  EXPECT_GT(static_cast<double>(dbl.cpu_bytes), 0.5 * static_cast<double>(engine.memory_bytes()));
  EXPECT_LT(static_cast<double>(dbl.cpu_bytes), 2.0 * static_cast<double>(engine.memory_bytes()));
  EXPECT_LT(mixed_engine_bytes, engine.memory_bytes()) << "mixed: the grid in float";
}

// Froude similitude: the same dam break built at length scale s = 0.5 (apply_froude_scaling: lengths x s, times and
// velocities x s^0.5, moduli x s) runs the same motion, scaled: its particles at t s^0.5 are the unscaled ones at t,
// times s, to rounding (the CFL steps scale by s^0.5 too).
TEST(FroudeScaling, ScaledSceneGivesTheUnscaledMotionScaled) {
  Scene scene = empty_scene(r3(1.0, 0.6, 0.2), 0.04, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.04, 0.04, 0.04), r3(0.3, 0.4, 0.12)));
  BoundarySpec walls;
  walls.object = BoundaryObject::Walls;
  walls.contact = Contact::Slip;
  scene.boundaries.push_back(walls);
  const double s = 0.5, t = 0.3;
  Scene scaled = scene;
  scaled.simulation.froude_scaling = s;
  apply_froude_scaling(scaled);
  CpuEngine<double> a(scene), b(scaled);
  a.set_log(nullptr);
  b.set_log(nullptr);
  ASSERT_TRUE(a.advance_to(t).ok);
  ASSERT_TRUE(b.advance_to(t * std::sqrt(s)).ok);
  ASSERT_EQ(a.particle_count(0), b.particle_count(0));
  double moved = 0.0, diff = 0.0;
  const Scene fresh = scene;
  CpuEngine<double> start(fresh);
  for (std::size_t i = 0; i < a.particle_count(0); ++i) {
    moved = std::max(moved, norm(a.positions(0)[i] - start.positions(0)[i]));
    diff = std::max(diff, norm(b.positions(0)[i] / s - a.positions(0)[i]));
  }
  std::cout << "[measured] Froude s = 0.5: the column moved up to " << moved << " m; scaled-back difference " << diff
            << " m\n";
  EXPECT_GT(moved, 0.05);
  EXPECT_LT(diff, 1e-6);
}

// ------------------------------------------------------------------------------------------------ failures

Scene two_body_scene() {
  Scene scene = empty_scene(r3(1, 1, 1), 0.05, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::FixedCorotated, r3(0.2, 0.2, 0.2), r3(0.1, 0.1, 0.1)));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.6, 0.6, 0.6), r3(0.1, 0.1, 0.1)));
  return scene;
}

TEST(Failure, NaNIsReportedWithBodyStepTimeAndStateKept) {
  CpuEngine<double> engine(two_body_scene());
  engine.set_log(nullptr);
  ASSERT_TRUE(engine.step(1e-3).ok);
  ASSERT_TRUE(engine.step(1e-3).ok);
  engine.set_velocities(1, [](const Vec3d& x) {
    return x[0] < 0.62 && x[1] < 0.62 && x[2] < 0.62 ? Vec3d{{std::nan(""), 0, 0}} : Vec3d::zero();
  });
  const std::vector<Vec3d> before = engine.positions(1);
  const StepReport r = engine.step(1e-3);
  ASSERT_FALSE(r.ok);
  ASSERT_EQ(r.failures.size(), 1u);
  const FailureReport& f = r.failures[0];
  EXPECT_EQ(f.kind, FailureKind::NonFinite);
  EXPECT_EQ(f.body, 1);
  EXPECT_EQ(f.step, 3);
  EXPECT_NEAR(f.time, 2e-3, 1e-18);
  EXPECT_GE(f.count, 1);
  EXPECT_EQ(f.first_particle, 0);
  EXPECT_EQ(engine.steps(), 2);            // not committed
  EXPECT_EQ(engine.positions(1), before);  // state untouched
  EXPECT_NE(r.message().find("body 1"), std::string::npos) << r.message();
  EXPECT_NE(r.message().find("step 3"), std::string::npos);
  EXPECT_NE(r.message().find("t = 0.002 s"), std::string::npos);
}

// A particle moving 1.5 cells in one step is a CFL violation (fused G2P2G cannot hold it).
TEST(Failure, CflViolationIsReported) {
  CpuEngine<double> engine(two_body_scene());
  engine.set_log(nullptr);
  const double dt = 1e-3;
  for (int s = 0; s < 3; ++s) ASSERT_TRUE(engine.step(dt).ok);
  engine.set_velocities(0, [&](const Vec3d&) { return Vec3d{{0, 1.5 * 0.05 / dt, 0}}; });
  const StepReport r = engine.step(dt);
  ASSERT_FALSE(r.ok);
  ASSERT_EQ(r.failures.size(), 1u);
  EXPECT_EQ(r.failures[0].kind, FailureKind::CflViolation);
  EXPECT_EQ(r.failures[0].body, 0);
  EXPECT_EQ(r.failures[0].step, 4);
  EXPECT_NEAR(r.failures[0].time, 3e-3, 1e-18);
  EXPECT_EQ(r.failures[0].count, static_cast<long long>(engine.particle_count(0)));
  EXPECT_NE(r.message().find("CFL"), std::string::npos);
}

// on_failure = reduce_dt: the step is repeated from the saved state with dt/2 (0.75 cells: fine) and logged.
TEST(Failure, ReduceDtRetriesWithHalfStep) {
  Scene scene = two_body_scene();
  scene.simulation.on_failure = OnFailure::ReduceDt;
  CpuEngine<double> engine(scene);
  std::ostringstream log;
  engine.set_log(&log);
  const double dt = 1e-3;
  engine.set_velocities(0, [&](const Vec3d&) { return Vec3d{{0, 1.5 * 0.05 / dt, 0}}; });
  const std::vector<Vec3d> x0 = engine.positions(0);
  const StepReport r = engine.step(dt);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.retries, 1);
  EXPECT_EQ(r.dt, dt / 2);
  ASSERT_EQ(r.retried.size(), 1u);
  EXPECT_EQ(r.retried[0].kind, FailureKind::CflViolation);
  EXPECT_EQ(engine.time(), dt / 2);
  EXPECT_NEAR(engine.positions(0)[0][1] - x0[0][1], 0.75 * 0.05, 1e-12);
  EXPECT_NE(log.str().find("retrying the step with dt = 0.0005 s"), std::string::npos) << log.str();
}

// A particle that leaves [0, domain] is reported at the first step whose end position is outside: body 0's highest
// particles sit at x = 0.29375 (lattice 0.25 + (i + 0.5) dx/2 ...); moving +x at 1 m/s toward a domain of 0.3 m
// they cross at t = 6.25e-3 s, i.e. during step 7 of dt = 1e-3 s.
TEST(Failure, LeavingTheDomainIsReported) {
  Scene scene = empty_scene(r3(0.3, 1, 1), 0.025, r3(0, 0, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.2, 0.2, 0.2), r3(0.1, 0.1, 0.1), r3(1.0, 0, 0)));
  scene.bodies[0].material.bulk_modulus = 1e4;  // c = 3.2 m/s: the fixed 1 ms steps stay stable
  CpuEngine<double> engine(scene);
  double x_max = 0;
  for (const Vec3d& x : engine.positions(0)) x_max = std::max(x_max, x[0]);
  ASSERT_NEAR(x_max, 0.29375, 1e-12);
  StepReport r;
  // A particle leaves the domain 8 cells (kDomainMarginCells) beyond its face: x > 0.5 after the step starting at
  // t = 0.206 s (0.29375 + 0.207 > 0.5), the 207th.
  while ((r = engine.step(1e-3)).ok) ASSERT_LT(engine.steps(), 300);
  ASSERT_EQ(r.failures.size(), 1u) << r.message();
  EXPECT_EQ(r.failures[0].kind, FailureKind::LeftDomain);
  EXPECT_EQ(r.failures[0].body, 0);
  EXPECT_EQ(r.failures[0].step, 207);
  EXPECT_NEAR(r.failures[0].time, 206e-3, 1e-12);
  EXPECT_EQ(r.failures[0].count, static_cast<long long>(engine.particle_count(0)) / 8);  // the last of 8 lattice layers
  EXPECT_NE(r.message().find("left the domain"), std::string::npos);
}

// ------------------------------------------------------------------------------------------------ API

// Hydrostatic start (as in the hydrostatic column of docs/validation.md): J(y) given per particle, mass rescaled so
// that the current density is rho0 / J; pressures then follow the equation of state.
TEST(Api, VolumeRatioFieldForJFluid) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.05, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.2, 0.2, 0.2), r3(0.2, 0.2, 0.2)));
  CpuEngine<double> engine(scene);
  const double K = 1e6, gamma = 7.0, rho = 1000.0, g = 9.81, top = 0.4;
  auto J_of = [&](const Vec3d& x) { return std::pow(1.0 + gamma * rho * g * (top - x[1]) / K, -1.0 / gamma); };
  engine.set_volume_ratios(0, J_of);
  const auto J = engine.volume_ratios(0);
  const auto p = engine.pressures(0);
  const double V = 0.05 * 0.05 * 0.05 / 8;
  for (std::size_t i = 0; i < J.size(); ++i) {
    const Vec3d& x = engine.positions(0)[i];
    EXPECT_NEAR(J[i], J_of(x), 1e-15);
    EXPECT_NEAR(p[i], rho * g * (top - x[1]), 1e-9 * rho * g);
    EXPECT_NEAR(engine.masses(0)[i], rho * V / J[i], 1e-15);
    EXPECT_NEAR(engine.volumes(0)[i], V / J[i], 1e-18);
  }
  EXPECT_THROW(CpuEngine<double>(two_body_scene()).set_volume_ratios(0, J_of), std::invalid_argument);
  EXPECT_THROW(CpuEngine<double>(two_body_scene()).deformation_gradients(1), std::invalid_argument);
}

TEST(Api, UnsupportedInputIsRefusedNamingTheBody) {
  Scene scene = two_body_scene();
  scene.bodies[1].output_attribs = {"ID", "DefGrad_XX"};  // JFluid stores no F
  try {
    CpuEngine<double> engine(scene);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("bodies[1].output_attribs"), std::string::npos) << e.what();
  }
  scene = two_body_scene();
  BoundarySpec sphere;
  sphere.object = BoundaryObject::Sphere;
  scene.boundaries.push_back(sphere);
  EXPECT_THROW(CpuEngine<double>{scene}, std::invalid_argument);
}

TEST(Api, FrameCarriesRequestedAttributes) {
  Scene scene = two_body_scene();
  scene.bodies[0].output_attribs = {"ID", "Velocity_Y", "DefGrad_XX", "VonMisesStress", "J"};
  scene.bodies[1].output_attribs = {"Pressure", "Mass", "DefGrad_Determinant"};
  CpuEngine<double> engine(scene);
  engine.set_velocities(0, [](const Vec3d& x) { return Vec3d{{0, x[0], 0}}; });
  const io::ParticleFrame f0 = engine.frame(0);
  ASSERT_EQ(f0.size(), engine.particle_count(0));
  ASSERT_NE(f0.find("ID"), nullptr);
  EXPECT_EQ(f0.find("ID")->ints()[5], 5);
  EXPECT_FLOAT_EQ(f0.find("Velocity_Y")->floats()[7], static_cast<float>(engine.positions(0)[7][0]));
  EXPECT_FLOAT_EQ(f0.find("DefGrad_XX")->floats()[0], 1.0f);
  EXPECT_FLOAT_EQ(f0.find("VonMisesStress")->floats()[0], 0.0f);
  const io::ParticleFrame f1 = engine.frame(1);
  EXPECT_NE(f1.find("J"), nullptr);  // alias DefGrad_Determinant -> J
  EXPECT_FLOAT_EQ(f1.find("Mass")->floats()[0], static_cast<float>(1000.0 * 0.05 * 0.05 * 0.05 / 8));
}

// run_cpu: frames 0..frames written with ClaymoreUW's names; a failure is exit code 2 with a message naming the body.
TEST(Api, RunCpuWritesFramesAndReportsFailures) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "fbar_test_run_cpu";
  std::filesystem::remove_all(dir);
  Scene scene = two_body_scene();
  scene.simulation.save_path = dir.string();
  scene.simulation.save_suffix = ".csv";
  scene.simulation.frames = 2;
  scene.simulation.fps = 100;
  scene.bodies[1].model = 1;
  std::ostringstream log;
  RunResult r = run_cpu(scene, RunOptions{false, &log});
  EXPECT_EQ(r.exit_code, 0) << r.message << log.str();
  EXPECT_NEAR(r.end_time, 0.02, 1e-15);
  for (int f = 0; f <= 2; ++f) {
    EXPECT_TRUE(std::filesystem::exists(dir / ("model[0]_dev[0]_frame[" + std::to_string(f) + "].csv")));
    EXPECT_TRUE(std::filesystem::exists(dir / ("model[1]_dev[0]_frame[" + std::to_string(f) + "].csv")));
  }
  EXPECT_NE(log.str().find("frame 2/2"), std::string::npos) << log.str();

  scene.bodies[1].velocity = {0, 0, 1e3};  // 1000 m/s leaves the 1 m domain within the first frame
  scene.simulation.default_dt = 1e-3;
  std::ostringstream log2;
  r = run_cpu(scene, RunOptions{true, &log2});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.message.find("body 1"), std::string::npos) << r.message;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fbar

namespace fbar {
namespace {

// The GPU memory plan of --check (memory_plan.h): frames cost N (3 sizeof(T) + 4 per float attribute); the
// per-particle figure of a compact single-precision JFluid body is at most 135 B with frames of its positions (120 B
// with float grid sums; their int64 words, grid_buffer.cuh "Order-free grid sums", add 9.6 B at this size); a
// device too small gets a message naming a coarser dx, fewer ppc and more GPUs, and none when it fits.
TEST(Summary, GpuPlanCountsFramesAndNamesWhatFits) {
  Scene scene = empty_scene(r3(1, 1, 1), 0.02, r3(0, -9.81, 0));
  scene.bodies.push_back(box_body(Constitutive::JFluid, r3(0.1, 0.1, 0.1), r3(0.8, 0.8, 0.8)));
  scene.simulation.precision = Precision::Single;
  scene.bodies[0].output_attribs = {"ID"};
  SummaryOptions no_frames;
  no_frames.frames = false;
  const SceneSummary bare = summarize_scene(scene, no_frames);
  const SceneSummary with = summarize_scene(scene);
  const long long n = with.bodies[0].particles;
  ASSERT_EQ(n, 40LL * 40 * 40 * 8);
  EXPECT_EQ(with.gpu_plans[0].frames, static_cast<std::size_t>(n) * 12);
  EXPECT_EQ(with.gpu_bytes[0] - bare.gpu_bytes[0], static_cast<std::size_t>(n) * 12);
  scene.bodies[0].output_attribs = {"ID", "Pressure", "Velocity_Magnitude"};
  EXPECT_EQ(summarize_scene(scene).gpu_plans[0].frames, static_cast<std::size_t>(n) * (12 + 8));
  EXPECT_LE(static_cast<double>(with.gpu_bytes[0]) / static_cast<double>(n), 135.0);
  const DeviceMemoryPlan& plan = with.gpu_plans[0];
  EXPECT_TRUE(memory_fit_message(plan, plan.total() + 1, plan.total() * 2, scene, "GPU 0").empty());
  const std::string m = memory_fit_message(plan, plan.total() / 3, plan.total(), scene, "GPU 0");
  EXPECT_NE(m.find("default_dx 0.02 -> "), std::string::npos) << m;
  EXPECT_NE(m.find("ppc 8 -> 2"), std::string::npos) << m;
  EXPECT_NE(m.find("4 GPUs"), std::string::npos) << m;
  EXPECT_GT(with.host_setup_bytes, 0u);
  EXPECT_LT(with.host_setup_bytes, static_cast<std::size_t>(n) * 100);
}

}  // namespace
}  // namespace fbar
