#include "fillgs/render/raster_grad.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <type_traits>

#include "fillgs/base/error.hpp"
#include "fillgs/model/sh.hpp"
#include "render/raster_internal.hpp"
#include "render/preprocess.hpp"
#include "render/splat_backward_rows.hpp"
#include "render/tile_kernel.hpp"

namespace fillgs {

// ---------------------------------------------------------------------------------
// Projection (the 3DGS preprocess) and its backward

template <typename Real>
SplatProjection<Real> project_splat(const Real* mean, const Real* scale, const Real* rotation, const Camera& cam) {
  SplatProjection<Real> out;
  // Written out rather than with Eigen products: this runs for every Gaussian of every
  // render (the priority renders 15 views per viewpoint), and Σ2 = (T·M)(T·M)ᵀ with
  // M = R·S and T = J·W takes half the operations of T·(R S² Rᵀ)·Tᵀ.
  Real W[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) W[r][c] = Real(cam.R(r, c));
  Real p[3];
  for (int r = 0; r < 3; ++r) p[r] = W[r][0] * mean[0] + W[r][1] * mean[1] + W[r][2] * mean[2] + Real(cam.t[r]);
  if (!(p[2] > Real(kNearPlane))) return out;
  const Real qw = rotation[0], qx = rotation[1], qy = rotation[2], qz = rotation[3];
  const Real R[3][3] = {{Real(1) - Real(2) * (qy * qy + qz * qz), Real(2) * (qx * qy - qw * qz), Real(2) * (qx * qz + qw * qy)},
                        {Real(2) * (qx * qy + qw * qz), Real(1) - Real(2) * (qx * qx + qz * qz), Real(2) * (qy * qz - qw * qx)},
                        {Real(2) * (qx * qz - qw * qy), Real(2) * (qy * qz + qw * qx), Real(1) - Real(2) * (qx * qx + qy * qy)}};
  const Real fx = Real(cam.fx), fy = Real(cam.fy), z = p[2];
  const Real limx = Real(1.3) * Real(cam.width / (2.0 * cam.fx)), limy = Real(1.3) * Real(cam.height / (2.0 * cam.fy));
  const Real tx = std::clamp(p[0] / z, -limx, limx) * z;
  const Real ty = std::clamp(p[1] / z, -limy, limy) * z;
  // T = J·W, J = [[fx/z, 0, −fx·tx/z²], [0, fy/z, −fy·ty/z²]].
  const Real j00 = fx / z, j02 = -(fx * tx) / (z * z), j11 = fy / z, j12 = -(fy * ty) / (z * z);
  Real T0[3], T1[3];
  for (int c = 0; c < 3; ++c) T0[c] = j00 * W[0][c] + j02 * W[2][c], T1[c] = j11 * W[1][c] + j12 * W[2][c];
  // U = T·R·S (2×3); Σ2 = U Uᵀ.
  Real U0[3], U1[3];
  for (int k = 0; k < 3; ++k) {
    U0[k] = (T0[0] * R[0][k] + T0[1] * R[1][k] + T0[2] * R[2][k]) * scale[k];
    U1[k] = (T1[0] * R[0][k] + T1[1] * R[1][k] + T1[2] * R[2][k]) * scale[k];
  }
  const Real a = U0[0] * U0[0] + U0[1] * U0[1] + U0[2] * U0[2] + Real(kDilation);
  const Real b = U0[0] * U1[0] + U0[1] * U1[1] + U0[2] * U1[2];
  const Real c = U1[0] * U1[0] + U1[1] * U1[1] + U1[2] * U1[2] + Real(kDilation);
  const Real det = a * c - b * b;
  if (!(det > Real(0)) || !std::isfinite(det)) return out;
  out.u = fx * p[0] / z + Real(cam.cx) - Real(0.5);
  out.v = fy * p[1] / z + Real(cam.cy) - Real(0.5);
  if (!std::isfinite(out.u) || !std::isfinite(out.v)) return out;
  out.cov[0] = a;
  out.cov[1] = b;
  out.cov[2] = c;
  out.conic[0] = c / det;
  out.conic[1] = -b / det;
  out.conic[2] = a / det;
  out.depth = z;
  out.valid = true;
  return out;
}

template <typename Real>
void project_splat_backward(const Real* mean, const Real* scale, const Real* rotation, const Camera& cam, Real dL_du,
                            Real dL_dv, const Real dL_dconic[3], Real* dL_dmean, Real* dL_dscale, Real* dL_drot) {
  using V3 = Eigen::Matrix<Real, 3, 1>;
  using M3 = Eigen::Matrix<Real, 3, 3>;
  const M3 W = cam.R.cast<Real>();
  const V3 p = W * V3(mean[0], mean[1], mean[2]) + cam.t.cast<Real>();
  if (!(p.z() > Real(kNearPlane))) return;
  const Real w = rotation[0], x = rotation[1], y = rotation[2], z = rotation[3];
  const M3 Rg = quat_to_matrix<Real>(Eigen::Matrix<Real, 4, 1>(w, x, y, z));
  const V3 s(scale[0], scale[1], scale[2]);
  const M3 M = Rg * s.asDiagonal();
  const M3 cov3 = M * M.transpose();
  const Real fx = Real(cam.fx), fy = Real(cam.fy), pz = p.z();
  const Real limx = Real(1.3) * Real(cam.width / (2.0 * cam.fx)), limy = Real(1.3) * Real(cam.height / (2.0 * cam.fy));
  const Real rx = p.x() / pz, ry = p.y() / pz;
  const bool clamp_x = rx < -limx || rx > limx, clamp_y = ry < -limy || ry > limy;
  const Real tx = std::clamp(rx, -limx, limx) * pz, ty = std::clamp(ry, -limy, limy) * pz;
  Eigen::Matrix<Real, 2, 3> J;
  J << fx / pz, Real(0), -(fx * tx) / (pz * pz), Real(0), fy / pz, -(fy * ty) / (pz * pz);
  const Eigen::Matrix<Real, 2, 3> T = J * W;
  const Eigen::Matrix<Real, 2, 2> cov = T * cov3 * T.transpose();
  const Real a = cov(0, 0) + Real(kDilation), b = cov(0, 1), c = cov(1, 1) + Real(kDilation);
  const Real det = a * c - b * b;
  if (!(det > Real(0))) return;

  // conic (A, B, C) = (c, −b, a) / det  →  dilated covariance (a, b, c)
  const Real d2 = det * det;
  const Real gA = dL_dconic[0], gB = dL_dconic[1], gC = dL_dconic[2];
  const Real ga = gA * (-c * c / d2) + gB * (b * c / d2) + gC * (-b * b / d2);
  const Real gb = gA * (Real(2) * b * c / d2) + gB * (Real(-1) / det - Real(2) * b * b / d2) + gC * (Real(2) * a * b / d2);
  const Real gc = gA * (-b * b / d2) + gB * (a * b / d2) + gC * (-a * a / d2);
  // Σ2 = T Σ3 Tᵀ with the symmetric gradient G2 (b appears once in the conic, twice in Σ2).
  Eigen::Matrix<Real, 2, 2> G2;
  G2 << ga, Real(0.5) * gb, Real(0.5) * gb, gc;
  const M3 G3 = T.transpose() * G2 * T;
  const Eigen::Matrix<Real, 2, 3> GT = Real(2) * G2 * T * cov3;
  const Eigen::Matrix<Real, 2, 3> GJ = GT * W.transpose();

  // J(p): J00 = fx/z, J11 = fy/z, J02 = −fx·tx/z², J12 = −fy·ty/z²; a clamped tx is rx_c·z.
  V3 gp = V3::Zero();
  gp.z() += -fx / (pz * pz) * GJ(0, 0) - fy / (pz * pz) * GJ(1, 1);
  if (clamp_x) {
    gp.z() += fx * (tx / pz) / (pz * pz) * GJ(0, 2);
  } else {
    gp.x() += -fx / (pz * pz) * GJ(0, 2);
    gp.z() += Real(2) * fx * p.x() / (pz * pz * pz) * GJ(0, 2);
  }
  if (clamp_y) {
    gp.z() += fy * (ty / pz) / (pz * pz) * GJ(1, 2);
  } else {
    gp.y() += -fy / (pz * pz) * GJ(1, 2);
    gp.z() += Real(2) * fy * p.y() / (pz * pz * pz) * GJ(1, 2);
  }
  // Mean's pixel position.
  gp.x() += fx / pz * dL_du;
  gp.y() += fy / pz * dL_dv;
  gp.z() += -fx * p.x() / (pz * pz) * dL_du - fy * p.y() / (pz * pz) * dL_dv;
  const V3 gm = W.transpose() * gp;
  for (int k = 0; k < 3; ++k) dL_dmean[k] += gm[k];

  // Σ3 = M Mᵀ, M = R S.
  const M3 GM = Real(2) * G3 * M;
  for (int k = 0; k < 3; ++k) dL_dscale[k] += Rg.col(k).dot(GM.col(k));
  const M3 G = GM * s.asDiagonal();  // dL/dR
  dL_drot[0] += Real(2) * (-z * G(0, 1) + y * G(0, 2) + z * G(1, 0) - x * G(1, 2) - y * G(2, 0) + x * G(2, 1));
  dL_drot[1] += Real(2) * (y * G(0, 1) + z * G(0, 2) + y * G(1, 0) - Real(2) * x * G(1, 1) - w * G(1, 2) + z * G(2, 0) +
                           w * G(2, 1) - Real(2) * x * G(2, 2));
  dL_drot[2] += Real(2) * (Real(-2) * y * G(0, 0) + x * G(0, 1) + w * G(0, 2) + x * G(1, 0) + z * G(1, 2) - w * G(2, 0) +
                           z * G(2, 1) - Real(2) * y * G(2, 2));
  dL_drot[3] += Real(2) * (Real(-2) * z * G(0, 0) - w * G(0, 1) + x * G(0, 2) + w * G(1, 0) - Real(2) * z * G(1, 1) +
                           y * G(1, 2) + x * G(2, 0) + y * G(2, 1));
}

namespace {

/// A number with its derivatives along x, y, z: differentiates the SH basis exactly.
template <typename Real>
struct Dual3 {
  Real v = 0, d[3] = {0, 0, 0};
  Dual3() = default;
  explicit Dual3(double c) : v(Real(c)) {}
  friend Dual3 operator+(const Dual3& a, const Dual3& b) {
    Dual3 r;
    r.v = a.v + b.v;
    for (int k = 0; k < 3; ++k) r.d[k] = a.d[k] + b.d[k];
    return r;
  }
  friend Dual3 operator-(const Dual3& a, const Dual3& b) {
    Dual3 r;
    r.v = a.v - b.v;
    for (int k = 0; k < 3; ++k) r.d[k] = a.d[k] - b.d[k];
    return r;
  }
  friend Dual3 operator*(const Dual3& a, const Dual3& b) {
    Dual3 r;
    r.v = a.v * b.v;
    for (int k = 0; k < 3; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
    return r;
  }
};

}  // namespace

// ---------------------------------------------------------------------------------
// Forward

template <typename Real>
void DiffRasterizer<Real>::forward(const DiffFrame<Real>& G, const Camera& cam, const DiffRenderOptions& opt) {
  FILLGS_CHECK(cam.width > 0 && cam.height > 0);
  FILLGS_CHECK(opt.feature_channels == 0 || opt.features != nullptr);
  frame_ = &G;
  camera_ = cam;
  options_ = opt;
  const int W = cam.width, H = cam.height;
  width_ = W;
  height_ = H;
  const size_t N = G.size();
  const int F = opt.feature_channels;
  const int C = 3 + F;
  channels_ = C;

  tiles::SplatSource<Real> source;
  source.count = N;
  source.sh_degree = G.sh_degree;
  source.means = G.means.data();
  source.scales = G.scales.data();
  source.rotations = G.rotations.data();
  source.opacities = G.opacities.data();
  source.sh = G.sh;
  std::vector<ProjectedGaussian> proj;
  tiles::prepare_splats(source, cam, C,
                        tiles::SplatSetup<Real>{&radii_, &proj, &visible_, &splat_data_, &half_extent_, &colour_, &colour_clamped_},
                        [&](size_t, uint32_t g, const ProjectedGaussian&, Real* ch) {
                          for (int f = 0; f < F; ++f) ch[3 + f] = Real(opt.features[size_t(g) * F + f]);
                        });

  // The vector kernel's pairs are binned only into the tiles that hold a pixel of their α
  // spans, which it reads rather than computes per entry. The images' buffers (every pixel
  // written by the tile pass below) are made beside the binning.
  const bool simd = uses_simd();
  alpha_spans_.clear();
  if constexpr (std::is_same_v<Real, float>) {
    if (simd) tiles::alpha_spans(splat_data_.data(), half_extent_.data(), visible_.size(), &alpha_spans_);
  }
  const int32_t* spans = alpha_spans_.empty() ? nullptr : alpha_spans_.data();
  internal::TileBins bins;
  tbb::parallel_invoke([&] { bins = internal::bin_tiles(proj, visible_, W, H, spans); },
                       [&] {
                         image_.resize(size_t(W) * H * 3);
                         features_.resize(size_t(W) * H * F);
                         alpha_.resize(size_t(W) * H);
                         final_T_.resize(size_t(W) * H);
                         last_entry_.resize(size_t(W) * H);
                       });
  grid_x_ = bins.grid_x;
  tile_start_ = std::move(bins.start);
  keys_ = std::move(bins.entries);
  const size_t tiles = size_t(bins.grid_x) * bins.grid_y;

  const tiles::TileSplats<Real> splats{splat_data_.data(), half_extent_.data(), colour_.data(), C, spans};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
    alignas(64) Real T[tiles::kTilePixels];
    uint32_t last[tiles::kTilePixels];
    std::vector<Real> acc(size_t(tiles::kTilePixels) * C);
    for (size_t t = r.begin(); t < r.end(); ++t) {
      const tiles::TileWork work = tile_work(t);
      tiles::TileForward<Real> fwd;
      fwd.T = T;
      fwd.acc = acc.data();
      fwd.last = last;
      tiles::forward_tile(simd, splats, work, fwd);
      // The tile's planar sums into the images, a row of the tile at a time.
      for (int py = work.y0; py < work.y1; ++py) {
        const int l0 = (py - work.y0) * kTileSize, n = work.x1 - work.x0;
        const size_t o0 = size_t(py) * W + size_t(work.x0);
        Real* image = image_.data() + 3 * o0;
        for (int k = 0; k < 3; ++k) {
          const Real* ak = acc.data() + size_t(k) * tiles::kTilePixels + l0;
          const Real bg = Real(opt.background[k]);
          for (int i = 0; i < n; ++i) image[3 * i + k] = ak[i] + T[l0 + i] * bg;
        }
        for (int f = 0; f < F; ++f) {
          const Real* af = acc.data() + size_t(3 + f) * tiles::kTilePixels + l0;
          Real* features = features_.data() + o0 * size_t(F) + size_t(f);
          for (int i = 0; i < n; ++i) features[size_t(i) * F] = af[i];
        }
        Real *alpha = alpha_.data() + o0, *final_T = final_T_.data() + o0;
        for (int i = 0; i < n; ++i) alpha[i] = Real(1) - T[l0 + i], final_T[i] = T[l0 + i];
        std::copy_n(last + l0, n, last_entry_.data() + o0);
      }
    }
  });
}

