// The vector tile kernel against the scalar reference (src/render/tile_kernel.hpp): its
// exp within the stated bound, the same images, contributor lists and gradients on real
// scenes, the same output for any thread count, the CLI's --kernel switch,
// FILLGS_INSTRUCTION_SET's cap, and the SSIM loss's vector blur.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <cstdlib>
#include <random>
#include <sstream>
#include <tuple>

#include "fillgs/cli.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/train/train_model.hpp"
#include "fillgs/visibility/accel.hpp"
#include "helpers.hpp"
#include "image/blur.hpp"
#include "render/frustum.hpp"
#include "render/preprocess.hpp"
#include "render/raster_internal.hpp"
#include "render/tile_kernel.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

/// The stated bound of the kernel's exp (src/README.md, "The rasterizer"): relative error over [−87, 0].
constexpr double kExpBound = 2.5e-7;

Camera orbit_camera(const GaussianCloud& c, double angle, int w, int h) {
  Vec3d centre = Vec3d::Zero();
  for (const Vec3f& p : c.means) centre += p.cast<double>();
  centre /= double(c.size());
  RingPlacement r;
  r.count = 1;
  r.centre = centre;
  r.radius = 4;
  r.elevation = 0.8;
  r.up = Vec3d(0, -1, 0);
  r.phase = angle;
  Camera lens;
  lens.set_fov_x(1.0, w, h);
  return camera_ring(r, lens)[0];
}

double max_abs_diff(const std::vector<float>& a, const std::vector<float>& b) {
  REQUIRE(a.size() == b.size());
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, double(std::fabs(a[i] - b[i])));
  return m;
}

}  // namespace

TEST_CASE("the vector kernel's exp stays within its stated relative error on [-87, 0]", "[kernel]") {
  INFO("instruction set " << simd_target());
  const double err = tiles::simd_exp_max_relative_error(-87.0f, 400000);
  CHECK(err < kExpBound);
  CHECK(err > 0.0);  // it is an approximation: a zero would mean the test measured nothing
}

TEST_CASE("vector and scalar kernels render the same images of real scenes", "[kernel][data]") {
  for (const char* name : {"playbot_3k.ply", "guitar.ply"}) {
    const GaussianCloud c = read_scene(shared_data() + "/scenes/" + name);
    const FrameGaussians g = frame_at(c, 0);
    for (double angle : {0.0, 2.0}) {
      const Camera cam = orbit_camera(c, angle, 200, 150);
      RenderOptions o;
      o.depth = true;
      o.max_weights = true;
      o.kernel = Kernel::Scalar;
      const RenderOutput ref = render(g, cam, o);
      o.kernel = Kernel::Simd;
      const RenderOutput vec = render(g, cam, o);
      INFO(name << " angle " << angle << " on " << simd_target());
      REQUIRE(ref.rendered > 1000);
      // A pixel's value is a sum of α·T·c over its contributors, each α carrying the exp's
      // relative error (≤ 2.5e-7) and the blend's fused multiply-adds; measured ≤ 1.2e-6.
      CHECK(max_abs_diff(ref.rgb, vec.rgb) < 1e-5);
      CHECK(max_abs_diff(ref.alpha, vec.alpha) < 1e-5);
      double max_depth = 0;
      for (float z : ref.depth) max_depth = std::max(max_depth, double(z));
      CHECK(max_abs_diff(ref.depth, vec.depth) < 1e-5 * std::max(1.0, max_depth));
      CHECK(max_abs_diff(ref.max_weight, vec.max_weight) < 1e-5);
      // Both kernels count the same work (the scalar kernel's α boxes), so evaluations/s compare.
      CHECK(ref.box_pixels == vec.box_pixels);
      CHECK(ref.box_pixels > ref.tile_entries);
    }
  }
}

