#pragma once
// The SSIM window as a separable filter: 11 taps, σ = 1.5, zero padding (PyTorch conv2d
// with padding 5, as the 3DGS loss). The window is defined here once; the training loss's
// vector SSIM (Google Highway, instruction set chosen at run time) is ssim_simd.cpp, the
// scalar reference the loops in loss.cpp.
#include <cmath>

namespace fillgs::image {

constexpr int kBlurTaps = 11;
constexpr double kSsimC1 = 0.01 * 0.01, kSsimC2 = 0.03 * 0.03;  ///< the SSIM's constants

/// The normalised window in Real (computed in double), tap k at offset k − 5.
template <typename Real>
const Real* ssim_window() {
  static const struct Window {
    Real w[kBlurTaps];
    Window() {
      double v[kBlurTaps], sum = 0;
      for (int i = 0; i < kBlurTaps; ++i) v[i] = std::exp(-double((i - 5) * (i - 5)) / (2 * 1.5 * 1.5)), sum += v[i];
      for (int i = 0; i < kBlurTaps; ++i) w[i] = Real(v[i] / sum);
    }
  } window;
  return window.w;
}

/// The float training loss's SSIM part with the vector kernel, fused: for each channel c of
/// the [H][W][3] images, ssim_out[c][p] = w[p]·SSIM_c(p) (w: weights[p], or 1 when null) and,
/// when grad is not null, grad[p][c] = l1_scale·w[p]·sign(render − target) − ssim_scale ·
/// d(Σ_p w[p]·SSIM_c(p))/d render[p][c]. Each blur output is a chain of the instruction
/// set's multiply-add over the taps in order (ssim_simd.cpp), every other operation rounds as
/// loss.cpp's scalar terms; the values do not depend on the thread count.
void ssim_loss_simd(const float* render, const float* target, const float* weights, int width, int height, float l1_scale,
                    float ssim_scale, float* const* ssim_out, float* grad);

}  // namespace fillgs::image
