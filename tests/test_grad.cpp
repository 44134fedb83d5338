// The backward pass against central finite differences of the forward, in double.
#include <catch2/catch.hpp>

#include <cmath>
#include <iterator>
#include <cstring>
#include <random>

#include "fillgs/render/loss.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/train/train_model.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "helpers.hpp"
#include "model/motion_keys.hpp"
#include "render/splat_backward_rows.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

/// A small random 4D scene in front of an axis camera: `n` Gaussians, the last `moving`
/// of them keyframed (4 keys, rotations, scales and opacities keyed), SH degree 2.
GaussianCloud random_scene(int n, int moving, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  GaussianCloud c;
  c.sh_degree = 2;
  c.resize(size_t(n));
  for (int g = 0; g < n; ++g) {
    c.means[g] = Vec3f(0.5f * U(rng), 0.4f * U(rng), 3.0f + 0.5f * U(rng));
    c.log_scales[g] = Vec3f(std::log(0.12f + 0.05f * U(rng)), std::log(0.08f + 0.03f * U(rng)), std::log(0.1f));
    c.rotations[g] = Vec4f(1.0f + 0.3f * U(rng), 0.4f * U(rng), 0.4f * U(rng), 0.4f * U(rng));
    c.opacity_logits[g] = 0.3f * U(rng);
    for (int k = 0; k < c.sh_count() * 3; ++k) c.sh[size_t(g) * c.sh_count() * 3 + k] = (k < 3 ? 0.8f : 0.2f) * U(rng);
  }
  if (moving > 0) {
    c.motion = MotionModel::Keyframed;
    KeyframedMotion& k = c.keyframed;
    k.key_count = 4;
    k.key_spacing = 1.0 / 3.0;
    for (int j = 0; j < moving; ++j) {
      const uint32_t g = uint32_t(n - moving + j);
      c.dynamic_ids.push_back(g);
      for (int key = 0; key < 4; ++key) {
        for (int a = 0; a < 3; ++a) k.positions.push_back(c.means[g][a] + 0.15f * U(rng));
        // Keys far enough apart that slerp takes its spherical branch.
        const Vec4f q = c.rotations[g] + Vec4f(0.0f, 0.5f * U(rng), 0.5f * U(rng), 0.5f * U(rng));
        for (int a = 0; a < 4; ++a) k.rotations.push_back(q[a]);
        for (int a = 0; a < 3; ++a) k.log_scales.push_back(c.log_scales[g][a] + 0.2f * U(rng));
        k.opacity_logits.push_back(c.opacity_logits[g] + 0.5f * U(rng));
      }
    }
  }
  c.validate("random scene");
  return c;
}

Camera test_camera() {
  Camera cam = axis_camera(48, 40, 50.0);
  cam.look_at(Vec3d(0.3, -0.2, -0.1), Vec3d(0.0, 0.0, 3.0), Vec3d(0, -1, 0));
  return cam;
}

/// Loss L = Σ r·image + Σ r_f·features with fixed random r: its gradient is r.
struct LinearLoss {
  std::vector<double> r_img, r_feat;
  LinearLoss(size_t pixels, int F, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    r_img.resize(pixels * 3);
    r_feat.resize(pixels * F);
    for (double& v : r_img) v = U(rng);
    for (double& v : r_feat) v = U(rng);
  }
  double operator()(const DiffRasterizer<double>& ras, const double* weights) const {
    double L = 0;
    const size_t P = r_img.size() / 3, F = P ? r_feat.size() / P : 0;
    for (size_t p = 0; p < P; ++p) {
      const double w = weights ? weights[p] : 1.0;
      for (int c = 0; c < 3; ++c) L += w * r_img[3 * p + c] * ras.image()[3 * p + c];
      for (size_t f = 0; f < F; ++f) L += w * r_feat[F * p + f] * ras.features()[F * p + f];
    }
    return L;
  }
};

/// Compares analytic and finite-difference gradients element by element.
void require_close(const std::vector<double>& analytic, const std::vector<double>& fd, const char* what) {
  REQUIRE(analytic.size() == fd.size());
  double scale = 0;
  for (double v : fd) scale = std::max(scale, std::abs(v));
  INFO(what << ": largest |gradient| " << scale);
  REQUIRE(scale > 0.0);
  for (size_t i = 0; i < fd.size(); ++i) {
    const double err = std::abs(analytic[i] - fd[i]);
    INFO(what << "[" << i << "] analytic " << analytic[i] << " finite difference " << fd[i]);
    // Relative error <= 1e-3, with a floor of 1e-7 of the group's largest entry for
    // entries that are (numerically) zero.
    CHECK(err <= 1e-3 * std::max(std::abs(fd[i]), 1e-4 * scale));
  }
}

}  // namespace

