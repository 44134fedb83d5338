// The Python module `fillgs`: models, cameras, observation tables and renders as NumPy
// arrays, over the same library calls the command line makes (pybind11).
//
// Arrays in: C-contiguous float32 is taken without a copy, anything else numeric is copied
// once; shapes, dtypes and finiteness are checked with a message naming the argument.
// Errors: fillgs.Error (a ValueError) carries the CLI's one-line message; a missing file is
// FileNotFoundError; a caller's frame function's own exception passes through unchanged.
// Long calls release the GIL and report progress to a callback (label, done, total), or to a
// tqdm bar with progress=True where tqdm is installed.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "fillgs/method/strategies.hpp"
#include "fillgs/base/bounds.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "fillgs/io/array_input.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/math.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/io/trained_models.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/method/finetune_job.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/method/weights.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/visibility/observe_io.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace py = pybind11;

namespace fillgs::python {
namespace {

// ------------------------------------------------------------------ arrays in and out

using FloatArray = py::array_t<float, py::array::c_style>;

/// `value` as a C-contiguous float32 array of `shape` (-1: any size), without a copy when it
/// is one already; a numeric array of another dtype or layout is copied once. Anything else
/// (strings, objects, complex, wrong shape, a non-finite value) raises naming `name`.
FloatArray float_array(const py::handle& value, const char* name, std::vector<py::ssize_t> shape) {
  py::array a = py::isinstance<py::array>(value) ? py::reinterpret_borrow<py::array>(value) : py::array(py::module_::import("numpy").attr("asarray")(value));
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(std::string(name) + ": expected real numbers, got dtype " + std::string(py::str(a.dtype())));
  if (a.ndim() != py::ssize_t(shape.size())) {
    std::string want = "[";
    for (size_t k = 0; k < shape.size(); ++k) want += (k ? ", " : "") + (shape[k] < 0 ? std::string("n") : std::to_string(shape[k]));
    throw py::value_error(std::string(name) + ": expected shape " + want + "], got " + std::to_string(a.ndim()) + " dimension(s)");
  }
  for (size_t k = 0; k < shape.size(); ++k)
    if (shape[k] >= 0 && a.shape(py::ssize_t(k)) != shape[k])
      throw py::value_error(std::string(name) + ": dimension " + std::to_string(k) + " is " + std::to_string(a.shape(py::ssize_t(k))) + ", expected " +
                            std::to_string(shape[k]));
  // No copy for C-contiguous float32; otherwise one, converting the dtype.
  FloatArray f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!f) throw py::type_error(std::string(name) + ": cannot be read as float32");
  const float* p = f.data();
  const size_t n = size_t(f.size());
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) {
      const size_t row = f.ndim() > 1 ? size_t(f.size() / f.shape(0)) : 1;
      throw py::value_error(std::string(name) + ": element " + std::to_string(i / row) + " is not finite (" + std::to_string(p[i]) + ")");
    }
  return f;
}

/// A NumPy array owning `v` (moved, no copy), of `shape`.
template <typename T>
py::array_t<T> to_array(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<T>(std::move(v));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owned->data(), free);
}

/// Eigen fixed vectors packed back to back, as a float array [n, D].
template <int D>
py::array_t<float> rows_of(const std::vector<Eigen::Matrix<float, D, 1>>& v) {
  std::vector<float> out(v.size() * D);
  if (!v.empty()) std::memcpy(out.data(), v.data(), out.size() * sizeof(float));
  return to_array(std::move(out), {py::ssize_t(v.size()), D});
}

/// An optional number keyword (None: the library's default), checked with the bounds the
/// command line's flag has, in the same words.
std::optional<double> number_or_none(const py::object& value, const char* name, const Bounds& bounds) {
  if (value.is_none()) return std::nullopt;
  if (py::isinstance<py::bool_>(value) || !(py::isinstance<py::int_>(value) || py::isinstance<py::float_>(value) || py::hasattr(value, "__float__")))
    throw py::type_error(std::string(name) + ": expected a number or None, got " + std::string(py::str(py::type::of(value).attr("__name__"))));
  const double x = value.cast<double>();
  check_within(name, x, bounds);
  return x;
}

void require_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    PyErr_SetString(PyExc_FileNotFoundError, (path + ": no such file or folder").c_str());
    throw py::error_already_set();
  }
}

// ------------------------------------------------------------------ messages

/// A library message with the command line's flags named as this module's keywords:
/// "--model-frames F" -> "frames=F", "--tau" -> "tau=". Flags without a keyword stay.
std::string as_keywords(const std::string& message) {
  static const std::vector<std::pair<std::string, std::string>> kKeywords = [] {
    std::vector<std::pair<std::string, std::string>> k = {
      {"--model-frames", "frames"}, {"--model-time-range", "time_range"}, {"--scene-format", "format"}, {"--model-evaluation", "evaluation"},
      {"--still-tolerance", "still_tolerance"}, {"--camera-format", "format"}, {"--train-cameras", "train_cameras"}, {"--downscale", "downscale"},
      {"--frames", "frames"}, {"--times", "times"}, {"--mode", "mode"}, {"--stride", "stride"}, {"--tau", "tau"}, {"--hit-cache", "hit_cache_mb"},
      {"--divisions", "divisions"}, {"--strategy", "strategy"}, {"--trajectories", "trajectories"}, {"--weighting", "weighting"},
      {"--background", "background"}};
    // The rows' own parameters: each flag is its key's spelling, each keyword the key.
    for (const RowParameter* p : model_format_table().parameters()) k.emplace_back(Spelling{}(p->key), p->key);
    return k;
  }();
  std::string out;
  for (size_t i = 0; i < message.size();) {
    bool replaced = false;
    if (message.compare(i, 2, "--") == 0 && (i == 0 || !std::isalnum(static_cast<unsigned char>(message[i - 1])))) {
      size_t end = i + 2;
      while (end < message.size() && (std::isalnum(static_cast<unsigned char>(message[end])) || message[end] == '-')) ++end;
      const std::string flag = message.substr(i, end - i);
      for (const auto& [f, keyword] : kKeywords)
        if (flag == f) {
          // "--model-frames F" -> "frames=F": the value the flag names follows without the
          // space; a word of the sentence ("--tau must be ...") keeps it.
          size_t word_end = end + 1;
          while (word_end < message.size() && message[word_end] != ' ' && message[word_end] != ',' && message[word_end] != ')') ++word_end;
          static const char* kWords[] = {"and", "or", "must", "is", "expects", "takes", "given", "has", "needs", "with", "to", "for", "of", "in", "at"};
          const std::string next = end < message.size() && message[end] == ' ' ? message.substr(end + 1, word_end - end - 1) : "";
          const bool value = !next.empty() && std::none_of(std::begin(kWords), std::end(kWords), [&](const char* w) { return next == w; });
          out += keyword + "=";
          i = end + (value ? 1 : 0);
          replaced = true;
          break;
        }
    }
    if (!replaced) out += message[i++];
  }
  return out;
}

// ------------------------------------------------------------------ progress

/// The Python exception that stopped a long call (Ctrl-C's KeyboardInterrupt, or what a
/// progress callback raised), kept while fillgs::Cancelled unwinds the library; the
/// translator registered for Cancelled raises it again, unchanged. Touched with the GIL held.
struct PendingError {
  PyObject *type = nullptr, *value = nullptr, *trace = nullptr;
  void keep() {  // the error set in the interpreter now
    clear();
    PyErr_Fetch(&type, &value, &trace);
  }
  void raise() {  // sets it again (or KeyboardInterrupt where none was kept)
    if (!type) {
      PyErr_SetNone(PyExc_KeyboardInterrupt);
      return;
    }
    PyErr_Restore(type, value, trace);
    type = value = trace = nullptr;
  }
  void clear() {
    Py_XDECREF(type), Py_XDECREF(value), Py_XDECREF(trace);
    type = value = trace = nullptr;
  }
};
PendingError& pending_error() {
  static PendingError* p = new PendingError;  // never destroyed: no Python object outlives the interpreter here
  return *p;
}

/// Progress reported to a Python callable (label, done, total), at most ten times a second
/// and at the end; with `true`, to a tqdm bar where tqdm is installed (else nowhere).
class PyProgress : public Progress {
 public:
  explicit PyProgress(const py::object& how) {
    if (how.is_none() || (py::isinstance<py::bool_>(how) && !how.cast<bool>())) return;
    if (py::isinstance<py::bool_>(how)) {
      try {
        tqdm_ = py::module_::import("tqdm").attr("tqdm");
      } catch (const py::error_already_set&) {
        PyErr_Clear();
        // Said once, not silently dropped: the caller asked for a bar.
        if (PyErr_WarnEx(PyExc_RuntimeWarning, "progress=True: tqdm is not installed, so no progress bar is shown (install tqdm, or pass a callable (label, done, total))", 1) != 0)
          throw py::error_already_set();
      }
      return;
    }
    if (!PyCallable_Check(how.ptr())) throw py::type_error("progress: expected a callable (label, done, total), True or None");
    callback_ = how;
  }
  ~PyProgress() override {
    py::gil_scoped_acquire gil;
    close_bar();
    callback_ = py::object();
    tqdm_ = py::object();
  }
  void start(const std::string& label, size_t total) override {
    label_ = label;
    total_ = total;
    done_ = 0;
    report(true);
  }
  void advance(size_t steps) override {
    done_ += steps;
    report(false);
  }
  void finish() override { report(true); }

