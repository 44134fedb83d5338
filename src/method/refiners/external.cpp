// `external`: any program, through the folder protocol of method/refine.hpp ({in}: the
// patch, {out}: the refined images), run without a shell and killed after its timeout.
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

const RefinerKind& row_external() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "external";
    k.description = "a program through the folder protocol ({in} -> {out})";
    k.order = 60;
    k.needs_command = true;
    k.make = [](const RefinerInputs& in) { return make_external_refiner(in.command, in.timeout_seconds); };
    k.identity = [](const RefinerInputs& in) {
      return nlohmann::json{{"name", "external"}, {"command", in.command}, {"timeout_seconds", in.timeout_seconds}};
    };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
