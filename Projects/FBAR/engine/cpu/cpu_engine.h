// The CPU reference engine: explicit MLS-MPM on a hashed sparse grid of 4x4x4 node blocks, OpenMP, any scene.
//
// It runs the same physics functions as the GPU engine (constitutive_models.cuh, transfer.cuh, grid_update.cuh,
// boundary.cuh, time_step.cuh), is the oracle of the GPU tests and the engine of the physics tests. Simple and
// readable first, then fast.
//
// One step (symplectic Euler, Hu et al. 2018 MLS-MPM, APIC):
//   1. partition  every body's particles are bucketed by the 4x4x4 block holding their stencil's base node
//                 (a "particle block"); the grid blocks it touches (the block and its +1 neighbours, 2x2x2) are
//                 activated in a std::unordered_map from packed block coordinates to a block index.
//   2. P2G        per particle block: the stress and the MLS payload of each particle are scattered into a private
//                 6x6x6-node arena, which is then added to the grid blocks. Blocks are processed in 8 colours
//                 (block coordinate parities); blocks of one colour write disjoint nodes, so a colour runs in
//                 parallel without atomics. Every node sum therefore has a fixed order (body, colour, particle
//                 order inside the block): results are bitwise independent of the number of threads.
//   3. grid       v = p/m + dt g, boundary projections, max |v| (for the next dt).
//   4. G2P        per particle block, from a 6x6x6 arena gathered from the grid: v, C, x += dt v, F or 1-J update,
//                 then the failure checks. New values go to a second set of arrays: the step commits (swaps) only
//                 when no check failed, so a failed step leaves the state untouched and can be retried.
// Failure checks (every step, every particle): NaN/Inf in x, v, C or the material state; a move of more than one
// cell along an axis in one step (CFL violation: the fused GPU G2P2G cannot represent it); a position outside the
// domain [0, simulation.domain]. on_failure = stop: step() reports (body, step, time, count) and does not commit.
// on_failure = reduce_dt: the step is retried from the unchanged state with dt/2, up to kMaxStepRetries times; the
// halving persists for later steps and is undone (x2) after kRecoverSteps clean steps (engine_common.h).
//
// Time step: dt = min(default_dt, min_b CFL_b dx / (c_b + |v|max)) where c_b is the largest wave speed of body b's
// particles (material wave_speed() of the current state, e.g. the compressed sound speed of JFluid; never below
// the material's speed at rest) and |v|max the largest grid speed of the previous step (the initial particle
// speed before the first step).
//
// Particles of a body are stored in their sampling order for the whole run (index = ID); only an index list is
// sorted by block each step. Mass and reference volume are per particle (rho dx^3/ppc and dx^3/ppc at start;
// set_volume_ratios may change them to start in a pre-compressed state).
//
// Use (a physics test; every quantity in SI units):
//   Scene scene = ...;                                    // bodies, boundaries (scene.h)
//   CpuEngine<double> engine(scene);                      // samples the bodies (geometry.h)
//   engine.set_volume_ratios(0, [&](const Vec3d& x) { return J_hydrostatic(x[1]); });   // optional initial state
//   const StepReport r = engine.advance_to(0.5);          // CFL steps, lands on t = 0.5 s
//   ASSERT_TRUE(r.ok) << r.message();
//   const std::vector<double> p = engine.pressures(0);    // per particle, index = ID, with positions(0)
//   const double e = engine.kinetic_energy() + engine.elastic_energy();
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>
#include <unordered_map>
#include <variant>
#include <vector>

#include "MnBase/Math/vec.h"
#include "MnSystem/IO/async_writer.h"
#include "comm/slab_partition.h"
#include "comm/transport.h"
#include "MnSystem/IO/particle_io.h"
#include "io/checkpoint.h"
#include "physics/boundary.cuh"
#include "physics/constitutive_models.cuh"
#include "physics/fem.cuh"
#include "physics/grid_fields.h"
#include "physics/sensors.cuh"
#include "engine/engine_common.h"
#include "engine/grid_channels.h"
#include "engine/run_constants.h"
#include "scene/scene.h"
#include "physics/transfer.cuh"

