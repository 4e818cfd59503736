// Validation: VonMises (J2 plasticity) in a structure, the elastic-perfectly-plastic thick-walled sphere under
// internal pressure (Hill 1950, The Mathematical Theory of Plasticity, ch. V sec. 3; the closed form is exact for any
// Poisson ratio, because spherical symmetry makes the von Mises and Tresca criteria one: sigma_theta - sigma_r =
// sigma_y in the plastic zone).
//
// Problem: inner radius a = 0.1 m, outer radius b = 0.2 m, E = 10 MPa, nu = 0.3, sigma_y = 10 kPa (sigma_y / E =
// 1e-3: small strain, where the closed form holds), rho = 1000 kg/m^3, no gravity. The internal pressure p rises
// smoothly to p_max, then holds. For p between the elastic limit p_e = (2/3) sigma_y (1 - a^3/b^3) = 0.583 sigma_y
// and the collapse pressure p_c = 2 sigma_y ln(b/a) = 1.386 sigma_y, the material yields out to the radius c with
//     p / sigma_y = 2 ln(c/a) + (2/3) (1 - c^3/b^3),
// and the stresses are
//     a <= r <= c (plastic):  sigma_r = -p + 2 sigma_y ln(r/a),               sigma_theta = sigma_r + sigma_y
//     c <= r <= b (elastic):  sigma_r = -(2 sigma_y c^3 / 3) (1/r^3 - 1/b^3),  sigma_theta = (2 sigma_y c^3 / 3)
//                                                                                 (1/(2 r^3) + 1/b^3)
// with the elastic zone's radial displacement u(r) = (r/E) [(1 - 2 nu) A + (1 + nu) B / (2 r^3)], B = 2 sigma_y c^3 / 3,
// A = B / b^3; at the outer surface u(b) = sigma_y (1 - nu) c^3 / (E b^2). The elastic law alone would give u(b) in
// proportion to p, 0.60 of the plastic value at p = 1.2 sigma_y: the displacement measures the plastic zone.
//
// Here: one octant (x, y, z >= the centre), with Slip symmetry planes (Box boundaries holding every node on or behind
// the plane), 8 ppc on a regular lattice (the particles with a <= |x - centre| <= b), APIC, CFL 0.5, double
// precision. The pressure acts on the inner layer of particles (reference radius < a + dx / 2) through the CPU
// engine's particle forces (set_particle_forces): p (pi a^2 / 2) / N_layer each, radially. Mass-proportional damping
// (-zeta m v, zeta = 2 x 0.5 x the breathing frequency) takes the kinetic energy out so that the hold ends at rest;
// it changes no equilibrium. Loading ramp (1 - cos(pi t / T)) / 2 over T = 0.1 s (about 30 breathing periods) keeps
// the loading quasi-static, so the plastic zone grows monotonically as the closed form assumes.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "engine/cpu/cpu_engine.h"
#include "validation_support.h"

