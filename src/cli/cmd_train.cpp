// fillgs train: training a 4D model from multi-view video.
#include "fillgs/cli.hpp"
#include "fillgs/io/camera_io.hpp"
#include <nlohmann/json.hpp>
#include <algorithm>
#include <cmath>
#include <limits>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include "fillgs/base/error.hpp"
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

// ------------------------------------------------------------------ train

struct TrainFlags {
  std::string images, cameras, out, points, resume, init, test_images, test_cameras, camera_times;
  int iterations = 3000;
  int draws_per_view = 0;  ///< > 0: iterations = this × the training views
  int checkpoint_every = 0;
  uint64_t seed = 1;
  bool static_only = false, colour_correction = false;
  TrainOptions train = TrainOptions::scaled(3000);
  ViewInitOptions view_init;
  DatasetOptions data;
};

/// --camera-times FILE: {"chosen": [{"camera": .., "frame": ..}, ..]} (finetune's
/// pool_chosen.json) or the list alone.
std::vector<std::pair<std::string, int>> read_camera_times(const std::string& path) {
  const nlohmann::json j = read_json_file(path);
  const nlohmann::json& list = j.is_object() && j.contains("chosen") ? j.at("chosen") : j;
  if (!list.is_array()) throw_error(path, ": camera-times must be a list of {\"camera\", \"frame\"} (or an object whose \"chosen\" is one)");
  std::vector<std::pair<std::string, int>> out;
  for (size_t i = 0; i < list.size(); ++i) {
    const nlohmann::json& e = list[i];
    if (!e.is_object() || !e.contains("camera") || !e.contains("frame") || !e.at("camera").is_string() || !e.at("frame").is_number_integer())
      throw_error(path, ": camera-time ", i, " needs \"camera\" (a name) and \"frame\" (a whole number)");
    // nlohmann's get<int> wraps a larger number (4294967298 -> 2): read it whole, then bound it.
    const nlohmann::json& frame = e.at("frame");
    const bool fits = frame.is_number_unsigned() ? frame.get<uint64_t>() <= uint64_t(std::numeric_limits<int>::max())
                                                  : frame.get<int64_t>() >= 0 && frame.get<int64_t>() <= std::numeric_limits<int>::max();
    if (!fits) throw_error(path, ": camera-time ", i, " has frame ", frame.dump(), ", not a frame number (0 to ", std::numeric_limits<int>::max(), ")");
    out.emplace_back(e.at("camera").get<std::string>(), int(frame.get<int64_t>()));
  }
  if (out.empty()) throw_error(path, ": no camera-times");
  return out;
}

int train(const TrainFlags& f, const Invocation& in) {
  TerminalProgress loading(in.err, in.progress());
  DatasetOptions dopt = f.data;
  if (in.given("--camera-times")) {
    if (dopt.cameras.empty()) in.fail("--camera-times adds single photographs to --train-cameras, and none were named");
    dopt.camera_times = read_camera_times(f.camera_times);
  }
  const Dataset data = Dataset::load(f.images, f.cameras, dopt, loading);
  if (in.given("--draws-per-view") && in.given("--iterations")) in.fail("--draws-per-view sets the iterations; give it or --iterations, not both");
  // A fixed number of draws per photograph: the run's length follows the number of views.
  const size_t scaled = size_t(f.draws_per_view) * data.views().size();
  if (in.given("--draws-per-view") && scaled > size_t(std::numeric_limits<int>::max()))
    in.fail("--draws-per-view ", f.draws_per_view, " x ", data.views().size(), " views is more iterations than a run can count");
  const int iterations = in.given("--draws-per-view") ? int(scaled) : f.iterations;
  // The schedule scales with the iteration count; the flags given override it.
  TrainOptions o = TrainOptions::scaled(iterations);
  o.seed = f.seed;
  for (const auto& [flag, apply] : std::vector<std::pair<const char*, std::function<void()>>>{
           {"--key-interval", [&] { o.key_interval_frames = f.train.key_interval_frames; }},
           {"--max-gaussians", [&] { o.max_gaussians = f.train.max_gaussians; }},
           {"--sh-degree", [&] { o.max_sh_degree = f.train.max_sh_degree; }},
           {"--motion", [&] { o.motion = f.train.motion; }},
           {"--time-ramp", [&] { o.time_ramp = f.train.time_ramp; }},
           {"--key-lr-scale", [&] { o.key_lr_scale = f.train.key_lr_scale; }},
           {"--motion-sparsity", [&] { o.motion_sparsity = f.train.motion_sparsity; }},
           {"--background", [&] { o.background = f.train.background; }}})
    if (in.given(flag)) apply();
  o.allow_dynamic = !f.static_only;
  o.keyed_opacity = f.train.keyed_opacity;
  o.flow_keys = f.train.flow_keys;
  o.change_from_masks = f.train.change_from_masks;
  if (o.change_from_masks && !data.has_masks()) in.fail("--motion-from-masks needs foreground masks (seg/ beside the meta file)");
  o.checkpoint_interval = in.given("--checkpoint-every") ? f.checkpoint_every : std::max(1, iterations / 5);
  o.colour_correction = f.colour_correction;
  // Test split (optional): loaded before anything is written, so bad input writes nothing.
  std::unique_ptr<Dataset> test;
  if (in.given("--test-cameras")) {
    DatasetOptions to = f.data;
    to.cameras.clear();
    test = std::make_unique<Dataset>(Dataset::load(in.given("--test-images") ? f.test_images : f.images, f.test_cameras, to));
  }

  TrainJob job;
  job.data = &data;
  job.out = f.out;
  job.options = o;
  job.iterations = iterations;
  job.iterations_name = in.given("--draws-per-view") ? "--draws-per-view " + std::to_string(f.draws_per_view) + " gives --iterations" : "--iterations";
  if (in.given("--resume")) job.resume = f.resume;
  // Initial points: --points, else points.ply beside the cameras, else from the views
  // (init.hpp: random points the first frame's cameras see, plus the foreground's visual
  // hull when the dataset has masks); --init picks explicitly.
  job.points = f.points;
  const std::string beside = join_path(std::filesystem::path(f.cameras).parent_path().string(), "points.ply");
  if (job.points.empty() && std::filesystem::exists(beside)) job.points = beside;
  job.init = in.given("--init") ? parse_name<InitSource>(f.init) : job.points.empty() ? InitSource::RandomAndCarve : InitSource::Points;
  if (job.init == InitSource::Points && job.points.empty()) in.fail("--init points needs --points (no points.ply beside ", f.cameras, ")");
  job.view_init = f.view_init;
  TerminalProgress progress(in.err, in.progress());
  TrainingReport report;
  const TrainJobResult r = run_train_job(job, in.out, progress, [&](const Trainer& trainer, const GaussianCloud& model, double seconds) {
    report = write_training_report(f.out, trainer, model, data, o, test.get(), seconds);
  });
  const GaussianCloud& model = r.model;
  const double train_seconds = r.seconds_train;
  if (o.colour_correction) {
    auto put = [&](const ColourCorrection& c) {
      char line[160];
      std::snprintf(line, sizeof line, " %s %.3f,%.3f,%.3f/%+.3f,%+.3f,%+.3f;", c.rig.c_str(), c.gain[0], c.gain[1], c.gain[2], c.offset[0],
                    c.offset[1], c.offset[2]);
      in.out << line;
    };
    in.out << "colours of the rig's mean camera, in those of " << data.rigs()[0] << " (gain r,g,b / offset r,g,b):";
    put(r.mean);
    in.out << "\ncolour correction per camera, relative to the mean camera:";
    for (const ColourCorrection& c : r.corrections) put(c);
    in.out << "\n";
  }
  in.out << "trained " << model.size() << " Gaussians (" << model.dynamic_count() << " moving) in " << train_seconds << " s; train PSNR "
         << report.train.psnr << " dB";
  if (test) in.out << ", test PSNR " << report.test.psnr << " dB over " << report.test.views << " views";
  in.out << ", peak memory " << (report.peak_memory_bytes >> 20) << " MB -> " << f.out << "\n";
  return 0;
}

}  // namespace

