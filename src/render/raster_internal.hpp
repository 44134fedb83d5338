#pragma once
// Pieces of the rasterizer shared by the forward renderer (raster.cpp), the differentiable
// one (raster_grad.cpp) and the tile kernel (src/render/), so that all cull, bin and order
// identically. bin_tiles lives in src/render/binning.cpp.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fillgs/render/raster.hpp"
#include "fillgs/render/raster_grad.hpp"

namespace fillgs::internal {

/// Screen coordinates are clamped to this before int conversion: a footprint covers at most the image.
constexpr double kHugeCoordinate = 1e8;

/// Radius and touched tiles of a projected splat (3DGS: ceil(3·sqrt(λmax)), tile rect);
/// false when 3DGS culls it. Fills every field of `out`.
bool splat_footprint(const SplatProjection<double>& p, const Camera& cam, ProjectedGaussian* out);

/// Gaussian-tile pairs: tile t owns entries [start[t], start[t+1]) of `entries`, each an
/// index into `visible`, ordered front to back by view depth (ties by index).
struct TileBins {
  int grid_x = 0, grid_y = 0;
  std::vector<uint64_t> start;
  std::vector<uint32_t> entries;
};
/// With `spans` ([V][4]: each splat's α ≥ 1/255 pixels x0, x1, y0, y1, tiles::alpha_spans),
/// a Gaussian is binned only into the tiles that hold one of those
/// pixels: the vector kernel skips every other pair (its per-entry cut leaves nothing) and
/// the scalar kernel's α test rejects each of their pixels, so leaving them out changes no
/// value either computes (tests/test_tile_kernel.cpp).
TileBins bin_tiles(const std::vector<ProjectedGaussian>& projected, const std::vector<uint32_t>& visible, int width,
                   int height, const int32_t* spans = nullptr);

/// Pixel half-extent of the region where a splat's α can reach 1/255, plus a pixel of margin.
inline void alpha_extent(float opacity, float cov_a, float cov_c, float* half_w, float* half_h) {
  const float r2 = 2.0f * std::log(std::max(opacity, kMinAlpha) / kMinAlpha);
  *half_w = std::sqrt(r2 * cov_a) + 1.0f;
  *half_h = std::sqrt(r2 * cov_c) + 1.0f;
}

/// Pixels of the tile [x0, x1) × [y0, y1) where a splat centred at (mx, my) with those
/// half-extents can reach α = 1/255 (inclusive bounds; empty when px0 > px1).
inline void pixel_box(float mx, float my, float half_w, float half_h, int x0, int y0, int x1, int y1, int* px0, int* px1,
                      int* py0, int* py1) {
  *px0 = std::max(x0, int(std::floor(mx - half_w)));
  *px1 = std::min(x1 - 1, int(std::ceil(mx + half_w)));
  *py0 = std::max(y0, int(std::floor(my - half_h)));
  *py1 = std::min(y1 - 1, int(std::ceil(my + half_h)));
}

}  // namespace fillgs::internal
