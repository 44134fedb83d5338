#include "fillgs/io/trained_models.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <type_traits>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/model/dense.hpp"
#include "fillgs/model/sh.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {

// ---------------------------------------------------------------------------------
// cfg_args: the repr of an argparse Namespace

class LiteralParser {
 public:
  LiteralParser(const std::string& s, const std::string& src) : s_(s), src_(src) {}
  nlohmann::json parse() {
    // Python writes str() as UTF-8; any other byte would surface later, in a JSON writer,
    // as a message that names no file.
    const size_t bad = first_invalid_utf8(s_);
    if (bad != std::string::npos) {
      at_ = bad;
      fail("invalid UTF-8 byte 0x" + hex_byte(static_cast<unsigned char>(s_[bad])));
    }
    nlohmann::json v = value(0);
    space();
    if (at_ != s_.size()) fail("unexpected text after the value");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw_error(src_, ": ", what, " at character ", at_, " (a Python literal such as Namespace(key=value, ...) expected)");
  }
  void space() {
    while (at_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[at_]))) ++at_;
  }
  bool eat(char c) {
    space();
    if (at_ < s_.size() && s_[at_] == c) {
      ++at_;
      return true;
    }
    return false;
  }
  std::string word() {
    space();
    const size_t from = at_;
    while (at_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[at_])) || s_[at_] == '_')) ++at_;
    return s_.substr(from, at_ - from);
  }
  nlohmann::json value(int depth) {
    if (depth > 64) fail("nesting deeper than 64");
    space();
    if (at_ >= s_.size()) fail("value missing");
    const char c = s_[at_];
    if (c == '\'' || c == '"') return string_value();
    if (c == '[' || c == '(') {
      const char close = c == '[' ? ']' : ')';
      ++at_;
      nlohmann::json a = nlohmann::json::array();
      while (!eat(close)) {
        a.push_back(value(depth + 1));
        if (!eat(',')) {
          if (!eat(close)) fail(std::string("expected ',' or '") + close + "'");
          break;
        }
      }
      return a;
    }
    if (c == '{') {
      ++at_;
      nlohmann::json o = nlohmann::json::object();
      while (!eat('}')) {
        const nlohmann::json k = value(depth + 1);
        if (!eat(':')) fail("expected ':' in a dict");
        o[k.is_string() ? k.get<std::string>() : k.dump()] = value(depth + 1);
        if (!eat(',')) {
          if (!eat('}')) fail("expected ',' or '}'");
          break;
        }
      }
      return o;
    }
    if (c == '-' || c == '+' || c == '.' || std::isdigit(static_cast<unsigned char>(c))) return number();
    const std::string w = word();
    if (w == "True") return true;
    if (w == "False") return false;
    if (w == "None") return nullptr;
    if (w == "inf" || w == "nan") fail("non-finite number");
    if (w.empty()) fail(std::string("unexpected character '") + c + "'");
    // A call: Namespace(key=value, ...) or any Name(...), read as an object.
    if (!eat('(')) fail("name '" + w.substr(0, 40) + "' is not a literal");
    nlohmann::json o = nlohmann::json::object();
    while (!eat(')')) {
      const std::string k = word();
      if (k.empty() || !eat('=')) fail("expected key=value in " + w.substr(0, 40) + "(...)");
      o[k] = value(depth + 1);
      if (!eat(',')) {
        if (!eat(')')) fail("expected ',' or ')'");
        break;
      }
    }
    return o;
  }
  nlohmann::json string_value() {
    const char q = s_[at_++];
    std::string out;
    while (true) {
      if (at_ >= s_.size()) fail("unterminated string");
      const char c = s_[at_++];
      if (c == q) break;
      if (c == '\\') {
        if (at_ >= s_.size()) fail("unterminated string");
        const char e = s_[at_++];
        out += e == 'n' ? '\n' : e == 't' ? '\t' : e;
      } else {
        out += c;
      }
    }
    return out;
  }
  nlohmann::json number() {
    const size_t from = at_;
    while (at_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[at_])) || s_[at_] == '.' || s_[at_] == '-' || s_[at_] == '+' || s_[at_] == '_'))
      ++at_;
    std::string t = s_.substr(from, at_ - from);
    t.erase(std::remove(t.begin(), t.end(), '_'), t.end());
    const bool integral = t.find_first_of(".eE") == std::string::npos;
    char* end = nullptr;
    if (integral) {
      errno = 0;
      const long long v = std::strtoll(t.c_str(), &end, 10);
      if (end != t.c_str() + t.size() || errno) fail("bad integer '" + t.substr(0, 40) + "'");
      return v;
    }
    const double d = std::strtod(t.c_str(), &end);
    if (end != t.c_str() + t.size() || !std::isfinite(d)) fail("bad number '" + t.substr(0, 40) + "'");
    return d;
  }

  const std::string& s_;
  const std::string& src_;
  size_t at_ = 0;
};

/// cfg_args of a model folder as JSON (an object; empty when the file is absent).
nlohmann::json read_cfg_args(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return nlohmann::json::object();
  const nlohmann::json j = LiteralParser(read_file(path), path).parse();
  if (!j.is_object()) throw_error(path, ": not a Namespace(...) of settings");
  return j;
}

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