template <typename Real>
tiles::TileWork DiffRasterizer<Real>::tile_work(size_t t) const {
  return tiles::tile_work(grid_x_, tile_start_.data(), keys_.data(), t, width_, height_);
}

template <typename Real>
bool DiffRasterizer<Real>::uses_simd() const {
  return std::is_same_v<Real, float> && resolve_kernel(options_.kernel) == Kernel::Simd;
}

// ---------------------------------------------------------------------------------
// Backward: tiles back to front, recovering T by division like the CUDA backward.

template <typename Real>
template <typename MakeVisitor>
void DiffRasterizer<Real>::backward_tiles(MakeVisitor&& make_visitor) const {
  const size_t tiles = tile_start_.empty() ? 0 : tile_start_.size() - 1;
  const tiles::TileSplats<Real> splats{splat_data_.data(), half_extent_.data(), colour_.data(), channels_};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
    auto visitor = make_visitor();
    tiles::BackwardScratch<Real> scratch;
    for (size_t t = r.begin(); t < r.end(); ++t)
      tiles::backward_tile_scalar(splats, tile_work(t), final_T_.data(), last_entry_.data(), width_, &scratch, visitor,
                                   tile_start_[t]);
  });
}

template <typename Real>
void DiffRasterizer<Real>::backward_tiles_simd(const Real* dL_dimage, const Real* dL_dfeatures, const Real* pixel_weights,
                                              Real* records, uint32_t* ids, uint32_t* written) const {
  if constexpr (std::is_same_v<Real, float>) {
    const int W = width_, C = channels_, F = C - 3, R = 6 + C;
    const size_t tiles = tile_start_.empty() ? 0 : tile_start_.size() - 1;
    const tiles::TileSplats<float> splats{splat_data_.data(), half_extent_.data(), colour_.data(), C,
                                          alpha_spans_.empty() ? nullptr : alpha_spans_.data()};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles, 1), [&](const tbb::blocked_range<size_t>& r) {
      alignas(64) float final_T[tiles::kTilePixels];
      alignas(64) uint32_t last[tiles::kTilePixels];
      std::vector<float> dpix(size_t(C) * tiles::kTilePixels);
      for (size_t t = r.begin(); t < r.end(); ++t) {
        const tiles::TileWork work = tile_work(t);
        // Tile-local, planar copies, a row of the tile at a time; pixels outside the image
        // were never reached.
        const int n = work.x1 - work.x0;
        if (n < kTileSize || work.y1 - work.y0 < kTileSize) {
          std::fill(final_T, final_T + tiles::kTilePixels, 1.0f);
          std::fill(last, last + tiles::kTilePixels, 0u);
          std::fill(dpix.begin(), dpix.end(), 0.0f);
        } else if (!dL_dfeatures) {
          std::fill(dpix.begin() + 3 * tiles::kTilePixels, dpix.end(), 0.0f);
        }
        for (int py = work.y0; py < work.y1; ++py) {
          const int l0 = (py - work.y0) * kTileSize;
          const size_t o0 = size_t(py) * W + size_t(work.x0);
          std::copy_n(final_T_.data() + o0, n, final_T + l0);
          std::copy_n(last_entry_.data() + o0, n, last + l0);
          float wpx[kTileSize];
          for (int i = 0; i < n; ++i) wpx[i] = pixel_weights ? pixel_weights[o0 + i] : 1.0f;
          for (int c = 0; c < 3; ++c) {
            float* dc = dpix.data() + size_t(c) * tiles::kTilePixels + l0;
            const float* from = dL_dimage + o0 * 3 + size_t(c);
            for (int i = 0; i < n; ++i) dc[i] = from[3 * size_t(i)] * wpx[i];
          }
          if (dL_dfeatures)
            for (int f = 0; f < F; ++f) {
              float* df = dpix.data() + size_t(3 + f) * tiles::kTilePixels + l0;
              const float* from = dL_dfeatures + o0 * F + size_t(f);
              for (int i = 0; i < n; ++i) df[i] = from[size_t(i) * F] * wpx[i];
            }
        }
        tiles::TileBackward io;
        io.final_T = final_T;
        io.last = last;
        io.dpix = dpix.data();
        for (int c = 0; c < 3; ++c) io.background[c] = options_.background[c];
        io.records = records + tile_start_[t] * R;
        io.ids = ids + tile_start_[t];
        written[t] = tiles::backward_tile_simd(splats, work, io);
      }
    });
  }
}

