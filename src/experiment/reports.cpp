// What the commands write beside their results (reports.hpp).
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/camera_io.hpp"

#include <algorithm>
#include <cmath>

#include "fillgs/io/camera_json.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/base/memory.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/visibility/observe_io.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/base/timing.hpp"

namespace fillgs {

void write_loss_png(const std::string& path, const std::vector<float>& history, const std::string& title) {
  ScatterSeries loss{"loss", {}, {}, {}};
  const size_t every = std::max<size_t>(1, history.size() / 400);
  for (size_t i = 0; i < history.size(); i += every) loss.x.push_back(double(i + 1)), loss.y.push_back(history[i]);
  write_scatter_png(path, {loss}, {title, "iteration", "loss"}, false);
}

void write_metrics_json(const std::string& path, const std::vector<SplitMetrics>& splits) {
  nlohmann::json j = nlohmann::json::object();
  auto num = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  for (const SplitMetrics& m : splits) {
    // Every view's metrics, as rows (a per-camera table pools them; the moving region's
    // squared error and pixels add up to the split's).
    nlohmann::json rows = nlohmann::json::array();
    for (const ViewMetrics& v : m.per_view)
      rows.push_back({v.camera, v.frame, v.psnr, v.ssim, num(v.psnr_ls_gain), num(v.psnr_affine), v.moving_squared_error, v.moving_pixels});
    j[m.split] = {{"views", m.views}, {"psnr", m.psnr}, {"ssim", m.ssim}, {"psnr_moving", num(m.psnr_moving)},
                  {"moving_pixels", m.moving_pixels}, {"lpips", num(m.lpips)}, {"psnr_ls_gain", num(m.psnr_ls_gain)},
                  {"psnr_affine", num(m.psnr_affine)},
                  {"per_view_columns", {"camera", "frame", "psnr", "ssim", "psnr_ls_gain", "psnr_affine", "moving_squared_error", "moving_pixels"}},
                  {"per_view", rows}};
  }
  write_file_atomically(path, j.dump(2) + "\n");
}

// ------------------------------------------------------------------ exploration

nlohmann::json exploration_summary(const ExplorationGrid& g, const ExplorationStats* s) {
  const auto c = g.counts();
  nlohmann::json j = {{"box_min", {g.box().lo.x(), g.box().lo.y(), g.box().lo.z()}},
                      {"box_max", {g.box().hi.x(), g.box().hi.y(), g.box().hi.z()}},
                      {"divisions", {g.dims().x(), g.dims().y(), g.dims().z()}},
                      {"voxel_size", {g.voxel_size().x(), g.voxel_size().y(), g.voxel_size().z()}},
                      {"step", g.step()},
                      {"free", c[0]},
                      {"occupied", c[1]},
                      {"unexplored", c[2]}};
  if (s) {
    j["occupied_by_static"] = s->occupied_by_static;
    j["occupying_gaussians"] = s->occupying_gaussians;
    j["sweep_time_samples"] = s->time_samples;
    j["seconds"] = s->seconds;
  }
  return j;
}

void write_exploration(const std::string& dir, const ExplorationGrid& grid, const std::vector<Camera>& cameras, const ExplorationStats& stats,
                       double seconds) {
  grid.write(join_path(dir, "exploration.vdb"));
  write_topdown_png(join_path(dir, "exploration.png"), topdown_slice(grid, cameras), cameras, {}, "exploration space");
  const nlohmann::json j = {{"command", "explore"}, {"grid", exploration_summary(grid, &stats)}, {"seconds", seconds}};
  write_file_atomically(join_path(dir, "summary.json"), j.dump(2) + "\n");
}

// ------------------------------------------------------------------ selection

SelectionReport write_selection(const std::string& dir, const SelectInput& in, const SelectOptions& o, const SelectResult& r,
                                const ExplorationGrid& grid, const std::vector<Camera>& cams, const SelectionReportOptions& report,
                                Progress& progress) {
  std::vector<Camera> virtual_cams;
  nlohmann::json trajs = nlohmann::json::array(), flat = nlohmann::json::array();
  for (const Trajectory& tr : r.trajectories) {
    const ObservedView* sv = tr.start_view >= 0 ? &in.views[size_t(tr.start_view)] : nullptr;
    nlohmann::json start = sv ? nlohmann::json{{"camera", sv->camera.name}, {"frame", sv->frame}, {"time", sv->camera.time}} : nlohmann::json();
    nlohmann::json poses = nlohmann::json::array();
    for (size_t j = 0; j < tr.poses.size(); ++j) poses.push_back({{"camera", camera_json(tr.poses[j])}, {"score", tr.scores[j]}});
    trajs.push_back({{"index", tr.index}, {"frame", tr.frame}, {"global", tr.global}, {"start", start}, {"patch_frames", tr.patch_frames},
                     {"poses", poses}});
    const std::vector<Camera> views = tr.views();
    for (size_t v = 0; v < views.size(); ++v) {
      const size_t pose = v / tr.patch_frames.size();
      nlohmann::json cj = camera_json(views[v]);
      cj["trajectory"] = tr.index;
      cj["pose"] = pose;
      cj["frame"] = tr.patch_frames[v % tr.patch_frames.size()];
      cj["start"] = start;
      cj["score"] = tr.scores[pose];
      flat.push_back(cj);
      Camera c = views[v];
      c.image_path = "renders/" + c.name + ".png";
      virtual_cams.push_back(c);
    }
  }
  nlohmann::json tj = {{"strategy", o.strategy}, {"seed", o.seed}, {"frames", in.frames},
                       {"deficiency_scale", r.deficiency_scale}, {"trajectories", trajs}, {"cameras", flat}};
  write_file_atomically(join_path(dir, "trajectories.json"), tj.dump(2) + "\n");
  write_transforms_json(join_path(dir, "transforms.json"), virtual_cams);
  if (!virtual_cams.empty()) write_colmap_text(join_path(dir, "colmap"), virtual_cams);

  // Renders: RGB and the normalised deficiency D̂ (initial tables) of every virtual view.
  double mean_selected_deficiency = 0;
  if (report.renders && !virtual_cams.empty()) {
    DeficiencyField field(r.initial_tables, o.deficiency_quantile);
    FrameSampler ev(*in.scene);
    progress.start("renders", virtual_cams.size());
    for (const Camera& c : virtual_cams) {
      const int f = FrameGrid(in.frames).nearest(c.time);
      const std::vector<float> d = field.values(f, CandidateScore::Deficiency);
      RenderOptions ro;
      ro.features = d.data();
      ro.feature_channels = 1;
      ro.background = in.background;
      const RenderOutput img = render(ev.at(c.time), c, ro);
      const Image rgb(c.width, c.height, 3, img.rgb), dmap(c.width, c.height, 1, img.features);
      for (float v : img.features) mean_selected_deficiency += v / double(img.features.size() * virtual_cams.size());
      write_image(join_path(dir, "renders/" + c.name + ".png"), rgb);
      write_image(join_path(dir, "renders/" + c.name + "_D.png"), dmap);
      progress.advance();
    }
    progress.finish();
  }

  // Priority scores as arrays [pose][frame] (NaN where not evaluated) and heatmaps.
  nlohmann::json prio;
  if (!r.priority.views.empty()) {
    uint32_t poses = 0;
    for (const ObservedView& v : in.views) poses = std::max(poses, v.pose + 1);
    const size_t F = size_t(in.frames);
    auto table = [&](const std::vector<double>& per_view) {
      std::vector<float> t(poses * F, std::nanf(""));
      for (size_t k = 0; k < r.priority.views.size(); ++k) {
        const ObservedView& v = in.views[r.priority.views[k]];
        t[v.pose * F + size_t(v.frame)] = float(per_view[k]);
      }
      return t;
    };
    std::vector<double> V(r.priority.views.size());
    for (size_t k = 0; k < V.size(); ++k) V[k] = r.priority.translation[k] + r.priority.rotation[k] + r.priority.time[k];
    const std::vector<float> E = table(r.priority.priority);
    write_npy(join_path(dir, "priority_E.npy"), E.data(), {poses, F});
    write_npy(join_path(dir, "priority_L.npy"), table(r.priority.error).data(), {poses, F});
    write_npy(join_path(dir, "priority_V.npy"), table(V).data(), {poses, F});
    write_npy(join_path(dir, "priority_V_time.npy"), table(r.priority.time).data(), {poses, F});
    std::vector<float> shown = E;
    for (float& x : shown)
      if (std::isnan(x)) x = 0;
    std::vector<double> per_camera(poses, 0.0), per_frame(F, 0.0);
    std::vector<int> nc(poses, 0), nf(F, 0);
    for (size_t p = 0; p < poses; ++p)
      for (size_t f = 0; f < F; ++f)
        if (!std::isnan(E[p * F + f])) per_camera[p] += E[p * F + f], per_frame[f] += E[p * F + f], ++nc[p], ++nf[f];
    std::vector<std::string> cam_names(poses), frame_names(F);
    for (const ObservedView& v : in.views) cam_names[v.pose] = v.camera.name.substr(0, v.camera.name.find('/'));
    for (size_t p = 0; p < poses; ++p) per_camera[p] /= std::max(1, nc[p]);
    for (size_t f = 0; f < F; ++f) per_frame[f] /= std::max(1, nf[f]), frame_names[f] = std::to_string(f);
    write_heatmap_png(join_path(dir, "priority_heatmap.png"), shown, int(poses), int(F),
                      {"exploration priority E = L + V (rows: cameras, columns: frames)", "frame", "camera"}, &per_camera);
    write_bar_chart_png(join_path(dir, "priority_over_cameras.png"), cam_names, per_camera, {"mean E per camera", "camera", "E"});
    write_bar_chart_png(join_path(dir, "priority_over_time.png"), frame_names, per_frame, {"mean E per frame", "frame", "E"});
    prio = {{"evaluated_views", r.priority.views.size()}, {"seconds", r.priority.seconds}};
  }
  write_topdown_png(join_path(dir, "trajectories.png"), topdown_slice(grid, cams), cams, virtual_cams,
                    std::string("strategy ") + o.strategy + ": " + std::to_string(r.trajectories.size()) + " trajectories");

  const SelectTimings& tm = r.timings;
  nlohmann::json s = {{"command", "select"},
                      {"strategy", o.strategy},
                      {"seed", o.seed},
                      {"trajectories", r.trajectories.size()},
                      {"virtual_views", virtual_cams.size()},
                      {"mean_deficiency_of_selected_views", mean_selected_deficiency},
                      {"grid", exploration_summary(grid, report.grid_stats)},
                      {"priority", prio},
                      {"notes", r.notes},
                      {"seconds",
                       {{"grid", report.grid_seconds},
                        {"observe", tm.observe},
                        {"priority", tm.priority},
                        {"candidates", tm.candidates},
                        {"scoring", tm.scoring},
                        {"update", tm.update},
                        {"select_total", tm.total},
                        {"total", seconds_since(report.started)}}},
                      {"candidates_scored", tm.candidates_scored},
                      {"candidates_rejected", tm.candidates_rejected}};
  write_file_atomically(join_path(dir, "summary.json"), s.dump(2) + "\n");
  return {virtual_cams.size(), mean_selected_deficiency};
}

// ------------------------------------------------------------------ training

TrainingReport write_training_report(const std::string& dir, const Trainer& trainer, const GaussianCloud& model, const Dataset& data,
                                     const TrainOptions& o, const Dataset* test, double seconds) {
  TrainingReport report;
  nlohmann::json j;
  j["iterations"] = trainer.iteration();
  j["seconds"] = seconds;
  j["views"] = data.views().size();
  j["cameras"] = data.rigs();
  j["frames"] = data.frames();
  j["gaussians"] = model.size();
  j["moving_gaussians"] = model.dynamic_count();
  j["final_loss_ema"] = trainer.status().loss;
  j["motion"] = {{"learning", to_string(o.motion)}, {"keyed_opacity", o.keyed_opacity}, {"time_ramp", o.time_ramp},
                 {"key_lr_scale", o.key_lr_scale}, {"motion_sparsity", o.motion_sparsity}, {"key_interval_frames", o.key_interval_frames},
                 {"flow_keys", o.flow_keys}, {"keys_placed_by_flow", trainer.flow_placed().first}};
  nlohmann::json dens = nlohmann::json::array();
  for (const DensifyRecord& r : trainer.densify_log())
    dens.push_back({{"iteration", r.iteration}, {"gaussians", r.gaussians}, {"keyed", r.dynamic}, {"promoted", r.promoted},
                    {"cloned", r.cloned}, {"split", r.split}, {"pruned", r.pruned}});
  j["densification"] = dens;
  // How often each real photograph was drawn: what a time curriculum or a view count does to
  // a photograph's exposure (the pool benchmark reads the chosen photographs' from here).
  const std::vector<uint32_t>& draws = trainer.view_draws();
  if (draws.size() == data.views().size() && !draws.empty()) {
    nlohmann::json per = nlohmann::json::array();
    for (size_t v = 0; v < draws.size(); ++v) per.push_back({data.views()[v].rig, data.views()[v].frame, draws[v]});
    const auto [lo, hi] = std::minmax_element(draws.begin(), draws.end());
    double sum = 0;
    for (uint32_t d : draws) sum += d;
    j["draws"] = {{"min", *lo}, {"max", *hi}, {"mean", sum / double(draws.size())}, {"per_view", per},
                  {"per_view_columns", {"camera", "frame", "draws"}}};
  }
  report.train = evaluate_training_sample(model, data, o.background);
  j["train_psnr"] = report.train.psnr;
  j["train_ssim"] = report.train.ssim;
  if (test) {
    EvalOptions eo;
    eo.background = o.background;
    eo.moving = false;
    report.test = evaluate_split(model, *test, "test", eo);
    j["test_psnr"] = report.test.psnr;
    j["test_ssim"] = report.test.ssim;
    j["test_views"] = report.test.views;
  }
  // Peak resident memory of the whole run (images held 8-bit, the model, the optimiser).
  report.peak_memory_bytes = peak_memory_bytes();
  j["peak_memory_bytes"] = report.peak_memory_bytes;
  j["images"] = {{"bytes", data.image_bytes()}, {"spilled", data.images_spilled()}};
  write_loss_png(join_path(dir, "loss.png"), trainer.loss_history(), "training loss (L1 + 0.2 D-SSIM)");
  write_file_atomically(join_path(dir, "summary.json"), j.dump(2) + "\n");
  return report;
}

FinetuneReport write_finetune_report(const std::string& dir, const FinetuneResult& r, const Dataset& data, const FinetuneOptions& o,
                                     const std::string& refiner, double seconds) {
  FinetuneReport report;
  write_fillgs_ply(join_path(dir, "model.ply"), r.model, data.frames());
  if (!r.colour_correction.empty()) write_colour_correction(join_path(dir, "colour_correction.json"), r.colour_correction);
  write_transforms_json(join_path(dir, "virtual_views.json"), r.virtual_views);
  nlohmann::json rounds = nlohmann::json::array();
  for (const FinetuneRound& rd : r.rounds) {
    nlohmann::json f = nlohmann::json::array();
    for (const auto& [patch, why] : rd.refine_failures) f.push_back({{"patch", patch}, {"error", why}});
    rounds.push_back({{"iteration", rd.iteration},
                      {"trajectories", rd.trajectories},
                      {"views_added", rd.views_added},
                      {"views_dropped", rd.views_dropped},
                      {"mean_weight", rd.mean_weight},
                      {"refine_failures", f},
                      {"notes", rd.notes},
                      {"seconds", {{"select", rd.seconds_select}, {"render", rd.seconds_render}, {"refine", rd.seconds_refine},
                                   {"weights", rd.seconds_weights}}}});
    report.dropped += rd.views_dropped;
  }
  report.train = evaluate_training_sample(r.model, data, Vec3f::Zero());
  nlohmann::json j = {{"iterations", o.iterations}, {"select_every", o.select_every}, {"trajectories_per_round", o.trajectories},
                            {"strategy", o.select.strategy}, {"weighting", to_string(o.weighting)}, {"refiner", refiner},
                            {"rounds", rounds}, {"virtual_views", r.virtual_views.size()}, {"virtual_views_dropped", report.dropped},
                            {"train_psnr", report.train.psnr}, {"train_ssim", report.train.ssim}, {"gaussians", r.model.size()},
                            {"moving_gaussians", r.model.dynamic_count()}, {"seconds", {{"train", r.seconds_train}, {"total", seconds}}}};
  if (r.keys.keys > 0)
    j["keys"] = {{"count", r.keys.keys}, {"interval_frames", r.keys.interval}, {"frames", r.keys.frames},
                 {"worst_position_error", r.keys.worst_error}, {"worst_share_of_tolerance", r.keys.worst_share},
                 {"decided_by", r.keys.limiting}, {"colour_change", r.keys.colour_change}, {"keyed_sh_bands", r.keys.keyed_bands}, {"sample_gaussians", r.keys.sample}};
  if (o.pool) {  // real photographs instead of trajectories
    j.erase("trajectories_per_round");
    j["pool_budget"] = o.pool_budget;
  }
  write_loss_png(join_path(dir, "loss.png"), r.loss_history, "fine-tuning loss (weighted on refined views)");
  write_file_atomically(join_path(dir, "summary.json"), j.dump(2) + "\n");
  return report;
}

FinetuneReport write_finetune_job_report(const std::string& dir, const FinetuneJobResult& r, const Dataset& data) {
  const FinetuneReport report = write_finetune_report(dir, r.result, data, r.options, r.refiner, r.seconds);
  if (r.pool && r.options.pool_budget > 0) write_pool_report(dir, r.result, *r.pool, r.options.select.strategy);
  return report;
}

void write_pool_report(const std::string& dir, const FinetuneResult& r, const Dataset& pool, const std::string& strategy) {
  std::vector<std::string> rigs;  // pool cameras in first-seen order
  auto row_of = [&](const std::string& rig) {
    const auto it = std::find(rigs.begin(), rigs.end(), rig);
    if (it != rigs.end()) return size_t(it - rigs.begin());
    rigs.push_back(rig);
    return rigs.size() - 1;
  };
  for (const TrainView& v : pool.views()) row_of(v.rig);
  const int F = pool.frames();
  std::vector<float> cells(rigs.size() * size_t(F), 0.0f);
  std::vector<double> per_camera(rigs.size(), 0.0);
  nlohmann::json chosen = nlohmann::json::array();
  for (const PoolPick& p : r.pool_chosen) {
    const TrainView& v = pool.views().at(p.view);
    const size_t row = row_of(v.rig);
    cells[row * size_t(F) + size_t(v.frame)] = float(p.round + 1);
    per_camera[row] += 1;
    chosen.push_back({{"camera", v.rig}, {"frame", v.frame}, {"score", p.score}, {"round", p.round}});
  }
  const nlohmann::json j = {{"strategy", strategy}, {"cameras", rigs}, {"frames", F}, {"chosen", chosen}};
  write_file_atomically(join_path(dir, "pool_chosen.json"), j.dump(2) + "\n");
  PlotLabels labels{strategy + ": the pool's camera-times chosen (the round + 1)", "frame", "pool camera"};
  labels.row_names = rigs;
  write_heatmap_png(join_path(dir, "pool_chosen.png"), cells, int(rigs.size()), F, labels, &per_camera);
}

}  // namespace fillgs
