// run_gpu(): the scene's precision picks run_gpu_as<T, TG> (gpu_engine_impl.cuh), compiled with that precision's
// driver in instances/driver_*.cu.
#include "engine/gpu/gpu_engine.h"

#include <iostream>
#include <stdexcept>

#include "MnSystem/Cuda/device_query.h"
#include "scene/scene_parse.h"

namespace fbar {

RunResult run_gpu(const Scene& scene, const RunOptions& options) {
  std::ostream& log = options.log ? *options.log : std::cout;
  return run_guarded([&] {
    check_supported(scene);  // before any sampling: also scenes built in code get the release policy's errors
    if (options.gpu >= 0) FBAR_CUDA_CHECK(cudaSetDevice(options.gpu));
    switch (scene.simulation.precision) {
      case Precision::Single: return run_gpu_as<float, float>(scene, options, log);
      case Precision::Double: return run_gpu_as<double, double>(scene, options, log);
      case Precision::Mixed: return run_gpu_as<double, float>(scene, options, log);
    }
    throw std::invalid_argument("simulation.precision: unknown value");
  });
}

}  // namespace fbar