 private:
  void report(bool always) {
    const auto now = std::chrono::steady_clock::now();
    if (!always && now - last_ < std::chrono::milliseconds(100) && done_ < total_) return;
    last_ = now;
    py::gil_scoped_acquire gil;
    // Ctrl-C stops the call within a tenth of a second of the library's next step, even
    // with no callback: the handler only sets a flag, which is looked at here.
    if (PyErr_CheckSignals() != 0) stop();
    if (!callback_ && !tqdm_) return;
    try {
      show();
    } catch (py::error_already_set& e) {
      e.restore();  // the callback's own exception, passed through unchanged
      stop();
    }
  }
  [[noreturn]] void stop() {
    pending_error().keep();
    throw Cancelled();
  }
  void show() {
    if (callback_) {
      callback_(label_, done_, total_);
      return;
    }
    if (!bar_ || bar_label_ != label_) {
      close_bar();
      bar_ = tqdm_(py::arg("total") = total_, py::arg("desc") = label_, py::arg("leave") = false);
      bar_label_ = label_;
      shown_ = 0;
    }
    if (done_ > shown_) bar_.attr("update")(done_ - shown_);
    shown_ = done_;
  }
  void close_bar() {
    if (bar_) bar_.attr("close")();
    bar_ = py::object();
  }
  py::object callback_, tqdm_, bar_;
  std::string label_, bar_label_;
  size_t total_ = 0, done_ = 0, shown_ = 0;
  std::chrono::steady_clock::time_point last_{};
};

// ------------------------------------------------------------------ models

/// A model: any scene the command line reads, or Gaussians from arrays.
struct Model {
  std::shared_ptr<const GaussianCloud> cloud;
  std::string source;
};

/// The Gaussians at normalised time t as arrays, in the files' parametrisation.
py::dict state_at(const Model& m, double t) {
  check_within("t", t, within(0, 1));  // as render() and the command line take times: never clamped
  FrameGaussians g;
  {
    py::gil_scoped_release release;
    g = frame_at(*m.cloud, t);
  }
  const size_t N = g.size();
  std::vector<float> log_scales(N * 3), logits(N);
  for (size_t i = 0; i < N; ++i) {
    for (int a = 0; a < 3; ++a) log_scales[i * 3 + size_t(a)] = std::log(g.scales[i][a]);
    logits[i] = logit(g.opacities[i]);
  }
  const size_t K = size_t((g.sh_degree + 1) * (g.sh_degree + 1));
  std::vector<float> sh(g.sh, g.sh + N * K * 3);
  py::dict d;
  d["means"] = rows_of<3>(g.means);
  d["log_scales"] = to_array(std::move(log_scales), {py::ssize_t(N), 3});
  d["quaternions"] = rows_of<4>(g.rotations);
  d["opacity_logits"] = to_array(std::move(logits), {py::ssize_t(N)});
  d["sh"] = to_array(std::move(sh), {py::ssize_t(N), py::ssize_t(K), 3});
  return d;
}

/// Gaussians of one frame from a dict of arrays (means [N,3], log_scales [N,3], quaternions
/// [N,4] (w, x, y, z), opacity_logits [N], sh [N,K,3] optional), checked.
ModelState state_from(const py::handle& frame, const char* what, py::ssize_t n) {
  if (!py::isinstance<py::dict>(frame)) throw py::type_error(std::string(what) + ": expected a dict of arrays (means, log_scales, quaternions, opacity_logits[, sh])");
  const py::dict d = py::reinterpret_borrow<py::dict>(frame);
  for (const char* key : {"means", "log_scales", "quaternions", "opacity_logits"})
    if (!d.contains(key)) throw py::key_error(std::string(what) + ": no '" + key + "'");
  const std::string w(what);
  const FloatArray means = float_array(d["means"], (w + " means").c_str(), {n, 3});
  const py::ssize_t N = means.shape(0);
  const FloatArray scales = float_array(d["log_scales"], (w + " log_scales").c_str(), {N, 3});
  const FloatArray quats = float_array(d["quaternions"], (w + " quaternions").c_str(), {N, 4});
  const FloatArray logits = float_array(d["opacity_logits"], (w + " opacity_logits").c_str(), {N});
  if (d.contains("sh") && !d["sh"].is_none()) {
    const FloatArray sh = float_array(d["sh"], (w + " sh").c_str(), {N, -1, 3});
    return gaussians_from_arrays(size_t(N), means.data(), scales.data(), quats.data(), logits.data(), sh.data(), size_t(sh.shape(1)), w);
  }
  return gaussians_from_arrays(size_t(N), means.data(), scales.data(), quats.data(), logits.data(), nullptr, 0, w);
}

GaussianCloud cloud_from(const ModelState& s) {
  GaussianCloud c;
  c.sh_degree = s.sh_degree;
  c.means = s.means;
  c.log_scales = s.log_scales;
  c.rotations = s.rotations;
  c.opacity_logits = s.opacity_logits;
  c.sh = s.sh;
  return c;
}

/// A caller's Gaussians frame by frame: `frame(f)` returns frame f's arrays (f = 0 … F-1),
/// called with the GIL held, at most once per frame while the frames near the current one
/// are kept (three).
class CallerFrames : public MotionSource {
 public:
  CallerFrames(py::object fn, int frames, ModelState first, const StillRule& rule)
      : fn_(std::move(fn)), frames_(frames), rule_(rule), departure_(first.size(), 0.0f), first_(std::move(first)) {}
  ~CallerFrames() override {
    py::gil_scoped_acquire gil;
    fn_ = py::object();
    failure_ = {};
  }
  std::shared_ptr<const ModelState> evaluate(double t, const std::vector<uint32_t>& rows) const override {
    const int f = int(std::lround(std::clamp(t, 0.0, 1.0) * double(frames_ - 1)));
    std::lock_guard<std::mutex> lock(mutex_);
    std::shared_ptr<const ModelState> all;
    for (const auto& k : kept_)
      if (k.first == f) all = k.second;
    if (!all) {
      if (failed_) throw Error("the frame function failed before");
      {  // the caller's function, with the GIL
        py::gil_scoped_acquire gil;
        try {
          auto s = std::make_shared<ModelState>(state_from(fn_(f), ("frame " + std::to_string(f)).c_str(), py::ssize_t(first_.size())));
          if (s->sh_degree != first_.sh_degree)
            throw py::value_error("frame " + std::to_string(f) + " sh: degree " + std::to_string(s->sh_degree) + ", frame 0 had " + std::to_string(first_.sh_degree));
          all = s;
        } catch (py::error_already_set& e) {
          failed_ = true;
          failure_ = {e.type(), e.value(), e.trace()};
          throw Error("the frame function raised at frame " + std::to_string(f));
        } catch (const std::exception& e) {
          failed_ = true;
          message_ = e.what();
          throw Error(message_);
        }
      }
      // The still rule as it sees each frame once (the GIL released): every Gaussian's largest
      // departure from frame 0, not measured again once it moves.
      tbb::parallel_for(tbb::blocked_range<size_t>(0, all->size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i)
          if (departure_[i] <= 1.0f) departure_[i] = std::max(departure_[i], still_departure(*all, i, first_, i, rule_));
      });
      if (kept_.size() == 3) kept_.erase(kept_.begin());
      kept_.emplace_back(f, all);
    }
    bool identity = rows.size() == all->size();
    for (size_t i = 0; identity && i < rows.size(); ++i) identity = rows[i] == i;
    if (identity) return all;
    return std::make_shared<ModelState>(all->rows(rows));
  }
  int frame_count() const override { return frames_; }
  bool one_pass() const override { return true; }  // the caller's network runs once per frame
  /// After a pass over every frame: whether Gaussian i stayed within the still rule's
  /// tolerances of frame 0 at all of them.
  bool still(size_t i) const { return departure_[i] <= 1.0f; }
  /// After the engine returns (GIL held): the frame function's own exception, raised again,
  /// or a check's ValueError.
  void raise_failure() const {
    if (!failed_) return;
    if (failure_[0]) {
      PyErr_Restore(failure_[0].inc_ref().ptr(), failure_[1].inc_ref().ptr(), failure_[2].inc_ref().ptr());
      throw py::error_already_set();
    }
    throw py::value_error(message_);
  }

 private:
  py::object fn_;
  int frames_;
  StillRule rule_;
  mutable std::vector<float> departure_;
  ModelState first_;
  mutable std::mutex mutex_;
  mutable std::vector<std::pair<int, std::shared_ptr<const ModelState>>> kept_;
  mutable bool failed_ = false;
  mutable std::array<py::object, 3> failure_;
  mutable std::string message_;
};

/// A model from a caller's frame function: frame 0 read now; every Gaussian moves.
std::pair<Model, std::shared_ptr<const CallerFrames>> model_from_frames(const py::object& fn, int frames, const StillRule& rule) {
  if (!PyCallable_Check(fn.ptr())) throw py::type_error("frames: expected a callable f -> dict of arrays");
  if (frames < 1) throw py::value_error("frame_count: " + std::to_string(frames) + ", expected at least 1");
  ModelState first = state_from(fn(0), "frame 0", -1);
  auto c = std::make_shared<GaussianCloud>(cloud_from(first));
  auto source = std::make_shared<CallerFrames>(fn, frames, std::move(first), rule);
  if (frames > 1) {
    c->motion = MotionModel::Evaluated;
    c->dynamic_ids.resize(c->size());
    for (size_t i = 0; i < c->size(); ++i) c->dynamic_ids[i] = uint32_t(i);
    c->source_rows = c->dynamic_ids;
    c->source = source;
  }
  return {Model{c, "frames"}, source};
}

/// A row's own parameters as the module lists them: {key: {default, help}}.
py::dict parameters_of(const RowHeading& row) {
  py::dict out;
  for (const RowParameter* q : row.parameters) out[q->key.c_str()] = py::dict(py::arg("default") = q->default_text, py::arg("help") = q->help);
  return out;
}

/// Where the keywords of one kind of row go: the parameters its rows declare
/// (base/row_table.hpp), and the values they set.
struct KeywordRows {
  std::vector<const RowParameter*> parameters;
  RowParameterValues* values;
};

