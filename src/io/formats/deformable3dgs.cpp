// Deformable 3D Gaussians: point_cloud/iteration_N/point_cloud.ply, deform/iteration_N/
// deform.pth (an MLP on positionally encoded position and time) and cfg_args.
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

class Deformable3dgs : public TrainedModel {
 public:
  Deformable3dgs(const std::string& path, const SceneReadOptions& opt) {
    std::error_code ec;
    fs::path run(path);
    if (!fs::is_directory(run, ec)) run = run.parent_path();
    while (!run.empty() && !fs::is_directory(run / "deform", ec) && run.has_parent_path() && run != run.parent_path()) run = run.parent_path();
    if (!fs::is_directory(run / "deform", ec)) throw_error(path, ": no deform/ folder (Deformable 3D Gaussians saves deform/iteration_N/deform.pth)");
    source = run.string();
    const std::string cfg_path = (run / "cfg_args").string();
    const nlohmann::json c = read_cfg_args(cfg_path);
    if (c.empty()) notes.push_back("no cfg_args beside the model: Deformable 3D Gaussians' defaults used");
    if (cfg<bool>(c, "is_6dof", false, cfg_path)) throw_error(cfg_path, ": is_6dof=True (SE(3) warps) is not supported");
    blender_ = cfg<bool>(c, "is_blender", false, cfg_path);
    const RunFolder gaussians = run_folder(source, "point_cloud.ply");
    // deform/iteration_N: the same iteration as the point cloud.
    const std::string pth = (run / "deform" / ("iteration_" + std::to_string(gaussians.iteration)) / "deform.pth").string();
    const std::string ply_path = join_path(gaussians.iteration_dir, "point_cloud.ply");
    canonical_ = read_vertex_state(read_ply(ply_path).element("vertex"), notes);
    const TorchFile tf(pth);
    const StateDict sd(tf, tf.root(), "deform.pth");
    for (int i = 0;; ++i) {
      const std::string k = "linear." + std::to_string(i) + ".weight";
      if (!sd.has(k)) break;
      Linear l;
      const TorchTensor w = sd.get(k);
      if (w.shape.size() != 2) throw_error(pth, ": key '", k, "' has shape ", w.shape_text(), ", expected [out, in]");
      l.out = int(w.shape[0]);
      l.in = int(w.shape[1]);
      l.w = Eigen::Map<const RowMat>(w.values.data(), l.out, l.in);
      const TorchTensor b = sd.get("linear." + std::to_string(i) + ".bias", {l.out});
      l.b = Eigen::Map<const Eigen::RowVectorXf>(b.values.data(), l.out);
      layers_.push_back(std::move(l));
    }
    if (layers_.size() < 3)
      throw_error(pth, ": ", layers_.size(), " 'linear.*' layers; fillgs reads 3 or more (the skip joins after the middle one, before the last)");
    skip_ = int(layers_.size()) / 2;
    t_freqs_ = blender_ ? 6 : 10;
    const int x_in = 3 * (1 + 2 * 10), t_in = 1 + 2 * t_freqs_;
    int t_out = t_in;
    if (blender_) {
      timenet_ = sd.sequential("timenet");
      if (timenet_.front().in != t_in) throw_error(pth, ": key 'timenet.0.weight' takes ", timenet_.front().in, " inputs, expected ", t_in);
      t_out = timenet_.back().out;
    }
    const int W = layers_.front().out;
    for (size_t i = 0; i < layers_.size(); ++i) {
      const int in = i == 0 ? x_in + t_out : int(i) - 1 == skip_ ? W + x_in + t_out : W;
      if (layers_[i].in != in || layers_[i].out != W)
        throw_error(pth, ": key 'linear.", i, ".weight' has shape [", layers_[i].out, ", ", layers_[i].in, "], expected [", W, ", ", in, "]");
    }
    const char* heads[3] = {"gaussian_warp", "gaussian_rotation", "gaussian_scaling"};
    const int outs[3] = {3, 4, 3};
    for (int h = 0; h < 3; ++h) {
      const TorchTensor w = sd.get(std::string(heads[h]) + ".weight", {outs[h], W});
      const TorchTensor b = sd.get(std::string(heads[h]) + ".bias", {outs[h]});
      heads_[h].in = W;
      heads_[h].out = outs[h];
      heads_[h].w = Eigen::Map<const RowMat>(w.values.data(), outs[h], W);
      heads_[h].b = Eigen::Map<const Eigen::RowVectorXf>(b.values.data(), outs[h]);
    }
    charge_network(tf, size_t(W + x_in + t_out), "Deformable 3D Gaussians");
    for (size_t i = 0; i < layers_.size(); ++i) {
      if (i == 0) dense_.trunk.push_back(DenseLinear::from(layers_[i], {{0, x_in}}, {x_in, x_in + t_out}));
      else if (int(i) - 1 == skip_) dense_.trunk.push_back(DenseLinear::from(layers_[i], {{0, x_in}, {x_in + t_out, x_in + t_out + W}}, {x_in, x_in + t_out}));
      else dense_.trunk.push_back(DenseLinear::whole(layers_[i]));
    }
    const std::vector<Linear> one[3] = {{heads_[0]}, {heads_[1]}, {heads_[2]}};
    const bool on[3] = {true, true, true};
    dense_.heads = DenseHeads(one, 3, on);
    if (opt.model_frames < 1)
      throw_error(source, ": Deformable 3D Gaussians does not store its frame count; give --model-frames F (its loaders time frame f at f/(F-1))");
    if (opt.model_time_range.empty()) {
      frames = opt.model_frames;
      time_first = 0.0;
      time_last = 1.0;
    } else {
      set_times(*this, opt.model_frames, time_range(opt.model_time_range, source));
    }
    notes.push_back("Deformable 3D Gaussians at iteration " + std::to_string(gaussians.iteration) + ": scales are its activated scales plus the "
                    "network's delta (a negative sum is used by its magnitude, as the covariance does)");
  }

