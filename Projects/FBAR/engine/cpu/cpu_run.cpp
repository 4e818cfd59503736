// run_cpu() (engine_api.h): the CPU engine built for the scene's precision, run through the frame loop of run_loop.h.
#include <omp.h>

#include <cmath>
#include <cstddef>
#include <iostream>
#include <memory>
#include <string>

#include "engine/cpu/cpu_engine.h"
#include "engine/engine_api.h"
#include "engine/run_loop.h"
#include "scene/scene_parse.h"

namespace fbar {
namespace {

template <typename T, typename TG>
RunResult run_with(const Scene& scene, const RunOptions& options, std::ostream& log) {
  comm::Transport* transport = options.transport;
  const bool decomposed = transport && transport->size() > 1;
  std::unique_ptr<io::Checkpoint> restart;
  if (!options.restart.empty())
    restart = std::make_unique<io::Checkpoint>(
        io::read_checkpoint_for(options.restart, decomposed ? transport->rank() : 0, decomposed ? transport->size() : 1));
  std::unique_ptr<CpuEngine<T, TG>> engine =
      restart      ? std::make_unique<CpuEngine<T, TG>>(scene, *restart, transport)
      : decomposed ? std::make_unique<CpuEngine<T, TG>>(scene, *transport)
                   : std::make_unique<CpuEngine<T, TG>>(scene);
  engine->set_log(decomposed && transport->rank() != 0 ? nullptr : &log);
  std::size_t particles = engine->particle_count();
  if (decomposed) particles = static_cast<std::size_t>(transport->sum(static_cast<long long>(particles)));
  std::string line = std::string("fbar: CPU reference engine (") + precision_description(scene.simulation.precision) +
                     "), " + std::to_string(particles) + " particles, " + std::to_string(engine->body_count()) +
                     " bodies, " + std::to_string(omp_get_max_threads()) + " threads";
  if (decomposed)
    line += " per rank; " + std::to_string(transport->size()) + " ranks, " + engine->slabs().describe() +
            ", imbalance " + std::to_string(std::lround(100.0 * engine->imbalance())) + " %";
  if (restart) {  // the particles are the engine's now; the loop needs the rest
    for (io::CheckpointBody& b : restart->bodies) b = io::CheckpointBody{};
  }
  return run_frames(*engine, scene, options, log, line, restart.get());
}

}  // namespace

RunResult run_cpu(const Scene& scene, const RunOptions& options) {
  std::ostream& log = options.log ? *options.log : std::cout;
  return run_guarded([&] {
    check_supported(scene);  // before any sampling: also scenes built in code get the release policy's errors
    switch (scene.simulation.precision) {
      case Precision::Single: return run_with<float, float>(scene, options, log);
      case Precision::Mixed: return run_with<double, float>(scene, options, log);
      case Precision::Double: break;
    }
    return run_with<double, double>(scene, options, log);
  });
}

}  // namespace fbar