TEST_CASE("vector and scalar kernels list the same contributors", "[kernel]") {
  const GaussianCloud c = read_scene(shared_data() + "/scenes/playbot_3k.ply");
  const FrameGaussians g = frame_at(c, 0);
  const Camera cam = orbit_camera(c, 1.0, 160, 120);
  RenderOptions o;
  o.contributors = true;
  o.kernel = Kernel::Scalar;
  const RenderOutput ref = render(g, cam, o);
  o.kernel = Kernel::Simd;
  const RenderOutput vec = render(g, cam, o);
  REQUIRE(ref.contributors.ids.size() > size_t(cam.width) * cam.height);
  // Lists can differ only where an α sits within the exp's error of 1/255 or T of 1e-4.
  size_t differing = 0;
  double max_diff = 0;
  for (size_t p = 0; p + 1 < ref.contributors.offsets.size(); ++p) {
    const uint64_t a0 = ref.contributors.offsets[p], a1 = ref.contributors.offsets[p + 1];
    const uint64_t b0 = vec.contributors.offsets[p], b1 = vec.contributors.offsets[p + 1];
    if (a1 - a0 != b1 - b0 || !std::equal(ref.contributors.ids.begin() + long(a0), ref.contributors.ids.begin() + long(a1),
                                          vec.contributors.ids.begin() + long(b0))) {
      ++differing;
      continue;
    }
    for (uint64_t k = 0; k < a1 - a0; ++k)
      max_diff = std::max(max_diff, double(std::fabs(vec.contributors.weights[b0 + k] - ref.contributors.weights[a0 + k])));
  }
  INFO("max |weight difference| " << max_diff << " on " << simd_target());
  CHECK(differing == 0);
  CHECK(max_diff < 1e-5);
}

TEST_CASE("vector and scalar backward give the same gradients", "[kernel][grad][data]") {
  const GaussianCloud c = read_scene(shared_data() + "/scenes/playbot_3k.ply");
  const ModelParams<float> params = params_from_cloud<float>(c);
  DiffFrame<float> frame;
  params_at(params, 0.0, &frame);
  const Camera cam = orbit_camera(c, 0.5, 160, 120);
  const size_t P = size_t(cam.width) * cam.height;
  std::vector<float> target(P * 3), weights(P);
  for (size_t i = 0; i < target.size(); ++i) target[i] = float((i * 7919) % 97) / 97.0f;
  for (size_t i = 0; i < P; ++i) weights[i] = 0.25f + float(i % 5) * 0.25f;
  std::vector<DiffFrameGrad<float>> grads(2);
  std::vector<std::vector<float>> images(2);
  for (int k = 0; k < 2; ++k) {
    DiffRenderOptions o;
    o.kernel = k == 0 ? Kernel::Scalar : Kernel::Simd;
    o.background = Vec3f(0.2f, 0.3f, 0.4f);
    DiffRasterizer<float> r;
    r.forward(frame, cam, o);
    std::vector<float> dimg(P * 3);
    photometric_loss<float>(r.image().data(), target.data(), cam.width, cam.height, nullptr, 0.2, dimg.data());
    r.backward(dimg.data(), nullptr, weights.data(), &grads[k]);
    images[k] = r.image();
  }
  INFO("on " << simd_target());
  CHECK(max_abs_diff(images[0], images[1]) < 1e-5);
  // Each Gaussian's gradient is a sum over its pixels; compare against the field's scale.
  auto compare = [](const char* what, const std::vector<float>& a, const std::vector<float>& b) {
    double scale = 0, diff = 0;
    for (size_t i = 0; i < a.size(); ++i) scale = std::max(scale, double(std::fabs(a[i])));
    for (size_t i = 0; i < a.size(); ++i) diff = std::max(diff, double(std::fabs(a[i] - b[i])));
    INFO(what << ": max |difference| " << diff << " of max |gradient| " << scale);
    CHECK(scale > 0);
    CHECK(diff <= 1e-5 * scale);  // measured ≤ 1.9e-6 of the scale (rotations)
  };
  compare("means", grads[0].means, grads[1].means);
  compare("scales", grads[0].scales, grads[1].scales);
  compare("rotations", grads[0].rotations, grads[1].rotations);
  compare("opacities", grads[0].opacities, grads[1].opacities);
  compare("sh", grads[0].sh, grads[1].sh);
  compare("screen", grads[0].screen, grads[1].screen);
}

