#pragma once
// The refiners fillgs drives, one table (base/row_table.hpp): each is one file under src/method/refiners/ that
// defines its row (its fields named: name, what it needs, make(inputs), identity(inputs)), and
// the build collects every file there into the table (CMakeLists.txt, src/row_table.cpp.in).
// The fine-tuning job (`fillgs finetune`, the module's `finetune`) and the benchmark's runs
// make refiners here; adding a refiner is adding its file (and its test).
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fillgs/base/row_table.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/method/refine.hpp"

namespace fillgs {

/// What a refiner may be made from; a row says which it needs (make_refiner checks).
struct RefinerInputs {
  const GaussianCloud* truth = nullptr;  ///< the ground-truth scene (synthetic data)
  std::vector<Camera> observers;         ///< the training cameras, with their times (the oracle's support)
  int frames = 0;                        ///< the video's frame count
  const RigPool* pool = nullptr;         ///< a rig's pool cameras and their photographs
  /// The values given for the refiners' own parameters (each declared in its row: the
  /// external program's refiner_command and refiner_timeout, the rig's rig_max_distance and
  /// rig_max_angle).
  RowParameterValues parameters;
  OracleOptions oracle;                  ///< the oracles' artifacts, window and background (the row sets the support)
  ReferenceOptions reference;            ///< the reference-conditioned refiners' parameters
  SupportStats* stats = nullptr;         ///< where the oracles and the reference-conditioned refiners record what they restored
};

/// The heading's name is what --refiner takes, its description what it restores (help,
/// reports), its order the listing's (base/row_table.hpp).
struct RefinerKind : RowHeading {
  bool needs_truth = false;    ///< a synthetic scene's ground truth
  bool needs_pool = false;     ///< a rig's pool cameras
  /// Made from the truth and the training cameras alone, so the benchmark (synthetic scenes)
  /// can run it.
  bool benchmark = false;
  /// The benchmark calibrated it before any strategy ran with it (its calibration rows).
  bool calibrated = false;
  /// Where it needs the truth: the refiner to name for real data instead ("" : none).
  std::string on_real_data;
  std::function<std::unique_ptr<Refiner>(const RefinerInputs&)> make;
  /// What of the inputs decides its output, as JSON: a benchmark run's identity
  /// (experiment/identity.hpp).
  std::function<nlohmann::json(const RefinerInputs&)> identity;
};

/// Completes `inputs` for a run on `data` with `seed`: the training cameras as observers, the
/// video's frame count, and the artifacts' seed (the reference refiners' strength is the
/// oracle's). The fine-tuning job and the benchmark's runs both make their refiners so.
void complete_refiner_inputs(RefinerInputs& inputs, const Dataset& data, uint64_t seed);

/// What of a refiner's options decides its output, as JSON: a benchmark run's identity
/// (experiment/identity.hpp), kept beside the refiners that read them.
nlohmann::json identity_json(const ArtifactOptions& o);
nlohmann::json identity_json(const ReferenceOptions& o);  ///< with "name": "reference"

/// The table of refiners.
const RowTable<RefinerKind>& refiner_table();
/// Every refiner, in listing order.
const std::vector<const RefinerKind*>& refiner_kinds();
/// The refiner of that name; one line listing the names otherwise.
const RefinerKind& refiner_kind(const std::string& name);
/// "a, b or c": the refiners' names (only the benchmark's with `benchmark_only`).
std::string refiner_names(bool benchmark_only = false);
/// The refiner `name` made from `inputs`; one line naming what it needs and lacks.
std::unique_ptr<Refiner> make_refiner(const std::string& name, const RefinerInputs& inputs);

}  // namespace fillgs
