// `random`: a random walk from a random free position.
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs::strategy_rows {

namespace {

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

}  // namespace

const StrategyRow& row_random() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "random";
    r.description = "a free position and frame drawn uniformly, then random free local steps; a pool in random order";
    r.order = 20;
    r.make = [](SelectionContext&) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<RandomStrategy>(); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
