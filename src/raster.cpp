#include "fillgs/raster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "fillgs/error.hpp"
#include "fillgs/sh.hpp"
#include "raster_internal.hpp"

namespace fillgs {

namespace {
constexpr double kHugeCoordinate = 1e8;  // clamp before int conversion: a footprint covers at most the image
}  // namespace

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

TileBins bin_tiles(const std::vector<ProjectedGaussian>& proj, const std::vector<uint32_t>& visible, int W, int H) {
  TileBins b;
  b.grid_x = (W + kTileSize - 1) / kTileSize;
  b.grid_y = (H + kTileSize - 1) / kTileSize;
  const int gx = b.grid_x;
  const size_t tiles = size_t(b.grid_x) * b.grid_y;
  const size_t V = visible.size();
  // Serial scatter keeps the order deterministic.
  b.start.assign(tiles + 1, 0);
  for (size_t i = 0; i < V; ++i) {
    const ProjectedGaussian& p = proj[visible[i]];
    for (int ty = p.rect_min[1]; ty < p.rect_max[1]; ++ty)
      for (int tx = p.rect_min[0]; tx < p.rect_max[0]; ++tx) ++b.start[size_t(ty) * gx + tx + 1];
  }
  std::partial_sum(b.start.begin(), b.start.end(), b.start.begin());
  struct Key {
    float depth;
    uint32_t index;
  };
  std::vector<Key> keys(b.start[tiles]);
  {
    std::vector<uint64_t> fill(b.start.begin(), b.start.end() - 1);
    for (size_t i = 0; i < V; ++i) {
      const ProjectedGaussian& p = proj[visible[i]];
      for (int ty = p.rect_min[1]; ty < p.rect_max[1]; ++ty)
        for (int tx = p.rect_min[0]; tx < p.rect_max[0]; ++tx) keys[fill[size_t(ty) * gx + tx]++] = {p.depth, uint32_t(i)};
    }
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t t = r.begin(); t < r.end(); ++t)
      std::sort(keys.begin() + b.start[t], keys.begin() + b.start[t + 1], [](const Key& x, const Key& y) {
        return x.depth < y.depth || (x.depth == y.depth && x.index < y.index);
      });
  });
  b.entries.resize(keys.size());
  for (size_t e = 0; e < keys.size(); ++e) b.entries[e] = keys[e].index;
  return b;
}

}  // namespace internal

namespace {

struct Splat {
  Vec2f mean;
  Vec3f conic;
  float opacity;
  float half_w, half_h;  // pixel half-extent of the region where α can reach 1/255
  float depth;
};

}  // namespace

