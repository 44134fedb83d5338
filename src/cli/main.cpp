#include <iostream>

#include "fillgs/cli.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  return fillgs::cli::run(args, std::cout, std::cerr);
}
