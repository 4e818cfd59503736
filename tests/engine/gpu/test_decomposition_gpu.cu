// The GPU engine decomposed over 2 and 3 ranks against the same scene on one rank: every particle exactly once (so
// the same total mass exactly), momentum to summation order, particle states within a stated tolerance, the same
// steps and time. The ranks are threads of this process on device 0 with the peer-copy device transport
// (comm/device_transport.h): the halo sums, the agreed time step and the migration run exactly as with NCCL on
// several GPUs, so a one-GPU machine tests the decomposition logic; the two-GPU NCCL runs are in
// tools/benchmark/run_multi_gpu.sh.
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <stdexcept>
#include <thread>
#include <vector>

#include "comm/device_transport.h"
#include "comm/slab_partition.h"
#include "comm/transport.h"
#include "engine/gpu/gpu_engine.h"
#include "MnSystem/IO/async_writer.h"
#include "MnSystem/IO/particle_io.h"
#include "decomposition_support.h"
#include "gpu_test_support.h"

namespace fbar {
namespace {

using test::dam_break;
using test::run_rank;
using test::RunResult;
using test::travelling_block;

/// `ranks` threads; rank r on GPU r % gpus, NCCL when nccl (then every rank needs its own GPU).
RunResult run_decomposed(const Scene& scene, int ranks, int steps, int gpus = 1, bool nccl = false,
                         bool overlap = true, int rebalance_every = 0, int migrant_capacity = 0, double dt = 0.0) {
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(ranks);
  std::vector<RunResult> results(static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) threads.emplace_back([&, r] { results[r] = run_rank(scene, hosts[r].get(), steps, r % gpus, nccl, overlap, rebalance_every, migrant_capacity, dt); });
  for (auto& t : threads) t.join();
  RunResult merged;
  merged.mass = results[0].mass;
  for (int r = 0; r < ranks; ++r) {
    const RunResult& one = results[static_cast<std::size_t>(r)];
    if (!one.error.empty()) merged.error += "rank " + std::to_string(r) + ": " + one.error + "\n";
    merged.migrated += one.migrated;
    merged.compactions += one.compactions;
    merged.migration_repeats = std::max(merged.migration_repeats, one.migration_repeats);  // the same on every rank
    merged.halo_blocks = std::max(merged.halo_blocks, one.halo_blocks);
    merged.halo_particle_blocks = std::max(merged.halo_particle_blocks, one.halo_particle_blocks);
    merged.always_owned = merged.always_owned && one.always_owned;
    merged.rebalances = one.rebalances;  // the same on every rank
    merged.imbalance = one.imbalance;
    for (const auto& [key, state] : one.states)
      if (!merged.states.emplace(key, state).second)
        merged.error += "particle " + std::to_string(key.second) + " is on two ranks\n";
    if (r > 0 && (one.time != results[0].time || one.steps != results[0].steps))
      merged.error += "rank " + std::to_string(r) + " took other steps\n";
  }
  merged.time = results[0].time;
  merged.steps = results[0].steps;
  return merged;
}

using test::kMomentumTolerance;
using test::kPositionTolerance;
using test::kTimeTolerance;
using test::kVelocityTolerance;

/// gpus = 1: 2 and 3 ranks on GPU 0 (peer copies); gpus > 1: that many ranks, one per GPU, with NCCL. overlap:
/// the halo-first G2P2G with the halo sums on a second stream (GpuEngineOptions::overlap_halo), or one after the
/// other.
/// dt > 0: steps of exactly dt.
/// bits: the grid's sums (the seepage sums included) are fixed point and order-free and every rank uses the same
/// bounds and quanta (grid_buffer.cuh "Order-free grid sums"), so the ranks give one rank's particles bit for bit,
/// time included; the tolerances below remain as the looser bound of the same comparison.
void expect_same_run(const Scene& scene, int steps, bool expect_migration, int gpus = 1, bool overlap = true,
                     double dt = 0.0, bool bits = true) {
  FBAR_REQUIRE_DEVICE();
  const RunResult one = run_rank(scene, nullptr, steps, 0, false, true, 0, 0, dt);
  ASSERT_TRUE(one.error.empty()) << one.error;
  const std::vector<int> rank_counts = gpus > 1 ? std::vector<int>{gpus} : std::vector<int>{2, 3};
  for (int ranks : rank_counts) {
    SCOPED_TRACE(std::to_string(ranks) + " ranks" + (gpus > 1 ? " on as many GPUs (NCCL)" : " on one GPU") +
                 (overlap ? ", halo overlapped" : ", halo after G2P2G"));
    const RunResult many = run_decomposed(scene, ranks, steps, gpus, gpus > 1, overlap, 0, 0, dt);
    ASSERT_TRUE(many.error.empty()) << many.error;
    ASSERT_EQ(many.states.size(), one.states.size()) << "particles lost or doubled";
    for (const auto& [key, s] : one.states) ASSERT_EQ(many.states.count(key), 1u) << "particle " << key.second;
    EXPECT_EQ(many.mass, one.mass);  // per-particle mass per body; with every ID once, the total mass is exact
    EXPECT_EQ(many.steps, one.steps);
    EXPECT_NEAR(many.time, one.time, kTimeTolerance * one.time);
    EXPECT_TRUE(many.always_owned) << "a particle sat on a rank that does not own its block";
    EXPECT_GT(many.halo_blocks, 0u);
    if (overlap) EXPECT_GT(many.halo_particle_blocks, 0u) << "no particle block was run before the halo exchange";
    if (expect_migration)  // the scene moves particles across the cuts ...
      EXPECT_GT(many.migrated, 0);
    else  // ... or none (the placed bodies, the mesh by method)
      EXPECT_EQ(many.migrated, 0);
    const test::Comparison c = test::compare(one, many.states);
    const double max_dx = c.max_dx, max_dv = c.max_dv, momentum = c.momentum;
    std::printf("[ GPU ranks %d%s ] %lld steps, t = %.6g s, migrated %lld, halo blocks %zu, max |dx| %.3g m, "
                "max |dv| %.3g m/s, momentum %.3g, pore pressure %.3g\n",
                ranks, gpus > 1 ? " NCCL" : "", many.steps, many.time, many.migrated, many.halo_blocks, max_dx, max_dv, momentum,
                c.pore_pressure);
    EXPECT_LT(c.pore_pressure, test::kPorePressureTolerance);
    if (bits) {
      EXPECT_EQ(max_dx, 0.0) << "positions differ from one rank's";
      EXPECT_EQ(max_dv, 0.0) << "velocities differ from one rank's";
      EXPECT_EQ(many.time, one.time);
    }
    EXPECT_LT(max_dx, kPositionTolerance);
    EXPECT_LT(max_dv, kVelocityTolerance);
    EXPECT_LT(momentum, kMomentumTolerance);
  }
}

/// Two runs of one scene on one GPU give the same bits (grid_buffer.cuh "Order-free grid sums"): an elastic block
/// falling into the dam break's water, the water with ASFLIP and F-bar, at dx = 1 cm (65,000 particles, every node
/// summed from several particle blocks in arrival order), 400 CFL steps; positions, velocities, J and the time.
template <typename T>
void expect_two_runs_equal() {
  Scene scene = dam_break(true);
  scene.simulation.dx = 0.01;
  Scene with_block = test::placed_bodies(false);
  BodySpec block = with_block.bodies[1];
  block.gpu = scene.bodies[0].gpu;
  scene.bodies.push_back(block);
  std::vector<ParticleSnapshot<T>> runs[2];
  double time[2] = {0, 0};
  for (int run = 0; run < 2; ++run) {
    GpuEngine<T> engine(scene);
    engine.set_log(nullptr);
    engine.set_record_velocities(true);
    for (int s = 0; s < 400; ++s) ASSERT_TRUE(engine.step().ok);
    for (int b = 0; b < engine.body_count(); ++b) runs[run].push_back(engine.snapshot(b));
    time[run] = engine.time();
  }
  EXPECT_EQ(time[0], time[1]);
  ASSERT_EQ(runs[0].size(), 2u);
  std::size_t particles = 0;
  for (std::size_t b = 0; b < runs[0].size(); ++b) {
    const ParticleSnapshot<T>& a = runs[0][b];
    const ParticleSnapshot<T>& c = runs[1][b];
    ASSERT_EQ(a.x.size(), c.x.size());
    particles += a.x.size();
    std::size_t differ = 0;
    for (std::size_t p = 0; p < a.x.size(); ++p)
      differ += !(a.x[p] == c.x[p]) || !(a.v[p] == c.v[p]) || a.J[p] != c.J[p];
    EXPECT_EQ(differ, 0u) << "body " << b << ": particles whose state differs between two runs";
  }
  EXPECT_GT(particles, 60000u);
}
TEST(GpuDecomposition, TwoRunsGiveTheSameBitsFloat) {
  FBAR_REQUIRE_DEVICE();
  expect_two_runs_equal<float>();
}
TEST(GpuDecomposition, TwoRunsGiveTheSameBitsDouble) {
  FBAR_REQUIRE_DEVICE();
  expect_two_runs_equal<double>();
}

TEST(GpuDecomposition, DamBreakCrossesTheCuts) { expect_same_run(dam_break(false), 120, true); }

TEST(GpuDecomposition, DamBreakWithAsflipAndFbar) { expect_same_run(dam_break(true), 120, true); }
// ClaymoreUW's nodal F-bar, fused and split: the node sums cross the cuts, each particle's JBar migrates with it.
TEST(GpuDecomposition, DamBreakWithNodalFbar) {
  for (const bool fused : {true, false}) {
    SCOPED_TRACE(fused ? "fused" : "split");
    Scene scene = dam_break(true);
    scene.bodies[0].algorithm.fbar_scheme = FbarScheme::Nodal;
    scene.bodies[0].algorithm.fbar_fused_kernel = fused;
    expect_same_run(scene, 120, true);
  }
}

// The same runs with the halo sums after the whole G2P2G (no second stream): both orders give the one-rank result.
TEST(GpuDecomposition, DamBreakWithoutOverlap) { expect_same_run(dam_break(true), 120, true, 1, false); }

// A saturated soil block (CoupledUP, its pore water carrying its weight at the start; test::saturate), thrown along
// the slabs' axis against the tank's far wall while its water drains through its top: the seepage sums cross the
// halo before every grid update and the pore pressure migrates with the particles.
// Steps of 1.5e-4 s (the CFL step is 2.2e-4 s: c = 43 m/s undrained, 2 m/s, dx 0.02, CFL 0.5).
TEST(GpuDecomposition, SaturatedSoilDrainsAcrossTheCuts) {
  Scene scene = dam_break(false);
  test::saturate(scene.bodies[0]);
  scene.bodies[0].velocity = test::r3(2.0, 0.0, 0.0);
  expect_same_run(scene, 150, true, 1, true, 1.5e-4);
  expect_same_run(scene, 150, true, 1, false, 1.5e-4);  // the halo sums after the whole G2P2G
}

TEST(GpuDecomposition, TravellingBlockMigratesEveryParticle) { expect_same_run(travelling_block(), 120, true); }

// The travelling block leaves grid blocks behind on every rank: each rank compacts its grid on its own (its halo
// lists renumbered with it), and the ranks still give one rank's bits.
TEST(GpuDecomposition, TravellingBlockCompactsEachRanksGrid) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = travelling_block();
  const RunResult one = run_rank(scene, nullptr, 200);
  ASSERT_TRUE(one.error.empty()) << one.error;
  EXPECT_GE(one.compactions, 1);
  for (const bool overlap : {true, false}) {  // the halo-first G2P2G's block lists are renumbered too
    SCOPED_TRACE(overlap ? "halo overlapped" : "halo after G2P2G");
    const RunResult many = run_decomposed(scene, 2, 200, 1, false, overlap);
    ASSERT_TRUE(many.error.empty()) << many.error;
    EXPECT_GE(many.compactions, 1);  // each rank holds half the block: the 64-block floor is reached once
    std::printf("[ GPU ranks 2 ] grid compactions: one rank %lld, two ranks %lld (summed)\n", one.compactions,
                many.compactions);
    ASSERT_EQ(many.states.size(), one.states.size());
    const test::Comparison c = test::compare(one, many.states);
    EXPECT_EQ(c.max_dx, 0.0) << "positions differ from one rank's";
    EXPECT_EQ(c.max_dv, 0.0) << "velocities differ from one rank's";
  }
}

// Migration messages of 2 particles per body and side: the travelling block sends about 50 a step, so the first
// steps overflow them, are repeated with larger messages on every rank, and the run is still the one-rank run.
TEST(GpuDecomposition, MigrationMessagesGrowAndTheStepIsRepeated) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = travelling_block();
  const RunResult one = run_rank(scene, nullptr, 120);
  ASSERT_TRUE(one.error.empty()) << one.error;
  for (int ranks : {2, 3}) {
    SCOPED_TRACE(std::to_string(ranks) + " ranks, messages of 2 particles at first");
    const RunResult many = run_decomposed(scene, ranks, 120, 1, false, true, 0, 2);
    ASSERT_TRUE(many.error.empty()) << many.error;
    ASSERT_EQ(many.states.size(), one.states.size()) << "particles lost or doubled";
    EXPECT_EQ(many.mass, one.mass);
    EXPECT_EQ(many.steps, one.steps);
    EXPECT_GT(many.migration_repeats, 0) << "the messages never overflowed";
    EXPECT_LE(many.migration_repeats, 8) << "the messages grow geometrically";
    EXPECT_TRUE(many.always_owned);
    const test::Comparison c = test::compare(one, many.states);
    std::printf("[ GPU ranks %d ] messages from 2 particles: migrated %lld, %lld steps repeated, max |dx| %.3g m, "
                "max |dv| %.3g m/s, momentum %.3g\n", ranks, many.migrated, many.migration_repeats, c.max_dx, c.max_dv,
                c.momentum);
    EXPECT_LT(c.max_dx, kPositionTolerance);
    EXPECT_LT(c.max_dv, kVelocityTolerance);
    EXPECT_LT(c.momentum, kMomentumTolerance);
  }
}

