#pragma once
// Training a 4D Gaussian model from multi-view video (the sparse-view backbone) and the
// optimiser fine-tuning reuses: Adam with the original 3DGS schedule, L1 + 0.2 D-SSIM,
// progressive SH, densification (clone / split / prune / opacity reset) with a cap, and
// keyframed motion for the Gaussians that need it.
//
// Motion (MotionLearning):
//  * `all` (default): every Gaussian carries keys while it trains — positions, rotations and,
//    with keyed_opacity, opacities — so anything can move from the first iteration on. Motion
//    is kept only where the images show it (motion_where_images_change): at every
//    densification step keyed Gaussians that never landed on a changing pixel are made
//    static, and the written model folds the remaining ones whose keys stay within
//    still_distance / `still` into static Gaussians (fold_still_keys, then
//    partition_static_dynamic): the output carries no motion for what does not move. An
//    optional L1 prior on key-to-key steps (motion_sparsity, off by default) pulls still
//    keys together during training.
//  * `promote` (the earlier behaviour): every Gaussian starts static. The mean gradient of
//    each static Gaussian is accumulated in `time_bins` bins of time; a static Gaussian
//    becomes keyframed at a densification step when its screen-space gradient is above the
//    densification threshold and the bins disagree, |Σ_b ḡ_b| < promote_agreement · Σ_b |ḡ_b|
//    over at least two bins with promote_min_samples views each. Its keys start at its pose.
// Time curriculum (time_ramp > 0): the trained window of frames grows from frame 0 to the
// whole video over the first time_ramp of the iterations, frontier_share of the iterations
// drawing one of its newest frontier_frames frames; whenever the window enters a new key
// interval, the keys beyond it are continued at constant velocity (extrapolate_keys), so a
// Gaussian that tracks its content up to now starts the next interval where the content
// goes. Key position learning rates stay at their initial value until the ramp ends, then
// decay like the position one.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/train/train_model.hpp"

