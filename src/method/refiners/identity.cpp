// `identity`: the render itself, unrefined (what fine-tuning on the model's own views does).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_identity() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "identity";
    k.description = "the render itself, unrefined";
    k.order = 70;
    k.make = [](const RefinerInputs&) { return make_identity_refiner(); };
    k.identity = [](const RefinerInputs&) { return nlohmann::json{{"name", "identity"}}; };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
