#pragma once
// The splat rasterizer's one tile kernel: the front-to-back blend of a 16×16 tile and its
// backward, shared by the forward renderer (render(), raster.cpp) and the differentiable
// one (DiffRasterizer, raster_grad.cpp). Depth and features are just channels.
//
// Two implementations of the same math (raster.hpp, clamp for clamp):
//  * `Kernel::Scalar` — one pixel at a time, templated on the scalar (float trains, double
//    checks gradients); the reference every benchmark measures the vector path against;
//  * `Kernel::Simd` — float only, a row of the tile per instruction (16 lanes with
//    AVX-512, 8 with AVX2, 4 with SSE4/NEON; chosen at run time by Google Highway), with
//    an exp of 14 instructions (relative error ≤ 2.5e-7 on [−87, 0], measured in
//    tests/test_tile_kernel.cpp).
// Tile-local arrays are planar: pixel l = ly·16 + lx of the tile; channel k of pixel l at
// acc[k·256 + l]. Pixels of an edge tile outside the image are never touched.
#include <cstdint>
#include <vector>

#include "fillgs/raster.hpp"

namespace fillgs::tiles {

constexpr int kTilePixels = kTileSize * kTileSize;

/// The splats a tile blends, by visible index (structure of arrays over the visible set).
template <typename Real>
struct TileSplats {
  const Real* splat = nullptr;     ///< [V][6]: u, v (pixels), conic a, b, c, opacity
  const float* extent = nullptr;   ///< [V][2]: half-width, half-height where α can reach 1/255
  const Real* channels = nullptr;  ///< [V][C]
  int C = 0;
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
  void clear() { entry.clear(), weight.clear(), pixel.clear(); }
};

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
  /// [count][6 + C] per entry: dL/du, dL/dv, dL/dconic (a, b, c), dL/dopacity, dL/dchannel[C]
  float* records = nullptr;
};

/// The reference forward blend of one tile (the scalar kernel).
template <typename Real>
void forward_tile_scalar(const TileSplats<Real>& splats, const TileWork& tile, const TileForward<Real>& out);

/// The vector forward blend of one tile (same outputs within the exp approximation).
void forward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileForward<float>& out);

/// The vector backward of one tile: per-entry gradient records, back to front.
void backward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileBackward& io);

/// The instruction set the vector kernel runs with on this machine ("AVX3", "AVX2", ...).
const char* simd_target_name();

/// max |exp_simd(x) − exp(x)| / exp(x) over `count` points spread on [lo, 0] (tests, README).
double simd_exp_max_relative_error(float lo, int count);

}  // namespace fillgs::tiles
