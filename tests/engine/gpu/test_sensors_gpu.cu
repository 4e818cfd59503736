// Grid sensors on the GPU engine: the same sums as the CPU engine (its oracle) sample by sample, and the same sums on
// 2 and 3 ranks (threads on one GPU, peer copies) as on one, each halo node counted once.
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "comm/device_transport.h"
#include "comm/transport.h"
#include "engine/cpu/cpu_engine.h"
#include "engine/gpu/gpu_engine.h"
#include "io/sensor_recorder.h"
#include "../cpu/decomposition_scenes.h"
#include "gpu_test_support.h"

namespace fbar {
namespace {

/// The dam break's load cells: floor force (Y-), the right half's x momentum, all mass, the largest x velocity,
/// the average speed along y, the count of nodes with mass, the volume on the nodes of the left half and the mean
/// and least JBar of all nodes.
std::vector<GridSensorSpec> dam_break_sensors() {
  const auto make = test::grid_sensor_spec;
  const Real3 all_lo{0, 0, 0}, all_hi{0.64, 0.4, 0.2};
  return {make("Force", SensorOperation::Sum, all_lo, {0.64, 0.05, 0.2}, {0, 1, 0}, -1),
          make("Momentum", SensorOperation::Sum, {0.2, 0, 0}, all_hi, {1, 0, 0}, 0),
          make("Mass", SensorOperation::Sum, all_lo, all_hi, {1, 0, 0}, 0),
          make("Velocity", SensorOperation::Max, all_lo, all_hi, {1, 0, 0}, 0),
          make("Velocity", SensorOperation::Average, all_lo, all_hi, {0, 1, 0}, 0),
          make("Mass", SensorOperation::Count, all_lo, all_hi, {1, 0, 0}, 0),
          make("Volume", SensorOperation::Sum, all_lo, {0.3, 0.4, 0.2}, {1, 0, 0}, 0),
          make("JBar", SensorOperation::Average, all_lo, all_hi, {1, 0, 0}, 0),
          make("JBar", SensorOperation::Min, all_lo, all_hi, {1, 0, 0}, 0)};
}

constexpr int kSteps = 60;

/// Per step, per sensor: the reduced value (allreduced over the ranks of `host`).
using Series = std::vector<std::vector<double>>;

/// Fixed steps of kDt (the engines' CFL steps are compared elsewhere: here the sensors are).
constexpr double kDt = 2e-4;

/// The ranks' parts of one sample merged as the recorder does (io/sensor_recorder.cpp): the sums' words as integers.
void merge_over_ranks(SensorAccum& x, comm::Transport& host) {
  constexpr int kW = ExactSum::kWords;
  long long words[2 * kW];
  double rest[3] = {x.sum.special, x.sum_sq.special, x.count};
  for (int w = 0; w < kW; ++w) {
    words[w] = x.sum.word[w];
    words[kW + w] = x.sum_sq.word[w];
  }
  host.allreduce_sum(words, 2 * kW);
  host.allreduce_sum(rest, 3);
  host.allreduce_max(&x.max, 1);
  host.allreduce_min(&x.min, 1);
  for (int w = 0; w < kW; ++w) {
    x.sum.word[w] = words[w];
    x.sum_sq.word[w] = words[kW + w];
  }
  x.sum.special = rest[0];
  x.sum_sq.special = rest[1];
  x.count = rest[2];
}

template <class Engine>
Series sample_every_step(Engine& engine, comm::Transport* host, const std::vector<GridSensorSpec>& sensors) {
  Series out;
  engine.set_grid_sensors(sensors);
  for (int s = 0; s < kSteps; ++s) {
    engine.set_grid_sample(0);
    const StepReport r = engine.step(kDt);
    if (!r.ok) throw std::runtime_error(r.message());
    std::vector<SensorAccum> a = engine.grid_samples(1);
    std::vector<double> row;
    for (std::size_t i = 0; i < sensors.size(); ++i) {
      SensorAccum x = a[i];
      if (host && host->size() > 1) merge_over_ranks(x, *host);
      row.push_back(sensor_result(sensors[i].operation, x));
    }
    out.push_back(row);
  }
  return out;
}

/// |a - b| <= rel * scale + floor per entry (scale: the largest |value| of that column over the run; floor: for
/// columns whose exact value is 0, e.g. a momentum that cancels).
void expect_series_near(const Series& a, const Series& b, double rel, const char* what, double floor = 1e-14) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.front().size(); ++i) {
    double scale = 0.0;
    for (const auto& row : a) scale = test::worst(scale, std::fabs(row[i]));
    for (std::size_t s = 0; s < a.size(); ++s)
      EXPECT_NEAR(a[s][i], b[s][i], rel * scale + floor) << what << ": sensor " << i << ", step " << s + 1;
  }
}

