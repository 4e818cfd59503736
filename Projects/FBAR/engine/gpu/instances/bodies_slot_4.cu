// Slot 4 of the GPU engine's bodies: the laws of MaterialTypes at indices 4, 4 + kBodySlots, ... (body_factory.cuh) at
// every precision, Body<M> and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_SLOT(4);

}  // namespace fbar
