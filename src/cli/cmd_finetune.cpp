// fillgs finetune, eval, bench and run: the refinement loop, its evaluation, the paper's
// comparison and the main job.
#include <optional>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "common.hpp"
#include "progress_bar.hpp"
#include "fillgs/limits.hpp"
#include "fillgs/evaluate.hpp"
#include "fillgs/experiment.hpp"
#include "fillgs/finetune.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/html_report.hpp"
#include "fillgs/plot.hpp"
#include "fillgs/ply.hpp"
#include "fillgs/raster.hpp"
#include "fillgs/scene_io.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace fillgs::cli {

namespace {

/// Flags of finetune: the selection ablations, --paper-schedule, --quiet.
const std::set<std::string> kFinetuneFlags = {"no-start-selection", "no-error-term", "no-sensitivity-term", "no-candidate-scoring",
                                            "no-global", "count-only", "speed-only", "quiet", "paper-schedule"};

void apply_select_flags(const Args& a, SelectOptions& s) {
  s.strategy = parse_strategy(a.get("strategy", "fillgs"));
  s.time_stride = a.integer("time-stride", s.time_stride);
  if (s.time_stride < 1) throw_error("fillgs ", a.command(), ": --time-stride must be at least 1");
  s.seed = uint64_t(a.integer("seed", 1));
  s.no_start_selection = a.flag("no-start-selection");
  s.no_error_term = a.flag("no-error-term");
  s.no_sensitivity_term = a.flag("no-sensitivity-term");
  s.no_candidate_scoring = a.flag("no-candidate-scoring");
  s.no_global = a.flag("no-global");
  if (a.flag("count-only") && a.flag("speed-only")) throw_error("fillgs ", a.command(), ": --count-only and --speed-only exclude each other");
  if (a.flag("count-only")) s.score = CandidateScore::CountOnly;
  if (a.flag("speed-only")) s.score = CandidateScore::SpeedOnly;
}

/// --motion-rates repair|gentle, --position-lr LR, --key-lr-scale k: how fast fine-tuning
/// moves Gaussians (finetune.hpp, MotionRates); the two numbers override the preset.
const std::set<std::string> kMotionRateOptions = {"motion-rates", "position-lr", "key-lr-scale"};
MotionRates motion_rates(const Args& a) {
  const std::string preset = a.get("motion-rates", "repair");
  if (preset != "repair" && preset != "gentle") throw_error("fillgs ", a.command(), ": unknown --motion-rates \"", preset, "\" (repair, gentle)");
  MotionRates r = preset == "gentle" ? MotionRates::gentle() : MotionRates();
  r.position_lr = a.number("position-lr", r.position_lr);
  r.key_lr_scale = a.number("key-lr-scale", r.key_lr_scale);
  if (!(r.position_lr > 0) || !(r.key_lr_scale > 0)) throw_error("fillgs ", a.command(), ": --position-lr and --key-lr-scale must be positive");
  return r;
}

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

}  // namespace

// ------------------------------------------------------------------ finetune

