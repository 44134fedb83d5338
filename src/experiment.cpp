#include "fillgs/experiment.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <ostream>
#include <set>
#include <sstream>

#include "fillgs/error.hpp"
#include "fillgs/timing.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/plot.hpp"
#include "fillgs/scene_io.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace fillgs {

namespace {


json options_json(const ExperimentOptions& o) {
  return {{"variant", o.variant},
          {"seed", o.seed},
          {"width", o.width},
          {"height", o.height},
          {"frames", o.frames},
          {"train_cameras", o.train_cameras},
          {"interpolation_cameras", o.interpolation_cameras},
          {"extrapolation_cameras", o.extrapolation_cameras},
          {"backbone_iterations", o.backbone_iterations}};
}

/// Every frame of the named rig cameras (looked up in the scene's splits), for a Dataset.
std::vector<Camera> split_cameras(const SynthScene& s, const std::vector<std::string>& names) {
  std::vector<Camera> rig;
  for (const std::string& n : names) {
    const Camera* found = nullptr;
    for (const auto* list : {&s.train, &s.interpolation, &s.extrapolation})
      for (const Camera& c : *list)
        if (c.name == n) found = &c;
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
          {"group", r.group},
          {"variant", r.variant},
          {"seed", r.seed},
          {"interpolation", metrics_json(r.interpolation)},
          {"extrapolation", metrics_json(r.extrapolation)},
          {"train", metrics_json(r.train)},
          {"trajectories", r.trajectories},
          {"views_added", r.views_added},
          {"mean_weight", r.mean_weight},
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
  r.group = j.at("group");
  r.variant = j.at("variant");
  r.seed = j.at("seed");
  r.interpolation = metrics_from(j.at("interpolation"), "interpolation");
  r.extrapolation = metrics_from(j.at("extrapolation"), "extrapolation");
  r.train = metrics_from(j.at("train"), "train");
  r.trajectories = j.at("trajectories");
  r.views_added = j.at("views_added");
  r.mean_weight = j.at("mean_weight");
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

}  // namespace

void save_result(const std::string& path, const RunResult& r) { write_file_atomically(path, result_json(r).dump(1) + "\n"); }

RunResult load_result(const std::string& path) {
  try {
    return result_from(json::parse(read_file(path)));
  } catch (const json::exception& e) {
    throw_error(path, ": not a fillgs result (", e.what(), ")");
  }
}

std::vector<RunResult> collect_results(const std::string& root) {
  std::vector<std::string> order = {"backbone"};
  for (const RunConfig& c : standard_configs()) order.push_back(c.id);
  std::vector<std::pair<std::string, RunResult>> found;
  if (!fs::is_directory(root)) return {};
  std::vector<fs::path> scenes;
  for (const auto& e : fs::directory_iterator(root))
    if (e.is_directory() && fs::exists(e.path() / "options.json")) scenes.push_back(e.path());
  std::sort(scenes.begin(), scenes.end());
  std::vector<RunResult> out;
  for (const fs::path& sc : scenes) {
    std::vector<RunResult> rs;
    if (fs::exists(sc / "backbone" / "result.json")) rs.push_back(load_result((sc / "backbone" / "result.json").string()));
    if (fs::is_directory(sc / "runs"))
      for (const auto& e : fs::directory_iterator(sc / "runs"))
        if (fs::exists(e.path() / "result.json")) rs.push_back(load_result((e.path() / "result.json").string()));
    auto rank = [&](const std::string& id) { return size_t(std::find(order.begin(), order.end(), id) - order.begin()); };
    std::sort(rs.begin(), rs.end(), [&](const RunResult& a, const RunResult& b) { return rank(a.id) != rank(b.id) ? rank(a.id) < rank(b.id) : a.id < b.id; });
    out.insert(out.end(), rs.begin(), rs.end());
  }
  return out;
}

PreparedScene prepare_scene(const std::string& root, const ExperimentOptions& o, Progress& progress, std::ostream& log) {
  PreparedScene p;
  p.dir = join_path(root, o.variant + "_s" + std::to_string(o.seed));
  const std::string scene_dir = join_path(p.dir, "scene"), stamp_path = join_path(p.dir, "options.json");
  const json stamp = options_json(o);
  if (fs::exists(stamp_path)) {
    const json old = json::parse(read_file(stamp_path));
    if (old != stamp)
      throw_error(stamp_path, ": this folder holds a run made with other options (", old.dump(), "); use another --out");
  }
  make_directories(p.dir);
  SynthOptions so;
  so.variant = o.variant;
  so.seed = o.seed;
  so.width = o.width;
  so.height = o.height;
  so.frames = o.frames;
  auto t0 = Clock::now();
  p.synth = make_synthetic_scene(so);
  p.reused_scene = fs::exists(join_path(scene_dir, "synth.json")) && fs::exists(stamp_path);
  if (!p.reused_scene) {
    write_synthetic_scene(p.synth, scene_dir, progress, o.threads);
    write_file_atomically(stamp_path, stamp.dump(1) + "\n");
    p.seconds_synth = seconds_since(t0);
    log << "scene " << o.variant << " (seed " << o.seed << "): " << p.synth.scene.size() << " Gaussians, " << p.synth.scene.dynamic_count()
        << " moving, " << o.width << "x" << o.height << ", " << o.frames << " frames, rendered in " << fmt(p.seconds_synth, 1) << " s" << std::endl;
  }
  DatasetOptions dopt;
  dopt.cameras = o.train_cameras;
  p.train = std::make_unique<Dataset>(Dataset::load(scene_dir, join_path(scene_dir, "transforms_train.json"), dopt));
  p.interpolation = load_split(p.dir, scene_dir, p.synth, "interpolation", o.interpolation_cameras);
  p.extrapolation = load_split(p.dir, scene_dir, p.synth, "extrapolation", o.extrapolation_cameras);

  const std::string bb = join_path(p.dir, "backbone");
  const std::string model_path = join_path(bb, "model.ply");
  if (fs::exists(model_path)) {
    p.backbone = read_scene(model_path);
    p.reused_backbone = true;
    log << "backbone reused: " << model_path << "\n";
    return p;
  }
  t0 = Clock::now();
  TrainOptions to = TrainOptions::scaled(o.backbone_iterations);
  to.seed = o.seed;
  to.threads = o.threads;
  Trainer trainer(*p.train, init_from_points(read_points(join_path(scene_dir, "points.ply"))), to);
  trainer.run(o.backbone_iterations, progress);
  p.backbone = trainer.model();
  p.seconds_backbone = seconds_since(t0);
  make_directories(bb);
  write_fillgs_ply(model_path, p.backbone, o.frames);
  const json summary = {{"iterations", o.backbone_iterations},
                        {"seconds", p.seconds_backbone},
                        {"gaussians", p.backbone.size()},
                        {"moving_gaussians", p.backbone.dynamic_count()},
                        {"train_cameras", o.train_cameras}};
  write_file_atomically(join_path(bb, "summary.json"), summary.dump(1) + "\n");
  log << "backbone: " << o.backbone_iterations << " iterations on " << p.train->views().size() << " views ("
      << p.train->rigs().size() << " cameras) in " << fmt(p.seconds_backbone, 1) << " s, " << p.backbone.size() << " Gaussians ("
      << p.backbone.dynamic_count() << " moving)" << std::endl;
  return p;
}

std::vector<RunConfig> standard_configs(Weighting baseline_weighting, double strength) {
  std::vector<RunConfig> out;
  auto add = [&](const std::string& id, const std::string& group, Strategy s, Weighting w, double a, int k) {
    RunConfig c;
    c.id = id;
    c.group = group;
    c.select.strategy = s;
    c.weighting = w;
    c.artifact_strength = a;
    c.trajectories = k;
    out.push_back(c);
    return &out.back();
  };
  add("no-refinement", "control", Strategy::FillGS, Weighting::None, strength, 0);
  const Strategy all[] = {Strategy::FillGS,     Strategy::Random,     Strategy::Negative,  Strategy::Interpolation,
                          Strategy::FisherRF,   Strategy::Coverage3D, Strategy::Coverage4D};
  for (Strategy s : all) add(to_string(s), "strategy", s, s == Strategy::FillGS ? Weighting::FillGS : baseline_weighting, strength, 5);
  const char* ablations[] = {"no-start-selection", "no-error-term", "no-sensitivity-term", "no-candidate-scoring",
                             "no-global",          "count-only",    "speed-only"};
  for (const char* a : ablations) {
    RunConfig* c = add(std::string("fillgs.") + a, "ablation", Strategy::FillGS, Weighting::FillGS, strength, 5);
    const std::string n = a;
    c->select.no_start_selection = n == "no-start-selection";
    c->select.no_error_term = n == "no-error-term";
    c->select.no_sensitivity_term = n == "no-sensitivity-term";
    c->select.no_candidate_scoring = n == "no-candidate-scoring";
    c->select.no_global = n == "no-global";
    if (n == "count-only") c->select.score = CandidateScore::CountOnly;
    if (n == "speed-only") c->select.score = CandidateScore::SpeedOnly;
  }
  for (Weighting w : {Weighting::None, Weighting::NoConsistency, Weighting::NoCovisibility, Weighting::Enhancer3DGS, Weighting::ExploreGS,
                      Weighting::UA4DGS})
    add(std::string("fillgs.w-") + to_string(w), "weighting", Strategy::FillGS, w, strength, 5);
  // fillgs's own options beyond the paper: model-independent sweep matching, density weight on static content.
  add("fillgs.m-sweep", "weighting", Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.method = MaskMethod::Sweep;
  add("fillgs.covis-static-count", "weighting", Strategy::FillGS, Weighting::FillGS, strength, 5)->mask.static_count = true;
  {
    RunConfig* c = add("fillgs.sweep+static-count", "weighting", Strategy::FillGS, Weighting::FillGS, strength, 5);
    c->mask.method = MaskMethod::Sweep;
    c->mask.static_count = true;
  }
  for (int k : {1, 10, 20}) add("fillgs.k" + std::to_string(k), "budget", Strategy::FillGS, Weighting::FillGS, strength, k);
  for (Strategy s : all)
    add(std::string(to_string(s)) + ".clean", "refiner", s, s == Strategy::FillGS ? Weighting::FillGS : baseline_weighting, 0.0, 5);
  return out;
}

RunResult evaluate_model(const PreparedScene& p, const GaussianCloud& model, const std::string& id, int threads, const std::string& save_dir,
                         Progress& progress) {
  const auto t0 = Clock::now();
  RunResult r;
  r.id = id;
  r.variant = p.synth.options.variant;
  r.seed = p.synth.options.seed;
  EvalOptions eo;
  eo.threads = threads;
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

RunResult run_config(const PreparedScene& p, const RunConfig& c, const FinetuneOptions& base, Progress& progress, std::ostream& log) {
  const std::string dir = join_path(join_path(p.dir, "runs"), c.id);
  const std::string result_path = join_path(dir, "result.json");
  if (fs::exists(result_path)) {
    RunResult r = load_result(result_path);
    log << c.id << ": reused " << result_path << "\n";
    return r;
  }
  const auto t0 = Clock::now();
  ArtifactOptions ao;
  ao.strength = c.artifact_strength;
  ao.seed = p.synth.options.seed;
  const std::unique_ptr<Refiner> refiner = make_oracle_refiner(p.synth.scene, ao, Vec3f::Zero(), base.threads);
  FinetuneOptions fo = base;
  fo.select = c.select;
  fo.select.seed = base.select.seed;
  fo.trajectories = c.trajectories;
  fo.weighting = c.weighting;
  fo.mask = c.mask;
  fo.work_dir = join_path(dir, "work");
  make_directories(dir);
  const FinetuneResult fr = finetune(*p.train, p.backbone, *refiner, fo, progress);
  RunResult r = evaluate_model(p, fr.model, c.id, base.threads, "", progress);
  r.group = c.group;
  r.trajectories = 0;
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
  r.seconds_train = fr.seconds_train;
  r.seconds_total = seconds_since(t0);
  write_fillgs_ply(join_path(dir, "model.ply"), fr.model, p.synth.options.frames);
  save_result(result_path, r);
  log << c.id << ": interpolation " << fmt(r.interpolation.psnr) << " dB (moving " << fmt(r.interpolation.psnr_moving) << "), extrapolation "
      << fmt(r.extrapolation.psnr) << " dB (moving " << fmt(r.extrapolation.psnr_moving) << "), train " << fmt(r.train.psnr) << " dB; "
      << r.trajectories << " trajectories, " << r.views_added << " views, mean weight " << fmt(r.mean_weight, 3) << ", "
      << fmt(r.seconds_total, 0) << " s" << std::endl;
  return r;
}

void write_bench_report(const std::string& root, const std::vector<RunResult>& results) {
  // CSV: every run.
  std::ostringstream csv;
  csv << "variant,seed,id,group,interp_psnr,interp_ssim,interp_psnr_moving,extrap_psnr,extrap_ssim,extrap_psnr_moving,train_psnr,"
         "trajectories,views_added,mean_weight,refine_failures,s_select,s_refine,s_weights,s_train,s_eval,s_total\n";
  for (const RunResult& r : results)
    csv << r.variant << "," << r.seed << "," << r.id << "," << r.group << "," << r.interpolation.psnr << "," << r.interpolation.ssim << ","
        << r.interpolation.psnr_moving << "," << r.extrapolation.psnr << "," << r.extrapolation.ssim << "," << r.extrapolation.psnr_moving
        << "," << r.train.psnr << "," << r.trajectories << "," << r.views_added << "," << r.mean_weight << "," << r.refine_failures << ","
        << r.seconds_select << "," << r.seconds_refine << "," << r.seconds_weights << "," << r.seconds_train << "," << r.seconds_eval << ","
        << r.seconds_total << "\n";
  write_file_atomically(join_path(root, "results.csv"), csv.str());

  // Means per configuration, in first-seen order.
  struct Mean {
    std::string id, group, variant;
    int n = 0;
    double v[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};  // ip is im ep es em tp weight traj
    double t[5] = {0, 0, 0, 0, 0};
  };
  std::vector<Mean> means;
  auto accumulate = [&](const RunResult& r) {
    // Means over seeds, per scene variant (variants differ too much to average).
    auto it = std::find_if(means.begin(), means.end(), [&](const Mean& m) { return m.id == r.id && m.variant == r.variant; });
    if (it == means.end()) means.push_back({r.id, r.group, r.variant}), it = means.end() - 1;
    const double x[9] = {r.interpolation.psnr, r.interpolation.ssim, r.interpolation.psnr_moving, r.extrapolation.psnr,
                         r.extrapolation.ssim,  r.extrapolation.psnr_moving, r.train.psnr, r.mean_weight, double(r.trajectories)};
    for (int k = 0; k < 9; ++k) it->v[k] += x[k];
    const double s[5] = {r.seconds_select, r.seconds_refine, r.seconds_weights, r.seconds_train, r.seconds_eval};
    for (int k = 0; k < 5; ++k) it->t[k] += s[k];
    it->n += 1;
  };
  for (const RunResult& r : results) accumulate(r);
  for (Mean& m : means) {
    for (double& x : m.v) x /= m.n;
    for (double& x : m.t) x /= m.n;
  }
  std::set<std::string> scenes;
  for (const RunResult& r : results) scenes.insert(r.variant + " seed " + std::to_string(r.seed));
  std::ostringstream md;
  md << "# fillgs bench\n\nMeans over seeds, per scene variant; " << scenes.size() << " scene run(s):";
  for (const std::string& s : scenes) md << " " << s << ";";
  md << "\nPSNR in dB. \"moving\": PSNR over the pixels of the moving object (ground truth). Train: PSNR on the 2 training cameras.\n\n";
  const char* groups[][2] = {{"control", "Without generated views"},      {"strategy", "Viewpoint selection strategies (Table 1 of the paper)"},
                             {"ablation", "FillGS selection ablations"},   {"weighting", "Fine-tuning weights (Table 4 of the paper)"},
                             {"budget", "Trajectory budget per round"},    {"refiner", "Clean oracle (no generation artifacts)"}};
  for (const auto& g : groups) {
    bool any = false;
    for (const Mean& m : means) any |= m.group == g[0] || (std::string(g[0]) == "control" && m.id == "backbone");
    if (!any) continue;
    md << "## " << g[1] << "\n\n| Scene | Method | Interp PSNR | SSIM | moving PSNR | Extrap PSNR | SSIM | moving PSNR | Train PSNR | weight | runs |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Mean& m : means) {
      if (!(m.group == g[0] || (std::string(g[0]) == "control" && m.id == "backbone"))) continue;
      md << "| " << m.variant << " | " << m.id << " | " << fmt(m.v[0]) << " | " << fmt(m.v[1], 3) << " | " << fmt(m.v[2]) << " | " << fmt(m.v[3]) << " | "
         << fmt(m.v[4], 3) << " | " << fmt(m.v[5]) << " | " << fmt(m.v[6]) << " | " << fmt(m.v[7], 3) << " | " << m.n << " |\n";
    }
    md << "\n";
  }
  md << "## Seconds per phase (mean per run)\n\n| Scene | Method | select | refine | weights | train | eval |\n|---|---|---|---|---|---|---|\n";
  for (const Mean& m : means)
    if (m.id != "backbone")
      md << "| " << m.variant << " | " << m.id << " | " << fmt(m.t[0], 1) << " | " << fmt(m.t[1], 1) << " | " << fmt(m.t[2], 1) << " | " << fmt(m.t[3], 1) << " | "
         << fmt(m.t[4], 1) << " |\n";
  write_file_atomically(join_path(root, "results.md"), md.str());

  // Plots.
  // Plots: the first scene variant (the chair scene when present).
  const std::string plotted = means.empty() ? "" : means.front().variant;
  std::vector<std::string> names;
  std::vector<double> interp, extrap;
  for (const Mean& m : means)
    if (m.variant == plotted && (m.group == "strategy" || m.group == "control" || m.id == "backbone"))
      names.push_back(m.id), interp.push_back(m.v[0]), extrap.push_back(m.v[3]);
  if (!names.empty()) {
    write_bar_chart_png(join_path(root, "psnr_interpolation.png"), names, interp, {"interpolation PSNR per strategy (" + plotted + ")", "", "PSNR (dB)"});
    write_bar_chart_png(join_path(root, "psnr_extrapolation.png"), names, extrap, {"extrapolation PSNR per strategy (" + plotted + ")", "", "PSNR (dB)"});
  }
  ScatterSeries bi{"interpolation", {}, {}, {}}, be{"extrapolation", {}, {}, {}};
  for (const Mean& m : means)
    if (m.variant == plotted && (m.group == "budget" || m.id == "fillgs")) {
      const double k = m.v[8];  // trajectories selected over all rounds
      bi.x.push_back(k), bi.y.push_back(m.v[0]);
      be.x.push_back(k), be.y.push_back(m.v[3]);
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
}

}  // namespace fillgs