namespace fillgs {

/// Points with colours, as SfM gives them (COLMAP points3D.txt or points3D.bin, or a .ply
/// with x, y, z and optional red, green, blue in 0..255 or 0..1).
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
/// (fraction kept, Gaussian noise of `noise` world units, colour = SH DC), seeded. With
/// `observers`, only Gaussians that at least `min_views` of them observe at time t (exact
/// visibility: largest α·T ≥ 1/255) — what SfM can triangulate from those images.
PointSet pseudo_sfm_points(const GaussianCloud& scene, double t, double fraction, double noise, uint64_t seed,
                           const std::vector<Camera>& observers = {}, int min_views = 2);

/// How a model learns motion (see above).
enum class MotionLearning { All, Promote };
FILLGS_ENUM_NAMES(MotionLearning, "motion learning", {MotionLearning::All, "all"}, {MotionLearning::Promote, "promote"});

/// What training keeps finite: positions within 1e7 world units, log-scales in [-30, 20],
/// SH coefficients within 1e4 (a model beyond these turns into inf and NaN under the
/// optimiser's steps).
constexpr double kMaxTrainCoordinate = 1e7, kMinTrainLogScale = -30, kMaxTrainLogScale = 20, kMaxTrainSh = 1e4;

/// Throws one line naming `source`, the Gaussian and the value when `cloud` holds a value
/// outside those bounds; train and finetune call it on what they read.
void check_trainable(const GaussianCloud& cloud, const std::string& source);

/// A rig camera's learned colour correction: its real images ≈ gain ⊙ render + offset.
struct ColourCorrection {
  std::string rig;
  Vec3f gain = Vec3f::Ones(), offset = Vec3f::Zero();
};

struct TrainOptions {
  int iterations = 3000;
  uint64_t seed = 1;
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
  bool allow_dynamic = true;    ///< false: a static model (no keys at all)
  MotionLearning motion = MotionLearning::All;
  int key_interval_frames = 3;  ///< keyframe spacing in frames (keys at t = k·spacing)
  bool keyed_opacity = true;    ///< an opacity logit per key for moving Gaussians
  double time_ramp = 0.7;       ///< fraction of the iterations over which the time window grows (0: none)
  double frontier_share = 0.5;  ///< while it grows: share of iterations on its newest frames
  double densify_after_ramp = 0.1;  ///< densification goes on at least this fraction of the iterations after the ramp
  int frontier_frames = 2;
  double key_lr_scale = 3.0;    ///< key position learning rate / position learning rate
  double extrapolate_min_step = 0.5;  ///< keys continue a motion only of at least this × the Gaussian's size per key
  double freeze_distance = 0.0; ///< `all`: at the end of the ramp, Gaussians whose keys stayed within this × their size become static (0: never)
  /// Motion only where the images change: for a fixed camera of the rig, a pixel changes when
  /// some channel varies by more than change_threshold over the frames (dilated by
  /// change_dilation pixels). A Gaussian earns motion once its mean falls on a changing pixel
  /// of a view that renders it; at every densification step the keyed Gaussians that have not
  /// are made static, and only those that have may be promoted. Off, or a dataset without a
  /// fixed camera over 3 or more frames: any Gaussian may move.
  bool motion_where_images_change = true;
  double change_threshold = 0.1;
  int change_dilation = 2;
  /// With foreground masks (Dataset::has_masks), a camera's changing pixels are the union
  /// over its frames of its foreground masks instead of its colour changes: motion only
  /// where the masks put the movers (objects the masks leave out, e.g. a thrown ball, stay
  /// static). Off by default; a dataset without masks keeps the colour rule (`fillgs train
  /// --motion-from-masks` refuses one).
  bool change_from_masks = false;
  /// Keys where the images say the content goes: whenever the time window enters a new key
  /// interval, the next two keys of every moving Gaussian are placed by following its
  /// projection through the optical flow of every fixed camera that sees it (front surface,
  /// forward–backward consistent flow; least squares over the cameras, no depth change from
  /// a single camera). Gaussians no camera follows keep the constant-velocity keys.
  bool flow_keys = true;
  bool flow_changing_only = true;  ///< follow a Gaussian only from cameras where it sits on a changing pixel
  double flow_tolerance = 1.0;  ///< forward–backward disagreement allowed per frame step (px)
  double motion_sparsity = 0.0;  ///< L1 step on the key-to-key steps (shrink_key_deviations), × the key learning rate (0: off)
  /// The written model folds Gaussians whose keys change less than this into static ones;
  /// the position tolerance is a fraction of the camera extent.
  double still_distance = 1e-3;
  StillTolerance still;
  int time_bins = 4;            ///< `promote` only
  double promote_agreement = 0.3;
  double promote_grad_scale = 1.0;  ///< promotion needs this × the densification gradient threshold
  int promote_min_samples = 3;  ///< views per time bin before a bin counts
  int checkpoint_interval = 0;  ///< 0: only at the end
  /// Real rigs differ in exposure and white balance per camera: learn, per rig camera, an
  /// affine colour correction gain ⊙ render + offset applied before the loss on its real
  /// views (refined views have none). The dataset's first camera is the reference (held at
  /// identity), which fixes the gauge between the corrections and the Gaussians' colours.
  bool colour_correction = false;
  /// Corrections to start from, by rig (fine-tuning a model trained with them: its
  /// colour_correction.json). Given, every rig named starts from its own and the dataset's
  /// first camera is held at its given correction instead of identity; rigs not named start at
  /// identity and learn. Needs colour_correction.
  std::vector<ColourCorrection> initial_colour;
  double colour_lr = 5e-3;
  /// Fine-tuning: probability that an iteration trains on a refined view (once any were
  /// added) instead of a real one. Refined views would otherwise outnumber real ones on a
  /// sparse rig (20 trajectories × 9 views against 2 cameras × 30 frames).
  double refined_share = 0.3;
  /// Adam leaves a value and its moments as they are in an iteration where its gradient is
  /// exactly zero: the keys of other frames, Gaussians the view does not reach. Without it,
  /// momentum keeps moving them after every view that touched them (about 30 × the learning
  /// rate per touch at β1 0.9, β2 0.999), which a converged model does not survive.
  bool sparse_adam = false;
  /// The 3DGS schedule (defined for 30,000 iterations) scaled to `iterations`.
  static TrainOptions scaled(int iterations);
};

struct TrainStatus {
  int iteration = 0;
  double loss = 0, psnr = 0;  ///< exponential moving averages over recent iterations
  size_t gaussians = 0, dynamic = 0;
  double iterations_per_second = 0;
  int window_frames = 0;      ///< frames in the trained time window (all once the ramp ends)
};

/// Writes / reads `{"<rig>": {"gain": [r, g, b], "offset": [r, g, b]}, ...}` (atomically;
/// one error naming the file and the camera on bad input).
void write_colour_correction(const std::string& path, const std::vector<ColourCorrection>& corrections);
std::vector<ColourCorrection> read_colour_correction(const std::string& path);
/// `rgb` ([pixels][3]) becomes gain ⊙ rgb + offset, in place.
void apply_colour_correction(const ColourCorrection& correction, std::vector<float>& rgb);
/// Re-expresses a model trained with per-camera corrections in the colours of the rig's
/// mean camera — the best guess for a camera with no correction of its own (a held-out
/// one): with ḡ, ō the per-channel means of the gains and offsets, every Gaussian's colour
/// c becomes ḡ ⊙ c + ō (SH DC and higher coefficients; exact wherever the colour is not
/// clamped at 0) and each correction (g, o) becomes (g / ḡ, o − g / ḡ ⊙ ō), so every
/// training camera renders as before and the corrections average to gain 1, offset 0.
/// A background b would become ḡ ⊙ b + ō; the model carries none. Returns (ḡ, ō) as
/// rig "mean".
ColourCorrection fold_mean_colour(GaussianCloud& model, std::vector<ColourCorrection>& corrections);

/// What a densification step did (for diagnostics and summaries).
struct DensifyRecord {
  int iteration = 0;
  size_t gaussians = 0, dynamic = 0, promoted = 0, cloned = 0, split = 0, pruned = 0;
  size_t made_static = 0;  ///< keyed Gaussians made static (never on a changing pixel)
};

/// A refined (generated) view for fine-tuning: its camera (with time), image and per-pixel
/// loss weights (the paper, Sec. 3.5: the loss on it is weight × photometric error).
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
  /// Every densification step of this session (not stored in checkpoints).
  const std::vector<DensifyRecord>& densify_log() const { return densify_log_; }
  /// How many iterations of this session drew each real view (indexed as Dataset::views;
  /// refined views not counted; not stored in checkpoints).
  const std::vector<uint32_t>& view_draws() const { return view_draws_; }
  /// The last frame of the trained time window at an iteration (time curriculum).
  int window_last_frame(int iteration) const;
  /// How many Gaussians were made static again when the window reached the whole video.
  size_t frozen() const { return frozen_; }
  /// Key placements made by optical flow so far (flow_keys), and how many were tried.
  std::pair<size_t, size_t> flow_placed() const { return {flow_placed_, flow_tried_}; }
  /// Per view, the share of its pixels that change over the video (−1: no fixed camera).
  std::vector<double> changing_share() const;
  /// The trained model as a cloud (keys that never moved folded back into static Gaussians).
  GaussianCloud model() const;
  /// Per rig camera (Dataset::rigs order) its colour correction; identity when off.
  const std::vector<ColourCorrection>& colour_correction() const { return colour_; }

