#include "fillgs/method/strategies.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/camera_io.hpp"
#include "options.hpp"
#include "progress_bar.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs::cli {

std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::unique_ptr<CLI::App> make_parser(const std::string& name, const std::string& summary) {
  auto app = std::make_unique<CLI::App>(summary, name);
  app->allow_extras();  // unknown flags get fillgs's own line (parse_flags)
  app->option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  app->get_formatter()->column_width(36);
  app->get_formatter()->label("REQUIRED", "(required)");
  return app;
}

bool parse_flags(CLI::App& app, const std::vector<std::string>& args, std::ostream& out) {
  // Help wins wherever it stands: a flag that takes a value must not swallow it
  // (`--out --help` would run the whole job into a folder named "--help"). A value that
  // really is "--help" can still be given as `--out=--help`.
  for (const std::string& a : args)
    if (a == "--help" || a == "-h") {
      out << app.help();
      return false;
    }
  std::string parse_error;
  try {
    std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them last first
    app.parse(reversed);
  } catch (const CLI::CallForHelp&) {
    out << app.help();
    return false;
  } catch (const CLI::ParseError& e) {
    parse_error = e.what();  // reported after the unknown flags, which say more
    const std::string required = " is required";  // "--scene is required" → "missing --scene"
    if (parse_error.size() > required.size() && parse_error.compare(parse_error.size() - required.size(), required.size(), required) == 0)
      parse_error = "missing " + parse_error.substr(0, parse_error.size() - required.size());
  }
  for (const std::string& extra : app.remaining()) {
    if (extra.rfind("--", 0) == 0)
      throw_error(app.get_name(), ": unknown option ", extra.substr(0, extra.find('=')), " (see '", app.get_name(), " --help')");
    throw_error(app.get_name(), ": unexpected argument '", extra, "' (see '", app.get_name(), " --help')");
  }
  if (!parse_error.empty()) throw_error(app.get_name(), ": ", parse_error);
  return true;
}

CLI::Option* add_flag(CLI::App& app, const std::string& flag, bool& dest, const std::string& help) {
  return app.add_flag(flag, dest, help);
}

CLI::Option* add_switch_off(CLI::App& app, const std::string& flag, bool& dest, const std::string& help) {
  return app.add_flag_callback(flag, [&dest] { dest = false; }, help);
}

CLI::Option* add_text(CLI::App& app, const std::string& flag, std::string& dest, const std::string& help, const std::string& type) {
  CLI::Option* o = app.add_option(flag, dest, help)->type_name(type);
  if (!dest.empty()) o->default_str(dest);
  return o;
}

CLI::Option* add_list(CLI::App& app, const std::string& flag, std::vector<std::string>& dest, const std::string& help) {
  CLI::Option* o = app.add_option(
      flag,
      [&dest](const CLI::results_t& r) {
        // Given again, a list grows: --merge a --merge b,c is a,b,c (never only the last).
        dest.clear();
        for (const std::string& part : r)
          for (std::string& item : split_commas(part)) dest.push_back(std::move(item));
        return true;
      },
      help);
  o->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  o->type_name("A,B,..");
  std::string def;
  for (const std::string& s : dest) def += (def.empty() ? "" : ",") + s;
  if (!def.empty()) o->default_str(def);
  return o;
}

CLI::Option* add_colour(CLI::App& app, const std::string& flag, Vec3f& dest, const std::string& help) {
  const std::string name = app.get_name();
  CLI::Option* o = app.add_option(
      flag,
      [&dest, flag, name](const CLI::results_t& r) {
        const std::string v = r.back();
        std::vector<double> c;
        std::stringstream ss(v);
        std::string part;
        double x = 0;
        while (std::getline(ss, part, ',') && parse_number(part, &x)) c.push_back(x);
        if (c.size() != 3 || !ss.eof() || (!v.empty() && v.back() == ','))
          throw_error(name, ": ", flag, " expects 3 comma-separated numbers, got '", v, "'");
        // Colours are what images hold: [0, 1] per channel (a background of 1e30 would turn
        // every gradient into inf and NaN).
        for (double x : c)
          if (!(x >= 0.0 && x <= 1.0)) throw_error(name, ": ", flag, " takes colours in [0, 1] per channel, got '", v, "'");
        dest = Vec3f(float(c[0]), float(c[1]), float(c[2]));
        return true;
      },
      help);
  o->type_name("R,G,B")->default_str(number_text(dest[0]) + "," + number_text(dest[1]) + "," + number_text(dest[2]));
  return o;
}

