#pragma once
#include <cmath>
#include <cstddef>
// Real spherical harmonics exactly as the 3DGS code evaluates them (utils/sh_utils.py,
// cuda_rasterizer computeColorFromSH): rgb = Σ_k Y_k(d) sh_k + 0.5, clamped below at 0.
#include "fillgs/base/math.hpp"

namespace fillgs {

constexpr float kSHC0 = 0.28209479177387814f;

/// The (degree+1)² basis values Y_k(d) for a unit direction d, in 3DGS order and sign.
/// Generic in the scalar so that the backward pass can differentiate it (T needs +, −, ×
/// and construction from double).
template <typename T>
void sh_basis_generic(int degree, const T& x, const T& y, const T& z, T* Y) {
  const double C1 = 0.4886025119029199;
  const double C2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
                        0.5462742152960396};
  const double C3[7] = {-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
                        -0.4570457994644658, 1.445305721320277, -0.5900435899266435};
  Y[0] = T(0.28209479177387814);
  if (degree < 1) return;
  Y[1] = T(-C1) * y;
  Y[2] = T(C1) * z;
  Y[3] = T(-C1) * x;
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
  Y[4] = T(C2[0]) * xy;
  Y[5] = T(C2[1]) * yz;
  Y[6] = T(C2[2]) * (T(2.0) * zz - xx - yy);
  Y[7] = T(C2[3]) * xz;
  Y[8] = T(C2[4]) * (xx - yy);
  if (degree < 3) return;
  Y[9] = T(C3[0]) * y * (T(3.0) * xx - yy);
  Y[10] = T(C3[1]) * xy * z;
  Y[11] = T(C3[2]) * y * (T(4.0) * zz - xx - yy);
  Y[12] = T(C3[3]) * z * (T(2.0) * zz - T(3.0) * xx - T(3.0) * yy);
  Y[13] = T(C3[4]) * x * (T(4.0) * zz - xx - yy);
  Y[14] = T(C3[5]) * z * (xx - yy);
  Y[15] = T(C3[6]) * x * (xx - T(3.0) * yy);
}

void sh_basis(int degree, const Vec3f& dir, float* out);

/// Colour along unit direction (x, y, z) from [(degree+1)²][3] coefficients: Σ_k Y_k c_k + 0.5,
/// clamped below at 0 like 3DGS. Returns a bit per channel that was clamped (no gradient
/// flows through it). The one colour rule of both rasterizers.
template <typename Real>
unsigned sh_colour(int degree, const Real* coeffs, Real x, Real y, Real z, Real rgb[3]) {
  Real Y[16];
  sh_basis_generic<Real>(degree, x, y, z, Y);
  const int K = (degree + 1) * (degree + 1);
  unsigned clamped = 0;
  for (int c = 0; c < 3; ++c) {
    Real v = Real(0.5);
    for (int k = 0; k < K; ++k) v += Y[k] * coeffs[3 * k + c];
    if (v < Real(0)) {
      v = Real(0);
      clamped |= 1u << c;
    }
    rgb[c] = v;
  }
  return clamped;
}

/// Colour of one Gaussian seen along unit direction `dir` (mean minus camera centre).
/// `coeffs` holds [(degree+1)²][3] coefficients. No upper clamp, like 3DGS.
Vec3f sh_to_rgb(int degree, const float* coeffs, const Vec3f& dir);

/// DC coefficient for a colour: (rgb - 0.5) / C0.
/// The largest |Y_k| over directions of each of the 16 real SH basis functions (degree <= 3,
/// in the order and signs 3DGS evaluates them): a change d_k of coefficient k changes the
/// colour by at most sum_k |d_k| kSHBasisMax[k] in any direction. k = 0 is kSHC0; the rest are
/// the constants times the polynomials' maxima on the unit sphere (1, 1/2, 2, 1/(3 sqrt 3),
/// 4 sqrt(4/15)/3, ...), checked against 4,000,000 random directions.
constexpr float kSHBasisMax[16] = {0.28209479f, 0.48860251f, 0.48860251f, 0.48860251f, 0.54627422f, 0.54627422f, 0.63078313f, 0.54627422f,
                                   0.54627422f, 0.59004359f, 0.55629831f, 0.62937030f, 0.74635267f, 0.62937030f, 0.55629831f, 0.59004359f};

/// The largest change of channel `channel`'s colour in any direction between two Gaussians'
/// SH coefficients a and b ([coefficients][3] each): sum_k |a_k - b_k| kSHBasisMax[k], a bound
/// that the still rule and the training keys share; from coefficient `from` on (1: the bands
/// above the DC alone).
inline float sh_colour_change(const float* a, const float* b, size_t coefficients, size_t channel, size_t from = 0) {
  float change = 0.0f;
  for (size_t k = from; k < coefficients && k < 16; ++k) change += std::fabs(a[k * 3 + channel] - b[k * 3 + channel]) * kSHBasisMax[k];
  return change;
}

inline float rgb_to_sh_dc(float c) { return (c - 0.5f) / kSHC0; }

}  // namespace fillgs
