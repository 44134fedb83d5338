// The dense-layer kernel (model/dense.hpp): register-blocked MR x (2 vectors) tiles of the
// output, one weight broadcast per row and step, two vector loads of the inputs per step.
// MR = 12 where the target has 32 vector registers (AVX-512: 24 accumulators), 4 otherwise;
// the last rows of a layer in one smaller tile.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "model/dense_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "fillgs/model/dense.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::dense {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;

template <int MR>
HWY_INLINE void Tile(const float* W, size_t ldw, const float* bias, int o0, int in, const float* X, float* Y, size_t c0, bool relu) {
  const D d;
  const size_t L = hn::Lanes(d);
  using V = hn::Vec<D>;
  V a0[MR], a1[MR];
#pragma GCC unroll 12
  for (int r = 0; r < MR; ++r) {
    a0[r] = hn::Zero(d);
    a1[r] = hn::Zero(d);
  }
  const float* w = W + size_t(o0) * ldw;
  for (int k = 0; k < in; ++k) {
    const float* x = X + size_t(k) * kBlock + c0;
    const V x0 = hn::LoadU(d, x), x1 = hn::LoadU(d, x + L);
#pragma GCC unroll 12
    for (int r = 0; r < MR; ++r) {
      const V wr = hn::Set(d, w[size_t(r) * ldw + size_t(k)]);
      a0[r] = hn::MulAdd(wr, x0, a0[r]);
      a1[r] = hn::MulAdd(wr, x1, a1[r]);
    }
  }
#pragma GCC unroll 12
  for (int r = 0; r < MR; ++r) {
    const V b = hn::Set(d, bias[o0 + r]);
    V y0 = hn::Add(a0[r], b), y1 = hn::Add(a1[r], b);
    if (relu) {
      y0 = hn::Max(y0, hn::Zero(d));
      y1 = hn::Max(y1, hn::Zero(d));
    }
    float* y = Y + size_t(o0 + r) * kBlock + c0;
    hn::StoreU(y0, d, y);
    hn::StoreU(y1, d, y + L);
  }
}

void Layer(const float* W, size_t ldw, const float* bias, int out, int in, const float* X, float* Y, bool relu) {
  const D d;
  const size_t step = 2 * hn::Lanes(d);
  constexpr int kMR = (HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3) ? 12 : 4;  // AVX-512 has 32 vector registers
  for (size_t c0 = 0; c0 < kBlock; c0 += step) {
    int o = 0;
    for (; o + kMR <= out; o += kMR) Tile<kMR>(W, ldw, bias, o, in, X, Y, c0, relu);
    // The remaining rows in one pass over the inputs (a head of 3 outputs is one tile).
    switch (out - o) {
      case 0: break;
      case 1: Tile<1>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      case 2: Tile<2>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      case 3: Tile<3>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      case 4: Tile<4>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      case 5: Tile<5>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      case 6: Tile<6>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      case 7: Tile<7>(W, ldw, bias, o, in, X, Y, c0, relu); break;
      default:  // 8 to 11 (AVX-512's tiles of 12)
        Tile<8>(W, ldw, bias, o, in, X, Y, c0, relu);
        if (out - o == 9) Tile<1>(W, ldw, bias, o + 8, in, X, Y, c0, relu);
        if (out - o == 10) Tile<2>(W, ldw, bias, o + 8, in, X, Y, c0, relu);
        if (out - o == 11) Tile<3>(W, ldw, bias, o + 8, in, X, Y, c0, relu);
        break;
    }
  }
}

const char* TargetName() { return hwy::TargetName(HWY_TARGET); }
int LaneCount() { return int(hn::Lanes(D())); }

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::dense
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::dense {

HWY_EXPORT(Layer);
HWY_EXPORT(TargetName);
HWY_EXPORT(LaneCount);

void layer(const float* W, size_t ldw, const float* bias, int out, int in, const float* X, float* Y, bool relu) {
  HWY_DYNAMIC_DISPATCH(Layer)(W, ldw, bias, out, in, X, Y, relu);
}
const char* target_name() { return HWY_DYNAMIC_DISPATCH(TargetName)(); }
int lane_count() { return HWY_DYNAMIC_DISPATCH(LaneCount)(); }

}  // namespace fillgs::dense
#endif
