#pragma once
// The 4D Gaussian scene model: structure of arrays, static and dynamic index sets.
//
// Time convention (everywhere in fillgs): normalised t in [0, 1]; a video of F frames
// has frame f at t = f / (F - 1). Readers convert other conventions into this one.
//
// Stored values are the raw (pre-activation) values the 3DGS family stores:
// log-scales, opacity logits, unnormalised quaternions (w, x, y, z), SH coefficients.
// Static Gaussians carry no motion data; motion arrays are indexed by position in
// `dynamic_ids`, not by Gaussian id.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/base/math.hpp"

namespace fillgs {

enum class MotionModel { Static, Polynomial, Keyframed, Evaluated };
FILLGS_ENUM_NAMES(MotionModel, "motion model",
    {MotionModel::Static, "static"}, {MotionModel::Polynomial, "polynomial"}, {MotionModel::Keyframed, "keyframed"},
    {MotionModel::Evaluated, "evaluated"});

/// Gaussians at one time as a trained model gives them: raw values (log-scales,
/// unnormalised quaternions, opacity logits, SH), as its renderer hands them to the rasteriser.
struct ModelState {
  int sh_degree = 0;
  std::vector<Vec3f> means, log_scales;
  std::vector<Vec4f> rotations;
  std::vector<float> opacity_logits;
  std::vector<float> opacity_factor;  ///< a temporal factor applied after the sigmoid (4DGS); empty: 1
  std::vector<float> sh;              ///< [N][(degree+1)^2][3]
  size_t size() const { return means.size(); }
  /// Rows `rows` of this state, in that order.
  ModelState rows(const std::vector<uint32_t>& rows) const;
  /// The same into `out`, whose storage is reused (a frame's state written over the last one's).
  void rows_into(const std::vector<uint32_t>& rows, ModelState& out) const;
};

/// Motion that a trained model's own code computes at each time (its deformation network,
/// its closed-form slice): evaluated exactly at the time asked, for the Gaussians asked,
/// never stored per frame (io/trained_models.hpp).
class MotionSource {
 public:
  virtual ~MotionSource() = default;
  /// The source's Gaussians `rows` at normalised time t in [0, 1] (rows.size() of them),
  /// shared: a source may hand the same evaluation to several callers without copying it.
  virtual std::shared_ptr<const ModelState> evaluate(double t, const std::vector<uint32_t>& rows) const = 0;
  /// Frames the model covers (frame f at t = f / (frames - 1)).
  virtual int frame_count() const = 0;
  /// Whether each frame should be asked for once only, in order (a caller's own network, run
  /// for every frame it is asked): commands then skip passes that read every frame ahead of
  /// their walk (observe's swept boxes of the moving Gaussians), which are shortcuts only.
  virtual bool one_pass() const { return false; }
};

/// Spacetime Gaussians motion (polynomial position, linear rotation, temporal RBF opacity).
/// Model time is t_model = t * time_scale (STG uses (frame)/D, so time_scale = (D-1)/D).
struct PolynomialMotion {
  std::vector<float> coeffs;          ///< [M][9]: x,y,z coefficients of Δ, then Δ², then Δ³
  std::vector<float> omega;           ///< [M][4]: quaternion rate
  std::vector<float> trbf_center;     ///< [M]: temporal centre, model time
  std::vector<float> trbf_log_scale;  ///< [M]: log temporal scale
  double time_scale = 1.0;
};

enum class KeyInterp { CatmullRom, Linear, Pchip };

/// Keyframed motion (Ex4DGS dynamic set, fillgs baked tracks). Keys are uniformly spaced:
/// key k sits at t = first_key_time + k * key_spacing (normalised time).
struct KeyframedMotion {
  int key_count = 0;
  double first_key_time = 0.0;
  double key_spacing = 1.0;
  KeyInterp position_interp = KeyInterp::CatmullRom;
  /// false: fillgs convention (interval index clamped to [0, K-2], end keys repeated
  /// for tangents, shortest-arc slerp). true: Ex4DGS convention (index clamped to
  /// [1, K-3] and extrapolated, slerp without sign flip).
  bool ex4dgs_edges = false;
  std::vector<float> positions;       ///< [M][K][3]
  std::vector<float> rotations;       ///< [M][K][4] raw quaternions; empty: constant (cloud value)
  std::vector<float> log_scales;      ///< [M][K][3]; empty: constant
  std::vector<float> opacity_logits;  ///< [M][K]; empty: constant
  /// [M][K][3] the SH DC coefficients (colour) per key, linearly interpolated; empty: the
  /// cloud's constant SH DC.
  std::vector<float> colours;
  /// [M][K][C-1][3] the higher SH bands per key (C = the cloud's sh_count()), linearly
  /// interpolated; empty: the cloud's constant higher bands. Only with `colours`.
  std::vector<float> sh_rest;
  /// Ex4DGS temporal opacity, [M][4]: c0, c1, v0, v1 in key units; empty: none.
  std::vector<float> temporal_opacity;
  double temporal_width_pad = 0.0;  ///< Ex4DGS var_pad / (2.36 * I)
};

/// A 4D Gaussian cloud. Every per-Gaussian array has size() entries.
struct GaussianCloud {
  int sh_degree = 0;
  std::vector<Vec3f> means;           ///< canonical world-space means
  std::vector<Vec3f> log_scales;
  std::vector<Vec4f> rotations;       ///< (w, x, y, z), not necessarily unit
  std::vector<float> opacity_logits;
  std::vector<float> sh;              ///< [N][sh_count()][3], coefficient-major per Gaussian

