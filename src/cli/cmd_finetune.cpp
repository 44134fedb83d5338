// fillgs finetune, eval, bench and run: the refinement loop, its evaluation, the paper's
// comparison and the main job.
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
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"

namespace fs = std::filesystem;

namespace fillgs::cli {
/// What turns a rendered patch into a refined one (--refiner).
enum class RefinerChoice { Identity, Oracle, External, Rig, Reference, Warp };
}  // namespace fillgs::cli

namespace fillgs {
FILLGS_ENUM_NAMES(cli::RefinerChoice, "refiner", {cli::RefinerChoice::Identity, "identity"}, {cli::RefinerChoice::Oracle, "oracle"},
                  {cli::RefinerChoice::External, "external"}, {cli::RefinerChoice::Rig, "rig"}, {cli::RefinerChoice::Reference, "reference"},
                  {cli::RefinerChoice::Warp, "warp"});
}  // namespace fillgs

namespace fillgs::cli {

namespace {

std::string fixed(double x, int digits = 2) {
  if (!std::isfinite(x)) return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, x);
  return b;
}

/// The folder must not exist yet or be empty: outputs never mix with an earlier run's.
void require_fresh(const std::string& dir, const std::string& command) {
  if (fs::exists(dir) && !fs::is_empty(dir)) throw_error("fillgs ", command, ": ", dir, " exists and is not empty");
}

// ------------------------------------------------------------------ finetune

struct FinetuneFlags {
  std::string model, images, cameras, out, refiner_command, truth, confidence;
  RefinerChoice refiner = RefinerChoice::Identity;
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
           << "), positions within " << keys.worst_error << " world units of its network at every frame (" << keys.sample << " moving Gaussians measured)\n";
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

