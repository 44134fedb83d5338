#pragma once
// Photometric losses and image metrics.
//
// The training loss is the 3DGS one: (1 − λ)·L1 + λ·(1 − SSIM), λ = 0.2, SSIM with an 11×11
// Gaussian window (σ = 1.5), zero padding (PyTorch conv2d with padding 5, as the 3DGS code),
// constants C1 = 0.01², C2 = 0.03². Optional per-pixel weights multiply both terms pixel by
// pixel; means are over all pixels and channels (weights are not renormalised, so a weight
// map of 0.5 halves the loss).
#include <cstddef>
#include <vector>

namespace fillgs {

struct LossValue {
  double l1 = 0, ssim = 0, total = 0;  ///< mean weighted L1, mean weighted SSIM, the loss
};

/// Loss of `render` against `target` (both [H][W][3]) and its gradient dL/drender
/// (written into `grad`, [H][W][3]; may be null). `weights` is [H][W] or null.
template <typename Real>
LossValue photometric_loss(const Real* render, const float* target, int width, int height, const Real* weights,
                           double lambda_dssim, Real* grad);

/// The PSNR of identical images, and the most any pair scores: 150 dB, above what any two
/// 8-bit images can differ by (one level in one channel of a 65536² image is 149 dB), so
/// the cap never changes a real difference and an exact match stays a finite number that
/// averages over a split (NaN is kept for "nothing to compare").
constexpr double kMaxPsnr = 150.0;
/// 10·log10(1 / mse), at most kMaxPsnr.
double psnr_of_mse(double mse);

/// Peak signal-to-noise ratio for images in [0, 1] (values clamped to [0, 1] first, like an
/// 8-bit save). `mask` ([H·W], nonzero = counted) restricts it to a region; kMaxPsnr when
/// equal, NaN when the mask counts no pixel.
double psnr(const float* a, const float* b, int width, int height, int channels, const unsigned char* mask = nullptr);

/// Mean SSIM over pixels and channels (window as above), images clamped to [0, 1].
double ssim(const float* a, const float* b, int width, int height, int channels);

}  // namespace fillgs
