#pragma once
// What the commands write beside their results, as library calls (like observe_to_directory):
// the exploration grid's files, a selection's trajectories, renders, priorities and
// pictures, and the training and fine-tuning summaries. The front end only binds flags to
// options, calls these and prints what they return.
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/method/finetune_job.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/train/train.hpp"

namespace fillgs {

/// loss.png: the loss history (at most 400 points, every k-th) under `title`.
void write_loss_png(const std::string& path, const std::vector<float>& history, const std::string& title);

/// `fillgs eval`: metrics.json, one entry per split (by its name) with views, PSNR, SSIM,
/// the moving region's PSNR and pixels, LPIPS and the least-squares-gain PSNR (null where
/// not measured).
void write_metrics_json(const std::string& path, const std::vector<SplitMetrics>& splits);

/// The exploration grid's summary (box, divisions, voxel size, step, label counts; with
/// `stats` the build's statistics) as summary.json holds it.
nlohmann::json exploration_summary(const ExplorationGrid& grid, const ExplorationStats* stats);

/// `fillgs explore`: exploration.vdb, exploration.png (top view with the cameras) and
/// summary.json into `dir`.
void write_exploration(const std::string& dir, const ExplorationGrid& grid, const std::vector<Camera>& cameras, const ExplorationStats& stats,
                       double seconds);

struct SelectionReportOptions {
  bool renders = true;             ///< renders/<view>.png and renders/<view>_D.png
  const ExplorationStats* grid_stats = nullptr;  ///< the grid's build statistics, when built here
  double grid_seconds = 0;
  Clock::time_point started = Clock::now();  ///< when the command began (summary.json's total)
};
struct SelectionReport {
  size_t virtual_views = 0;
  double mean_selected_deficiency = 0;  ///< mean rendered D̂ over the virtual views (renders only)
};
/// `fillgs select`: into `dir`, trajectories.json (every pose with its score and start),
/// transforms.json and colmap/ (the virtual views, images renders/<name>.png), the renders
/// of every virtual view (RGB and the initial D̂), priority_{E,L,V,V_time}.npy [pose][frame]
/// (NaN where not evaluated) with the priority heatmap and bar charts, trajectories.png (top
/// view) and summary.json. `cameras` are the training views' cameras.
SelectionReport write_selection(const std::string& dir, const SelectInput& in, const SelectOptions& options, const SelectResult& result,
                                const ExplorationGrid& grid, const std::vector<Camera>& cameras, const SelectionReportOptions& report,
                                Progress& progress = null_progress());

struct TrainingReport {
  SplitMetrics train;  ///< on a sample of the training views (evaluate_training_sample)
  SplitMetrics test;   ///< on the test split, when there is one (views 0 otherwise)
  size_t peak_memory_bytes = 0;
};
/// `fillgs train`: summary.json (counts, the motion settings, the densification log, train
/// and test metrics, memory) and loss.png into `dir`.
TrainingReport write_training_report(const std::string& dir, const Trainer& trainer, const GaussianCloud& model, const Dataset& data,
                                     const TrainOptions& options, const Dataset* test, double seconds);

struct FinetuneReport {
  SplitMetrics train;
  size_t dropped = 0;  ///< virtual views the refiner dropped
};
/// `fillgs finetune`: model.ply, virtual_views.json, loss.png and summary.json (the rounds
/// with their timings and refiner failures) into `dir`.
FinetuneReport write_finetune_report(const std::string& dir, const FinetuneResult& result, const Dataset& data, const FinetuneOptions& options,
                                     const std::string& refiner, double seconds);
/// With a pool (FinetuneOptions::pool; `pool` the Dataset its views came from, in the same
/// order): pool_chosen.json (every chosen photograph: camera, frame, score, round) and
/// pool_chosen.png, the camera × frame picture of what was chosen (the round it was chosen
/// in + 1; 0: not chosen), rows in the pool's camera order.
void write_pool_report(const std::string& dir, const FinetuneResult& result, const Dataset& pool, const std::string& strategy);
/// What a finished fine-tuning job writes into `dir` (every face's): write_finetune_report,
/// and write_pool_report where it chose pool photographs.
FinetuneReport write_finetune_job_report(const std::string& dir, const FinetuneJobResult& result, const Dataset& data);

}  // namespace fillgs
