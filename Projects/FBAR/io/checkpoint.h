// Checkpoints: the full state of one rank of a run, in an HDF5 file, and what `fbar --restart=FILE` reads back.
//
// A checkpoint holds everything the next step depends on, so that a run restarted from it writes the same frames
// and sensor rows as the run that was never stopped (bitwise on the CPU engine with the same number of ranks; on the
// GPU engine to the last bits of its grid sums: docs/user_guide.md §4.7):
//   * per body, per particle in this rank's slot order: ID, position, velocity and APIC matrix C of the last G2P
//     (ASFLIP: the particle's own velocity), mass, reference volume and the material's stored state (the scalars
//     of material_state_t<M, T> in member order: 1 - J for JFluid, F row-major, then logJp, ...), in the run's
//     precision (float32 for "single", float64 for "double" and "mixed");
//   * time, step count, the last dt and the next one, the largest grid speed and per body the largest wave speed
//     (the CFL inputs), the reduce_dt state, the decomposition (slab axis and cuts);
//   * the run's frame count and start time, and the byte length of every sensor and tracker CSV at that moment
//     (a restart truncates the files there and appends).
// Boundaries move as functions of time (motion_path.h), so the time is their state.
//
// Files, in simulation.save_path, one per rank d (ClaymoreUW's dev[d] naming):
//   checkpoint_frame[f]_dev[d].h5   written at frame f every simulation.checkpoint_every frames
//   checkpoint_step[s]_dev[d].h5    written when a run stops at step s (SIGINT / SIGTERM, or a failure)
// Layout: root attributes (format, precision, engine, reason, rank, ranks, time, ...), per-body groups /body[b]
// with attributes (law, state_scalars, particles, global_particles, max_wave_speed) and datasets ID (int64),
// Position (N x 3), Velocity (N x 3), C (N x 9), Mass (N), Volume (N), State (N x state_scalars: the law's state, then 1 - JBar with the nodal F-bar), on the GPU
// engine (attribute p2g_blocks = 1) P2GID (M) and P2GBlock (M x 3), and /csv with the sensor files' names and
// lengths. Each file is written to <name>.part and renamed when complete.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace fbar {
struct Scene;
}

