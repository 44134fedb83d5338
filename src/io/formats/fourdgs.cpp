// 4D Gaussian Splatting (Yang et al.): chkpnt*.pth (4D means, scales, two quaternions,
// time mean and scale, SH with time terms), sliced in time in closed form.
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
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

class FourDGS : public TrainedModel {
 public:
  FourDGS(const std::string& path, const SceneReadOptions& opt) {
    std::error_code ec;
    source = path;
    if (fs::is_directory(path, ec)) {  // the run folder: chkpnt_best.pth or the newest chkpnt<N>.pth
      std::string best;
      for (const auto& e : fs::directory_iterator(path, ec)) {
        const std::string n = e.path().filename().string();
        if (n.rfind("chkpnt", 0) == 0 && n.size() > 10 && n.compare(n.size() - 4, 4, ".pth") == 0 && (best.empty() || n > best)) best = n;
      }
      if (best.empty()) throw_error(path, ": no chkpnt*.pth inside");
      source = join_path(path, best);
    }
    const TorchFile tf(source);
    const auto& top = tf.items(tf.root());
    if (tf.kind(tf.root()) != PickleValues::Kind::Tuple || top.size() != 2 || tf.kind(top[0]) != PickleValues::Kind::Tuple)
      throw_error(source, ": not a 4DGS checkpoint (expected a tuple (model, iteration), found a ", tf.kind_name(tf.root()), ")");
    const auto& m = tf.items(top[0]);
    if (m.size() != 19)
      throw_error(source, ": model tuple has ", m.size(), " entries; a 4D (gaussian_dim 4) 4DGS checkpoint has 19");
    auto tensor = [&](size_t i, const char* name, std::vector<int64_t> shape) {
      const std::string what = "entry " + std::to_string(i) + " (" + name + ")";
      return checked(tf.tensor(m[i], what), source, what, shape);
    };
    auto degree = [&](size_t i, int max) {
      const char* name = i == 0 ? "active SH degree" : "active time SH degree";
      if (!tf.is_number(m[i])) throw_error(source, ": entry ", i, " (", name, ") is a ", tf.kind_name(m[i]), ", not a number");
      const double d = tf.number(m[i]);
      if (!(d >= 0 && d <= max) || d != std::floor(d)) throw_error(source, ": entry ", i, " (", name, ") ", d, " is not a whole number in [0, ", max, "]");
      return int(d);
    };
    deg_ = degree(0, 3);
    deg_t_ = degree(18, 2);
    rot_4d_ = tf.kind(m[16]) == PickleValues::Kind::Bool && tf.integer(m[16]) != 0;
    const TorchTensor xyz = tensor(1, "_xyz", {-1, 3});
    const int64_t N = xyz.shape[0];
    const TorchTensor dc = tensor(2, "_features_dc", {N, 1, 3});
    const TorchTensor rest = tensor(3, "_features_rest", {N, -1, 3});
    const TorchTensor scaling = tensor(4, "_scaling", {N, 3});
    const TorchTensor rotation = tensor(5, "_rotation", {N, 4});
    const TorchTensor opacity = tensor(6, "_opacity", {N, 1});
    const TorchTensor tmean = tensor(13, "_t", {N, 1});
    const TorchTensor tscale = tensor(14, "_scaling_t", {N, 1});
    if (rest.shape[1] > 47)  // time degree 2 at space degree 3: 48 channels, the most 4DGS stores
      throw_error(source, ": entry 3 (_features_rest) has ", rest.shape[1], " SH channels, more than the 47 of 4DGS's largest basis");
    channels_ = int(rest.shape[1]) + 1;
    if (rot_4d_) rot_r_ = tensor(15, "_rotation_r", {N, 4}).values;
    if (deg_ < 0 || deg_ > 3 || deg_t_ < 0 || deg_t_ > 2) throw_error(source, ": active SH degrees ", deg_, " / ", deg_t_, " out of range");
    if (deg_t_ == 0 && channels_ != 16 && channels_ != (deg_ + 1) * (deg_ + 1) && channels_ > 16)
      throw_error(source, ": ", channels_, " SH channels with time degree 0: the 4D SH basis (force_sh_3d off, eval_shfs_4d off) is not supported");
    if (channels_ < 16 * (deg_t_ + 1) && deg_t_ > 0)
      throw_error(source, ": ", channels_, " SH channels cannot hold time degree ", deg_t_, " (needs ", 16 * (deg_t_ + 1), ")");
    if (channels_ < (deg_ + 1) * (deg_ + 1)) throw_error(source, ": ", channels_, " SH channels cannot hold degree ", deg_);
    const size_t n = size_t(N);
    xyz_.resize(n);
    scale4_.resize(n);
    rot_.resize(n);
    opacity_ = opacity.values;
    sh_all_.resize(n * size_t(channels_) * 3);
    for (size_t i = 0; i < n; ++i) {
      for (int a = 0; a < 3; ++a) {
        xyz_[i][a] = xyz.values[i * 3 + size_t(a)];
        scale4_[i][a] = scaling.values[i * 3 + size_t(a)];
      }
      scale4_[i][3] = tscale.values[i];
      for (int a = 0; a < 4; ++a) rot_[i][a] = rotation.values[i * 4 + size_t(a)];
      for (int ch = 0; ch < 3; ++ch) sh_all_[i * size_t(channels_) * 3 + size_t(ch)] = dc.values[i * 3 + size_t(ch)];
      std::copy(rest.values.begin() + ptrdiff_t(i * size_t(channels_ - 1) * 3), rest.values.begin() + ptrdiff_t((i + 1) * size_t(channels_ - 1) * 3),
                sh_all_.begin() + ptrdiff_t(i * size_t(channels_) * 3 + 3));
    }
    tmean_ = tmean.values;
    if (opt.model_frames < 1 || opt.model_time_range.empty())
      throw_error(source, ": a 4DGS checkpoint stores neither its frame count nor its time range; give --model-frames F and --model-time-range T0:T1 "
                          "(its config's time_duration, e.g. 0:10 for N3V at 30 fps)");
    const auto range = time_range(opt.model_time_range, source);
    duration_ = range.second - range.first;
    set_times(*this, opt.model_frames, range);
    notes.push_back(std::string("4DGS ") + (rot_4d_ ? "4D rotations" : "axis-aligned time") + ", SH degree " + std::to_string(deg_) +
                    " with time degree " + std::to_string(deg_t_) + "; the 3D Gaussian at each time is the 4D one conditioned on it");
  }

