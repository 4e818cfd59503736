// The GPU driver at mixed precision: MgspBenchmark<double, float>'s members, GpuEngine<double, float> and run_gpu_as<double, float>
// (the kernels of the grid, partition, halo, sensors and frames; the laws' kernels are in bodies_<law>.cu).
#include "engine/gpu/gpu_engine_impl.cuh"

namespace fbar {

template class MgspBenchmark<double, float>;
template class GpuEngine<double, float>;
template RunResult run_gpu_as<double, float>(const Scene&, const RunOptions&, std::ostream&);

}  // namespace fbar
