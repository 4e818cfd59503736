// The GPU driver at single precision: MgspBenchmark<float, float>'s members, GpuEngine<float, float> and run_gpu_as<float, float>
// (the kernels of the grid, partition, halo, sensors and frames; the laws' kernels are in bodies_<law>.cu).
#include "engine/gpu/gpu_engine_impl.cuh"

namespace fbar {

template class MgspBenchmark<float, float>;
template class GpuEngine<float, float>;
template RunResult run_gpu_as<float, float>(const Scene&, const RunOptions&, std::ostream&);

}  // namespace fbar
