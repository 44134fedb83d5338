#pragma once
// A run's identity: every option that decides its result, as JSON. `fillgs bench` and
// `fillgs run` reuse a finished run only when the identity stored beside it equals the one
// they would run now, and otherwise refuse with one line that names the first option that
// differs (identity_difference). Defaults are written out, so a run made by a fillgs whose
// defaults have changed is not taken for one made with today's.
//
// Every serialiser below is guarded by the size of its struct: adding a field fails the
// build until the field is either written here or said not to change results.
#include <string>

#include <nlohmann/json.hpp>

#include "fillgs/method/refiners.hpp"  // the refiners' options' identities, beside them

#include "fillgs/method/finetune.hpp"
#include "fillgs/method/refine.hpp"

namespace fillgs {

nlohmann::json identity_json(const TrainOptions& o);
nlohmann::json identity_json(const SelectOptions& o);
nlohmann::json identity_json(const MaskOptions& o);
nlohmann::json identity_json(const ExplorationOptions& o);
/// All but `work_dir` (where, not what) and `extra_views` (images: the caller names what
/// they are).
nlohmann::json identity_json(const FinetuneOptions& o);

/// "" when equal; else the first differing key as a path with both values, e.g.
/// "finetune.weighting: was \"explore-gs\", now \"fillgs\"" (a key only one side has: "absent").
std::string identity_difference(const nlohmann::json& was, const nlohmann::json& now);

}  // namespace fillgs
