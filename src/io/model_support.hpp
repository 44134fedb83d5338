#pragma once
// What the readers of the field's deformation models share (src/io/formats/): their
// settings (cfg_args, a Python Namespace repr), their run folders
// (point_cloud/iteration_N/), their networks read from a PyTorch state dict and evaluated
// two ways (Eigen products on row-major blocks, the reference; the dense kernel on
// feature-major blocks, the fast path), and their times.
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <type_traits>
#include <vector>

#include "fillgs/base/error.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/io/trained_models.hpp"
#include "fillgs/model/dense.hpp"

namespace fillgs::model_io {

namespace fs = std::filesystem;

/// cfg_args of a model folder as JSON (an object; empty when the file is absent).
nlohmann::json read_cfg_args(const std::string& path);

template <typename T>
T cfg(const nlohmann::json& j, const std::string& key, T fallback, const std::string& source) {
  if (!j.contains(key) || j[key].is_null()) return fallback;
  if constexpr (std::is_same_v<T, int>) {
    const double v = j[key].is_number() ? j[key].get<double>() : std::nan("");
    if (!(v >= -1e9 && v <= 1e9) || v != std::floor(v))
      throw_error(source, ": setting '", key, "' is not an integer in [-1e9, 1e9] (", j[key].dump().substr(0, 40), ")");
    return int(v);
  }
  if constexpr (std::is_same_v<T, bool>) {
    if (!j[key].is_boolean()) throw_error(source, ": setting '", key, "' is not True or False (", j[key].dump().substr(0, 40), ")");
  }
  try {
    return j[key].get<T>();
  } catch (const std::exception&) {
    throw_error(source, ": setting '", key, "' has the wrong type (", j[key].dump().substr(0, 40), ")");
  }
}

// ---------------------------------------------------------------------------------
// Model folders

/// A training run's folder: cfg_args and point_cloud/iteration_N/. Accepts the run
/// folder (newest iteration) or an iteration folder.
struct RunFolder {
  std::string run, iteration_dir;
  int iteration = 0;
};

int iteration_of(const fs::path& dir);

RunFolder run_folder(const std::string& path, const char* needed);

// ---------------------------------------------------------------------------------
// Networks

using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Linear {
  int in = 0, out = 0;
  RowMat w;               // [out][in], as nn.Linear stores it
  Eigen::RowVectorXf b;   // [out]
  /// Y = X W^T + b for a block of rows.
  RowMat apply(const RowMat& x) const {
    RowMat y = x * w.transpose();
    y.rowwise() += b;
    return y;
  }
};
/// `t` with its shape checked against `shape` (-1: any) and every value finite; `what`
/// names it in the one-line error ("key 'weight'", "entry 4 (_scaling)").
TorchTensor checked(TorchTensor t, const std::string& source, const std::string& what, const std::vector<int64_t>& shape);

/// A state dict's tensors by key, with shape checks that name the file, the key and both shapes.
class StateDict {
 public:
  StateDict(const TorchFile& file, PickleValues::Ref dict, std::string what) : file_(file) {
    for (const auto& [k, r] : file.string_entries(dict, what))
      if (file.kind(r) == PickleValues::Kind::Tensor) refs_[k] = r;
  }
  bool has(const std::string& key) const { return refs_.count(key) != 0; }
  std::vector<std::string> keys_with_prefix(const std::string& prefix) const {
    std::vector<std::string> out;
    for (const auto& [k, r] : refs_)
      if (k.rfind(prefix, 0) == 0) out.push_back(k);
    return out;
  }
  TorchTensor get(const std::string& key, const std::vector<int64_t>& shape = {}) const {
    const auto it = refs_.find(key);
    if (it == refs_.end()) throw_error(file_.source(), ": key '", key, "' missing");
    const std::string what = "key '" + key + "'";
    return checked(file_.tensor(it->second, what), file_.source(), what, shape);
  }
  /// An nn.Sequential's Linear layers (keys PREFIX.<i>.weight / .bias in index order).
  std::vector<Linear> sequential(const std::string& prefix) const {
    std::map<int, std::string> layers;
    for (const std::string& k : keys_with_prefix(prefix + ".")) {
      const std::string rest = k.substr(prefix.size() + 1);
      const size_t dot = rest.find('.');
      if (dot == std::string::npos || rest.substr(dot) != ".weight") continue;
      const std::string idx = rest.substr(0, dot);
      if (idx.empty() || idx.size() > 4 || idx.find_first_not_of("0123456789") != std::string::npos) continue;
      layers[std::stoi(idx)] = k.substr(0, prefix.size() + 1 + dot);
    }
    if (layers.empty()) throw_error(file_.source(), ": key '", prefix, ".*.weight' missing (no layers of ", prefix, ")");
    std::vector<Linear> out;
    for (const auto& [i, name] : layers) {
      TorchTensor w = get(name + ".weight");
      if (w.shape.size() != 2) throw_error(file_.source(), ": key '", name, ".weight' has shape ", w.shape_text(), ", expected [out, in]");
      Linear l;
      l.out = int(w.shape[0]);
      l.in = int(w.shape[1]);
      if (!out.empty() && out.back().out != l.in)
        throw_error(file_.source(), ": key '", name, ".weight' has shape ", w.shape_text(), ", expected [*, ", out.back().out, "]");
      l.w = Eigen::Map<const RowMat>(w.values.data(), l.out, l.in);
      const TorchTensor b = get(name + ".bias", {l.out});
      l.b = Eigen::Map<const Eigen::RowVectorXf>(b.values.data(), l.out);
      out.push_back(std::move(l));
    }
    return out;
  }

