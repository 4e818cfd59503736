// The GPU decomposition with one MPI process per rank and NCCL (the batch-job path): run under
//   mpirun -np 2 gpu_mpi_decomposition_check        (tools/benchmark/run_multi_gpu.sh; NCCL_NVLS_ENABLE=0 on shared hosts,
//                                                    NCCL_P2P_DISABLE=1 NCCL_SHM_DISABLE=1 for the network path)
// Every rank runs the ASFLIP + F-bar dam break and the travelling block on GPU (rank % visible GPUs); rank 0
// gathers the particles by ID, runs the same scene on one GPU without decomposition and compares with the
// tolerances of test_decomposition_gpu.cu. Exit code 0 when every comparison holds, 1 otherwise.
#include <cstdio>
#include <cstring>
#include <string>

#include "MnSystem/Cuda/device_query.h"
#include "comm/mpi_transport.h"
#include "decomposition_support.h"

using namespace fbar;

namespace {

comm::Bytes pack(const test::RunResult& r) {
  comm::Bytes out;
  auto put = [&](const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    out.insert(out.end(), b, b + n);
  };
  put(&r.time, sizeof(r.time));
  put(&r.steps, sizeof(r.steps));
  put(&r.migrated, sizeof(r.migrated));
  for (const auto& [key, s] : r.states) {
    put(&key.first, sizeof(int));
    put(&key.second, sizeof(int));
    put(&s, sizeof(s));
  }
  return out;
}

int check(const char* name, const Scene& scene, comm::Transport& mpi, int steps) {
  const int gpu = mpi.rank() % cuda::device_count();
  const test::RunResult mine = test::run_rank(scene, &mpi, steps, gpu, true);
  if (!mine.error.empty()) {
    std::fprintf(stderr, "%s: rank %d: %s\n", name, mpi.rank(), mine.error.c_str());
    mpi.abort(2);
  }
  const std::vector<comm::Bytes> all = mpi.allgather(pack(mine));
  if (mpi.rank() != 0) return 0;
  test::StateById merged;
  std::string problems;
  long long migrated = 0;
  for (std::size_t r = 0; r < all.size(); ++r) {
    const comm::Bytes& b = all[r];
    std::size_t at = 0;
    double time;
    long long steps_taken, moved;
    std::memcpy(&time, b.data() + at, sizeof(time));
    at += sizeof(time);
    std::memcpy(&steps_taken, b.data() + at, sizeof(steps_taken));
    at += sizeof(steps_taken);
    std::memcpy(&moved, b.data() + at, sizeof(moved));
    at += sizeof(moved);
    migrated += moved;
    if (steps_taken != mine.steps || time != mine.time) problems += "rank " + std::to_string(r) + " took other steps; ";
    while (at < b.size()) {
      int body, id;
      test::ParticleState s;
      std::memcpy(&body, b.data() + at, sizeof(int));
      std::memcpy(&id, b.data() + at + sizeof(int), sizeof(int));
      std::memcpy(&s, b.data() + at + 2 * sizeof(int), sizeof(s));
      at += 2 * sizeof(int) + sizeof(s);
      if (!merged.emplace(std::make_pair(body, id), s).second) problems += "particle " + std::to_string(id) + " twice; ";
    }
  }
  const test::RunResult one = test::run_rank(scene, nullptr, steps, 0, false);
  if (!one.error.empty()) problems += "one GPU: " + one.error + "; ";
  if (merged.size() != one.states.size()) problems += "particles lost or doubled; ";
  const test::Comparison c = test::compare(one, merged);
  const double max_dx = c.max_dx, max_dv = c.max_dv, momentum = c.momentum;
  const double dt_rel = std::fabs(mine.time - one.time) / one.time;
  if (!(max_dx < test::kPositionTolerance)) problems += "positions; ";
  if (!(max_dv < test::kVelocityTolerance)) problems += "velocities; ";
  if (!(momentum < test::kMomentumTolerance)) problems += "momentum; ";
  if (!(dt_rel < test::kTimeTolerance)) problems += "time; ";
  if (migrated == 0) problems += "no particle migrated; ";
  std::printf("[ MPI ranks %zu NCCL ] %s: %lld steps, migrated %lld, max |dx| %.3g m, max |dv| %.3g m/s, momentum "
              "%.3g, time %.3g: %s\n",
              all.size(), name, mine.steps, migrated, max_dx, max_dv, momentum, dt_rel,
              problems.empty() ? "OK" : problems.c_str());
  return problems.empty() ? 0 : 1;
}

}  // namespace

int main() {
#ifdef FBAR_HAS_MPI
  if (cuda::device_count() == 0) {
    std::fprintf(stderr, "no CUDA device: %s\n", cuda::no_device_reason().c_str());
    return 1;
  }
  comm::MpiTransport mpi;
  int failed = check("dam break (ASFLIP, F-bar)", test::dam_break(true), mpi, 120);
  failed += check("travelling block", test::travelling_block(mpi.size()), mpi, 120);
  failed = static_cast<int>(mpi.sum(static_cast<long long>(failed)));
  return failed == 0 ? 0 : 1;
#else
  std::fprintf(stderr, "built without MPI\n");
  return 1;
#endif
}