int iteration_of(const fs::path& dir) {
  const std::string n = dir.filename().string();
  if (n.rfind("iteration_", 0) != 0) return -1;
  const std::string d = n.substr(10);
  if (d.empty() || d.size() > 9 || d.find_first_not_of("0123456789") != std::string::npos) return -1;
  return std::stoi(d);
}

RunFolder run_folder(const std::string& path, const char* needed) {
  std::error_code ec;
  fs::path p(path);
  if (!fs::is_directory(p, ec)) p = p.parent_path();
  RunFolder r;
  if (iteration_of(p) >= 0) {
    r.iteration_dir = p.string();
    r.iteration = iteration_of(p);
    r.run = p.parent_path().parent_path().string();
    return r;
  }
  if (fs::exists(p / needed, ec)) {  // a folder holding the files directly
    r.iteration_dir = p.string();
    r.run = p.string();
    return r;
  }
  const fs::path pc = p / "point_cloud";
  int best = -1;
  if (fs::is_directory(pc, ec))
    for (const auto& e : fs::directory_iterator(pc, ec)) {
      const int it = iteration_of(e.path());
      if (it > best && fs::exists(e.path() / needed, ec)) {
        best = it;
        r.iteration_dir = e.path().string();
      }
    }
  if (best < 0) throw_error(path, ": no point_cloud/iteration_*/", needed, " inside");
  r.iteration = best;
  r.run = p.string();
  return r;
}

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
TorchTensor checked(TorchTensor t, const std::string& source, const std::string& what, const std::vector<int64_t>& shape) {
  bool ok = shape.empty() || t.shape.size() == shape.size();
  for (size_t d = 0; ok && d < shape.size(); ++d) ok = shape[d] < 0 || shape[d] == t.shape[d];
  if (!ok) {
    TorchTensor want;
    want.shape = shape;
    std::string w = want.shape_text();
    for (size_t p = w.find("-1"); p != std::string::npos; p = w.find("-1")) w.replace(p, 2, "*");
    throw_error(source, ": ", what, " has shape ", t.shape_text(), ", expected ", w);
  }
  for (size_t i = 0; i < t.values.size(); ++i)
    if (!std::isfinite(t.values[i])) throw_error(source, ": ", what, " element ", i, " is not finite");
  return t;
}

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
RowMat run_trunk(const std::vector<Linear>& layers, RowMat x) {
  for (size_t i = 0; i < layers.size(); ++i) x = layers[i].apply(i > 0 ? RowMat(x.cwiseMax(0.0f)) : x);
  return x;
}

/// A head: (ReLU, Linear) for each of its Linear layers.
RowMat run_head(const std::vector<Linear>& layers, const RowMat& h) {
  RowMat x = h;
  for (const Linear& l : layers) x = l.apply(x.cwiseMax(0.0f));
  return x;
}

/// The five heads (position, scale, rotation, opacity, SH) of a deformation MLP added to the
/// raw values of rows [first, first + h.rows()), each scaled by its coefficient; a head
/// whose coefficient is `off` is not run.
struct HeadWeights {
  float k[5] = {1, 1, 1, 1, 1};
  bool on[5] = {true, true, true, true, true};
};

void add_heads(const std::vector<Linear> (&heads)[5], const RowMat& h, size_t first, const HeadWeights& w, ModelState& s) {
  const size_t B = size_t(h.rows());
  for (int head = 0; head < 5; ++head) {
    if (!w.on[head]) continue;
    const RowMat d = run_head(heads[head], h);
    const float k = w.k[head];
    for (size_t r = 0; r < B; ++r) {
      const size_t i = first + r;
      const float* v = d.row(Eigen::Index(r)).data();
      switch (head) {
        case 0: for (int a = 0; a < 3; ++a) s.means[i][a] += v[a] * k; break;
        case 1: for (int a = 0; a < 3; ++a) s.log_scales[i][a] += v[a] * k; break;
        case 2: for (int a = 0; a < 4; ++a) s.rotations[i][a] += v[a] * k; break;
        case 3: s.opacity_logits[i] += v[0] * k; break;
        default: for (size_t q = 0; q < 48; ++q) s.sh[i * 48 + q] += v[q] * k; break;
      }
    }
  }
}

constexpr size_t kBlock = 1024;  // rows per matrix product

/// The widest layer side (inputs or outputs) of the networks given.
size_t widest(std::initializer_list<const std::vector<Linear>*> nets) {
  size_t w = 0;
  for (const std::vector<Linear>* n : nets)
    for (const Linear& l : *n) w = std::max({w, size_t(l.in), size_t(l.out)});
  return w;
}

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
void add_head_rows(int head, const float* D, size_t first, size_t count, float k, ModelState& s) {
  for (size_t r = 0; r < count; ++r) {
    const size_t i = first + r;
    switch (head) {
      case 0: for (int a = 0; a < 3; ++a) s.means[i][a] += D[size_t(a) * kRows + r] * k; break;
      case 1: for (int a = 0; a < 3; ++a) s.log_scales[i][a] += D[size_t(a) * kRows + r] * k; break;
      case 2: for (int a = 0; a < 4; ++a) s.rotations[i][a] += D[size_t(a) * kRows + r] * k; break;
      case 3: s.opacity_logits[i] += D[r] * k; break;
      default: for (size_t q = 0; q < 48; ++q) s.sh[i * 48 + q] += D[q * kRows + r] * k; break;
    }
  }
}

