#pragma once
// Training a 4D Gaussian model from multi-view video (the sparse-view backbone) and the
// optimiser fine-tuning reuses: Adam with the original 3DGS schedule, L1 + 0.2 D-SSIM,
// progressive SH, densification (clone / split / prune / opacity reset) with a cap, and
// keyframed motion for the Gaussians that need it.
//
// Static → dynamic: every Gaussian starts static (no motion parameters). The mean gradient
// of each static Gaussian is accumulated separately in `time_bins` bins of time. A static
// Gaussian is promoted to a keyframed one at a densification step when (a) its screen-space
// gradient is above the densification threshold (it is under stress) and (b) the time bins
// disagree: |Σ_b ḡ_b| < promote_agreement · Σ_b |ḡ_b| over at least two bins with
// promote_min_samples views each — no
// single position satisfies it at every time. Its keys start at its current pose. Models
// are written with partition_static_dynamic, so keys that never moved become static again.
#include <cstdint>
#include <string>
#include <vector>

#include "fillgs/camera.hpp"
#include "fillgs/progress.hpp"
#include "fillgs/train_model.hpp"

namespace fillgs {

/// One training image: a camera at a frame time.
struct TrainView {
  Camera camera;           ///< with time t = frame / (frames − 1)
  std::string image_path;  ///< resolved file
  std::string rig;         ///< camera of the rig ("cam00")
  int frame = 0;
};

struct DatasetOptions {
  /// Rig cameras to train on (names as in the camera file, e.g. "cam00"); empty: all.
  std::vector<std::string> cameras;
};

/// Multi-view video. Two layouts:
///  * cameras with times and image paths (transforms.json with `time`, fillgs synth output):
///    one view per entry; the image is looked up under the images folder by its path
///    (a leading "images/" may be dropped), then beside the camera file;
///  * a rig without times (COLMAP, transforms without `time`, ...): `images/<camera>/<frame>.png`,
///    frames sorted by name, frame f at t = f / (F − 1).
/// Every image must exist and match its camera's size. Images are cached as 8-bit RGB.
class Dataset {
 public:
  static Dataset load(const std::string& images_dir, const std::string& cameras_path, const DatasetOptions& options = {});

  const std::vector<TrainView>& views() const { return views_; }
  const std::vector<std::string>& rigs() const { return rigs_; }
  int frames() const { return frames_; }
  /// The view's image as float RGB in [0, 1] ([H][W][3]).
  std::vector<float> image(size_t view) const;
  /// Centre and radius of the camera centres ×1.1 (3DGS "cameras_extent").
  std::pair<Vec3f, float> camera_extent() const;

