// The scalar tile kernel: the reference for the vector one (tile_kernel_simd.cpp).
#include "render/tile_kernel.hpp"

#include <algorithm>
#include <cmath>

#include "raster_internal.hpp"

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
    const Real* sd = &S.splat[6 * size_t(i)];
    const Real* ch = &S.channels[size_t(i) * C];
    int px0, px1, py0, py1;
    internal::pixel_box(float(sd[0]), float(sd[1]), S.extent[2 * i], S.extent[2 * i + 1], tile.x0, tile.y0, tile.x1,
                        tile.y1, &px0, &px1, &py0, &py1);
    if (out.box_pixels && px0 <= px1 && py0 <= py1) *out.box_pixels += uint64_t(px1 - px0 + 1) * uint64_t(py1 - py0 + 1);
    float emax = 0.0f;
    for (int py = py0; py <= py1; ++py)
      for (int px = px0; px <= px1; ++px) {
        const int l = (py - tile.y0) * kTileSize + (px - tile.x0);
        if (done[l]) continue;
        const Real dx = sd[0] - Real(px), dy = sd[1] - Real(py);
        const Real power = Real(-0.5) * (sd[2] * dx * dx + sd[4] * dy * dy) - sd[3] * dx * dy;
        if (power > Real(0)) continue;
        const Real alpha = std::min(Real(kMaxAlpha), sd[5] * std::exp(power));
        if (alpha < Real(kMinAlpha)) continue;
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
