// The rasterizer against closed forms: a single Gaussian's footprint (centre, 1σ, 2σ,
// the tile-rectangle cut-off at 3σ, the 0.3 dilation), the α clamps and the
// transmittance stop, and threads against a single thread, bit for bit.
#include <cstring>

#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/experiment/synth.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

struct Footprint {
  double a, c;  // dilated 2D covariance diagonal (b = 0 for a mean at y = 0 plane)
};

/// 2D covariance of an isotropic Gaussian of std s at camera-space (x, 0, z), by hand:
/// J = [[f/z, 0, -f x/z²], [0, f/z, 0]], Σ2 = s² J Jᵀ + 0.3 I.
Footprint footprint(double s, double x, double z, double f) {
  const double j00 = f / z, j02 = -f * x / (z * z);
  return {s * s * (j00 * j00 + j02 * j02) + 0.3, s * s * (f / z) * (f / z) + 0.3};
}

float pixel(const RenderOutput& r, int x, int y, int ch = 0) { return r.rgb[(size_t(y) * r.width + x) * 3 + ch]; }

}  // namespace

TEST_CASE("single Gaussian: centre, 1 sigma and 2 sigma match the analytic footprint", "[raster]") {
  const double f = 64, z = 5;
  const Camera cam = axis_camera(64, 64, f);
  // Mean on pixel centre (31, 31): u = f x / z + cx - 0.5 = 31 → x = -0.5 z / f.
  const double x = -0.5 * z / f;
  // Choose s so that the dilated variance along x is exactly 16 px² (σ = 4 px).
  const double s = std::sqrt((16.0 - 0.3) / ((f / z) * (f / z) + (f * x / (z * z)) * (f * x / (z * z))));
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(float(x), float(-0.5 * z / f), float(z)), float(s), logit(0.8f), Vec3f(1, 1, 1));
  const RenderOutput r = render(frame_at(cloud, 0), cam);
  const Footprint fp = footprint(s, x, z, f);
  REQUIRE(fp.a == Approx(16.0));
  // Σ2 also has an off-diagonal term from y = -0.5 z/f; include it exactly.
  const double y = -0.5 * z / f;
  const double b = s * s * (f * x / (z * z)) * (f * y / (z * z));
  const double c = fp.c + s * s * (f * y / (z * z)) * (f * y / (z * z));
  const double det = fp.a * c - b * b;
  auto analytic = [&](double dx, double dy) {
    const double power = -0.5 * (c * dx * dx + fp.a * dy * dy - 2 * b * dx * dy) / det;
    return 0.8 * std::exp(power);
  };
  CHECK(pixel(r, 31, 31) == Approx(0.8).epsilon(1e-5));
  CHECK(pixel(r, 35, 31) == Approx(analytic(4, 0)).epsilon(1e-4));  // 1σ: ≈ 0.8 e^-0.5
  CHECK(pixel(r, 39, 31) == Approx(analytic(8, 0)).epsilon(1e-4));  // 2σ: ≈ 0.8 e^-2
  CHECK(pixel(r, 27, 31) == Approx(analytic(4, 0)).epsilon(1e-4));
  REQUIRE(analytic(4, 0) == Approx(0.8 * std::exp(-0.5)).epsilon(2e-3));  // premise: 4 px is 1σ
  // White Gaussian on black: the three channels agree, alpha equals the value.
  CHECK(pixel(r, 35, 31, 1) == pixel(r, 35, 31, 0));
  CHECK(r.alpha[31 * 64 + 35] == Approx(pixel(r, 35, 31)).epsilon(1e-6));
  // Radius = ceil(3 sqrt(λmax)) with 3DGS's floor: λ = mid + sqrt(max(0.1, mid² − det)).
  const double mid = 0.5 * (fp.a + c);
  CHECK(r.radii[0] == int(std::ceil(3 * std::sqrt(mid + std::sqrt(std::max(0.1, mid * mid - det))))));
}