int cmd_finetune(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("finetune", args, 1,
         merge({"model", "images", "cameras", "out", "train-cameras", "iterations", "select-every", "trajectories", "strategy", "weighting",
                "refiner", "refiner-command", "refiner-timeout", "truth", "artifact-strength", "confidence", "seed", "threads",
                "time-stride", "refined-share", "mask-sigma", "mask", "covis", "support", "support-window", "pool-cameras", "rig-max-distance",
                "rig-max-angle"},
               merge(merge(kSceneOptions, kMotionRateOptions), kDatasetOptions)),
         kFinetuneFlags);
  const auto t0 = Clock::now();
  const std::string out_dir = a.require("out");
  const Dataset data = Dataset::load(a.require("images"), a.require("cameras"), dataset_options(a, "train-cameras"));
  const GaussianCloud model = read_scene(a.require("model"), scene_options(a));
  FinetuneOptions o = a.flag("paper-schedule") ? FinetuneOptions::paper() : FinetuneOptions();
  o.iterations = a.integer("iterations", o.iterations);
  o.select_every = a.integer("select-every", o.select_every);
  o.trajectories = a.integer("trajectories", o.trajectories);
  if (o.iterations < 1 || o.select_every < 1 || o.trajectories < 0)
    throw_error("fillgs finetune: --iterations and --select-every must be at least 1, --trajectories at least 0");
  o.train = fine_tune_schedule(o.iterations, motion_rates(a));
  o.train.seed = uint64_t(a.integer("seed", 1));
  o.train.refined_share = a.number("refined-share", o.train.refined_share);
  if (!(o.train.refined_share >= 0 && o.train.refined_share <= 1)) throw_error("fillgs finetune: --refined-share must be in [0, 1]");
  apply_select_flags(a, o.select);
  o.weighting = parse_weighting(a.get("weighting", "fillgs"));
  o.mask.sigma = a.number("mask-sigma", o.mask.sigma);
  o.mask.method = parse_mask_method(a.get("mask", "depth-warp"));
  o.mask.covisibility = parse_covisibility(a.get("covis", "paper"));
  if (a.has("confidence")) {
    o.mask.method = MaskMethod::External;
    o.mask.external_dir = a.get("confidence");
    if (!fs::is_directory(o.mask.external_dir)) throw_error("fillgs finetune: --confidence ", o.mask.external_dir, " is not a folder");
  }
  o.threads = a.threads();
  o.work_dir = join_path(out_dir, "work");

  const std::string kind = a.get("refiner", "identity");
  std::unique_ptr<Refiner> refiner;
  std::unique_ptr<GaussianCloud> truth;
  std::unique_ptr<Dataset> pool_data;
  if (kind == "identity") {
    refiner = make_identity_refiner();
  } else if (kind == "oracle") {
    truth = std::make_unique<GaussianCloud>(read_scene(a.require("truth"), scene_options(a)));
    OracleOptions oo;
    oo.artifacts.strength = a.number("artifact-strength", 0.0);
    oo.artifacts.seed = o.train.seed;
    oo.support = parse_oracle_support(a.get("support", "observed"));
    oo.window = a.integer("support-window", oo.window);
    if (oo.window < 0) throw_error("fillgs finetune: --support-window must be at least 0");
    for (const TrainView& v : data.views()) oo.observers.push_back(v.camera);
    oo.frames = data.frames();
    oo.threads = o.threads;
    refiner = make_oracle_refiner(*truth, oo);
  } else if (kind == "external") {
    refiner = make_external_refiner(a.require("refiner-command"), a.number("refiner-timeout", 600.0));
  } else if (kind == "rig") {
    // The pool: rig cameras neither trained on nor held out, every frame the training views have.
    DatasetOptions po = dataset_options(a, "pool-cameras");
    po.monocular_cycle.clear();
    if (po.cameras.empty()) throw_error("fillgs finetune: --refiner rig needs --pool-cameras a,b,.. (rig cameras neither trained on nor held out)");
    for (const std::string& c : po.cameras)
      for (const std::string& t : data.rigs())
        if (c == t) throw_error("fillgs finetune: --pool-cameras names ", c, ", a training camera");
    pool_data = std::make_unique<Dataset>(Dataset::load(a.require("images"), a.require("cameras"), po));
    if (pool_data->frames() != data.frames())
      throw_error("fillgs finetune: the pool cameras have ", pool_data->frames(), " frames, the training cameras ", data.frames());
    RigPool pool;
    for (const TrainView& v : pool_data->views()) pool.cameras.push_back(v.camera);
    pool.frame_count = pool_data->frames();
    pool.image = [d = pool_data.get()](size_t i) { return d->image(i); };
    RigOptions ro;
    ro.max_distance = a.number("rig-max-distance", ro.max_distance);
    ro.max_angle_degrees = a.number("rig-max-angle", ro.max_angle_degrees);
    refiner = make_rig_refiner(std::move(pool), ro);
  } else {
    throw_error("fillgs finetune: unknown --refiner \"", kind, "\" (identity, oracle, external, rig)");
  }
  require_fresh(out_dir, "finetune");
  make_directories(out_dir);
  out << "fine-tuning " << model.size() << " Gaussians on " << data.views().size() << " views for " << o.iterations << " iterations; "
      << o.trajectories << " trajectories (" << to_string(o.select.strategy) << ") every " << o.select_every << ", refiner "
      << refiner->name() << ", weights " << to_string(o.weighting) << "\n";
  TerminalProgress progress(err, progress_enabled(a));
  const FinetuneResult r = finetune(data, model, *refiner, o, progress);
  write_fillgs_ply(join_path(out_dir, "model.ply"), r.model, data.frames());
  write_transforms_json(join_path(out_dir, "virtual_views.json"), r.virtual_views);
  json rounds = json::array();
  for (const FinetuneRound& rd : r.rounds) {
    json f = json::array();
    for (const auto& [patch, why] : rd.refine_failures) f.push_back({{"patch", patch}, {"error", why}});
    rounds.push_back({{"iteration", rd.iteration},
                      {"trajectories", rd.trajectories},
                      {"views_added", rd.views_added},
                      {"views_dropped", rd.views_dropped},
                      {"mean_weight", rd.mean_weight},
                      {"refine_failures", f},
                      {"notes", rd.notes},
                      {"seconds", {{"select", rd.seconds_select}, {"render", rd.seconds_render}, {"refine", rd.seconds_refine},
                                   {"weights", rd.seconds_weights}}}});
    for (const auto& [patch, why] : rd.refine_failures) err << "warning: refinement failed for " << why << "\n";
  }
  const EvalResult tr = evaluate_views(r.model, data, std::max<int>(1, int(data.views().size() / 32)), Vec3f::Zero(), o.threads);
  size_t dropped = 0;
  for (const FinetuneRound& rd : r.rounds) dropped += rd.views_dropped;
  const json j = {{"iterations", o.iterations}, {"select_every", o.select_every}, {"trajectories_per_round", o.trajectories},
                  {"strategy", to_string(o.select.strategy)}, {"weighting", to_string(o.weighting)}, {"refiner", refiner->name()},
                  {"rounds", rounds}, {"virtual_views", r.virtual_views.size()}, {"virtual_views_dropped", dropped}, {"train_psnr", tr.psnr}, {"train_ssim", tr.ssim},
                  {"gaussians", r.model.size()}, {"moving_gaussians", r.model.dynamic_count()},
                  {"seconds", {{"train", r.seconds_train}, {"total", seconds_since(t0)}}}};
  ScatterSeries loss{"loss", {}, {}, {}};
  const size_t every = std::max<size_t>(1, r.loss_history.size() / 400);
  for (size_t i = 0; i < r.loss_history.size(); i += every) loss.x.push_back(double(i + 1)), loss.y.push_back(r.loss_history[i]);
  write_scatter_png(join_path(out_dir, "loss.png"), {loss}, {"fine-tuning loss (weighted on refined views)", "iteration", "loss"}, false);
  write_file_atomically(join_path(out_dir, "summary.json"), j.dump(2) + "\n");
  out << "fine-tuned in " << fixed(seconds_since(t0), 1) << " s: " << r.virtual_views.size() << " refined views added"
      << (dropped ? " (" + std::to_string(dropped) + " dropped by the refiner)" : "") << ", train PSNR "
      << fixed(tr.psnr) << " dB -> " << out_dir << "\n";
  return 0;
}

