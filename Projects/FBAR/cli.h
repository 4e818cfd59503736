// The command line of SCHEMA.md: parses arguments, loads and validates the scene, runs or checks it.
#pragma once

namespace fbar {

/// Entry point of the fbar executable; returns the process exit code (0 ok, 1 bad input, 2 run-time failure).
int cli_main(int argc, char** argv);

}  // namespace fbar
