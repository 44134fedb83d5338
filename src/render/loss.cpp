#include "fillgs/render/loss.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <type_traits>

#include "fillgs/render/raster.hpp"
#include "image/blur.hpp"

namespace fillgs {

namespace {

constexpr double kC1 = image::kSsimC1, kC2 = image::kSsimC2;

/// One 11-tap pass of the window along x (along_x) or y, zero padding.
template <typename Real>
void blur_pass(const std::vector<Real>& in, int W, int H, bool along_x, std::vector<Real>& out) {
  const Real* w = image::ssim_window<Real>();
  out.resize(in.size());
  const int len = along_x ? W : H;
  const size_t step = along_x ? 1 : size_t(W);
  tbb::parallel_for(tbb::blocked_range<int>(0, H, 16), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y)
      for (int x = 0; x < W; ++x) {
        const int at = along_x ? x : y;
        const size_t o = size_t(y) * W + x;
        Real s = 0;
        for (int k = std::max(0, 5 - at); k < image::kBlurTaps && at + k - 5 < len; ++k)
          s += w[k] * in[o + (ptrdiff_t(k) - 5) * ptrdiff_t(step)];
        out[o] = s;
      }
  });
}

constexpr size_t kChunk = 16384;  // pixels per parallel chunk of the per-pixel loops

/// body(begin, end) over fixed chunks of [0, n), in parallel.
template <typename Body>
void chunked_for(size_t n, Body&& body) {
  tbb::parallel_for(size_t(0), (n + kChunk - 1) / kChunk, [&](size_t k) { body(k * kChunk, std::min(n, (k + 1) * kChunk)); });
}

/// Σ over [0, n) of body(begin, end) (each returning its range's sum), the chunks' sums
/// added in order: the same result for any thread count.
template <typename Body>
double chunked_sum(size_t n, Body&& body) {
  std::vector<double> partial((n + kChunk - 1) / kChunk, 0.0);
  chunked_for(n, [&](size_t i0, size_t i1) { partial[i0 / kChunk] = body(i0, i1); });
  double total = 0;
  for (double v : partial) total += v;
  return total;
}

/// Scratch planes of the SSIM, kept per thread so that a training iteration does not
/// allocate and zero ~15 fresh planes per channel: at 676×507 the loss took 28 → 16 ms
/// with them (fresh pages faulted in), and still 13.2 → 11.2 ms once the executables keep
/// freed memory (`fillgs_bench train --only speed --gaussians 100000 --resolution 676x507`).
template <typename Real>
struct SsimScratch {
  std::vector<Real> tmp, product, mx, my, sxx, syy, sxy, dmu, dvar, dcov, t1, g1, g2, g3;
};

/// out[p] = the separable 11×11 Gaussian filter (zero padding) of a[p] ⊙ b[p] (b[p] null:
/// a[p]) for several planes: the scalar reference, product and two passes per plane (the
/// vector kernel's loss is fused_loss below).
template <typename Real, size_t P>
void blur_planes(const std::array<const std::vector<Real>*, P>& a, const std::array<const std::vector<Real>*, P>& b, int W, int H,
                 std::vector<Real>& tmp, std::vector<Real>& product, const std::array<std::vector<Real>*, P>& out) {
  const size_t n = a[0]->size();
  for (size_t p = 0; p < P; ++p) {
    const std::vector<Real>* in = a[p];
    if (b[p]) {
      product.resize(n);
      chunked_for(n, [&](size_t i0, size_t i1) {
        for (size_t i = i0; i < i1; ++i) product[i] = (*a[p])[i] * (*b[p])[i];
      });
      in = &product;
    }
    blur_pass(*in, W, H, true, tmp);
    blur_pass(tmp, W, H, false, *out[p]);
  }
}