CLI::Option* add_bytes(CLI::App& app, const std::string& flag, int64_t& dest, double unit, const std::string& unit_name, const std::string& help) {
  const std::string name = app.get_name();
  CLI::Option* o = app.add_option(
      flag,
      [&dest, flag, name, unit, unit_name](const CLI::results_t& r) {
        double x = 0;
        if (!parse_number(r.back(), &x) || !(x >= 0 && x < 1e6 * (double(int64_t(1) << 30) / unit)))
          throw_error(name, ": ", flag, " must be a number of ", unit_name, ", at least 0 (got ", r.back(), ")");
        dest = int64_t(x * unit);
        return true;
      },
      help);
  o->type_name(unit_name);
  return o;
}

CLI::Option* add_row_choice(CLI::App& app, const std::string& flag, std::string& dest, const std::vector<std::string>& names,
                            std::function<std::string(const std::string&)> canonical, const std::string& help) {
  const std::string name = app.get_name();
  CLI::Option* o = app.add_option(
      flag,
      [&dest, flag, name, canonical](const CLI::results_t& r) {
        try {
          dest = canonical(r.back());
        } catch (const Error& e) {
          throw_error(name, ": ", flag, ": ", e.what());
        }
        return true;
      },
      help);
  std::string type;
  for (const std::string& n : names) type += (type.empty() ? "" : "|") + n;
  o->type_name(type);
  o->default_str(dest);
  return o;
}

void add_row_parameters(CLI::App& app, RowParameterValues& values, const std::vector<const RowParameter*>& parameters, const std::string& group) {
  const std::string name = app.get_name();
  for (const RowParameter* p : parameters) {
    const std::string flag = Spelling{}(p->key);
    std::string type = p->kind == RowParameter::Kind::Integer ? "N" : p->kind == RowParameter::Kind::Text ? "TEXT" : "X";
    if (p->kind == RowParameter::Kind::Choice) {
      type.clear();
      for (const std::string& c : p->choices) type += (type.empty() ? "" : "|") + c;
    }
    // The flag, then each older name as its own flag, so that a refused value is named as typed.
    std::vector<std::string> names = {flag};
    names.insert(names.end(), p->flag_aliases.begin(), p->flag_aliases.end());
    for (const std::string& given : names) {
      CLI::Option* o = app.add_option(
          given,
          [&values, p, given, name](const CLI::results_t& r) {
            try {
              values.set(*p, r.back(), given);  // the one check, naming the flag as typed
            } catch (const Error& e) {
              throw_error(name, ": ", e.what());
            }
            return true;
          },
          given == flag ? p->help : "the same as " + flag);
      o->type_name(type)->default_str(p->default_text);
      if (!group.empty()) o->group(group);
    }
  }
}

void add_scene_flags(CLI::App& app, SceneReadOptions& o) {
  std::vector<std::string> formats = {"auto"};
  for (const ModelFormat* f : model_formats()) formats.push_back(f->name);
  add_row_choice(app, "--scene-format", o.format, formats,
                 [](const std::string& v) { return v == "auto" ? v : model_format(v).name; }, "the scene's format (auto: from the file)")
      ->group("Scene options");
  add_row_parameters(app, o.parameters, model_format_table().parameters(), "Scene options");
  add_number(app, "--model-frames", o.model_frames, "trained models: frames the model covers (0: E-D3DGS's cfg_args; 4DGaussians, 4DGS, Deformable 3D Gaussians need it)", at_least(0))
      ->group("Scene options");
  add_text(app, "--model-time-range", o.model_time_range, "E-D3DGS, 4DGaussians, 4DGS: the model times the frames span, T0:T1 (frame f at T0 + f (T1-T0)/F; default 0:1; 4DGS: its time_duration)", "T0:T1")
      ->group("Scene options");
  add_number(app, "--model-camera", o.model_camera, "E-D3DGS: the training camera whose time offset to use (-1: their mean, as at test views)", at_least(-1))
      ->group("Scene options");
  add_number(app, "--model-iteration", o.model_iteration, "E-D3DGS: the iteration its coarse-to-fine schedule is at (-1: the saved one)", at_least(-1))
      ->group("Scene options");
  add_number(app, "--static-threshold", o.partition.static_speed_threshold, "speed below which a Gaussian counts as static", at_least(0))
      ->group("Scene options");
  add_choice(app, "--model-evaluation", o.model_evaluation,
             "trained networks and 4DGS: streamed (evaluated exactly at each time a command asks for) or keys (every frame sampled into memory first, "
             "interpolated between frames)")
      ->group("Scene options");
  add_choice(app, "--network-kernel", o.network_kernel, "trained networks: simd (the dense kernel) or eigen (the reference products)")->group("Scene options");
  add_number(app, "--still-tolerance", o.still.position,
             "trained models, streamed: a Gaussian that stays this close (world units) to where it is at frame 0, and within 1 degree, 1 % of scale, "
             "1/255 of opacity and colour, is still: evaluated once, static",
             at_least(0))
      ->group("Scene options");
  add_number(app, "--still-sweep", o.still.sweep_frames, "trained models, streamed: frames the still rule samples, evenly, the first and last among them",
             at_least(2))
      ->group("Scene options");
  add_number(app, "--still-recheck", o.still.recheck,
             "trained models, streamed: a Gaussian the sweep finds still but past this share of a tolerance is checked at every frame (1: none)",
             at_least(0))
      ->group("Scene options");
}