TEST(GpuGridSensors, MatchTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::dam_break(false);
  const std::vector<GridSensorSpec> sensors = dam_break_sensors();
  CpuEngine<double> cpu(scene);
  cpu.set_log(nullptr);
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const Series c = sample_every_step(cpu, nullptr, sensors);
  const Series g = sample_every_step(gpu, nullptr, sensors);
  // Double precision, the same fixed steps: the engines' states agree to ~1e-16 m (test_gpu_vs_cpu.cu), node sums
  // to summation order: 1e-9 of each sensor's range. The node count is exact.
  expect_series_near(c, g, 1e-9, "GPU vs CPU");
  for (int s = 0; s < kSteps; ++s) EXPECT_EQ(c[s][5], g[s][5]) << "node count, step " << s + 1;
  EXPECT_GT(c.back()[0], 0.0);  // the floor carries the water
}

// Volume and JBar of a body with ClaymoreUW's nodal F-bar (the stored JBar, fused and split): the CPU engine's
// values sample by sample.
TEST(GpuGridSensors, VolumeAndJBarOfNodalFbarMatchTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  for (const bool fused : {true, false}) {
    Scene scene = test::dam_break(false);
    scene.bodies[0].algorithm.fbar_psi = 0.5;
    scene.bodies[0].algorithm.fbar_scheme = FbarScheme::Nodal;
    scene.bodies[0].algorithm.fbar_fused_kernel = fused;
    const std::vector<GridSensorSpec> sensors = dam_break_sensors();
    CpuEngine<double> cpu(scene);
    cpu.set_log(nullptr);
    GpuEngine<double> gpu(scene);
    gpu.set_log(nullptr);
    const Series c = sample_every_step(cpu, nullptr, sensors);
    const Series g = sample_every_step(gpu, nullptr, sensors);
    expect_series_near(c, g, 1e-9, fused ? "nodal fused, GPU vs CPU" : "nodal split, GPU vs CPU");
    EXPECT_LT(c.back()[8], 1.0 - 1e-5) << "the water compresses: some node's JBar is below 1";
  }
}

/// `ranks` GPU ranks as threads, each running sample(engine, host) on its engine; returns every rank's series (every
/// rank must complete). nccl: rank r on GPU r through NCCL (FBAR_REQUIRE_GPUS); otherwise all on device 0 (peer copies).
template <class Sample>
std::vector<Series> run_gpu_ranks(const Scene& scene, int ranks, const Sample& sample, bool nccl = false) {
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(ranks);
  std::vector<Series> series(ranks);
  std::vector<std::string> errors(ranks);
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      try {
        FBAR_CUDA_CHECK(cudaSetDevice(nccl ? r : 0));
        std::unique_ptr<comm::DeviceTransport> device =
            nccl ? comm::make_nccl_transport(*hosts[r]) : comm::make_thread_device_transport(*hosts[r]);
        GpuEngineOptions options;
        options.ranks = hosts[r].get();
        options.device_ranks = device.get();
        GpuEngine<double> engine(scene, options);
        engine.set_log(nullptr);
        series[r] = sample(engine, hosts[r].get());
      } catch (const std::exception& e) {
        errors[r] = e.what();
        hosts[r]->abort(2);
      }
    });
  for (auto& t : threads) t.join();
  for (int r = 0; r < ranks; ++r) EXPECT_EQ(errors[r], "") << "rank " << r;
  return series;
}

