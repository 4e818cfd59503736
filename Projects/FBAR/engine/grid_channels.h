// The grid's channel sets, each declared once: what a grid block holds besides the hash table, in both engines.
//
// A channel set is a group of per-node channels that one pass writes and others read (the P2G sums, the grid
// velocity, F-bar's cell sums, the seepage channels, ...). Its declaration below says how it is stored, whether it
// is double-buffered with the P2G, which scenes need it, how long its contents live, whether a decomposed run sums
// its halo blocks, and whether the CPU engine keeps it apart. Everything that sizes or moves grid state follows from
// the table:
//   - the memory plan and --check (engine/memory_plan.cpp grid_channel_bytes, engine_api.cpp's "grid channels" row
//     and the CPU grid's estimate);
//   - the GPU engine's buffers (engine/gpu/grid_channels.cuh GridChannels: allocation, growth, compaction, the
//     step's halo sums, the device bytes), whose block sizes are checked against the table at compile time;
//   - the CPU engine's grid blocks (engine/cpu/cpu_engine.h: their sizes are checked against the table).
// Checkpoints hold no grid channel: a restart sums the AcrossSteps sets again from the particles it reads (the P2G
// record), so a new channel set needs nothing there. Grid sensors read the node values the grid update leaves
// (physics/sensors.cuh); a set a sensor reads names the sensor attribute in `sensor`.
// Adding a channel set: docs/developer_guide.md "Adding a grid channel".
#pragma once

#include <cstddef>
#include <string>

#include "scene/scene.h"

