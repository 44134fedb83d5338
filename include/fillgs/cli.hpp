#pragma once
// The command-line front end as a library call, so tests can drive it.
#include <ostream>
#include <string>
#include <vector>

namespace fillgs::cli {

/// Runs `fillgs <args...>` (args excludes the program name). Prints results to `out`,
/// progress and the one-line error to `err`; returns the exit status.
int run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace fillgs::cli
