#pragma once
// The paper's comparison on synthetic scenes (what `fillgs bench` and `fillgs run` run):
// a scene is rendered, a backbone is trained on the 2 training cameras of its split, and
// every configuration (a selection strategy or ablation, a weighting, an oracle refiner with
// or without artifacts and with full or observation-limited support, a budget, an upper
// bound) fine-tunes that backbone and is evaluated on the interpolation and extrapolation
// cameras. Everything lands in a folder and is reused: an interrupted benchmark continues
// where it stopped.
//
// Layout: <root>/<scene>_s<seed>/scene/ (synth), backbone/ (model.ply, summary.json,
// result.json), dense/ (the upper.dense backbone), runs/<config id>/ (work folders,
// model.ply, result.json). <scene> is the rig ("n3v", "technicolor") or the ring's variant
// ("chair", "orbit", "lift").
#include <cmath>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/method/refine.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/train/train.hpp"

namespace fillgs {

/// The part of the comparison a configuration belongs to (a section of the report).
/// Calibration: the unweighted random views the refiner is calibrated with; Selection: the
/// other strategies with FillGS's fine-tuning and weights (the paper's Table 3 protocol).
enum class ConfigGroup { Control, Upper, Calibration, Strategy, Ablation, Selection, Weighting, Budget, Refiner, Unweighted };
FILLGS_ENUM_NAMES(ConfigGroup, "configuration group", {ConfigGroup::Control, "control"}, {ConfigGroup::Upper, "upper"},
                  {ConfigGroup::Calibration, "calibration"}, {ConfigGroup::Strategy, "strategy"}, {ConfigGroup::Ablation, "ablation"},
                  {ConfigGroup::Selection, "selection"}, {ConfigGroup::Weighting, "weighting"}, {ConfigGroup::Budget, "budget"},
                  {ConfigGroup::Refiner, "refiner"}, {ConfigGroup::Unweighted, "unweighted"});

/// The refiners the benchmark runs: the rows of method/refiners.hpp made from the truth and
/// the training cameras alone (`benchmark`), in listing order: the reference-conditioned one
/// (the default, calibrated: refine.hpp, ReferenceOptions), then the oracles with observed
/// and full support (labelled bounds).
std::vector<std::string> bench_refiners();
/// `name` when it is one of bench_refiners(); one line listing them otherwise.
std::string bench_refiner(const std::string& name);

/// The reference refiner of the benchmark: its calibrated parameters (bench/results/README.md,
/// "Calibrating the refiner"), with the configuration's artifact strength and seed.
ReferenceOptions bench_reference_options(double artifact_strength, uint64_t seed);

/// A scene of the comparison by name: "n3v", "technicolor" (the kitchen on those rigs) or a
/// ring variant ("chair", "orbit", "lift"). Throws for other names.
struct SceneChoice {
  std::string rig, variant;
};
SceneChoice parse_scene(const std::string& name);
std::vector<std::string> bench_scenes();  ///< every name parse_scene knows

struct ExperimentOptions {
  std::string rig = "n3v";
  std::string variant;          ///< empty: the rig's default
  uint64_t seed = 1;
  int width = 0, height = 0;    ///< 0: the rig's default (160×120; technicolor 192×102)
  int frames = 20;
  /// Cameras of the split; empty: the scene's own (SynthScene::split).
  std::vector<std::string> train_cameras, interpolation_cameras, extrapolation_cameras;
  int backbone_iterations = 2000;
  /// The scene's folder name: the rig, or the ring's variant.
  std::string scene_name() const;
  /// The options with the rig's defaults filled in.
  ExperimentOptions resolved() const;
};

struct PreparedScene {
  SynthScene synth;
  ExperimentOptions options;  ///< resolved
  std::string dir;  ///< <root>/<scene>_s<seed>
  std::unique_ptr<Dataset> train, interpolation, extrapolation;
  GaussianCloud backbone;  ///< empty until ensure_backbone (prepare_scene's default calls it)
  bool has_backbone = false;
  double seconds_synth = 0, seconds_backbone = 0;  ///< 0 when reused
  bool reused_scene = false, reused_backbone = false;
  std::string scene_dir() const;
  /// <dir>/runs/<id>/result.json: where a configuration's finished run lies.
  std::string result_path(const std::string& config_id) const;
};

/// Renders the scene and trains the backbone, or reuses what an earlier run left (checked
/// against the options it was made with). With `with_backbone` false the backbone is left
/// for ensure_backbone, so a seed whose runs are all finished trains none.
PreparedScene prepare_scene(const std::string& root, const ExperimentOptions& options, Progress& progress, std::ostream& log,
                            bool with_backbone = true);

/// Reads the seed's backbone, or trains it (deterministically from the scene's options)
/// where it is not there; does nothing once the scene has it.
void ensure_backbone(PreparedScene& p, Progress& progress, std::ostream& log);

/// What a configuration does with the backbone.
enum class RunKind {
  Finetune,   ///< select, refine (oracle), weight, fine-tune
  TestViews,  ///< upper.test-views: fine-tune on clean ground truth at every test camera and frame, weight 1,
              ///< drawn as often as the real views
  Dense,      ///< upper.dense: a backbone trained on every camera of the scene's rig
};

/// One configuration of the comparison.
struct RunConfig {
  std::string id;           ///< folder name and table row, e.g. "fillgs", "random", "fillgs.no-global", "fillgs@full"
  ConfigGroup group = ConfigGroup::Strategy;
  RunKind kind = RunKind::Finetune;
  SelectOptions select;     ///< strategy and ablation flags
  Weighting weighting = Weighting::FillGS;
  MaskOptions mask;
  ExplorationOptions grid;  ///< the exploration space (label_unexplored is the one a configuration sets)
  double artifact_strength = 0.5;  ///< the refiner's injected artifacts (0: none)
  int trajectories = 5;     ///< per round; 0: fine-tune on the real views only (the control)
  std::string refiner = "reference";  ///< a row of bench_refiners()
  /// The reference refiner's parameters (the calibrated ones unless the calibration's
  /// knobs say otherwise); its artifact strength and seed are the run's.
  ReferenceOptions reference = bench_reference_options(0.5, 1);
};

/// The paper's comparison, for every refiner in `refiners` (ids of the second and later
/// end in "@<refiner>", e.g. "random@oracle"; the first's have no suffix): the control (no
/// refined views, once), the calibration row (random views, no weights), every strategy
/// (FillGS with its weights, baselines with `baseline_weighting`, the paper's protocol:
/// ExploreGS), FillGS's selection ablations and the other strategies with FillGS's
/// weights (Table 3), weighting ablations (Table 4), budgets 1/10/20, the clean refiner;
/// then the two upper bounds (once).
std::vector<RunConfig> standard_configs(Weighting baseline_weighting = Weighting::ExploreGS, double artifact_strength = 0.5,
                                        const std::vector<std::string>& refiners = {"reference"});

struct RunResult {
  std::string id, variant;         ///< variant: the scene name
  ConfigGroup group = ConfigGroup::Control;
  uint64_t seed = 0;
  SplitMetrics interpolation, extrapolation, train;
  int trajectories = 0;
  size_t views_added = 0;
  double mean_weight = 0;
  std::string support;             ///< the refiner ("reference", "oracle", "oracle-full"), or "" (no generated views)
  double support_share = 0;        ///< mean share of the refined pixels its reference (oracle: the training cameras) supports
  double seconds_select = 0, seconds_refine = 0, seconds_weights = 0, seconds_train = 0, seconds_eval = 0, seconds_total = 0;
  int refine_failures = 0;
};

/// Evaluates a model on the prepared scene's splits (moving region from the ground truth).
RunResult evaluate_model(const PreparedScene& scene, const GaussianCloud& model, const std::string& id,
                         const std::string& save_dir = "", Progress& progress = null_progress());

/// Runs `config` on the backbone (fine-tuning with the oracle refiner, or an upper bound),
/// evaluates, writes <scene.dir>/runs/<id>/result.json; returns the stored result when it
/// exists already.
RunResult run_config(const PreparedScene& scene, const RunConfig& config, const FinetuneOptions& base, Progress& progress,
                     std::ostream& log);

/// A benchmark to run: every configuration over every scene and seed, in one folder.
struct BenchPlan {
  std::string root;                  ///< the folder (resumable: finished runs are reused)
  std::vector<std::string> scenes;   ///< parse_scene's names
  std::vector<uint64_t> seeds;
  std::vector<RunConfig> configs;    ///< in order
  ExperimentOptions scene;           ///< the built-in scene's size and backbone (rig, variant and seed set per run)
  FinetuneOptions finetune;          ///< the fine-tuning's counts and rates
};

/// The configurations of `all` a bench runs: those in `groups` (all when empty) and in `ids`
/// (all when empty), and with `smoke` only the control, calibration, strategy and upper
/// groups. One line where none is left.
std::vector<RunConfig> choose_configs(const std::vector<RunConfig>& all, const std::vector<ConfigGroup>& groups,
                                      const std::vector<std::string>& ids, bool smoke);

/// Runs `plan`: for every scene and seed, the backbone read or trained only where a run still
/// to make needs it, each configuration run (or its finished result reused), the tables
/// rewritten after every run over everything the folder holds. Returns the results of the
/// runs made or reused here.
std::vector<RunResult> run_bench_plan(const BenchPlan& plan, Progress& progress, std::ostream& log);

/// A result as JSON on disk (atomic) and back.
void save_result(const std::string& path, const RunResult& result);
RunResult load_result(const std::string& path);
/// A kept run's result.json, checked against the run it is reused for: its id (and, where
/// given, its seed > 0 and its scene) must be that run's, or one line names the file and both values.
RunResult load_result(const std::string& path, const std::string& id, uint64_t seed = 0, const std::string& scene = "");

/// Every result stored under a benchmark root: <scene>_s<seed>/backbone/result.json and
/// <scene>_s<seed>/runs/*/result.json, sorted by scene then configuration order of
/// standard_configs (backbone first).
std::vector<RunResult> collect_results(const std::string& root);

/// The first line of a bench's results.csv (one run a row; write_bench_report writes it).
inline constexpr const char* kResultsCsvHeader =
    "scene,seed,id,group,refiner,interp_psnr,interp_ssim,interp_psnr_moving,extrap_psnr,extrap_ssim,extrap_psnr_moving,train_psnr,"
    "trajectories,views_added,mean_weight,support_share,refine_failures,s_select,s_refine,s_weights,s_train,s_eval,s_total";

/// The runs of a results.csv. What the CSV does not hold (view and pixel counts, LPIPS,
/// per-split seconds) stays at its default. Bad rows: one error naming file, line and column.
std::vector<RunResult> read_results_csv(const std::string& path);

/// The union of several benches' runs — each input a bench folder (its result.json files)
/// or a results.csv — ordered by scene, seed, then as collect_results orders a folder: seeds
/// run on different machines, or kept only as CSV, make one table. A run (scene, seed, id)
/// found in two inputs must agree to the CSV's 6 significant digits, else one error names
/// both inputs.
std::vector<RunResult> merge_results(const std::vector<std::string>& inputs);

/// `reference` minus another configuration, paired by scene and seed: the way to read a
/// comparison whose spread between seeds is larger than the differences between methods.
struct PairedDifference {
  std::string variant, id;
  ConfigGroup group = ConfigGroup::Control;
  int seeds = 0;  ///< seeds where both ran
  /// interpolation PSNR, its moving region, extrapolation PSNR, its moving region (dB)
  double mean[4] = {}, sd[4] = {};
  /// Half-width of the 95 % confidence interval of the mean difference, t over the paired
  /// seeds: t(0.975, seeds − 1) · sd / √seeds (NaN with fewer than 2 seeds).
  double half_width[4] = {};
  /// The interval excludes 0: the only case a report calls the two "separated".
  bool separated(int k) const { return std::isfinite(half_width[k]) && std::abs(mean[k]) > half_width[k]; }
};

/// The 0.975 quantile of Student's t with `df` ≥ 1 degrees of freedom (12.706 at 1, 2.776 at
/// 4, → 1.960), from its distribution function's closed form for integer df (Abramowitz and
/// Stegun 26.7.3–4) inverted by bisection.
double student_t_975(int df);

/// The fewest paired seeds n ≥ 2 whose 95 % interval, t(0.975, n − 1) · sd / √n, is at most
/// `half_width` for a paired SD of `sd` (what a report prints where the measured interval is
/// wider than the criterion's); 0 where more than 10,000 would be needed or `sd` is not finite.
int seeds_for_half_width(double sd, double half_width);

/// For every configuration but the reference (and the backbone): `reference` − it, over
/// the seeds both have in the same scene. A configuration run with the second oracle
/// support ("random@full") is paired with the reference of that support ("fillgs@full").
/// A strategy run under a named weighting ("random.w-none") is paired with the reference
/// under the same weighting ("fillgs.w-none") where that run exists, so that only the
/// selection differs; otherwise with the reference itself.
std::vector<PairedDifference> paired_differences(const std::vector<RunResult>& results, const std::string& reference = "fillgs");

/// results.csv (every run), results.md (mean ± standard deviation over seeds per scene,
/// shaped like the paper's tables, FillGS paired against each method), psnr_interpolation.png, psnr_extrapolation.png,
/// budget.png, time_per_phase.png.
void write_bench_report(const std::string& root, const std::vector<RunResult>& results);

/// The records of a run's refined views (SupportStats::views) as CSV (atomic), and back.
void write_refined_view_records(const std::string& path, const std::vector<RefinedViewRecord>& records);
std::vector<RefinedViewRecord> read_refined_view_records(const std::string& path);

/// The refiner's behaviour: refined-vs-truth PSNR against the parallax angle to the
/// reference, one point series per entry (a label, e.g. "seed 1", and its records), the
/// means per 5° bin of the refined images and of the renders they were given; `path`.png
/// with its .csv and .gp, and `path`.md, the binned table. Nothing is written without records.
void write_refiner_calibration(const std::string& path, const std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>>& runs,
                               const std::string& title);

/// What `fillgs run` compared, for its report.
struct RunReportInput {
  const PreparedScene* scene = nullptr;
  std::vector<RunResult> results;    ///< the backbone first, then each run
  std::vector<std::string> run_ids;  ///< the fine-tuned runs, their models under <scene dir>/runs/<id>
  FinetuneOptions finetune;          ///< their schedule
  std::string refiner = "reference";
  double artifact_strength = 0;
  std::string command;               ///< the command line, as typed
};
/// report.md and report.html into `dir`: the scene and schedule, a table of every result,
/// side-by-side renders (ground truth, backbone, each model) at the view and moment of each
/// split where the moving content covers most of the image, the bench charts, and the
/// virtual views each strategy chose.
void write_run_report(const std::string& dir, const RunReportInput& in);

}  // namespace fillgs