TEST_CASE("the vector kernel's output does not depend on the thread count", "[kernel][data]") {
  const GaussianCloud c = read_scene(shared_data() + "/scenes/guitar.ply");
  const FrameGaussians g = frame_at(c, 0);
  const Camera cam = orbit_camera(c, 1.0, 320, 240);
  std::vector<RenderOutput> out;
  for (int threads : {1, 2, 5}) {
    RenderOptions o;
    o.kernel = Kernel::Simd;
    o.max_weights = true;
    out.push_back(with_threads(threads, [&] { return render(g, cam, o); }));
  }
  for (int k : {1, 2}) {
    CHECK(std::memcmp(out[0].rgb.data(), out[k].rgb.data(), out[0].rgb.size() * sizeof(float)) == 0);
    CHECK(out[0].max_weight == out[k].max_weight);
  }
}

TEST_CASE("the kernel option selects the kernel for one command and rejects unknown names", "[kernel][cli]") {
  std::ostringstream out, err;
  CHECK(cli::run({"info", "--kernel", "vector", shared_data() + "/scenes/playbot_3k.ply"}, out, err) == 1);
  CHECK(err.str().find("unknown kernel 'vector'") != std::string::npos);
  CHECK(resolve_kernel(Kernel::Default) == Kernel::Simd);
  // The kernel that rendered is recorded: scalar for this command only, then the default again.
  // The rig's cameras at 32x24 (COLMAP stores 2690x2016, which --width does not override).
  std::vector<Camera> rig = read_cameras(shared_data() + "/video/n3v_flame_steak_frame0/sparse/0");
  for (Camera& c : rig) {
    c = scaled_camera(c, 32.0 / c.width);
    REQUIRE((c.width == 32 && c.height == 24));  // 2016 x 32 / 2690 = 23.98, rounded
  }
  const std::string cams = join_path(scratch("kernel_option_cameras"), "transforms.json");
  write_transforms_json(cams, rig);
  for (const char* kernel : {"scalar", "simd"}) {
    const std::string dir = scratch(std::string("kernel_option_") + kernel);
    std::vector<std::string> args = {"render", "--scene", shared_data() + "/scenes/playbot_3k.ply", "--cameras", cams, "--out", dir, "--quiet"};
    if (std::string(kernel) == "scalar") args.insert(args.end(), {"--kernel", "scalar"});
    std::ostringstream o, e;
    REQUIRE(cli::run(args, o, e) == 0);
    const std::string summary = read_file(join_path(dir, "summary.json"));
    CHECK(summary.find(std::string("\"name\": \"") + kernel + "\"") != std::string::npos);
    CHECK(resolve_kernel(Kernel::Default) == Kernel::Simd);
  }
}

