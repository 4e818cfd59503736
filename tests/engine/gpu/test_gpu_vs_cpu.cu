// The GPU engine against the CPU reference engine: the same scene, the same initial positions and the same fixed
// dt, N steps, then every particle by ID: position, velocity, J and F; total mass exactly; momentum to
// summation order; the grid mass equals the particle mass (partition of unity).
//
// Why the engines can differ at all: both evaluate the same functions (transfer.cuh, materials, boundary.cuh) in the
// same precision, but the GPU sums node contributions with atomics in an arbitrary order (shared then global),
// nvcc contracts a*b+c into FMAs where the host compiler does not, and the particle order inside a block differs.
// Each step therefore adds a few ulps per quantity, which the dynamics may amplify (stiff fluid: an error in J is
// turned into a pressure impulse). Tolerances, for N = 60 steps:
//   double (eps 1.1e-16): x 1e-13 m, v 1e-12 m/s, J and F 1e-13: ~1e3 eps of O(1) values, room for 60 steps of
//     round-off growth yet far below any modelling error (a wrong weight or term is 1e-3 and more).
//   float (eps 6e-8): x 5e-6 m (1e-4 dx), v 1e-4 m/s (5e-5 of the 2 m/s impact speed), J 2e-5, F 2e-5: 60 steps of
//     O(10) eps per step amplified by the pressure/stress feedback; still far below an off-by-one-node or
//     missing-term error, which moves a particle by O(dx dt) per step.
// Measured on an H100 (first run): float |dx| 1.2e-7 / 2.4e-7 m, |dv| 2.1e-6 / 5.2e-6 m/s, |dJ| 1.2e-7 / 1.7e-6,
// |dF| 1.1e-6; double |dx| 1.1e-16 / 2.2e-16 m, |dv| 3.6e-15 / 2.6e-15 m/s, |dJ| 2.2e-16 / 1.8e-15
// (JFluid / FixedCorotated).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "engine/gpu/gpu_engine.h"
#include "gpu_test_support.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

struct Tolerance {
  double x, v, J, F, momentum_rel, grid_mass_rel;
};
// Plastic laws (DruckerPrager, NACC) amplify round-off more: whether a particle on the yield surface yields in a
// step, and by how much, is decided by the last bits of its trial state, and the plastic increment then changes F
// by the strain increment of the step, not by ulps; the granular flow that follows spreads that difference. The
// same amplification shows in double (measured on an H100 at ac3ad0b, 60 steps: |dF| 3.6e-14 DruckerPrager,
// 1.0e-14 NACC against 1.2e-15 FixedCorotated), which keeps double's 1e-13 tolerances and so checks that the two
// engines compute the same return mapping. In float the same factor (25-150x) lifts the measured differences to
// |dv| 2.3e-4 m/s, |dJ| 2.3e-4, |dF| 2.3e-4, |dlogJp| 2e-5 (DruckerPrager) and |dv| 1e-4, |dJ| 3.4e-5 (NACC):
// float tolerances for plastic laws are 1e-3 for v, J and F and 1e-4 for logJp and momentum. They stay far below
// the physics being compared: the impact strain is rho c_p v / (lambda + 2 mu) = 1000 x 11.6 x 2 / 1.35e5 = 0.17,
// so a wrong or missing term in the return mapping moves F by O(1e-2) and more.
// Mixed precision (T = double particles, TG = float grid): the grid sums and grid velocities round to float, so the
// engines differ by float-sized amounts each step; the elastic float tolerances apply to every law. The plastic
// laws' extra amplification does not: it acts on trial states rounded to float, and mixed keeps them in double.
// Measured on an H100 (60 steps): |dv| 1.5e-6 to 2.5e-6 m/s, |dJ| 9e-8 to 2.4e-7, |dF| 2.3e-7 to 3.6e-7, |dlogJp|
// 3.3e-7 (NACC) for every law, against single's 2.3e-4 m/s / 2e-4 (DruckerPrager).
// CoupledUP starts with the pore water carrying the overburden, so its skeleton sits at zero effective stress, the
// DruckerPrager cone's apex, where rounding decides whether a particle is projected to the tip; its J then differs
// by a step's strain, in mixed precision too (the float grid velocities feed the trial state). Measured on an H200
// (60 steps): mixed |dJ| 5.9e-5, |dF| 6.6e-5, single |dJ| 9.6e-5, |dF| 1.1e-4: mixed gets 3e-4 for J and F. Pore
// pressure, relative to the largest (7.4 kPa): single 1.09e-3, mixed 5.3e-5, double 2.4e-13 (tol_p in compare()).
template <typename T, typename TG = T>
Tolerance tolerance(Constitutive law) {
  if (law == Constitutive::CoupledUP && !std::is_same_v<T, TG>) return {5e-6, 1e-4, 3e-4, 3e-4, 5e-6, 1e-6};
  const bool plastic = law == Constitutive::DruckerPrager || law == Constitutive::NACC || law == Constitutive::VonMises ||
                       law == Constitutive::CoupledUP;
  if constexpr (std::is_same_v<TG, double>) return {1e-13, 1e-12, 1e-13, 1e-13, 1e-12, 1e-13};
  else if (!std::is_same_v<T, TG>) return {5e-6, 1e-4, 2e-5, 2e-5, 5e-6, 1e-6};
  else if (plastic) return {1e-5, 1e-3, 1e-3, 1e-3, 1e-4, 1e-6};
  else return {5e-6, 1e-4, 2e-5, 2e-5, 5e-6, 1e-6};
}