 private:
  /// Applies the view's colour correction to `image` in place and returns the rig's index
  /// when it has a learned one (−1: none).
  int correct_colour(size_t view, std::vector<float>& image) const;
  /// Gradient of the corrected image → the correction's Adam step, and `dimg` → the render's.
  void colour_backward(int rig, const std::vector<float>& render, float* dimg);
  void adam_step();
  void densify_and_prune(bool prune_big, DensifyRecord* record);
  size_t promote_static();
  size_t freeze_still();
  size_t fold_unchanging();
  /// Makes the flagged keyed Gaussians static (their key means), carrying every per-Gaussian state.
  size_t make_static(const std::vector<uint8_t>& flags);
  void find_fixed_rigs();
  void build_change_masks();
  void carry(const std::vector<uint32_t>& sources);
  void enter_key_interval();
  void place_keys_by_flow(int from_frame);
  /// Zeroes the Adam moments of keys `from` on (positions only, or every keyed value).
  void restart_key_moments(int from, bool positions_only);
  void motion_sparsity_step(double key_lr);
  int key_interval_of_frame(int frame) const;
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
  std::vector<DensifyRecord> densify_log_;
  std::vector<uint32_t> view_draws_;
  size_t frozen_ = 0;
  size_t flow_placed_ = 0, flow_tried_ = 0;
  // Per rig camera that keeps one pose, its view at every frame (−1: none).
  std::vector<std::vector<long>> fixed_rigs_;
  // Motion where the images change: per view the index of its camera's mask (−1: none),
  // the masks ([H][W], 1 = changing), and per Gaussian whether it has been on one.
  std::vector<int> view_mask_;
  std::vector<std::vector<uint8_t>> change_masks_;
  std::vector<uint8_t> on_change_;
  std::vector<RefinedView> refined_;
  // Colour correction per rig camera: value, Adam moments ([6]: gain rgb, offset rgb), steps.
  std::vector<ColourCorrection> colour_;
  std::vector<std::array<float, 6>> colour_m_, colour_v_;
  std::vector<int> colour_steps_;
  std::vector<int> view_rig_;  // per view, its rig's index in Dataset::rigs
  std::vector<size_t> views_by_frame_;  // view indices sorted by frame
  std::vector<size_t> frame_begin_;     // [F + 1] offsets into views_by_frame_
};

}  // namespace fillgs
