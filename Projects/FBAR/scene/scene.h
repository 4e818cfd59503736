// The resolved scene: what the JSON front end produces and every engine consumes (SI units).
//
// scene_parse.cpp fills these structs from a scene file (docs/user_guide.md §2), applying defaults,
// validation and Froude scaling; engines never look at JSON. Every field documents its unit.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "physics/boundary_spec.h"
#include "physics/material_spec.h"
#include "geometry/tet_mesh.h"

namespace fbar {

using Real3 = std::array<double, 3>;
using Int3 = std::array<int, 3>;

enum class Precision { Single, Double, Mixed };
enum class OnFailure { Stop, ReduceDt };
/// A body's state at t = 0 (bodies[].initial_state): Rest, stress-free (ClaymoreUW's); Hydrostatic, a fluid's
/// pressure in equilibrium with gravity below the top of its geometry (engine/hydrostatic.h).
enum class InitialState { Rest, Hydrostatic };
enum class Backend { Auto, Gpu, Cpu };
/// How scaling treats the materials' stresses and moduli (HydroUQ's use_cauchy_scaling): Default (the key absent):
/// x froude_scaling, Cauchy similitude at equal density; Off: as written (ClaymoreUW's behaviour); On: x
/// cauchy_bulk_ratio. Viscosities follow with an extra s^0.5 (stress x time); Off leaves them as written too.
enum class CauchyScaling { Default, Off, On };

struct SimulationSpec {
  Real3 domain{1.0, 1.0, 1.0};          ///< [m] extent of the simulated box, origin at (0,0,0)
  double dx = 0.1;                      ///< [m] grid spacing (default_dx)
  double default_dt = 0.0;              ///< [s] upper bound of the step; dx/100 when absent
  Real3 gravity{0.0, -9.81, 0.0};       ///< [m/s^2]
  double time = 0.0;                    ///< [s] start time
  double fps = 60.0;                    ///< [1/s] frames per simulated second
  int frames = 60;                      ///< number of frames written after the initial one
  std::string save_path = "./";         ///< output directory
  std::string save_suffix = ".bgeo";    ///< ".bgeo", ".geo", ".csv", ".h5"
  bool particles_output_exterior_only = false;
  double froude_scaling = 1.0;          ///< length scale factor s (1: none)
  /// True once froude_scaling has been applied to every field (the parser does it; a scene written by
  /// write_scene_json carries `"froude_scaling_applied": true` so that re-reading it does not scale twice).
  bool froude_scaling_applied = false;
  CauchyScaling cauchy_scaling = CauchyScaling::Default;
  double cauchy_bulk_ratio = 1.0;       ///< [Pa/Pa] model / prototype stiffness (CauchyScaling::On)
  int info_rate = 0;                    ///< log every N steps (0: once per frame)
  /// Write a checkpoint (io/checkpoint.h) every N frames (0: only when a run stops on a signal or a failure).
  int checkpoint_every = 0;
  Precision precision = Precision::Single;
  OnFailure on_failure = OnFailure::Stop;
  std::uint64_t seed = 0;               ///< seed for jittered particle sampling
};

/// F-bar's volume average (bodies[].algorithm.FBAR_scheme): Cell, fbar's per grid cell (physics/transfer.cuh); Nodal,
/// ClaymoreUW's JBar per particle through the nodes (physics/fbar_nodal.cuh).
enum class FbarScheme { Cell, Nodal };

struct AlgorithmSpec {
  std::string type = "particles";
  bool use_asflip = true;
  double asflip_alpha = 0.0;
  double asflip_beta_min = 0.0;
  double asflip_beta_max = 0.0;
  bool use_fbar = true;
  double fbar_psi = 0.0;
  bool fbar_fused_kernel = false;
  FbarScheme fbar_scheme = FbarScheme::Nodal;  // ClaymoreUW's; "cell" is fbar's own choice
  bool use_fem = false;