RenderOutput render(const FrameGaussians& G, const Camera& cam, const RenderOptions& opt) {
  const int W = cam.width, H = cam.height;
  FILLGS_CHECK(W > 0 && H > 0);
  FILLGS_CHECK(opt.feature_channels == 0 || opt.features != nullptr);
  const size_t N = G.size();
  const int F = opt.feature_channels;
  const int C = (opt.rgb ? 3 : 0) + (opt.depth ? 1 : 0) + F;
  const int depth_channel = opt.rgb ? 3 : 0;
  const int feature_channel = depth_channel + (opt.depth ? 1 : 0);

  RenderOutput out;
  out.width = W;
  out.height = H;
  out.radii.assign(N, 0);

  tbb::task_arena arena(opt.threads > 0 ? opt.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    // ---- preprocess: project every Gaussian ----
    std::vector<ProjectedGaussian> proj(N);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, N, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t g = r.begin(); g < r.end(); ++g)
        if (project_gaussian(G.means[g], G.scales[g], G.rotations[g], cam, &proj[g])) out.radii[g] = proj[g].radius;
    });
    std::vector<uint32_t> visible;
    for (uint32_t g = 0; g < N; ++g)
      if (out.radii[g] > 0 && G.opacities[g] >= kMinAlpha) visible.push_back(g);
    out.rendered = size_t(std::count_if(out.radii.begin(), out.radii.end(), [](int r) { return r > 0; }));
    const size_t V = visible.size();

    // ---- per-visible splat data and blended channels ----
    std::vector<Splat> splats(V);
    std::vector<float> chan(V * size_t(C));
    const Vec3f campos = cam.centre().cast<float>();
    const int K = (G.sh_degree + 1) * (G.sh_degree + 1);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const uint32_t g = visible[i];
        const ProjectedGaussian& p = proj[g];
        Splat& s = splats[i];
        s.mean = p.mean;
        s.conic = p.conic;
        s.opacity = G.opacities[g];
        s.depth = p.depth;
        // α ≥ 1/255 needs dᵀΣ⁻¹d ≤ 2 ln(255 o); bound that ellipse, plus a pixel of margin.
        internal::alpha_extent(s.opacity, p.cov2d[0], p.cov2d[2], &s.half_w, &s.half_h);
        float* ch = &chan[i * size_t(C)];
        if (opt.rgb) {
          Vec3f dir = G.means[g] - campos;
          const float len = dir.norm();
          dir = len > 0.0f ? Vec3f(dir / len) : Vec3f(0, 0, 1);
          const Vec3f rgb = sh_to_rgb(G.sh_degree, G.sh + size_t(g) * K * 3, dir);
          ch[0] = rgb[0];
          ch[1] = rgb[1];
          ch[2] = rgb[2];
        }
        if (opt.depth) ch[depth_channel] = p.depth;
        for (int f = 0; f < F; ++f) ch[feature_channel + f] = opt.features[size_t(g) * F + f];
      }
    });

    // ---- bin into tiles, front to back per tile ----
    const internal::TileBins bins = internal::bin_tiles(proj, visible, W, H);
    const int gx = bins.grid_x;
    const size_t tiles = size_t(bins.grid_x) * bins.grid_y;
    const std::vector<uint64_t>& tile_start = bins.start;
    out.tile_entries = bins.entries.size();

    // ---- blend ----
    if (opt.rgb) out.rgb.assign(size_t(W) * H * 3, 0.0f);
    if (opt.depth) out.depth.assign(size_t(W) * H, 0.0f);
    if (F) out.features.assign(size_t(W) * H * F, 0.0f);
    out.alpha.assign(size_t(W) * H, 0.0f);
    std::vector<float> entry_max;  // per tile entry: max α·T, reduced per Gaussian below
    if (opt.max_weights) entry_max.assign(bins.entries.size(), 0.0f);
    // Contributors are gathered per tile, then laid out in pixel order.
    std::vector<std::vector<uint32_t>> tile_ids(opt.contributors ? tiles : 0);
    std::vector<std::vector<float>> tile_w(opt.contributors ? tiles : 0);
    std::vector<std::vector<uint16_t>> tile_px(opt.contributors ? tiles : 0);

    tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
      constexpr int P = kTileSize * kTileSize;
      float T[P];
      bool done[P];
      std::vector<float> acc(size_t(P) * C);
      for (size_t t = r.begin(); t < r.end(); ++t) {
        const int x0 = int(t % gx) * kTileSize, y0 = int(t / gx) * kTileSize;
        const int x1 = std::min(x0 + kTileSize, W), y1 = std::min(y0 + kTileSize, H);
        const int tw = x1 - x0, th = y1 - y0, npix = tw * th;
        std::fill(T, T + P, 1.0f);
        std::fill(done, done + P, false);
        std::fill(acc.begin(), acc.end(), 0.0f);
        int n_done = 0;
        for (uint64_t e = tile_start[t]; e < tile_start[t + 1] && n_done < npix; ++e) {
          const uint32_t i = bins.entries[e];
          const Splat& s = splats[i];
          const float* ch = &chan[size_t(i) * C];
          int px0, px1, py0, py1;
          internal::pixel_box(s.mean.x(), s.mean.y(), s.half_w, s.half_h, x0, y0, x1, y1, &px0, &px1, &py0, &py1);
          float emax = 0.0f;
          for (int py = py0; py <= py1; ++py) {
            for (int px = px0; px <= px1; ++px) {
              const int l = (py - y0) * kTileSize + (px - x0);
              if (done[l]) continue;
              const float dx = s.mean.x() - float(px), dy = s.mean.y() - float(py);
              const float power = -0.5f * (s.conic[0] * dx * dx + s.conic[2] * dy * dy) - s.conic[1] * dx * dy;
              if (power > 0.0f) continue;
              const float alpha = std::min(kMaxAlpha, s.opacity * std::exp(power));
              if (alpha < kMinAlpha) continue;
              const float test_T = T[l] * (1.0f - alpha);
              if (test_T < kMinTransmittance) {
                done[l] = true;
                ++n_done;
                continue;
              }
              const float w = alpha * T[l];
              float* a = &acc[size_t(l) * C];
              for (int k = 0; k < C; ++k) a[k] += ch[k] * w;
              T[l] = test_T;
              if (w > emax) emax = w;
              if (opt.contributors) {
                tile_ids[t].push_back(visible[i]);
                tile_w[t].push_back(w);
                tile_px[t].push_back(uint16_t(l));
              }
            }
          }
          if (opt.max_weights) entry_max[e] = emax;
        }
        for (int py = y0; py < y1; ++py)
          for (int px = x0; px < x1; ++px) {
            const int l = (py - y0) * kTileSize + (px - x0);
            const size_t o = size_t(py) * W + px;
            const float* a = &acc[size_t(l) * C];
            if (opt.rgb)
              for (int k = 0; k < 3; ++k) out.rgb[o * 3 + k] = a[k] + T[l] * opt.background[k];
            if (opt.depth) out.depth[o] = a[depth_channel];
            for (int f = 0; f < F; ++f) out.features[o * F + f] = a[feature_channel + f];
            out.alpha[o] = 1.0f - T[l];
          }
      }
    });

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
      for (size_t t = 0; t < tiles; ++t) {
        const int x0 = int(t % gx) * kTileSize, y0 = int(t / gx) * kTileSize;
        for (uint16_t l : tile_px[t]) ++cl.offsets[size_t(y0 + l / kTileSize) * W + x0 + l % kTileSize + 1];
      }
      std::partial_sum(cl.offsets.begin(), cl.offsets.end(), cl.offsets.begin());
      cl.ids.resize(cl.offsets.back());
      cl.weights.resize(cl.offsets.back());
      std::vector<uint64_t> fill(cl.offsets.begin(), cl.offsets.end() - 1);
      // Within a tile, entries were appended front to back per pixel, so pixel order is kept.
      for (size_t t = 0; t < tiles; ++t) {
        const int x0 = int(t % gx) * kTileSize, y0 = int(t / gx) * kTileSize;
        for (size_t k = 0; k < tile_px[t].size(); ++k) {
          const uint16_t l = tile_px[t][k];
          const uint64_t at = fill[size_t(y0 + l / kTileSize) * W + x0 + l % kTileSize]++;
          cl.ids[at] = tile_ids[t][k];
          cl.weights[at] = tile_w[t][k];
        }
      }
    }
  });
  return out;
}

}  // namespace fillgs
