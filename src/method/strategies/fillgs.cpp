// `fillgs`: the paper's strategy (Sec. 3.2-3.3).
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"
#include "method/strategies/deficiency.hpp"

namespace fillgs::strategy_rows {

const StrategyRow& row_fillgs() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "fillgs";
    r.description = "the paper's: starts by exploration priority, candidates scored by their rendered motion-aware deficiency";
    r.order = 10;
    r.method = true;
    r.make = [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<DeficiencyStrategy>(c); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
