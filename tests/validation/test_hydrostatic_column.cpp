// Validation: hydrostatic JFluid column (docs/validation.md; the cb-geo benchmark) at two resolutions.
// The problem, its reference and the run are in hydrostatic_column_case.h; the tests here run it on the CPU engine.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "hydrostatic_column_case.h"

namespace fbar {
namespace {

using namespace hydrostatic_case;

// Equilibrium start, bed on the zero-velocity plane: the engine's discrete equilibrium is the exact hydrostatic field.
// Why it must be exact: every free node's support is complete (validation_support.h), and the MLS node force of a
// particle pressure field p(y) is sum_p V p_p D^-1 (x_i - x_p) w_ip; on the 2-per-cell lattice the B-spline moments
// are sum w d = sum w d^3 = 0 and D^-1 sum w d^2 = sum w, so the node force of any p quadratic in y equals the exact
// weight of the node's mass (the Tait curvature of p(y) is quadratic to 1e-6). Only the top particle row (free
// surface, truncated support) is out of balance, by a fraction of rho0 g dx/4 Pa, which sets off a tiny acoustic
// disturbance. Expected base error: zero up to that disturbance (measured < 1e-6).
// Tolerance 1e-4 on the bottom row: 100x the measured value, and 200x tighter than cb-geo's 2.33 %, so any O(dx)
// discretisation error of the bulk (>= 1e-2 at these resolutions) or a wrong force scaling (D^-1, V0, mass
// rescaling of set_volume_ratios) fails it. Kinetic energy: the state is a rest state; 1e-9 m g H allows the surface
// disturbance (measured 1.5e-11) and nothing dynamic; it must not grow (last fifth <= first fifth).
// (With the bed on the last wall node plane instead, the same start leaves +11 % in the bottom cell at both dx:
// docs/validation.md.)
TEST(HydrostaticColumn, EquilibriumStartIsDiscreteEquilibrium) {
  const ColumnResult coarse = run_column<double>(0.01, Start::Equilibrium, 0.3, validation::WallFit::ZeroVelocityPlane);
  const ColumnResult fine = run_column<double>(0.005, Start::Equilibrium, 0.3, validation::WallFit::ZeroVelocityPlane);
  ASSERT_TRUE(coarse.ok && fine.ok);
  for (const ColumnResult* r : {&coarse, &fine}) {
    EXPECT_LE(std::fabs(r->base_row_error()), 1e-4);
    EXPECT_LE(r->ke_max, 1e-9 * r->weight_energy);
    EXPECT_LE(r->ke_last, r->ke_first);
  }
  // The remaining error is the free-surface row, one row of 2 H/dx: the RMS must fall with refinement.
  EXPECT_LT(fine.profile_rms, coarse.profile_rms);
}

// The scene's hydrostatic initial state (bodies[].initial_state "hydrostatic", what a user sets) is the same kind of
// discrete equilibrium, with the particles' mass rho0 V0 kept: the Kirchhoff pressure J p = rho0 g (surface - y) is
// linear in y, so the argument above makes the node forces exact. Same tolerances as the equilibrium start, for the
// same reasons (measured: see the printout). Without it the column rings (the stress-free start below: KE ~1e-3 m g H).
TEST(HydrostaticColumn, HydrostaticInitialStateIsDiscreteEquilibrium) {
  const ColumnResult r = run_column<double>(0.01, Start::Hydrostatic, 0.3, validation::WallFit::ZeroVelocityPlane);
  ASSERT_TRUE(r.ok);
  EXPECT_LE(std::fabs(r.base_row_error()), 1e-4);
  EXPECT_LE(r.profile_rms, 1e-3);
  EXPECT_LE(r.ke_max, 1e-9 * r.weight_energy);
  EXPECT_LE(r.ke_last, r.ke_first);
}

// Single precision keeps the equilibrium: the state is stored as 1 - J (~1e-3 here), whose float quantum is 1e-10 of
// J, i.e. 1e-4 Pa of pressure; positions carry 6e-9 m of round-off (1e-6 of a cell). The residual force per step is
// float round-off of m g dt against the stress impulse; over 1400 steps it stays far below the 1e-4 bound of the
// double run, which therefore applies unchanged.
TEST(HydrostaticColumn, EquilibriumStartSinglePrecision) {
  const ColumnResult r = run_column<float>(0.01, Start::Equilibrium, 0.3, validation::WallFit::ZeroVelocityPlane);
  ASSERT_TRUE(r.ok);
  EXPECT_LE(std::fabs(r.base_row_error()), 1e-4);
  EXPECT_LE(r.ke_max, 1e-9 * r.weight_energy);
}

// Stress-free start (cb-geo's procedure), bed on the last wall node plane: gravity loads a stress-free column; the
// period-averaged field is compared with p = rho0 g (H - y_ref), base rho0 g H = 1765.8 Pa exactly.
//  * Asserted: the base pressure read from the bulk profile (least-squares line through the cell means of the middle
//    half of the column, extrapolated to the bed) within cb-geo's first-order errors at the same dx (4.85 % at 0.01,
//    2.33 % at 0.005: fbar must be at least as accurate as the benchmark's method) and decreasing with refinement.
//  * Not converging, asserted by its trend: the particles of the bottom cell. The grid displacement is a C1 quadratic
//    spline whose wall nodes are zero, so it has zero normal slope at the wall, and the first free node lacks half a
//    cell of its support: the bottom cell's mean pressure is off by about +10 % (+9.8 % at dx = 0.01, +9.5 % at
//    0.005; its two rows +0.5 % and +19 %). The layer is ~2 cells thick at any dx: it thins with refinement, its
//    error does not fall. This is the boundary-treatment limitation of node-layer walls with B-splines (Steffen,
//    Wallstedt, Guilkey, Kirby & Berzins 2008, CMES 31(2):107-127: boundary treatment and basis decide spatial
//    convergence; the remedy in the literature is boundary-modified splines). The bed on the zero-velocity plane is
//    worse here (bottom row -82 %, bottom cell -42 %: its first row is frozen into the wall). Since it does not
//    converge, its trend under refinement is asserted (replacing a 15 % guard that had no budget). An error of fixed
//    size in a layer of fixed cell count keeps its sign (the frozen row carries load the fluid above does not:
//    overpressure, e > 0), and the bed force it adds, e dx per unit of rho0 g H, halves with dx (first order):
//    e(0.005) x 0.005 / (e(0.01) x 0.01) in 0.5 +- 10 %. The 10 % is the change of the layer's own error with dx,
//    bounded by its rows' (the frozen row moves by 1.5 % of rho0 g H, 8 % of its +19 %, between the two dx).
//    Measured: +9.85 %, +9.53 %, ratio 0.484. A wall treatment that gets worse at fine dx, or a layer that thickens, fails.
//  * Inside, the two particle rows of a cell alternate by about +-0.1 rho0 g dx around the exact value (a
//    particle-level null-space mode of 2 particles per cell per axis excited by the drop); cell means remove it.
// Kinetic energy: the oscillation may only decay (APIC dissipation, no viscosity): last fifth <= first fifth.
TEST(HydrostaticColumn, StressFreeStartConvergesToHydrostaticBasePressure) {
  const ColumnResult coarse = run_column<double>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  const ColumnResult fine = run_column<double>(0.005, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  ASSERT_TRUE(coarse.ok && fine.ok);
  EXPECT_LE(std::fabs(coarse.base_fit_error()), 0.0485);
  EXPECT_LE(std::fabs(fine.base_fit_error()), 0.0233);
  EXPECT_LT(std::fabs(fine.base_fit_error()), std::fabs(coarse.base_fit_error()));
  const double e_coarse = coarse.cell_error.front(), e_fine = fine.cell_error.front();
  std::printf("[measured] bottom cell error %+.4f (dx 0.01), %+.4f (dx 0.005); bed-force ratio %.3f\n", e_coarse,
              e_fine, e_fine * 0.005 / (e_coarse * 0.01));
  EXPECT_GT(e_coarse, 0.0);
  EXPECT_GT(e_fine, 0.0);
  EXPECT_GE(e_fine * 0.005 / (e_coarse * 0.01), 0.45);
  EXPECT_LE(e_fine * 0.005 / (e_coarse * 0.01), 0.55);
  EXPECT_LE(coarse.ke_last, coarse.ke_first);
  EXPECT_LE(fine.ke_last, fine.ke_first);
}

// The same stress-free column with and without F-bar: the hydrostatic pressure error and the
// checkerboard index of each. The row alternation inside cells described above is a volume mode: F-bar pulls
// both rows of a cell to the cell's J every step, so it must vanish (checkerboard index: RMS over the cells above the bottom
// one of half the difference of their two row means, over rho0 g H), while the base pressure read from the bulk
// keeps cb-geo's accuracy. Tolerances: F-bar's checkerboard below a tenth of the plain run's (the mode is gone, what
// is left is the time-average residue), base error within cb-geo's 4.85 %; the plain run must show the mode.
// Measured (dx 0.01, double, 2026-11-25): checkerboard 0.020 rho0 g H without, 0.00074 with F-bar (both rows start
// each step from the cell's J and differ by one step's own volume change); base error +0.198 % without, +0.039 %
// with.
TEST(HydrostaticColumn, FbarRemovesTheRowCheckerboard) {
  const ColumnResult plain = run_column<double>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  const ColumnResult fbar =
      run_column<double>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane, 1.0);
  ASSERT_TRUE(plain.ok && fbar.ok);
  EXPECT_GT(plain.checkerboard, 1e-3);
  EXPECT_LT(fbar.checkerboard, 0.1 * plain.checkerboard);
  EXPECT_LE(std::fabs(fbar.base_fit_error()), 0.0485);
}

// Precision chart (float J and float grid sums limit the hydrostatic accuracy: single against mixed against
// double): the stress-free column at dx = 0.01 in the three precisions of simulation.precision. Mixed keeps the
// particle state in double and sums the grid in float (CpuEngine<double, float>, as the GPU engine's mixed mode).
// Printed per precision: base error from the bulk profile, profile RMS, checkerboard, and the largest difference of
// the period-averaged row pressures from the double run (rho0 g H).
// Measured: all three give the same base error (+0.1984 %), RMS and checkerboard to 4 digits; the row pressures
// differ from double by 5.6e-8 rho0 g H (mixed) and 4.5e-6 (single). Float grid sums cost the averaged field nothing
// measurable; float particle state (positions and 1 - J rounded every step, 2848 steps) is what single loses.
// Asserted: every precision meets cb-geo's 4.85 %; single within 1e-4 and mixed within 1e-6 of double (about 20x
// the measured values: round-off, never the 2e-3 discretisation error); mixed closer to double than single is.
TEST(HydrostaticColumn, PrecisionChartSingleMixedDouble) {
  const ColumnResult d = run_column<double>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  const ColumnResult m =
      run_column<double, float>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  const ColumnResult f = run_column<float>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  ASSERT_TRUE(d.ok && m.ok && f.ok);
  auto deviation = [&](const ColumnResult& r) {
    double e = 0.0;
    for (std::size_t i = 0; i < r.row_pressure.size(); ++i)
      e = std::max(e, std::fabs(r.row_pressure[i] - d.row_pressure[i]));
    return e / kBasePressure;
  };
  std::printf("precision chart (stress-free column, dx 0.01, %lld steps):\n", d.steps);
  std::printf("  %-7s %12s %12s %12s %16s %8s\n", "prec", "base err %", "profile RMS", "checkerboard",
              "max |p - p_dbl|", "wall s");
  const char* names[3] = {"double", "mixed", "single"};
  const ColumnResult* runs[3] = {&d, &m, &f};
  for (int i = 0; i < 3; ++i)
    std::printf("  %-7s %+12.5f %12.4g %12.4g %16.3g %8.2f\n", names[i], 100 * runs[i]->base_fit_error(),
                runs[i]->profile_rms, runs[i]->checkerboard, deviation(*runs[i]), runs[i]->seconds);
  for (const ColumnResult* r : runs) EXPECT_LE(std::fabs(r->base_fit_error()), 0.0485);
  EXPECT_LE(deviation(m), 1e-6);
  EXPECT_LE(deviation(f), 1e-4);
  EXPECT_LT(deviation(m), deviation(f));
}

}  // namespace
}  // namespace fbar