// ClaymoreUW's bodies[].gpu: the water whole on rank 0 and the falling block whole on rank 1 (on 3 ranks the third
// holds nothing); their blocks are shared by ranks that need not be slab neighbours and are summed over all holders
// in rank order (no halo-first G2P2G: placed runs switch the overlap off). Nothing migrates.
TEST(GpuDecomposition, PlacedBodiesStayOnTheirRanks) {
  expect_same_run(test::placed_bodies(false), 120, false, 1, false);
}

// Placed and spread ("gpu": "all") bodies together: the spread column migrates between its slabs, whose blocks are
// also held by the placed bodies' ranks.
TEST(GpuDecomposition, PlacedAndSpreadBodiesTogether) {
  expect_same_run(test::placed_bodies(true), 120, true, 1, false);
}

// Partition by method: an FEM post (kernels/fem_kernels.cuh) whole on rank 1 while the dam break's water is
// spread over the ranks; the mesh's element impulse reaches the grid before the shared blocks are summed. In these
// 120 steps no water particle crosses a cut (measured on an H200: 2.7e-14 m/s from one rank, 2 and 3 ranks); the post
// and the water meet in the blocks the ranks share.
TEST(GpuDecomposition, PlacedMeshWithSpreadWater) {
  expect_same_run(test::dam_break_with_post(1), 120, false, 1, false);
}

