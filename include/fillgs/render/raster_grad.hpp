#pragma once
// The splat rasterizer's differentiable path: a forward that keeps what the backward
// needs, the backward pass (gradients of the rendered image and of any blended feature
// channel with respect to every Gaussian value), and the diagonal Fisher information
// Σ_pixels Σ_channels (∂Î/∂θ)² that the `fisherrf` baseline needs.
//
// The math is the forward rasterizer's (raster.hpp), clamp for clamp:
//  * α = min(0.99, o·G): where the clamp is active, α does not depend on o or G and gets
//    no gradient (the finite difference of the forward is zero there);
//  * α < 1/255 is skipped in both directions; a pixel stops before T falls under 1e-4 and
//    the Gaussian that would have crossed it contributes nothing, in both directions;
//  * the EWA Jacobian clamp at 1.3·tan(fov/2) cuts the gradient of the clamped component;
//  * colour from SH is clamped below at 0; a clamped channel gets no gradient.
// Templated on the scalar: `float` trains, `double` checks gradients against finite
// differences. Tiles are processed in parallel; per-Gaussian sums are reduced in tile
// order afterwards, so results are bit-identical for any thread count. Memory is bounded
// by the number of Gaussian-tile pairs (one gradient record each), never per pixel lists.
// The blend and its backward are the tile kernel's (src/render/tile_kernel.hpp): the
// vector kernel for float unless `DiffRenderOptions::kernel` (or --kernel) picks the scalar
// one; double always runs the scalar kernel, and the Fisher diagonal always does.
#include <cstdint>
#include <vector>

#include "fillgs/model/camera.hpp"
#include "fillgs/render/raster.hpp"

namespace fillgs {
namespace tiles {
struct TileWork;
}

/// Gaussians at one time, activated, as flat arrays of any scalar type.
template <typename Real>
struct DiffFrame {
  int sh_degree = 0;
  std::vector<Real> means;      ///< [N][3] world space
  std::vector<Real> scales;     ///< [N][3] exp(log-scale)
  std::vector<Real> rotations;  ///< [N][4] unit quaternions (w, x, y, z)
  std::vector<Real> opacities;  ///< [N] in (0, 1), temporal factors included
  const Real* sh = nullptr;     ///< [N][(degree+1)²][3], coefficient-major per Gaussian
  std::vector<Real> sh_storage; ///< the frame's own SH where it differs from the model's (keyed colour), else empty
  /// Kept by params_at for its backward (train_model.hpp, keep_for_backward): each moving
  /// Gaussian's slerp state; empty otherwise.
  std::vector<Real> key_state;
  bool kept_for_backward = false;
  size_t size() const { return opacities.size(); }
  void resize(size_t n) {
    means.assign(3 * n, Real(0));
    scales.assign(3 * n, Real(0));
    rotations.assign(4 * n, Real(0));
    opacities.assign(n, Real(0));
  }
};

/// Gradients with respect to a DiffFrame's values (same layout), plus the summed
/// screen-space gradient of every mean (pixels), which densification thresholds.
template <typename Real>
struct DiffFrameGrad {
  std::vector<Real> means, scales, rotations, opacities, sh, features;
  std::vector<Real> screen;  ///< [N][2] dL/d(pixel position of the mean), summed over pixels
  void reset(size_t n, int sh_count, int feature_channels) {
    means.assign(3 * n, Real(0));
    scales.assign(3 * n, Real(0));
    rotations.assign(4 * n, Real(0));
    opacities.assign(n, Real(0));
    sh.assign(n * size_t(sh_count) * 3, Real(0));
    features.assign(n * size_t(feature_channels), Real(0));
    screen.assign(2 * n, Real(0));
  }
};

/// Diagonal Fisher information per Gaussian at one view: Σ_pixels Σ_rgb (∂Î/∂θ)² for
/// θ = mean (3), log-scale (3), unit rotation (4), opacity logit (1), SH DC (3).
/// The dependence of view-dependent colour on the mean is left out (as in FisherRF).
struct FisherDiagonal {
  static constexpr int kParams = 14;
  std::vector<double> values;  ///< [N][14]
};

struct DiffRenderOptions {
  Vec3f background = Vec3f::Zero();
  const float* features = nullptr;  ///< optional [N][feature_channels] blended like colour (background 0)
  int feature_channels = 0;
  Kernel kernel = Kernel::Default;  ///< the vector kernel applies to float only
};

/// Differentiable rendering of one view. Usage: forward(), read image(), compute dL/dimage,
/// backward(). The object keeps the forward's state until the next forward().
template <typename Real>
class DiffRasterizer {
 public:
  void forward(const DiffFrame<Real>& frame, const Camera& camera, const DiffRenderOptions& options = {});

