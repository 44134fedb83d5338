// fillgs_bench <benchmark> [--smoke] [options]: benchmarks that call the library's own
// code paths and print ratios against references measured in the same run.
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "fillgs/base/error.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "fillgs/base/memory.hpp"

int bench_render(const std::vector<std::string>& args);
int bench_visibility(const std::vector<std::string>& args);
int bench_train(const std::vector<std::string>& args);
int bench_select(const std::vector<std::string>& args);
int bench_motion(const std::vector<std::string>& args);
int bench_n3v_rig(const std::vector<std::string>& args);
int bench_warp_check(const std::vector<std::string>& args);
int bench_networks(const std::vector<std::string>& args);
int bench_city(const std::vector<std::string>& args);

int main(int argc, char** argv) {
  fillgs::keep_freed_memory();
  if (argc < 2) {
    std::cerr << "usage: fillgs_bench render|visibility|train|select|motion|n3v-rig|warp-check|networks|city [options]; 'fillgs_bench <benchmark> --help' lists its options\n";
    return 2;
  }
  const std::string name = argv[1];
  std::vector<std::string> args(argv + 2, argv + argc);
  try {
    fillgs::limit_instruction_set_from_environment();
    if (name == "render") return bench_render(args);
    if (name == "visibility") return bench_visibility(args);
    if (name == "train") return bench_train(args);
    if (name == "select") return bench_select(args);
    if (name == "motion") return bench_motion(args);
    if (name == "n3v-rig") return bench_n3v_rig(args);
    if (name == "warp-check") return bench_warp_check(args);
    if (name == "networks") return bench_networks(args);
    if (name == "city") return bench_city(args);
    std::cerr << "error: unknown benchmark '" << name << "'\n";
    return 2;
  } catch (const fillgs::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