// The travelling block leaves its first slabs: without rebalancing it ends on one rank; rebalancing every 10 steps
// (as the run loop does at frames) chooses the slabs again from the particles, moves them through the restart path,
// and the run stays the one-rank run (to the restart's tolerance: the rebuilt state's first grid is a fresh P2G).
TEST(GpuDecomposition, TravellingBlockIsRebalanced) {
  FBAR_REQUIRE_DEVICE();
  const Scene scene = travelling_block();
  const int steps = 120;
  const RunResult one = run_rank(scene, nullptr, steps);
  ASSERT_TRUE(one.error.empty()) << one.error;
  for (int ranks : {2, 3}) {
    SCOPED_TRACE(std::to_string(ranks) + " ranks");
    const RunResult fixed = run_decomposed(scene, ranks, steps);
    const RunResult moved = run_decomposed(scene, ranks, steps, 1, false, true, 10);
    ASSERT_TRUE(fixed.error.empty()) << fixed.error;
    ASSERT_TRUE(moved.error.empty()) << moved.error;
    EXPECT_EQ(fixed.rebalances, 0);
    EXPECT_GT(moved.rebalances, 0);
    ASSERT_EQ(moved.states.size(), one.states.size()) << "particles lost or doubled";
    EXPECT_EQ(moved.mass, one.mass);
    EXPECT_EQ(moved.steps, one.steps);
    EXPECT_TRUE(moved.always_owned) << "a particle sat on a rank that does not own its block";
    const test::Comparison c = test::compare(one, moved.states);
    std::printf("[ GPU ranks %d ] imbalance at the end %.3g without rebalancing, %.3g with %d rebalances; "
                "max |dx| %.3g m, max |dv| %.3g m/s, momentum %.3g\n",
                ranks, fixed.imbalance, moved.imbalance, moved.rebalances, c.max_dx, c.max_dv, c.momentum);
    EXPECT_LT(moved.imbalance, fixed.imbalance);
    EXPECT_LT(c.max_dx, test::kRebalancedPositionTolerance);
    EXPECT_LT(c.max_dv, test::kRebalancedVelocityTolerance);
    EXPECT_LT(c.momentum, 1e-12);
  }
}

