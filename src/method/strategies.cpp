// The selection strategies (selection_strategy.hpp), one class each, and their registry.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "fillgs/base/error.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/train/train_model.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs {

namespace {

/// fillgs (the paper's): starts by the exploration priority E; a candidate scores the mean
/// of its rendered D̂ map (or, with SelectOptions::score_gain, the sum of D̂ over what it
/// sees), the counts and ablations as SelectOptions::score says.
class DeficiencyStrategy : public SelectionStrategy {
 public:
  explicit DeficiencyStrategy(SelectionContext& c) : c_(c) {}
  Starts starts() const override { return Starts::HighestPriority; }
  std::vector<double> score(const std::vector<Camera>& cands, int frame) override {
    std::vector<double> s(cands.size(), 0.0);
    const double t = c_.time_of(frame);
    const std::vector<float> values = c_.field.values(frame, c_.options.score);
    if (c_.options.score_gain) {
      c_.engine.set_time(t);
      for (size_t i = 0; i < cands.size(); ++i)
        for (uint32_t g : c_.engine.visible_set(cands[i])) s[i] += double(values[g]);
    } else {
      for (size_t i = 0; i < cands.size(); ++i) s[i] = map_mean(cands[i], t, values.data());
    }
    return s;
  }

 private:
  /// The mean of the rendered per-Gaussian `values` at time t.
  double map_mean(const Camera& cam, double t, const float* values) {
    if (c_.options.renderer == MapRenderer::Raytraced) {
      c_.engine.set_time(t);
      return c_.engine.render_maps(cam, values, nullptr, c_.options.stride).score();
    }
    return mean_value(render_value_map(c_.sampler.at(t), cam, values));
  }
  SelectionContext& c_;
};

/// negative (ablation): fillgs turned round, the least-priority starts and the lowest-scoring
/// candidates.
class NegativeStrategy : public DeficiencyStrategy {
 public:
  using DeficiencyStrategy::DeficiencyStrategy;
  Starts starts() const override { return Starts::LowestPriority; }
  bool lowest_wins() const override { return true; }
};

/// random: a free position and frame drawn uniformly, then random free local steps.
class RandomStrategy : public SelectionStrategy {
 public:
  Paths paths() const override { return Paths::RandomWalk; }
  /// A pool: in the seed's random order, each with score 0.
  std::optional<std::vector<std::pair<size_t, double>>> pool_order(const std::vector<ObservedView>&, const std::vector<Camera>&,
                                                                   const std::vector<size_t>& shuffled) const override {
    std::vector<std::pair<size_t, double>> out;
    for (size_t i : shuffled) out.emplace_back(i, 0.0);
    return out;
  }
};

/// interpolation (GS-GS): poses between neighbouring training cameras.
class InterpolationStrategy : public SelectionStrategy {
 public:
  Paths paths() const override { return Paths::BetweenCameras; }
  /// A pool: nearest the chords between neighbouring training poses first (score: minus the
  /// distance), ties in the seed's random order.
  std::optional<std::vector<std::pair<size_t, double>>> pool_order(const std::vector<ObservedView>& pool, const std::vector<Camera>& training,
                                                                   const std::vector<size_t>& shuffled) const override {
    // Chords: each training pose with its nearest other pose (distinct centres).
    std::vector<Vec3d> poses;
    for (const Camera& c : training)
      if (std::none_of(poses.begin(), poses.end(), [&](const Vec3d& p) { return (p - c.centre()).norm() < 1e-9; })) poses.push_back(c.centre());
    std::vector<std::pair<Vec3d, Vec3d>> chords;
    for (size_t a = 0; a < poses.size(); ++a) {
      size_t b = a;
      for (size_t j = 0; j < poses.size(); ++j)
        if (j != a && (b == a || (poses[j] - poses[a]).norm() < (poses[b] - poses[a]).norm())) b = j;
      if (b != a) chords.emplace_back(poses[a], poses[b]);
    }
    if (chords.empty()) throw_error("select: interpolation needs two training poses at distinct centres");
    auto distance = [&](const Vec3d& p) {
      double best = std::numeric_limits<double>::infinity();
      for (const auto& [a, b] : chords) {
        const Vec3d ab = b - a;
        const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
        best = std::min(best, (p - (a + t * ab)).norm());
      }
      return best;
    };
    std::vector<double> d(pool.size());
    for (size_t i = 0; i < pool.size(); ++i) d[i] = distance(pool[i].camera.centre());
    std::vector<size_t> order = shuffled;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return d[a] < d[b]; });
    std::vector<std::pair<size_t, double>> out;
    for (size_t i : order) out.emplace_back(i, -d[i]);
    return out;
  }
};

/// fisherrf: a candidate scores Σ_params H_cand / (H_train + λ), H the diagonal Fisher
/// information Σ_pixels (∂Î/∂θ)² at the selection's render scale; accepted views join H_train.
class FisherStrategy : public SelectionStrategy {
 public:
  explicit FisherStrategy(SelectionContext& c) : c_(c), params_(params_from_cloud<float>(*c.in.scene)) {}
  std::vector<double> score(const std::vector<Camera>& cands, int frame) override {
    std::vector<double> s(cands.size(), 0.0);
    const std::vector<double>& train = train_information(frame);
    for (size_t i = 0; i < cands.size(); ++i) {
      const FisherDiagonal h = information(cands[i], frame);
      double total = 0;
      for (size_t k = 0; k < h.values.size(); ++k) total += h.values[k] / (train[k] + double(c_.options.fisher_lambda));
      s[i] = total;
    }
    return s;
  }
  void accept(const Camera& view, int frame) override {
    std::vector<double>& train = train_information(frame);
    const FisherDiagonal h = information(view, frame);
    for (size_t k = 0; k < h.values.size(); ++k) train[k] += h.values[k];
  }

