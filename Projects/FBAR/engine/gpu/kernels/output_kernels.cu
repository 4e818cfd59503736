// The output kernels that are not templates (output_kernels.cuh declares them), defined in one unit.
#include "engine/gpu/kernels/output_kernels.cuh"

namespace fbar {

__global__ void __launch_bounds__(kOutputThreads)
    p2g_blocks_by_id(const int* record, int slots, int particles, int blocks, int first, int count, int* block_of,
                     int* errors) {
  const int slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot >= slots) return;
  const int id = record[2 * static_cast<std::size_t>(slot)], block = record[2 * static_cast<std::size_t>(slot) + 1];
  if (id < 0) return;
  if (id >= particles || block < 0 || block >= blocks) {
    atomicAdd(errors, 1);
    return;
  }
  if (id < first || id - first >= count) return;
  if (atomicExch(block_of + (id - first), block) != -1) atomicAdd(errors, 1);
}

}  // namespace fbar
