// Numerics at the extremes: tiny and huge Gaussians, saturated opacities, cameras inside
// Gaussians, the near plane, t = 0 and t = 1, and an empty scene. Finite output, no crash.
#include "fillgs/render/raster.hpp"
#include "fillgs/experiment/synth.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

TEST_CASE("scales from 1e-7 to 1e4 and opacity logits of +-40 render finite images", "[extremes]") {
  GaussianCloud c;
  int k = 0;
  for (float s : {1e-7f, 1e-3f, 1.0f, 1e2f, 1e4f})
    for (float o : {-40.0f, 0.0f, 40.0f}) {
      add_gaussian(c, Vec3f(0.3f * (k % 5) - 0.6f, 0.2f * (k / 5) - 0.2f, 3.0f + 0.1f * k), s, o, Vec3f(0.2f, 0.5f, 0.9f));
      ++k;
    }
  RenderOptions ro;
  ro.depth = true;
  ro.max_weights = true;
  const RenderOutput r = render(frame_at(c, 0), axis_camera(64, 48, 50), ro);
  CHECK(all_finite(r.rgb));
  CHECK(all_finite(r.depth));
  CHECK(all_finite(r.alpha));
  for (float a : r.alpha) CHECK((a >= 0.0f && a <= 1.0f));
  // Opacity logit -40 never reaches 1/255: those Gaussians contribute nothing anywhere.
  for (size_t g = 0; g < c.size(); g += 3) CHECK(r.max_weight[g] == 0.0f);
  // The 1e4 Gaussians cover the whole image.
  for (float a : r.alpha) CHECK(a > 0.9f);
}

TEST_CASE("a camera inside a Gaussian, at its mean, on the near plane, or in front of it", "[extremes]") {
  const Camera cam = axis_camera(32, 32, 30);
  SECTION("inside a huge Gaussian whose mean is ahead") {
    GaussianCloud c;
    add_gaussian(c, Vec3f(0, 0, 1), 100.0f, 40.0f, Vec3f(1, 1, 1));
    const RenderOutput r = render(frame_at(c, 0), cam);
    CHECK(all_finite(r.rgb));
    CHECK(r.rgb[(16 * 32 + 16) * 3] == Approx(0.99f));
  }
  SECTION("exactly at the mean (z = 0) and behind: culled, no NaN") {
    GaussianCloud c;
    add_gaussian(c, Vec3f(0, 0, 0), 1.0f, 40.0f, Vec3f(1, 1, 1));
    add_gaussian(c, Vec3f(0, 0, -3), 1.0f, 40.0f, Vec3f(1, 1, 1));
    const RenderOutput r = render(frame_at(c, 0), cam);
    CHECK(r.radii[0] == 0);
    CHECK(r.radii[1] == 0);
    for (float v : r.rgb) CHECK(v == 0.0f);
  }
  SECTION("on the near plane z = 0.2: culled; just beyond: drawn") {
    GaussianCloud c;
    add_gaussian(c, Vec3f(0, 0, 0.2f), 0.01f, 40.0f, Vec3f(1, 1, 1));
    add_gaussian(c, Vec3f(0, 0, 0.2001f), 0.01f, 40.0f, Vec3f(1, 1, 1));
    const RenderOutput r = render(frame_at(c, 0), cam);
    CHECK(r.radii[0] == 0);
    CHECK(r.radii[1] > 0);
    CHECK(all_finite(r.rgb));
  }
  SECTION("degenerate rotation (zero quaternion) becomes the identity") {
    GaussianCloud c;
    add_gaussian(c, Vec3f(0, 0, 3), 0.5f, 2.0f, Vec3f(1, 1, 1));
    c.rotations[0] = Vec4f::Zero();
    const RenderOutput r = render(frame_at(c, 0), cam);
    CHECK(all_finite(r.rgb));
    CHECK(r.radii[0] > 0);
  }
}

TEST_CASE("an empty scene renders the background", "[extremes]") {
  GaussianCloud c;
  RenderOptions o;
  o.background = Vec3f(0.25f, 0.5f, 1.0f);
  o.contributors = true;
  const RenderOutput r = render(frame_at(c, 0.5), axis_camera(20, 10, 10), o);
  for (size_t p = 0; p < 200; ++p) {
    CHECK(r.rgb[p * 3 + 0] == 0.25f);
    CHECK(r.rgb[p * 3 + 2] == 1.0f);
    CHECK(r.alpha[p] == 0.0f);
  }
  CHECK(r.contributors.ids.empty());
  CHECK(r.contributors.offsets.size() == 201);
}

TEST_CASE("t = 0 and t = 1 evaluate the end keys and times outside [0, 1] clamp", "[extremes][motion]") {
  const SynthScene s = small_synth(5, 64, 48, 0.05);
  const GaussianCloud& c = s.scene;
  const size_t K = 5;
  const FrameGaussians a = frame_at(c, 0.0), b = frame_at(c, 1.0);
  for (size_t j = 0; j < c.dynamic_count(); j += 97) {
    const uint32_t g = c.dynamic_ids[j];
    CHECK(a.means[g] == Eigen::Map<const Vec3f>(&c.keyframed.positions[j * K * 3]));
    CHECK(b.means[g] == Eigen::Map<const Vec3f>(&c.keyframed.positions[(j * K + K - 1) * 3]));
  }
  CHECK(frame_at(c, -0.5).means == a.means);
  CHECK(frame_at(c, 1.5).means == b.means);
  CHECK(all_finite(std::vector<float>(a.opacities)));
}
