#pragma once
// Fine-tuning a trained model, the whole job `fillgs finetune` and the Python module's
// `finetune` run: the model keyed for training (a network's, as dense as its motion needs),
// its colour corrections continued, the refiner made from its row, the pool loaded and
// checked, the run, the folder marked unfinished until its reports are written. Every check
// of the job's options is made here, once, in the words of the face that asks (`Spelling`):
// the command line's flags and the module's keywords get the same sentence.
#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fillgs/base/bounds.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/method/refiners.hpp"

namespace fillgs {

struct FinetuneJob {
  const Dataset* data = nullptr;  ///< the training views
  GaussianCloud model;            ///< as read (a network's model is keyed here for training)
  std::string model_path;         ///< its file: named in messages; a colour_correction.json beside it is continued
  std::string out;                ///< the folder: new or empty
  /// The schedule (iterations, select_every, trajectories), the selection, the weighting and
  /// the mask; `train` is made by the job from `rates` (fine_tune_schedule).
  FinetuneOptions options;
  MotionRates rates = MotionRates::converged_model();
  std::optional<double> refined_share;  ///< unset: the schedule's
  uint64_t seed = 1;                    ///< training, selection and the refiners' artifacts
  /// Unset: `identity`, or the pool's photographs with options.pool_budget > 0 (which takes
  /// no refiner). The refiner's knobs are in refiner_inputs (the rows' own
  /// parameters, the oracles' and the reference refiners' shared options, the truth); the job adds the training cameras, frames, seeds and pool.
  std::optional<std::string> refiner;
  RefinerInputs refiner_inputs;
  bool trajectories_given = false;  ///< options.trajectories was asked for (a pool budget takes none)
  /// The pool (a refiner that needs one, or options.pool_budget > 0): rig cameras neither
  /// trained on nor held out, read as the training views were (`images`, `cameras`,
  /// `data_options` with its cameras replaced), every frame the training views have.
  std::vector<std::string> pool_cameras;
  std::string images, cameras;
  DatasetOptions data_options;
  std::string confidence_dir;  ///< non-empty: consistency maps computed elsewhere (MaskMethod::External)
};

struct FinetuneJobResult {
  FinetuneResult result;
  FinetuneOptions options;      ///< as run (its train schedule made)
  std::string refiner;          ///< the refiner's name, or "pool"
  std::unique_ptr<Dataset> pool;  ///< the pool's views where there was one
  double seconds = 0;
};

/// Checks `job` before anything runs (the model trainable, the refiner's needs, a pool's
/// cameras and frames, the combinations), each problem one line in `spelling`'s words.
void check_finetune_job(const FinetuneJob& job, const Spelling& spelling);

/// Runs `job` (check_finetune_job first), writing the lines `fillgs finetune` prints to
/// `log`. `report` runs on the finished result before the folder stops being marked
/// unfinished (the faces write summary.json and the model there). Fine-tuning does not
/// resume: a folder holding an interrupted run, or any file, is refused.
FinetuneJobResult run_finetune_job(FinetuneJob job, const Spelling& spelling, std::ostream& log, Progress& progress,
                                   const std::function<void(const FinetuneJobResult&)>& report);

}  // namespace fillgs