// The same runs on every visible GPU, one rank each, through NCCL (tools/benchmark/run_multi_gpu.sh runs them on two
// GPUs with NCCL_NVLS_ENABLE=0; with NCCL_P2P_DISABLE=1 NCCL_SHM_DISABLE=1 they take NCCL's network path).
// (FBAR_REQUIRE_GPUS and test::visible_gpus(): gpu_test_support.h)

TEST(GpuDecomposition, NcclDamBreakOnEveryGpu) {
  FBAR_REQUIRE_GPUS(2);
  expect_same_run(dam_break(true), 120, true, test::visible_gpus());
}

TEST(GpuDecomposition, NcclTravellingBlockOnEveryGpu) {
  FBAR_REQUIRE_GPUS(2);
  expect_same_run(travelling_block(test::visible_gpus()), 120, true, test::visible_gpus());
}

// The same with the halo sums after the whole G2P2G (GpuEngineOptions::overlap_halo off, fbar's default).
TEST(GpuDecomposition, NcclDamBreakOnEveryGpuWithoutOverlap) {
  FBAR_REQUIRE_GPUS(2);
  expect_same_run(dam_break(true), 120, true, test::visible_gpus(), false);
}

TEST(GpuDecomposition, NcclTravellingBlockOnEveryGpuWithoutOverlap) {
  FBAR_REQUIRE_GPUS(2);
  expect_same_run(travelling_block(test::visible_gpus()), 120, true, test::visible_gpus(), false);
}