TEST_CASE("FILLGS_INSTRUCTION_SET holds the vector kernels to a narrower instruction set", "[kernel][data]") {
  const std::string widest = simd_target();
  const GaussianCloud c = read_scene(shared_data() + "/scenes/playbot_3k.ply");
  const FrameGaussians g = frame_at(c, 0);
  const Camera cam = orbit_camera(c, 1.0, 160, 120);
  RenderOptions o;
  o.kernel = Kernel::Scalar;
  const RenderOutput ref = render(g, cam, o);
  // Highway's names and a float vector's lanes: 128 bits for SSE4, 256 for AVX2.
  for (const auto& [name, target, lanes] : {std::tuple<std::string, std::string, int>{"sse4", "SSE4", 4}, {"avx2", "AVX2", 8}}) {
    try {
      limit_instruction_set(name, "FILLGS_INSTRUCTION_SET");
    } catch (const Error& e) {
      WARN("skipped " << name << ": " << e.what());  // a CPU without it
      continue;
    }
    INFO("held to " << name);
    CHECK(instruction_set_limit() == name);
    CHECK(std::string(simd_target()) == target);
    CHECK(kernel_instruction_set() == target);
    CHECK(tiles::simd_lane_count() == lanes);
    CHECK(embree_device_config() == (name == "sse4" ? "max_isa=sse4.2" : "max_isa=avx2"));
    CHECK_NOTHROW(accel::accel_info());  // Embree takes the cap in its device's configuration
    o.kernel = Kernel::Simd;
    CHECK(max_abs_diff(ref.rgb, render(g, cam, o).rgb) < 1e-5);  // the same bound as the widest target's
  }
  limit_instruction_set("native", "test");
  CHECK(instruction_set_limit().empty());
  CHECK(embree_device_config().empty());
  CHECK(std::string(simd_target()) == widest);
  CHECK_THROWS_WITH(limit_instruction_set("avx9", "FILLGS_INSTRUCTION_SET"),
                    Catch::Contains("FILLGS_INSTRUCTION_SET: 'avx9' is not an instruction set"));
  // The command line reads the variable and refuses a bad value in one line.
  ::setenv("FILLGS_INSTRUCTION_SET", "avx9", 1);
  std::ostringstream out, err;
  const int code = cli::run({"--version"}, out, err);
  ::unsetenv("FILLGS_INSTRUCTION_SET");
  CHECK(code == 1);
  CHECK(err.str() == "error: FILLGS_INSTRUCTION_SET: 'avx9' is not an instruction set fillgs can be held to (avx512, avx2, sse4 or native)\n");
  CHECK(std::string(simd_target()) == widest);
}

TEST_CASE("the vector preprocess writes the scalar preprocess's projection and footprint, bit for bit, at each instruction set",
          "[kernel][extremes]") {
  std::vector<Camera> cams;
  const GaussianCloud c = preprocess_extremes(&cams);
  const size_t N = c.size();
  std::vector<Vec3f> scales(N);
  for (size_t g = 0; g < N; ++g) scales[g] = c.log_scales[g].array().exp();
  auto bits = [](double x) { return bits_of(x); };
  for_each_instruction_set([&](const char* set) {
    for (size_t k = 0; k < cams.size(); ++k) {
      INFO(set << " (" << kernel_instruction_set() << "), camera " << k);
      const internal::FrustumCamera fc(cams[k]);
      std::vector<SplatProjection<double>> exact(N);
      std::vector<ProjectedGaussian> projected(N);
      std::vector<int> radii(N, 0);
      internal::project_rows(fc, c.means[0].data(), scales[0].data(), c.rotations[0].data(), 0, N, exact.data(), projected.data(),
                             radii.data());
      size_t kept = 0, mismatched = 0;
      for (size_t g = 0; g < N; ++g) {
        const double m[3] = {c.means[g][0], c.means[g][1], c.means[g][2]}, s[3] = {scales[g][0], scales[g][1], scales[g][2]},
                     q[4] = {c.rotations[g][0], c.rotations[g][1], c.rotations[g][2], c.rotations[g][3]};
        const SplatProjection<double> e = project_splat<double>(m, s, q, cams[k]);
        ProjectedGaussian p;
        const bool keep = internal::splat_footprint(e, cams[k], &p);
        kept += keep;
        bool same = radii[g] == (keep ? p.radius : 0);
        if (keep) {
          const SplatProjection<double>& v = exact[g];
          const ProjectedGaussian& w = projected[g];
          same = same && v.valid && bits(v.u) == bits(e.u) && bits(v.v) == bits(e.v) && bits(v.depth) == bits(e.depth);
          for (int i = 0; i < 3; ++i) same = same && bits(v.cov[i]) == bits(e.cov[i]) && bits(v.conic[i]) == bits(e.conic[i]);
          same = same && w.mean == p.mean && w.cov2d == p.cov2d && w.conic == p.conic && w.depth == p.depth && w.radius == p.radius &&
                 w.rect_min[0] == p.rect_min[0] && w.rect_min[1] == p.rect_min[1] && w.rect_max[0] == p.rect_max[0] &&
                 w.rect_max[1] == p.rect_max[1];
        }
        mismatched += !same;
      }
      CHECK(kept > 1000);
      CHECK(N - kept > 1000);
      CHECK(mismatched == 0);
    }
  });
}

