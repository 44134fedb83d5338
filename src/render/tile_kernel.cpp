// The scalar tile kernel: the reference for the vector one (tile_kernel_simd.cpp).
#include "render/tile_kernel.hpp"

#include <algorithm>
#include <cmath>

#include "render/raster_internal.hpp"

namespace fillgs::tiles {

template <typename Real>
void forward_tile_scalar(const TileSplats<Real>& S, const TileWork& tile, const TileForward<Real>& out) {
  const int C = S.C;
  const int npix = (tile.x1 - tile.x0) * (tile.y1 - tile.y0);
  bool done[kTilePixels];
  std::fill(out.T, out.T + kTilePixels, Real(1));
  std::fill(out.acc, out.acc + size_t(C) * kTilePixels, Real(0));
  std::fill(done, done + kTilePixels, false);
  if (out.last) std::fill(out.last, out.last + kTilePixels, 0u);
  int n_done = 0;
  for (uint32_t k = 0; k < tile.count; ++k) {
    if (n_done >= npix) {  // every pixel saturated: the rest contribute nothing
      if (out.entry_max) std::fill(out.entry_max + k, out.entry_max + tile.count, 0.0f);
      break;
    }
    const uint32_t i = tile.entries[k];
    const ScalarEntry<Real> en(S, tile, i);
    const Real* ch = en.ch;
    if (out.box_pixels && en.px0 <= en.px1 && en.py0 <= en.py1)
      *out.box_pixels += uint64_t(en.px1 - en.px0 + 1) * uint64_t(en.py1 - en.py0 + 1);
    float emax = 0.0f;
    for (int py = en.py0; py <= en.py1; ++py)
      for (int px = en.px0; px <= en.px1; ++px) {
        const int l = (py - tile.y0) * kTileSize + (px - tile.x0);
        if (done[l]) continue;
        BlendPair<Real> pr;
        if (!en.pair(px, py, &pr)) continue;
        const Real alpha = pr.alpha;
        const Real test_T = out.T[l] * (Real(1) - alpha);
        if (test_T < Real(kMinTransmittance)) {
          done[l] = true;
          ++n_done;
          continue;
        }
        const Real w = alpha * out.T[l];
        for (int c = 0; c < C; ++c) out.acc[c * kTilePixels + l] += ch[c] * w;
        out.T[l] = test_T;
        if (out.last) out.last[l] = k + 1;
        emax = std::max(emax, float(w));
        if (out.contributors) {
          out.contributors->entry.push_back(i);
          out.contributors->weight.push_back(float(w));
          out.contributors->pixel.push_back(uint16_t(l));
        }
      }
    if (out.entry_max) out.entry_max[k] = emax;
  }
}

template void forward_tile_scalar<float>(const TileSplats<float>&, const TileWork&, const TileForward<float>&);
template void forward_tile_scalar<double>(const TileSplats<double>&, const TileWork&, const TileForward<double>&);

}  // namespace fillgs::tiles