// Saturated soil on every GPU: the seepage sums' halo through NCCL (both halo orders).
TEST(GpuDecomposition, NcclSaturatedSoilOnEveryGpu) {
  FBAR_REQUIRE_GPUS(2);
  Scene scene = dam_break(false);
  test::saturate(scene.bodies[0]);
  scene.bodies[0].velocity = test::r3(2.0, 0.0, 0.0);
  expect_same_run(scene, 150, true, test::visible_gpus(), true, 1.5e-4);
  expect_same_run(scene, 150, true, test::visible_gpus(), false, 1.5e-4);
}

// Placed bodies on separate GPUs (NCCL between any pair of ranks, not only neighbours).
TEST(GpuDecomposition, NcclPlacedAndSpreadBodiesOnEveryGpu) {
  FBAR_REQUIRE_GPUS(2);
  expect_same_run(test::placed_bodies(true), 120, true, test::visible_gpus(), false);
}

// Partition by method on separate GPUs: the mesh on GPU 1, the water spread over every GPU (NCCL).
TEST(GpuDecomposition, NcclPlacedMeshWithSpreadWaterOnEveryGpu) {
  FBAR_REQUIRE_GPUS(2);
  expect_same_run(test::dam_break_with_post(1), 120, false, test::visible_gpus(), false);
}