  MotionModel motion = MotionModel::Static;
  std::vector<uint32_t> dynamic_ids;  ///< ascending Gaussian ids that move
  PolynomialMotion polynomial;
  KeyframedMotion keyframed;
  /// MotionModel::Evaluated: the model that computes the dynamic Gaussians at each time, and
  /// the source's row of each (indexed like dynamic_ids). Copies of the cloud share it.
  std::shared_ptr<const MotionSource> source;
  std::vector<uint32_t> source_rows;

  std::vector<std::string> notes;     ///< what the reader approximated, for `info`
  std::string model_times;            ///< the model's own time at t = 0 … 1, where it has one (trained models), for `info`
  /// The model's own time (its training code's) at t = 0 and t = 1: frame f of F at
  /// model_time_first + f / (F - 1) (model_time_last - model_time_first). 0 and 1 where the
  /// model has no time of its own (normalised time is its time).
  double model_time_first = 0.0, model_time_last = 1.0;

  size_t size() const { return means.size(); }
  int sh_count() const { return (sh_degree + 1) * (sh_degree + 1); }
  size_t dynamic_count() const { return dynamic_ids.size(); }
  size_t static_count() const { return size() - dynamic_ids.size(); }
  /// Ascending ids of the Gaussians that do not move.
  std::vector<uint32_t> static_ids() const;
  /// Resizes every per-Gaussian array (SH zero-filled).
  void resize(size_t n);
  /// Throws Error naming `source` and the element if any array is inconsistent or non-finite.
  void validate(const std::string& source) const;
};

/// Gaussians evaluated at one time: activated, world space. Static entries are written
/// once; FrameSampler rewrites only the dynamic ones per time.
struct FrameGaussians {
  double time = 0.0;
  int sh_degree = 0;
  std::vector<Vec3f> means;
  std::vector<Vec3f> scales;     ///< exp(log-scale)
  std::vector<Vec4f> rotations;  ///< unit quaternions
  std::vector<float> opacities;  ///< sigmoid(logit) times any temporal factor
  const float* sh = nullptr;     ///< [N][K][3]: the cloud's SH array, or sh_storage where colour is keyed
  std::vector<float> sh_storage; ///< the SH at `time` when the cloud has colour keys; empty otherwise
  size_t size() const { return means.size(); }