/// Transfer scheme of a comparison: APIC unless alpha or beta are given (PIC-FLIP, FLIP, ASFLIP).
struct Scheme {
  double alpha = 0, beta_min = 0, beta_max = 0;
  bool nodal = false, fused = false;  ///< F-bar's scheme (FBAR_scheme "nodal", FBAR_fused_kernel)
};

template <typename T, typename TG = T>
void compare(Constitutive law, double dt, int steps, const GpuEngineOptions& options = {}, double fbar_psi = 0.0,
             Scheme scheme = {}, const std::function<void(const GpuEngine<T, TG>&)>& inspect = {}) {
  constexpr Precision kPrecision = !std::is_same_v<T, TG>       ? Precision::Mixed
                                   : std::is_same_v<T, double> ? Precision::Double
                                                               : Precision::Single;
  Scene scene = test::small_scene(law, kPrecision);
  scene.bodies[0].algorithm.use_fbar = fbar_psi != 0.0;
  scene.bodies[0].algorithm.fbar_psi = fbar_psi;
  scene.bodies[0].algorithm.use_asflip = scheme.alpha != 0.0 || scheme.beta_min != 0.0 || scheme.beta_max != 0.0;
  scene.bodies[0].algorithm.asflip_alpha = scheme.alpha;
  scene.bodies[0].algorithm.asflip_beta_min = scheme.beta_min;
  scene.bodies[0].algorithm.asflip_beta_max = scheme.beta_max;
  scene.bodies[0].algorithm.fbar_scheme = scheme.nodal ? FbarScheme::Nodal : FbarScheme::Cell;
  scene.bodies[0].algorithm.fbar_fused_kernel = scheme.fused;
  // NACC: a consolidated clay (p0 = kappa sinh(0.8 x 0.3) = 2e4 Pa, about the impact stress rho c v = 2.3e4 Pa), so
  // the impact yields part of the block and hardens it; DruckerPrager (phi 30 deg, volume correction on) yields
  // where the walls shear it.
  if (law == Constitutive::NACC) scene.bodies[0].material.logJp0 = -0.3;
  // CoupledUP: a DruckerPrager skeleton (the elastic constants above) saturated with water that carries its weight at
  // the start (n 0.4, Kf 1e7, Ks 2.2e7: M = 1.5e7 Pa, undrained c = 122 m/s, CFL 0.49 at dt 2e-4 s) and drains
  // through its faces: Kperm 2e-4 m/s gives c_v = kappa M = 0.3 m^2/s, a cell's diffusion length in the 12 ms run,
  // the seepage bound dx^2 / (8 kappa M) = 1.0e-3 s.
  if (law == Constitutive::CoupledUP) {
    MaterialSpec& m = scene.bodies[0].material;
    m.poro = 0.4;
    m.Kf = 1e7;
    m.Ks = 2.2e7;
    m.Kperm = 2e-4;
    scene.bodies[0].initial_state = InitialState::Hydrostatic;
  }
  const auto positions = test::sample_scene(scene);
  CpuEngine<T, TG> cpu(scene, positions);
  GpuEngine<T, TG> gpu(scene, positions, options);
  std::ostringstream log;
  gpu.set_log(&log);
  gpu.set_record_velocities(true);
  ASSERT_EQ(gpu.particle_count(), cpu.particle_count());
  EXPECT_EQ(gpu.total_mass(), cpu.total_mass()) << "per-body mass x count must equal the CPU's sum exactly";
  for (int s = 0; s < steps; ++s) {
    const StepReport rc = cpu.step(dt);
    const StepReport rg = gpu.step(dt);
    ASSERT_TRUE(rc.ok) << rc.message();
    ASSERT_TRUE(rg.ok) << rg.message();
  }
  EXPECT_EQ(gpu.steps(), cpu.steps());
  EXPECT_DOUBLE_EQ(gpu.time(), cpu.time());
  const Tolerance tol = tolerance<T, TG>(law);
  if (fbar_psi != 0.0) {  // F-bar must have changed the run by far more than the engines differ
    Scene plain_scene = scene;
    plain_scene.bodies[0].algorithm.fbar_psi = 0.0;
    CpuEngine<T, TG> plain(plain_scene, positions);
    for (int s = 0; s < steps; ++s) ASSERT_TRUE(plain.step(dt).ok);
    // The nodal scheme's elastic laws keep their own J: its effect is on the volume ratio the stress sees.
    const double effect = test::max_diff_scalar(plain.volume_ratios(0), cpu.jbar_ratios(0));
    std::cout << "[measured] F-bar (psi " << fbar_psi << (scheme.nodal ? ", nodal" : "")
              << ") changes the stressed J by up to " << effect << "\n";
    EXPECT_GT(effect, 100 * tol.J);
  }
  if (scene.bodies[0].algorithm.use_asflip) {  // the scheme must have changed the velocities far beyond tolerance
    Scene plain_scene = scene;
    plain_scene.bodies[0].algorithm.use_asflip = false;
    CpuEngine<T, TG> plain(plain_scene, positions);
    for (int s = 0; s < steps; ++s) ASSERT_TRUE(plain.step(dt).ok);
    const double effect = test::max_diff(plain.velocities(0), cpu.velocities(0));
    std::cout << "[measured] scheme (alpha " << scheme.alpha << ", beta " << scheme.beta_min << ".." << scheme.beta_max
              << ") changes v by up to " << effect << " m/s\n";
    EXPECT_GT(effect, 100 * tol.v);
  }
  const ParticleSnapshot<T> g = gpu.snapshot(0);
  const double ex = test::max_diff(g.x, cpu.positions(0));
  const double ev = test::max_diff(g.v, cpu.velocities(0));
  const double eJ = std::max(test::max_diff_scalar(g.J, cpu.volume_ratios(0)),
                             test::max_diff_scalar(g.jbar, cpu.jbar_ratios(0)));  // JBar: J without nodal F-bar
  double eF = 0.0;
  if (law != Constitutive::JFluid) eF = test::max_diff(g.F, cpu.deformation_gradients(0));
  double eL = 0.0;  // plastic state: compared like J
  if (law == Constitutive::CoupledUP) eL = test::max_diff_scalar(g.logJp, cpu.plastic_log_volumes(0));
  if (law == Constitutive::DruckerPrager || law == Constitutive::NACC) {
    eL = test::max_diff_scalar(g.logJp, cpu.plastic_log_volumes(0));
    const std::vector<T> l = cpu.plastic_log_volumes(0);
    const double initial = scene.bodies[0].material.logJp0;
    long long changed = 0;
    for (T x : l) changed += static_cast<double>(x) != initial;
    std::cout << "[measured] " << to_string(law) << ": logJp changed on " << changed << " of " << l.size()
              << " particles\n";
    EXPECT_GT(changed, 0) << "the scene must exercise the return mapping";
  }
  // Saturated: the pore pressure by particle, relative to the largest; the seepage must have changed it by far more
  // (the same run undrained, Kperm = 0, on the CPU engine).
  if (law == Constitutive::CoupledUP) {
    const std::vector<T> p_cpu = cpu.pore_pressures(0);
    double scale = 0.0;
    for (T p : p_cpu) scale = test::worst(scale, std::fabs(static_cast<double>(p)));
    const double ep = test::max_diff_scalar(g.pore_pressure, p_cpu) / scale;
    Scene undrained_scene = scene;
    undrained_scene.bodies[0].material.Kperm = 0.0;
    CpuEngine<T, TG> undrained(undrained_scene, positions);
    for (int s = 0; s < steps; ++s) ASSERT_TRUE(undrained.step(dt).ok);
    const double effect = test::max_diff_scalar(undrained.pore_pressures(0), p_cpu) / scale;
    const double tol_p = std::is_same_v<TG, double> ? 1e-12 : std::is_same_v<T, TG> ? 5e-3 : 3e-4;
    std::cout << "[measured] " << to_string(kPrecision) << " CoupledUP: pore pressure up to " << scale
              << " Pa, GPU - CPU " << ep << " of it, seepage changes it by " << effect << " of it\n";
    EXPECT_LE(ep, tol_p);
    EXPECT_GT(effect, 100 * tol_p) << "the seepage did not act";
  }
  // Momentum: double sums in ID order on both sides.
  Vec3d pg = Vec3d::zero();
  for (std::size_t p = 0; p < g.v.size(); ++p) pg += g.v[p].template cast<double>() * static_cast<double>(cpu.masses(0)[p]);
  const Vec3d pc = cpu.total_momentum();
  const double e_momentum = max_abs(pg - pc) / std::max(1e-30, static_cast<double>(norm(pc)));
  const double e_grid_mass = std::fabs(gpu.grid_mass() - gpu.total_mass()) / gpu.total_mass();
  std::cout << "[measured] " << to_string(kPrecision) << " "
            << to_string(law) << " after " << steps << " steps: |dx| " << ex << " m, |dv| " << ev << " m/s, |dJ| "
            << eJ << ", |dF| " << eF << ", |dlogJp| " << eL
            << ", momentum rel " << e_momentum << ", grid mass rel " << e_grid_mass << "\n";
  EXPECT_LE(ex, tol.x);
  EXPECT_LE(ev, tol.v);
  EXPECT_LE(eJ, tol.J);
  EXPECT_LE(eF, tol.F);
  EXPECT_LE(eL, (std::is_same_v<T, double> ? tol.J : 1e-4));
  EXPECT_LE(e_momentum, tol.momentum_rel);
  EXPECT_LE(e_grid_mass, tol.grid_mass_rel);
  if (inspect) inspect(gpu);
  // The block did reach the floor (the walls acted). Free fall alone gives every particle v_y = -2 - g t (-2.12 m/s
  // for JFluid's 60 x 2e-4 s, -2.29 m/s for 60 x 5e-4 s), so a bound on the slowest particle proves nothing; the same
  // scene without walls (CPU engine, same steps) is the reference: the walls' impulse on the block, (p_y - p_y,free) /
  // M, must be upward and far beyond the engines' difference (100 tol.v), and so must the largest change of one
  // particle's v_y. Measured on the CPU engine (double, walls of 6809431): impulse / M 0.368 / 1.367 / 1.188 / 1.348
  // m/s and largest particle change 1.38 / 2.14 / 2.03 / 2.17 m/s (JFluid / FixedCorotated / DruckerPrager / NACC).
  {
    Scene free_scene = scene;
    free_scene.boundaries.clear();
    CpuEngine<T, TG> free_fall(free_scene, positions);
    for (int s = 0; s < steps; ++s) ASSERT_TRUE(free_fall.step(dt).ok);
    double m = 0, p_walls = 0, p_free = 0, largest = 0;
    for (std::size_t p = 0; p < free_fall.particle_count(0); ++p) {
      const double mp = static_cast<double>(cpu.masses(0)[p]);
      const double vw = static_cast<double>(cpu.velocities(0)[p][1]), vf = static_cast<double>(free_fall.velocities(0)[p][1]);
      m += mp, p_walls += mp * vw, p_free += mp * vf;
      largest = std::max(largest, vw - vf);
    }
    std::cout << "[measured] " << to_string(law) << ": walls' impulse / M " << (p_walls - p_free) / m
              << " m/s, largest particle v_y change " << largest << " m/s\n";
    EXPECT_GT((p_walls - p_free) / m, 100 * tol.v) << "the walls did not act";
    EXPECT_GT(largest, 100 * tol.v) << "the walls did not act";
  }
}

