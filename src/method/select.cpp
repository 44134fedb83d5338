#include "fillgs/method/strategies.hpp"
#include "fillgs/method/select.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <random>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/render/raster.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs {

namespace {



std::vector<Camera> cameras_of(const std::vector<ObservedView>& views) {
  std::vector<Camera> c;
  for (const ObservedView& v : views) c.push_back(v.camera);
  return c;
}

Camera with_pose(const Camera& c, const Mat3d& R, const Vec3d& centre) {
  Camera out = c;
  out.R = R;
  out.t = -R * centre;
  return out;
}

Mat3d axis_rotation(int axis, double radians) { return Eigen::AngleAxisd(radians, Vec3d::Unit(axis)).toRotationMatrix(); }


double mean_squared_difference(const std::vector<float>& a, const std::vector<float>& b) {
  FILLGS_CHECK_EQ(a.size(), b.size());
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += double(a[i] - b[i]) * double(a[i] - b[i]);
  return a.empty() ? 0.0 : s / double(a.size());
}

bool same_pose(const Camera& a, const Camera& b, double tol) {
  return (a.centre() - b.centre()).norm() <= tol && (a.R - b.R).cwiseAbs().maxCoeff() <= 1e-6;
}

}  // namespace

// ------------------------------------------------------------------ cameras

std::vector<float> render_value_map(const FrameGaussians& frame, const Camera& camera, const float* values) {
  RenderOptions ro;
  ro.rgb = false;
  ro.features = values;
  ro.feature_channels = 1;
  return render(frame, camera, ro).features;
}

double mean_value(const std::vector<float>& map) {
  double sum = 0;
  for (float x : map) sum += x;
  return map.empty() ? 0.0 : sum / double(map.size());
}

Camera interpolate_camera(const Camera& a, const Camera& b, double s) {
  const Eigen::Quaterniond qa(a.R), qb(b.R);
  const Mat3d R = qa.slerp(s, qb).normalized().toRotationMatrix();
  return with_pose(a, R, (1 - s) * a.centre() + s * b.centre());
}

std::vector<Camera> local_candidates(const Camera& cur, const std::vector<Camera>& training, double step, double rotation_degrees) {
  std::vector<Camera> out;
  const Vec3d c = cur.centre();
  for (int axis = 0; axis < 3; ++axis)
    for (double sign : {1.0, -1.0}) out.push_back(with_pose(cur, cur.R, c + sign * step * cur.R.row(axis).transpose()));
  const double a = rotation_degrees * kPi / 180.0;
  for (int axis = 0; axis < 2; ++axis)  // about the camera's right (x) and up (y) axes
    for (double sign : {1.0, -1.0}) out.push_back(with_pose(cur, axis_rotation(axis, sign * a) * cur.R, c));
  std::vector<std::pair<double, size_t>> near;
  for (size_t i = 0; i < training.size(); ++i) {
    const double d = (training[i].centre() - c).norm();
    if (d > 1e-9 * std::max(1.0, c.norm())) near.emplace_back(d, i);
  }
  std::sort(near.begin(), near.end());
  for (size_t k = 0; k < 2 && k < near.size(); ++k) out.push_back(interpolate_camera(cur, training[near[k].second], 0.5));
  return out;
}

std::vector<Camera> global_candidates(const Camera& start, const std::vector<Camera>& training, const ExplorationGrid& grid, int count,
                                      double grow, std::mt19937_64& rng) {
  std::vector<std::pair<double, size_t>> near;
  for (size_t i = 0; i < training.size(); ++i) {
    const double d = (training[i].centre() - start.centre()).norm();
    if (d > 1e-9 * std::max(1.0, start.centre().norm())) near.emplace_back(d, i);
  }
  std::sort(near.begin(), near.end());
  if (near.empty()) return {};
  // Two training cameras (the paper's setting): the start and its one neighbour span the box
  // and the directions. More: the start's two nearest neighbours.
  const Camera& a = near.size() >= 2 ? training[near[0].second] : start;
  const Camera& b = near.size() >= 2 ? training[near[1].second] : training[near[0].second];
  Box3 box{start.centre(), start.centre()};
  box.extend(a.centre());
  box.extend(b.centre());
  box.lo -= Vec3d::Constant(grow);
  box.hi += Vec3d::Constant(grow);
  std::vector<Camera> out;
  for (const Vec3d& p : grid.sample_free(box, count, rng)) {
    const double da = (p - a.centre()).norm(), db = (p - b.centre()).norm();
    const Camera c = interpolate_camera(a, b, da / std::max(1e-12, da + db));
    out.push_back(with_pose(start, c.R, p));
  }
  return out;
}