TEST_CASE("frame gradients match finite differences for every value (double)", "[grad]") {
  const GaussianCloud cloud = random_scene(7, 0, 11);
  const ModelParams<double> params = params_from_cloud<double>(cloud);
  DiffFrame<double> frame;
  params_at(params, 0.0, &frame);
  const Camera cam = test_camera();
  const int F = 2;
  std::vector<float> feats(cloud.size() * F);
  std::mt19937 rng(5);
  for (float& f : feats) f = std::uniform_real_distribution<float>(0.0f, 2.0f)(rng);
  DiffRenderOptions opt;
  opt.background = Vec3f(0.2f, 0.5f, 0.9f);
  opt.features = feats.data();
  opt.feature_channels = F;
  const size_t P = size_t(cam.width) * cam.height;
  const LinearLoss loss(P, F, 3);
  std::vector<double> weights(P);
  for (double& w : weights) w = std::uniform_real_distribution<double>(0.0, 2.0)(rng);

  for (const bool weighted : {false, true}) {
    DYNAMIC_SECTION((weighted ? "with per-pixel weights" : "unweighted")) {
      const double* wp = weighted ? weights.data() : nullptr;
      DiffRasterizer<double> ras;
      ras.forward(frame, cam, opt);
      size_t drawn = 0;
      for (int r : ras.radii()) drawn += r > 0;
      REQUIRE(drawn == cloud.size());
      std::vector<double> dimg(P * 3), dfeat(P * F);
      for (size_t i = 0; i < dimg.size(); ++i) dimg[i] = loss.r_img[i];
      for (size_t i = 0; i < dfeat.size(); ++i) dfeat[i] = loss.r_feat[i];
      DiffFrameGrad<double> grad;
      ras.backward(dimg.data(), dfeat.data(), wp, &grad);

      auto fd_of = [&](std::vector<double>& values, double h) {
        std::vector<double> out(values.size());
        for (size_t i = 0; i < values.size(); ++i) {
          const double keep = values[i];
          DiffRasterizer<double> r2;
          values[i] = keep + h;
          r2.forward(frame, cam, opt);
          const double lp = loss(r2, wp);
          values[i] = keep - h;
          r2.forward(frame, cam, opt);
          const double lm = loss(r2, wp);
          values[i] = keep;
          out[i] = (lp - lm) / (2 * h);
        }
        return out;
      };
      require_close(grad.means, fd_of(frame.means, 1e-6), "mean");
      require_close(grad.scales, fd_of(frame.scales, 1e-7), "scale");
      require_close(grad.rotations, fd_of(frame.rotations, 1e-6), "rotation");
      require_close(grad.opacities, fd_of(frame.opacities, 1e-6), "opacity");
      std::vector<double> sh(params.sh);
      frame.sh = sh.data();
      require_close(grad.sh, fd_of(sh, 1e-6), "SH");
      frame.sh = params.sh.data();
      // Features are float inputs: the loss is linear in them, so the gradient is exact.
      std::vector<double> fd_feat(feats.size());
      for (size_t i = 0; i < feats.size(); ++i) {
        const float keep = feats[i];
        DiffRasterizer<double> r2;
        feats[i] = keep + 0.25f;
        r2.forward(frame, cam, opt);
        const double lp = loss(r2, wp);
        feats[i] = keep - 0.25f;
        r2.forward(frame, cam, opt);
        const double lm = loss(r2, wp);
        feats[i] = keep;
        fd_feat[i] = (lp - lm) / 0.5;
      }
      require_close(grad.features, fd_feat, "feature");
    }
  }
}