// dt: JFluid c = sqrt(2e6/1000) = 44.7 m/s, CFL 0.5 dx / c = 5.6e-4 s -> 2e-4 s; 60 steps = 12 ms, 2.4 cm of fall
// at 2 m/s from 9 cm above the floor: the bottom layer (stencils reach 1.5 dx = 7.5 cm of wall) meets the walls.
TEST(GpuVsCpu, JFluidFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::JFluid, 2e-4, 60);
}
TEST(GpuVsCpu, JFluidDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::JFluid, 2e-4, 60);
}
// FixedCorotated E = 1e5, nu = 0.3: c_p = sqrt((lambda + 2 mu)/rho) = 11.6 m/s; dt 5e-4 s (CFL 0.37).
TEST(GpuVsCpu, FixedCorotatedFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::FixedCorotated, 5e-4, 60);
}
TEST(GpuVsCpu, FixedCorotatedDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::FixedCorotated, 5e-4, 60);
}
// Fixed-point P2G (single precision, kernels/g2p2g_kernel.cuh): a stress-free body at rest gives a momentum bound
// of 0 in its initial P2G, so gravity exceeds it in the first step. The step must be repeated with the measured
// bound (p2g_range_repeats >= 1) and the run must still match the CPU engine to the float tolerance above.
TEST(GpuVsCpu, FixedPointBoundRepeatsAStepAndMatchesCpu) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::small_scene(Constitutive::JFluid, Precision::Single, {0.0, 0.0, 0.0});
  const auto positions = test::sample_scene(scene);
  CpuEngine<float> cpu(scene, positions);
  GpuEngine<float> gpu(scene, positions);
  gpu.set_record_velocities(true);
  for (int s = 0; s < 40; ++s) {
    ASSERT_TRUE(cpu.step(2e-4).ok);
    ASSERT_TRUE(gpu.step(2e-4).ok);
  }
  const ParticleSnapshot<float> g = gpu.snapshot(0);
  const Tolerance tol = tolerance<float>(Constitutive::JFluid);
  const double ex = test::max_diff(g.x, cpu.positions(0)), ev = test::max_diff(g.v, cpu.velocities(0));
  std::cout << "[measured] fixed-point bound repeats in 40 steps from rest: " << gpu.p2g_range_repeats() << "; |dx| "
            << ex << " m, |dv| " << ev << " m/s\n";
  EXPECT_GE(gpu.p2g_range_repeats(), 1);
  EXPECT_LE(ex, tol.x);
  EXPECT_LE(ev, tol.v);
  EXPECT_EQ(gpu.steps(), cpu.steps());
}