namespace fbar {
namespace thick_sphere_case {

using validation::kPi;
using validation::r3;

constexpr double kA = 0.1;      // [m] inner radius
constexpr double kB = 0.2;      // [m] outer radius
constexpr double kE = 1e7;      // [Pa]
constexpr double kNu = 0.3;     // [-]
constexpr double kSy = 1e4;     // [Pa] tensile yield strength
constexpr double kRho = 1000;   // [kg/m^3]
constexpr double kRamp = 0.1;   // [s]
constexpr double kHold = 0.05;  // [s]

/// Plastic radius c [m] of the closed form at internal pressure p [Pa] (a when p <= p_e), by bisection.
inline double plastic_radius(double p) {
  const auto f = [](double c) { return 2 * std::log(c / kA) + 2.0 / 3.0 * (1 - std::pow(c / kB, 3)); };
  if (p / kSy <= f(kA)) return kA;
  double lo = kA, hi = kB;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) < p / kSy ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

/// Closed-form radial and hoop stresses [Pa] at radius r for plastic radius c and pressure p.
inline void exact_stress(double r, double c, double p, double& sr, double& st) {
  if (r <= c) {
    sr = -p + 2 * kSy * std::log(r / kA);
    st = sr + kSy;
  } else {
    const double B = 2 * kSy * c * c * c / 3;
    sr = -B * (1 / (r * r * r) - 1 / (kB * kB * kB));
    st = B * (1 / (2 * r * r * r) + 1 / (kB * kB * kB));
  }
}

/// Closed-form radial displacement [m] of the elastic zone (r >= c); with c = a it is the elastic solution at p_e.
inline double exact_displacement(double r, double c) {
  const double B = 2 * kSy * c * c * c / 3, A = B / (kB * kB * kB);
  return r / kE * ((1 - 2 * kNu) * A + (1 + kNu) * B / (2 * r * r * r));
}

struct SphereResult {
  bool ok = false;
  double pressure = 0;         // [Pa] applied at the end
  double c_exact = 0;          // [m] closed-form plastic radius
  double c_measured = 0;       // [m] largest reference radius of a yielded particle (q >= 0.99 sigma_y)
  double inner_unyielded = 0;  // [-] fraction of the particles with r < c - dx that did not yield (0 expected)
  double outer_yielded = 0;    // [-] fraction of the particles with r > c + dx that yielded (0 expected)
  double ub_exact = 0;         // [m] closed-form u(b)
  double ub_measured = 0;      // [m] mean radial displacement of the outer particle layer (r > b - dx / 2)
  double u_rms = 0;            // [-] RMS over the elastic-zone particles (r > c + dx) of (u - u_exact(r)) / u(b)
  double sr_rms = 0;           // [-] RMS over radial bins away from the loaded layer of (sigma_r - exact) / sigma_y
  double diff_plastic = 0;     // [-] mean (sigma_theta - sigma_r) / sigma_y over the plastic particles (1 exact)
  double ke_end = 0;           // [J] kinetic energy at the end
  // Particles behind each figure above (outer layer, elastic zone, plastic, inside c - dx, outside c + dx; bins).
  int n_outer_layer = 0, n_elastic = 0, n_plastic = 0, n_inner = 0, n_outer = 0, n_bins = 0;
  std::size_t particles = 0;
  long long steps = 0;
  double seconds = 0;
};

/// Runs the octant at grid spacing dx to p_max [Pa]; `yield` [Pa] replaces sigma_y in the material (a large value
/// gives the elastic control run; the closed form stays the plastic one).
inline SphereResult run_sphere(double dx, double p_max, double yield = kSy) {
  validation::Stopwatch clock;
  const double c0 = 4 * dx, size = c0 + kB + 4 * dx;
  Scene scene = validation::make_scene(r3(size, size, size), dx, r3(0, 0, 0));
  BodySpec body = validation::make_body(Constitutive::VonMises, kRho);
  body.material.youngs_modulus = kE;
  body.material.poisson_ratio = kNu;
  body.material.tensile_yield_strength = yield;
  body.material.hardening_modulus = 0.0;
  scene.bodies.push_back(body);
  for (int axis = 0; axis < 3; ++axis) {  // symmetry planes: every node at or behind x_axis = c0 keeps v_axis = 0
    BoundarySpec plane;
    plane.object = BoundaryObject::Box;
    plane.contact = Contact::Slip;
    plane.domain_start = r3(-validation::kFar, -validation::kFar, -validation::kFar);
    plane.domain_end = r3(validation::kFar, validation::kFar, validation::kFar);
    plane.domain_end[axis] = c0;
    scene.boundaries.push_back(plane);
  }

  // The lattice of 8 ppc (2 per cell and axis) inside the shell.
  std::vector<Vec3d> x_ref;
  const int n = static_cast<int>(std::ceil(2 * kB / dx));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const Vec3d d{{(i + 0.5) * dx / 2, (j + 0.5) * dx / 2, (k + 0.5) * dx / 2}};
        const double r = std::sqrt(dot(d, d));
        if (r >= kA && r <= kB) x_ref.push_back(Vec3d{{c0 + d[0], c0 + d[1], c0 + d[2]}});
      }
  CpuEngine<double> engine(scene, {x_ref});
  SphereResult result;
  result.particles = x_ref.size();

