// Trainer checkpoints (train.hpp, Trainer::save_checkpoint and Trainer::resume).
#include "fillgs/train/train.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <sstream>
#include <utility>

#include "fillgs/base/error.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/io/video.hpp"

namespace fs = std::filesystem;

namespace fillgs {

// ---------------------------------------------------------------------------------
// Checkpoints: a small binary file, written atomically.

namespace {
constexpr char kMagic[8] = {'F', 'I', 'L', 'L', 'G', 'S', 'C', 'K'};
constexpr uint32_t kVersion = 5;  // 2: keyed-opacity flag; 3: Gaussians on changing pixels; 4: the dataset's fingerprint; 5: colour keys

struct Writer {
  std::string bytes;
  template <typename T>
  void pod(const T& v) {
    bytes.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <typename T>
  void vec(const std::vector<T>& v) {
    pod(uint64_t(v.size()));
    bytes.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
};
struct Reader {
  const std::string& bytes;
  std::string path;
  size_t at = 0;
  template <typename T>
  T pod() {
    if (at + sizeof(T) > bytes.size()) throw_error(path, ": checkpoint is truncated");
    T v;
    std::memcpy(&v, bytes.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  template <typename T>
  std::vector<T> vec() {
    const uint64_t n = pod<uint64_t>();
    if (n > (bytes.size() - at) / sizeof(T)) throw_error(path, ": checkpoint is truncated");
    std::vector<T> v(n);
    if (n) std::memcpy(v.data(), bytes.data() + at, n * sizeof(T));  // an empty vector's data() may be null
    at += n * sizeof(T);
    return v;
  }
};

void write_params(Writer& w, const ModelParams<float>& p) {
  w.pod(int32_t(p.sh_degree));
  w.pod(int32_t(p.key_count));
  w.pod(p.first_key_time);
  w.pod(p.key_spacing);
  w.pod(uint8_t(p.keyed_opacity));
  w.vec(p.dynamic_ids);
  for (const std::vector<float>* a : p.arrays()) w.vec(*a);
}

ModelParams<float> read_params(Reader& r) {
  ModelParams<float> p;
  p.sh_degree = r.pod<int32_t>();
  p.key_count = r.pod<int32_t>();
  p.first_key_time = r.pod<double>();
  p.key_spacing = r.pod<double>();
  p.keyed_opacity = r.pod<uint8_t>() != 0;
  p.dynamic_ids = r.vec<uint32_t>();
  for (std::vector<float>* a : p.arrays()) *a = r.vec<float>();
  // Every shape is checked before anything indexes the arrays (the file's word is not taken).
  const size_t n = p.size(), m = p.dynamic_ids.size();
  if (p.sh_degree < 0 || p.sh_degree > 3) throw_error(r.path, ": checkpoint SH degree ", p.sh_degree, " is not 0..3");
  if (p.key_count < 0 || p.key_count > 1000000 || (m > 0 && p.key_count < 1))
    throw_error(r.path, ": checkpoint key count ", p.key_count, " is not 0..1000000 (at least 1 with moving Gaussians)");
  if (!std::isfinite(p.first_key_time) || !(p.key_spacing > 0) || !std::isfinite(p.key_spacing))
    throw_error(r.path, ": checkpoint key layout (first ", p.first_key_time, ", spacing ", p.key_spacing, ") is not finite and positive");
  const size_t K = size_t(p.key_count);
  auto shape = [&](const std::vector<float>& a, size_t want, const char* what) {
    if (a.size() != want) throw_error(r.path, ": checkpoint array '", what, "' has ", a.size(), " values, the model needs ", want);
  };
  shape(p.means, 3 * n, "means");
  shape(p.log_scales, 3 * n, "log_scales");
  shape(p.rotations, 4 * n, "rotations");
  shape(p.sh, n * size_t(p.sh_count()) * 3, "sh");
  shape(p.key_positions, m * K * 3, "key_positions");
  shape(p.key_rotations, m * K * 4, "key_rotations");
  if (!p.key_log_scales.empty()) shape(p.key_log_scales, m * K * 3, "key_log_scales");
  if (p.keyed_opacity || !p.key_opacity_logits.empty()) shape(p.key_opacity_logits, m * K, "key_opacity_logits");
  if (!p.key_sh.empty()) shape(p.key_sh, m * K * size_t(p.sh_count()) * 3, "key_sh");
  for (size_t i = 0; i < m; ++i)
    if (p.dynamic_ids[i] >= n || (i > 0 && p.dynamic_ids[i] <= p.dynamic_ids[i - 1]))
      throw_error(r.path, ": checkpoint moving Gaussian ", i, " has id ", p.dynamic_ids[i], " (ids must ascend below ", n, ")");
  for (const std::vector<float>* a : p.arrays())
    for (float v : *a)
      if (!std::isfinite(v)) throw_error(r.path, ": checkpoint holds a non-finite parameter");
  return p;
}
}  // namespace

namespace {

/// What a checkpoint was trained on, as one number: every view's rig camera, frame, image
/// size and pose (to 1e-6). A checkpoint resumes only on the dataset it was made from.
uint64_t dataset_fingerprint(const Dataset& data) {
  uint64_t h = 1469598103934665603ull;  // FNV-1a
  auto mix = [&](const void* p, size_t n) {
    for (size_t i = 0; i < n; ++i) h = (h ^ static_cast<const unsigned char*>(p)[i]) * 1099511628211ull;
  };
  for (const TrainView& v : data.views()) {
    mix(v.rig.data(), v.rig.size());
    const int64_t ints[3] = {v.frame, v.camera.width, v.camera.height};
    mix(ints, sizeof ints);
    for (int i = 0; i < 3; ++i) {
      const int64_t row[4] = {std::llround(v.camera.R(i, 0) * 1e6), std::llround(v.camera.R(i, 1) * 1e6), std::llround(v.camera.R(i, 2) * 1e6),
                              std::llround(v.camera.t[i] * 1e6)};
      mix(row, sizeof row);
    }
  }
  return h;
}

}  // namespace

void Trainer::save_checkpoint(const std::string& path) const {
  Writer w;
  w.bytes.append(kMagic, 8);
  w.pod(kVersion);
  w.pod(int32_t(iteration_));
  w.pod(uint8_t(opacity_was_reset_));
  w.pod(uint64_t(data_->views().size()));
  w.pod(options_.seed);
  w.pod(dataset_fingerprint(*data_));
  write_params(w, params_);
  write_params(w, adam_m_);
  write_params(w, adam_v_);
  w.vec(grad_accum_);
  w.vec(max_radii_);
  w.vec(denom_);
  w.vec(bin_grad_);
  w.vec(bin_count_);
  w.vec(loss_history_);
  w.vec(on_change_);
  w.pod(status_.loss);
  w.pod(status_.psnr);
  // Colour corrections (a trailing section; checkpoints without it restart at identity).
  std::vector<float> colour;
  for (size_t r = 0; r < colour_.size(); ++r) {
    for (int k = 0; k < 3; ++k) colour.push_back(colour_[r].gain[k]);
    for (int k = 0; k < 3; ++k) colour.push_back(colour_[r].offset[k]);
    colour.insert(colour.end(), colour_m_[r].begin(), colour_m_[r].end());
    colour.insert(colour.end(), colour_v_[r].begin(), colour_v_[r].end());
    colour.push_back(float(colour_steps_[r]));
  }
  w.vec(colour);
  write_file_atomically(path, w.bytes);
}

Trainer Trainer::resume(const Dataset& data, const std::string& path, const TrainOptions& options) {
  const std::string bytes = read_file(path);
  Reader r{bytes, path};
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kMagic, 8) != 0) throw_error(path, ": not a fillgs checkpoint");
  r.at = 8;
  if (const uint32_t version = r.pod<uint32_t>(); version != kVersion)
    throw_error(path, ": checkpoint version ", version, ", this fillgs reads version ", kVersion, " (made by another fillgs; train again)");
  const int it = r.pod<int32_t>();
  const bool was_reset = r.pod<uint8_t>() != 0;
  const uint64_t views = r.pod<uint64_t>();
  if (views != data.views().size())
    throw_error(path, ": checkpoint was trained on ", views, " views, this dataset has ", data.views().size());
  if (r.pod<uint64_t>() != options.seed) throw_error(path, ": checkpoint was trained with another seed");
  if (r.pod<uint64_t>() != dataset_fingerprint(data))
    throw_error(path, ": checkpoint was trained on other views (another scene, other cameras, frames or image sizes)");
  ModelParams<float> p = read_params(r);
  Trainer t(data, p, options);
  t.params_ = std::move(p);  // as saved: the constructor's conversions (keys for every Gaussian) do not apply
  t.adam_m_ = read_params(r);
  t.adam_v_ = read_params(r);
  t.iteration_ = it;
  t.opacity_was_reset_ = was_reset;
  t.grad_accum_ = r.vec<float>();
  t.max_radii_ = r.vec<float>();
  t.denom_ = r.vec<uint32_t>();
  t.bin_grad_ = r.vec<float>();
  t.bin_count_ = r.vec<uint32_t>();
  t.loss_history_ = r.vec<float>();
  t.on_change_ = r.vec<uint8_t>();
  t.status_.loss = r.pod<double>();
  t.status_.psnr = r.pod<double>();
  // The state's shapes follow the model's: checked here, before training indexes them.
  const size_t n = t.params_.size();
  const auto want = std::as_const(t.params_).arrays(), am = std::as_const(t.adam_m_).arrays(), av = std::as_const(t.adam_v_).arrays();
  for (size_t k = 0; k < want.size(); ++k)
    if (am[k]->size() != want[k]->size() || av[k]->size() != want[k]->size())
      throw_error(path, ": checkpoint optimiser moments do not match the model's arrays (array ", k, ")");
  const size_t bins = size_t(std::max(1, options.time_bins));
  if (t.grad_accum_.size() != n || t.max_radii_.size() != n || t.denom_.size() != n || t.on_change_.size() != n ||
      t.bin_count_.size() != n * bins || t.bin_grad_.size() != n * bins * 3 || it < 0)
    throw_error(path, ": checkpoint densification state does not match its ", n, " Gaussians");
  if (r.at < bytes.size()) {
    const std::vector<float> colour = r.vec<float>();
    if (colour.size() != t.colour_.size() * 19) throw_error(path, ": the colour corrections are for ", colour.size() / 19, " cameras, the dataset has ", t.colour_.size());
    for (float v : colour)
      if (!std::isfinite(v)) throw_error(path, ": checkpoint colour corrections hold a non-finite value");
    for (size_t c = 0; c < t.colour_.size(); ++c) {
      const float* x = &colour[c * 19];
      if (!(x[18] >= 0 && x[18] <= 1e9f)) throw_error(path, ": checkpoint colour correction ", c, " has step count ", x[18]);
      t.colour_[c].gain = Vec3f(x[0], x[1], x[2]);
      t.colour_[c].offset = Vec3f(x[3], x[4], x[5]);
      std::copy(x + 6, x + 12, t.colour_m_[c].begin());
      std::copy(x + 12, x + 18, t.colour_v_[c].begin());
      t.colour_steps_[c] = int(x[18]);
    }
  }
  t.status_.iteration = it;
  t.status_.gaussians = t.params_.size();
  t.status_.dynamic = t.params_.dynamic_count();
  if (t.grad_accum_.size() != t.params_.size() || t.on_change_.size() != t.params_.size() || t.adam_m_.size() != t.params_.size() ||
      t.adam_v_.size() != t.params_.size() || t.adam_m_.dynamic_ids != t.params_.dynamic_ids || t.adam_v_.dynamic_ids != t.params_.dynamic_ids)
    throw_error(path, ": checkpoint statistics disagree with its model");
  return t;
}

// ---------------------------------------------------------------------------------

}  // namespace fillgs
