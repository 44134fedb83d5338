// The vector tile kernel: the scalar kernel's math (tile_kernel.cpp) on a row of the tile
// per instruction. Compiled once per instruction set by Google Highway (foreach_target)
// and dispatched at run time, so one binary uses AVX-512 where the machine has it.
//
// Lanes are pixels of one tile row; a lane is live when its pixel lies in the splat's
// box, has not saturated (forward) or was reached by the forward (backward). Lanes that
// are not live compute but never store. Per-entry sums are reduced across lanes in a
// fixed order, so results do not depend on the thread count.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/tile_kernel_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "raster_internal.hpp"
#include "render/tile_kernel.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::tiles {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::CappedTag<float, kTileSize>;
using DI = hn::RebindToSigned<D>;

/// e^x for x ≤ 0, the kernel's exp: e^x = 2^n · e^f with n = round(x·log2 e), |f| ≤ ½ ln 2
/// and e^f by its degree-6 Taylor polynomial (truncation ≤ (½ ln 2)⁷/7! ≈ 1.2e-7 relative);
/// 14 instructions against Highway's Exp's ~25. Below −87 (e^x < 2^−125) the argument is
/// clamped: α = o·e^x is then far under 1/255 and rejected. The measured bound, float
/// rounding included, is in tests/test_tile_kernel.cpp and the README.
template <class DF, class V>
HWY_INLINE V ExpNonPositive(DF d, V x) {
  const hn::RebindToSigned<DF> di;
  const auto xc = hn::Max(x, hn::Set(d, -87.0f));
  const auto n = hn::Round(hn::Mul(xc, hn::Set(d, 1.44269504088896341f)));
  // f = x − n ln 2 with ln 2 in two parts (Cody–Waite), exact enough for n up to 126.
  const auto f = hn::NegMulAdd(n, hn::Set(d, 1.42860677e-6f), hn::NegMulAdd(n, hn::Set(d, 0.693145752f), xc));
  auto p = hn::Set(d, 1.0f / 720.0f);
  p = hn::MulAdd(p, f, hn::Set(d, 1.0f / 120.0f));
  p = hn::MulAdd(p, f, hn::Set(d, 1.0f / 24.0f));
  p = hn::MulAdd(p, f, hn::Set(d, 1.0f / 6.0f));
  p = hn::MulAdd(p, f, hn::Set(d, 0.5f));
  p = hn::MulAdd(p, f, hn::Set(d, 1.0f));
  p = hn::MulAdd(p, f, hn::Set(d, 1.0f));
  // Scale by 2^n: add n to the exponent field.
  const auto bits = hn::Add(hn::BitCast(di, p), hn::ShiftLeft<23>(hn::ConvertTo(di, n)));
  return hn::BitCast(d, bits);
}

/// A splat's box in tile-local pixels, and the test that skips the box's rows the α ≥ 1/255
/// ellipse misses; false when the box misses the tile.
struct LocalBox {
  int lx0, lx1, ly0, ly1;
  // Row test: along a row at offset dy, the quadratic dᵀΣ⁻¹d is at least (c − b²/a)·dy², and
  // α ≥ 1/255 needs it ≤ 2 ln(255 o). The box bounds the ellipse with a pixel of margin on
  // each side; the test removes those rows (a third of a small splat's). Loosened by 0.1%
  // so that rounding never drops a row the scalar kernel would blend.
  float row_q = 0, row_limit = 0;
  bool row_empty(float dy) const { return dy * dy * row_q > row_limit; }
};
inline bool local_box(const TileSplats<float>& S, uint32_t i, const TileWork& t, LocalBox* b) {
  const float* sd = &S.splat[6 * size_t(i)];
  int px0, px1, py0, py1;
  internal::pixel_box(sd[0], sd[1], S.extent[2 * i], S.extent[2 * i + 1], t.x0, t.y0, t.x1, t.y1, &px0, &px1, &py0, &py1);
  b->lx0 = px0 - t.x0, b->lx1 = px1 - t.x0, b->ly0 = py0 - t.y0, b->ly1 = py1 - t.y0;
  const float a = sd[2], bb = sd[3], c = sd[4];
  if (a > 0.0f && sd[5] > 0.0f) {
    b->row_q = c - bb * bb / a;
    b->row_limit = 2.0f * std::log(std::max(255.0f * sd[5], 1.0f)) * 1.001f + 1e-3f;
  } else {
    b->row_q = 0.0f, b->row_limit = 1.0f;  // never skips
  }
  return px0 <= px1 && py0 <= py1;
}