  const Vec3d centre{{c0, c0, c0}};
  std::vector<double> r_ref(x_ref.size());
  std::vector<char> loaded(x_ref.size(), 0);
  int layer = 0;
  for (std::size_t p = 0; p < x_ref.size(); ++p) {
    const Vec3d d = x_ref[p] - centre;
    r_ref[p] = std::sqrt(dot(d, d));
    if (r_ref[p] < kA + 0.5 * dx) loaded[p] = 1, ++layer;
  }
  const double area = kPi * kA * kA / 2;  // the octant's inner surface
  const double lambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu)), mu = kE / (2 * (1 + kNu));
  const double wave = std::sqrt((lambda + 2 * mu) / kRho);
  const double zeta = 2 * 0.5 * (wave * kPi / (kB - kA));  // about the breathing mode's angular frequency
  const auto pressure_at = [&](double t) {
    return t >= kRamp ? p_max : p_max * 0.5 * (1 - std::cos(kPi * t / kRamp));
  };
  engine.set_particle_forces(0, [&](std::int64_t id, const Vec3d& x, double t) {
    const std::size_t p = static_cast<std::size_t>(id);
    Vec3d f = engine.velocities(0)[p] * (-zeta * engine.masses(0)[p]);
    if (loaded[p]) {
      const Vec3d d = x - centre;
      f += d * (pressure_at(t) * area / layer / std::sqrt(dot(d, d)));
    }
    return f;
  });
  const StepReport s = engine.advance_to(kRamp + kHold);
  if (!s.ok) {
    ADD_FAILURE() << s.message();
    return result;
  }
  result.steps = engine.steps();
  result.ke_end = engine.kinetic_energy();
  result.pressure = p_max;
  const double c = plastic_radius(p_max);
  result.c_exact = c;
  result.ub_exact = exact_displacement(kB, c);

  const std::vector<Mat3d> sigma = engine.cauchy_stresses(0);
  const std::vector<Vec3d>& x = engine.positions(0);
  double ub = 0, u2 = 0, diff = 0;
  int nb = 0, nu2 = 0, nplastic = 0, inner = 0, inner_bad = 0, outer = 0, outer_bad = 0;
  const int bins = static_cast<int>(std::lround((kB - kA) / (0.5 * dx)));
  std::vector<double> bin_sr(bins, 0.0), bin_r(bins, 0.0);
  std::vector<int> bin_n(bins, 0);
  for (std::size_t p = 0; p < x.size(); ++p) {
    const Vec3d d = x[p] - centre;
    const double r = std::sqrt(dot(d, d));
    const Vec3d e = d * (1 / r);
    const Mat3d& sg = sigma[p];
    const Vec3d se = sg * e;
    const double sr = dot(e, se), st = 0.5 * (sg(0, 0) + sg(1, 1) + sg(2, 2) - sr);
    const double mean = (sg(0, 0) + sg(1, 1) + sg(2, 2)) / 3;
    double ss = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const double dev = sg(i, j) - (i == j ? mean : 0.0);
        ss += dev * dev;
      }
    const bool yielded = std::sqrt(1.5 * ss) >= 0.99 * yield;
    const double u = r - r_ref[p];
    if (yielded) {
      result.c_measured = std::max(result.c_measured, r_ref[p]);
      diff += (st - sr) / kSy, ++nplastic;
    }
    if (r_ref[p] < c - dx) ++inner, inner_bad += !yielded;
    if (r_ref[p] > c + dx) {
      ++outer, outer_bad += yielded;
      const double e_u = (u - exact_displacement(r_ref[p], c)) / result.ub_exact;
      u2 += e_u * e_u, ++nu2;
    }
    if (r_ref[p] > kB - 0.5 * dx) ub += u, ++nb;
    const int bin = std::min(bins - 1, static_cast<int>((r_ref[p] - kA) / (0.5 * dx)));
    bin_sr[bin] += sr, bin_r[bin] += r_ref[p], ++bin_n[bin];
  }
  // An empty particle set gives NaN, which fails every band the tests set (no vacuous pass); the counts are kept.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  result.n_outer_layer = nb, result.n_elastic = nu2, result.n_plastic = nplastic, result.n_inner = inner,
  result.n_outer = outer;
  result.ub_measured = nb ? ub / nb : nan;
  result.u_rms = nu2 ? std::sqrt(u2 / nu2) : nan;
  result.diff_plastic = nplastic ? diff / nplastic : nan;
  result.inner_unyielded = inner ? double(inner_bad) / inner : nan;
  result.outer_yielded = outer ? double(outer_bad) / outer : nan;
  // sigma_r by radial bin (half a cell wide), leaving out the loaded layer and the free surface's bin.
  double s2 = 0;
  int ns = 0;
  for (int i = 2; i < bins - 1; ++i) {
    if (!bin_n[i]) continue;
    double sr_exact, st_exact;
    exact_stress(bin_r[i] / bin_n[i], c, p_max, sr_exact, st_exact);
    const double e_s = (bin_sr[i] / bin_n[i] - sr_exact) / kSy;
    s2 += e_s * e_s, ++ns;
  }
  result.sr_rms = ns ? std::sqrt(s2 / ns) : nan;
  result.n_bins = ns;
  result.seconds = clock.seconds();
  result.ok = true;
  std::printf(
      "thick sphere dx = %g m, p = %.3g sigma_y, yield %.3g Pa: %zu particles, %lld steps, %.1f s; c %.4f m (exact "
      "%.4f), inner unyielded %.3f, outer yielded %.3f; u(b) %.4g m (exact %.4g, ratio %.4f), u rms %.4f; sigma_r rms "
      "%.4f sigma_y; plastic (st - sr)/sy %.4f; KE end %.3g J; particles: %d outer layer, %d elastic, %d plastic, %d inside "
      "c - dx, %d outside c + dx, %d bins\n",
      dx, p_max / kSy, yield, result.particles, result.steps, result.seconds, result.c_measured, c,
      result.inner_unyielded, result.outer_yielded, result.ub_measured, result.ub_exact,
      result.ub_measured / result.ub_exact, result.u_rms, result.sr_rms, result.diff_plastic, result.ke_end, nb, nu2, nplastic, inner, outer, ns);
  return result;
}

}  // namespace thick_sphere_case
}  // namespace fbar