 private:
  const TorchFile& file_;
  std::map<std::string, PickleValues::Ref> refs_;
};

/// The feature MLP on a block of rows: Linear, then (ReLU, Linear) for each further layer.
RowMat run_trunk(const std::vector<Linear>& layers, RowMat x);

/// A head: (ReLU, Linear) for each of its Linear layers.
RowMat run_head(const std::vector<Linear>& layers, const RowMat& h);

/// The five heads (position, scale, rotation, opacity, SH) of a deformation MLP added to the
/// raw values of rows [first, first + h.rows()), each scaled by its coefficient; a head
/// whose coefficient is `off` is not run.
struct HeadWeights {
  float k[5] = {1, 1, 1, 1, 1};
  bool on[5] = {true, true, true, true, true};
};

void add_heads(const std::vector<Linear> (&heads)[5], const RowMat& h, size_t first, const HeadWeights& w, ModelState& s);

constexpr size_t kBlock = 1024;  // rows per matrix product

/// The widest layer side (inputs or outputs) of the networks given.
size_t widest(std::initializer_list<const std::vector<Linear>*> nets);

// ---------------------------------------------------------------------------------
// The fast path: feature-major blocks of dense::kBlock Gaussians through the dense kernel

constexpr size_t kRows = dense::kBlock;

/// nn.Linear in the kernel's form: the weights of its per-Gaussian inputs packed row-major
/// (`in` of them), and those of its per-frame inputs, whose product with the frame's values
/// joins the bias once per frame instead of once per Gaussian.
struct DenseLinear {
  int out = 0, in = 0, in_time = 0;
  std::vector<float> w, w_time, b;
  /// `l` with columns `gauss` (ranges, concatenated in order) per Gaussian and `time` per frame.
  static DenseLinear from(const Linear& l, const std::vector<std::pair<int, int>>& gauss, std::pair<int, int> time = {0, 0}) {
    DenseLinear d;
    d.out = l.out;
    for (auto [c0, c1] : gauss) d.in += c1 - c0;
    d.in_time = time.second - time.first;
    d.w.resize(size_t(d.out) * size_t(d.in));
    d.w_time.resize(size_t(d.out) * size_t(d.in_time));
    d.b.assign(l.b.data(), l.b.data() + l.out);
    for (int o = 0; o < l.out; ++o) {
      size_t k = 0;
      for (auto [c0, c1] : gauss)
        for (int c = c0; c < c1; ++c) d.w[size_t(o) * size_t(d.in) + k++] = l.w(o, c);
      for (int c = time.first; c < time.second; ++c) d.w_time[size_t(o) * size_t(d.in_time) + size_t(c - time.first)] = l.w(o, c);
    }
    return d;
  }
  static DenseLinear whole(const Linear& l) { return from(l, {{0, l.in}}); }
  /// The bias at a frame whose per-frame inputs are `tv`.
  std::vector<float> bias_at(const float* tv) const {
    std::vector<float> out = b;
    for (int o = 0; o < this->out; ++o) {
      float sum = 0.0f;
      for (int k = 0; k < in_time; ++k) sum += w_time[size_t(o) * size_t(in_time) + size_t(k)] * tv[k];
      out[size_t(o)] += sum;
    }
    return out;
  }
  void run(const float* X, float* Y, bool relu, const float* bias = nullptr) const {
    dense::layer(w.data(), size_t(in), bias ? bias : b.data(), out, in, X, Y, relu);
  }
  double multiply_adds() const { return double(out) * double(in); }
};

/// A network's heads on the kernel: the first layers of the heads with more than one
/// stacked into one product (ReLU after), those of the one-layer heads into another (no
/// ReLU); then each deep head's further layers. `emit(head, D)` gets each head's output,
/// [out][kRows] feature-major.
class DenseHeads {
 public:
  DenseHeads() = default;
  DenseHeads(const std::vector<Linear>* heads, int count, const bool* on) {
    std::vector<Linear> deep_first, shallow;
    for (int h = 0; h < count; ++h) {
      if (!on[h]) continue;
      Head hd;
      hd.id = h;
      hd.deep = heads[h].size() > 1;
      std::vector<Linear>& stack = hd.deep ? deep_first : shallow;
      hd.offset = 0;
      for (const Linear& l : stack) hd.offset += l.out;
      stack.push_back(heads[h].front());
      for (size_t i = 1; i < heads[h].size(); ++i) hd.rest.push_back(DenseLinear::whole(heads[h][i]));
      hd.out = heads[h].back().out;
      heads_.push_back(std::move(hd));
    }
    deep_ = stacked(deep_first);
    shallow_ = stacked(shallow);
  }
  /// Rows of run()'s buffers: `stack` (the stacked first layers) and `a`, `b` (the rest).
  size_t stack_rows() const { return size_t(deep_.out + shallow_.out); }
  size_t scratch_rows() const {
    size_t r = 1;
    for (const Head& h : heads_)
      for (const DenseLinear& l : h.rest) r = std::max(r, size_t(l.out));
    return r;
  }
  template <typename Emit>
  void run(const float* H, std::vector<float>& stack, std::vector<float>& a, std::vector<float>& b, Emit&& emit) const {
    float* shallow_out = stack.data() + size_t(deep_.out) * kRows;
    if (deep_.out) deep_.run(H, stack.data(), true);
    if (shallow_.out) shallow_.run(H, shallow_out, false);
    for (const Head& h : heads_) {
      if (!h.deep) {
        emit(h.id, shallow_out + size_t(h.offset) * kRows);
        continue;
      }
      const float* x = stack.data() + size_t(h.offset) * kRows;
      for (size_t i = 0; i < h.rest.size(); ++i) {
        float* y = (i % 2 == 0 ? a : b).data();
        h.rest[i].run(x, y, i + 1 < h.rest.size());
        x = y;
      }
      emit(h.id, x);
    }
  }
  double multiply_adds() const {
    double m = deep_.multiply_adds() + shallow_.multiply_adds();
    for (const Head& h : heads_)
      for (const DenseLinear& l : h.rest) m += l.multiply_adds();
    return m;
  }