TEST_CASE("single Gaussian: nothing is drawn outside the tiles of its 3-sigma rectangle", "[raster]") {
  // σ = 10 px: λmax = 100 + sqrt(0.1) (3DGS's floor), radius ceil(3·10.016) = 31. With the
  // mean at u = 47.2 the rectangle starts at tile 1 (pixel 16). Pixel 15 is 3.22σ away,
  // where α = min(0.99, 1·e^{-5.18}) ≈ 0.0056 > 1/255, yet 3DGS draws nothing there.
  const double f = 64, z = 5;
  const Camera cam = axis_camera(64, 64, f);
  const double x = (47.2 - 31.5) * z / f;  // u = f x/z + 32 - 0.5
  const double jx = f * x / (z * z);
  const double s = std::sqrt((100.0 - 0.3) / ((f / z) * (f / z) + jx * jx));
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(float(x), float(-0.5 * z / f), float(z)), float(s), 40.0f, Vec3f(1, 1, 1));
  const RenderOutput r = render(frame_at(cloud, 0), cam);
  REQUIRE(r.radii[0] == 31);
  const double a15 = std::exp(-0.5 * (32.2 * 32.2) / 100.0);
  REQUIRE(a15 > 1.0 / 255.0);
  CHECK(pixel(r, 15, 31) == 0.0f);
  CHECK(pixel(r, 16, 31) == Approx(std::exp(-0.5 * (31.2 * 31.2) / 100.0)).epsilon(1e-4));
}

TEST_CASE("the 0.3 dilation sets the footprint of a vanishing Gaussian", "[raster]") {
  const Camera cam = axis_camera(32, 32, 32);
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(-0.5f * 4 / 32, -0.5f * 4 / 32, 4), 1e-6f, logit(0.9f), Vec3f(1, 1, 1));
  const RenderOutput r = render(frame_at(cloud, 0), cam);
  CHECK(pixel(r, 15, 15) == Approx(0.9).epsilon(1e-5));
  CHECK(pixel(r, 16, 15) == Approx(0.9 * std::exp(-0.5 / 0.3)).epsilon(1e-4));
  REQUIRE(0.9 * std::exp(-0.5 * 4 / 0.3) < 1.0 / 255);  // premise of the next check
  CHECK(pixel(r, 17, 15) == 0.0f);  // 0.9 e^{-6.67} ≈ 0.0011 < 1/255: skipped
}

TEST_CASE("alpha clamps at 0.99, drops below 1/255, and blending stops before T < 1e-4", "[raster]") {
  const Camera cam = axis_camera(16, 16, 16);
  const Vec3f at(-0.5f / 16, -0.5f / 16, 1);  // pixel (7, 7) at depth 1; scaled per depth below
  SECTION("opacity 1 is clamped to 0.99") {
    GaussianCloud c;
    add_gaussian(c, at * 5, 1e-6f, 40.0f, Vec3f(1, 1, 1));
    CHECK(pixel(render(frame_at(c, 0), cam), 7, 7) == Approx(0.99f).epsilon(1e-6));
  }
  SECTION("opacity under 1/255 draws nothing") {
    GaussianCloud c;
    add_gaussian(c, at * 5, 0.1f, logit(0.0035f), Vec3f(1, 1, 1));
    const RenderOutput r = render(frame_at(c, 0), cam);
    for (float v : r.rgb) CHECK(v == 0.0f);
  }
  SECTION("the Gaussian that would take T under 1e-4 is not blended") {
    // α 0.99 → T = 0.01; α 0.9 → T = 0.001; the third (α 0.99) would leave 1e-5 < 1e-4.
    GaussianCloud c;
    add_gaussian(c, at * 5, 1e-6f, 40.0f, Vec3f(1, 0, 0));
    add_gaussian(c, at * 6, 1e-6f, logit(0.9f), Vec3f(0, 1, 0));
    add_gaussian(c, at * 7, 1e-6f, 40.0f, Vec3f(0, 0, 1));
    RenderOptions o;
    o.contributors = true;
    const RenderOutput r = render(frame_at(c, 0), cam, o);
    CHECK(pixel(r, 7, 7, 0) == Approx(0.99).epsilon(1e-6));
    CHECK(pixel(r, 7, 7, 1) == Approx(0.01 * 0.9).epsilon(1e-4));
    CHECK(pixel(r, 7, 7, 2) == 0.0f);
    CHECK(r.alpha[7 * 16 + 7] == Approx(1 - 1e-3).epsilon(1e-6));
    const size_t p = 7 * 16 + 7;
    REQUIRE(r.contributors.offsets[p + 1] - r.contributors.offsets[p] == 2);
    CHECK(r.contributors.ids[r.contributors.offsets[p]] == 0);
    CHECK(r.contributors.ids[r.contributors.offsets[p] + 1] == 1);
  }
}