std::vector<ObservedView> observed_views(const std::vector<Camera>& cameras, int frames) {
  FILLGS_CHECK(frames >= 1);
  std::vector<ObservedView> out;
  for (const Camera& c : cameras) {
    if (c.has_time()) {
      ObservedView v{c, FrameGrid(frames).nearest(c.time), 0};
      v.camera.time = FrameGrid(frames).time(v.frame);
      out.push_back(v);
    } else {
      for (int f = 0; f < frames; ++f) {
        ObservedView v{c, f, 0};
        v.camera.time = FrameGrid(frames).time(f);
        out.push_back(v);
      }
    }
  }
  std::vector<Camera> cams;
  for (const ObservedView& v : out) cams.push_back(v.camera);
  size_t distinct = 0;
  const std::vector<uint32_t> groups = camera_pose_groups(cams, &distinct);
  // Number the poses in the order of their (rig) camera names, so tables read cam00, cam01, ...
  std::vector<std::string> names(distinct);
  for (size_t i = out.size(); i-- > 0;) names[groups[i]] = out[i].camera.name;
  std::vector<uint32_t> order(distinct), rank(distinct);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return names[a] < names[b]; });
  for (uint32_t r = 0; r < distinct; ++r) rank[order[r]] = r;
  for (size_t i = 0; i < out.size(); ++i) out[i].pose = rank[groups[i]];
  return out;
}

std::vector<Camera> Trajectory::views() const {
  std::vector<Camera> out;
  for (size_t j = 0; j < poses.size(); ++j)
    for (size_t i = 0; i < patch_frames.size(); ++i) {
      const int f = patch_frames[i];
      Camera c = poses[j];
      c.time = patch_times[i];
      char name[64];
      std::snprintf(name, sizeof name, "traj%02d_v%zu_f%04d", index, j, f);
      c.name = name;
      c.image_path.clear();
      out.push_back(c);
    }
  return out;
}

// ------------------------------------------------------------------ deficiency field


float weighted_quantile(const std::vector<float>& values, const std::vector<float>& weights, double quantile) {
  FILLGS_CHECK(values.size() == weights.size());
  std::vector<std::pair<float, float>> vw;
  double total = 0;
  for (size_t i = 0; i < values.size(); ++i)
    if (weights[i] > 0) vw.emplace_back(values[i], weights[i]), total += double(weights[i]);
  if (vw.empty()) return 1.0f;
  std::sort(vw.begin(), vw.end());
  const double target = std::clamp(quantile, 0.0, 1.0) * total;
  double cumulative = 0;
  for (const auto& [v, w] : vw) {
    cumulative += double(w);
    if (cumulative >= target) return v;
  }
  return vw.back().first;
}

DeficiencyField::DeficiencyField(ObservationTables tables, float quantile, const std::vector<float>* opacity) : tables_(std::move(tables)) {
  dynamic_index_.assign(tables_.gaussians, -1);
  const size_t M = tables_.dynamic_ids.size(), T = size_t(tables_.frames());
  for (size_t j = 0; j < M; ++j) dynamic_index_[tables_.dynamic_ids[j]] = int32_t(j);
  scale_ = tables_.deficiency_scale(quantile);
  if (opacity) {
    if (opacity->size() != T * M) throw_error("deficiency: ", opacity->size(), " opacities for ", T, " frames x ", M, " moving Gaussians");
    frame_scale_.assign(T, scale_);
    std::vector<float> d, w;
    for (size_t f = 0; f < T; ++f) {
      d.clear(), w.clear();
      for (size_t j = 0; j < M; ++j) {
        const float D = tables_.dynamic_deficiency[f * M + j], a = (*opacity)[f * M + j];
        if (D > 0 && a >= kMinAlpha) d.push_back(D), w.push_back(a);
      }
      if (!d.empty()) frame_scale_[f] = std::max(weighted_quantile(d, w, quantile), 1e-30f);
    }
  }
  std::vector<float> speeds;
  for (float s : tables_.dynamic_speed)
    if (s > 0) speeds.push_back(s);
  if (!speeds.empty()) {
    const size_t k = std::min(speeds.size() - 1, size_t(double(quantile) * double(speeds.size() - 1) + 0.5));
    std::nth_element(speeds.begin(), speeds.begin() + std::ptrdiff_t(k), speeds.end());
    speed_scale_ = speeds[k] > 0 ? speeds[k] : 1.0f;
  }
}

std::vector<float> DeficiencyField::values(int f, CandidateScore score) const {
  const size_t N = tables_.gaussians, M = tables_.dynamic_ids.size();
  std::vector<float> v(N, 0.0f);
  switch (score) {
    case CandidateScore::Deficiency:
      for (size_t j = 0; j < M; ++j)
        v[tables_.dynamic_ids[j]] = std::min(1.0f, tables_.dynamic_deficiency[size_t(f) * M + j] / scale(f));
      break;
    case CandidateScore::SpeedOnly:
      for (size_t j = 0; j < M; ++j) v[tables_.dynamic_ids[j]] = std::min(1.0f, tables_.dynamic_speed[size_t(f) * M + j] / speed_scale_);
      break;
    case CandidateScore::CountOnly:
      for (size_t g = 0; g < N; ++g) v[g] = 1.0f / (1.0f + float(tables_.counts[size_t(f) * N + g]));
      break;
  }
  return v;
}

