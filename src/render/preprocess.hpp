#pragma once
// The splat preprocess shared by render() and DiffRasterizer: every Gaussian projected (the
// 3DGS preprocess in double, raster_grad.hpp's project_splat), the visible ones (radius > 0,
// opacity ≥ 1/255) set up for the tile kernel — splat (u, v, conic, opacity), the α box's
// half-extents and the colour from SH with its clamp bits. Templated on the scalar of the
// Gaussians' arrays; one definition, so that both rasterizers cull and colour identically.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "fillgs/render/raster.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/model/sh.hpp"
#include "render/frustum.hpp"
#include "render/raster_internal.hpp"

namespace fillgs::tiles {

/// Gaussians at one time as flat arrays (activated values).
template <typename Real>
struct SplatSource {
  size_t count = 0;
  int sh_degree = 0;
  const Real* means = nullptr;      ///< [N][3]
  const Real* scales = nullptr;     ///< [N][3]
  const Real* rotations = nullptr;  ///< [N][4] unit quaternions (w, x, y, z)
  const Real* opacities = nullptr;  ///< [N]
  const Real* sh = nullptr;         ///< [N][(degree+1)²][3]; null: no colour channels
};

/// Where the preprocess writes (each resized here).
template <typename Real>
struct SplatSetup {
  std::vector<int>* radii;                     ///< [N], 0 where culled
  std::vector<ProjectedGaussian>* projected;   ///< [N], for binning
  std::vector<uint32_t>* visible;              ///< visible index → Gaussian
  std::vector<Real>* splat;                    ///< [V][6]
  std::vector<float>* extent;                  ///< [V][2]
  std::vector<Real>* channels;                 ///< [V][C]; colour at 0..2 when the source has SH
  std::vector<uint8_t>* clamped = nullptr;     ///< optional [V]: colour channels clamped at 0
};

/// Unit direction from the camera centre to a mean; (0, 0, 1) for a zero vector.
template <typename Real>
void view_direction(const Real* mean, const Real* centre, Real dir[3], Real* length) {
  for (int k = 0; k < 3; ++k) dir[k] = mean[k] - centre[k];
  const Real len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  *length = len;
  if (len > Real(0)) {
    for (int k = 0; k < 3; ++k) dir[k] /= len;
  } else {
    dir[0] = dir[1] = Real(0);
    dir[2] = Real(1);
  }
}

/// Runs the preprocess for C channels; `extra(i, g, projected, channels_of_i)` fills the
/// channels after the colour (depth, features). Threads: the caller's arena.
template <typename Real, typename Extra>
void prepare_splats(const SplatSource<Real>& G, const Camera& cam, int C, const SplatSetup<Real>& out, Extra&& extra) {
  const size_t N = G.count;
  out.radii->assign(N, 0);
  out.projected->resize(N);
  std::vector<SplatProjection<double>> exact(N);
  if constexpr (std::is_same_v<Real, float>) {
    // A lane of Gaussians per instruction (frustum.hpp), every value the loop below writes for double.
    const internal::FrustumCamera fc(cam);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, N, 1024), [&](const tbb::blocked_range<size_t>& r) {
      internal::project_rows(fc, G.means, G.scales, G.rotations, r.begin(), r.end(), exact.data(), out.projected->data(),
                             out.radii->data());
    });
  } else {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, N, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t g = r.begin(); g < r.end(); ++g) {
        double m[3], s[3], q[4];
        for (int k = 0; k < 3; ++k) m[k] = double(G.means[3 * g + k]), s[k] = double(G.scales[3 * g + k]);
        for (int k = 0; k < 4; ++k) q[k] = double(G.rotations[4 * g + k]);
        exact[g] = project_splat<double>(m, s, q, cam);
        if (internal::splat_footprint(exact[g], cam, &(*out.projected)[g])) (*out.radii)[g] = (*out.projected)[g].radius;
      }
    });
  }
  out.visible->clear();
  for (uint32_t g = 0; g < N; ++g)
    if ((*out.radii)[g] > 0 && G.opacities[g] >= Real(kMinAlpha)) out.visible->push_back(g);
  const size_t V = out.visible->size();
  out.splat->assign(V * 6, Real(0));
  out.extent->assign(V * 2, 0.0f);
  out.channels->assign(V * size_t(C), Real(0));
  if (out.clamped) out.clamped->assign(V, 0);
  const int K = (G.sh_degree + 1) * (G.sh_degree + 1);
  const Vec3d centre = cam.centre();
  const Real campos[3] = {Real(centre.x()), Real(centre.y()), Real(centre.z())};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint32_t g = (*out.visible)[i];
      const SplatProjection<double>& p = exact[g];
      Real* sd = &(*out.splat)[6 * i];
      // Real = float rounds as the splats have always been stored (u, v and conic from double).
      sd[0] = Real(p.u);
      sd[1] = Real(p.v);
      for (int k = 0; k < 3; ++k) sd[2 + k] = Real(p.conic[k]);
      sd[5] = G.opacities[g];
      internal::alpha_extent(float(G.opacities[g]), float(p.cov[0]), float(p.cov[2]), &(*out.extent)[2 * i],
                             &(*out.extent)[2 * i + 1]);
      Real* ch = out.channels->data() + i * size_t(C);  // C may be 0 (alpha only): no element access
      if (G.sh) {
        Real dir[3], len;
        view_direction(&G.means[3 * g], campos, dir, &len);
        const unsigned bits = sh_colour<Real>(G.sh_degree, G.sh + size_t(g) * K * 3, dir[0], dir[1], dir[2], ch);
        if (out.clamped) (*out.clamped)[i] = uint8_t(bits);
      }
      extra(i, g, (*out.projected)[g], ch);
    }
  });
}

}  // namespace fillgs::tiles