/// Sets each keyword in the values of the rows that declare it, checked as the command line
/// checks its flag; a keyword no row declares is a TypeError naming the ones they do.
void set_row_parameters(const py::kwargs& given, const char* function, std::initializer_list<KeywordRows> rows) {
  for (const auto& [key, value] : given) {
    const std::string k = py::str(key).cast<std::string>();
    const RowParameter* p = nullptr;
    RowParameterValues* values = nullptr;
    std::vector<std::string> keys;
    for (const KeywordRows& r : rows)
      for (const RowParameter* q : r.parameters) {
        keys.push_back(q->key);
        if (!p && q->key == k) p = q, values = r.values;
      }
    if (!p) throw py::type_error(std::string(function) + "() got an unexpected keyword argument '" + k + "' (its rows' parameters: " + join_names(keys) + ")");
    const bool text = p->kind == RowParameter::Kind::Choice || p->kind == RowParameter::Kind::Text;
    if (py::isinstance<py::bool_>(value) || (text ? !py::isinstance<py::str>(value) : !(py::isinstance<py::int_>(value) || py::isinstance<py::float_>(value))))
      throw py::type_error(k + ": expected " + (text ? "a string" : p->kind == RowParameter::Kind::Integer ? "an integer" : "a number"));
    values->set(*p, py::str(value).cast<std::string>(), Spelling{false});
  }
}

Model load_model(const std::string& path, const std::string& format, int frames, const std::string& time_range, const std::string& evaluation,
                 const py::object& still_tolerance, const py::object& still_times, const py::object& progress, const py::kwargs& parameters) {
  require_file(path);
  SceneReadOptions o;
  set_row_parameters(parameters, "load_model", {{model_format_table().parameters(), &o.parameters}});
  o.format = format == "auto" ? format : model_format(format).name;
  check_within("frames", frames, at_least(0));  // --model-frames' bounds
  o.model_frames = frames;
  o.model_time_range = time_range;
  o.model_evaluation = parse_name<ModelEvaluation>(evaluation);
  if (const auto x = number_or_none(still_tolerance, "still_tolerance", at_least(0))) o.still.position = float(*x);
  if (!still_times.is_none()) {  // what `fillgs observe --frames F` / `--times` tell its still rule
    const auto t = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(still_times);
    if (!t || t.ndim() != 1) throw py::value_error("still_times: expected a 1-D array of times in [0, 1]");
    for (py::ssize_t i = 0; i < t.size(); ++i)
      if (!(t.data()[i] >= 0.0 && t.data()[i] <= 1.0))
        throw py::value_error("still_times: element " + std::to_string(i) + " is " + std::string(py::str(py::float_(t.data()[i]))) + ", not a time in [0, 1]");
    o.still.times.assign(t.data(), t.data() + t.size());
    std::sort(o.still.times.begin(), o.still.times.end());
  }
  PyProgress shown(progress);
  o.progress = &shown;
  std::shared_ptr<GaussianCloud> c;
  {
    py::gil_scoped_release release;
    c = std::make_shared<GaussianCloud>(read_scene(path, o));
  }
  return Model{c, path};
}

// ------------------------------------------------------------------ cameras

struct Cameras {
  std::vector<Camera> list;
};

Cameras read_cameras_py(const std::string& path, const std::string& format, int width, int height) {
  require_file(path);
  CameraReadOptions o;
  o.format = parse_name<CameraFormat>(format);
  o.width = width;
  o.height = height;
  Cameras c;
  c.list = read_cameras(path, o);
  return c;
}

/// One value per camera: a scalar for every camera, or an array of shape [C] (float64).
std::vector<double> per_camera(const py::handle& v, py::ssize_t C, const char* name) {
  py::array a = py::array(py::module_::import("numpy").attr("asarray")(v));
  if (a.ndim() == 0) a = py::array(py::module_::import("numpy").attr("full")(C, v));
  const auto f = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!f || f.ndim() != 1 || f.shape(0) != C) throw py::value_error(std::string(name) + ": expected one value or shape [" + std::to_string(C) + "]");
  return std::vector<double>(f.data(), f.data() + C);
}

/// The cameras' times (None: NaN, a fixed rig's camera at every frame) and names (None: camI).
std::vector<double> camera_times(const py::handle& time, py::ssize_t C) {
  return time.is_none() ? std::vector<double>(size_t(C), std::numeric_limits<double>::quiet_NaN()) : per_camera(time, C, "time");
}
std::vector<std::string> camera_names(const py::object& names, py::ssize_t C) {
  std::vector<std::string> out;
  if (names.is_none()) {
    for (py::ssize_t i = 0; i < C; ++i) out.push_back("cam" + std::to_string(i));
    return out;
  }
  if (py::isinstance<py::str>(names) || !py::isinstance<py::sequence>(names)) throw py::type_error("names: expected a sequence of " + std::to_string(C) + " strings");
  const py::sequence seq = py::reinterpret_borrow<py::sequence>(names);
  if (py::ssize_t(py::len(seq)) != C) throw Error("names: " + std::to_string(py::len(seq)) + " names for " + std::to_string(C) + " cameras");
  for (const py::handle n : seq) out.push_back(py::str(n).cast<std::string>());
  return out;
}

/// Cameras from arrays: K [C,3,3], world_to_camera [C,4,4], width and height [C] (or one
/// value), time [C] (NaN: a fixed rig's camera, at every frame) and names; checked by the
/// library (io/array_input.hpp).
Cameras cameras_from(const py::handle& K, const py::handle& w2c, const py::handle& width, const py::handle& height, const py::handle& time,
                     const py::object& names) {
  const FloatArray k = float_array(K, "K", {-1, 3, 3});
  const py::ssize_t C = k.shape(0);
  const FloatArray m = float_array(w2c, "world_to_camera", {C, 4, 4});
  const std::vector<double> W = per_camera(width, C, "width"), H = per_camera(height, C, "height"), T = camera_times(time, C);
  const std::vector<std::string> label = camera_names(names, C);
  Cameras out;
  for (py::ssize_t i = 0; i < C; ++i)
    out.list.push_back(camera_from_arrays(k.data() + i * 9, m.data() + i * 16, W[size_t(i)], H[size_t(i)], T[size_t(i)], label[size_t(i)], size_t(i)));
  return out;
}

/// Cameras as the 3DGS family holds them: R [C,3,3] (the transpose of the world-to-camera
/// rotation), T [C,3], FoVx and FoVy [C] (radians), width and height, time [C] or None.
Cameras cameras_from_3dgs_py(const py::handle& R, const py::handle& T, const py::handle& fov_x, const py::handle& fov_y, const py::handle& width,
                             const py::handle& height, const py::handle& time, const py::object& names) {
  using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
  const F64 r = F64::ensure(R), t = F64::ensure(T);
  if (!r || r.ndim() != 3 || r.shape(1) != 3 || r.shape(2) != 3) throw py::value_error("R: expected shape [C, 3, 3]");
  const py::ssize_t C = r.shape(0);
  if (!t || t.ndim() != 2 || t.shape(0) != C || t.shape(1) != 3) throw py::value_error("T: expected shape [" + std::to_string(C) + ", 3]");
  const std::vector<double> fx = per_camera(fov_x, C, "fov_x"), fy = per_camera(fov_y, C, "fov_y"), W = per_camera(width, C, "width"),
                            H = per_camera(height, C, "height"), times = camera_times(time, C);
  const std::vector<std::string> label = camera_names(names, C);
  Cameras out;  // non-finite R or T: refused by camera_from_arrays, which camera_from_3dgs ends in
  for (py::ssize_t i = 0; i < C; ++i)
    out.list.push_back(camera_from_3dgs(r.data() + i * 9, t.data() + i * 3, fx[size_t(i)], fy[size_t(i)], W[size_t(i)], H[size_t(i)], times[size_t(i)],
                                        label[size_t(i)], size_t(i)));
  return out;
}

/// The cameras as the 3DGS family holds them (camera_to_3dgs): what E-D3DGS's and
/// 4DGaussians' scene/cameras.py Camera takes.
py::dict cameras_to_3dgs(const Cameras& c) {
  const size_t C = c.list.size();
  std::vector<double> R(C * 9), T(C * 3), fx(C), fy(C), time(C);
  std::vector<int32_t> W(C), H(C);
  for (size_t i = 0; i < C; ++i) {
    const Camera& x = c.list[i];
    const Camera3dgs g = camera_to_3dgs(x, i);
    std::copy_n(g.R, 9, &R[i * 9]);
    std::copy_n(g.T, 3, &T[i * 3]);
    fx[i] = g.fov_x, fy[i] = g.fov_y, W[i] = x.width, H[i] = x.height, time[i] = x.time;
  }
  py::dict d;
  d["R"] = to_array(std::move(R), {py::ssize_t(C), 3, 3});
  d["T"] = to_array(std::move(T), {py::ssize_t(C), 3});
  d["fov_x"] = to_array(std::move(fx), {py::ssize_t(C)});
  d["fov_y"] = to_array(std::move(fy), {py::ssize_t(C)});
  d["width"] = to_array(std::move(W), {py::ssize_t(C)});
  d["height"] = to_array(std::move(H), {py::ssize_t(C)});
  d["time"] = to_array(std::move(time), {py::ssize_t(C)});
  return d;
}