TEST_CASE("pairs binned to their alpha spans: each tile keeps, in order, the entries whose span reaches it, and both kernels "
          "blend each tile as over the whole 3-sigma rectangles, bit for bit", "[kernel][data]") {
  const GaussianCloud c = read_scene(shared_data() + "/scenes/guitar.ply");
  const ModelParams<float> params = params_from_cloud<float>(c);
  DiffFrame<float> frame;
  params_at(params, 0.0, &frame);
  // render()'s Gaussians as the frame holds them (frame_at normalises rotations in its own order).
  FrameGaussians g = frame_at(c, 0);
  for (size_t i = 0; i < c.size(); ++i)
    for (int k = 0; k < 4; ++k) g.rotations[i][k] = frame.rotations[4 * i + k];
  for_each_instruction_set([&](const char* set) {
    for (const auto& [w, h] : {std::pair{320, 240}, std::pair{203, 117}}) {
      const Camera cam = orbit_camera(c, 0.7, w, h);
      INFO(set << " (" << kernel_instruction_set() << "), " << w << "x" << h);
      tiles::SplatSource<float> source;
      source.count = frame.size();
      source.sh_degree = frame.sh_degree;
      source.means = frame.means.data(), source.scales = frame.scales.data(), source.rotations = frame.rotations.data();
      source.opacities = frame.opacities.data(), source.sh = frame.sh;
      std::vector<int> radii;
      std::vector<ProjectedGaussian> proj;
      std::vector<uint32_t> visible;
      std::vector<float> splat, extent, colour;
      tiles::prepare_splats(source, cam, 3, tiles::SplatSetup<float>{&radii, &proj, &visible, &splat, &extent, &colour},
                            [](size_t, uint32_t, const ProjectedGaussian&, float*) {});
      std::vector<int32_t> spans;
      tiles::alpha_spans(splat.data(), extent.data(), visible.size(), &spans);
      const internal::TileBins all = internal::bin_tiles(proj, visible, w, h), cut = internal::bin_tiles(proj, visible, w, h, spans.data());
      REQUIRE(all.start.size() == cut.start.size());
      const tiles::TileSplats<float> splats{splat.data(), extent.data(), colour.data(), 3, spans.data()};
      // The reference: every pair of the 3-sigma rectangles, kept where the span and the tile
      // share a pixel (the vector kernel's per-entry cut, written out here).
      size_t dropped = 0, wrong = 0, blended_differently = 0;
      for (size_t t = 0; t + 1 < all.start.size(); ++t) {
        const int x0 = int(t % size_t(all.grid_x)) * kTileSize, y0 = int(t / size_t(all.grid_x)) * kTileSize;
        const int x1 = std::min(x0 + kTileSize, w) - 1, y1 = std::min(y0 + kTileSize, h) - 1;
        std::vector<uint32_t> expected;
        for (uint64_t e = all.start[t]; e < all.start[t + 1]; ++e) {
          const int32_t* a = &spans[4 * size_t(all.entries[e])];
          if (std::max(x0, a[0]) <= std::min(x1, a[1]) && std::max(y0, a[2]) <= std::min(y1, a[3]))
            expected.push_back(all.entries[e]);
          else
            ++dropped;
        }
        const std::vector<uint32_t> got(cut.entries.begin() + long(cut.start[t]), cut.entries.begin() + long(cut.start[t + 1]));
        wrong += got != expected;
        // Each kernel over the tile's whole list and over the cut one: the same transmittance and sums.
        for (const bool simd : {false, true}) {
          float T[2][tiles::kTilePixels], acc[2][3 * tiles::kTilePixels];
          for (int k = 0; k < 2; ++k) {
            std::fill(T[k], T[k] + tiles::kTilePixels, 1.0f);
            std::fill(acc[k], acc[k] + 3 * tiles::kTilePixels, 0.0f);
            const internal::TileBins& bins = k == 0 ? all : cut;
            tiles::TileForward<float> out;
            out.T = T[k];
            out.acc = acc[k];
            tiles::forward_tile(simd, splats, tiles::tile_work(bins.grid_x, bins.start.data(), bins.entries.data(), t, w, h), out);
          }
          blended_differently += std::memcmp(T[0], T[1], sizeof T[0]) != 0 || std::memcmp(acc[0], acc[1], sizeof acc[0]) != 0;
        }
      }
      CHECK(wrong == 0);
      CHECK(blended_differently == 0);
      CHECK(dropped > all.entries.size() / 10);  // measured: 43 % of the pairs at 320x240, 35 % at 203x117
      RenderOptions ro;
      ro.kernel = Kernel::Simd;
      ro.background = Vec3f(0.1f, 0.3f, 0.7f);
      const RenderOutput reference = render(g, cam, ro);
      DiffRenderOptions dro;
      dro.kernel = Kernel::Simd;
      dro.background = ro.background;
      DiffRasterizer<float> ras;
      ras.forward(frame, cam, dro);
      REQUIRE(ras.image().size() == reference.rgb.size());
      CHECK(std::memcmp(ras.image().data(), reference.rgb.data(), reference.rgb.size() * sizeof(float)) == 0);
      CHECK(std::memcmp(ras.alpha().data(), reference.alpha.data(), reference.alpha.size() * sizeof(float)) == 0);
    }
  });
}

