// The FixedCorotated bodies of the GPU engine at every precision: Body<FixedCorotated> (device_bodies.cuh) and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_OF(FixedCorotated);

}  // namespace fbar
