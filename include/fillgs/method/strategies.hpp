#pragma once
// The selection strategies, one table (base/row_table.hpp): each is one file under
// src/method/strategies/ that defines its row {heading, make(context)}, and the build
// collects every file there into the table (CMakeLists.txt, src/row_table.cpp.in).
// SelectOptions::strategy names a row; the strategy's class (src/method/selection_strategy.hpp)
// decides everything it does differently: its starts, paths, scores and its order of a pool.
// A strategy's own parameters are declared in its row (RowHeading::parameters): the command
// line's flags, select's and finetune's keywords and the run identity are made from them,
// and the strategy reads their values through SelectionContext::options.parameters.
// Adding a strategy is adding its file (and its test); nothing else names it.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/row_table.hpp"

namespace fillgs {

class SelectionStrategy;
struct SelectionContext;

/// The heading's name is what --strategy and select(strategy=) take.
struct StrategyRow : RowHeading {
  /// The paper's own strategy: the benchmark weighs its views with FillGS's weights, the
  /// baselines' with the baseline weighting, and `fillgs run` compares the others with it.
  bool method = false;
  /// The strategy, sharing `context` (which must outlive it).
  std::function<std::unique_ptr<SelectionStrategy>(SelectionContext&)> make;
};

/// The table of strategies, in listing order.
const RowTable<StrategyRow>& strategy_table();
/// The strategy of that name; one line listing the names otherwise.
const StrategyRow& strategy_row(const std::string& name);
/// The paper's own strategy (the row with `method`).
const StrategyRow& method_strategy();

}  // namespace fillgs
