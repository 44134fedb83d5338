#include "model_support.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>

#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/ply.hpp"

namespace fillgs::model_io {

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


nlohmann::json read_cfg_args(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return nlohmann::json::object();
  const nlohmann::json j = LiteralParser(read_file(path), path).parse();
  if (!j.is_object()) throw_error(path, ": not a Namespace(...) of settings");
  return j;
}

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

TorchTensor checked(TorchTensor t, const std::string& source, const std::string& what, const std::vector<int64_t>& shape) {
  for (size_t d = 0; d < t.shape.size(); ++d)  // a size no tensor has (an empty one still claims it)
    if (t.shape[d] < 0) throw_error(source, ": ", what, " has shape ", t.shape_text(), ": dimension ", d, " is negative");
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

RowMat run_trunk(const std::vector<Linear>& layers, RowMat x) {
  for (size_t i = 0; i < layers.size(); ++i) x = layers[i].apply(i > 0 ? RowMat(x.cwiseMax(0.0f)) : x);
  return x;
}

RowMat run_head(const std::vector<Linear>& layers, const RowMat& h) {
  RowMat x = h;
  for (const Linear& l : layers) x = l.apply(x.cwiseMax(0.0f));
  return x;
}

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

size_t widest(std::initializer_list<const std::vector<Linear>*> nets) {
  size_t w = 0;
  for (const std::vector<Linear>* n : nets)
    for (const Linear& l : *n) w = std::max({w, size_t(l.in), size_t(l.out)});
  return w;
}

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

double model_time_checked(double t, const std::string& source, const char* what) {
  if (!(std::fabs(t) <= kMaxModelTime)) throw_error(source, ": ", what, " ", t, " is not a finite time within +-", kMaxModelTime);
  return t;
}

void set_times(TrainedModel& m, int frames, std::pair<double, double> range) {
  if (frames < 1 || frames > 100000) throw_error(m.source, ": the model covers ", frames, " frames (fillgs reads 1 to 100000)");
  m.frames = frames;
  m.time_first = range.first;
  m.time_last = range.first + (range.second - range.first) * double(frames - 1) / double(frames);
}

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

std::string deformation_run_header(const FormatProbe& probe) {
  std::error_code ec;
  std::string dir = probe.path();
  if (!probe.directory()) {
    if (probe.filename() != "deformation.pth") return "";
    dir = fs::path(dir).parent_path().string();
  }
  try {
    const RunFolder rf = run_folder(dir, "deformation.pth");
    return read_ply_header(join_path(rf.iteration_dir, "point_cloud.ply"));
  } catch (const Error&) {
    return "";
  }
}

}  // namespace fillgs::model_io

namespace fillgs {

std::string python_literal_to_json(const std::string& text, const std::string& source) {
  return model_io::LiteralParser(text, source).parse().dump();
}

}  // namespace fillgs