TEST_CASE("parameter gradients through frame_at(t), motion included, match finite differences", "[grad]") {
  const GaussianCloud cloud = random_scene(6, 3, 21);
  ModelParams<double> params = params_from_cloud<double>(cloud);
  REQUIRE(params.dynamic_count() > 0);
  REQUIRE(params.key_count >= 4);
  const bool colour_keys = GENERATE(false, true);
  if (colour_keys) {  // every SH coefficient of the moving Gaussians per key, each key different
    const size_t K = size_t(params.key_count), S = size_t(params.sh_count()) * 3;
    params.key_sh.resize(params.dynamic_count() * K * S);
    for (size_t j = 0; j < params.dynamic_count(); ++j)
      for (size_t k = 0; k < K; ++k)
        for (size_t a = 0; a < S; ++a)
          params.key_sh[(j * K + k) * S + a] = params.sh[params.dynamic_ids[j] * S + a] + 0.3 * std::sin(double(1 + j + 3 * k + 7 * a));
  }
  const Camera cam = test_camera();
  const size_t P = size_t(cam.width) * cam.height;
  const LinearLoss loss(P, 0, 8);
  DiffRenderOptions opt;
  opt.background = Vec3f(0.1f, 0.1f, 0.1f);
  // t inside an interior interval (Catmull-Rom uses four keys) and at both ends.
  for (const double t : {0.0, 0.45, 1.0}) {
    DYNAMIC_SECTION("t = " << t << (colour_keys ? ", colour keys" : "")) {
      DiffFrame<double> frame;
      auto eval_loss = [&] {
        DiffFrame<double> f;
        params_at(params, t, &f);
        DiffRasterizer<double> r;
        r.forward(f, cam, opt);
        return loss(r, nullptr);
      };
      params_at(params, t, &frame);
      DiffRasterizer<double> ras;
      ras.forward(frame, cam, opt);
      DiffFrameGrad<double> fg;
      std::vector<double> dimg(loss.r_img);
      ras.backward(dimg.data(), nullptr, nullptr, &fg);
      ModelParams<double> grad = params.zeros_like();
      params_at_backward(params, t, fg, &grad);

      const char* names[] = {"mean", "log-scale", "rotation", "opacity logit", "SH",
                             "key position", "key rotation", "key log-scale", "key opacity logit", "key SH"};
      auto values = params.arrays();
      auto analytic = grad.arrays();
      REQUIRE(values.size() == std::size(names));
      CHECK(params.key_sh.empty() != colour_keys);
      for (size_t a = 0; a < values.size(); ++a) {
        std::vector<double>& v = *values[a];
        std::vector<double> fd(v.size());
        for (size_t i = 0; i < v.size(); ++i) {
          const double keep = v[i], h = 1e-6;
          v[i] = keep + h;
          const double lp = eval_loss();
          v[i] = keep - h;
          const double lm = eval_loss();
          v[i] = keep;
          fd[i] = (lp - lm) / (2 * h);
        }
        // Means and rotations of moving Gaussians, and keys outside the interval, have
        // exactly zero gradient in both.
        bool any = false;
        for (double x : fd) any = any || x != 0.0;
        if (!any) {
          for (double x : *analytic[a]) CHECK(x == 0.0);
          continue;
        }
        require_close(*analytic[a], fd, names[a]);
      }
    }
  }
}

