#include "fillgs/model/sh.hpp"

#include <algorithm>

namespace fillgs {

void sh_basis(int degree, const Vec3f& d, float* Y) { sh_basis_generic<float>(degree, d.x(), d.y(), d.z(), Y); }

Vec3f sh_to_rgb(int degree, const float* coeffs, const Vec3f& dir) {
  Vec3f rgb;
  sh_colour<float>(degree, coeffs, dir.x(), dir.y(), dir.z(), rgb.data());
  return rgb;
}

}  // namespace fillgs
