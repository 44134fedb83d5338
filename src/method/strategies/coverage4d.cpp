// `coverage4d`: new (Gaussian x direction) cells per frame.
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"
#include "method/strategies/coverage.hpp"

namespace fillgs::strategy_rows {

const StrategyRow& row_coverage4d() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "coverage4d";
    r.description = "a candidate scores the Gaussian-direction cells no view has covered at its frame";
    r.order = 70;
    r.make = [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<CoverageStrategy>(c, true); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
