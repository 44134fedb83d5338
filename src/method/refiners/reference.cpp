// `reference`: conditioned on the patch's start view alone, confidence falling with the
// parallax angle to it; its content is the ground truth the start camera saw (synthetic
// scenes). The benchmark's calibrated refiner (method/refine.hpp, ReferenceOptions). What it
// restores is what a training view already saw: it cannot reward a selection.
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_reference() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "reference";
    k.description = "conditioned on the start view alone, confidence falling with the parallax angle to it (synthetic scenes; calibrated)";
    k.order = 10;
    k.needs_truth = true;
    k.benchmark = true;
    k.calibrated = true;
    k.on_real_data = "warp";
    k.make = [](const RefinerInputs& in) { return make_reference_refiner(*in.truth, in.reference, in.stats); };
    k.identity = [](const RefinerInputs& in) { return identity_json(in.reference); };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