// A decomposed rank's .bgeo frame: the GPU writes the point records (pack_bgeo_records) with each entry's ID taken
// from the rank's ID directory; read back, the file equals the rank's host-built frame (positions, ID, velocity).
TEST(GpuDecomposition, RankBgeoFramesHoldTheirIds) {
  FBAR_REQUIRE_DEVICE();
  Scene scene = dam_break(false);
  scene.bodies[0].output_attribs = {"ID", "Velocity_X", "Pressure"};
  const int ranks = 2;
  const auto dir = std::filesystem::temp_directory_path() / "fbar_rank_bgeo";
  std::filesystem::create_directories(dir);
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(ranks);
  std::vector<std::string> errors(ranks);
  std::vector<std::size_t> counts(ranks, 0);
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      try {
        std::unique_ptr<comm::DeviceTransport> device = comm::make_thread_device_transport(*hosts[r]);
        GpuEngineOptions options;
        options.ranks = hosts[r].get();
        options.device_ranks = device.get();
        options.frames = true;
        GpuEngine<double> engine(scene, options);
        engine.set_log(nullptr);
        engine.set_record_velocities(true);  // frame(): the host-built reference reads the recorded v and C
        for (int s = 0; s < 60; ++s) {
          engine.set_frame_capture(s == 59);
          if (!engine.step().ok) throw std::runtime_error("a step failed");
        }
        const auto file = dir / ("rank" + std::to_string(r) + ".bgeo");
        io::AsyncWriter writer(1);
        engine.submit_frame(0, file, writer);
        writer.close();
        const io::ParticleFrame reference = engine.frame(0), written = io::read_bgeo(file);
        counts[r] = written.size();
        if (written.size() != reference.size()) throw std::runtime_error("the file has another length");
        for (std::size_t p = 0; p < written.size(); ++p)
          for (int d = 0; d < 3; ++d)
            if (std::fabs(written.position(p)[d] - reference.position(p)[d]) > 1e-6)
              throw std::runtime_error("position of entry " + std::to_string(p));
        const io::FrameAttribute *id = reference.find("ID"), *id_written = written.find("ID");
        if (!id || !id_written || id->values != id_written->values) throw std::runtime_error("the ID column");
        // The device's and the host's evaluation of the same state: equal up to rounding (1e-5 of the scale).
        for (const char* name : {"Velocity_X", "Pressure"}) {
          const io::FrameAttribute *a = reference.find(name), *w = written.find(name);
          if (!a || !w) throw std::runtime_error(std::string("no column ") + name);
          const auto &av = std::get<std::vector<float>>(a->values), &wv = std::get<std::vector<float>>(w->values);
          double scale = 1e-30, err = 0.0;
          for (std::size_t p = 0; p < av.size(); ++p) {
            scale = test::worst(scale, std::fabs(static_cast<double>(av[p])));
            err = test::worst(err, std::fabs(static_cast<double>(av[p]) - static_cast<double>(wv[p])));
          }
          if (err > 1e-5 * scale) throw std::runtime_error(std::string("column ") + name + " differs by " + std::to_string(err));
        }
        const auto& ids = std::get<std::vector<std::int32_t>>(written.find("ID")->values);
        if (!std::is_sorted(ids.begin(), ids.end())) throw std::runtime_error("IDs out of order");
      } catch (const std::exception& e) {
        errors[r] = e.what();
        hosts[r]->abort(1);
      }
    });
  for (auto& t : threads) t.join();
  for (int r = 0; r < ranks; ++r) EXPECT_TRUE(errors[r].empty()) << "rank " << r << ": " << errors[r];
  EXPECT_GT(counts[0], 0u);
  EXPECT_GT(counts[1], 0u);
}

