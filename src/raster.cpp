#include "fillgs/raster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "fillgs/error.hpp"
#include "fillgs/sh.hpp"

namespace fillgs {

namespace {
constexpr double kHugeCoordinate = 1e8;  // clamp before int conversion: a footprint covers at most the image
}  // namespace

bool project_gaussian(const Vec3f& mean, const Vec3f& scale, const Vec4f& rotation, const Camera& cam,
                      ProjectedGaussian* out) {
  out->radius = 0;
  // The preprocess runs in double: it is per Gaussian (cheap) and keeps huge and tiny
  // Gaussians finite where float would overflow or cancel.
  const Vec3d p = cam.R * mean.cast<double>() + cam.t;
  if (!(p.z() > double(kNearPlane))) return false;
  const Mat3d Rg = quat_to_matrix<double>(rotation.cast<double>());
  const Vec3d s2 = scale.cast<double>().array().square();
  const Mat3d cov3 = Rg * s2.asDiagonal() * Rg.transpose();

  const double tan_fovx = cam.width / (2.0 * cam.fx), tan_fovy = cam.height / (2.0 * cam.fy);
  const double limx = 1.3 * tan_fovx, limy = 1.3 * tan_fovy;
  const double tx = std::clamp(p.x() / p.z(), -limx, limx) * p.z();
  const double ty = std::clamp(p.y() / p.z(), -limy, limy) * p.z();
  Eigen::Matrix<double, 2, 3> J;
  J << cam.fx / p.z(), 0.0, -(cam.fx * tx) / (p.z() * p.z()), 0.0, cam.fy / p.z(), -(cam.fy * ty) / (p.z() * p.z());
  const Eigen::Matrix<double, 2, 3> T = J * cam.R;
  const Eigen::Matrix2d cov = T * cov3 * T.transpose();
  const double a = cov(0, 0) + kDilation, b = cov(0, 1), c = cov(1, 1) + kDilation;
  const double det = a * c - b * b;
  if (!(det > 0.0) || !std::isfinite(det)) return false;
  const double mid = 0.5 * (a + c);
  const double disc = std::sqrt(std::max(0.1, mid * mid - det));
  const double lambda = std::max(mid + disc, mid - disc);
  const double r = std::ceil(3.0 * std::sqrt(lambda));
  const double u = cam.fx * p.x() / p.z() + cam.cx - 0.5;
  const double v = cam.fy * p.y() / p.z() + cam.cy - 0.5;
  if (!std::isfinite(u) || !std::isfinite(v) || !std::isfinite(r)) return false;
  const int radius = int(std::min(r, kHugeCoordinate));
  const int gx = (cam.width + kTileSize - 1) / kTileSize, gy = (cam.height + kTileSize - 1) / kTileSize;
  auto tile = [](double x, int limit) { return std::min(limit, std::max(0, int(std::clamp(x, -kHugeCoordinate, kHugeCoordinate) / kTileSize))); };
  out->rect_min[0] = tile(u - radius, gx);
  out->rect_min[1] = tile(v - radius, gy);
  out->rect_max[0] = tile(u + radius + kTileSize - 1, gx);
  out->rect_max[1] = tile(v + radius + kTileSize - 1, gy);
  if ((out->rect_max[0] - out->rect_min[0]) * (out->rect_max[1] - out->rect_min[1]) == 0) return false;
  out->mean = Vec2f(float(u), float(v));
  out->cov2d = Vec3f(float(a), float(b), float(c));
  out->conic = Vec3f(float(c / det), float(-b / det), float(a / det));
  out->depth = float(p.z());
  out->radius = radius;
  return true;
}

namespace {

struct Splat {
  Vec2f mean;
  Vec3f conic;
  float opacity;
  float half_w, half_h;  // pixel half-extent of the region where α can reach 1/255
  float depth;
};

struct TileKey {
  float depth;
  uint32_t index;  // index into the visible array
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
        const float r2 = 2.0f * std::log(std::max(s.opacity, kMinAlpha) / kMinAlpha);
        s.half_w = std::sqrt(r2 * p.cov2d[0]) + 1.0f;
        s.half_h = std::sqrt(r2 * p.cov2d[2]) + 1.0f;
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

    // ---- bin into tiles (serial scatter keeps the order deterministic) ----
    const int gx = (W + kTileSize - 1) / kTileSize, gy = (H + kTileSize - 1) / kTileSize;
    const size_t tiles = size_t(gx) * gy;
    std::vector<uint64_t> tile_start(tiles + 1, 0);
    for (size_t i = 0; i < V; ++i) {
      const ProjectedGaussian& p = proj[visible[i]];
      for (int ty = p.rect_min[1]; ty < p.rect_max[1]; ++ty)
        for (int tx = p.rect_min[0]; tx < p.rect_max[0]; ++tx) ++tile_start[size_t(ty) * gx + tx + 1];
    }
    std::partial_sum(tile_start.begin(), tile_start.end(), tile_start.begin());
    std::vector<TileKey> keys(tile_start[tiles]);
    {
      std::vector<uint64_t> fill(tile_start.begin(), tile_start.end() - 1);
      for (size_t i = 0; i < V; ++i) {
        const ProjectedGaussian& p = proj[visible[i]];
        for (int ty = p.rect_min[1]; ty < p.rect_max[1]; ++ty)
          for (int tx = p.rect_min[0]; tx < p.rect_max[0]; ++tx) keys[fill[size_t(ty) * gx + tx]++] = {p.depth, uint32_t(i)};
      }
    }
    out.tile_entries = keys.size();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t t = r.begin(); t < r.end(); ++t)
        std::sort(keys.begin() + tile_start[t], keys.begin() + tile_start[t + 1], [](const TileKey& a, const TileKey& b) {
          return a.depth < b.depth || (a.depth == b.depth && a.index < b.index);
        });
    });

    // ---- blend ----
    if (opt.rgb) out.rgb.assign(size_t(W) * H * 3, 0.0f);
    if (opt.depth) out.depth.assign(size_t(W) * H, 0.0f);
    if (F) out.features.assign(size_t(W) * H * F, 0.0f);
    out.alpha.assign(size_t(W) * H, 0.0f);
    std::vector<float> entry_max;  // per tile entry: max α·T, reduced per Gaussian below
    if (opt.max_weights) entry_max.assign(keys.size(), 0.0f);
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
          const uint32_t i = keys[e].index;
          const Splat& s = splats[i];
          const float* ch = &chan[size_t(i) * C];
          const int px0 = std::max(x0, int(std::floor(s.mean.x() - s.half_w)));
          const int px1 = std::min(x1 - 1, int(std::ceil(s.mean.x() + s.half_w)));
          const int py0 = std::max(y0, int(std::floor(s.mean.y() - s.half_h)));
          const int py1 = std::min(y1 - 1, int(std::ceil(s.mean.y() + s.half_h)));
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
      for (size_t e = 0; e < keys.size(); ++e) {
        const uint32_t g = visible[keys[e].index];
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
