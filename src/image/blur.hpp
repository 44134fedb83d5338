#pragma once
// The SSIM window as a separable filter: 11 taps, σ = 1.5, zero padding (PyTorch conv2d
// with padding 5, as the 3DGS loss). The window is defined here once; the vector blur
// (Google Highway, instruction set chosen at run time) is blur_simd.cpp, the scalar
// reference the loop in loss.cpp.
#include <cmath>

namespace fillgs::image {

constexpr int kBlurTaps = 11;

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

/// out[p] = window ⊛ (a[p] ⊙ b[p]) along x then y, for `planes` [H][W] planes at once (b[p]
/// null: a[p] itself; the SSIM's five windows in one call), in strips of rows whose row pass
/// stays in the cache for the column pass. Each plane's values are those of a call for it
/// alone with its product formed first, and do not depend on the thread count (TBB, the
/// caller's arena, over strips).
void blur11_planes_simd(int planes, const float* const* a, const float* const* b, int width, int height, float* const* out);

}  // namespace fillgs::image
