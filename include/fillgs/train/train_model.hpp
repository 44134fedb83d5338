#pragma once
// The trainable 4D model: the parameters the optimiser updates, their evaluation at a time
// (into a DiffFrame the differentiable rasterizer reads) and the backward of that
// evaluation (frame gradients → parameter gradients, motion parameters included).
//
// Motion: static Gaussians have no motion parameters. Moving ones carry keyframed
// positions and rotations (keys k at t = first_key_time + k·key_spacing, Catmull-Rom
// positions with repeated end keys, shortest-arc slerp of normalised key quaternions —
// fillgs' KeyframedMotion convention, evaluated by the same code as frame_at(t):
// src/model/motion_keys.hpp — so a model converts to and from GaussianCloud without change),
// and optionally keyed log-scales, opacity logits and SH coefficients (linear).
// The same struct holds gradients and Adam moments (same layout).
#include <cstdint>
#include <vector>

#include "fillgs/model/gaussians.hpp"
#include "fillgs/render/raster_grad.hpp"

namespace fillgs {

template <typename Real>
struct ModelParams {
  int sh_degree = 0;
  std::vector<Real> means;           ///< [N][3]; unused for moving Gaussians (keys rule)
  std::vector<Real> log_scales;      ///< [N][3]
  std::vector<Real> rotations;       ///< [N][4] raw quaternions; unused for moving ones
  std::vector<Real> opacity_logits;  ///< [N]
  std::vector<Real> sh;              ///< [N][(degree+1)²][3]
  std::vector<uint32_t> dynamic_ids; ///< ascending
  int key_count = 0;
  double first_key_time = 0.0, key_spacing = 1.0;
  std::vector<Real> key_positions;       ///< [M][K][3]
  std::vector<Real> key_rotations;       ///< [M][K][4]
  std::vector<Real> key_log_scales;      ///< [M][K][3] or empty (the Gaussian's own)
  /// Whether moving Gaussians carry an opacity logit per key (content that appears and
  /// disappears); key_opacity_logits is then [M][K], else empty and the own logit rules.
  bool keyed_opacity = false;
  std::vector<Real> key_opacity_logits;  ///< [M][K] or empty
  /// Every SH coefficient of moving Gaussians per key, linearly interpolated ([M][K][C][3],
  /// C = sh_count()), or empty (each Gaussian's own `sh`): a model whose colour changes in time
  /// (a network's, keyed by keyed_for_training) keeps it while it trains.
  std::vector<Real> key_sh;

  size_t size() const { return opacity_logits.size(); }
  size_t dynamic_count() const { return dynamic_ids.size(); }
  int sh_count() const { return (sh_degree + 1) * (sh_degree + 1); }
  /// Same shapes, every value zero (for gradients and Adam moments).
  ModelParams zeros_like() const;
  /// Reshapes this to `shape`'s sizes, every value zero (keeps allocations).
  void set_zeros_like(const ModelParams& shape);
  /// Every value array, in a fixed order, with its width per row (for generic loops).
  std::vector<std::vector<Real>*> arrays();
  std::vector<const std::vector<Real>*> arrays() const;
};

/// Sets the key layout for a video of `frames` frames: keys every `interval` frames
/// (the last key at t = 1 or beyond), first key at t = 0.
template <typename Real>
void set_key_layout(ModelParams<Real>& params, int frames, int interval);

/// Makes every static Gaussian a moving one whose keys all hold its own pose (and opacity,
/// when opacities are keyed), so that any Gaussian can move while training; nothing renders
/// differently. Needs the key layout. Returns how many were converted.
template <typename Real>
size_t key_every_gaussian(ModelParams<Real>& params);

/// Gives every moving Gaussian one opacity logit per key (each its own logit) when the
/// model has none.
template <typename Real>
void add_key_opacities(ModelParams<Real>& params);

/// Continues the keys of every moving Gaussian from key `from` on at constant velocity:
/// position k = 2·(k−1) − (k−2), rotation k = (k−1)·((k−2)⁻¹·(k−1)), opacity k = opacity
/// k−1 — when its last step (key from−1 minus key from−2) is at least `min_step` times its
/// largest scale; otherwise (no evidence of motion) every later key holds key from−1.
/// `from` must be at least 2.
void extrapolate_keys(ModelParams<float>& params, int from, float min_step = 0.0f);

/// The sparsity prior on motion: a group-lasso proximal step on each moving Gaussian's keys
/// 0..keys−1. Per Gaussian and per kind (positions, rotations, opacities), the deviations of
/// its keys from their mean, as one vector, shrink in length by τ, and vanish exactly when
/// shorter: still Gaussians end with equal keys (and fold back to static), moving ones keep
/// their motion less τ. Rotation keys are first put on the first key's hemisphere.
/// `only`, when given ([N], Gaussian ids), limits the step to the Gaussians marked non-zero.
/// `per_value`: soft-threshold each value's deviation by τ instead (an L1 step per value).
void shrink_key_deviations(ModelParams<float>& params, int keys, float tau_position, float tau_rotation, float tau_opacity,
                           const std::vector<uint8_t>* only = nullptr, bool per_value = false);

/// Converts a cloud into trainable parameters. Static and fillgs-convention keyframed
/// clouds convert exactly; any other motion (polynomial, Ex4DGS edges or temporal
/// opacity) is first baked to `bake_frames` keys with bake_tracks (an Error if 0).
template <typename Real>
ModelParams<Real> params_from_cloud(const GaussianCloud& cloud, int bake_frames = 0);

/// The cloud of float parameters (canonical mean/rotation of moving ones = first key).
GaussianCloud cloud_from_params(const ModelParams<float>& params);

/// Gaussians at time t (clamped to [0, 1]). `frame.sh` points into params.sh. With
/// keep_for_backward the frame also keeps what params_at_backward would evaluate again
/// (each moving Gaussian's slerp state: norms, normalised keys, sines).
template <typename Real>
void params_at(const ModelParams<Real>& params, double t, DiffFrame<Real>* frame, bool keep_for_backward = false);

/// Adds dL/dparams for a loss whose gradient with respect to params_at(t) is `grad`. Given
/// `frame`, params_at(params, t, frame, true)'s (the same parameters and time), it reads the
/// values the forward kept instead of evaluating them again: the same gradients, bit for bit.
template <typename Real>
void params_at_backward(const ModelParams<Real>& params, double t, const DiffFrameGrad<Real>& grad,
                        ModelParams<Real>* dparams, const DiffFrame<Real>* frame = nullptr);

}  // namespace fillgs
