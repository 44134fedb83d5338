#pragma once
// Runs the command line in-process for tests: exit status, both streams, wall time.
#include <chrono>
#include <sstream>
#include <string>
#include <vector>

#include "fillgs/cli.hpp"

namespace fillgs::test {

struct CliResult {
  int code;
  std::string out, err;
  double seconds;
};

inline CliResult run_cli(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  const auto t0 = std::chrono::steady_clock::now();
  const int code = cli::run(args, out, err);
  return {code, out.str(), err.str(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
}

}  // namespace fillgs::test
