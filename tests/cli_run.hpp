#pragma once
// Runs the command line in-process for tests: exit status, both streams, wall time.
#include <catch2/catch.hpp>

#include <algorithm>
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

/// One line, exit 1, naming every word; and no message that names nothing (a library's own
/// words: stod, a JSON exception, an allocation).
inline void expect_error(const CliResult& r, const std::vector<std::string>& words) {
  INFO("stderr: " << r.err);
  CHECK(r.code == 1);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  for (const std::string& w : words) {
    INFO("should mention '" << w << "'");
    CHECK(r.err.find(w) != std::string::npos);
  }
  for (const char* nameless : {"error: stod", "error: stoull", "error: out of memory", "error: [json.exception", "error: cannot create std::vector"})
    CHECK(r.err.find(nameless) == std::string::npos);
}

}  // namespace fillgs::test
