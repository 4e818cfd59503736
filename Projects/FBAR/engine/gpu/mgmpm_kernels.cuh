// The GPU engine's kernels (ClaymoreUW's entry point name): one header per kernel family.
#pragma once

#include "engine/gpu/kernels/kernel_common.cuh"
#include "engine/gpu/kernels/grid_update_kernels.cuh"
#include "engine/gpu/kernels/g2p2g_kernel.cuh"
#include "engine/gpu/kernels/fbar_kernels.cuh"
#include "engine/gpu/kernels/partition_kernels.cuh"
#include "engine/gpu/kernels/output_kernels.cuh"
#include "engine/gpu/kernels/halo_kernels.cuh"
#include "engine/gpu/kernels/seepage_kernels.cuh"
#include "engine/gpu/kernels/fem_kernels.cuh"
