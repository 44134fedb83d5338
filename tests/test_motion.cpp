// Learning motion: keys for every Gaussian, extrapolation at the time window's frontier,
// the sparsity prior that folds still Gaussians back to static, the time curriculum, and a
// small scene where the trained model must follow the moving object.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

#include "fillgs/model/camera.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/train/flow.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/train/train_model.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

/// Two static Gaussians and one keyframed one (4 keys), fillgs conventions.
GaussianCloud two_static_one_moving() {
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 3), 0.1f, 1.0f, Vec3f(1, 0, 0));
  add_gaussian(c, Vec3f(0.5f, 0.1f, 3), 0.2f, -0.5f, Vec3f(0, 1, 0));
  add_gaussian(c, Vec3f(-0.5f, 0, 3), 0.15f, 0.5f, Vec3f(0, 0, 1));
  c.rotations[1] = Vec4f(0.9f, 0.1f, -0.3f, 0.2f);
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = {2};
  KeyframedMotion& k = c.keyframed;
  k.key_count = 4;
  k.key_spacing = 1.0 / 3;
  for (int i = 0; i < 4; ++i) {
    k.positions.insert(k.positions.end(), {-0.5f + 0.2f * i, 0.05f * i * i, 3.0f});
    const Vec4f q = normalize_quat(Vec4f(1.0f, 0.1f * i, 0.0f, 0.05f));
    k.rotations.insert(k.rotations.end(), {q[0], q[1], q[2], q[3]});
    k.opacity_logits.push_back(0.5f - 0.3f * i);
  }
  canonical_from_first_key(c);
  c.validate("test cloud");
  return c;
}

}  // namespace

TEST_CASE("keys for every Gaussian change nothing that renders", "[motion]") {
  const GaussianCloud c = two_static_one_moving();
  const ModelParams<float> before = params_from_cloud<float>(c);
  ModelParams<float> after = before;
  REQUIRE(key_every_gaussian(after) == 2);
  REQUIRE(after.dynamic_count() == 3);
  CHECK(after.keyed_opacity);
  for (double t : {0.0, 0.2, 0.5, 0.77, 1.0}) {
    DiffFrame<float> a, b;
    params_at(before, t, &a);
    params_at(after, t, &b);
    // Equal keys pass through Catmull-Rom weights (summing to 1) and a slerp (normalising
    // twice): the same values to float rounding.
    for (size_t i = 0; i < a.means.size(); ++i) CHECK(a.means[i] == Approx(b.means[i]).margin(1e-6));
    for (size_t i = 0; i < a.rotations.size(); ++i) CHECK(a.rotations[i] == Approx(b.rotations[i]).margin(1e-7));
    CHECK(a.scales == b.scales);
    CHECK(a.opacities == b.opacities);
  }
  // And the cloud written from it folds the still ones back: the same two static Gaussians.
  GaussianCloud back = cloud_from_params(after);
  partition_static_dynamic(back);
  CHECK(back.dynamic_ids == std::vector<uint32_t>{2});
}

TEST_CASE("opacity keys are added at each Gaussian's own opacity", "[motion]") {
  GaussianCloud c = two_static_one_moving();
  c.keyframed.opacity_logits.clear();
  ModelParams<float> p = params_from_cloud<float>(c);
  REQUIRE_FALSE(p.keyed_opacity);
  DiffFrame<float> a, b;
  params_at(p, 0.4, &a);
  add_key_opacities(p);
  REQUIRE(p.keyed_opacity);
  REQUIRE(p.key_opacity_logits.size() == 4);
  params_at(p, 0.4, &b);
  CHECK(a.opacities == b.opacities);
}

