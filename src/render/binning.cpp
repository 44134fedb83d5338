// Binning: Gaussian-tile pairs ordered front to back per tile (raster_internal.hpp).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "render/raster_internal.hpp"

namespace fillgs::internal {

namespace {

/// Sorts a tile's keys (depth bits above the visible index, indices already ascending) by
/// depth, ties by index: a least-significant-digit radix sort on the depth's 32 bits, which
/// is stable and so keeps the index order; bytes that every key shares are skipped (depths
/// of one tile usually share the top one). Short lists use a comparison sort.
void sort_by_depth(uint64_t* keys, size_t n, std::vector<uint64_t>* scratch) {
  if (n < 96) {
    std::sort(keys, keys + n);
    return;
  }
  scratch->resize(n);
  uint64_t *from = keys, *to = scratch->data();
  uint32_t counts[4][256] = {};
  for (size_t i = 0; i < n; ++i)
    for (int d = 0; d < 4; ++d) ++counts[d][(keys[i] >> (32 + 8 * d)) & 0xff];
  for (int d = 0; d < 4; ++d) {
    const uint32_t* c = counts[d];
    if (c[(from[0] >> (32 + 8 * d)) & 0xff] == n) continue;  // one value of this byte: nothing to do
    uint32_t offset[256];
    uint32_t sum = 0;
    for (int v = 0; v < 256; ++v) offset[v] = sum, sum += c[v];
    for (size_t i = 0; i < n; ++i) to[offset[(from[i] >> (32 + 8 * d)) & 0xff]++] = from[i];
    std::swap(from, to);
  }
  if (from != keys) std::copy(from, from + n, keys);
}

/// floor(v / kTileSize) for any int (the division rounds toward zero).
int floor_div_tile(int v) { return v >= 0 ? v / kTileSize : -((kTileSize - 1 - v) / kTileSize); }

}  // namespace

TileBins bin_tiles(const std::vector<ProjectedGaussian>& proj, const std::vector<uint32_t>& visible, int W, int H,
                   const int32_t* spans) {
  TileBins b;
  b.grid_x = (W + kTileSize - 1) / kTileSize;
  b.grid_y = (H + kTileSize - 1) / kTileSize;
  const int gx = b.grid_x;
  const size_t tiles = size_t(b.grid_x) * b.grid_y;
  const size_t V = visible.size();
  // A counting sort by tile over blocks of Gaussians, in parallel: block k's pairs of tile t
  // go after blocks 0..k−1's, so each tile lists its Gaussians in visible order whatever
  // the thread count; then each tile sorts by (depth, index).
  const size_t blocks = std::clamp<size_t>(V / 4096, 1, 64), per_block = (V + blocks - 1) / blocks;
  std::vector<uint32_t> counts(blocks * tiles, 0);  // [block][tile]
  // Each visible Gaussian's tiles [tx0, tx1) × [ty0, ty1) and depth, made by the counting
  // pass and read again by the keys' pass.
  struct Tiles {
    int32_t tx0, tx1, ty0, ty1;
    float depth;
  };
  std::vector<Tiles> span_tiles(V);
  auto tiles_of = [&](size_t i) {
    const ProjectedGaussian& p = proj[visible[i]];
    Tiles r{p.rect_min[0], p.rect_max[0], p.rect_min[1], p.rect_max[1], p.depth};
    if (spans) {
      // A tile of columns [16 t, min(16 t + 16, size)) holds a pixel of the span [lo, hi]
      // exactly when lo <= hi, lo < size and floor(lo / 16) <= t <= floor(hi / 16).
      const int32_t* a = spans + 4 * i;
      auto cut = [](int32_t* t0, int32_t* t1, int lo, int hi, int size) {
        if (lo > hi || lo >= size) {
          *t1 = *t0;
          return;
        }
        *t0 = std::max(*t0, floor_div_tile(lo));
        *t1 = std::max(*t0, std::min(*t1, floor_div_tile(hi) + 1));
      };
      cut(&r.tx0, &r.tx1, a[0], a[1], W);
      cut(&r.ty0, &r.ty1, a[2], a[3], H);
    }
    return r;
  };
  auto for_each_pair = [&](size_t block, auto&& visit) {
    for (size_t i = block * per_block; i < std::min(V, (block + 1) * per_block); ++i) {
      const Tiles& r = span_tiles[i];
      for (int ty = r.ty0; ty < r.ty1; ++ty)
        for (int tx = r.tx0; tx < r.tx1; ++tx) visit(size_t(ty) * gx + tx, i, r.depth);
    }
  };
  tbb::parallel_for(size_t(0), blocks, [&](size_t k) {
    for (size_t i = k * per_block; i < std::min(V, (k + 1) * per_block); ++i) span_tiles[i] = tiles_of(i);
    uint32_t* c = &counts[k * tiles];
    for_each_pair(k, [&](size_t t, size_t, float) { ++c[t]; });
  });
  b.start.assign(tiles + 1, 0);
  std::vector<uint64_t> cursor(blocks * tiles);  // where block k writes its next pair of tile t
  uint64_t at = 0;
  for (size_t t = 0; t < tiles; ++t) {
    b.start[t] = at;
    for (size_t k = 0; k < blocks; ++k) cursor[k * tiles + t] = at, at += counts[k * tiles + t];
  }
  b.start[tiles] = at;
  // Key: the depth's bits (positive floats order like their bits) above the visible index.
  std::vector<uint64_t> keys(at);
  tbb::parallel_for(size_t(0), blocks, [&](size_t k) {
    uint64_t* cur = &cursor[k * tiles];
    for_each_pair(k, [&](size_t t, size_t i, float depth) {
      uint32_t bits;
      std::memcpy(&bits, &depth, sizeof bits);
      keys[cur[t]++] = (uint64_t(bits) << 32) | uint32_t(i);
    });
  });
  b.entries.resize(keys.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<uint64_t> scratch;
    for (size_t t = r.begin(); t < r.end(); ++t) {
      uint64_t* first = keys.data() + b.start[t];
      sort_by_depth(first, size_t(b.start[t + 1] - b.start[t]), &scratch);
      for (uint64_t e = b.start[t]; e < b.start[t + 1]; ++e) b.entries[e] = uint32_t(keys[e]);
    }
  });
  return b;
}

}  // namespace fillgs::internal
