// `identity`: the render itself, unrefined (what fine-tuning on the model's own views does).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_identity() {
  static const RefinerKind row{"identity", "the render itself, unrefined", 70, false, false, false, false,
                               [](const RefinerInputs&) { return make_identity_refiner(); },
                               [](const RefinerInputs&) { return nlohmann::json{{"name", "identity"}}; }};
  return row;
}

}  // namespace fillgs::refiner_rows