  /// The transfer is PIC-FLIP / ASFLIP (transfer.cuh): use_ASFLIP with some alpha or beta non-zero. All zero is
  /// APIC, and then neither engine stores particle velocities or v^n.
  bool asflip_active() const {
    return use_asflip && (asflip_alpha != 0.0 || asflip_beta_min != 0.0 || asflip_beta_max != 0.0);
  }
  /// F-bar's blend psi when use_FBAR is on, else 0 (0: off, no cell sums).
  double fbar_blend() const { return use_fbar ? fbar_psi : 0.0; }
  /// F-bar runs ClaymoreUW's nodal scheme (and the body carries JBar).
  bool fbar_nodal() const { return fbar_blend() != 0.0 && fbar_scheme == FbarScheme::Nodal; }
};

/// Bathymetry: water above a bed profile inside the box [offset, offset + span]; OsuLwf / OsuTwb: the same above a
/// facility's bed (scene/facilities.h), placed at offset.
enum class GeometryObject { Box, Sphere, Cylinder, File, Bathymetry, OsuLwf, OsuTwb };
enum class GeometryOperation { Add, Subtract, Union, Intersection, Difference };

struct GeometrySpec {
  GeometryObject object = GeometryObject::Box;
  GeometryOperation operation = GeometryOperation::Add;
  Real3 span{1.0, 1.0, 1.0};            ///< [m] box extent; cylinder length along its axis
  Real3 offset{0.0, 0.0, 0.0};          ///< [m] min corner of the box / of the bounding box
  double radius = 0.0;                  ///< [m] sphere and cylinder radius
  int axis = 0;                         ///< cylinder axis: 0 = X, 1 = Y, 2 = Z
  Real3 rotate{0.0, 0.0, 0.0};          ///< [deg] Euler angles (X, then Y, then Z) about fulcrum
  Real3 fulcrum{0.0, 0.0, 0.0};         ///< [m]
  Int3 array{1, 1, 1};                  ///< copies along X, Y, Z
  Real3 spacing{0.0, 0.0, 0.0};         ///< [m] distance between copies
  std::string file;                     ///< resolved path for object File
  int padding = 1;
  double scaling_factor = 1.0;
  bool use_froude_scaling = true;
  bool has_attributes = false;
  std::vector<std::string> input_attribs;
  std::vector<long long> track_particle_id;  ///< ClaymoreUW: ids (local to this entry) appended to the body's list
  /// [m] Bathymetry: the bed's [x, y] points (absolute); OsuLwf / OsuTwb with use_custom_bathymetry: they replace the
  /// facility's bed
  std::vector<std::array<double, 2>> bathymetry;
  bool use_custom_bathymetry = false;
};

/// BodySpec::gpu "all": the body is spread over every GPU rank by space (comm/placement.h).
constexpr int kAllGpus = -1;

struct BodySpec {
  /// ClaymoreUW's GPU of the whole body (>= 0), or kAllGpus. fbar places bodies on GPUs only when the scene's bodies
  /// name more than one GPU (comm/placement.h); otherwise every body is spread over the ranks by space and `gpu`
  /// names the frame files of a one-rank run (dev[gpu]).
  int gpu = 0;
  int model = 0;
  Real3 velocity{0.0, 0.0, 0.0};        ///< [m/s] initial velocity
  InitialState initial_state = InitialState::Rest;  ///< initial_state: "rest" or "hydrostatic"
  /// [m] particles outside [partition_start, partition_end] are removed at start.
  Real3 partition_start{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                        -std::numeric_limits<double>::infinity()};
  Real3 partition_end{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                      std::numeric_limits<double>::infinity()};
  std::vector<long long> track_particle_id;
  std::vector<std::string> output_attribs{"ID"};  ///< canonical attribute names (see attributes.h)
  bool output_exterior_only = false;  ///< output.exterior_only: frames hold the surface particles (io::ExteriorFilter)
  /// output.exterior_threshold: a particle is written when its grid block or a neighbour holds at most this many of
  /// the body's particles (ClaymoreUW's compile-time cutoff, 128, by default)
  double exterior_threshold = 128.0;
  std::vector<std::string> track_attribs;
  std::vector<std::string> target_attribs;
  MaterialSpec material;
  AlgorithmSpec algorithm;
  std::vector<GeometrySpec> geometry;
  /// >= 0: this body is the vertices of meshes[mesh] (an FEM body; physics/fem.cuh), appended after the particle
  /// bodies by the parser (append_mesh_bodies, scene_parse.h); its particles are the mesh's vertices and its
  /// material the elements' law. -1: a particle body.
  int mesh = -1;
  /// The mesh of meshes[mesh] (shared with it): sample_body() returns its vertices.
  std::shared_ptr<const TetMesh> tet_mesh;
};

enum class SensorOperation { Sum, Max, Min, Count, Average, STDEV, Variance };

struct GridSensorSpec {
  std::string name;                     ///< label (ClaymoreUW's "name"; files are named by index)
  bool toggle = true;                   ///< false: the sensor is switched off (no file)
  std::string attribute = "Force";      ///< Force, BoundaryForce, Acceleration, Momentum, Velocity, Mass, Volume, JBar
  SensorOperation operation = SensorOperation::Sum;
  Real3 direction{1.0, 0.0, 0.0};       ///< unit projection direction
  int direction_sign = 0;               ///< +1: only positive projections, -1: only negative, 0: both
  double output_frequency = 60.0;       ///< [Hz]
  Real3 domain_start{0.0, 0.0, 0.0};
  Real3 domain_end{0.0, 0.0, 0.0};
};

struct ParticleSensorSpec {
  std::string name;                     ///< label (ClaymoreUW's "name")
  bool toggle = true;                   ///< false: the sensor is switched off
  std::string attribute = "Position_Y";    ///< ClaymoreUW's default quantity (a wave gauge)
  SensorOperation operation = SensorOperation::Max;  ///< ClaymoreUW's particle-sensor default
  double output_frequency = 60.0;
  Real3 domain_start{0.0, 0.0, 0.0};
  Real3 domain_end{0.0, 0.0, 0.0};
};

/// One entry of the top-level "grid-fields" array (fbar's): the grid's node values inside a box, written at a
/// frequency as frame files ParaView opens as a time series (io/grid_field_recorder.h), from the same P2G state the
/// grid sensors read; or one point per grid block with its nodes' sums (`blocks`).
struct GridFieldSpec {
  std::string name;                     ///< label (files are named by the field's index)
  bool toggle = true;                   ///< false: switched off (no files)
  Real3 domain_start{0.0, 0.0, 0.0};    ///< [m] box, both ends included
  Real3 domain_end{0.0, 0.0, 0.0};
  double output_frequency = 0.0;        ///< [Hz]; 0: the frame rate (simulation.fps)
  /// Canonical names (kGridFieldAttributes: Mass, Velocity, Momentum, Force, BoundaryForce, Volume, JBar, MassWater,
  /// PorePressure); empty: Mass, Velocity, Force.
  std::vector<std::string> attributes;
  bool blocks = false;                  ///< one point per grid block (its nodes' sums) instead of one per node
};

/// One entry of the top-level "meshes" array (ClaymoreUW's FEM bodies, its keys and meanings: read_scene_input.h),
/// read and checked at parse, its mesh included (geometry/tet_mesh.h). The parser appends one body per entry to
/// Scene::bodies (BodySpec::mesh), which the CPU engine runs (physics/fem.cuh).
struct MeshEntrySpec {
  std::string file_vertices, file_elements;  ///< ClaymoreUW's CSV pair (resolved paths), or both empty
  std::string file;                          ///< a Gmsh MSH 4.1 file (resolved; fbar's), or empty
  Real3 offset{0.0, 0.0, 0.0};               ///< [m] added to every vertex
  Real3 velocity{0.0, 0.0, 0.0};             ///< [m/s] initial velocity of every vertex
  int gpu = 0;                               ///< the GPU (rank) that holds the whole mesh
  /// The elements' law: "Meshed" is ClaymoreUW's name for its FixedCorotated tetrahedra; FixedCorotated and
  /// NeoHookean may be named.
  Constitutive law = Constitutive::FixedCorotated;
  bool fbar_elements = false;                ///< use_FBAR: ClaymoreUW's Tetrahedron_FBar (J averaged per element)
  double rho = 1000.0;                       ///< [kg/m^3]
  double youngs_modulus = 1e7;               ///< [Pa]
  double poisson_ratio = 0.3;                ///< [-]
  double ppc = 8.0;                          ///< ClaymoreUW reads it for the vertex particles' volume (unused by its FEM)
  bool use_fem = false, use_asflip = true;   ///< ClaymoreUW runs a mesh only with both true
  double alpha = 0.0, beta_min = 0.0, beta_max = 0.0;  ///< ASFLIP (ClaymoreUW's legacy names; its FEM uses beta 0)
  /// use_FBAR's blend psi (physics/fem.cuh): ClaymoreUW reads FBAR_ratio and averages fully (psi = 1), fbar's default
  double fbar_ratio = 1.0;
  bool fbar_fused_kernel = false;            ///< read and unused by ClaymoreUW's FEM path
  std::vector<std::string> output_attribs{"ID"};
  std::vector<std::string> track_attribs;
  std::vector<long long> track_particle_id;
  std::string summary;                       ///< "8 vertices, 6 tetrahedra, volume ... m^3, ..."
  /// The mesh, its vertices placed at offset [m] (read once at parse; shared by the copies of the scene): the file's
  /// vertex x s + offset, s the Froude length factor (one way for a scene and for its written copy: both give the
  /// same bits).
  std::shared_ptr<const TetMesh> mesh;
  std::shared_ptr<const TetMesh> file_mesh;  ///< as the files hold it (unscaled, not placed)
  /// check_tet_mesh's measures of `mesh` (volume, quality, smallest height: the element step bound), taken once: by
  /// the parser, by Froude scaling, or by append_mesh_bodies for a mesh built in code.
  TetMeshStats stats;
};

struct Scene {
  std::string source_path;              ///< the scene file it came from ("" when built in code)
  std::string data_dir;                 ///< where geometry files are looked up
  SimulationSpec simulation;
  std::vector<BodySpec> bodies;
  std::vector<BoundarySpec> boundaries;
  std::vector<GridSensorSpec> grid_sensors;
  std::vector<ParticleSensorSpec> particle_sensors;
  std::vector<GridFieldSpec> grid_fields;  ///< the top-level "grid-fields" array (fbar's)
  std::vector<MeshEntrySpec> meshes;    ///< the top-level "meshes" array (FEM bodies; each also a body)
  /// HydroUQ's wrapper keys (Application, EventClassification, type, subtype, in that order; absent ones omitted):
  /// metadata that ClaymoreUW prints and fbar records (the scene writer, hence run.json); nothing reads them.
  std::vector<std::pair<std::string, std::string>> wrapper;
};

/// The JSON path of body b in messages: "meshes[m]" for a mesh's body (BodySpec::mesh), else "bodies[b]".
inline std::string body_path(const Scene& scene, std::size_t b) {
  const int m = b < scene.bodies.size() ? scene.bodies[b].mesh : -1;
  return m >= 0 ? "meshes[" + std::to_string(m) + "]" : "bodies[" + std::to_string(b) + "]";
}

}  // namespace fbar
