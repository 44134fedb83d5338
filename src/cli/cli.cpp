#include "fillgs/cli.hpp"

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <optional>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "fillgs/error.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/image_io.hpp"
#include "fillgs/init.hpp"
#include "fillgs/observe_io.hpp"
#ifdef FILLGS_WITH_MPI
#include "fillgs/observe_mpi.hpp"
#endif
#include "fillgs/raster.hpp"
#include "fillgs/scene_io.hpp"
#include "fillgs/synth.hpp"
#include "fillgs/train.hpp"
#include "fillgs/plot.hpp"
#include "fillgs/visibility.hpp"
#include "commands.hpp"
#include "common.hpp"
#include "progress_bar.hpp"

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
  j["notes"] = c.notes;
  return j;
}

int cmd_info(const std::vector<std::string>& args, std::ostream& out, std::ostream&) {
  Args a("info", args, 1, kSceneOptions, {"json"});
  if (a.positional.size() != 1) throw_error("fillgs info: give exactly one scene path");
  const GaussianCloud c = read_scene(a.positional[0], scene_options(a));
  const nlohmann::json j = scene_summary(c);
  if (a.flag("json")) {
    out << j.dump(2) << "\n";
    return 0;
  }
  out << "scene        " << a.positional[0] << "\n";
  for (const char* key : {"gaussians", "sh_degree", "motion_model", "static", "dynamic", "keyframes", "bbox_min", "bbox_max"})
    if (j.contains(key)) {
      std::string label = key;
      std::replace(label.begin(), label.end(), '_', ' ');
      std::string value;
      if (j[key].is_string()) value = j[key].get<std::string>();
      else if (j[key].is_array())
        for (const auto& x : j[key]) value += (value.empty() ? "" : " ") + x.dump();
      else value = j[key].dump();
      out << label << std::string(label.size() < 13 ? 13 - label.size() : 1, ' ') << value << "\n";
    }
  for (const std::string& n : c.notes) out << "note         " << n << "\n";
  return 0;
}

// ------------------------------------------------------------------ render

int cmd_render(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("render", args, 1,
         merge(merge({"scene", "cameras", "time", "channel", "format", "out", "threads", "background"}, kSceneOptions), kCameraOptions),
         {"quiet"});
  const auto t0 = Clock::now();
  const std::string out_dir = a.require("out");
  const std::string channel = a.get("channel", "rgb");
  if (channel != "rgb" && channel != "depth" && channel != "alpha")
    throw_error("fillgs render: --channel must be rgb, depth or alpha (got '", channel, "')");
  const std::string format = a.get("format", "png");
  if (format != "png" && format != "exr") throw_error("fillgs render: --format must be png or exr (got '", format, "')");
  const bool fixed_time = a.has("time");
  const double time = a.number("time", 0.0);
  if (fixed_time && (time < 0 || time > 1)) throw_error("fillgs render: --time must lie in [0, 1] (got ", time, ")");
  RenderOptions ro;
  ro.threads = a.threads();
  ro.rgb = channel == "rgb";
  ro.depth = channel == "depth";
  if (a.has("background")) {
    const std::vector<double> c = a.numbers("background", 3);
    ro.background = Vec3f(float(c[0]), float(c[1]), float(c[2]));
  }
  const GaussianCloud cloud = read_scene(a.require("scene"), scene_options(a));
  const std::vector<Camera> cams = read_cameras(a.require("cameras"), camera_options(a));
  const double load_s = seconds_since(t0);

  OutputFolder folder(out_dir);  // nothing replaces the folder's files unless every view renders
  FrameEvaluator ev(cloud);
  TerminalProgress progress(err, progress_enabled(a));
  progress.start("rendering", cams.size());
  double render_s = 0;
  size_t rendered = 0;
  nlohmann::json views = nlohmann::json::array();
  for (const Camera& cam : cams) {
    const double t = fixed_time ? time : (cam.has_time() ? cam.time : 0.0);
    const auto tr = Clock::now();
    const RenderOutput r = render(ev.evaluate(t), cam, ro);
    render_s += seconds_since(tr);
    rendered += r.rendered;
    Image img(cam.width, cam.height, channel == "rgb" ? 3 : 1);
    double depth_scale = 1.0;
    if (channel == "rgb") img.pixels = r.rgb;
    else if (channel == "alpha") img.pixels = r.alpha;
    else {
      float max_depth = 0.0f;
      for (size_t p = 0; p < r.alpha.size(); ++p) {
        img.pixels[p] = r.alpha[p] > 1e-6f ? r.depth[p] / r.alpha[p] : 0.0f;
        max_depth = std::max(max_depth, img.pixels[p]);
      }
      // 8-bit output holds [0, 1]: depth is divided by its maximum (recorded in summary.json).
      if (format == "png" && max_depth > 0) {
        depth_scale = max_depth;
        for (float& v : img.pixels) v /= max_depth;
      }
    }
    write_image(join_path(folder.path(), cam.name + "." + format), img);
    views.push_back({{"camera", cam.name}, {"time", t}, {"gaussians_rendered", r.rendered}, {"depth_scale", depth_scale}});
    progress.advance();
  }
  progress.finish();
  nlohmann::json s;
  s["command"] = "render";
  s["scene"] = scene_summary(cloud);
  s["cameras"] = cams.size();
  s["channel"] = channel;
  s["seconds"] = {{"load", load_s}, {"render", render_s}, {"total", seconds_since(t0)}};
  s["ms_per_view"] = cams.empty() ? 0.0 : 1000.0 * render_s / cams.size();
  s["kernel"] = {{"name", kernel_name(Kernel::Default)}, {"instruction_set", simd_target()}};
  s["views"] = views;
  write_file_atomically(join_path(folder.path(), "summary.json"), s.dump(2) + "\n");
  folder.commit();
  out << "rendered " << cams.size() << " views (" << channel << ") into " << out_dir << ": "
      << (cams.empty() ? 0.0 : 1000.0 * render_s / cams.size()) << " ms per view, " << rendered / std::max<size_t>(1, cams.size())
      << " Gaussians per view\n";
  return 0;
}