TEST_CASE("params_at_backward from the state params_at kept gives the gradients it computes alone, bit for bit", "[grad][motion]") {
  // Float, as training runs it: keyed rotations, scales, opacities and colours, with slerps on
  // each branch: spherical, nearly equal keys (the normalised lerp), keys on opposite
  // hemispheres (the flip) and a zero key (no normalisation).
  ModelParams<float> p = params_from_cloud<float>(random_scene(40, 30, 5));
  const size_t K = size_t(p.key_count), D = p.dynamic_count(), S = size_t(p.sh_count()) * 3;
  REQUIRE(D == 30);
  REQUIRE(!p.key_log_scales.empty());
  REQUIRE(p.keyed_opacity);
  p.key_sh.resize(D * K * S);
  for (size_t i = 0; i < p.key_sh.size(); ++i) p.key_sh[i] = 0.3f * std::sin(float(i));
  for (size_t k = 0; k < K; ++k)
    for (int a = 0; a < 4; ++a) {
      float* q = &p.key_rotations[(0 * K + k) * 4];
      q[a] = p.key_rotations[a] + 1e-4f * float(k * a);                         // moving Gaussian 0: nearly equal keys
      p.key_rotations[(1 * K + k) * 4 + size_t(a)] = (k % 2 ? -1.0f : 1.0f) * q[a];  // 1: alternate hemispheres
      p.key_rotations[(2 * K + k) * 4 + size_t(a)] = 0.0f;                     // 2: zero keys
    }
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  DiffFrameGrad<float> fg;
  fg.reset(p.size(), p.sh_count(), 0);
  for (std::vector<float>* v : {&fg.means, &fg.scales, &fg.rotations, &fg.opacities, &fg.sh})
    for (float& x : *v) x = U(rng);
  for (const double t : {0.0, 0.2, 0.45, 0.5, 1.0}) {
    INFO("t = " << t);
    DiffFrame<float> plain, kept;
    params_at(p, t, &plain);
    params_at(p, t, &kept, true);
    constexpr size_t kState = keys::Slerp<float>::kState;
    REQUIRE(kept.key_state.size() == D * kState);
    CHECK(plain.key_state.empty());
    // The slerps meet the branches the keys were built for.
    keys::Slerp<float> near_equal, opposite, zero_key, apart;
    near_equal.load(&kept.key_state[0 * kState]);
    opposite.load(&kept.key_state[1 * kState]);
    zero_key.load(&kept.key_state[2 * kState]);
    apart.load(&kept.key_state[3 * kState]);
    CHECK(near_equal.linear);
    CHECK(opposite.flipped);
    CHECK(!keys::normalizable(zero_key.n0));
    CHECK(!apart.linear);
    // Keeping changes nothing the frame holds.
    CHECK(plain.means == kept.means);
    CHECK(plain.scales == kept.scales);
    CHECK(plain.rotations == kept.rotations);
    CHECK(plain.opacities == kept.opacities);
    CHECK(plain.sh_storage == kept.sh_storage);
    ModelParams<float> alone = p.zeros_like(), from_kept = p.zeros_like(), from_plain = p.zeros_like();
    params_at_backward(p, t, fg, &alone);
    params_at_backward(p, t, fg, &from_kept, &kept);
    params_at_backward(p, t, fg, &from_plain, &plain);  // nothing kept: computed alone
    const auto a = alone.arrays(), b = from_kept.arrays(), c = from_plain.arrays();
    for (size_t i = 0; i < a.size(); ++i) {
      INFO("array " << i);
      REQUIRE(a[i]->size() == b[i]->size());
      CHECK(std::memcmp(a[i]->data(), b[i]->data(), a[i]->size() * sizeof(float)) == 0);
      CHECK(std::memcmp(a[i]->data(), c[i]->data(), a[i]->size() * sizeof(float)) == 0);
    }
    // The zero keys' Gaussian gets no rotation gradient; the others do.
    float zero_keys = 0, others = 0;
    for (size_t k = 0; k < K * 4; ++k) zero_keys += std::fabs(alone.key_rotations[2 * K * 4 + k]), others += std::fabs(alone.key_rotations[k]);
    CHECK(zero_keys == 0.0f);
    CHECK(others > 0.0f);
  }
}

namespace {

/// One pixel, Gaussians on its centre at depths 2, 3, 4...: α_i = o_i exactly.
struct PixelStack {
  Camera cam = axis_camera(1, 1, 10.0);
  DiffFrame<double> frame;
  std::vector<double> sh;
  explicit PixelStack(const std::vector<double>& opacities) {
    const size_t n = opacities.size();
    frame.resize(n);
    sh.assign(n * 3, 0.0);
    for (size_t g = 0; g < n; ++g) {
      frame.means[3 * g + 2] = 2.0 + double(g);
      for (int k = 0; k < 3; ++k) frame.scales[3 * g + k] = 0.05;
      frame.rotations[4 * g] = 1.0;
      frame.opacities[g] = opacities[g];
      for (int c = 0; c < 3; ++c) sh[3 * g + c] = (0.2 + 0.3 * double(g) + 0.1 * c - 0.5) / 0.28209479177387814;
    }
    frame.sh = sh.data();
  }
  double red() {
    DiffRasterizer<double> r;
    r.forward(frame, cam);
    return r.image()[0];
  }
  std::vector<double> opacity_gradient() {
    DiffRasterizer<double> r;
    r.forward(frame, cam);
    const double up[3] = {1, 0, 0};
    DiffFrameGrad<double> g;
    r.backward(up, nullptr, nullptr, &g);
    return g.opacities;
  }
  double fd_opacity(size_t g, double h = 1e-7) {
    const double keep = frame.opacities[g];
    frame.opacities[g] = keep + h;
    const double p = red();
    frame.opacities[g] = keep - h;
    const double m = red();
    frame.opacities[g] = keep;
    return (p - m) / (2 * h);
  }
};

}  // namespace

