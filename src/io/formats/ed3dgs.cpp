// E-D3DGS (the FillGS paper's backbone): point_cloud/iteration_N/point_cloud.ply with
// per-Gaussian embeddings (embedding_*), deformation.pth (temporal embeddings, per-camera
// time offsets, a coarse and a fine MLP) and cfg_args, evaluated as its renderer does.
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

class Ed3dgs : public TrainedModel {
 public:
  Ed3dgs(const std::string& path, const SceneReadOptions& opt) {
    const DeformationRun run = open_run(path, *this, "E-D3DGS");
    const RunFolder& rf = run.folder;
    const std::string &cfg_path = run.cfg_path, &ply_path = run.ply_path, &pth = run.pth;
    const nlohmann::json& c = run.cfg;
    const PlyData ply = read_ply(ply_path);
    const PlyElement& v = ply.element("vertex");
    canonical_ = read_vertex_state(v, notes);
    const std::vector<std::string> emb = v.indexed_properties("embedding_");
    if (emb.empty()) throw_error(ply_path, ": no 'embedding_*' properties: not an E-D3DGS point cloud");
    gdim_ = int(emb.size());
    embedding_.resize(v.count * emb.size());
    for (size_t d = 0; d < emb.size(); ++d) {
      const auto& col = v.finite_column(emb[d]);
      for (size_t i = 0; i < v.count; ++i) embedding_[i * emb.size() + d] = col[i];
    }
    const TorchFile tf(pth);
    const StateDict sd(tf, tf.root(), "deformation.pth");
    // Settings (cfg_args, E-D3DGS's ModelHiddenParams defaults otherwise).
    tdim_ = cfg<int>(c, "temporal_embedding_dim", 256, cfg_path);
    const int gdim_cfg = cfg<int>(c, "gaussian_embedding_dim", 32, cfg_path);
    if (gdim_cfg != gdim_)
      throw_error(ply_path, ": ", gdim_, " 'embedding_*' properties, cfg_args gaussian_embedding_dim is ", gdim_cfg);
    min_emb_ = cfg<int>(c, "min_embeddings", 30, cfg_path);
    max_emb_ = cfg<int>(c, "max_embeddings", 150, cfg_path);
    iteration_ = rf.iteration;
    if (opt.model_iteration >= 0) iteration_ = opt.model_iteration;
    c2f_iter_ = cfg<int>(c, "c2f_temporal_iter", 20000, cfg_path);
    deform_from_ = cfg<int>(c, "deform_from_iter", 0, cfg_path);
    use_anneal_ = cfg<bool>(c, "use_anneal", true, cfg_path);
    use_coarse_emb_ = cfg<bool>(c, "use_coarse_temporal_embedding", false, cfg_path);
    no_c2f_ = cfg<bool>(c, "no_c2f_temporal_embedding", false, cfg_path);
    no_coarse_ = cfg<bool>(c, "no_coarse_deform", false, cfg_path);
    no_fine_ = cfg<bool>(c, "no_fine_deform", false, cfg_path);
    no_ds_ = cfg<bool>(c, "no_ds", false, cfg_path);
    no_dr_ = cfg<bool>(c, "no_dr", false, cfg_path);
    no_do_ = cfg<bool>(c, "no_do", true, cfg_path);
    no_dc_ = cfg<bool>(c, "no_dc", false, cfg_path);
    const int total_frames = cfg<int>(c, "total_num_frames", 300, cfg_path);
    if (min_emb_ < 1 || max_emb_ < min_emb_ || c2f_iter_ < 1 || tdim_ < 2)
      throw_error(cfg_path, ": embedding settings out of range (min_embeddings ", min_emb_, ", max_embeddings ", max_emb_,
                  ", c2f_temporal_iter ", c2f_iter_, ")");
    weight_ = sd.get("weight", {max_emb_, tdim_}).values;
    const TorchTensor off = sd.get("offsets", {-1, 1});
    for (size_t i = 0; i < off.values.size(); ++i)
      if (!(std::fabs(off.values[i]) <= kMaxModelTime))
        throw_error(pth, ": key 'offsets' element ", i, " (", off.values[i], ") is no time offset within +-", kMaxModelTime);
    // At a view that is no training camera, E-D3DGS's renderer uses the mean of the non-zero offsets.
    if (opt.model_camera >= 0) {
      if (size_t(opt.model_camera) >= off.values.size())
        throw_error(pth, ": --model-camera ", opt.model_camera, " but key 'offsets' holds ", off.values.size(), " cameras");
      offset_ = off.values[size_t(opt.model_camera)];
    } else {
      double sum = 0;
      int count = 0;
      for (float o : off.values)
        if (o != 0.0f) {
          sum += o;
          ++count;
        }
      offset_ = count ? float(sum / count) : 0.0f;
      if (count) notes.push_back("E-D3DGS per-camera time offsets: the mean of the " + std::to_string(count) +
                                 " non-zero ones is used at every view, as its renderer does at test views");
    }
    for (int pass = 0; pass < 2; ++pass) {
      const std::string sfx = pass == 0 ? "_c" : "_f";
      Net& n = net_[pass];
      n.trunk = sd.sequential("feature_out" + sfx);
      if (n.trunk.front().in != tdim_ + gdim_)
        throw_error(pth, ": key 'feature_out", sfx, ".0.weight' has shape [", n.trunk.front().out, ", ", n.trunk.front().in, "], expected [",
                    n.trunk.front().out, ", ", tdim_ + gdim_, "]");
      const int W = n.trunk.back().out;
      const char* heads[5] = {"pos_deform", "scales_deform", "rotations_deform", "opacity_deform", "rgb_deform"};
      const int outs[5] = {3, 3, 4, 1, 48};
      for (int h = 0; h < 5; ++h) {
        n.heads[h] = sd.sequential(std::string(heads[h]) + sfx);
        check_head(n.heads[h], W, outs[h], pth, std::string(heads[h]) + sfx);
      }
    }
    if (!no_dc_ && canonical_.sh_degree != 3)
      throw_error(ply_path, ": SH degree ", canonical_.sh_degree, "; E-D3DGS's colour head deforms 16 coefficients (degree 3)");
    const bool on[5] = {true, !no_ds_, !no_dr_, !no_do_, !no_dc_};
    for (int pass = 0; pass < 2; ++pass) {
      DenseNet& d = dense_[pass];
      // The first layer's temporal-embedding columns depend on the time alone: per frame.
      d.trunk.push_back(DenseLinear::from(net_[pass].trunk.front(), {{tdim_, tdim_ + gdim_}}, {0, tdim_}));
      for (size_t i = 1; i < net_[pass].trunk.size(); ++i) d.trunk.push_back(DenseLinear::whole(net_[pass].trunk[i]));
      d.heads = DenseHeads(net_[pass].heads, 5, on);
    }
    // The coarse and fine passes run one after the other on a block: the wider one's memory.
    size_t width = 0;
    for (const Net& n : net_) width = std::max(width, widest({&n.trunk, &n.heads[0], &n.heads[1], &n.heads[2], &n.heads[3], &n.heads[4]}));
    charge_network(tf, width, "E-D3DGS");
    set_times(*this, opt.model_frames > 0 ? opt.model_frames : total_frames, {0.0, 1.0});
    if (!opt.model_time_range.empty()) set_times(*this, frames, time_range(opt.model_time_range, source));
    notes.push_back("E-D3DGS at iteration " + std::to_string(iteration_) + ": temporal embeddings " +
                    std::to_string(coarse_count()) + " (coarse) and " + std::to_string(fine_count()) + " (fine) of " + std::to_string(max_emb_));
  }