// ------------------------------------------------------------------ eval

int cmd_eval(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("eval", args, 1,
         merge(merge({"model", "images", "cameras", "splits", "select-cameras", "truth", "lpips", "out", "stride", "threads", "colour-correction"},
                     kSceneOptions),
               kDatasetOptions),
         {"quiet", "no-renders", "ls-gain"});
  const GaussianCloud model = read_scene(a.require("model"), scene_options(a));
  const std::vector<std::string> files = split_commas(a.require("cameras"));
  std::vector<std::string> names = split_commas(a.get("splits"));
  if (names.empty())
    for (const std::string& f : files) names.push_back(fs::path(f).stem().string());
  if (names.size() != files.size()) throw_error("fillgs eval: ", names.size(), " --splits names for ", files.size(), " camera files");
  const DatasetOptions dopt = dataset_options(a, "select-cameras");
  std::vector<Dataset> splits;
  for (const std::string& f : files) splits.push_back(Dataset::load(a.require("images"), f, dopt));
  std::unique_ptr<GaussianCloud> truth;
  if (a.has("truth")) truth = std::make_unique<GaussianCloud>(read_scene(a.get("truth"), scene_options(a)));
  EvalOptions eo;
  eo.stride = a.integer("stride", 1);
  eo.threads = a.threads();
  eo.truth = truth.get();
  eo.lpips_onnx = a.get("lpips");
  if (a.has("colour-correction")) eo.colour = read_colour_correction(a.get("colour-correction"));
  eo.ls_gain = a.flag("ls-gain");
  if (!eo.lpips_onnx.empty() && !fs::exists(eo.lpips_onnx)) throw_error("fillgs eval: --lpips ", eo.lpips_onnx, " does not exist");
  const std::string out_dir = a.get("out");
  std::optional<OutputFolder> folder;  // a failed or killed run leaves the folder as it was
  if (!out_dir.empty()) folder.emplace(out_dir);
  TerminalProgress progress(err, progress_enabled(a));
  json j = json::object();
  out << "split            views   PSNR    SSIM   moving PSNR" << (eo.lpips_onnx.empty() ? "" : "   LPIPS")
      << (eo.ls_gain ? "   PSNR (least-squares gain per image)" : "") << "\n";
  for (size_t k = 0; k < splits.size(); ++k) {
    eo.save_dir = !folder || a.flag("no-renders") ? "" : join_path(join_path(folder->path(), "renders"), names[k]);
    const SplitMetrics m = evaluate_split(model, splits[k], names[k], eo, progress);
    char line[200];
    std::snprintf(line, sizeof line, "%-16s %5zu  %6.2f  %6.4f  %11s", names[k].c_str(), m.views, m.psnr, m.ssim, fixed(m.psnr_moving).c_str());
    out << line << (eo.lpips_onnx.empty() ? "" : "   " + fixed(m.lpips, 4)) << (eo.ls_gain ? "   " + fixed(m.psnr_ls_gain) : "") << "\n";
    auto num = [](double x) { return std::isfinite(x) ? json(x) : json(nullptr); };
    j[names[k]] = {{"views", m.views}, {"psnr", m.psnr}, {"ssim", m.ssim}, {"psnr_moving", num(m.psnr_moving)},
                   {"moving_pixels", m.moving_pixels}, {"lpips", num(m.lpips)}, {"psnr_ls_gain", num(m.psnr_ls_gain)}};
  }
  if (folder) {
    write_file_atomically(join_path(folder->path(), "metrics.json"), j.dump(2) + "\n");
    folder->commit();
  }
  if (!truth && !std::any_of(splits.begin(), splits.end(), [](const Dataset& d) { return d.has_masks(); }))
    out << "(moving-region PSNR needs --truth SCENE, the ground truth with its moving Gaussians, or foreground masks in seg/ beside the cameras)\n";
  return 0;
}