namespace fbar {

/// The channel sets, in the order of kGridSets.
enum class GridSet : int { Sums, Velocity, Transported, OldVelocity, FbarSums, PoreValues, PoreSums };
inline constexpr int kGridSetCount = 7;

/// How a set's values are stored on the GPU.
enum class GridStorage {
  FixedSum,  ///< order-free fixed-point sums: one int64 word per value (float grids) or two (double grids)
  Value,     ///< values of the grid scalar type TG
};

/// Which scenes carry a set.
enum class GridNeed {
  Always,
  Asflip,  ///< some body uses PIC-FLIP / ASFLIP
  Fbar,    ///< some body uses F-bar, or a grid sensor reads Volume or JBar (node_volume)
  Pore,    ///< some body is saturated (CoupledUP)
};

/// How long a set's contents must live, which decides what the grid's growth and compaction do with it.
enum class GridLifetime {
  /// The committed step's P2G sums, read by the next step's grid update: kept when the grid grows and moved with
  /// their blocks when it is compacted. Such a set is double-buffered (copies == 2): the compaction moves the
  /// current copy through the other one.
  AcrossSteps,
  /// Written by the grid update and read by the G2P of the same step: kept when the grid grows (a growth may come
  /// inside a step), left behind by a compaction (it comes between steps; the next grid update rewrites it).
  WithinStep,
  /// Refilled before every use (a pass sums it and the next pass reads it): neither kept nor moved.
  PerPass,
};

/// The scenes' features that decide which sets exist.
struct GridFeatures {
  bool asflip = false;
  bool fbar = false;
  bool pore = false;
  bool node_volume = false;  ///< a grid sensor reads Volume or JBar (the F-bar sums hold the nodes' volume then)
  constexpr bool has(GridNeed n) const {
    return n == GridNeed::Always || (n == GridNeed::Asflip && asflip) || (n == GridNeed::Fbar && (fbar || node_volume)) ||
           (n == GridNeed::Pore && pore);
  }
};

/// One channel: its name and SI unit (in fixed point: of the value a unit stands for).
struct GridChannel {
  const char* name;
  const char* unit;
};

inline constexpr int kMaxGridChannels = 8;

struct GridSetDecl {
  GridSet id;
  const char* name;       ///< for --check and messages
  GridStorage storage;
  int copies;             ///< 2: double-buffered with the P2G (step n reads copy gc and sums into copy 1 - gc)
  GridNeed need;
  GridLifetime lifetime;
  bool halo_summed;       ///< a decomposed run sums its halo blocks with the neighbours (after the pass writing it)
  bool p2g;               ///< a body's particles sum into it (listed per body by --check)
  bool every_body;        ///< when the scene carries it, every body sums into it (not only those that need it)
  bool cpu;               ///< the CPU engine keeps it in blocks of its own (in TG); otherwise in another set's place
  int channels;
  GridChannel channel[kMaxGridChannels];
};

/// The declarations. Channel indices are the order of `channel` (kernels name them: grid_buffer.cuh).
inline constexpr GridSetDecl kGridSets[kGridSetCount] = {
    {GridSet::Sums, "mass, momentum", GridStorage::FixedSum, 2, GridNeed::Always, GridLifetime::AcrossSteps, true,
     true, true, true, 4, {{"mass", "kg"}, {"momentum x", "kg m/s"}, {"momentum y", "kg m/s"}, {"momentum z", "kg m/s"}}},
    {GridSet::Velocity, "velocity", GridStorage::Value, 1, GridNeed::Always, GridLifetime::WithinStep, false, false,
     false, false, 3, {{"velocity x", "m/s"}, {"velocity y", "m/s"}, {"velocity z", "m/s"}}},
    {GridSet::Transported, "transported momentum", GridStorage::FixedSum, 2, GridNeed::Asflip,
     GridLifetime::AcrossSteps, true, true, true, false, 3,
     {{"transported momentum x", "kg m/s"}, {"transported momentum y", "kg m/s"}, {"transported momentum z", "kg m/s"}}},
    {GridSet::OldVelocity, "ASFLIP v^n", GridStorage::Value, 1, GridNeed::Asflip, GridLifetime::WithinStep, false,
     false, false, true, 3, {{"v^n x", "m/s"}, {"v^n y", "m/s"}, {"v^n z", "m/s"}}},
    {GridSet::FbarSums, "F-bar / node volume sums", GridStorage::FixedSum, 1, GridNeed::Fbar, GridLifetime::PerPass, true, true,
     false, true, 2, {{"volume x compression", "m^3"}, {"volume", "m^3"}}},
    {GridSet::PoreValues, "seepage node values", GridStorage::Value, 1, GridNeed::Pore, GridLifetime::PerPass,
     false, false, false, true, 5,
     {{"pore volume / -", "m^3"}, {"head / h_i", "Pa m^3 / Pa"}, {"inflow / r_i", "m^3/s / 1/s"},
      {"water mass", "kg"}, {"water density sum / p_i", "kg / Pa"}}},
    {GridSet::PoreSums, "seepage channels", GridStorage::FixedSum, 1, GridNeed::Pore, GridLifetime::PerPass, true,
     true, false, false, 5,
     {{"pore volume", "m^3"}, {"head", "Pa m^3"}, {"inflow", "m^3/s"}, {"water mass", "kg"},
      {"water density sum", "kg"}}},
};

constexpr const GridSetDecl& grid_set(GridSet s) { return kGridSets[static_cast<int>(s)]; }

/// The table is consistent: ids in order, channel counts in range, AcrossSteps sets double-buffered.
constexpr bool grid_sets_consistent() {
  for (int i = 0; i < kGridSetCount; ++i) {
    const GridSetDecl& d = kGridSets[i];
    if (static_cast<int>(d.id) != i || d.channels < 1 || d.channels > kMaxGridChannels) return false;
    if (d.copies < 1 || d.copies > 2) return false;
    if (d.lifetime == GridLifetime::AcrossSteps && d.copies != 2) return false;
    for (int c = 0; c < d.channels; ++c)
      if (d.channel[c].name == nullptr || d.channel[c].unit == nullptr) return false;
  }
  return true;
}
static_assert(grid_sets_consistent(), "kGridSets: ids in order, 1..8 channels, AcrossSteps sets double-buffered");

/// Bytes of one value of a set on the GPU: a fixed-point sum is one int64 word (float grids) or two (double grids,
/// grid_buffer.cuh FixedSumFormat); a value is one TG.
constexpr std::size_t grid_value_bytes(GridStorage storage, std::size_t grid_scalar_bytes) {
  return storage == GridStorage::FixedSum ? (grid_scalar_bytes == 8 ? 16 : 8) : grid_scalar_bytes;
}
/// Bytes of one 64-node block of one copy of a set on the GPU.
constexpr std::size_t grid_set_block_bytes(const GridSetDecl& d, std::size_t grid_scalar_bytes) {
  return static_cast<std::size_t>(d.channels) * 64 * grid_value_bytes(d.storage, grid_scalar_bytes);
}
/// The grid scalar's bytes at a precision (mixed: float grid).
constexpr std::size_t grid_scalar_bytes(Precision p) { return p == Precision::Double ? 8 : 4; }

/// GPU bytes of every set a scene with `features` carries, all copies, per grid block.
constexpr std::size_t grid_channel_block_bytes(Precision precision, GridFeatures features) {
  std::size_t bytes = 0;
  for (const GridSetDecl& d : kGridSets)
    if (features.has(d.need)) bytes += static_cast<std::size_t>(d.copies) * grid_set_block_bytes(d, grid_scalar_bytes(precision));
  return bytes;
}
/// The CPU engine's channels per node (its sets with `cpu`, in TG).
constexpr int cpu_grid_channels(GridFeatures features) {
  int channels = 0;
  for (const GridSetDecl& d : kGridSets)
    if (d.cpu && features.has(d.need)) channels += d.channels;
  return channels;
}
/// --check's "grid channels" of one body: the sets its particles sum into, with their channel counts ("mass,
/// momentum (4) + F-bar / node volume sums (2)"). `body` holds what this body uses; `scene` what any body does (a set needed
/// by any body is summed by every body: the transported momentum).
std::string grid_channels_of_body(GridFeatures body, GridFeatures scene);

}  // namespace fbar