TEST_CASE("extrapolated keys continue at constant velocity and rotation rate", "[motion]") {
  ModelParams<float> p;
  p.sh_degree = 0;
  p.means = {0, 0, 0};
  p.log_scales = {0, 0, 0};
  p.rotations = {1, 0, 0, 0};
  p.opacity_logits = {0};
  p.sh = {0, 0, 0};
  p.key_count = 6;
  p.key_spacing = 0.2;
  p.dynamic_ids = {0};
  p.keyed_opacity = true;
  const Vec3d x0(0.1, -0.2, 3.0), v(0.05, 0.02, -0.01);
  const double angle = 0.3;  // per key, about a fixed axis
  const Vec3d axis = Vec3d(1, 2, 2).normalized();
  for (int k = 0; k < 6; ++k) {
    const Vec3d x = k < 2 ? Vec3d(x0 + k * v) : Vec3d(9, 9, 9);  // keys 2.. hold junk
    for (int a = 0; a < 3; ++a) p.key_positions.push_back(float(x[a]));
    const Eigen::Quaterniond q(Eigen::AngleAxisd(k < 2 ? k * angle : 2.0, axis));
    p.key_rotations.insert(p.key_rotations.end(), {float(q.w()), float(q.x()), float(q.y()), float(q.z())});
    p.key_opacity_logits.push_back(k < 2 ? 0.7f + 0.1f * k : -5.0f);
  }
  extrapolate_keys(p, 2);
  for (int k = 2; k < 6; ++k) {
    INFO("key " << k);
    const Vec3d expect = x0 + k * v;
    for (int a = 0; a < 3; ++a) CHECK(p.key_positions[3 * k + a] == Approx(expect[a]).margin(1e-5));
    const Eigen::Quaterniond q(Eigen::AngleAxisd(k * angle, axis));
    const Vec4d got(p.key_rotations[4 * k], p.key_rotations[4 * k + 1], p.key_rotations[4 * k + 2], p.key_rotations[4 * k + 3]);
    CHECK(std::fabs(got.dot(Vec4d(q.w(), q.x(), q.y(), q.z()))) == Approx(1.0).margin(1e-6));
    CHECK(p.key_opacity_logits[size_t(k)] == Approx(0.8f));
  }
}

TEST_CASE("the sparsity step folds small key deviations exactly and shrinks large ones by tau", "[motion]") {
  ModelParams<float> p;
  p.means = {0, 0, 0, 0, 0, 0};
  p.log_scales = p.means;
  p.rotations = {1, 0, 0, 0, 1, 0, 0, 0};
  p.opacity_logits = {0, 0};
  p.sh = p.means;
  p.key_count = 3;
  p.key_spacing = 0.5;
  p.dynamic_ids = {0, 1};
  p.keyed_opacity = true;
  // Gaussian 0 wanders by 1 mm around (1, 2, 3); Gaussian 1 moves 0.4 along x.
  p.key_positions = {1.001f, 2, 3, 0.999f, 2, 3, 1, 2.0005f, 3, 0, 0, 0, 0.2f, 0, 0, 0.4f, 0, 0};
  for (int k = 0; k < 6; ++k) p.key_rotations.insert(p.key_rotations.end(), {1, 0, 0, 0});
  p.key_rotations[4 * 4 + 0] = -1;  // the same rotation on the other hemisphere
  p.key_opacity_logits = {0.5f, 0.5f, 0.5f, 0.0f, 1.0f, 2.0f};
  const float tau = 0.01f;
  shrink_key_deviations(p, 3, tau, 0.01f, 0.1f);
  // Still: every key equal to the mean, exactly.
  for (int k = 1; k < 3; ++k)
    for (int a = 0; a < 3; ++a) CHECK(p.key_positions[3 * k + a] == p.key_positions[a]);
  CHECK(p.key_positions[0] == Approx(1.0f).margin(1e-6));
  // Moving: deviations (−0.2, 0, 0.2) along x, length 0.2828; shrunk by τ along themselves.
  const double n = 0.2 * std::sqrt(2.0), keep = 1 - tau / n;
  CHECK(p.key_positions[9 + 0] == Approx(0.2 - 0.2 * keep).margin(1e-6));
  CHECK(p.key_positions[9 + 3] == Approx(0.2f).margin(1e-6));
  CHECK(p.key_positions[9 + 6] == Approx(0.2 + 0.2 * keep).margin(1e-6));
  // The flipped quaternion is the same rotation: no deviation left, every key the identity.
  for (int k = 0; k < 3; ++k) CHECK(p.key_rotations[(3 + k) * 4] == Approx(1.0f));
  // Opacities: Gaussian 0's are equal already; Gaussian 1's (0, 1, 2) shrink by 0.1 in length.
  CHECK(p.key_opacity_logits[0] == 0.5f);
  const double on = std::sqrt(2.0), ok = 1 - 0.1 / on;
  CHECK(p.key_opacity_logits[3] == Approx(1 - ok).margin(1e-6));
  CHECK(p.key_opacity_logits[5] == Approx(1 + ok).margin(1e-6));
}

