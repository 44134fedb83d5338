// Does training learn motion? The synthetic scene trained from scratch on a camera set
// (all 16 ring cameras by default: dense views, where a 4D model must get the moving
// object right), once per training configuration, measured on the held-out cameras:
//  * PSNR of the whole image and of the moving region (ground truth's moving pixels),
//    pooled, and the moving-region PSNR per frame;
//  * tracking: at every frame, the distance from each ground-truth moving Gaussian to the
//    nearest model Gaussian that is visible then (opacity ≥ 0.1) — median over the moving
//    Gaussians, then mean and worst over frames; a model that leaves the object behind has
//    large distances at the frames where it moved;
//  * how many model Gaussians move, how many of them move with the object, densification;
//  * a picture per configuration: ground truth over model at five moments of one camera.
// Configurations are written as `label:key=value;key=value` (keys below), so one run prints
// the before/after rows of bench/results/README.md and any ablation.
#include <iostream>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/visibility/visibility.hpp"

using namespace fillgs;
using namespace fillgs::bench;

namespace {

struct MotionConfig {
  std::string label;
  TrainOptions options;
};

/// `label:key=value;...` on top of TrainOptions::scaled(iterations). Keys: motion (all |
/// promote), ramp (time_ramp), frontier (frontier_share), opacity (keyed opacity 0/1),
/// klr (key_lr_scale), sparsity, keys (key interval, frames), seed.
MotionConfig parse_config(const std::string& spec, int iterations) {
  MotionConfig c;
  c.options = TrainOptions::scaled(iterations);
  const size_t colon = spec.find(':');
  c.label = spec.substr(0, colon);
  if (c.label == "before") {  // the trainer as of commit 1cc6089
    c.options.motion = MotionLearning::Promote;
    c.options.keyed_opacity = false;
    c.options.time_ramp = 0;
    c.options.motion_sparsity = 0;
    c.options.key_lr_scale = 1;
    c.options.motion_where_images_change = false;
    c.options.flow_keys = false;
  }
  if (colon == std::string::npos) return c;
  std::stringstream ss(spec.substr(colon + 1));
  std::string kv;
  while (std::getline(ss, kv, ';')) {
    const size_t eq = kv.find('=');
    if (eq == std::string::npos) throw_error("bench motion: '", kv, "' is not key=value");
    const std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
    if (k == "motion") c.options.motion = parse_name<MotionLearning>(v);
    else if (k == "ramp") c.options.time_ramp = std::stod(v);
    else if (k == "frontier") c.options.frontier_share = std::stod(v);
    else if (k == "opacity") c.options.keyed_opacity = v != "0";
    else if (k == "klr") c.options.key_lr_scale = std::stod(v);
    else if (k == "sparsity") c.options.motion_sparsity = std::stod(v);
    else if (k == "keys") c.options.key_interval_frames = std::stoi(v);
    else if (k == "seed") c.options.seed = std::stoull(v);
    else if (k == "xmin") c.options.extrapolate_min_step = std::stod(v);
    else if (k == "freeze") c.options.freeze_distance = std::stod(v);
    else if (k == "agree") c.options.promote_agreement = std::stod(v);
    else if (k == "pgrad") c.options.promote_grad_scale = std::stod(v);
    else if (k == "change") c.options.motion_where_images_change = v != "0";
    else if (k == "flow") c.options.flow_keys = v != "0";
    else if (k == "flowc") c.options.flow_changing_only = v != "0";
    else if (k == "dafter") c.options.densify_after_ramp = std::stod(v);
    else throw_error("bench motion: unknown key '", k, "'");
  }
  return c;
}

struct MotionResult {
  double psnr = 0, psnr_moving = 0, extrap_psnr = 0, extrap_moving = 0;
  std::vector<double> moving_per_frame;  // interpolation cameras
  double track_mean = 0, track_worst = 0;
  double speed_on_object = 0;  // share of the summed speed on Gaussians that move with the object
  size_t gaussians = 0, dynamic = 0, dynamic_on_object = 0, promoted = 0;
  double seconds = 0;
};

/// Median over the truth's moving Gaussians of the distance to the nearest model Gaussian
/// visible (opacity ≥ 0.1) at time t; also marks model Gaussians within 5 cm of the object.
double tracking_error(const FrameGaussians& truth, const std::vector<uint32_t>& object, const FrameGaussians& model,
                      std::vector<uint8_t>* near_object) {
  Vec3f lo = Vec3f::Constant(1e30f), hi = -lo;
  for (uint32_t g : object) lo = lo.cwiseMin(truth.means[g]), hi = hi.cwiseMax(truth.means[g]);
  const float pad = 0.5f;
  std::vector<uint32_t> cand;
  for (uint32_t g = 0; g < model.size(); ++g)
    if (model.opacities[g] >= 0.1f && (model.means[g].array() >= (lo.array() - pad)).all() && (model.means[g].array() <= (hi.array() + pad)).all())
      cand.push_back(g);
  std::vector<float> d(object.size(), pad);
  for (size_t i = 0; i < object.size(); ++i) {
    float best = pad * pad;
    for (uint32_t g : cand) best = std::min(best, (model.means[g] - truth.means[object[i]]).squaredNorm());
    d[i] = std::sqrt(best);
  }
  if (near_object)
    for (uint32_t g : cand)
      for (uint32_t o : object)
        if ((model.means[g] - truth.means[o]).squaredNorm() < 0.05f * 0.05f) {
          (*near_object)[g] = 1;
          break;
        }
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

MotionResult measure(const SynthScene& s, const GaussianCloud& m, const Dataset& interp, const Dataset& extrap, const std::string& picture,
                     const std::string& camera) {
  MotionResult r;
  const int F = s.options.frames;
  EvalOptions eo;
  eo.truth = &s.scene;
  const SplitMetrics e = evaluate_split(m, extrap, "extrapolation", eo);
  r.extrap_psnr = e.psnr;
  r.extrap_moving = e.psnr_moving;
  // Interpolation: per frame moving-region error, pooled.
  std::vector<double> se(size_t(F), 0.0);
  std::vector<size_t> px(size_t(F), 0);
  FrameSampler ev(m);
  std::vector<std::vector<float>> truth_shots, model_shots;
  std::vector<std::string> truth_captions, model_captions;
  double psnr_sum = 0;
  for (size_t v = 0; v < interp.views().size(); ++v) {
    const TrainView& view = interp.views()[v];
    const RenderOutput out = render(ev.at(view.camera.time), view.camera);
    const std::vector<float> target = interp.image(v);
    psnr_sum += psnr(out.rgb.data(), target.data(), view.camera.width, view.camera.height, 3);
    const std::vector<unsigned char> mask = moving_region(s.scene, view.camera);
    for (size_t p = 0; p < mask.size(); ++p) {
      if (!mask[p]) continue;
      px[size_t(view.frame)] += 3;
      for (int c = 0; c < 3; ++c) {
        const double d = std::clamp(out.rgb[p * 3 + c], 0.0f, 1.0f) - target[p * 3 + c];
        se[size_t(view.frame)] += d * d;
      }
    }
    bool shown = false;  // five moments: frames (F−1)·k/6, k = 1..5
    for (int k = 1; k <= 5; ++k) shown |= view.frame == int(std::lround((F - 1) * k / 6.0));
    if (view.rig == camera && shown) {
      truth_shots.push_back(target);
      model_shots.push_back(out.rgb);
      truth_captions.push_back("truth, frame " + std::to_string(view.frame));
      model_captions.push_back("model, frame " + std::to_string(view.frame));
    }
  }
  r.psnr = psnr_sum / double(interp.views().size());
  double se_all = 0;
  size_t px_all = 0;
  for (int f = 0; f < F; ++f) {
    se_all += se[size_t(f)], px_all += px[size_t(f)];
    r.moving_per_frame.push_back(px[size_t(f)] ? 10.0 * std::log10(double(px[size_t(f)]) / std::max(se[size_t(f)], 1e-12)) : std::nan(""));
  }
  r.psnr_moving = px_all ? 10.0 * std::log10(double(px_all) / std::max(se_all, 1e-12)) : std::nan("");
  // Tracking over every frame.
  std::vector<uint8_t> near(m.size(), 0);
  FrameSampler truth(s.scene);
  for (int f = 0; f < F; ++f) {
    const double t = FrameGrid(F).time(f);
    const double d = tracking_error(truth.at(t), s.moving_ids, ev.at(t), &near);
    r.track_mean += d / F;
    r.track_worst = std::max(r.track_worst, d);
  }
  // The motion signal FillGS reads: the share of the model's summed speed (over Gaussians and
  // frames) carried by Gaussians that move with the object (within 5 cm of it at some frame).
  {
    double on = 0, all = 0;
    std::vector<float> speed;
    for (int f = 0; f < F; ++f) {
      dynamic_speeds(m, FrameGrid(F).time(f), FrameGrid(F).step(), speed);
      for (size_t j = 0; j < speed.size(); ++j) {
        all += speed[j];
        if (near[m.dynamic_ids[j]]) on += speed[j];
      }
    }
    r.speed_on_object = all > 0 ? on / all : 0.0;
  }
  r.gaussians = m.size();
  r.dynamic = m.dynamic_count();
  // How much the moving Gaussians that are not on the object change over their keys.
  if (m.motion == MotionModel::Keyframed && m.dynamic_count() > 0) {
    const KeyframedMotion& k = m.keyframed;
    const size_t K = size_t(k.key_count);
    std::vector<float> dp, dr, dop;
    for (size_t j = 0; j < m.dynamic_count(); ++j) {
      if (near[m.dynamic_ids[j]]) continue;
      Vec3f pm = Vec3f::Zero();
      for (size_t i = 0; i < K; ++i) pm += Eigen::Map<const Vec3f>(&k.positions[(j * K + i) * 3]) / float(K);
      float a = 0, b = 0, o = 0;
      float omin = 1e9f, omax = -1e9f;
      for (size_t i = 0; i < K; ++i) {
        a = std::max(a, (Eigen::Map<const Vec3f>(&k.positions[(j * K + i) * 3]) - pm).norm());
        const Vec4f q0 = normalize_quat(Eigen::Map<const Vec4f>(&k.rotations[j * K * 4])), q = normalize_quat(Eigen::Map<const Vec4f>(&k.rotations[(j * K + i) * 4]));
        b = std::max(b, float(2 * std::acos(std::min(1.0f, std::fabs(q.dot(q0)))) * 180 / kPi));
        if (!k.opacity_logits.empty()) omin = std::min(omin, k.opacity_logits[j * K + i]), omax = std::max(omax, k.opacity_logits[j * K + i]);
      }
      o = k.opacity_logits.empty() ? 0 : omax - omin;
      dp.push_back(a), dr.push_back(b), dop.push_back(o);
    }
    auto q = [](std::vector<float> v, double f) {
      if (v.empty()) return 0.0f;
      std::nth_element(v.begin(), v.begin() + size_t(f * (v.size() - 1)), v.end());
      return v[size_t(f * (v.size() - 1))];
    };
    std::fprintf(stderr, "off-object moving Gaussians: %zu; position deviation p10/50/90 %.4f %.4f %.4f m; rotation %.2f %.2f %.2f deg; opacity logit range %.3f %.3f %.3f\n",
                 dp.size(), q(dp, 0.1), q(dp, 0.5), q(dp, 0.9), q(dr, 0.1), q(dr, 0.5), q(dr, 0.9), q(dop, 0.1), q(dop, 0.5), q(dop, 0.9));
  }
  for (uint32_t g : m.dynamic_ids) r.dynamic_on_object += near[g];
  if (!truth_shots.empty() && !picture.empty()) {  // truth above, model below
    const size_t n = truth_shots.size();
    truth_shots.insert(truth_shots.end(), model_shots.begin(), model_shots.end());
    truth_captions.insert(truth_captions.end(), model_captions.begin(), model_captions.end());
    write_image_grid_png(picture, truth_shots, s.options.width, s.options.height, truth_captions, int(n), 2);
  }
  return r;
}

}  // namespace

int bench_motion(const std::vector<std::string>& args) {
  const ThreadLimit two_threads(2);  // the tables say "2 threads"
  bool smoke = false;
  std::string out = "bench/results/motion", rig = "ring", variant, cameras = "all", camera;
  int iterations = 2000, width = 160, height = 120, frames = 20;
  std::vector<std::string> specs;
  auto app = cli::make_parser("fillgs_bench motion", "motion learning: a 4D model trained on a rig, its moving region and tracking");
  cli::add_flag(*app, "--smoke", smoke, "64x48, 6 frames, 60 iterations (overrides the sizes)");
  cli::add_text(*app, "--out", out, "the folder for pictures and tables", "DIR");
  cli::add_text(*app, "--rig", rig, "the synthetic rig: " + join_names(synthetic_rigs()), "NAME");
  cli::add_text(*app, "--variant", variant, "the moving content (default: the rig's first)", "NAME");
  cli::add_text(*app, "--cameras", cameras, "training cameras: all, or names a,b", "A,B,..");
  cli::add_number(*app, "--iterations", iterations, "training iterations", cli::at_least(1));
  cli::add_number(*app, "--width", width, "image width", cli::at_least(8));
  cli::add_number(*app, "--height", height, "image height", cli::at_least(8));
  cli::add_number(*app, "--frames", frames, "frames of the video", cli::at_least(2));
  cli::add_text(*app, "--picture-camera", camera, "the camera of the pictures (default: chosen by the moving content)", "NAME");
  app->add_option("--config", specs, "a configuration label:k=v;.. (repeatable; default: before, after)")->type_name("SPEC")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  if (smoke) width = 64, height = 48, frames = 6, iterations = 60;
  if (specs.empty()) specs = {"before", "after"};
  SynthOptions so;
  so.rig = rig;
  so.variant = variant;
  so.width = width, so.height = height, so.frames = frames;
  if (smoke) so.spacing = 0.05;
  const std::string name = so.scene_name();
  const std::string dir = join_path(out, name + "_" + std::to_string(width) + "x" + std::to_string(height) + "_f" + std::to_string(frames));
  const SynthScene s = make_synthetic_scene(so);
  if (camera.empty()) camera = s.interpolation.empty() ? s.split.interpolation.front() : "interp05";
  if (!std::filesystem::exists(join_path(dir, "synth.json"))) write_synthetic_scene(s, dir, null_progress());
  DatasetOptions d;
  if (cameras != "all") {
    std::stringstream ss(cameras);
    std::string c;
    while (std::getline(ss, c, ',')) d.cameras.push_back(c);
  }
  const Dataset data = Dataset::load(dir, join_path(dir, "transforms_train.json"), d);
  const Dataset interp = Dataset::load(dir, join_path(dir, "transforms_interpolation.json"));
  const Dataset extrap = Dataset::load(dir, join_path(dir, "transforms_extrapolation.json"));
  const PointSet points = read_points(join_path(dir, "points.ply"));
  std::printf("\n## Motion learning: %s scene, %dx%d, %d frames, trained on %s cameras for %d iterations (2 threads)\n\n", name.c_str(), width,
              height, frames, cameras.c_str(), iterations);
  std::printf("| config | interp PSNR | moving | extrap PSNR | moving | tracking mean (m) | worst frame (m) | Gaussians | moving | with the object | speed on the object | promoted | s |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<std::pair<std::string, std::vector<double>>> per_frame;
  for (const std::string& spec : specs) {
    MotionConfig c = parse_config(spec, iterations);
    const auto t0 = Clock::now();
    Trainer t(data, init_from_points(points), c.options);
    t.run(iterations, null_progress());
    const double secs = seconds_since(t0);
    const GaussianCloud m = t.model();
    MotionResult r = measure(s, m, interp, extrap, join_path(out, "motion_" + name + "_" + c.label + ".png"), camera);
    r.seconds = secs;
    for (const DensifyRecord& rec : t.densify_log()) r.promoted += rec.promoted;
    std::fprintf(stderr, "%s: %zu frozen at the end of the ramp; keys placed by flow %zu of %zu\n", c.label.c_str(), t.frozen(),
                 t.flow_placed().first, t.flow_placed().second);
    std::printf("| %s | %.2f | %.2f | %.2f | %.2f | %.3f | %.3f | %zu | %zu | %zu | %.0f%% | %zu | %.0f |\n", c.label.c_str(), r.psnr, r.psnr_moving,
                r.extrap_psnr, r.extrap_moving, r.track_mean, r.track_worst, r.gaussians, r.dynamic, r.dynamic_on_object, 100 * r.speed_on_object,
                r.promoted, r.seconds);
    std::fflush(stdout);
    per_frame.emplace_back(c.label, r.moving_per_frame);
  }
  std::printf("\nMoving-region PSNR per frame (interpolation cameras):\n\n| config |");
  for (int f = 0; f < frames; ++f) std::printf(" %d |", f);
  std::printf("\n|---|");
  for (int f = 0; f < frames; ++f) std::printf("---|");
  std::printf("\n");
  for (const auto& [label, v] : per_frame) {
    std::printf("| %s |", label.c_str());
    for (double x : v) std::printf(" %.1f |", x);
    std::printf("\n");
  }
  return 0;
}