 private:
  std::vector<TrainView> views_;
  std::vector<std::string> rigs_;
  int frames_ = 1;
  std::vector<std::vector<uint8_t>> pixels_;
};

/// Points with colours, as SfM gives them (COLMAP points3D.txt/.bin-less text, or a .ply with
/// x, y, z and optional red, green, blue in 0..255 or 0..1).
struct PointSet {
  std::vector<Vec3f> positions;
  std::vector<Vec3f> colours;  ///< [0, 1]
};
PointSet read_points(const std::string& path);
/// Writes x, y, z, red, green, blue (0..255) as a binary PLY, atomically.
void write_points_ply(const std::string& path, const PointSet& points);

/// 3DGS initialisation: isotropic scale = √(mean squared distance to the 3 nearest
/// neighbours), identity rotation, opacity 0.1, SH DC from the colour, degree 0, all static.
ModelParams<float> init_from_points(const PointSet& points);

/// A noisy subsample of a scene's Gaussian means at one time, standing in for SfM points
/// (fraction kept, Gaussian noise of `noise` world units, colour = SH DC), seeded.
PointSet pseudo_sfm_points(const GaussianCloud& scene, double t, double fraction, double noise, uint64_t seed);

struct TrainOptions {
  int iterations = 3000;
  uint64_t seed = 1;
  int threads = 0;
  Vec3f background = Vec3f::Zero();
  double lambda_dssim = 0.2;
  int max_sh_degree = 3;
  int sh_increase_interval = 1000;  ///< raise the active SH degree every this many iterations
  // Learning rates (3DGS defaults); positions scale with the scene extent and decay
  // exponentially from init to final over `iterations`.
  double position_lr_init = 1.6e-4, position_lr_final = 1.6e-6;
  double scaling_lr = 5e-3, rotation_lr = 1e-3, opacity_lr = 0.05, feature_lr = 2.5e-3;
  // Densification (3DGS defaults for 30k iterations; scaled() adapts them).
  int densify_from = 500, densify_until = 15000, densify_interval = 100, opacity_reset_interval = 3000;
  double densify_grad_threshold = 0.0002;  ///< NDC screen-space gradient
  double percent_dense = 0.01;
  double min_opacity = 0.005;
  int max_screen_size = 20;  ///< pixels, pruning after the first opacity reset
  size_t max_gaussians = 300000;
  // Motion.
  int key_interval_frames = 3;  ///< keyframe spacing in frames (keys at t = k·spacing)
  int time_bins = 4;
  double promote_agreement = 0.3;
  int promote_min_samples = 3;  ///< views per time bin before a bin counts
  bool allow_dynamic = true;
  int checkpoint_interval = 0;  ///< 0: only at the end
  /// Fine-tuning: probability that an iteration trains on a refined view (once any were
  /// added) instead of a real one. Refined views would otherwise outnumber real ones on a
  /// sparse rig (20 trajectories × 9 views against 2 cameras × 30 frames).
  double refined_share = 0.3;
  /// The 3DGS schedule (defined for 30,000 iterations) scaled to `iterations`.
  static TrainOptions scaled(int iterations);
};

struct TrainStatus {
  int iteration = 0;
  double loss = 0, psnr = 0;  ///< exponential moving averages over recent iterations
  size_t gaussians = 0, dynamic = 0;
  double iterations_per_second = 0;
};

/// A refined (generated) view for fine-tuning: its camera (with time), image and per-pixel
/// loss weights (METHOD.md §7: the loss on it is weight × photometric error).
struct RefinedView {
  Camera camera;
  std::vector<float> rgb;     ///< [H][W][3] in [0, 1]
  std::vector<float> weight;  ///< [H][W]
};

class Trainer {
 public:
  Trainer(const Dataset& data, ModelParams<float> initial, const TrainOptions& options);
  /// Continues from a checkpoint written by save_checkpoint (same dataset and options).
  static Trainer resume(const Dataset& data, const std::string& checkpoint, const TrainOptions& options);

  /// One iteration (view choice, forward, loss, backward, Adam, densification).
  void step();
  /// Steps until `iteration() == until`, reporting progress and status.
  void run(int until, Progress& progress);

  /// Adds refined views; from now on an iteration picks one of them with probability
  /// options.refined_share. Not stored in checkpoints.
  void add_refined(std::vector<RefinedView> views);
  size_t refined_count() const { return refined_.size(); }

  void save_checkpoint(const std::string& path) const;
  int iteration() const { return iteration_; }
  const ModelParams<float>& params() const { return params_; }
  TrainStatus status() const { return status_; }
  /// Loss of every iteration so far (for plots).
  const std::vector<float>& loss_history() const { return loss_history_; }
  /// The trained model as a cloud (keys that never moved folded back into static Gaussians).
  GaussianCloud model() const;

 private:
  void adam_step();
  void densify_and_prune(bool prune_big);
  void promote_static();
  void raise_sh_degree();
  void reset_opacity();
  void reset_stats();
  size_t pick_view() const;

  const Dataset* data_;
  TrainOptions options_;
  ModelParams<float> params_, grad_, adam_m_, adam_v_;
  int iteration_ = 0;
  float extent_ = 1.0f;
  // Densification statistics, per Gaussian.
  std::vector<float> grad_accum_, max_radii_;
  std::vector<uint32_t> denom_;
  std::vector<float> bin_grad_;       // [N][bins][3]
  std::vector<uint32_t> bin_count_;   // [N][bins]
  bool opacity_was_reset_ = false;
  TrainStatus status_;
  std::vector<float> loss_history_;
  std::vector<RefinedView> refined_;
};

/// PSNR and SSIM of a model against every view of a dataset (optionally every k-th).
struct EvalResult {
  double psnr = 0, ssim = 0;
  size_t views = 0;
};
EvalResult evaluate_views(const GaussianCloud& model, const Dataset& data, int stride = 1, const Vec3f& background = Vec3f::Zero(),
                          int threads = 0);

}  // namespace fillgs
