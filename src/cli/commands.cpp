// The command table and the entry point: `fillgs <command>` parses the command's flags
// and runs it (each command in cmd_<name>.cpp).
#include "fillgs/cli.hpp"
#include "fillgs/io/camera_io.hpp"
#include <nlohmann/json.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include "fillgs/base/error.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/train/init.hpp"
#include "fillgs/visibility/observe_io.hpp"
#include "fillgs/visibility/observe_mpi.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/train/train_job.hpp"
#include "fillgs/visibility/visibility.hpp"
#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"

namespace fillgs::cli {

namespace {


/// `--kernel simd|scalar`, accepted by every command: which tile kernel renders, trains and
/// blurs the loss for this invocation (raster.hpp, Kernel); the default again afterwards.
class KernelChoice {
 public:
  explicit KernelChoice(Kernel kernel) {
    if (kernel != Kernel::Default) set_default_kernel(kernel);
  }
  ~KernelChoice() { set_default_kernel(previous_); }

 private:
  Kernel previous_ = resolve_kernel(Kernel::Default);
};

void add_common_flags(CLI::App& app, CommonFlags& c) {
  add_number(app, "--threads", c.threads, "worker threads (0: all cores)", at_least(0))->group("Common options");
  add_flag(app, "--quiet", c.quiet, "no progress bar")->group("Common options");
  add_choice(app, "--kernel", c.kernel, "the tile kernel: vector (default) or the scalar reference")->group("Common options");
}

void print_overview(std::ostream& out) {
  out << "fillgs: fill observation gaps in 4D Gaussian Splatting\n\nusage: fillgs <command> [options]\n\ncommands:\n";
  for (const Command& c : commands()) {
    std::string name = c.name;
    out << "  " << name << std::string(name.size() < 10 ? 10 - name.size() : 1, ' ') << c.summary << "\n";
  }
  out << "\n'fillgs <command> --help' lists a command's options with their defaults; 'fillgs --version'.\n"
      << "README.md explains the workflow, from your own 4D model to fine-tuned results; the formats are in data/README.md.\n";
}

/// One command's parser: its flags, the common ones, and help made from them.
std::unique_ptr<CLI::App> make_app(const Command& c, CommonFlags& common, Action* action) {
  auto app = make_parser(std::string("fillgs ") + c.name, c.summary);
  *action = c.declare(*app);
  add_common_flags(*app, common);
  return app;
}

std::string help_of(const Command& c) {
  CommonFlags common;
  Action action;
  return make_app(c, common, &action)->help();
}

}  // namespace

const std::vector<Command>& commands() {
  static const std::vector<Command> all = {
      {"info", "Gaussian count, SH degree, motion, static/dynamic, bounding box", declare_info},
      {"render", "render every camera of a camera file", declare_render},
      {"synth", "the chair/shelf analysis scene with ground-truth images", declare_synth},
      {"convert", "a model as 3DGS, fillgs or one 3DGS PLY per frame", declare_convert},
      {"cameras", "cameras as transforms.json or COLMAP text", declare_cameras},
      {"observe", "observation counts C[t][g], speeds s, deficiency D = s/(1+C)", declare_observe},
      {"train", "train a 4D Gaussian model from multi-view video", declare_train},
      {"explore", "the exploration grid: exploration.vdb, exploration.png", declare_explore},
      {"select", "viewpoint-time selection by a strategy", declare_select},
      {"finetune", "fine-tune with refined virtual views (a trained network's model is given keys first, as dense as its motion needs: it says how many)", declare_finetune},
      {"eval", "PSNR, SSIM, moving-region PSNR per split", declare_eval},
      {"bench", "the paper's comparison (resumable); --merge: its tables over finished runs", declare_bench},
      {"run", "the whole pipeline on the built-in scene, with a report", declare_run},
  };
  return all;
}

std::string command_help(const std::string& name) {
  for (const Command& c : commands())
    if (name == c.name) return help_of(c);
  throw_error("fillgs: unknown command '", name, "' (see 'fillgs help')");
}

int run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  try {
    if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
      if (args.size() >= 2 && args[0] == "help") out << command_help(args[1]);
      else print_overview(out);
      return args.empty() ? 2 : 0;
    }
    limit_instruction_set_from_environment();
    if (args[0] == "--version") {
      const std::string& cap = instruction_set_limit();
      out << "fillgs " << FILLGS_VERSION << "\nkernels: " << kernel_instruction_set()
          << (cap.empty() ? std::string(" (the CPU's widest)") : " (held to " + cap + " by FILLGS_INSTRUCTION_SET)") << "\n";
      return 0;
    }
    const Command* command = nullptr;
    for (const Command& c : commands())
      if (args[0] == c.name) command = &c;
    if (!command) throw_error("fillgs: unknown command '", args[0], "' (see 'fillgs help')");
    CommonFlags common;
    Action action;
    const std::unique_ptr<CLI::App> app = make_app(*command, common, &action);
    if (!parse_flags(*app, std::vector<std::string>(args.begin() + 1, args.end()), out)) return 0;  // --help
    const KernelChoice kernel(common.kernel);
    const ThreadLimit threads(common.threads);
    const Invocation in{command->name, *app, common, args, out, err};
    return action(in);
  } catch (const Error& e) {
    err << "error: " << output_paths(e.what()) << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    err << "error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    err << "error: " << output_paths(e.what()) << "\n";
    return 1;
  }
}

}  // namespace fillgs::cli