py::dict cameras_arrays(const Cameras& c) {
  const size_t C = c.list.size();
  std::vector<double> K(C * 9, 0.0), M(C * 16, 0.0), T(C);
  std::vector<int32_t> W(C), H(C);
  for (size_t i = 0; i < C; ++i) {
    const Camera& x = c.list[i];
    K[i * 9 + 0] = x.fx, K[i * 9 + 4] = x.fy, K[i * 9 + 2] = x.cx, K[i * 9 + 5] = x.cy, K[i * 9 + 8] = 1.0;
    for (int r = 0; r < 3; ++r) {
      for (int q = 0; q < 3; ++q) M[i * 16 + size_t(r * 4 + q)] = x.R(r, q);
      M[i * 16 + size_t(r * 4 + 3)] = x.t[r];
    }
    M[i * 16 + 15] = 1.0;
    W[i] = x.width, H[i] = x.height, T[i] = x.time;
  }
  py::dict d;
  d["K"] = to_array(std::move(K), {py::ssize_t(C), 3, 3});
  d["world_to_camera"] = to_array(std::move(M), {py::ssize_t(C), 4, 4});
  d["width"] = to_array(std::move(W), {py::ssize_t(C)});
  d["height"] = to_array(std::move(H), {py::ssize_t(C)});
  d["time"] = to_array(std::move(T), {py::ssize_t(C)});
  return d;
}

// ------------------------------------------------------------------ observe

/// The observation tables of a model (or of a caller's frames) under `cameras`, as the CLI's
/// `observe` computes and writes them: counts [T, N] (uint8 where at most 255 views share a
/// time, else uint16), speed and deficiency [T, N] float32 (0 for static Gaussians), times
/// [T], dynamic_ids [M]. Written straight into the arrays returned (no second copy).
py::dict observe_py(const Model& model, const std::shared_ptr<const CallerFrames>& caller, const Cameras& cameras, int frames,
                    const py::object& times_arg, const std::string& mode, int stride, const py::object& tau, const py::object& hit_cache_mb,
                    const py::object& progress) {
  const GaussianCloud& cloud = *model.cloud;
  if (cameras.list.empty()) throw py::value_error("cameras: none");
  // The command line's check of --frames and --times (visibility.hpp), with the tables'
  // memory: this call holds them as arrays.
  std::optional<std::vector<double>> asked;
  if (!times_arg.is_none()) {
    if (caller) throw py::value_error("times: a frame function gives whole frames only; leave times out");
    const auto t = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(times_arg);
    if (!t || t.ndim() != 1 || t.size() == 0) throw py::value_error("times: expected a non-empty 1-D array of times in [0, 1]");
    asked.emplace(t.data(), t.data() + t.size());
  }
  const ObserveTimes requested = observe_times(cloud, cameras.list, frames, asked ? &*asked : nullptr, true, Spelling{false});
  frames = requested.frames;
  const std::vector<double>& times = requested.times;
  const double frame_step = requested.frame_step;
  ObservationOptions o;
  o.visibility.mode = parse_name<VisibilityMode>(mode);
  check_within("stride", stride, stride_bounds());  // the bounds --stride, --tau and --hit-cache declare
  o.visibility.stride = stride;
  if (const auto x = number_or_none(tau, "tau", tau_bounds())) o.visibility.min_weight = float(*x);
  if (const auto x = number_or_none(hit_cache_mb, "hit_cache_mb", hit_cache_mb_bounds())) o.static_hit_cache_bytes = size_t(*x * 1048576.0);
  const size_t T = times.size(), N = cloud.size();
  const bool narrow = counts_fit_uint8(max_views_per_frame(cameras.list, times, frame_step));
  py::array counts = narrow ? py::array(py::array_t<uint8_t>({py::ssize_t(T), py::ssize_t(N)})) : py::array(py::array_t<uint16_t>({py::ssize_t(T), py::ssize_t(N)}));
  py::array_t<float> speed({py::ssize_t(T), py::ssize_t(N)}), deficiency({py::ssize_t(T), py::ssize_t(N)});
  void* cp = counts.mutable_data();
  float* sp = speed.mutable_data();
  float* dp = deficiency.mutable_data();
  PyProgress shown(progress);
  ObservationSummary summary;
  {
    py::gil_scoped_release release;
    std::fill(sp, sp + T * N, 0.0f);
    std::fill(dp, dp + T * N, 0.0f);
    const auto sink = [&](const FrameObservation& fo) {
      const size_t f = size_t(fo.frame);
      if (narrow) {
        uint8_t* row = static_cast<uint8_t*>(cp) + f * N;
        for (size_t g = 0; g < N; ++g) row[g] = uint8_t(fo.counts[g]);
      } else {
        std::memcpy(static_cast<uint16_t*>(cp) + f * N, fo.counts, N * sizeof(uint16_t));
      }
      const size_t M = cloud.dynamic_count();
      for (size_t j = 0; j < M; ++j) {
        sp[f * N + cloud.dynamic_ids[j]] = fo.dynamic_speed[j];
        dp[f * N + cloud.dynamic_ids[j]] = fo.dynamic_deficiency[j];
      }
    };
    try {
      summary = observe(cloud, cameras.list, times, frame_step, o, sink, shown);
    } catch (const Error&) {
      if (caller) {
        py::gil_scoped_acquire gil;
        caller->raise_failure();
      }
      throw;
    }
  }
  py::dict d;
  d["counts"] = counts;
  d["speed"] = speed;
  d["deficiency"] = deficiency;
  d["times"] = py::array_t<double>(py::ssize_t(T), times.data());
  std::vector<uint32_t> ids;
  for (uint32_t g : cloud.dynamic_ids) {
    // A frame function's Gaussians the still rule found still over the pass are static: no
    // speed, no deficiency (deficiency = speed / (1 + count), so nothing else changes).
    if (caller && caller->still(g)) {
      for (size_t f = 0; f < T; ++f) sp[f * N + g] = dp[f * N + g] = 0.0f;
      continue;
    }
    ids.push_back(g);
  }
  const py::ssize_t M = py::ssize_t(ids.size());
  d["dynamic_ids"] = to_array(std::move(ids), {M});
  d["views"] = py::int_(summary.views);
  d["seconds"] = py::float_(summary.seconds_total);
  return d;
}

// ------------------------------------------------------------------ load_observation

/// Counts as the folder stores them: uint8 where it does, else uint16.
py::array count_array(const std::vector<uint16_t>& v, bool narrow, std::vector<py::ssize_t> shape) {
  if (!narrow) return to_array(std::vector<uint16_t>(v), std::move(shape));
  return to_array(std::vector<uint8_t>(v.begin(), v.end()), std::move(shape));
}

py::dict load_observation_py(const std::string& path, bool dense) {
  require_file(path);
  ObservationFolder o;
  {
    py::gil_scoped_release release;
    o = read_observation(path);
  }
  const py::ssize_t T = py::ssize_t(o.frames()), N = py::ssize_t(o.gaussians), M = py::ssize_t(o.dynamic_ids.size());
  py::dict d;
  d["tables"] = to_string(o.layout);
  d["times"] = to_array(std::vector<double>(o.times), {T});
  d["dynamic_ids"] = to_array(std::vector<uint32_t>(o.dynamic_ids), {M});
  if (dense) {  // the [T, N] view, as observe() returns it
    std::vector<uint16_t> counts(size_t(T) * size_t(N));
    std::vector<float> speed(counts.size(), 0.0f), deficiency(counts.size(), 0.0f);
    for (size_t f = 0; f < size_t(T); ++f) {
      o.count_row(f, counts.data() + f * size_t(N));
      for (size_t j = 0; j < size_t(M); ++j) {
        speed[f * size_t(N) + o.dynamic_ids[j]] = o.dynamic_speed[f * size_t(M) + j];
        deficiency[f * size_t(N) + o.dynamic_ids[j]] = o.dynamic_deficiency[f * size_t(M) + j];
      }
    }
    d["counts"] = count_array(counts, o.narrow, {T, N});
    d["speed"] = to_array(std::move(speed), {T, N});
    d["deficiency"] = to_array(std::move(deficiency), {T, N});
    return d;
  }
  if (o.layout == TableLayout::Compact) {
    const py::ssize_t R = py::ssize_t(o.static_rows), E = py::ssize_t(o.change_ids.size());
    d["count_static"] = count_array(o.count_static, o.narrow, {R, N});
    d["count_rows"] = to_array(std::move(o.count_rows), {T});
    d["count_dynamic"] = count_array(o.count_dynamic, o.narrow, {T, M});
    d["count_change_offsets"] = to_array(std::move(o.change_offsets), {T + 1});
    d["count_change_ids"] = to_array(std::move(o.change_ids), {E});
    d["count_change_values"] = count_array(o.change_values, o.narrow, {E});
  } else {
    d["count"] = count_array(o.counts, o.narrow, {T, N});
  }
  d["speed_dynamic"] = to_array(std::move(o.dynamic_speed), {T, M});
  d["deficiency_dynamic"] = to_array(std::move(o.dynamic_deficiency), {T, M});
  return d;
}

// ------------------------------------------------------------------ render

py::dict render_py(const Model& model, const Cameras& cameras, size_t index, double t, const std::vector<float>& background) {
  if (index >= cameras.list.size()) throw py::index_error("camera " + std::to_string(index) + ": there are " + std::to_string(cameras.list.size()));
  check_within("t", t, within(0, 1));  // as Model.at
  if (background.size() != 3) throw py::value_error("background: expected three values");
  for (size_t k = 0; k < 3; ++k) check_within("background[" + std::to_string(k) + "]", background[k], within(0, 1));  // --background's range
  RenderOptions o;
  o.depth = true;
  o.background = Vec3f(background[0], background[1], background[2]);
  RenderOutput r;
  {
    py::gil_scoped_release release;
    const FrameGaussians g = frame_at(*model.cloud, t);
    r = render(g, cameras.list[index], o);
  }
  const py::ssize_t H = r.height, W = r.width;
  py::dict d;
  d["colour"] = to_array(std::move(r.rgb), {H, W, 3});
  d["depth"] = to_array(std::move(r.depth), {H, W});
  d["alpha"] = to_array(std::move(r.alpha), {H, W});
  return d;
}

// ------------------------------------------------------------------ images and views

