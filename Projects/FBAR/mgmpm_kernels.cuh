// The GPU engine's kernels (ClaymoreUW's entry point name): one header per kernel family.
#pragma once

#include "kernels/kernel_common.cuh"
#include "kernels/grid_update_kernels.cuh"
#include "kernels/g2p2g_kernel.cuh"
#include "kernels/partition_kernels.cuh"
#include "kernels/output_kernels.cuh"
