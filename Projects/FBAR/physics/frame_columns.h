// Output attributes as values: which quantity a frame column holds and its formula, host and device (the CPU
// engine's frames and the GPU engine's frame kernel evaluate the same function).
#pragma once

#include "MnBase/Math/svd.h"
#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"
#include "physics/fbar_nodal.cuh"
#include "physics/materials/material_common.cuh"

namespace fbar {

/// What one output attribute is, resolved once from its name (both engines; the GPU evaluates it in a kernel).
enum class FrameQuantity : int {
  Id, Mass, Volume, Position, Velocity, VelocityMagnitude, J, JBar, LogJp, DefGrad, Pressure, VonMises, Stress,
  StressPK1, StressPK2, StrainSmall, VonMisesStrain, PorePressure
};

/// A tensor column's `row` when it is not a component: an invariant or a principal value (`col` = 0, 1, 2).
inline constexpr int kTensorInvariant = -1;
inline constexpr int kTensorPrincipal = -2;

/// One output attribute: quantity and component (axis for Position / Velocity, row and column for tensors, or
/// kTensorInvariant / kTensorPrincipal with the index in `col`).
struct FrameColumn {
  FrameQuantity quantity = FrameQuantity::Id;
  int row = 0;
  int col = 0;
};

/// The tensor of a tensor quantity (DefGrad F, Stress = Cauchy sigma, StressPK1 P = J sigma F^-T, StressPK2
/// S = F^-1 P, StrainSmall eps = (F + F^T)/2 - I).
template <typename T>
FBAR_HOST_DEVICE inline Mat3<T> frame_tensor(FrameQuantity q, const Mat3<T>& F, const Mat3<T>& sigma, T J) {
  switch (q) {
    case FrameQuantity::DefGrad: return F;
    case FrameQuantity::StressPK1: return sigma * transpose(inverse(F)) * J;
    case FrameQuantity::StressPK2: {
      const Mat3<T> Finv = inverse(F);
      return Finv * sigma * transpose(Finv) * J;
    }
    case FrameQuantity::StrainSmall: return (F + transpose(F)) * T(0.5) - Mat3<T>::identity();
    default: return sigma;
  }
}

/// Component, invariant (I1 = tr A, I2 = (tr(A)^2 - tr(A^2)) / 2, I3 = det A) or principal value of a tensor:
/// eigenvalues of the symmetric tensors (Cauchy, PK2, small strain), singular values of F and PK1 (the principal
/// stretches and nominal stresses; the last carries the sign of det), both largest first.
template <typename T>
FBAR_HOST_DEVICE inline T tensor_value(FrameQuantity q, const Mat3<T>& A, int row, int col) {
  if (row >= 0) return A(row, col);
  if (row == kTensorInvariant) {
    if (col == 0) return trace(A);
    if (col == 1) return T(0.5) * (trace(A) * trace(A) - trace(A * A));
    return determinant(A);
  }
  if (q == FrameQuantity::DefGrad || q == FrameQuantity::StressPK1) return svd(A).sigma[col];
  return symmetric_eigen(A).lambda[col];
}

/// The per-particle values an attribute may read.
template <typename T>
struct FrameInputs {
  Vec3<T> x;       ///< [m]
  Vec3<T> v;       ///< [m/s]
  T mass;          ///< [kg]
  T volume0;       ///< [m^3]
  T J;             ///< [-]
  T jbar;          ///< [-] the J the stress sees: nodal F-bar's JBar, else J
  T logJp;         ///< [-]
  Mat3<T> F;       ///< [-]
  Mat3<T> sigma;   ///< [Pa] Cauchy stress
  T pore_pressure;  ///< [Pa] (saturated materials, kOutputs.pore_pressure)
};

/// Whether a quantity reads the Cauchy stress (then also C, through a rate law's viscous stress).
FBAR_HOST_DEVICE constexpr bool frame_quantity_reads_stress(FrameQuantity q) {
  return q == FrameQuantity::Pressure || q == FrameQuantity::VonMises || q == FrameQuantity::Stress ||
         q == FrameQuantity::StressPK1 || q == FrameQuantity::StressPK2;
}

/// The inputs of frame_value() for one particle of material M (frames, particle sensors, trackers; both engines):
/// the stored state's J, F (identity for a material without F) and logJp, and its Cauchy stress when `sigma` (rate
/// terms read C). nodal: the body runs nodal F-bar and the particle's 1 - JBar is `one_minus_jbar`: JBar is that,
/// and the stress is the one its P2G uses (fbar_stress_state).
template <typename M, typename T>
FBAR_HOST_DEVICE inline FrameInputs<T> particle_frame_inputs(const Vec3<T>& x, const Vec3<T>& v, const Mat3<T>& C,
                                                             const typename M::template State<T>& s,
                                                             const typename M::template Params<T>& material, T mass,
                                                             T volume, bool sigma, bool nodal = false,
                                                             T one_minus_jbar = T(0)) {
  FrameInputs<T> in{};
  in.x = x;
  in.v = v;
  in.mass = mass;
  in.volume0 = volume;
  in.J = M::volume_ratio(s);
  in.jbar = nodal ? T(1) - one_minus_jbar : in.J;
  in.logJp = T(0);
  in.F = Mat3<T>::identity();
  if constexpr (M::kOutputs.deformation_gradient) in.F = s.F;
  if constexpr (M::kOutputs.log_jp) in.logJp = s.logJp;
  if constexpr (M::kOutputs.pore_pressure) in.pore_pressure = s.pore_pressure;
  if (sigma)
    in.sigma = cauchy_stress(M::kirchhoff_stress(material, nodal ? fbar_stress_state<M>(material, s, one_minus_jbar) : s, C));
  return in;
}

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
    case FrameQuantity::JBar: return in.jbar;
    case FrameQuantity::LogJp: return in.logJp;
    case FrameQuantity::PorePressure: return in.pore_pressure;
    case FrameQuantity::DefGrad:
    case FrameQuantity::Stress:
    case FrameQuantity::StressPK1:
    case FrameQuantity::StressPK2:
    case FrameQuantity::StrainSmall:
      return tensor_value(c.quantity, frame_tensor(c.quantity, in.F, in.sigma, in.J), c.row, c.col);
    case FrameQuantity::VonMisesStrain: {  // sqrt(2/3 e:e), e = dev(eps): the equivalent small strain
      using std::sqrt;
      const Mat3<T> e = deviatoric_part(frame_tensor(FrameQuantity::StrainSmall, in.F, in.sigma, in.J));
      return sqrt(T(2) / T(3) * ddot(e, e));
    }
    case FrameQuantity::Pressure: return mean_pressure(in.sigma);
    case FrameQuantity::VonMises: return von_mises_stress(in.sigma);
    case FrameQuantity::Id: break;
  }
  return T(0);
}

/// Most float columns of one body's frame (the GPU's capture table; scene_support.cpp refuses more).
inline constexpr int kMaxFrameColumns = 32;

}  // namespace fbar