  size_t size() const override { return canonical_.size(); }
  bool has_network() const override { return true; }

  double multiply_adds() const override {
    double m = 0;
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 0 ? no_coarse_ : no_fine_) continue;
      m += dense_[pass].multiply_adds();
    }
    return m;
  }

  void evaluate(double model_time, const std::vector<uint32_t>& rows, ModelState& out) const override {
    const float t = float(model_time_checked(model_time, source)) + offset_;
    std::vector<float> emb[2];
    temporal_embedding(t, coarse_count(), emb[0]);
    temporal_embedding(t, fine_count(), emb[1]);
    float k[5];
    head_coefficients(k);
    std::vector<float> bias0[2];
    for (int pass = 0; pass < 2; ++pass) bias0[pass] = dense_[pass].trunk.front().bias_at(emb[pass].data());
    canonical_.rows_into(rows, out);
    struct Scratch {
      std::vector<float> x;
      DenseNet::Scratch net;  // both passes', in turn
    };
    over_blocks(
        rows.size(), [&] { return Scratch{block_buffer(size_t(gdim_)), DenseNet::scratch_for({&dense_[0], &dense_[1]})}; },
        [&](size_t first, size_t count, Scratch& S) {
          const size_t G = size_t(gdim_);
          for (size_t r = 0; r < count; ++r) {
            const float* e = &embedding_[size_t(rows[first + r]) * G];
            for (size_t d = 0; d < G; ++d) S.x[d * kRows + r] = e[d];
          }
          for (int pass = 0; pass < 2; ++pass)
            if (!(pass == 0 ? no_coarse_ : no_fine_))
              dense_[pass].run(S.x.data(), bias0[pass].data(), S.net,
                               [&](int h, const float* D) { add_head_rows(h, D, first, count, k[h], out); });
        });
  }

  ModelState at(double model_time) const override {
    // Added in float32, as its code adds them; both sides lie within +-1e6 (the offset
    // checked when read), so the sum is finite and within +-2e6.
    const float t = float(model_time_checked(model_time, source)) + offset_;
    std::vector<float> emb_c, emb_f;
    temporal_embedding(t, coarse_count(), emb_c);
    temporal_embedding(t, fine_count(), emb_f);
    ModelState s = canonical_;
    const size_t n = size();
    HeadWeights w;
    float k[5];
    head_coefficients(k);
    const bool on[5] = {true, !no_ds_, !no_dr_, !no_do_, !no_dc_};
    for (int h = 0; h < 5; ++h) w.k[h] = k[h], w.on[h] = on[h];
    // The hidden state depends on the time and the Gaussian's embedding only: one matrix
    // product per block of Gaussians and pass.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kBlock), [&](const tbb::blocked_range<size_t>& r) {
      const Eigen::Index B = Eigen::Index(r.size());
      for (int pass = 0; pass < 2; ++pass) {
        if (pass == 0 ? no_coarse_ : no_fine_) continue;
        const std::vector<float>& emb = pass == 0 ? emb_c : emb_f;
        RowMat x(B, tdim_ + gdim_);
        x.leftCols(tdim_).rowwise() = Eigen::Map<const Eigen::RowVectorXf>(emb.data(), tdim_);
        x.rightCols(gdim_) = Eigen::Map<const RowMat>(&embedding_[r.begin() * size_t(gdim_)], B, gdim_);
        add_heads(net_[pass].heads, run_trunk(net_[pass].trunk, std::move(x)), r.begin(), w, s);
      }
    });
    return s;
  }

 private:
  struct Net {
    std::vector<Linear> trunk;
    std::vector<Linear> heads[5];
  };
  /// The heads' coefficients at the model's iteration: its annealing of the deformation.
  void head_coefficients(float (&k)[5]) const {
    const float it = float(iteration_);
    const float coef = use_anneal_ ? std::clamp(it / 1000.0f, 0.0f, 1.0f) : 1.0f;
    const float coef_late = use_anneal_ ? std::clamp((it - float(deform_from_)) / 1000.0f, 0.0f, 1.0f) : 1.0f;
    const float v[5] = {coef, coef * coef_late, coef, coef * coef_late, coef_late};
    std::copy(v, v + 5, k);
  }
  static int lininterp(int iter, int from, int to, int until) {
    return int(double(from) + double(to - from) * double(std::min(std::max(iter, 0), until)) / double(until));
  }
  int coarse_count() const {
    if (use_coarse_emb_) return min_emb_;
    return no_c2f_ ? max_emb_ : lininterp(iteration_, min_emb_, max_emb_, c2f_iter_);
  }
  int fine_count() const { return no_c2f_ ? max_emb_ : lininterp(iteration_, min_emb_, max_emb_, c2f_iter_); }

  /// The embedding table resized to `rows` rows (bilinear, align_corners) and sampled at
  /// row t (rows - 1) with reflection at the ends, as F.interpolate and F.grid_sample do.
  void temporal_embedding(float t, int rows, std::vector<float>& out) const {
    const int D = tdim_;
    std::vector<float> resized(size_t(rows) * size_t(D));
    const float scale = rows > 1 ? float(max_emb_ - 1) / float(rows - 1) : 0.0f;
    for (int i = 0; i < rows; ++i) {
      const float src = scale * float(i);
      const int i0 = std::min(int(src), max_emb_ - 1);
      const int i1 = i0 + (i0 < max_emb_ - 1 ? 1 : 0);
      const float l1 = src - float(i0), l0 = 1.0f - l1;
      for (int d = 0; d < D; ++d)
        resized[size_t(i) * size_t(D) + size_t(d)] = l0 * weight_[size_t(i0) * size_t(D) + size_t(d)] + l1 * weight_[size_t(i1) * size_t(D) + size_t(d)];
    }
    // grid y = (t - 0.5) * 2, unnormalised with align_corners: ((y + 1) / 2) (rows - 1).
    const float gy = (t - 0.5f) * 2.0f;
    float y = ((gy + 1.0f) / 2.0f) * float(rows - 1);
    if (rows > 1) {  // reflect about 0 and rows - 1, then clip
      // |t| <= 2e6 keeps y finite; the parity of the reflections is taken in float, so no
      // coordinate, however large, becomes an integer before it is inside [0, rows - 1].
      const float span = float(rows - 1);
      y = std::fabs(y);
      const float extra = std::fmod(y, span);
      const float flips = std::floor(y / span);
      y = std::fmod(flips, 2.0f) == 0.0f ? extra : span - extra;
      y = y > 0.0f ? std::min(y, span) : 0.0f;  // NaN cannot reach here; if it did, row 0
    } else {
      y = 0.0f;
    }
    const int y0 = int(std::floor(y));
    const int y1 = std::min(y0 + 1, rows - 1);
    const float w1 = y - float(y0), w0 = 1.0f - w1;
    out.resize(size_t(D));
    for (int d = 0; d < D; ++d)
      out[size_t(d)] = w0 * resized[size_t(y0) * size_t(D) + size_t(d)] + w1 * resized[size_t(y1) * size_t(D) + size_t(d)];
  }

  ModelState canonical_;
  std::vector<float> embedding_, weight_;
  int gdim_ = 0, tdim_ = 256, min_emb_ = 30, max_emb_ = 150, iteration_ = 0, c2f_iter_ = 20000, deform_from_ = 0;
  bool use_anneal_ = true, use_coarse_emb_ = false, no_c2f_ = false, no_coarse_ = false, no_fine_ = false;
  bool no_ds_ = false, no_dr_ = false, no_do_ = true, no_dc_ = false;
  float offset_ = 0.0f;
  Net net_[2];
  DenseNet dense_[2];
};

}  // namespace

const ModelFormat& row_ed3dgs() {
  static const ModelFormat row{{"e-d3dgs", {}, "E-D3DGS: point_cloud.ply with embedding_*, deformation.pth and cfg_args (its run folder or an iteration folder)", 50, {}},
      [](const FormatProbe& p) { return deformation_run_header(p).find(" embedding_0\n") != std::string::npos; },
      [](const std::string& path, const SceneReadOptions& o) -> std::unique_ptr<TrainedModel> { return std::make_unique<Ed3dgs>(path, o); },
      true, nullptr};
  return row;
}

}  // namespace fillgs::model_io
