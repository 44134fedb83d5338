// `oracle`: the ground truth wherever a training camera saw the surface (a static Gaussian
// at any frame, a moving one within +-window frames), the model's render degraded as
// diffusion models fail elsewhere: a bound on what a refiner conditioned on the capture can
// restore, not a generator (synthetic scenes).
#include "fillgs/method/refiners.hpp"

namespace fillgs::refiner_rows {

/// An oracle row: the ground truth at the virtual view with `support`; its identity, as the
/// benchmark's runs store it, names "oracle" with the artifacts, the support and the window.
RefinerKind oracle_kind(std::string name, std::string description, int order, OracleSupport support) {
  auto options = [support](const RefinerInputs& in) {
    OracleOptions o = in.oracle;
    o.support = support;
    o.observers = in.observers;
    o.frames = in.frames;
    return o;
  };
  RefinerKind k;
  k.name = std::move(name);
  k.description = std::move(description);
  k.order = order;
  k.needs_truth = true;
  k.benchmark = true;
  k.make = [options](const RefinerInputs& in) { return make_oracle_refiner(*in.truth, options(in), in.stats); };
  k.identity = [options](const RefinerInputs& in) {
    const OracleOptions o = options(in);
    return nlohmann::json{{"name", "oracle"}, {"artifacts", identity_json(o.artifacts)}, {"support", to_string(o.support)}, {"window", o.window}};
  };
  return k;
}

const RefinerKind& row_oracle() {
  static const RefinerKind row = oracle_kind(
      "oracle", "the ground truth wherever a training camera saw it, the render degraded elsewhere (a bound, not a generator)", 20, OracleSupport::Observed);
  return row;
}

}  // namespace fillgs::refiner_rows
