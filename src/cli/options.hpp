#pragma once
// Declaring a command's flags: each flag is declared once, with its name, its typed
// destination (a field of the library's option struct where there is one), its default
// (the destination's value when declared), its help and its check. Parsing, `--help` and
// the error lines are all made from those declarations (CLI11 underneath).
//
//   Action declare_render(CLI::App& app) {
//     auto f = std::make_shared<RenderFlags>();
//     add_path(app, "--scene", f->scene, "the model (PLY)")->required();
//     add_number(app, "--time", f->time, "render every camera at this time", within(0, 1));
//     return [f](const Invocation& in) { ... };
//   }
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <functional>
#include <limits>
#include <memory>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "fillgs/model/camera.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/bounds.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/base/math.hpp"
#include "fillgs/base/names.hpp"
#include "fillgs/base/row_table.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/train/train.hpp"

namespace fillgs::cli {

// The bounds live in the library (base/bounds.hpp), where the Python module checks with them too.
using fillgs::Bounds;
using fillgs::at_least;
using fillgs::from_below;
using fillgs::positive;
using fillgs::within;
using fillgs::within_open;

using fillgs::Clock;
using fillgs::seconds_since;

/// The flags every command accepts.
struct CommonFlags {
  int threads = 0;  ///< 0: all cores
  bool quiet = false;
  Kernel kernel = Kernel::Default;
};

/// A parsed command line, handed to the command's action.
struct Invocation {
  std::string command;  ///< "render"
  const CLI::App& app;
  const CommonFlags& common;
  const std::vector<std::string>& args;  ///< as typed, the command's name first
  std::ostream& out;
  std::ostream& err;

