#pragma once
// Fine-tuning with refined virtual views (the paper, Sec. 3.5 and Appendix A): continue training the 4D model
// on its real views; every `select_every` iterations select `trajectories` new ones with a
// strategy, export their patches, refine them, weight every refined view and add it.
//
// Defaults are scaled down from the paper's (30,000 iterations, 20 trajectories every
// 6,000) to a laptop CPU: 1,200 iterations, 5 trajectories every 400 (3 rounds, 15
// trajectories). `FinetuneOptions::paper()` gives the paper's schedule.
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/method/refine.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/method/weights.hpp"

namespace fillgs {

struct FinetuneOptions {
  int iterations = 2400;
  int select_every = 800;     ///< M: a selection round at iterations 0, M, 2M, ... (< iterations)
  int trajectories = 5;       ///< K per round
  SelectOptions select;       ///< strategy and its knobs (trajectories is overridden by K)
  Weighting weighting = Weighting::FillGS;
  MaskOptions mask;
  ExplorationOptions grid;
  TrainOptions train;         ///< see fine_tune_schedule
  std::string work_dir;       ///< patches/, refined/ (with masks and weights) per round
  /// Views with their weights added before the first iteration, beside any selected ones
  /// (the upper bound upper.test-views: ground truth at the test cameras).
  std::vector<RefinedView> extra_views;
  /// Real camera-times instead of refined virtual views: with a pool, every round chooses
  /// its share of `pool_budget` (spread evenly over the rounds) among the pool's views not
  /// chosen yet, by the strategy's own score (select_from_pool), and adds each chosen
  /// photograph at its real pose, weighted by `weighting` (none: weight 1). The refiner is
  /// not used. The pool's cameras carry their times; its frame count must be the video's.
  const RigPool* pool = nullptr;
  int pool_budget = 0;
  /// A round whose every patch the refiner failed on (a missing program, one that exits 0
  /// and writes nothing) ends the fine-tuning with an Error naming the first failure, unless
  /// this is set: then the run goes on, each failure a warning.
  bool allow_failed_refinement = false;
  /// Paper: 30,000 iterations, 20 trajectories every 6,000.
  static FinetuneOptions paper();
};

/// How fast fine-tuning moves Gaussians: the initial position learning rate (× the scene
/// extent, decaying to a tenth of it over the run), the keys' rate as a multiple of it, and
/// whether the model is converged.
///  * `repair` (MotionRates{}): training's initial rate with keys ×10, the other rates
///    3DGS's, densification over the first 60 %: what repairing motion from new views takes on
///    fillgs's own 3,000-iteration backbones (with it the upper bound upper.test-views comes
///    within 0.6 / 1.6 dB of the dense model's moving-region PSNR; bench/results/README.md,
///    "The comparison"). The benchmark's setting.
///  * `gentle()`: as repair, positions at training's final rate ×10, keys ×3.
///  * `converged_model()`: a model trained to convergence (a user's E-D3DGS or 4DGaussians
///    model, or any model fillgs reads): every rate at kConvergedRate = 1/300 of 3DGS's
///    initial one (positions 5.3e-7, a third of 3DGS's final rate; keys ×1; SH, opacity, scale
///    and rotation likewise), sparse Adam (TrainOptions::sparse_adam), no densification, and
///    the model's own moving / static partition kept (`promote` with no densification step,
///    so no static Gaussian gains keys). Why so small: at convergence the photometric gradient
///    is residual noise, and Adam moves every value by about its rate per step whatever the
///    gradient's size. tests/test_keep_model.cpp measures 600 iterations with no generated
///    views on the E-D3DGS and 4DGaussians fixtures rendered by the model itself (~60 dB;
///    `bin/fillgs_model_tests "[keep-model]" -s` prints the figures): held-out PSNR falls by
///    0.04 and 0.40 dB, and by 42 and 30 dB at the benchmark's repair rates. The trade: a value
///    moves 300× more slowly than at 3DGS's rates (over the paper's 30,000 iterations, by up to
///    100 × 3DGS's per-step rate: SH DC 0.25, opacity 5 logits).
constexpr double kConvergedRate = 1.0 / 300.0;
struct MotionRates {
  double position_lr = 1.6e-4;
  double key_lr_scale = 10.0;
  bool converged = false;
  static MotionRates gentle() { return {1.6e-5, 3.0, false}; }
  static MotionRates converged_model() { return {1.6e-4 * kConvergedRate, 1.0, true}; }
};

/// The presets by name (`--motion-rates`, the module's `motion_rates`).
enum class RatePreset { Repair, Gentle, Converged };
FILLGS_ENUM_NAMES(RatePreset, "motion rates", {RatePreset::Repair, "repair"}, {RatePreset::Gentle, "gentle"}, {RatePreset::Converged, "converged"});
MotionRates motion_rates_of(RatePreset preset);

/// The training schedule for fine-tuning a trained model for `iterations`: the 3DGS one
/// scaled, positions and keys at `rates`, no opacity reset (it would erase the trained
/// model), no time curriculum; densification over the first 60 % unless the rates are a
/// converged model's (see MotionRates).
TrainOptions fine_tune_schedule(int iterations, const MotionRates& rates = {});

struct FinetuneRound {
  int iteration = 0;
  int trajectories = 0;
  size_t views_added = 0;
  size_t views_dropped = 0;  ///< virtual views the refiner left out (the rig refiner: no pool camera in tolerance)
  std::vector<std::pair<int, std::string>> refine_failures;
  double seconds_select = 0, seconds_render = 0, seconds_refine = 0, seconds_weights = 0;
  std::vector<std::string> notes;
  double mean_weight = 0;  ///< mean per-pixel weight of the added views
};

/// One pool view a round chose (FinetuneOptions::pool).
struct PoolPick {
  size_t view = 0;   ///< index into RigPool::cameras
  double score = 0;  ///< the strategy's score when chosen
  int round = 0;
};

struct FinetuneResult {
  GaussianCloud model;
  std::vector<FinetuneRound> rounds;
  std::vector<Camera> virtual_views;  ///< every refined view (or chosen pool photograph) added, in order
  std::vector<PoolPick> pool_chosen;  ///< the pool views chosen, in order
  double seconds_train = 0, seconds_total = 0;
  std::vector<float> loss_history;
  KeyChoice keys;  ///< a model evaluated by its network: the keys it was given to train (keys 0: none)
  /// With FinetuneOptions::train.colour_correction: per training camera its correction,
  /// relative to the rig's mean camera, whose colours `model` is written in (fold_mean_colour).
  std::vector<ColourCorrection> colour_correction;
};

/// Fine-tunes `model` (trained on `data`) with views refined by `refiner`.
FinetuneResult finetune(const Dataset& data, const GaussianCloud& model, Refiner& refiner, const FinetuneOptions& options,
                        Progress& progress = null_progress());

}  // namespace fillgs
