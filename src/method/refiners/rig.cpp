// `rig`: the real photograph of the nearest pool camera of the rig (neither trained on nor
// held out) at the view's frame, at that camera's real pose (method/refine.hpp, RigOptions).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_rig() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "rig";
    k.description = "the nearest pool camera's real photograph, at its real pose (real captures)";
    k.order = 50;
    k.needs_pool = true;
    k.make = [](const RefinerInputs& in) { return make_rig_refiner(*in.pool, in.rig); };
    k.identity = [](const RefinerInputs& in) {
      return nlohmann::json{{"name", "rig"}, {"max_distance", in.rig.max_distance}, {"max_angle_degrees", in.rig.max_angle_degrees}};
    };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