  FrameGaussians() = default;
  FrameGaussians(FrameGaussians&&) = default;  // a moved vector keeps its buffer: `sh` stays valid
  FrameGaussians& operator=(FrameGaussians&&) = default;
  FrameGaussians(const FrameGaussians& o) { *this = o; }
  /// Copies; `sh` then points into the copy's own storage where colour is keyed.
  FrameGaussians& operator=(const FrameGaussians& o) {
    time = o.time;
    sh_degree = o.sh_degree;
    means = o.means;
    scales = o.scales;
    rotations = o.rotations;
    opacities = o.opacities;
    sh_storage = o.sh_storage;
    sh = sh_storage.empty() ? o.sh : sh_storage.data();
    return *this;
  }
};

/// The Gaussians of a cloud at any time, touching only the dynamic set after the first call.
class FrameSampler {
 public:
  explicit FrameSampler(const GaussianCloud& cloud);
  /// Gaussians at normalised time t (values outside [0, 1] are clamped to it).
  const FrameGaussians& at(double t);
  const GaussianCloud& cloud() const { return cloud_; }

 private:
  const GaussianCloud& cloud_;
  FrameGaussians frame_;
  std::shared_ptr<const ModelState> state_;  ///< evaluated motion: the dynamic set at frame_.time
};

/// The Gaussians at time t, one shot (copies the static set).
FrameGaussians frame_at(const GaussianCloud& cloud, double t);

/// The model's own time (its training code's, e.g. E-D3DGS's f / total_num_frames, 4DGS's
/// seconds) at normalised time t in [0, 1], and back: normalised_time() refuses a model time
/// outside the ones the model covers. Identity for models without a time of their own.
double model_time(const GaussianCloud& cloud, double t);
double normalised_time(const GaussianCloud& cloud, double model_time);

/// World-space means of the dynamic set at time t, in `dynamic_ids` order.
void dynamic_means_at(const GaussianCloud& cloud, double t, std::vector<Vec3f>& out);

struct PartitionOptions {
  /// A Gaussian whose speed (world units per unit normalised time) never exceeds this,
  /// and whose rotation, scale and opacity do not change, is static.
  float static_speed_threshold = 1e-4f;
  int samples = 64;  ///< time samples used to bound the speed of polynomial motion
};

/// Moves dynamic Gaussians that do not move (per PartitionOptions) into the static set,
/// freezing them at their time-averaged position. Returns how many were moved.
size_t partition_static_dynamic(GaussianCloud& cloud, const PartitionOptions& options = {});

/// How little a keyframed Gaussian may change to count as still (fold_still_keys).
struct StillTolerance {
  float position = 1e-3f;         ///< largest distance of a key from the keys' mean, world units
  float rotation_degrees = 1.0f;  ///< largest angle between a key's rotation and the keys' mean
  float opacity_logit = 0.1f;     ///< largest difference of a key's opacity logit from the mean
};

/// Sets every key of each keyframed Gaussian that changes less than `tolerance` to the keys'
/// mean (position, normalised mean rotation, mean opacity logit), so that
/// partition_static_dynamic then folds it into the static set. Returns how many were set.
size_t fold_still_keys(GaussianCloud& cloud, const StillTolerance& tolerance);

/// Reorders the cloud so that its static Gaussians come first, then the moving ones (each
/// in their order): the order fillgs 4D PLY files store, so that a model written and read
/// back is the same cloud, Gaussian for Gaussian.
void static_first(GaussianCloud& cloud);

/// Keyframed motion with one key per frame (key f at t = f / (frames - 1)), fillgs
/// conventions, positions and rotations sized for `gaussians` tracks (zero-filled).
KeyframedMotion per_frame_tracks(size_t gaussians, int frames);

/// Sets every dynamic Gaussian's canonical mean and rotation to its first key, so that
/// tools that read only the canonical values (splat viewers, bounds) see time 0.
void canonical_from_first_key(GaussianCloud& cloud);

/// The frames a cloud's motion is given at: its key count (keyframed), its model's frame
/// count (evaluated); 0 for other motion.
int motion_frames(const GaussianCloud& cloud);

/// Axis-aligned bounds of the canonical means (min, max).
std::pair<Vec3f, Vec3f> bounding_box(const GaussianCloud& cloud);

}  // namespace fillgs