/// Charges the memory evaluating a network will take to the file that declared it, before
/// any of it is taken: on every thread, a block of kBlock rows of the widest layer, four
/// times (input, output, activation, head). A file that declares 200,000-wide layers with
/// zero strides is refused here, not when the blocks are allocated.
void charge_network(const TorchFile& tf, size_t width, const char* code) {
  const size_t threads = size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
  const std::string what = std::string(code) + "'s network evaluation (" + std::to_string(threads) + " threads x " + std::to_string(kBlock) +
                           " rows x 4 blocks of its widest layer, " + std::to_string(width) + " values)";
  tf.budget().charge(checked_mul(checked_mul(checked_mul(threads, kBlock, tf.source(), what), width, tf.source(), what), 4 * sizeof(float),
                                 tf.source(), what),
                     what);
}

void check_head(const std::vector<Linear>& head, int in, int out, const std::string& source, const std::string& name) {
  if (head.front().in != in || head.back().out != out)
    throw_error(source, ": key '", name, "' maps ", head.front().in, " -> ", head.back().out, " values, expected ", in, " -> ", out);
}

/// The canonical Gaussians of a deformation model's point_cloud.ply (raw values).
ModelState read_canonical(const PlyElement& v, const std::string& path) {
  ModelState s;
  const size_t n = v.count;
  const size_t rest = v.indexed_properties("f_rest_").size();
  const int K = int(rest / 3) + 1;
  s.sh_degree = K == 1 ? 0 : K == 4 ? 1 : K == 9 ? 2 : K == 16 ? 3 : -1;
  if (s.sh_degree < 0 || rest % 3) throw_error(path, ": ", rest, " 'f_rest_*' properties do not make an SH degree 0..3");
  s.means.resize(n);
  s.log_scales.resize(n);
  s.rotations.resize(n);
  s.opacity_logits = v.finite_column("opacity");
  s.sh.resize(n * size_t(K) * 3);
  const char* xyz[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    const auto& p = v.finite_column(xyz[a]);
    const auto& sc = v.finite_column("scale_" + std::to_string(a));
    for (size_t i = 0; i < n; ++i) {
      s.means[i][a] = p[i];
      s.log_scales[i][a] = sc[i];
    }
  }
  for (int a = 0; a < 4; ++a) {
    const auto& q = v.finite_column("rot_" + std::to_string(a));
    for (size_t i = 0; i < n; ++i) s.rotations[i][a] = q[i];
  }
  for (int ch = 0; ch < 3; ++ch) {
    const auto& dc = v.finite_column("f_dc_" + std::to_string(ch));
    for (size_t i = 0; i < n; ++i) s.sh[i * size_t(K) * 3 + size_t(ch)] = dc[i];
    for (int k = 1; k < K; ++k) {
      const auto& col = v.finite_column("f_rest_" + std::to_string(ch * (K - 1) + k - 1));
      for (size_t i = 0; i < n; ++i) s.sh[(i * size_t(K) + size_t(k)) * 3 + size_t(ch)] = col[i];
    }
  }
  return s;
}

/// The model times fillgs evaluates a network at: |t| <= kMaxModelTime. Larger times are no
/// time a model was trained on, and in float32 they overflow its time encodings (E-D3DGS's
/// grid coordinate 2t - 1 reaches infinity at 1.7e38).
constexpr double kMaxModelTime = 1e6;

/// "T0:T1" -> (T0, T1): finite, within [-1e6, 1e6], T1 - T0 at least 1e-6.
std::pair<double, double> time_range(const std::string& text, const std::string& source) {
  const size_t colon = text.find(':');
  if (colon == std::string::npos) throw_error(source, ": --model-time-range '", text.substr(0, 40), "' is not T0:T1");
  const double a = parse_number(text.substr(0, colon), source, "--model-time-range start");
  const double b = parse_number(text.substr(colon + 1), source, "--model-time-range end");
  if (!(std::fabs(a) <= kMaxModelTime && std::fabs(b) <= kMaxModelTime))
    throw_error(source, ": --model-time-range ", text.substr(0, 40), " reaches beyond model times of +-", kMaxModelTime);
  if (!(b - a >= 1e-6)) throw_error(source, ": --model-time-range ", text.substr(0, 40), " must have T1 - T0 >= 1e-6");
  return {a, b};
}

/// `t` when it is a time a model can be evaluated at; one line naming the model when it is
/// not finite or lies beyond kMaxModelTime (no time is turned into an index unchecked).
double model_time_checked(double t, const std::string& source, const char* what = "model time") {
  if (!(std::fabs(t) <= kMaxModelTime)) throw_error(source, ": ", what, " ", t, " is not a finite time within +-", kMaxModelTime);
  return t;
}

/// Frames and times: frame f at T0 + f (T1 - T0) / F, as the field's multi-view loaders
/// time frame f of F at f / F (E-D3DGS, 4DGaussians) or f / fps (4DGS).
void set_times(TrainedModel& m, int frames, std::pair<double, double> range) {
  if (frames < 1 || frames > 100000) throw_error(m.source, ": the model covers ", frames, " frames (fillgs reads 1 to 100000)");
  m.frames = frames;
  m.time_first = range.first;
  m.time_last = range.first + (range.second - range.first) * double(frames - 1) / double(frames);
}

/// A deformation model's run: its iteration folder (point_cloud.ply + deformation.pth) and
/// its settings (cfg_args two folders up).
struct DeformationRun {
  RunFolder folder;
  std::string cfg_path, ply_path, pth;
  nlohmann::json cfg;
};

