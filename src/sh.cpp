#include "fillgs/sh.hpp"

#include <algorithm>

namespace fillgs {

namespace {
constexpr float C1 = 0.4886025119029199f;
constexpr float C2[5] = {1.0925484305920792f, -1.0925484305920792f, 0.31539156525252005f,
                         -1.0925484305920792f, 0.5462742152960396f};
constexpr float C3[7] = {-0.5900435899266435f, 2.890611442640554f, -0.4570457994644658f,
                         0.3731763325901154f, -0.4570457994644658f, 1.445305721320277f,
                         -0.5900435899266435f};
}  // namespace

void sh_basis(int degree, const Vec3f& d, float* Y) {
  Y[0] = kSHC0;
  if (degree < 1) return;
  const float x = d.x(), y = d.y(), z = d.z();
  Y[1] = -C1 * y;
  Y[2] = C1 * z;
  Y[3] = -C1 * x;
  if (degree < 2) return;
  const float xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
  Y[4] = C2[0] * xy;
  Y[5] = C2[1] * yz;
  Y[6] = C2[2] * (2.0f * zz - xx - yy);
  Y[7] = C2[3] * xz;
  Y[8] = C2[4] * (xx - yy);
  if (degree < 3) return;
  Y[9] = C3[0] * y * (3.0f * xx - yy);
  Y[10] = C3[1] * xy * z;
  Y[11] = C3[2] * y * (4.0f * zz - xx - yy);
  Y[12] = C3[3] * z * (2.0f * zz - 3.0f * xx - 3.0f * yy);
  Y[13] = C3[4] * x * (4.0f * zz - xx - yy);
  Y[14] = C3[5] * z * (xx - yy);
  Y[15] = C3[6] * x * (xx - 3.0f * yy);
}

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