py::array_t<float> read_image_py(const std::string& path) {
  require_file(path);
  Image im = read_image(path);
  return to_array(std::move(im.pixels), {py::ssize_t(im.height), py::ssize_t(im.width), py::ssize_t(im.channels)});
}

/// A rig's views as training reads them (`--images`, `--cameras`, `--train-cameras`,
/// `--frames`, `--downscale`): the views' cameras, each at its time, and their images.
py::dict load_views(const std::string& images, const std::string& cameras, const std::vector<std::string>& only, const std::string& frames,
                    int downscale, const py::object& progress) {
  require_file(images);
  require_file(cameras);
  DatasetOptions o;
  o.cameras = only;
  o.frames = FrameRange::parse(frames);
  o.downscale = downscale;
  PyProgress shown(progress);
  std::unique_ptr<Dataset> d;
  {
    py::gil_scoped_release release;
    d = std::make_unique<Dataset>(Dataset::load(images, cameras, o, shown));
  }
  Cameras c;
  py::list imgs;
  std::vector<int32_t> source_frame;
  // A frame range keeps the video's times (frame f of the source's F at f / (F - 1), the model's
  // frames), not the chosen frames renumbered as a video of their own.
  const int F = d->source_frames();
  for (size_t i = 0; i < d->views().size(); ++i) {
    Camera cam = d->views()[i].camera;
    source_frame.push_back(d->views()[i].source_frame);
    if (F != d->frames()) cam.time = FrameGrid(F).time(d->views()[i].source_frame);
    c.list.push_back(cam);
    // 8-bit, as the command line holds them, handed over from the dataset (never twice in memory).
    imgs.append(to_array(d->take_image8(i), {py::ssize_t(cam.height), py::ssize_t(cam.width), 3}));
  }
  py::dict out;
  out["cameras"] = c;
  out["images"] = imgs;
  out["frames"] = F;
  out["source_frames"] = to_array(std::move(source_frame), {py::ssize_t(c.list.size())});
  return out;
}

/// Timed observed views of `cameras` over `frames` (0: the model's or the cameras' count).
std::pair<std::vector<ObservedView>, int> views_of(const GaussianCloud& cloud, const Cameras& cameras, int frames) {
  if (cameras.list.empty()) throw py::value_error("cameras: none");
  if (frames < 0) throw py::value_error("frames: " + std::to_string(frames) + ", expected at least 1");
  if (!frames) frames = observation_frames(cloud, cameras.list);
  if (!frames) throw py::value_error("cannot tell the frame count from the model or the cameras; give frames=F");
  std::vector<Camera> timed;
  for (const ObservedView& v : observed_views(cameras.list, frames)) timed.push_back(v.camera);
  return {observed_views(timed, frames), frames};
}

/// Images for `views` from a sequence of [H,W,3] arrays, checked against each view's size and
/// held as given, without a copy: uint8 (load_views', 0 … 255) or float32 in [0, 1] (C-contiguous;
/// any other dtype or layout is converted once). get(i) makes view i's floats when the library
/// asks for it, with no Python call, so it runs with the GIL released.
class ViewImages {
 public:
  ViewImages() = default;
  ViewImages(const py::object& images, const std::vector<ObservedView>& views, const char* name) {
    const py::sequence seq = py::reinterpret_borrow<py::sequence>(images);
    if (py::len(seq) != views.size())
      throw py::value_error(std::string(name) + ": " + std::to_string(py::len(seq)) + " images for " + std::to_string(views.size()) + " views");
    for (size_t i = 0; i < views.size(); ++i) {
      const Camera& c = views[i].camera;
      const std::string what = std::string(name) + " " + std::to_string(i);
      const py::handle item = seq[i];
      using U8 = py::array_t<uint8_t, py::array::c_style>;
      if (py::isinstance<py::array>(item) && py::reinterpret_borrow<py::array>(item).dtype().is(py::dtype::of<uint8_t>())) {
        const U8 a = U8::ensure(item);  // no copy where C-contiguous
        if (!a || a.ndim() != 3 || a.shape(0) != c.height || a.shape(1) != c.width || a.shape(2) != 3)
          throw py::value_error(what + ": expected a [" + std::to_string(c.height) + ", " + std::to_string(c.width) + ", 3] image");
        bytes_.push_back(a);
        floats_.emplace_back();
        is_bytes_.push_back(true);
      } else {
        floats_.push_back(float_array(item, what.c_str(), {c.height, c.width, 3}));
        bytes_.emplace_back();
        is_bytes_.push_back(false);
      }
    }
  }
  size_t size() const { return floats_.size(); }
  std::vector<float> get(size_t i) const {
    if (is_bytes_[i]) {
      const uint8_t* p = bytes_[i].data();
      std::vector<float> out(size_t(bytes_[i].size()));
      for (size_t k = 0; k < out.size(); ++k) out[k] = float(p[k]) / 255.0f;  // as Dataset::image
      return out;
    }
    return std::vector<float>(floats_[i].data(), floats_[i].data() + floats_[i].size());
  }

 private:
  std::vector<py::array_t<uint8_t, py::array::c_style>> bytes_;  // a default array_t is an empty array, not "none": is_bytes_ says which holds the image
  std::vector<FloatArray> floats_;
  std::vector<bool> is_bytes_;
};

// ------------------------------------------------------------------ exploration and selection

struct Grid {
  std::shared_ptr<const ExplorationGrid> grid;
};

Grid explore_py(const Model& model, const Cameras& cameras, int frames, int divisions, const py::object& progress) {
  check_within("divisions", divisions, divisions_bounds());  // as --divisions
  ExplorationOptions o;
  o.divisions = divisions;
  std::vector<double> sweep;
  if (frames > 0) sweep = FrameGrid(frames).times();
  PyProgress shown(progress);
  py::gil_scoped_release release;
  return Grid{std::make_shared<ExplorationGrid>(build_exploration_grid(*model.cloud, cameras.list, sweep, o, nullptr, shown))};
}

py::array_t<uint8_t> grid_labels(const Grid& g) {
  const Vec3i d = g.grid->dims();
  std::vector<uint8_t> out(size_t(d.x()) * size_t(d.y()) * size_t(d.z()));
  size_t k = 0;
  for (int z = 0; z < d.z(); ++z)
    for (int y = 0; y < d.y(); ++y)
      for (int x = 0; x < d.x(); ++x) out[k++] = uint8_t(g.grid->label(Vec3i(x, y, z)));
  return to_array(std::move(out), {d.z(), d.y(), d.x()});
}

py::array_t<uint8_t> grid_label_at(const Grid& g, const py::handle& points) {
  const FloatArray p = float_array(points, "points", {-1, 3});
  std::vector<uint8_t> out(size_t(p.shape(0)));
  for (size_t i = 0; i < out.size(); ++i) {
    const Vec3i ijk = g.grid->voxel_of(Vec3d(p.data()[i * 3], p.data()[i * 3 + 1], p.data()[i * 3 + 2]));
    out[i] = uint8_t(g.grid->inside(ijk) ? g.grid->label(ijk) : VoxelLabel::Unexplored);
  }
  return to_array(std::move(out), {p.shape(0)});
}

/// A trajectory chosen by select: poses at the trajectory's frame, each rendered over its patch frames.
struct PyTrajectory {
  Trajectory t;
};

py::dict select_py(const Model& model, const Cameras& cameras, int frames, const std::string& strategy, int trajectories, int views, int patch_frames,
                   uint64_t seed, const py::object& images, const py::object& grid, const py::object& progress, const py::kwargs& parameters) {
  const GaussianCloud& cloud = *model.cloud;
  if (cloud.size() == 0) throw py::value_error("model: no Gaussians, so no camera observes anything and there is no view to choose");
  SelectOptions o;
  o.strategy = strategy_row(strategy).name;
  o.trajectories = trajectories;
  o.views = views;
  o.patch_frames = patch_frames;
  o.seed = seed;
  set_row_parameters(parameters, "select", {{strategy_table().parameters(), &o.parameters}});
  check_select_options(o, Spelling{false});  // the command line's check, in the keywords' names
  SelectInput in;
  in.scene = &cloud;
  std::tie(in.views, in.frames) = views_of(cloud, cameras, frames);
  ViewImages pixels;
  if (!images.is_none()) {
    pixels = ViewImages(images, in.views, "images");
    in.image = [&pixels](size_t i) { return pixels.get(i); };
  }
  if (!grid.is_none() && !py::isinstance<Grid>(grid))
    throw py::type_error("grid: expected a fillgs.ExplorationGrid (from explore, select or read_grid) or None, got " +
                         std::string(py::str(py::type::of(grid).attr("__name__"))));
  std::shared_ptr<const ExplorationGrid> g = grid.is_none() ? nullptr : grid.cast<const Grid&>().grid;
  PyProgress shown(progress);
  SelectResult r;
  {
    py::gil_scoped_release release;
    std::vector<Camera> cams;
    for (const ObservedView& v : in.views) cams.push_back(v.camera);
    if (!g) g = std::make_shared<ExplorationGrid>(build_exploration_grid(cloud, cams, {}, ExplorationOptions(), nullptr, shown));
    in.grid = g.get();
    r = select_viewpoints(in, o, shown);
  }
  py::list trajs;
  for (Trajectory& t : r.trajectories) trajs.append(PyTrajectory{std::move(t)});
  py::dict d;
  d["trajectories"] = trajs;
  d["deficiency_scale"] = r.deficiency_scale;
  d["notes"] = r.notes;
  d["grid"] = Grid{g};
  return d;
}

// ------------------------------------------------------------------ weights

// ------------------------------------------------------------------ finetune

