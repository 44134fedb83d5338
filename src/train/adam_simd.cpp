// The element-wise Adam step (adam.hpp) on a lane of elements per instruction. Products and
// sums stay separate operations (this file is compiled with -ffp-contract=off) in the scalar
// form's order, and division and square root are correctly rounded in both, so every value
// stored is the scalar one's. Compiled once per instruction set by Google Highway.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "train/adam_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <cmath>

#include "train/adam.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::train {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void AdamUpdate(const AdamStep& s, float* HWY_RESTRICT x, const float* HWY_RESTRICT g, float* HWY_RESTRICT m,
                float* HWY_RESTRICT v, size_t n) {
  const hn::ScalableTag<float> d;
  const size_t L = hn::Lanes(d);
  const auto b1 = hn::Set(d, s.b1), b2 = hn::Set(d, s.b2), c1 = hn::Set(d, 1.0f - s.b1), c2 = hn::Set(d, 1.0f - s.b2);
  const auto a = hn::Set(d, s.a), s2 = hn::Set(d, s.s2), eps = hn::Set(d, s.eps), zero = hn::Zero(d);
  size_t i = 0;
  for (; i + L <= n; i += L) {
    const auto G = hn::LoadU(d, g + i);
    const auto M = hn::Add(hn::Mul(b1, hn::LoadU(d, m + i)), hn::Mul(c1, G));
    const auto V = hn::Add(hn::Mul(b2, hn::LoadU(d, v + i)), hn::Mul(hn::Mul(c2, G), G));
    const auto X0 = hn::LoadU(d, x + i);
    const auto X = hn::Sub(X0, hn::Div(hn::Mul(a, M), hn::Add(hn::Mul(hn::Sqrt(V), s2), eps)));
    if (s.sparse) {
      const auto keep = hn::Eq(G, zero);  // an exactly-zero gradient leaves the element as it was
      hn::StoreU(hn::IfThenElse(keep, hn::LoadU(d, m + i), M), d, m + i);
      hn::StoreU(hn::IfThenElse(keep, hn::LoadU(d, v + i), V), d, v + i);
      hn::StoreU(hn::IfThenElse(keep, X0, X), d, x + i);
    } else {
      hn::StoreU(M, d, m + i);
      hn::StoreU(V, d, v + i);
      hn::StoreU(X, d, x + i);
    }
  }
  if (i < n) adam_update_scalar(s, x + i, g + i, m + i, v + i, n - i);
}

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::train
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::train {

HWY_EXPORT(AdamUpdate);

void adam_update(const AdamStep& step, float* x, const float* g, float* m, float* v, size_t n) {
  HWY_DYNAMIC_DISPATCH(AdamUpdate)(step, x, g, m, v, n);
}

void adam_update_scalar(const AdamStep& s, float* x, const float* g, float* m, float* v, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    if (s.sparse && g[i] == 0.0f) continue;
    m[i] = s.b1 * m[i] + (1 - s.b1) * g[i];
    v[i] = s.b2 * v[i] + (1 - s.b2) * g[i] * g[i];
    x[i] -= s.a * m[i] / (std::sqrt(v[i]) * s.s2 + s.eps);
  }
}

}  // namespace fillgs::train
#endif
