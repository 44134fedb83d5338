// fillgs info, render, synth, convert, cameras, observe and train; the command table, help
// and the error line.
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
#ifdef FILLGS_WITH_MPI
#include "fillgs/visibility/observe_mpi.hpp"
#endif
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

/// What `fillgs render` writes per pixel, `convert` and `cameras` write to.
enum class Channel { Rgb, Depth, Alpha };
enum class ImageFormat { Png, Exr };
enum class SceneTarget { Gaussian3D, Fillgs, Frames };
enum class CameraTarget { Transforms, Colmap };
/// observe's per-frame tables: every Gaussian, or the moving ones only.
enum class MotionTables { Dense, Dynamic };

}  // namespace fillgs::cli

namespace fillgs {
FILLGS_ENUM_NAMES(cli::Channel, "channel", {cli::Channel::Rgb, "rgb"}, {cli::Channel::Depth, "depth"}, {cli::Channel::Alpha, "alpha"});
FILLGS_ENUM_NAMES(cli::ImageFormat, "image format", {cli::ImageFormat::Png, "png"}, {cli::ImageFormat::Exr, "exr"});
FILLGS_ENUM_NAMES(cli::SceneTarget, "scene format",
    {cli::SceneTarget::Gaussian3D, "3dgs"}, {cli::SceneTarget::Fillgs, "fillgs"}, {cli::SceneTarget::Frames, "frames"});
FILLGS_ENUM_NAMES(cli::CameraTarget, "camera format", {cli::CameraTarget::Transforms, "transforms"}, {cli::CameraTarget::Colmap, "colmap"});
FILLGS_ENUM_NAMES(cli::MotionTables, "motion table layout", {cli::MotionTables::Dense, "dense"}, {cli::MotionTables::Dynamic, "dynamic"});
}  // namespace fillgs