/// One splat broadcast to the lanes: the geometry both passes evaluate, row by row.
struct SplatLanes {
  hn::Vec<D> mx, ca, cb, cc, opacity;
  hn::Vec<DI> box_lo, box_hi, x0;  // integer lanes compare strictly only (Highway 1.0)
  hn::Vec<D> cdy2, bdy, dy;        // the current row's terms
  SplatLanes(const float* sd, const LocalBox& b, const TileWork& tile)
      : mx(hn::Set(D(), sd[0])), ca(hn::Set(D(), sd[2])), cb(hn::Set(D(), sd[3])), cc(hn::Set(D(), sd[4])),
        opacity(hn::Set(D(), sd[5])), box_lo(hn::Set(DI(), b.lx0 - 1)), box_hi(hn::Set(DI(), b.lx1 + 1)),
        x0(hn::Set(DI(), tile.x0)), cdy2(hn::Zero(D())), bdy(hn::Zero(D())), dy(hn::Zero(D())) {}
  void set_row(float dy_row) {
    dy = hn::Set(D(), dy_row);
    cdy2 = hn::Mul(cc, hn::Mul(dy, dy));
    bdy = hn::Mul(cb, dy);
  }
  /// Tile-local columns lx inside the box.
  hn::Mask<DI> in_box(hn::Vec<DI> lx) const { return hn::And(hn::Gt(lx, box_lo), hn::Lt(lx, box_hi)); }
  /// Mean minus pixel along x, as the scalar kernel computes it.
  hn::Vec<D> dx(hn::Vec<DI> lx) const { return hn::Sub(mx, hn::ConvertTo(D(), hn::Add(lx, x0))); }
  /// −½ dᵀΣ⁻¹d.
  hn::Vec<D> power(hn::Vec<D> dxv) const {
    return hn::NegMulAdd(bdy, dxv, hn::Mul(hn::Set(D(), -0.5f), hn::MulAdd(hn::Mul(ca, dxv), dxv, cdy2)));
  }
};

/// Visits the box's rows the splat's ellipse reaches, a row chunk at a time:
/// visit(l, lx) with l the chunk's first tile-local pixel and lx its lanes' columns.
template <class Visit>
HWY_INLINE void for_each_chunk(const LocalBox& b, float mean_y, const TileWork& tile, SplatLanes& g, Visit&& visit) {
  const DI di;
  const int N = int(hn::Lanes(D()));
  const auto iota = hn::Iota(di, 0);
  for (int ly = b.ly0; ly <= b.ly1; ++ly) {
    const float dy_row = mean_y - float(tile.y0 + ly);
    if (b.row_empty(dy_row)) continue;
    g.set_row(dy_row);
    for (int cx = (b.lx0 / N) * N; cx <= b.lx1; cx += N) visit(ly * kTileSize + cx, hn::Add(hn::Set(di, cx), iota));
  }
}

