// `coverage3d`: new (Gaussian x direction) cells over the whole video.
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"
#include "method/strategies/coverage.hpp"

namespace fillgs::strategy_rows {

const StrategyRow& row_coverage3d() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "coverage3d";
    r.description = "a candidate scores the Gaussian-direction cells no view has covered, one set for the whole video";
    r.order = 60;
    r.make = [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<CoverageStrategy>(c, false); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
