// The NeoHookean bodies of the GPU engine at every precision: Body<NeoHookean> (device_bodies.cuh) and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_OF(NeoHookean);

}  // namespace fbar