void ForwardTile(const TileSplats<float>& S, const TileWork& tile, const TileForward<float>& out) {
  const D d;
  const DI di;
  const int N = int(hn::Lanes(d));
  const int C = S.C;
  const int npix = (tile.x1 - tile.x0) * (tile.y1 - tile.y0);
  HWY_ALIGN int32_t done[kTilePixels];
  HWY_ALIGN float wbuf[kTileSize];
  std::fill(out.T, out.T + kTilePixels, 1.0f);
  std::fill(out.acc, out.acc + size_t(C) * kTilePixels, 0.0f);
  std::fill(done, done + kTilePixels, 0);
  if (out.last) std::fill(out.last, out.last + kTilePixels, 0u);
  int32_t* last = reinterpret_cast<int32_t*>(out.last);
  const auto zero = hn::Zero(d), one = hn::Set(d, 1.0f);
  const auto max_alpha = hn::Set(d, kMaxAlpha), min_alpha = hn::Set(d, kMinAlpha), min_T = hn::Set(d, kMinTransmittance);
  int n_done = 0;
  for (uint32_t k = 0; k < tile.count; ++k) {
    if (n_done >= npix) {
      if (out.entry_max) std::fill(out.entry_max + k, out.entry_max + tile.count, 0.0f);
      break;
    }
    const uint32_t i = tile.entries[k];
    LocalBox b;
    if (!local_box(S, i, tile, &b)) {
      if (out.entry_max) out.entry_max[k] = 0.0f;
      continue;
    }
    if (out.box_pixels) *out.box_pixels += uint64_t(b.lx1 - b.lx0 + 1) * uint64_t(b.ly1 - b.ly0 + 1);
    const float* sd = &S.splat[6 * size_t(i)];
    const float* ch = &S.channels[size_t(i) * C];
    SplatLanes g(sd, b, tile);
    const auto entry = hn::Set(di, int32_t(k + 1));
    auto emax = zero;
    for_each_chunk(b, sd[1], tile, g, [&](int l, hn::Vec<DI> lx) {
        auto live = hn::RebindMask(d, hn::And(g.in_box(lx), hn::Eq(hn::LoadU(di, done + l), hn::Zero(di))));
        if (hn::AllFalse(d, live)) return;
        const auto power = g.power(g.dx(lx));
        const auto alpha = hn::Min(max_alpha, hn::Mul(g.opacity, ExpNonPositive(d, hn::Min(power, zero))));
        // No branch on the exp's result: lanes that fail only stop storing (a mispredicted
        // branch here costs more than the stores it would save).
        live = hn::And(live, hn::And(hn::Le(power, zero), hn::Ge(alpha, min_alpha)));
        const auto T = hn::LoadU(d, out.T + l);
        const auto test_T = hn::Mul(T, hn::Sub(one, alpha));
        const auto stop = hn::And(live, hn::Lt(test_T, min_T));
        if (!hn::AllFalse(d, stop)) {
          n_done += int(hn::CountTrue(d, stop));
          hn::StoreU(hn::Or(hn::LoadU(di, done + l), hn::VecFromMask(di, hn::RebindMask(di, stop))), di, done + l);
        }
        const auto accept = hn::AndNot(stop, live);
        const auto w = hn::IfThenElseZero(accept, hn::Mul(alpha, T));
        for (int c = 0; c < C; ++c) {
          float* a = out.acc + size_t(c) * kTilePixels + l;
          hn::StoreU(hn::MulAdd(hn::Set(d, ch[c]), w, hn::LoadU(d, a)), d, a);
        }
        hn::StoreU(hn::IfThenElse(accept, test_T, T), d, out.T + l);
        if (last) hn::StoreU(hn::IfThenElse(hn::RebindMask(di, accept), entry, hn::LoadU(di, last + l)), di, last + l);
        emax = hn::Max(emax, w);
        if (out.contributors) {
          hn::Store(w, d, wbuf);
          for (int j = 0; j < N; ++j)
            if (wbuf[j] > 0.0f) {
              out.contributors->entry.push_back(i);
              out.contributors->weight.push_back(wbuf[j]);
              out.contributors->pixel.push_back(uint16_t(l + j));
            }
        }
    });
    if (out.entry_max) out.entry_max[k] = hn::GetLane(hn::MaxOfLanes(d, emax));
  }
}

