#include "fillgs/io/trained_models.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
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
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/model/dense.hpp"
#include "fillgs/model/sh.hpp"

namespace fs = std::filesystem;

namespace fillgs {

std::unique_ptr<TrainedModel> open_trained_model(const std::string& path, const std::string& format, const SceneReadOptions& options) {
  return open_trained_model(path, format == "auto" ? model_format(detect_scene_format(path)) : model_format(format), options);
}

std::unique_ptr<TrainedModel> open_trained_model(const std::string& path, const ModelFormat& f, const SceneReadOptions& options) {
  if (!f.open) throw_error(path, ": ", f.name, " is not a trained-model format (its Gaussians are read whole)");
  std::unique_ptr<TrainedModel> m = f.open(path, options);
  m->format = f.name;
  return m;
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
    os << model.time_first << " … " << model.time_last << " (" << model.format << " time of frames 0 … " << F - 1 << ")";
    c.model_times = os.str();
    c.model_time_first = model.time_first, c.model_time_last = model.time_last;
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
    // The oldest kept evaluation makes way; where no caller holds it any more, its storage
    // takes the new one (no fresh pages for every frame).
    std::shared_ptr<ModelState> s;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (kept_.size() == kKept) {
        if (kept_.front().state.use_count() == 1) s = std::move(kept_.front().state);
        kept_.erase(kept_.begin());
      }
    }
    if (!s) s = std::make_shared<ModelState>();
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
    std::shared_ptr<ModelState> state;  // handed out as const
  };
  /// The frame coordinate of normalised time t: t (F - 1), a whole frame when within 1e-9 of
  /// one (f / (F - 1) times F - 1, or a time less a frame step, can miss f by an ulp).
  double frame_of(double t) const {
    double f = std::clamp(t, 0.0, 1.0) * double(m_->frames - 1);
    if (std::fabs(f - std::round(f)) < 1e-9) f = std::round(f);
    return f;
  }
  void check(const ModelState& s, const std::vector<uint32_t>& rows, double mt) const {
    const size_t bad = first_not_finite(s);
    if (bad < s.size())
      throw_error(m_->source, ": Gaussian ", rows[bad], " is not finite at model time ", mt, " (its network's output overflowed)");
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

size_t first_not_finite(const ModelState& s) {
  const size_t row = s.size() ? s.sh.size() / s.size() : 0;
  // In parallel blocks, each stopping at its first such row or at a lower one found already.
  std::atomic<size_t> bad{s.size()};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, s.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end() && i < bad.load(std::memory_order_relaxed); ++i) {
      bool ok = s.means[i].allFinite() && s.log_scales[i].allFinite() && s.rotations[i].allFinite() && std::isfinite(s.opacity_logits[i]) &&
                (s.opacity_factor.empty() || std::isfinite(s.opacity_factor[i]));
      for (size_t q = 0; ok && q < row; ++q) ok = std::isfinite(s.sh[i * row + q]);
      if (!ok) {
        for (size_t seen = bad.load(); i < seen && !bad.compare_exchange_weak(seen, i);) {
        }
        break;
      }
    }
  });
  return bad.load();
}

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