/// Two ranks (threads) each send the other two messages in one exchange call, of different sizes and contents: the
/// k-th message one rank sends the other arrives in the other's k-th message with it (the step sends its halo sums
/// and its migrants to a neighbour in one call). nccl: rank r on GPU r through NCCL; else peer copies on device 0.
void expect_messages_pair_in_order(bool nccl) {
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(2);
  std::vector<std::string> errors(2);
  std::vector<std::thread> threads;
  for (int r = 0; r < 2; ++r)
    threads.emplace_back([&, r] {
      try {
        FBAR_CUDA_CHECK(cudaSetDevice(nccl ? r : 0));
        std::unique_ptr<comm::DeviceTransport> device =
            nccl ? comm::make_nccl_transport(*hosts[r]) : comm::make_thread_device_transport(*hosts[r]);
        cudaStream_t stream;
        FBAR_CUDA_CHECK(cudaStreamCreate(&stream));
        const std::size_t sizes[2] = {64, 1000};  // ints per message: the first, then the second
        std::vector<int*> out(2), in(2);
        std::vector<comm::DeviceTransport::Message> messages;
        for (int k = 0; k < 2; ++k) {
          std::vector<int> values(sizes[k]);
          for (std::size_t i = 0; i < values.size(); ++i) values[i] = 1000000 * r + 1000 * k + static_cast<int>(i % 997);
          FBAR_CUDA_CHECK(cudaMalloc(&out[k], sizeof(int) * sizes[k]));
          FBAR_CUDA_CHECK(cudaMalloc(&in[k], sizeof(int) * sizes[k]));
          FBAR_CUDA_CHECK(cudaMemcpy(out[k], values.data(), sizeof(int) * sizes[k], cudaMemcpyHostToDevice));
          comm::DeviceTransport::Message m;
          m.peer = 1 - r;
          m.send = out[k];
          m.recv = in[k];
          m.send_bytes = m.recv_bytes = sizeof(int) * sizes[k];
          messages.push_back(m);
        }
        device->exchange(messages, stream);
        FBAR_CUDA_CHECK(cudaStreamSynchronize(stream));
        for (int k = 0; k < 2; ++k) {
          std::vector<int> got(sizes[k]);
          FBAR_CUDA_CHECK(cudaMemcpy(got.data(), in[k], sizeof(int) * sizes[k], cudaMemcpyDeviceToHost));
          for (std::size_t i = 0; i < got.size(); ++i)
            if (got[i] != 1000000 * (1 - r) + 1000 * k + static_cast<int>(i % 997))
              throw std::runtime_error("message " + std::to_string(k) + " entry " + std::to_string(i) + ": got " +
                                       std::to_string(got[i]));
          FBAR_CUDA_CHECK(cudaFree(out[k]));
          FBAR_CUDA_CHECK(cudaFree(in[k]));
        }
        hosts[r]->barrier();  // the peer's copies out of this rank's buffers are done (the exchange waited for them)
        FBAR_CUDA_CHECK(cudaStreamDestroy(stream));
      } catch (const std::exception& e) {
        errors[r] = e.what();
        hosts[r]->abort(1);
      }
    });
  for (auto& t : threads) t.join();
  for (int r = 0; r < 2; ++r) EXPECT_EQ(errors[r], "") << "rank " << r;
}

TEST(GpuDecomposition, SeveralMessagesToOneRankPairInOrder) {
  FBAR_REQUIRE_DEVICE();
  expect_messages_pair_in_order(false);
}

TEST(GpuDecomposition, NcclSeveralMessagesToOneRankPairInOrder) {
  FBAR_REQUIRE_GPUS(2);
  expect_messages_pair_in_order(true);
}

TEST(GpuDecomposition, RefusesOneSidedTransports) {
  FBAR_REQUIRE_DEVICE();
  std::vector<std::unique_ptr<comm::Transport>> hosts = comm::make_thread_transports(1);
  GpuEngineOptions options;
  options.ranks = hosts[0].get();  // a host transport without a device transport
  EXPECT_THROW(GpuEngine<double>(dam_break(false), options), std::invalid_argument);
}

}  // namespace
}  // namespace fbar
