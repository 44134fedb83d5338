// The vector tile kernel: the scalar kernel's math (tile_kernel.cpp) on a block of the
// tile per instruction. Compiled once per instruction set by Google Highway (foreach_target)
// and dispatched at run time, so one binary uses AVX-512 where the machine has it.
//
// Lanes are a block of tile pixels (BlockLayout); a lane is live when its pixel lies in
// the splat's box, has not saturated (forward) or was reached by the forward (backward). Lanes that
// are not live compute but never store. Per-entry sums are reduced across lanes in a
// fixed order, so results do not depend on the thread count.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/tile_kernel_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/cache_control.h>
#include <hwy/highway.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/raster_internal.hpp"
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
/// rounding included, is in tests/test_tile_kernel.cpp and src/README.md.
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

/// Lanes are a block of the tile: bw columns × bh = lanes / bw rows (4×4 with
/// AVX-512, 4×2 with AVX2, 4×1 with SSE4), so a small splat takes a few blocks where it
/// took one instruction per row. Tile-local arrays inside the kernel are block-major
/// (block b's lanes at b·lanes …); they are converted from and to the row-major layout of
/// the interface once per tile.
struct BlockLayout {
  int lanes, bw, bh, blocks_x;  // lanes per block, block width and height, blocks per tile row
  HWY_ALIGN int32_t col[kTileSize], row[kTileSize];  // each lane's column and row in its block
  BlockLayout() : lanes(int(hn::Lanes(D()))), bw(std::min(4, lanes)), bh(lanes / bw), blocks_x(kTileSize / bw) {
    for (int j = 0; j < lanes; ++j) col[j] = j % bw, row[j] = j / bw;
  }
  /// Row-major tile pixel of lane j of the block at (bx, by).
  int pixel(int bx, int by, int j) const { return (by * bh + j / bw) * kTileSize + bx * bw + j % bw; }
  int base(int bx, int by) const { return (by * blocks_x + bx) * lanes; }
  /// Block-major copy of row-major planes (`planes` planes of kTilePixels), or back.
  template <typename T>
  void convert(const T* from, T* to, int planes, bool to_blocks) const {
    for (int p = 0; p < planes; ++p)
      for (int by = 0; by < kTileSize / bh; ++by)
        for (int bx = 0; bx < blocks_x; ++bx)
          for (int j = 0; j < lanes; ++j) {
            const int row_major = p * kTilePixels + pixel(bx, by, j), block_major = p * kTilePixels + base(bx, by) + j;
            to[to_blocks ? block_major : row_major] = from[to_blocks ? row_major : block_major];
          }
  }
  template <typename T>
  void to_blocks(const T* rows, T* blocks, int planes) const { convert(rows, blocks, planes, true); }
  template <typename T>
  void to_rows(const T* blocks, T* rows, int planes) const { convert(blocks, rows, planes, false); }
};

/// A splat's pixels in a tile: its α ≥ 1/255 pixels (alpha_spans) within the tile. False
/// when none is.
struct LocalBox {
  int lx0, lx1, ly0, ly1;
  uint64_t box_pixels;  // pixels of pixel_box's box before the cut (the scalar kernel's work)
};
inline bool local_box(const TileSplats<float>& S, uint32_t i, const TileWork& t, LocalBox* b) {
  const float* sd = &S.splat[6 * size_t(i)];
  int px0, px1, py0, py1;
  internal::pixel_box(sd[0], sd[1], S.extent[2 * i], S.extent[2 * i + 1], t.x0, t.y0, t.x1, t.y1, &px0, &px1, &py0, &py1);
  b->box_pixels = px0 <= px1 && py0 <= py1 ? uint64_t(px1 - px0 + 1) * uint64_t(py1 - py0 + 1) : 0;
  const int32_t* a = &S.spans[4 * size_t(i)];
  px0 = std::max(t.x0, a[0]);
  px1 = std::min(t.x1 - 1, a[1]);
  py0 = std::max(t.y0, a[2]);
  py1 = std::min(t.y1 - 1, a[3]);
  b->lx0 = px0 - t.x0, b->lx1 = px1 - t.x0, b->ly0 = py0 - t.y0, b->ly1 = py1 - t.y0;
  return px0 <= px1 && py0 <= py1;
}

