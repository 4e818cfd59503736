// The command line (docs/user_guide.md §1): parses arguments, loads and validates the scene, runs or checks it.
#pragma once

#include "engine/engine_api.h"
#include "engine/gpu/gpu_architectures.h"

namespace fbar {

/// The engines an executable links beyond the CPU reference engine. The fbar executable (project.cu) passes the GPU
/// engine's run_gpu and gpu_engine_fit when it is built with the GPU engine; a program that links only the front
/// end (the CLI tests, a build without the CUDA toolkit) passes nothing and runs on the CPU.
struct EngineSet {
  RunResult (*run_gpu)(const Scene& scene, const RunOptions& options) = nullptr;
  /// Whether the GPU engine runs on CUDA device d (gpu_check.cu); nullptr: taken to run on every device.
  GpuCodeFit (*gpu_fit)(int device) = nullptr;
};

/// Entry point of the fbar executable; returns the process exit code (0 ok, 1 bad input, 2 run-time failure).
int cli_main(int argc, char** argv, const EngineSet& engines = {});

}  // namespace fbar
