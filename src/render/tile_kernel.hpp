#pragma once
// The splat rasterizer's one tile kernel: the front-to-back blend of a 16×16 tile and its
// backward, shared by the forward renderer (render(), raster.cpp) and the differentiable
// one (DiffRasterizer, raster_grad.cpp). Depth and features are just channels.
//
// Two implementations of the same math (raster.hpp, clamp for clamp):
//  * `Kernel::Scalar` — one pixel at a time, templated on the scalar (float trains, double
//    checks gradients); the reference every benchmark measures the vector path against;
//  * `Kernel::Simd` — float only, a block of the tile per instruction (4×4 pixels with
//    AVX-512, 4×2 with AVX2, 4×1 with SSE4/NEON; chosen at run time by Google Highway),
//    with an exp of 14 instructions (relative error ≤ 2.5e-7 on [−87, 0], measured in
//    tests/test_tile_kernel.cpp) and the channel count a template parameter for 1, 3 and
//    4 channels (a feature, RGB, RGB + depth).
// Tile-local arrays are planar: pixel l = ly·16 + lx of the tile; channel k of pixel l at
// acc[k·256 + l]. Pixels of an edge tile outside the image are never touched.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "fillgs/render/raster.hpp"
#include "render/raster_internal.hpp"

namespace fillgs::tiles {

constexpr int kTilePixels = kTileSize * kTileSize;

/// The splats a tile blends, by visible index (structure of arrays over the visible set).
template <typename Real>
struct TileSplats {
  const Real* splat = nullptr;     ///< [V][6]: u, v (pixels), conic a, b, c, opacity
  const float* extent = nullptr;   ///< [V][2]: half-width, half-height where α can reach 1/255
  const Real* channels = nullptr;  ///< [V][C]
  int C = 0;
  /// [V][4]: each splat's α ≥ 1/255 pixels x0, x1, y0, y1 (alpha_spans); the vector kernel
  /// cuts each entry's box to them (the scalar kernel does not read them).
  const int32_t* spans = nullptr;
};

/// One tile: its pixel rectangle [x0, x1) × [y0, y1) and its entries front to back.
struct TileWork {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  const uint32_t* entries = nullptr;  ///< visible indices, front to back
  uint32_t count = 0;
};

/// Accepted (Gaussian, pixel) pairs of a tile in blend order, for contributor lists.
struct TileContributors {
  std::vector<uint32_t> entry;   ///< visible index
  std::vector<float> weight;     ///< α·T
  std::vector<uint16_t> pixel;   ///< tile-local pixel
};

/// Tile t of a binning (grid_x tiles per row, entries of tile t at [start[t], start[t+1])).
inline TileWork tile_work(int grid_x, const uint64_t* start, const uint32_t* entries, size_t t, int width, int height) {
  TileWork w;
  w.x0 = int(t % size_t(grid_x)) * kTileSize, w.y0 = int(t / size_t(grid_x)) * kTileSize;
  w.x1 = std::min(w.x0 + kTileSize, width), w.y1 = std::min(w.y0 + kTileSize, height);
  w.entries = entries + start[t];
  w.count = uint32_t(start[t + 1] - start[t]);
  return w;
}

/// Calls f(l, o) for every pixel of a tile: l its tile-local index, o its index in an image
/// `width` pixels wide (row-major).
template <typename F>
inline void for_each_tile_pixel(const TileWork& tile, int width, F&& f) {
  for (int py = tile.y0; py < tile.y1; ++py)
    for (int px = tile.x0; px < tile.x1; ++px) f((py - tile.y0) * kTileSize + (px - tile.x0), size_t(py) * width + px);
}

/// What a forward pass over one tile writes (every array tile-local, planar).
template <typename Real>
struct TileForward {
  Real* T = nullptr;                          ///< [256] final transmittance
  Real* acc = nullptr;                        ///< [C][256] Σ α·T·channel
  uint32_t* last = nullptr;                   ///< optional [256]: 1 + last accepted entry (0: none)
  float* entry_max = nullptr;                 ///< optional [count]: max α·T of each entry
  TileContributors* contributors = nullptr;   ///< optional, appended in blend order
  uint64_t* box_pixels = nullptr;             ///< optional: += pixels of the boxes of the entries blended
};

/// What a backward pass over one tile reads and writes.
struct TileBackward {
  const float* final_T = nullptr;  ///< [256] from the forward
  const uint32_t* last = nullptr;  ///< [256] from the forward
  const float* dpix = nullptr;     ///< [C][256] dL/d(pixel channel), pixel weights applied
  float background[3] = {0, 0, 0};
  /// Up to [count][6 + C]: dL/du, dL/dv, dL/dconic (a, b, c), dL/dopacity, dL/dchannel[C] of
  /// each entry that reaches a pixel, packed from the front in the order met (back to front);
  /// the entries left out reach no pixel, so their records would be zeros.
  float* records = nullptr;
  uint32_t* ids = nullptr;  ///< [count]: the Gaussian (tile.entries' value) of each record
};

/// One accepted (Gaussian, pixel) pair met back to front, with what a backward needs.
template <typename Real>
struct BlendPair {
  Real dx, dy;          ///< mean minus pixel
  Real gauss;           ///< exp(power)
  Real alpha;
  bool clamped;         ///< α hit 0.99: no gradient through o or G
  Real T;               ///< transmittance in front of this Gaussian
  const Real* behind;   ///< per channel: colour blended behind it, relative to T·(1−α)
  Real bg_term;         ///< −T_final / (1 − α), times the background in the caller
};

/// A tile entry as the scalar kernel reads it: the splat, its channels and its pixel box.
template <typename Real>
struct ScalarEntry {
  const Real* sd;  ///< u, v, conic a b c, opacity
  const Real* ch;
  int px0, px1, py0, py1;
  ScalarEntry(const TileSplats<Real>& S, const TileWork& tile, uint32_t i)
      : sd(&S.splat[6 * size_t(i)]), ch(&S.channels[size_t(i) * S.C]) {
    internal::pixel_box(float(sd[0]), float(sd[1]), S.extent[2 * i], S.extent[2 * i + 1], tile.x0, tile.y0, tile.x1,
                        tile.y1, &px0, &px1, &py0, &py1);
  }
  /// The pair with pixel (px, py) by raster.hpp's rule: offsets, exp(power), α and its clamp;
  /// false when the pair is skipped (power > 0 or α < 1/255).
  bool pair(int px, int py, BlendPair<Real>* pr) const {
    pr->dx = sd[0] - Real(px);
    pr->dy = sd[1] - Real(py);
    const Real power = Real(-0.5) * (sd[2] * pr->dx * pr->dx + sd[4] * pr->dy * pr->dy) - sd[3] * pr->dx * pr->dy;
    if (power > Real(0)) return false;
    pr->gauss = std::exp(power);
    const Real oG = sd[5] * pr->gauss;
    pr->alpha = std::min(Real(kMaxAlpha), oG);
    pr->clamped = oG > Real(kMaxAlpha);
    return pr->alpha >= Real(kMinAlpha);
  }
};

/// Per-thread scratch of the scalar backward.
template <typename Real>
struct BackwardScratch {
  std::vector<Real> T, behind;
};

/// The reference backward of one tile (the scalar kernel): visits its accepted pairs back to
/// front, recovering T by division like the CUDA backward. `final_T` and `last` are the
/// forward's per-pixel arrays over the whole image (row stride `width`). The visitor gets
/// begin(entry index in the tile list's global numbering, visible index), pair(image pixel,
/// BlendPair, channels) and end(entry) — the gradient records and the Fisher diagonal are
/// two visitors (raster_grad.cpp).
template <typename Real, typename Visitor>
void backward_tile_scalar(const TileSplats<Real>& S, const TileWork& tile, const Real* final_T, const uint32_t* last,
                          int width, BackwardScratch<Real>* scratch, Visitor& visitor, uint64_t first_entry);

/// The reference forward blend of one tile (the scalar kernel).
template <typename Real>
void forward_tile_scalar(const TileSplats<Real>& splats, const TileWork& tile, const TileForward<Real>& out);

/// The vector forward blend of one tile (same outputs within the exp approximation).
void forward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileForward<float>& out);

