// The reference-conditioned refiners (reference, warp), the visible-set scale of D-hat and
// the weighted loss normalised by its mean weight.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>

#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/random.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/method/refine.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/method/weights.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/render/raster.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

/// A textured wall of opaque Gaussians in the plane z = `depth`, 4 m wide: a checker of two
/// colours with a colour ramp, so that a misplaced or blurred copy differs from it.
GaussianCloud textured_wall(double depth = 2.0) {
  GaussianCloud c;
  for (int i = -40; i <= 40; ++i)
    for (int j = -40; j <= 40; ++j) {
      const bool dark = ((i / 3) + (j / 3)) % 2 == 0;
      const Vec3f rgb = dark ? Vec3f(0.1f, 0.15f + 0.004f * float(i + 40), 0.2f) : Vec3f(0.9f, 0.8f, 0.3f + 0.005f * float(j + 40));
      add_gaussian(c, Vec3f(0.05f * float(i), 0.05f * float(j), float(depth)), 0.035f, logit(0.99f), rgb);
    }
  c.validate("textured_wall");
  return c;
}

/// A camera looking at the point (0, 0, depth) from `distance` away, turned by `degrees`
/// about the vertical (y) axis through that point.
Camera orbit_camera(double degrees, double depth = 2.0, double distance = 2.0) {
  Camera c = axis_camera(48, 36, 40);
  const double a = degrees * kPi / 180.0;
  const Vec3d centre(-distance * std::sin(a), 0.0, depth - distance * std::cos(a));
  Mat3d R;  // rows: the camera's x, y, z axes in the world (OpenCV: y down, z forward, x = y × z)
  const Vec3d z = (Vec3d(0, 0, depth) - centre).normalized();
  const Vec3d x = Vec3d(0, 1, 0).cross(z).normalized();
  R.row(0) = x.transpose(), R.row(1) = z.cross(x).transpose(), R.row(2) = z.transpose();
  c.R = R;
  c.t = -R * centre;
  c.time = 0.0;
  return c;
}

/// A patch of one observed image (the reference, at frame 0) and the given virtual views;
/// every image written to `in`: the reference from the truth, the renders a flat grey.
Patch write_test_patch(const std::string& in, const GaussianCloud& truth, const Camera& reference, const std::vector<Camera>& views) {
  make_directories(in);
  Patch p;
  p.name = "p";
  PatchImage ref;
  ref.file = "f0000_v0.png";
  ref.camera = reference;
  ref.observed = true;
  p.images.push_back(ref);
  write_image(join_path(in, ref.file), Image(reference.width, reference.height, 3, render(frame_at(truth, reference.time), reference).rgb));
  for (size_t k = 0; k < views.size(); ++k) {
    PatchImage im;
    im.file = "f0000_v" + std::to_string(k + 1) + ".png";
    im.camera = views[k];
    im.camera.name = "virtual" + std::to_string(k);
    im.view = int(k + 1);
    p.images.push_back(im);
    Image grey(views[k].width, views[k].height, 3);
    std::fill(grey.pixels.begin(), grey.pixels.end(), 0.5f);
    write_image(join_path(in, im.file), grey);
  }
  return p;
}

double max_difference(const std::vector<float>& a, const std::vector<float>& b) {
  REQUIRE(a.size() == b.size());
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, double(std::fabs(a[i] - b[i])));
  return worst;
}

ReferenceOptions test_options(uint64_t seed = 1) {
  ReferenceOptions o;  // the defaults (the benchmark's calibration lives in bench_reference_options)
  o.artifacts.strength = 0.5;
  o.artifacts.seed = seed;
  return o;
}

}  // namespace

TEST_CASE("reference refiner: a virtual view at the reference's pose gets the reference back", "[refine][reference]") {
  const GaussianCloud wall = textured_wall();
  const Camera ref = orbit_camera(0);
  const std::string d = scratch("reference_same");
  const Patch p = write_test_patch(join_path(d, "in"), wall, ref, {ref});
  SupportStats stats;
  const auto refiner = make_reference_refiner(wall, test_options(), &stats);
  refiner->refine(join_path(d, "in"), join_path(d, "out"), p);
  const Image out = read_image(join_path(join_path(d, "out"), "f0000_v1.png"));
  const Image reference = read_image(join_path(join_path(d, "in"), "f0000_v0.png"));
  // The same 8-bit image, to the rounding of one save.
  CHECK(max_difference(out.pixels, reference.pixels) <= 1.0 / 255 + 1e-6);
  REQUIRE(stats.views.size() == 1);
  CHECK(stats.views[0].parallax_degrees == Approx(0).margin(1e-3));
  CHECK(stats.views[0].support == 1.0);
  CHECK(stats.views[0].psnr_refined > 45);

  // The warp form does the same through a render whose geometry is right (the truth as the model).
  SupportStats warp_stats;
  const auto warp = make_warp_refiner(test_options(), &warp_stats, &wall);
  warp->begin_round(wall, Vec3f::Zero());
  warp->refine(join_path(d, "in"), join_path(d, "warp"), p);
  const Image warped = read_image(join_path(join_path(d, "warp"), "f0000_v1.png"));
  REQUIRE(warp_stats.views.size() == 1);
  INFO("warp support " << warp_stats.views[0].support << ", parallax " << warp_stats.views[0].parallax_degrees);
  CHECK(max_difference(warped.pixels, reference.pixels) <= 1.0 / 255 + 1e-6);
}

