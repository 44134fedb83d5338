// `warp`: the start photograph warped into the virtual view through the render's depth,
// with the reference refiner's confidence and fill (any data, real video included; with the
// truth, its records carry PSNRs against it).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_warp() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "warp";
    k.description = "the start photograph warped through the render's depth (any data)";
    k.order = 40;
    k.make = [](const RefinerInputs& in) { return make_warp_refiner(in.reference, in.stats, in.truth); };
    k.identity = [](const RefinerInputs& in) {
      nlohmann::json j = identity_json(in.reference);
      j["name"] = "warp";
      return j;
    };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