/// The forward blend of one tile with the kernel asked for (double: always scalar).
template <typename Real>
void forward_tile(bool simd, const TileSplats<Real>& splats, const TileWork& tile, const TileForward<Real>& out) {
  if constexpr (std::is_same_v<Real, float>) {
    if (simd) return forward_tile_simd(splats, tile, out);
  }
  forward_tile_scalar(splats, tile, out);
}

/// The vector backward of one tile: the gradient records of the entries that reach a pixel,
/// back to front. Returns how many it wrote.
uint32_t backward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileBackward& io);

/// Each splat's α ≥ 1/255 pixels, [count][4] x0, x1, y0, y1 inclusive (empty when x0 > x1 or
/// y0 > y1): pixel_box's bounds cut to the α ellipse's own box. alpha_extent's half-width is
/// sqrt(r²·Σxx) + 1, and sqrt(r²·Σxx) is exactly the ellipse's half-width (r² = 2 ln(255 o));
/// the cut drops that pixel of margin, loosened by 0.05 % (r² by 0.1 %) and 1e-3 px so that
/// rounding never drops a pixel the scalar kernel would blend. Computed by the vector
/// kernel's own build (fused multiply-adds where the instruction set has them), in parallel
/// in the caller's arena.
void alpha_spans(const float* splat, const float* extent, size_t count, std::vector<int32_t>* spans);

