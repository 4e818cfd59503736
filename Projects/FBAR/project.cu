// fbar's main: hands the command line and the GPU engine (when built) to the front end (cli.h), which runs the scene.
// Host code only: a build without the CUDA toolkit compiles it as C++ (Projects/FBAR/CMakeLists.txt).
#include "cli.h"
#if defined(FBAR_HAS_CUDA)
#include "engine/gpu/gpu_engine.h"
#endif

int main(int argc, char** argv) {
  fbar::EngineSet engines;
#if defined(FBAR_HAS_CUDA)
  engines.run_gpu = &fbar::run_gpu;
  engines.gpu_fit = &fbar::gpu_engine_fit;
#endif
  return fbar::cli_main(argc, argv, engines);
}
