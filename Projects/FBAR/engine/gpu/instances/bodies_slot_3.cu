// Slot 3 of the GPU engine's bodies: the laws of MaterialTypes at indices 3, 3 + kBodySlots, ... (body_factory.cuh) at
// every precision, Body<M> and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_SLOT(3);

}  // namespace fbar