  /// Whether the flag was given (rather than left at its default); false for a flag the
  /// command does not declare.
  bool given(const std::string& flag) const {
    const CLI::Option* o = app.get_option_no_throw(flag);
    return o && o->count() > 0;
  }
  /// Progress on stderr unless --quiet: a bar on a terminal, lines in a log (TerminalProgress).
  bool progress() const { return !common.quiet; }
  /// Throws the one-line error "fillgs <command>: <parts>".
  template <typename... Parts>
  [[noreturn]] void fail(const Parts&... parts) const {
    throw_error("fillgs ", command, ": ", parts...);
  }
};

/// read_scene, the model's walk over its frames (a trained model's still rule or keys) on the
/// command's progress bar.
GaussianCloud read_scene_shown(const std::string& path, SceneReadOptions options, const Invocation& in);


using Action = std::function<int(const Invocation&)>;

/// A command of the front end: its name, one line for `fillgs help`, and the function that
/// declares its flags and returns what runs once they are parsed.
struct Command {
  const char* name;
  const char* summary;
  Action (*declare)(CLI::App& app);
};

/// Every command, in the order `fillgs help` lists them.
const std::vector<Command>& commands();

/// An empty parser named `name` ("fillgs render"), with `summary` heading its help: unknown
/// flags are collected for parse_flags to name, and a flag given twice counts the last time.
std::unique_ptr<CLI::App> make_parser(const std::string& name, const std::string& summary);
/// Parses a command's own arguments (its name left out) into the flags declared on `app`.
/// Returns false when --help was asked for (the help is then printed to `out`); otherwise
/// an unknown flag, a bad value or a missing one throws the one-line Error.
bool parse_flags(CLI::App& app, const std::vector<std::string>& args, std::ostream& out);

// ------------------------------------------------------------------ checks

// ------------------------------------------------------------------ declarations

/// A flag without a value: `dest` becomes true when given.
CLI::Option* add_flag(CLI::App& app, const std::string& flag, bool& dest, const std::string& help);
/// A flag without a value that turns `dest` off (--no-plots, --from-scratch).
CLI::Option* add_switch_off(CLI::App& app, const std::string& flag, bool& dest, const std::string& help);
/// A string; `type` names it in the help (PATH, DIR, NAME, CMD).
CLI::Option* add_text(CLI::App& app, const std::string& flag, std::string& dest, const std::string& help, const std::string& type = "TEXT");
/// A comma-separated list ("a,b,c"); empty items are dropped.
CLI::Option* add_list(CLI::App& app, const std::string& flag, std::vector<std::string>& dest, const std::string& help);
/// Three comma-separated numbers, "r,g,b".
CLI::Option* add_colour(CLI::App& app, const std::string& flag, Vec3f& dest, const std::string& help);
/// A size given in `unit` bytes (MB, GB) as a number >= 0, stored in bytes.
CLI::Option* add_bytes(CLI::App& app, const std::string& flag, int64_t& dest, double unit, const std::string& unit_name, const std::string& help);

using fillgs::check_number;

/// A number: integral types take integers only; the bounds are checked.
template <class T>
CLI::Option* add_number(CLI::App& app, const std::string& flag, T& dest, const std::string& help, Bounds bounds = {}) {
  static_assert(std::is_arithmetic_v<T>);
  constexpr bool integral = std::is_integral_v<T>;
  if (integral) {
    bounds.lo = std::max(bounds.lo, double(std::numeric_limits<T>::lowest()));
    bounds.hi = std::min(bounds.hi, std::min(double(std::numeric_limits<T>::max()), 1e15));
  }
  const std::string name = app.get_name();
  CLI::Option* o = app.add_option(
      flag,
      [&dest, flag, bounds, name](const CLI::results_t& r) {
        double x = 0;
        const std::string why = check_number(r.back(), integral, bounds, &x);
        if (!why.empty()) throw_error(name, ": ", flag, " ", why);
        dest = T(x);
        return true;
      },
      help);
  std::ostringstream def;
  def << dest;
  o->type_name(integral ? "N" : "X")->default_str(def.str());
  return o;
}

/// The items of a comma-separated list ("a,b,c"); empty items are dropped.
std::vector<std::string> split_commas(const std::string& s);

/// The value of `name`'s `flag` that an enum's table names; otherwise one line naming the
/// command, the flag and the value.
template <class E>
E parse_choice(const std::string& name, const std::string& flag, const std::string& value) {
  try {
    return parse_name<E>(value);
  } catch (const Error& e) {
    throw_error(name, ": ", flag, ": ", e.what());
  }
}

/// "a|b|c": an enum's names as the value type the help shows.
template <class E>
std::string choice_type() {
  std::string names;
  for (const std::string& n : names_of<E>()) names += (names.empty() ? "" : "|") + n;
  return names;
}

/// One of an enum's names (names.hpp); the help lists them.
template <class E>
CLI::Option* add_choice(CLI::App& app, const std::string& flag, E& dest, const std::string& help) {
  const std::string name = app.get_name();
  CLI::Option* o = app.add_option(
      flag,
      [&dest, flag, name](const CLI::results_t& r) {
        dest = parse_choice<E>(name, flag, r.back());
        return true;
      },
      help);
  o->type_name(choice_type<E>());
  if (std::string(to_string(dest)) != "?") o->default_str(to_string(dest));
  return o;
}

/// One of a table's names (model formats, refiners): `canonical` turns a name the user gave
/// into the row's own, or throws the table's one-line message; the help lists `names`.
CLI::Option* add_row_choice(CLI::App& app, const std::string& flag, std::string& dest, const std::vector<std::string>& names,
                            std::function<std::string(const std::string&)> canonical, const std::string& help);

/// A flag for each of `parameters` (rows' own, base/row_table.hpp): `--<key>` and its
/// aliases, its help, default and check from the declaration; a value given lands in `values`.
void add_row_parameters(CLI::App& app, RowParameterValues& values, const std::vector<const RowParameter*>& parameters, const std::string& group);

/// One of a row table's names (its aliases parse to the row's own); the help lists them.
template <class Row>
CLI::Option* add_table_choice(CLI::App& app, const std::string& flag, std::string& dest, const RowTable<Row>& table, const std::string& help) {
  std::vector<std::string> names;
  for (const Row* r : table.rows()) names.push_back(r->name);
  return add_row_choice(app, flag, dest, names, [&table](const std::string& v) { return table.find(v).name; }, help);
}

/// A comma-separated list of an enum's names ("a,b"); the help lists them.
template <class E>
CLI::Option* add_choice_list(CLI::App& app, const std::string& flag, std::vector<E>& dest, const std::string& help) {
  const std::string name = app.get_name();
  CLI::Option* o = app.add_option(
      flag,
      [&dest, flag, name](const CLI::results_t& r) {
        dest.clear();
        for (const std::string& item : split_commas(r.back())) dest.push_back(parse_choice<E>(name, flag, item));
        return true;
      },
      help);
  o->type_name(choice_type<E>() + ",..");
  return o;
}

// ------------------------------------------------------------------ groups shared by commands

/// --scene-format, --duration, --stg-duration, --stg-color, --static-threshold.
void add_scene_flags(CLI::App& app, SceneReadOptions& o);
/// --camera-format, --width, --height, --llff-downscale.
void add_camera_flags(CLI::App& app, CameraReadOptions& o);
/// --frames first:last:step, --downscale, --monocular-cycle, --image-memory; and, when
/// `cameras_flag` is given (--train-cameras, --select-cameras), the rig cameras to keep.
void add_dataset_flags(CLI::App& app, DatasetOptions& o, const std::string& cameras_flag);

/// The time grid of observe and select: --times, or --frames F, or what the scene or the
/// cameras imply (a static scene with untimed cameras has one time, t = 0).
struct TimeFlags {
  int frames = 0;
  std::vector<double> times;
};
/// --frames F and, with `times`, --times t1,t2,...
void add_time_flags(CLI::App& app, TimeFlags& f, bool times);
/// The times to observe at. Refuses, before any work, a frame count whose views (a camera
/// per time) and, with `tables_in_memory`, [T, N] tables would need more memory than the
/// process may use.
std::vector<double> observe_times(const Invocation& in, const TimeFlags& f, const GaussianCloud& cloud, const std::vector<Camera>& cams,
                                  double* frame_step, bool tables_in_memory = false);

}  // namespace fillgs::cli

