// fillgs finetune: the refinement loop (refined virtual views, or real camera-times chosen
// from a pool).
#include <optional>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/method/refiners.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"

namespace fs = std::filesystem;

namespace fillgs::cli {

namespace {

/// The folder must not exist yet or be empty: outputs never mix with an earlier run's.
void require_fresh(const std::string& dir, const std::string& command) {
  if (fs::exists(dir) && !fs::is_empty(dir)) throw_error("fillgs ", command, ": ", dir, " exists and is not empty");
}

// ------------------------------------------------------------------ finetune

struct FinetuneFlags {
  std::string model, images, cameras, out, refiner_command, truth, confidence;
  std::string refiner = "identity";
  bool paper_schedule = false;
  uint64_t seed = 1;
  double refiner_timeout = 600.0, refined_share = TrainOptions().refined_share;
  ReferenceOptions reference = bench_reference_options(0.5, 1);  ///< reference/warp: the calibrated refiner, --reference-angle sets θ0
  FinetuneOptions finetune;
  OracleOptions oracle;
  std::vector<std::string> pool_cameras;
  RigOptions rig;
  MotionRateFlags rates;
  DatasetOptions data;
  SceneReadOptions read;
};

int finetune_model(const FinetuneFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  TerminalProgress loading(in.err, in.progress());
  const Dataset data = Dataset::load(f.images, f.cameras, f.data, loading);
  // A network's model trains as fillgs's keyed model: keys as dense as its motion needs.
  KeyChoice keys;
  const GaussianCloud model = keyed_for_training(read_scene_shown(f.model, f.read, in), &keys);
  if (keys.keys > 0)
    in.out << "keys: " << keys.keys << " for its " << keys.frames << " frames (one every " << fixed(keys.interval, 2)
           << "), positions, rotations, scales, opacities and colours (" << (keys.keyed_bands ? "every SH band" : "the SH DC") << ") within "
           << fixed(keys.worst_share, 2) << " of their tolerances of its network at every frame (" << keys.sample << " moving Gaussians measured"
           << (keys.limiting.empty() ? std::string() : "; " + keys.limiting + " decided the interval") << ")\n";
  if (model.size() == 0) throw_error(f.model, ": has no Gaussians; fine-tuning needs a trained model");
  check_trainable(model, f.model);
  // --paper-schedule picks the paper's counts; the flags given override them.
  FinetuneOptions o = f.paper_schedule ? FinetuneOptions::paper() : FinetuneOptions();
  if (in.given("--iterations")) o.iterations = f.finetune.iterations;
  if (in.given("--select-every")) o.select_every = f.finetune.select_every;
  if (in.given("--trajectories")) o.trajectories = f.finetune.trajectories;
  o.train = fine_tune_schedule(o.iterations, motion_rates(in, f.rates));
  o.train.seed = f.seed;
  // The model's spherical-harmonics degree is kept (a degree-0 model stays one).
  o.train.max_sh_degree = model.sh_degree;
  // A model trained with colour correction keeps it: its corrections (beside it, as train
  // writes them) continue, so the model stays in the colours of the rig's mean camera.
  const std::string corrections = join_path(fs::path(f.model).parent_path().string(), "colour_correction.json");
  if (fs::is_regular_file(corrections)) {
    o.train.colour_correction = true;
    o.train.initial_colour = read_colour_correction(corrections);
    in.out << "colour correction: continuing the " << o.train.initial_colour.size() << " cameras' corrections of " << corrections << "\n";
  }
  if (in.given("--refined-share")) o.train.refined_share = f.refined_share;
  o.select = f.finetune.select;
  o.select.seed = f.seed;
  check_selection(in, o.select);
  o.weighting = f.finetune.weighting;
  o.mask = f.finetune.mask;
  o.allow_failed_refinement = f.finetune.allow_failed_refinement;
  if (in.given("--confidence")) {
    o.mask.method = MaskMethod::External;
    o.mask.external_dir = f.confidence;
    if (!fs::is_directory(o.mask.external_dir)) in.fail("--confidence ", o.mask.external_dir, " is not a folder");
  }
  o.work_dir = join_path(f.out, "work");

  // The refiner (method/refiners.hpp): what it is made from, then the row's own make.
  const RefinerKind& kind = refiner_kind(f.refiner);
  RefinerInputs ri;
  std::unique_ptr<GaussianCloud> truth;
  if (in.given("--truth")) {
    truth = std::make_unique<GaussianCloud>(read_scene_shown(f.truth, f.read, in));
    ri.truth = truth.get();
  }
  if (kind.needs_truth && !truth)
    in.fail("--refiner ", kind.name, " needs --truth (the ground-truth scene", kind.name == "reference" ? "; on real data use --refiner warp)" : ")");
  if (kind.needs_command && !in.given("--refiner-command")) in.fail("missing --refiner-command");
  for (const TrainView& v : data.views()) ri.observers.push_back(v.camera);
  ri.frames = data.frames();
  ri.command = f.refiner_command;
  ri.timeout_seconds = f.refiner_timeout;
  ri.oracle = f.oracle;
  ri.oracle.artifacts.seed = o.train.seed;
  // The benchmark's calibrated reference refiner (bench/results/README.md, "Calibrating the
  // refiner"), --reference-angle setting its angle.
  ri.reference = f.reference;
  ri.reference.artifacts.strength = f.oracle.artifacts.strength;
  ri.reference.artifacts.seed = o.train.seed;
  ri.rig = f.rig;
  // The pool: rig cameras neither trained on nor held out, every frame the training views have.
  RigPool pool;
  std::unique_ptr<Dataset> pool_data;
  if (kind.needs_pool || f.finetune.pool_budget > 0) {
    const std::string why = f.finetune.pool_budget > 0 ? "--pool-budget" : "--refiner " + kind.name;
    if (f.finetune.pool_budget > 0 && in.given("--refiner"))
      in.fail("--pool-budget adds the pool's own photographs: it takes no --refiner");
    if (f.finetune.pool_budget > 0 && in.given("--trajectories"))
      in.fail("--pool-budget chooses photographs, not trajectories: it takes no --trajectories");
    DatasetOptions po = f.data;
    po.cameras = f.pool_cameras;
    po.monocular_cycle.clear();
    if (po.cameras.empty()) in.fail(why, " needs --pool-cameras a,b,.. (rig cameras neither trained on nor held out)");
    for (const std::string& c : po.cameras)
      for (const std::string& t : data.rigs())
        if (c == t) in.fail("--pool-cameras names ", c, ", a training camera");
    pool_data = std::make_unique<Dataset>(Dataset::load(f.images, f.cameras, po));
    if (pool_data->frames() != data.frames())
      in.fail("the pool cameras have ", pool_data->frames(), " frames, the training cameras ", data.frames());
    for (const TrainView& v : pool_data->views()) pool.cameras.push_back(v.camera);
    pool.frame_count = pool_data->frames();
    pool.image = [d = pool_data.get()](size_t i) { return d->image(i); };
    ri.pool = &pool;
  }
  const std::unique_ptr<Refiner> refiner = make_refiner(kind.name, ri);
  if (f.finetune.pool_budget > 0) {
    o.pool = &pool;
    o.pool_budget = f.finetune.pool_budget;
  }
  if (UnfinishedMarker::present(f.out))
    throw_error(f.out, ": holds an interrupted finetune (", UnfinishedMarker::path_in(f.out),
                "); fine-tuning does not resume, because its refined views and weights are not kept in checkpoints: remove the folder or use another --out");
  require_fresh(f.out, "finetune");
  UnfinishedMarker unfinished(f.out, "finetune");
  if (o.pool)
    in.out << "fine-tuning " << model.size() << " Gaussians on " << data.views().size() << " views for " << o.iterations << " iterations; "
        << o.pool_budget << " of the pool's " << pool.cameras.size() << " photographs (" << to_string(o.select.strategy) << "), chosen over "
        << (o.iterations + o.select_every - 1) / o.select_every << " rounds, weights " << to_string(o.weighting) << "\n";
  else
    in.out << "fine-tuning " << model.size() << " Gaussians on " << data.views().size() << " views for " << o.iterations << " iterations; "
        << o.trajectories << " trajectories (" << to_string(o.select.strategy) << ") every " << o.select_every << ", refiner "
        << refiner->name() << ", weights " << to_string(o.weighting) << "\n";
  TerminalProgress progress(in.err, in.progress());
  FinetuneResult r = finetune(data, model, *refiner, o, progress);
  r.keys = keys;
  const FinetuneReport report = write_finetune_report(f.out, r, data, o, o.pool ? "pool" : refiner->name(), seconds_since(t0));
  if (o.pool) write_pool_report(f.out, r, *pool_data, to_string(o.select.strategy));
  unfinished.finish();
  for (const FinetuneRound& rd : r.rounds)
    for (const auto& [patch, why] : rd.refine_failures) in.err << "warning: refinement failed for " << why << "\n";
  const size_t dropped = report.dropped;
  const SplitMetrics& tr = report.train;
  in.out << "fine-tuned in " << fixed(seconds_since(t0), 1) << " s: " << r.virtual_views.size() << (o.pool ? " pool photographs" : " refined views")
      << " added"
      << (dropped ? " (" + std::to_string(dropped) + " dropped by the refiner)" : "") << ", train PSNR "
      << fixed(tr.psnr) << " dB -> " << f.out << "\n";
  return 0;
}

}  // namespace

Action declare_finetune(CLI::App& app) {
  auto f = std::make_shared<FinetuneFlags>();
  FinetuneOptions& o = f->finetune;
  add_text(app, "--model", f->model, "the trained model", "PATH")->required();
  add_text(app, "--images", f->images, "the training images", "DIR")->required();
  add_text(app, "--cameras", f->cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for model.ply, virtual_views.json, work/ and summary.json (new or empty)", "DIR")->required();
  add_number(app, "--iterations", o.iterations, "fine-tuning iterations", at_least(1));
  add_number(app, "--select-every", o.select_every, "M: a selection round every M iterations", at_least(1));
  add_number(app, "--trajectories", o.trajectories, "K: trajectories per round (at most 100000)", within(0, 100000));
  add_flag(app, "--paper-schedule", f->paper_schedule, "the paper's counts: 30,000 iterations, 20 trajectories every 6,000");
  add_number(app, "--seed", f->seed, "random seed (training and selection)");
  add_number(app, "--refined-share", f->refined_share, "share of iterations that draw a refined view", within(0, 1));
  add_choice(app, "--weighting", o.weighting, "how refined pixels are trusted (fillgs: the paper's; the others: baselines and ablations)");
  add_number(app, "--mask-sigma", o.mask.sigma, "colour difference at which consistency is 1/e", positive());
  add_choice(app, "--mask", o.mask.method, "how consistency with the real views is measured");
  add_choice(app, "--covis", o.mask.covisibility, "how the co-visibility weight reads the observation tables");
  add_text(app, "--confidence", f->confidence, "consistency maps computed elsewhere (a folder)", "DIR");
  add_choice(app, "--covis-scale", o.mask.scale, "the co-visibility weight's D-hat scale: per frame over the visible moving Gaussians, or global");
  add_flag(app, "--normalise-weights", o.mask.normalise, "divide each refined view's weights by their mean");
  {
    std::vector<std::string> names;
    std::string help = "the refiner:";
    for (const RefinerKind* k : refiner_kinds()) {
      names.push_back(k->name);
      help += " " + k->name + ", " + k->description + (k->needs_truth ? " (needs --truth)" : k->needs_pool ? " (needs --pool-cameras)" : "") + ";";
    }
    help.back() = '.';
    add_row_choice(app, "--refiner", f->refiner, names, [](const std::string& v) { return refiner_kind(v).name; }, help);
  }
  add_number(app, "--reference-angle", f->reference.angle_scale_degrees, "reference/warp: the parallax angle (degrees) at which confidence falls to 1/e",
             positive());
  add_text(app, "--refiner-command", f->refiner_command, "external: the command, with {in} and {out}", "CMD");
  add_number(app, "--refiner-timeout", f->refiner_timeout, "external: seconds per patch", positive());
  add_flag(app, "--allow-failed-refinement", o.allow_failed_refinement,
           "go on when the refiner fails on every patch of a round (default: that ends the run with an error, nothing written)");
  add_text(app, "--truth", f->truth, "oracle/reference: the ground-truth scene (warp: only for its records)", "PATH");
  add_number(app, "--artifact-strength", f->oracle.artifacts.strength, "oracle/reference/warp: strength of the simulated refiner artifacts", at_least(0));
  add_number(app, "--support-window", f->oracle.window, "oracle: frames either side that count as observed", at_least(0));
  add_list(app, "--pool-cameras", f->pool_cameras, "rig and --pool-budget: cameras neither trained on nor held out");
  add_number(app, "--pool-budget", o.pool_budget,
             "real camera-times: choose this many (camera, frame) photographs of the --pool-cameras by the strategy's own score, "
             "spread over the rounds, instead of refined virtual views (0: off)",
             within(0, 1000000));
  add_number(app, "--rig-max-distance", f->rig.max_distance, "rig: how far a pool camera may stand from the virtual view", at_least(0));
  add_number(app, "--rig-max-angle", f->rig.max_angle_degrees, "rig: how far it may look away (degrees)", within(0, 180));
  add_selection_flags(app, o.select);
  f->rates.preset = RatePreset::Converged;  // a user's model is kept; the benchmark asks for repair
  add_motion_rate_flags(app, f->rates);
  add_dataset_flags(app, f->data, "--train-cameras");
  add_scene_flags(app, f->read);
  return bind(f, finetune_model);
}

}  // namespace fillgs::cli
