#pragma once
// The SSIM window as a separable filter: 11 taps, σ = 1.5, zero padding (PyTorch conv2d
// with padding 5, as the 3DGS loss). The vector path (Google Highway, instruction set
// chosen at run time); the scalar reference is the loop in loss.cpp.
namespace fillgs::image {

constexpr int kBlurTaps = 11;

/// The normalised window, tap k at offset k − 5.
const float* blur_window();

/// out = window ⊛ in along x then y, one [H][W] plane; `scratch` holds W·H floats.
/// Threads over rows (TBB, the caller's arena); the result does not depend on them.
void blur11_simd(const float* in, int width, int height, float* scratch, float* out);

}  // namespace fillgs::image
