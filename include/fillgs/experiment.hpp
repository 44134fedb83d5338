#pragma once
// The paper's comparison on synthetic scenes (what `fillgs bench` and `fillgs run` run):
// a scene variant is rendered, a backbone is trained on 2 of its cameras, and every
// configuration (a selection strategy or ablation, a weighting, an oracle refiner with or
// without artifacts, a budget) fine-tunes that backbone and is evaluated on the
// interpolation and extrapolation cameras. Everything lands in a folder and is reused:
// an interrupted benchmark continues where it stopped.
//
// Layout: <root>/<variant>_s<seed>/scene/ (synth), backbone/ (model.ply, summary.json),
// runs/<config id>/ (work folders, model.ply, result.json).
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/evaluate.hpp"
#include "fillgs/finetune.hpp"
#include "fillgs/synth.hpp"
#include "fillgs/train.hpp"

namespace fillgs {

struct ExperimentOptions {
  std::string variant = "chair";
  uint64_t seed = 1;
  int width = 160, height = 120, frames = 20;
  std::vector<std::string> train_cameras = {"cam04", "cam06"};
  /// Between the two training cameras (same ring) / outside their arc (the neighbouring
  /// ring cameras and the raised, closer camera above the arc).
  std::vector<std::string> interpolation_cameras = {"interp04", "interp05"};
  std::vector<std::string> extrapolation_cameras = {"cam03", "cam07", "extrap02"};
  int backbone_iterations = 2000;
  int threads = 0;
};

struct PreparedScene {
  SynthScene synth;
  std::string dir;  ///< <root>/<variant>_s<seed>
  std::unique_ptr<Dataset> train, interpolation, extrapolation;
  GaussianCloud backbone;
  double seconds_synth = 0, seconds_backbone = 0;  ///< 0 when reused
  bool reused_scene = false, reused_backbone = false;
};

/// Renders the scene and trains the backbone, or reuses what an earlier run left (checked
/// against the options it was made with).
PreparedScene prepare_scene(const std::string& root, const ExperimentOptions& options, Progress& progress, std::ostream& log);

/// One fine-tuning configuration.
struct RunConfig {
  std::string id;           ///< folder name and table row, e.g. "fillgs", "random", "fillgs.no-global"
  std::string group;        ///< "strategy", "ablation", "weighting", "budget", "refiner", "control"
  SelectOptions select;     ///< strategy and ablation flags
  Weighting weighting = Weighting::FillGS;
  MaskOptions mask;
  double artifact_strength = 0.5;  ///< oracle artifacts (0: clean ground truth)
  int trajectories = 5;     ///< per round; 0: fine-tune on the real views only (the control)
};

/// The paper's comparison: the control (no refined views), every strategy (FillGS with its
/// weights, baselines with `baseline_weighting`, the paper's protocol: ExploreGS), FillGS's
/// selection ablations, weighting ablations, budgets 1/5/10/20, the clean oracle.
std::vector<RunConfig> standard_configs(Weighting baseline_weighting = Weighting::ExploreGS, double artifact_strength = 0.5);

struct RunResult {
  std::string id, group, variant;
  uint64_t seed = 0;
  SplitMetrics interpolation, extrapolation, train;
  int trajectories = 0;
  size_t views_added = 0;
  double mean_weight = 0;
  double seconds_select = 0, seconds_refine = 0, seconds_weights = 0, seconds_train = 0, seconds_eval = 0, seconds_total = 0;
  int refine_failures = 0;
};

/// Evaluates a model on the prepared scene's splits (moving region from the ground truth).
RunResult evaluate_model(const PreparedScene& scene, const GaussianCloud& model, const std::string& id, int threads,
                         const std::string& save_dir = "", Progress& progress = null_progress());

/// Fine-tunes the backbone with `config` (oracle refiner), evaluates, writes
/// <scene.dir>/runs/<id>/result.json; returns the stored result when it exists already.
RunResult run_config(const PreparedScene& scene, const RunConfig& config, const FinetuneOptions& base, Progress& progress,
                     std::ostream& log);

/// A result as JSON on disk (atomic) and back.
void save_result(const std::string& path, const RunResult& result);
RunResult load_result(const std::string& path);

/// Every result stored under a benchmark root: <variant>_s<seed>/backbone/result.json and
/// <variant>_s<seed>/runs/*/result.json, sorted by scene then configuration order of
/// standard_configs (backbone first).
std::vector<RunResult> collect_results(const std::string& root);

/// results.csv (every run), results.md (means over scenes and seeds, shaped like the
/// paper's tables), psnr_per_strategy.png, budget.png, time_per_phase.png.
void write_bench_report(const std::string& root, const std::vector<RunResult>& results);

}  // namespace fillgs
