#include "fillgs/experiment/experiment.hpp"
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

std::string fmt(double x, int digits = 2) {
  if (!std::isfinite(x)) return "–";
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << x;
  return s.str();
}

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

/// Mean and sample standard deviation of values added one at a time.
struct Moments {
  double sum = 0, squares = 0;
  int n = 0;
  void add(double x) { sum += x, squares += x * x, ++n; }
  double mean() const { return sum / n; }
  double sd() const { return n > 1 ? std::sqrt(std::max(0.0, (squares - sum * sum / n) / (n - 1))) : 0.0; }
};

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

/// The comma-separated cells of a CSV line (no quoting: fillgs's files have none); a
/// trailing comma ends in an empty cell.
std::vector<std::string> csv_cells(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ls(line);
  for (std::string cell; std::getline(ls, cell, ',');) f.push_back(cell);
  if (!line.empty() && line.back() == ',') f.emplace_back();
  return f;
}

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
    auto add = [&](const std::string& id, ConfigGroup group, Strategy s, Weighting w, double a, int k) {
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
    add("random.w-none", ConfigGroup::Calibration, Strategy::Random, Weighting::None, strength, 5);
    for (Strategy s : values_of<Strategy>()) add(to_string(s), ConfigGroup::Strategy, s, s == Strategy::FillGS ? Weighting::FillGS : baseline_weighting, strength, 5);
    const char* ablations[] = {"no-start-selection", "no-error-term", "no-sensitivity-term", "no-candidate-scoring",
                               "no-global",          "count-only",    "speed-only"};
    for (const char* a : ablations) {
      RunConfig* c = add(std::string("fillgs.") + a, ConfigGroup::Ablation, Strategy::FillGS, Weighting::FillGS, strength, 5);
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
    for (Strategy s : values_of<Strategy>())
      if (s != Strategy::FillGS) add(std::string(to_string(s)) + ".w-fillgs", ConfigGroup::Selection, s, Weighting::FillGS, strength, 5);
    for (Weighting w : {Weighting::None, Weighting::NoConsistency, Weighting::NoCovisibility, Weighting::Enhancer3DGS, Weighting::ExploreGS,
                        Weighting::UA4DGS})
      add(std::string("fillgs.w-") + to_string(w), ConfigGroup::Weighting, Strategy::FillGS, w, strength, 5);
    // fillgs's own options beyond the paper: the weights' D̂ scaled over every moving Gaussian
    // of every frame (the earlier rule), the weighted loss normalised by the view's mean
    // weight, model-independent sweep matching, co-visibility rules that weigh static content
    // by its observation density (static-count, density).
    add("fillgs.covis-global", ConfigGroup::Weighting, Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.scale = CovisibilityScale::Global;
    add("fillgs.normalised", ConfigGroup::Weighting, Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.normalise = true;
    add("fillgs.m-sweep", ConfigGroup::Weighting, Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.method = MaskMethod::Sweep;
    add("fillgs.covis-static-count", ConfigGroup::Weighting, Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.covisibility =
        Covisibility::StaticCount;
    add("fillgs.covis-density", ConfigGroup::Weighting, Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.covisibility = Covisibility::Density;
    {
      RunConfig* c = add("fillgs.sweep+static-count", ConfigGroup::Weighting, Strategy::FillGS, Weighting::FillGS, strength, 5);
      c->mask.method = MaskMethod::Sweep;
      c->mask.covisibility = Covisibility::StaticCount;
    }
    // fillgs's option beyond the paper: starts of one round whose patches do not overlap on
    // a camera; with FillGS's weights and with none (to see the views without the weights).
    add("fillgs.spread-starts", ConfigGroup::Ablation, Strategy::FillGS, Weighting::FillGS, strength, 5)->select.spread_starts = true;
    add("fillgs.w-none.spread-starts", ConfigGroup::Weighting, Strategy::FillGS, Weighting::None, strength, 5)->select.spread_starts = true;
    // ... and candidates scored by the D̂ they see (sum over their visible set), unweighted.
    add("fillgs.w-none.gain-score", ConfigGroup::Weighting, Strategy::FillGS, Weighting::None, strength, 5)->select.score_gain = true;
    {
      RunConfig* c = add("fillgs.w-none.spread+gain", ConfigGroup::Weighting, Strategy::FillGS, Weighting::None, strength, 5);
      c->select.spread_starts = true;
      c->select.score_gain = true;
    }
    // The score alone: FillGS's candidate score and coverage4d's, both unweighted from the
    // same shuffled starts (no start selection; the same seed shuffles the same way).
    {
      RunConfig* c = add("fillgs.w-none.no-start-selection", ConfigGroup::Ablation, Strategy::FillGS, Weighting::None, strength, 5);
      c->select.no_start_selection = true;
      add("coverage4d.w-none", ConfigGroup::Ablation, Strategy::Coverage4D, Weighting::None, strength, 5);
    }
    // Table 1 with one weighting: every strategy's views unweighted, so that only the selection
    // differs (random's, FillGS's and coverage4d's unweighted rows are above).
    for (Strategy s : {Strategy::Negative, Strategy::Interpolation, Strategy::FisherRF, Strategy::Coverage3D})
      add(std::string(to_string(s)) + ".w-none", ConfigGroup::Unweighted, s, Weighting::None, strength, 5);
    // The exploration space as the paper masks it: occupied voxels only, no "unexplored" label.
    add("fillgs.occupied-only", ConfigGroup::Ablation, Strategy::FillGS, Weighting::FillGS, strength, 5)->grid.label_unexplored = false;
    for (int k : {1, 10, 20}) add("fillgs.k" + std::to_string(k), ConfigGroup::Budget, Strategy::FillGS, Weighting::FillGS, strength, k);
    for (Strategy s : values_of<Strategy>())
      add(std::string(to_string(s)) + ".clean", ConfigGroup::Refiner, s, s == Strategy::FillGS ? Weighting::FillGS : baseline_weighting, 0.0, 5);
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

void write_refined_view_records(const std::string& path, const std::vector<RefinedViewRecord>& records) {
  std::ostringstream csv;
  csv.precision(7);
  csv << "file,frame,parallax_degrees,axis_degrees,baseline,support,confidence,psnr_refined,psnr_render,psnr_seen\n";
  for (const RefinedViewRecord& r : records)
    csv << r.file << "," << r.frame << "," << r.parallax_degrees << "," << r.axis_degrees << "," << r.baseline << "," << r.support << ","
        << r.confidence << "," << r.psnr_refined << "," << r.psnr_render << "," << r.psnr_seen << "\n";
  write_file_atomically(path, csv.str());
}

std::vector<RefinedViewRecord> read_refined_view_records(const std::string& path) {
  std::istringstream in(read_file(path));
  std::string line;
  std::getline(in, line);
  std::vector<RefinedViewRecord> out;
  for (size_t row = 2; std::getline(in, line); ++row) {
    if (line.empty()) continue;
    const std::vector<std::string> f = csv_cells(line);
    if (f.size() != 10) throw_error(path, ": line ", row, " has ", f.size(), " columns, expected 10");
    double v[9];
    for (size_t k = 1; k < 10; ++k) {
      if (f[k] == "nan" || f[k] == "-nan") v[k - 1] = std::nan("");
      else if (!parse_number(f[k], &v[k - 1])) throw_error(path, ": line ", row, " column ", k + 1, ": '", f[k], "' is not a number");
    }
    RefinedViewRecord r;
    r.file = f[0], r.frame = int(v[0]), r.parallax_degrees = v[1], r.axis_degrees = v[2], r.baseline = v[3], r.support = v[4];
    r.confidence = v[5], r.psnr_refined = v[6], r.psnr_render = v[7], r.psnr_seen = v[8];
    out.push_back(r);
  }
  return out;
}

void write_refiner_calibration(const std::string& path, const std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>>& runs,
                               const std::string& title) {
  constexpr double kBin = 5.0;
  std::vector<ScatterSeries> series;
  std::map<int, std::array<Moments, 4>> bins;  // bin -> refined where the reference saw, whole refined image, render, support
  for (const auto& [label, records] : runs) {
    ScatterSeries pts;
    pts.name = "where the reference saw, " + label;
    pts.joined = false;
    for (const RefinedViewRecord& r : records) {
      if (!std::isfinite(r.psnr_refined)) continue;
      std::array<Moments, 4>& b = bins[int(r.parallax_degrees / kBin)];
      if (std::isfinite(r.psnr_seen)) {
        pts.x.push_back(r.parallax_degrees), pts.y.push_back(r.psnr_seen);
        b[0].add(std::min(r.psnr_seen, 60.0));  // an exact match (150 dB) would swamp a mean
      }
      b[1].add(r.psnr_refined);
      if (std::isfinite(r.psnr_render)) b[2].add(r.psnr_render);
      b[3].add(r.support);
    }
    if (!pts.x.empty()) series.push_back(std::move(pts));
  }
  if (bins.empty()) return;
  ScatterSeries seen_mean{"where the reference saw, mean per 5 degrees", {}, {}, {}, true},
      whole_mean{"whole image, mean per 5 degrees", {}, {}, {}, true}, render_mean{"the render it was given, mean per 5 degrees", {}, {}, {}, true};
  std::ostringstream md;
  md << "| parallax to the reference (degrees) | views | refined PSNR where the reference saw (dB) | refined PSNR, whole image (dB) | "
        "render given, whole image (dB) | share the reference saw |\n|---|---|---|---|---|---|\n";
  for (const auto& [bin, m] : bins) {
    const double centre = (bin + 0.5) * kBin;
    if (m[0].n) seen_mean.x.push_back(centre), seen_mean.y.push_back(m[0].mean());
    whole_mean.x.push_back(centre), whole_mean.y.push_back(m[1].mean());
    if (m[2].n) render_mean.x.push_back(centre), render_mean.y.push_back(m[2].mean());
    md << "| " << fmt(bin * kBin, 0) << "–" << fmt((bin + 1) * kBin, 0) << " | " << m[1].n << " | "
       << (m[0].n ? fmt(m[0].mean(), 2) + " ± " + fmt(m[0].sd(), 2) : "–") << " | " << fmt(m[1].mean(), 2) << " ± " << fmt(m[1].sd(), 2) << " | "
       << (m[2].n ? fmt(m[2].mean(), 2) : "–") << " | " << fmt(100 * m[3].mean(), 1) << "% |\n";
  }
  for (ScatterSeries* s : {&seen_mean, &whole_mean, &render_mean})
    if (!s->x.empty()) series.push_back(*s);
  write_scatter_png(path + ".png", series, {title, "parallax angle to the reference view (degrees, median over the view)", "PSNR against the truth (dB)"}, false);
  write_file_atomically(path + ".md", md.str());
}

double student_t_975(int df) {
  if (df < 1) throw_error("Student's t needs at least 1 degree of freedom, not ", df);
  // P(|T| <= t) for integer df (Abramowitz and Stegun 26.7.3-4), with theta = atan(t / sqrt(df)).
  auto central = [df](double t) {
    const double theta = std::atan(t / std::sqrt(double(df))), s = std::sin(theta), c2 = std::cos(theta) * std::cos(theta);
    double term = 1.0, sum = 1.0;
    if (df % 2 == 0) {
      for (int k = 2; k <= df - 2; k += 2) term *= c2 * double(k - 1) / double(k), sum += term;
      return s * sum;
    }
    if (df == 1) return 2.0 * theta / kPi;
    for (int k = 3; k <= df - 2; k += 2) term *= c2 * double(k - 1) / double(k), sum += term;
    return 2.0 / kPi * (theta + s * std::cos(theta) * sum);
  };
  double lo = 0.0, hi = 1000.0;  // t(0.975, 1) = 12.7
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (central(mid) < 0.95 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

int seeds_for_half_width(double sd, double half_width) {
  if (!std::isfinite(sd) || !(half_width > 0)) return 0;
  // t(0.975, df) > 1.96 for every df, so no n below (1.96 sd / half-width)² can do.
  const double lower = std::ceil(std::pow(1.959963 * sd / half_width, 2));
  if (lower > 10000) return 0;
  for (int n = std::max(2, int(lower)); n <= 10000; ++n)
    if (student_t_975(n - 1) * sd / std::sqrt(double(n)) <= half_width) return n;
  return 0;
}

std::vector<PairedDifference> paired_differences(const std::vector<RunResult>& results, const std::string& reference) {
  auto values = [](const RunResult& r) {
    return std::array<double, 4>{r.interpolation.psnr, r.interpolation.psnr_moving, r.extrapolation.psnr, r.extrapolation.psnr_moving};
  };
  std::vector<PairedDifference> out;
  std::vector<std::array<Moments, 4>> moments;  // per entry of out
  // Indexes, so that the report is linear in its rows (a merge of 100,000 rows scanned them
  // all for each row): runs by (scene, seed, id), ids run per scene, out's rows by (scene, id).
  auto key = [](const std::string& variant, const std::string& id, uint64_t seed) { return variant + '\x1f' + id + '\x1f' + std::to_string(seed); };
  std::unordered_map<std::string, size_t> run_at, out_at;
  std::unordered_set<std::string> ran;
  for (size_t i = 0; i < results.size(); ++i) {
    run_at.emplace(key(results[i].variant, results[i].id, results[i].seed), i);
    ran.insert(key(results[i].variant, results[i].id, 0));
  }
  for (const RunResult& r : results) {
    if (r.id == "backbone") continue;
    // Each run against the reference of its own oracle: "x@full" against "fillgs@full", the
    // clean-oracle "x.clean" against "fillgs.clean".
    const size_t at = r.id.find('@');
    const std::string support = at == std::string::npos ? "" : r.id.substr(at);
    const std::string base = r.id.substr(0, at);
    const bool clean = base.size() > 6 && base.compare(base.size() - 6, 6, ".clean") == 0;
    auto find = [&](const std::string& id) {
      const auto at = run_at.find(key(r.variant, id, r.seed));
      return at == run_at.end() ? results.end() : results.begin() + ptrdiff_t(at->second);
    };
    // "random.w-none" against "fillgs.w-none" where it ran: one weighting, only the selection differs.
    const size_t w = base.find(".w-");
    const std::string same_weighting = w == std::string::npos || base.substr(0, w) == reference ? "" : reference + base.substr(w) + support;
    std::string ref_id = reference + (clean ? ".clean" : "") + support;
    if (!same_weighting.empty() && ran.count(key(r.variant, same_weighting, 0)))
      ref_id = same_weighting;
    if (r.id == ref_id) continue;
    const auto ref = find(ref_id);
    if (ref == results.end()) continue;
    const auto [slot, fresh] = out_at.emplace(key(r.variant, r.id, 0), out.size());
    if (fresh) {
      out.push_back({r.variant, r.id, r.group});
      moments.emplace_back();
    }
    const auto it = out.begin() + ptrdiff_t(slot->second);
    const std::array<double, 4> a = values(*ref), b = values(r);
    std::array<Moments, 4>& m = moments[size_t(it - out.begin())];
    for (size_t j = 0; j < 4; ++j) m[j].add(a[j] - b[j]);
  }
  for (size_t k = 0; k < out.size(); ++k) {
    out[k].seeds = moments[k][0].n;
    const int n = out[k].seeds;
    const double t = n > 1 ? student_t_975(n - 1) / std::sqrt(double(n)) : std::numeric_limits<double>::quiet_NaN();
    for (size_t j = 0; j < 4; ++j) out[k].mean[j] = moments[k][j].mean(), out[k].sd[j] = moments[k][j].sd(), out[k].half_width[j] = t * out[k].sd[j];
  }
  return out;
}

namespace {
/// "negative.w-none", "fillgs.w-none@oracle": a strategy's views with no weights.
bool unweighted_strategy_row(const std::string& id) {
  const std::string base = id.substr(0, id.find('@'));
  for (Strategy s : values_of<Strategy>())
    if (base == std::string(to_string(s)) + ".w-none") return true;
  return false;
}
}  // namespace

void write_bench_report(const std::string& root, const std::vector<RunResult>& results) {
  // CSV: every run.
  std::ostringstream csv;
  csv << kResultsCsvHeader << "\n";
  for (const RunResult& r : results)
    csv << r.variant << "," << r.seed << "," << r.id << "," << to_string(r.group) << "," << r.support << "," << r.interpolation.psnr << "," << r.interpolation.ssim
        << "," << r.interpolation.psnr_moving << "," << r.extrapolation.psnr << "," << r.extrapolation.ssim << "," << r.extrapolation.psnr_moving
        << "," << r.train.psnr << "," << r.trajectories << "," << r.views_added << "," << r.mean_weight << "," << r.support_share << ","
        << r.refine_failures << "," << r.seconds_select << "," << r.seconds_refine << "," << r.seconds_weights << "," << r.seconds_train << ","
        << r.seconds_eval << "," << r.seconds_total << "\n";
  write_file_atomically(join_path(root, "results.csv"), csv.str());

  // Mean and standard deviation over seeds, per scene and configuration, in first-seen order.
  constexpr int kValues = 10;  // ip is im ep es em tp weight trajectories support
  struct Mean {
    std::string id, variant, support;
    ConfigGroup group = ConfigGroup::Control;
    int n = 0;
    Moments v[kValues];
    double t[5] = {};
    double mean(int k) const { return v[k].mean(); }
    double sd(int k) const { return v[k].sd(); }
  };
  std::vector<Mean> means;
  std::unordered_map<std::string, size_t> mean_at;  // (scene, id) -> row of means: linear in the runs
  for (const RunResult& r : results) {
    const auto [slot, fresh] = mean_at.emplace(r.variant + '\x1f' + r.id, means.size());
    if (fresh) {
      means.emplace_back();
      means.back().id = r.id, means.back().group = r.group, means.back().variant = r.variant, means.back().support = r.support;
    }
    const auto it = means.begin() + ptrdiff_t(slot->second);
    const double x[kValues] = {r.interpolation.psnr, r.interpolation.ssim, r.interpolation.psnr_moving, r.extrapolation.psnr,
                               r.extrapolation.ssim,  r.extrapolation.psnr_moving, r.train.psnr, r.mean_weight, double(r.trajectories),
                               r.support_share};
    for (int k = 0; k < kValues; ++k) it->v[k].add(x[k]);
    const double sec[5] = {r.seconds_select, r.seconds_refine, r.seconds_weights, r.seconds_train, r.seconds_eval};
    for (int k = 0; k < 5; ++k) it->t[k] += sec[k];
    it->n += 1;
  }
  for (Mean& m : means)
    for (double& x : m.t) x /= m.n;
  auto cell = [](const Mean& m, int k, int digits) {
    std::string c = fmt(m.mean(k), digits);
    if (m.n > 1 && std::isfinite(m.mean(k))) c += " ± " + fmt(m.sd(k), digits);
    return c;
  };
  std::set<std::string> scenes;
  for (const RunResult& r : results) scenes.insert(r.variant + " seed " + std::to_string(r.seed));
  std::ostringstream md;
  md << "# fillgs bench\n\nMean ± standard deviation over seeds, per scene; " << scenes.size() << " scene run(s):";
  for (const std::string& s : scenes) md << " " << s << ";";
  md << "\nPSNR in dB. \"moving\": PSNR over the pixels of the moving objects (ground truth). Train: PSNR on the training cameras. "
        "Refiner: \"reference\" is conditioned on the start view's own image at each frame (calibrated; bench/results/README.md), "
        "\"oracle\" restores the truth wherever any training camera saw it, \"oracle-full\" everywhere. "
        "\"supported\": share of the refined pixels the refiner's observations support.\n\n";
  const std::pair<ConfigGroup, const char*> groups[] = {{ConfigGroup::Control, "Without generated views"},
                                                      {ConfigGroup::Upper, "Upper bounds"},
                                                      {ConfigGroup::Calibration, "Refiner calibration (random views, no weights)"},
                                                      {ConfigGroup::Strategy, "Viewpoint selection strategies (Table 1 of the paper)"},
                                                      {ConfigGroup::Ablation, "FillGS selection ablations (Table 3 of the paper)"},
                                                      {ConfigGroup::Selection, "Other strategies with FillGS's fine-tuning and weights (Table 3 of the paper)"},
                                                      {ConfigGroup::Weighting, "Fine-tuning weights (Table 4 of the paper)"},
                                                      {ConfigGroup::Budget, "Trajectory budget per round"},
                                                      {ConfigGroup::Refiner, "Clean refiner (no injected artifacts)"},
                                                      {ConfigGroup::Unweighted, "Table 1 with one weighting: every strategy's views unweighted (only the selection differs)"}};
  auto in_group = [](const Mean& m, ConfigGroup g) {
    return m.group == g || (g == ConfigGroup::Control && m.id == "backbone") || (g == ConfigGroup::Unweighted && unweighted_strategy_row(m.id));
  };
  for (const auto& g : groups) {
    if (std::none_of(means.begin(), means.end(), [&](const Mean& m) { return in_group(m, g.first); })) continue;
    md << "## " << g.second << "\n\n| Scene | Method | refiner | Interp PSNR | SSIM | moving PSNR | Extrap PSNR | SSIM | moving PSNR | Train PSNR | weight | supported | runs |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Mean& m : means) {
      if (!in_group(m, g.first)) continue;
      md << "| " << m.variant << " | " << m.id << " | " << (m.support.empty() ? "–" : m.support) << " | " << cell(m, 0, 2) << " | " << cell(m, 1, 3)
         << " | " << cell(m, 2, 2) << " | " << cell(m, 3, 2) << " | " << cell(m, 4, 3) << " | " << cell(m, 5, 2) << " | " << cell(m, 6, 2) << " | "
         << fmt(m.mean(7), 3) << " | " << (m.support.empty() ? "–" : fmt(100 * m.mean(9), 1) + "%") << " | " << m.n << " |\n";
    }
    md << "\n";
  }
  const std::vector<PairedDifference> paired = paired_differences(results);
  bool paired_chart = false;
  if (!paired.empty()) {
    md << "## FillGS − each method, paired by seed\n\nPer seed, FillGS's PSNR minus the method's (dB; positive: FillGS ahead): the mean "
          "over the seeds both ran, ± the standard deviation, and the 95 % confidence interval of the mean (t over the paired seeds); "
          "**separated** only where the interval excludes 0. A strategy's unweighted row (`x.w-none`) is paired with FillGS's unweighted "
          "row, every other row with `fillgs`. Ablation and weighting rows read as the paper's Tables 3 and 4: what the component "
          "is worth. \"Seeds for ±0.5\": where an interval is wider than ±0.5 dB, the paired seeds its measured SD would need "
          "for ±0.5 dB (interpolation / extrapolation; \"met\" where it already is).\n\n"
          "| Scene | Method | group | Interp ΔPSNR | 95 % CI | Extrap ΔPSNR | 95 % CI | moving Δ interp / extrap | seeds | seeds for ±0.5 |\n"
          "|---|---|---|---|---|---|---|---|---|---|\n";
    auto interval = [](const PairedDifference& d, int j) {
      if (d.seeds < 2) return std::string("–");
      const std::string iv = "[" + fmt(d.mean[j] - d.half_width[j], 2) + ", " + fmt(d.mean[j] + d.half_width[j], 2) + "]";
      return d.separated(j) ? "**" + iv + "**" : iv;
    };
    auto seeds_needed = [](const PairedDifference& d, int j) {
      if (d.seeds < 2) return std::string("–");
      if (d.half_width[j] <= 0.5) return std::string("met");
      const int n = seeds_for_half_width(d.sd[j], 0.5);
      return n > 0 ? std::to_string(n) : std::string("> 10,000");
    };
    for (const PairedDifference& d : paired) {
      md << "| " << d.variant << " | " << d.id << " | " << to_string(d.group);
      for (int j : {0, 2}) md << " | " << fmt(d.mean[j], 2) << (d.seeds > 1 ? " ± " + fmt(d.sd[j], 2) : "") << " | " << interval(d, j);
      md << " | " << fmt(d.mean[1], 2) << " / " << fmt(d.mean[3], 2) << " | " << d.seeds << " | " << seeds_needed(d, 0) << " / " << seeds_needed(d, 2)
         << " |\n";
    }
    md << "\n";
    // Table 1's intervals as a picture (the first scene): each strategy under both protocols
    // (its own weights; one weighting) and the control.
    std::vector<std::string> rows;
    IntervalSeries si{"interpolation", {}, {}, {}}, se{"extrapolation", {}, {}, {}};
    for (const PairedDifference& d : paired) {
      if (d.variant != paired.front().variant || d.seeds < 2) continue;
      // FillGS's own rows (its weights against none) belong to Table 4, not here.
      if (d.id.rfind("fillgs", 0) == 0 || !(d.group == ConfigGroup::Strategy || d.id == "no-refinement" || unweighted_strategy_row(d.id))) continue;
      rows.push_back(d.id);
      for (auto [series, j] : {std::pair<IntervalSeries*, int>{&si, 0}, {&se, 2}}) {
        series->estimate.push_back(d.mean[j]);
        series->low.push_back(d.mean[j] - d.half_width[j]);
        series->high.push_back(d.mean[j] + d.half_width[j]);
      }
    }
    if (!rows.empty()) {
      write_interval_chart_png(join_path(root, "paired_table1.png"), rows, {si, se},
                               {"FillGS minus each (" + paired.front().variant + "): mean and 95 % interval over paired seeds; filled: excludes 0",
                                "PSNR difference (dB; x.w-none rows: FillGS's unweighted row minus x's)", ""});
      paired_chart = true;
    }
  }
  md << "## Seconds per phase (mean per run)\n\n| Scene | Method | select | refine | weights | train | eval |\n|---|---|---|---|---|---|---|\n";
  for (const Mean& m : means)
    if (m.id != "backbone")
      md << "| " << m.variant << " | " << m.id << " | " << fmt(m.t[0], 1) << " | " << fmt(m.t[1], 1) << " | " << fmt(m.t[2], 1) << " | " << fmt(m.t[3], 1) << " | "
         << fmt(m.t[4], 1) << " |\n";

  // Plots of the first scene: strategies with the first support mode, the control, the upper bounds.
  const std::string plotted = means.empty() ? "" : means.front().variant;
  std::vector<std::string> names;
  std::vector<double> interp, extrap;
  for (const Mean& m : means)
    if (m.variant == plotted && m.id.find('@') == std::string::npos &&
        (m.group == ConfigGroup::Strategy || m.group == ConfigGroup::Control || m.group == ConfigGroup::Upper || m.id == "backbone"))
      names.push_back(m.id), interp.push_back(m.mean(0)), extrap.push_back(m.mean(3));
  if (!names.empty()) {
    write_bar_chart_png(join_path(root, "psnr_interpolation.png"), names, interp, {"interpolation PSNR per strategy (" + plotted + ")", "", "PSNR (dB)"});
    write_bar_chart_png(join_path(root, "psnr_extrapolation.png"), names, extrap, {"extrapolation PSNR per strategy (" + plotted + ")", "", "PSNR (dB)"});
  }
  ScatterSeries bi{"interpolation", {}, {}, {}}, be{"extrapolation", {}, {}, {}};
  for (const Mean& m : means)
    if (m.variant == plotted && m.id.find('@') == std::string::npos && (m.group == ConfigGroup::Budget || m.id == "fillgs")) {
      bi.x.push_back(m.mean(8)), bi.y.push_back(m.mean(0));
      be.x.push_back(m.mean(8)), be.y.push_back(m.mean(3));
    }
  if (bi.x.size() >= 2)
    write_scatter_png(join_path(root, "budget.png"), {bi, be}, {"FillGS: PSNR against trajectories (3 rounds)", "trajectories in all", "PSNR (dB)"},
                      false);
  const char* phases[] = {"select", "refine", "weights", "train", "eval"};
  std::vector<double> t(5, 0.0);
  int runs = 0;
  for (const Mean& m : means)
    if (m.id != "backbone") {
      for (int k = 0; k < 5; ++k) t[size_t(k)] += m.t[k];
      ++runs;
    }
  if (runs) {
    for (double& x : t) x /= runs;
    write_bar_chart_png(join_path(root, "time_per_phase.png"), std::vector<std::string>(phases, phases + 5), t,
                        {"mean seconds per phase and run", "", "seconds"});
  }
  // Each strategy's gain over the control (same scene), per refiner: the chart the
  // comparison is read from.
  std::vector<std::string> figures = {"psnr_interpolation", "psnr_extrapolation", "budget", "time_per_phase"};
  if (paired_chart) figures.insert(figures.begin(), "paired_table1");
  {
    std::vector<std::string> gain_names;
    std::vector<double> gain_interp, gain_extrap;
    for (const Mean& m : means) {
      if (m.variant != plotted || m.group != ConfigGroup::Strategy) continue;
      const auto found = mean_at.find(m.variant + '\x1f' + "no-refinement");
      if (found == mean_at.end()) continue;
      const auto control = means.begin() + ptrdiff_t(found->second);
      gain_names.push_back(m.id);
      gain_interp.push_back(m.mean(0) - control->mean(0));
      gain_extrap.push_back(m.mean(3) - control->mean(3));
    }
    if (!gain_names.empty()) {
      write_bar_chart_png(join_path(root, "gain_interpolation.png"), gain_names, gain_interp,
                          {"interpolation: gain over the control per strategy and refiner (" + plotted + ")", "", "PSNR gain (dB)"});
      write_bar_chart_png(join_path(root, "gain_extrapolation.png"), gain_names, gain_extrap,
                          {"extrapolation: gain over the control per strategy and refiner (" + plotted + ")", "", "PSNR gain (dB)"});
      figures.insert(figures.begin(), {"gain_interpolation", "gain_extrapolation"});
    }
  }
  // The refiner's calibration: refined-vs-truth PSNR against the angle to the reference, over
  // the calibration runs this folder holds (one per refiner that records its views).
  if (fs::is_directory(root)) {
    std::map<std::string, std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>>> by_id;
    std::vector<fs::path> scene_dirs;
    for (const auto& e : fs::directory_iterator(root))
      if (e.is_directory()) scene_dirs.push_back(e.path());
    std::sort(scene_dirs.begin(), scene_dirs.end());
    for (const fs::path& sc : scene_dirs) {
      if (!fs::is_directory(sc / "runs")) continue;
      std::vector<fs::path> runs;
      for (const auto& e : fs::directory_iterator(sc / "runs")) runs.push_back(e.path());
      std::sort(runs.begin(), runs.end());
      for (const fs::path& run : runs)
        if (run.filename().string().rfind("random.w-none", 0) == 0 && fs::exists(run / "refined_views.csv") && fs::exists(run / "result.json"))
          by_id[run.filename().string()].emplace_back(sc.filename().string(), read_refined_view_records((run / "refined_views.csv").string()));
    }
    for (const auto& [id, runs] : by_id) {
      const std::string name = "calibration" + id.substr(std::string("random.w-none").size());
      write_refiner_calibration(join_path(root, name), runs, "refiner calibration: " + id + " (random views)");
      if (fs::exists(join_path(root, name + ".md"))) {
        md << "\n## Refiner calibration (" << id << ")\n\nRefined-vs-truth PSNR of the random views against the parallax angle to "
              "their reference view, per 5° bin over every seed (the render it was given alongside).\n\n"
           << read_file(join_path(root, name + ".md")) << "\n";
        figures.push_back(name);
      }
    }
  }
  // The figures drawn above, named in the Markdown (and so embedded in the HTML page).
  md << "\n## Figures\n\nEach figure's numbers are in the CSV of its name, and `gnuplot NAME.gp` re-draws it.\n\n";
  for (const std::string& f : figures)
    if (fs::exists(join_path(root, f + ".png"))) md << "![" << f << "](" << f << ".png)\n\n";
  write_file_atomically(join_path(root, "results.md"), md.str());
  write_html_report(join_path(root, "results.md"), join_path(root, "results.html"));
}

void write_run_report(const std::string& dir, const RunReportInput& in) {
  const ExperimentOptions& o = in.scene->options;
  // Side-by-side pictures: ground truth | backbone | each fine-tuned model, at the moment of
  // each split where the moving content covers most of a view (a moving moment).
  std::vector<GaussianCloud> models = {in.scene->backbone};
  for (const std::string& id : in.run_ids) models.push_back(read_scene(join_path(join_path(join_path(in.scene->dir, "runs"), id), "model.ply")));
  std::vector<std::string> pictures;
  for (const auto* split : {in.scene->extrapolation.get(), in.scene->interpolation.get()}) {
    size_t best = 0, most = 0;
    for (size_t v = 0; v < split->views().size(); ++v) {
      const std::vector<unsigned char> m = moving_region(in.scene->synth.scene, split->views()[v].camera);
      const size_t n = size_t(std::count(m.begin(), m.end(), 1));
      if (n > most) most = n, best = v;
    }
    const TrainView& view = split->views()[best];
    std::vector<std::vector<float>> imgs = {split->image(best)};
    std::vector<std::string> caps = {"ground truth"};
    for (size_t m = 0; m < models.size(); ++m) {
      imgs.push_back(render(frame_at(models[m], view.camera.time), view.camera).rgb);
      caps.push_back(m == 0 ? "backbone" : in.run_ids[m - 1]);
    }
    const std::string file = "compare_" + view.rig + "_f" + std::to_string(view.frame) + ".png";
    write_side_by_side_png(join_path(dir, file), imgs, view.camera.width, view.camera.height, caps, 2);
    pictures.push_back(file);
  }
  // Report.
  std::ostringstream md;
  md << "# fillgs run\n\nScene: built-in synthetic (" << o.scene_name() << "), " << o.width << "x" << o.height << ", " << o.frames
     << " frames; backbone trained on " << in.scene->train->rigs().size() << " cameras (";
  for (size_t k = 0; k < in.scene->options.train_cameras.size(); ++k) md << (k ? ", " : "") << in.scene->options.train_cameras[k];
  md << ") for " << o.backbone_iterations << " iterations; each fine-tuning: " << in.finetune.iterations << " iterations, "
     << in.finetune.trajectories << " trajectories every " << in.finetune.select_every << " iterations, refiner `" << in.refiner << "` ("
     << refiner_kind(in.refiner).description << (refiner_kind(in.refiner).calibrated ? "; calibrated before any strategy ran with it, see the calibration below" : "")
     << ") with artifacts (strength " << in.artifact_strength << "). Baselines use ExploreGS weights (the paper's protocol); FillGS its own.\n\n";
  // The result as measured, in one sentence.
  auto find = [&](const std::string& id) -> const RunResult* {
    for (const RunResult& r : in.results)
      if (r.id == id) return &r;
    return nullptr;
  };
  const RunResult* ours = find("fillgs");
  const RunResult* control = find("no-refinement");
  const RunResult* other = nullptr;
  for (const std::string& id : in.run_ids)
    if (id != "fillgs" && id != "no-refinement") other = find(id);
  if (ours && control && other) {
    auto signed_db = [](double x) { return (x >= 0 ? "+" : "") + fmt(x) + " dB"; };
    md << "**Measured here:** FillGS " << fmt(ours->interpolation.psnr) << " / " << fmt(ours->extrapolation.psnr) << " dB (interpolation / "
       << "extrapolation), " << other->id << " " << fmt(other->interpolation.psnr) << " / " << fmt(other->extrapolation.psnr)
       << " dB, no generated views " << fmt(control->interpolation.psnr) << " / " << fmt(control->extrapolation.psnr) << " dB: FillGS "
       << signed_db(ours->interpolation.psnr - other->interpolation.psnr) << " / " << signed_db(ours->extrapolation.psnr - other->extrapolation.psnr)
       << " against " << other->id << ", " << signed_db(ours->interpolation.psnr - control->interpolation.psnr) << " / "
       << signed_db(ours->extrapolation.psnr - control->extrapolation.psnr)
       << " against the control. One seed; the benchmark's tables over three seeds are in bench/results/README.md.\n\n";
  }
  md << "| Method | Interp PSNR | SSIM | moving PSNR | Extrap PSNR | SSIM | moving PSNR | Train PSNR | seconds |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const RunResult& r : in.results) {
    md << "| " << r.id << " | " << fmt(r.interpolation.psnr) << " | " << fmt(r.interpolation.ssim, 3) << " | " << fmt(r.interpolation.psnr_moving)
       << " | " << fmt(r.extrapolation.psnr) << " | " << fmt(r.extrapolation.ssim, 3) << " | " << fmt(r.extrapolation.psnr_moving) << " | "
       << fmt(r.train.psnr) << " | " << fmt(r.seconds_total, 0) << " |\n";
  }
  md << "\n## Renders\n\nGround truth, the backbone and each fine-tuned model at the view and moment of each split where the moving content "
        "covers most of the image.\n\n";
  for (const std::string& f : pictures) md << "![" << f << "](" << f << ")\n\n";
  for (const char* chart : {"psnr_interpolation", "psnr_extrapolation"})
    if (fs::exists(join_path(dir, std::string(chart) + ".png"))) md << "![" << chart << "](" << chart << ".png)\n\n";
  // What the refiner made of these runs' views against the truth.
  std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>> records;
  for (const std::string& id : in.run_ids) {
    const std::string csv = join_path(join_path(join_path(in.scene->dir, "runs"), id), "refined_views.csv");
    if (fs::exists(csv)) records.emplace_back(id, read_refined_view_records(csv));
  }
  write_refiner_calibration(join_path(dir, "refiner"), records, "the refiner on this run's views");
  if (fs::exists(join_path(dir, "refiner.png")))
    md << "## The refiner\n\nEach refined view against the truth, by the parallax angle to the start view it was conditioned on (the "
          "benchmark's calibration on random views: bench/results/README.md, \"Calibrating the refiner\").\n\n![refiner](refiner.png)\n\n"
       << read_file(join_path(dir, "refiner.md")) << "\n";
  // The virtual views each strategy chose (top view), copied beside the report.
  md << "## Virtual views\n\n";
  for (const std::string& id : in.run_ids) {
    const std::string from = join_path(join_path(join_path(in.scene->dir, "runs"), id), "views.png"), file = "views_" + id + ".png";
    std::error_code ec;
    if (id != "no-refinement" && fs::exists(from, ec) && fs::copy_file(from, join_path(dir, file), fs::copy_options::overwrite_existing, ec))
      md << "![" << file << "](" << file << ")\n\n";
  }
  md << "## Command\n\n```\n" << in.command << "\n```\n\n";
  md << "Per-run folders (patches, refined views with their support, consistency mask, co-visibility and weight images): `"
     << join_path(in.scene->dir, "runs") << "`.\n";
  write_file_atomically(join_path(dir, "report.md"), md.str());
  write_html_report(join_path(dir, "report.md"), join_path(dir, "report.html"));
}

}  // namespace fillgs
