// `interpolation` (GS-GS): poses between neighbouring training cameras.
#include <algorithm>
#include <limits>

#include "fillgs/base/error.hpp"
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs::strategy_rows {

namespace {

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

}  // namespace

const StrategyRow& row_interpolation() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "interpolation";
    r.description = "poses between neighbouring training cameras; a pool nearest their chords first";
    r.order = 40;
    r.make = [](SelectionContext&) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<InterpolationStrategy>(); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
