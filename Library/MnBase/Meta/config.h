// Host/device decoration macros shared by every Library and project header.
#pragma once

#if defined(__CUDACC__)
#define FBAR_HOST_DEVICE __host__ __device__
#define FBAR_DEVICE __device__
#define FBAR_FORCE_INLINE __forceinline__
#else
#define FBAR_HOST_DEVICE
#define FBAR_DEVICE
#define FBAR_FORCE_INLINE inline __attribute__((always_inline))
#endif

// True while compiling device code (the nvcc device pass).
#if defined(__CUDA_ARCH__)
#define FBAR_IN_DEVICE_CODE 1
#else
#define FBAR_IN_DEVICE_CODE 0
#endif