/// The instruction set the vector kernel runs with on this machine ("AVX3", "AVX2", ...).
const char* simd_target_name();
/// Its lanes per instruction (the floats of one tile block).
int simd_lane_count();

/// max |exp_simd(x) − exp(x)| / exp(x) over `count` points spread on [lo, 0] (tests, src/README.md).
double simd_exp_max_relative_error(float lo, int count);

// ---- the scalar backward's definition (a template over the visitor) ----

template <typename Real, typename Visitor>
void backward_tile_scalar(const TileSplats<Real>& S, const TileWork& tile, const Real* final_T, const uint32_t* last,
                          int width, BackwardScratch<Real>* scratch, Visitor& visitor, uint64_t first_entry) {
  const int C = S.C;
  std::vector<Real>& T = scratch->T;
  std::vector<Real>& behind = scratch->behind;
  T.assign(kTilePixels, Real(1));
  behind.assign(size_t(kTilePixels) * C, Real(0));
  for_each_tile_pixel(tile, width, [&](int l, size_t o) { T[l] = final_T[o]; });
  for (uint32_t k = tile.count; k-- > 0;) {
    const uint32_t i = tile.entries[k];
    const ScalarEntry<Real> en(S, tile, i);
    const Real* ch = en.ch;
    visitor.begin(first_entry + k, i);
    for (int py = en.py0; py <= en.py1; ++py)
      for (int px = en.px0; px <= en.px1; ++px) {
        const size_t o = size_t(py) * width + px;
        if (k >= last[o]) continue;  // the forward stopped this pixel before it
        const int l = (py - tile.y0) * kTileSize + (px - tile.x0);
        BlendPair<Real> pr;
        if (!en.pair(px, py, &pr)) continue;
        pr.T = T[l] / (Real(1) - pr.alpha);
        T[l] = pr.T;
        Real* b = &behind[size_t(l) * C];
        pr.behind = b;
        pr.bg_term = -final_T[o] / (Real(1) - pr.alpha);
        visitor.pair(o, pr, ch);
        for (int c = 0; c < C; ++c) b[c] = pr.alpha * ch[c] + (Real(1) - pr.alpha) * b[c];
      }
    visitor.end(first_entry + k);
  }
}

}  // namespace fillgs::tiles