// ------------------------------------------------------------------ synth

SynthOptions synth_options(const Args& a) {
  SynthOptions o;
  o.frames = a.integer("frames", o.frames);
  o.width = a.integer("width", o.width);
  o.height = a.integer("height", o.height);
  o.seed = uint64_t(a.integer("seed", int(o.seed)));
  o.spacing = a.number("spacing", o.spacing);
  o.rig = a.get("rig", o.rig);
  o.variant = a.get("variant", o.variant);
  return o;
}

int cmd_synth(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("synth", args, 1, {"out", "frames", "width", "height", "seed", "spacing", "threads", "rig", "variant"}, {"quiet"});
  const auto t0 = Clock::now();
  const std::string dir = a.require("out");
  const SynthScene s = make_synthetic_scene(synth_options(a));
  TerminalProgress progress(err, progress_enabled(a));
  OutputFolder folder(dir);  // a failed or killed run leaves the folder as it was
  write_synthetic_scene(s, folder.path(), progress, a.threads());
  folder.commit();
  out << "synthetic scene: " << s.scene.size() << " Gaussians (" << s.scene.dynamic_count() << " moving), "
      << s.train.size() << " rig cameras (" << s.options.rig << ", split: train " << s.split.train.size() << ", interpolation "
      << s.split.interpolation.size() << ", extrapolation " << s.split.extrapolation.size() << "), " << s.options.frames << " frames, " << s.options.width << "x" << s.options.height
      << ", written to " << dir << " in " << seconds_since(t0) << " s\n";
  return 0;
}

// ------------------------------------------------------------------ convert / cameras

int cmd_convert(const std::vector<std::string>& args, std::ostream& out, std::ostream&) {
  Args a("convert", args, 1, merge({"scene", "out", "to", "time", "frames"}, kSceneOptions), {});
  const GaussianCloud c = read_scene(a.require("scene"), scene_options(a));
  const std::string to = a.get("to", "3dgs"), path = a.require("out");
  if (to == "frames") {
    // One standard 3DGS PLY per frame, t = f/(F−1): a sequence splat viewers can play.
    const int frames = a.integer("frames", c.motion == MotionModel::Keyframed ? c.keyframed.key_count : 0);
    if (frames < 1) throw_error("fillgs convert: --to frames needs --frames F (F >= 1)");
    OutputFolder folder(path);
    const std::vector<double> times = frame_times(frames);
    for (int f = 0; f < frames; ++f) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04d.ply", f);
      write_3dgs_ply(join_path(folder.path(), name), c, times[size_t(f)]);
    }
    folder.commit();
    out << "wrote " << frames << " frames to " << path << " (3dgs, frame_0000.ply … at t = f/" << std::max(1, frames - 1) << ", " << c.size()
        << " Gaussians each)\n";
    return 0;
  }
  if (to == "3dgs") write_3dgs_ply(path, c, a.number("time", 0.0));
  else if (to == "fillgs") write_fillgs_ply(path, c, a.integer("frames", 0));
  else throw_error("fillgs convert: --to must be 3dgs, fillgs or frames (got '", to, "')");
  out << "wrote " << path << " (" << to << ", " << c.size() << " Gaussians)\n";
  return 0;
}

