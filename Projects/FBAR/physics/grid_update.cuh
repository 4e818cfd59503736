// Grid node update of explicit MPM: velocity from momentum plus gravity (host and device formula).
#pragma once

#include "MnBase/Math/vec.h"
#include "MnBase/Meta/config.h"

namespace fbar {

/// v_i = p_i / m_i + dt g [m/s] for a node with mass; zero for an empty node (m_i <= 0: no material, no velocity).
/// mass [kg], momentum [kg m/s] (already holding the internal-force impulse from P2G), gravity [m/s^2], dt [s].
/// Boundary projections (boundary.cuh) act on the result.
template <typename T>
FBAR_HOST_DEVICE constexpr Vec3<T> grid_node_velocity(T mass, const Vec3<T>& momentum, const Vec3<T>& gravity, T dt) {
  if (!(mass > T(0))) return Vec3<T>::zero();
  return momentum / mass + gravity * dt;
}

}  // namespace fbar