 private:
  FisherDiagonal information(const Camera& cam, int frame) {
    if (frame != frame_index_) {
      params_at(params_, c_.time_of(frame), &frame_);
      frame_index_ = frame;
    }
    DiffRenderOptions ro;
    ro.background = c_.in.background;
    raster_.forward(frame_, scaled_camera(cam, c_.options.render_scale), ro);
    FisherDiagonal h;
    raster_.accumulate_fisher(&h);
    if (h.values.empty()) h.values.assign(c_.in.scene->size() * FisherDiagonal::kParams, 0.0);
    return h;
  }
  std::vector<double>& train_information(int frame) {
    auto it = train_.find(frame);
    if (it != train_.end()) return it->second;
    std::vector<double> sum(c_.in.scene->size() * FisherDiagonal::kParams, 0.0);
    for (const ObservedView& v : c_.in.views)
      if (v.frame == frame) {
        const FisherDiagonal h = information(v.camera, frame);
        for (size_t k = 0; k < sum.size(); ++k) sum[k] += h.values[k];
      }
    return train_.emplace(frame, std::move(sum)).first->second;
  }

  SelectionContext& c_;
  ModelParams<float> params_;
  DiffFrame<float> frame_;
  int frame_index_ = -1;
  DiffRasterizer<float> raster_;
  std::map<int, std::vector<double>> train_;  ///< H_train per frame
};

/// coverage3d / coverage4d: a candidate scores the (Gaussian × direction bin) cells it sees
/// that no view has covered, 8 azimuth × 4 elevation bins of 45°; 4D keeps one set of cells
/// per frame, 3D one for the whole video. The training views cover first.
class CoverageStrategy : public SelectionStrategy {
 public:
  CoverageStrategy(SelectionContext& c, bool per_frame) : c_(c), per_frame_(per_frame) {
    coverage_.assign((per_frame ? size_t(c.in.frames) : 1) * c.in.scene->size(), 0u);
    for (const ObservedView& v : c.in.views) cover(v.camera, v.frame);
  }
  std::vector<double> score(const std::vector<Camera>& cands, int frame) override {
    std::vector<double> s(cands.size(), 0.0);
    c_.engine.set_time(c_.time_of(frame));
    for (size_t i = 0; i < cands.size(); ++i) s[i] = double(new_cells(cands[i], frame));
    return s;
  }
  void accept(const Camera& view, int frame) override { cover(view, frame); }

 private:
  uint32_t direction_bit(const Vec3d& from_gaussian) const {
    const int a = (c_.vertical + 1) % 3, b = (c_.vertical + 2) % 3;
    const Vec3d d = from_gaussian.normalized();
    const double el = std::asin(std::clamp(d[c_.vertical], -1.0, 1.0)) * 180.0 / kPi;  // [-90, 90]
    const double az = std::atan2(d[b], d[a]) * 180.0 / kPi;                              // (-180, 180]
    const int e = std::clamp(int(std::floor((el + 90.0) / 45.0)), 0, 3);
    const int z = std::clamp(int(std::floor((az + 180.0) / 45.0)), 0, 7);
    return 1u << (e * 8 + z);
  }
  uint32_t* row(int frame) { return coverage_.data() + (per_frame_ ? size_t(frame) * c_.in.scene->size() : 0); }
  size_t new_cells(const Camera& cam, int frame) {
    const uint32_t* r = row(frame);
    const FrameGaussians& fg = c_.engine.frame();
    const Vec3d centre = cam.centre();
    size_t n = 0;
    for (uint32_t g : c_.engine.visible_set(cam))
      if (!(r[g] & direction_bit(centre - fg.means[g].cast<double>()))) ++n;
    return n;
  }
  void cover(const Camera& cam, int frame) {
    c_.engine.set_time(c_.time_of(frame));
    uint32_t* r = row(frame);
    const FrameGaussians& fg = c_.engine.frame();
    const Vec3d centre = cam.centre();
    for (uint32_t g : c_.engine.visible_set(cam)) r[g] |= direction_bit(centre - fg.means[g].cast<double>());
  }

  SelectionContext& c_;
  bool per_frame_;
  std::vector<uint32_t> coverage_;
};

/// The registry: each strategy's maker, by its value (whose name is in select.hpp).
struct StrategyEntry {
  Strategy id;
  std::unique_ptr<SelectionStrategy> (*make)(SelectionContext& c);
};
const StrategyEntry kStrategies[] = {
    {Strategy::FillGS, [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<DeficiencyStrategy>(c); }},
    {Strategy::Random, [](SelectionContext&) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<RandomStrategy>(); }},
    {Strategy::Negative, [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<NegativeStrategy>(c); }},
    {Strategy::Interpolation, [](SelectionContext&) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<InterpolationStrategy>(); }},
    {Strategy::FisherRF, [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<FisherStrategy>(c); }},
    {Strategy::Coverage3D, [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<CoverageStrategy>(c, false); }},
    {Strategy::Coverage4D, [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<CoverageStrategy>(c, true); }},
};

}  // namespace

std::unique_ptr<SelectionStrategy> make_strategy(Strategy s, SelectionContext& context) {
  for (const StrategyEntry& e : kStrategies)
    if (e.id == s) return e.make(context);
  throw_error("select: strategy '", to_string(s), "' has no maker in the registry");
}

}  // namespace fillgs