TEST_CASE("reference refiner: behind a wall the reference never saw, the output is the degraded render (no truth leaks)", "[refine][reference]") {
  // The oracle tests' scene: at frame 2 the red object stands behind the wall, hidden from the
  // reference camera at the origin; a camera behind the wall sees only the object.
  GaussianCloud truth;
  for (int i = -10; i <= 10; ++i)
    for (int j = -10; j <= 10; ++j) add_gaussian(truth, Vec3f(0.1f * i, 0.1f * j, 2.0f), 0.06f, logit(0.99f), Vec3f(0.8f, 0.8f, 0.7f));
  for (int i = -6; i <= 6; ++i)
    for (int j = -6; j <= 6; ++j) add_gaussian(truth, Vec3f(0.05f * i, 0.05f * j, 3.0f), 0.04f, logit(0.99f), Vec3f(0.9f, 0.1f, 0.1f));
  Camera ref = axis_camera(32, 24, 40);
  ref.time = 0.0;
  Camera behind = axis_camera(32, 24, 40);
  behind.R = Vec3d(1, -1, -1).asDiagonal();
  behind.t = -behind.R * Vec3d(0, 0, 3.5);
  behind.time = 0.0;
  const std::string d = scratch("reference_behind");
  const Patch p = write_test_patch(join_path(d, "in"), truth, ref, {behind});
  ReferenceOptions o = test_options(3);
  o.artifacts.strength = 0;  // only the fill: the expected image is then computed here exactly
  o.hallucination = 0.5;     // with misplaced reference texture in it
  SupportStats stats;
  make_reference_refiner(truth, o, &stats)->refine(join_path(d, "in"), join_path(d, "out"), p);
  const Image expected = reference_fill(read_image(join_path(join_path(d, "in"), "f0000_v1.png")),  // the render it was given
                                        read_image(join_path(join_path(d, "in"), "f0000_v0.png")), o.fill_strength, o.fill_blur * 32, o.hallucination,
                                        o.artifacts.seed, string_key("p/f0000_v1.png"));
  const Image out = read_image(join_path(join_path(d, "out"), "f0000_v1.png"));
  CHECK(max_difference(out.pixels, expected.pixels) <= 0.5 / 255 + 1e-6);  // one 8-bit rounding
  REQUIRE(stats.views.size() == 1);
  CHECK(stats.views[0].support == 0.0);
  // Not the red object.
  double red = 0;
  for (size_t q = 0; q < size_t(32 * 24); ++q) red += out.pixels[q * 3] - out.pixels[q * 3 + 1];
  CHECK(red / (32 * 24) < 0.3);
}

TEST_CASE("reference refiner: it cannot create geometry the render lacks", "[refine][reference]") {
  // The reference sees the wall at 2 m; the model of the round put it at 3 m, or nowhere:
  // the refined view is then the fill, as where the reference saw nothing.
  const GaussianCloud truth = textured_wall(2.0);
  const Camera ref = orbit_camera(0);
  const std::string d = scratch("reference_placed");
  const Patch p = write_test_patch(join_path(d, "in"), truth, ref, {orbit_camera(4)});
  ReferenceOptions o = test_options(5);
  o.artifacts.strength = 0;
  const Image expected = reference_fill(read_image(join_path(join_path(d, "in"), "f0000_v1.png")), read_image(join_path(join_path(d, "in"), "f0000_v0.png")),
                                        o.fill_strength, o.fill_blur * 48, o.hallucination, o.artifacts.seed, string_key("p/f0000_v1.png"));
  for (const GaussianCloud& model : {textured_wall(3.0), GaussianCloud()}) {
    SupportStats stats;
    const auto refiner = make_reference_refiner(truth, o, &stats);
    refiner->begin_round(model, Vec3f::Zero());
    const std::string out = join_path(d, model.size() ? "misplaced" : "empty");
    refiner->refine(join_path(d, "in"), out, p);
    CHECK(max_difference(read_image(join_path(out, "f0000_v1.png")).pixels, expected.pixels) <= 0.5 / 255 + 1e-6);
    REQUIRE(stats.views.size() == 1);
    CHECK(stats.views[0].support < 1e-6);
  }
  // The model that places the wall right gets the reference's content back (most of the view seen).
  SupportStats stats;
  const auto refiner = make_reference_refiner(truth, o, &stats);
  refiner->begin_round(truth, Vec3f::Zero());
  refiner->refine(join_path(d, "in"), join_path(d, "right"), p);
  REQUIRE(stats.views.size() == 1);
  CHECK(stats.views[0].support > 0.95);
}

