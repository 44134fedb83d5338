// `rig`: the real photograph of the nearest pool camera of the rig (neither trained on nor
// held out) at the view's frame, at that camera's real pose (method/refine.hpp, RigOptions).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

namespace {
const RowParameter& rig_max_distance() {
  static const RowParameter p = RowParameter::number("rig_max_distance", RigOptions{}.max_distance, at_least(0),
                                                     "rig: how far a pool camera may stand from the virtual view");
  return p;
}
const RowParameter& rig_max_angle() {
  static const RowParameter p = RowParameter::number("rig_max_angle", RigOptions{}.max_angle_degrees, within(0, 180),
                                                     "rig: how far it may look away (degrees)");
  return p;
}
RigOptions rig_options(const RefinerInputs& in) {
  RigOptions o;
  o.max_distance = in.parameters.number(rig_max_distance());
  o.max_angle_degrees = in.parameters.number(rig_max_angle());
  return o;
}
}  // namespace

const RefinerKind& row_rig() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "rig";
    k.description = "the nearest pool camera's real photograph, at its real pose (real captures)";
    k.order = 50;
    k.needs_pool = true;
    k.parameters = {&rig_max_distance(), &rig_max_angle()};
    k.make = [](const RefinerInputs& in) { return make_rig_refiner(*in.pool, rig_options(in)); };
    k.identity = [](const RefinerInputs& in) {
      nlohmann::json j = in.parameters.identity({&rig_max_distance(), &rig_max_angle()});
      j["name"] = "rig";
      return j;
    };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