 private:
  struct Head {
    int id = 0, offset = 0, out = 0;
    bool deep = false;
    std::vector<DenseLinear> rest;
  };
  static DenseLinear stacked(const std::vector<Linear>& ls) {
    DenseLinear d;
    if (ls.empty()) return d;
    d.in = ls.front().in;
    for (const Linear& l : ls) {
      d.out += l.out;
      d.w.insert(d.w.end(), l.w.data(), l.w.data() + size_t(l.out) * size_t(l.in));
      d.b.insert(d.b.end(), l.b.data(), l.b.data() + l.out);
    }
    return d;
  }
  DenseLinear deep_, shallow_;
  std::vector<Head> heads_;
};

/// Feature-major scratch for one thread's blocks: `rows` rows of kRows floats.
inline std::vector<float> block_buffer(size_t rows) { return std::vector<float>(std::max<size_t>(rows, 1) * kRows, 0.0f); }

/// A trunk (each layer's output through ReLU, as every consumer of it takes it) and its heads
/// on the kernel: E-D3DGS's passes and 4DGaussians' network.
struct DenseNet {
  std::vector<DenseLinear> trunk;
  DenseHeads heads;
  /// One thread's buffers for run(): the trunk's two alternating outputs and the heads'.
  struct Scratch {
    std::vector<float> h[2], stack, a, b;
  };
  Scratch scratch() const { return scratch_for({this}); }
  /// Buffers any of `nets` can run in, one after the other (one set in cache, not one each).
  static Scratch scratch_for(std::initializer_list<const DenseNet*> nets) {
    size_t width = 1, stack = 1, rows = 1;
    for (const DenseNet* n : nets) {
      for (const DenseLinear& l : n->trunk) width = std::max(width, size_t(l.out));
      stack = std::max(stack, n->heads.stack_rows());
      rows = std::max(rows, n->heads.scratch_rows());
    }
    return Scratch{{block_buffer(width), block_buffer(width)}, block_buffer(stack), block_buffer(rows), block_buffer(rows)};
  }
  /// The trunk on a block's inputs `x` (its first layer's bias `bias0` where the frame gives
  /// one, else its own), then the heads: emit(head, D) with D [out][kRows].
  template <typename Emit>
  void run(const float* x, const float* bias0, Scratch& S, Emit&& emit) const {
    for (size_t i = 0; i < trunk.size(); ++i) {
      float* y = S.h[i % 2].data();
      trunk[i].run(x, y, true, i == 0 ? bias0 : nullptr);
      x = y;
    }
    heads.run(x, S.stack, S.a, S.b, emit);
  }
  /// Multiply-adds per Gaussian.
  double multiply_adds() const {
    double m = heads.multiply_adds();
    for (const DenseLinear& l : trunk) m += l.multiply_adds();
    return m;
  }
};

/// Runs `body(first, count)` over blocks of kRows of [0, n), spread over the cores, with
/// `scratch()` made once per task.
template <typename Scratch, typename Body>
void over_blocks(size_t n, Scratch&& scratch, Body&& body) {
  const size_t blocks = (n + kRows - 1) / kRows;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 1), [&](const tbb::blocked_range<size_t>& r) {
    auto s = scratch();
    for (size_t blk = r.begin(); blk < r.end(); ++blk) {
      const size_t first = blk * kRows;
      body(first, std::min(kRows, n - first), s);
    }
  });
}