// NeoHookean, same parameters and dt as FixedCorotated (c_p = 11.6 m/s, CFL 0.37).
TEST(GpuVsCpu, NeoHookeanFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::NeoHookean, 5e-4, 60);
}
TEST(GpuVsCpu, NeoHookeanDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::NeoHookean, 5e-4, 60);
}
// Hencky (the worked example of the developer guide), same constants and dt as FixedCorotated.
TEST(GpuVsCpu, HenckyFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::Hencky, 5e-4, 60);
}
TEST(GpuVsCpu, HenckyDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::Hencky, 5e-4, 60);
}
// VonMises, elastic constants as above, sigma_y = 5 kPa: the landing (rho c_p v = 23 kPa) yields the bottom layers.
TEST(GpuVsCpu, VonMisesFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::VonMises, 5e-4, 60);
}
TEST(GpuVsCpu, VonMisesDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::VonMises, 5e-4, 60);
}
// DruckerPrager and NACC, elastic constants as above (c_p = 11.6 m/s for both: kappa + 4 mu/3 = lambda + 2 mu).
TEST(GpuVsCpu, DruckerPragerFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::DruckerPrager, 5e-4, 60);
}
TEST(GpuVsCpu, DruckerPragerDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::DruckerPrager, 5e-4, 60);
}
// CoupledUP (saturated DruckerPrager skeleton; the water's constants at compare()): 2e-4 s as for JFluid.
TEST(GpuVsCpu, CoupledUPFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::CoupledUP, 2e-4, 60);
}
TEST(GpuVsCpu, CoupledUPDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::CoupledUP, 2e-4, 60);
}
TEST(GpuVsCpu, CoupledUPMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::CoupledUP, 2e-4, 60);
}
TEST(GpuVsCpu, NaccFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::NACC, 5e-4, 60);
}
TEST(GpuVsCpu, NaccDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::NACC, 5e-4, 60);
}
// F-bar (transfer.cuh: J pulled to the cell's mean; the GPU's fbar_cell_sums kernel sums cells with atomics, the CPU in
// particle order): same tolerances as without, and the run must differ from plain MLS-MPM.
TEST(GpuVsCpu, FbarFixedCorotatedFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::FixedCorotated, 5e-4, 60, {}, 1.0);
}
TEST(GpuVsCpu, FbarFixedCorotatedDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::FixedCorotated, 5e-4, 60, {}, 1.0);
}
TEST(GpuVsCpu, FbarJFluidDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::JFluid, 2e-4, 60, {}, 0.5);
}
TEST(GpuVsCpu, FbarDruckerPragerDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::DruckerPrager, 5e-4, 60, {}, 1.0);
}