  size_t size() const override { return xyz_.size(); }

  ModelState at(double model_time) const override {
    ModelState s;
    slice(model_time, nullptr, s);
    return s;
  }
  /// The closed form per Gaussian: only the rows asked for.
  void evaluate(double model_time, const std::vector<uint32_t>& rows, ModelState& out) const override { slice(model_time, &rows, out); }

  /// The temporal opacity exp(-(t - t_mean)^2 / (2 sigma_t)) over the covered times: 1 where
  /// t_mean lies among them, else its value at the nearer end; its least at the farther end.
  std::vector<float> opacity_variation() const override {
    std::vector<float> out(size());
    const double lo = std::min(time_first, time_last), hi = std::max(time_first, time_last);
    for (size_t i = 0; i < out.size(); ++i) {
      const double mu = tmean_[i], var = time_variance(i);
      auto factor = [&](double t) { return std::exp(-0.5 * (t - mu) * (t - mu) / var); };
      const double top = mu >= lo && mu <= hi ? 1.0 : std::max(factor(lo), factor(hi));
      out[i] = float(double(sigmoid(opacity_[i])) * (top - std::min(factor(lo), factor(hi))));
    }
    return out;
  }

 private:
  /// The 3D Gaussians at `model_time` of `rows` (every one when null), in that order.
  void slice(double model_time, const std::vector<uint32_t>* rows, ModelState& s) const {
    const size_t n = rows ? rows->size() : size();
    s = ModelState();
    s.sh_degree = 3;
    if (deg_t_ == 0 && channels_ == (deg_ + 1) * (deg_ + 1)) s.sh_degree = deg_;
    const size_t K = size_t((s.sh_degree + 1) * (s.sh_degree + 1));
    s.means.resize(n);
    s.log_scales.resize(n);
    s.rotations.resize(n);
    s.opacity_logits.resize(n);
    s.opacity_factor.resize(n);
    s.sh.assign(n * K * 3, 0.0f);
    const double tau = model_time_checked(model_time, source);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t j = r.begin(); j < r.end(); ++j) {
        const size_t i = rows ? size_t((*rows)[j]) : j;  // the Gaussian; j: its row in `s`
        s.opacity_logits[j] = opacity_[i];
        const double dt = tau - double(tmean_[i]);
        Eigen::Matrix3d cov;
        Eigen::Vector3d mean = xyz_[i].cast<double>();
        double sigma_t;
        if (rot_4d_) {
          const Eigen::Matrix4d R = rotation_4d(rot_[i].cast<double>(), Eigen::Map<const Vec4f>(&rot_r_[i * 4]).cast<double>());
          Eigen::Vector4d sc;
          for (int a = 0; a < 4; ++a) sc[a] = std::exp(double(scale4_[i][a]));
          const Eigen::Matrix4d L = R * sc.asDiagonal();
          const Eigen::Matrix4d S = L * L.transpose();
          const Eigen::Vector3d c12 = S.block<3, 1>(0, 3);
          sigma_t = S(3, 3);
          cov = S.block<3, 3>(0, 0) - c12 * c12.transpose() / sigma_t;
          mean += c12 / sigma_t * dt;
        } else {
          const Eigen::Matrix3d R = quat_to_matrix(Vec4d(rot_[i].cast<double>().normalized()));
          Eigen::Vector3d sc;
          for (int a = 0; a < 3; ++a) sc[a] = std::exp(double(scale4_[i][a]));
          cov = R * sc.cwiseAbs2().asDiagonal() * R.transpose();
          sigma_t = std::exp(double(scale4_[i][3]));  // its code uses exp(_scaling_t) as the variance
        }
        s.means[j] = mean.cast<float>();
        s.opacity_factor[j] = float(std::exp(-0.5 * dt * dt / sigma_t));
        // The conditional covariance as scales and a rotation (eigen-decomposition).
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(0.5 * (cov + cov.transpose()));
        Eigen::Matrix3d V = es.eigenvectors();
        if (V.determinant() < 0) V.col(0) = -V.col(0);
        for (int a = 0; a < 3; ++a) s.log_scales[j][a] = float(0.5 * std::log(std::max(es.eigenvalues()[a], 1e-30)));
        s.rotations[j] = matrix_to_quat(V).cast<float>();
        // SH at this time: band b of the time terms weighted by cos(2 pi b (t_mean - t) / duration).
        const float* src = &sh_all_[i * size_t(channels_) * 3];
        float* dst = &s.sh[j * K * 3];
        const size_t active = size_t((deg_ + 1) * (deg_ + 1));
        for (size_t k = 0; k < std::min(K, active); ++k)
          for (int ch = 0; ch < 3; ++ch) {
            double v = src[k * 3 + size_t(ch)];
            for (int b = 1; b <= deg_t_; ++b)
              v += std::cos(2.0 * kPi * b * (-dt) / duration_) * double(src[(size_t(16 * b) + k) * 3 + size_t(ch)]);
            dst[k * 3 + size_t(ch)] = float(v);
          }
      }
    });
  }

 private:
  /// Gaussian i's variance in time (model time squared), as slice() conditions on it.
  double time_variance(size_t i) const {
    if (!rot_4d_) return std::exp(double(scale4_[i][3]));  // its code uses exp(_scaling_t) as the variance
    const Eigen::Matrix4d R = rotation_4d(rot_[i].cast<double>(), Eigen::Map<const Vec4f>(&rot_r_[i * 4]).cast<double>());
    double v = 0;
    for (int a = 0; a < 4; ++a) v += R(3, a) * R(3, a) * std::exp(2.0 * double(scale4_[i][a]));
    return v;  // (R diag(s)^2 R^T)(3, 3)
  }

  static Eigen::Matrix4d rotation_4d(Eigen::Vector4d l, Eigen::Vector4d r) {
    l /= l.norm();
    r /= r.norm();
    const double a = l[0], b = l[1], c = l[2], d = l[3];
    const double p = r[0], q = r[1], rr = r[2], s = r[3];
    Eigen::Matrix4d Ml, Mr;
    Ml << a, -b, -c, -d, b, a, -d, c, c, d, a, -b, d, -c, b, a;
    Mr << p, q, rr, s, -q, p, -s, rr, -rr, s, p, -q, -s, -rr, q, p;
    const Eigen::Matrix4d A = Ml * Mr;
    Eigen::Matrix4d F;  // A.flip(1, 2): rows and columns reversed
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) F(i, j) = A(3 - i, 3 - j);
    return F;
  }

  std::vector<Vec3f> xyz_;
  std::vector<Vec4f> scale4_, rot_;
  std::vector<float> rot_r_, opacity_, tmean_, sh_all_;
  int deg_ = 0, deg_t_ = 0, channels_ = 1;
  bool rot_4d_ = false;
  double duration_ = 1.0;
};

}  // namespace

const ModelFormat& row_fourdgs() {
  static const ModelFormat row{{"4dgs", {}, "4D Gaussian Splatting (Yang et al.): a chkpnt*.pth, or the folder holding them (the newest)", 40, {}},
      [](const FormatProbe& p) {
        auto checkpoint = [](const std::string& n) { return n.rfind("chkpnt", 0) == 0 && n.size() > 10 && n.compare(n.size() - 4, 4, ".pth") == 0; };
        if (!p.directory()) return checkpoint(p.filename());
        std::error_code ec;
        for (const auto& e : fs::directory_iterator(p.path(), ec))
          if (checkpoint(e.path().filename().string())) return true;
        return false;
      },
      [](const std::string& path, const SceneReadOptions& o) -> std::unique_ptr<TrainedModel> { return std::make_unique<FourDGS>(path, o); },
      true, nullptr};
  return row;
}

}  // namespace fillgs::model_io
