// The training loss's SSIM map and gradient for float images with the vector kernel,
// fused (blur.hpp, ssim_loss_simd): each band of rows runs a channel row by row through
// rings of 11 rows that stay in the cache, where a loss over whole planes (as loss.cpp's
// scalar reference) writes and reads ~15 planes per channel.
//
// Rounding, the same on every path through this file: each blur output is a chain of the
// instruction set's multiply-add over the taps inside the image, in tap order from zero
// (fused on AVX2 and AVX-512, a product then a sum on SSE4), its edges included; the file is
// compiled without contraction, so every other product and sum of the per-pixel terms
// rounds as loss.cpp's scalar code does.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "image/ssim_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "image/blur.hpp"

#ifndef FILLGS_IMAGE_SSIM_SIMD_ONCE
#define FILLGS_IMAGE_SSIM_SIMD_ONCE
namespace fillgs::image {
struct LossImages {
  const float *render, *target, *weights;  // [H][W][3], [H][W][3], [H][W] or null
  int W, H;
  float l1_scale, ssim_scale;
  float* const* ssim_out;  // [3][H·W]
  float* grad;             // [H][W][3] or null
};
constexpr int kRing = kBlurTaps;  // the rows a column pass reads
/// A band's working rows are W rounded up to whole vectors (of up to 64 floats): the
/// per-pixel loops run whole vectors, the last one past W inside the row.
inline size_t band_stride(int W) { return (size_t(W) + 63) / 64 * 64; }
/// The floats of a band's working rows (BandRows) at width W.
inline size_t band_floats(int W) { return size_t(5 * kRing + 3 * kRing + 4 + 5 + 3 + 3) * band_stride(W); }
}  // namespace fillgs::image
#endif