std::vector<float> DeficiencyField::covisibility(int f, Covisibility rule) const {
  if (rule == Covisibility::Paper) return values(f, CandidateScore::Deficiency);
  const size_t N = tables_.gaussians, M = tables_.dynamic_ids.size();
  const uint16_t* C = tables_.counts.data() + size_t(f) * N;
  std::vector<float> v(N);
  for (size_t g = 0; g < N; ++g) v[g] = 1.0f / (1.0f + float(C[g]));  // static: the observation density
  for (size_t j = 0; j < M; ++j) {
    const uint32_t g = tables_.dynamic_ids[j];
    v[g] = rule == Covisibility::StaticCount
               ? std::min(1.0f, tables_.dynamic_deficiency[size_t(f) * M + j] / scale(f))
               : std::min(1.0f, (1.0f + tables_.dynamic_speed[size_t(f) * M + j] / speed_scale_) * v[g]);
  }
  return v;
}

void DeficiencyField::add_view(int f, const std::vector<uint32_t>& visible) {
  const size_t N = tables_.gaussians, M = tables_.dynamic_ids.size();
  for (uint32_t g : visible) {
    uint16_t& c = tables_.counts[size_t(f) * N + g];
    if (c < 65535) ++c;
    const int32_t j = dynamic_index_[g];
    if (j >= 0) tables_.dynamic_deficiency[size_t(f) * M + size_t(j)] = tables_.dynamic_speed[size_t(f) * M + size_t(j)] / (1.0f + float(c));
  }
}

// ------------------------------------------------------------------ exploration priority (the paper, Sec. 3.2)

PriorityScores exploration_priority(const SelectInput& in, const SelectOptions& o, Progress& progress) {
  FILLGS_CHECK(in.scene && in.grid);
  const auto t0 = Clock::now();
  PriorityScores p;
  if (o.time_stride < 1) throw_error("select: time_stride must be at least 1");
  if (!(o.render_scale > 0 && o.render_scale <= 1)) throw_error("select: render_scale must lie in (0, 1]");
  for (size_t i = 0; i < in.views.size(); ++i)
    if (in.views[i].frame % o.time_stride == 0) p.views.push_back(uint32_t(i));
  const size_t n = p.views.size();
  p.raw_error.assign(n, 0.0);
  std::vector<double> raw_tr(n, 0.0), raw_rot(n, 0.0), raw_time(n, 0.0);
  // Translations of one fifth of the voxel size (the edge of a cube of the voxel's volume).
  const Vec3d vs = in.grid->voxel_size();
  const double shift = std::cbrt(vs.x() * vs.y() * vs.z()) / 5.0, angle = 0.2 * kPi / 180.0;
  const int F = in.frames;
  FrameSampler at_t(*in.scene), at_minus(*in.scene), at_plus(*in.scene);
  RenderOptions ro;
  ro.background = in.background;
  auto rgb = [&](const FrameGaussians& fg, const Camera& c) { return render(fg, c, ro).rgb; };
  progress.start("priority (L, V)", n);
  int current = -1;
  const FrameGaussians *ft = nullptr, *fm = nullptr, *fp = nullptr;
  for (size_t k = 0; k < n; ++k) {
    const ObservedView& v = in.views[p.views[k]];
    if (v.frame != current) {
      current = v.frame;
      // Time perturbation ±1 frame; at the ends the window moves inward (same span, 2 frames).
      const std::vector<int> window = FrameGrid(F).consecutive(v.frame, 3);
      const int lo = window.front(), hi = window.back();
      ft = &at_t.at(FrameGrid(F).time(v.frame));
      fm = &at_minus.at(FrameGrid(F).time(lo));
      fp = &at_plus.at(FrameGrid(F).time(hi));
    }
    // L at full resolution: a reduced render differs from a reduced image on fine texture
    // (aliasing), which would rank texture, not error.
    if (in.image) p.raw_error[k] = mean_squared_difference(rgb(*ft, v.camera), in.image(p.views[k]));
    const Camera cam = scaled_camera(v.camera, o.render_scale);
    const Vec3d c = cam.centre();
    for (int axis = 0; axis < 3; ++axis) {
      const Vec3d d = shift * cam.R.row(axis).transpose();
      raw_tr[k] += mean_squared_difference(rgb(*ft, with_pose(cam, cam.R, c + d)), rgb(*ft, with_pose(cam, cam.R, c - d)));
      raw_rot[k] += mean_squared_difference(rgb(*ft, with_pose(cam, axis_rotation(axis, angle) * cam.R, c)),
                                            rgb(*ft, with_pose(cam, axis_rotation(axis, -angle) * cam.R, c)));
    }
    if (F > 1) raw_time[k] = mean_squared_difference(rgb(*fp, cam), rgb(*fm, cam));
    progress.advance();
  }
  progress.finish();
  // Normalisation: L averages 1; each group g of n_g perturbations averages n_g / 7.
  auto normalised = [&](const std::vector<double>& raw, double target_mean) {
    const double mean = n ? std::accumulate(raw.begin(), raw.end(), 0.0) / double(n) : 0.0;
    std::vector<double> out(n, 0.0);
    if (mean > 0)
      for (size_t k = 0; k < n; ++k) out[k] = raw[k] / mean * target_mean;
    return out;
  };
  p.error = normalised(p.raw_error, 1.0);
  p.translation = normalised(raw_tr, 3.0 / 7.0);
  p.rotation = normalised(raw_rot, 3.0 / 7.0);
  p.time = normalised(raw_time, 1.0 / 7.0);
  p.priority.assign(n, 0.0);
  for (size_t k = 0; k < n; ++k) {
    if (!o.no_error_term) p.priority[k] += p.error[k];
    if (!o.no_sensitivity_term) p.priority[k] += p.translation[k] + p.rotation[k] + p.time[k];
  }
  p.seconds = seconds_since(t0);
  return p;
}