TEST_CASE("gradients at the clamps are the finite differences of the forward", "[grad]") {
  SECTION("alpha clamped at 0.99: no gradient through opacity") {
    PixelStack s({0.995});
    REQUIRE(s.red() == Approx(0.2 * 0.99).margin(1e-12));
    REQUIRE(s.fd_opacity(0) == 0.0);
    REQUIRE(s.opacity_gradient()[0] == 0.0);
  }
  SECTION("alpha just below 0.99 still has the unclamped gradient") {
    PixelStack s({0.985});
    const double g = s.opacity_gradient()[0];
    REQUIRE(g == Approx(0.2).epsilon(1e-9));
    REQUIRE(g == Approx(s.fd_opacity(0)).epsilon(1e-6));
  }
  SECTION("alpha just under 1/255 is skipped in both directions") {
    PixelStack under({double(kMinAlpha) * (1.0 - 1e-4)});
    REQUIRE(under.red() == 0.0);
    REQUIRE(under.fd_opacity(0, 1e-9) == 0.0);
    REQUIRE(under.opacity_gradient()[0] == 0.0);
    PixelStack over({double(kMinAlpha) * (1.0 + 1e-4)});
    REQUIRE(over.opacity_gradient()[0] == Approx(over.fd_opacity(0, 1e-9)).epsilon(1e-6));
    REQUIRE(over.opacity_gradient()[0] == Approx(0.2).epsilon(1e-9));
  }
  SECTION("the Gaussian that would push T under 1e-4 contributes nothing") {
    // T after two: 0.05², then α3 = 0.97 would leave 7.5e-5 < 1e-4: the pixel stops.
    PixelStack stop({0.95, 0.95, 0.97});
    const std::vector<double> g = stop.opacity_gradient();
    REQUIRE(stop.fd_opacity(2) == 0.0);
    REQUIRE(g[2] == 0.0);
    for (size_t k = 0; k < 2; ++k) REQUIRE(g[k] == Approx(stop.fd_opacity(k)).epsilon(1e-6));
    // With α3 = 0.95 the pixel goes on (1.25e-4 >= 1e-4) and the third one has a gradient.
    PixelStack go({0.95, 0.95, 0.95});
    const std::vector<double> g2 = go.opacity_gradient();
    REQUIRE(g2[2] != 0.0);
    for (size_t k = 0; k < 3; ++k) REQUIRE(g2[k] == Approx(go.fd_opacity(k)).epsilon(1e-6));
  }
}

TEST_CASE("the differentiable forward renders what the forward rasterizer renders", "[grad]") {
  const SynthScene s = small_synth(6, 96, 72, 0.05);
  const GaussianCloud& cloud = s.scene;
  const ModelParams<float> params = params_from_cloud<float>(cloud);
  for (const double t : {0.0, 0.5, 1.0}) {
    DiffFrame<float> frame;
    params_at(params, t, &frame);
    const FrameGaussians ref = frame_at(cloud, t);
    for (size_t g = 0; g < cloud.size(); ++g) {
      for (int k = 0; k < 3; ++k) REQUIRE(frame.means[3 * g + k] == Approx(ref.means[g][k]).margin(1e-5));
      for (int k = 0; k < 4; ++k) REQUIRE(std::abs(frame.rotations[4 * g + k]) == Approx(std::abs(ref.rotations[g][k])).margin(1e-5));
      REQUIRE(frame.opacities[g] == Approx(ref.opacities[g]).margin(1e-6));
    }
    for (size_t v = 0; v < s.train.size(); v += 5) {
      const RenderOutput out = render(ref, s.train[v]);
      DiffRasterizer<float> ras;
      ras.forward(frame, s.train[v]);
      double worst = 0;
      for (size_t i = 0; i < out.rgb.size(); ++i) worst = std::max(worst, double(std::abs(out.rgb[i] - ras.image()[i])));
      INFO("t " << t << " view " << v);
      // Measured: 0 (bit-identical) at t = 0 and 1; <= 8.9e-7 at t = 0.5, where the moving
      // chair's means differ in the last bits (Catmull-Rom as weights vs as tangents).
      CHECK(worst < 1e-5);
    }
  }
}

