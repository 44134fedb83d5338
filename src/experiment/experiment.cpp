#include "fillgs/method/strategies.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "experiment/experiment_text.hpp"
#include "fillgs/method/refiners.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/json_file.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <nlohmann/json.hpp>
#include <ostream>
#include <set>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/identity.hpp"
#include "fillgs/io/html_report.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace fillgs {

namespace {


json options_json(const ExperimentOptions& o) {
  return {{"rig", o.rig},
          {"variant", o.variant},
          {"seed", o.seed},
          {"width", o.width},
          {"height", o.height},
          {"frames", o.frames},
          {"train_cameras", o.train_cameras},
          {"interpolation_cameras", o.interpolation_cameras},
          {"extrapolation_cameras", o.extrapolation_cameras},
          {"backbone_iterations", o.backbone_iterations}};
}

/// Every frame of the named cameras (looked up in the scene's rigs), for a Dataset.
std::vector<Camera> split_cameras(const SynthScene& s, const std::vector<std::string>& names) {
  std::vector<Camera> rig;
  for (const std::string& n : names) {
    const Camera* found = s.camera(n);
    if (!found) throw_error("experiment: no camera named ", n, " in the synthetic scene");
    rig.push_back(*found);
  }
  return cameras_over_time(rig, s.options.frames);
}

std::unique_ptr<Dataset> load_split(const std::string& dir, const std::string& scene_dir, const SynthScene& s, const std::string& name,
                                    const std::vector<std::string>& cameras) {
  const std::string path = join_path(dir, "split_" + name + ".json");
  write_transforms_json(path, split_cameras(s, cameras));
  return std::make_unique<Dataset>(Dataset::load(scene_dir, path));
}

json metrics_json(const SplitMetrics& m) {
  auto num = [](double x) { return std::isfinite(x) ? json(x) : json(nullptr); };
  return {{"views", m.views},         {"psnr", num(m.psnr)}, {"ssim", num(m.ssim)}, {"psnr_moving", num(m.psnr_moving)},
          {"moving_pixels", m.moving_pixels}, {"lpips", num(m.lpips)}, {"seconds", m.seconds}};
}
SplitMetrics metrics_from(const json& j, const std::string& split) {
  auto num = [](const json& v) { return v.is_null() ? std::nan("") : v.get<double>(); };
  SplitMetrics m;
  m.split = split;
  m.views = j.at("views").get<size_t>();
  m.psnr = num(j.at("psnr"));
  m.ssim = num(j.at("ssim"));
  m.psnr_moving = num(j.at("psnr_moving"));
  m.moving_pixels = j.at("moving_pixels").get<size_t>();
  m.lpips = num(j.at("lpips"));
  m.seconds = j.at("seconds").get<double>();
  return m;
}

json result_json(const RunResult& r) {
  return {{"id", r.id},
          {"group", to_string(r.group)},
          {"variant", r.variant},
          {"seed", r.seed},
          {"interpolation", metrics_json(r.interpolation)},
          {"extrapolation", metrics_json(r.extrapolation)},
          {"train", metrics_json(r.train)},
          {"trajectories", r.trajectories},
          {"views_added", r.views_added},
          {"mean_weight", r.mean_weight},
          {"support", r.support},
          {"support_share", r.support_share},
          {"refine_failures", r.refine_failures},
          {"seconds",
           {{"select", r.seconds_select},
            {"refine", r.seconds_refine},
            {"weights", r.seconds_weights},
            {"train", r.seconds_train},
            {"eval", r.seconds_eval},
            {"total", r.seconds_total}}}};
}

RunResult result_from(const json& j) {
  RunResult r;
  r.id = j.at("id");
  r.group = parse_name<ConfigGroup>(j.at("group").get<std::string>());
  r.variant = j.at("variant");
  r.seed = j.at("seed");
  r.interpolation = metrics_from(j.at("interpolation"), "interpolation");
  r.extrapolation = metrics_from(j.at("extrapolation"), "extrapolation");
  r.train = metrics_from(j.at("train"), "train");
  r.trajectories = j.at("trajectories");
  r.views_added = j.at("views_added");
  r.mean_weight = j.at("mean_weight");
  r.support = j.value("support", "");
  r.support_share = j.value("support_share", 0.0);
  r.refine_failures = j.at("refine_failures");
  const json& s = j.at("seconds");
  r.seconds_select = s.at("select");
  r.seconds_refine = s.at("refine");
  r.seconds_weights = s.at("weights");
  r.seconds_train = s.at("train");
  r.seconds_eval = s.at("eval");
  r.seconds_total = s.at("total");
  return r;
}

using detail::fmt;

/// The backbone: trained from the scene's points on `data` for the experiment's iterations.
/// How a backbone (and the upper.dense model) is trained.
TrainOptions backbone_train_options(const ExperimentOptions& o) {
  TrainOptions to = TrainOptions::scaled(o.backbone_iterations);
  to.seed = o.seed;
  return to;
}

GaussianCloud train_backbone(const Dataset& data, const std::string& points, const ExperimentOptions& o, Progress& progress) {
  Trainer trainer(data, init_from_points(read_points(points)), backbone_train_options(o));
  trainer.run(o.backbone_iterations, progress);
  return trainer.model();
}

}  // namespace

void save_result(const std::string& path, const RunResult& r) { write_file_atomically(path, result_json(r).dump(1) + "\n"); }