namespace fbar {

/// T: particle scalar type (positions, velocities, state, transfers); TG: grid scalar type (P2G sums, grid
/// velocities, grid update). CpuEngine<float> runs "single", CpuEngine<double> "double" and CpuEngine<double, float>
/// "mixed", the GPU engine's three precisions (the grid sums of mixed are floats, as on the GPU).
template <typename T, typename TG = T>
class CpuEngine {
 public:
  using Vec3T = Vec3<T>;
  using Mat3T = Mat3<T>;


  /// Samples every body with sample_body() (geometry.h). Throws SceneError (sampling) or std::invalid_argument
  /// naming the body / boundary for what this engine does not implement (material law, boundary object, output
  /// attribute).
  explicit CpuEngine(const Scene& scene);
  /// As above with given initial positions [m] per body (tests, restarts); positions must lie inside the domain.
  CpuEngine(const Scene& scene, const std::vector<std::vector<Vec3d>>& positions);
  /// One rank of a decomposed run (comm/slab_partition.h): every rank samples the scene, keeps the particles of its
  /// slab (slabs chosen from the particle distribution along its longest axis), sums the halo plane it shares with
  /// each neighbour after P2G (and after F-bar's cell sums), agrees with the other ranks on the grid speed, wave
  /// speeds and failures (so every rank takes the same dt and the same decision), and sends particles whose block
  /// left its slab to their new owner after each step, with everything they carry. Every rank calls every step.
  /// `rebalance_threshold`: the slabs are chosen again when imbalance() exceeds it (<= 0: never).
  CpuEngine(const Scene& scene, comm::Transport& transport, double rebalance_threshold = 0.25);
  /// Continues from a checkpoint (io/checkpoint.h): this rank's own file when the run has as many ranks as the
  /// one that wrote it (slot order, slabs, CFL inputs and reduce_dt state as they were, so the run goes on bit for
  /// bit), otherwise the whole set merged in ID order (io::read_checkpoint_set), which the ranks divide anew.
  /// Throws std::invalid_argument naming what does not match the scene (bodies, material laws, state size).
  CpuEngine(const Scene& scene, const io::Checkpoint& checkpoint, comm::Transport* transport = nullptr,
            double rebalance_threshold = 0.25);
  ~CpuEngine();
  CpuEngine(const CpuEngine&) = delete;
  CpuEngine& operator=(const CpuEngine&) = delete;

  // ------------------------------------------------------------------ stepping
  /// One step with the CFL time step (next_dt()).
  StepReport step();
  /// One step of exactly dt [s] (no CFL bound; reduce_dt may still halve it on failure).
  StepReport step(double dt);
  /// Steps with the CFL time step until time() == t_end [s]: the last two steps share what remains (no sliver
  /// step) and the last one lands on t_end exactly.
  /// Stops at the first failure that is not repaired; then time() < t_end.
  StepReport advance_to(double t_end);
  /// One step of advance_to(t_end): the CFL step, or what remains when that reaches t_end (landing on it exactly),
  /// or half of what remains when one CFL step would leave a sliver.
  StepReport step_toward(double t_end);
  /// The same (the CPU engine chooses each dt at the step's start: the following target changes nothing).
  StepReport step_toward(double t_end, double /*t_following*/) { return step_toward(t_end); }

  double time() const { return time_; }        ///< [s]
  long long steps() const { return steps_; }   ///< committed steps
  double last_dt() const { return last_dt_; }  ///< [s] size of the last committed step
  /// [s] the dt step() would take now: min(default_dt, min_b CFL_b dx / (c_b + |v|max)) x reduce_dt factor.
  double next_dt() const;
  double max_grid_speed() const { return max_grid_speed_; }  ///< [m/s] |v|max of the last grid update
  /// Redirects reduce_dt retry messages (default std::cerr; nullptr: silent).
  void set_log(std::ostream* log) { log_ = log; }

