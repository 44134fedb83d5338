// The 3DGS frustum rule (project_gaussian's answer: radius > 0) on a lane of Gaussians per
// instruction, in double, with the scalar code's operations in its order (no fused
// multiply-adds: this file is compiled with -ffp-contract=off), so every decision is the
// scalar one's. Compiled once per instruction set by Google Highway and dispatched at run time.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/frustum_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/frustum.hpp"

HWY_BEFORE_NAMESPACE();
namespace fillgs::internal {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using DD = hn::ScalableTag<double>;
using VD = hn::Vec<DD>;
using MD = hn::Mask<DD>;

/// One lane of Gaussians through project_splat and splat_footprint: every value the scalar
/// code computes, in its order, and `keep` where splat_footprint returns true.
struct ProjectedLanes {
  MD keep;
  VD u, v, a, b, c, det, z, radius, min_x, min_y, max_x, max_y;
};

/// Loads lanes of rows (ids[i] or i) [i, i + n) into buf (means, scales, rotations as double);
/// the last lanes repeat the last row.
HWY_INLINE void GatherRows(const float* means, const float* scales, const float* rotations, const uint32_t* ids, size_t i,
                           size_t n, size_t L, double (*buf)[hn::MaxLanes(DD())], uint32_t* lane_id) {
  for (size_t k = 0; k < L; ++k) {
    const size_t row = i + std::min(k, n - 1);
    const uint32_t g = ids ? ids[row] : uint32_t(row);
    lane_id[k] = g;
    for (int c = 0; c < 3; ++c) buf[c][k] = double(means[size_t(g) * 3 + size_t(c)]);
    for (int c = 0; c < 3; ++c) buf[3 + c][k] = double(scales[size_t(g) * 3 + size_t(c)]);
    for (int c = 0; c < 4; ++c) buf[6 + c][k] = double(rotations[size_t(g) * 4 + size_t(c)]);
  }
}

/// A lane of rows as every camera reads them: the means, the scales and the rotation matrix
/// of the quaternion (the scalar code's operations in its order), made once for all cameras.
struct RowLanes {
  VD mx, my, mz, s[3], R[3][3];
};

HWY_INLINE void LoadRowLanes(double (*buf)[hn::MaxLanes(DD())], RowLanes* g) {
  const DD d;
  const VD one = hn::Set(d, 1.0), two = hn::Set(d, 2.0);
  g->mx = hn::Load(d, buf[0]), g->my = hn::Load(d, buf[1]), g->mz = hn::Load(d, buf[2]);
  for (int k = 0; k < 3; ++k) g->s[k] = hn::Load(d, buf[3 + k]);
  const VD qw = hn::Load(d, buf[6]), qx = hn::Load(d, buf[7]), qy = hn::Load(d, buf[8]), qz = hn::Load(d, buf[9]);
  g->R[0][0] = hn::Sub(one, hn::Mul(two, hn::Add(hn::Mul(qy, qy), hn::Mul(qz, qz))));
  g->R[0][1] = hn::Mul(two, hn::Sub(hn::Mul(qx, qy), hn::Mul(qw, qz)));
  g->R[0][2] = hn::Mul(two, hn::Add(hn::Mul(qx, qz), hn::Mul(qw, qy)));
  g->R[1][0] = hn::Mul(two, hn::Add(hn::Mul(qx, qy), hn::Mul(qw, qz)));
  g->R[1][1] = hn::Sub(one, hn::Mul(two, hn::Add(hn::Mul(qx, qx), hn::Mul(qz, qz))));
  g->R[1][2] = hn::Mul(two, hn::Sub(hn::Mul(qy, qz), hn::Mul(qw, qx)));
  g->R[2][0] = hn::Mul(two, hn::Sub(hn::Mul(qx, qz), hn::Mul(qw, qy)));
  g->R[2][1] = hn::Mul(two, hn::Add(hn::Mul(qy, qz), hn::Mul(qw, qx)));
  g->R[2][2] = hn::Sub(one, hn::Mul(two, hn::Add(hn::Mul(qx, qx), hn::Mul(qy, qy))));
}

/// False when no lane can be kept (the z test fails for all): the other fields are then unset.
HWY_INLINE bool ProjectLanes(const FrustumCamera& cam, const RowLanes& g, ProjectedLanes* o) {
  const DD d;
  using V = VD;
  auto S = [&](double x) { return hn::Set(d, x); };
  const V zero = S(0.0), one = S(1.0);
  V p[3];
  for (int r = 0; r < 3; ++r)
    p[r] = hn::Add(hn::Add(hn::Add(hn::Mul(S(cam.W[r][0]), g.mx), hn::Mul(S(cam.W[r][1]), g.my)), hn::Mul(S(cam.W[r][2]), g.mz)), S(cam.t[r]));
  auto keep = hn::Gt(p[2], S(cam.near));
  if (hn::AllFalse(d, keep)) return false;
  const V(&R)[3][3] = g.R;
  const V fx = S(cam.fx), fy = S(cam.fy), z = p[2];
  // std::clamp(v, lo, hi): lo where v < lo, else hi where hi < v, else v (NaN stays NaN).
  auto clamp = [&](V v, double lo, double hi) { return hn::IfThenElse(hn::Lt(v, S(lo)), S(lo), hn::IfThenElse(hn::Lt(S(hi), v), S(hi), v)); };
  const V tx = hn::Mul(clamp(hn::Div(p[0], z), -cam.limx, cam.limx), z);
  const V ty = hn::Mul(clamp(hn::Div(p[1], z), -cam.limy, cam.limy), z);
  const V zz = hn::Mul(z, z);
  const V j00 = hn::Div(fx, z), j02 = hn::Neg(hn::Div(hn::Mul(fx, tx), zz)), j11 = hn::Div(fy, z), j12 = hn::Neg(hn::Div(hn::Mul(fy, ty), zz));
  V T0[3], T1[3];
  for (int c = 0; c < 3; ++c) {
    T0[c] = hn::Add(hn::Mul(j00, S(cam.W[0][c])), hn::Mul(j02, S(cam.W[2][c])));
    T1[c] = hn::Add(hn::Mul(j11, S(cam.W[1][c])), hn::Mul(j12, S(cam.W[2][c])));
  }
  V U0[3], U1[3];
  for (int k = 0; k < 3; ++k) {
    const V s = g.s[k];
    U0[k] = hn::Mul(hn::Add(hn::Add(hn::Mul(T0[0], R[0][k]), hn::Mul(T0[1], R[1][k])), hn::Mul(T0[2], R[2][k])), s);
    U1[k] = hn::Mul(hn::Add(hn::Add(hn::Mul(T1[0], R[0][k]), hn::Mul(T1[1], R[1][k])), hn::Mul(T1[2], R[2][k])), s);
  }
  auto dot = [&](const V* x, const V* y) { return hn::Add(hn::Add(hn::Mul(x[0], y[0]), hn::Mul(x[1], y[1])), hn::Mul(x[2], y[2])); };
  const V a = hn::Add(dot(U0, U0), S(cam.dilation)), b = dot(U0, U1), c = hn::Add(dot(U1, U1), S(cam.dilation));
  const V det = hn::Sub(hn::Mul(a, c), hn::Mul(b, b));
  keep = hn::And(keep, hn::And(hn::Gt(det, zero), hn::IsFinite(det)));
  const V u = hn::Sub(hn::Add(hn::Div(hn::Mul(fx, p[0]), z), S(cam.cx)), S(0.5));
  const V v = hn::Sub(hn::Add(hn::Div(hn::Mul(fy, p[1]), z), S(cam.cy)), S(0.5));
  keep = hn::And(keep, hn::And(hn::IsFinite(u), hn::IsFinite(v)));
  // splat_footprint: the radius and the tile rectangle, which must not be empty.
  const V mid = hn::Mul(S(0.5), hn::Add(a, c));
  const V spread = hn::Sub(hn::Mul(mid, mid), det);
  const V disc = hn::Sqrt(hn::IfThenElse(hn::Lt(S(0.1), spread), spread, S(0.1)));  // std::max(0.1, spread)
  const V hi = hn::Add(mid, disc), lo = hn::Sub(mid, disc);
  const V lambda = hn::IfThenElse(hn::Lt(hi, lo), lo, hi);  // std::max(hi, lo)
  const V r = hn::Ceil(hn::Mul(S(3.0), hn::Sqrt(lambda)));
  keep = hn::And(keep, hn::IsFinite(r));
  const V radius = hn::IfThenElse(hn::Lt(S(cam.huge), r), S(cam.huge), r);  // std::min(r, huge), an integer
  // tile(x) = min(limit, max(0, int(clamp(x, -huge, huge) / 16))), int() truncating.
  auto tile = [&](V x, double limit) {
    const V t = hn::Trunc(hn::Div(clamp(x, -cam.huge, cam.huge), S(cam.tile)));
    const V at_least_0 = hn::IfThenElse(hn::Lt(t, zero), zero, t);
    return hn::IfThenElse(hn::Lt(S(limit), at_least_0), S(limit), at_least_0);
  };
  o->min_x = tile(hn::Sub(u, radius), cam.grid_x), o->min_y = tile(hn::Sub(v, radius), cam.grid_y);
  o->max_x = tile(hn::Sub(hn::Add(hn::Add(u, radius), S(cam.tile)), one), cam.grid_x);
  o->max_y = tile(hn::Sub(hn::Add(hn::Add(v, radius), S(cam.tile)), one), cam.grid_y);
  o->keep = hn::And(keep, hn::And(hn::Ne(o->max_x, o->min_x), hn::Ne(o->max_y, o->min_y)));
  o->u = u, o->v = v, o->a = a, o->b = b, o->c = c, o->det = det, o->z = z, o->radius = radius;
  return true;
}

/// visit(c, o, kept, lane_id, n) for each block of rows [begin, end) (ids[i], or i without
/// ids) and each camera c of cams[0, ncams) whose rule keeps some lane: o its lanes' values,
/// kept their mask's bits, lane_id their rows, n the rows of the block. A block's rows are
/// loaded once for all the cameras.
template <class Visit>
HWY_INLINE void ForEachKeptBlock(const FrustumCamera* cams, size_t ncams, const float* means, const float* scales, const float* rotations,
                                 const uint32_t* ids, size_t begin, size_t end, Visit&& visit) {
  const DD d;
  const size_t L = hn::Lanes(d);
  HWY_ALIGN double buf[10][hn::MaxLanes(d)];
  uint32_t lane_id[hn::MaxLanes(d)];
  for (size_t i = begin; i < end; i += L) {
    const size_t n = std::min(L, end - i);
    GatherRows(means, scales, rotations, ids, i, n, L, buf, lane_id);
    RowLanes rows;
    LoadRowLanes(buf, &rows);
    for (size_t c = 0; c < ncams; ++c) {
      ProjectedLanes o;
      if (!ProjectLanes(cams[c], rows, &o) || hn::AllFalse(d, o.keep)) continue;
      HWY_ALIGN uint8_t kept[hn::MaxLanes(d) * 8];
      hn::StoreMaskBits(d, o.keep, kept);
      visit(c, o, kept, lane_id, n);
    }
  }
}

/// Appends to outs[c] the ids among rows [begin, end) (ids[i], or i without ids) that the rule
/// keeps for camera cams[c].
void FrustumKeep(const FrustumCamera* cams, size_t ncams, const float* means, const float* scales, const float* rotations, const uint32_t* ids,
                 size_t begin, size_t end, std::vector<uint32_t>* outs) {
  auto append = [&](size_t c, const ProjectedLanes&, const uint8_t* kept, const uint32_t* lane_id, size_t n) {
    for (size_t k = 0; k < n; ++k)
      if ((kept[k / 8] >> (k % 8)) & 1) outs[c].push_back(lane_id[k]);
  };
  ForEachKeptBlock(cams, ncams, means, scales, rotations, ids, begin, end, append);
}

/// project_splat and splat_footprint for rows [begin, end): for each kept row g, exact[g],
/// projected[g] and radii[g] as the scalar preprocess writes them; other rows untouched.
void ProjectRows(const FrustumCamera& cam, const float* means, const float* scales, const float* rotations, size_t begin, size_t end,
                 SplatProjection<double>* exact, ProjectedGaussian* projected, int* radii) {
  const DD d;
  auto write = [&](size_t, const ProjectedLanes& o, const uint8_t* kept, const uint32_t* lane_id, size_t n) {
    const VD conic_a = hn::Div(o.c, o.det), conic_b = hn::Div(hn::Neg(o.b), o.det), conic_c = hn::Div(o.a, o.det);
    const VD fields[14] = {o.u, o.v, o.a, o.b, o.c, conic_a, conic_b, conic_c, o.z, o.radius, o.min_x, o.min_y, o.max_x, o.max_y};
    HWY_ALIGN double out[14][hn::MaxLanes(d)];
    for (int f = 0; f < 14; ++f) hn::Store(fields[f], d, out[f]);
    for (size_t k = 0; k < n; ++k) {
      if (!((kept[k / 8] >> (k % 8)) & 1)) continue;
      const size_t g = lane_id[k];
      SplatProjection<double>& e = exact[g];
      e.u = out[0][k], e.v = out[1][k];
      for (int q = 0; q < 3; ++q) e.cov[q] = out[2 + q][k], e.conic[q] = out[5 + q][k];
      e.depth = out[8][k];
      e.valid = true;
      ProjectedGaussian& p = projected[g];
      p.mean = Vec2f(float(e.u), float(e.v));
      p.cov2d = Vec3f(float(e.cov[0]), float(e.cov[1]), float(e.cov[2]));
      p.conic = Vec3f(float(e.conic[0]), float(e.conic[1]), float(e.conic[2]));
      p.depth = float(e.depth);
      p.radius = int(out[9][k]);
      p.rect_min[0] = int(out[10][k]), p.rect_min[1] = int(out[11][k]);
      p.rect_max[0] = int(out[12][k]), p.rect_max[1] = int(out[13][k]);
      radii[g] = p.radius;
    }
  };
  ForEachKeptBlock(&cam, 1, means, scales, rotations, nullptr, begin, end, write);
}

}  // namespace HWY_NAMESPACE
}  // namespace fillgs::internal
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fillgs::internal {

HWY_EXPORT(FrustumKeep);
HWY_EXPORT(ProjectRows);

FrustumCamera::FrustumCamera(const Camera& c) {
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) W[r][k] = c.R(r, k);
    t[r] = c.t[r];
  }
  fx = c.fx, fy = c.fy, cx = c.cx, cy = c.cy;
  limx = 1.3 * (c.width / (2.0 * c.fx));
  limy = 1.3 * (c.height / (2.0 * c.fy));
  grid_x = double((c.width + kTileSize - 1) / kTileSize);
  grid_y = double((c.height + kTileSize - 1) / kTileSize);
}

void frustum_keep(const FrustumCamera* cams, size_t ncams, const Vec3f* means, const Vec3f* scales, const Vec4f* rotations, const uint32_t* ids,
                  size_t begin, size_t end, std::vector<uint32_t>* outs) {
  static_assert(sizeof(Vec3f) == 3 * sizeof(float) && sizeof(Vec4f) == 4 * sizeof(float), "packed vectors");
  HWY_DYNAMIC_DISPATCH(FrustumKeep)(cams, ncams, means->data(), scales->data(), rotations->data(), ids, begin, end, outs);
}

void project_rows(const FrustumCamera& cam, const float* means, const float* scales, const float* rotations, size_t begin, size_t end,
                  SplatProjection<double>* exact, ProjectedGaussian* projected, int* radii) {
  HWY_DYNAMIC_DISPATCH(ProjectRows)(cam, means, scales, rotations, begin, end, exact, projected, radii);
}

}  // namespace fillgs::internal
#endif