  size_t size() const override { return canonical_.size(); }
  bool has_network() const override { return true; }

  double multiply_adds() const override { return dense_.multiply_adds(); }

  void evaluate(double model_time, const std::vector<uint32_t>& rows, ModelState& out) const override {
    const float t = float(model_time_checked(model_time, source));
    std::vector<float> te(size_t(1 + 2 * t_freqs_));
    encode(&t, 1, t_freqs_, te.data());
    if (blender_) {
      const RowMat tv = run_trunk(timenet_, Eigen::Map<const Eigen::RowVectorXf>(te.data(), Eigen::Index(te.size())));
      te.assign(tv.data(), tv.data() + tv.size());
    }
    std::vector<float> bias[2] = {dense_.trunk.front().bias_at(te.data()), dense_.trunk[size_t(skip_) + 1].bias_at(te.data())};
    canonical_.rows_into(rows, out);
    const size_t x_in = 3 * 21, W = size_t(dense_.trunk.front().out);
    struct Scratch {
      std::vector<float> xe;
      DenseNet::Scratch net;
    };
    over_blocks(
        rows.size(), [&] { return Scratch{block_buffer(x_in + W), dense_.scratch()}; },
        [&](size_t first, size_t count, Scratch& S) {
          float enc[3 * 21];
          for (size_t r = 0; r < count; ++r) {
            encode(canonical_.means[rows[first + r]].data(), 3, 10, enc);
            for (size_t f = 0; f < x_in; ++f) S.xe[f * kRows + r] = enc[f];
          }
          // Layer skip writes after the encoding in `xe`, so that the next layer reads both.
          const float* x = S.xe.data();
          for (size_t i = 0; i < dense_.trunk.size(); ++i) {
            float* y = int(i) == skip_ ? S.xe.data() + x_in * kRows : S.net.h[i % 2].data();
            const float* b = i == 0 ? bias[0].data() : int(i) - 1 == skip_ ? bias[1].data() : nullptr;
            dense_.trunk[i].run(int(i) - 1 == skip_ ? S.xe.data() : x, y, true, b);
            x = y;
          }
          const float* D[3] = {};
          dense_.heads.run(x, S.net.stack, S.net.a, S.net.b, [&](int h, const float* d) { D[h] = d; });
          for (size_t r = 0; r < count; ++r) {
            const size_t i = first + r;
            const uint32_t g = rows[i];
            const Vec4f q = normalize_quat(canonical_.rotations[g]);
            for (int a = 0; a < 3; ++a) {
              out.means[i][a] += D[0][size_t(a) * kRows + r];
              const float sc = std::exp(canonical_.log_scales[g][a]) + D[2][size_t(a) * kRows + r];
              out.log_scales[i][a] = std::log(std::max(std::fabs(sc), 1e-30f));
            }
            for (int a = 0; a < 4; ++a) out.rotations[i][a] = q[a] + D[1][size_t(a) * kRows + r];
          }
        });
  }