TEST_CASE("reference refiner: its error grows with the angle to the reference on a planar textured scene", "[refine][reference]") {
  const GaussianCloud wall = textured_wall();
  const std::vector<double> angles = {0, 3, 6, 10, 15, 20, 30};
  std::vector<Camera> views;
  for (double a : angles) views.push_back(orbit_camera(a));
  const std::string d = scratch("reference_angle");
  const Patch p = write_test_patch(join_path(d, "in"), wall, orbit_camera(0), views);
  SupportStats stats;
  make_reference_refiner(wall, test_options(), &stats)->refine(join_path(d, "in"), join_path(d, "out"), p);
  REQUIRE(stats.views.size() == angles.size());
  for (size_t k = 0; k < angles.size(); ++k) {
    INFO("angle " << angles[k] << ": parallax " << stats.views[k].parallax_degrees << ", PSNR " << stats.views[k].psnr_refined);
    // The parallax at the wall's centre is the orbit angle; over the view it varies a little.
    CHECK(stats.views[k].parallax_degrees == Approx(angles[k]).margin(0.15 * angles[k] + 0.01));
    if (k > 0) CHECK(stats.views[k].psnr_refined < stats.views[k - 1].psnr_refined);
  }
  // Several dB over 0-30 degrees (the calibration's requirement (a)).
  CHECK(stats.views[1].psnr_refined - stats.views.back().psnr_refined > 5.0);
}

TEST_CASE("reference refiner: seeded", "[refine][reference]") {
  const GaussianCloud wall = textured_wall();
  const std::string d = scratch("reference_seed");
  const Patch p = write_test_patch(join_path(d, "in"), wall, orbit_camera(0), {orbit_camera(12)});
  auto run = [&](uint64_t seed, const std::string& name) {
    make_reference_refiner(wall, test_options(seed))->refine(join_path(d, "in"), join_path(d, name), p);
    return read_image(join_path(join_path(d, name), "f0000_v1.png")).pixels;
  };
  const std::vector<float> a = run(1, "a"), b = run(1, "b"), c = run(2, "c");
  CHECK(a == b);
  CHECK(a != c);
}

TEST_CASE("reference refiner: bad options are refused", "[refine][reference]") {
  const GaussianCloud wall = textured_wall();
  ReferenceOptions o;
  o.angle_scale_degrees = 0;
  CHECK_THROWS_WITH(make_reference_refiner(wall, o), Catch::Contains("angle scale"));
  o = ReferenceOptions();
  o.flicker = std::nan("");
  CHECK_THROWS_WITH(make_warp_refiner(o), Catch::Contains("finite"));
}