HWY_BEFORE_NAMESPACE();
namespace fillgs::image {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// s + w·v rounded as this instruction set's hn::MulAdd rounds it (fused where it has FMA),
/// for one value: the blurs' edges round as their lanes do.
HWY_INLINE float MulAdd1(float w, float v, float s) {
#if HWY_NATIVE_FMA
  return std::fma(w, v, s);
#else
  return s + w * v;
#endif
}

/// The row pass of one row: o[x] = Σ_k w_k row[x + k − 5], taps outside the row skipped.
/// Both passes stay out of line (inlined into the stages, the loss measured slower).
HWY_NOINLINE void BlurRow(const float* w, const float* row, int W, float* o) {
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  auto edge = [&](int x) {
    float s = 0.0f;
    for (int k = std::max(0, 5 - x); k < kBlurTaps && x + k - 5 < W; ++k) s = MulAdd1(w[k], row[x + k - 5], s);
    o[x] = s;
  };
  int x = 0;
  for (; x < std::min(5, W); ++x) edge(x);
  // Four output vectors at a time: each sum is a chain of 11 dependent multiply-adds, and
  // four independent chains keep the FMA units busy (each still sums its taps in order).
  for (; x + 4 * N + 5 <= W; x += 4 * N) {
    auto s0 = hn::Zero(d), s1 = hn::Zero(d), s2 = hn::Zero(d), s3 = hn::Zero(d);
    for (int k = 0; k < kBlurTaps; ++k) {
      const auto wk = hn::Set(d, w[k]);
      const float* r = row + x + k - 5;
      s0 = hn::MulAdd(wk, hn::LoadU(d, r), s0);
      s1 = hn::MulAdd(wk, hn::LoadU(d, r + N), s1);
      s2 = hn::MulAdd(wk, hn::LoadU(d, r + 2 * N), s2);
      s3 = hn::MulAdd(wk, hn::LoadU(d, r + 3 * N), s3);
    }
    hn::StoreU(s0, d, o + x), hn::StoreU(s1, d, o + x + N), hn::StoreU(s2, d, o + x + 2 * N), hn::StoreU(s3, d, o + x + 3 * N);
  }
  for (; x + N + 5 <= W; x += N) {
    auto s = hn::Zero(d);
    for (int k = 0; k < kBlurTaps; ++k) s = hn::MulAdd(hn::Set(d, w[k]), hn::LoadU(d, row + x + k - 5), s);
    hn::StoreU(s, d, o + x);
  }
  for (; x < W; ++x) edge(x);
}

/// The row pass of a ⊙ b (b null: a), the product formed into `product` first.
HWY_INLINE void BlurRowOf(const float* w, const float* a, const float* b, int W, float* product, float* out) {
  if (b) {
    const hn::ScalableTag<float> d;
    const int N = int(hn::Lanes(d));
    int x = 0;
    for (; x + N <= W; x += N) hn::StoreU(hn::Mul(hn::LoadU(d, a + x), hn::LoadU(d, b + x)), d, product + x);
    for (; x < W; ++x) product[x] = a[x] * b[x];
    a = product;
  }
  BlurRow(w, a, W, out);
}

/// The column pass of one output row: o[x] = Σ_{k0 ≤ k < k1} w_k rows[k][x], where rows[k]
/// is input row y + k − 5 and [k0, k1) the taps inside the image.
HWY_NOINLINE void BlurColumnRow(const float* w, const float* const* rows, int k0, int k1, int W, float* o) {
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  int x = 0;
  for (; x + 4 * N <= W; x += 4 * N) {  // four independent chains, as in BlurRow
    auto s0 = hn::Zero(d), s1 = hn::Zero(d), s2 = hn::Zero(d), s3 = hn::Zero(d);
    for (int k = k0; k < k1; ++k) {
      const auto wk = hn::Set(d, w[k]);
      const float* r = rows[k] + x;
      s0 = hn::MulAdd(wk, hn::LoadU(d, r), s0);
      s1 = hn::MulAdd(wk, hn::LoadU(d, r + N), s1);
      s2 = hn::MulAdd(wk, hn::LoadU(d, r + 2 * N), s2);
      s3 = hn::MulAdd(wk, hn::LoadU(d, r + 3 * N), s3);
    }
    hn::StoreU(s0, d, o + x), hn::StoreU(s1, d, o + x + N), hn::StoreU(s2, d, o + x + 2 * N), hn::StoreU(s3, d, o + x + 3 * N);
  }
  for (; x + N <= W; x += N) {
    auto s = hn::Zero(d);
    for (int k = k0; k < k1; ++k) s = hn::MulAdd(hn::Set(d, w[k]), hn::LoadU(d, rows[k] + x), s);
    hn::StoreU(s, d, o + x);
  }
  for (; x < W; ++x) {
    float s = 0.0f;
    for (int k = k0; k < k1; ++k) s = MulAdd1(w[k], rows[k][x], s);
    o[x] = s;
  }
}

/// A band's working rows (band_floats(W) of them): rings of row-pass outputs, indexed by image row modulo 11.
struct BandRows {
  float* a[5];  // stage 1: row pass of x, y, x², y², xy (kRing rows each)
  float* b[3];  // stage 2: row pass of t1, dvar, dcov (kRing rows each)
  float *x, *y, *w, *product, *m[5], *t[3], *g[3];  // one row each
  size_t stride;  // of every row, band_stride(W)