template <typename Real>
void DiffRasterizer<Real>::backward(const Real* dL_dimage, const Real* dL_dfeatures, const Real* pixel_weights,
                                   DiffFrameGrad<Real>* grad) const {
  FILLGS_CHECK(frame_ != nullptr);
  const DiffFrame<Real>& G = *frame_;
  const int C = channels_, F = C - 3;
  const int K = (G.sh_degree + 1) * (G.sh_degree + 1);
  const size_t V = visible_.size();
  // One record per Gaussian-tile pair: du, dv, dA, dB, dC, dopacity, dchannel[C]. The tile
  // pass writes every record the sums read, so they start uninitialised: at 676×507 zeroing
  // them took ~0.5 ms of a ~16 ms backward. The vector pass writes only the records of the
  // entries that reach a pixel (a fifth to a third of them at 676×507), packed per tile:
  // `ids` names each record's Gaussian and `written` counts them per tile. The scalar pass
  // writes every entry's record in the entries' order.
  const int R = 6 + C;
  const size_t tiles = tile_start_.empty() ? 0 : tile_start_.size() - 1;
  const std::unique_ptr<Real[]> records(new Real[keys_.size() * size_t(R)]);
  const uint32_t* ids = keys_.data();
  std::unique_ptr<uint32_t[]> packed_ids;
  std::vector<uint32_t> written(tiles);
  for (size_t t = 0; t < tiles; ++t) written[t] = uint32_t(tile_start_[t + 1] - tile_start_[t]);
  const Vec3f bgf = options_.background;
  const Real bg[3] = {Real(bgf[0]), Real(bgf[1]), Real(bgf[2])};

  struct Visitor {
    const DiffRasterizer* self;
    const Real *dimg, *dfeat, *weights;
    Real* records;
    const Real* bg;
    int C, F, R;
    Real acc[6 + 64];
    const Real* sd = nullptr;
    size_t entry = 0;
    void begin(size_t e, uint32_t i) {
      entry = e;
      sd = &self->splat_data_[6 * i];
      std::fill(acc, acc + R, Real(0));
    }
    void pair(size_t o, const tiles::BlendPair<Real>& pr, const Real* ch) {
      const Real wpx = weights ? weights[o] : Real(1);
      Real dpix[64];
      for (int c = 0; c < 3; ++c) dpix[c] = dimg[o * 3 + c] * wpx;
      for (int f = 0; f < F; ++f) dpix[3 + f] = dfeat ? dfeat[o * F + f] * wpx : Real(0);
      const Real w = pr.alpha * pr.T;
      Real dL_dalpha = 0;
      for (int k = 0; k < C; ++k) {
        acc[6 + k] += w * dpix[k];
        dL_dalpha += (ch[k] - pr.behind[k]) * dpix[k];
      }
      dL_dalpha *= pr.T;
      dL_dalpha += pr.bg_term * (bg[0] * dpix[0] + bg[1] * dpix[1] + bg[2] * dpix[2]);
      if (pr.clamped) return;
      acc[5] += pr.gauss * dL_dalpha;
      const Real dp = pr.alpha * dL_dalpha;  // dL/dpower
      acc[0] += -dp * (sd[2] * pr.dx + sd[3] * pr.dy);
      acc[1] += -dp * (sd[4] * pr.dy + sd[3] * pr.dx);
      acc[2] += Real(-0.5) * dp * pr.dx * pr.dx;
      acc[3] += -dp * pr.dx * pr.dy;
      acc[4] += Real(-0.5) * dp * pr.dy * pr.dy;
    }
    void end(size_t e) { std::copy(acc, acc + R, records + e * R); }
  };
  FILLGS_CHECK(C <= 64);
  if constexpr (std::is_same_v<Real, float>) {
    if (uses_simd()) {
      packed_ids.reset(new uint32_t[keys_.size()]);
      ids = packed_ids.get();
      backward_tiles_simd(dL_dimage, dL_dfeatures, pixel_weights, records.get(), packed_ids.get(), written.data());
    } else {
      backward_tiles([&] { return Visitor{this, dL_dimage, dL_dfeatures, pixel_weights, records.get(), bg, C, F, R, {}}; });
    }
  } else {
    backward_tiles([&] { return Visitor{this, dL_dimage, dL_dfeatures, pixel_weights, records.get(), bg, C, F, R, {}}; });
  }

  // Reduce per Gaussian in tile order (deterministic for any thread count), one thread
  // reading the records once in order; the zeroing of the gradients (~22 MB at 90,854
  // Gaussians of degree 3) and of the projection's gradients runs beside it. A record left
  // out would add +0 to a sum that starts at +0 and so is never −0: no sum changes.
  std::vector<Real> sums;
  std::vector<double> projection_grads;  // float Gaussians: the projection's backward, below
  tbb::parallel_invoke(
      [&] {
        sums.assign(V * size_t(R), Real(0));
        for (size_t t = 0; t < tiles; ++t)
          for (uint64_t e = tile_start_[t]; e < tile_start_[t] + written[t]; ++e) {
            Real* s = &sums[size_t(ids[e]) * R];
            const Real* rec = records.get() + e * R;
            for (int k = 0; k < R; ++k) s[k] += rec[k];
          }
      },
      [&] {
        grad->reset(G.size(), K, F);
        if constexpr (std::is_same_v<Real, float>) projection_grads.resize(V * 10);
      });
  const Vec3d centre = camera_.centre();
  const Real campos[3] = {Real(centre.x()), Real(centre.y()), Real(centre.z())};
  // The projection's backward: for float Gaussians on a lane of them per instruction, with
  // project_splat_backward<double>'s values (splat_backward_rows.hpp).
  if constexpr (std::is_same_v<Real, float>) {
    const internal::FrustumCamera bc(camera_);
    const internal::BackwardRowsInput in{visible_.data(), G.means.data(), G.scales.data(), G.rotations.data(), sums.data(), R};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 512), [&](const tbb::blocked_range<size_t>& r) {
      internal::project_backward_rows(bc, in, r.begin(), r.end(), projection_grads.data());
    });
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 512), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint32_t g = visible_[i];
      const Real* s = &sums[i * R];
      grad->screen[2 * g] = s[0];
      grad->screen[2 * g + 1] = s[1];
      double gm[3] = {0, 0, 0}, gs[3] = {0, 0, 0}, gq[4] = {0, 0, 0, 0};
      if (!projection_grads.empty()) {
        const double* pg = &projection_grads[i * 10];
        std::copy(pg, pg + 3, gm), std::copy(pg + 3, pg + 6, gs), std::copy(pg + 6, pg + 10, gq);
      } else {
        double m[3], sc[3], q[4];
        for (int k = 0; k < 3; ++k) m[k] = double(G.means[3 * g + k]), sc[k] = double(G.scales[3 * g + k]);
        for (int k = 0; k < 4; ++k) q[k] = double(G.rotations[4 * g + k]);
        const double gconic[3] = {double(s[2]), double(s[3]), double(s[4])};
        project_splat_backward<double>(m, sc, q, camera_, double(s[0]), double(s[1]), gconic, gm, gs, gq);
      }
      for (int k = 0; k < 3; ++k) grad->means[3 * g + k] += Real(gm[k]), grad->scales[3 * g + k] += Real(gs[k]);
      for (int k = 0; k < 4; ++k) grad->rotations[4 * g + k] += Real(gq[k]);
      grad->opacities[g] += s[5];
      for (int f = 0; f < F; ++f) grad->features[size_t(g) * F + f] = s[9 + f];
      // Colour from SH: coefficients, and the mean through the view direction.
      const Real gcol[3] = {colour_clamped_[i] & 1 ? Real(0) : s[6], colour_clamped_[i] & 2 ? Real(0) : s[7],
                            colour_clamped_[i] & 4 ? Real(0) : s[8]};
      Real dir[3], len;
      tiles::view_direction(&G.means[3 * g], campos, dir, &len);
      Dual3<Real> dx(0), dy(0), dz(0), Y[16];
      dx.v = dir[0], dy.v = dir[1], dz.v = dir[2];
      dx.d[0] = dy.d[1] = dz.d[2] = Real(1);
      sh_basis_generic<Dual3<Real>>(G.sh_degree, dx, dy, dz, Y);
      const Real* coeffs = G.sh + size_t(g) * K * 3;
      Real* gsh = &grad->sh[size_t(g) * K * 3];
      Real gdir[3] = {0, 0, 0};
      for (int k = 0; k < K; ++k)
        for (int c = 0; c < 3; ++c) {
          gsh[3 * k + c] = Y[k].v * gcol[c];
          for (int a = 0; a < 3; ++a) gdir[a] += Y[k].d[a] * coeffs[3 * k + c] * gcol[c];
        }
      if (K > 1 && len > Real(0)) {
        const Real dot = gdir[0] * dir[0] + gdir[1] * dir[1] + gdir[2] * dir[2];
        for (int a = 0; a < 3; ++a) grad->means[3 * g + a] += (gdir[a] - dot * dir[a]) / len;
      }
    }
  });
}