RunResult load_result(const std::string& path) {
  try {
    return result_from(read_json_file(path));
  } catch (const json::exception& e) {
    throw_error(path, ": not a fillgs result (", e.what(), ")");
  }
}

RunResult load_result(const std::string& path, const std::string& id, uint64_t seed, const std::string& scene) {
  RunResult r = load_result(path);
  if (!scene.empty() && r.variant != scene)
    throw_error(path, ": holds the result of scene '", r.variant, "', not of scene '", scene, "'; delete it to run ", id, " again");
  if (r.id != id)
    throw_error(path, ": holds run '", r.id, "', not '", id, "' whose folder it is in (a copied or moved record); delete it to run ", id, " again");
  if (seed > 0 && r.seed != seed) throw_error(path, ": holds seed ", r.seed, "'s result, not seed ", seed, "'s; delete it to run ", id, " again");
  return r;
}

namespace {

/// Runs of one scene and seed in the order of standard_configs (backbone first, then by id).
void sort_by_configuration(std::vector<RunResult>::iterator first, std::vector<RunResult>::iterator last) {
  std::vector<std::string> order = {"backbone"};
  for (const RunConfig& c : standard_configs(Weighting::ExploreGS, 0.5, bench_refiners())) order.push_back(c.id);
  std::unordered_map<std::string, size_t> ranks;  // first place of each id; others after every listed one
  for (size_t k = 0; k < order.size(); ++k) ranks.emplace(order[k], k);
  auto rank = [&](const std::string& id) {
    const auto it = ranks.find(id);
    return it == ranks.end() ? order.size() : it->second;
  };
  std::stable_sort(first, last, [&](const RunResult& a, const RunResult& b) { return rank(a.id) != rank(b.id) ? rank(a.id) < rank(b.id) : a.id < b.id; });
}

}  // namespace

std::vector<RunResult> collect_results(const std::string& root) {
  if (!fs::is_directory(root)) return {};
  std::vector<fs::path> scenes;
  for (const auto& e : fs::directory_iterator(root))
    if (e.is_directory() && fs::exists(e.path() / "options.json")) scenes.push_back(e.path());
  std::sort(scenes.begin(), scenes.end());
  std::vector<RunResult> out;
  for (const fs::path& sc : scenes) {
    std::vector<RunResult> rs;
    if (fs::exists(sc / "backbone" / "result.json")) rs.push_back(load_result((sc / "backbone" / "result.json").string(), "backbone"));
    if (fs::is_directory(sc / "runs"))
      for (const auto& e : fs::directory_iterator(sc / "runs"))
        if (fs::exists(e.path() / "result.json")) rs.push_back(load_result((e.path() / "result.json").string(), e.path().filename().string()));
    sort_by_configuration(rs.begin(), rs.end());
    out.insert(out.end(), rs.begin(), rs.end());
  }
  return out;
}

namespace {

using detail::csv_cells;

}  // namespace