  int width() const { return width_; }
  int height() const { return height_; }
  const std::vector<Real>& image() const { return image_; }        ///< [H][W][3], background included
  const std::vector<Real>& features() const { return features_; }  ///< [H][W][F]
  const std::vector<Real>& alpha() const { return alpha_; }        ///< [H][W], 1 − final T
  const std::vector<int>& radii() const { return radii_; }         ///< [N], 0 where culled
  size_t tile_entries() const { return keys_.size(); }

  /// Gradients of a loss L given dL/dimage ([H][W][3]) and optionally dL/dfeatures
  /// ([H][W][F]); `pixel_weights` ([H][W], optional) multiplies both per pixel.
  void backward(const Real* dL_dimage, const Real* dL_dfeatures, const Real* pixel_weights,
                DiffFrameGrad<Real>* grad) const;

  /// Adds this view's diagonal Fisher information (per-pixel squared gradients of the RGB
  /// image) to `fisher` (resized to N×14 on first use).
  void accumulate_fisher(FisherDiagonal* fisher) const;

 private:
  /// Visits accepted (Gaussian, pixel) pairs tile by tile, back to front; `make_visitor`
  /// returns a fresh per-thread visitor with begin(entry, visible index), pair(pixel,
  /// pair state, channels) and end(entry).
  template <typename MakeVisitor>
  void backward_tiles(MakeVisitor&& make_visitor) const;
  /// The vector backward (float): the gradient records of the entries that reach a pixel,
  /// each tile's packed from its first entry's slot, with their visible indices in `ids`
  /// and their count in `written` (per tile).
  void backward_tiles_simd(const Real* dL_dimage, const Real* dL_dfeatures, const Real* pixel_weights, Real* records,
                           uint32_t* ids, uint32_t* written) const;
  tiles::TileWork tile_work(size_t tile) const;
  bool uses_simd() const;

  const DiffFrame<Real>* frame_ = nullptr;
  Camera camera_;
  DiffRenderOptions options_;
  int width_ = 0, height_ = 0, channels_ = 0, grid_x_ = 0;
  std::vector<uint32_t> visible_;
  std::vector<Real> splat_data_;        // per visible: u, v, conic a b c, opacity
  std::vector<Real> colour_;            // per visible: channel values
  std::vector<uint8_t> colour_clamped_; // per visible: rgb clamped at 0 (bit per channel)
  std::vector<float> half_extent_;      // per visible: half_w, half_h (pixels)
  std::vector<int32_t> alpha_spans_;    // vector kernel, per visible: its α ≥ 1/255 pixels x0, x1, y0, y1
  std::vector<uint64_t> tile_start_;
  std::vector<uint32_t> keys_;          // per tile entry: index into visible_
  std::vector<Real> image_, features_, alpha_, final_T_;
  std::vector<uint32_t> last_entry_;    // per pixel: entries [0, last) of its tile were considered
  std::vector<int> radii_;
};

/// The projection of one Gaussian with every value the backward needs, in any scalar.
template <typename Real>
struct SplatProjection {
  Real u = 0, v = 0;                    ///< pixel position of the mean (3DGS convention)
  Real conic[3] = {0, 0, 0};            ///< inverse dilated 2D covariance (a, b, c)
  Real cov[3] = {0, 0, 0};              ///< dilated 2D covariance
  Real depth = 0;
  bool valid = false;
};

/// Forward projection (the preprocess of raster.hpp); instantiated for double, the precision
/// both rasterizers project in.
template <typename Real>
SplatProjection<Real> project_splat(const Real* mean, const Real* scale, const Real* rotation, const Camera& cam);

/// Backward of project_splat (double): given dL/du, dL/dv and dL/dconic, adds dL/dmean, dL/dscale
/// and dL/drotation (unit quaternion) into the output arrays (3, 3, 4 values).
template <typename Real>
void project_splat_backward(const Real* mean, const Real* scale, const Real* rotation, const Camera& cam,
                            Real dL_du, Real dL_dv, const Real dL_dconic[3], Real* dL_dmean, Real* dL_dscale,
                            Real* dL_drotation);

}  // namespace fillgs