/// `fillgs finetune` as a function: the same job (method/finetune_job.hpp), checked in this
/// module's keywords, writing the same folder; returns its summary.json as a dict.
py::dict finetune_py(const Model& model, const std::string& images, const std::string& cameras, const std::string& out,
                     const std::vector<std::string>& train_cameras, const std::string& frames, int downscale, int iterations, int select_every,
                     const py::object& trajectories, uint64_t seed, const std::string& strategy, const std::string& weighting,
                     const py::object& refiner, const py::object& truth, const std::vector<std::string>& pool_cameras, int pool_budget,
                     const std::string& motion_rates, const py::object& refined_share, const py::object& reference_angle,
                     const py::object& artifact_strength, const py::object& support_window, const py::object& progress, const py::kwargs& parameters) {
  require_file(images);
  require_file(cameras);
  FinetuneJob job;
  job.images = images, job.cameras = cameras, job.out = out, job.seed = seed;
  job.data_options.cameras = train_cameras;
  job.data_options.frames = FrameRange::parse(frames);
  job.data_options.downscale = downscale;
  job.options.iterations = iterations;
  job.options.select_every = select_every;
  if (!trajectories.is_none()) job.options.trajectories = trajectories.cast<int>(), job.trajectories_given = true;
  job.options.select.strategy = strategy_row(strategy).name;
  job.options.weighting = parse_name<Weighting>(weighting);
  if (!refiner.is_none()) job.refiner = refiner.cast<std::string>();
  set_row_parameters(parameters, "finetune",
                     {{refiner_table().parameters(), &job.refiner_inputs.parameters}, {strategy_table().parameters(), &job.options.select.parameters}});
  job.refiner_inputs.reference = bench_reference_options(0.5, 1);  // as the command line's (add_refiner_flags)
  // The options several refiners share; their check is the job's (check_finetune_job).
  if (!reference_angle.is_none()) job.refiner_inputs.reference.angle_scale_degrees = number_or_none(reference_angle, "reference_angle", {}).value();
  if (!artifact_strength.is_none()) job.refiner_inputs.oracle.artifacts.strength = number_or_none(artifact_strength, "artifact_strength", {}).value();
  if (const auto w = number_or_none(support_window, "support_window", {})) {
    if (*w != std::floor(*w) || std::abs(*w) > 1e9) throw Error("support_window expects an integer, got " + number_text(*w));
    job.refiner_inputs.oracle.window = int(*w);
  }
  if (!truth.is_none()) job.refiner_inputs.truth = truth.cast<const Model&>().cloud.get();
  job.pool_cameras = pool_cameras;
  job.options.pool_budget = pool_budget;
  job.rates = motion_rates_of(parse_name<RatePreset>(motion_rates));
  if (const auto x = number_or_none(refined_share, "refined_share", within(0, 1))) job.refined_share = *x;
  job.model = *model.cloud;
  job.model_path = model.source;
  PyProgress shown(progress);
  {
    py::gil_scoped_release release;
    const Dataset data = Dataset::load(images, cameras, job.data_options, shown);
    job.data = &data;
    std::ostringstream log;
    run_finetune_job(std::move(job), Spelling{false}, log, shown, [&](const FinetuneJobResult& r) { write_finetune_job_report(out, r, data); });
  }
  return py::module_::import("json").attr("loads")(read_file(join_path(out, "summary.json")));
}

/// The fine-tuning weights of refined images against `model` and the observed views
/// (`cameras` with `images`), as `fillgs finetune` computes them for each refined view.
py::list weights_py(const Model& model, const Cameras& cameras, const py::object& images, const py::object& refined, const Cameras& refined_cameras,
                    const std::string& weighting, int frames, const py::object& mask_sigma, const std::string& mask_method, const std::string& covis,
                    const std::string& covis_scale, bool normalise, const py::object& tables_arg, const py::object& progress) {
  const GaussianCloud& cloud = *model.cloud;
  const std::pair<std::vector<ObservedView>, int> viewed = views_of(cloud, cameras, frames);
  const std::vector<ObservedView>& views = viewed.first;
  const int F = viewed.second;
  const ViewImages observed(images, views, "images");
  std::vector<ObservedView> refined_views;
  for (const Camera& c : refined_cameras.list) {
    if (!c.has_time() || c.time < 0 || c.time > 1) throw py::value_error("refined_cameras: " + c.name + " has no time in [0, 1]");
    refined_views.push_back({c, 0});
  }
  const ViewImages given(refined, refined_views, "refined");
  const Weighting w = parse_name<Weighting>(weighting);
  // finetune's options (--mask-sigma, --mask, --covis, --covis-scale, --normalise-weights),
  // with its bounds; the background is its training's (black), as finetune's context has it.
  // observe()'s result, where given: its tables are used, not computed again.
  std::optional<ObservationTables> given_tables;
  if (!tables_arg.is_none()) {
    if (!py::isinstance<py::dict>(tables_arg)) throw py::type_error("tables: expected the dict observe() returns");
    const py::dict d = py::reinterpret_borrow<py::dict>(tables_arg);
    for (const char* key : {"counts", "speed", "deficiency", "times", "dynamic_ids"})
      if (!d.contains(key)) throw py::key_error(std::string("tables: no '") + key + "' (the dict observe() returns)");
    using U16 = py::array_t<uint16_t, py::array::c_style | py::array::forcecast>;
    using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
    using U32 = py::array_t<uint32_t, py::array::c_style | py::array::forcecast>;
    const U16 counts = U16::ensure(d["counts"]);
    if (!counts || counts.ndim() != 2) throw py::value_error("tables: counts is not a [T, N] array");
    const py::ssize_t T = counts.shape(0), N = counts.shape(1);
    const FloatArray speed = float_array(d["speed"], "tables speed", {T, N}), deficiency = float_array(d["deficiency"], "tables deficiency", {T, N});
    const F64 times = F64::ensure(d["times"]);
    const U32 ids = U32::ensure(d["dynamic_ids"]);
    if (!times || times.ndim() != 1 || times.shape(0) != T) throw py::value_error("tables: times is not a [" + std::to_string(T) + "] array");
    if (!ids || ids.ndim() != 1) throw py::value_error("tables: dynamic_ids is not a 1-D array");
    given_tables = tables_from_arrays(size_t(T), size_t(N), counts.data(), speed.data(), deficiency.data(), times.data(), size_t(ids.shape(0)),
                                      ids.data(), cloud);
    const FrameGrid grid(F);
    if (given_tables->frames() != F || given_tables->times != grid.times())
      throw Error("tables: " + std::to_string(given_tables->frames()) + " times, not the " + std::to_string(F) +
                  " frames of the views (observe the model with frames=" + std::to_string(F) + ")");
  }
  MaskOptions mask;
  if (const auto x = number_or_none(mask_sigma, "mask_sigma", positive())) mask.sigma = *x;
  mask.method = parse_name<MaskMethod>(mask_method);
  mask.covisibility = parse_name<Covisibility>(covis);
  mask.scale = parse_name<CovisibilityScale>(covis_scale);
  mask.normalise = normalise;
  SelectOptions so;
  PyProgress shown(progress);
  std::vector<ViewWeights> out;
  {
    py::gil_scoped_release release;
    std::vector<Camera> cams;
    for (const ObservedView& v : views) cams.push_back(v.camera);
    ObservationOptions oo;
    oo.visibility = so.visibility;
    const FrameGrid grid(F);
    const ObservationTables tables = given_tables ? std::move(*given_tables) : observation_tables(cloud, cams, grid.times(), grid.step(), oo, nullptr, shown);
    // finetune's weigher, with its training's background (fine_tune_schedule's).
    const RefinedViewWeigher weigh(cloud, tables, so.deficiency_quantile, mask, w, views,
                                   [&](size_t i) { return Image(views[i].camera.width, views[i].camera.height, 3, observed.get(i)); }, F,
                                   fine_tune_schedule(1).background);
    shown.start("weights (" + weighting + ")", given.size());
    for (size_t i = 0; i < given.size(); ++i) {
      const Camera& c = refined_cameras.list[i];
      out.push_back(weigh(Image(c.width, c.height, 3, given.get(i)), c));
      if (mask.normalise) normalise_by_mean(out.back().weight);  // as finetune weighs its loss
      shown.advance(1);
    }
    shown.finish();
  }
  py::list result;
  for (size_t i = 0; i < out.size(); ++i) {
    const py::ssize_t H = refined_cameras.list[i].height, W = refined_cameras.list[i].width;
    py::dict d;
    d["weight"] = to_array(std::move(out[i].weight), {H, W});
    d["consistency"] = out[i].consistency.empty() ? py::object(py::none()) : py::object(to_array(std::move(out[i].consistency), {H, W}));
    d["covisibility"] = out[i].covisibility.empty() ? py::object(py::none()) : py::object(to_array(std::move(out[i].covisibility), {H, W}));
    result.append(d);
  }
  return result;
}

}  // namespace
}  // namespace fillgs::python

