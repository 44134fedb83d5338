// fillgs render: every camera of a camera file.
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
/// What `fillgs render` writes per pixel.
enum class Channel { Rgb, Depth, Alpha };
enum class ImageFormat { Png, Exr };
}  // namespace fillgs::cli

namespace fillgs {
FILLGS_ENUM_NAMES(cli::Channel, "channel", {cli::Channel::Rgb, "rgb"}, {cli::Channel::Depth, "depth"}, {cli::Channel::Alpha, "alpha"});
FILLGS_ENUM_NAMES(cli::ImageFormat, "image format", {cli::ImageFormat::Png, "png"}, {cli::ImageFormat::Exr, "exr"});
}  // namespace fillgs

namespace fillgs::cli {

namespace {

// ------------------------------------------------------------------ render

struct RenderFlags {
  std::string scene, cameras, out;
  double time = 0.0;
  Channel channel = Channel::Rgb;
  ImageFormat format = ImageFormat::Png;
  Vec3f background = Vec3f::Zero();
  SceneReadOptions read;
  CameraReadOptions camera_read;
};

int render_views(const RenderFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  const bool fixed_time = in.given("--time");
  RenderOptions ro;
  ro.rgb = f.channel == Channel::Rgb;
  ro.depth = f.channel == Channel::Depth;
  ro.background = f.background;
  const std::string ext = to_string(f.format);
  const GaussianCloud cloud = read_scene_shown(f.scene, f.read, in);
  const std::vector<Camera> cams = read_cameras(f.cameras, f.camera_read);
  const double load_s = seconds_since(t0);

  OutputFolder folder(f.out);  // nothing replaces the folder's files unless every view renders
  FrameSampler ev(cloud);
  TerminalProgress progress(in.err, in.progress());
  progress.start("rendering", cams.size());
  double render_s = 0;
  size_t rendered = 0;
  nlohmann::json views = nlohmann::json::array();
  for (const Camera& cam : cams) {
    const double t = fixed_time ? f.time : (cam.has_time() ? cam.time : 0.0);
    const auto tr = Clock::now();
    const RenderOutput r = render(ev.at(t), cam, ro);
    render_s += seconds_since(tr);
    rendered += r.rendered;
    Image img(cam.width, cam.height, f.channel == Channel::Rgb ? 3 : 1);
    double depth_scale = 1.0;
    if (f.channel == Channel::Rgb) img.pixels = r.rgb;
    else if (f.channel == Channel::Alpha) img.pixels = r.alpha;
    else {
      float max_depth = 0.0f;
      for (size_t p = 0; p < r.alpha.size(); ++p) {
        img.pixels[p] = r.alpha[p] > 1e-6f ? r.depth[p] / r.alpha[p] : 0.0f;
        max_depth = std::max(max_depth, img.pixels[p]);
      }
      // 8-bit output holds [0, 1]: depth is divided by its maximum (recorded in summary.json).
      if (f.format == ImageFormat::Png && max_depth > 0) {
        depth_scale = max_depth;
        for (float& v : img.pixels) v /= max_depth;
      }
    }
    write_image(join_path(folder.path(), cam.name + "." + ext), img);
    views.push_back({{"camera", cam.name}, {"time", t}, {"gaussians_rendered", r.rendered}, {"depth_scale", depth_scale}});
    progress.advance();
  }
  progress.finish();
  nlohmann::json s;
  s["command"] = "render";
  s["scene"] = scene_summary(cloud);
  s["cameras"] = cams.size();
  s["channel"] = to_string(f.channel);
  s["seconds"] = {{"load", load_s}, {"render", render_s}, {"total", seconds_since(t0)}};
  s["ms_per_view"] = cams.empty() ? 0.0 : 1000.0 * render_s / cams.size();
  s["kernel"] = {{"name", kernel_name(Kernel::Default)}, {"instruction_set", simd_target()}};
  s["views"] = views;
  write_file_atomically(join_path(folder.path(), "summary.json"), s.dump(2) + "\n");
  folder.commit();
  in.out << "rendered " << cams.size() << " views (" << to_string(f.channel) << ") into " << f.out << ": "
         << (cams.empty() ? 0.0 : 1000.0 * render_s / cams.size()) << " ms per view, " << rendered / std::max<size_t>(1, cams.size())
         << " Gaussians per view\n";
  return 0;
}

}  // namespace

Action declare_render(CLI::App& app) {
  auto f = std::make_shared<RenderFlags>();
  add_text(app, "--scene", f->scene, "the model", "PATH")->required();
  add_text(app, "--cameras", f->cameras, "the cameras to render", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for <camera>.<format> and summary.json", "DIR")->required();
  add_number(app, "--time", f->time, "render every camera at this time (default: each camera's own time, else 0)", within(0, 1))->default_str("");
  add_choice(app, "--channel", f->channel, "what each pixel holds (depth: divided by its maximum in PNG)");
  add_choice(app, "--format", f->format, "the image format");
  add_colour(app, "--background", f->background, "the background colour");
  add_scene_flags(app, f->read);
  add_camera_flags(app, f->camera_read);
  return bind(f, render_views);
}

}  // namespace fillgs::cli