  BandRows(float* s, int W) : stride(band_stride(W)) {
    auto take = [&](int rows) {
      float* p = s;
      s += size_t(rows) * stride;
      return p;
    };
    for (float*& p : a) p = take(kRing);
    for (float*& p : b) p = take(kRing);
    x = take(1), y = take(1), w = take(1), product = take(1);
    for (float*& p : m) p = take(1);
    for (float*& p : t) p = take(1);
    for (float*& p : g) p = take(1);
  }
};

/// Channel c of an interleaved row into a plain one.
HWY_INLINE void Deinterleave(const float* in, int c, int W, float* out) {
  for (int x = 0; x < W; ++x) out[x] = in[size_t(x) * 3 + size_t(c)];
}

/// Stage 1 for image row r: channel c of render and target, and the row pass of x, y, x²,
/// y², xy into the rings.
HWY_INLINE void RowPassInputs(const float* win, const LossImages& im, int c, int r, BandRows& s) {
  const int W = im.W;
  Deinterleave(im.render + size_t(r) * W * 3, c, W, s.x);
  Deinterleave(im.target + size_t(r) * W * 3, c, W, s.y);
  const size_t slot = size_t(r % kRing) * s.stride;
  const float* a[5] = {s.x, s.y, s.x, s.y, s.x};
  const float* b[5] = {nullptr, nullptr, s.x, s.y, s.y};
  for (int p = 0; p < 5; ++p) BlurRowOf(win, a[p], b[p], W, s.product, s.a[p] + slot);
}

/// The column pass at image row y of `planes` rings (the row pass of rows y − 5 … y + 5,
/// those inside the image) into out[p].
HWY_INLINE void ColumnPass(const float* win, float* const* rings, int planes, int y, int W, int H, size_t stride, float* const* out) {
  const int k0 = std::max(0, 5 - y), k1 = std::min(kBlurTaps, H - y + 5);
  const float* rows[kBlurTaps] = {};
  for (int p = 0; p < planes; ++p) {
    for (int k = k0; k < k1; ++k) rows[k] = rings[p] + size_t((y + k - 5) % kRing) * stride;
    BlurColumnRow(win, rows, k0, k1, W, out[p]);
  }
}

/// A row of the weights (1 where there are none) into the band's row w.
HWY_INLINE void WeightsRow(const LossImages& im, int y, BandRows& s) {
  if (im.weights)
    std::memcpy(s.w, im.weights + size_t(y) * im.W, sizeof(float) * size_t(im.W));
  else
    std::fill(s.w, s.w + im.W, 1.0f);
}

/// Stage 2 for image row m: the window's means and sums of the channel, the SSIM term
/// (stored when the band owns the row) and, for the gradient, the row pass of t1, dvar and
/// dcov into the rings. The terms are loss.cpp's, operation for operation.
HWY_INLINE void SsimTerms(const float* win, const LossImages& im, int c, int m, bool owned, BandRows& s) {
  const int W = im.W;
  ColumnPass(win, s.a, 5, m, W, im.H, s.stride, s.m);
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  const auto two = hn::Set(d, 2.0f), c1 = hn::Set(d, float(kSsimC1)), c2 = hn::Set(d, float(kSsimC2));
  WeightsRow(im, m, s);
  // Whole vectors, the last one past W within the rows' stride (its extra lanes unused).
  for (int x = 0; x < W; x += N) {
    const auto mx = hn::LoadU(d, s.m[0] + x), my = hn::LoadU(d, s.m[1] + x);
    const auto sxx = hn::LoadU(d, s.m[2] + x), syy = hn::LoadU(d, s.m[3] + x), sxy = hn::LoadU(d, s.m[4] + x);
    const auto coef = hn::LoadU(d, s.w + x);
    const auto vx = hn::Sub(sxx, hn::Mul(mx, mx)), vy = hn::Sub(syy, hn::Mul(my, my));
    const auto cxy = hn::Sub(sxy, hn::Mul(mx, my));
    const auto a1 = hn::Add(hn::Mul(hn::Mul(two, mx), my), c1), a2 = hn::Add(hn::Mul(two, cxy), c2);
    const auto b1 = hn::Add(hn::Add(hn::Mul(mx, mx), hn::Mul(my, my)), c1), b2 = hn::Add(hn::Add(vx, vy), c2);
    const auto b12 = hn::Mul(b1, b2);
    const auto ssim = hn::Div(hn::Mul(a1, a2), b12);
    if (owned) hn::StoreU(hn::Mul(coef, ssim), d, s.product + x);
    if (!im.grad) continue;
    const auto dmu = hn::Mul(coef, hn::Sub(hn::Div(hn::Mul(hn::Mul(two, my), a2), b12), hn::Div(hn::Mul(hn::Mul(ssim, two), mx), b1)));
    const auto dvar = hn::Mul(coef, hn::Div(hn::Neg(ssim), b2));
    const auto dcov = hn::Mul(coef, hn::Div(hn::Mul(two, a1), b12));
    // x enters μx, σx² = G*(x²) − μx², σxy = G*(xy) − μxμy; G is symmetric.
    const auto t1 = hn::Sub(hn::Sub(dmu, hn::Mul(hn::Mul(two, dvar), mx)), hn::Mul(dcov, my));
    hn::StoreU(t1, d, s.t[0] + x), hn::StoreU(dvar, d, s.t[1] + x), hn::StoreU(dcov, d, s.t[2] + x);
  }
  if (owned) std::memcpy(im.ssim_out[c] + size_t(m) * W, s.product, sizeof(float) * size_t(W));
  if (!im.grad) return;
  const size_t slot = size_t(m % kRing) * s.stride;
  for (int p = 0; p < 3; ++p) BlurRowOf(win, s.t[p], nullptr, W, s.product, s.b[p] + slot);
}

/// Stage 3 for image row y: the column pass of t1, dvar, dcov, and channel c of the
/// gradient: k_l1·w·sign(x − y) − k_ssim·(G*t1 + 2x·G*dvar + y·G*dcov).
HWY_INLINE void GradientRow(const float* win, const LossImages& im, int c, int y, BandRows& s) {
  const int W = im.W;
  ColumnPass(win, s.b, 3, y, W, im.H, s.stride, s.g);
  Deinterleave(im.render + size_t(y) * W * 3, c, W, s.x);
  Deinterleave(im.target + size_t(y) * W * 3, c, W, s.y);
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  const auto two = hn::Set(d, 2.0f), zero = hn::Zero(d), one = hn::Set(d, 1.0f), minus_one = hn::Set(d, -1.0f);
  const auto l1_scale = hn::Set(d, im.l1_scale), ssim_scale = hn::Set(d, im.ssim_scale);
  WeightsRow(im, y, s);
  float* out = s.product;  // the channel's gradient row, then into the interleaved image
  for (int x = 0; x < W; x += N) {  // whole vectors, as in SsimTerms
    const auto xv = hn::LoadU(d, s.x + x), yv = hn::LoadU(d, s.y + x);
    const auto g = hn::Add(hn::Add(hn::LoadU(d, s.g[0] + x), hn::Mul(hn::Mul(two, xv), hn::LoadU(d, s.g[1] + x))),
                           hn::Mul(yv, hn::LoadU(d, s.g[2] + x)));
    const auto diff = hn::Sub(xv, yv);
    const auto sign = hn::IfThenElse(hn::Gt(diff, zero), one, hn::IfThenElse(hn::Lt(diff, zero), minus_one, zero));
    hn::StoreU(hn::Sub(hn::Mul(hn::Mul(l1_scale, hn::LoadU(d, s.w + x)), sign), hn::Mul(ssim_scale, g)), d, out + x);
  }
  float* grad = im.grad + size_t(y) * W * 3 + size_t(c);
  for (int x = 0; x < W; ++x) grad[size_t(x) * 3] = out[x];
}

/// Channel c over the rows [y0, y1): stage 1 runs 10 rows ahead of stage 3 and stage 2 five,
/// each reading the 11 rows of the stage before it from its ring.
void SsimLossBand(const LossImages& im, int c, int y0, int y1, float* scratch) {
  const float* win = ssim_window<float>();
  BandRows s(scratch, im.W);
  const int H = im.H;
  int next_input = std::max(0, y0 - 10);
  const int m0 = std::max(0, y0 - 5), m1 = std::min(H, y1 + 5);
  for (int m = m0; m < m1; ++m) {
    for (; next_input <= std::min(H - 1, m + 5); ++next_input) RowPassInputs(win, im, c, next_input, s);
    SsimTerms(win, im, c, m, m >= y0 && m < y1, s);
    if (im.grad && m - 5 >= y0 && m - 5 < y1) GradientRow(win, im, c, m - 5, s);
  }
  if (im.grad)
    for (int y = std::max(y0, m1 - 5); y < y1; ++y) GradientRow(win, im, c, y, s);  // the last rows' taps end at the image
}

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::image
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::image {

HWY_EXPORT(SsimLossBand);

void ssim_loss_simd(const float* render, const float* target, const float* weights, int W, int H, float l1_scale, float ssim_scale,
                    float* const* ssim_out, float* grad) {
  const LossImages im{render, target, weights, W, H, l1_scale, ssim_scale, ssim_out, grad};
  // A band of rows per thread and channel: each band recomputes 10 rows of its neighbours'
  // row pass and 5 of their terms, so fewer, taller bands cost less; the values do not
  // depend on them.
  const int bands = std::clamp(tbb::this_task_arena::max_concurrency(), 1, std::max(1, H / 16));
  const int rows = (H + bands - 1) / bands;
  tbb::parallel_for(tbb::blocked_range<int>(0, 3 * bands, 1), [&](const tbb::blocked_range<int>& r) {
    static thread_local std::vector<float> scratch;
    scratch.resize(band_floats(W));
    for (int k = r.begin(); k < r.end(); ++k) {
      const int c = k / bands, y0 = (k % bands) * rows, y1 = std::min(H, y0 + rows);
      if (y0 < y1) HWY_DYNAMIC_DISPATCH(SsimLossBand)(im, c, y0, y1, scratch.data());
    }
  });
}

}  // namespace fillgs::image
#endif
