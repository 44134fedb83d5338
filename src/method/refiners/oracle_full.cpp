// `oracle-full`: the ground truth everywhere, also where no training camera looked (a bound
// that rewards looking away from the capture; synthetic scenes).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

RefinerKind oracle_kind(std::string name, std::string description, int order, OracleSupport support);  // oracle.cpp

const RefinerKind& row_oracle_full() {
  static const RefinerKind row =
      oracle_kind("oracle-full", "the ground truth everywhere (a bound that rewards looking away from the capture)", 30, OracleSupport::Full);
  return row;
}

}  // namespace fillgs::refiner_rows
