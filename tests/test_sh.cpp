// SH evaluation against values computed by hand (Python, double precision, from the
// constants in the 3DGS sh_utils.py) for d = (1, 2, 3)/sqrt(14).
#include "fillgs/model/sh.hpp"

#include "helpers.hpp"

using namespace fillgs;

TEST_CASE("SH basis matches hand-computed values for degrees 0-3", "[sh]") {
  const Vec3f d = Vec3f(1, 2, 3).normalized();
  const double expected[16] = {0.28209479177387814, -0.261169028265409,   0.3917535423981135,   -0.1305845141327045,
                               0.15607834722743988, -0.46823504168231966, 0.29286359630591147,  -0.23411752084115983,
                               -0.11705876042057992, 0.022527968946608582, 0.331092173162734,   -0.5409527810353757,
                               0.06411572363594459, -0.27047639051768785, -0.24831912987205046, 0.12390382920634718};
  float Y[16];
  sh_basis(3, d, Y);
  for (int k = 0; k < 16; ++k) {
    INFO("k = " << k);
    CHECK(Y[k] == Approx(expected[k]).margin(2e-7));
  }
}

TEST_CASE("SH colour per degree, with the lower clamp at 0 and no upper clamp", "[sh]") {
  const Vec3f d = Vec3f(1, 2, 3).normalized();
  // Coefficient k, channel c: 0.1 (k+1) * {1, -0.5, 0.25}[c].
  float coeffs[48];
  const float ch_scale[3] = {1.0f, -0.5f, 0.25f};
  for (int k = 0; k < 16; ++k)
    for (int c = 0; c < 3; ++c) coeffs[3 * k + c] = 0.1f * (k + 1) * ch_scale[c];
  const double expected[4][3] = {{0.5282094791773878, 0.4858952604113061, 0.507052369794347},
                                 {0.5412679305906583, 0.4793660347046709, 0.5103169826476646},
                                 {0.25072369555767454, 0.6246381522211627, 0.43768092388941865},
                                 {0.0 /* -0.48 clamped */, 0.9906196781675578, 0.2546901609162211}};
  for (int deg = 0; deg <= 3; ++deg) {
    const Vec3f rgb = sh_to_rgb(deg, coeffs, d);
    for (int c = 0; c < 3; ++c) {
      INFO("degree " << deg << " channel " << c);
      CHECK(rgb[c] == Approx(expected[deg][c]).margin(1e-6));
    }
  }
  // No upper clamp: a large DC gives a value above 1.
  float bright[3] = {10.0f, 0.0f, 0.0f};
  CHECK(sh_to_rgb(0, bright, d)[0] == Approx(0.5 + 10 * 0.28209479177387814));
}
