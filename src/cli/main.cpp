#include <iostream>

#include "fillgs/cli.hpp"
#include "fillgs/base/memory.hpp"

int main(int argc, char** argv) {
  fillgs::keep_freed_memory();
  std::vector<std::string> args(argv + 1, argv + argc);
  return fillgs::cli::run(args, std::cout, std::cerr);
}