// ------------------------------------------------------------------ bench

namespace {

struct BenchSetup {
  ExperimentOptions scene;
  FinetuneOptions finetune;
};

BenchSetup bench_setup(const Args& a, bool smoke) {
  BenchSetup b;
  ExperimentOptions& e = b.scene;
  if (smoke) e.width = 64, e.height = 48, e.frames = 6, e.backbone_iterations = 150;
  e.width = a.integer("width", e.width);
  e.height = a.integer("height", e.height);
  e.frames = a.integer("frames", e.frames);
  e.backbone_iterations = a.integer("backbone-iterations", e.backbone_iterations);
  e.threads = a.threads();
  FinetuneOptions& f = b.finetune;
  f.iterations = a.integer("iterations", smoke ? 60 : f.iterations);
  f.select_every = a.integer("select-every", smoke ? 30 : f.select_every);
  if (f.iterations < 1 || f.select_every < 1 || e.backbone_iterations < 1) throw_error("fillgs ", a.command(), ": iteration counts must be at least 1");
  f.train = fine_tune_schedule(f.iterations, motion_rates(a));
  f.threads = e.threads;
  f.select.time_stride = a.integer("time-stride", 1);
  f.select.seed = 1;
  return b;
}

std::vector<OracleSupport> parse_supports(const std::string& s) {
  if (s == "both") return {OracleSupport::Observed, OracleSupport::Full};
  return {parse_oracle_support(s)};
}

}  // namespace

