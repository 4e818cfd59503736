// A body's material as the physics reads it: the law and its parameters in SI units (bodies[].material of the
// scene file, after defaults, validation and scaling: scene/scene_parse.cpp). The materials (physics/materials/)
// read this plain description and nothing else of the scene (docs/developer_guide.md "Layers").
#pragma once

#include <limits>
#include <string>

namespace fbar {

enum class Constitutive { JFluid, FixedCorotated, NeoHookean, DruckerPrager, NACC, Hencky, VonMises, CoupledUP };

struct MaterialSpec {
  Constitutive law = Constitutive::JFluid;
  std::string type = "particles";       ///< "particles" | "mesh"
  double ppc = 8.0;                     ///< particles per cell at start
  double cfl = 0.5;                     ///< CFL number of this body, (0, 1]
  double rho = 1000.0;                  ///< [kg/m^3] initial density
  // JFluid (Tait-Murnaghan)
  double bulk_modulus = 2e7;            ///< [Pa]
  double gamma = 7.1;                   ///< [-]
  double viscosity = 1e-3;              ///< [Pa s] dynamic viscosity
  double tension_cutoff = std::numeric_limits<double>::infinity();  ///< [Pa] most tension carried (inf: no cutoff)
  // Elastic solids
  double youngs_modulus = 1e7;          ///< [Pa]
  double poisson_ratio = 0.2;           ///< [-], in [0, 0.5) (negative allowed down to -1)
  // Plasticity (DruckerPrager, NACC)
  double friction_angle = 30.0;         ///< [deg]
  double cohesion = 0.0;                ///< [-] (log-strain cohesion, ClaymoreUW's meaning)
  double logJp0 = 0.0;                  ///< [-]
  double beta = 0.5;                    ///< [-]
  bool vol_correction = true;           ///< DruckerPrager SandVolCorrection
  double xi = 0.8;                      ///< [-] NACC hardening
  bool hardening = true;                ///< NACC hardeningOn
  double tensile_yield_strength = 2e6;  ///< [Pa] VonMises initial yield stress sigma_y (ClaymoreUW default)
  double hardening_modulus = 0.0;       ///< [Pa] VonMises linear isotropic hardening H (ClaymoreUW reads 1e6, then ignores it)
  // Saturated soil (CoupledUP: the DruckerPrager skeleton above and its pore water; ClaymoreUW's keys and defaults)
  double rhow = 1e3;                    ///< [kg/m^3] pore water density
  double alpha1 = 1.0;                  ///< [-] Biot coefficient, poro <= alpha1 <= 1
  double poro = 0.9;                    ///< [-] porosity n, 0 < n < 1 (ClaymoreUW's loader default)
  double Kf = 1e7;                      ///< [Pa] bulk modulus of the pore water
  double Ks = 2.2e7;                    ///< [Pa] bulk modulus of the solid grains
  double Kperm = 1e-5;                  ///< [m/s] hydraulic conductivity (Darcy: q = -Kperm / (rhow g0) (grad p - rhow g))
};

}  // namespace fbar