TEST_CASE("the vector SSIM loss agrees with the scalar one to float rounding", "[kernel][loss]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  // The same sums, with fused multiply-adds in the vector form: value and gradient agree to
  // float rounding.
  const int W = 96, H = 70;
  const size_t P = size_t(W) * H;
  std::vector<float> render(P * 3), target(P * 3), weights(P);
  for (size_t i = 0; i < render.size(); ++i) render[i] = U(rng), target[i] = U(rng);
  for (float& w : weights) w = 0.5f + U(rng);
  std::vector<std::vector<float>> grads(2, std::vector<float>(P * 3));
  LossValue lv[2];
  for (int k = 0; k < 2; ++k) {
    set_default_kernel(k == 0 ? Kernel::Scalar : Kernel::Simd);
    lv[k] = photometric_loss<float>(render.data(), target.data(), W, H, weights.data(), 0.2, grads[size_t(k)].data());
  }
  set_default_kernel(Kernel::Simd);
  CHECK(lv[1].total == Approx(lv[0].total).epsilon(1e-6));
  CHECK(lv[1].ssim == Approx(lv[0].ssim).epsilon(1e-6));
  double scale = 0;
  for (float g : grads[0]) scale = std::max(scale, double(std::fabs(g)));
  CHECK(scale > 0);
  CHECK(max_abs_diff(grads[0], grads[1]) <= 1e-5 * scale);
}

