#pragma once
// The commands declared outside cli.cpp: each declares its flags on `app` and returns what
// runs once they are parsed (options.hpp).
#include "options.hpp"

namespace fillgs::cli {

Action declare_explore(CLI::App& app);
Action declare_select(CLI::App& app);
Action declare_finetune(CLI::App& app);
Action declare_eval(CLI::App& app);
Action declare_bench(CLI::App& app);
Action declare_run(CLI::App& app);

}  // namespace fillgs::cli