/// SSIM map of one channel plane and, when `grad` is given, d(Σ_p c_p·SSIM_p)/dx for the
/// per-pixel coefficients c (the weights times the loss's scale).
template <typename Real>
double ssim_plane(const std::vector<Real>& x, const std::vector<Real>& y, int W, int H, const std::vector<Real>* coef,
                  std::vector<Real>* grad) {
  // The calling thread's scratch, by reference: inside the parallel loops below the name of
  // a thread_local would denote each worker's own instance.
  static thread_local SsimScratch<Real> scratch;
  SsimScratch<Real>& w = scratch;
  const size_t n = x.size();
  const std::vector<Real>&mx = w.mx, &my = w.my, &sxx = w.sxx, &syy = w.syy, &sxy = w.sxy;
  // μx, μy, and the window's sums of x², y², xy.
  blur_planes<Real, 5>({&x, &y, &x, &y, &x}, {nullptr, nullptr, &x, &y, &y}, W, H, w.tmp, w.product, {&w.mx, &w.my, &w.sxx, &w.syy, &w.sxy});
  std::vector<Real>&dmu = w.dmu, &dvar = w.dvar, &dcov = w.dcov;
  if (grad) dmu.resize(n), dvar.resize(n), dcov.resize(n);
  const double total = chunked_sum(n, [&](size_t i0, size_t i1) {
    double sum = 0;
    for (size_t i = i0; i < i1; ++i) {
      const Real vx = sxx[i] - mx[i] * mx[i], vy = syy[i] - my[i] * my[i], cxy = sxy[i] - mx[i] * my[i];
      const Real a1 = Real(2) * mx[i] * my[i] + Real(kC1), a2 = Real(2) * cxy + Real(kC2);
      const Real b1 = mx[i] * mx[i] + my[i] * my[i] + Real(kC1), b2 = vx + vy + Real(kC2);
      const Real s = a1 * a2 / (b1 * b2);
      sum += double(coef ? (*coef)[i] * s : s);
      if (grad) {
        const Real c = (*coef)[i];
        dmu[i] = c * (Real(2) * my[i] * a2 / (b1 * b2) - s * Real(2) * mx[i] / b1);
        dvar[i] = c * (-s / b2);
        dcov[i] = c * (Real(2) * a1 / (b1 * b2));
      }
    }
    return sum;
  });
  if (grad) {
    // x enters μx, σx² = G*(x²) − μx², σxy = G*(xy) − μxμy; G is symmetric.
    std::vector<Real>& t1 = w.t1;
    t1.resize(n);
    chunked_for(n, [&](size_t i0, size_t i1) {
      for (size_t i = i0; i < i1; ++i) t1[i] = dmu[i] - Real(2) * dvar[i] * mx[i] - dcov[i] * my[i];
    });
    blur_planes<Real, 3>({&t1, &dvar, &dcov}, {nullptr, nullptr, nullptr}, W, H, w.tmp, w.product, {&w.g1, &w.g2, &w.g3});
    grad->resize(n);
    chunked_for(n, [&](size_t i0, size_t i1) {
      for (size_t i = i0; i < i1; ++i) (*grad)[i] = w.g1[i] + Real(2) * x[i] * w.g2[i] + y[i] * w.g3[i];
    });
  }
  return total;
}

/// The loss from the fused vector pass (image::ssim_loss_simd), for float with the vector
/// kernel: the same values as the planes below, and the sums in the same order.
LossValue fused_loss(const float* render, const float* target, int W, int H, const float* weights, double lambda, float* grad) {
  const size_t P = size_t(W) * H, n = P * 3;
  static thread_local std::vector<float> planes[3];  // reused (see SsimScratch)
  float* ssim_out[3];
  for (int c = 0; c < 3; ++c) planes[c].resize(P), ssim_out[c] = planes[c].data();
  image::ssim_loss_simd(render, target, weights, W, H, float((1.0 - lambda) / double(n)), float(lambda / double(n)), ssim_out, grad);
  // Per chunk, in chunked_sum's order: the L1 terms of its pixels' three channels, and each
  // channel's SSIM terms. Four chunks at a time per thread, so that four chains of dependent
  // additions overlap.
  struct Sums {
    double l1 = 0, ssim[3] = {0, 0, 0};
  };
  auto add = [&](Sums& sums, size_t p) {
    const float w = weights ? weights[p] : 1.0f;
    for (size_t i = 3 * p; i < 3 * p + 3; ++i) sums.l1 += double(w * std::abs(render[i] - target[i]));
    for (int c = 0; c < 3; ++c) sums.ssim[c] += double(ssim_out[c][p]);
  };
  const size_t chunks = (P + kChunk - 1) / kChunk;
  std::vector<Sums> partial(chunks);
  tbb::parallel_for(size_t(0), (chunks + 3) / 4, [&](size_t group) {
    Sums s0, s1, s2, s3;
    size_t begin[4], end[4];
    for (size_t j = 0; j < 4; ++j) begin[j] = std::min(P, (4 * group + j) * kChunk), end[j] = std::min(P, begin[j] + kChunk);
    const size_t common = std::min({end[0] - begin[0], end[1] - begin[1], end[2] - begin[2], end[3] - begin[3]});
    for (size_t q = 0; q < common; ++q) add(s0, begin[0] + q), add(s1, begin[1] + q), add(s2, begin[2] + q), add(s3, begin[3] + q);
    Sums* sums[4] = {&s0, &s1, &s2, &s3};
    for (size_t j = 0; j < 4 && 4 * group + j < chunks; ++j) {
      for (size_t p = begin[j] + common; p < end[j]; ++p) add(*sums[j], p);
      partial[4 * group + j] = *sums[j];
    }
  });
  LossValue lv;
  double l1 = 0, s = 0;
  for (const Sums& part : partial) l1 += part.l1;
  for (int c = 0; c < 3; ++c) {
    double channel = 0;
    for (const Sums& part : partial) channel += part.ssim[c];
    s += channel;
  }
  lv.l1 = l1 / double(n);
  lv.ssim = s / double(n);
  return lv;
}