/// Grid sensors of the dam break on 1 rank and on each of `rank_counts` ranks (nccl: one GPU per rank).
void expect_grid_sums_as_one_rank(std::initializer_list<int> rank_counts, bool nccl) {
  const Scene scene = test::dam_break(false);
  const std::vector<GridSensorSpec> sensors = dam_break_sensors();
  GpuEngine<double> one(scene);
  one.set_log(nullptr);
  const Series s1 = sample_every_step(one, nullptr, sensors);
  for (int ranks : rank_counts) {
    const std::vector<Series> all = run_gpu_ranks(
        scene, ranks, [&](GpuEngine<double>& e, comm::Transport* host) { return sample_every_step(e, host, sensors); },
        nccl);
    for (int r = 1; r < ranks; ++r) EXPECT_EQ(all[r], all[0]) << "every rank reduces to the same values";
    const Series& sn = all[0];
    if (sn.empty()) continue;
    // The grid is one rank's bit for bit and the sensors' sums are order-free (physics/sensors.cuh ExactSum): every
    // value equal, the halo nodes counted once.
    EXPECT_EQ(sn, s1) << (ranks == 2 ? "2 ranks" : "3 ranks");
  }
}

TEST(GpuGridSensors, RanksSumToOneRank) {
  FBAR_REQUIRE_DEVICE();
  expect_grid_sums_as_one_rank({2, 3}, false);
}

// The same sums with each rank on its own GPU, the halo and migration through NCCL.
TEST(GpuGridSensors, NcclRanksSumToOneRank) {
  FBAR_REQUIRE_GPUS(2);
  expect_grid_sums_as_one_rank({2}, true);
}

/// A grid field's nodes every step (ordered by index), as the run loop's recorder orders them.
template <class Engine>
std::vector<std::vector<GridFieldNode>> field_every_step(Engine& engine, comm::Transport* host, const GridFieldSpec& f) {
  std::vector<std::vector<GridFieldNode>> out;
  engine.set_grid_fields({f});
  for (int s = 0; s < kSteps; ++s) {
    engine.set_grid_field_sample(1u);
    const StepReport r = engine.step(kDt);
    if (!r.ok) throw std::runtime_error(r.message());
    GridFieldSample g = engine.grid_field_sample(0);
    if (g.dt != kDt) throw std::runtime_error("grid field: the sample's dt is not the step's");
    if (host && host->size() > 1) {  // every rank's nodes
      comm::Bytes mine(g.nodes.size() * sizeof(GridFieldNode));
      if (!g.nodes.empty()) std::memcpy(mine.data(), g.nodes.data(), mine.size());
      g.nodes.clear();
      for (const comm::Bytes& b : host->allgather(mine)) {
        const std::size_t at = g.nodes.size(), n = b.size() / sizeof(GridFieldNode);
        g.nodes.resize(at + n);
        if (n) std::memcpy(g.nodes.data() + at, b.data(), n * sizeof(GridFieldNode));
      }
    }
    std::sort(g.nodes.begin(), g.nodes.end(), [](const GridFieldNode& a, const GridFieldNode& b) {
      return std::tie(a.index[0], a.index[1], a.index[2]) < std::tie(b.index[0], b.index[1], b.index[2]);
    });
    out.push_back(std::move(g.nodes));
  }
  return out;
}

