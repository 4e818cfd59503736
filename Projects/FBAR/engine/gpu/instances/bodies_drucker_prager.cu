// The DruckerPrager bodies of the GPU engine at every precision: Body<DruckerPrager> (device_bodies.cuh) and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_OF(DruckerPrager);

}  // namespace fbar
