// The CoupledUP bodies of the GPU engine at every precision: Body<CoupledUP> (device_bodies.cuh) and its kernels.
#include "engine/gpu/body_factory.cuh"

namespace fbar {

FBAR_GPU_BODIES_OF(CoupledUP);

}  // namespace fbar