int cmd_bench(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("bench", args, 1,
         merge({"out", "scenes", "variants", "seeds", "only", "configs", "iterations", "select-every", "backbone-iterations", "width", "height",
                "frames", "artifact-strength", "baseline-weighting", "threads", "time-stride", "support", "merge"},
               kMotionRateOptions),
         {"quiet", "smoke"});
  const bool smoke = a.flag("smoke");
  const std::string root = a.get("out", "fillgs_bench");
  if (a.has("merge")) {
    // Tables over finished runs only: bench folders or results.csv files, nothing run.
    if (!a.has("out")) throw_error("fillgs bench: --merge needs --out DIR (the folder for the merged tables)");
    for (const std::string& k : merge({"scenes", "variants", "seeds", "only", "configs", "iterations", "select-every", "backbone-iterations", "width",
                                       "height", "frames", "artifact-strength", "baseline-weighting", "time-stride", "support"},
                                      kMotionRateOptions))
      if (a.has(k)) throw_error("fillgs bench: --merge runs nothing, so --", k, " has no meaning with it");
    if (smoke) throw_error("fillgs bench: --merge runs nothing, so --smoke has no meaning with it");
    const std::vector<std::string> inputs = split_commas(a.get("merge"));
    const std::vector<RunResult> all = merge_results(inputs);
    make_directories(root);
    write_bench_report(root, all);
    out << "fillgs bench: " << all.size() << " runs from " << inputs.size() << " inputs -> " << join_path(root, "results.md") << ", "
        << join_path(root, "results.csv") << "\n";
    return 0;
  }
  BenchSetup setup = bench_setup(a, smoke);
  // --variants is the earlier name of --scenes.
  const std::vector<std::string> scenes = split_commas(a.get("scenes", a.get("variants", "n3v")));
  for (const std::string& sc : scenes) parse_scene(sc);  // unknown names fail before any work
  std::vector<uint64_t> seeds;
  for (const std::string& s : split_commas(a.get("seeds", smoke ? "1" : "1,2,3")))
    seeds.push_back(uint64_t(parse_count(s, size_t(1) << 62, "fillgs bench", "--seeds value")));
  const double strength = a.number("artifact-strength", 0.5);
  const std::vector<OracleSupport> supports = parse_supports(a.get("support", "observed"));
  std::vector<RunConfig> configs = standard_configs(parse_weighting(a.get("baseline-weighting", "exploregs")), strength, supports);
  const std::vector<std::string> only = split_commas(a.get("only")), ids = split_commas(a.get("configs"));
  std::vector<RunConfig> chosen;
  for (const RunConfig& c : configs) {
    const bool by_group = only.empty() || std::count(only.begin(), only.end(), c.group);
    const bool by_id = ids.empty() || std::count(ids.begin(), ids.end(), c.id);
    if (by_group && by_id && (!smoke || c.group == "control" || c.group == "strategy" || c.group == "upper")) chosen.push_back(c);
  }
  if (chosen.empty()) throw_error("fillgs bench: --only/--configs select no configuration");
  make_directories(root);
  TerminalProgress progress(err, progress_enabled(a));
  std::vector<RunResult> results;
  out << "fillgs bench: " << scenes.size() << " scene(s) x " << seeds.size() << " seed(s) x " << chosen.size() << " configurations -> " << root
      << " (resumable: finished runs are reused)\n";
  for (const std::string& sc : scenes)
    for (uint64_t seed : seeds) {
      ExperimentOptions eo = setup.scene;
      const SceneChoice choice = parse_scene(sc);
      eo.rig = choice.rig;
      eo.variant = choice.variant;
      eo.seed = seed;
      const PreparedScene p = prepare_scene(root, eo, progress, out);
      const std::string bb_path = join_path(join_path(p.dir, "backbone"), "result.json");
      RunResult bb;
      if (fs::exists(bb_path)) {
        bb = load_result(bb_path);
      } else {
        bb = evaluate_model(p, p.backbone, "backbone", eo.threads, "", progress);
        bb.group = "control";
        save_result(bb_path, bb);
      }
      out << sc << " seed " << seed << " backbone: interpolation " << fixed(bb.interpolation.psnr) << " dB, extrapolation "
          << fixed(bb.extrapolation.psnr) << " dB, train " << fixed(bb.train.psnr) << " dB\n";
      for (const RunConfig& c : chosen) {
        FinetuneOptions fo = setup.finetune;
        results.push_back(run_config(p, c, fo, progress, out));
        // After every run, over everything the folder holds (earlier invocations included):
        // an interrupted bench still has its tables.
        write_bench_report(root, collect_results(root));
      }
    }
  write_bench_report(root, collect_results(root));
  out << "fillgs bench: " << results.size() << " runs here, tables over every run in the folder: " << join_path(root, "results.md") << ", " << join_path(root, "results.csv")
      << "\n";
  return 0;
}