template <typename Real>
void DiffRasterizer<Real>::accumulate_fisher(FisherDiagonal* fisher) const {
  FILLGS_CHECK(frame_ != nullptr);
  const DiffFrame<Real>& G = *frame_;
  const size_t V = visible_.size();
  constexpr int P = FisherDiagonal::kParams;
  if (fisher->values.size() != G.size() * P) fisher->values.assign(G.size() * P, 0.0);
  // Per visible Gaussian: Jacobian of (u, v, A, B, C) w.r.t. (mean, log-scale, rotation).
  std::vector<double> jac(V * 50, 0.0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 512), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint32_t g = visible_[i];
      double m[3], sc[3], q[4];
      for (int k = 0; k < 3; ++k) m[k] = double(G.means[3 * g + k]), sc[k] = double(G.scales[3 * g + k]);
      for (int k = 0; k < 4; ++k) q[k] = double(G.rotations[4 * g + k]);
      for (int row = 0; row < 5; ++row) {
        double up[5] = {0, 0, 0, 0, 0};
        up[row] = 1.0;
        double* J = &jac[i * 50 + row * 10];
        project_splat_backward<double>(m, sc, q, camera_, up[0], up[1], up + 2, J, J + 3, J + 6);
        for (int k = 0; k < 3; ++k) J[3 + k] *= sc[k];  // d/dlog-scale
      }
    }
  });
  std::vector<double> records(keys_.size() * size_t(P), 0.0);
  const Vec3f bg = options_.background;
  struct Visitor {
    const DiffRasterizer* self;
    const double* jac;
    double* records;
    Vec3f bg;
    double acc[P];
    const Real* sd = nullptr;
    uint32_t vis = 0;
    void begin(size_t, uint32_t i) {
      vis = i;
      sd = &self->splat_data_[6 * i];
      std::fill(acc, acc + P, 0.0);
    }
    void pair(size_t, const tiles::BlendPair<Real>& pr, const Real* ch) {
      const double o = double(sd[5]);
      const double* J = &jac[size_t(vis) * 50];
      for (int c = 0; c < 3; ++c) {
        const double dI_dalpha = double(pr.T) * double(ch[c] - pr.behind[c]) + double(pr.bg_term) * bg[c];
        double g[P] = {0};
        if (!pr.clamped) {
          const double dp = double(pr.alpha) * dI_dalpha;
          const double d2[5] = {-dp * double(sd[2] * pr.dx + sd[3] * pr.dy), -dp * double(sd[4] * pr.dy + sd[3] * pr.dx),
                                -0.5 * dp * double(pr.dx * pr.dx), -dp * double(pr.dx * pr.dy),
                                -0.5 * dp * double(pr.dy * pr.dy)};
          for (int row = 0; row < 5; ++row)
            for (int k = 0; k < 10; ++k) g[k] += J[row * 10 + k] * d2[row];
          g[10] = double(pr.gauss) * dI_dalpha * o * (1.0 - o);
        }
        if (!(self->colour_clamped_[vis] & (1u << c))) g[11 + c] = 0.28209479177387814 * double(pr.alpha * pr.T);
        for (int k = 0; k < P; ++k) acc[k] += g[k] * g[k];
      }
    }
    void end(size_t e) { std::copy(acc, acc + P, records + e * P); }
  };
  backward_tiles([&] { return Visitor{this, jac.data(), records.data(), bg, {}}; });
  for (size_t e = 0; e < keys_.size(); ++e) {
    double* f = &fisher->values[size_t(visible_[keys_[e]]) * P];
    for (int k = 0; k < P; ++k) f[k] += records[e * P + k];
  }
}

template class DiffRasterizer<float>;
template class DiffRasterizer<double>;
template SplatProjection<double> project_splat<double>(const double*, const double*, const double*, const Camera&);
template void project_splat_backward<double>(const double*, const double*, const double*, const Camera&, double,
                                             double, const double[3], double*, double*, double*);

}  // namespace fillgs
