// GridChannels<TG>: the GPU engine's grid channel sets, one owner for all of them, driven by their declarations
// (engine/grid_channels.h kGridSets). Allocation, growth, compaction moves, the step's halo sums and the device bytes
// follow from each set's storage, copies, need and lifetime; the passes reach a set's buffer by its id.
#pragma once

#include <cstddef>
#include <tuple>
#include <type_traits>
#include <utility>

#include "engine/grid_channels.h"
#include "engine/gpu/grid_buffer.cuh"

namespace fbar {

/// The buffer type of set S on a grid of scalar TG: fixed-point sums or a block structural of TG values, with the
/// declared channels.
template <typename TG, GridSet S>
struct GridSetBuffer {
  static constexpr GridStorage kStorage = grid_set(S).storage;
  static constexpr int kChannels = grid_set(S).channels;
  static constexpr GridLifetime kLifetime = grid_set(S).lifetime;
  using type = std::conditional_t<kStorage == GridStorage::FixedSum, FixedGridBuffer<TG, kChannels>,
                                  BlockBuffer<typename GridLayout<TG>::template value_block_<kChannels>>>;
  static_assert(type::kBlockBytes == grid_set_block_bytes(grid_set(S), sizeof(TG)),
                "a GPU buffer's block is the size kGridSets declares (memory_plan.cpp sizes it from there)");
  static_assert(kLifetime != GridLifetime::AcrossSteps || type::kBlockBytes % 16 == 0,
                "the compaction moves AcrossSteps blocks in 16-byte words");
};

template <typename TG>
class GridChannels {
 public:
  template <GridSet S>
  using Buffer = typename GridSetBuffer<TG, S>::type;

  /// Allocates every set `features` needs at `capacity` blocks (zeroed).
  void allocate(int capacity, GridFeatures features) {
    features_ = features;
    each([&](const GridSetDecl&, auto& buffer, int) { buffer.allocate(capacity); });
  }
  /// New capacity: AcrossSteps and WithinStep sets keep blocks [0, keep) (a growth may come inside a step), PerPass
  /// sets are refilled before their next use; the AcrossSteps sums are zero beyond `keep`.
  void grow(int capacity, int keep, cudaStream_t stream) {
    each([&](const GridSetDecl& d, auto& buffer, int) {
      buffer.grow(capacity, d.lifetime == GridLifetime::PerPass ? 0 : keep, stream);
      if (d.lifetime == GridLifetime::AcrossSteps) buffer.clear(keep, capacity, stream);
    });
  }
  /// For a compaction: move(current, spare, block_bytes) for each AcrossSteps set (its copy `current` holds the
  /// committed sums; the other copy is free until the next P2G clears it).
  template <typename Move>
  void each_carried(int current, Move&& move) {
    each([&](const GridSetDecl& d, auto& buffer, int copy) {
      if (d.lifetime != GridLifetime::AcrossSteps || copy != current) return;
      move(buffer.data(), buffer_of(d.id, 1 - current), buffer.kBlockBytes);
    });
  }
  /// f(decl, data, block_bytes) for copy `copy` of each halo-summed AcrossSteps set: what a step's halo sums.
  template <typename F>
  void each_step_halo(int copy, F&& f) const {
    const_cast<GridChannels*>(this)->each([&](const GridSetDecl& d, auto& buffer, int c) {
      if (d.halo_summed && d.lifetime == GridLifetime::AcrossSteps && c == copy)
        f(d, buffer.data(), buffer.kBlockBytes);
    });
  }
  template <GridSet S>
  Buffer<S>& get(int copy = 0) {
    return std::get<static_cast<int>(S)>(slots_).copy[copy];
  }
  template <GridSet S>
  const Buffer<S>& get(int copy = 0) const {
    return std::get<static_cast<int>(S)>(slots_).copy[copy];
  }
  /// Whether the scene carries set s.
  bool has(GridSet s) const { return features_.has(grid_set(s).need); }
  /// Device bytes of every set.
  std::size_t bytes() const {
    std::size_t total = 0;
    const_cast<GridChannels*>(this)->each([&](const GridSetDecl&, auto& buffer, int) { total += buffer.bytes(); });
    return total;
  }

 private:
  template <GridSet S>
  struct Slot {
    static constexpr int kCopies = grid_set(S).copies;
    Buffer<S> copy[kCopies];
  };
  template <typename Seq>
  struct SlotsOf;
  template <std::size_t... I>
  struct SlotsOf<std::index_sequence<I...>> {
    using type = std::tuple<Slot<static_cast<GridSet>(I)>...>;
  };

  /// f(decl, buffer, copy) for every copy of every set the scene carries, in kGridSets order.
  template <typename F>
  void each(F&& f) {
    each_impl(f, std::make_index_sequence<kGridSetCount>{});
  }
  template <typename F, std::size_t... I>
  void each_impl(F& f, std::index_sequence<I...>) {
    (visit<static_cast<GridSet>(I)>(f), ...);
  }
  template <GridSet S, typename F>
  void visit(F& f) {
    if (!features_.has(grid_set(S).need)) return;
    for (int c = 0; c < grid_set(S).copies; ++c) f(grid_set(S), get<S>(c), c);
  }
  std::byte* buffer_of(GridSet s, int copy) {
    std::byte* out = nullptr;
    each([&](const GridSetDecl& d, auto& buffer, int c) {
      if (d.id == s && c == copy) out = buffer.data();
    });
    return out;
  }

  typename SlotsOf<std::make_index_sequence<kGridSetCount>>::type slots_;
  GridFeatures features_;
};

}  // namespace fbar