TEST_CASE("depth, alpha and feature channels blend like colour", "[raster]") {
  const Camera cam = axis_camera(16, 16, 16);
  GaussianCloud c;
  add_gaussian(c, Vec3f(-0.5f / 16 * 3, -0.5f / 16 * 3, 3), 1e-6f, logit(0.5f), Vec3f(1, 1, 1));
  add_gaussian(c, Vec3f(-0.5f / 16 * 6, -0.5f / 16 * 6, 6), 1e-6f, logit(0.5f), Vec3f(1, 1, 1));
  const float features[4] = {2.0f, -1.0f, 10.0f, 4.0f};  // [N][2]
  RenderOptions o;
  o.depth = true;
  o.features = features;
  o.feature_channels = 2;
  const RenderOutput r = render(frame_at(c, 0), cam, o);
  const size_t p = 7 * 16 + 7;
  // Weights 0.5 and 0.5 * 0.5.
  CHECK(r.depth[p] == Approx(0.5 * 3 + 0.25 * 6).epsilon(1e-5));
  CHECK(r.alpha[p] == Approx(0.75).epsilon(1e-6));
  CHECK(r.features[p * 2 + 0] == Approx(0.5 * 2 + 0.25 * 10).epsilon(1e-5));
  CHECK(r.features[p * 2 + 1] == Approx(0.5 * -1 + 0.25 * 4).epsilon(1e-5));
}

TEST_CASE("multi-threaded render equals single-threaded render bit for bit", "[raster]") {
  const SynthScene s = small_synth(5, 200, 150);
  FrameSampler ev(s.scene);
  for (int cam : {0, 5, 8}) {
    RenderOptions o;
    o.depth = true;
    o.max_weights = true;
    const FrameGaussians& g = ev.at(0.5);
    const RenderOutput a = with_threads(1, [&] { return render(g, s.train[size_t(cam)], o); });
    const RenderOutput b = with_threads(4, [&] { return render(g, s.train[size_t(cam)], o); });
    REQUIRE(a.rgb.size() == b.rgb.size());
    CHECK(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0);
    CHECK(std::memcmp(a.depth.data(), b.depth.data(), a.depth.size() * sizeof(float)) == 0);
    CHECK(std::memcmp(a.alpha.data(), b.alpha.data(), a.alpha.size() * sizeof(float)) == 0);
    CHECK(a.max_weight == b.max_weight);
  }
}

TEST_CASE("SH degree 2 on the real playbot scene renders view-dependent colour, identically across threads",
          "[raster][data]") {
  const GaussianCloud c = read_scene(shared_data() + "/scenes/playbot_3k.ply");
  REQUIRE(c.sh_degree == 2);
  Camera cam;
  cam.set_fov_x(1.0, 160, 120);
  cam.look_at(Vec3d(0, -0.5, -4), Vec3d(0, 0, 0), Vec3d(0, -1, 0));
  const FrameGaussians g = frame_at(c, 0);
  const RenderOutput a = with_threads(1, [&] { return render(g, cam); });
  const RenderOutput b = with_threads(3, [&] { return render(g, cam); });
  CHECK(a.rendered > 2000);
  CHECK(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0);
  // Dropping the higher-order terms changes the image: the SH rest is used.
  GaussianCloud dc = c;
  for (size_t g2 = 0; g2 < dc.size(); ++g2)
    for (int k = 1; k < dc.sh_count(); ++k)
      for (int ch = 0; ch < 3; ++ch) dc.sh[(g2 * dc.sh_count() + k) * 3 + ch] = 0.0f;
  const RenderOutput d = render(frame_at(dc, 0), cam);
  double diff = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) diff += std::fabs(a.rgb[i] - d.rgb[i]);
  CHECK(diff > 1.0);
}

TEST_CASE("per-pixel contributor lists reproduce the rendered colour", "[raster]") {
  const SynthScene s = small_synth(3, 96, 72);
  const FrameGaussians g = frame_at(s.scene, 0.5);
  RenderOptions o;
  o.contributors = true;
  const Camera& cam = s.train[8];
  const RenderOutput r = render(g, cam, o);
  // Re-blend each pixel from its list with colours computed independently (degree 0).
  const Vec3f campos = cam.centre().cast<float>();
  double max_err = 0;
  for (size_t p = 0; p < size_t(r.width) * r.height; ++p) {
    Vec3f acc = Vec3f::Zero();
    for (uint64_t k = r.contributors.offsets[p]; k < r.contributors.offsets[p + 1]; ++k) {
      const uint32_t id = r.contributors.ids[k];
      const Vec3f rgb = sh_to_rgb(0, g.sh + size_t(id) * 3, (g.means[id] - campos).normalized());
      acc += r.contributors.weights[k] * rgb;
    }
    for (int ch = 0; ch < 3; ++ch) max_err = std::max(max_err, double(std::fabs(acc[ch] - r.rgb[p * 3 + ch])));
  }
  CHECK(max_err < 1e-5);
  CHECK(r.contributors.ids.size() > size_t(r.width) * r.height);
}