int cmd_cameras(const std::vector<std::string>& args, std::ostream& out, std::ostream&) {
  Args a("cameras", args, 1, merge({"cameras", "out", "to"}, kCameraOptions), {});
  const std::vector<Camera> cams = read_cameras(a.require("cameras"), camera_options(a));
  const std::string to = a.get("to", "transforms"), path = a.require("out");
  if (to == "transforms") write_transforms_json(path, cams);
  else if (to == "colmap") write_colmap_text(path, cams);
  else throw_error("fillgs cameras: --to must be transforms or colmap (got '", to, "')");
  out << "wrote " << cams.size() << " cameras to " << path << " (" << to << ")\n";
  return 0;
}

// ------------------------------------------------------------------ observe

namespace {

/// What `fillgs observe` computes: the scene, the cameras, the times and how.
struct ObserveJob {
  ObservationOptions options;
  ObserveOutputOptions output;
  GaussianCloud cloud;
  std::vector<Camera> cameras;
  std::vector<double> times;
  double frame_step = 0;
};

ObserveJob observe_job(const Args& a) {
  ObserveJob job;
  ObservationOptions& o = job.options;
  o.visibility.mode = parse_visibility_mode(a.get("mode", "frustum"));
  o.visibility.stride = a.integer("stride", o.visibility.stride);
  if (o.visibility.stride < 1) throw_error("fillgs observe: --stride must be at least 1");
  o.visibility.min_weight = float(a.number("tau", o.visibility.min_weight));
  if (!(o.visibility.min_weight > 0.0f && o.visibility.min_weight < 1.0f)) throw_error("fillgs observe: --tau must lie in (0, 1)");
  o.visibility.threads = a.threads();
  o.visibility.dilate = !a.flag("no-raster-match");
  o.incremental = !a.flag("from-scratch");
  if (a.has("hit-cache")) {
    const double mb = a.number("hit-cache", 0.0);
    if (!(mb >= 0 && mb < 1e9)) throw_error("fillgs observe: --hit-cache must be a number of MB, at least 0 (got ", a.get("hit-cache"), ")");
    o.static_hit_cache_bytes = size_t(mb * 1048576.0);
  }
  const std::string tables = a.get("motion-tables", "dense");
  if (tables != "dense" && tables != "dynamic") throw_error("fillgs observe: --motion-tables must be dense or dynamic (got '", tables, "')");
  job.output.dense_motion_tables = tables == "dense";
  job.output.plots = !a.flag("no-plots");
  job.cloud = read_scene(a.require("scene"), scene_options(a));
  job.cameras = read_cameras(a.require("cameras"), camera_options(a));
  if (job.cameras.empty()) throw_error(a.get("cameras"), ": no cameras");
  job.times = observe_times(a, job.cloud, job.cameras, &job.frame_step);
  if (a.has("shard")) {
    // --shard i/n: the i-th of n contiguous blocks of frames (1-based), for observe --merge.
    const std::string spec = a.get("shard");
    const size_t slash = spec.find('/');
    size_t index = 0, count = 0;
    if (slash != std::string::npos) {
      index = parse_count(spec.substr(0, slash), 1u << 20, "fillgs observe", "--shard index");
      count = parse_count(spec.substr(slash + 1), 1u << 20, "fillgs observe", "--shard count");
    }
    if (slash == std::string::npos || index < 1 || count < 1 || index > count)
      throw_error("fillgs observe: --shard expects i/n with 1 <= i <= n (got '", spec, "')");
    if (count > job.times.size()) throw_error("fillgs observe: --shard ", spec, ": more shards than the ", job.times.size(), " frames");
    o.frames = shard_frames(job.times.size(), index - 1, count);
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
int observe_over_mpi(const Args& a, const std::string& out_dir, std::ostream& out, std::ostream& err) {
#ifdef FILLGS_WITH_MPI
  const auto t0 = Clock::now();
  mpi::Session session;
  ObserveJob job;
  std::optional<OutputFolder> folder;
  std::string failure;
  try {
    if (a.has("shard")) throw_error("fillgs observe: --mpi shares the whole job between the ranks; --shard splits it between separate runs");
    job = observe_job(a);
    if (session.rank() == 0) folder.emplace(out_dir);
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
    TerminalProgress progress(err, progress_enabled(a));
    const ObserveReport r =
        write_observation(job.cloud, job.cameras, job.times, job.frame_step, job.options, source, folder->path(), job.output, progress);
    folder->commit();
    print_observed(out, job, r, seconds_since(t0), out_dir);
    out << "(" << session.size() << " MPI ranks)\n";
    return 0;
  } catch (const std::exception& e) {
    // The ranks are exchanging frames: one that stops would leave the others waiting.
    err << "error: " << (session.rank() ? "rank " + std::to_string(session.rank()) + ": " : std::string()) << e.what() << "\n";
    err.flush();
    session.abort(1);
  }
#else
  (void)a, (void)out_dir, (void)out, (void)err;
  throw_error("fillgs observe: --mpi needs fillgs built with MPI (scripts/install-deps.sh installs libopenmpi-dev; then rebuild)");
#endif
}

}  // namespace

int cmd_observe(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("observe", args, 1,
         merge(merge({"scene", "cameras", "frames", "times", "mode", "stride", "threads", "out", "tau", "motion-tables", "shard", "merge", "hit-cache"},
                     kSceneOptions),
               kCameraOptions),
         {"quiet", "from-scratch", "no-raster-match", "no-plots", "mpi"});
  const auto t0 = Clock::now();
  const std::string out_dir = a.require("out");
  if (a.has("merge")) {
    for (const char* k : {"scene", "cameras", "frames", "times", "mode", "stride", "tau", "motion-tables", "shard", "hit-cache"})
      if (a.has(k)) throw_error("fillgs observe: --merge combines finished shards; --", k, " belongs to the shards' own runs");
    const std::vector<std::string> shards = split_commas(a.get("merge"));
    OutputFolder folder(out_dir);
    const ObserveReport r = merge_observations(shards, folder.path(), !a.flag("no-plots"));
    folder.commit();
    out << "merged " << shards.size() << " shards: " << r.summary.gaussians << " Gaussians over " << r.summary.frames << " frames and "
        << r.summary.views << " views -> " << out_dir << "\n";
    return 0;
  }
  if (a.flag("mpi")) return observe_over_mpi(a, out_dir, out, err);
  const ObserveJob job = observe_job(a);
  TerminalProgress progress(err, progress_enabled(a));
  OutputFolder folder(out_dir);  // a failed or killed run leaves the folder as it was
  const ObserveReport r = observe_to_directory(job.cloud, job.cameras, job.times, job.frame_step, job.options, folder.path(), job.output, progress);
  folder.commit();
  print_observed(out, job, r, seconds_since(t0), out_dir);
  return 0;
}

// ------------------------------------------------------------------ train

int cmd_train(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("train", args, 1,
         merge({"images", "cameras", "points", "iterations", "out", "train-cameras", "resume", "checkpoint-every", "seed", "threads",
                "key-interval", "max-gaussians", "sh-degree", "test-images", "test-cameras", "background", "motion", "time-ramp",
                "key-lr-scale", "motion-sparsity", "init", "init-points"},
               kDatasetOptions),
         {"quiet", "static-only", "no-keyed-opacity", "no-flow-keys", "colour-correction", "motion-from-masks"});
  const auto t0 = Clock::now();
  const std::string out_dir = a.require("out");
  const std::string cameras = a.require("cameras");
  const DatasetOptions dopt = dataset_options(a, "train-cameras");
  const Dataset data = Dataset::load(a.require("images"), cameras, dopt);
  const int iterations = a.integer("iterations", 3000);
  if (iterations < 1) throw_error("fillgs train: --iterations must be at least 1");
  TrainOptions o = TrainOptions::scaled(iterations);
  o.seed = uint64_t(a.integer("seed", 1));
  o.threads = a.threads();
  o.key_interval_frames = a.integer("key-interval", o.key_interval_frames);
  if (o.key_interval_frames < 1) throw_error("fillgs train: --key-interval must be at least 1 frame");
  o.max_gaussians = size_t(a.integer("max-gaussians", int(o.max_gaussians)));
  o.max_sh_degree = a.integer("sh-degree", o.max_sh_degree);
  if (o.max_sh_degree < 0 || o.max_sh_degree > 3) throw_error("fillgs train: --sh-degree must be 0..3");
  o.allow_dynamic = !a.flag("static-only");
  o.motion = motion_learning_from_string(a.get("motion", to_string(o.motion)));
  o.keyed_opacity = !a.flag("no-keyed-opacity");
  o.flow_keys = !a.flag("no-flow-keys");
  o.change_from_masks = a.flag("motion-from-masks");
  if (o.change_from_masks && !data.has_masks()) throw_error("fillgs train: --motion-from-masks needs foreground masks (seg/ beside the meta file)");
  o.time_ramp = a.number("time-ramp", o.time_ramp);
  if (!(o.time_ramp >= 0 && o.time_ramp < 1)) throw_error("fillgs train: --time-ramp must be in [0, 1)");
  o.key_lr_scale = a.number("key-lr-scale", o.key_lr_scale);
  if (!(o.key_lr_scale > 0)) throw_error("fillgs train: --key-lr-scale must be positive");
  o.motion_sparsity = a.number("motion-sparsity", o.motion_sparsity);
  if (!(o.motion_sparsity >= 0)) throw_error("fillgs train: --motion-sparsity must be at least 0");
  o.checkpoint_interval = a.integer("checkpoint-every", std::max(1, iterations / 5));
  o.colour_correction = a.flag("colour-correction");
  if (a.has("background")) {
    const std::vector<double> c = a.numbers("background", 3);
    for (int k = 0; k < 3; ++k) o.background[k] = float(c[size_t(k)]);
  }
  // Test split (optional): loaded before anything is written, so bad input writes nothing.
  std::unique_ptr<Dataset> test;
  if (a.has("test-cameras")) test = std::make_unique<Dataset>(Dataset::load(a.get("test-images", a.get("images")), a.get("test-cameras"), dataset_options(a, "")));

  std::unique_ptr<Trainer> trainer;
  PointSet init_points;  // written beside the model when made from the views
  if (a.has("resume")) {
    trainer = std::make_unique<Trainer>(Trainer::resume(data, a.get("resume"), o));
  } else {
    // Initial points: --points, else points.ply beside the cameras, else from the views
    // (init.hpp: random points the first frame's cameras see, plus the foreground's visual
    // hull when the dataset has masks); --init picks explicitly.
    std::string points = a.get("points");
    const std::string beside = join_path(std::filesystem::path(cameras).parent_path().string(), "points.ply");
    if (points.empty() && std::filesystem::exists(beside)) points = beside;
    const std::string init = a.get("init", points.empty() ? "random+carve" : "points");
    if (init == "points") {
      if (points.empty()) throw_error("fillgs train: --init points needs --points (no points.ply beside ", cameras, ")");
      trainer = std::make_unique<Trainer>(data, init_from_points(read_points(points)), o);
    } else if (init == "random" || init == "random+carve") {
      ViewInitOptions vo;
      vo.method = init == "random" ? ViewInit::Random : ViewInit::RandomAndCarve;
      vo.random_points = size_t(a.integer("init-points", int(vo.random_points)));
      vo.seed = o.seed;
      const ViewInitResult vi = points_from_views(data, vo);
      out << "initial points from the cameras' first views: " << vi.random << " random in the cameras' common volume"
          << (vo.method == ViewInit::RandomAndCarve ? ", " + std::to_string(vi.carved) + " carved from the foreground masks" +
                                                          (data.has_masks() ? "" : " (no masks)")
                                                    : "")
          << "\n";
      init_points = vi.points;
      trainer = std::make_unique<Trainer>(data, init_from_points(vi.points), o);
    } else {
      throw_error("fillgs train: unknown --init \"", init, "\" (points, random, random+carve)");
    }
  }
  make_directories(join_path(out_dir, "checkpoints"));
  if (!init_points.positions.empty()) write_points_ply(join_path(out_dir, "init_points.ply"), init_points);
  out << "training on " << data.views().size() << " views (" << data.rigs().size() << " cameras x " << data.frames() << " frames; "
      << (data.image_bytes() >> 20) << " MB of 8-bit images " << (data.images_spilled() ? "in the image cache file, read on demand" : "in memory")
      << "), " << trainer->params().size() << " initial Gaussians, " << iterations << " iterations\n";
  TerminalProgress progress(err, progress_enabled(a));
  while (trainer->iteration() < iterations) {
    const int next = std::min(iterations, (trainer->iteration() / o.checkpoint_interval + 1) * o.checkpoint_interval);
    trainer->run(next, progress);
    const TrainStatus st = trainer->status();
    char line[200];
    std::snprintf(line, sizeof line, "iteration %d: loss %.4f, PSNR %.2f dB, %zu Gaussians (%zu moving), %.1f it/s\n", st.iteration,
                  st.loss, st.psnr, st.gaussians, st.dynamic, st.iterations_per_second);
    out << line << std::flush;
    trainer->save_checkpoint(join_path(out_dir, "checkpoints/latest.ckpt"));
  }
  const double train_seconds = seconds_since(t0);
  const GaussianCloud model = trainer->model();
  write_fillgs_ply(join_path(out_dir, "model.ply"), model, data.frames());
  write_3dgs_ply(join_path(out_dir, "frame0_3dgs.ply"), model, 0.0);
  if (o.colour_correction) {
    write_colour_correction(join_path(out_dir, "colour_correction.json"), trainer->colour_correction());
    out << "colour correction per camera (gain r,g,b / offset r,g,b; " << data.rigs()[0] << " is the reference):";
    for (const ColourCorrection& c : trainer->colour_correction()) {
      char line[160];
      std::snprintf(line, sizeof line, " %s %.3f,%.3f,%.3f/%+.3f,%+.3f,%+.3f;", c.rig.c_str(), c.gain[0], c.gain[1], c.gain[2], c.offset[0],
                    c.offset[1], c.offset[2]);
      out << line;
    }
    out << "\n";
  }
  nlohmann::json j;
  j["iterations"] = trainer->iteration();
  j["seconds"] = train_seconds;
  j["views"] = data.views().size();
  j["cameras"] = data.rigs();
  j["frames"] = data.frames();
  j["gaussians"] = model.size();
  j["moving_gaussians"] = model.dynamic_count();
  j["final_loss_ema"] = trainer->status().loss;
  j["motion"] = {{"learning", to_string(o.motion)}, {"keyed_opacity", o.keyed_opacity}, {"time_ramp", o.time_ramp},
                 {"key_lr_scale", o.key_lr_scale}, {"motion_sparsity", o.motion_sparsity}, {"key_interval_frames", o.key_interval_frames},
                 {"flow_keys", o.flow_keys}, {"keys_placed_by_flow", trainer->flow_placed().first}};
  nlohmann::json dens = nlohmann::json::array();
  for (const DensifyRecord& r : trainer->densify_log())
    dens.push_back({{"iteration", r.iteration}, {"gaussians", r.gaussians}, {"keyed", r.dynamic}, {"promoted", r.promoted},
                    {"cloned", r.cloned}, {"split", r.split}, {"pruned", r.pruned}});
  j["densification"] = dens;
  const EvalResult tr = evaluate_views(model, data, std::max<int>(1, int(data.views().size() / 32)), o.background, o.threads);
  j["train_psnr"] = tr.psnr;
  j["train_ssim"] = tr.ssim;
  out << "trained " << model.size() << " Gaussians (" << model.dynamic_count() << " moving) in " << train_seconds << " s; train PSNR "
      << tr.psnr << " dB";
  if (test) {
    const EvalResult te = evaluate_views(model, *test, 1, o.background, o.threads);
    j["test_psnr"] = te.psnr;
    j["test_ssim"] = te.ssim;
    j["test_views"] = te.views;
    out << ", test PSNR " << te.psnr << " dB over " << te.views << " views";
  }
  // Peak resident memory of the whole run (images held 8-bit, the model, the optimiser).
  j["peak_memory_bytes"] = peak_memory_bytes();
  j["images"] = {{"bytes", data.image_bytes()}, {"spilled", data.images_spilled()}};
  out << ", peak memory " << (peak_memory_bytes() >> 20) << " MB -> " << out_dir << "\n";
  ScatterSeries loss{"loss", {}, {}, {}};
  const std::vector<float>& h = trainer->loss_history();
  const size_t every = std::max<size_t>(1, h.size() / 400);
  for (size_t i = 0; i < h.size(); i += every) loss.x.push_back(double(i + 1)), loss.y.push_back(h[i]);
  write_scatter_png(join_path(out_dir, "loss.png"), {loss}, {"training loss (L1 + 0.2 D-SSIM)", "iteration", "loss"}, false);
  write_file_atomically(join_path(out_dir, "summary.json"), j.dump(2) + "\n");
  return 0;
}

void print_help(std::ostream& out) {
  out << "fillgs: fill observation gaps in 4D Gaussian Splatting\n\n"
         "usage: fillgs <command> [options]\n\n"
         "  info SCENE [--json]                       Gaussian count, SH degree, motion, static/dynamic, bbox\n"
         "  render --scene S --cameras C --out DIR    render every camera to DIR/<camera>.png\n"
         "         [--time t] [--channel rgb|depth|alpha] [--format png|exr] [--threads n] [--background r,g,b]\n"
         "  synth --out DIR [--frames F] [--width W] [--height H] [--seed n] [--spacing m] [--rig ring|n3v|technicolor]\n"
         "        [--variant chair|orbit|lift (ring) | kitchen (n3v, technicolor)]\n"
         "                                            the chair/shelf analysis scene with ground-truth images\n"
         "  convert --scene S --out F.ply [--to 3dgs|fillgs|frames] [--time t] [--frames F]\n"
         "  cameras --cameras C --out PATH [--to transforms|colmap]\n"
         "  observe --scene S --cameras C --out DIR   observation counts C[t][g], speeds s, deficiency D = s/(1+C)\n"
         "         [--frames F | --times t1,t2,..] [--mode frustum|raytraced|exact] [--stride s] [--tau w]\n"
         "         [--threads n] [--motion-tables dense|dynamic] [--from-scratch] [--no-raster-match] [--no-plots]\n"
         "         [--hit-cache MB]                 raytraced: static hits kept for re-traced rays (default 2048; 0: none)\n"
         "         [--shard i/n]                    the i-th of n blocks of frames, for --merge\n"
         "         [--mpi]                          under mpirun: frames shared by the ranks, rank 0 writes\n"
         "  observe --merge DIR1,DIR2,.. --out DIR [--no-plots]   shards combined into the single-process tables\n"
         "  train --images DIR --cameras C --out DIR [--points P] [--iterations N] [--train-cameras a,b]\n"
         "         [--resume CKPT] [--checkpoint-every N] [--seed n] [--key-interval F] [--max-gaussians N]\n"
         "         [--sh-degree D] [--test-cameras C --test-images DIR] [--static-only] [--background r,g,b]\n"
         "         [--motion all|promote] [--time-ramp r] [--key-lr-scale s] [--motion-sparsity s] [--no-keyed-opacity] [--no-flow-keys]\n"
         "         [--motion-from-masks]\n"
         "         [--init points|random|random+carve] [--init-points N] [--colour-correction]\n"
         "                                            train a 4D Gaussian model from multi-view video\n"
         "  explore --scene S --cameras C --out DIR   the exploration grid: exploration.vdb, exploration.png\n"
         "         [--divisions n] [--occupancy-alpha a] [--frames F]\n"
         "  select --scene S --cameras C --out DIR [--images DIR] [--strategy NAME] [--trajectories K] [--seed n]\n"
         "         [--views n] [--patch-frames n] [--time-stride k] [--render-scale s] [--renderer raytraced|raster]\n"
         "         [--stride s] [--global-candidates n] [--grid exploration.vdb | --divisions n] [--mode frustum|raytraced|exact]\n"
         "         [--no-start-selection] [--no-error-term] [--no-sensitivity-term] [--no-candidate-scoring]\n"
         "         [--no-global] [--count-only | --speed-only] [--no-renders]\n"
         "                                            viewpoint-time selection; strategies: fillgs random negative\n"
         "                                            interpolation fisherrf coverage3d coverage4d\n"
         "  finetune --model M --images DIR --cameras C --out DIR [--train-cameras a,b] [--iterations N]\n"
         "         [--select-every M] [--trajectories K] [--strategy NAME] [--weighting NAME] [--paper-schedule]\n"
         "         [--refiner identity|oracle|external|rig] [--refiner-command 'cmd {in} {out}'] [--refiner-timeout s]\n"
         "         [--pool-cameras a,b --rig-max-distance d --rig-max-angle deg]\n"
         "         [--truth SCENE --artifact-strength a --support observed|full --support-window w]\n"
         "         [--confidence DIR] [--mask depth-warp|sweep]\n"
         "         [--covis paper|static-count|density] [--mask-sigma s] [--refined-share p] [selection flags]\n"
         "         [--motion-rates repair|gentle] [--position-lr LR] [--key-lr-scale k]\n"
         "                                            fine-tune with refined virtual views; weightings: fillgs none\n"
         "                                            no-consistency no-covisibility 3dgs-enhancer exploregs ua-4dgs\n"
         "  eval --model M --images DIR --cameras C1[,C2] [--splits n1,n2] [--select-cameras a,b] [--truth SCENE]\n"
         "         [--colour-correction colour_correction.json] [--ls-gain]\n"
         "         [--lpips NET.onnx] [--out DIR] [--stride k]     PSNR, SSIM, moving-region PSNR per split\n"
         "  bench [--out DIR] [--scenes n3v,technicolor,chair,orbit,lift] [--seeds 1,2,3] [--only GROUPS] [--configs IDS]\n"
         "         [--support observed|full|both] [--iterations N] [--backbone-iterations N] [--width W --height H --frames F]\n"
         "         [--artifact-strength a] [--baseline-weighting NAME] [--motion-rates repair|gentle] [--position-lr LR]\n"
         "         [--key-lr-scale k] [--smoke]                the paper's comparison (resumable)\n"
         "  bench --merge A,B,.. --out DIR             its tables over finished runs: bench folders or results.csv files\n"
         "  run [--out DIR] [--scene NAME] [--baseline NAME] [--support observed|full] [--motion-rates repair|gentle] [--smoke]\n"
         "                                            the whole pipeline on the built-in scene, with a report\n\n"
         "scene options:  --scene-format auto|3dgs|stg|ex4dgs|fillgs --duration F (Ex4DGS) --stg-duration F\n"
         "                --stg-color auto|sigmoid|clamp|none --static-threshold v\n"
         "camera options: --camera-format auto|colmap|llff|transforms|3dgs|technicolor|d3dgs --width W --height H\n"
         "                --llff-downscale s\n"
         "image options:  --frames first:last:step (Python's slice; the frames kept become the video)\n"
         "                --downscale k (k×k block average; train, finetune, eval)\n"
         "                --monocular-cycle a,b,.. (frame f keeps only camera [f mod n])\n"
         "                --image-memory GB (images beyond it wait in a temporary file in $TMPDIR, read\n"
         "                on demand; default a quarter of the machine's memory)\n"
         "common:         --quiet (no progress bar)\n"
         "                --kernel simd|scalar (the tile kernel: vector, default, or the scalar reference)\n";
}

}  // namespace

/// `--kernel simd|scalar`, accepted by every command: which tile kernel renders, trains and
/// blurs the loss for this invocation (raster.hpp, Kernel). Removed from the arguments here.
class KernelChoice {
 public:
  explicit KernelChoice(std::vector<std::string>* args) {
    for (size_t i = 1; i < args->size(); ++i) {
      if ((*args)[i] != "--kernel") continue;
      if (i + 1 >= args->size()) throw_error("fillgs ", (*args)[0], ": --kernel needs a value (simd or scalar)");
      set_default_kernel(parse_kernel((*args)[i + 1]));
      args->erase(args->begin() + long(i), args->begin() + long(i) + 2);
      break;
    }
  }
  ~KernelChoice() { set_default_kernel(previous_); }

