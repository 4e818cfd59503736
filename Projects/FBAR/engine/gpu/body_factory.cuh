// The Body<M> of one scene material (body.cuh): included only by the translation units that compile the laws'
// bodies, instances/bodies_slot_<S>.cu, so that no other unit instantiates a law's kernels. The driver's add_body
// (engine_setup.cuh) calls new_body<M>, which the linker finds in the law's slot. Slot S compiles the laws of
// MaterialTypes at indices S, S + kBodySlots and S + 2 kBodySlots: a law appended to MaterialTypes gets a slot with
// no file to edit.
#pragma once

#include <cstddef>
#include <type_traits>

#include "engine/gpu/body.cuh"

namespace fbar {

inline constexpr std::size_t kBodySlots = 8;   ///< instances/bodies_slot_0.cu ... bodies_slot_7.cu
inline constexpr std::size_t kBodyRounds = 3;  ///< laws per slot in FBAR_GPU_BODIES_SLOT
static_assert(MaterialTypes::count <= kBodySlots * kBodyRounds,
              "more laws than the GPU body slots hold: add a round to FBAR_GPU_BODIES_SLOT and raise kBodyRounds");

/// The placeholder of an index past MaterialTypes: its new_body makes nothing and compiles no kernel.
template <std::size_t I>
struct NoLaw {};
template <typename M>
inline constexpr bool kIsNoLaw = false;
template <std::size_t I>
inline constexpr bool kIsNoLaw<NoLaw<I>> = true;

/// The law at index I of MaterialTypes, or NoLaw<I> past its end.
template <std::size_t I>
using law_or_none = std::conditional_t<(I < MaterialTypes::count),
                                       typename MaterialTypes::template type<(I < MaterialTypes::count ? I : 0)>,
                                       NoLaw<I>>;

template <typename T, typename TG>
template <typename M>
std::unique_ptr<typename MgspBenchmark<T, TG>::BodyBase> MgspBenchmark<T, TG>::new_body(
    const MaterialSpec& mat, const HydrostaticProfile& hydrostatic, const Aabb& geometry_bounds) const {
  if constexpr (kIsNoLaw<M>) {
    return nullptr;
  } else {
    return new_law_body<M>(mat, hydrostatic, geometry_bounds);
  }
}

template <typename T, typename TG>
template <typename M>
std::unique_ptr<typename MgspBenchmark<T, TG>::BodyBase> MgspBenchmark<T, TG>::new_law_body(
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

/// The bodies of law M at every precision; inside namespace fbar.
#define FBAR_GPU_BODIES_OF(M)                                                                                    \
  template std::unique_ptr<MgspBenchmark<float, float>::BodyBase> MgspBenchmark<float, float>::new_body<M>(     \
      const MaterialSpec&, const HydrostaticProfile&, const Aabb&) const;                                      \
  template std::unique_ptr<MgspBenchmark<double, double>::BodyBase> MgspBenchmark<double, double>::new_body<M>( \
      const MaterialSpec&, const HydrostaticProfile&, const Aabb&) const;                                      \
  template std::unique_ptr<MgspBenchmark<double, float>::BodyBase> MgspBenchmark<double, float>::new_body<M>(   \
      const MaterialSpec&, const HydrostaticProfile&, const Aabb&) const

/// The laws of slot S (a literal, 0 <= S < kBodySlots) at every precision: instances/bodies_slot_<S>.cu says
/// FBAR_GPU_BODIES_SLOT(S); inside namespace fbar.
#define FBAR_GPU_BODIES_SLOT(S)                   \
  FBAR_GPU_BODIES_OF(law_or_none<(S)>);             \
  FBAR_GPU_BODIES_OF(law_or_none<(S) + kBodySlots>); \
  FBAR_GPU_BODIES_OF(law_or_none<(S) + 2 * kBodySlots>)
