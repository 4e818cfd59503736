// Output attributes as values: which quantity a frame column holds and its formula, host and device (the CPU
// engine's frames and the GPU engine's frame kernel evaluate the same function).
#pragma once

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/materials/material_common.cuh"

namespace fbar {

/// What one output attribute is, resolved once from its name (both engines; the GPU evaluates it in a kernel).
enum class FrameQuantity : int {
  Id, Mass, Volume, Position, Velocity, VelocityMagnitude, J, LogJp, DefGrad, Pressure, VonMises, Stress
};

/// One output attribute: quantity and component (axis for Position / Velocity, row and column for tensors).
struct FrameColumn {
  FrameQuantity quantity = FrameQuantity::Id;
  int row = 0;
  int col = 0;
};

/// The per-particle values an attribute may read.
template <typename T>
struct FrameInputs {
  Vec3<T> x;       ///< [m]
  Vec3<T> v;       ///< [m/s]
  T mass;          ///< [kg]
  T volume0;       ///< [m^3]
  T J;             ///< [-]
  T logJp;         ///< [-]
  Mat3<T> F;       ///< [-]
  Mat3<T> sigma;   ///< [Pa] Cauchy stress
};

/// The value of attribute `c` (not Id) of one particle: the one formula both engines write.
template <typename T>
FBAR_HOST_DEVICE inline T frame_value(const FrameColumn& c, const FrameInputs<T>& in) {
  switch (c.quantity) {
    case FrameQuantity::Mass: return in.mass;
    case FrameQuantity::Volume: return in.volume0 * in.J;  // current volume V0 J
    case FrameQuantity::Position: return in.x[c.row];
    case FrameQuantity::Velocity: return in.v[c.row];
    case FrameQuantity::VelocityMagnitude: return norm(in.v);
    case FrameQuantity::J: return in.J;
    case FrameQuantity::LogJp: return in.logJp;
    case FrameQuantity::DefGrad: return in.F(c.row, c.col);
    case FrameQuantity::Pressure: return mean_pressure(in.sigma);
    case FrameQuantity::VonMises: return von_mises_stress(in.sigma);
    case FrameQuantity::Stress: return in.sigma(c.row, c.col);
    case FrameQuantity::Id: break;
  }
  return T(0);
}

/// Most float columns of one body's frame (every attribute of attributes.h but ID: 31).
inline constexpr int kMaxFrameColumns = 32;

}  // namespace fbar