namespace fillgs::cli {

/// The action of a command whose flags live in `flags`: `run(flags, invocation)`.
template <class Flags>
Action bind(std::shared_ptr<Flags> flags, int (*run)(const Flags&, const Invocation&)) {
  return [flags, run](const Invocation& in) { return run(*flags, in); };
}

}  // namespace fillgs::cli

#include "fillgs/explore/exploration.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/method/refiners.hpp"
#include "fillgs/method/select.hpp"

namespace fillgs::cli {

/// The selection's strategy and ablations, shared by select and finetune: --strategy,
/// --time-stride, --no-start-selection, --no-error-term, --no-sensitivity-term,
/// --no-candidate-scoring, --no-global, --count-only | --speed-only.
void add_selection_flags(CLI::App& app, SelectOptions& o);
/// finetune's refiner: --refiner (the table's rows), the truth's path, and each row's knobs.
void add_refiner_flags(CLI::App& app, std::string& refiner, std::string& truth, RefinerInputs& inputs);
/// What the flags cannot say alone: the two terms switched off together.
void check_selection(const Invocation& in, const SelectOptions& o);

/// --divisions, --occupancy-alpha: the exploration grid.
void add_grid_flags(CLI::App& app, ExplorationOptions& o);

/// --motion-rates repair|gentle, --position-lr LR, --key-lr-scale k: how fast fine-tuning
/// moves Gaussians (finetune.hpp, MotionRates); the two numbers override the preset.
struct MotionRateFlags {
  RatePreset preset = RatePreset::Repair;
  double position_lr = MotionRates().position_lr, key_lr_scale = MotionRates().key_lr_scale;
};
void add_motion_rate_flags(CLI::App& app, MotionRateFlags& f);
MotionRates motion_rates(const Invocation& in, const MotionRateFlags& f);

/// x with `digits` decimals ("-" when not finite), as the commands print figures.
std::string fixed(double x, int digits = 2);

}  // namespace fillgs::cli