// Grid fields (physics/grid_fields.h): the GPU records the CPU engine's nodes step by step (the same nodes; values to
// 1e-9 of their range in double), and 2 ranks record one rank's nodes bit for bit (order-free sums).
TEST(GpuGridFields, MatchTheCpuEngineAndRanksRecordOneRanksNodes) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::dam_break(false);
  GridFieldSpec f;
  f.domain_start = {0.2, 0.0, 0.0};
  f.domain_end = {0.64, 0.4, 0.2};
  f.attributes = {"Mass", "Momentum", "BoundaryForce", "Volume", "JBar"};
  CpuEngine<double> cpu(scene);
  cpu.set_log(nullptr);
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const auto c = field_every_step(cpu, nullptr, f);
  const auto g = field_every_step(gpu, nullptr, f);
  ASSERT_EQ(c.size(), g.size());
  for (std::size_t s = 0; s < c.size(); ++s) {
    ASSERT_EQ(c[s].size(), g[s].size()) << "step " << s + 1;
    ASSERT_GT(c[s].size(), 0u);
    for (std::size_t i = 0; i < c[s].size(); ++i) {
      const GridFieldNode &a = c[s][i], &b = g[s][i];
      ASSERT_TRUE(a.index[0] == b.index[0] && a.index[1] == b.index[1] && a.index[2] == b.index[2]) << "step " << s + 1;
      EXPECT_NEAR(a.m, b.m, 1e-9 * (1.0 + a.m));
      for (int d = 0; d < 3; ++d) {
        EXPECT_NEAR(a.p[d], b.p[d], 1e-9 * (1.0 + std::fabs(a.p[d])));
        EXPECT_NEAR(a.boundary[d], b.boundary[d], 1e-6 * (1.0 + std::fabs(a.boundary[d])));
      }
      EXPECT_NEAR(a.volume, b.volume, 1e-9 * a.volume);
      EXPECT_NEAR(a.volume_jbar, b.volume_jbar, 1e-9 * a.volume + 1e-20);
    }
  }
  std::vector<std::vector<std::vector<GridFieldNode>>> ranks(2);
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(2);
  std::vector<std::string> errors(2);
  std::vector<std::thread> threads;
  for (int r = 0; r < 2; ++r)
    threads.emplace_back([&, r] {
      try {
        std::unique_ptr<comm::DeviceTransport> device = comm::make_thread_device_transport(*hosts[r]);
        GpuEngineOptions options;
        options.ranks = hosts[r].get();
        options.device_ranks = device.get();
        GpuEngine<double> engine(scene, options);
        engine.set_log(nullptr);
        ranks[r] = field_every_step(engine, hosts[r].get(), f);
      } catch (const std::exception& e) {
        errors[r] = e.what();
        hosts[r]->abort(2);
      }
    });
  for (auto& t : threads) t.join();
  for (int r = 0; r < 2; ++r) ASSERT_EQ(errors[r], "") << "rank " << r;
  ASSERT_EQ(ranks[0].size(), g.size());
  for (std::size_t s = 0; s < g.size(); ++s) {
    ASSERT_EQ(ranks[0][s].size(), g[s].size()) << "step " << s + 1;
    EXPECT_EQ(std::memcmp(ranks[0][s].data(), g[s].data(), g[s].size() * sizeof(GridFieldNode)), 0)
        << "step " << s + 1 << ": 2 ranks record one rank's nodes bit for bit";
  }
}

// ClaymoreUW-placed load cells (against each wall of a hydrostatic tank, from outside; decomposition_scenes.h
// claymore_tank): the GPU reads what the CPU engine reads, step by step, on 1 rank and on 2 (threads on one GPU, the
// cut between the walls), and both walls read rho g H^2 D / 2 within the budget of the CPU test
// (test_sensors.cpp GridSensors.ClaymorePlacedTankLoadCellsReadTheWallLoad: 1 %, the compressibility dominating).
TEST(GpuGridSensors, ClaymorePlacedTankLoadCellsMatchTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::claymore_tank();
  CpuEngine<double> cpu(scene);
  cpu.set_log(nullptr);
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const Series c = sample_every_step(cpu, nullptr, scene.grid_sensors);
  const Series g = sample_every_step(gpu, nullptr, scene.grid_sensors);
  expect_series_near(c, g, 1e-9, "GPU vs CPU");
  for (int wall : {0, 1}) {
    double mean = 0.0;
    for (const auto& row : g) mean += row[wall] / g.size();
    EXPECT_NEAR(mean, test::kClaymoreTankLoad, 0.01 * test::kClaymoreTankLoad) << "wall " << wall;
  }
  const std::vector<Series> two = run_gpu_ranks(scene, 2, [&](GpuEngine<double>& e, comm::Transport* host) {
    return sample_every_step(e, host, scene.grid_sensors);
  });
  if (!two[0].empty()) EXPECT_EQ(two[0], g) << "2 ranks";  // bit for bit (order-free sums)
}

