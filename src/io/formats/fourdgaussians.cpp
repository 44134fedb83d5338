// 4DGaussians: point_cloud/iteration_N/point_cloud.ply, deformation.pth (HexPlane feature
// planes and MLP heads) and cfg_args, evaluated as its renderer does.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/model/sh.hpp"
#include "io/model_support.hpp"
#include "io/ply_gaussians.hpp"

namespace fillgs::model_io {

namespace {

class FourDGaussians : public TrainedModel {
 public:
  FourDGaussians(const std::string& path, const SceneReadOptions& opt) {
    const DeformationRun run = open_run(path, *this, "4DGaussians");
    const std::string &cfg_path = run.cfg_path, &ply_path = run.ply_path, &pth = run.pth;
    const nlohmann::json& c = run.cfg;
    canonical_ = read_vertex_state(read_ply(ply_path).element("vertex"), notes);
    const TorchFile tf(pth);
    const StateDict sd(tf, tf.root(), "deformation.pth");
    for (const char* k : {"no_grid", "static_mlp", "empty_voxel", "apply_rotation"})
      if (cfg<bool>(c, k, false, cfg_path)) throw_error(cfg_path, ": setting ", k, "=True is not supported (4DGaussians marks it unused)");
    if (cfg<int>(c, "grid_pe", 0, cfg_path) > 1) throw_error(cfg_path, ": setting grid_pe > 1 is not supported (4DGaussians marks it unused)");
    no_dx_ = cfg<bool>(c, "no_dx", false, cfg_path);
    no_ds_ = cfg<bool>(c, "no_ds", false, cfg_path);
    no_dr_ = cfg<bool>(c, "no_dr", false, cfg_path);
    no_do_ = cfg<bool>(c, "no_do", true, cfg_path);
    no_dshs_ = cfg<bool>(c, "no_dshs", true, cfg_path);
    aabb_ = sd.get("deformation_net.grid.aabb", {2, 3}).values;
    // 4DGaussians stores [max, min]; either order is read, but the scale 2 / (min - max) must
    // be a finite number, or a position becomes an infinite or NaN grid coordinate.
    for (int a = 0; a < 3; ++a) {
      const float k = 2.0f / (aabb_[size_t(3 + a)] - aabb_[size_t(a)]);
      if (!std::isfinite(k) || aabb_[size_t(a)] == aabb_[size_t(3 + a)])
        throw_error(pth, ": key 'deformation_net.grid.aabb' has an empty or degenerate extent on axis ", a, " (", aabb_[size_t(a)], " to ",
                    aabb_[size_t(3 + a)], ")");
    }
    // Planes: grids.<scale>.<plane>, shape [1, C, reso[b], reso[a]] for the pair (a, b).
    for (int s = 0;; ++s) {
      const std::string p0 = "deformation_net.grid.grids." + std::to_string(s) + ".0";
      if (!sd.has(p0)) break;
      Scale sc;
      for (int p = 0; p < 6; ++p) {
        const std::string key = "deformation_net.grid.grids." + std::to_string(s) + "." + std::to_string(p);
        TorchTensor t = sd.get(key);
        if (t.shape.size() != 4 || t.shape[0] != 1 || t.shape[1] < 1 || t.shape[2] < 1 || t.shape[3] < 1)
          throw_error(pth, ": key '", key, "' has shape ", t.shape_text(), ", expected [1, C, H, W] with C, H, W >= 1");
        if (p > 0) checked(t, pth, "key '" + key + "'", {1, sc.planes[0].shape[1], -1, -1});
        sc.planes[p] = std::move(t);
      }
      feat_ += int(sc.planes[0].shape[1]);
      // Channel-last copies for the fast path: a corner's channels in one cache line.
      for (int p = 0; p < 6; ++p) {
        const TorchTensor& g = sc.planes[p];
        const size_t C = size_t(g.shape[1]), HW = size_t(g.shape[2]) * size_t(g.shape[3]);
        sc.hwc[p].resize(C * HW);
        for (size_t ch = 0; ch < C; ++ch)
          for (size_t q = 0; q < HW; ++q) sc.hwc[p][q * C + ch] = g.values[ch * HW + q];
      }
      scales_.push_back(std::move(sc));
    }
    if (scales_.empty()) throw_error(pth, ": key 'deformation_net.grid.grids.0.0' missing");
    trunk_ = sd.sequential("deformation_net.feature_out");
    if (trunk_.front().in != feat_)
      throw_error(pth, ": key 'deformation_net.feature_out.0.weight' has shape [", trunk_.front().out, ", ", trunk_.front().in, "], expected [",
                  trunk_.front().out, ", ", feat_, "]");
    const int W = trunk_.back().out;
    const char* heads[5] = {"pos_deform", "scales_deform", "rotations_deform", "opacity_deform", "shs_deform"};
    const int outs[5] = {3, 3, 4, 1, 48};
    for (int h = 0; h < 5; ++h) {
      heads_[h] = sd.sequential(std::string("deformation_net.") + heads[h]);
      check_head(heads_[h], W, outs[h], pth, std::string("deformation_net.") + heads[h]);
    }
    if (!no_dshs_ && canonical_.sh_degree != 3)
      throw_error(ply_path, ": SH degree ", canonical_.sh_degree, "; 4DGaussians' colour head deforms 16 coefficients (degree 3)");
    charge_network(tf, widest({&trunk_, &heads_[0], &heads_[1], &heads_[2], &heads_[3], &heads_[4]}), "4DGaussians");
    const bool on[5] = {!no_dx_, !no_ds_, !no_dr_, !no_do_, !no_dshs_};
    for (const Linear& l : trunk_) dense_.trunk.push_back(DenseLinear::whole(l));
    dense_.heads = DenseHeads(heads_, 5, on);
    // The spatial planes' product per Gaussian, once: a third of the lookups per frame, and
    // the ones that miss the cache (the planes are megabytes, the time lines kilobytes).
    const size_t n = canonical_.size();
    check_allocation(checked_mul(checked_mul(n, size_t(feat_), pth, "spatial features"), sizeof(float), pth, "spatial features"), pth,
                     "the spatial planes' product of every Gaussian");
    for (size_t k = 0; k < scales_.size(); ++k)
      if (scales_[k].planes[0].shape[1] > 64)
        throw_error(pth, ": key 'deformation_net.grid.grids.", k, ".0' has ", scales_[k].planes[0].shape[1], " channels; fillgs reads up to 64 per scale");
    spatial_.resize(n * size_t(feat_));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) spatial_product(i, &spatial_[i * size_t(feat_)]);
    });
    if (opt.model_frames < 1)
      throw_error(source, ": 4DGaussians does not store its frame count; give --model-frames F (its multi-view loaders time frame f at f/F)");
    set_times(*this, opt.model_frames, opt.model_time_range.empty() ? std::pair<double, double>{0.0, 1.0} : time_range(opt.model_time_range, source));
  }

  size_t size() const override { return canonical_.size(); }
  bool has_network() const override { return true; }

  double multiply_adds() const override { return dense_.multiply_adds(); }

  void evaluate(double model_time, const std::vector<uint32_t>& rows, ModelState& out) const override {
    const float t = float(model_time_checked(model_time, source));
    const std::vector<std::vector<float>> lines = time_lines(t);
    canonical_.rows_into(rows, out);
    struct Scratch {
      std::vector<float> x;
      DenseNet::Scratch net;
    };
    over_blocks(
        rows.size(), [&] { return Scratch{block_buffer(size_t(feat_)), dense_.scratch()}; },
        [&](size_t first, size_t count, Scratch& S) {
          for (size_t r = 0; r < count; ++r) features_at(rows[first + r], lines, &S.x[r]);
          dense_.run(S.x.data(), nullptr, S.net, [&](int h, const float* D) { add_head_rows(h, D, first, count, 1.0f, out); });
        });
  }

  ModelState at(double model_time) const override {
    ModelState s = canonical_;
    const size_t n = size();
    const float t = float(model_time_checked(model_time, source));
    HeadWeights w;
    const bool on[5] = {!no_dx_, !no_ds_, !no_dr_, !no_do_, !no_dshs_};
    for (int h = 0; h < 5; ++h) w.on[h] = on[h];
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kBlock), [&](const tbb::blocked_range<size_t>& r) {
      RowMat x(Eigen::Index(r.size()), feat_);
      std::vector<float> f;
      for (size_t i = r.begin(); i < r.end(); ++i) {
        features(canonical_.means[i], t, f);
        x.row(Eigen::Index(i - r.begin())) = Eigen::Map<const Eigen::RowVectorXf>(f.data(), feat_);
      }
      add_heads(heads_, run_trunk(trunk_, std::move(x)), r.begin(), w, s);
    });
    return s;
  }

 private:
  struct Scale {
    TorchTensor planes[6];
    std::vector<float> hwc[6];  ///< the planes channel-last, [H][W][C]
  };
  /// Bilinear plane sampling (align_corners, border padding), product over the six planes,
  /// concatenation over scales.
  void features(const Vec3f& p, float t, std::vector<float>& out) const {
    float q[4];
    grid_coordinates(p, q);
    q[3] = t;
    out.clear();
    for (const Scale& sc : scales_) {
      const size_t C = size_t(sc.planes[0].shape[1]);
      std::vector<float> f(C, 1.0f);
      for (int p = 0; p < 6; ++p) {
        const TorchTensor& g = sc.planes[p];
        const int H = int(g.shape[2]), W = int(g.shape[3]);
        int x0, x1, y0, y1;
        float wx, wy;
        pixel(q[kPairs[p][0]], W, x0, x1, wx);
        pixel(q[kPairs[p][1]], H, y0, y1, wy);
        const float w00 = (1 - wx) * (1 - wy), w01 = wx * (1 - wy), w10 = (1 - wx) * wy, w11 = wx * wy;
        for (size_t ch = 0; ch < C; ++ch) {
          const float* plane = &g.values[ch * size_t(H) * size_t(W)];
          const float v = w00 * plane[size_t(y0) * size_t(W) + size_t(x0)] + w01 * plane[size_t(y0) * size_t(W) + size_t(x1)] +
                          w10 * plane[size_t(y1) * size_t(W) + size_t(x0)] + w11 * plane[size_t(y1) * size_t(W) + size_t(x1)];
          f[ch] *= v;
        }
      }
      out.insert(out.end(), f.begin(), f.end());
    }
  }

  static constexpr int kPairs[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

  /// Border-padded pixel coordinate of a grid coordinate in [-1, 1] on a side of n pixels:
  /// the lower pixel and the weight of the upper one (a NaN lands on pixel 0).
  static void pixel(float q, int n, int& i0, int& i1, float& w) {
    float x = ((q + 1.0f) / 2.0f) * float(n - 1);
    x = x > 0.0f ? std::min(x, float(n - 1)) : 0.0f;
    i0 = int(std::floor(x));
    i1 = std::min(i0 + 1, n - 1);
    w = x - float(i0);
  }

  /// The time planes (x-t, y-t, z-t) of every scale interpolated at time t once: a line of
  /// [C][W] values each, indexed [scale * 3 + k] for the k-th time plane.
  std::vector<std::vector<float>> time_lines(float t) const {
    std::vector<std::vector<float>> lines;
    for (const Scale& sc : scales_)
      for (int p : {2, 4, 5}) {
        const TorchTensor& g = sc.planes[p];
        const size_t C = size_t(g.shape[1]), H = size_t(g.shape[2]), W = size_t(g.shape[3]);
        int y0, y1;
        float wy;
        pixel(t, int(H), y0, y1, wy);
        std::vector<float> line(C * W);  // [W][C]
        const float* hwc = sc.hwc[p].data();
        for (size_t x = 0; x < W; ++x)
          for (size_t ch = 0; ch < C; ++ch)
            line[x * C + ch] = (1 - wy) * hwc[(size_t(y0) * W + x) * C + ch] + wy * hwc[(size_t(y1) * W + x) * C + ch];
        lines.push_back(std::move(line));
      }
    return lines;
  }

  /// The grid coordinates in [-1, 1] of a mean (AABB-normalised).
  void grid_coordinates(const Vec3f& p, float* q) const {
    for (int a = 0; a < 3; ++a) q[a] = (p[a] - aabb_[size_t(a)]) * (2.0f / (aabb_[size_t(3 + a)] - aabb_[size_t(a)])) - 1.0f;
  }

  /// Gaussian i's product of the three spatial planes (x-y, x-z, y-z), per scale and channel:
  /// it does not depend on the time, so the fast path computes it once (spatial_).
  void spatial_product(size_t i, float* out) const {
    float q[3];
    grid_coordinates(canonical_.means[i], q);
    size_t f0 = 0;
    for (const Scale& sc : scales_) {
      const size_t C = size_t(sc.planes[0].shape[1]);
      for (size_t ch = 0; ch < C; ++ch) out[f0 + ch] = 1.0f;
      for (int p : {0, 1, 3}) {
        const TorchTensor& g = sc.planes[p];
        const int H = int(g.shape[2]), W = int(g.shape[3]);
        int x0, x1, y0, y1;
        float wx, wy;
        pixel(q[kPairs[p][0]], W, x0, x1, wx);
        pixel(q[kPairs[p][1]], H, y0, y1, wy);
        const float w00 = (1 - wx) * (1 - wy), w01 = wx * (1 - wy), w10 = (1 - wx) * wy, w11 = wx * wy;
        const float* hwc = sc.hwc[p].data();
        const float *c00 = hwc + (size_t(y0) * size_t(W) + size_t(x0)) * C, *c01 = hwc + (size_t(y0) * size_t(W) + size_t(x1)) * C;
        const float *c10 = hwc + (size_t(y1) * size_t(W) + size_t(x0)) * C, *c11 = hwc + (size_t(y1) * size_t(W) + size_t(x1)) * C;
        for (size_t ch = 0; ch < C; ++ch) out[f0 + ch] *= w00 * c00[ch] + w01 * c01[ch] + w10 * c10[ch] + w11 * c11[ch];
      }
      f0 += C;
    }
  }

  /// Gaussian i's features at the frame of `lines` (time_lines()): its spatial product times
  /// the time planes' lines, written feature-major (a stride of kRows) from `out`. The same
  /// products as features(), the spatial ones first: equal to a few float roundings.
  void features_at(size_t i, const std::vector<std::vector<float>>& lines, float* out) const {
    float q[3];
    grid_coordinates(canonical_.means[i], q);
    const float* spatial = &spatial_[i * size_t(feat_)];
    size_t f0 = 0;
    for (size_t s = 0; s < scales_.size(); ++s) {
      const Scale& sc = scales_[s];
      const size_t C = size_t(sc.planes[0].shape[1]);
      float f[64];
      std::copy_n(spatial + f0, C, f);
      for (int k = 0; k < 3; ++k) {
        const int p = k == 0 ? 2 : k == 1 ? 4 : 5;
        const int W = int(sc.planes[p].shape[3]);
        int x0, x1;
        float wx;
        pixel(q[kPairs[p][0]], W, x0, x1, wx);
        const float* line = lines[s * 3 + size_t(k)].data();
        const float *a = line + size_t(x0) * C, *b = line + size_t(x1) * C;
        for (size_t ch = 0; ch < C; ++ch) f[ch] *= (1 - wx) * a[ch] + wx * b[ch];
      }
      for (size_t ch = 0; ch < C; ++ch) out[(f0 + ch) * kRows] = f[ch];
      f0 += C;
    }
  }

  ModelState canonical_;
  std::vector<float> spatial_;  ///< [N][feat_]: spatial_product() of every Gaussian
  DenseNet dense_;
  std::vector<float> aabb_;
  std::vector<Scale> scales_;
  int feat_ = 0;
  std::vector<Linear> trunk_;
  std::vector<Linear> heads_[5];
  bool no_dx_ = false, no_ds_ = false, no_dr_ = false, no_do_ = true, no_dshs_ = true;
};

}  // namespace

const ModelFormat& row_fourdgaussians() {
  static const ModelFormat row{{"4dgaussians", {}, "4DGaussians: point_cloud.ply, deformation.pth (HexPlane) and cfg_args (its run folder or an iteration folder)", 51, {}},
      [](const FormatProbe& p) {
        const std::string header = deformation_run_header(p);
        return !header.empty() && header.find(" embedding_0\n") == std::string::npos;
      },
      [](const std::string& path, const SceneReadOptions& o) -> std::unique_ptr<TrainedModel> { return std::make_unique<FourDGaussians>(path, o); },
      true, nullptr};
  return row;
}

}  // namespace fillgs::model_io
