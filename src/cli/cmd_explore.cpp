// fillgs explore: the exploration grid.
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

// ------------------------------------------------------------------ explore

struct ExploreFlags {
  std::string scene, cameras, out;
  int frames = 0;
  ExplorationOptions grid;
  SceneReadOptions read;
  CameraReadOptions camera_read;
};

int explore(const ExploreFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  const GaussianCloud cloud = read_scene_shown(f.scene, f.read, in);
  const std::vector<Camera> cams = read_cameras(f.cameras, f.camera_read);
  if (cams.empty()) throw_error(f.cameras, ": no cameras");
  std::vector<double> sweep;
  if (in.given("--frames")) sweep = FrameGrid(f.frames).times();
  TerminalProgress progress(in.err, in.progress());
  ExplorationStats stats;
  ExplorationOptions go = f.grid;
  const ExplorationGrid grid = build_exploration_grid(cloud, cams, sweep, go, &stats, progress);
  OutputFolder folder(f.out);  // a failed or killed run leaves the folder as it was
  write_exploration(folder.path(), grid, cams, stats, seconds_since(t0));
  folder.commit();
  in.out << "exploration grid " << grid.dims().x() << "^3 over [" << grid.box().lo.transpose() << "] .. [" << grid.box().hi.transpose()
      << "]: " << stats.occupied << " occupied (" << stats.occupied_by_static << " by static Gaussians), " << stats.unexplored
      << " unexplored, " << stats.free << " free; step " << grid.step() << " -> " << f.out << " (" << seconds_since(t0) << " s)\n";
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

}  // namespace fillgs::cli