// PIC-FLIP, FLIP and ASFLIP (transfer.cuh; the GPU keeps particle velocities beside the bins and adds the
// transported momentum with global atomics, the CPU in particle order): same tolerances as APIC.
TEST(GpuVsCpu, PicFlipFixedCorotatedFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::FixedCorotated, 5e-4, 60, {}, 0.0, Scheme{0.95, 0, 0});
}
TEST(GpuVsCpu, PicFlipFixedCorotatedDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::FixedCorotated, 5e-4, 60, {}, 0.0, Scheme{0.95, 0, 0});
}
TEST(GpuVsCpu, FlipJFluidDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::JFluid, 2e-4, 60, {}, 0.0, Scheme{1.0, 0, 0});
}
TEST(GpuVsCpu, AsflipJFluidFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::JFluid, 2e-4, 60, {}, 0.0, Scheme{0.9, 0.05, 0.2});
}
// DruckerPrager with beta_min = beta_max: ASFLIP's beta switches at J = 1 (transfer.cuh), and a cohesionless grain
// projected to the cone's tip has J = 1 to the last bit, so with beta_min != beta_max a 1-ulp difference between the
// engines picks a different beta and moves the particle by (beta_max - beta_min) dt |v_p - v_old| (measured on an
// H100 with 0.05 / 0.2: |dx| 3.8e-5 m, |dv| 4.1e-4 m/s in double). With equal betas the update is continuous.
TEST(GpuVsCpu, AsflipDruckerPragerDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::DruckerPrager, 5e-4, 60, {}, 0.0, Scheme{0.9, 0.1, 0.1});
}
TEST(GpuVsCpu, AsflipFbarNeoHookeanDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::NeoHookean, 5e-4, 60, {}, 1.0, Scheme{0.75, 0.0, 0.1});
}

