#pragma once
#include "fillgs/base/progress.hpp"
// Reading a scene or model of any format fillgs reads (the formats are rows of one table,
// io/model_formats.hpp, one file each under src/io/formats/), and the writers: standard
// 3DGS PLY and the fillgs 4D PLY (baked tracks, documented in data/README.md).
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/base/row_table.hpp"
#include "fillgs/model/gaussians.hpp"

namespace fillgs {

/// Trained models' static rule (io/trained_models.hpp): a Gaussian is still when, at every frame of the sweep (and at every
/// frame of the model where the sweep saw it near a tolerance), its state stays within these of its state at frame 0.
struct StillRule {
  float position = 1e-3f;         ///< distance, world units
  float rotation_degrees = 1.0f;  ///< angle of the normalised rotation
  float log_scale = 0.01f;        ///< any axis (1 %)
  float opacity = 1.0f / 255.0f;  ///< activated opacity, temporal factor included (4DGS: its whole range over the covered times, in closed form)
  float colour = 1.0f / 255.0f;   ///< colour in any direction, any channel: every SH band, sum_k |change_k| max|Y_k| (model/sh.hpp)
  int sweep_frames = 30;          ///< frames the sweep samples, evenly, frame 0 and the last among them (>= frames: all)
  /// A Gaussian the sweep finds still whose largest departure there exceeds this share of a
  /// tolerance is checked at every frame (motion between the sweep's frames); 1: none are.
  /// 0.5: a motion up to twice what the sweep's frames saw is caught (bench/results/README.md,
  /// "Trained models at scale", measures the trade).
  float recheck = 0.5f;
  /// The normalised times a job will evaluate, where it knows them before reading (observe
  /// with --frames or --times). Fewer than the sweep's frames: the rule checks exactly these
  /// (against frame 0) and no others, so a Gaussian is still where it stays within every
  /// tolerance at every time the job asks for. Empty: the sweep.
  std::vector<double> times;
};

/// How a trained model is read: streamed (its moving Gaussians evaluated by the model at each
/// time a command asks for, exactly) or as keys at each of its frames (the whole video in
/// memory, interpolated between frames).
enum class ModelEvaluation { Streamed, Keys };
FILLGS_ENUM_NAMES(ModelEvaluation, "model evaluation", {ModelEvaluation::Streamed, "streamed"}, {ModelEvaluation::Keys, "keys"});
/// The networks' evaluation: the dense kernel on feature-major blocks, or Eigen products on
/// row-major blocks (the reference).
enum class NetworkKernel { Simd, Eigen };
FILLGS_ENUM_NAMES(NetworkKernel, "network kernel", {NetworkKernel::Simd, "simd"}, {NetworkKernel::Eigen, "eigen"});

struct SceneReadOptions {
  /// A format's name or alias (io/model_formats.hpp), or "auto": detected from the path.
  std::string format = "auto";
  /// The values given for the formats' own parameters (each declared in its format's row,
  /// io/model_formats.hpp: Spacetime Gaussians' stg_duration and stg_color, Ex4DGS's
  /// ex4dgs_duration, ex4dgs_interval and ex4dgs_pad); a parameter not given is its default.
  RowParameterValues parameters;
  /// Trained 4D models (E-D3DGS, 4DGaussians, 4DGS): frames the model covers (0: from its
  /// files: E-D3DGS's cfg_args), the model-time range they span ("T0:T1"; frame f at
  /// T0 + f (T1 - T0) / F; empty: 0:1), E-D3DGS's camera whose time offset to use (-1: the
  /// mean, as its renderer at test views) and the iteration its coarse-to-fine schedule is at
  /// (-1: the saved one).
  int model_frames = 0;
  std::string model_time_range;
  int model_camera = -1;
  int model_iteration = -1;
  ModelEvaluation model_evaluation = ModelEvaluation::Streamed;
  NetworkKernel network_kernel = NetworkKernel::Simd;
  StillRule still;
  PartitionOptions partition;
  /// Where a trained model's walk over its frames (the still rule's sweep, or its keys) is
  /// reported; not owned (null: nowhere).
  Progress* progress = nullptr;
};

/// Reads a scene, detecting the format from the path and header unless told.
/// Throws fillgs::Error with one line naming the file and element on bad input.
GaussianCloud read_scene(const std::string& path, const SceneReadOptions& options = {});

/// The name of the format a path holds (a file or a folder); one line naming the path when
/// no format fillgs reads holds it.
std::string detect_scene_format(const std::string& path);

/// Writes a standard 3DGS PLY of the scene at time t (62 floats at degree 3; opens in
/// common splat viewers). Values are stored raw (logits, log-scales), like 3DGS.
void write_3dgs_ply(const std::string& path, const GaussianCloud& cloud, double t = 0.0);

/// Samples any motion model into the fillgs convention: one key per frame,
/// t_f = f / (frames - 1), Catmull-Rom positions, shortest-arc slerp rotations, and
/// per-key opacities where opacity changes in time. A network's model gets per-key log-scales
/// and SH DC, and with `keyed_bands` its higher SH bands per key too (KeyframedMotion::sh_rest;
/// (C - 1) × 3 more floats per Gaussian and key); a keyed cloud keeps the bands it keys.
GaussianCloud bake_tracks(const GaussianCloud& cloud, int frames, bool keyed_bands = false);

/// How close the keys a network's model is given for training (choose_keys) must stay to the
/// network at every frame: each property the keys carry, with the still rule's tolerances.
struct KeyTolerance {
  float position = 1e-3f;         ///< world units
  float rotation_degrees = 1.0f;  ///< angle of the normalised rotation
  float log_scale = 0.01f;        ///< any axis (1 %)
  float opacity = 1.0f / 255.0f;  ///< activated opacity, temporal factor included
  float colour = 1.0f / 255.0f;   ///< largest colour change in any direction and channel, every SH band (sh_colour_change)
};

/// The keys a model evaluated by its network (MotionModel::Evaluated) needs where a command
/// trains fillgs's own keyed model: the fewest, K keys at t = k / (K - 1), whose Catmull-Rom
/// positions, slerped rotations and interpolated log-scales, opacities and colours (the SH DC,
/// and every band where the higher bands change beyond the colour tolerance) stay within the
/// tolerances of the network at every frame, measured on up to `sample` moving Gaussians
/// (evenly spread over them); intervals tried: 1, 2, 4, ... 32 frames (at most 32: no interval
/// is chosen on fewer than 8 keys' evidence).
struct KeyChoice {
  int keys = 0;             ///< K
  double interval = 1.0;    ///< frames between keys, (frames - 1) / (K - 1)
  double worst_error = 0;   ///< largest position error at a frame over the sample, world units
  double worst_share = 0;   ///< largest error of any property, as a share of its tolerance (<= 1 but where interval 1 cannot reach it)
  std::string limiting;     ///< the property whose error stopped a longer interval ("" where 32 frames fit)
  double colour_change = 0; ///< largest change of the network's colour over the frames from frame 0's, any direction and channel
  bool keyed_bands = false; ///< the higher SH bands are keyed too (they change beyond the colour tolerance)
  size_t sample = 0;        ///< Gaussians measured
  int frames = 0;
};
KeyChoice choose_keys(const GaussianCloud& cloud, const KeyTolerance& tolerance = {}, size_t sample = 2000);

/// The cloud with keys: evaluated motion baked to choose_keys()'s K keys (what `finetune`
/// trains), any other cloud as it is. `choice` gets what was chosen (keys 0: nothing baked).
GaussianCloud keyed_for_training(const GaussianCloud& cloud, KeyChoice* choice = nullptr, const KeyTolerance& tolerance = {});

/// Writes the fillgs 4D PLY. Keyframed clouds in the fillgs convention are written as they
/// are; other motion is baked to `frames` keys first (frames >= 2 required then).
/// Static Gaussians come first in the file, then the dynamic ones, row for row with the
/// `track` element.
void write_fillgs_ply(const std::string& path, const GaussianCloud& cloud, int frames = 0);

}  // namespace fillgs
