#include "fillgs/method/strategies.hpp"
#include "fillgs/experiment/identity.hpp"

#include <set>

#include "fillgs/base/names.hpp"

namespace fillgs {

using json = nlohmann::json;

namespace {

const char* name_of(CandidateScore s) {
  switch (s) {
    case CandidateScore::Deficiency: return "deficiency";
    case CandidateScore::CountOnly: return "count-only";
    case CandidateScore::SpeedOnly: return "speed-only";
  }
  return "?";
}

json vec3(const Vec3f& v) { return json::array({v.x(), v.y(), v.z()}); }

// A new field nearly always changes its struct's size (one that fits into padding does
// not): the build then stops here until the field's serialiser below has been looked at
// and these sizes updated (x86-64, the platform fillgs builds on).
#if defined(__x86_64__)
static_assert(sizeof(TrainOptions) == 368, "TrainOptions changed: add the new field to identity_json(TrainOptions), then update this size");
static_assert(sizeof(SelectOptions) == 192, "SelectOptions changed: add the new field to identity_json(SelectOptions), then update this size");
static_assert(sizeof(VisibilityOptions) == 20, "VisibilityOptions changed: add the new field to identity_json(SelectOptions), then update this size");
static_assert(sizeof(MaskOptions) == 104, "MaskOptions changed: add the new field to identity_json(MaskOptions), then update this size");
static_assert(sizeof(ExplorationOptions) == 32, "ExplorationOptions changed: add the new field to identity_json(ExplorationOptions), then update this size");
static_assert(sizeof(ArtifactOptions) == 24, "ArtifactOptions changed: add the new field to identity_json(ArtifactOptions), then update this size");
static_assert(sizeof(ReferenceOptions) == 112, "ReferenceOptions changed: add the new field to identity_json(ReferenceOptions), then update this size");
static_assert(sizeof(FinetuneOptions) == 792, "FinetuneOptions changed: add the new field to identity_json(FinetuneOptions), then update this size");
#endif

void differences(const json& was, const json& now, const std::string& path, std::string& first) {
  if (!first.empty() || was == now) return;
  if (was.is_object() && now.is_object()) {
    std::set<std::string> keys;
    for (auto it = was.begin(); it != was.end(); ++it) keys.insert(it.key());
    for (auto it = now.begin(); it != now.end(); ++it) keys.insert(it.key());
    for (const std::string& k : keys) {
      const std::string p = path.empty() ? k : path + "." + k;
      if (!was.contains(k) || !now.contains(k)) {
        first = p + ": was " + (was.contains(k) ? was[k].dump() : "absent") + ", now " + (now.contains(k) ? now[k].dump() : "absent");
        return;
      }
      differences(was[k], now[k], p, first);
      if (!first.empty()) return;
    }
    return;
  }
  first = (path.empty() ? std::string("the whole identity") : path) + ": was " + was.dump() + ", now " + now.dump();
}

}  // namespace

json identity_json(const TrainOptions& o) {
  json j = {{"iterations", o.iterations},
          {"seed", o.seed},
          {"background", vec3(o.background)},
          {"lambda_dssim", o.lambda_dssim},
          {"max_sh_degree", o.max_sh_degree},
          {"sh_increase_interval", o.sh_increase_interval},
          {"position_lr_init", o.position_lr_init},
          {"position_lr_final", o.position_lr_final},
          {"scaling_lr", o.scaling_lr},
          {"rotation_lr", o.rotation_lr},
          {"opacity_lr", o.opacity_lr},
          {"feature_lr", o.feature_lr},
          {"densify_from", o.densify_from},
          {"densify_until", o.densify_until},
          {"densify_interval", o.densify_interval},
          {"opacity_reset_interval", o.opacity_reset_interval},
          {"densify_grad_threshold", o.densify_grad_threshold},
          {"percent_dense", o.percent_dense},
          {"min_opacity", o.min_opacity},
          {"max_screen_size", o.max_screen_size},
          {"max_gaussians", o.max_gaussians},
          {"allow_dynamic", o.allow_dynamic},
          {"motion", to_string(o.motion)},
          {"key_interval_frames", o.key_interval_frames},
          {"keyed_opacity", o.keyed_opacity},
          {"time_ramp", o.time_ramp},
          {"frontier_share", o.frontier_share},
          {"densify_after_ramp", o.densify_after_ramp},
          {"frontier_frames", o.frontier_frames},
          {"key_lr_scale", o.key_lr_scale},
          {"extrapolate_min_step", o.extrapolate_min_step},
          {"freeze_distance", o.freeze_distance},
          {"motion_where_images_change", o.motion_where_images_change},
          {"change_threshold", o.change_threshold},
          {"change_dilation", o.change_dilation},
          {"change_from_masks", o.change_from_masks},
          {"flow_keys", o.flow_keys},
          {"flow_changing_only", o.flow_changing_only},
          {"flow_tolerance", o.flow_tolerance},
          {"motion_sparsity", o.motion_sparsity},
          {"still_distance", o.still_distance},
          {"still", {{"position", o.still.position}, {"rotation_degrees", o.still.rotation_degrees}, {"opacity_logit", o.still.opacity_logit}}},
          {"time_bins", o.time_bins},
          {"promote_agreement", o.promote_agreement},
          {"promote_grad_scale", o.promote_grad_scale},
          {"promote_min_samples", o.promote_min_samples},
          // checkpoint_interval: when checkpoints are written, not what is learned.
          {"colour_correction", o.colour_correction},
          {"colour_lr", o.colour_lr},
          {"refined_share", o.refined_share},
          {"sparse_adam", o.sparse_adam}};
  // Only where given, so that the identities of runs without them stay as they were.
  if (!o.initial_colour.empty()) {
    json c = json::object();
    for (const ColourCorrection& x : o.initial_colour) c[x.rig] = {{"gain", vec3(x.gain)}, {"offset", vec3(x.offset)}};
    j["initial_colour"] = c;
  }
  return j;
}

json identity_json(const SelectOptions& o) {
  json j = {{"strategy", o.strategy},
          {"trajectories", o.trajectories},
          {"views", o.views},
          {"patch_frames", o.patch_frames},
          {"seed", o.seed},
          {"time_stride", o.time_stride},
          {"render_scale", o.render_scale},
          {"global_candidates", o.global_candidates},
          {"rotation_step_degrees", o.rotation_step_degrees},
          {"renderer", to_string(o.renderer)},
          {"stride", o.stride},
          {"deficiency_quantile", o.deficiency_quantile},
          {"visibility",
           {{"mode", to_string(o.visibility.mode)},
            {"stride", o.visibility.stride},
            {"min_weight", o.visibility.min_weight},
            {"min_transmittance", o.visibility.min_transmittance},
            {"dilate", o.visibility.dilate}}},
          {"no_start_selection", o.no_start_selection},
          {"no_error_term", o.no_error_term},
          {"no_sensitivity_term", o.no_sensitivity_term},
          {"no_candidate_scoring", o.no_candidate_scoring},
          {"no_global", o.no_global},
          {"score", name_of(o.score)},
          {"spread_starts", o.spread_starts},
          {"score_gain", o.score_gain},
          {"fisher_lambda", o.fisher_lambda}};
  // The strategy's own parameters, where its row declares any (a strategy without them keeps
  // the identity runs recorded before rows could declare them).
  if (const StrategyRow* row = strategy_table().lookup(o.strategy); row && !row->parameters.empty())
    j["parameters"] = o.parameters.identity(row->parameters);
  return j;
}

json identity_json(const MaskOptions& o) {
  return {{"method", to_string(o.method)},         {"sigma", o.sigma},
          {"window", o.window},                    {"search", o.search},
          {"depth_tolerance", o.depth_tolerance},  {"min_alpha", o.min_alpha},
          {"sweep_planes", o.sweep_planes},        {"sweep_near", o.sweep_near},
          {"external_dir", o.external_dir},        {"covisibility", to_string(o.covisibility)},
          {"scale", to_string(o.scale)},           {"normalise", o.normalise}};
}

json identity_json(const ExplorationOptions& o) {
  return {{"divisions", o.divisions}, {"occupancy_alpha", o.occupancy_alpha}, {"bounds_quantile", o.bounds_quantile}, {"margin", o.margin},
          {"label_unexplored", o.label_unexplored}};
}


json identity_json(const FinetuneOptions& o) {
  json j = {{"iterations", o.iterations},
            {"select_every", o.select_every},
            {"trajectories", o.trajectories},
            {"select", identity_json(o.select)},
            {"weighting", to_string(o.weighting)},
            {"mask", identity_json(o.mask)},
            {"grid", identity_json(o.grid)},
            {"train", identity_json(o.train)}};
  // Only with a pool (so that the identities of runs without one stay what they were).
  if (o.pool) {
    json names = json::array();
    for (const Camera& c : o.pool->cameras) names.push_back(c.name);
    j["pool"] = {{"budget", o.pool_budget}, {"views", names}};
  }
  return j;
}

std::string identity_difference(const json& was, const json& now) {
  std::string first;
  differences(was, now, "", first);
  return first;
}

}  // namespace fillgs