// ClaymoreUW's nodal F-bar (physics/fbar_nodal.cuh; the GPU's fbar_node_sums kernel sums the nodes with atomics,
// the CPU in particle order), fused and split, an elastic law that keeps its own J and plastic ones stored at JBar,
// with ASFLIP (its expansion test reads JBar): the same tolerances, JBar compared like J.
TEST(GpuVsCpu, NodalFbarFusedJFluidDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::JFluid, 2e-4, 60, {}, 0.9, Scheme{0, 0, 0, true, true});
}
TEST(GpuVsCpu, NodalFbarSplitJFluidFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::JFluid, 2e-4, 60, {}, 0.9, Scheme{0, 0, 0, true, false});
}
TEST(GpuVsCpu, NodalFbarSplitFixedCorotatedDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::FixedCorotated, 5e-4, 60, {}, 1.0, Scheme{0, 0, 0, true, false});
}
TEST(GpuVsCpu, NodalFbarFusedDruckerPragerDouble) {
  FBAR_REQUIRE_DEVICE();
  compare<double>(Constitutive::DruckerPrager, 5e-4, 60, {}, 0.8, Scheme{0, 0, 0, true, true});
}
TEST(GpuVsCpu, NodalFbarAsflipJFluidFloat) {
  FBAR_REQUIRE_DEVICE();
  compare<float>(Constitutive::JFluid, 2e-4, 60, {}, 0.9, Scheme{0.9, 0.05, 0.2, true, true});
}
TEST(GpuVsCpu, NodalFbarSplitNaccMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::NACC, 5e-4, 60, {}, 0.8, Scheme{0, 0, 0, true, false});
}

// Mixed precision (simulation.precision "mixed": particles in double, grid and P2G arena in float, as ClaymoreUW):
// the CPU engine runs the same split (CpuEngine<double, float>), so every law and scheme path of the mixed kernels
// (double payloads rounded into the int32 arena, float grid read into double G2P, float F-bar cell sums, float
// transported momentum) is compared with it.
TEST(GpuVsCpu, JFluidMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::JFluid, 2e-4, 60);
}
TEST(GpuVsCpu, FixedCorotatedMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::FixedCorotated, 5e-4, 60);
}
TEST(GpuVsCpu, NaccMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::NACC, 5e-4, 60);
}
TEST(GpuVsCpu, FbarDruckerPragerMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::DruckerPrager, 5e-4, 60, {}, 1.0);
}
TEST(GpuVsCpu, AsflipFbarNeoHookeanMixed) {
  FBAR_REQUIRE_DEVICE();
  compare<double, float>(Constitutive::NeoHookean, 5e-4, 60, {}, 1.0, Scheme{0.75, 0.0, 0.1});
}

// Capacity growth: 8 grid blocks and 64 bins to start (the block needs ~100 blocks and ~60 bins per layout); the
// engine grows both at run time without a restart and must still match the CPU engine.
// No growth ahead of the steps: whatever the falling block needs beyond the start's capacities grows inside a step
// (GrowthInsideAStepChangesNoBit makes sure one does).
TEST(GpuVsCpu, CapacityGrowthMatchesCpu) {
  FBAR_REQUIRE_DEVICE();
  GpuEngineOptions small;
  small.block_capacity = 8;
  small.bin_capacity = 1;
  small.grow_ahead = false;
  compare<double, double>(Constitutive::JFluid, 2e-4, 30, small, 0.0, {}, [](const GpuEngine<double>& gpu) {
    EXPECT_GT(gpu.active_grid_blocks(), 8u) << "the table did not grow past its start";
    std::cout << "[measured] capacity growth: " << gpu.active_grid_blocks() << " grid blocks, "
              << gpu.partition_redos() << " partitions redone inside a step\n";
  });
}

