// Separable 11-tap blur, vector and scalar (blur.hpp).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "image/blur_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "image/blur.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::image {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// Rows [y0, y1): out[y][x] = Σ_k w_k in[y][x + k − 5], taps outside the row skipped.
void BlurRows(const float* w, const float* in, int W, int y0, int y1, float* out) {
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  for (int y = y0; y < y1; ++y) {
    const float* row = in + size_t(y) * W;
    float* o = out + size_t(y) * W;
    auto scalar_at = [&](int x) {
      float s = 0.0f;
      for (int k = std::max(0, 5 - x); k < kBlurTaps && x + k - 5 < W; ++k) s += w[k] * row[x + k - 5];
      o[x] = s;
    };
    int x = 0;
    for (; x < std::min(5, W); ++x) scalar_at(x);
    for (; x + N + 5 <= W; x += N) {
      auto s = hn::Zero(d);
      for (int k = 0; k < kBlurTaps; ++k) s = hn::MulAdd(hn::Set(d, w[k]), hn::LoadU(d, row + x + k - 5), s);
      hn::StoreU(s, d, o + x);
    }
    for (; x < W; ++x) scalar_at(x);
  }
}

/// Rows [y0, y1): out[y][x] = Σ_k w_k in[y + k − 5][x], rows outside the image skipped.
void BlurColumns(const float* w, const float* in, int W, int H, int y0, int y1, float* out) {
  const hn::ScalableTag<float> d;
  const int N = int(hn::Lanes(d));
  for (int y = y0; y < y1; ++y) {
    float* o = out + size_t(y) * W;
    const int k0 = std::max(0, 5 - y), k1 = std::min(kBlurTaps, H - y + 5);
    int x = 0;
    for (; x + N <= W; x += N) {
      auto s = hn::Zero(d);
      for (int k = k0; k < k1; ++k) s = hn::MulAdd(hn::Set(d, w[k]), hn::LoadU(d, in + size_t(y + k - 5) * W + x), s);
      hn::StoreU(s, d, o + x);
    }
    for (; x < W; ++x) {
      float s = 0.0f;
      for (int k = k0; k < k1; ++k) s += w[k] * in[size_t(y + k - 5) * W + x];
      o[x] = s;
    }
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::image
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::image {

HWY_EXPORT(BlurRows);
HWY_EXPORT(BlurColumns);

void blur11_simd(const float* in, int W, int H, float* scratch, float* out) {
  const float* w = ssim_window<float>();
  const int grain = std::max(1, 16384 / std::max(1, W));
  tbb::parallel_for(tbb::blocked_range<int>(0, H, grain), [&](const tbb::blocked_range<int>& r) {
    HWY_DYNAMIC_DISPATCH(BlurRows)(w, in, W, r.begin(), r.end(), scratch);
  });
  tbb::parallel_for(tbb::blocked_range<int>(0, H, grain), [&](const tbb::blocked_range<int>& r) {
    HWY_DYNAMIC_DISPATCH(BlurColumns)(w, scratch, W, H, r.begin(), r.end(), out);
  });
}

}  // namespace fillgs::image
#endif