namespace fbar::io {

/// One body's particles on one rank, in slot order.
struct CheckpointBody {
  std::string law;                ///< the material law's name (law_name())
  int state_scalars = 0;          ///< stored state scalars per particle
  long long global_particles = 0; ///< particles of the body over every rank (IDs 0 .. global_particles - 1)
  double max_wave_speed = 0.0;    ///< [m/s] over the body's particles (the next dt's CFL bound)
  std::vector<std::int64_t> id;
  std::vector<double> x;          ///< (particle, 3) [m]
  std::vector<double> v;          ///< (particle, 3) [m/s]
  std::vector<double> C;          ///< (particle, 9) [1/s] row-major
  std::vector<double> mass;       ///< [kg]
  std::vector<double> volume;     ///< [m^3] reference volume V0
  std::vector<double> state;      ///< (particle, state_scalars)
  /// [kg m/s] GPU engine: the P2G bound (before the arena's headroom, the maximum over the ranks) its last G2P2G
  /// summed the grid with, so that a restart sums the same grid bit for bit; < 0: not known (a CPU checkpoint, or
  /// one written before this field existed: the restart measures its own bound and continues to round-off)
  double p2g_bound = -1.0;
  /// GPU engine: whether that G2P2G was a frame step's, whose kernel is another instantiation (it also writes the
  /// frame): a restart's P2G runs the one its run did, the same machine code summing the same particles.
  bool p2g_capture = false;
  /// GPU engine: the grid block (block coordinates, 4 cells a side) each particle's last P2G summed it from, which
  /// is the block it started that step in, not the one it ends in: each block sums its particles in a fixed-point
  /// quantum of its own (kernels/g2p2g_kernel.cuh), so a restart groups them the same way to sum the same grid.
  /// In one rank's file: the particles that rank summed (p2g_id; after a migration not those of `id`); merged
  /// (merge_checkpoints): every particle in ID order. p2g_known false: not recorded (a CPU checkpoint, one written
  /// before this field existed, or before a run's first step): the restart groups the particles by position, as a
  /// run's first P2G does.
  bool p2g_known = false;
  std::vector<std::int64_t> p2g_id;
  std::vector<std::int32_t> p2g_block;  ///< (p2g_id, 3)
  std::size_t particles() const { return id.size(); }
  /// The same body without particles (law, state scalars, global count; max_wave_speed 0).
  CheckpointBody description() const {
    CheckpointBody d;
    d.law = law;
    d.state_scalars = state_scalars;
    d.global_particles = global_particles;
    return d;
  }
};

/// A body's particle datasets in write_checkpoint's order.
enum class CheckpointDataset { Id, Position, Velocity, C, Mass, Volume, State, P2GId, P2GBlock };

/// A body's particle datasets read piece by piece instead of from its CheckpointBody's arrays (which stay empty): a
/// body too large to copy into host memory. pieces(dataset, emit) calls emit(rows, values) for consecutive pieces of
/// the dataset in its row order, `particles` rows in all (`p2g_rows` for P2GId and P2GBlock): doubles, rows x width
/// (width 3, 3, 9, 1, 1, state_scalars), int64 IDs, int32 blocks (rows x 3).
struct CheckpointPieces {
  std::size_t particles = 0;
  std::size_t p2g_rows = 0;
  std::function<void(CheckpointDataset, const std::function<void(std::size_t rows, const void* values)>& emit)> pieces;
};

struct Checkpoint {
  static constexpr int kFormat = 1;
  int format = kFormat;
  std::string precision;          ///< "single", "double" or "mixed" (the run's)
  std::string engine;             ///< "cpu" or "gpu" (which engine wrote it; either may read it)
  std::string reason;             ///< "frame", "SIGTERM", "SIGINT", "failure"
  int rank = 0, ranks = 1;
  double start_time = 0.0;        ///< [s] the run's t0 (simulation.time of the first run): frame f is at t0 + f / fps
  double time = 0.0;              ///< [s]
  long long steps = 0;
  int frame = 0;                  ///< the last frame written
  double last_dt = 0.0;           ///< [s]
  double next_dt = 0.0;           ///< [s] the dt of the next step (the GPU's P2G impulse was made with it)
  double max_grid_speed = 0.0;    ///< [m/s] of the last grid update
  double dt_scale = 1.0;          ///< reduce_dt: current halving factor
  int clean_steps = 0;            ///< reduce_dt: clean steps since the last halving
  int slab_axis = 0;              ///< decomposition: slab axis and cuts (ranks + 1 entries; empty on one rank)
  std::vector<int> slab_cuts;
  double chosen_imbalance = 0.0;  ///< decomposition: the imbalance when the slabs were last chosen (rebalancing)
  /// The particle sensors had not yet sampled the state at `time` (a run's last frame: no run samples its end), so
  /// the restarted run samples it first. Absent from checkpoints written before this field existed: false.
  bool particle_sample_due = false;
  std::vector<std::pair<std::string, long long>> csv;  ///< sensor / tracker file name and length [bytes] (rank 0)
  std::vector<CheckpointBody> bodies;
  /// Per body (empty, or as many as bodies): its datasets read in pieces (write_checkpoint) where `pieces` is set;
  /// such a body's arrays are empty, and the source must outlive the write (the GPU engine's reads its device
  /// state: the run writes such a checkpoint before the next step).
  std::vector<CheckpointPieces> streamed;
  bool is_streamed(std::size_t b) const { return b < streamed.size() && static_cast<bool>(streamed[b].pieces); }
};

/// checkpoint_frame[f]_dev[d].h5 / checkpoint_step[s]_dev[d].h5 in `dir`.
std::filesystem::path checkpoint_frame_path(const std::filesystem::path& dir, int frame, int rank);
std::filesystem::path checkpoint_step_path(const std::filesystem::path& dir, long long step, int rank);
/// The file of rank `rank` of the checkpoint set `given` names (any rank's file of the set): "_dev[d]" replaced.
/// Throws std::invalid_argument when `given` has no "_dev[d]" part and rank != its rank.
std::filesystem::path checkpoint_rank_path(const std::filesystem::path& given, int rank);

/// Writes `c` (positions and state in float32 when c.precision is "single"), each dataset a piece at a time (a
/// streamed body's from its source, the others' 4,194,304 rows at a time). Throws std::runtime_error.
void write_checkpoint(const std::filesystem::path& path, const Checkpoint& c);
/// Reads a checkpoint (without `particles`: the root attributes only, every body left empty); throws
/// std::runtime_error naming the file and what is missing or inconsistent.
Checkpoint read_checkpoint(const std::filesystem::path& path, bool particles = true);

/// Whether a run of `scene` can continue from `c`: as many bodies, each of the same material law with as many
/// stored state scalars. Throws std::invalid_argument naming the body and the difference (both engines call it).
void check_matches(const Checkpoint& c, const Scene& scene);

/// Every rank's file of the set `given` belongs to (rank 0 .. ranks - 1, each checked to be of the same step), as
/// one checkpoint whose bodies hold every particle in ID order (rank = 0, ranks = 1, no slabs): what a run with a
/// different number of ranks starts from.
Checkpoint read_checkpoint_set(const std::filesystem::path& given);

/// The parts (every rank's state at the same step, rank 0's first) as one checkpoint with every particle in ID order
/// (rank 0's header, rank = 0, ranks = 1, no slabs). `what` names the parts in errors. Throws std::runtime_error
/// when a particle is missing or on two ranks.
Checkpoint merge_checkpoints(std::vector<Checkpoint> parts, const std::string& what);

/// Every body's particle arrays (and largest wave speed) of `c` as bytes, and back into a checkpoint whose header
/// and bodies' law, state_scalars and global_particles are already set: what ranks exchange in memory to rebalance.
std::vector<std::uint8_t> checkpoint_particle_bytes(const Checkpoint& c);
void read_checkpoint_particle_bytes(const std::vector<std::uint8_t>& bytes, Checkpoint& into);

/// What rank `rank` of a run of `ranks` ranks restarts from: its own file of the set when the set was written by as
/// many ranks (the run then goes on as it was), otherwise read_checkpoint_set(given).
Checkpoint read_checkpoint_for(const std::filesystem::path& given, int rank, int ranks);

}  // namespace fbar::io