std::vector<RunResult> read_results_csv(const std::string& path) {
  const std::string text = read_file(path);
  std::istringstream in(text);
  std::string line;
  // The header before the reference refiner named the column "support", its values the
  // oracle's support: observed (now "oracle") or full ("oracle-full").
  std::string old_header = kResultsCsvHeader;
  old_header.replace(old_header.find(",refiner,"), 9, ",support,");
  bool old_names = false;
  if (!std::getline(in, line) || (line != kResultsCsvHeader && !(old_names = line == old_header)))
    throw_error(path, ": not a fillgs bench results.csv (the first line must be the header '", kResultsCsvHeader, "')");
  constexpr size_t kColumns = 23;
  std::vector<RunResult> out;
  for (size_t row = 2; std::getline(in, line); ++row) {
    if (line.empty()) continue;
    const std::vector<std::string> f = csv_cells(line);
    if (f.size() != kColumns) throw_error(path, ": line ", row, " has ", f.size(), " columns, the header ", kColumns);
    if (f[0].empty() || f[2].empty()) throw_error(path, ": line ", row, ": empty scene or id");
    const std::string where = "line " + std::to_string(row);
    auto num = [&](size_t k) {
      // The writer prints a missing metric (no moving pixels) as nan.
      if (f[k] == "nan" || f[k] == "-nan") return std::nan("");
      double x = 0;
      if (!parse_number(f[k], &x)) throw_error(path, ": ", where, " column ", k + 1, ": '", f[k], "' is not a number");
      return x;
    };
    // A count read into an int holds at most INT_MAX: 3e9 trajectories is refused, not
    // wrapped to a negative number.
    auto count = [&](size_t k, double max = 9.0e15) {
      const double x = num(k);
      if (!(x >= 0 && x == std::floor(x) && x <= max))
        throw_error(path, ": ", where, " column ", k + 1, ": '", f[k], "' is not a count in [0, ", max, "]");
      return x;
    };
    constexpr double kIntMax = 2147483647.0;
    RunResult r;
    r.variant = f[0];
    r.seed = uint64_t(count(1));
    r.id = f[2];
    try {
      r.group = parse_name<ConfigGroup>(f[3]);
    } catch (const Error& e) {
      throw_error(path, ": ", where, " column 4: ", e.what());
    }
    r.support = f[4];
    if (old_names && r.support == "observed") r.support = "oracle";
    if (old_names && r.support == "full") r.support = "oracle-full";
    r.interpolation.split = "interpolation", r.extrapolation.split = "extrapolation", r.train.split = "train";
    r.interpolation.psnr = num(5), r.interpolation.ssim = num(6), r.interpolation.psnr_moving = num(7);
    r.extrapolation.psnr = num(8), r.extrapolation.ssim = num(9), r.extrapolation.psnr_moving = num(10);
    r.train.psnr = num(11);
    r.trajectories = int(count(12, kIntMax));
    r.views_added = size_t(count(13));
    r.mean_weight = num(14), r.support_share = num(15);
    r.refine_failures = int(count(16, kIntMax));
    r.seconds_select = num(17), r.seconds_refine = num(18), r.seconds_weights = num(19), r.seconds_train = num(20), r.seconds_eval = num(21),
    r.seconds_total = num(22);
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<RunResult> merge_results(const std::vector<std::string>& inputs) {
  struct Found {
    RunResult result;
    std::string source;
  };
  std::vector<Found> all;
  for (const std::string& in : inputs) {
    if (!fs::exists(in)) throw_error(in, ": no such bench folder or results.csv");
    const std::vector<RunResult> rs = fs::is_directory(in) ? collect_results(in) : read_results_csv(in);
    if (rs.empty()) throw_error(in, ": holds no finished run");
    for (const RunResult& r : rs) all.push_back({r, in});
  }
  // A run found twice must be the same run: equal to the CSV's 6 significant digits.
  auto same = [](double a, double b) { return (std::isnan(a) && std::isnan(b)) || std::abs(a - b) <= 1e-5 * std::max(1.0, std::abs(a)); };
  std::vector<RunResult> out;
  std::vector<std::string> sources;
  std::map<std::tuple<std::string, uint64_t, std::string>, size_t> index;  // (variant, seed, id) -> row: linear in rows, not quadratic
  for (const Found& f : all) {
    const RunResult& r = f.result;
    const auto [slot, fresh] = index.emplace(std::make_tuple(r.variant, r.seed, r.id), out.size());
    if (fresh) {
      out.push_back(r);
      sources.push_back(f.source);
      continue;
    }
    const auto it = out.begin() + ptrdiff_t(slot->second);
    const std::pair<double, double> metrics[] = {{it->interpolation.psnr, r.interpolation.psnr},
                                                 {it->interpolation.psnr_moving, r.interpolation.psnr_moving},
                                                 {it->extrapolation.psnr, r.extrapolation.psnr},
                                                 {it->extrapolation.psnr_moving, r.extrapolation.psnr_moving},
                                                 {it->train.psnr, r.train.psnr},
                                                 {it->mean_weight, r.mean_weight}};
    for (const auto& [a, b] : metrics)
      if (!same(a, b))
        throw_error(sources[size_t(it - out.begin())], " and ", f.source, " disagree on ", r.variant, " seed ", r.seed, " ", r.id, " (", a, " against ",
                    b, "): two different runs under one name");
  }
  std::stable_sort(out.begin(), out.end(), [](const RunResult& a, const RunResult& b) { return a.variant != b.variant ? a.variant < b.variant : a.seed < b.seed; });
  for (auto first = out.begin(); first != out.end();) {
    auto last = std::find_if(first, out.end(), [&](const RunResult& x) { return x.variant != first->variant || x.seed != first->seed; });
    sort_by_configuration(first, last);
    first = last;
  }
  return out;
}

SceneChoice parse_scene(const std::string& name) {
  const std::vector<std::string> scenes = bench_scenes(), ring = synthetic_variants("ring");
  if (!std::count(scenes.begin(), scenes.end(), name)) throw_error("unknown scene \"", name, "\" (", join_names(scenes), ")");
  return std::count(ring.begin(), ring.end(), name) ? SceneChoice{"ring", name} : SceneChoice{name, ""};
}

std::vector<std::string> bench_scenes() {
  // The rigs of the kitchen by name, then the ring's variants (synthetic_rigs / synthetic_variants).
  std::vector<std::string> names;
  for (const std::string& rig : synthetic_rigs())
    if (rig != "ring") names.push_back(rig);
  for (const std::string& v : synthetic_variants("ring")) names.push_back(v);
  return names;
}

std::string ExperimentOptions::scene_name() const {
  SynthOptions so;
  so.rig = rig;
  so.variant = variant;
  return so.scene_name();
}

ExperimentOptions ExperimentOptions::resolved() const {
  ExperimentOptions o = *this;
  SynthOptions so;
  so.rig = rig;
  so.variant = variant;
  o.variant = so.resolved_variant();
  if (o.width <= 0 || o.height <= 0) {
    if (rig == "technicolor") o.width = 192, o.height = 102;  // 2048×1088 aspect
    else o.width = 160, o.height = 120;
  }
  return o;
}

std::string PreparedScene::scene_dir() const { return join_path(dir, "scene"); }

PreparedScene prepare_scene(const std::string& root, const ExperimentOptions& options, Progress& progress, std::ostream& log,
                            bool with_backbone) {
  PreparedScene p;
  ExperimentOptions o = options.resolved();
  SynthOptions so;
  so.rig = o.rig;
  so.variant = o.variant;
  so.seed = o.seed;
  so.width = o.width;
  so.height = o.height;
  so.frames = o.frames;
  auto t0 = Clock::now();
  p.synth = make_synthetic_scene(so);
  if (o.train_cameras.empty()) o.train_cameras = p.synth.split.train;
  if (o.interpolation_cameras.empty()) o.interpolation_cameras = p.synth.split.interpolation;
  if (o.extrapolation_cameras.empty()) o.extrapolation_cameras = p.synth.split.extrapolation;
  p.options = o;
  p.dir = join_path(root, o.scene_name() + "_s" + std::to_string(o.seed));
  const std::string scene_dir = p.scene_dir(), stamp_path = join_path(p.dir, "options.json");
  // The scene's and the backbone's identity: every option that decides them.
  json stamp = options_json(o);
  stamp["backbone_train"] = identity_json(backbone_train_options(o));
  if (fs::exists(stamp_path)) {
    const std::string diff = identity_difference(read_json_file(stamp_path), stamp);
    if (!diff.empty())
      throw_error(stamp_path, ": this folder holds a scene and backbone made with other options (", diff, "); use another --out");
  }
  make_directories(p.dir);
  p.reused_scene = fs::exists(join_path(scene_dir, "synth.json")) && fs::exists(stamp_path);
  if (!p.reused_scene) {
    write_synthetic_scene(p.synth, scene_dir, progress);
    write_file_atomically(stamp_path, stamp.dump(1) + "\n");
    p.seconds_synth = seconds_since(t0);
    log << "scene " << o.scene_name() << " (seed " << o.seed << "): " << p.synth.scene.size() << " Gaussians, " << p.synth.scene.dynamic_count()
        << " moving, " << o.width << "x" << o.height << ", " << o.frames << " frames, rendered in " << fmt(p.seconds_synth, 1) << " s" << std::endl;
  }
  DatasetOptions dopt;
  dopt.cameras = o.train_cameras;
  p.train = std::make_unique<Dataset>(Dataset::load(scene_dir, join_path(scene_dir, "transforms_train.json"), dopt));
  p.interpolation = load_split(p.dir, scene_dir, p.synth, "interpolation", o.interpolation_cameras);
  p.extrapolation = load_split(p.dir, scene_dir, p.synth, "extrapolation", o.extrapolation_cameras);

  if (with_backbone) ensure_backbone(p, progress, log);
  return p;
}

std::string PreparedScene::result_path(const std::string& config_id) const {
  return join_path(join_path(join_path(dir, "runs"), config_id), "result.json");
}

void ensure_backbone(PreparedScene& p, Progress& progress, std::ostream& log) {
  if (p.has_backbone) return;
  const ExperimentOptions& o = p.options;
  const std::string bb = join_path(p.dir, "backbone");
  const std::string model_path = join_path(bb, "model.ply");
  const std::string summary_path = join_path(bb, "summary.json");
  if (fs::exists(model_path)) {
    p.backbone = read_scene(model_path);
    p.has_backbone = p.reused_backbone = true;
    if (fs::exists(summary_path)) {
      json record = read_json_object(summary_path);
      const std::string fingerprint = fnv1a64_hex(read_file(model_path));
      if (!record.contains("model_fnv1a64")) {
        record["model_fnv1a64"] = fingerprint;
        write_file_atomically(summary_path, record.dump(1) + "\n");
      } else if (record["model_fnv1a64"] != fingerprint) {
        throw_error(model_path, ": not the backbone ", summary_path, " names (model_fnv1a64 ", record["model_fnv1a64"].dump(), ", the file's \"",
                    fingerprint, "\"); use another --out, or delete ", p.dir, " to run the seed again");
      }
    }
    log << "backbone reused: " << model_path << "\n";
    return;
  }
  const auto t0 = Clock::now();
  const std::string scene_dir = p.scene_dir();
  p.backbone = train_backbone(*p.train, join_path(scene_dir, "points.ply"), o, progress);
  p.seconds_backbone = seconds_since(t0);
  make_directories(bb);
  // Written beside the model first: a backbone trained again is kept only if it is the one
  // the seed's record (summary.json, which git keeps) names.
  const std::string fresh_path = join_path(bb, "model.again.ply");
  write_fillgs_ply(fresh_path, p.backbone, o.frames);
  const json summary = {{"iterations", o.backbone_iterations},
                        {"seconds", p.seconds_backbone},
                        {"gaussians", p.backbone.size()},
                        {"moving_gaussians", p.backbone.dynamic_count()},
                        {"model_fnv1a64", fnv1a64_hex(read_file(fresh_path))},
                        {"train_cameras", o.train_cameras}};
  if (fs::exists(summary_path)) {
    // The seed's backbone was made before (its runs may be finished): the same options give
    // the same model on the same kind of machine, but another SIMD target (AVX2 against
    // AVX-512) rounds otherwise and trains another backbone, whose runs would not pair.
    const json before = read_json_object(summary_path);
    std::string differs;
    for (const char* key : {"model_fnv1a64", "gaussians", "moving_gaussians"})
      if (before.contains(key) && before[key] != summary[key]) {
        differs = std::string(key) + " " + before[key].dump() + " there, " + summary[key].dump() + " now";
        break;
      }
    if (!differs.empty()) {
      fs::remove(fresh_path);
      throw_error(summary_path, ": the backbone trained again is not the one this seed was made with (", differs,
                  "; a machine with another SIMD target trains another); use another --out, or delete ", p.dir, " to run the seed again");
    }
    log << "backbone trained again: the model " << summary_path << " names\n";
  }
  fs::rename(fresh_path, model_path);
  if (!fs::exists(summary_path)) {
    write_file_atomically(summary_path, summary.dump(1) + "\n");
  } else {
    // A seed recorded before the fingerprint keeps its record (its seconds) and gains it.
    json before = read_json_object(summary_path);
    if (!before.contains("model_fnv1a64")) {
      before["model_fnv1a64"] = summary["model_fnv1a64"];
      write_file_atomically(summary_path, before.dump(1) + "\n");
    }
  }
  log << "backbone: " << o.backbone_iterations << " iterations on " << p.train->views().size() << " views ("
      << p.train->rigs().size() << " cameras) in " << fmt(p.seconds_backbone, 1) << " s, " << p.backbone.size() << " Gaussians ("
      << p.backbone.dynamic_count() << " moving)" << std::endl;
  p.has_backbone = true;
}

ReferenceOptions bench_reference_options(double artifact_strength, uint64_t seed) {
  // The calibration (bench/results/README.md, "Calibrating the refiner"), set on the n3v
  // scene from the unweighted random views against the control, seeds 1-3, before any
  // other strategy ran with this refiner, and never changed afterwards: the fill is the
  // render unblurred (a blurred fill regularised the model: +1.4 dB on seed 1), no
  // hallucinated texture (it raised the gain further), θ0 = 10° as first set.
  ReferenceOptions o;
  o.angle_scale_degrees = 10.0;
  o.shift_per_degree = 0.001;
  o.blur_per_degree = 0.0005;
  o.flicker = 0.05;
  o.fill_strength = 0.5;
  o.fill_blur = 0.0;
  o.hallucination = 0.0;
  o.placement_tolerance = 0.1;
  o.artifacts.strength = artifact_strength;
  o.artifacts.seed = seed;
  return o;
}

std::vector<std::string> bench_refiners() {
  std::vector<std::string> out;
  for (const RefinerKind* k : refiner_kinds())
    if (k->benchmark) out.push_back(k->name);
  return out;
}

std::string bench_refiner(const std::string& name) {
  for (const std::string& n : bench_refiners())
    if (n == name) return n;
  throw_error("unknown bench refiner '", name.substr(0, 40), "' (expected ", refiner_names(true), ")");
}

std::vector<RunConfig> standard_configs(Weighting baseline_weighting, double strength, const std::vector<std::string>& refiners) {
  std::vector<RunConfig> out;
  {
    RunConfig c;  // the control has no generated views: one row whatever the refiners
    c.id = "no-refinement";
    c.group = ConfigGroup::Control;
    c.weighting = Weighting::None;
    c.trajectories = 0;
    c.refiner = refiners.empty() ? "reference" : bench_refiner(refiners.front());
    out.push_back(c);
  }
  for (size_t ri = 0; ri < refiners.size(); ++ri) {
    const std::string refiner = bench_refiner(refiners[ri]);
    const std::string suffix = ri == 0 ? "" : "@" + refiner;
    auto add = [&](const std::string& id, ConfigGroup group, const std::string& s, Weighting w, double a, int k) {
      RunConfig c;
      c.id = id + suffix;
      c.group = group;
      c.select.strategy = s;
      c.weighting = w;
      c.artifact_strength = a;
      c.trajectories = k;
      c.refiner = refiner;
      out.push_back(c);
      return &out.back();
    };
    // The paper's strategy carries FillGS's weights; the baselines the baseline weighting.
    auto weighting_of = [&](const StrategyRow& r) { return r.method ? Weighting::FillGS : baseline_weighting; };
    add("random.w-none", ConfigGroup::Calibration, "random", Weighting::None, strength, 5);
    for (const StrategyRow* r : strategy_table().rows()) add(r->name, ConfigGroup::Strategy, r->name, weighting_of(*r), strength, 5);
    const char* ablations[] = {"no-start-selection", "no-error-term", "no-sensitivity-term", "no-candidate-scoring",
                               "no-global",          "count-only",    "speed-only"};
    for (const char* a : ablations) {
      RunConfig* c = add(std::string("fillgs.") + a, ConfigGroup::Ablation, "fillgs", Weighting::FillGS, strength, 5);
      const std::string n = a;
      c->select.no_start_selection = n == "no-start-selection";
      c->select.no_error_term = n == "no-error-term";
      c->select.no_sensitivity_term = n == "no-sensitivity-term";
      c->select.no_candidate_scoring = n == "no-candidate-scoring";
      c->select.no_global = n == "no-global";
      if (n == "count-only") c->select.score = CandidateScore::CountOnly;
      if (n == "speed-only") c->select.score = CandidateScore::SpeedOnly;
    }
    // Table 3's "other selection strategy" rows: each strategy's views with FillGS's fine-tuning and weights.
    for (const StrategyRow* r : strategy_table().rows())
      if (!r->method) add(r->name + ".w-fillgs", ConfigGroup::Selection, r->name, Weighting::FillGS, strength, 5);
    for (Weighting w : {Weighting::None, Weighting::NoConsistency, Weighting::NoCovisibility, Weighting::Enhancer3DGS, Weighting::ExploreGS,
                        Weighting::UA4DGS})
      add(std::string("fillgs.w-") + to_string(w), ConfigGroup::Weighting, "fillgs", w, strength, 5);
    // fillgs's own options beyond the paper: the weights' D̂ scaled over every moving Gaussian
    // of every frame (the earlier rule), the weighted loss normalised by the view's mean
    // weight, model-independent sweep matching, co-visibility rules that weigh static content
    // by its observation density (static-count, density).
    add("fillgs.covis-global", ConfigGroup::Weighting, "fillgs", Weighting::FillGS, strength, 5)->mask.scale = CovisibilityScale::Global;
    add("fillgs.normalised", ConfigGroup::Weighting, "fillgs", Weighting::FillGS, strength, 5)->mask.normalise = true;
    add("fillgs.m-sweep", ConfigGroup::Weighting, "fillgs", Weighting::FillGS, strength, 5)->mask.method = MaskMethod::Sweep;
    add("fillgs.covis-static-count", ConfigGroup::Weighting, "fillgs", Weighting::FillGS, strength, 5)->mask.covisibility =
        Covisibility::StaticCount;
    add("fillgs.covis-density", ConfigGroup::Weighting, "fillgs", Weighting::FillGS, strength, 5)->mask.covisibility = Covisibility::Density;
    {
      RunConfig* c = add("fillgs.sweep+static-count", ConfigGroup::Weighting, "fillgs", Weighting::FillGS, strength, 5);
      c->mask.method = MaskMethod::Sweep;
      c->mask.covisibility = Covisibility::StaticCount;
    }
    // fillgs's option beyond the paper: starts of one round whose patches do not overlap on
    // a camera; with FillGS's weights and with none (to see the views without the weights).
    add("fillgs.spread-starts", ConfigGroup::Ablation, "fillgs", Weighting::FillGS, strength, 5)->select.spread_starts = true;
    add("fillgs.w-none.spread-starts", ConfigGroup::Weighting, "fillgs", Weighting::None, strength, 5)->select.spread_starts = true;
    // ... and candidates scored by the D̂ they see (sum over their visible set), unweighted.
    add("fillgs.w-none.gain-score", ConfigGroup::Weighting, "fillgs", Weighting::None, strength, 5)->select.score_gain = true;
    {
      RunConfig* c = add("fillgs.w-none.spread+gain", ConfigGroup::Weighting, "fillgs", Weighting::None, strength, 5);
      c->select.spread_starts = true;
      c->select.score_gain = true;
    }
    // The score alone: FillGS's candidate score and coverage4d's, both unweighted from the
    // same shuffled starts (no start selection; the same seed shuffles the same way).
    {
      RunConfig* c = add("fillgs.w-none.no-start-selection", ConfigGroup::Ablation, "fillgs", Weighting::None, strength, 5);
      c->select.no_start_selection = true;
      add("coverage4d.w-none", ConfigGroup::Ablation, "coverage4d", Weighting::None, strength, 5);
    }
    // Table 1 with one weighting: every strategy's views unweighted, so that only the selection
    // differs (random's, FillGS's and coverage4d's unweighted rows are above).
    for (const char* s : {"negative", "interpolation", "fisherrf", "coverage3d"})
      add(std::string(s) + ".w-none", ConfigGroup::Unweighted, s, Weighting::None, strength, 5);
    // The exploration space as the paper masks it: occupied voxels only, no "unexplored" label.
    add("fillgs.occupied-only", ConfigGroup::Ablation, "fillgs", Weighting::FillGS, strength, 5)->grid.label_unexplored = false;
    for (int k : {1, 10, 20}) add("fillgs.k" + std::to_string(k), ConfigGroup::Budget, "fillgs", Weighting::FillGS, strength, k);
    for (const StrategyRow* r : strategy_table().rows()) add(r->name + ".clean", ConfigGroup::Refiner, r->name, weighting_of(*r), 0.0, 5);
  }
  RunConfig tv;
  tv.id = "upper.test-views";
  tv.group = ConfigGroup::Upper;
  tv.kind = RunKind::TestViews;
  tv.weighting = Weighting::None;
  tv.artifact_strength = 0;
  tv.trajectories = 0;
  out.push_back(tv);
  RunConfig dense = tv;
  dense.id = "upper.dense";
  dense.kind = RunKind::Dense;
  out.push_back(dense);
  return out;
}

RunResult evaluate_model(const PreparedScene& p, const GaussianCloud& model, const std::string& id, const std::string& save_dir,
                         Progress& progress) {
  const auto t0 = Clock::now();
  RunResult r;
  r.id = id;
  r.variant = p.options.scene_name();
  r.seed = p.options.seed;
  EvalOptions eo;
  eo.truth = &p.synth.scene;
  eo.save_dir = save_dir.empty() ? "" : join_path(save_dir, "interpolation");
  r.interpolation = evaluate_split(model, *p.interpolation, "interpolation", eo, progress);
  eo.save_dir = save_dir.empty() ? "" : join_path(save_dir, "extrapolation");
  r.extrapolation = evaluate_split(model, *p.extrapolation, "extrapolation", eo, progress);
  eo.save_dir.clear();
  r.train = evaluate_split(model, *p.train, "train", eo, progress);
  r.seconds_eval = seconds_since(t0);
  return r;
}

std::vector<RunConfig> choose_configs(const std::vector<RunConfig>& all, const std::vector<ConfigGroup>& groups,
                                      const std::vector<std::string>& ids, bool smoke) {
  std::vector<RunConfig> chosen;
  for (const RunConfig& c : all) {
    const bool by_group = groups.empty() || std::count(groups.begin(), groups.end(), c.group);
    const bool by_id = ids.empty() || std::count(ids.begin(), ids.end(), c.id);
    const bool in_smoke = c.group == ConfigGroup::Control || c.group == ConfigGroup::Calibration || c.group == ConfigGroup::Strategy ||
                          c.group == ConfigGroup::Upper;
    if (by_group && by_id && (!smoke || in_smoke)) chosen.push_back(c);
  }
  if (chosen.empty()) throw_error("--only/--configs select no configuration");
  return chosen;
}

std::vector<RunResult> run_bench_plan(const BenchPlan& plan, Progress& progress, std::ostream& log) {
  for (const std::string& sc : plan.scenes) parse_scene(sc);  // unknown names fail before any work
  make_directories(plan.root);
  remove_stale_temporaries(plan.root);  // a chart's PNG or log a killed bench left
  std::vector<RunResult> results;
  log << "fillgs bench: " << plan.scenes.size() << " scene(s) x " << plan.seeds.size() << " seed(s) x " << plan.configs.size()
      << " configurations -> " << plan.root << " (resumable: finished runs are reused)\n";
  for (const std::string& sc : plan.scenes)
    for (uint64_t seed : plan.seeds) {
      ExperimentOptions eo = plan.scene;
      const SceneChoice choice = parse_scene(sc);
      eo.rig = choice.rig;
      eo.variant = choice.variant;
      eo.seed = seed;
      // The backbone is read or trained only where something still needs it: a seed whose
      // runs are all finished trains none.
      PreparedScene p = prepare_scene(plan.root, eo, progress, log, false);
      const std::string bb_path = join_path(join_path(p.dir, "backbone"), "result.json");
      // A run still to make that fine-tunes the backbone (the dense model trains its own).
      const auto needs_backbone = [&](const RunConfig& c) { return c.kind != RunKind::Dense && !fs::exists(p.result_path(c.id)); };
      const bool all_finished = std::none_of(plan.configs.begin(), plan.configs.end(), needs_backbone);
      RunResult bb;
      if (fs::exists(bb_path)) {
        bb = load_result(bb_path, "backbone", seed, eo.scene_name());
      } else if (!all_finished) {
        ensure_backbone(p, progress, log);
        bb = evaluate_model(p, p.backbone, "backbone", "", progress);
        bb.group = ConfigGroup::Control;
        save_result(bb_path, bb);
      }
      if (fs::exists(bb_path)) {
        char line[200];
        std::snprintf(line, sizeof line, " backbone: interpolation %.2f dB, extrapolation %.2f dB, train %.2f dB\n", bb.interpolation.psnr,
                      bb.extrapolation.psnr, bb.train.psnr);
        log << sc << " seed " << seed << line;
      } else
        log << sc << " seed " << seed << ": every run is finished and the backbone's own row was not kept; it is not trained again for it\n";
      for (const RunConfig& c : plan.configs) {
        if (needs_backbone(c)) ensure_backbone(p, progress, log);
        results.push_back(run_config(p, c, plan.finetune, progress, log));
        // After every run, over everything the folder holds (earlier invocations included):
        // an interrupted bench still has its tables.
        write_bench_report(plan.root, collect_results(plan.root));
      }
    }
  write_bench_report(plan.root, collect_results(plan.root));
  return results;
}

RunResult run_config(const PreparedScene& p, const RunConfig& c, const FinetuneOptions& base, Progress& progress, std::ostream& log) {
  const std::string dir = join_path(join_path(p.dir, "runs"), c.id);
  const std::string result_path = p.result_path(c.id), identity_path = join_path(dir, "identity.json");
  const int F = p.options.frames;
  // What the run does, all of it decided before anything runs: its identity is every option
  // among these (and the scene's, options.json), so a folder is reused only for the same run.
  FinetuneOptions fo = base;
  // The configuration picks the strategy and its ablations; the bench's own knobs (seed,
  // --time-stride) come from `base`.
  fo.select = c.select;
  fo.select.seed = base.select.seed;
  fo.select.time_stride = base.select.time_stride;
  fo.trajectories = c.trajectories;
  fo.weighting = c.weighting;
  fo.mask = c.mask;
  fo.grid.label_unexplored = c.grid.label_unexplored;  // the one exploration option a configuration sets
  fo.work_dir = join_path(dir, "work");
  size_t test_views = 0;
  if (c.kind == RunKind::TestViews) {
    // Clean ground truth at every test camera and frame, weight 1, drawn as often as the
    // real views (with the generated views' 30% share each of the 260 n3v test views was
    // drawn 1.4 times in 1,200 iterations, and the bound measured the budget, not the views).
    test_views = p.interpolation->views().size() + p.extrapolation->views().size();
    fo.train.refined_share = double(test_views) / (double(test_views) + double(p.train->views().size()));
  }
  const bool generated = c.kind == RunKind::Finetune && c.trajectories > 0;
  // The refiner's inputs (method/refiners.hpp): the truth and the training cameras.
  SupportStats stats;
  RefinerInputs ri;
  ri.truth = &p.synth.scene;
  ri.oracle.artifacts.strength = c.artifact_strength;
  ri.reference = c.reference;
  ri.stats = &stats;
  complete_refiner_inputs(ri, *p.train, p.options.seed);
  const RefinerKind& refiner_row = refiner_kind(bench_refiner(c.refiner));
  json identity = {{"id", c.id}, {"scene", options_json(p.options)}};
  if (c.kind == RunKind::Dense) {
    identity["kind"] = "dense";
    identity["train"] = identity_json(backbone_train_options(p.options));
  } else {
    identity["kind"] = c.kind == RunKind::TestViews ? "test-views" : "finetune";
    identity["finetune"] = identity_json(fo);
    // The refiner is part of what a run is only where it refines something.
    if (generated) identity["refiner"] = refiner_row.identity(ri);
    if (c.kind == RunKind::TestViews) identity["test_views"] = test_views;
  }
  if (fs::exists(result_path)) {
    if (!fs::exists(identity_path))
      throw_error(result_path, ": run ", c.id, " has no identity.json (made by an older fillgs), so what it was made with is unknown; use another --out, or delete ",
                  dir, " to run it again");
    const std::string diff = identity_difference(read_json_file(identity_path), identity);
    if (!diff.empty())
      throw_error(identity_path, ": run ", c.id, " was made with other options (", diff, "); use another --out, or delete ", dir,
                  " to run it again");
    RunResult r = load_result(result_path, c.id, p.options.seed, p.options.scene_name());
    log << c.id << ": reused " << result_path << "\n";
    return r;
  }
  if (c.kind != RunKind::Dense && !p.has_backbone) throw_error("run ", c.id, ": the scene's backbone was not prepared (ensure_backbone)");
  const auto t0 = Clock::now();
  make_directories(dir);
  write_file_atomically(identity_path, identity.dump(1) + "\n");
  if (c.kind == RunKind::Dense) {
    // Every camera of the rig, trained like the backbone.
    const Dataset all = Dataset::load(p.scene_dir(), join_path(p.scene_dir(), "transforms_train.json"));
    const GaussianCloud model = train_backbone(all, join_path(p.scene_dir(), "points.ply"), p.options, progress);
    const double train_s = seconds_since(t0);
    RunResult r = evaluate_model(p, model, c.id, "", progress);
    r.group = c.group;
    r.seconds_train = train_s;
    r.seconds_total = seconds_since(t0);
    write_fillgs_ply(join_path(dir, "model.ply"), model, F);
    save_result(result_path, r);
    log << c.id << ": " << all.rigs().size() << " cameras; interpolation " << fmt(r.interpolation.psnr) << " dB (moving "
        << fmt(r.interpolation.psnr_moving) << "), extrapolation " << fmt(r.extrapolation.psnr) << " dB (moving "
        << fmt(r.extrapolation.psnr_moving) << "), " << fmt(r.seconds_total, 0) << " s" << std::endl;
    return r;
  }
  if (c.kind == RunKind::TestViews) {
    FrameSampler truth(p.synth.scene);
    for (const Dataset* split : {p.interpolation.get(), p.extrapolation.get()})
      for (const TrainView& v : split->views()) {
        const size_t P = size_t(v.camera.width) * size_t(v.camera.height);
        fo.extra_views.push_back({v.camera, render(truth.at(v.camera.time), v.camera).rgb, std::vector<float>(P, 1.0f)});
      }
  }
  const std::unique_ptr<Refiner> refiner = make_refiner(refiner_row.name, ri);
  const FinetuneResult fr = finetune(*p.train, p.backbone, *refiner, fo, progress);
  RunResult r = evaluate_model(p, fr.model, c.id, "", progress);
  r.group = c.group;
  r.trajectories = 0;
  if (generated) {
    r.support = c.refiner;
    r.support_share = stats.share();
  }
  if (!stats.views.empty()) write_refined_view_records(join_path(dir, "refined_views.csv"), stats.views);
  for (const FinetuneRound& round : fr.rounds) {
    r.trajectories += round.trajectories;
    r.views_added += round.views_added;
    r.mean_weight += round.mean_weight * double(round.views_added);
    r.seconds_select += round.seconds_select;
    r.seconds_refine += round.seconds_refine + round.seconds_render;
    r.seconds_weights += round.seconds_weights;
    r.refine_failures += int(round.refine_failures.size());
    for (const std::string& n : round.notes) log << c.id << ": round at iteration " << round.iteration << ": " << n << "\n";
  }
  if (r.views_added) r.mean_weight /= double(r.views_added);
  if (c.kind == RunKind::TestViews) r.views_added = fo.extra_views.size(), r.mean_weight = 1.0;
  r.seconds_train = fr.seconds_train;
  r.seconds_total = seconds_since(t0);
  write_fillgs_ply(join_path(dir, "model.ply"), fr.model, F);
  if (!fr.virtual_views.empty()) {
    // Where the strategy looked: the refined views, and their top view over the split.
    write_transforms_json(join_path(dir, "virtual_views.json"), fr.virtual_views);
    write_split_picture(p.synth, join_path(dir, "views.png"), fr.virtual_views,
                        c.id + ": " + std::to_string(fr.virtual_views.size()) + " virtual views (" + p.options.scene_name() + ", seed " +
                            std::to_string(p.options.seed) + ")");
  }
  save_result(result_path, r);
  log << c.id << ": interpolation " << fmt(r.interpolation.psnr) << " dB (moving " << fmt(r.interpolation.psnr_moving) << "), extrapolation "
      << fmt(r.extrapolation.psnr) << " dB (moving " << fmt(r.extrapolation.psnr_moving) << "), train " << fmt(r.train.psnr) << " dB; "
      << r.trajectories << " trajectories, " << r.views_added << " views, mean weight " << fmt(r.mean_weight, 3);
  if (!r.support.empty()) log << ", supported " << fmt(100 * r.support_share, 1) << "%";
  log << ", " << fmt(r.seconds_total, 0) << " s" << std::endl;
  return r;
}

}  // namespace fillgs