  const RefinerChoice kind = f.refiner;
  std::unique_ptr<Refiner> refiner;
  std::unique_ptr<GaussianCloud> truth;
  std::unique_ptr<Dataset> pool_data;
  if (kind == RefinerChoice::Identity) {
    refiner = make_identity_refiner();
  } else if (kind == RefinerChoice::Oracle) {
    if (!in.given("--truth")) in.fail("missing --truth");
    truth = std::make_unique<GaussianCloud>(read_scene_shown(f.truth, f.read, in));
    OracleOptions oo = f.oracle;
    oo.artifacts.seed = o.train.seed;
    for (const TrainView& v : data.views()) oo.observers.push_back(v.camera);
    oo.frames = data.frames();
    refiner = make_oracle_refiner(*truth, oo);
  } else if (kind == RefinerChoice::Reference || kind == RefinerChoice::Warp) {
    // The benchmark's calibrated refiner (bench/results/README.md, "Calibrating the refiner").
    ReferenceOptions ro = f.reference;
    ro.artifacts.strength = f.oracle.artifacts.strength;
    ro.artifacts.seed = o.train.seed;
    if (in.given("--truth")) truth = std::make_unique<GaussianCloud>(read_scene_shown(f.truth, f.read, in));
    if (kind == RefinerChoice::Reference) {
      if (!truth) in.fail("--refiner reference needs --truth (the ground-truth scene; on real data use --refiner warp)");
      refiner = make_reference_refiner(*truth, ro);
    } else {
      refiner = make_warp_refiner(ro, nullptr, truth.get());
    }
  } else if (kind == RefinerChoice::External) {
    if (!in.given("--refiner-command")) in.fail("missing --refiner-command");
    refiner = make_external_refiner(f.refiner_command, f.refiner_timeout);
  }
  // The pool: rig cameras neither trained on nor held out, every frame the training views have.
  RigPool pool;
  if (kind == RefinerChoice::Rig || f.finetune.pool_budget > 0) {
    const std::string why = kind == RefinerChoice::Rig ? "--refiner rig" : "--pool-budget";
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
    if (kind == RefinerChoice::Rig) refiner = make_rig_refiner(pool, f.rig);
  }
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
  f->oracle.support = OracleSupport::Observed;  // the benchmark's protocol: truth only where the cameras looked
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
  add_choice(app, "--refiner", f->refiner,
             "reference: conditioned on the start view (synthetic, needs --truth); warp: the start photograph warped through the render's depth "
             "(any data); oracle: the ground truth; external: a command; rig: real pool cameras");
  add_number(app, "--reference-angle", f->reference.angle_scale_degrees, "reference/warp: the parallax angle (degrees) at which confidence falls to 1/e",
             positive());
  add_text(app, "--refiner-command", f->refiner_command, "external: the command, with {in} and {out}", "CMD");
  add_number(app, "--refiner-timeout", f->refiner_timeout, "external: seconds per patch", positive());
  add_flag(app, "--allow-failed-refinement", o.allow_failed_refinement,
           "go on when the refiner fails on every patch of a round (default: that ends the run with an error, nothing written)");
  add_text(app, "--truth", f->truth, "oracle/reference: the ground-truth scene (warp: only for its records)", "PATH");
  add_number(app, "--artifact-strength", f->oracle.artifacts.strength, "oracle/reference/warp: strength of the simulated refiner artifacts", at_least(0));
  add_choice(app, "--support", f->oracle.support, "oracle: truth everywhere, or only where the training cameras observed");
  add_number(app, "--support-window", f->oracle.window, "oracle: frames either side that count as observed", at_least(0));
  add_list(app, "--pool-cameras", f->pool_cameras, "rig and --pool-budget: cameras neither trained on nor held out");
  add_number(app, "--pool-budget", o.pool_budget,
             "real camera-times: choose this many (camera, frame) photographs of the --pool-cameras by the strategy's own score, "
             "spread over the rounds, instead of refined virtual views (0: off)",
             within(0, 1000000));
  add_number(app, "--rig-max-distance", f->rig.max_distance, "rig: how far a pool camera may stand from the virtual view", at_least(0));
  add_number(app, "--rig-max-angle", f->rig.max_angle_degrees, "rig: how far it may look away (degrees)", within(0, 180));
  add_selection_flags(app, o.select);
  add_motion_rate_flags(app, f->rates);
  add_dataset_flags(app, f->data, "--train-cameras");
  add_scene_flags(app, f->read);
  return bind(f, finetune_model);
}

namespace {

// ------------------------------------------------------------------ eval

struct EvalFlags {
  std::string model, images, out, truth, lpips, colour_correction;
  std::vector<std::string> cameras, splits;
  int view_stride = 1;
  bool no_renders = false, ls_gain = false;
  DatasetOptions data;
  SceneReadOptions read;
};

int eval(const EvalFlags& f, const Invocation& in) {
  const GaussianCloud model = read_scene_shown(f.model, f.read, in);
  const std::vector<std::string>& files = f.cameras;
  std::vector<std::string> names = f.splits;
  if (names.empty())
    for (const std::string& file : files) names.push_back(fs::path(file).stem().string());
  if (names.size() != files.size()) in.fail(names.size(), " --splits names for ", files.size(), " camera files");
  std::vector<Dataset> splits;
  TerminalProgress loading(in.err, in.progress());
  for (const std::string& file : files) splits.push_back(Dataset::load(f.images, file, f.data, loading));
  std::unique_ptr<GaussianCloud> truth;
  if (in.given("--truth")) truth = std::make_unique<GaussianCloud>(read_scene_shown(f.truth, f.read, in));
  EvalOptions eo;
  eo.view_stride = f.view_stride;
  eo.truth = truth.get();
  eo.lpips_onnx = f.lpips;
  if (in.given("--colour-correction")) eo.colour = read_colour_correction(f.colour_correction);
  eo.ls_gain = f.ls_gain;
  if (!eo.lpips_onnx.empty() && !fs::exists(eo.lpips_onnx)) in.fail("--lpips ", eo.lpips_onnx, " does not exist");
  std::optional<OutputFolder> folder;  // a failed or killed run leaves the folder as it was
  if (!f.out.empty()) folder.emplace(f.out);
  TerminalProgress progress(in.err, in.progress());
  std::vector<SplitMetrics> metrics;
  in.out << "split            views   PSNR    SSIM   moving PSNR" << (eo.lpips_onnx.empty() ? "" : "   LPIPS")
      << (eo.ls_gain ? "   PSNR (least-squares gain per image)" : "") << "\n";
  for (size_t k = 0; k < splits.size(); ++k) {
    eo.save_dir = !folder || f.no_renders ? "" : join_path(join_path(folder->path(), "renders"), names[k]);
    const SplitMetrics m = evaluate_split(model, splits[k], names[k], eo, progress);
    char line[200];
    std::snprintf(line, sizeof line, "%-16s %5zu  %6.2f  %6.4f  %11s", names[k].c_str(), m.views, m.psnr, m.ssim, fixed(m.psnr_moving).c_str());
    in.out << line << (eo.lpips_onnx.empty() ? "" : "   " + fixed(m.lpips, 4)) << (eo.ls_gain ? "   " + fixed(m.psnr_ls_gain) : "") << "\n";
    metrics.push_back(m);
  }
  if (folder) {
    write_metrics_json(join_path(folder->path(), "metrics.json"), metrics);
    folder->commit();
  }
  if (!truth && !std::any_of(splits.begin(), splits.end(), [](const Dataset& d) { return d.has_masks(); }))
    in.out << "(moving-region PSNR needs --truth SCENE, the ground truth with its moving Gaussians, or foreground masks in seg/ beside the cameras)\n";
  return 0;
}

// ------------------------------------------------------------------ bench

/// The built-in scene's size and the fine-tuning's counts, shared by bench and run; --smoke
/// shrinks the defaults.
struct SetupFlags {
  bool smoke = false;
  int width = ExperimentOptions().width, height = ExperimentOptions().height, frames = ExperimentOptions().frames;
  int backbone_iterations = ExperimentOptions().backbone_iterations;
  int iterations = FinetuneOptions().iterations, select_every = FinetuneOptions().select_every, time_stride = 1;
  MotionRateFlags rates;
};

struct BenchSetup {
  ExperimentOptions scene;
  FinetuneOptions finetune;
};

BenchSetup bench_setup(const SetupFlags& s, const Invocation& in) {
  BenchSetup b;
  ExperimentOptions& e = b.scene;
  if (s.smoke) e.width = 64, e.height = 48, e.frames = 6, e.backbone_iterations = 150;
  if (in.given("--width")) e.width = s.width;
  if (in.given("--height")) e.height = s.height;
  if (in.given("--frames")) e.frames = s.frames;
  if (in.given("--backbone-iterations")) e.backbone_iterations = s.backbone_iterations;
  FinetuneOptions& f = b.finetune;
  f.iterations = in.given("--iterations") ? s.iterations : s.smoke ? 60 : f.iterations;
  f.select_every = in.given("--select-every") ? s.select_every : s.smoke ? 30 : f.select_every;
  f.train = fine_tune_schedule(f.iterations, motion_rates(in, s.rates));
  f.select.time_stride = s.time_stride;
  f.select.seed = 1;
  return b;
}

struct BenchFlags {
  std::string out = "fillgs_bench";
  std::vector<std::string> scenes = {"n3v"}, seeds, configs, merge;
  std::vector<ConfigGroup> only;
  double artifact_strength = 0.5;
  Weighting baseline_weighting = Weighting::ExploreGS;
  std::vector<BenchRefiner> refiners = {BenchRefiner::Reference};
  ReferenceOptions reference = bench_reference_options(0.5, 1);  ///< the calibration's knobs set its fields
  SetupFlags setup;
};

int bench(const BenchFlags& f, const Invocation& in) {
  const bool smoke = f.setup.smoke;
  const std::string& root = f.out;
  if (in.given("--merge")) {
    // Tables over finished runs only: bench folders or results.csv files, nothing run.
    if (!in.given("--out")) in.fail("--merge needs --out DIR (the folder for the merged tables)");
    for (const char* k : {"--scenes", "--seeds", "--only", "--configs", "--iterations", "--select-every", "--backbone-iterations", "--width",
                          "--height", "--frames", "--artifact-strength", "--baseline-weighting", "--time-stride", "--refiner", "--reference-angle",
                          "--reference-hallucination", "--reference-fill-blur", "--reference-fill-strength", "--motion-rates",
                          "--position-lr", "--key-lr-scale", "--smoke"})
      if (in.given(k)) in.fail("--merge runs nothing, so ", k, " has no meaning with it");
    const std::vector<RunResult> all = merge_results(f.merge);
    make_directories(root);
    write_bench_report(root, all);
    in.out << "fillgs bench: " << all.size() << " runs from " << f.merge.size() << " inputs -> " << join_path(root, "results.md") << ", "
        << join_path(root, "results.csv") << "\n";
    return 0;
  }
  BenchSetup setup = bench_setup(f.setup, in);
  for (const std::string& sc : f.scenes) parse_scene(sc);  // unknown names fail before any work
  std::vector<uint64_t> seeds;
  for (const std::string& s : in.given("--seeds") ? f.seeds : std::vector<std::string>(smoke ? std::vector<std::string>{"1"} : std::vector<std::string>{"1", "2", "3"}))
    seeds.push_back(uint64_t(parse_count(s, size_t(1) << 62, "fillgs bench", "--seeds value")));
  for (size_t i = 0; i < f.refiners.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (f.refiners[i] == f.refiners[j]) in.fail("--refiner names ", to_string(f.refiners[i]), " twice");
  std::vector<RunConfig> configs = standard_configs(f.baseline_weighting, f.artifact_strength, f.refiners);
  for (RunConfig& c : configs) c.reference = f.reference;
  const std::vector<ConfigGroup>& only = f.only;
  const std::vector<std::string>& ids = f.configs;
  std::vector<RunConfig> chosen;
  for (const RunConfig& c : configs) {
    const bool by_group = only.empty() || std::count(only.begin(), only.end(), c.group);
    const bool by_id = ids.empty() || std::count(ids.begin(), ids.end(), c.id);
    const bool in_smoke = c.group == ConfigGroup::Control || c.group == ConfigGroup::Calibration || c.group == ConfigGroup::Strategy ||
                          c.group == ConfigGroup::Upper;
    if (by_group && by_id && (!smoke || in_smoke)) chosen.push_back(c);
  }
  if (chosen.empty()) in.fail("--only/--configs select no configuration");
  make_directories(root);
  remove_stale_temporaries(root);  // a chart's PNG or log a killed bench left
  TerminalProgress progress(in.err, in.progress());
  std::vector<RunResult> results;
  in.out << "fillgs bench: " << f.scenes.size() << " scene(s) x " << seeds.size() << " seed(s) x " << chosen.size() << " configurations -> " << root
      << " (resumable: finished runs are reused)\n";
  for (const std::string& sc : f.scenes)
    for (uint64_t seed : seeds) {
      ExperimentOptions eo = setup.scene;
      const SceneChoice choice = parse_scene(sc);
      eo.rig = choice.rig;
      eo.variant = choice.variant;
      eo.seed = seed;
      const PreparedScene p = prepare_scene(root, eo, progress, in.out);
      const std::string bb_path = join_path(join_path(p.dir, "backbone"), "result.json");
      RunResult bb;
      if (fs::exists(bb_path)) {
        bb = load_result(bb_path);
      } else {
        bb = evaluate_model(p, p.backbone, "backbone", "", progress);
        bb.group = ConfigGroup::Control;
        save_result(bb_path, bb);
      }
      in.out << sc << " seed " << seed << " backbone: interpolation " << fixed(bb.interpolation.psnr) << " dB, extrapolation "
          << fixed(bb.extrapolation.psnr) << " dB, train " << fixed(bb.train.psnr) << " dB\n";
      for (const RunConfig& c : chosen) {
        FinetuneOptions fo = setup.finetune;
        results.push_back(run_config(p, c, fo, progress, in.out));
        // After every run, over everything the folder holds (earlier invocations included):
        // an interrupted bench still has its tables.
        write_bench_report(root, collect_results(root));
      }
    }
  write_bench_report(root, collect_results(root));
  in.out << "fillgs bench: " << results.size() << " runs here, tables over every run in the folder: " << join_path(root, "results.md") << ", "
      << join_path(root, "results.csv") << "\n";
  return 0;
}

// ------------------------------------------------------------------ run

/// The refiner's artifact strength in `fillgs run` (the benchmark's default).
constexpr double kRunArtifactStrength = 0.5;

struct RunFlags {
  std::string out = "fillgs_run", scene = "n3v";
  Strategy baseline = Strategy::Coverage4D;
  BenchRefiner refiner = BenchRefiner::Reference;
  SetupFlags setup;
};

int run_pipeline(const RunFlags& f, const Invocation& in) {
  const std::string& dir = f.out;
  const std::string baseline = to_string(f.baseline);
  const BenchRefiner refiner = f.refiner;
  if (f.baseline == Strategy::FillGS) in.fail("--baseline must be another strategy than fillgs");
  const auto t0 = Clock::now();
  BenchSetup setup = bench_setup(f.setup, in);
  const SceneChoice choice = parse_scene(f.scene);
  setup.scene.rig = choice.rig;
  setup.scene.variant = choice.variant;
  TerminalProgress progress(in.err, in.progress());
  const ExperimentOptions eo = setup.scene.resolved();
  in.out << "fillgs run: the whole pipeline on the built-in scene (" << eo.scene_name() << ", " << eo.width << "x" << eo.height << ", "
      << eo.frames << " frames): train a backbone on 2 cameras, then fine-tune it without generated views, with FillGS's and with "
      << baseline << "'s viewpoints (" << to_string(refiner) << " refiner, artifacts) -> " << dir << "\n";
  const PreparedScene p = prepare_scene(dir, setup.scene, progress, in.out);
  RunResult bb = evaluate_model(p, p.backbone, "backbone", "", progress);
  bb.group = ConfigGroup::Control;
  std::vector<RunResult> results;
  std::vector<std::string> run_ids;
  for (const RunConfig& c : standard_configs(Weighting::ExploreGS, kRunArtifactStrength, {refiner}))
    if (c.id == "no-refinement" || c.id == "fillgs" || c.id == baseline) {
      results.push_back(run_config(p, c, setup.finetune, progress, in.out));
      run_ids.push_back(c.id);
    }
  std::vector<RunResult> all = {bb};
  all.insert(all.end(), results.begin(), results.end());
  write_bench_report(dir, all);

  RunReportInput report;
  report.scene = &p;
  report.results = all;
  report.run_ids = run_ids;
  report.finetune = setup.finetune;
  report.refiner = refiner;
  report.artifact_strength = kRunArtifactStrength;
  report.command = "fillgs";
  for (const std::string& s : in.args) report.command += " " + s;  // args[0] is "run"
  write_run_report(dir, report);
  in.out << "\nmethod           interp PSNR (moving)   extrap PSNR (moving)   train PSNR\n";
  for (const RunResult& r : all) {
    char line[200];
    std::snprintf(line, sizeof line, "%-16s %6s (%6s)        %6s (%6s)        %6s\n", r.id.c_str(), fixed(r.interpolation.psnr).c_str(),
                  fixed(r.interpolation.psnr_moving).c_str(), fixed(r.extrapolation.psnr).c_str(), fixed(r.extrapolation.psnr_moving).c_str(),
                  fixed(r.train.psnr).c_str());
    in.out << line;
  }
  in.out << "\nfillgs run: finished in " << fixed(seconds_since(t0), 0) << " s.\n"
      << "The report: " << join_path(dir, "report.html") << " (one self-contained page: open it in a browser, e.g. xdg-open "
      << join_path(dir, "report.html") << "), or " << join_path(dir, "report.md") << " as text.\n";
  return 0;
}

void add_setup_flags(CLI::App& app, SetupFlags& s, bool sizes) {
  add_flag(app, "--smoke", s.smoke, "a small, fast version (64x48, 6 frames, short runs)");
  if (sizes) {
    add_number(app, "--width", s.width, "image width of the built-in scene (0: the rig's, 160; technicolor 192; smoke 64)", at_least(0));
    add_number(app, "--height", s.height, "image height (0: the rig's, 120; technicolor 102; smoke 48)", at_least(0));
    add_number(app, "--frames", s.frames, "frames of the video (smoke 6)", at_least(2));
    add_number(app, "--backbone-iterations", s.backbone_iterations, "training iterations of the backbone (smoke 150)", at_least(1));
    add_number(app, "--iterations", s.iterations, "fine-tuning iterations (smoke 60)", at_least(1));
    add_number(app, "--select-every", s.select_every, "a selection round every M iterations (smoke 30)", at_least(1));
    add_number(app, "--time-stride", s.time_stride, "starting-view priority on every k-th frame only", at_least(1));
  }
  add_motion_rate_flags(app, s.rates);
}

}  // namespace

Action declare_eval(CLI::App& app) {
  auto f = std::make_shared<EvalFlags>();
  add_text(app, "--model", f->model, "the model", "PATH")->required();
  add_text(app, "--images", f->images, "the images folder", "DIR")->required();
  add_list(app, "--cameras", f->cameras, "one camera file per split")->required();
  add_list(app, "--splits", f->splits, "the splits' names (default: the camera files' names)");
  add_text(app, "--truth", f->truth, "the ground-truth scene: its moving Gaussians mark the moving region", "PATH");
  add_text(app, "--lpips", f->lpips, "LPIPS network (ONNX)", "PATH");
  add_text(app, "--colour-correction", f->colour_correction, "a colour_correction.json from train --colour-correction", "PATH");
  add_flag(app, "--ls-gain", f->ls_gain, "also PSNR after a least-squares gain per image");
  add_text(app, "--out", f->out, "the folder for metrics.json and renders", "DIR");
  add_flag(app, "--no-renders", f->no_renders, "no renders in --out");
  add_number(app, "--view-stride", f->view_stride, "every k-th view of each split", at_least(1));
  add_dataset_flags(app, f->data, "--select-cameras");
  add_scene_flags(app, f->read);
  return bind(f, eval);
}

Action declare_bench(CLI::App& app) {
  auto f = std::make_shared<BenchFlags>();
  add_text(app, "--out", f->out, "the benchmark's folder (resumable)", "DIR");
  add_list(app, "--scenes,--variants", f->scenes, "built-in scenes: " + join_names(bench_scenes()));
  add_list(app, "--seeds", f->seeds, "seeds (default 1,2,3; smoke 1)");
  add_choice_list(app, "--only", f->only, "only these groups of configurations");
  add_list(app, "--configs", f->configs, "only these configurations");
  add_number(app, "--artifact-strength", f->artifact_strength, "strength of the oracle's simulated refiner artifacts", at_least(0));
  add_choice(app, "--baseline-weighting", f->baseline_weighting, "the weights the baseline strategies fine-tune with");
  add_choice_list(app, "--refiner", f->refiners,
                  "refiners, a table each (the first's rows unsuffixed, the others' ending @NAME): reference (calibrated, the default), oracle, oracle-full");
  add_number(app, "--reference-angle", f->reference.angle_scale_degrees,
             "the reference refiner's confidence angle in degrees (the calibration's knob; default: the calibrated value)", positive());
  add_number(app, "--reference-hallucination", f->reference.hallucination,
             "the reference refiner's share of misplaced texture in its fill (the calibration's knob; default: the calibrated value)", within(0, 1));
  add_number(app, "--reference-fill-blur", f->reference.fill_blur,
             "the reference refiner's fill blur, a fraction of the width (the calibration's knob; default: the calibrated value)", at_least(0));
  add_number(app, "--reference-fill-strength", f->reference.fill_strength,
             "the reference refiner's fill degradation (colour drift, blob; the calibration's knob; default: the calibrated value)", at_least(0));
  add_list(app, "--merge", f->merge, "tables over finished runs: bench folders or results.csv files (needs --out)");
  add_setup_flags(app, f->setup, true);
  return bind(f, bench);
}

Action declare_run(CLI::App& app) {
  auto f = std::make_shared<RunFlags>();
  add_text(app, "--out", f->out, "the folder for the report, pictures and runs", "DIR");
  add_text(app, "--scene", f->scene, "built-in scene: " + join_names(bench_scenes()), "NAME");
  add_choice(app, "--baseline", f->baseline, "the strategy FillGS is compared with");
  add_choice(app, "--refiner", f->refiner, "the refiner: reference (calibrated, the default), oracle (truth where any camera saw), oracle-full");
  add_setup_flags(app, f->setup, false);
  return bind(f, run_pipeline);
}

}  // namespace fillgs::cli