// ------------------------------------------------------------------ run

int cmd_run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("run", args, 1, merge({"out", "threads", "baseline", "scene", "support"}, kMotionRateOptions), {"quiet", "smoke"});
  const auto t0 = Clock::now();
  const std::string dir = a.get("out", "fillgs_run");
  const std::string baseline = a.get("baseline", "coverage4d");
  const Strategy baseline_strategy = parse_strategy(baseline);
  if (baseline_strategy == Strategy::FillGS) throw_error("fillgs run: --baseline must be another strategy than fillgs");
  const OracleSupport support = parse_oracle_support(a.get("support", "observed"));
  BenchSetup setup = bench_setup(a, a.flag("smoke"));
  const SceneChoice choice = parse_scene(a.get("scene", "n3v"));
  setup.scene.rig = choice.rig;
  setup.scene.variant = choice.variant;
  TerminalProgress progress(err, progress_enabled(a));
  const ExperimentOptions eo = setup.scene.resolved();
  out << "fillgs run: the whole pipeline on the built-in scene (" << eo.scene_name() << ", " << eo.width << "x" << eo.height << ", "
      << eo.frames << " frames): train a backbone on 2 cameras, then fine-tune it without generated views, with FillGS's and with "
      << baseline << "'s viewpoints (oracle refiner, " << to_string(support) << " support, artifacts) -> " << dir << "\n";
  const PreparedScene p = prepare_scene(dir, setup.scene, progress, out);
  RunResult bb = evaluate_model(p, p.backbone, "backbone", eo.threads, "", progress);
  bb.group = "control";
  std::vector<RunResult> results;
  std::vector<std::string> run_ids;
  for (const RunConfig& c : standard_configs(Weighting::ExploreGS, 0.5, {support}))
    if (c.id == "no-refinement" || c.id == "fillgs" || c.id == baseline) {
      results.push_back(run_config(p, c, setup.finetune, progress, out));
      run_ids.push_back(c.id);
    }
  std::vector<RunResult> all = {bb};
  all.insert(all.end(), results.begin(), results.end());
  write_bench_report(dir, all);

  // Side-by-side pictures: ground truth | backbone | each fine-tuned model, at the moment of
  // each split where the moving content covers most of a view (a moving moment).
  std::vector<GaussianCloud> models = {p.backbone};
  for (const std::string& id : run_ids) models.push_back(read_scene(join_path(join_path(join_path(p.dir, "runs"), id), "model.ply")));
  std::vector<std::string> pictures;
  for (const auto* split : {p.extrapolation.get(), p.interpolation.get()}) {
    size_t best = 0, most = 0;
    for (size_t v = 0; v < split->views().size(); ++v) {
      const std::vector<unsigned char> m = moving_region(p.synth.scene, split->views()[v].camera, eo.threads);
      const size_t n = size_t(std::count(m.begin(), m.end(), 1));
      if (n > most) most = n, best = v;
    }
    const TrainView& view = split->views()[best];
    std::vector<std::vector<float>> imgs = {split->image(best)};
    std::vector<std::string> caps = {"ground truth"};
    for (size_t m = 0; m < models.size(); ++m) {
      RenderOptions ro;
      ro.threads = eo.threads;
      imgs.push_back(render(evaluate(models[m], view.camera.time), view.camera, ro).rgb);
      caps.push_back(m == 0 ? "backbone" : run_ids[m - 1]);
    }
    const std::string file = "compare_" + view.rig + "_f" + std::to_string(view.frame) + ".png";
    write_side_by_side_png(join_path(dir, file), imgs, view.camera.width, view.camera.height, caps, 2);
    pictures.push_back(file);
  }
  // Report.
  std::ostringstream md;
  md << "# fillgs run\n\nScene: built-in synthetic (" << eo.scene_name() << "), " << eo.width << "x" << eo.height << ", " << eo.frames
     << " frames; backbone trained on " << p.train->rigs().size() << " cameras (";
  for (size_t k = 0; k < p.options.train_cameras.size(); ++k) md << (k ? ", " : "") << p.options.train_cameras[k];
  md << ") for " << eo.backbone_iterations << " iterations; each fine-tuning: " << setup.finetune.iterations << " iterations, "
     << setup.finetune.trajectories << " trajectories every " << setup.finetune.select_every << " iterations, oracle refiner ("
     << to_string(support) << " support) with artifacts (strength 0.5). Baselines use ExploreGS weights (the paper's protocol); FillGS its own.\n\n"
     << "| Method | Interp PSNR | SSIM | moving PSNR | Extrap PSNR | SSIM | moving PSNR | Train PSNR | seconds |\n|---|---|---|---|---|---|---|---|---|\n";
  out << "\nmethod           interp PSNR (moving)   extrap PSNR (moving)   train PSNR\n";
  for (const RunResult& r : all) {
    md << "| " << r.id << " | " << fixed(r.interpolation.psnr) << " | " << fixed(r.interpolation.ssim, 3) << " | " << fixed(r.interpolation.psnr_moving)
       << " | " << fixed(r.extrapolation.psnr) << " | " << fixed(r.extrapolation.ssim, 3) << " | " << fixed(r.extrapolation.psnr_moving) << " | "
       << fixed(r.train.psnr) << " | " << fixed(r.seconds_total, 0) << " |\n";
    char line[200];
    std::snprintf(line, sizeof line, "%-16s %6s (%6s)        %6s (%6s)        %6s\n", r.id.c_str(), fixed(r.interpolation.psnr).c_str(),
                  fixed(r.interpolation.psnr_moving).c_str(), fixed(r.extrapolation.psnr).c_str(), fixed(r.extrapolation.psnr_moving).c_str(),
                  fixed(r.train.psnr).c_str());
    out << line;
  }
  md << "\n## Renders\n\nGround truth, the backbone and each fine-tuned model at the view and moment of each split where the moving content "
        "covers most of the image.\n\n";
  for (const std::string& f : pictures) md << "![" << f << "](" << f << ")\n\n";
  for (const char* chart : {"psnr_interpolation", "psnr_extrapolation"})
    if (fs::exists(join_path(dir, std::string(chart) + ".png"))) md << "![" << chart << "](" << chart << ".png)\n\n";
  // The virtual views each strategy chose (top view), copied beside the report.
  md << "## Virtual views\n\n";
  for (const std::string& id : run_ids) {
    const std::string from = join_path(join_path(join_path(p.dir, "runs"), id), "views.png"), file = "views_" + id + ".png";
    std::error_code ec;
    if (id != "no-refinement" && fs::exists(from, ec) && fs::copy_file(from, join_path(dir, file), fs::copy_options::overwrite_existing, ec))
      md << "![" << file << "](" << file << ")\n\n";
  }
  md << "## Command\n\n```\nfillgs";
  for (const std::string& s : args) md << " " << s;  // args[0] is "run"
  md << "\n```\n\n";
  md << "Per-run folders (patches, refined views with their support, consistency mask, co-visibility and weight images): `"
     << join_path(p.dir, "runs") << "`.\n";
  write_file_atomically(join_path(dir, "report.md"), md.str());
  write_html_report(join_path(dir, "report.md"), join_path(dir, "report.html"));
  out << "\nfillgs run: finished in " << fixed(seconds_since(t0), 0) << " s; report " << join_path(dir, "report.md") << " and "
      << join_path(dir, "report.html") << "\n";
  return 0;
}

}  // namespace fillgs::cli
