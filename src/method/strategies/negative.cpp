// `negative` (ablation): fillgs turned round.
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"
#include "method/strategies/deficiency.hpp"

namespace fillgs::strategy_rows {

namespace {

/// negative (ablation): fillgs turned round, the least-priority starts and the lowest-scoring
/// candidates.
class NegativeStrategy : public DeficiencyStrategy {
 public:
  using DeficiencyStrategy::DeficiencyStrategy;
  Starts starts() const override { return Starts::LowestPriority; }
  bool lowest_wins() const override { return true; }
};

}  // namespace

const StrategyRow& row_negative() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "negative";
    r.description = "fillgs turned round: the least-priority starts and the lowest-scoring candidates (the negative control)";
    r.order = 30;
    r.make = [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<NegativeStrategy>(c); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
