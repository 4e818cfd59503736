// Slot 0 of the GPU engine's bodies: the laws of MaterialTypes at indices 0, 0 + kBodySlots, ... (body_factory.cuh) at
// every precision, Body<M> and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_SLOT(0);

}  // namespace fbar
