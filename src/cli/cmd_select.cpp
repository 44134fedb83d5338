// fillgs explore and fillgs select.
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>

#include "commands.hpp"
#include "options.hpp"
#include "fillgs/frame_grid.hpp"
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

// ------------------------------------------------------------------ explore

struct ExploreFlags {
  std::string scene, cameras, out;
  int frames = 0;
  ExplorationOptions grid;
  SceneReadOptions read;
  CameraReadOptions camera_read;
};

int explore(const ExploreFlags& f, const Invocation& in) {
  std::ostream& out = in.out;
  const std::string& out_dir = f.out;
  const auto t0 = Clock::now();
  const GaussianCloud cloud = read_scene(f.scene, f.read);
  const std::vector<Camera> cams = read_cameras(f.cameras, f.camera_read);
  if (cams.empty()) throw_error(f.cameras, ": no cameras");
  std::vector<double> sweep;
  if (in.given("--frames")) sweep = FrameGrid(f.frames).times();
  TerminalProgress progress(in.err, in.progress());
  ExplorationStats stats;
  ExplorationOptions go = f.grid;
  go.threads = in.common.threads;
  const ExplorationGrid grid = ExplorationGrid::build(cloud, cams, sweep, go, &stats, progress);
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

// ------------------------------------------------------------------ select

struct SelectFlags {
  std::string scene, cameras, images, out, grid;
  TimeFlags time;
  SelectOptions select;
  Vec3f background = Vec3f::Zero();
  bool no_renders = false;
  ExplorationOptions grid_options;
  SceneReadOptions read;
  CameraReadOptions camera_read;
};

int select_views(const SelectFlags& f, const Invocation& invocation) {
  std::ostream& out = invocation.out;
  const std::string& out_dir = f.out;
  const auto t0 = Clock::now();
  SelectOptions o = f.select;
  o.threads = invocation.common.threads;
  o.visibility.threads = o.threads;
  check_selection(invocation, o);

  // Inputs, all read before anything is written.
  const std::string& cameras_path = f.cameras;
  const GaussianCloud cloud = read_scene(f.scene, f.read);
  SelectInput in;
  in.scene = &cloud;
  in.background = f.background;
  std::unique_ptr<Dataset> data;
  std::vector<Camera> cams;
  if (invocation.given("--images")) {
    data = std::make_unique<Dataset>(Dataset::load(f.images, cameras_path));
    in.frames = data->frames();
    for (const TrainView& v : data->views()) cams.push_back(v.camera);
    in.image = [&](size_t i) { return data->image(i); };
  } else {
    const std::vector<Camera> read = read_cameras(cameras_path, f.camera_read);
    if (read.empty()) throw_error(cameras_path, ": no cameras");
    double step = 0;
    in.frames = int(observe_times(invocation, f.time, cloud, read, &step).size());
    cams = timed_cameras(read, in.frames);
  }
  in.views = observed_views(cams, in.frames);
  if (data)  // same order as the dataset (observed_views keeps input order)
    for (size_t i = 0; i < in.views.size(); ++i) FILLGS_CHECK_EQ(in.views[i].frame, data->views()[i].frame);

  TerminalProgress progress(invocation.err, invocation.progress());
  ExplorationStats gstats;
  std::unique_ptr<ExplorationGrid> grid;
  ExplorationOptions go = f.grid_options;
  go.threads = o.threads;
  if (invocation.given("--grid")) grid = std::make_unique<ExplorationGrid>(ExplorationGrid::read(f.grid));
  else grid = std::make_unique<ExplorationGrid>(ExplorationGrid::build(cloud, cams, {}, go, &gstats, progress));
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
  if (!f.no_renders && !virtual_cams.empty()) {
    DeficiencyField field(r.initial_tables, o.deficiency_quantile);
    FrameEvaluator ev(cloud);
    progress.start("renders", virtual_cams.size());
    for (const Camera& c : virtual_cams) {
      const int f = FrameGrid(in.frames).nearest(c.time);
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
                      {"grid", grid_json(*grid, invocation.given("--grid") ? nullptr : &gstats)},
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

}  // namespace

Action declare_explore(CLI::App& app) {
  auto f = std::make_shared<ExploreFlags>();
  add_text(app, "--scene", f->scene, "the model", "PATH")->required();
  add_text(app, "--cameras", f->cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for exploration.vdb, exploration.png and summary.json", "DIR")->required();
  add_number(app, "--frames", f->frames, "sweep the moving Gaussians over F frames (default: the static scene)", at_least(1))->default_str("");
  add_grid_flags(app, f->grid);
  add_scene_flags(app, f->read);
  add_camera_flags(app, f->camera_read);
  return bind(f, explore);
}

Action declare_select(CLI::App& app) {
  auto f = std::make_shared<SelectFlags>();
  SelectOptions& o = f->select;
  add_text(app, "--scene", f->scene, "the model", "PATH")->required();
  add_text(app, "--cameras", f->cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for trajectories.json, renders, priorities and pictures", "DIR")->required();
  add_text(app, "--images", f->images, "the training images (the priority's error term L needs them)", "DIR");
  add_time_flags(app, f->time, false);
  add_number(app, "--trajectories", o.trajectories, "trajectories to select", at_least(0));
  add_number(app, "--seed", o.seed, "random seed");
  add_number(app, "--views", o.views, "virtual poses per trajectory", at_least(1));
  add_number(app, "--patch-frames", o.patch_frames, "consecutive frames each pose is rendered at", at_least(1));
  add_number(app, "--render-scale", o.render_scale, "priority renders at this fraction of the resolution", within_open(0, 1e3));
  add_choice(app, "--renderer", o.renderer, "how candidate maps are rendered");
  add_number(app, "--stride", o.stride, "raytraced candidate maps: one ray every s pixels", at_least(1));
  add_number(app, "--global-candidates", o.global_candidates, "candidates drawn from the whole exploration space", at_least(0));
  add_choice(app, "--mode", o.visibility.mode, "how the counts C decide that a camera observes a Gaussian");
  add_colour(app, "--background", f->background, "the background colour");
  add_text(app, "--grid", f->grid, "a grid written by fillgs explore (default: built here)", "VDB");
  add_flag(app, "--no-renders", f->no_renders, "no RGB and deficiency renders of the virtual views");
  add_selection_flags(app, o);
  add_grid_flags(app, f->grid_options);
  add_scene_flags(app, f->read);
  add_camera_flags(app, f->camera_read);
  return bind(f, select_views);
}

}  // namespace fillgs::cli