/// The dam break's particle sensors: a gauge (Position_Y Max) over the column, the water's Velocity_X Average, the
/// Pressure Average and the Count over the whole tank, the speed's Max.
std::vector<ParticleSensorSpec> dam_break_particle_sensors() {
  const auto make = test::particle_sensor_spec;
  const Real3 lo{0, 0, 0}, hi{0.64, 0.4, 0.2};
  return {make("Position_Y", SensorOperation::Max, {0.1, 0, 0}, {0.2, 0.4, 0.2}),
          make("Velocity_X", SensorOperation::Average, lo, hi), make("Pressure", SensorOperation::Average, lo, hi),
          make("Mass", SensorOperation::Count, lo, hi), make("Velocity_Magnitude", SensorOperation::Max, lo, hi)};
}

/// Per sample (the initial state, then after every step), per sensor: the value, reduced over the ranks of `host`.
template <class Engine>
Series sample_particles_every_step(Engine& engine, comm::Transport* host, const std::vector<ParticleSensorSpec>& sensors) {
  Series out;
  engine.set_particle_sensors(sensors);
  auto take = [&](int slot) {
    engine.sample_particles(slot);
    std::vector<SensorAccum> a = engine.particle_samples(slot + 1);
    std::vector<double> row;
    for (std::size_t i = 0; i < sensors.size(); ++i) {
      SensorAccum x = a[static_cast<std::size_t>(slot) * sensors.size() + i];  // one body
      if (host && host->size() > 1) merge_over_ranks(x, *host);
      row.push_back(sensor_result(sensors[i].operation, x));
    }
    out.push_back(row);
  };
  take(0);
  for (int s = 0; s < kSteps; ++s) {
    engine.keep_particle_inputs(true);
    const StepReport r = engine.step(kDt);
    if (!r.ok) throw std::runtime_error(r.message());
    take(s % 4 + 1);  // slots reused as between two flushes
  }
  return out;
}

TEST(GpuParticleSensors, MatchTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::dam_break(false);
  const std::vector<ParticleSensorSpec> sensors = dam_break_particle_sensors();
  CpuEngine<double> cpu(scene);
  cpu.set_log(nullptr);
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const Series c = sample_particles_every_step(cpu, nullptr, sensors);
  const Series g = sample_particles_every_step(gpu, nullptr, sensors);
  expect_series_near(c, g, 1e-9, "particle sensors, GPU vs CPU");
  for (std::size_t s = 0; s < c.size(); ++s) EXPECT_EQ(g[s][3], 7200.0) << "every particle counted, sample " << s;
  EXPECT_NEAR(c.front()[0], 0.24 - 0.005, 1e-12);  // the still column's top particle row
  EXPECT_GT(c.back()[1], 0.005);                     // the water flows along +x (measured 0.009 m/s)
}

// Stress attributes derived from F and sigma (PK1, PK2) and strains of a solid block hitting the floor: the GPU
// kernel must compute the stress for them too (it did only for the Cauchy quantities).
TEST(GpuParticleSensors, SolidStressesMatchTheCpuEngine) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::small_scene(Constitutive::FixedCorotated, Precision::Double);
  const Real3 lo{0, 0, 0}, hi{1, 1, 1};
  const std::vector<ParticleSensorSpec> sensors = {test::particle_sensor_spec("StressPK1_YY", SensorOperation::Min, lo, hi),
                                                   test::particle_sensor_spec("StressPK2_1", SensorOperation::Max, lo, hi),
                                                   test::particle_sensor_spec("VonMisesStrain", SensorOperation::Average, lo, hi),
                                                   test::particle_sensor_spec("StressCauchy_Invariant1", SensorOperation::Sum, lo, hi)};
  CpuEngine<double> cpu(scene);
  cpu.set_log(nullptr);
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const Series c = sample_particles_every_step(cpu, nullptr, sensors);
  const Series g = sample_particles_every_step(gpu, nullptr, sensors);
  expect_series_near(c, g, 1e-9, "solid stresses, GPU vs CPU");
  EXPECT_LT(c.back()[0], -1.0);  // the impact compresses the block: a compressive nominal stress [Pa]
}

