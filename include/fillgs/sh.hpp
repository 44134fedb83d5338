#pragma once
// Real spherical harmonics exactly as the 3DGS code evaluates them (utils/sh_utils.py,
// cuda_rasterizer computeColorFromSH): rgb = Σ_k Y_k(d) sh_k + 0.5, clamped below at 0.
#include "fillgs/math.hpp"

namespace fillgs {

constexpr float kSHC0 = 0.28209479177387814f;

/// The (degree+1)² basis values Y_k(d) for a unit direction d, in 3DGS order and sign.
void sh_basis(int degree, const Vec3f& dir, float* out);

/// Colour of one Gaussian seen along unit direction `dir` (mean minus camera centre).
/// `coeffs` holds [(degree+1)²][3] coefficients. No upper clamp, like 3DGS.
Vec3f sh_to_rgb(int degree, const float* coeffs, const Vec3f& dir);

/// DC coefficient for a colour: (rgb - 0.5) / C0.
inline float rgb_to_sh_dc(float c) { return (c - 0.5f) / kSHC0; }

}  // namespace fillgs
