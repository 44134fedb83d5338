// fillgs info: what a model holds.
#include "fillgs/io/model_formats.hpp"
#include "fillgs/cli.hpp"
#include "fillgs/io/camera_io.hpp"
#include <nlohmann/json.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include "fillgs/base/error.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/train/init.hpp"
#include "fillgs/visibility/observe_io.hpp"
#include "fillgs/visibility/observe_mpi.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/train/train_job.hpp"
#include "fillgs/visibility/visibility.hpp"
#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"

namespace fillgs::cli {

nlohmann::json scene_summary(const GaussianCloud& c) {
  nlohmann::json j;
  j["gaussians"] = c.size();
  j["sh_degree"] = c.sh_degree;
  j["motion_model"] = to_string(c.motion);
  j["static"] = c.static_count();
  j["dynamic"] = c.dynamic_count();
  const auto [lo, hi] = bounding_box(c);
  if (c.size()) {
    j["bbox_min"] = {lo.x(), lo.y(), lo.z()};
    j["bbox_max"] = {hi.x(), hi.y(), hi.z()};
  }
  if (c.motion == MotionModel::Keyframed) j["keyframes"] = c.keyframed.key_count;
  if (c.motion == MotionModel::Evaluated) j["frames"] = motion_frames(c);
  j["notes"] = c.notes;
  return j;
}

namespace {

// ------------------------------------------------------------------ info

struct InfoFlags {
  std::string scene;
  bool json = false;
  SceneReadOptions read;
};

int info(const InfoFlags& f, const Invocation& in) {
  const GaussianCloud c = read_scene_shown(f.scene, f.read, in);
  nlohmann::json j = scene_summary(c);
  j["format"] = f.read.format == "auto" ? detect_scene_format(f.scene) : model_format(f.read.format).name;
  j["moving_share"] = c.size() ? double(c.dynamic_count()) / double(c.size()) : 0.0;
  if (c.motion == MotionModel::Keyframed) {
    const KeyframedMotion& k = c.keyframed;
    j["key_times"] = {k.first_key_time, k.first_key_time + k.key_spacing * (k.key_count - 1)};
  }
  if (!c.model_times.empty()) j["model_times"] = c.model_times;
  if (c.motion == MotionModel::Evaluated) {  // what finetune would key it with
    const KeyChoice k = choose_keys(c);
    std::ostringstream os;
    os << k.keys << " (one every " << k.interval << " frames; every keyed property within " << k.worst_share << " of its tolerance of the model on "
       << k.sample << " moving Gaussians" << (k.limiting.empty() ? std::string() : ", " + k.limiting + " decided the interval") << ")";
    j["training_keys"] = os.str();
  }
  if (f.json) {
    in.out << j.dump(2) << "\n";
    return 0;
  }
  in.out << "scene        " << f.scene << "\n";
  for (const char* key : {"format", "gaussians", "sh_degree", "motion_model", "static", "dynamic", "moving_share", "keyframes", "frames", "training_keys", "key_times",
                          "model_times", "bbox_min", "bbox_max"})
    if (j.contains(key)) {
      std::string label = key;
      std::replace(label.begin(), label.end(), '_', ' ');
      std::string value;
      if (j[key].is_string()) value = j[key].get<std::string>();
      else if (j[key].is_array())
        for (const auto& x : j[key]) value += (value.empty() ? "" : " ") + x.dump();
      else value = j[key].dump();
      in.out << label << std::string(label.size() < 13 ? 13 - label.size() : 1, ' ') << value << "\n";
    }
  for (const std::string& n : c.notes) in.out << "note         " << n << "\n";
  return 0;
}

}  // namespace

Action declare_info(CLI::App& app) {
  auto f = std::make_shared<InfoFlags>();
  app.add_option("scene", f->scene, "the model: a PLY (3DGS, Spacetime Gaussians, Ex4DGS, fillgs) or a trained model (E-D3DGS or 4DGaussians run, 4DGS chkpnt*.pth, params.npz, a folder of per-frame PLYs)")
      ->type_name("SCENE")
      ->required();
  add_flag(app, "--json", f->json, "the summary as JSON");
  add_scene_flags(app, f->read);
  return bind(f, info);
}

}  // namespace fillgs::cli