// Growths inside a step (MgspBenchmark::handle_overflow): 32 one-cell boxes of 8 particles, each alone in its
// particle block and two blocks from the next box along x, move 0.8 dx along x in one step, so half of each box
// crosses into the empty block next to it and the next layout needs 64 bins and new grid blocks. Started with 36
// bins and exactly the grid blocks of the start, and no growth between steps (grow_ahead off), the engine must grow
// inside the step (partition_redos counts it), partition again from the particles' new positions and place every
// particle. Three checks: the run with the growths gives the bits of the same run started with room for everything
// (order-free sums: the growth must not change the answer); that run did not grow; and both follow the CPU engine
// within the float position budget (compare()'s 5e-6 m), at a stable step: the water's bulk modulus is 100 Pa
// (c = 0.32 m/s, c dt / dx = 0.25), so rounding is not amplified by an acoustic instability (at the default
// 2e7 Pa the step is 70 times the acoustic bound and the engines drift apart by 1e-5 m in two steps).
TEST(GpuVsCpu, GrowthInsideAStepChangesNoBit) {
  FBAR_REQUIRE_DEVICE();
  const double speed = 1.0;
  // small_scene's JFluid (dx 0.05 in a 1 m domain), without walls, gravity or viscosity, its block replaced by the
  // boxes below.
  Scene scene = test::small_scene(Constitutive::JFluid, Precision::Single, {speed, 0.0, 0.0}, false);
  scene.simulation.gravity = {0.0, 0.0, 0.0};
  BodySpec& body = scene.bodies[0];
  body.material.viscosity = 0.0;
  body.material.bulk_modulus = 100.0;
  body.output_attribs = {"ID"};
  body.geometry.clear();
  const double dx = scene.simulation.dx;
  // A particle at x belongs to the block of its stencil base minus one, floor((floor(x / dx - 0.5) - 1) / 4): the
  // cells 4q + 4 (x) and 4q + 3 (y, z) keep both particle planes of a cell in block q; 0.8 dx along x moves the
  // upper x plane (4q + 4.75 -> 4q + 5.55) into block q + 1, the lower one (4q + 4.25 -> 4q + 5.05) stays: 32 -> 64
  // blocks, then 32 again after a second step.
  for (int qx : {0, 2})
    for (int cy : {3, 7, 11, 15})
      for (int cz : {3, 7, 11, 15}) {
        GeometrySpec box;
        box.object = GeometryObject::Box;
        box.span = {dx, dx, dx};
        box.offset = {(4 * qx + 4) * dx, cy * dx, cz * dx};
        body.geometry.push_back(box);
      }
  const auto positions = test::sample_scene(scene);
  ASSERT_EQ(positions[0].size(), 32u * 8u);
  GpuEngineOptions roomy;  // room for every layout and grid of the run: nothing grows
  roomy.block_capacity = 4096;
  roomy.bin_capacity = 4096;
  GpuEngine<float> reference(scene, positions, roomy);
  GpuEngineOptions tight;
  tight.bin_capacity = 36;
  tight.block_capacity = static_cast<int>(reference.active_grid_blocks());  // what the start needs
  tight.grow_ahead = false;
  GpuEngine<float> gpu(scene, positions, tight);
  CpuEngine<float> cpu(scene, positions);
  const double dt = 0.8 * dx / speed;
  for (int step = 0; step < 2; ++step) {
    ASSERT_TRUE(gpu.step(dt).ok) << "step " << step;
    ASSERT_TRUE(reference.step(dt).ok) << "step " << step;
    ASSERT_TRUE(cpu.step(dt).ok) << "step " << step;
    if (step == 0) EXPECT_GE(gpu.partition_redos(), 1) << "the first step did not outgrow the bins";
  }
  EXPECT_EQ(reference.partition_redos(), 0) << "the roomy run grew inside a step";
  EXPECT_EQ(gpu.particle_count(), positions[0].size());
  const ParticleSnapshot<float> g = gpu.snapshot(0), r = reference.snapshot(0);
  ASSERT_EQ(g.x.size(), r.x.size());
  EXPECT_EQ(std::memcmp(g.x.data(), r.x.data(), sizeof(g.x[0]) * g.x.size()), 0) << "positions differ";
  EXPECT_EQ(std::memcmp(g.J.data(), r.J.data(), sizeof(g.J[0]) * g.J.size()), 0) << "J differs";
  const double ex = test::max_diff(g.x, cpu.positions(0));
  std::cout << "[measured] growth inside a step (" << gpu.partition_redos() << " partitions redone): |x_gpu - x_cpu| "
            << ex << " m\n";
  EXPECT_LE(ex, 5e-6) << "NaN fails too";
  double moved = 0.0;  // and the boxes did travel 2 x 0.8 dx
  for (std::size_t i = 0; i < g.x.size(); ++i)
    moved = test::worst(moved, std::fabs(g.x[i][0] - positions[0][i][0] - 1.6 * dx));
  EXPECT_LE(moved, 1e-5);
}

