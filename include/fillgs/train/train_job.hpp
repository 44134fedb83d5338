#pragma once
// Training a 4D model from multi-view video, the whole job `fillgs train` runs: the initial
// points (a file, or made from the views), the folder's old results removed, the run in
// checkpointed pieces (resumable), the model written in the rig's mean camera's colours with
// its colour corrections. The command line only parses flags for it.
#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/progress.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/train/init.hpp"
#include "fillgs/train/train.hpp"

namespace fillgs {

/// Where the initial Gaussians come from.
enum class InitSource { Points, Random, RandomAndCarve };
FILLGS_ENUM_NAMES(InitSource, "initialisation", {InitSource::Points, "points"}, {InitSource::Random, "random"},
                  {InitSource::RandomAndCarve, "random+carve"});

struct TrainJob {
  const Dataset* data = nullptr;
  std::string out;         ///< model.ply, frame0_3dgs.ply, colour_correction.json, init_points.ply, checkpoints/
  TrainOptions options;    ///< its schedule for `iterations`; checkpoint_interval > 0
  int iterations = 3000;
  /// How the caller names `iterations` in its messages ("--iterations" on the command line).
  std::string iterations_name = "iterations";
  std::string resume;      ///< a checkpoint to continue ("" : a new run)
  /// Initial points: `points` (a PLY or COLMAP file) for InitSource::Points; the views'
  /// random points (and the masks' visual hull) otherwise, written as init_points.ply.
  InitSource init = InitSource::RandomAndCarve;
  std::string points;
  ViewInitOptions view_init;
};

struct TrainJobResult {
  GaussianCloud model;                       ///< as written (the mean camera's colours)
  std::vector<ColourCorrection> corrections;  ///< per rig camera, relative to the mean camera (empty: off)
  ColourCorrection mean;                      ///< the mean camera in the first camera's colours
  double seconds_train = 0;
};

/// Runs `job`, writing the progress lines `fillgs train` prints to `log`. `report` runs on
/// the finished trainer and model before the folder stops being marked unfinished (the CLI
/// writes its summary there). Bad input (a checkpoint past `iterations`, points beyond what
/// training keeps finite, masks asked for without any) throws before anything is written.
TrainJobResult run_train_job(const TrainJob& job, std::ostream& log, Progress& progress,
                             const std::function<void(const Trainer&, const GaussianCloud&, double seconds)>& report = {});

}  // namespace fillgs
