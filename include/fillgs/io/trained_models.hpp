#pragma once
// The 4D models users train with the field's codebases, read as their training code saves
// them and evaluated at any time exactly as their renderers do: E-D3DGS (the FillGS paper's
// backbone), 4DGaussians, 4D Gaussian Splatting (Yang et al.), Deformable 3D Gaussians,
// Dynamic 3D Gaussians and folders of per-frame 3DGS PLYs, each one file under
// src/io/formats/ (io/model_formats.hpp lists them).
//
// The networks and 4DGS's slice are streamed (stream_trained_model): a command evaluates
// their moving Gaussians exactly at each time it asks for; Gaussians the still rule finds
// still are evaluated once. The per-frame formats are sampled into keyframed tracks (one key
// per frame). data/README.md lists what each format needs and what is approximated.
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/math.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/model/gaussians.hpp"

namespace fillgs {

class TrainedModel {
 public:
  virtual ~TrainedModel() = default;
  virtual size_t size() const = 0;
  /// The Gaussians at model time `model_time` (the training code's own time value), every
  /// one, by the reference path: for networks, Eigen products on row-major blocks.
  virtual ModelState at(double model_time) const = 0;
  /// The Gaussians `rows` at model time `model_time`, by the fast path: networks run on
  /// feature-major blocks with the dense kernel (model/dense.hpp), what depends on the time
  /// alone computed once. `out` holds rows.size() Gaussians. Default: at(), those rows.
  virtual void evaluate(double model_time, const std::vector<uint32_t>& rows, ModelState& out) const { out = at(model_time).rows(rows); }
  /// Multiply-adds per Gaussian and frame in evaluate()'s network (0: no network).
  virtual double multiply_adds() const { return 0.0; }
  /// Whether evaluate() is a network's (moving Gaussians are worth telling from still ones).
  virtual bool has_network() const { return false; }
  /// Per Gaussian, how far its activated opacity ranges over the covered times by a term the
  /// model knows in closed form (4DGS's temporal opacity), which a sweep of frames can miss
  /// when the Gaussian lives between them; empty where the model has none. The still rule
  /// counts it as a departure.
  virtual std::vector<float> opacity_variation() const { return {}; }

  std::string format;          ///< its format's name (io/model_formats.hpp)
  std::string source;
  int frames = 0;                ///< frames the model covers
  double time_first = 0.0;       ///< model time of frame 0
  double time_last = 0.0;        ///< model time of frame frames-1
  std::vector<std::string> notes;

  /// Model time of (fractional) frame f.
  double frame_time(double f) const {
    return frames > 1 ? time_first + (time_last - time_first) * f / double(frames - 1) : time_first;
  }
};

/// Opens a trained model of format `format` (a name; "auto": detected), one whose own code
/// evaluates it at any time (a row of io/model_formats.hpp with open()).
std::unique_ptr<TrainedModel> open_trained_model(const std::string& path, const std::string& format, const SceneReadOptions& options);
/// The same for a format already resolved (read_scene resolves it once).
std::unique_ptr<TrainedModel> open_trained_model(const std::string& path, const ModelFormat& format, const SceneReadOptions& options);

/// The model sampled at each of its frames into keyframed tracks, one key per frame
/// (t_f = f / (frames - 1)); SH bands above the DC keep their mean over the frames. What
/// fillgs read trained models as before they were streamed (`--model-evaluation keys`).
/// `reference`: by at() (Eigen products), else by evaluate().
GaussianCloud sample_trained_model(const TrainedModel& model, bool reference = true, Progress& progress = null_progress());

/// A trained model as a cloud whose moving Gaussians are evaluated by the model at each time
/// asked (MotionModel::Evaluated), exactly, never stored per frame; still ones (StillRule, on
/// a sweep of the frames) are evaluated once, at frame 0, and static. `reference`: the
/// reference path (at()) instead of evaluate(). Notes say how many are still and by what rule.
GaussianCloud stream_trained_model(std::shared_ptr<const TrainedModel> model, const StillRule& rule, bool reference = false,
                                   Progress& progress = null_progress());

/// How far row j of `s` departs from row i of `first` (frame 0), as the largest share of a
/// still-rule tolerance any property reaches (> 1: moving; a zero tolerance makes any departure
/// infinite): position, log-scale, activated opacity, rotation angle, colour (every SH band).
float still_departure(const ModelState& s, size_t j, const ModelState& first, size_t i, const StillRule& rule);

/// The frames of the sweep (ascending, frame 0 and frames-1 among them).
std::vector<int> sweep_frames(int frames, int wanted);

/// The first row of `s` holding a value that is not finite (any field, any SH coefficient);
/// s.size() when every value is finite.
size_t first_not_finite(const ModelState& s);

/// A Python literal (what cfg_args holds: Namespace(key=value, ...)) as JSON; exposed for tests.
std::string python_literal_to_json(const std::string& text, const std::string& source);

}  // namespace fillgs
