#include "fillgs/method/strategies.hpp"

#include "fillgs/base/error.hpp"

namespace fillgs {

namespace strategy_rows {
std::vector<const StrategyRow*> rows();  // generated from src/method/strategies/ (src/row_table.cpp.in)
}  // namespace strategy_rows

const RowTable<StrategyRow>& strategy_table() {
  static const RowTable<StrategyRow> table("strategy", strategy_rows::rows());
  return table;
}

const StrategyRow& strategy_row(const std::string& name) { return strategy_table().find(name); }

const StrategyRow& method_strategy() {
  for (const StrategyRow* r : strategy_table().rows())
    if (r->method) return *r;
  throw_error("no strategy row is the method's");
}

}  // namespace fillgs