DeformationRun open_run(const std::string& path, TrainedModel& m, const char* code) {
  DeformationRun r;
  r.folder = run_folder(path, "deformation.pth");
  m.source = r.folder.iteration_dir;
  r.cfg_path = join_path(r.folder.run, "cfg_args");
  r.cfg = read_cfg_args(r.cfg_path);
  if (r.cfg.empty()) m.notes.push_back(std::string("no cfg_args beside the model: ") + code + "'s defaults used");
  r.ply_path = join_path(r.folder.iteration_dir, "point_cloud.ply");
  r.pth = join_path(r.folder.iteration_dir, "deformation.pth");
  return r;
}

// ---------------------------------------------------------------------------------
// E-D3DGS

class Ed3dgs : public TrainedModel {
 public:
  Ed3dgs(const std::string& path, const SceneReadOptions& opt) {
    format = SceneFormat::Ed3dgs;
    const DeformationRun run = open_run(path, *this, "E-D3DGS");
    const RunFolder& rf = run.folder;
    const std::string &cfg_path = run.cfg_path, &ply_path = run.ply_path, &pth = run.pth;
    const nlohmann::json& c = run.cfg;
    const PlyData ply = read_ply(ply_path);
    const PlyElement& v = ply.element("vertex");
    canonical_ = read_canonical(v, ply_path);
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
    out = canonical_.rows(rows);
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

// ---------------------------------------------------------------------------------
// 4DGaussians (HexPlane)

class FourDGaussians : public TrainedModel {
 public:
  FourDGaussians(const std::string& path, const SceneReadOptions& opt) {
    format = SceneFormat::FourDGaussians;
    const DeformationRun run = open_run(path, *this, "4DGaussians");
    const std::string &cfg_path = run.cfg_path, &ply_path = run.ply_path, &pth = run.pth;
    const nlohmann::json& c = run.cfg;
    canonical_ = read_canonical(read_ply(ply_path).element("vertex"), ply_path);
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
    out = canonical_.rows(rows);
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

// ---------------------------------------------------------------------------------
// Deformable 3D Gaussians (an MLP on positionally encoded position and time)

class Deformable3dgs : public TrainedModel {
 public:
  Deformable3dgs(const std::string& path, const SceneReadOptions& opt) {
    format = SceneFormat::Deformable3DGS;
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
    canonical_ = read_canonical(read_ply(ply_path).element("vertex"), ply_path);
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
    out = canonical_.rows(rows);
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

// ---------------------------------------------------------------------------------
// 4D Gaussian Splatting (Yang et al.)

class FourDGS : public TrainedModel {
 public:
  FourDGS(const std::string& path, const SceneReadOptions& opt) {
    format = SceneFormat::FourDGS;
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

// ---------------------------------------------------------------------------------
// Per-frame sequences: Dynamic 3D Gaussians' params.npz and folders of 3DGS PLYs

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

class Dynamic3dgs : public FrameSequence {
 public:
  Dynamic3dgs(const std::string& path, const SceneReadOptions&) {
    format = SceneFormat::Dynamic3DGS;
    std::error_code ec;
    source = fs::is_directory(path, ec) ? join_path(path, "params.npz") : path;
    require_regular_file(source);
    const ZipArchive zip(source);
    auto array = [&](const std::string& key, size_t dims) {
      const std::string entry = key + ".npy";
      if (!zip.has(entry)) throw_error(source, ": key '", key, "' missing");
      NpyArray a = parse_npy(zip.read(entry), source + " (" + entry + ")");
      if (a.shape.size() != dims) throw_error(source, ": key '", key, "' has ", a.shape.size(), " dimensions, expected ", dims);
      if (a.fortran_order) throw_error(source, ": key '", key, "' is stored in Fortran order");
      return a;
    };
    auto shape_text = [](const std::vector<size_t>& s) {
      std::string t = "[";
      for (size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
      return t + "]";
    };
    const NpyArray means = array("means3D", 3), colours = array("rgb_colors", 3), rots = array("unnorm_rotations", 3);
    const NpyArray scales = array("log_scales", 2), opac = array("logit_opacities", 2);
    const size_t T = means.shape[0], N = means.shape[1];
    auto expect = [&](const char* key, const NpyArray& a, std::vector<size_t> shape) {
      if (a.shape != shape) throw_error(source, ": key '", key, "' has shape ", shape_text(a.shape), ", expected ", shape_text(shape));
    };
    expect("means3D", means, {T, N, 3});
    expect("rgb_colors", colours, {T, N, 3});
    expect("unnorm_rotations", rots, {T, N, 4});
    expect("log_scales", scales, {N, 3});
    expect("logit_opacities", opac, {N, 1});
    if (T < 1) throw_error(source, ": key 'means3D' holds no frames");
    const std::vector<double> M = means.to_doubles(source), C = colours.to_doubles(source), R = rots.to_doubles(source);
    const std::vector<double> S = scales.to_doubles(source), O = opac.to_doubles(source);
    for (const auto* v : {&M, &C, &R, &S, &O})
      for (size_t i = 0; i < v->size(); ++i)
        if (!std::isfinite((*v)[i])) throw_error(source, ": a value is not finite (element ", i, ")");
    frames_.resize(T);
    for (size_t f = 0; f < T; ++f) {
      ModelState& s = frames_[f];
      s.sh_degree = 0;
      s.means.resize(N);
      s.log_scales.resize(N);
      s.rotations.resize(N);
      s.opacity_logits.resize(N);
      s.sh.resize(N * 3);
      for (size_t i = 0; i < N; ++i) {
        for (int a = 0; a < 3; ++a) {
          s.means[i][a] = float(M[(f * N + i) * 3 + size_t(a)]);
          s.log_scales[i][a] = float(S[i * 3 + size_t(a)]);
          // Colours are given as RGB (its renderer takes them precomputed): the DC that gives them.
          s.sh[i * 3 + size_t(a)] = rgb_to_sh_dc(float(C[(f * N + i) * 3 + size_t(a)]));
        }
        for (int a = 0; a < 4; ++a) s.rotations[i][a] = float(R[(f * N + i) * 4 + size_t(a)]);
        s.opacity_logits[i] = float(O[i]);
      }
    }
    finish_times();
    if (zip.has("seg_colors.npy")) notes.push_back("Dynamic 3D Gaussians' seg_colors are not read (colour comes from rgb_colors)");
  }
};

class PlyFrames : public FrameSequence {
 public:
  PlyFrames(const std::string& dir, const SceneReadOptions&) {
    format = SceneFormat::PlyFrames;
    source = dir;
    const std::vector<std::string> files = frame_files(dir);
    if (files.empty()) throw_error(dir, ": no frame PLYs (time_*.ply or frame_*.ply)");
    for (const std::string& f : files) {
      const PlyData ply = read_ply(f);
      const PlyElement& v = ply.element("vertex");
      frames_.push_back(read_canonical(v, f));
      const ModelState& s = frames_.back();
      if (s.size() != frames_[0].size())
        throw_error(f, ": ", s.size(), " Gaussians, the first frame (", files[0], ") has ", frames_[0].size(), "; frames must hold the same Gaussians in the same order");
      if (s.sh_degree != frames_[0].sh_degree) throw_error(f, ": SH degree ", s.sh_degree, ", the first frame has ", frames_[0].sh_degree);
    }
    finish_times();
  }

  /// time_00000.ply … (4DGaussians' export) or frame_0000.ply … (fillgs convert --to frames),
  /// in numeric order; the numbers must run 0, 1, 2, … without gaps.
  static std::vector<std::string> frame_files(const std::string& dir) {
    std::error_code ec;
    std::map<long, std::string> by_index;
    std::string prefix;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      const std::string n = e.path().filename().string();
      for (const char* p : {"time_", "frame_"}) {
        const std::string ps(p);
        if (n.rfind(ps, 0) != 0 || n.size() <= ps.size() + 4 || n.compare(n.size() - 4, 4, ".ply") != 0) continue;
        const std::string digits = n.substr(ps.size(), n.size() - ps.size() - 4);
        if (digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
        if (!prefix.empty() && prefix != ps) throw_error(dir, ": holds both ", prefix, "*.ply and ", ps, "*.ply frames");
        prefix = ps;
        const auto [at, fresh] = by_index.emplace(std::stol(digits), e.path().string());
        if (!fresh)
          throw_error(dir, ": ", fs::path(at->second).filename().string(), " and ", n, " are both frame ", at->first,
                      "; keep one (fillgs will not choose)");
      }
    }
    std::vector<std::string> out;
    long expect = 0;
    for (const auto& [i, p] : by_index) {
      if (i != expect) throw_error(dir, ": frame ", expect, " missing (the next file is ", fs::path(p).filename().string(), ")");
      out.push_back(p);
      ++expect;
    }
    return out;
  }
};

}  // namespace

std::string python_literal_to_json(const std::string& text, const std::string& source) {
  return LiteralParser(text, source).parse().dump();
}

std::unique_ptr<TrainedModel> open_trained_model(const std::string& path, SceneFormat format, const SceneReadOptions& options) {
  switch (format) {
    case SceneFormat::Ed3dgs: return std::make_unique<Ed3dgs>(path, options);
    case SceneFormat::FourDGaussians: return std::make_unique<FourDGaussians>(path, options);
    case SceneFormat::FourDGS: return std::make_unique<FourDGS>(path, options);
    case SceneFormat::Deformable3DGS: return std::make_unique<Deformable3dgs>(path, options);
    case SceneFormat::Dynamic3DGS: return std::make_unique<Dynamic3dgs>(path, options);
    case SceneFormat::PlyFrames: return std::make_unique<PlyFrames>(path, options);
    default: break;
  }
  throw_error(path, ": ", to_string(format), " is not a trained-model format");
}

GaussianCloud sample_trained_model(const TrainedModel& model, bool reference, Progress& progress) {
  const size_t N = model.size();
  std::vector<uint32_t> all;
  if (!reference)
    for (size_t i = 0; i < N; ++i) all.push_back(uint32_t(i));
  const auto state_at = [&](double mt) {
    if (reference) return model.at(mt);
    ModelState s;
    model.evaluate(mt, all, s);
    return s;
  };
  const int F = model.frames;
  GaussianCloud c;
  if (F < 1) throw_error(model.source, ": the model covers no frames");
  const size_t K = size_t(std::max(F, 2));
  ModelState first = state_at(model.frame_time(0));
  c.sh_degree = first.sh_degree;
  c.resize(N);
  const size_t row = size_t(c.sh_count()) * 3;
  // Memory: N x K keys of 14 floats, plus one state.
  check_allocation(checked_mul(checked_mul(N, K, model.source, "keys"), 14 * sizeof(float), model.source, "key memory"), model.source,
                   "one key per frame for every Gaussian");
  KeyframedMotion km = per_frame_tracks(N, int(K));
  km.log_scales.resize(N * K * 3);
  km.opacity_logits.resize(N * K);
  km.colours.resize(N * K * 3);
  std::vector<double> sh_sum(N * row, 0.0);
  std::vector<float> sh_min(N * row, std::numeric_limits<float>::infinity()), sh_max(N * row, -std::numeric_limits<float>::infinity());
  progress.start("keys", K);
  for (size_t k = 0; k < K; ++k) {
    const ModelState s = k == 0 ? std::move(first) : state_at(model.frame_time(double(std::min<size_t>(k, size_t(F - 1)))));
    progress.advance();
    if (s.size() != N || s.sh.size() != N * row) throw_error(model.source, ": frame ", k, " has another size");
    tbb::parallel_for(tbb::blocked_range<size_t>(0, N, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        for (int a = 0; a < 3; ++a) {
          km.positions[(i * K + k) * 3 + size_t(a)] = s.means[i][a];
          km.log_scales[(i * K + k) * 3 + size_t(a)] = s.log_scales[i][a];
          km.colours[(i * K + k) * 3 + size_t(a)] = s.sh[i * row + size_t(a)];
        }
        for (int a = 0; a < 4; ++a) km.rotations[(i * K + k) * 4 + size_t(a)] = s.rotations[i][a];
        float o = s.opacity_logits[i];
        if (!s.opacity_factor.empty()) o = logit(sigmoid(o) * s.opacity_factor[i]);
        km.opacity_logits[i * K + k] = std::clamp(o, -40.0f, 40.0f);
        for (size_t q = 0; q < row; ++q) {
          const float v = s.sh[i * row + q];
          sh_sum[i * row + q] += v;
          sh_min[i * row + q] = std::min(sh_min[i * row + q], v);
          sh_max[i * row + q] = std::max(sh_max[i * row + q], v);
        }
      }
    });
    if (k == 0)
      for (size_t i = 0; i < N; ++i) {
        c.means[i] = s.means[i];
        c.log_scales[i] = s.log_scales[i];
        c.rotations[i] = s.rotations[i];
        c.opacity_logits[i] = km.opacity_logits[i * K];
      }
  }
  progress.finish();
  float band_spread = 0.0f;
  for (size_t i = 0; i < N; ++i)
    for (size_t q = 0; q < row; ++q) {
      c.sh[i * row + q] = float(sh_sum[i * row + q] / double(K));
      if (q >= 3) band_spread = std::max(band_spread, sh_max[i * row + q] - sh_min[i * row + q]);
    }
  c.keyframed = std::move(km);
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids.resize(N);
  for (size_t i = 0; i < N; ++i) c.dynamic_ids[i] = uint32_t(i);
  if (F == 1) c.notes.push_back("the model covers one frame: it is static");
  c.notes.insert(c.notes.end(), model.notes.begin(), model.notes.end());
  {
    std::ostringstream os;
    os << model.time_first << " … " << model.time_last << " (" << to_string(model.format) << " time of frames 0 … " << F - 1 << ")";
    c.model_times = os.str();
  }
  c.notes.push_back(std::string("sampled at its ") + std::to_string(F) + " frames (model times " + std::to_string(model.time_first) + " … " +
                    std::to_string(model.time_last) + "); between frames fillgs interpolates");
  if (band_spread > 0.0f) {
    std::ostringstream os;
    os << "SH bands above the DC vary in time by up to " << band_spread << "; fillgs keys the DC and keeps their mean";
    c.notes.push_back(os.str());
  }
  return c;
}

namespace {

/// A trained model as the motion of a cloud: normalised time t -> the model's time of frame
/// t (frames - 1); every value it returns checked finite (one line naming the model, the
/// Gaussian and the time, not a NaN in a table).
class TrainedMotion : public MotionSource {
 public:
  TrainedMotion(std::shared_ptr<const TrainedModel> m, bool reference) : m_(std::move(m)), reference_(reference) {}
  std::shared_ptr<const ModelState> evaluate(double t, const std::vector<uint32_t>& rows) const override {
    // The last few evaluations are kept: a command walking frames asks for frame f, then
    // for f - 1 and f + 1 (speeds), then for f + 1 again; each is evaluated once, and handed
    // out without a copy. Kept by frame coordinate, so that t - dt and the previous frame's t meet.
    const double f = frame_of(t);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const Kept& k : kept_)
        if (k.t == f && k.rows == rows) return k.state;
    }
    auto s = std::make_shared<ModelState>();
    evaluate_once(t, rows, *s);
    std::lock_guard<std::mutex> lock(mutex_);
    if (kept_.size() == kKept) kept_.erase(kept_.begin());
    kept_.push_back({f, rows, s});
    return s;
  }
  int frame_count() const override { return m_->frames; }
  /// The model at t, not kept (the still rule's sweep over every Gaussian).
  void evaluate_once(double t, const std::vector<uint32_t>& rows, ModelState& out) const {
    const double mt = m_->frame_time(frame_of(t));
    if (reference_) out = m_->at(mt).rows(rows);
    else m_->evaluate(mt, rows, out);
    check(out, rows, mt);
  }

 private:
  static constexpr size_t kKept = 3;
  struct Kept {
    double t;
    std::vector<uint32_t> rows;
    std::shared_ptr<const ModelState> state;
  };
  /// The frame coordinate of normalised time t: t (F - 1), a whole frame when within 1e-9 of
  /// one (f / (F - 1) times F - 1, or a time less a frame step, can miss f by an ulp).
  double frame_of(double t) const {
    double f = std::clamp(t, 0.0, 1.0) * double(m_->frames - 1);
    if (std::fabs(f - std::round(f)) < 1e-9) f = std::round(f);
    return f;
  }
  void check(const ModelState& s, const std::vector<uint32_t>& rows, double mt) const {
    const size_t row = s.size() ? s.sh.size() / s.size() : 0;
    for (size_t i = 0; i < s.size(); ++i) {
      bool ok = s.means[i].allFinite() && s.log_scales[i].allFinite() && s.rotations[i].allFinite() && std::isfinite(s.opacity_logits[i]) &&
                (s.opacity_factor.empty() || std::isfinite(s.opacity_factor[i]));
      for (size_t q = 0; ok && q < row; ++q) ok = std::isfinite(s.sh[i * row + q]);
      if (!ok) throw_error(m_->source, ": Gaussian ", rows[i], " is not finite at model time ", mt, " (its network's output overflowed)");
    }
  }
  std::shared_ptr<const TrainedModel> m_;
  bool reference_;
  mutable std::mutex mutex_;
  mutable std::vector<Kept> kept_;
};

float activated_opacity(const ModelState& s, size_t i) {
  return sigmoid(s.opacity_logits[i]) * (s.opacity_factor.empty() ? 1.0f : s.opacity_factor[i]);
}

}  // namespace

std::vector<int> sweep_frames(int frames, int wanted) {
  std::vector<int> out;
  if (frames <= 1) return {0};
  const int n = std::max(2, std::min(wanted, frames));
  for (int k = 0; k < n; ++k) {
    const int f = int(std::lround(double(k) * double(frames - 1) / double(n - 1)));
    if (out.empty() || f != out.back()) out.push_back(f);
  }
  return out;
}

GaussianCloud stream_trained_model(std::shared_ptr<const TrainedModel> model, const StillRule& rule, bool reference, Progress& progress) {
  const size_t N = model->size();
  const int F = model->frames;
  if (F < 1) throw_error(model->source, ": the model covers no frames");
  const auto motion = std::make_shared<TrainedMotion>(model, reference);
  std::vector<uint32_t> all(N);
  for (size_t i = 0; i < N; ++i) all[i] = uint32_t(i);
  ModelState first;
  motion->evaluate_once(0.0, all, first);
  // The sweep: the still rule at each of its frames against frame 0, as the largest share of a
  // tolerance any of a Gaussian's departures reaches (> 1: moving).
  const std::vector<int> sweep = sweep_frames(F, rule.sweep_frames);
  std::vector<float> departure(N, 0.0f);
  const size_t row = first.size() ? first.sh.size() / first.size() : 0;
  // Departure of row j of s (Gaussian i) from frame 0, in shares of the tolerances; a zero
  // tolerance counts any departure as infinitely many shares.
  auto share = [](float d, float tolerance) { return d <= 0.0f ? 0.0f : tolerance > 0.0f ? d / tolerance : INFINITY; };
  auto depart = [&](const ModelState& s, size_t j, size_t i) {
    float r = share((s.means[j] - first.means[i]).norm(), rule.position);
    r = std::max(r, share((s.log_scales[j] - first.log_scales[i]).cwiseAbs().maxCoeff(), rule.log_scale));
    r = std::max(r, share(std::fabs(activated_opacity(s, j) - activated_opacity(first, i)), rule.opacity));
    const double c = std::min(1.0, double(std::fabs(normalize_quat(s.rotations[j]).dot(normalize_quat(first.rotations[i])))));
    r = std::max(r, share(float(2.0 * std::acos(c) * 180.0 / M_PI), rule.rotation_degrees));
    for (size_t a = 0; a < 3 && row; ++a) r = std::max(r, share(std::fabs(s.sh[j * row + a] - first.sh[i * row + a]) * kSHC0, rule.colour));
    return r;
  };
  auto sweep_rows = [&](const std::vector<int>& frames, const std::vector<uint32_t>& rows) {
    for (const int f : frames) {
      if (f == 0) continue;
      ModelState s;
      motion->evaluate_once(F > 1 ? double(f) / double(F - 1) : 0.0, rows, s);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, rows.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t j = r.begin(); j < r.end(); ++j) departure[rows[j]] = std::max(departure[rows[j]], depart(s, j, rows[j]));
      });
      progress.advance();
    }
  };
  progress.start("still rule", sweep.size() - 1);
  sweep_rows(sweep, all);
  progress.finish();
  // Gaussians the sweep found still but not far from a tolerance are checked at every frame:
  // a motion between the sweep's frames can exceed what its frames saw.
  std::vector<uint32_t> recheck;
  if (int(sweep.size()) < F)
    for (size_t i = 0; i < N; ++i)
      if (departure[i] <= 1.0f && departure[i] > rule.recheck) recheck.push_back(uint32_t(i));
  if (!recheck.empty()) {
    std::vector<int> rest;  // the frames the sweep did not evaluate
    for (int f = 0; f < F; ++f)
      if (!std::binary_search(sweep.begin(), sweep.end(), f)) rest.push_back(f);
    progress.start("still rule, rechecked at every frame", rest.size());
    sweep_rows(rest, recheck);
    progress.finish();
  }
  std::vector<char> moving(N, 0);
  for (size_t i = 0; i < N; ++i) moving[i] = departure[i] > 1.0f;
  GaussianCloud c;
  c.sh_degree = first.sh_degree;
  c.resize(N);
  for (size_t i = 0; i < N; ++i) {
    c.means[i] = first.means[i];
    c.log_scales[i] = first.log_scales[i];
    c.rotations[i] = first.rotations[i];
    c.opacity_logits[i] = std::clamp(logit(activated_opacity(first, i)), -40.0f, 40.0f);
    if (moving[i]) {
      c.dynamic_ids.push_back(uint32_t(i));
      c.source_rows.push_back(uint32_t(i));
    }
  }
  c.sh = std::move(first.sh);
  if (!c.dynamic_ids.empty()) {
    c.motion = MotionModel::Evaluated;
    c.source = motion;
  }
  c.notes.insert(c.notes.end(), model->notes.begin(), model->notes.end());
  {
    std::ostringstream os;
    os << model->time_first << " … " << model->time_last << " (" << to_string(model->format) << " time of frames 0 … " << F - 1 << ")";
    c.model_times = os.str();
    std::ostringstream still;
    still << N - c.dynamic_ids.size() << " of " << N << " Gaussians still (evaluated once, at frame 0): at each of " << sweep.size() << " of its "
          << F << " frames";
    if (int(sweep.size()) < F) still << " (all " << F << " for the " << recheck.size() << " whose departure there exceeded " << rule.recheck << " of a tolerance)";
    still << " within " << rule.position << " world units, " << rule.rotation_degrees << " degrees, " << rule.log_scale
          << " in log-scale, " << rule.opacity << " in opacity and " << rule.colour << " in colour of frame 0";
    c.notes.push_back(still.str());
    c.notes.push_back(std::string("the ") + std::to_string(c.dynamic_ids.size()) + " moving Gaussians are evaluated by the model at each time asked, exactly" +
                      (!model->has_network() ? std::string()
                       : reference           ? std::string(" (its network by the Eigen reference products)")
                                             : " (its network by the dense kernel, " + std::string(dense::target_name()) + ")"));
  }
  return c;
}

SceneFormat detect_trained_model(const std::string& path) {
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) {
    if (fs::exists(p / "params.npz", ec)) return SceneFormat::Dynamic3DGS;
    if (fs::is_directory(p / "deform", ec)) return SceneFormat::Deformable3DGS;
    for (const auto& e : fs::directory_iterator(p, ec)) {
      const std::string n = e.path().filename().string();
      if (n.rfind("chkpnt", 0) == 0 && n.size() > 10 && n.compare(n.size() - 4, 4, ".pth") == 0) return SceneFormat::FourDGS;
    }
    try {
      const RunFolder rf = run_folder(path, "deformation.pth");
      const std::string header = read_ply_header(join_path(rf.iteration_dir, "point_cloud.ply"));
      return header.find(" embedding_0\n") != std::string::npos ? SceneFormat::Ed3dgs : SceneFormat::FourDGaussians;
    } catch (const Error&) {
    }
    if (!PlyFrames::frame_files(path).empty()) return SceneFormat::PlyFrames;
    return SceneFormat::Auto;
  }
  const std::string n = p.filename().string();
  if (n.size() > 4 && n.compare(n.size() - 4, 4, ".npz") == 0) return SceneFormat::Dynamic3DGS;
  if (n.rfind("chkpnt", 0) == 0 && n.size() > 4 && n.compare(n.size() - 4, 4, ".pth") == 0) return SceneFormat::FourDGS;
  if (n == "deformation.pth") return detect_trained_model(p.parent_path().string());
  return SceneFormat::Auto;
}

void refuse_canonical_ply(const std::string& ply, const std::string& header) {
  std::error_code ec;
  const fs::path dir = fs::path(ply).parent_path();
  const bool embeddings = header.find(" embedding_0\n") != std::string::npos;
  const bool deformation = fs::exists(dir / "deformation.pth", ec);
  const bool deform_dir = fs::is_directory(dir.parent_path().parent_path() / "deform", ec) || fs::is_directory(dir / "deform", ec);
  if (!embeddings && !deformation && !deform_dir) return;
  const std::string what = embeddings ? "the canonical point cloud of an E-D3DGS model (it has embedding_* properties)"
                           : deformation ? "the canonical point cloud of a deformation model (deformation.pth lies beside it)"
                                         : "the canonical point cloud of a Deformable 3D Gaussians model (a deform/ folder lies beside it)";
  const std::string instead = deform_dir && !deformation && !embeddings
                                  ? "pass the training run's folder (the one holding deform/ and point_cloud/) instead"
                                  : "pass the folder " + (dir.empty() ? std::string(".") : dir.string()) + " (or the training run's folder) instead";
  throw_error(ply, ": ", what, ", which is no frame of the video: fillgs will not read it as a static scene; ", instead);
}

}  // namespace fillgs
