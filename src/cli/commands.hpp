#pragma once
// Every command, one file each (cmd_<name>.cpp; convert and cameras share cmd_convert.cpp):
// each declares its flags on `app` and returns what runs once they are parsed (options.hpp);
// commands.cpp holds the table of them and the entry point.
#include <nlohmann/json.hpp>

#include "options.hpp"

namespace fillgs::cli {

Action declare_info(CLI::App& app);
/// A model's summary as `fillgs info --json` prints it (render's summary.json repeats it).
nlohmann::json scene_summary(const GaussianCloud& c);
Action declare_render(CLI::App& app);
Action declare_synth(CLI::App& app);
Action declare_convert(CLI::App& app);
Action declare_cameras(CLI::App& app);
Action declare_observe(CLI::App& app);
Action declare_train(CLI::App& app);
Action declare_explore(CLI::App& app);
Action declare_select(CLI::App& app);
Action declare_finetune(CLI::App& app);
Action declare_eval(CLI::App& app);
Action declare_bench(CLI::App& app);
Action declare_run(CLI::App& app);

}  // namespace fillgs::cli