  ModelState at(double model_time) const override {
    ModelState s = canonical_;
    const size_t n = size();
    const float t = float(model_time_checked(model_time, source));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kBlock), [&](const tbb::blocked_range<size_t>& r) {
      const Eigen::Index B = Eigen::Index(r.size());
      const int x_in = 3 * 21;
      RowMat xe(B, x_in);
      for (Eigen::Index row = 0; row < B; ++row) encode(canonical_.means[r.begin() + size_t(row)].data(), 3, 10, xe.row(row).data());
      std::vector<float> te(size_t(1 + 2 * t_freqs_));
      encode(&t, 1, t_freqs_, te.data());
      RowMat tvec = Eigen::Map<const Eigen::RowVectorXf>(te.data(), Eigen::Index(te.size()));
      if (blender_) tvec = run_trunk(timenet_, tvec);  // Linear, ReLU, Linear
      RowMat te_rows(B, tvec.cols());
      te_rows.rowwise() = tvec.row(0);
      RowMat h(B, x_in + tvec.cols());
      h << xe, te_rows;
      for (size_t i = 0; i < layers_.size(); ++i) {
        h = layers_[i].apply(h).cwiseMax(0.0f);
        if (int(i) == skip_) {
          RowMat cat(B, x_in + tvec.cols() + h.cols());
          cat << xe, te_rows, h;
          h = std::move(cat);
        }
      }
      const RowMat dx = heads_[0].apply(h), dr = heads_[1].apply(h), ds = heads_[2].apply(h);
      for (Eigen::Index row = 0; row < B; ++row) {
        const size_t i = r.begin() + size_t(row);
        const Vec4f q = normalize_quat(canonical_.rotations[i]);
        for (int a = 0; a < 3; ++a) {
          s.means[i][a] += dx(row, a);
          const float sc = std::exp(canonical_.log_scales[i][a]) + ds(row, a);
          s.log_scales[i][a] = std::log(std::max(std::fabs(sc), 1e-30f));
        }
        for (int a = 0; a < 4; ++a) s.rotations[i][a] = q[a] + dr(row, a);
      }
    });
    return s;
  }

 private:
  /// [x, sin(x), cos(x), sin(2x), cos(2x), ...] over `freqs` octaves, as its Embedder orders them.
  static void encode(const float* x, int d, int freqs, float* out) {
    int k = 0;
    for (int a = 0; a < d; ++a) out[k++] = x[a];
    for (int f = 0; f < freqs; ++f) {
      const float w = std::ldexp(1.0f, f);
      for (int a = 0; a < d; ++a) out[k++] = std::sin(x[a] * w);
      for (int a = 0; a < d; ++a) out[k++] = std::cos(x[a] * w);
    }
  }

  ModelState canonical_;
  std::vector<Linear> layers_, timenet_;
  Linear heads_[3];
  DenseNet dense_;  ///< its layers (the skip's inputs packed) and heads; run by evaluate()'s own loop
  int skip_ = 4, t_freqs_ = 10;
  bool blender_ = false;
};

}  // namespace

const ModelFormat& row_deformable3dgs() {
  static const ModelFormat row{{"deformable3dgs", {}, "Deformable 3D Gaussians: point_cloud/, deform/iteration_N/deform.pth and cfg_args (its run folder)", 30, {}},
      [](const FormatProbe& p) { return p.directory() && p.beside("deform", true); },
      [](const std::string& path, const SceneReadOptions& o) -> std::unique_ptr<TrainedModel> { return std::make_unique<Deformable3dgs>(path, o); },
      true, nullptr};
  return row;
}

}  // namespace fillgs::model_io