TEST_CASE("the Fisher diagonal equals per-pixel squared gradients summed", "[grad]") {
  GaussianCloud cloud = random_scene(4, 0, 33);
  cloud.sh_degree = 0;  // Fisher leaves out view-dependent colour's dependence on the mean
  cloud.sh.resize(cloud.size() * 3);
  for (size_t g = 0; g < cloud.size(); ++g)
    for (int c = 0; c < 3; ++c) cloud.sh[3 * g + c] = 0.3f * float(c + 1) - 0.4f * float(g % 2);
  const ModelParams<double> params = params_from_cloud<double>(cloud);
  DiffFrame<double> frame;
  params_at(params, 0.0, &frame);
  Camera cam = axis_camera(20, 16, 22.0);
  DiffRenderOptions opt;
  opt.background = Vec3f(0.3f, 0.6f, 0.1f);
  DiffRasterizer<double> ras;
  ras.forward(frame, cam, opt);
  FisherDiagonal fisher;
  ras.accumulate_fisher(&fisher);
  // Reference: one backward per pixel and channel, squared and summed.
  const size_t P = size_t(cam.width) * cam.height, N = frame.size();
  std::vector<double> ref(N * FisherDiagonal::kParams, 0.0);
  std::vector<double> up(P * 3, 0.0);
  for (size_t i = 0; i < P * 3; ++i) {
    up[i] = 1.0;
    DiffFrameGrad<double> g;
    ras.backward(up.data(), nullptr, nullptr, &g);
    up[i] = 0.0;
    for (size_t n = 0; n < N; ++n) {
      double v[FisherDiagonal::kParams];
      for (int k = 0; k < 3; ++k) v[k] = g.means[3 * n + k];
      for (int k = 0; k < 3; ++k) v[3 + k] = g.scales[3 * n + k] * frame.scales[3 * n + k];
      for (int k = 0; k < 4; ++k) v[6 + k] = g.rotations[4 * n + k];
      const double o = frame.opacities[n];
      v[10] = g.opacities[n] * o * (1 - o);
      for (int c = 0; c < 3; ++c) v[11 + c] = g.sh[3 * n + c];
      for (int k = 0; k < FisherDiagonal::kParams; ++k) ref[n * FisherDiagonal::kParams + k] += v[k] * v[k];
    }
  }
  double scale = 0;
  for (double v : ref) scale = std::max(scale, v);
  REQUIRE(scale > 0);
  for (size_t i = 0; i < ref.size(); ++i) {
    INFO("Gaussian " << i / FisherDiagonal::kParams << " parameter " << i % FisherDiagonal::kParams);
    CHECK(fisher.values[i] == Approx(ref[i]).epsilon(1e-9).margin(1e-12 * scale));
  }
}

TEST_CASE("backward is bit-identical for any thread count", "[grad]") {
  const SynthScene s = small_synth(4, 80, 64, 0.05);
  const ModelParams<float> params = params_from_cloud<float>(s.scene);
  DiffFrame<float> frame;
  params_at(params, 0.5, &frame);
  std::vector<float> up(80 * 64 * 3);
  for (size_t i = 0; i < up.size(); ++i) up[i] = float((i * 7919) % 13) / 13.0f - 0.5f;
  std::vector<DiffFrameGrad<float>> grads(2);
  for (int threads : {1, 2}) {
    with_threads(threads, [&] {
      DiffRasterizer<float> r;
      r.forward(frame, s.train[3], DiffRenderOptions());
      r.backward(up.data(), nullptr, nullptr, &grads[threads - 1]);
    });
  }
  REQUIRE(grads[0].means == grads[1].means);
  REQUIRE(grads[0].scales == grads[1].scales);
  REQUIRE(grads[0].rotations == grads[1].rotations);
  REQUIRE(grads[0].opacities == grads[1].opacities);
  REQUIRE(grads[0].sh == grads[1].sh);
}

