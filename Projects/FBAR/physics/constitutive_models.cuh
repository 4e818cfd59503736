// The materials of fbar: one header per law in materials/, and the compile-time list the engines dispatch on.
//
// Adding a material (docs/developer_guide.md, "Adding a material"):
//   1. write materials/<name>.cuh with a type M providing everything check_material<M>() asserts below:
//        kJsonName, kLaw, kParameters (JSON keys, units, ranges: materials/material_parameters.h),
//        Params<T> (trivially copyable, units documented), State<T> (what a particle stores), kStoredScalars,
//        kOutputs, make_params<T>(MaterialSpec) (host), reference_state<T>(), volume_ratio,
//        kirchhoff_stress(params, state, C) -> StressResult<T>, advance(params, state, C, dt) (the state update
//        with its return mapping), wave_speed(params, state), energy_density(params, state);
//      optional: kAliases (other JSON names), initial_state<T>(MaterialSpec) (a state set by parameters, e.g.
//      logJp0), check(MaterialSpec) -> ParameterProblem (a rule across parameters), hydrostatic_state<T>(params,
//      kirchhoff_pressure) (host: lets bodies[].initial_state be "hydrostatic", engine/hydrostatic.h),
//      wave_speed_order(params, state) with wave_speed_at_order(params, key) (a key that orders states by wave
//      speed, and the wave speed at a key: the GPU then evaluates the wave speed once per particle block, at its
//      largest key, instead of once per particle);
//   2. include it here and append M to MaterialTypes; add its enumerator to Constitutive (scene.h).
// Parsing, validation, --check, the scene writer, Froude scaling, both engines' kernels and particle bins, and the
// output attributes follow from the type. Engines never compare strings: visit_material(law, f) calls f(M{}) for
// the one type whose kLaw matches.
#pragma once

#include <cmath>
#include <cstddef>
#include <iterator>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "MnBase/Meta/type_seq.h"
#include "physics/seed_layout.h"
#include "physics/materials/coupled_up.cuh"
#include "physics/materials/drucker_prager.cuh"
#include "physics/materials/fixed_corotated.cuh"
#include "physics/materials/hencky.cuh"
#include "physics/materials/jfluid.cuh"
#include "physics/materials/material_common.cuh"
#include "physics/materials/material_parameters.h"
#include "physics/materials/nacc.cuh"
#include "physics/materials/neo_hookean.cuh"
#include "physics/materials/von_mises.cuh"
#include "physics/material_spec.h"