/// (1 − λ)·L1 + λ·(1 − SSIM) from the means; weighted: mean of w·(1 − S) = mean(w) − mean(w·S).
template <typename Real>
void set_total(LossValue& lv, const Real* weights, size_t P, double lambda) {
  double wmean = 1.0;
  if (weights) {
    wmean = 0;
    for (size_t i = 0; i < P; ++i) wmean += double(weights[i]);
    wmean /= double(P);
  }
  lv.total = (1.0 - lambda) * lv.l1 + lambda * (wmean - lv.ssim);
}

}  // namespace

template <typename Real>
LossValue photometric_loss(const Real* render, const float* target, int W, int H, const Real* weights,
                           double lambda, Real* grad) {
  const size_t P = size_t(W) * H, n = P * 3;
  if constexpr (std::is_same_v<Real, float>) {
    if (resolve_kernel(Kernel::Default) == Kernel::Simd) {  // unless the scalar reference is selected (raster.hpp)
      LossValue lv = fused_loss(render, target, W, H, weights, lambda, grad);
      set_total(lv, weights, P, lambda);
      return lv;
    }
  }
  LossValue lv;
  const double l1 = chunked_sum(P, [&](size_t p0, size_t p1) {
    double sum = 0;
    for (size_t i = 3 * p0; i < 3 * p1; ++i) {
      const Real d = render[i] - Real(target[i]);
      const Real w = weights ? weights[i / 3] : Real(1);
      sum += double(w * std::abs(d));
      if (grad) grad[i] = Real((1.0 - lambda) / double(n)) * w * (d > Real(0) ? Real(1) : d < Real(0) ? Real(-1) : Real(0));
    }
    return sum;
  });
  lv.l1 = l1 / double(n);
  double s = 0;
  static thread_local std::vector<Real> planes[4];  // reused (see SsimScratch); by reference below
  std::vector<Real>&x = planes[0], &y = planes[1], &coef = planes[2], &g = planes[3];
  x.resize(P), y.resize(P), coef.resize(P);
  for (size_t i = 0; i < P; ++i) coef[i] = weights ? weights[i] : Real(1);
  for (int c = 0; c < 3; ++c) {
    chunked_for(P, [&](size_t p0, size_t p1) {
      for (size_t i = p0; i < p1; ++i) x[i] = render[i * 3 + c], y[i] = Real(target[i * 3 + c]);
    });
    s += ssim_plane(x, y, W, H, &coef, grad ? &g : nullptr);
    if (grad)
      chunked_for(P, [&](size_t p0, size_t p1) {
        for (size_t i = p0; i < p1; ++i) grad[i * 3 + c] -= Real(lambda / double(n)) * g[i];
      });
  }
  lv.ssim = s / double(n);
  set_total(lv, weights, P, lambda);
  return lv;
}

template LossValue photometric_loss<float>(const float*, const float*, int, int, const float*, double, float*);
template LossValue photometric_loss<double>(const double*, const float*, int, int, const double*, double, double*);

double psnr(const float* a, const float* b, int W, int H, int C, const unsigned char* mask) {
  double se = 0;
  size_t count = 0;
  for (size_t p = 0; p < size_t(W) * H; ++p) {
    if (mask && !mask[p]) continue;
    for (int c = 0; c < C; ++c) {
      const double d = std::clamp(double(a[p * C + c]), 0.0, 1.0) - std::clamp(double(b[p * C + c]), 0.0, 1.0);
      se += d * d;
      ++count;
    }
  }
  if (count == 0) return std::numeric_limits<double>::quiet_NaN();
  return psnr_of_mse(se / double(count));
}

double psnr_of_mse(double mse) { return std::min(kMaxPsnr, -10.0 * std::log10(std::max(mse, 1e-300))); }

double ssim(const float* a, const float* b, int W, int H, int C) {
  const size_t P = size_t(W) * H;
  std::vector<double> x(P), y(P);
  double s = 0;
  for (int c = 0; c < C; ++c) {
    for (size_t i = 0; i < P; ++i)
      x[i] = std::clamp(double(a[i * C + c]), 0.0, 1.0), y[i] = std::clamp(double(b[i * C + c]), 0.0, 1.0);
    s += ssim_plane<double>(x, y, W, H, nullptr, nullptr);
  }
  return s / double(P * C);
}

}  // namespace fillgs