TEST_CASE("the time window grows a frame at a time over the ramp, then covers the video", "[motion][train]") {
  // A rig of 2 cameras without times over 10 frames: images/<camera>/<frame>.png.
  const std::string d = scratch("ramp");
  std::vector<Camera> rig = {axis_camera(8, 8, 8), axis_camera(8, 8, 8)};
  rig[0].name = "a";
  rig[1].name = "b";
  rig[1].t = Vec3d(0.1, 0, 0);
  write_transforms_json(join_path(d, "rig.json"), rig);
  Image im(8, 8, 3);
  for (const Camera& c : rig)
    for (int f = 0; f < 10; ++f) write_image(join_path(d, "images/" + c.name + "/" + std::to_string(100 + f) + ".png"), im);
  const Dataset data = Dataset::load(join_path(d, "images"), join_path(d, "rig.json"));
  REQUIRE(data.frames() == 10);
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 3), 0.1f, 0.0f, Vec3f(0.5f, 0.5f, 0.5f));
  TrainOptions o = TrainOptions::scaled(1000);
  o.time_ramp = 0.5;  // 500 iterations: each frame is the newest for 50
  const Trainer t(data, params_from_cloud<float>(c), o);
  CHECK(t.window_last_frame(0) == 0);
  CHECK(t.window_last_frame(49) == 0);
  CHECK(t.window_last_frame(50) == 1);
  CHECK(t.window_last_frame(449) == 8);
  CHECK(t.window_last_frame(450) == 9);
  CHECK(t.window_last_frame(999) == 9);
  for (int i = 1; i < 1000; ++i) CHECK(t.window_last_frame(i) >= t.window_last_frame(i - 1));
  // Without a ramp, or for a static model, the whole video from the start.
  o.time_ramp = 0;
  CHECK(Trainer(data, params_from_cloud<float>(c), o).window_last_frame(0) == 9);
  o.time_ramp = 0.5;
  o.allow_dynamic = false;
  const Trainer s(data, params_from_cloud<float>(c), o);
  CHECK(s.window_last_frame(0) == 9);
  CHECK(s.params().dynamic_count() == 0);
}

TEST_CASE("static_first puts static Gaussians first and keeps every Gaussian as it was", "[motion]") {
  GaussianCloud c = two_static_one_moving();
  // Move the keyframed Gaussian to the front: ids 0 (moving), 1, 2 (static).
  GaussianCloud m = c;
  std::rotate(m.means.begin(), m.means.begin() + 2, m.means.end());
  std::rotate(m.log_scales.begin(), m.log_scales.begin() + 2, m.log_scales.end());
  std::rotate(m.rotations.begin(), m.rotations.begin() + 2, m.rotations.end());
  std::rotate(m.opacity_logits.begin(), m.opacity_logits.begin() + 2, m.opacity_logits.end());
  std::rotate(m.sh.begin(), m.sh.begin() + 6, m.sh.end());
  m.dynamic_ids = {0};
  m.validate("moved");
  GaussianCloud back = m;
  static_first(back);
  CHECK(back.dynamic_ids == std::vector<uint32_t>{2});
  for (double t : {0.0, 0.3, 1.0}) {
    const FrameGaussians a = frame_at(m, t), b = frame_at(back, t);
    CHECK(b.means[2] == a.means[0]);
    CHECK(b.means[0] == a.means[1]);
    CHECK(b.means[1] == a.means[2]);
    CHECK(b.opacities[2] == a.opacities[0]);
  }
  CHECK(back.sh == c.sh);
}

