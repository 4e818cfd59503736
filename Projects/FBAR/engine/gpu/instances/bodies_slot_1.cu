// Slot 1 of the GPU engine's bodies: the laws of MaterialTypes at indices 1, 1 + kBodySlots, ... (body_factory.cuh) at
// every precision, Body<M> and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_SLOT(1);

}  // namespace fbar