/// Adds head `head`'s output D ([out][kRows]) times k to rows [first, first + count) of `s`
/// (the five heads of add_heads: position, scale, rotation, opacity, SH).
void add_head_rows(int head, const float* D, size_t first, size_t count, float k, ModelState& s);

/// Charges the memory evaluating a network will take to the file that declared it, before
/// any of it is taken: on every thread, a block of kBlock rows of the widest layer, four
/// times (input, output, activation, head). A file that declares 200,000-wide layers with
/// zero strides is refused here, not when the blocks are allocated.
void charge_network(const TorchFile& tf, size_t width, const char* code);

void check_head(const std::vector<Linear>& head, int in, int out, const std::string& source, const std::string& name);

/// The model times fillgs evaluates a network at: |t| <= kMaxModelTime. Larger times are no
/// time a model was trained on, and in float32 they overflow its time encodings (E-D3DGS's
/// grid coordinate 2t - 1 reaches infinity at 1.7e38).
constexpr double kMaxModelTime = 1e6;

/// "T0:T1" -> (T0, T1): finite, within [-1e6, 1e6], T1 - T0 at least 1e-6.
std::pair<double, double> time_range(const std::string& text, const std::string& source);

/// `t` when it is a time a model can be evaluated at; one line naming the model when it is
/// not finite or lies beyond kMaxModelTime (no time is turned into an index unchecked).
double model_time_checked(double t, const std::string& source, const char* what = "model time");

/// Frames and times: frame f at T0 + f (T1 - T0) / F, as the field's multi-view loaders
/// time frame f of F at f / F (E-D3DGS, 4DGaussians) or f / fps (4DGS).
void set_times(TrainedModel& m, int frames, std::pair<double, double> range);

/// A deformation model's run: its iteration folder (point_cloud.ply + deformation.pth) and
/// its settings (cfg_args two folders up).
struct DeformationRun {
  RunFolder folder;
  std::string cfg_path, ply_path, pth;
  nlohmann::json cfg;
};

DeformationRun open_run(const std::string& path, TrainedModel& m, const char* code);

// ---------------------------------------------------------------------------------
// Per-frame sequences (Dynamic 3D Gaussians' params.npz, folders of 3DGS PLYs): the frames
// read whole, the model at a time its nearest frame.
class FrameSequence : public TrainedModel {
 public:
  size_t size() const override { return frames_.empty() ? 0 : frames_[0].size(); }
  ModelState at(double model_time) const override {
    const long f = std::lround(std::clamp(model_time_checked(model_time, source), 0.0, double(frames_.size() - 1)));
    return frames_[size_t(f)];
  }

 protected:
  void finish_times() {
    frames = int(frames_.size());
    time_first = 0.0;
    time_last = double(frames - 1);
  }
  std::vector<ModelState> frames_;
};

// ---------------------------------------------------------------------------------
// Detection

/// The canonical PLY header of the deformation run (E-D3DGS, 4DGaussians) at `probe` (its
/// run folder, an iteration folder, or deformation.pth), or "" where it holds none.
std::string deformation_run_header(const FormatProbe& probe);

}  // namespace fillgs::model_io