  // ------------------------------------------------------------------ output (run_loop.h)
  /// Nothing to prepare: frame() builds a frame from the current state (the GPU engine captures it during a step).
  void set_frame_capture(bool) {}
  /// Queues frame(body) on the writer (waiting while the writer's queue is full).
  void submit_frame(int body, const std::filesystem::path& path, io::AsyncWriter& writer);
  double output_wait_seconds() const { return output_wait_s_; }  ///< [s] waited in submit_frame
  std::string resource_note() const;                             ///< threads, for progress lines

  // ------------------------------------------------------------------ checkpoints (io/checkpoint.h)
  /// This rank's state: particles in slot order, time, steps, dt, CFL inputs, reduce_dt state, slabs (engine
  /// "cpu"; the run loop adds the frame, start time and sensor files). Collective on several ranks.
  io::Checkpoint checkpoint() const;
  /// Always: the CPU engine holds every particle's velocity and C (the GPU engine only after a recorded step).
  bool checkpoint_ready() const { return true; }
  void keep_checkpoint_inputs(bool) {}

  // ------------------------------------------------------------------ grid sensors (physics/sensors.cuh)
  /// The grid sensors a sampling step evaluates (at most GridSensorSet::kMax), in this order.
  void set_grid_sensors(const std::vector<GridSensorSpec>& sensors);
  /// The next steps' grid updates write every grid sensor's reduction over the nodes this rank owns into `slot`
  /// (-1: they do not sample). A retried step overwrites the slot with its successful try.
  void set_grid_sample(int slot) { grid_sample_slot_ = slot; }
  /// This rank's values of slots [0, slots), slot-major (values[slot * sensors + i]).
  std::vector<SensorAccum> grid_samples(int slots) const;
  /// Grid fields (physics/grid_fields.h; at most GridFieldSet::kMax), in this order: the next steps' grid updates
  /// record the nodes this rank owns inside the boxes of the fields in `mask` (bit i: field i; 0: none), which
  /// grid_field_sample(i) then returns with the step's dt. A retried step records its successful try.
  void set_grid_fields(const std::vector<GridFieldSpec>& fields);
  void set_grid_field_sample(unsigned mask) { grid_fields_.mask = mask; }
  GridFieldSample grid_field_sample(int field) const;
  /// Particle sensors (at most ParticleSensorSet::kMax): sample_particles(slot) reduces this rank's particles of
  /// every body in each sensor's box (frame_value() of the sensor's attribute) into `slot`; particle_samples(n)
  /// returns slots [0, n) as values[(slot * bodies + body) * sensors + i]. keep_particle_inputs: nothing to keep
  /// (the CPU engine holds v and C of every particle).
  void set_particle_sensors(const std::vector<ParticleSensorSpec>& sensors);
  void keep_particle_inputs(bool) {}
  void sample_particles(int slot);
  std::vector<SensorAccum> particle_samples(int slots) const;
  /// Trackers (physics/sensors.cuh TrackerSet): track() evaluates the tracked particles of `body` this rank holds,
  /// found by ID: values[i * attribs + a] (i: index in the sorted IDs) and present[i] = 1 (0 where absent).
  void set_tracker(int body, const TrackerSet& set);
  void track(int body, std::vector<double>& values, std::vector<double>& present) const;