namespace fbar {
namespace {
using namespace hydrostatic_case;
// ClaymoreUW's nodal F-bar on the stress-free column (psi 1, both variants): the base pressure keeps cb-geo's
// accuracy and the profile fits better than without F-bar, but the row alternation inside cells stays: the
// nodes' average spans two cells and does not tie a cell's two rows to one J (the cell scheme removes it, above).
// Measured (dx 0.01, double, 2026-12-04): base error -0.040 % fused, -0.369 % split; profile RMS 0.0181 and
// 0.0164 rho0 g H (0.042 without F-bar); checkerboard 0.0258 and 0.0261 (0.020 without). Tolerances: cb-geo's
// 4.85 %, the profile RMS below 0.6 of the plain run's, and the checkerboard above half the plain run's (the mode
// is not removed; if it were, this documents the wrong scheme).
TEST(HydrostaticColumn, NodalFbarKeepsTheBasePressureNotTheRowMode) {
  const ColumnResult plain = run_column<double>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane);
  ASSERT_TRUE(plain.ok);
  for (const bool fused : {true, false}) {
    SCOPED_TRACE(fused ? "fused" : "split");
    const ColumnResult r = run_column<double>(0.01, Start::StressFree, 0.6, validation::WallFit::LastWallNodePlane, 1.0,
                                              FbarScheme::Nodal, fused);
    ASSERT_TRUE(r.ok);
    EXPECT_LE(std::fabs(r.base_fit_error()), 0.0485);
    EXPECT_LT(r.profile_rms, 0.6 * plain.profile_rms);
    EXPECT_GT(r.checkerboard, 0.5 * plain.checkerboard);
  }
}
}  // namespace
}  // namespace fbar