// ------------------------------------------------------------------ scoring

namespace {

struct Candidate {
  Camera camera;
  bool global = false;
};

}  // namespace

// ------------------------------------------------------------------ selection

namespace {

/// The observation tables of the observed viewpoints over every frame: where a selection starts.
ObservationTables training_tables(const SelectInput& in, const SelectOptions& o, const std::vector<Camera>& cameras, Progress& progress) {
  ObservationOptions oo;
  oo.visibility = o.visibility;
  const FrameGrid grid(in.frames);
  return observation_tables(*in.scene, cameras, grid.times(), grid.step(), oo, nullptr, progress);
}

/// A view (with its time) becomes an observation: the counts C at its nearest frame, then
/// the strategy's own state.
void count_view(const Camera& v, int frames, DeficiencyField& field, VisibilityEngine& engine, SelectionStrategy& strategy) {
  const FrameGrid grid(frames);
  const int f = grid.nearest(v.time);
  engine.set_time(grid.time(f));
  field.add_view(f, engine.visible_set(v));
  strategy.accept(v, f);
}

class Selector {
 public:
  Selector(const SelectInput& in, const SelectOptions& o, SelectResult& result, Progress& progress)
      : in_(in), o_(o), result_(result), progress_(progress), rng_(o.seed), cameras_(cameras_of(in.views)),
        vertical_(vertical_axis(cameras_)) {}

  void run() {
    const auto t_start = Clock::now();
    const int F = in_.frames;
    // Observation tables over every frame of the training views.
    auto t0 = Clock::now();
    ObservationTables tables = training_tables(in_, o_, cameras_, progress_);
    result_.initial_tables = tables;
    DeficiencyField field(std::move(tables), o_.deficiency_quantile);
    result_.deficiency_scale = field.scale();
    result_.timings.observe = seconds_since(t0);
    if (in_.scene->dynamic_ids.empty()) result_.notes.push_back("the scene has no moving Gaussians: D = 0 everywhere");

    // The strategy, with what it shares.
    VisibilityEngine engine(*in_.scene, o_.visibility);
    FrameSampler sampler(*in_.scene);
    SelectionContext context{in_, o_, field, engine, sampler, vertical_};
    const std::unique_ptr<SelectionStrategy> strategy = strategy_row(o_.strategy).make(context);
    strategy_ = strategy.get();
    engine_ = &engine;

    // Starting viewpoints.
    const bool uses_priority = strategy->starts() != SelectionStrategy::Starts::Shuffled && !o_.no_start_selection;
    if (uses_priority) {
      t0 = Clock::now();
      result_.priority = in_.priority ? *in_.priority : exploration_priority(in_, o_, progress_);
      result_.timings.priority = seconds_since(t0);
      if (!in_.image && !o_.no_error_term) result_.notes.push_back("no training images: the error term L is 0");
      starts_ = result_.priority.views;
      const std::vector<double>& e = result_.priority.priority;
      std::vector<size_t> order(starts_.size());
      std::iota(order.begin(), order.end(), 0);
      const bool ascending = strategy->starts() == SelectionStrategy::Starts::LowestPriority;
      std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return ascending ? e[a] < e[b] : e[a] > e[b]; });
      std::vector<uint32_t> sorted;
      for (size_t k : order) sorted.push_back(starts_[k]);
      starts_ = sorted;
    } else {
      starts_.resize(in_.views.size());
      std::iota(starts_.begin(), starts_.end(), 0u);
      for (size_t i = starts_.size(); i > 1; --i) std::swap(starts_[i - 1], starts_[size_t(rng_() % i)]);
    }

