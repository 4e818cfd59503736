// fbar's main: hands the command line and the GPU engine to the front end (cli.h), which loads the scene and runs it.
#include "cli.h"
#include "engine/gpu/gpu_engine.h"

int main(int argc, char** argv) {
  fbar::EngineSet engines;
  engines.run_gpu = &fbar::run_gpu;
  return fbar::cli_main(argc, argv, engines);
}
