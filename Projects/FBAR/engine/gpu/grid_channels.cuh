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
  static_assert(kLifetime != GridLifetime::AcrossSteps || grid_set(S).copies == 2,
                "an AcrossSteps set is committed in one copy while the step sums the other");
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
  /// Allocates, at `capacity` blocks (zeroed), the sets `more` needs that the scene did not carry yet (a grid sensor
  /// set after the start that reads the nodes' volume); the sets already carried are left as they are.
  void add(GridFeatures more, int capacity) {
    const GridFeatures before = features_;
    features_ = GridFeatures{before.asflip || more.asflip, before.fbar || more.fbar, before.pore || more.pore,
                             before.node_volume || more.node_volume};
    each_slot(*this, [&](const GridSetDecl& d, auto& slot) {
      if (before.has(d.need)) return;
      for (auto& buffer : slot.copy) buffer.allocate(capacity);
    });
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
    each_slot(*this, [&](const GridSetDecl& d, auto& slot) {
      if (d.lifetime != GridLifetime::AcrossSteps) return;
      move(slot.copy[current].data(), slot.copy[1 - current].data(), slot.copy[current].kBlockBytes);
    });
  }
  /// f(decl, data, block_bytes) for copy `copy` of each halo-summed AcrossSteps set: what a step's halo sums.
  template <typename F>
  void each_step_halo(int copy, F&& f) const {
    each_slot(*this, [&](const GridSetDecl& d, const auto& slot) {
      if (d.halo_summed && d.lifetime == GridLifetime::AcrossSteps)
        f(d, slot.copy[copy].data(), slot.copy[copy].kBlockBytes);
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
  /// Device bytes of every set.
  std::size_t bytes() const {
    std::size_t total = 0;
    each_slot(*this, [&](const GridSetDecl&, const auto& slot) {
      for (const auto& buffer : slot.copy) total += buffer.bytes();
    });
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

  /// f(decl, slot) for every set the scene carries, in kGridSets order (self: *this, const or not).
  template <typename Self, typename F>
  static void each_slot(Self& self, F&& f) {
    each_slot_impl(self, f, std::make_index_sequence<kGridSetCount>{});
  }
  template <typename Self, typename F, std::size_t... I>
  static void each_slot_impl(Self& self, F& f, std::index_sequence<I...>) {
    const auto visit = [&](const GridSetDecl& d, auto& slot) {
      if (self.features_.has(d.need)) f(d, slot);
    };
    (visit(grid_set(static_cast<GridSet>(I)), std::get<I>(self.slots_)), ...);
  }
  /// f(decl, buffer, copy) for every copy of every set the scene carries, in kGridSets order.
  template <typename F>
  void each(F&& f) {
    each_slot(*this, [&](const GridSetDecl& d, auto& slot) {
      for (int c = 0; c < d.copies; ++c) f(d, slot.copy[c], c);
    });
  }

  typename SlotsOf<std::make_index_sequence<kGridSetCount>>::type slots_;
  GridFeatures features_;
};

}  // namespace fbar
