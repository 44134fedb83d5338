// fillgs select: viewpoint-time selection by a strategy.
#include <algorithm>
#include <array>
#include <filesystem>
#include <memory>
#include <sstream>

#include "commands.hpp"
#include "options.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/train/train.hpp"
#include "progress_bar.hpp"

namespace fillgs::cli {

namespace {

/// Training viewpoints with times: every camera entry with a time, a rig expanded over frames.
std::vector<Camera> timed_cameras(const std::vector<Camera>& cams, int frames) {
  std::vector<Camera> out;
  for (const ObservedView& v : observed_views(cams, frames)) out.push_back(v.camera);
  return out;
}

// ------------------------------------------------------------------ select

/// A grid given with --grid must be this scene's: its box holds every training camera and
/// the bulk of the static Gaussians that occupy space (1st to 99th percentile per axis), to
/// a voxel. A grid
/// made for another scene would make select sample candidates from the wrong space.
void check_grid_fits(const std::string& path, const ExplorationGrid& grid, const GaussianCloud& cloud, const std::vector<Camera>& cams) {
  const Vec3d slack = grid.voxel_size();
  Box3 loose{grid.box().lo - slack, grid.box().hi + slack};
  auto where = [](const Vec3d& p) {
    std::ostringstream s;
    s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
    return s.str();
  };
  const std::string box = where(grid.box().lo) + " to " + where(grid.box().hi);
  for (const Camera& c : cams)
    if (!loose.contains(c.centre()))
      throw_error(path, ": camera ", c.name, " at ", where(c.centre()), " lies outside the grid's box ", box,
                  ": the grid was made for another scene or other cameras; build it with fillgs explore on these");
  const float occupying_logit = logit(grid.occupancy_alpha());  // the opacity the grid was built at
  std::vector<char> moving(cloud.size(), 0);
  for (uint32_t g : cloud.dynamic_ids) moving[g] = 1;
  std::array<std::vector<double>, 3> coords;
  for (uint32_t g = 0; g < cloud.size(); ++g)
    if (!moving[g] && cloud.opacity_logits[g] >= occupying_logit)  // the Gaussians that shape the grid's box
      for (int k = 0; k < 3; ++k) coords[size_t(k)].push_back(cloud.means[g][k]);
  if (coords[0].size() < 10) return;
  for (int k = 0; k < 3; ++k) {
    auto& v = coords[size_t(k)];
    std::sort(v.begin(), v.end());
    const double lo = v[v.size() / 100], hi = v[v.size() - 1 - v.size() / 100];
    if (lo < loose.lo[k] || hi > loose.hi[k])
      throw_error(path, ": the scene's Gaussians reach from ", lo, " to ", hi, " along axis ", "xyz"[k], ", beyond the grid's box ", box,
                  ": the grid was made for another scene; build it with fillgs explore on this one");
  }
}

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
  const auto t0 = Clock::now();
  SelectOptions o = f.select;
  check_selection(invocation, o);

  // Inputs, all read before anything is written.
  const std::string& cameras_path = f.cameras;
  const GaussianCloud cloud = read_scene_shown(f.scene, f.read, invocation);
  if (cloud.size() == 0) throw_error(f.scene, ": has no Gaussians, so no camera observes anything and there is no view to choose");
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
    in.frames = int(observe_times(invocation, f.time, cloud, read, &step, true).size());
    cams = timed_cameras(read, in.frames);
  }
  in.views = observed_views(cams, in.frames);
  if (data)  // same order as the dataset (observed_views keeps input order)
    for (size_t i = 0; i < in.views.size(); ++i) FILLGS_CHECK_EQ(in.views[i].frame, data->views()[i].frame);

  TerminalProgress progress(invocation.err, invocation.progress());
  ExplorationStats gstats;
  std::unique_ptr<ExplorationGrid> grid;
  ExplorationOptions go = f.grid_options;
  if (invocation.given("--grid")) {
    grid = std::make_unique<ExplorationGrid>(ExplorationGrid::read(f.grid));
    check_grid_fits(f.grid, *grid, cloud, cams);
  }
  else grid = std::make_unique<ExplorationGrid>(build_exploration_grid(cloud, cams, {}, go, &gstats, progress));
  in.grid = grid.get();
  const double grid_s = seconds_since(t0);

  const SelectResult r = select_viewpoints(in, o, progress);

  OutputFolder folder(f.out);  // a failed or killed run leaves the folder as it was
  SelectionReportOptions ro;
  ro.renders = !f.no_renders;
  ro.grid_stats = invocation.given("--grid") ? nullptr : &gstats;
  ro.grid_seconds = grid_s;
  ro.started = t0;
  const SelectionReport report = write_selection(folder.path(), in, o, r, *grid, cams, ro, progress);
  folder.commit();
  const SelectTimings& tm = r.timings;
  invocation.out << "selected " << r.trajectories.size() << " trajectories (" << report.virtual_views << " virtual views) with " << o.strategy
      << " in " << seconds_since(t0) << " s (priority " << tm.priority << " s, scoring " << tm.scoring << " s of "
      << tm.candidates_scored << " candidates) -> " << f.out << "\n";
  for (const std::string& n : r.notes) invocation.out << "note: " << n << "\n";
  return 0;
}

}  // namespace

Action declare_select(CLI::App& app) {
  auto f = std::make_shared<SelectFlags>();
  SelectOptions& o = f->select;
  add_text(app, "--scene", f->scene, "the model", "PATH")->required();
  add_text(app, "--cameras", f->cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", f->out, "the folder for trajectories.json, renders, priorities and pictures", "DIR")->required();
  add_text(app, "--images", f->images, "the training images (the priority's error term L needs them)", "DIR");
  add_time_flags(app, f->time, false);
  add_number(app, "--trajectories", o.trajectories, "trajectories to select (at most 100000)", trajectory_bounds());
  add_number(app, "--seed", o.seed, "random seed");
  add_number(app, "--views", o.views, "virtual poses per trajectory (at most 1000: each is scored, rendered and refined)", views_bounds());
  add_number(app, "--patch-frames", o.patch_frames, "consecutive frames each pose is rendered at (at most 1000)", patch_frame_bounds());
  add_number(app, "--render-scale", o.render_scale, "priority renders at this fraction of the resolution", within_open(0, 1e3));
  add_choice(app, "--renderer", o.renderer, "how candidate maps are rendered");
  add_number(app, "--stride", o.stride, "raytraced candidate maps: one ray every s pixels", stride_bounds());
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