  // ------------------------------------------------------------------ decomposition (one rank: trivial)
  int rank() const { return transport_->rank(); }
  int ranks() const { return transport_->size(); }
  const comm::SlabPartition& slabs() const { return slabs_; }
  /// The rank holding body b whole (bodies[].gpu, comm/placement.h), or kAllGpus when it is spread by space.
  int body_home(int body) const { return body_at(body).home; }
  /// max / mean - 1 of the particles per rank after the last step (0 on one rank).
  double imbalance() const { return imbalance_; }
  long long migrated() const { return migrated_; }      ///< particles this rank sent to others so far
  int rebalances() const { return rebalances_; }        ///< times the slabs were chosen again
  /// The run loop's rebalancing points (run_loop.h): this engine rebalances within its steps, so never.
  bool rebalance_due() const { return false; }
  bool rebalance_if_drifted() { return false; }
  /// Particle IDs of this rank's particles of `body`, in slot order (one rank: 0, 1, 2, ...: slot = ID).
  const std::vector<std::int64_t>& ids(int body) const;

  // ------------------------------------------------------------------ particles (slot; on one rank slot = ID)
  int body_count() const { return static_cast<int>(bodies_.size()); }
  std::size_t particle_count(int body) const;
  std::size_t particle_count() const;  ///< all bodies
  Constitutive law(int body) const;
  const std::vector<Vec3T>& positions(int body) const;       ///< [m]
  const std::vector<Vec3T>& velocities(int body) const;      ///< [m/s]
  const std::vector<Mat3T>& affine(int body) const;          ///< [1/s] APIC C (velocity gradient)
  const std::vector<T>& masses(int body) const;              ///< [kg]
  const std::vector<T>& volumes(int body) const;             ///< [m^3] reference volume V0
  std::vector<T> volume_ratios(int body) const;              ///< [-] J
  std::vector<T> jbar_ratios(int body) const;                ///< [-] the J the stress sees (nodal F-bar's JBar, else J)
  std::vector<Mat3T> deformation_gradients(int body) const;  ///< [-] F; throws for a law without F (JFluid)
  std::vector<T> plastic_log_volumes(int body) const;        ///< [-] logJp; throws for a law without it
  std::vector<T> pore_pressures(int body) const;             ///< [Pa] CoupledUP p; throws for a law without it
  std::vector<Mat3T> cauchy_stresses(int body) const;        ///< [Pa] sigma = tau / J
  std::vector<T> pressures(int body) const;                  ///< [Pa] -tr(sigma)/3
  std::vector<T> wave_speeds(int body) const;                ///< [m/s] current material wave speed

  /// Overwrites the velocity of every particle of `body` with v(x) [m/s] (C is left as is).
  void set_velocities(int body, const std::function<Vec3d(const Vec3d&)>& velocity_of_position);
  /// Starts a JFluid body compressed: J(x) per particle (e.g. hydrostatic: J(y) = (1 + gamma p(y)/K)^(-1/gamma)).
  /// The particles sit where they were sampled, each occupying dx^3/ppc now, so with rescale_mass the reference
  /// volume becomes V0 = (dx^3/ppc) / J and the mass rho0 V0 (the current density is then rho0 / J, consistent
  /// with the state). Throws std::invalid_argument for a body that does not store J, or J <= 0.
  void set_volume_ratios(int body, const std::function<double(const Vec3d&)>& J_of_position, bool rescale_mass = true);
  /// External forces [N] on the particles of `body`: force(id, x, t) of the particle with ID `id` at x [m], at the
  /// start of each step (time t [s]), added to its P2G momentum (sum_i w_ip f_p dt over its nodes). For programs
  /// that drive the engine (a pressure on a surface, a coupled solver; tests/validation/thick_sphere_case.h); scenes
  /// have no such key. One rank only; not kept in checkpoints. An empty function removes the forces.
  using ParticleForce = std::function<Vec3d(std::int64_t id, const Vec3d& x, double t)>;
  void set_particle_forces(int body, ParticleForce force);
  /// Overwrites F(x) of a body whose material stores F (FixedCorotated, NeoHookean, DruckerPrager, NACC); throws
  /// otherwise.
  void set_deformation_gradients(int body, const std::function<Mat3d(const Vec3d&)>& F_of_position);

