// `reference`: conditioned on the patch's start view alone, confidence falling with the
// parallax angle to it; its content is the ground truth the start camera saw (synthetic
// scenes). The benchmark's calibrated refiner (method/refine.hpp, ReferenceOptions). What it
// restores is what a training view already saw: it cannot reward a selection.
#include "fillgs/experiment/identity.hpp"
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_reference() {
  static const RefinerKind row{
      "reference", "conditioned on the start view alone, confidence falling with the parallax angle to it (synthetic scenes; calibrated)", 10,
      true, false, false, true, [](const RefinerInputs& in) { return make_reference_refiner(*in.truth, in.reference, in.stats); },
      [](const RefinerInputs& in) { return identity_json(in.reference); }};
  return row;
}

}  // namespace fillgs::refiner_rows
