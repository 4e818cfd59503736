// Runs the fbar command line in-process with captured output (the CLI tests here and in tests/engine/gpu).
#pragma once

#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cli.h"

namespace fbar::test {

struct CliResult {
  int code = -1;
  std::string out, err;
};

/// Runs cli_main with `args` (argv[0] = "fbar") and `engines`, capturing std::cout and std::cerr.
inline CliResult run_cli(std::vector<std::string> args, const EngineSet& engines = {}) {
  args.insert(args.begin(), "fbar");
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::ostringstream out, err;
  struct Redirect {
    std::ostream& s;
    std::streambuf* old;
    Redirect(std::ostream& stream, std::streambuf* to) : s(stream), old(stream.rdbuf(to)) {}
    ~Redirect() { s.rdbuf(old); }
  } r1(std::cout, out.rdbuf()), r2(std::cerr, err.rdbuf());
  CliResult r;
  r.code = cli_main(static_cast<int>(args.size()), argv.data(), engines);
  r.out = out.str();
  r.err = err.str();
  return r;
}

}  // namespace fbar::test