  // ------------------------------------------------------------------ totals (double sums in particle order)
  double total_mass() const;       ///< [kg] sum of particle masses
  Vec3d total_momentum() const;    ///< [kg m/s] sum m v
  Vec3d angular_momentum() const;  ///< [kg m^2/s] about the origin, with the APIC affine spin
  double kinetic_energy() const;   ///< [J] sum m |v|^2 / 2
  double elastic_energy() const;   ///< [J] sum V0 psi(state)
  /// [kg] sum of grid node masses of the last P2G (equals total_mass() to round-off: partition of unity).
  double grid_mass() const { return grid_mass_; }
  std::size_t active_grid_blocks() const { return grid_.blocks.size(); }

  // ------------------------------------------------------------------ output
  /// The body's particles with its output_attribs (canonical names; aliases resolved), positions in T, for the
  /// particle_io writers: ID int32 (= particle index), everything else float. Volume is the current volume V0 J
  /// [m^3], Pressure -tr(sigma)/3 [Pa], VonMisesStress sqrt(3/2 s:s) [Pa].
  io::ParticleFrame frame(int body) const;
  /// Host memory held by particles and grid [bytes].
  std::size_t memory_bytes() const;

  const Scene& scene() const { return scene_; }

 private:
  // Per-material part of a body: parameters and the stored state (current and next, for transactional steps).
  template <typename M>
  struct MaterialBody {
    using material_type = M;
    material_params_t<M, T> params;
    std::vector<material_state_t<M, T>> state, next_state;
  };
  template <typename... Ms>
  using MaterialVariantOf = std::variant<MaterialBody<Ms>...>;
  using MaterialVariant = typename MaterialTypes::template apply<MaterialVariantOf>;

  // Particle blocks of one body, rebuilt from the positions before every step.
  struct Partition {
    std::vector<std::uint64_t> block_keys;          // (particle block) packed block coordinates
    std::vector<Vec3i> block_coords;                // (particle block) block coordinates
    std::vector<int> block_start;                   // (particle block + 1) offsets into `order`
    std::vector<int> order;                         // particle indices sorted by block (stable)
    std::vector<std::array<int, 8>> grid_blocks;    // (particle block, 2x2x2 neighbour) grid block index
    std::array<std::vector<int>, 8> colour_blocks;  // particle blocks of each parity colour
    int largest_colour = 0;                         // blocks in the largest colour (whether to go parallel)
    std::vector<int> particle_block;                // (particle) its particle block (scratch)
    std::vector<std::uint64_t> particle_key;        // (particle) packed block coordinates (scratch)
  };

  // A mesh body's elements (physics/fem.cuh): the body's particles are the mesh's vertices (slot = vertex ID: a mesh
  // lives whole on its rank and never migrates). `force` is the elements' force on each vertex at the committed
  // positions, `force_next` at the positions a try computed; P2G adds force dt in place of the MLS stress.
  struct MeshPart {
    T fbar_psi = T(0);         // use_FBAR's blend (0: plain tetrahedra)
    std::vector<TetElement<T>> elements;
    std::vector<int> vertex_start, vertex_elements;  // CSR: the elements of each vertex (corner = 4 e + k), in order
    std::vector<Vec3T> force, force_next;            // (vertex) [N]
  };

