// The GPU driver at double precision: MgspBenchmark<double, double>'s members, GpuEngine<double, double> and run_gpu_as<double, double>
// (the kernels of the grid, partition, halo, sensors and frames; the laws' kernels are in bodies_<law>.cu).
#include "engine/gpu/gpu_engine_impl.cuh"

namespace fbar {

template class MgspBenchmark<double, double>;
template class GpuEngine<double, double>;
template RunResult run_gpu_as<double, double>(const Scene&, const RunOptions&, std::ostream&);

}  // namespace fbar