namespace fbar {

/// Every material an engine can run, in the order of their variant indices.
using MaterialTypes = type_seq<JFluid, FixedCorotated, NeoHookean, DruckerPrager, NACC, Hencky, VonMises, CoupledUP>;

template <typename M, typename T>
using material_params_t = typename M::template Params<T>;
template <typename M, typename T>
using material_state_t = typename M::template State<T>;

namespace material_detail {
template <typename M, typename = void>
struct has_stress : std::false_type {};
template <typename M>
struct has_stress<M, std::void_t<decltype(M::kirchhoff_stress(std::declval<const material_params_t<M, double>&>(),
                                                              std::declval<const material_state_t<M, double>&>(),
                                                              std::declval<const Mat3<double>&>()))>>
    : std::is_same<decltype(M::kirchhoff_stress(std::declval<const material_params_t<M, double>&>(),
                                                std::declval<const material_state_t<M, double>&>(),
                                                std::declval<const Mat3<double>&>())),
                   StressResult<double>> {};
template <typename M, typename = void>
struct has_advance : std::false_type {};
template <typename M>
struct has_advance<M, std::void_t<decltype(M::advance(std::declval<const material_params_t<M, double>&>(),
                                                      std::declval<const material_state_t<M, double>&>(),
                                                      std::declval<const Mat3<double>&>(), 1.0))>>
    : std::is_same<decltype(M::advance(std::declval<const material_params_t<M, double>&>(),
                                       std::declval<const material_state_t<M, double>&>(),
                                       std::declval<const Mat3<double>&>(), 1.0)),
                   material_state_t<M, double>> {};
template <typename M, typename = void>
struct has_wave_speed : std::false_type {};
template <typename M>
struct has_wave_speed<M, std::void_t<decltype(M::wave_speed(std::declval<const material_params_t<M, double>&>(),
                                                            std::declval<const material_state_t<M, double>&>()))>>
    : std::true_type {};
template <typename M, typename = void>
struct has_wave_speed_order : std::false_type {};
template <typename M>
struct has_wave_speed_order<
    M, std::void_t<decltype(M::wave_speed_order(std::declval<const material_params_t<M, float>&>(),
                                                std::declval<const material_state_t<M, float>&>())),
                   decltype(M::wave_speed_at_order(std::declval<const material_params_t<M, float>&>(), 1.0f))>>
    : std::true_type {};
template <typename M, typename = void>
struct has_energy : std::false_type {};
template <typename M>
struct has_energy<M, std::void_t<decltype(M::energy_density(std::declval<const material_params_t<M, double>&>(),
                                                            std::declval<const material_state_t<M, double>&>()))>>
    : std::true_type {};
template <typename M, typename = void>
struct has_parameters : std::false_type {};
template <typename M>
struct has_parameters<M, std::void_t<decltype(std::size(M::kParameters))>>
    : std::is_same<std::remove_cv_t<std::remove_reference_t<decltype(M::kParameters[0])>>, MaterialParameter> {};
template <typename M, typename = void>
struct has_aliases : std::false_type {};
template <typename M>
struct has_aliases<M, std::void_t<decltype(std::size(M::kAliases))>> : std::true_type {};
template <typename M, typename = void>
struct has_initial_state : std::false_type {};
template <typename M>
struct has_initial_state<M, std::void_t<decltype(M::template initial_state<double>(std::declval<const MaterialSpec&>()))>>
    : std::true_type {};
template <typename M, typename = void>
struct has_state_with_J : std::false_type {};
template <typename M>
struct has_state_with_J<M, std::void_t<decltype(M::template state_with_J<double>(1.0))>> : std::true_type {};
template <typename M, typename = void>
struct has_hydrostatic_state : std::false_type {};
template <typename M>
struct has_hydrostatic_state<M, std::void_t<decltype(M::template hydrostatic_state<double>(
                                    std::declval<const material_params_t<M, double>&>(), 0.0))>> : std::true_type {};
template <typename M, typename = void>
struct has_check : std::false_type {};
template <typename M>
struct has_check<M, std::void_t<decltype(M::check(std::declval<const MaterialSpec&>()))>> : std::true_type {};
template <typename M, typename = void>
struct has_make_params : std::false_type {};
template <typename M>
struct has_make_params<M, std::void_t<decltype(M::template make_params<double>(std::declval<const MaterialSpec&>()))>>
    : std::true_type {};
}  // namespace material_detail

/// Compile-time check that M is a complete material; each missing piece is one readable error.
template <typename M>
constexpr bool check_material() {
  using P = material_params_t<M, float>;
  using S = material_state_t<M, float>;
  static_assert(std::is_trivially_copyable_v<P>, "material Params<T> must be trivially copyable (kernel argument)");
  static_assert(std::is_trivially_copyable_v<S>, "material State<T> must be trivially copyable (particle bins)");
  static_assert(std::is_same_v<std::remove_cv_t<decltype(M::kLaw)>, Constitutive>, "material needs kLaw");
  static_assert(std::is_convertible_v<decltype(M::kJsonName), const char*>, "material needs kJsonName");
  static_assert(M::kStoredScalars >= 4, "material needs kStoredScalars (position + its state)");
  static_assert(std::is_same_v<std::remove_cv_t<decltype(M::kOutputs)>, MaterialOutputs>, "material needs kOutputs");
  static_assert(material_detail::has_parameters<M>::value,
                "material needs kParameters, an array of MaterialParameter (materials/material_parameters.h)");
  static_assert(material_detail::has_make_params<M>::value, "material needs make_params<T>(const MaterialSpec&)");
  static_assert(material_detail::has_stress<M>::value,
                "material needs kirchhoff_stress(Params<T>, State<T>, Mat3<T> C) -> StressResult<T>");
  static_assert(material_detail::has_advance<M>::value,
                "material needs advance(Params<T>, State<T>, Mat3<T> C, T dt) -> State<T> (with its return mapping)");
  static_assert(material_detail::has_wave_speed<M>::value, "material needs wave_speed(Params<T>, State<T>)");
  static_assert(material_detail::has_energy<M>::value, "material needs energy_density(Params<T>, State<T>)");
  return true;
}

namespace material_detail {
template <std::size_t I>
using material_at = typename MaterialTypes::template type<I>;

template <std::size_t... Is>
constexpr bool check_all(std::index_sequence<Is...>) {
  return (check_material<material_at<Is>>() && ...);
}
/// Index of the first listed type for which pred(M{}) holds, or -1 (a fold, no recursion).
template <typename Pred, std::size_t... Is>
int find_index(Pred pred, std::index_sequence<Is...>) {
  int index = -1;
  static_cast<void>(((pred(material_at<Is>{}) ? (index = static_cast<int>(Is), true) : false) || ...));
  return index;
}
template <typename F, std::size_t... Is>
void call_at(int index, F&& f, std::index_sequence<Is...>) {
  static_cast<void>(((index == static_cast<int>(Is) ? (f(material_at<Is>{}), true) : false) || ...));
}
template <std::size_t... Is>
std::string names(std::index_sequence<Is...>) {
  std::string s;
  ((s += (Is == 0 ? "" : ", "), s += material_at<Is>::kJsonName), ...);
  return s;
}
}  // namespace material_detail

static_assert(material_detail::check_all(std::make_index_sequence<MaterialTypes::count>{}));

/// Index in MaterialTypes of the type implementing `law`, or -1 when no engine material implements it.
inline int material_index(Constitutive law) {
  return material_detail::find_index([law](auto m) { return decltype(m)::kLaw == law; },
                                     std::make_index_sequence<MaterialTypes::count>{});
}
/// Index in MaterialTypes of the material whose JSON name is `name` (canonical spelling), or -1.
inline int material_index(std::string_view name) {
  return material_detail::find_index([name](auto m) { return std::string_view(decltype(m)::kJsonName) == name; },
                                     std::make_index_sequence<MaterialTypes::count>{});
}

/// Calls f(M{}) for the material type M with M::kLaw == law; false (f not called) when none implements `law`.
template <typename F>
bool visit_material(Constitutive law, F&& f) {
  const int index = material_index(law);
  material_detail::call_at(index, std::forward<F>(f), std::make_index_sequence<MaterialTypes::count>{});
  return index >= 0;
}

/// Calls f(M{}) for the material whose JSON name is `name`; false (f not called) when none.
template <typename F>
bool visit_material(std::string_view name, F&& f) {
  const int index = material_index(name);
  material_detail::call_at(index, std::forward<F>(f), std::make_index_sequence<MaterialTypes::count>{});
  return index >= 0;
}

/// The state a particle of material M starts in: M::initial_state(spec) when the material has one (a state set by
/// scene parameters such as logJp0), otherwise M::reference_state().
template <typename M, typename T>
material_state_t<M, T> material_initial_state(const MaterialSpec& spec) {
  if constexpr (material_detail::has_initial_state<M>::value)
    return M::template initial_state<T>(spec);
  else
    return M::template reference_state<T>();
}

/// The state of a particle of material M seeded from a file's attributes (physics/seed_layout.h; NaN: not given),
/// starting from `s` (material_initial_state): a material that stores F takes DefGrad_* (or, given only J, the
/// isotropic F = J^(1/3) I); a material whose state is J (state_with_J, JFluid) takes J (or det F); one that stores
/// logJp takes logJp. Host only (both engines seed on the host).
template <typename M, typename T>
material_state_t<M, T> material_seeded_state(material_state_t<M, T> s, const double* seed) {
  const bool has_F = !std::isnan(seed[kSeedDefGrad]);
  const bool has_J = !std::isnan(seed[kSeedJ]);
  Mat3<double> F = Mat3<double>::identity();
  if (has_F)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) F(i, j) = seed[kSeedDefGrad + 3 * i + j];
  if constexpr (M::kOutputs.deformation_gradient) {
    if (!has_F && has_J) F = Mat3<double>::identity() * std::cbrt(seed[kSeedJ]);
    if (has_F || has_J)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) s.F(i, j) = static_cast<T>(F(i, j));
  } else if constexpr (material_detail::has_state_with_J<M>::value) {
    if (has_J || has_F) s = M::template state_with_J<T>(static_cast<T>(has_J ? seed[kSeedJ] : determinant(F)));
  }
  if constexpr (M::kOutputs.log_jp)
    if (!std::isnan(seed[kSeedLogJp])) s.logJp = static_cast<T>(seed[kSeedLogJp]);
  return s;
}

