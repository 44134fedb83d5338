// fillgs explore and fillgs select.
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>

#include "common.hpp"
#include "commands.hpp"
#include "fillgs/camera_json.hpp"
#include "fillgs/exploration.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/image_io.hpp"
#include "fillgs/npy.hpp"
#include "fillgs/plot.hpp"
#include "fillgs/raster.hpp"
#include "fillgs/select.hpp"
#include "fillgs/train.hpp"
#include "progress_bar.hpp"

namespace fillgs::cli {

namespace {

const std::set<std::string> kGridOptions = {"divisions", "occupancy-alpha", "grid"};

ExplorationOptions exploration_options(const Args& a) {
  ExplorationOptions o;
  o.divisions = a.integer("divisions", o.divisions);
  o.occupancy_alpha = float(a.number("occupancy-alpha", o.occupancy_alpha));
  o.threads = a.threads();
  return o;
}

nlohmann::json grid_json(const ExplorationGrid& g, const ExplorationStats* s) {
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

/// Training viewpoints with times: every camera entry with a time, a rig expanded over frames.
std::vector<Camera> timed_cameras(const std::vector<Camera>& cams, int frames) {
  std::vector<Camera> out;
  for (const ObservedView& v : observed_views(cams, frames)) out.push_back(v.camera);
  return out;
}


}  // namespace

int cmd_explore(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("explore", args, 1, merge(merge(merge({"scene", "cameras", "out", "frames", "threads"}, kGridOptions), kSceneOptions), kCameraOptions),
         {"quiet"});
  const auto t0 = Clock::now();
  const std::string out_dir = a.require("out");
  const GaussianCloud cloud = read_scene(a.require("scene"), scene_options(a));
  const std::vector<Camera> cams = read_cameras(a.require("cameras"), camera_options(a));
  if (cams.empty()) throw_error(a.get("cameras"), ": no cameras");
  std::vector<double> sweep;
  if (a.has("frames")) sweep = frame_times(a.integer("frames", 2));
  TerminalProgress progress(err, progress_enabled(a));
  ExplorationStats stats;
  const ExplorationGrid grid = ExplorationGrid::build(cloud, cams, sweep, exploration_options(a), &stats, progress);
  OutputFolder folder(out_dir);  // a failed or killed run leaves the folder as it was
  grid.write(join_path(folder.path(), "exploration.vdb"));
  write_topdown_png(join_path(folder.path(), "exploration.png"), grid, cams, {}, "exploration space");
  nlohmann::json j = {{"command", "explore"}, {"grid", grid_json(grid, &stats)}, {"seconds", seconds_since(t0)}};
  write_file_atomically(join_path(folder.path(), "summary.json"), j.dump(2) + "\n");
  folder.commit();
  out << "exploration grid " << grid.dims().x() << "^3 over [" << grid.box().lo.transpose() << "] .. [" << grid.box().hi.transpose()
      << "]: " << stats.occupied << " occupied (" << stats.occupied_by_static << " by static Gaussians), " << stats.unexplored
      << " unexplored, " << stats.free << " free; step " << grid.step() << " -> " << out_dir << " (" << seconds_since(t0) << " s)\n";
  return 0;
}

int cmd_select(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  Args a("select", args, 1,
         merge(merge(merge({"scene", "cameras", "images", "out", "strategy", "trajectories", "seed", "threads", "frames", "views",
                            "patch-frames", "time-stride", "render-scale", "renderer", "stride", "global-candidates", "mode", "background"},
                           kGridOptions),
                     kSceneOptions),
               kCameraOptions),
         {"quiet", "no-start-selection", "no-error-term", "no-sensitivity-term", "no-candidate-scoring", "no-global", "count-only",
          "speed-only", "no-renders"});
  const auto t0 = Clock::now();
  const std::string out_dir = a.require("out");
  SelectOptions o;
  o.strategy = parse_strategy(a.get("strategy", "fillgs"));
  o.trajectories = a.integer("trajectories", o.trajectories);
  o.seed = uint64_t(a.integer("seed", int(o.seed)));
  o.threads = a.threads();
  o.views = a.integer("views", o.views);
  o.patch_frames = a.integer("patch-frames", o.patch_frames);
  o.time_stride = a.integer("time-stride", o.time_stride);
  o.render_scale = a.number("render-scale", o.render_scale);
  o.renderer = parse_map_renderer(a.get("renderer", "raster"));
  o.stride = a.integer("stride", o.stride);
  o.global_candidates = a.integer("global-candidates", o.global_candidates);
  o.visibility.mode = parse_visibility_mode(a.get("mode", "frustum"));
  o.visibility.threads = o.threads;
  o.no_start_selection = a.flag("no-start-selection");
  o.no_error_term = a.flag("no-error-term");
  o.no_sensitivity_term = a.flag("no-sensitivity-term");
  o.no_candidate_scoring = a.flag("no-candidate-scoring");
  o.no_global = a.flag("no-global");
  if (a.flag("count-only") && a.flag("speed-only")) throw_error("fillgs select: --count-only and --speed-only exclude each other");
  if (a.flag("count-only")) o.score = CandidateScore::CountOnly;
  if (a.flag("speed-only")) o.score = CandidateScore::SpeedOnly;
  if (o.no_error_term && o.no_sensitivity_term) throw_error("fillgs select: --no-error-term and --no-sensitivity-term leave no priority");

  // Inputs, all read before anything is written.
  const std::string scene_path = a.require("scene"), cameras_path = a.require("cameras");
  const GaussianCloud cloud = read_scene(scene_path, scene_options(a));
  SelectInput in;
  in.scene = &cloud;
  if (a.has("background")) {
    const std::vector<double> c = a.numbers("background", 3);
    for (int k = 0; k < 3; ++k) in.background[k] = float(c[size_t(k)]);
  }
  std::unique_ptr<Dataset> data;
  std::vector<Camera> cams;
  if (a.has("images")) {
    data = std::make_unique<Dataset>(Dataset::load(a.get("images"), cameras_path));
    in.frames = data->frames();
    for (const TrainView& v : data->views()) cams.push_back(v.camera);
    in.image = [&](size_t i) { return data->image(i); };
  } else {
    const std::vector<Camera> read = read_cameras(cameras_path, camera_options(a));
    if (read.empty()) throw_error(cameras_path, ": no cameras");
    double step = 0;
    in.frames = int(observe_times(a, cloud, read, &step).size());
    cams = timed_cameras(read, in.frames);
  }
  in.views = observed_views(cams, in.frames);
  if (data)  // same order as the dataset (observed_views keeps input order)
    for (size_t i = 0; i < in.views.size(); ++i) FILLGS_CHECK_EQ(in.views[i].frame, data->views()[i].frame);

  TerminalProgress progress(err, progress_enabled(a));
  ExplorationStats gstats;
  std::unique_ptr<ExplorationGrid> grid;
  if (a.has("grid")) grid = std::make_unique<ExplorationGrid>(ExplorationGrid::read(a.get("grid")));
  else grid = std::make_unique<ExplorationGrid>(ExplorationGrid::build(cloud, cams, {}, exploration_options(a), &gstats, progress));
  in.grid = grid.get();
  const double grid_s = seconds_since(t0);

  const SelectResult r = select_viewpoints(in, o, progress);

  // ---- outputs
  OutputFolder folder(out_dir);  // a failed or killed run leaves the folder as it was
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
  nlohmann::json tj = {{"strategy", to_string(o.strategy)}, {"seed", o.seed}, {"frames", in.frames},
                       {"deficiency_scale", r.deficiency_scale}, {"trajectories", trajs}, {"cameras", flat}};
  write_file_atomically(join_path(folder.path(), "trajectories.json"), tj.dump(2) + "\n");
  write_transforms_json(join_path(folder.path(), "transforms.json"), virtual_cams);
  if (!virtual_cams.empty()) write_colmap_text(join_path(folder.path(), "colmap"), virtual_cams);

  // Renders: RGB and the normalised deficiency D̂ (initial tables) of every virtual view.
  double mean_selected_deficiency = 0;
  if (!a.flag("no-renders") && !virtual_cams.empty()) {
    DeficiencyField field(r.initial_tables, o.deficiency_quantile);
    FrameEvaluator ev(cloud);
    progress.start("renders", virtual_cams.size());
    for (const Camera& c : virtual_cams) {
      const int f = int(std::lround(c.time * (in.frames - 1)));
      const std::vector<float> d = field.values(f, CandidateScore::Deficiency);
      RenderOptions ro;
      ro.features = d.data();
      ro.feature_channels = 1;
      ro.background = in.background;
      ro.threads = o.threads;
      const RenderOutput img = render(ev.evaluate(c.time), c, ro);
      Image rgb(c.width, c.height, 3), dmap(c.width, c.height, 1);
      rgb.pixels = img.rgb;
      dmap.pixels = img.features;
      for (float v : img.features) mean_selected_deficiency += v / double(img.features.size() * virtual_cams.size());
      write_image(join_path(folder.path(), "renders/" + c.name + ".png"), rgb);
      write_image(join_path(folder.path(), "renders/" + c.name + "_D.png"), dmap);
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
    write_npy(join_path(folder.path(), "priority_E.npy"), E.data(), {poses, F});
    write_npy(join_path(folder.path(), "priority_L.npy"), table(r.priority.error).data(), {poses, F});
    write_npy(join_path(folder.path(), "priority_V.npy"), table(V).data(), {poses, F});
    write_npy(join_path(folder.path(), "priority_V_time.npy"), table(r.priority.time).data(), {poses, F});
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
    write_heatmap_png(join_path(folder.path(), "priority_heatmap.png"), shown, int(poses), int(F),
                      {"exploration priority E = L + V (rows: cameras, columns: frames)", "frame", "camera"}, &per_camera);
    write_bar_chart_png(join_path(folder.path(), "priority_over_cameras.png"), cam_names, per_camera, {"mean E per camera", "camera", "E"});
    write_bar_chart_png(join_path(folder.path(), "priority_over_time.png"), frame_names, per_frame, {"mean E per frame", "frame", "E"});
    prio = {{"evaluated_views", r.priority.views.size()}, {"seconds", r.priority.seconds}};
  }
  write_topdown_png(join_path(folder.path(), "trajectories.png"), *grid, cams, virtual_cams,
                    std::string("strategy ") + to_string(o.strategy) + ": " + std::to_string(r.trajectories.size()) + " trajectories");

  const SelectTimings& tm = r.timings;
  nlohmann::json s = {{"command", "select"},
                      {"strategy", to_string(o.strategy)},
                      {"seed", o.seed},
                      {"trajectories", r.trajectories.size()},
                      {"virtual_views", virtual_cams.size()},
                      {"mean_deficiency_of_selected_views", mean_selected_deficiency},
                      {"grid", grid_json(*grid, a.has("grid") ? nullptr : &gstats)},
                      {"priority", prio},
                      {"notes", r.notes},
                      {"seconds",
                       {{"grid", grid_s},
                        {"observe", tm.observe},
                        {"priority", tm.priority},
                        {"candidates", tm.candidates},
                        {"scoring", tm.scoring},
                        {"update", tm.update},
                        {"select_total", tm.total},
                        {"total", seconds_since(t0)}}},
                      {"candidates_scored", tm.candidates_scored},
                      {"candidates_rejected", tm.candidates_rejected}};
  write_file_atomically(join_path(folder.path(), "summary.json"), s.dump(2) + "\n");
  folder.commit();
  out << "selected " << r.trajectories.size() << " trajectories (" << virtual_cams.size() << " virtual views) with " << to_string(o.strategy)
      << " in " << seconds_since(t0) << " s (priority " << tm.priority << " s, scoring " << tm.scoring << " s of "
      << tm.candidates_scored << " candidates) -> " << out_dir << "\n";
  for (const std::string& n : r.notes) out << "note: " << n << "\n";
  return 0;
}

}  // namespace fillgs::cli