  struct Body {
    BodySpec spec;
    MeshPart mesh;  // a mesh's elements (spec.mesh >= 0)
    bool is_mesh() const { return spec.mesh >= 0; }
    std::vector<std::int64_t> id;  // particle ID of each slot
    std::vector<Vec3T> x, v, x_next, v_next;
    std::vector<Mat3T> C, C_next;
    std::vector<T> mass, volume;
    MaterialVariant material;
    double max_wave_speed = 0.0;  // [m/s] over the particles of the committed state
    int home = kAllGpus;          // the rank holding the whole body (bodies[].gpu, comm/placement.h), or spread by space
    bool asflip = false;          // PIC-FLIP / ASFLIP velocity and position update (transfer.cuh)
    AsflipParams<T> asflip_params{T(0), T(0), T(0)};
    T fbar_psi = T(0);  // F-bar: the blend psi (FBAR_psi); 0: off
    bool fbar_nodal = false;  // F-bar is ClaymoreUW's nodal JBar (physics/fbar_nodal.cuh), else the cell mean (transfer.cuh)
    bool fbar_fused = false;  // nodal F-bar's fused variant (FBAR_fused_kernel), else the split one
    std::vector<T> jbar, jbar_next;  // (slot) nodal F-bar's 1 - JBar; empty otherwise
    ParticleForce force_of;    // set_particle_forces; empty: none
    std::vector<Vec3T> force;  // (slot) [N] force_of at the start of the step being tried
    Partition partition;
  };

  // Grid blocks of 4x4x4 nodes, structure of arrays inside a block: channel[node], node = (i*4 + j)*4 + k.
  struct GridBlock {
    TG mass[64];
    TG momentum[3][64];  // momentum after P2G, velocity after the grid update
  };
  // ASFLIP's v^n (only when a body uses it): P2G accumulates the transported momentum m (v + C (x_i - x_p)) without
  // the MLS stress impulse, the grid update divides it by the mass.
  struct AsflipBlock {
    TG old_velocity[3][64];
  };
  // F-bar's sums of one body before its G2P (only when a body uses F-bar). Cell scheme: sum V0 (1 - J) and sum V0 of
  // the cell c at node c; nodal scheme: sum w V s and sum w V (s = 1 - JBar, V = V0 J; fbar_nodal.cuh). On a step
  // a Volume or JBar grid sensor samples, before the grid update: every body's sum w V s and sum w V (s = 1 - JBar
  // of the JBar attribute: nodal F-bar's stored one, else 1 - J).
  struct FbarBlock {
    TG sums[2][64];
  };
  // Seepage channels (only when a body is saturated, CoupledUP: physics/seepage.cuh). P2G sums volume = sum w V,
  // head = sum w V h (h = p - rhow g . x), inflow = sum V q . grad w, water = sum w n rhow V0 and density =
  // sum w V rhow over the saturated particles; the grid update turns head into h_i and inflow into r_i, which G2P
  // interpolates (water and density feed the sensors and the drained nodes' h_i).
  struct PoreBlock {
    TG volume[64];
    TG head[64];
    TG inflow[64];
    TG water[64];
    TG density[64];
  };
  // The CPU's blocks hold the channel sets grid_channels.h marks `cpu`, in TG (its velocity replaces the momentum
  // in place; ASFLIP's transported momentum is summed into v^n's place; the seepage sums into the node values').
  static_assert(sizeof(GridBlock) == grid_set(GridSet::Sums).channels * 64 * sizeof(TG), "GridBlock: kGridSets");
  static_assert(sizeof(AsflipBlock) == grid_set(GridSet::OldVelocity).channels * 64 * sizeof(TG),
                "AsflipBlock: kGridSets");
  static_assert(sizeof(FbarBlock) == grid_set(GridSet::FbarSums).channels * 64 * sizeof(TG), "FbarBlock: kGridSets");
  static_assert(sizeof(PoreBlock) == grid_set(GridSet::PoreValues).channels * 64 * sizeof(TG), "PoreBlock: kGridSets");
  struct Grid {
    std::unordered_map<std::uint64_t, int> index;  // packed block coordinates -> block
    std::vector<Vec3i> coords;                     // (block) block coordinates
    std::vector<GridBlock> blocks;
    std::vector<AsflipBlock> asflip;  // (block), empty unless a body uses ASFLIP
    std::vector<FbarBlock> fbar;      // (block), empty unless a body uses F-bar
    std::vector<PoreBlock> pore;      // (block), empty unless a body is saturated
  };

