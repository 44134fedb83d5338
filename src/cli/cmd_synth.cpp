// fillgs synth: the synthetic analysis scene.
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

namespace {

// ------------------------------------------------------------------ synth

struct SynthFlags {
  std::string out;
  SynthOptions synth;
};

int synth(const SynthFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  const SynthScene s = make_synthetic_scene(f.synth);
  TerminalProgress progress(in.err, in.progress());
  OutputFolder folder(f.out);  // a failed or killed run leaves the folder as it was
  write_synthetic_scene(s, folder.path(), progress);
  folder.commit();
  in.out << "synthetic scene: " << s.scene.size() << " Gaussians (" << s.scene.dynamic_count() << " moving), " << s.train.size()
         << " rig cameras (" << s.options.rig << ", split: train " << s.split.train.size() << ", interpolation " << s.split.interpolation.size()
         << ", extrapolation " << s.split.extrapolation.size() << "), " << s.options.frames << " frames, " << s.options.width << "x"
         << s.options.height << ", written to " << f.out << " in " << seconds_since(t0) << " s\n";
  return 0;
}

}  // namespace

Action declare_synth(CLI::App& app) {
  auto f = std::make_shared<SynthFlags>();
  SynthOptions& o = f->synth;
  add_text(app, "--out", f->out, "the folder for the scene, its cameras and ground-truth images", "DIR")->required();
  add_number(app, "--frames", o.frames, "frames of the video", at_least(1));
  add_number(app, "--width", o.width, "image width", at_least(1));
  add_number(app, "--height", o.height, "image height", at_least(1));
  add_number(app, "--seed", o.seed, "random seed");
  add_number(app, "--spacing", o.spacing, "surface sample spacing (metres)", positive());
  add_text(app, "--rig", o.rig, "the camera rig: " + join_names(synthetic_rigs()), "NAME");
  std::string variants;
  for (const std::string& rig : synthetic_rigs())
    variants += (variants.empty() ? "" : "; ") + join_names(synthetic_variants(rig)) + " (" + rig + ")";
  add_text(app, "--variant", o.variant, "the moving content: " + variants + "; default: the rig's first", "NAME");
  return bind(f, synth);
}

}  // namespace fillgs::cli
