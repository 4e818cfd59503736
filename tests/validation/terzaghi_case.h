// Validation case: Terzaghi's one-dimensional consolidation of a saturated column under its own weight, templated on
// the engine (test_terzaghi.cpp runs it on the CPU engine, tests/engine/gpu/test_validation_gpu.cu on the GPU engine).
//
// Problem: a CoupledUP column of height H = 1 m (rho 2000 kg/m^3 saturated, E 1e7 Pa, nu 0.3, DruckerPrager at
// friction 35 deg, elastic throughout), pore water rhow 1000 kg/m^3, alpha 1, n 0.4, Kf = n K_oed (so that the Biot
// modulus M equals the skeleton's oedometric modulus K_oed = E (1 - nu) / ((1 + nu)(1 - 2 nu)) and the pore
// pressure's fast diffusion, kappa M, sets a time step of thousands, not millions, per consolidation time), grains
// incompressible (Ks 1e13 Pa), in Slip walls two cells wide (a 1-D column), gravity 9.81 m/s^2. It starts with
// `initial_state: "hydrostatic"`: the pore water carries the whole overburden, p = rho g z (z the depth), the skeleton
// nothing. That is an equilibrium (no wave starts), with an excess pore pressure u = p - rhow g z = (rho - rhow) g z
// above the hydrostatic one. The top drains (p = 0), the floor is impermeable.
// Reference: with constant total stress, u obeys du/dt = c_v d2u/dz2, c_v = kappa / (1/M + alpha^2 / K_oed),
// kappa = Kperm / (rhow g0) (Biot's 1-D consolidation, Terzaghi's equation); for the triangular start and a drained
// top, impermeable bottom, u(z, t) = sum_m 2 g' H (-1)^m / M_m^2 sin(M_m z / H) exp(-M_m^2 T), M_m = (2m + 1) pi / 2,
// T = c_v t / H^2, g' = (rho - rhow) g. Kperm is set for c_v = 2 m^2/s (T = 1 at t = 0.5 s).
// Measured (CPU engine, double): the largest error over the particles, relative to g' H, at T = 0.05, 0.2, 0.5, 1:
// dx = H/16: 0.013, 0.017, 0.018, 0.007; dx = H/32: 0.009, 0.011, 0.010, 0.004 (first order: the drained surface
// sits within a cell of the soil's top). Tolerances: 3 % at H/16 and 1.8 % at H/32 (about 1.6 x the measured,
// both inside 5 %), and the error must fall with dx at every time factor.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "validation_support.h"