  struct TryResult {
    std::vector<FailureReport> failures;  // built from counts / first after the reduction over ranks
    double max_grid_speed = 0.0;
    std::vector<double> max_wave_speed;  // per body, of the new state
    std::vector<std::array<long long, kFailureKinds>> count;  // (body, FailureKind) failing particles
    std::vector<std::array<long long, kFailureKinds>> first;  // (body, FailureKind) smallest failing ID
  };

  void init(const std::vector<std::vector<Vec3d>>& positions);
  /// Velocities and states of particles read with has_attributes (geometry/particle_seed.h), after init().
  void apply_seeds(const std::vector<ParticleSeeds>& seeds);
  /// bodies[].initial_state "hydrostatic": each particle's state from its depth below the top of `bounds[b]`, the
  /// body's geometry (engine/hydrostatic.h). Before apply_seeds (a point file's J wins).
  void apply_hydrostatic(const std::vector<Aabb>& bounds);
  void build_partition();
  TryResult try_step(double dt);
  void p2g(Body& body, T dt);
  double update_grid(TG dt);
  void fbar_cell_sums(Body& body);
  // Nodal F-bar's sums (fused: of the stored JBar; split: advanced by C), after clearing; volume_sensor: a volume
  // sensor's sums (the stored JBar, or J), added to what the grid holds.
  void fbar_node_sums(Body& body, T dt, bool volume_sensor = false);
  void clear_fbar_sums();                 // F-bar's sums zeroed on every block (before a body's pass)
  /// Adds a particle block's arena of F-bar sums (the two sums by arena node) into the grid blocks it overlaps.
  void add_fbar_arena(const std::array<int, 8>& blocks, const T* sums, const T* volumes);
  void init_jbar(Body& body);             // nodal F-bar: JBar = the particle's own J (after any initial state)
  void g2p(int body_index, Body& body, T dt, TryResult& result);
  /// A mesh body's elements at positions x: the vertex forces (into `force`), the vertex states (the V0-weighted
  /// mean F of their elements, into `states`), the largest wave speed, and the elements turned inside out (count,
  /// smallest index). physics/fem.cuh.
  struct MeshPassResult {
    double max_wave_speed = 0.0;
    long long inverted = 0, first_inverted = -1;    // elements
    long long nonfinite = 0, first_nonfinite = -1;  // vertices (ID): a NaN or Inf force or state
  };
  /// Each element's gradient at positions x, the one its stress uses (F = Ds Dm^-1, scaled by F-bar's volume
  /// ratio when use_FBAR); returns the elements with J <= 0 (then F is raw) and the first of them.
  long long element_gradients(const Body& body, const std::vector<Vec3T>& x, std::vector<Mat3T>& F,
                              long long& first_inverted) const;
  template <typename M, typename States>
  MeshPassResult mesh_pass(const Body& body, const material_params_t<M, T>& params, const std::vector<Vec3T>& x,
                           std::vector<Vec3T>& force, States& states) const;
  void init_mesh(Body& body);  // elements, lumped masses and the forces at the start (init)
  /// After a try's G2P: mesh_pass at x_next into force_next and the next states.
  MeshPassResult mesh_after_g2p(Body& body);
  /// sum_e V0_e psi(F_e) over a mesh body's elements at the committed positions [J].
  double mesh_elastic_energy(const Body& body) const;
  void commit(const TryResult& result, double dt);
  void exchange_halo(bool fbar_sums);  // sums the halo planes with the neighbours (P2G channels or F-bar sums)
  /// Placed bodies (comm/placement.h): the grid blocks this rank shares with each other rank, from every rank's
  /// block keys (collective; after P2G), and which blocks count here (sensors, grid mass).
  void find_shared_blocks();
  /// exchange_halo of a run with placed bodies: every shared block summed over all its holders in rank order.
  void exchange_shared_blocks(bool fbar_sums);
  void reduce_try(TryResult& result, double dt);  // over ranks: speeds, failure counts; builds the reports
  void migrate();                      // particles whose block left this rank's slab go to their owner
  void keep_own_particles(Body& body, const std::vector<int>& owner);  // drops those of other ranks, in order
  void resize_scratch(Body& body);     // the next-state arrays follow the particle count
  void measure_balance();              // imbalance_ from every rank's particle count (collective)
  void divide_replicated();            // every rank holds every particle: choose the slabs, keep its own (collective)
  /// Slabs from the particles: of this rank only when every rank holds every particle (`replicated`, at start),
  /// else of every rank (to rebalance).
  void choose_slabs_now(bool replicated);
  int owner_of(const Body& body, const Vec3T& x) const;  // rank owning a particle of `body` at x
  /// fn(p, inputs) for every particle p of `b` that accept(p) takes, with frame_value()'s inputs of its current state
  /// (particle_frame_inputs, the GPU's formula; the Cauchy stress only when `sigma`), in slot order.
  template <class Accept, class Fn>
  void each_particle_input(const Body& b, bool sigma, const Accept& accept, const Fn& fn) const;
  StepReport step_impl(double dt, bool cfl_dt);
  const Body& body_at(int body) const;
  Body& body_at(int body);