    for (const Camera& v : in_.earlier_views) {
      if (!v.has_time()) throw_error("select: earlier virtual view ", v.name, " has no time");
      accept(v, field);
    }
    progress_.start(std::string("select (") + o_.strategy + ")", size_t(o_.trajectories));
    size_t next_start = 0;
    for (int k = 0; k < o_.trajectories; ++k) {
      Trajectory tr;
      // A start whose neighbourhood has no free candidate yields nothing: try the next one.
      for (int attempt = 0; attempt < 64 && tr.poses.empty(); ++attempt) {
        if (strategy->paths() == SelectionStrategy::Paths::BetweenCameras) tr = interpolation_trajectory(k);
        else if (strategy->paths() == SelectionStrategy::Paths::RandomWalk) tr = random_trajectory();
        else {
          while (next_start < starts_.size() && o_.spread_starts && overlaps_earlier_start(starts_[next_start])) ++next_start;
          if (next_start >= starts_.size()) break;
          tr = grow(starts_[next_start]);
          if (!tr.poses.empty()) taken_starts_.push_back(starts_[next_start]);
          ++next_start;
        }
      }
      if (tr.poses.empty()) {
        result_.notes.push_back("stopped after " + std::to_string(k) + " trajectories: no free candidates left");
        break;
      }
      tr.index = k;
      tr.patch_frames = FrameGrid(F).consecutive(tr.frame, o_.patch_frames);
      for (int f : tr.patch_frames) tr.patch_times.push_back(time_of(f));
      t0 = Clock::now();
      for (const Camera& v : tr.views()) accept(v, field);
      result_.timings.update += seconds_since(t0);
      result_.trajectories.push_back(std::move(tr));
      progress_.advance();
    }
    progress_.finish();
    result_.timings.total = seconds_since(t_start);
  }

 private:
  double time_of(int f) const { return FrameGrid(in_.frames).time(f); }

  /// One virtual view (with its time) becomes an observation: the counts C, then the
  /// strategy's own state.
  void accept(const Camera& v, DeficiencyField& field) { count_view(v, in_.frames, field, *engine_, *strategy_); }

  /// Whether a trajectory of this call grew from a starting view of the same pose fewer
  /// than patch_frames frames from `view` (SelectOptions::spread_starts). The starting view,
  /// not Trajectory::start_view: a global winner moves that to the nearest training camera.
  bool overlaps_earlier_start(uint32_t view) const {
    const ObservedView& v = in_.views[view];
    for (uint32_t taken : taken_starts_) {
      const ObservedView& s = in_.views[taken];
      if (s.pose == v.pose && std::abs(s.frame - v.frame) < o_.patch_frames) return true;
    }
    return false;
  }

  /// One camera per distinct pose observing frame f.
  std::vector<Camera> training_at(int f, std::vector<uint32_t>* view_ids = nullptr) const {
    std::vector<Camera> out;
    std::vector<uint32_t> seen;
    for (size_t i = 0; i < in_.views.size(); ++i)
      if (in_.views[i].frame == f && std::find(seen.begin(), seen.end(), in_.views[i].pose) == seen.end()) {
        seen.push_back(in_.views[i].pose);
        out.push_back(in_.views[i].camera);
        if (view_ids) view_ids->push_back(uint32_t(i));
      }
    return out;
  }

  /// Each pose's view at its earliest frame (indices into in_.views), ordered by (frame,
  /// index): at frame 0 of a multi-view video the same as training_at(0).
  std::vector<uint32_t> first_view_of_each_pose() const {
    std::vector<uint32_t> first;
    for (size_t i = 0; i < in_.views.size(); ++i) {
      auto same = std::find_if(first.begin(), first.end(), [&](uint32_t j) { return in_.views[j].pose == in_.views[i].pose; });
      if (same == first.end()) first.push_back(uint32_t(i));
      else if (in_.views[i].frame < in_.views[*same].frame) *same = uint32_t(i);
    }
    std::stable_sort(first.begin(), first.end(), [&](uint32_t x, uint32_t y) { return in_.views[x].frame < in_.views[y].frame; });
    return first;
  }

  /// Nearest observed view at frame f to a point (index into in_.views).
  uint32_t nearest_view(int f, const Vec3d& p) const {
    std::vector<uint32_t> ids;
    const std::vector<Camera> cams = training_at(f, &ids);
    size_t best = 0;
    for (size_t i = 1; i < cams.size(); ++i)
      if ((cams[i].centre() - p).norm() < (cams[best].centre() - p).norm()) best = i;
    return ids[best];
  }

  Trajectory grow(uint32_t start_view) {
    const ObservedView& sv = in_.views[start_view];
    const int f = sv.frame;
    const double step = in_.grid->step(), tol = 1e-6 * step;
    const std::vector<Camera> train = training_at(f);
    Trajectory tr;
    tr.start_view = int(start_view);
    tr.frame = f;
    Camera cur = sv.camera;
    std::vector<Camera> visited{cur};
    for (int s = 0; s < o_.views; ++s) {
      auto t0 = Clock::now();
      std::vector<Candidate> cands;
      for (Camera& c : local_candidates(cur, train, step, o_.rotation_step_degrees)) {
        const bool moved = (c.centre() - cur.centre()).norm() > tol;
        if (!in_.grid->is_free(c.centre()) || (moved && !in_.grid->segment_free(cur.centre(), c.centre()))) {
          ++result_.timings.candidates_rejected;
          continue;
        }
        if (std::any_of(visited.begin(), visited.end(), [&](const Camera& v) { return same_pose(v, c, tol); })) continue;
        cands.push_back({c, false});
      }
      if (s == 0 && !o_.no_global)
        for (Camera& g : global_candidates(sv.camera, train, *in_.grid, o_.global_candidates, o_.views * step, rng_))
          cands.push_back({std::move(g), true});
      result_.timings.candidates += seconds_since(t0);
      if (cands.empty()) break;
      t0 = Clock::now();
      size_t pick = 0;
      std::vector<double> scores(cands.size(), 0.0);
      if (o_.no_candidate_scoring) {
        pick = size_t(rng_() % cands.size());
      } else {
        std::vector<Camera> cc;
        for (const Candidate& c : cands) cc.push_back(c.camera);
        scores = strategy_->score(cc, f);
        result_.timings.candidates_scored += cands.size();
        const bool lowest = strategy_->lowest_wins();
        for (size_t i = 1; i < scores.size(); ++i)
          if (lowest ? scores[i] < scores[pick] : scores[i] > scores[pick]) pick = i;
      }
      result_.timings.scoring += seconds_since(t0);
      const Candidate& win = cands[pick];
      if (win.global) {
        // The trajectory becomes the path from the nearest training camera to the winner.
        const uint32_t near = nearest_view(f, win.camera.centre());
        tr.start_view = int(near);
        tr.global = true;
        tr.poses.clear();
        tr.scores.clear();
        for (int j = 1; j <= o_.views; ++j) {
          tr.poses.push_back(interpolate_camera(in_.views[near].camera, win.camera, double(j) / o_.views));
          tr.scores.push_back(scores[pick]);
        }
        break;
      }
      tr.poses.push_back(win.camera);
      tr.scores.push_back(scores[pick]);
      visited.push_back(win.camera);
      cur = win.camera;
    }
    for (Camera& c : tr.poses) c.time = time_of(f);
    return tr;
  }

  /// `random`: a free position and frame drawn uniformly, looking at a random opaque
  /// Gaussian, then random free local steps.
  Trajectory random_trajectory() {
    Trajectory tr;
    const int f = int(rng_() % uint64_t(in_.frames));
    tr.frame = f;
    const std::vector<Vec3d> p = in_.grid->sample_free(in_.grid->box(), 1, rng_);
    if (p.empty()) return tr;
    engine_->set_time(time_of(f));
    const FrameGaussians& fg = engine_->frame();
    Vec3d target = p[0];
    for (int tries = 0; tries < 100 && (target - p[0]).norm() < 1e-6; ++tries) {
      const uint32_t g = uint32_t(rng_() % uint64_t(fg.size()));
      if (fg.opacities[g] >= 0.5f) target = fg.means[g].cast<double>();
    }
    Vec3d up = Vec3d::Zero();
    up[vertical_] = 1.0;
    const uint32_t near = nearest_view(f, p[0]);
    Camera cur = in_.views[near].camera;
    cur.look_at(p[0], target, up);
    tr.start_view = int(near);
    tr.poses.push_back(cur);
    tr.scores.push_back(0.0);
    const std::vector<Camera> train = training_at(f);
    const double step = in_.grid->step();
    while (int(tr.poses.size()) < o_.views) {
      std::vector<Camera> free;
      for (Camera& c : local_candidates(cur, train, step, o_.rotation_step_degrees))
        if (in_.grid->is_free(c.centre()) && in_.grid->segment_free(cur.centre(), c.centre())) free.push_back(c);
      if (free.empty()) break;
      cur = free[size_t(rng_() % free.size())];
      tr.poses.push_back(cur);
      tr.scores.push_back(0.0);
    }
    for (Camera& c : tr.poses) c.time = time_of(f);
    return tr;
  }

  /// `interpolation` (GS-GS): poses between neighbouring training cameras, one pair per
  /// trajectory in turn, at a frame drawn uniformly; centres lerped, rotations slerped. The
  /// cameras are the rig's, each as first seen (frame 0 of a multi-view video; a monocular
  /// one holds each camera at some frames only): the pair need not be filmed at the frame.
  Trajectory interpolation_trajectory(int k) {
    if (pairs_.empty()) {
      std::vector<uint32_t> ids = first_view_of_each_pose();
      std::vector<Camera> cams;
      for (uint32_t i : ids) cams.push_back(in_.views[i].camera);
      for (size_t i = 0; i < cams.size(); ++i) {  // each camera with its two nearest
        std::vector<std::pair<double, size_t>> near;
        for (size_t j = 0; j < cams.size(); ++j)
          if (j != i) near.emplace_back((cams[j].centre() - cams[i].centre()).norm(), j);
        std::sort(near.begin(), near.end());
        for (size_t n = 0; n < 2 && n < near.size(); ++n) {
          const uint32_t u = in_.views[ids[i]].pose, w = in_.views[ids[near[n].second]].pose;
          const std::pair<uint32_t, uint32_t> pr(std::min(u, w), std::max(u, w));
          if (std::find(pairs_.begin(), pairs_.end(), pr) == pairs_.end()) pairs_.push_back(pr);
        }
      }
      if (pairs_.empty()) throw_error("interpolation strategy: needs at least two distinct training cameras");
    }
    const auto [pa, pb] = pairs_[size_t(k) % pairs_.size()];
    const int f = int(rng_() % uint64_t(in_.frames));
    Trajectory tr;
    tr.frame = f;
    const Camera *a = nullptr, *b = nullptr;
    for (size_t i = 0; i < in_.views.size(); ++i)
      if (in_.views[i].frame == f) {
        if (in_.views[i].pose == pa && !a) a = &in_.views[i].camera, tr.start_view = int(i);
        if (in_.views[i].pose == pb && !b) b = &in_.views[i].camera;
      }
    // Not filmed at f (monocular video): the camera's pose from its first view; the patch
    // then starts from the nearest view filmed at f (start_view stays -1).
    for (uint32_t i : first_view_of_each_pose()) {
      if (!a && in_.views[i].pose == pa) a = &in_.views[i].camera;
      if (!b && in_.views[i].pose == pb) b = &in_.views[i].camera;
    }
    if (!a || !b) return tr;
    for (int j = 1; j <= o_.views; ++j) {
      Camera c = interpolate_camera(*a, *b, double(j) / (o_.views + 1));
      c.time = time_of(f);
      tr.poses.push_back(c);
      tr.scores.push_back(0.0);
    }
    return tr;
  }

  const SelectInput& in_;
  const SelectOptions& o_;
  SelectResult& result_;
  Progress& progress_;
  std::mt19937_64 rng_;
  std::vector<uint32_t> starts_;
  std::vector<uint32_t> taken_starts_;  // starting views that grew a trajectory (spread_starts)
  std::vector<std::pair<uint32_t, uint32_t>> pairs_;
  const std::vector<Camera> cameras_;  ///< the observed viewpoints' cameras
  const int vertical_;                 ///< world axis closest to the cameras' up
  SelectionStrategy* strategy_ = nullptr;  ///< made in run()
  VisibilityEngine* engine_ = nullptr;     ///< the strategies' engine, made in run()
};

}  // namespace