void add_camera_flags(CLI::App& app, CameraReadOptions& o) {
  add_choice(app, "--camera-format", o.format, "the cameras' format (auto: from the path)")->group("Camera options");
  add_number(app, "--width", o.width, "image width for formats that store none (0: from the image)", at_least(0))->group("Camera options");
  add_number(app, "--height", o.height, "image height for formats that store none (0: from the image)", at_least(0))->group("Camera options");
  add_number(app, "--llff-downscale", o.llff_downscale, "LLFF: divide the stored H, W, f by this", positive())->group("Camera options");
}

void add_dataset_flags(CLI::App& app, DatasetOptions& o, const std::string& cameras_flag) {
  const std::string name = app.get_name();
  if (!cameras_flag.empty()) add_list(app, cameras_flag, o.cameras, "the rig cameras to use (names as in the camera file; default: all)")->group("Image options");
  app.add_option(
         "--frames",
         [&o, name](const CLI::results_t& r) {
           try {
             o.frames = FrameRange::parse(r.back());
           } catch (const Error& e) {
             throw_error(name, ": --frames: ", e.what());
           }
           return true;
         },
         "frames first:last:step (Python's slice; the frames kept become the video)")
      ->type_name("A:B:S")
      ->group("Image options");
  add_number(app, "--downscale", o.downscale, "images averaged over k x k blocks, cameras scaled to match", within(1, 64))->group("Image options");
  add_list(app, "--monocular-cycle", o.monocular_cycle, "frame f keeps only camera [f mod n]")->group("Image options");
  if (cameras_flag == "--train-cameras")
    add_text(app, "--held-out", o.held_out,
             "a camera file of held-out cameras: any training or pool camera standing where one of them stands is refused, before an image is read",
             "PATH")
        ->group("Image options");
  if (cameras_flag == "--train-cameras") {
    add_number(app, "--held-out-distance", o.held_out_distance, "--held-out: centres this close (world units) count as the same camera", at_least(0))
        ->group("Image options");
    add_number(app, "--held-out-angle", o.held_out_degrees, "--held-out: and viewing directions this close (degrees)", within(0, 180))
        ->group("Image options");
  }
  add_bytes(app, "--image-memory", o.image_memory, double(int64_t(1) << 30), "GB",
            "images beyond this wait in a temporary file in $TMPDIR, read on demand (default: a quarter of the machine's memory)")
      ->group("Image options");
}

void add_time_flags(CLI::App& app, TimeFlags& f, bool times) {
  add_number(app, "--frames", f.frames, "frame count F: times t = f/(F-1) (0: from the scene or the cameras)", at_least(0));
  if (!times) return;
  const std::string name = app.get_name();
  app.add_option(
         "--times",
         [&f, name](const CLI::results_t& r) {
           f.times.clear();
           std::istringstream in(r.back());
           std::string tok;
           while (std::getline(in, tok, ',')) {
             char* end = nullptr;
             const double t = std::strtod(tok.c_str(), &end);
             // A number each; which times are allowed is the library's one check (observe_times).
             if (end == tok.c_str() || *end != '\0') throw_error(name, ": --times expects comma-separated times in [0, 1], got '", tok, "'");
             f.times.push_back(t);
           }
           if (f.times.empty()) throw_error(name, ": --times is empty");
           return true;
         },
         "only these times of the frame grid (t1,t2,..; needs --frames F)")
      ->type_name("T1,T2,..");
}

std::vector<double> observe_times(const Invocation& in, const TimeFlags& tf, const GaussianCloud& cloud, const std::vector<Camera>& cams,
                                  double* frame_step, bool tables_in_memory) {
  const ObserveTimes r = observe_times(cloud, cams, tf.frames, in.given("--times") ? &tf.times : nullptr, tables_in_memory, Spelling{});
  *frame_step = r.frame_step;
  return r.times;
}

}  // namespace fillgs::cli