void expect_particle_sums_as_one_rank(bool nccl) {
  const Scene scene = test::dam_break(false);
  const std::vector<ParticleSensorSpec> sensors = dam_break_particle_sensors();
  GpuEngine<double> one(scene);
  one.set_log(nullptr);
  const Series s1 = sample_particles_every_step(one, nullptr, sensors);
  const std::vector<Series> series = run_gpu_ranks(
      scene, 2, [&](GpuEngine<double>& e, comm::Transport* host) { return sample_particles_every_step(e, host, sensors); },
      nccl);
  ASSERT_FALSE(series[0].empty());
  EXPECT_EQ(series[1], series[0]) << "every rank reduces to the same values";
  EXPECT_EQ(series[0], s1) << (nccl ? "particle sensors, 2 GPUs" : "particle sensors, 2 ranks");  // bit for bit
}

TEST(GpuParticleSensors, RanksSumToOneRank) {
  FBAR_REQUIRE_DEVICE();
  expect_particle_sums_as_one_rank(false);
}

TEST(GpuParticleSensors, NcclRanksSumToOneRank) {
  FBAR_REQUIRE_GPUS(2);
  expect_particle_sums_as_one_rank(true);
}

/// Tracked particles of the travelling block (every particle migrates; bins are reordered every step): IDs 0, 100,
/// 4095 with position, velocity and pressure, after every fixed step.
TrackerSet block_tracker() {
  TrackerSet t;
  t.ids = 3;
  t.id[0] = 0;
  t.id[1] = 100;
  t.id[2] = 4095;
  t.attribs = 3;
  t.column[0] = FrameColumn{FrameQuantity::Position, 0, 0};
  t.column[1] = FrameColumn{FrameQuantity::Velocity, 0, 0};
  t.column[2] = FrameColumn{FrameQuantity::Pressure, 0, 0};
  return t;
}

template <class Engine>
Series track_every_step(Engine& engine, comm::Transport* host) {
  Series out;
  engine.set_tracker(0, block_tracker());
  for (int s = 0; s < kSteps; ++s) {
    engine.keep_particle_inputs(true);
    const StepReport r = engine.step(kDt);
    if (!r.ok) throw std::runtime_error(r.message());
    std::vector<double> values, present;
    engine.track(0, values, present);
    if (host && host->size() > 1) {
      host->allreduce_sum(values.data(), static_cast<int>(values.size()));
      host->allreduce_sum(present.data(), static_cast<int>(present.size()));
    }
    for (double p : present) EXPECT_EQ(p, 1.0) << "every tracked particle on exactly one rank, step " << s + 1;
    out.push_back(values);
  }
  return out;
}

TEST(GpuTrackers, FollowParticlesThroughReorderingAndMigration) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = test::travelling_block();
  CpuEngine<double> cpu(scene);
  cpu.set_log(nullptr);
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const Series c = track_every_step(cpu, nullptr);
  const Series g = track_every_step(gpu, nullptr);
  // The unstressed block's pressure is round-off, E x 1e-16 ~ 1e-12 Pa, and differs with the summation order (ranks):
  // an absolute 1e-9 (Pa, and far below any position or velocity error that matters) covers it.
  expect_series_near(c, g, 1e-9, "trackers, GPU vs CPU", 1e-9);
  const std::vector<Series> series =
      run_gpu_ranks(scene, 2, [](GpuEngine<double>& e, comm::Transport* host) { return track_every_step(e, host); });
  ASSERT_FALSE(series[0].empty());
  expect_series_near(g, series[0], 1e-9, "trackers, 2 ranks", 1e-9);
  // The block moves at 2 m/s: each tracked particle too.
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(g.back()[i * 3 + 1], 2.0, 1e-9);
}

// The tracked particles cross from one GPU to the other (NCCL migration) and are followed there.
TEST(GpuTrackers, FollowParticlesAcrossGpus) {
  FBAR_REQUIRE_GPUS(2);
  const Scene scene = test::travelling_block();
  GpuEngine<double> gpu(scene);
  gpu.set_log(nullptr);
  const Series g = track_every_step(gpu, nullptr);
  const std::vector<Series> series = run_gpu_ranks(
      scene, 2, [](GpuEngine<double>& e, comm::Transport* host) { return track_every_step(e, host); }, true);
  ASSERT_FALSE(series[0].empty());
  expect_series_near(g, series[0], 1e-9, "trackers, 2 GPUs", 1e-9);
}

}  // namespace
}  // namespace fbar
