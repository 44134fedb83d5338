#include "fillgs/sh.hpp"

#include <algorithm>

namespace fillgs {

void sh_basis(int degree, const Vec3f& d, float* Y) { sh_basis_generic<float>(degree, d.x(), d.y(), d.z(), Y); }

Vec3f sh_to_rgb(int degree, const float* coeffs, const Vec3f& dir) {
  float Y[16];
  sh_basis(degree, dir, Y);
  const int K = (degree + 1) * (degree + 1);
  Vec3f rgb(0.5f, 0.5f, 0.5f);
  for (int k = 0; k < K; ++k)
    for (int c = 0; c < 3; ++c) rgb[c] += Y[k] * coeffs[3 * k + c];
  return rgb.cwiseMax(0.0f);
}

}  // namespace fillgs