namespace {

/// A smooth texture (sums of sines, no repetition within the image) shifted by (dx, dy).
std::vector<float> textured(int W, int H, double dx, double dy) {
  std::vector<float> im(size_t(W) * size_t(H) * 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double u = x + 0.5 - dx, v = y + 0.5 - dy;
      const double l = 0.5 + 0.2 * std::sin(0.31 * u + 0.7 * std::sin(0.11 * v)) + 0.15 * std::sin(0.23 * v - 0.4 * std::cos(0.07 * u)) +
                       0.1 * std::sin(0.05 * u * 0.9 + 0.13 * v);
      for (int c = 0; c < 3; ++c) im[(size_t(y) * size_t(W) + size_t(x)) * 3 + size_t(c)] = float(l);
    }
  return im;
}

}  // namespace

TEST_CASE("optical flow recovers a known shift and chains it", "[motion][flow]") {
  const int W = 120, H = 90;
  const std::vector<float> a = textured(W, H, 0, 0), b = textured(W, H, 3, -2), c = textured(W, H, 5, -1);
  const FlowField ab = optical_flow(a, b, W, H), bc = optical_flow(b, c, W, H);
  const FlowField ba = optical_flow(b, a, W, H), cb = optical_flow(c, b, W, H);
  // Interior pixels (away from what enters or leaves the image): the true shift.
  double worst = 0;
  for (int y = 15; y < H - 15; y += 5)
    for (int x = 15; x < W - 15; x += 5) {
      double u, v;
      ab.sample(x + 0.5, y + 0.5, u, v);
      worst = std::max(worst, std::hypot(u - 3, v + 2));
    }
  CHECK(worst < 0.3);
  // Chained over two steps: (3, −2) then (2, 1).
  const auto to = chain_flow({ab, bc}, {ba, cb}, 60.0, 45.0, 2);
  REQUIRE(to.has_value());
  CHECK(to->first == Approx(65.0).margin(0.4));
  CHECK(to->second == Approx(44.0).margin(0.4));
  // A point carried out of the image has no answer; so does one whose backward flow disagrees.
  CHECK_FALSE(chain_flow({ab}, {ba}, W - 1.0, 45.0, 1).has_value());
  CHECK_FALSE(chain_flow({ab}, {ab}, 60.0, 45.0, 1).has_value());
  // Bilinear sampling of a known field, corner convention: centres at i + 0.5.
  FlowField f;
  f.width = 2, f.height = 1;
  f.uv = {0, 0, 2, 4};
  double u, v;
  f.sample(1.0, 0.5, u, v);
  CHECK(u == Approx(1.0));
  CHECK(v == Approx(2.0));
  CHECK_THROWS(optical_flow(a, b, W, H + 1));
}