TEST_CASE("the fused vector SSIM loss gives the gradient of the loss written out plane by plane bit for bit, at any size and thread count",
          "[kernel][loss]") {
  // The reference: the loss written out plane by plane, every per-pixel term in float one
  // operation at a time, each blur output a chain over the taps inside the image in tap
  // order from zero, with the instruction set's multiply-add: fused (one rounding) on the
  // AVX targets, a product and then a sum on SSE4 (this file is compiled without FMA, so
  // `s + w * v` rounds twice).
  auto blur = [](const std::vector<float>& in, int W, int H, bool fused, std::vector<float>& out) {
    const float* w = image::ssim_window<float>();
    auto madd = [fused](float wk, float v, float s) { return fused ? std::fma(wk, v, s) : s + wk * v; };
    std::vector<float> rows(in.size());
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        float s = 0.0f;
        for (int k = std::max(0, 5 - x); k < 11 && x + k - 5 < W; ++k) s = madd(w[k], in[size_t(y) * W + size_t(x + k - 5)], s);
        rows[size_t(y) * W + size_t(x)] = s;
      }
    out.assign(in.size(), 0.0f);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        float s = 0.0f;
        for (int k = std::max(0, 5 - y); k < 11 && y + k - 5 < H; ++k) s = madd(w[k], rows[size_t(y + k - 5) * W + size_t(x)], s);
        out[size_t(y) * W + size_t(x)] = s;
      }
  };
  auto reference = [&blur](const std::vector<float>& render, const std::vector<float>& target, const float* weights, int W, int H,
                           bool fused, std::vector<float>& grad, double* l1, double* ssim) {
    const size_t P = size_t(W) * H, n = 3 * P;
    const float l1_scale = float((1.0 - 0.2) / double(n)), ssim_scale = float(0.2 / double(n));
    grad.assign(n, 0.0f);
    *l1 = 0, *ssim = 0;
    for (size_t i = 0; i < n; ++i) {
      const float d = render[i] - target[i], w = weights ? weights[i / 3] : 1.0f;
      *l1 += double(w * std::fabs(d));
      grad[i] = l1_scale * w * (d > 0.0f ? 1.0f : d < 0.0f ? -1.0f : 0.0f);
    }
    std::vector<std::vector<float>> m(5), t(3, std::vector<float>(P)), g(3);
    std::vector<float> x(P), y(P), xx(P), yy(P), xy(P);
    const float c1 = float(0.01 * 0.01), c2 = float(0.03 * 0.03);
    for (int c = 0; c < 3; ++c) {
      for (size_t i = 0; i < P; ++i) x[i] = render[3 * i + size_t(c)], y[i] = target[3 * i + size_t(c)];
      for (size_t i = 0; i < P; ++i) xx[i] = x[i] * x[i], yy[i] = y[i] * y[i], xy[i] = x[i] * y[i];
      for (const auto& [plane, blurred] : {std::pair{&x, &m[0]}, {&y, &m[1]}, {&xx, &m[2]}, {&yy, &m[3]}, {&xy, &m[4]}})
        blur(*plane, W, H, fused, *blurred);
      for (size_t i = 0; i < P; ++i) {
        const float mx = m[0][i], my = m[1][i], coef = weights ? weights[i] : 1.0f;
        const float vx = m[2][i] - mx * mx, vy = m[3][i] - my * my, cxy = m[4][i] - mx * my;
        const float a1 = 2.0f * mx * my + c1, a2 = 2.0f * cxy + c2, b1 = mx * mx + my * my + c1, b2 = vx + vy + c2;
        const float s = a1 * a2 / (b1 * b2);
        *ssim += double(coef * s);
        const float dmu = coef * (2.0f * my * a2 / (b1 * b2) - s * 2.0f * mx / b1), dvar = coef * (-s / b2),
                    dcov = coef * (2.0f * a1 / (b1 * b2));
        t[0][i] = dmu - 2.0f * dvar * mx - dcov * my, t[1][i] = dvar, t[2][i] = dcov;
      }
      for (int k = 0; k < 3; ++k) blur(t[size_t(k)], W, H, fused, g[size_t(k)]);
      for (size_t i = 0; i < P; ++i) grad[3 * i + size_t(c)] -= ssim_scale * (g[0][i] + 2.0f * x[i] * g[1][i] + y[i] * g[2][i]);
    }
    *l1 /= double(n), *ssim /= double(n);
  };
  for_each_instruction_set([&](const char* set) {
    const bool fused = std::string(simd_target()).rfind("AVX", 0) == 0;  // AVX2, AVX3…: FMA
    std::mt19937 rng(23);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    // That rounding of the blur against the 2D window evaluated in double, zero padding:
    // float rounding only; and a constant plane keeps its value away from the borders.
    for (const auto& [W, H] : std::vector<std::pair<int, int>>{{1, 1}, {3, 7}, {37, 64}, {70, 65}}) {
      double win[11], wsum = 0;  // the window written out: σ = 1.5, normalised
      for (int i = 0; i < 11; ++i) win[i] = std::exp(-double((i - 5) * (i - 5)) / 4.5), wsum += win[i];
      for (double& v : win) v /= wsum;
      std::vector<float> in(size_t(W) * H), out;
      for (float& v : in) v = U(rng);
      blur(in, W, H, fused, out);
      double worst = 0;
      for (int py = 0; py < H; ++py)
        for (int px = 0; px < W; ++px) {
          double ref = 0;
          for (int j = 0; j < 11; ++j)
            for (int i = 0; i < 11; ++i) {
              const int qx = px + i - 5, qy = py + j - 5;
              if (qx >= 0 && qy >= 0 && qx < W && qy < H) ref += win[j] * win[i] * double(in[size_t(qy) * W + size_t(qx)]);
            }
          worst = std::max(worst, std::fabs(ref - double(out[size_t(py) * W + size_t(px)])));
        }
      CHECK(worst < 1e-6);
      if (W > 10 && H > 10) {
        blur(std::vector<float>(in.size(), 0.75f), W, H, fused, out);
        CHECK(out[size_t(H / 2) * W + size_t(W / 2)] == Approx(0.75f).epsilon(1e-6));
      }
    }
    // Widths below, at and past a vector of lanes and the 5-pixel border; heights below the
    // window, below and past a band (the rings wrap), and a wide short image.
    for (const auto& [W, H] : std::vector<std::pair<int, int>>{{1, 1}, {2, 3}, {4, 12}, {13, 11}, {17, 40}, {37, 64}, {70, 65}, {160, 90}, {333, 131}, {700, 23}}) {
      const size_t P = size_t(W) * H;
      std::vector<float> render(3 * P), target(3 * P), weights(P);
      for (size_t i = 0; i < 3 * P; ++i) render[i] = U(rng), target[i] = i % 7 == 0 ? render[i] : U(rng);  // some d = 0
      for (float& w : weights) w = U(rng) < 0.25f ? 0.0f : 2.0f * U(rng);
      for (const float* wp : {static_cast<const float*>(nullptr), static_cast<const float*>(weights.data())}) {
        std::vector<float> want;
        double l1 = 0, ssim = 0;
        reference(render, target, wp, W, H, fused, want, &l1, &ssim);
        for (int threads : {1, 2}) {
          INFO(W << "x" << H << (wp ? " weighted" : "") << ", " << threads << " threads, on " << simd_target() << " (" << set << ")");
          const ThreadLimit limit(threads);
          std::vector<float> got(3 * P, -7.0f);
          const LossValue lv = photometric_loss<float>(render.data(), target.data(), W, H, wp, 0.2, got.data());
          CHECK(std::memcmp(got.data(), want.data(), got.size() * sizeof(float)) == 0);
          CHECK(lv.l1 == Approx(l1).epsilon(1e-12));
          CHECK(lv.ssim == Approx(ssim).epsilon(1e-12));
          // Without the gradient: the same values.
          const LossValue value_only = photometric_loss<float>(render.data(), target.data(), W, H, wp, 0.2, nullptr);
          CHECK(value_only.total == lv.total);
        }
      }
    }
  });
}