Action declare_train(CLI::App& app) {
  auto f = std::make_shared<TrainFlags>();
  TrainOptions& o = f->train;
  add_text(app, "--images", f->images, "the images folder", "DIR")->required();
  add_text(app, "--cameras", f->cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for model.ply, checkpoints and summary.json", "DIR")->required();
  add_text(app, "--points", f->points, "initial points (PLY; default: points.ply beside the cameras)", "PATH");
  add_number(app, "--iterations", f->iterations, "training iterations (the schedule scales with them)", at_least(1));
  add_number(app, "--draws-per-view", f->draws_per_view,
             "iterations = this x the training views (each photograph drawn this often with --time-ramp 0); instead of --iterations", at_least(1))
      ->default_str("");
  add_text(app, "--resume", f->resume, "continue from this checkpoint", "CKPT");
  add_number(app, "--checkpoint-every", f->checkpoint_every, "iterations between checkpoints (default: a fifth of the run)", at_least(1))->default_str("");
  add_number(app, "--seed", f->seed, "random seed");
  add_number(app, "--key-interval", o.key_interval_frames, "frames between motion keys", at_least(1));
  add_number(app, "--max-gaussians", o.max_gaussians, "densification stops at this count", at_least(1));
  add_number(app, "--sh-degree", o.max_sh_degree, "spherical-harmonics degree", within(0, 3));
  add_text(app, "--test-cameras", f->test_cameras, "held-out cameras, evaluated at the end", "PATH");
  add_text(app, "--test-images", f->test_images, "their images (default: --images)", "DIR");
  add_flag(app, "--static-only", f->static_only, "no Gaussian moves");
  add_colour(app, "--background", o.background, "the background colour");
  add_choice(app, "--motion", o.motion, "all: every Gaussian may move; promote: static until promoted");
  add_number(app, "--time-ramp", o.time_ramp, "share of the run over which time opens from frame 0 to the whole clip", from_below(0, 1));
  add_number(app, "--key-lr-scale", o.key_lr_scale, "learning-rate scale of motion keys", positive());
  add_number(app, "--motion-sparsity", o.motion_sparsity, "weight of the penalty on motion", at_least(0));
  add_switch_off(app, "--no-keyed-opacity", o.keyed_opacity, "opacity does not change over time");
  add_switch_off(app, "--no-flow-keys", o.flow_keys, "motion keys not placed by optical flow");
  add_flag(app, "--motion-from-masks", o.change_from_masks, "what moves found from the foreground masks, not from image change");
  add_text(app, "--init", f->init, "initial points: points, random or random+carve (default: points when there are any)", "NAME");
  add_number(app, "--init-points", f->view_init.random_points, "random: how many points", at_least(1));
  add_flag(app, "--colour-correction", f->colour_correction, "learn a gain and offset per camera");
  add_text(app, "--camera-times", f->camera_times,
           "single photographs trained on beside --train-cameras: a JSON list of {camera, frame} (finetune --pool-budget's pool_chosen.json)", "PATH");
  add_dataset_flags(app, f->data, "--train-cameras");
  return bind(f, train);
}

}  // namespace fillgs::cli