TEST_CASE("co-visibility scale: the opacity-weighted quantile over the visible moving Gaussians of each frame", "[refine][weights]") {
  // Two frames, five moving Gaussians; D and opacities by hand.
  ObservationTables t;
  t.times = {0.0, 1.0};
  t.gaussians = 6;
  t.dynamic_ids = {1, 2, 3, 4, 5};
  t.counts.assign(12, 0);
  t.dynamic_speed = {1, 2, 3, 4, 50, 1, 1, 1, 1, 1};
  t.dynamic_deficiency = {1, 2, 3, 4, 50, 0.5f, 0.25f, 0, 2, 8};
  // Opacity tenths: frame 0 — the fast one (D = 50) is faint (0.1) and another invisible.
  const std::vector<float> opacity = {0.5f, 0.3f, 0.8f, 0.0f, 0.1f, 0.9f, 0.9f, 0.9f, 0.2f, 0.1f};
  for (double q : {0.5, 0.9, 0.99}) {
    const DeficiencyField field(t, float(q), &opacity);
    // Independent: each visible Gaussian (opacity >= 1/255, D > 0) repeated (opacity in
    // tenths) times, the smallest value whose running count reaches q of the total.
    for (int f = 0; f < 2; ++f) {
      std::vector<float> repeated;
      for (size_t j = 0; j < 5; ++j) {
        const float D = t.dynamic_deficiency[size_t(f) * 5 + j], a = opacity[size_t(f) * 5 + j];
        if (D > 0 && a >= 1.0f / 255)
          for (int k = 0; k < int(std::lround(a * 10)); ++k) repeated.push_back(D);
      }
      std::sort(repeated.begin(), repeated.end());
      const size_t at = size_t(std::ceil(q * double(repeated.size()) - 1e-9)) - 1;
      INFO("quantile " << q << ", frame " << f);
      CHECK(field.scale(f) == Approx(repeated[at]));
    }
    // The global scale: every moving Gaussian of every frame with D > 0, unweighted, the
    // value at rank round(q · (n − 1)) of the sorted D.
    std::vector<float> all;
    for (float D : t.dynamic_deficiency)
      if (D > 0) all.push_back(D);
    std::sort(all.begin(), all.end());
    CHECK(DeficiencyField(t, float(q)).scale(0) == all[size_t(std::lround(q * double(all.size() - 1)))]);
  }
  // Frame 0 at q = 0.9: the faint fast Gaussian does not set the scale (it did globally).
  CHECK(DeficiencyField(t, 0.9f, &opacity).scale(0) == 3.0f);
  CHECK(DeficiencyField(t, 0.9f).scale(0) == 8.0f);
  CHECK(weighted_quantile({}, {}, 0.5) == 1.0f);
}

TEST_CASE("weights normalised by their mean: a uniformly weighted view's gradient is the unweighted one", "[refine][weights]") {
  const int W = 24, H = 16;
  const size_t P = size_t(W) * H;
  std::vector<float> render_img(P * 3), target(P * 3);
  for (size_t i = 0; i < P * 3; ++i) render_img[i] = float(uniform(7, i, 0)), target[i] = float(uniform(7, i, 1));
  std::vector<float> g1(P * 3), gw(P * 3);
  photometric_loss<float>(render_img.data(), target.data(), W, H, nullptr, 0.2, g1.data());
  for (float c : {0.01f, 0.3f, 1.0f, 4.0f}) {
    std::vector<float> w(P, c);
    normalise_by_mean(w);
    photometric_loss<float>(render_img.data(), target.data(), W, H, w.data(), 0.2, gw.data());
    for (size_t i = 0; i < P * 3; ++i) REQUIRE(gw[i] == Approx(g1[i]).margin(1e-9));
  }
  // A non-uniform map keeps its shape and gets mean 1; an all-zero map stays zero.
  std::vector<float> w(P);
  for (size_t p = 0; p < P; ++p) w[p] = float(p % 5) * 0.01f;
  const std::vector<float> before = w;
  normalise_by_mean(w);
  double sum = 0;
  for (float x : w) sum += x;
  CHECK(sum / double(P) == Approx(1.0));
  CHECK(w[3] / w[1] == Approx(before[3] / before[1]));
  std::vector<float> zero(P, 0.0f);
  normalise_by_mean(zero);
  CHECK(*std::max_element(zero.begin(), zero.end()) == 0.0f);
}

