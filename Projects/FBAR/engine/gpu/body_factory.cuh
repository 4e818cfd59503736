// The Body<M> of one scene material (device_bodies.cuh): included only by the translation units that compile a law's
// bodies, instances/bodies_<law>.cu, so that no other unit instantiates a law's kernels. The driver's add_body
// (engine_setup.cuh) calls new_body<M>, which the linker finds in the law's unit.
#pragma once

#include "engine/gpu/body.cuh"

namespace fbar {

template <typename T, typename TG>
template <typename M>
std::unique_ptr<typename MgspBenchmark<T, TG>::BodyBase> MgspBenchmark<T, TG>::new_body(
    const MaterialSpec& mat, const HydrostaticProfile& hydrostatic, const Aabb& geometry_bounds) const {
  auto body = std::make_unique<Body<M>>();
  body->params = M::template make_params<T>(mat);
  body->rest_wave_speed = static_cast<double>(M::wave_speed(M::template make_params<double>(mat),
                                                            M::template reference_state<double>()));
  if (hydrostatic.active) {  // the deepest particle's sound speed
    double deepest = 0.0;
    for (int c = 0; c < 8; ++c) {
      Vec3d corner;
      for (int d = 0; d < 3; ++d) corner[d] = (c >> d) & 1 ? geometry_bounds.hi[d] : geometry_bounds.lo[d];
      deepest = std::max(deepest, hydrostatic.kirchhoff_pressure(corner));
    }
    const auto params_d = M::template make_params<double>(mat);
    body->rest_wave_speed = std::max(
        body->rest_wave_speed,
        static_cast<double>(M::wave_speed(params_d, material_hydrostatic_state<M, double>(params_d, deepest))));
  }
  return body;
}

}  // namespace fbar

/// The bodies of law M at every precision: instances/bodies_<law>.cu says FBAR_GPU_BODIES_OF(M); inside namespace fbar.
#define FBAR_GPU_BODIES_OF(M)                                                                                    \
  template std::unique_ptr<MgspBenchmark<float, float>::BodyBase> MgspBenchmark<float, float>::new_body<M>(     \
      const MaterialSpec&, const HydrostaticProfile&, const Aabb&) const;                                      \
  template std::unique_ptr<MgspBenchmark<double, double>::BodyBase> MgspBenchmark<double, double>::new_body<M>( \
      const MaterialSpec&, const HydrostaticProfile&, const Aabb&) const;                                      \
  template std::unique_ptr<MgspBenchmark<double, float>::BodyBase> MgspBenchmark<double, float>::new_body<M>(   \
      const MaterialSpec&, const HydrostaticProfile&, const Aabb&) const