PoolSelectResult select_from_pool(const SelectInput& in, const std::vector<ObservedView>& pool, int count, const SelectOptions& o, bool exhaustive,
                                  Progress& progress) {
  if (!in.scene) throw_error("select: a scene is required");
  if (in.views.empty()) throw_error("select: no observed viewpoints");
  if (in.scene->size() == 0) throw_error("select: the scene has no Gaussians, so no camera observes anything and there is no view to choose");
  if (count < 0) throw_error("select: the number of pool views to choose must be at least 0");
  const auto t_start = Clock::now();
  const FrameGrid grid(in.frames);
  for (const ObservedView& v : pool)
    if (v.frame < 0 || v.frame >= in.frames) throw_error("select: pool view ", v.camera.name, " has frame ", v.frame, " outside 0..", in.frames - 1);
  PoolSelectResult result;
  const std::vector<Camera> cameras = cameras_of(in.views);
  result.initial_tables = training_tables(in, o, cameras, progress);
  DeficiencyField field(result.initial_tables, o.deficiency_quantile);
  result.deficiency_scale = field.scale();
  if (in.scene->dynamic_ids.empty()) result.notes.push_back("the scene has no moving Gaussians: D = 0 everywhere");
  VisibilityEngine engine(*in.scene, o.visibility);
  FrameSampler sampler(*in.scene);
  SelectionContext context{in, o, field, engine, sampler, vertical_axis(cameras)};
  const std::unique_ptr<SelectionStrategy> strategy = strategy_row(o.strategy).make(context);
  for (const Camera& v : in.earlier_views) {
    if (!v.has_time()) throw_error("select: earlier view ", v.name, " has no time");
    count_view(v, in.frames, field, engine, *strategy);
  }
  const size_t n = std::min(pool.size(), size_t(count));
  std::mt19937_64 rng(o.seed);
  std::vector<size_t> order(pool.size());
  std::iota(order.begin(), order.end(), size_t(0));
  for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[size_t(rng() % i)]);
  progress.start(std::string("select from the pool (") + o.strategy + ")", n);
  auto choose = [&](size_t c, double score) {
    result.chosen.push_back({c, score});
    Camera v = pool[c].camera;
    v.time = grid.time(pool[c].frame);
    count_view(v, in.frames, field, engine, *strategy);
    progress.advance();
  };
  if (const auto fixed = strategy->pool_order(pool, cameras, order)) {
    for (size_t k = 0; k < std::min(n, fixed->size()); ++k) choose((*fixed)[k].first, (*fixed)[k].second);
  } else {
    // Scores per frame (a strategy scores candidates of one frame at a time).
    std::vector<std::vector<size_t>> at(size_t(in.frames));
    for (size_t i = 0; i < pool.size(); ++i) at[size_t(pool[i].frame)].push_back(i);
    std::vector<double> score(pool.size(), 0.0);
    std::vector<uint8_t> taken(pool.size(), 0);
    auto rescore = [&](const std::vector<size_t>& ids, int f) {
      std::vector<Camera> cams;
      std::vector<size_t> live;
      for (size_t i : ids)
        if (!taken[i]) {
          cams.push_back(pool[i].camera);
          cams.back().time = grid.time(f);
          live.push_back(i);
        }
      if (live.empty()) return;
      const std::vector<double> s = strategy->score(cams, f);
      for (size_t k = 0; k < live.size(); ++k) score[live[k]] = s[k];
      result.scored += live.size();
    };
    for (int f = 0; f < in.frames; ++f) rescore(at[size_t(f)], f);
    const bool lowest = strategy->lowest_wins();
    auto better = [&](size_t a, size_t b) { return lowest ? score[a] < score[b] : score[a] > score[b]; };
    if (lowest || exhaustive) {
      for (size_t k = 0; k < n; ++k) {
        size_t best = pool.size();
        for (size_t i = 0; i < pool.size(); ++i)
          if (!taken[i] && (best == pool.size() || better(i, best))) best = i;
        taken[best] = 1;
        choose(best, score[best]);
        if (exhaustive) {
          for (int f = 0; f < in.frames; ++f) rescore(at[size_t(f)], f);
        } else {
          rescore(at[size_t(pool[best].frame)], pool[best].frame);  // only the chosen frame's counts changed
        }
      }
    } else {
      // Lazy greedy: scores are upper bounds until rescored after the latest choice.
      std::vector<size_t> fresh_at(pool.size(), 0);  // the choice count when last scored
      auto before = [&](size_t a, size_t b) { return score[a] < score[b] || (score[a] == score[b] && a > b); };
      std::priority_queue<size_t, std::vector<size_t>, decltype(before)> heap(before);
      for (size_t i = 0; i < pool.size(); ++i) heap.push(i);
      while (result.chosen.size() < n && !heap.empty()) {
        const size_t top = heap.top();
        heap.pop();
        if (fresh_at[top] == result.chosen.size()) {
          taken[top] = 1;
          choose(top, score[top]);
          continue;
        }
        rescore({top}, pool[top].frame);
        fresh_at[top] = result.chosen.size();
        heap.push(top);
      }
    }
  }
  progress.finish();
  result.seconds = seconds_since(t_start);
  return result;
}

