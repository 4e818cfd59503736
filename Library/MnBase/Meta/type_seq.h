// Compile-time lists: type_seq<Ts...> (indexable, concatenable type list), value_seq<T, Vs...> (sums, maxima).
#pragma once

#include <cstddef>
#include <type_traits>
#include <utility>

#include "MnBase/Meta/config.h"

namespace fbar {

namespace detail {

// Indexing without recursion: the list derives from one tagged base per element, and overload
// resolution picks the base whose index matches (constant depth whatever the list length).
template <std::size_t I, typename T>
struct indexed_type {
  using type = T;
};

template <typename Indices, typename... Ts>
struct indexed_types;

template <std::size_t... Is, typename... Ts>
struct indexed_types<std::index_sequence<Is...>, Ts...> : indexed_type<Is, Ts>... {};

template <std::size_t I, typename T>
indexed_type<I, T> select_indexed(indexed_type<I, T>);

}  // namespace detail

/// The I-th type of Ts... (0-based).
template <std::size_t I, typename... Ts>
using type_at_t =
    typename decltype(detail::select_indexed<I>(detail::indexed_types<std::index_sequence_for<Ts...>, Ts...>{}))::type;

/// A list of types: type_seq<A, B>::type<1> is B.
template <typename... Ts>
struct type_seq {
  static constexpr std::size_t count = sizeof...(Ts);

  template <std::size_t I>
  using type = type_at_t<I, Ts...>;

  /// Applies a template to the whole list, e.g. apply<std::tuple>.
  template <template <typename...> class F>
  using apply = F<Ts...>;
};

/// Concatenation of type_seqs: type_seq_cat_t<type_seq<A>, type_seq<B, C>> is type_seq<A, B, C>
/// (e.g. a particle bin's attributes = the material's + the transfer scheme's).
template <typename... Seqs>
struct type_seq_cat {
  using type = type_seq<>;
};
template <typename... As>
struct type_seq_cat<type_seq<As...>> {
  using type = type_seq<As...>;
};
template <typename... As, typename... Bs, typename... Rest>
struct type_seq_cat<type_seq<As...>, type_seq<Bs...>, Rest...> : type_seq_cat<type_seq<As..., Bs...>, Rest...> {};

template <typename... Seqs>
using type_seq_cat_t = typename type_seq_cat<Seqs...>::type;

/// A list of values of type T with its reductions; all constexpr and usable on host and device.
template <typename T, T... Vs>
struct value_seq {
  using value_type = T;
  static constexpr std::size_t count = sizeof...(Vs);
  static constexpr T sum = (T{0} + ... + Vs);

  /// Largest value (T{0} for an empty list, so it can serve as "no alignment requirement").
  static constexpr T max = [] {
    T m{0};
    ((m = Vs > m ? Vs : m), ...);
    return m;
  }();

  /// The i-th value.
  FBAR_HOST_DEVICE static constexpr T at(std::size_t i) {
    const T values[] = {Vs..., T{0}};  // trailing 0 keeps the array non-empty
    return values[i];
  }

  /// Sum of the first i values (exclusive prefix sum): exclusive_sum(0) == 0, exclusive_sum(count) == sum.
  FBAR_HOST_DEVICE static constexpr T exclusive_sum(std::size_t i) {
    const T values[] = {Vs..., T{0}};
    T s{0};
    for (std::size_t k = 0; k < i; ++k) s += values[k];
    return s;
  }
};

}  // namespace fbar
