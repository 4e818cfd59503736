// Validation: the plastic laws inside the engine against their single-particle reference (docs/validation.md),
// NACC and DruckerPrager.
//
// Problem: a free cube (0.6 m, dx 0.025 m, 8 ppc, no gravity, no walls) given the linear velocity field
// v = L (x - x_c), L = [[-2, 10, 0], [0, -2, 0], [0, 0, -2]] 1/s: compression (-6 /s volumetric rate) with simple shear.
// While the stress is uniform it exerts no force, so every interior particle keeps its velocity: x = x0 + t L (x0 -
// x_c), F = I + t L, and the velocity gradient the grid holds at time t is l = L (I + t L)^-1 (quadratic B-splines
// reproduce a linear field; APIC's C is exact for it). Release waves start at the free faces at t = 0 and travel at
// the P-wave speed c_p; the explicit scheme also carries an exponentially small precursor ahead of the front (each
// step's P2G and G2P reach 1.5 cells each, while the wave moves 0.5 cells). A particle farther than c_p t + 5 dx from
// every face is untouched to within that tail; its state must be what the material's advance() gives a single
// particle driven by C = l(t_n) with the engine's time steps. Measured (double, 13 steps, 4 ms): the DruckerPrager F
// differs from its reference by 5.8e-5 at c_p t + 2 dx, 1.0e-5 at + 3 dx, 2.0e-6 at + 4 dx, 9.2e-7 at + 5 dx (the
// tail); NACC by 1.2e-7 at + 2 dx and 1.1e-7 at + 5 dx. Tolerances at + 5 dx: 1e-5 for F and logJp, 5e-4 of |sigma|
// for the Cauchy stress, 10x the tail; a wrong kinematic (the engine handing advance() another C, F-bar acting, a
// missing return mapping) moves the state by O(1e-3) and more (with C = L instead of l(t): 1.5e-4 in F).
// Shared by the CPU validation test and the GPU engine's (tests/engine/gpu/test_validation_gpu.cu): the run is
// templated on the engine (CpuEngine, or test::GpuValidationEngine with the same queries).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <type_traits>
#include <vector>

#include "physics/constitutive_models.cuh"
#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace element_case {

using validation::r3;

struct ElementResult {
  int interior = 0;
  double F_error = 0, logJp_error = 0, stress_error = 0;  // max over interior particles; stress relative
  double logJp_change = 0;  // how far the reference's plastic state moved (the return mapping acted)
  double plastic_effect = 0;  // |sigma_ref - sigma of the elastic Hencky law on the same path| / |sigma_ref|
  double t = 0;
  long long steps = 0;
  // DruckerPrager without a remembered dilation (logJp0 = 0) only: the closed form of the cone. Plastic flow on the
  // cone keeps the volume (the return scales dev ln s and keeps tr ln s), so the Kirchhoff pressure is the elastic
  // one of the imposed volume, p = -K ln J with J = det(I + t L) = (1 - 2t)^3, and a stress on the cone has
  // q = M p with M = 6 sin(phi) / (3 - sin(phi)) = 1.2 for phi = 30 deg (Mohr-Coulomb's compression meridian): max
  // over interior particles of |p - p_cf| / p_cf and |q - M p_cf| / (M p_cf).
  double closed_form_error = -1;
  // NACC under isotropic compression (shear 0) only: every step returns to the cap, so the state stays at the cap of
  // its hardening, p = p0(logJp), and the volume splits exactly, J_e exp(logJp - logJp0) = J = (1 - 2t)^3. Both give
  // one equation for logJp, p(J exp(logJp0 - logJp)) = p0(logJp), solved here by bisection: the closed-form state.
  // closed_form_error is max |p - p0(logJp*)| / p0(logJp*) and |logJp - logJp*| over interior particles;
  // closed_form_lag the explicit hardening's allowance (the cap moves after the projection: one step's change of p0,
  // relative).
  double closed_form_lag = 0;
  double dt_max = 0;
};