/// A tile's entries are depth-sorted, so their splats are read in no order the hardware can
/// predict: without a hint, the first read of each entry's splat, box and channels waits on
/// memory (about 30 % of both passes' time at the pool benchmark's 160×90, measured with
/// perf). The kernels ask for the entry kPrefetchAhead places further along the blend order
/// while they work on this one; the hint changes no value.
constexpr uint32_t kPrefetchAhead = 8;
HWY_INLINE void PrefetchEntry(const TileSplats<float>& S, uint32_t i, int C) {
  const float* sd = &S.splat[6 * size_t(i)];
  hwy::Prefetch(sd);
  hwy::Prefetch(sd + 5);  // the six floats may straddle a cache line
  hwy::Prefetch(&S.extent[2 * size_t(i)]);
  if (C > 0) {  // an alpha- or depth-only render has no channel rows (channels is null)
    const float* ch = &S.channels[size_t(i) * C];
    hwy::Prefetch(ch);
    hwy::Prefetch(ch + C - 1);
  }
}

/// kC planes of kPer floats each on the stack (kC = 0: the count known at run time only, on
/// the heap).
template <int kC, int kPer = kTilePixels>
struct ChannelPlanes {
  HWY_ALIGN float data[kC * kPer];
  explicit ChannelPlanes(int) {}
  float* get() { return data; }
};
template <int kPer>
struct ChannelPlanes<0, kPer> {
  std::vector<float> data;
  explicit ChannelPlanes(int planes) : data(size_t(planes) * kPer) {}
  float* get() { return data.data(); }
};

/// One splat broadcast to the lanes: the geometry both passes evaluate, block by block.
struct SplatLanes {
  hn::Vec<D> mx, my, ca, cb, cc, opacity;
  hn::Vec<DI> x_lo, x_hi, y_lo, y_hi;  // integer lanes compare strictly only (Highway 1.0)
  SplatLanes(const float* sd, const LocalBox& b, const TileWork& tile)
      : mx(hn::Set(D(), sd[0] - float(tile.x0))), my(hn::Set(D(), sd[1] - float(tile.y0))), ca(hn::Set(D(), sd[2])),
        cb(hn::Set(D(), sd[3])), cc(hn::Set(D(), sd[4])), opacity(hn::Set(D(), sd[5])), x_lo(hn::Set(DI(), b.lx0 - 1)),
        x_hi(hn::Set(DI(), b.lx1 + 1)), y_lo(hn::Set(DI(), b.ly0 - 1)), y_hi(hn::Set(DI(), b.ly1 + 1)) {}
  hn::Mask<DI> in_box(hn::Vec<DI> lx, hn::Vec<DI> ly) const {
    return hn::And(hn::And(hn::Gt(lx, x_lo), hn::Lt(lx, x_hi)), hn::And(hn::Gt(ly, y_lo), hn::Lt(ly, y_hi)));
  }
  /// −½ dᵀΣ⁻¹d for offsets mean − pixel (tile-local: exact in float for tile offsets < 2^24).
  hn::Vec<D> power(hn::Vec<D> dx, hn::Vec<D> dy) const {
    const auto quad = hn::MulAdd(hn::Mul(ca, dx), dx, hn::Mul(hn::Mul(cc, dy), dy));
    return hn::NegMulAdd(hn::Mul(cb, dx), dy, hn::Mul(hn::Set(D(), -0.5f), quad));
  }
};

