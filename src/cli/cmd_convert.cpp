// fillgs convert and fillgs cameras: a model or cameras in another format.
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
/// What `fillgs convert` and `fillgs cameras` write to.
enum class SceneTarget { Gaussian3D, Fillgs, Frames };
enum class CameraTarget { Transforms, Colmap };
}  // namespace fillgs::cli

namespace fillgs {
FILLGS_ENUM_NAMES(cli::SceneTarget, "scene format",
    {cli::SceneTarget::Gaussian3D, "3dgs"}, {cli::SceneTarget::Fillgs, "fillgs"}, {cli::SceneTarget::Frames, "frames"});
FILLGS_ENUM_NAMES(cli::CameraTarget, "camera format", {cli::CameraTarget::Transforms, "transforms"}, {cli::CameraTarget::Colmap, "colmap"});
}  // namespace fillgs

namespace fillgs::cli {

namespace {

// ------------------------------------------------------------------ convert / cameras

struct ConvertFlags {
  std::string scene, out;
  SceneTarget to = SceneTarget::Gaussian3D;
  double time = 0.0;
  int frames = 0;
  SceneReadOptions read;
};

int convert(const ConvertFlags& f, const Invocation& in) {
  const GaussianCloud c = read_scene_shown(f.scene, f.read, in);
  if (f.to == SceneTarget::Frames) {
    // One standard 3DGS PLY per frame, t = f/(F−1): a sequence splat viewers can play.
    const int frames = in.given("--frames") ? f.frames : motion_frames(c);
    if (frames < 1) in.fail("--to frames needs --frames F (F >= 1)");
    OutputFolder folder(f.out);
    const std::vector<double> times = FrameGrid(frames).times();
    for (int k = 0; k < frames; ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04d.ply", k);
      write_3dgs_ply(join_path(folder.path(), name), c, times[size_t(k)]);
    }
    folder.commit();
    in.out << "wrote " << frames << " frames to " << f.out << " (3dgs, frame_0000.ply … at t = f/" << std::max(1, frames - 1) << ", " << c.size()
           << " Gaussians each)\n";
    return 0;
  }
  if (f.to == SceneTarget::Gaussian3D) write_3dgs_ply(f.out, c, f.time);
  else write_fillgs_ply(f.out, c, f.frames);
  in.out << "wrote " << f.out << " (" << to_string(f.to) << ", " << c.size() << " Gaussians)\n";
  return 0;
}

}  // namespace

Action declare_convert(CLI::App& app) {
  auto f = std::make_shared<ConvertFlags>();
  add_text(app, "--scene", f->scene, "the model", "PATH")->required();
  add_text(app, "--out", f->out, "the PLY file (a folder for --to frames)", "PATH")->required();
  add_choice(app, "--to", f->to, "3dgs: the model at --time; fillgs: the 4D model; frames: one 3DGS PLY per frame");
  add_number(app, "--time", f->time, "3dgs: the time the static model shows", within(0, 1));
  add_number(app, "--frames", f->frames, "frames: how many (default: the model's keys); fillgs: the frame count recorded", at_least(0));
  add_scene_flags(app, f->read);
  return bind(f, convert);
}

struct CamerasFlags {
  std::string cameras, out;
  CameraTarget to = CameraTarget::Transforms;
  CameraReadOptions read;
};

int convert_cameras(const CamerasFlags& f, const Invocation& in) {
  const std::vector<Camera> cams = read_cameras(f.cameras, f.read);
  if (f.to == CameraTarget::Transforms) {
    write_transforms_json(f.out, cams);
  } else {
    // Three files, committed together through a staging folder.
    check_colmap_text_target(f.out);
    OutputFolder folder(f.out);
    write_colmap_text(folder.path(), cams);
    folder.commit();
  }
  in.out << "wrote " << cams.size() << " cameras to " << f.out << " (" << to_string(f.to) << ")\n";
  return 0;
}

Action declare_cameras(CLI::App& app) {
  auto f = std::make_shared<CamerasFlags>();
  add_text(app, "--cameras", f->cameras, "the cameras", "PATH")->required();
  add_text(app, "--out", f->out, "transforms.json, or the COLMAP text folder", "PATH")->required();
  add_choice(app, "--to", f->to, "the format written");
  add_camera_flags(app, f->read);
  return bind(f, convert_cameras);
}

}  // namespace fillgs::cli
