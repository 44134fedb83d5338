// Separable 11-tap blur, vector and scalar (blur.hpp).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "image/blur_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "image/blur.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::image {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// One row: o[x] = Σ_k w_k row[x + k − 5], taps outside the row skipped.
HWY_INLINE void BlurRow(const float* w, const float* row, int W, float* o) {
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  auto scalar_at = [&](int x) {
    float s = 0.0f;
    for (int k = std::max(0, 5 - x); k < kBlurTaps && x + k - 5 < W; ++k) s += w[k] * row[x + k - 5];
    o[x] = s;
  };
  int x = 0;
  for (; x < std::min(5, W); ++x) scalar_at(x);
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
  for (; x < W; ++x) scalar_at(x);
}

/// One output row y of the column pass: o[x] = Σ_{k0 ≤ k < k1} w_k rows[k][x], where rows[k]
/// is input row y + k − 5 and [k0, k1) the taps inside the image.
HWY_INLINE void BlurColumnRow(const float* w, const float* const* rows, int k0, int k1, int W, float* o) {
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
    for (int k = k0; k < k1; ++k) s += w[k] * rows[k][x];
    o[x] = s;
  }
}

// The row and column passes for other files of the same instruction set (the fused SSIM
// loss, ssim_simd.cpp, which is compiled without contraction): one definition of each pass,
// so the blurs there and here give the same values.

/// The row pass of one row of a ⊙ b (b null: a): the product into `product`, then BlurRow.
void BlurRowOf(const float* w, const float* a, const float* b, int W, float* product, float* out) {
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

/// The column pass of one output row (BlurColumnRow).
void BlurColumnRowOf(const float* w, const float* const* rows, int k0, int k1, int W, float* out) {
  BlurColumnRow(w, rows, k0, k1, W, out);
}

/// Output rows [y0, y1) of every plane of blur11_planes_simd: the row pass of the input
/// rows they need (y0 − 5 to y1 + 5, within the image) into `strip`, then the column pass
/// from it. `row` holds one product row.
void BlurPlanesStrip(const float* w, int planes, const float* const* a, const float* const* b, int W, int H, int y0, int y1,
                     float* strip, float* row, float* const* out) {
  const int r0 = std::max(0, y0 - 5), r1 = std::min(H, y1 + 5);
  for (int p = 0; p < planes; ++p) {
    for (int r = r0; r < r1; ++r)
      BlurRowOf(w, a[p] + size_t(r) * W, b[p] ? b[p] + size_t(r) * W : nullptr, W, row, strip + size_t(r - r0) * W);
    const float* rows[kBlurTaps] = {};
    for (int y = y0; y < y1; ++y) {
      const int k0 = std::max(0, 5 - y), k1 = std::min(kBlurTaps, H - y + 5);  // the taps inside the image
      for (int k = k0; k < k1; ++k) rows[k] = strip + size_t(y + k - 5 - r0) * W;
      BlurColumnRow(w, rows, k0, k1, W, out[p] + size_t(y) * W);
    }
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::image
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::image {

HWY_EXPORT(BlurPlanesStrip);

void blur11_planes_simd(int planes, const float* const* a, const float* const* b, int W, int H, float* const* out) {
  const float* w = ssim_window<float>();
  // Strips of kStripRows output rows: each strip's row pass (its rows and 5 more on each
  // side) stays in the cache for its column pass instead of a whole intermediate plane.
  constexpr int kStripRows = 64;
  tbb::parallel_for(tbb::blocked_range<int>(0, (H + kStripRows - 1) / kStripRows, 1), [&](const tbb::blocked_range<int>& r) {
    static thread_local std::vector<float> strip, row;
    strip.resize(size_t(kStripRows + 10) * size_t(W));
    row.resize(size_t(W));
    for (int s = r.begin(); s < r.end(); ++s)
      HWY_DYNAMIC_DISPATCH(BlurPlanesStrip)(w, planes, a, b, W, H, s * kStripRows, std::min(H, (s + 1) * kStripRows), strip.data(), row.data(), out);
  });
}

}  // namespace fillgs::image
#endif