TEST_CASE("patch.json reads back as written: cameras, frames, views and the observed flags", "[refine][reference]") {
  const std::string in = scratch("patch_read");
  const GaussianCloud wall = textured_wall();
  Camera reference = orbit_camera(0);
  reference.name = "images/cam00/0000";
  Patch p = write_test_patch(in, wall, reference, {orbit_camera(7), orbit_camera(-12.5)});
  p.images[2].frame = 3, p.images[2].camera.time = 0.375, p.images[2].order = 2;
  // write_patch writes the same patch through the protocol's own writer.
  std::vector<ObservedView> views = {{reference, 0, 0}};
  p.observed_view = 0;
  const std::string dir = join_path(in, "written");
  write_patch(dir, p, views, [&](size_t) { return render(frame_at(wall, 0.0), reference).rgb; },
              [](const Camera& c) { return std::vector<float>(size_t(c.width) * c.height * 3, 0.5f); });
  const Patch back = read_patch(dir);
  CHECK(back.name == p.name);
  REQUIRE(back.images.size() == p.images.size());
  for (size_t i = 0; i < p.images.size(); ++i) {
    const PatchImage &a = p.images[i], &b = back.images[i];
    CHECK(b.file == a.file);
    CHECK(b.frame == a.frame);
    CHECK(b.view == a.view);
    CHECK(b.order == a.order);
    CHECK(b.observed == a.observed);
    CHECK(b.camera.name == a.camera.name);
    CHECK(b.camera.width == a.camera.width);
    CHECK(b.camera.fx == a.camera.fx);
    CHECK(b.camera.cy == a.camera.cy);
    CHECK(b.camera.time == a.camera.time);
    CHECK((b.camera.R - a.camera.R).norm() < 1e-12);
    CHECK((b.camera.centre() - a.camera.centre()).norm() < 1e-12);
  }
  // Damaged files name the file, the image and the field.
  auto refused = [&](const std::string& json, const std::string& what) {
    const std::string bad = join_path(in, "bad");
    make_directories(bad);
    write_file_atomically(join_path(bad, "patch.json"), json);
    try {
      read_patch(bad);
      FAIL("accepted: " << json);
    } catch (const Error& e) {
      INFO(e.what());
      CHECK(std::string(e.what()).find(join_path(bad, "patch.json")) != std::string::npos);
      CHECK(std::string(e.what()).find(what) != std::string::npos);
    }
  };
  const std::string camera = R"({"name":"v","width":48,"height":36,"fx":40,"fy":40,"cx":24,"cy":18,"time":0,)"
                             R"("camera_to_world_opencv":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})";
  refused(R"({"images":[{"file":"a.png","order":0,"view":0,"observed":true,"camera":)" + camera + "}]}", "image 0: 'frame' is missing");
  refused(R"({"images":[{"file":"../a.png","order":0,"frame":0,"view":0,"observed":true,"camera":)" + camera + "}]}", "plain file name");
  std::string sheared = camera;
  sheared.replace(sheared.find("[1,0,0,0]"), 9, "[1,0.5,0,0]");
  refused(R"({"images":[{"file":"a.png","order":0,"frame":0,"view":0,"observed":true,"camera":)" + sheared + "}]}", "not a rigid transform");
  refused(R"({"images":3})", "no 'images' list");
}

namespace {
/// A colour texture with no repeating structure at the scale of a few pixels: three sums
/// of sinusoids with incommensurate frequencies, one per channel, in [0.1, 0.9].
double texture(double x, double y, int c) {
  const double a = 0.31 + 0.07 * c, b = 0.23 + 0.05 * c;
  return 0.5 + 0.13 * std::sin(a * x + 1.3 * c) + 0.13 * std::sin(b * y + 0.4) + 0.14 * std::sin(0.11 * x + 0.17 * y + c);
}
Image textured(int W, int H, const std::function<double(int, int, int)>& value) {
  Image im(W, H, 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y, c) = float(value(x, y, c));
  return im;
}
}  // namespace

TEST_CASE("flow check: a shifted copy passes, content duplicated by a fold or another texture fails", "[refine][weights]") {
  const int W = 96, H = 72;
  const Image reference = textured(W, H, [](int x, int y, int c) { return texture(x, y, c); });
  // Shifted by (3, 2): every pixel whose partner lies inside the reference has an exact match.
  const Image shifted = textured(W, H, [](int x, int y, int c) { return texture(x + 3, y + 2, c); });
  const std::vector<uint8_t> pass = flow_consistency(shifted, reference);
  size_t inside = 0, inside_pass = 0;
  for (int y = 8; y < H - 8; ++y)
    for (int x = 8; x < W - 8; ++x) ++inside, inside_pass += pass[size_t(y) * W + x];
  CHECK(double(inside_pass) / double(inside) >= 0.9);
  // A fold: both halves of the image show the reference's middle band, so each of its
  // pixels has two partners and the flow back returns to at most one of them.
  const Image folded = textured(W, H, [&](int x, int y, int c) { return x < W / 2 ? texture(x + W / 4, y, c) : texture(x - W / 4, y, c); });
  const std::vector<uint8_t> fold_pass = flow_consistency(folded, reference);
  size_t folded_pass = 0;
  for (uint8_t v : fold_pass) folded_pass += v;
  CHECK(double(folded_pass) / double(W * H) <= 0.55);
  // Unrelated content (the texture at other frequencies) mostly fails.
  const Image other = textured(W, H, [](int x, int y, int c) { return texture(1.7 * y + 5, 1.3 * x, 2 - c); });
  const std::vector<uint8_t> other_pass = flow_consistency(other, reference);
  size_t n = 0;
  for (uint8_t v : other_pass) n += v;
  CHECK(double(n) / double(W * H) <= 0.2);
  CHECK_THROWS_WITH(flow_consistency(Image(W, H, 3), Image(W + 1, H, 3)), Catch::Contains("one size"));
}