float still_departure(const ModelState& s, size_t j, const ModelState& first, size_t i, const StillRule& rule) {
  auto share = [](float d, float tolerance) { return d <= 0.0f ? 0.0f : tolerance > 0.0f ? d / tolerance : INFINITY; };
  const size_t row = first.size() ? first.sh.size() / first.size() : 0;
  float r = share((s.means[j] - first.means[i]).norm(), rule.position);
  r = std::max(r, share((s.log_scales[j] - first.log_scales[i]).cwiseAbs().maxCoeff(), rule.log_scale));
  r = std::max(r, share(std::fabs(activated_opacity(s, j) - activated_opacity(first, i)), rule.opacity));
  const double c = std::min(1.0, double(std::fabs(normalize_quat(s.rotations[j]).dot(normalize_quat(first.rotations[i])))));
  r = std::max(r, share(float(2.0 * std::acos(c) * 180.0 / M_PI), rule.rotation_degrees));
  // Colour: every SH band, as the largest change of the colour in any direction (bounded by
  // the coefficients' changes times their basis functions' maxima), any channel.
  for (size_t a = 0; a < 3 && row; ++a) r = std::max(r, share(sh_colour_change(&s.sh[j * row], &first.sh[i * row], row / 3, a), rule.colour));
  return r;
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
  // A job that evaluates fewer times than the sweep has frames: the rule checks exactly those
  // times against frame 0, so every time the job asks for is checked, and nothing else.
  std::vector<double> job_times;
  for (const double t : rule.times)
    if (t > 0.0 && t <= 1.0 && (job_times.empty() || t > job_times.back())) job_times.push_back(t);
  const bool by_job = !rule.times.empty() && job_times.size() + 1 < sweep.size();
  std::vector<float> departure(N, 0.0f);
  auto share = [](float d, float tolerance) { return d <= 0.0f ? 0.0f : tolerance > 0.0f ? d / tolerance : INFINITY; };
  auto depart = [&](const ModelState& s, size_t j, size_t i) { return still_departure(s, j, first, i, rule); };
  auto frame_times = [&](const std::vector<int>& frames) {
    std::vector<double> t;
    for (const int f : frames)
      if (f != 0) t.push_back(F > 1 ? double(f) / double(F - 1) : 0.0);
    return t;
  };
  // The rows at each time against frame 0. A row past a tolerance is moving whatever the later
  // times hold, so each time evaluates only the rows still within every tolerance: a model
  // whose Gaussians all move costs the sweep about one frame, not its whole length.
  auto check_until_moving = [&](const std::vector<double>& times, std::vector<uint32_t> pending) {
    for (const double t : times) {
      if (!pending.empty()) {
        ModelState s;
        motion->evaluate_once(t, pending, s);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, pending.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
          for (size_t j = r.begin(); j < r.end(); ++j) departure[pending[j]] = std::max(departure[pending[j]], depart(s, j, pending[j]));
        });
        pending.erase(std::remove_if(pending.begin(), pending.end(), [&](uint32_t g) { return departure[g] > 1.0f; }), pending.end());
      }
      progress.advance();
    }
  };
  // What the model knows in closed form (4DGS's temporal opacity) counts whatever the sweep
  // sees: a Gaussian living between two of its frames is not still.
  const std::vector<float> lived = model->opacity_variation();
  if (lived.size() == N)
    for (size_t i = 0; i < N; ++i) departure[i] = std::max(departure[i], share(lived[i], rule.opacity));
  const std::vector<double> swept = by_job ? job_times : frame_times(sweep);
  std::vector<uint32_t> within;
  for (size_t i = 0; i < N; ++i)
    if (departure[i] <= 1.0f) within.push_back(uint32_t(i));
  progress.start("still rule", swept.size());
  check_until_moving(swept, std::move(within));
  progress.finish();
  // Gaussians the sweep found still but not far from a tolerance are checked at every frame:
  // a motion between the sweep's frames can exceed what its frames saw.
  std::vector<uint32_t> recheck;
  if (!by_job && int(sweep.size()) < F)
    for (size_t i = 0; i < N; ++i)
      if (departure[i] <= 1.0f && departure[i] > rule.recheck) recheck.push_back(uint32_t(i));
  if (!recheck.empty()) {
    std::vector<int> rest;  // the frames the sweep did not evaluate
    for (int f = 0; f < F; ++f)
      if (!std::binary_search(sweep.begin(), sweep.end(), f)) rest.push_back(f);
    progress.start("still rule, rechecked at every frame", rest.size());
    check_until_moving(frame_times(rest), recheck);
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
    os << model->time_first << " … " << model->time_last << " (" << model->format << " time of frames 0 … " << F - 1 << ")";
    c.model_times = os.str();
    c.model_time_first = model->time_first, c.model_time_last = model->time_last;
    std::ostringstream still;
    still << N - c.dynamic_ids.size() << " of " << N << " Gaussians still (evaluated once, at frame 0): ";
    if (by_job)
      still << "at frame 0 and each of the " << job_times.size() << " other times the job evaluates (of the model's " << F << " frames)";
    else
      still << "at each of " << sweep.size() << " of its " << F << " frames";
    if (!by_job && int(sweep.size()) < F)
      still << " (all " << F << " for the " << recheck.size() << " whose departure there exceeded " << rule.recheck << " of a tolerance)";
    still << " within " << rule.position << " world units, " << rule.rotation_degrees << " degrees, " << rule.log_scale
          << " in log-scale, " << rule.opacity << " in opacity (its temporal term's whole range included) and " << rule.colour
          << " in colour (every SH band, in any direction) of frame 0";
    c.notes.push_back(still.str());
    c.notes.push_back(std::string("the ") + std::to_string(c.dynamic_ids.size()) + " moving Gaussians are evaluated by the model at each time asked, exactly" +
                      (!model->has_network() ? std::string()
                       : reference           ? std::string(" (its network by the Eigen reference products)")
                                             : " (its network by the dense kernel, " + std::string(dense::target_name()) + ")"));
  }
  return c;
}

}  // namespace fillgs
