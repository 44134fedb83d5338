#include "fillgs/method/refiners.hpp"

#include "fillgs/base/error.hpp"
#include "fillgs/base/names.hpp"

namespace fillgs {

namespace refiner_rows {
std::vector<const RefinerKind*> rows();  // generated from src/method/refiners/ (src/row_table.cpp.in)
}  // namespace refiner_rows

const RowTable<RefinerKind>& refiner_table() {
  static const RowTable<RefinerKind> table("refiner", refiner_rows::rows());
  return table;
}

const std::vector<const RefinerKind*>& refiner_kinds() { return refiner_table().rows(); }

std::string refiner_names(bool benchmark_only) {
  if (!benchmark_only) return refiner_table().names();
  std::vector<std::string> names;
  for (const RefinerKind* k : refiner_kinds())
    if (k->benchmark) names.push_back(k->name);
  return join_names(names);
}

const RefinerKind& refiner_kind(const std::string& name) { return refiner_table().find(name); }

nlohmann::json identity_json(const ArtifactOptions& o) {
  return {{"strength", o.strength}, {"seed", o.seed}, {"region_fraction", o.region_fraction}};
}

nlohmann::json identity_json(const ReferenceOptions& o) {
  return {{"name", "reference"},
          {"angle_scale_degrees", o.angle_scale_degrees},
          {"shift_per_degree", o.shift_per_degree},
          {"blur_per_degree", o.blur_per_degree},
          {"flicker", o.flicker},
          {"artifacts", identity_json(o.artifacts)},
          {"fill_strength", o.fill_strength},
          {"hallucination", o.hallucination},
          {"fill_blur", o.fill_blur},
          {"background", nlohmann::json::array({o.background.x(), o.background.y(), o.background.z()})},
          {"depth_tolerance", o.depth_tolerance},
          {"placement_tolerance", o.placement_tolerance}};
}

void complete_refiner_inputs(RefinerInputs& in, const Dataset& data, uint64_t seed) {
  in.observers.clear();
  for (const TrainView& v : data.views()) in.observers.push_back(v.camera);
  in.frames = data.frames();
  in.oracle.artifacts.seed = seed;
  in.reference.artifacts.strength = in.oracle.artifacts.strength;
  in.reference.artifacts.seed = seed;
}

std::unique_ptr<Refiner> make_refiner(const std::string& name, const RefinerInputs& in) {
  const RefinerKind& k = refiner_kind(name);
  if (k.needs_truth && !in.truth) throw_error("the ", k.name, " refiner needs the ground-truth scene (synthetic data)");
  if (k.needs_pool && (!in.pool || in.pool->cameras.empty())) throw_error("the ", k.name, " refiner needs pool cameras (rig cameras neither trained on nor held out)");
  in.parameters.require(k.parameters);
  return k.make(in);
}

}  // namespace fillgs
