// One body's output frame from its particle state, for both engines: attribute names, units and formulas in one place.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnSystem/IO/particle_io.h"
#include "scene/attributes.h"
#include "physics/frame_attributes.h"
#include "physics/frame_columns.h"
#include "scene/output_specs.h"
#include "physics/constitutive_models.cuh"
#include "physics/materials/material_common.cuh"
#include "scene/scene.h"

namespace fbar {


/// What a frame reads of one body: particles in ID order (slot p = particle ID p) unless `id` gives each slot's ID
/// (a rank of a decomposed run holds some particles, in any order). The per-particle arrays that
/// cost work to produce (J, F, Cauchy stress) are asked for only when an attribute needs them, once each.
template <typename T>
struct FrameSource {
  const std::vector<Vec3<T>>* x = nullptr;       ///< [m]
  const std::vector<Vec3<T>>* v = nullptr;       ///< [m/s]
  const std::vector<std::int64_t>* id = nullptr; ///< particle ID of each slot; nullptr: the slot index
  std::function<T(std::size_t)> mass;            ///< [kg] of particle p
  std::function<T(std::size_t)> volume0;         ///< [m^3] reference volume of particle p
  std::function<std::vector<T>()> J;             ///< [-]
  std::function<std::vector<T>()> jbar;          ///< [-] the J the stress sees (nodal F-bar's JBar); empty: J
  std::function<std::vector<Mat3<T>>()> F;       ///< [-] (materials that store F)
  std::function<std::vector<Mat3<T>>()> sigma;   ///< [Pa] Cauchy stress
  std::function<std::vector<T>()> logJp;         ///< [-] plastic state (materials with kOutputs.log_jp)
  std::function<std::vector<T>()> pore_pressure; ///< [Pa] (materials with kOutputs.pore_pressure)
};

/// Which inputs a list of attributes reads.
struct FrameNeeds {
  bool J = false, jbar = false, F = false, sigma = false, logJp = false, velocity = false, pore_pressure = false;
};


inline FrameNeeds frame_needs(const std::vector<FrameAttributeSpec>& attributes) {
  FrameNeeds n;
  for (const auto& a : attributes) n.sigma = n.sigma || frame_quantity_reads_stress(a.column.quantity);
  for (const auto& a : attributes) switch (a.column.quantity) {
      case FrameQuantity::Volume:
      case FrameQuantity::J: n.J = true; break;
      case FrameQuantity::JBar: n.jbar = true; break;
      case FrameQuantity::LogJp: n.logJp = true; break;
      case FrameQuantity::PorePressure: n.pore_pressure = true; break;
      case FrameQuantity::DefGrad:
      case FrameQuantity::StrainSmall:
      case FrameQuantity::VonMisesStrain: n.F = true; break;
      case FrameQuantity::StressPK1:
      case FrameQuantity::StressPK2: n.F = n.J = true; break;
      case FrameQuantity::Velocity:
      case FrameQuantity::VelocityMagnitude: n.velocity = true; break;
      default: break;
    }
  return n;
}

/// Float columns of a body's frame (every attribute but ID, which is the particle's index in ID order).
inline int frame_float_columns(const std::vector<FrameAttributeSpec>& attributes) {
  int n = 0;
  for (const auto& a : attributes) n += a.column.quantity != FrameQuantity::Id;
  return n;
}

/// The frame of `spec.output_attribs` (canonical names; an alias and its name count once). `engine` names the
/// engine in the error for an attribute it cannot produce (the release policy refuses those before a run).
/// The surface-only filter of body `body` (io::ExteriorFilter): on when simulation.particles_output_exterior_only or
/// bodies[].output.exterior_only is true; cubes of one grid block (4 dx); bodies[].output.exterior_threshold
/// particles of the body per block (ClaymoreUW's 128 by default).
inline io::ExteriorFilter exterior_filter(const Scene& scene, int body) {
  const BodySpec& spec = scene.bodies[static_cast<std::size_t>(body)];
  if (!scene.simulation.particles_output_exterior_only && !spec.output_exterior_only) return {};
  return io::ExteriorFilter{4.0 * scene.simulation.dx, spec.exterior_threshold};
}

template <typename T>
io::ParticleFrame build_frame(const BodySpec& spec, int body, const FrameSource<T>& src, const std::string& engine) {
  const std::size_t n = src.x->size();
  io::ParticleFrame f;
  if constexpr (std::is_same_v<T, double>) {
    f.positions = *src.x;
  } else {
    f.positions = std::vector<Vec3f>(src.x->begin(), src.x->end());
  }
  const std::vector<FrameAttributeSpec> attributes = frame_attributes(spec, body, engine);
  const FrameNeeds needs = frame_needs(attributes);
  std::vector<T> J, jbar, logJp, pore;
  std::vector<Mat3<T>> F, sigma;
  if (needs.J) J = src.J();
  if (needs.jbar) jbar = src.jbar ? src.jbar() : src.J();
  if (needs.F) F = src.F();
  if (needs.sigma) sigma = src.sigma();
  if (needs.logJp) logJp = src.logJp();
  if (needs.pore_pressure) pore = src.pore_pressure();
  for (const FrameAttributeSpec& a : attributes) {
    if (a.column.quantity == FrameQuantity::Id) {
      std::vector<std::int32_t> ids(n);
      for (std::size_t p = 0; p < n; ++p) ids[p] = static_cast<std::int32_t>(src.id ? (*src.id)[p] : p);
      f.add(a.name, 1, std::move(ids));
      continue;
    }
    std::vector<float> values(n);
    for (std::size_t p = 0; p < n; ++p) {
      FrameInputs<T> in{};
      in.x = (*src.x)[p];
      if (src.v) in.v = (*src.v)[p];
      in.mass = src.mass(p);
      in.volume0 = src.volume0(p);
      if (needs.J) in.J = J[p];
      if (needs.jbar) in.jbar = jbar[p];
      if (needs.logJp) in.logJp = logJp[p];
      if (needs.pore_pressure) in.pore_pressure = pore[p];
      if (needs.F) in.F = F[p];
      if (needs.sigma) in.sigma = sigma[p];
      values[p] = static_cast<float>(frame_value(a.column, in));
    }
    f.add(a.name, 1, std::move(values), a.unit);
  }
  return f;
}

}  // namespace fbar