template <typename M, class Engine = CpuEngine<double>>
ElementResult run_element(Constitutive law, double t_end, double logJp0 = 0.0, double shear = 10.0) {
  const double dx = 0.025, half = 0.3;
  Scene scene = validation::make_scene(r3(1, 1, 1), dx, r3(0, 0, 0));
  BodySpec body = validation::make_body(law, 1000.0);
  body.material.youngs_modulus = 1e6;
  body.material.poisson_ratio = 0.3;
  body.material.friction_angle = 30.0;
  body.material.logJp0 = logJp0;
  validation::add_box(body, r3(0.5 - half, 0.5 - half, 0.5 - half), r3(2 * half, 2 * half, 2 * half));
  scene.bodies.push_back(body);
  Engine engine(scene);
  Mat3d L = Mat3d::zero();
  L(0, 0) = L(1, 1) = L(2, 2) = -2.0;
  L(0, 1) = shear;
  const Vec3d centre{{0.5, 0.5, 0.5}};
  engine.set_velocities(0, [&](const Vec3d& x) { return L * (x - centre); });
  const std::vector<Vec3d> x0 = engine.positions(0);

  const auto params = M::template make_params<double>(scene.bodies[0].material);
  auto reference = material_initial_state<M, double>(scene.bodies[0].material);
  const auto elastic_params = Hencky::make_params<double>(scene.bodies[0].material);  // same E, nu, no yield
  auto elastic = Hencky::reference_state<double>();
  const double c = M::wave_speed(params, reference);
  ElementResult r;
  while (engine.time() < t_end) {
    // Force-free motion keeps each particle's velocity, so the spatial velocity gradient at time t is
    // l = L (I + t L)^-1 (x = x0 + t L (x0 - x_c)), and F = I + t L exactly: what the grid hands G2P this step.
    const Mat3d C = L * inverse(Mat3d::identity() + L * engine.time());
    const StepReport s = engine.step();
    if (!s.ok) {
      ADD_FAILURE() << s.message();
      return r;
    }
    r.dt_max = std::max(r.dt_max, engine.last_dt());
    reference = M::advance(params, reference, C, engine.last_dt());
    elastic = Hencky::advance(elastic_params, elastic, C, engine.last_dt());
    ++r.steps;
  }
  r.t = engine.time();
  const double reach = c * r.t + 5 * dx;
  const std::vector<Mat3d> F = engine.deformation_gradients(0);
  const std::vector<double> logJp = engine.plastic_log_volumes(0);
  const std::vector<Mat3d> sigma = engine.cauchy_stresses(0);
  const StressResult<double> ref_stress = M::kirchhoff_stress(params, reference, L);
  const Mat3d ref_sigma = ref_stress.kirchhoff * (1.0 / ref_stress.J);
  const double scale = max_abs(ref_sigma);
  for (std::size_t p = 0; p < x0.size(); ++p) {
    double depth = half;
    for (int a = 0; a < 3; ++a) depth = std::min(depth, half - std::fabs(x0[p][a] - centre[a]));
    if (depth <= reach) continue;
    ++r.interior;
    r.F_error = std::max(r.F_error, max_abs(F[p] - reference.F));
    r.logJp_error = std::max(r.logJp_error, std::fabs(logJp[p] - reference.logJp));
    r.stress_error = std::max(r.stress_error, max_abs(sigma[p] - ref_sigma) / scale);
  }
  if constexpr (std::is_same_v<M, DruckerPrager>) {
    if (logJp0 == 0.0) {
      const MaterialSpec& m = scene.bodies[0].material;
      const double E = m.youngs_modulus, nu = m.poisson_ratio;
      const double K = E / (3 * (1 - 2 * nu));
      const double sphi = std::sin(m.friction_angle * M_PI / 180.0);
      const double slope = 6 * sphi / (3 - sphi);
      const double J_t = std::pow(1 - 2 * r.t, 3);
      const double p_cf = -K * std::log(J_t);
      r.closed_form_error = 0.0;
      for (std::size_t p = 0; p < x0.size(); ++p) {
        double depth = half;
        for (int a = 0; a < 3; ++a) depth = std::min(depth, half - std::fabs(x0[p][a] - centre[a]));
        if (depth <= reach) continue;
        const Mat3d tau = sigma[p] * determinant(F[p]);
        const double pt = -(tau(0, 0) + tau(1, 1) + tau(2, 2)) / 3;
        const Mat3d dev = tau + Mat3d::identity() * pt;
        const double q = std::sqrt(1.5 * ddot(dev, dev));
        r.closed_form_error = std::max({r.closed_form_error, std::fabs(pt - p_cf) / p_cf,
                                        std::fabs(q - slope * p_cf) / (slope * p_cf)});
      }
      std::printf("DruckerPrager element, closed form: p = -K ln J = %.6g Pa, q = M p = %.6g Pa (M = %.4g); max "
                  "relative error %.3g over the interior\n", p_cf, slope * p_cf, slope, r.closed_form_error);
    }
  }
  if constexpr (std::is_same_v<M, NACC>) {
    if (shear == 0.0) {
      const double J_t = std::pow(1 - 2 * r.t, 3);
      const auto g = [&](double lj) { return M::pressure_of_J(params, J_t * std::exp(logJp0 - lj)) - M::cap_pressure(params, lj); };
      double lo = logJp0 + std::log(J_t), hi = logJp0;  // g(lo) < 0 (all of it plastic), g(hi) > 0 (all elastic)
      for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        (g(mid) > 0 ? hi : lo) = mid;
      }
      const double lj_cf = 0.5 * (lo + hi), p_cf = M::cap_pressure(params, lj_cf);
      // One step's volumetric strain, 6 /s x dt, moves logJp at most that much: the cap's change over it.
      r.closed_form_lag = std::fabs(M::cap_pressure(params, lj_cf - 6 * r.dt_max) - p_cf) / p_cf;
      r.closed_form_error = 0.0;
      for (std::size_t p = 0; p < x0.size(); ++p) {
        double depth = half;
        for (int a = 0; a < 3; ++a) depth = std::min(depth, half - std::fabs(x0[p][a] - centre[a]));
        if (depth <= reach) continue;
        const NaccYield<double> y = M::yield(params, F[p], logJp[p]);
        r.closed_form_error = std::max({r.closed_form_error, std::fabs(y.p - p_cf) / p_cf, std::fabs(logJp[p] - lj_cf)});
      }
      std::printf("NACC element, isotropic compression, closed form: logJp* = %.6g, p = p0(logJp*) = %.6g Pa; max "
                  "error %.3g over the interior (explicit hardening's lag %.3g)\n",
                  lj_cf, p_cf, r.closed_form_error, r.closed_form_lag);
    }
  }
  r.logJp_change = std::fabs(reference.logJp - scene.bodies[0].material.logJp0);
  const StressResult<double> el = Hencky::kirchhoff_stress(elastic_params, elastic, L);
  r.plastic_effect = max_abs(el.kirchhoff * (1.0 / el.J) - ref_sigma) / scale;
  std::printf("%s element: %d interior particles after %lld steps (t = %.4g s, c_p t + 5 dx = %.3g m): max |F - F_ref| "
              "%.3g, |logJp - ref| %.3g, stress %.3g of |sigma| = %.4g Pa; reference logJp moved by %.4g, stress %.3g away from elasticity\n",
              M::kJsonName, r.interior, r.steps, r.t, reach, r.F_error, r.logJp_error, r.stress_error, scale,
              r.logJp_change, r.plastic_effect);
  return r;
}

}  // namespace element_case
}  // namespace fbar