TEST_CASE("keys placed by optical flow follow a moving plane and leave the wall still", "[motion][flow][train]") {
  // A textured plane 3 m away moving 0.1 m per frame along x in front of a textured wall at
  // 5 m; two fixed cameras 0.3 m apart, 7 frames. With every learning rate at 0, the only
  // thing that moves a key is its placement by flow when the window leaves frame 0.
  const int W = 64, H = 48, F = 7;
  auto texture = [](double x, double y, double k) {
    return Vec3f(float(0.5 + 0.3 * std::sin(k * 9.0 * x + 3.0 * std::sin(5.0 * y))), float(0.5 + 0.3 * std::sin(k * 7.0 * y + 2.0 * x)),
                 float(0.5 + 0.2 * std::cos(k * 5.0 * (x + y))));
  };
  auto scene = [&](double shift) {
    GaussianCloud c;
    for (int i = -30; i <= 30; ++i)
      for (int j = -22; j <= 22; ++j) add_gaussian(c, Vec3f(0.05f * i, 0.05f * j, 5.0f), 0.05f, 3.0f, texture(0.05 * i, 0.05 * j, 1.0));
    for (int i = -8; i <= 8; ++i)
      for (int j = -8; j <= 8; ++j)
        add_gaussian(c, Vec3f(float(0.03 * i + shift), float(0.03 * j), 3.0f), 0.03f, 3.0f, texture(0.03 * i, 0.03 * j, 2.0));
    return c;
  };
  const size_t wall = 61 * 45;
  const std::string d = scratch("flowkeys");
  std::vector<Camera> rig = {axis_camera(W, H, 60), axis_camera(W, H, 60)};
  rig[0].name = "a";
  rig[1].name = "b";
  rig[1].t = Vec3d(-0.3, 0, 0);
  write_transforms_json(join_path(d, "rig.json"), rig);
  for (int f = 0; f < F; ++f) {
    const GaussianCloud s = scene(0.1 * f);
    for (const Camera& c : rig) {
      const RenderOutput r = render(frame_at(s, 0.0), c, RenderOptions{});
      const Image im(W, H, 3, r.rgb);
      write_image(join_path(d, "images/" + c.name + "/" + std::to_string(100 + f) + ".png"), im);
    }
  }
  const Dataset data = Dataset::load(join_path(d, "images"), join_path(d, "rig.json"));
  TrainOptions o = TrainOptions::scaled(700);
  o.time_ramp = 0.7;  // 490 iterations, 70 per frame
  o.position_lr_init = o.position_lr_final = 0;
  o.scaling_lr = o.rotation_lr = o.opacity_lr = o.feature_lr = 0;
  o.densify_from = 1000000;
  o.opacity_reset_interval = 0;
  const GaussianCloud first = scene(0.0);
  Trainer t(data, params_from_cloud<float>(first), o);
  REQUIRE(t.params().key_count == 3);  // keys at frames 0, 3, 6
  t.run(70, null_progress());
  CHECK(t.flow_placed().first == 0);
  t.run(71, null_progress());  // the window reaches frame 1: keys 1 and 2 are placed
  CHECK(t.flow_placed().first > 0);
  const ModelParams<float>& p = t.params();
  REQUIRE(p.dynamic_count() == first.size());
  std::vector<double> plane_dx, plane_off, wall_move;
  for (size_t j = 0; j < p.dynamic_count(); ++j) {
    const uint32_t g = p.dynamic_ids[j];
    const Vec3f k0 = Eigen::Map<const Vec3f>(&p.key_positions[(j * 3 + 0) * 3]), k1 = Eigen::Map<const Vec3f>(&p.key_positions[(j * 3 + 1) * 3]);
    if (g < wall) {
      wall_move.push_back((k1 - k0).norm());
    } else {
      // Only plane Gaussians that stay in both views for three frames.
      if (std::fabs(k0.x()) > 0.12 || std::fabs(k0.y()) > 0.2) continue;
      plane_dx.push_back(k1.x() - k0.x());
      plane_off.push_back(std::hypot(k1.y() - k0.y(), k1.z() - k0.z()));
    }
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  REQUIRE(plane_dx.size() > 20);
  CHECK(median(plane_dx) == Approx(0.3).margin(0.03));  // 3 frames × 0.1 m
  CHECK(median(plane_off) < 0.05);
  CHECK(median(wall_move) < 0.01);
}