PYBIND11_MODULE(_fillgs, m) {
  using namespace fillgs;
  using namespace fillgs::python;
  m.doc() = "fillgs: observation counts, motion-aware deficiency and renders of 4D Gaussian models, as NumPy arrays";
  m.attr("__version__") = FILLGS_VERSION;  // the project's version (CMakeLists.txt), as `fillgs --version` prints it
  // fillgs.Error (a ValueError) carries the library's one line, the command line's flags in
  // it named as this module's keywords ("give frames=F" where the command line says "give
  // --model-frames F").
  static py::exception<Error> error_type(m, "Error", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Cancelled&) {
      pending_error().raise();
    } catch (const Error& e) {
      PyErr_SetString(error_type.ptr(), as_keywords(e.what()).c_str());
    }
  });
  limit_instruction_set_from_environment();  // FILLGS_INSTRUCTION_SET, as the command line keeps to it

  py::class_<Model>(m, "Model", "A 4D Gaussian model: any the command line reads (load_model), or Gaussians from arrays (model_from_arrays)")
      .def_property_readonly("size", [](const Model& x) { return x.cloud->size(); }, "Gaussians")
      .def("__len__", [](const Model& x) { return x.cloud->size(); })
      .def_property_readonly("frames", [](const Model& x) { return motion_frames(*x.cloud); }, "frames its motion is given at (0: none)")
      .def_property_readonly("sh_degree", [](const Model& x) { return x.cloud->sh_degree; })
      .def_property_readonly("dynamic_ids", [](const Model& x) { std::vector<uint32_t> v = x.cloud->dynamic_ids; return to_array(std::move(v), {py::ssize_t(x.cloud->dynamic_count())}); },
                             "ascending ids of the moving Gaussians (uint32)")
      .def_property_readonly("static_count", [](const Model& x) { return x.cloud->static_count(); })
      .def_property_readonly("notes", [](const Model& x) { return x.cloud->notes; }, "what the reader decided, as `fillgs info` prints it")
      .def("model_time", [](const Model& x, double t) { return model_time(*x.cloud, t); }, py::arg("t"),
           "The model's own time (its training code's: E-D3DGS f / total_num_frames, 4DGaussians f / F, 4DGS seconds, ...) at normalised time t")
      .def("normalised_time", [](const Model& x, double model_time_value) { return normalised_time(*x.cloud, model_time_value); },
           py::arg("model_time"), "The normalised time t in [0, 1] fillgs uses (frame f of F at f / (F - 1)) of the model's own time")
      .def("at", &state_at, py::arg("t"),
           "The Gaussians at normalised time t in [0, 1]: a dict of float32 arrays means [N,3], log_scales [N,3], quaternions [N,4] (w, x, y, z, unit), "
           "opacity_logits [N], sh [N,K,3]")
      .def("__repr__", [](const Model& x) {
        return "<fillgs.Model " + std::to_string(x.cloud->size()) + " Gaussians (" + std::to_string(x.cloud->dynamic_count()) + " moving) from " + x.source + ">";
      });

  m.def("load_model", &load_model, py::arg("path"), py::arg("format") = "auto", py::arg("frames") = 0, py::arg("time_range") = "",
        py::arg("evaluation") = "streamed", py::arg("still_tolerance") = py::none(), py::arg("still_times") = py::none(), py::arg("progress") = py::none(),
        "Reads a model as the command line does (`--scene-format`, `--model-frames`, `--model-time-range`, `--model-evaluation`, `--still-tolerance`); "
        "a format's own parameters are keywords (stg_duration=50 for `--stg-duration 50`; model_formats() lists each format's). "
        "still_times: the times a job will observe, given to a streamed model's still rule as `fillgs observe --frames F` / `--times` "
        "gives them (fewer than its sweep: those times are checked, not the sweep's frames).");
  m.def(
      "refiners",
      [] {
        py::list out;
        for (const RefinerKind* k : refiner_kinds()) {
          py::dict d;
          d["name"] = k->name;
          d["description"] = k->description;
          d["needs_truth"] = k->needs_truth;
          d["needs_pool"] = k->needs_pool;
          d["benchmark"] = k->benchmark;
          d["parameters"] = parameters_of(*k);
          out.append(d);
        }
        return out;
      },
      "The refiners finetune takes, in listing order: dicts of name, description, needs_truth, needs_pool, benchmark (made from "
      "a synthetic scene's truth and training cameras alone) and parameters (its own finetune keywords: default and help).");
  m.def(
      "model_formats",
      [] {
        py::list out;
        for (const ModelFormat* f : model_formats()) {
          py::dict d;
          d["name"] = f->name;
          d["aliases"] = f->aliases;
          d["description"] = f->description;
          d["evaluated"] = bool(f->open);
          d["parameters"] = parameters_of(*f);
          out.append(d);
        }
        return out;
      },
      "The formats load_model reads, in detection order: dicts of name, aliases, description, evaluated (the model's own code "
      "evaluates it at any time; else its file is read whole) and parameters (its own load_model keywords: default and help).");
  m.def(
      "model_from_arrays",
      [](const py::dict& arrays) {
        auto c = std::make_shared<GaussianCloud>(cloud_from(state_from(arrays, "arrays", -1)));
        return Model{c, "arrays"};
      },
      py::arg("arrays"), "Static Gaussians from a dict of arrays (means, log_scales, quaternions, opacity_logits[, sh]) as Model.at returns them.");

  py::class_<Cameras>(m, "Cameras", "Cameras: read from a rig's files (read_cameras) or from arrays")
      .def(py::init(&cameras_from), py::arg("K"), py::arg("world_to_camera"), py::arg("width"), py::arg("height"), py::arg("time") = py::none(),
           py::arg("names") = py::none(),
           "K [C,3,3], world_to_camera [C,4,4] (OpenCV axes: x right, y down, z forward), width and height [C] or one value, time [C] in [0, 1] "
           "(NaN or None: a fixed rig's camera, at every frame)")
      .def("__len__", [](const Cameras& c) { return c.list.size(); })
      .def_property_readonly("names", [](const Cameras& c) {
        std::vector<std::string> n;
        for (const Camera& x : c.list) n.push_back(x.name);
        return n;
      })
      .def("arrays", &cameras_arrays, "A dict: K [C,3,3], world_to_camera [C,4,4] float64, width, height [C] int32, time [C] float64 (NaN: none)")
      .def("to_3dgs", &cameras_to_3dgs,
           "The cameras as E-D3DGS, 4DGaussians and 3DGS hold them (cameras_from_3dgs's inverse; their scene/cameras.py Camera takes "
           "R, T, FoVx, FoVy): a dict R [C,3,3] (the world-to-camera rotation transposed), T [C,3], fov_x, fov_y [C] radians, width, height "
           "[C] int32, time [C] normalised (Model.model_time gives a code's own; NaN: none). A camera whose principal point is more than half "
           "a pixel off the image centre is refused: those codes have none of their own.");
  m.def("cameras_from_3dgs", &cameras_from_3dgs_py, py::arg("R"), py::arg("T"), py::arg("fov_x"), py::arg("fov_y"), py::arg("width"),
        py::arg("height"), py::arg("time") = py::none(), py::arg("names") = py::none(),
        "Cameras as E-D3DGS, 4DGaussians and 3DGS hold them (scene/cameras.py: R the transpose of the world-to-camera rotation, T its translation, "
        "FoVx, FoVy in radians, a centred principal point): R [C,3,3], T [C,3], fov_x, fov_y, width, height [C] or one value, time [C] normalised "
        "(Model.normalised_time converts a code's own time) or None.");
  m.def("read_cameras", &read_cameras_py, py::arg("path"), py::arg("format") = "auto", py::arg("width") = 0, py::arg("height") = 0,
        "Reads cameras as the command line does (`--camera-format`, `--width`, `--height`).");

  m.def(
      "observe",
      [](const py::object& model, const Cameras& cameras, int frames, const py::object& times, const std::string& mode, int stride, const py::object& tau,
         const py::object& hit_cache_mb, const py::object& progress, const py::object& still_tolerance) {
        if (py::isinstance<Model>(model)) {
          if (!still_tolerance.is_none()) throw py::value_error("still_tolerance: a frame function's; a model's is load_model's");
          return observe_py(model.cast<const Model&>(), nullptr, cameras, frames, times, mode, stride, tau, hit_cache_mb, progress);
        }
        if (!PyCallable_Check(model.ptr())) throw py::type_error("model: expected a fillgs.Model or a frame function f -> dict of arrays");
        if (frames < 1) throw py::value_error("frames: give the frame count with a frame function");
        StillRule rule;
        if (const auto x = number_or_none(still_tolerance, "still_tolerance", at_least(0))) rule.position = float(*x);
        const auto made = model_from_frames(model, frames, rule);
        return observe_py(made.first, made.second, cameras, frames, times, mode, stride, tau, hit_cache_mb, progress);
      },
      py::arg("model"), py::arg("cameras"), py::arg("frames") = 0, py::arg("times") = py::none(), py::arg("mode") = "frustum", py::arg("stride") = 4,
      py::arg("tau") = py::none(), py::arg("hit_cache_mb") = py::none(), py::arg("progress") = py::none(), py::arg("still_tolerance") = py::none(),
      "Observation counts, speeds and the motion-aware deficiency for every Gaussian and frame, as `fillgs observe` writes them. `model`: a "
      "fillgs.Model, or a frame function f -> dict of arrays (means, log_scales, quaternions, opacity_logits[, sh]) for f = 0 … frames-1, "
      "called with the GIL held (e.g. your own deformation network), once per frame; its Gaussians that stay within the still rule's "
      "tolerances of frame 0 at every frame (`still_tolerance` world units, default 1e-3, 1 degree, 1 % of scale, 1/255 of opacity and "
      "colour: load_model's rule) are static, with no speed or deficiency. Returns a dict: counts [T,N] uint8 (uint16 above 255 views a "
      "frame), speed and deficiency [T,N] float32, times [T], dynamic_ids [M], views, seconds. `times`: observe at these times instead "
      "of every frame (as --times: in [0, 1], sorted, repeats dropped; frames=F >= 2 gives the speeds' step); frames, times and stride are "
      "checked by the command line's own check, the tables' memory included.");

  m.def("load_observation", &load_observation_py, py::arg("path"), py::arg("dense") = false,
        "The tables of a folder `fillgs observe` wrote, read and checked as the command line reads them. Returns a dict: tables (the "
        "layout: compact, dense or dynamic), times [T], dynamic_ids [M] and the arrays as stored (compact: count_static [R,N], count_rows "
        "[T], count_dynamic [T,M], count_change_offsets [T+1], count_change_ids [E], count_change_values [E]; dense: count [T,N]; "
        "speed_dynamic and deficiency_dynamic [T,M] in every layout). dense=True: the [T,N] view instead, with observe()'s keys (counts, "
        "speed, deficiency), which select(tables=...) takes.");
  m.def("read_image", &read_image_py, py::arg("path"), "An image file as fillgs reads it: float32 [H,W,C] in [0, 1], C the file's channels (3 for RGB, 1 for a grey map).");
  m.def(
      "write_image",
      [](const std::string& path, const py::handle& pixels) {
        py::array a = py::array(py::module_::import("numpy").attr("asarray")(pixels));
        if (a.ndim() == 2) a = py::array(a.attr("reshape")(a.shape(0), a.shape(1), 1));
        const FloatArray f = float_array(a, "pixels", {-1, -1, -1});
        const py::ssize_t C = f.shape(2);
        if (C != 1 && C != 3 && C != 4) throw py::value_error("pixels: " + std::to_string(C) + " channels, expected 1, 3 or 4");
        write_image(path, Image(int(f.shape(1)), int(f.shape(0)), int(C), std::vector<float>(f.data(), f.data() + f.size())));
      },
      py::arg("path"), py::arg("pixels"),
      "Writes float [H,W,C] (or [H,W]) in [0, 1] as the file's extension says (PNG: 8-bit), as fillgs writes its images.");
  m.def("load_views", &load_views, py::arg("images"), py::arg("cameras"), py::arg("train_cameras") = std::vector<std::string>(),
        py::arg("frames") = "", py::arg("downscale") = 1, py::arg("progress") = py::none(),
        "A rig's views as `fillgs train` reads them (`--images`, `--cameras`, `--train-cameras`, `--frames`, `--downscale`): a dict with "
        "cameras (each view at its time), images (uint8 [H,W,3] each, as the command line holds them; / 255 for floats in [0, 1]; select and "
        "weights take them without a copy), frames and source_frames (int32, each view's frame in the video). A frame range "
        "(`frames='0:300:10'`) keeps the video's times and frame count (frame f of F at f / (F - 1), the model's), not the chosen "
        "frames renumbered as a video of their own.");

  py::class_<Grid>(m, "ExplorationGrid", "The exploration space: every voxel free (0), occupied (1) or unexplored (2)")
      .def_property_readonly("dims", [](const Grid& g) { return std::vector<int>{g.grid->dims().x(), g.grid->dims().y(), g.grid->dims().z()}; },
                             "voxels along x, y, z")
      .def_property_readonly("box", [](const Grid& g) {
        return py::make_tuple(std::vector<double>{g.grid->box().lo.x(), g.grid->box().lo.y(), g.grid->box().lo.z()},
                              std::vector<double>{g.grid->box().hi.x(), g.grid->box().hi.y(), g.grid->box().hi.z()});
      }, "(lo, hi) corners")
      .def_property_readonly("labels", &grid_labels, "uint8 [Z,Y,X]: 0 free, 1 occupied, 2 unexplored")
      .def("label_at", &grid_label_at, py::arg("points"), "uint8 [n] label of each point [n,3] (outside the box: 2, unexplored)")
      .def("write", [](const Grid& g, const std::string& path) { g.grid->write(path); }, py::arg("path"), "as fillgs explore writes exploration.vdb");
  m.def("read_grid", [](const std::string& path) { require_file(path); return Grid{std::make_shared<ExplorationGrid>(ExplorationGrid::read(path))}; },
        py::arg("path"), "An exploration.vdb written by fillgs explore.");
  m.def("explore", &explore_py, py::arg("model"), py::arg("cameras"), py::arg("frames") = 0, py::arg("divisions") = 64, py::arg("progress") = py::none(),
        "The exploration grid, as `fillgs explore` builds it (frames > 0: the moving Gaussians swept over F frames).");

  py::class_<PyTrajectory>(m, "Trajectory", "Virtual poses chosen at one frame, each rendered over its patch frames")
      .def_property_readonly("index", [](const PyTrajectory& t) { return t.t.index; })
      .def_property_readonly("frame", [](const PyTrajectory& t) { return t.t.frame; }, "the frame the poses were chosen at")
      .def_property_readonly("start_view", [](const PyTrajectory& t) { return t.t.start_view; }, "index of the observed view it starts from (-1: none)")
      .def_property_readonly("is_global", [](const PyTrajectory& t) { return t.t.global; })
      .def_property_readonly("poses", [](const PyTrajectory& t) { return Cameras{t.t.poses}; }, "Cameras at the trajectory's frame")
      .def_property_readonly("scores", [](const PyTrajectory& t) { std::vector<double> v = t.t.scores; return to_array(std::move(v), {py::ssize_t(t.t.scores.size())}); })
      .def_property_readonly("patch_frames", [](const PyTrajectory& t) { std::vector<int> v = t.t.patch_frames; return to_array(std::move(v), {py::ssize_t(t.t.patch_frames.size())}); })
      .def("views", [](const PyTrajectory& t) { return Cameras{t.t.views()}; }, "every pose at every patch frame (pose-major), with times")
      .def("__repr__", [](const PyTrajectory& t) {
        return "<fillgs.Trajectory " + std::to_string(t.t.index) + ": " + std::to_string(t.t.poses.size()) + " poses at frame " + std::to_string(t.t.frame) + ">";
      });
  m.def("select", &select_py, py::arg("model"), py::arg("cameras"), py::arg("frames") = 0, py::arg("strategy") = "fillgs", py::arg("trajectories") = 5,
        py::arg("views") = SelectOptions().views, py::arg("patch_frames") = SelectOptions().patch_frames, py::arg("seed") = 1, py::arg("images") = py::none(),
        py::arg("grid") = py::none(), py::arg("progress") = py::none(),
        "Viewpoint-time selection as `fillgs select` runs it, by any strategy (fillgs, random, negative, interpolation, fisherrf, coverage3d, "
        "coverage4d). `images`: the observed views' images (their order: load_views) for the priority's error term; a strategy's own "
        "parameters (declared in its row) are keywords. Returns a dict: trajectories (list of Trajectory), deficiency_scale, notes, grid.");
  m.def("finetune", &finetune_py, py::arg("model"), py::arg("images"), py::arg("cameras"), py::arg("out"),
        py::arg("train_cameras") = std::vector<std::string>(), py::arg("frames") = "", py::arg("downscale") = 1, py::arg("iterations") = 2400,
        py::arg("select_every") = 800, py::arg("trajectories") = py::none(), py::arg("seed") = 1, py::arg("strategy") = "fillgs",
        py::arg("weighting") = "fillgs", py::arg("refiner") = py::none(), py::arg("truth") = py::none(),
        py::arg("pool_cameras") = std::vector<std::string>(), py::arg("pool_budget") = 0, py::arg("motion_rates") = "converged",
        py::arg("refined_share") = py::none(), py::arg("reference_angle") = py::none(), py::arg("artifact_strength") = py::none(),
        py::arg("support_window") = py::none(), py::arg("progress") = py::none(),
        "Fine-tunes a loaded model as `fillgs finetune` does, the same job with the same checks (each problem named by its keyword), "
        "writing the same folder `out` (model.ply, virtual_views.json, summary.json, pool_chosen.json with a pool budget); returns "
        "summary.json as a dict. images, cameras, train_cameras, frames, downscale: the training views as load_views reads them; "
        "trajectories None: 5 (a pool budget takes none); refiner None: identity (a pool budget takes none); truth: a loaded "
        "ground-truth scene (oracle, reference); motion_rates: converged, repair or gentle (--motion-rates); reference_angle, artifact_strength, "
        "support_window: the options several refiners share (--reference-angle, --artifact-strength, --support-window; None: the "
        "command line's defaults); a refiner's own parameters "
        "are keywords (refiner_command=, refiner_timeout= for external; refiners() lists each refiner's).");
  m.def("weights", &weights_py, py::arg("model"), py::arg("cameras"), py::arg("images"), py::arg("refined"), py::arg("refined_cameras"),
        py::arg("weighting") = "fillgs", py::arg("frames") = 0, py::arg("mask_sigma") = py::none(),
        py::arg("mask") = std::string(to_string(MaskOptions().method)), py::arg("covis") = std::string(to_string(MaskOptions().covisibility)),
        py::arg("covis_scale") = std::string(to_string(MaskOptions().scale)), py::arg("normalise") = false, py::arg("tables") = py::none(), py::arg("progress") = py::none(),
        "Fine-tuning weights of refined images (float32 [H,W,3] each, at refined_cameras, which carry times) against the model and its observed "
        "views (cameras with their images), as `fillgs finetune` computes them: a list of dicts weight [H,W] (the loss weight), consistency and "
        "covisibility [H,W] (None where the weighting has none). Weightings: fillgs, none, no-consistency, no-covisibility, 3dgs-enhancer, "
        "exploregs, ua-4dgs. mask_sigma (None: 0.05), mask, covis, covis_scale and normalise are finetune's --mask-sigma, --mask, --covis, "
        "--covis-scale and --normalise-weights. tables: observe()'s result for the model and cameras at the views' frames (not computed again).");

  m.def("render", &render_py, py::arg("model"), py::arg("cameras"), py::arg("index") = 0, py::arg("t") = 0.0,
        py::arg("background") = std::vector<float>{0, 0, 0},
        "Renders camera `index` at normalised time t: a dict of float32 arrays colour [H,W,3], depth [H,W] (the blended z; divide by alpha for "
        "the expected depth) and alpha [H,W].");
  m.def(
      "instruction_set",
      [] {
        py::dict d;
        d["kernels"] = kernel_instruction_set();
        d["held_to"] = instruction_set_limit();
        return d;
      },
      "The instruction set the vector kernels run on (Highway's name: 'AVX3', 'AVX2', ...) and the cap FILLGS_INSTRUCTION_SET set when the "
      "module was imported ('avx2', 'sse4', 'avx512'; '' for none): a model trained on an AVX2 machine is trained again bit for bit on an "
      "AVX-512 one held to avx2.");
}