namespace fillgs::cli {

void add_refiner_flags(CLI::App& app, std::string& refiner, std::string& truth, RefinerInputs& ri) {
  ri.reference = bench_reference_options(0.5, 1);  // reference/warp: the calibrated refiner, --reference-angle sets θ0
  {
    std::vector<std::string> names;
    std::string help = "the refiner:";
    for (const RefinerKind* k : refiner_kinds()) {
      names.push_back(k->name);
      help += " " + k->name + ", " + k->description + (k->needs_truth ? " (needs --truth)" : k->needs_pool ? " (needs --pool-cameras)" : "") + ";";
    }
    help.back() = '.';
    add_row_choice(app, "--refiner", refiner, names, [](const std::string& v) { return refiner_kind(v).name; }, help);
  }
  add_number(app, "--reference-angle", ri.reference.angle_scale_degrees, "reference/warp: the parallax angle (degrees) at which confidence falls to 1/e",
             positive());
  add_row_parameters(app, ri.parameters, refiner_table().parameters(), "");
  add_text(app, "--truth", truth, "oracle/reference: the ground-truth scene (warp: only for its records)", "PATH");
  add_number(app, "--artifact-strength", ri.oracle.artifacts.strength, "oracle/reference/warp: strength of the simulated refiner artifacts", at_least(0));
  add_number(app, "--support-window", ri.oracle.window, "oracle: frames either side that count as observed", at_least(0));
}

void add_selection_flags(CLI::App& app, SelectOptions& o) {
  const std::string g = "Selection options";
  add_table_choice(app, "--strategy", o.strategy, strategy_table(), "how virtual viewpoints are chosen (fillgs: the paper's; the others: baselines)")->group(g);
  add_row_parameters(app, o.parameters, strategy_table().parameters(), g);
  add_number(app, "--time-stride", o.time_stride, "starting-view priority on every k-th frame only", at_least(1))->group(g);
  add_flag(app, "--no-start-selection", o.no_start_selection, "ablation: random starting viewpoints")->group(g);
  add_flag(app, "--no-error-term", o.no_error_term, "ablation: priority E = V")->group(g);
  add_flag(app, "--no-sensitivity-term", o.no_sensitivity_term, "ablation: priority E = L")->group(g);
  add_flag(app, "--no-candidate-scoring", o.no_candidate_scoring, "ablation: a random candidate")->group(g);
  add_flag(app, "--no-global", o.no_global, "ablation: local candidates only")->group(g);
  app.add_flag_callback("--count-only", [&o] { o.score = CandidateScore::CountOnly; }, "ablation: candidates scored by counts only")->group(g);
  app.add_flag_callback("--speed-only", [&o] { o.score = CandidateScore::SpeedOnly; }, "ablation: candidates scored by speed only")->group(g);
}

void check_selection(const Invocation& in, const SelectOptions& o) {
  if (in.given("--count-only") && in.given("--speed-only")) in.fail("--count-only and --speed-only exclude each other");
  try {
    check_select_options(o);
  } catch (const Error& e) {
    in.fail(e.what());
  }
}

void add_grid_flags(CLI::App& app, ExplorationOptions& o) {
  add_number(app, "--divisions", o.divisions, "exploration grid cells along each axis", divisions_bounds())->group("Grid options");
  add_number(app, "--occupancy-alpha", o.occupancy_alpha, "a Gaussian occupies where its opacity reaches this", occupancy_alpha_bounds())
      ->group("Grid options");
}

void add_motion_rate_flags(CLI::App& app, MotionRateFlags& f) {
  const std::string g = "Fine-tuning rates";
  add_choice(app, "--motion-rates", f.preset,
             "converged: a converged model kept (every rate 1/300 of 3DGS's, sparse Adam, no densification); repair: training's initial "
             "rate, keys x10 (the benchmark's); gentle: its final rate x10, keys x3")->group(g);
  add_number(app, "--position-lr", f.position_lr, "initial position learning rate (x the scene extent; overrides the preset)")->group(g);
  add_number(app, "--key-lr-scale", f.key_lr_scale, "motion keys' rate as a multiple of it (overrides the preset)")->group(g);
}

MotionRates motion_rates(const Invocation& in, const MotionRateFlags& f) {
  MotionRates r = motion_rates_of(f.preset);
  if (in.given("--position-lr")) r.position_lr = f.position_lr;
  if (in.given("--key-lr-scale")) r.key_lr_scale = f.key_lr_scale;
  if (!(r.position_lr > 0) || !(r.key_lr_scale > 0)) in.fail("--position-lr and --key-lr-scale must be positive");
  return r;
}

GaussianCloud read_scene_shown(const std::string& path, SceneReadOptions options, const Invocation& in) {
  TerminalProgress progress(in.err, in.progress());
  options.progress = &progress;
  return read_scene(path, options);
}

std::string fixed(double x, int digits) {
  if (!std::isfinite(x)) return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, x);
  return b;
}

}  // namespace fillgs::cli