/// Visits the blocks of a splat's box: visit(l, lx, ly, dx, dy) with l the block's first
/// (block-major) index, lx/ly its lanes' tile-local columns and rows, dx/dy mean − pixel.
template <class Visit>
HWY_INLINE void for_each_block(const BlockLayout& L, const LocalBox& b, const SplatLanes& g, Visit&& visit) {
  const DI di;
  const D d;
  const auto lane_col = hn::Load(di, L.col), lane_row = hn::Load(di, L.row);
  for (int by = b.ly0 / L.bh; by <= b.ly1 / L.bh; ++by) {
    const auto ly = hn::Add(hn::Set(di, by * L.bh), lane_row);
    const auto dy = hn::Sub(g.my, hn::ConvertTo(d, ly));
    for (int bx = b.lx0 / L.bw; bx <= b.lx1 / L.bw; ++bx) {
      const auto lx = hn::Add(hn::Set(di, bx * L.bw), lane_col);
      visit(L.base(bx, by), lx, ly, hn::Sub(g.mx, hn::ConvertTo(d, lx)), dy);
    }
  }
}

/// The forward for kC channels (0: S.C at run time; 1, 3 and 4 — a feature, RGB, RGB and
/// depth — unroll the channel loop).
template <int kC>
void ForwardTileC(const TileSplats<float>& S, const TileWork& tile, const TileForward<float>& out) {
  const D d;
  const DI di;
  const BlockLayout L;
  const int N = L.lanes;
  const int C = kC ? kC : S.C;
  const int npix = (tile.x1 - tile.x0) * (tile.y1 - tile.y0);
  HWY_ALIGN int32_t done[kTilePixels], last[kTilePixels];
  HWY_ALIGN float T[kTilePixels], wbuf[kTileSize];
  HWY_ALIGN int32_t lxbuf[kTileSize], lybuf[kTileSize];
  ChannelPlanes<kC> acc_planes(C);  // block-major
  float* const acc = acc_planes.get();
  std::fill(acc, acc + size_t(C) * kTilePixels, 0.0f);
  std::fill(T, T + kTilePixels, 1.0f);
  std::fill(done, done + kTilePixels, 0);
  std::fill(last, last + kTilePixels, 0);
  const auto zero = hn::Zero(d), one = hn::Set(d, 1.0f);
  const auto max_alpha = hn::Set(d, kMaxAlpha), min_alpha = hn::Set(d, kMinAlpha), min_T = hn::Set(d, kMinTransmittance);
  int n_done = 0;
  for (uint32_t k = 0; k < std::min(tile.count, kPrefetchAhead); ++k) PrefetchEntry(S, tile.entries[k], C);
  for (uint32_t k = 0; k < tile.count; ++k) {
    if (n_done >= npix) {
      if (out.entry_max) std::fill(out.entry_max + k, out.entry_max + tile.count, 0.0f);
      break;
    }
    const uint32_t i = tile.entries[k];
    if (k + kPrefetchAhead < tile.count) PrefetchEntry(S, tile.entries[k + kPrefetchAhead], C);
    LocalBox b;
    const bool inside = local_box(S, i, tile, &b);
    if (out.box_pixels) *out.box_pixels += b.box_pixels;
    if (!inside) {
      if (out.entry_max) out.entry_max[k] = 0.0f;
      continue;
    }
    const float* ch = &S.channels[size_t(i) * C];
    const SplatLanes g(&S.splat[6 * size_t(i)], b, tile);
    const auto entry = hn::Set(di, int32_t(k + 1));
    auto emax = zero;
    for_each_block(L, b, g, [&](int l, hn::Vec<DI> lx, hn::Vec<DI> ly, hn::Vec<D> dx, hn::Vec<D> dy) {
      auto live = hn::RebindMask(d, hn::And(g.in_box(lx, ly), hn::Eq(hn::LoadU(di, done + l), hn::Zero(di))));
      if (hn::AllFalse(d, live)) return;
      const auto power = g.power(dx, dy);
      const auto alpha = hn::Min(max_alpha, hn::Mul(g.opacity, ExpNonPositive(d, hn::Min(power, zero))));
      // No branch on the exp's result: lanes that fail only stop storing (a mispredicted
      // branch here costs more than the stores it would save).
      live = hn::And(live, hn::And(hn::Le(power, zero), hn::Ge(alpha, min_alpha)));
      const auto Tv = hn::LoadU(d, T + l);
      const auto test_T = hn::Mul(Tv, hn::Sub(one, alpha));
      const auto stop = hn::And(live, hn::Lt(test_T, min_T));
      if (!hn::AllFalse(d, stop)) {
        n_done += int(hn::CountTrue(d, stop));
        hn::StoreU(hn::Or(hn::LoadU(di, done + l), hn::VecFromMask(di, hn::RebindMask(di, stop))), di, done + l);
      }
      const auto accept = hn::AndNot(stop, live);
      const auto w = hn::IfThenElseZero(accept, hn::Mul(alpha, Tv));
      for (int c = 0; c < C; ++c) {
        float* a = acc + size_t(c) * kTilePixels + l;
        hn::StoreU(hn::MulAdd(hn::Set(d, ch[c]), w, hn::LoadU(d, a)), d, a);
      }
      hn::StoreU(hn::IfThenElse(accept, test_T, Tv), d, T + l);
      hn::StoreU(hn::IfThenElse(hn::RebindMask(di, accept), entry, hn::LoadU(di, last + l)), di, last + l);
      emax = hn::Max(emax, w);
      if (out.contributors) {
        hn::StoreU(w, d, wbuf);
        hn::StoreU(lx, di, lxbuf);
        hn::StoreU(ly, di, lybuf);
        for (int j = 0; j < N; ++j)
          if (wbuf[j] > 0.0f) {
            out.contributors->entry.push_back(i);
            out.contributors->weight.push_back(wbuf[j]);
            out.contributors->pixel.push_back(uint16_t(lybuf[j] * kTileSize + lxbuf[j]));
          }
      }
    });
    if (out.entry_max) out.entry_max[k] = hn::GetLane(hn::MaxOfLanes(d, emax));
  }
  L.to_rows(T, out.T, 1);
  L.to_rows(acc, out.acc, C);
  if (out.last) L.to_rows(reinterpret_cast<const uint32_t*>(last), out.last, 1);
}