  Scene scene_;
  comm::LocalTransport local_transport_;        // the transport of a one-rank engine
  comm::Transport* transport_ = &local_transport_;
  comm::SlabPartition slabs_;                   // one slab (all of space) on one rank
  bool placed_ = false;                         // some body is placed whole on a rank: the general halo
  std::vector<std::vector<int>> shared_;        // placed_: per rank, the grid blocks shared with it, in key order
  std::vector<unsigned char> counted_;          // placed_: per grid block, 1 when its nodes count on this rank
  double rebalance_threshold_ = 0.0;
  double imbalance_ = 0.0;
  double chosen_imbalance_ = 0.0;               // imbalance right after the slabs were last chosen
  long long migrated_ = 0;
  int rebalances_ = 0;
  RunConstants<T> k_;    ///< dx, gravity, domain, default dt, boundaries (from the scene): particle side
  RunConstants<TG> kg_;  ///< the same in the grid scalar type: the grid update
  std::vector<Body> bodies_;
  Grid grid_;
  double time_ = 0.0;
  long long steps_ = 0;
  double last_dt_ = 0.0;
  double output_wait_s_ = 0.0;  // [s] in submit_frame
  double max_grid_speed_ = 0.0;
  double grid_mass_ = 0.0;
  DtRetryPolicy retry_;  // on_failure = reduce_dt (engine_common.h)
  bool partition_valid_ = false;
  bool asflip_ = false;  // some body uses ASFLIP: the grid update keeps v^n
  bool fbar_ = false;    // some body uses F-bar: the grid has cell sums
  bool node_volume_ = false;  // a grid sensor reads Volume or JBar: the grid has the F-bar sums for it
  bool pore_ = false;    // some body is saturated (CoupledUP): the grid has seepage channels
  GridSensorSet<TG> grid_sensors_;         // evaluated by update_grid when grid_sample_slot_ >= 0
  int grid_sample_slot_ = -1;
  std::vector<SensorAccum> grid_samples_;  // (slot, sensor)
  GridFieldSet<TG> grid_fields_;           // recorded by update_grid for the fields in grid_fields_.mask
  std::vector<GridFieldSample> field_samples_;  // (field) the last recorded sample
  ParticleSensorSet<T> particle_sensors_;
  std::vector<TrackerSet> trackers_;  // (body)
  std::vector<SensorAccum> particle_samples_;  // (slot, body, sensor)
  std::ostream* log_;
};

extern template class CpuEngine<double, double>;
extern template class CpuEngine<float, float>;
extern template class CpuEngine<double, float>;

}  // namespace fbar