void BackwardTile(const TileSplats<float>& S, const TileWork& tile, const TileBackward& io) {
  const D d;
  const DI di;
  const int N = int(hn::Lanes(d));
  const int C = S.C, R = 6 + C;
  HWY_ALIGN float T[kTilePixels];
  std::copy(io.final_T, io.final_T + kTilePixels, T);
  std::vector<float> behind(size_t(C) * kTilePixels, 0.0f);
  std::vector<float> channel_acc(size_t(C) * N);  // per channel, lanes
  const int32_t* last = reinterpret_cast<const int32_t*>(io.last);
  const auto zero = hn::Zero(d), one = hn::Set(d, 1.0f), minus_half = hn::Set(d, -0.5f);
  const auto max_alpha = hn::Set(d, kMaxAlpha), min_alpha = hn::Set(d, kMinAlpha);
  for (uint32_t k = tile.count; k-- > 0;) {
    float* rec = io.records + size_t(k) * R;
    const uint32_t i = tile.entries[k];
    LocalBox b;
    if (!local_box(S, i, tile, &b)) {
      std::fill(rec, rec + R, 0.0f);
      continue;
    }
    const float* sd = &S.splat[6 * size_t(i)];
    const float* ch = &S.channels[size_t(i) * C];
    SplatLanes g(sd, b, tile);
    const auto entry = hn::Set(di, int32_t(k));
    auto g_u = zero, g_v = zero, g_a = zero, g_b = zero, g_c = zero, g_o = zero;
    std::fill(channel_acc.begin(), channel_acc.end(), 0.0f);
    for_each_chunk(b, sd[1], tile, g, [&](int l, hn::Vec<DI> lx) {
        // Reached by the forward: entries [0, last) of the tile were blended at this pixel.
        auto live = hn::RebindMask(d, hn::And(g.in_box(lx), hn::Lt(entry, hn::LoadU(di, last + l))));
        if (hn::AllFalse(d, live)) return;
        const auto dx = g.dx(lx);
        const auto power = g.power(dx);
        const auto gauss = ExpNonPositive(d, hn::Min(power, zero));
        const auto oG = hn::Mul(g.opacity, gauss);
        const auto alpha = hn::Min(max_alpha, oG);
        live = hn::And(live, hn::And(hn::Le(power, zero), hn::Ge(alpha, min_alpha)));
        const auto transparency = hn::Sub(one, alpha);
        const auto inv_transparency = hn::Div(one, transparency);  // one division for T and the background
        const auto T_here = hn::LoadU(d, T + l);
        const auto T_front = hn::Mul(T_here, inv_transparency);  // transmittance in front of this Gaussian
        hn::StoreU(hn::IfThenElse(live, T_front, T_here), d, T + l);
        const auto w = hn::IfThenElseZero(live, hn::Mul(alpha, T_front));
        auto dL_dalpha = zero, bg_dot = zero;
        for (int c = 0; c < C; ++c) {
          const auto dpix = hn::LoadU(d, io.dpix + size_t(c) * kTilePixels + l);
          float* ca_c = channel_acc.data() + size_t(c) * N;
          hn::StoreU(hn::MulAdd(w, dpix, hn::LoadU(d, ca_c)), d, ca_c);
          float* bp = behind.data() + size_t(c) * kTilePixels + l;
          const auto bh = hn::LoadU(d, bp), chv = hn::Set(d, ch[c]);
          dL_dalpha = hn::MulAdd(hn::Sub(chv, bh), dpix, dL_dalpha);
          hn::StoreU(hn::IfThenElse(live, hn::MulAdd(alpha, chv, hn::Mul(transparency, bh)), bh), d, bp);
          if (c < 3) bg_dot = hn::MulAdd(hn::Set(d, io.background[c]), dpix, bg_dot);
        }
        const auto bg_term = hn::Neg(hn::Mul(hn::LoadU(d, io.final_T + l), inv_transparency));
        dL_dalpha = hn::MulAdd(bg_term, bg_dot, hn::Mul(dL_dalpha, T_front));
        // α clamped at 0.99: no gradient through the opacity or the Gaussian's shape.
        dL_dalpha = hn::IfThenElseZero(hn::AndNot(hn::Gt(oG, max_alpha), live), dL_dalpha);
        g_o = hn::MulAdd(gauss, dL_dalpha, g_o);
        const auto dp = hn::Mul(alpha, dL_dalpha);  // dL/dpower
        g_u = hn::NegMulAdd(dp, hn::MulAdd(g.ca, dx, g.bdy), g_u);
        g_v = hn::NegMulAdd(dp, hn::MulAdd(g.cb, dx, hn::Mul(g.cc, g.dy)), g_v);
        const auto half_dp = hn::Mul(minus_half, dp);
        g_a = hn::MulAdd(half_dp, hn::Mul(dx, dx), g_a);
        g_b = hn::NegMulAdd(dp, hn::Mul(dx, g.dy), g_b);
        g_c = hn::MulAdd(half_dp, hn::Mul(g.dy, g.dy), g_c);
    });
    rec[0] = hn::GetLane(hn::SumOfLanes(d, g_u));
    rec[1] = hn::GetLane(hn::SumOfLanes(d, g_v));
    rec[2] = hn::GetLane(hn::SumOfLanes(d, g_a));
    rec[3] = hn::GetLane(hn::SumOfLanes(d, g_b));
    rec[4] = hn::GetLane(hn::SumOfLanes(d, g_c));
    rec[5] = hn::GetLane(hn::SumOfLanes(d, g_o));
    for (int c = 0; c < C; ++c) rec[6 + c] = hn::GetLane(hn::SumOfLanes(d, hn::LoadU(d, channel_acc.data() + size_t(c) * N)));
  }
}

double ExpMaxRelativeError(float lo, int count) {
  const D d;
  const int N = int(hn::Lanes(d));
  HWY_ALIGN float x[kTileSize], y[kTileSize];
  double worst = 0;
  for (int s = 0; s < count; s += N) {
    for (int j = 0; j < N; ++j) x[j] = lo * (1.0f - float(std::min(s + j, count - 1)) / float(std::max(1, count - 1)));
    hn::Store(ExpNonPositive(d, hn::Load(d, x)), d, y);
    for (int j = 0; j < N; ++j) {
      const double ref = std::exp(double(x[j]));
      if (ref > 1e-30) worst = std::max(worst, std::abs(double(y[j]) - ref) / ref);
    }
  }
  return worst;
}

const char* TargetName() { return hwy::TargetName(HWY_TARGET); }

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::tiles
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::tiles {

HWY_EXPORT(ForwardTile);
HWY_EXPORT(BackwardTile);
HWY_EXPORT(ExpMaxRelativeError);
HWY_EXPORT(TargetName);

void forward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileForward<float>& out) {
  HWY_DYNAMIC_DISPATCH(ForwardTile)(splats, tile, out);
}

void backward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileBackward& io) {
  HWY_DYNAMIC_DISPATCH(BackwardTile)(splats, tile, io);
}

double simd_exp_max_relative_error(float lo, int count) { return HWY_DYNAMIC_DISPATCH(ExpMaxRelativeError)(lo, count); }

const char* simd_target_name() { return HWY_DYNAMIC_DISPATCH(TargetName)(); }

}  // namespace fillgs::tiles
#endif
