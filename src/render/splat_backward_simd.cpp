// The projection's backward (splat_backward.hpp) on a lane of Gaussians per instruction, in
// double, compiled without fused multiply-adds (-ffp-contract=off on this file): every value
// is project_splat_backward's. Compiled once per instruction set by Google Highway.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/splat_backward_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>

#include "render/splat_backward.hpp"
#include "render/splat_backward_rows.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::internal {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using DD = hn::ScalableTag<double>;

/// A lane of doubles with the operators splat_backward_math reads, each one instruction.
struct Lanes {
  hn::Vec<DD> v;
};
struct LaneMask {
  hn::Mask<DD> m;
};
HWY_INLINE Lanes operator+(Lanes a, Lanes b) { return {hn::Add(a.v, b.v)}; }
HWY_INLINE Lanes operator-(Lanes a, Lanes b) { return {hn::Sub(a.v, b.v)}; }
HWY_INLINE Lanes operator*(Lanes a, Lanes b) { return {hn::Mul(a.v, b.v)}; }
HWY_INLINE Lanes operator/(Lanes a, Lanes b) { return {hn::Div(a.v, b.v)}; }
HWY_INLINE Lanes neg(Lanes a) { return {hn::Neg(a.v)}; }
HWY_INLINE LaneMask less(Lanes a, Lanes b) { return {hn::Lt(a.v, b.v)}; }
HWY_INLINE Lanes pick(LaneMask m, Lanes a, Lanes b) { return {hn::IfThenElse(m.m, a.v, b.v)}; }
HWY_INLINE LaneMask both(LaneMask a, LaneMask b) { return {hn::And(a.m, b.m)}; }
HWY_INLINE LaneMask either(LaneMask a, LaneMask b) { return {hn::Or(a.m, b.m)}; }

// This target's copy of the math (the namespace's own overloads above serve Lanes).
#include "render/splat_backward_math.inl"

void BackwardRows(const FrustumCamera& cam, const BackwardRowsInput& in, size_t begin, size_t end, double* out) {
  const DD d;
  const size_t L = hn::Lanes(d);
  HWY_ALIGN double buf[15][hn::MaxLanes(d)];
  HWY_ALIGN double res[10][hn::MaxLanes(d)];
  for (size_t i = begin; i < end; i += L) {
    const size_t n = std::min(L, end - i);
    for (size_t k = 0; k < L; ++k) {
      const size_t row = i + std::min(k, n - 1);  // the last lanes repeat a row and are not stored
      const size_t g = in.visible[row];
      const float* s = in.sums + row * size_t(in.stride);
      for (int c = 0; c < 3; ++c) buf[c][k] = double(in.means[g * 3 + size_t(c)]);
      for (int c = 0; c < 3; ++c) buf[3 + c][k] = double(in.scales[g * 3 + size_t(c)]);
      for (int c = 0; c < 4; ++c) buf[6 + c][k] = double(in.rotations[g * 4 + size_t(c)]);
      for (int c = 0; c < 5; ++c) buf[10 + c][k] = double(s[c]);  // du, dv, d conic (a, b, c)
    }
    auto load = [&](int f) { return Lanes{hn::Load(d, buf[f])}; };
    const Lanes m[3] = {load(0), load(1), load(2)}, sc[3] = {load(3), load(4), load(5)}, q[4] = {load(6), load(7), load(8), load(9)};
    const Lanes gconic[3] = {load(12), load(13), load(14)};
    const Lanes zero{hn::Zero(d)};
    Lanes gm[3] = {zero, zero, zero}, gs[3] = {zero, zero, zero}, gq[4] = {zero, zero, zero, zero};
    LaneMask used{hn::FirstN(d, 0)};
    HWY_NAMESPACE::splat_backward_math<Lanes>(cam, m, sc, q, load(10), load(11), gconic, gm, gs, gq, &used,
                                              [&](double x) { return Lanes{hn::Set(d, x)}; });
    // Where the projection is undefined the scalar form adds nothing: 0.
    for (int c = 0; c < 3; ++c) hn::Store(hn::IfThenElseZero(used.m, gm[c].v), d, res[c]);
    for (int c = 0; c < 3; ++c) hn::Store(hn::IfThenElseZero(used.m, gs[c].v), d, res[3 + c]);
    for (int c = 0; c < 4; ++c) hn::Store(hn::IfThenElseZero(used.m, gq[c].v), d, res[6 + c]);
    for (size_t k = 0; k < n; ++k)
      for (int c = 0; c < 10; ++c) out[(i + k) * 10 + size_t(c)] = res[c][k];
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::internal
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::internal {

HWY_EXPORT(BackwardRows);

void project_backward_rows(const FrustumCamera& cam, const BackwardRowsInput& in, size_t begin, size_t end, double* out) {
  HWY_DYNAMIC_DISPATCH(BackwardRows)(cam, in, begin, end, out);
}

}  // namespace fillgs::internal
#endif
