#include "fillgs/render/raster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numeric>

#include "fillgs/base/error.hpp"
#include "render/raster_internal.hpp"
#include "render/preprocess.hpp"
#include "render/tile_kernel.hpp"

namespace fillgs {

using internal::kHugeCoordinate;

bool project_gaussian(const Vec3f& mean, const Vec3f& scale, const Vec4f& rotation, const Camera& cam,
                      ProjectedGaussian* out) {
  out->radius = 0;
  // The preprocess runs in double: it is per Gaussian (cheap) and keeps huge and tiny
  // Gaussians finite where float would overflow or cancel.
  const double m[3] = {mean[0], mean[1], mean[2]}, s[3] = {scale[0], scale[1], scale[2]},
               q[4] = {rotation[0], rotation[1], rotation[2], rotation[3]};
  return internal::splat_footprint(project_splat<double>(m, s, q, cam), cam, out);
}

namespace internal {

bool splat_footprint(const SplatProjection<double>& p, const Camera& cam, ProjectedGaussian* out) {
  out->radius = 0;
  if (!p.valid) return false;
  const double a = p.cov[0], c = p.cov[2];
  const double det = a * c - p.cov[1] * p.cov[1];
  const double mid = 0.5 * (a + c);
  const double disc = std::sqrt(std::max(0.1, mid * mid - det));
  const double lambda = std::max(mid + disc, mid - disc);
  const double r = std::ceil(3.0 * std::sqrt(lambda));
  if (!std::isfinite(r)) return false;
  const int radius = int(std::min(r, kHugeCoordinate));
  const int gx = (cam.width + kTileSize - 1) / kTileSize, gy = (cam.height + kTileSize - 1) / kTileSize;
  auto tile = [](double x, int limit) { return std::min(limit, std::max(0, int(std::clamp(x, -kHugeCoordinate, kHugeCoordinate) / kTileSize))); };
  out->rect_min[0] = tile(p.u - radius, gx);
  out->rect_min[1] = tile(p.v - radius, gy);
  out->rect_max[0] = tile(p.u + radius + kTileSize - 1, gx);
  out->rect_max[1] = tile(p.v + radius + kTileSize - 1, gy);
  if ((out->rect_max[0] - out->rect_min[0]) * (out->rect_max[1] - out->rect_min[1]) == 0) return false;
  out->mean = Vec2f(float(p.u), float(p.v));
  out->cov2d = Vec3f(float(p.cov[0]), float(p.cov[1]), float(p.cov[2]));
  out->conic = Vec3f(float(p.conic[0]), float(p.conic[1]), float(p.conic[2]));
  out->depth = float(p.depth);
  out->radius = radius;
  return true;
}

}  // namespace internal

namespace {
std::atomic<Kernel> g_default_kernel{Kernel::Simd};
}  // namespace

void set_default_kernel(Kernel kernel) {
  FILLGS_CHECK(kernel != Kernel::Default);
  g_default_kernel.store(kernel);
}

Kernel resolve_kernel(Kernel kernel) { return kernel == Kernel::Default ? g_default_kernel.load() : kernel; }

const char* kernel_name(Kernel kernel) { return resolve_kernel(kernel) == Kernel::Scalar ? "scalar" : "simd"; }

const char* simd_target() { return tiles::simd_target_name(); }

int simd_lanes() { return tiles::simd_lane_count(); }

RenderOutput render(const FrameGaussians& G, const Camera& cam, const RenderOptions& opt) {
  const int W = cam.width, H = cam.height;
  FILLGS_CHECK(W > 0 && H > 0);
  FILLGS_CHECK(opt.feature_channels == 0 || opt.features != nullptr || G.size() == 0);  // no Gaussians: no features
  const size_t N = G.size();
  const int F = opt.feature_channels;
  const int C = (opt.rgb ? 3 : 0) + (opt.depth ? 1 : 0) + F;
  const int depth_channel = opt.rgb ? 3 : 0;
  const int feature_channel = depth_channel + (opt.depth ? 1 : 0);
  const bool simd = resolve_kernel(opt.kernel) == Kernel::Simd;

  RenderOutput out;
  out.width = W;
  out.height = H;
  out.radii.assign(N, 0);

  // ---- preprocess: project every Gaussian, set up the visible ones ----
  static_assert(sizeof(Vec3f) == 3 * sizeof(float) && sizeof(Vec4f) == 4 * sizeof(float), "packed Eigen vectors");
  tiles::SplatSource<float> source;
  source.count = N;
  source.sh_degree = G.sh_degree;
  source.means = G.means.empty() ? nullptr : G.means[0].data();
  source.scales = G.scales.empty() ? nullptr : G.scales[0].data();
  source.rotations = G.rotations.empty() ? nullptr : G.rotations[0].data();
  source.opacities = G.opacities.data();
  source.sh = opt.rgb ? G.sh : nullptr;
  std::vector<ProjectedGaussian> proj;
  std::vector<uint32_t> visible;
  std::vector<float> splat, extent, chan;
  tiles::prepare_splats(source, cam, C, tiles::SplatSetup<float>{&out.radii, &proj, &visible, &splat, &extent, &chan},
                        [&](size_t, uint32_t g, const ProjectedGaussian& p, float* ch) {
                          if (opt.depth) ch[depth_channel] = p.depth;
                          for (int f = 0; f < F; ++f) ch[feature_channel + f] = opt.features[size_t(g) * F + f];
                        });
  out.rendered = size_t(std::count_if(out.radii.begin(), out.radii.end(), [](int r) { return r > 0; }));
  // Each splat's α ≥ 1/255 pixels as the vector kernel cuts its boxes: both kernels blend
  // only the tiles that hold one of them (the scalar kernel's α test rejects every pixel
  // outside them; the images are the same as over the whole 3σ rectangles).
  std::vector<int32_t> spans;
  tiles::alpha_spans(splat.data(), extent.data(), visible.size(), &spans);
  const tiles::TileSplats<float> splats{splat.data(), extent.data(), chan.data(), C, spans.data()};

  // ---- bin into tiles, front to back per tile ----
  const internal::TileBins bins = internal::bin_tiles(proj, visible, W, H, spans.data());
  const int gx = bins.grid_x;
  const size_t tiles = size_t(bins.grid_x) * bins.grid_y;
  out.tile_entries = bins.entries.size();

  // ---- blend ----
  if (opt.rgb) out.rgb.assign(size_t(W) * H * 3, 0.0f);
  if (opt.depth) out.depth.assign(size_t(W) * H, 0.0f);
  if (F) out.features.assign(size_t(W) * H * F, 0.0f);
  out.alpha.assign(size_t(W) * H, 0.0f);
  std::vector<float> entry_max;  // per tile entry: max α·T, reduced per Gaussian below
  if (opt.max_weights) entry_max.assign(bins.entries.size(), 0.0f);
  std::vector<tiles::TileContributors> tile_contrib(opt.contributors ? tiles : 0);
  std::vector<uint64_t> tile_box_pixels(tiles, 0);

  tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
    alignas(64) float T[tiles::kTilePixels];
    std::vector<float> acc(size_t(tiles::kTilePixels) * std::max(C, 1));
    for (size_t t = r.begin(); t < r.end(); ++t) {
      const tiles::TileWork work = tiles::tile_work(gx, bins.start.data(), bins.entries.data(), t, W, H);
      tiles::TileForward<float> fwd;
      fwd.T = T;
      fwd.acc = acc.data();
      if (opt.max_weights) fwd.entry_max = entry_max.data() + bins.start[t];
      if (opt.contributors) fwd.contributors = &tile_contrib[t];
      fwd.box_pixels = &tile_box_pixels[t];
      tiles::forward_tile(simd, splats, work, fwd);
      // The tile's planar sums into the images, a row of the tile at a time.
      const float* a = acc.data();
      for (int py = work.y0; py < work.y1; ++py) {
        const int l0 = (py - work.y0) * kTileSize, n = work.x1 - work.x0;
        const size_t o0 = size_t(py) * W + size_t(work.x0);
        if (opt.rgb) {
          float* rgb = out.rgb.data() + 3 * o0;
          for (int k = 0; k < 3; ++k) {
            const float* ak = a + size_t(k) * tiles::kTilePixels + l0;
            const float bg = opt.background[k];
            for (int i = 0; i < n; ++i) rgb[3 * i + k] = ak[i] + T[l0 + i] * bg;
          }
        }
        if (opt.depth) std::copy_n(a + size_t(depth_channel) * tiles::kTilePixels + l0, n, out.depth.data() + o0);
        for (int f = 0; f < F; ++f) {
          const float* af = a + size_t(feature_channel + f) * tiles::kTilePixels + l0;
          float* features = out.features.data() + o0 * size_t(F) + size_t(f);
          for (int i = 0; i < n; ++i) features[size_t(i) * F] = af[i];
        }
        float* alpha = out.alpha.data() + o0;
        for (int i = 0; i < n; ++i) alpha[i] = 1.0f - T[l0 + i];
      }
    }
  });

  out.box_pixels = std::accumulate(tile_box_pixels.begin(), tile_box_pixels.end(), uint64_t(0));
  if (opt.max_weights) {
    out.max_weight.assign(N, 0.0f);
    for (size_t e = 0; e < bins.entries.size(); ++e) {
      const uint32_t g = visible[bins.entries[e]];
      out.max_weight[g] = std::max(out.max_weight[g], entry_max[e]);
    }
  }
  if (opt.contributors) {
    ContributorLists& cl = out.contributors;
    cl.offsets.assign(size_t(W) * H + 1, 0);
    auto pixel_of = [&](size_t t, uint16_t l) {
      const int x0 = int(t % gx) * kTileSize, y0 = int(t / gx) * kTileSize;
      return size_t(y0 + l / kTileSize) * W + x0 + l % kTileSize;
    };
    for (size_t t = 0; t < tiles; ++t)
      for (uint16_t l : tile_contrib[t].pixel) ++cl.offsets[pixel_of(t, l) + 1];
    std::partial_sum(cl.offsets.begin(), cl.offsets.end(), cl.offsets.begin());
    cl.ids.resize(cl.offsets.back());
    cl.weights.resize(cl.offsets.back());
    std::vector<uint64_t> fill(cl.offsets.begin(), cl.offsets.end() - 1);
    // Within a tile, pairs were appended front to back per pixel, so pixel order is kept.
    for (size_t t = 0; t < tiles; ++t) {
      const tiles::TileContributors& tc = tile_contrib[t];
      for (size_t k = 0; k < tc.pixel.size(); ++k) {
        const uint64_t at = fill[pixel_of(t, tc.pixel[k])]++;
        cl.ids[at] = visible[tc.entry[k]];
        cl.weights[at] = tc.weight[k];
      }
    }
  }
  return out;
}

}  // namespace fillgs