/// A rule across parameters of material M that `spec` breaks (M::check), or an empty problem.
template <typename M>
ParameterProblem material_check(const MaterialSpec& spec) {
  if constexpr (material_detail::has_check<M>::value)
    return M::check(spec);
  else
    return ParameterProblem{};
}

/// Calls f(name) for every other JSON name of material M (M::kAliases, none when absent).
template <typename M, typename F>
void for_each_material_alias(F&& f) {
  if constexpr (material_detail::has_aliases<M>::value)
    for (const char* a : M::kAliases) f(a);
}

/// Calls f(parameter) for each MaterialParameter of the material implementing `law` (none for an unknown law).
template <typename F>
void for_each_material_parameter(Constitutive law, F&& f) {
  visit_material(law, [&](auto m) {
    for (const MaterialParameter& p : decltype(m)::kParameters) f(p);
  });
}

/// Calls f(M{}) for every material of MaterialTypes, in order.
template <typename F>
void for_each_material(F&& f) {
  for (int i = 0; i < static_cast<int>(MaterialTypes::count); ++i)
    material_detail::call_at(i, f, std::make_index_sequence<MaterialTypes::count>{});
}

/// Whether material `law` can start hydrostatic (bodies[].initial_state): it has M::hydrostatic_state(params,
/// kirchhoff_pressure), the state whose Kirchhoff pressure is the given one (JFluid).
inline bool material_has_hydrostatic_state(Constitutive law) {
  bool has = false;
  visit_material(law, [&](auto m) { has = material_detail::has_hydrostatic_state<decltype(m)>::value; });
  return has;
}

/// Whether material `law` carries pore water (IsPoreFluid): its bodies need the seepage channels, which only the CPU
/// engine has in this release (engine_common.cpp check_engine_body, cli.cpp's engine choice).
inline bool material_has_pore_fluid(Constitutive law) {
  bool pore = false;
  visit_material(law, [&](auto m) { pore = IsPoreFluid<decltype(m)>::value; });
  return pore;
}

/// The hydrostatic state of material M at Kirchhoff pressure `tau` [Pa] (host; M must have hydrostatic_state).
template <typename M, typename T>
material_state_t<M, T> material_hydrostatic_state(const material_params_t<M, T>& params, double tau) {
  if constexpr (material_detail::has_hydrostatic_state<M>::value)
    return M::template hydrostatic_state<T>(params, tau);
  else
    return M::template reference_state<T>();
}

/// "JFluid, FixedCorotated": the materials the engines implement, for error messages.
inline std::string supported_material_names() {
  return material_detail::names(std::make_index_sequence<MaterialTypes::count>{});
}

}  // namespace fbar
