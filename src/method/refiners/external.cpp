// `external`: any program, through the folder protocol of method/refine.hpp ({in}: the
// patch, {out}: the refined images), run without a shell and killed after its timeout.
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

namespace {
const RowParameter& external_command() {
  static const RowParameter p = RowParameter::text("refiner_command", "external: the command, with {in} and {out}", true);
  return p;
}
const RowParameter& external_timeout() {
  static const RowParameter p = RowParameter::number("refiner_timeout", 600, positive(), "external: seconds per patch");
  return p;
}
}  // namespace

const RefinerKind& row_external() {
  static const RefinerKind row = [] {
    RefinerKind k;
    k.name = "external";
    k.description = "a program through the folder protocol ({in} -> {out})";
    k.order = 60;
    k.parameters = {&external_command(), &external_timeout()};
    // make_refiner has checked that the command was given.
    k.make = [](const RefinerInputs& in) { return make_external_refiner(in.parameters.text(external_command()), in.parameters.number(external_timeout())); };
    k.identity = [](const RefinerInputs& in) {
      nlohmann::json j = in.parameters.identity({&external_command(), &external_timeout()});
      j["name"] = "external";
      return j;
    };
    return k;
  }();
  return row;
}

}  // namespace fillgs::refiner_rows