/// The backward for kC channels (0: S.C at run time; 3 and 4 unroll the channel loop).
template <int kC>
uint32_t BackwardTileC(const TileSplats<float>& S, const TileWork& tile, const TileBackward& io) {
  const D d;
  const DI di;
  const BlockLayout L;
  const int N = L.lanes;
  const int C = kC ? kC : S.C, R = 6 + C;
  HWY_ALIGN float T[kTilePixels], final_T[kTilePixels];
  HWY_ALIGN int32_t last[kTilePixels];
  L.to_blocks(io.final_T, final_T, 1);
  std::copy(final_T, final_T + kTilePixels, T);
  L.to_blocks(reinterpret_cast<const int32_t*>(io.last), last, 1);
  ChannelPlanes<kC> dpix_planes(C), behind_planes(C);  // block-major
  float* const dpix = dpix_planes.get();
  float* const behind = behind_planes.get();
  std::fill(behind, behind + size_t(C) * kTilePixels, 0.0f);
  L.to_blocks(io.dpix, dpix, C);
  ChannelPlanes<kC, kTileSize> channel_acc_lanes(C);  // per channel, lanes (N <= kTileSize)
  float* const channel_acc = channel_acc_lanes.get();
  const auto zero = hn::Zero(d), one = hn::Set(d, 1.0f), minus_half = hn::Set(d, -0.5f);
  const auto max_alpha = hn::Set(d, kMaxAlpha), min_alpha = hn::Set(d, kMinAlpha);
  // Entries at or behind every pixel's last blended one reach no pixel; nor does one whose
  // box misses the tile or whose blocks have no live lane. Their records would be zeros (the
  // sums below start at zero), so none is written: the per-Gaussian sum reads only the rest.
  uint32_t reached = 0, written = 0;
  for (int l = 0; l < kTilePixels; ++l) reached = std::max(reached, uint32_t(last[l]));
  reached = std::min(reached, tile.count);
  for (uint32_t k = 0; k < std::min(reached, kPrefetchAhead); ++k) PrefetchEntry(S, tile.entries[reached - 1 - k], C);
  for (uint32_t k = reached; k-- > 0;) {
    const uint32_t i = tile.entries[k];
    if (k >= kPrefetchAhead) PrefetchEntry(S, tile.entries[k - kPrefetchAhead], C);
    LocalBox b;
    if (!local_box(S, i, tile, &b)) continue;
    const float* ch = &S.channels[size_t(i) * C];
    const SplatLanes g(&S.splat[6 * size_t(i)], b, tile);
    const auto entry = hn::Set(di, int32_t(k));
    auto g_u = zero, g_v = zero, g_a = zero, g_b = zero, g_c = zero, g_o = zero;
    std::fill(channel_acc, channel_acc + size_t(C) * N, 0.0f);
    bool reaches = false;
    for_each_block(L, b, g, [&](int l, hn::Vec<DI> lx, hn::Vec<DI> ly, hn::Vec<D> dx, hn::Vec<D> dy) {
      // Reached by the forward: entries [0, last) of the tile were blended at this pixel.
      auto live = hn::RebindMask(d, hn::And(g.in_box(lx, ly), hn::Lt(entry, hn::LoadU(di, last + l))));
      if (hn::AllFalse(d, live)) return;
      reaches = true;
      const auto power = g.power(dx, dy);
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
        const auto dp_c = hn::LoadU(d, dpix + size_t(c) * kTilePixels + l);
        float* ca_c = channel_acc + size_t(c) * N;
        hn::StoreU(hn::MulAdd(w, dp_c, hn::LoadU(d, ca_c)), d, ca_c);
        float* bp = behind + size_t(c) * kTilePixels + l;
        const auto bh = hn::LoadU(d, bp), chv = hn::Set(d, ch[c]);
        dL_dalpha = hn::MulAdd(hn::Sub(chv, bh), dp_c, dL_dalpha);
        hn::StoreU(hn::IfThenElse(live, hn::MulAdd(alpha, chv, hn::Mul(transparency, bh)), bh), d, bp);
        if (c < 3) bg_dot = hn::MulAdd(hn::Set(d, io.background[c]), dp_c, bg_dot);
      }
      const auto bg_term = hn::Neg(hn::Mul(hn::LoadU(d, final_T + l), inv_transparency));
      dL_dalpha = hn::MulAdd(bg_term, bg_dot, hn::Mul(dL_dalpha, T_front));
      // α clamped at 0.99: no gradient through the opacity or the Gaussian's shape.
      dL_dalpha = hn::IfThenElseZero(hn::AndNot(hn::Gt(oG, max_alpha), live), dL_dalpha);
      g_o = hn::MulAdd(gauss, dL_dalpha, g_o);
      const auto dp = hn::Mul(alpha, dL_dalpha);  // dL/dpower
      g_u = hn::NegMulAdd(dp, hn::MulAdd(g.ca, dx, hn::Mul(g.cb, dy)), g_u);
      g_v = hn::NegMulAdd(dp, hn::MulAdd(g.cb, dx, hn::Mul(g.cc, dy)), g_v);
      const auto half_dp = hn::Mul(minus_half, dp);
      g_a = hn::MulAdd(half_dp, hn::Mul(dx, dx), g_a);
      g_b = hn::NegMulAdd(dp, hn::Mul(dx, dy), g_b);
      g_c = hn::MulAdd(half_dp, hn::Mul(dy, dy), g_c);
    });
    if (!reaches) continue;
    float* rec = io.records + size_t(written) * R;
    io.ids[written++] = i;
    rec[0] = hn::GetLane(hn::SumOfLanes(d, g_u));
    rec[1] = hn::GetLane(hn::SumOfLanes(d, g_v));
    rec[2] = hn::GetLane(hn::SumOfLanes(d, g_a));
    rec[3] = hn::GetLane(hn::SumOfLanes(d, g_b));
    rec[4] = hn::GetLane(hn::SumOfLanes(d, g_c));
    rec[5] = hn::GetLane(hn::SumOfLanes(d, g_o));
    for (int c = 0; c < C; ++c) rec[6 + c] = hn::GetLane(hn::SumOfLanes(d, hn::LoadU(d, channel_acc + size_t(c) * N)));
  }
  return written;
}