TEST_CASE("photometric loss gradient (L1 + 0.2 D-SSIM, weighted) matches finite differences", "[grad]") {
  const int W = 23, H = 17;
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<double> img(size_t(W) * H * 3), weights(size_t(W) * H);
  std::vector<float> target(img.size());
  for (size_t i = 0; i < img.size(); ++i) img[i] = U(rng), target[i] = float(U(rng));
  for (double& w : weights) w = U(rng);
  for (const bool weighted : {false, true}) {
    const double* wp = weighted ? weights.data() : nullptr;
    std::vector<double> grad(img.size());
    photometric_loss<double>(img.data(), target.data(), W, H, wp, 0.2, grad.data());
    std::vector<double> fd(img.size());
    for (size_t i = 0; i < img.size(); ++i) {
      const double keep = img[i], h = 1e-6;
      img[i] = keep + h;
      const double p = photometric_loss<double>(img.data(), target.data(), W, H, wp, 0.2, nullptr).total;
      img[i] = keep - h;
      const double m = photometric_loss<double>(img.data(), target.data(), W, H, wp, 0.2, nullptr).total;
      img[i] = keep;
      fd[i] = (p - m) / (2 * h);
    }
    require_close(grad, fd, weighted ? "weighted loss" : "loss");
  }
  // Identical images: SSIM 1, L1 0, loss 0.
  std::vector<float> same(target);
  std::vector<double> same_d(target.begin(), target.end());
  const LossValue lv = photometric_loss<double>(same_d.data(), same.data(), W, H, nullptr, 0.2, nullptr);
  REQUIRE(lv.total == Approx(0.0).margin(1e-12));
  REQUIRE(ssim(same.data(), same.data(), W, H, 3) == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("the projection's backward written out, and on lanes, gives the Eigen form's gradients bit for bit", "[grad][extremes]") {
  // The Gaussians and cameras built to meet each branch of the preprocess, with gradients
  // over 16 orders of magnitude; the written-out form in double, and the lane form at each
  // instruction set, against project_splat_backward<double> (Eigen products).
  std::vector<Camera> cams;
  const GaussianCloud c = preprocess_extremes(&cams);
  const size_t N = c.size();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f), expo(-8.0f, 8.0f);
  std::vector<Vec3f> scales(N);
  std::vector<float> sums(N * 6);
  std::vector<uint32_t> rows(N);
  for (size_t g = 0; g < N; ++g) {
    scales[g] = c.log_scales[g].array().exp();
    for (int a = 0; a < 5; ++a) sums[g * 6 + size_t(a)] = unit(rng) * std::pow(10.0f, expo(rng));
    rows[g] = uint32_t(N - 1 - g);  // rows read Gaussians through the visible list
  }
  auto bits = [](double x) { return bits_of(x); };
  for (size_t k = 0; k < cams.size(); ++k) {
    const internal::FrustumCamera bc(cams[k]);
    std::vector<double> expected(N * 10, 0.0);
    size_t used = 0, mismatched = 0;
    for (size_t i = 0; i < N; ++i) {
      const size_t g = rows[i];
      const float* s = &sums[i * 6];
      double m[3], sc[3], q[4];
      for (int a = 0; a < 3; ++a) m[a] = c.means[g][a], sc[a] = scales[g][a];
      for (int a = 0; a < 4; ++a) q[a] = c.rotations[g][a];
      const double gconic[3] = {s[2], s[3], s[4]};
      double* e = &expected[i * 10];
      project_splat_backward<double>(m, sc, q, cams[k], double(s[0]), double(s[1]), gconic, e, e + 3, e + 6);
      double h[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
      bool ok = false;
      internal::splat_backward_math<double>(bc, m, sc, q, double(s[0]), double(s[1]), gconic, h, h + 3, h + 6, &ok,
                                            [](double x) { return x; });
      used += ok;
      for (int a = 0; a < 10; ++a) mismatched += bits(ok ? h[a] : 0.0) != bits(e[a]);
    }
    INFO("camera " << k);
    CHECK(used > 1000);
    CHECK(N - used > 1000);
    CHECK(mismatched == 0);
    for_each_instruction_set([&](const char* set) {
      INFO(set << " (" << kernel_instruction_set() << ")");
      std::vector<double> got(N * 10, -1.0);
      const internal::BackwardRowsInput in{rows.data(), c.means[0].data(), scales[0].data(), c.rotations[0].data(), sums.data(), 6};
      internal::project_backward_rows(bc, in, 0, N - 3, got.data());  // two calls: a part lane at the end of each
      internal::project_backward_rows(bc, in, N - 3, N, got.data());
      size_t lane_mismatched = 0;
      for (size_t j = 0; j < N * 10; ++j) lane_mismatched += bits(got[j]) != bits(expected[j]);
      CHECK(lane_mismatched == 0);
    });
  }
}