SelectResult select_viewpoints(const SelectInput& in, const SelectOptions& o, Progress& progress) {
  if (!in.scene || !in.grid) throw_error("select: a scene and an exploration grid are required");
  if (in.views.empty()) throw_error("select: no observed viewpoints");
  if (in.scene->size() == 0) throw_error("select: the scene has no Gaussians, so no camera observes anything and there is no view to choose");
  if (o.trajectories < 0) throw_error("select: trajectories must be at least 0");
  if (o.views < 1) throw_error("select: views must be at least 1");
  if (o.patch_frames < 1) throw_error("select: patch_frames must be at least 1");
  if (o.stride < 1) throw_error("select: stride must be at least 1");
  SelectResult result;
  Selector(in, o, result, progress).run();
  return result;
}

Bounds trajectory_bounds() { return within(0, 100000); }
Bounds views_bounds() { return within(1, 1000); }
Bounds patch_frame_bounds() { return within(1, 1000); }

void check_select_options(const SelectOptions& o, const Spelling& s) {
  strategy_row(o.strategy);
  check_within(s("trajectories"), o.trajectories, trajectory_bounds());
  check_within(s("views"), o.views, views_bounds());
  check_within(s("patch_frames"), o.patch_frames, patch_frame_bounds());
  check_within(s("time_stride"), o.time_stride, at_least(1));
  if (o.no_error_term && o.no_sensitivity_term) throw_error(s("no_error_term"), " and ", s("no_sensitivity_term"), " leave no priority");
}

}  // namespace fillgs