namespace fbar::terzaghi {

using validation::r3;

constexpr double kH = 1.0, kRho = 2000.0, kRhow = 1000.0, kG = 9.81;
constexpr double kE = 1e7, kNu = 0.3, kPoro = 0.4;
constexpr double kCv = 2.0;  // [m^2/s]

inline double oedometric_modulus() { return kE * (1 - kNu) / ((1 + kNu) * (1 - 2 * kNu)); }

/// Terzaghi's series for the triangular start u0 = g' z (z the depth below the drained top).
inline double series(double z, double T) {
  const double gp = (kRho - kRhow) * kG;
  double u = 0.0;
  for (int m = 0; m < 400; ++m) {
    const double M = (2 * m + 1) * M_PI / 2;
    u += 2 * gp * kH * (m % 2 ? -1.0 : 1.0) / (M * M) * std::sin(M * z / kH) * std::exp(-M * M * T);
  }
  return u;
}

/// Terzaghi's settlement of the particles starting at depth a below the top: the compression of the column under
/// them, w = alpha / K_oed int_a^H (g' z - u) dz, with u the series (int_a^H u dz = sum 2 g' H^2 (-1)^m / M^3
/// cos(M a / H) exp(-M^2 T)).
inline double series_settlement(double a, double T) {
  const double gp = (kRho - kRhow) * kG;
  double sum = 0.0;
  for (int m = 0; m < 400; ++m) {
    const double M = (2 * m + 1) * M_PI / 2;
    sum += 2 * gp * kH * kH * (m % 2 ? -1.0 : 1.0) / (M * M * M) * std::cos(M * a / kH) * std::exp(-M * M * T);
  }
  return (gp * (kH * kH - a * a) / 2 - sum) / oedometric_modulus();
}

/// At each time factor: the largest |u - u_series| / (g' H) over the particles, and the settlement of the particles
/// starting H/8 (within half a cell) below the top against the series, (w - w_series) / w_series.
struct ColumnResult {
  std::vector<double> pressure;
  std::vector<double> settlement;
  std::size_t settlement_particles = 0;  ///< particles the settlement averages (none: the selection missed them)
};

/// The column on `Engine` (CpuEngine<double> or the GPU tests' GpuValidationEngine<double>) in Slip walls placed as
/// `fit` says (validation_support.h WallFit: the soil's faces on the walls' face node planes, or half a cell beyond
/// them so that those planes are the zero-velocity planes); empty after a failed step (reported).
template <typename Engine>
ColumnResult run_column(int cells, const std::vector<double>& factors, validation::WallFit fit) {
  const double dx = kH / cells, w = 2 * dx;
  const double base = -validation::wall_inset(fit, dx);  // the soil's low faces (the walls' box: wall_box)
  Scene scene = validation::make_scene(r3(w + 2 * base, 1.25 * kH, w + 2 * base), dx, r3(0, -kG, 0));
  BodySpec soil = validation::make_body(Constitutive::CoupledUP, kRho);
  MaterialSpec& m = soil.material;
  m.youngs_modulus = kE;
  m.poisson_ratio = kNu;
  m.friction_angle = 35.0;
  m.cohesion = 0.0;
  m.vol_correction = false;
  m.rhow = kRhow;
  m.alpha1 = 1.0;
  m.poro = kPoro;
  m.Kf = kPoro * oedometric_modulus();  // M = K_oed
  m.Ks = 1e13;
  const double storage = m.poro / m.Kf + (m.alpha1 - m.poro) / m.Ks;
  const double kappa = kCv * (storage + 1.0 / oedometric_modulus());
  m.Kperm = kappa * kRhow * kStandardGravity;
  soil.initial_state = InitialState::Hydrostatic;
  validation::add_box(soil, r3(base, base, base), r3(w, kH, w));
  scene.bodies.push_back(soil);
  scene.boundaries.push_back(validation::wall_box(Contact::Slip, r3(base, base, base),
                                                  r3(base + w, validation::kFar, base + w), dx, fit));
  Engine engine(scene);
  engine.set_log(nullptr);
  const double top = base + kH;
  std::vector<double> depth, y0;  // each particle's starting depth and height (slot = ID on one rank)
  for (const Vec3d& x : engine.positions(0)) {
    depth.push_back(top - x[1]);
    y0.push_back(x[1]);
  }
  ColumnResult out;
  const double gp = (kRho - kRhow) * kG;
  for (double T : factors) {
    const double t = T * kH * kH / kCv;
    while (engine.time() < t * (1 - 1e-12)) {
      const StepReport r = engine.step_toward(t);
      if (!r.ok) {
        ADD_FAILURE() << r.message();
        return {};
      }
    }
    const std::vector<double> p = engine.pore_pressures(0);
    const auto& x = engine.positions(0);
    double worst = 0.0, settled = 0.0, expected = 0.0;
    std::size_t selected = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const double u = p[i] - kRhow * kG * depth[i];
      const double e = std::fabs(u - series(depth[i], T)) / (gp * kH);
      worst = std::isnan(e) || std::isnan(worst) ? e : std::max(worst, e);  // a NaN pressure is the worst error
      if (std::fabs(depth[i] - kH / 8) <= 0.5 * dx) {
        settled += y0[i] - x[i][1];
        expected += series_settlement(depth[i], T);
        ++selected;
      }
    }
    out.settlement_particles = selected;
    out.pressure.push_back(worst);
    out.settlement.push_back(settled / expected - 1.0);
  }
  return out;
}

/// Both resolutions on `Engine`, the soil's faces on the walls' node planes, with the tolerances of the file comment.
/// The settlement at H/8 is 2-7 % short of the series next to the side walls (docs/validation.md, "Saturated soil",
/// open; measured +0.8 % to -7.1 % at H/16, +0.2 % to -6.0 % at H/32): it must stay within 8 % of the series, over a
/// selection of particles that is not empty.
template <typename Engine>
void expect_follows_the_series(const char* engine_name) {
  const std::vector<double> factors = {0.05, 0.2, 0.5, 1.0};
  const ColumnResult coarse = run_column<Engine>(16, factors, validation::WallFit::LastWallNodePlane);
  const ColumnResult fine = run_column<Engine>(32, factors, validation::WallFit::LastWallNodePlane);
  ASSERT_EQ(coarse.pressure.size(), factors.size());
  ASSERT_EQ(fine.pressure.size(), factors.size());
  ASSERT_GT(coarse.settlement_particles, 0u) << "no particle starts H/8 under the top (H/16)";
  ASSERT_GT(fine.settlement_particles, 0u) << "no particle starts H/8 under the top (H/32)";
  for (std::size_t k = 0; k < factors.size(); ++k) {
    std::printf("[measured] %s, T = %.2f: max |u - u_series| / (g' H) = %.4f at H/16, %.4f at H/32 (order %.2f); "
                "settlement at H/8 %+.2f %% at H/16, %+.2f %% at H/32\n",
                engine_name, factors[k], coarse.pressure[k], fine.pressure[k],
                std::log2(coarse.pressure[k] / fine.pressure[k]), 100 * coarse.settlement[k], 100 * fine.settlement[k]);
    EXPECT_LE(std::fabs(coarse.settlement[k]), 0.08) << "T = " << factors[k] << " (H/16)";
    EXPECT_LE(std::fabs(fine.settlement[k]), 0.08) << "T = " << factors[k] << " (H/32)";
    EXPECT_LE(coarse.pressure[k], 0.03) << "T = " << factors[k];
    EXPECT_LE(fine.pressure[k], 0.018) << "T = " << factors[k];
    EXPECT_LT(fine.pressure[k], coarse.pressure[k]) << "T = " << factors[k];
  }
}

}  // namespace fbar::terzaghi