void ForwardTile(const TileSplats<float>& S, const TileWork& tile, const TileForward<float>& out) {
  switch (S.C) {
    case 1: return ForwardTileC<1>(S, tile, out);
    case 3: return ForwardTileC<3>(S, tile, out);
    case 4: return ForwardTileC<4>(S, tile, out);
    default: return ForwardTileC<0>(S, tile, out);
  }
}

uint32_t BackwardTile(const TileSplats<float>& S, const TileWork& tile, const TileBackward& io) {
  switch (S.C) {
    case 3: return BackwardTileC<3>(S, tile, io);
    case 4: return BackwardTileC<4>(S, tile, io);
    default: return BackwardTileC<0>(S, tile, io);
  }
}

/// Splats [begin, end)'s α spans (alpha_spans in tile_kernel.hpp). pixel_box's outer bounds
/// cut by the ellipse's half-extent; `(h − 1)·1.0005 + 1e-3` contracts to a fused multiply-add
/// on the targets that have one, as this build's kernels always rounded it.
void AlphaSpans(const float* splat, const float* extent, size_t begin, size_t end, int32_t* spans) {
  for (size_t i = begin; i < end; ++i) {
    const float mx = splat[6 * i], my = splat[6 * i + 1], half_w = extent[2 * i], half_h = extent[2 * i + 1];
    const float hx = (half_w - 1.0f) * 1.0005f + 1e-3f, hy = (half_h - 1.0f) * 1.0005f + 1e-3f;
    int32_t* a = spans + 4 * i;
    a[0] = std::max(int(std::floor(mx - half_w)), int(std::ceil(mx - hx)));
    a[1] = std::min(int(std::ceil(mx + half_w)), int(std::floor(mx + hx)));
    a[2] = std::max(int(std::floor(my - half_h)), int(std::ceil(my - hy)));
    a[3] = std::min(int(std::ceil(my + half_h)), int(std::floor(my + hy)));
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

int LaneCount() { return int(hn::Lanes(D())); }

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::tiles
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::tiles {

HWY_EXPORT(ForwardTile);
HWY_EXPORT(BackwardTile);
HWY_EXPORT(AlphaSpans);
HWY_EXPORT(ExpMaxRelativeError);
HWY_EXPORT(TargetName);
HWY_EXPORT(LaneCount);

void forward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileForward<float>& out) {
  HWY_DYNAMIC_DISPATCH(ForwardTile)(splats, tile, out);
}

uint32_t backward_tile_simd(const TileSplats<float>& splats, const TileWork& tile, const TileBackward& io) {
  return HWY_DYNAMIC_DISPATCH(BackwardTile)(splats, tile, io);
}

void alpha_spans(const float* splat, const float* extent, size_t count, std::vector<int32_t>* spans) {
  spans->resize(count * 4);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 4096), [&](const tbb::blocked_range<size_t>& r) {
    HWY_DYNAMIC_DISPATCH(AlphaSpans)(splat, extent, r.begin(), r.end(), spans->data());
  });
}

double simd_exp_max_relative_error(float lo, int count) { return HWY_DYNAMIC_DISPATCH(ExpMaxRelativeError)(lo, count); }

const char* simd_target_name() { return HWY_DYNAMIC_DISPATCH(TargetName)(); }

int simd_lane_count() { return HWY_DYNAMIC_DISPATCH(LaneCount)(); }

}  // namespace fillgs::tiles
#endif