 private:
  Kernel previous_ = resolve_kernel(Kernel::Default);
};

int run(const std::vector<std::string>& all_args, std::ostream& out, std::ostream& err) {
  try {
    std::vector<std::string> args = all_args;
    const KernelChoice kernel(&args);
    if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
      print_help(out);
      return args.empty() ? 2 : 0;
    }
    const std::string& cmd = args[0];
    if (cmd == "info") return cmd_info(args, out, err);
    if (cmd == "render") return cmd_render(args, out, err);
    if (cmd == "synth") return cmd_synth(args, out, err);
    if (cmd == "convert") return cmd_convert(args, out, err);
    if (cmd == "cameras") return cmd_cameras(args, out, err);
    if (cmd == "observe") return cmd_observe(args, out, err);
    if (cmd == "run") return cmd_run(args, out, err);
    if (cmd == "train") return cmd_train(args, out, err);
    if (cmd == "explore") return cmd_explore(args, out, err);
    if (cmd == "select") return cmd_select(args, out, err);
    if (cmd == "finetune") return cmd_finetune(args, out, err);
    if (cmd == "eval") return cmd_eval(args, out, err);
    if (cmd == "bench") return cmd_bench(args, out, err);
    if (cmd == "--version") {
      out << "fillgs 0.1.0\n";
      return 0;
    }
    throw_error("fillgs: unknown command '", cmd, "' (see 'fillgs help')");
  } catch (const Error& e) {
    err << "error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    err << "error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    err << "error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace fillgs::cli