namespace fillgs::cli {

namespace {

// ------------------------------------------------------------------ info

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

struct InfoFlags {
  std::string scene;
  bool json = false;
  SceneReadOptions read;
};

int info(const InfoFlags& f, const Invocation& in) {
  const GaussianCloud c = read_scene_shown(f.scene, f.read, in);
  nlohmann::json j = scene_summary(c);
  j["format"] = to_string(f.read.format == SceneFormat::Auto ? detect_scene_format(f.scene) : f.read.format);
  j["moving_share"] = c.size() ? double(c.dynamic_count()) / double(c.size()) : 0.0;
  if (c.motion == MotionModel::Keyframed) {
    const KeyframedMotion& k = c.keyframed;
    j["key_times"] = {k.first_key_time, k.first_key_time + k.key_spacing * (k.key_count - 1)};
  }
  if (!c.model_times.empty()) j["model_times"] = c.model_times;
  if (c.motion == MotionModel::Evaluated) {  // what finetune would key it with
    const KeyChoice k = choose_keys(c);
    std::ostringstream os;
    os << k.keys << " (one every " << k.interval << " frames; positions within " << k.worst_error << " world units of the model on " << k.sample
       << " moving Gaussians)";
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

Action declare_info(CLI::App& app) {
  auto f = std::make_shared<InfoFlags>();
  app.add_option("scene", f->scene, "the model: a PLY (3DGS, Spacetime Gaussians, Ex4DGS, fillgs) or a trained model (E-D3DGS or 4DGaussians run, 4DGS chkpnt*.pth, params.npz, a folder of per-frame PLYs)")
      ->type_name("SCENE")
      ->required();
  add_flag(app, "--json", f->json, "the summary as JSON");
  add_scene_flags(app, f->read);
  return bind(f, info);
}

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

// ------------------------------------------------------------------ observe

struct ObserveFlags {
  std::string scene, cameras, out, shard;
  std::vector<std::string> merge;
  TimeFlags time;
  MotionTables tables = MotionTables::Dense;
  ObservationOptions options;
  ObserveOutputOptions output;
  bool mpi = false;
  double hit_cache_mb = 0;
  SceneReadOptions read;
  CameraReadOptions camera_read;
};

/// What `fillgs observe` computes: the scene, the cameras, the times and how.
struct ObserveJob {
  ObservationOptions options;
  ObserveOutputOptions output;
  GaussianCloud cloud;
  std::vector<Camera> cameras;
  std::vector<double> times;
  double frame_step = 0;
};

ObserveJob observe_job(const ObserveFlags& f, const Invocation& in) {
  ObserveJob job;
  job.options = f.options;
  if (in.given("--hit-cache")) job.options.static_hit_cache_bytes = size_t(f.hit_cache_mb * 1048576.0);
  job.output = f.output;
  job.output.dense_motion_tables = f.tables == MotionTables::Dense;
  job.cloud = read_scene_shown(f.scene, f.read, in);
  job.cameras = read_cameras(f.cameras, f.camera_read);
  if (job.cameras.empty()) throw_error(f.cameras, ": no cameras");
  job.times = observe_times(in, f.time, job.cloud, job.cameras, &job.frame_step);
  {
    // The tables' size on disk, before any work: [T, N] counts (1 byte, 2 above 255 views)
    // and speed and deficiency (4 bytes each, over the moving Gaussians only with
    // --motion-tables dynamic), against the space free where they will be written.
    const size_t T = job.times.size(), N = job.cloud.size(), M = job.cloud.dynamic_count();
    const size_t tables = checked_mul(T, checked_mul(N, 2, "--frames", "the tables") + checked_mul(job.output.dense_motion_tables ? N : M, 8, "--frames", "the tables"),
                                      "--frames", "the tables");
    namespace fs = std::filesystem;
    fs::path where = fs::absolute(f.out);
    std::error_code ec;
    while (!where.empty() && !fs::exists(where, ec)) where = where.parent_path();
    const fs::space_info space = fs::space(where, ec);
    if (!ec && tables > space.available)
      in.fail("the tables of ", N, " Gaussians at ", T, " frames need up to ", tables, " bytes, more than the ", space.available, " free under ",
              where.string());
  }
  if (in.given("--shard")) {
    // --shard i/n: the i-th of n contiguous blocks of frames (1-based), for observe --merge.
    const std::string& spec = f.shard;
    const size_t slash = spec.find('/');
    size_t index = 0, count = 0;
    if (slash != std::string::npos) {
      index = parse_count(spec.substr(0, slash), 1u << 20, "fillgs observe", "--shard index");
      count = parse_count(spec.substr(slash + 1), 1u << 20, "fillgs observe", "--shard count");
    }
    if (slash == std::string::npos || index < 1 || count < 1 || index > count) in.fail("--shard expects i/n with 1 <= i <= n (got '", spec, "')");
    if (count > job.times.size()) in.fail("--shard ", spec, ": more shards than the ", job.times.size(), " frames");
    job.options.frames = shard_frames(job.times.size(), index - 1, count);
  }
  return job;
}

void print_observed(std::ostream& out, const ObserveJob& job, const ObserveReport& r, double seconds, const std::string& out_dir) {
  const ObservationSummary& s = r.summary;
  out << "observed " << s.gaussians << " Gaussians (" << s.dynamic_count << " dynamic) over " << s.frames << " frames and " << s.views
      << " views (" << to_string(job.options.visibility.mode);
  if (job.options.visibility.mode == VisibilityMode::Raytraced) out << ", stride " << job.options.visibility.stride;
  out << ") in " << seconds << " s";
  if (s.counters.rays) out << ", " << s.counters.rays << " rays";
  out << ", peak memory " << (r.peak_memory_bytes >> 20) << " MB -> " << out_dir << "\n";
}

/// `fillgs observe --mpi` under mpirun: every rank reads the inputs; if any rank fails,
/// the lowest failing rank says why (one line) and every rank exits 1; then frames go
/// round the ranks and rank 0 writes the files.
int observe_over_mpi(const ObserveFlags& f, const Invocation& in) {
#ifdef FILLGS_WITH_MPI
  const auto t0 = Clock::now();
  mpi::Session session;
  ObserveJob job;
  std::optional<OutputFolder> folder;
  std::string failure;
  try {
    if (in.given("--shard")) in.fail("--mpi shares the whole job between the ranks; --shard splits it between separate runs");
    job = observe_job(f, in);
    if (session.rank() == 0) folder.emplace(f.out);
  } catch (const std::exception& e) {
    failure = e.what();
  }
  const int failed = session.first_failure(failure.empty());
  if (failed >= 0) {
    if (session.rank() != failed) return 1;
    throw_error(failed == 0 ? failure : "rank " + std::to_string(failed) + ": " + failure);
  }
  try {
    const FrameSource source = mpi::observe_source(job.cloud, job.cameras, job.times, job.frame_step, job.options);
    if (session.rank() != 0) {
      source([](const FrameObservation&) {}, null_progress());
      return 0;
    }
    TerminalProgress progress(in.err, in.progress());
    const ObserveReport r =
        write_observation(job.cloud, job.cameras, job.times, job.frame_step, job.options, source, folder->path(), job.output, progress);
    folder->commit();
    print_observed(in.out, job, r, seconds_since(t0), f.out);
    in.out << "(" << session.size() << " MPI ranks)\n";
    return 0;
  } catch (const std::exception& e) {
    // The ranks are exchanging frames: one that stops would leave the others waiting.
    in.err << "error: " << (session.rank() ? "rank " + std::to_string(session.rank()) + ": " : std::string()) << e.what() << "\n";
    in.err.flush();
    session.abort(1);
  }
#else
  (void)f;
  in.fail("--mpi needs fillgs built with MPI (scripts/install-deps.sh installs libopenmpi-dev; then rebuild)");
#endif
}

int observe(const ObserveFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  if (in.given("--merge")) {
    for (const char* k : {"--scene", "--cameras", "--frames", "--times", "--mode", "--stride", "--tau", "--motion-tables", "--shard", "--hit-cache"})
      if (in.given(k)) in.fail("--merge combines finished shards; ", k, " belongs to the shards' own runs");
    OutputFolder folder(f.out);
    const ObserveReport r = merge_observations(f.merge, folder.path(), f.output.plots);
    folder.commit();
    in.out << "merged " << f.merge.size() << " shards: " << r.summary.gaussians << " Gaussians over " << r.summary.frames << " frames and "
           << r.summary.views << " views -> " << f.out << "\n";
    return 0;
  }
  for (const char* k : {"--scene", "--cameras"})
    if (!in.given(k)) in.fail("missing ", k);
  if (f.mpi) return observe_over_mpi(f, in);
  const ObserveJob job = observe_job(f, in);
  TerminalProgress progress(in.err, in.progress());
  OutputFolder folder(f.out);  // a failed or killed run leaves the folder as it was
  const ObserveReport r = observe_to_directory(job.cloud, job.cameras, job.times, job.frame_step, job.options, folder.path(), job.output, progress);
  folder.commit();
  print_observed(in.out, job, r, seconds_since(t0), f.out);
  return 0;
}

Action declare_observe(CLI::App& app) {
  auto f = std::make_shared<ObserveFlags>();
  VisibilityOptions& v = f->options.visibility;
  add_text(app, "--scene", f->scene, "the model (required unless --merge)", "PATH");
  add_text(app, "--cameras", f->cameras, "the training cameras (required unless --merge)", "PATH");
  add_text(app, "--out", f->out, "the folder for the tables, summary.json and plots", "DIR")->required();
  add_time_flags(app, f->time, true);
  add_choice(app, "--mode", v.mode, "how a camera observes a Gaussian: its centre in the frustum, or traced rays");
  add_number(app, "--stride", v.stride, "raytraced: one ray every s pixels", at_least(1));
  add_number(app, "--tau", v.min_weight, "raytraced: the blending weight at which a hit counts", within_open(0, 1));
  add_switch_off(app, "--no-raster-match", v.dilate, "raytraced: footprints not widened to the rasterizer's");
  add_switch_off(app, "--from-scratch", f->options.incremental, "raytraced: every frame traced anew, not only what moved");
  add_number(app, "--hit-cache", f->hit_cache_mb, "raytraced: MB of static hits kept for re-traced rays (default 2048; 0: none)", from_below(0, 1e9))
      ->type_name("MB");
  add_choice(app, "--motion-tables", f->tables, "the per-frame tables: every Gaussian, or the moving ones only");
  add_switch_off(app, "--no-plots", f->output.plots, "no heatmaps or charts");
  add_text(app, "--shard", f->shard, "the i-th of n blocks of frames, for --merge", "I/N");
  add_list(app, "--merge", f->merge, "finished shards' folders, combined into the single-process tables");
  add_flag(app, "--mpi", f->mpi, "under mpirun: frames shared by the ranks, rank 0 writes");
  add_scene_flags(app, f->read);
  add_camera_flags(app, f->camera_read);
  return bind(f, observe);
}

// ------------------------------------------------------------------ train

struct TrainFlags {
  std::string images, cameras, out, points, resume, init, test_images, test_cameras, camera_times;
  int iterations = 3000;
  int checkpoint_every = 0;
  uint64_t seed = 1;
  bool static_only = false, colour_correction = false;
  TrainOptions train = TrainOptions::scaled(3000);
  ViewInitOptions view_init;
  DatasetOptions data;
};

/// --camera-times FILE: {"chosen": [{"camera": .., "frame": ..}, ..]} (finetune's
/// pool_chosen.json) or the list alone.
std::vector<std::pair<std::string, int>> read_camera_times(const std::string& path) {
  const nlohmann::json j = read_json_file(path);
  const nlohmann::json& list = j.is_object() && j.contains("chosen") ? j.at("chosen") : j;
  if (!list.is_array()) throw_error(path, ": camera-times must be a list of {\"camera\", \"frame\"} (or an object whose \"chosen\" is one)");
  std::vector<std::pair<std::string, int>> out;
  for (size_t i = 0; i < list.size(); ++i) {
    const nlohmann::json& e = list[i];
    if (!e.is_object() || !e.contains("camera") || !e.contains("frame") || !e.at("camera").is_string() || !e.at("frame").is_number_integer())
      throw_error(path, ": camera-time ", i, " needs \"camera\" (a name) and \"frame\" (a whole number)");
    out.emplace_back(e.at("camera").get<std::string>(), e.at("frame").get<int>());
  }
  if (out.empty()) throw_error(path, ": no camera-times");
  return out;
}

int train(const TrainFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  TerminalProgress loading(in.err, in.progress());
  DatasetOptions dopt = f.data;
  if (in.given("--camera-times")) {
    if (dopt.cameras.empty()) in.fail("--camera-times adds single photographs to --train-cameras, and none were named");
    dopt.camera_times = read_camera_times(f.camera_times);
  }
  const Dataset data = Dataset::load(f.images, f.cameras, dopt, loading);
  const int iterations = f.iterations;
  // The schedule scales with the iteration count; the flags given override it.
  TrainOptions o = TrainOptions::scaled(iterations);
  o.seed = f.seed;
  for (const auto& [flag, apply] : std::vector<std::pair<const char*, std::function<void()>>>{
           {"--key-interval", [&] { o.key_interval_frames = f.train.key_interval_frames; }},
           {"--max-gaussians", [&] { o.max_gaussians = f.train.max_gaussians; }},
           {"--sh-degree", [&] { o.max_sh_degree = f.train.max_sh_degree; }},
           {"--motion", [&] { o.motion = f.train.motion; }},
           {"--time-ramp", [&] { o.time_ramp = f.train.time_ramp; }},
           {"--key-lr-scale", [&] { o.key_lr_scale = f.train.key_lr_scale; }},
           {"--motion-sparsity", [&] { o.motion_sparsity = f.train.motion_sparsity; }},
           {"--background", [&] { o.background = f.train.background; }}})
    if (in.given(flag)) apply();
  o.allow_dynamic = !f.static_only;
  o.keyed_opacity = f.train.keyed_opacity;
  o.flow_keys = f.train.flow_keys;
  o.change_from_masks = f.train.change_from_masks;
  if (o.change_from_masks && !data.has_masks()) in.fail("--motion-from-masks needs foreground masks (seg/ beside the meta file)");
  o.checkpoint_interval = in.given("--checkpoint-every") ? f.checkpoint_every : std::max(1, iterations / 5);
  o.colour_correction = f.colour_correction;
  // Test split (optional): loaded before anything is written, so bad input writes nothing.
  std::unique_ptr<Dataset> test;
  if (in.given("--test-cameras")) {
    DatasetOptions to = f.data;
    to.cameras.clear();
    test = std::make_unique<Dataset>(Dataset::load(in.given("--test-images") ? f.test_images : f.images, f.test_cameras, to));
  }

  TrainJob job;
  job.data = &data;
  job.out = f.out;
  job.options = o;
  job.iterations = iterations;
  if (in.given("--resume")) job.resume = f.resume;
  // Initial points: --points, else points.ply beside the cameras, else from the views
  // (init.hpp: random points the first frame's cameras see, plus the foreground's visual
  // hull when the dataset has masks); --init picks explicitly.
  job.points = f.points;
  const std::string beside = join_path(std::filesystem::path(f.cameras).parent_path().string(), "points.ply");
  if (job.points.empty() && std::filesystem::exists(beside)) job.points = beside;
  job.init = in.given("--init") ? parse_name<InitSource>(f.init) : job.points.empty() ? InitSource::RandomAndCarve : InitSource::Points;
  if (job.init == InitSource::Points && job.points.empty()) in.fail("--init points needs --points (no points.ply beside ", f.cameras, ")");
  job.view_init = f.view_init;
  TerminalProgress progress(in.err, in.progress());
  TrainingReport report;
  const TrainJobResult r = run_train_job(job, in.out, progress, [&](const Trainer& trainer, const GaussianCloud& model, double seconds) {
    report = write_training_report(f.out, trainer, model, data, o, test.get(), seconds);
  });
  const GaussianCloud& model = r.model;
  const double train_seconds = r.seconds_train;
  if (o.colour_correction) {
    auto put = [&](const ColourCorrection& c) {
      char line[160];
      std::snprintf(line, sizeof line, " %s %.3f,%.3f,%.3f/%+.3f,%+.3f,%+.3f;", c.rig.c_str(), c.gain[0], c.gain[1], c.gain[2], c.offset[0],
                    c.offset[1], c.offset[2]);
      in.out << line;
    };
    in.out << "colours of the rig's mean camera, in those of " << data.rigs()[0] << " (gain r,g,b / offset r,g,b):";
    put(r.mean);
    in.out << "\ncolour correction per camera, relative to the mean camera:";
    for (const ColourCorrection& c : r.corrections) put(c);
    in.out << "\n";
  }
  in.out << "trained " << model.size() << " Gaussians (" << model.dynamic_count() << " moving) in " << train_seconds << " s; train PSNR "
         << report.train.psnr << " dB";
  if (test) in.out << ", test PSNR " << report.test.psnr << " dB over " << report.test.views << " views";
  in.out << ", peak memory " << (report.peak_memory_bytes >> 20) << " MB -> " << f.out << "\n";
  return 0;
}

Action declare_train(CLI::App& app) {
  auto f = std::make_shared<TrainFlags>();
  TrainOptions& o = f->train;
  add_text(app, "--images", f->images, "the images folder", "DIR")->required();
  add_text(app, "--cameras", f->cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for model.ply, checkpoints and summary.json", "DIR")->required();
  add_text(app, "--points", f->points, "initial points (PLY; default: points.ply beside the cameras)", "PATH");
  add_number(app, "--iterations", f->iterations, "training iterations (the schedule scales with them)", at_least(1));
  add_text(app, "--resume", f->resume, "continue from this checkpoint", "CKPT");
  add_number(app, "--checkpoint-every", f->checkpoint_every, "iterations between checkpoints (default: a fifth of the run)", at_least(1))->default_str("");
  add_number(app, "--seed", f->seed, "random seed");
  add_number(app, "--key-interval", o.key_interval_frames, "frames between motion keys", at_least(1));
  add_number(app, "--max-gaussians", o.max_gaussians, "densification stops at this count", at_least(1));
  add_number(app, "--sh-degree", o.max_sh_degree, "spherical-harmonics degree", within(0, 3));
  add_text(app, "--test-cameras", f->test_cameras, "held-out cameras, evaluated at the end", "PATH");
  add_text(app, "--test-images", f->test_images, "their images (default: --images)", "DIR");
  add_flag(app, "--static-only", f->static_only, "no Gaussian moves");
  add_colour(app, "--background", o.background, "the background colour");
  add_choice(app, "--motion", o.motion, "all: every Gaussian may move; promote: static until promoted");
  add_number(app, "--time-ramp", o.time_ramp, "share of the run over which time opens from frame 0 to the whole clip", from_below(0, 1));
  add_number(app, "--key-lr-scale", o.key_lr_scale, "learning-rate scale of motion keys", positive());
  add_number(app, "--motion-sparsity", o.motion_sparsity, "weight of the penalty on motion", at_least(0));
  add_switch_off(app, "--no-keyed-opacity", o.keyed_opacity, "opacity does not change over time");
  add_switch_off(app, "--no-flow-keys", o.flow_keys, "motion keys not placed by optical flow");
  add_flag(app, "--motion-from-masks", o.change_from_masks, "what moves found from the foreground masks, not from image change");
  add_text(app, "--init", f->init, "initial points: points, random or random+carve (default: points when there are any)", "NAME");
  add_number(app, "--init-points", f->view_init.random_points, "random: how many points", at_least(1));
  add_flag(app, "--colour-correction", f->colour_correction, "learn a gain and offset per camera");
  add_text(app, "--camera-times", f->camera_times,
           "single photographs trained on beside --train-cameras: a JSON list of {camera, frame} (finetune --pool-budget's pool_chosen.json)", "PATH");
  add_dataset_flags(app, f->data, "--train-cameras");
  return bind(f, train);
}

// ------------------------------------------------------------------ the command table

/// `--kernel simd|scalar`, accepted by every command: which tile kernel renders, trains and
/// blurs the loss for this invocation (raster.hpp, Kernel); the default again afterwards.
class KernelChoice {
 public:
  explicit KernelChoice(Kernel kernel) {
    if (kernel != Kernel::Default) set_default_kernel(kernel);
  }
  ~KernelChoice() { set_default_kernel(previous_); }

 private:
  Kernel previous_ = resolve_kernel(Kernel::Default);
};

void add_common_flags(CLI::App& app, CommonFlags& c) {
  add_number(app, "--threads", c.threads, "worker threads (0: all cores)", at_least(0))->group("Common options");
  add_flag(app, "--quiet", c.quiet, "no progress bar")->group("Common options");
  add_choice(app, "--kernel", c.kernel, "the tile kernel: vector (default) or the scalar reference")->group("Common options");
}

void print_overview(std::ostream& out) {
  out << "fillgs: fill observation gaps in 4D Gaussian Splatting\n\nusage: fillgs <command> [options]\n\ncommands:\n";
  for (const Command& c : commands()) {
    std::string name = c.name;
    out << "  " << name << std::string(name.size() < 10 ? 10 - name.size() : 1, ' ') << c.summary << "\n";
  }
  out << "\n'fillgs <command> --help' lists a command's options with their defaults; 'fillgs --version'.\n"
      << "README.md explains the workflow, from your own 4D model to fine-tuned results; the formats are in data/README.md.\n";
}

/// One command's parser: its flags, the common ones, and help made from them.
std::unique_ptr<CLI::App> make_app(const Command& c, CommonFlags& common, Action* action) {
  auto app = make_parser(std::string("fillgs ") + c.name, c.summary);
  *action = c.declare(*app);
  add_common_flags(*app, common);
  return app;
}

std::string help_of(const Command& c) {
  CommonFlags common;
  Action action;
  return make_app(c, common, &action)->help();
}

}  // namespace

const std::vector<Command>& commands() {
  static const std::vector<Command> all = {
      {"info", "Gaussian count, SH degree, motion, static/dynamic, bounding box", declare_info},
      {"render", "render every camera of a camera file", declare_render},
      {"synth", "the chair/shelf analysis scene with ground-truth images", declare_synth},
      {"convert", "a model as 3DGS, fillgs or one 3DGS PLY per frame", declare_convert},
      {"cameras", "cameras as transforms.json or COLMAP text", declare_cameras},
      {"observe", "observation counts C[t][g], speeds s, deficiency D = s/(1+C)", declare_observe},
      {"train", "train a 4D Gaussian model from multi-view video", declare_train},
      {"explore", "the exploration grid: exploration.vdb, exploration.png", declare_explore},
      {"select", "viewpoint-time selection by a strategy", declare_select},
      {"finetune", "fine-tune with refined virtual views (a trained network's model is given keys first, as dense as its motion needs: it says how many)", declare_finetune},
      {"eval", "PSNR, SSIM, moving-region PSNR per split", declare_eval},
      {"bench", "the paper's comparison (resumable); --merge: its tables over finished runs", declare_bench},
      {"run", "the whole pipeline on the built-in scene, with a report", declare_run},
  };
  return all;
}

std::string command_help(const std::string& name) {
  for (const Command& c : commands())
    if (name == c.name) return help_of(c);
  throw_error("fillgs: unknown command '", name, "' (see 'fillgs help')");
}

int run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  try {
    if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
      if (args.size() >= 2 && args[0] == "help") out << command_help(args[1]);
      else print_overview(out);
      return args.empty() ? 2 : 0;
    }
    if (args[0] == "--version") {
      out << "fillgs 0.1.0\n";
      return 0;
    }
    const Command* command = nullptr;
    for (const Command& c : commands())
      if (args[0] == c.name) command = &c;
    if (!command) throw_error("fillgs: unknown command '", args[0], "' (see 'fillgs help')");
    CommonFlags common;
    Action action;
    const std::unique_ptr<CLI::App> app = make_app(*command, common, &action);
    if (!parse_flags(*app, std::vector<std::string>(args.begin() + 1, args.end()), out)) return 0;  // --help
    const KernelChoice kernel(common.kernel);
    const ThreadLimit threads(common.threads);
    const Invocation in{command->name, *app, common, args, out, err};
    return action(in);
  } catch (const Error& e) {
    err << "error: " << output_paths(e.what()) << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    err << "error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    err << "error: " << output_paths(e.what()) << "\n";
    return 1;
  }
}

}  // namespace fillgs::cli