// CFL time step: both engines pick dt themselves; FixedCorotated's wave speed does not depend on the state, so the
// GPU's dt (computed on the device) must equal the CPU's up to the max-speed round-off.
TEST(GpuVsCpu, CflTimeStepMatchesCpu) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::small_scene(Constitutive::FixedCorotated, Precision::Double);
  const auto positions = test::sample_scene(scene);
  CpuEngine<double> cpu(scene, positions);
  GpuEngine<double> gpu(scene, positions);
  for (int s = 0; s < 20; ++s) {
    EXPECT_NEAR(gpu.next_dt(), cpu.next_dt(), 1e-12 * cpu.next_dt()) << "step " << s;
    ASSERT_TRUE(cpu.step().ok);
    ASSERT_TRUE(gpu.step().ok);
  }
  const StepReport rc = cpu.advance_to(cpu.time() + 0.01);
  const StepReport rg = gpu.advance_to(gpu.time() + 0.01);
  ASSERT_TRUE(rc.ok && rg.ok);
  EXPECT_EQ(gpu.time(), cpu.time()) << "advance_to lands exactly on the target";
  EXPECT_EQ(gpu.steps(), cpu.steps());
}

TEST(GpuEngine, FrameMatchesCpuAttributeNames) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::small_scene(Constitutive::JFluid, Precision::Single);
  const auto positions = test::sample_scene(scene);
  CpuEngine<float> cpu(scene, positions);
  GpuEngine<float> gpu(scene, positions);
  gpu.set_record_velocities(true);
  ASSERT_TRUE(cpu.step(2e-4).ok);
  ASSERT_TRUE(gpu.step(2e-4).ok);
  const io::ParticleFrame fc = cpu.frame(0), fg = gpu.frame(0);
  ASSERT_EQ(fc.size(), fg.size());
  ASSERT_EQ(fc.attributes.size(), fg.attributes.size());
  for (std::size_t i = 0; i < fc.attributes.size(); ++i) {
    EXPECT_EQ(fc.attributes[i].name, fg.attributes[i].name);
    EXPECT_EQ(fc.attributes[i].unit, fg.attributes[i].unit);
    EXPECT_EQ(fc.attributes[i].width, fg.attributes[i].width);
    EXPECT_EQ(fc.attributes[i].type(), fg.attributes[i].type());
  }
  EXPECT_EQ(fg.find("ID")->ints()[17], 17);
}

}  // namespace
}  // namespace fbar

namespace fbar {
namespace {

std::vector<std::string> read_lines(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

// run_gpu writes the same frames as run_cpu: same files, same header (attribute names and units), one row per
// particle, asynchronously through the writer; positions of frame 2 agree to the float tolerance above.
TEST(GpuEngine, RunGpuWritesFramesLikeRunCpu) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = test::small_scene(Constitutive::JFluid, Precision::Single);
  scene.simulation.fps = 200;
  scene.simulation.frames = 2;
  scene.simulation.save_suffix = ".csv";
  const std::filesystem::path root = std::filesystem::temp_directory_path() / "fbar_gpu_run_test";
  std::filesystem::remove_all(root);
  RunOptions options;
  std::ostringstream log;
  options.log = &log;
  options.quiet = true;
  scene.simulation.save_path = (root / "cpu").string();
  const RunResult rc = run_cpu(scene, options);
  scene.simulation.save_path = (root / "gpu").string();
  const RunResult rg = run_gpu(scene, options);
  ASSERT_EQ(rc.exit_code, 0) << rc.message;
  ASSERT_EQ(rg.exit_code, 0) << rg.message << "\n" << log.str();
  EXPECT_EQ(rg.steps, rc.steps);
  EXPECT_DOUBLE_EQ(rg.end_time, rc.end_time);
  for (int frame = 0; frame <= 2; ++frame) {
    const std::string name = io::frame_file_name(0, 0, frame, ".csv");
    const auto lc = read_lines(root / "cpu" / name);
    const auto lg = read_lines(root / "gpu" / name);
    ASSERT_FALSE(lg.empty()) << "missing GPU frame " << name;
    EXPECT_EQ(lg.size(), lc.size());
    EXPECT_EQ(lg.front(), lc.front()) << "header differs";
    // Frame 0 is the sampled state (v = initial velocity, J = 1, p = 0) in both engines: the same text.
    if (frame == 0) EXPECT_EQ(lg, lc);
  }
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace fbar
