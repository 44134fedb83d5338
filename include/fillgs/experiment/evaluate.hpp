#pragma once
// Evaluation (the paper, Sec. 4.1): PSNR, SSIM and PSNR restricted to the moving region, per test
// split; LPIPS through a user-supplied ONNX network (OpenCV DNN) when one is given.
//
// PSNR and SSIM are means over views (each view's PSNR first, as 3DGS reports it). The
// moving-region PSNR pools the squared error of every moving pixel of the split before
// taking the PSNR (a view may have no moving pixel). The moving region of a view is where
// the ground truth's moving Gaussians make up at least half of the rendered opacity
// (synthetic data); without a ground-truth scene it is the dataset's foreground masks where
// it has them (real video, e.g. Panoptic's seg/: "foreground PSNR"), else not computed.
//
// LPIPS network contract: an ONNX file with two inputs named `in0` and `in1`, each
// 1×3×H×W float RGB in [−1, 1], returning the distance as the first value of its output
// (the names and layout of the lpips package's forward(in0, in1) exported to ONNX).
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/train/train.hpp"

namespace fillgs {

struct EvalOptions {
  int view_stride = 1;                    ///< every k-th view of the split
  Vec3f background = Vec3f::Zero();
  const GaussianCloud* truth = nullptr;   ///< for the moving region (synthetic scenes)
  std::string lpips_onnx;                 ///< empty: no LPIPS
  std::string save_dir;                   ///< non-empty: renders written here as <view name>.png
  /// Learned colour corrections (train --colour-correction): applied to the renders of the
  /// views of the cameras they name; held-out cameras have none and are evaluated as rendered.
  std::vector<ColourCorrection> colour;
  /// Also the PSNR after a per-image, per-channel least-squares gain g = Σ r·t / Σ r² on the
  /// render (how some papers evaluate held-out cameras of a real rig): psnr_ls_gain.
  bool ls_gain = false;
  /// Also the PSNR after a per-image, per-channel least-squares affine map a·r + b of the
  /// render onto the image: exposure and white balance fitted away (psnr_affine).
  bool affine_fit = false;
  /// The moving region's PSNR where `truth` or the split's foreground masks allow.
  bool moving = true;
};

/// One evaluated view: its camera and frame, its metrics, and its moving region's squared
/// error and pixels (summed, so that a group of views pools them as the split does).
struct ViewMetrics {
  std::string camera;
  int frame = 0;
  double psnr = 0, ssim = 0;
  double psnr_ls_gain = std::numeric_limits<double>::quiet_NaN();
  double psnr_affine = std::numeric_limits<double>::quiet_NaN();
  double moving_squared_error = 0;
  size_t moving_pixels = 0;
};

struct SplitMetrics {
  std::string split;
  size_t views = 0;
  double psnr = 0, ssim = 0;
  double psnr_moving = std::numeric_limits<double>::quiet_NaN();
  size_t moving_pixels = 0;
  double lpips = std::numeric_limits<double>::quiet_NaN();
  double psnr_ls_gain = std::numeric_limits<double>::quiet_NaN();  ///< EvalOptions::ls_gain
  double psnr_affine = std::numeric_limits<double>::quiet_NaN();   ///< EvalOptions::affine_fit
  double seconds = 0;
  std::vector<ViewMetrics> per_view;  ///< every evaluated view, in the split's order
};

/// How a render's colours are fitted to its image before a PSNR: per image and channel, the
/// least-squares gain g·r or affine map g·r + b.
enum class ColourFit { Gain, Affine };
/// `render` ([P][3]) mapped per channel onto `target` by the least-squares fit (a channel
/// with no variance in the render keeps its gain 1 and, affine, takes the target's mean).
std::vector<float> fit_colours(const std::vector<float>& render, const std::vector<float>& target, ColourFit fit);

/// Metrics of `model` on every view of a split.
SplitMetrics evaluate_split(const GaussianCloud& model, const Dataset& split, const std::string& name, const EvalOptions& options = {},
                            Progress& progress = null_progress());

/// PSNR and SSIM on every max(1, V/32)-th training view: what the training summaries report.
SplitMetrics evaluate_training_sample(const GaussianCloud& model, const Dataset& data, const Vec3f& background);

/// The moving region of a camera at its time: 1 where the moving Gaussians of `truth`
/// make up at least half of the rendered opacity ([H][W]).
std::vector<unsigned char> moving_region(const GaussianCloud& truth, const Camera& camera);

/// LPIPS of two RGB images ([H][W][3] in [0, 1]) with an ONNX network (see above).
class LpipsNetwork {
 public:
  explicit LpipsNetwork(const std::string& onnx_path);
  ~LpipsNetwork();
  LpipsNetwork(LpipsNetwork&&) noexcept;  ///< move-only: it owns the loaded network
  LpipsNetwork& operator=(LpipsNetwork&&) noexcept;
  double distance(const float* a, const float* b, int width, int height);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fillgs
