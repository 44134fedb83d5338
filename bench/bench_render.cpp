// Rendering throughput: a real scene from an orbit of cameras at the Neural 3D Video
// working resolution (1352x1014) and at 640x480, single thread against all threads.
#include <tbb/info.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "fillgs/error.hpp"
#include "fillgs/raster.hpp"
#include "fillgs/scene_io.hpp"
#include "bench_common.hpp"

using namespace fillgs;

using namespace fillgs::bench;

namespace {

double time_views(const FrameGaussians& g, const std::vector<Camera>& cams, int threads, size_t* rendered) {
  RenderOptions o;
  o.threads = threads;
  render(g, cams[0], o);  // warm-up (allocations, thread pool)
  const auto t0 = std::chrono::steady_clock::now();
  size_t total = 0;
  for (const Camera& c : cams) total += render(g, c, o).rendered;
  *rendered = total / cams.size();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / cams.size();
}

}  // namespace

int bench_render(const std::vector<std::string>& args) {
  bool smoke = false;
  std::string scene = shared_data() + "/scenes/guitar.ply";
  int views = 8;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--smoke") smoke = true;
    else if (args[i] == "--scene" && i + 1 < args.size()) scene = args[++i];
    else if (args[i] == "--frames" && i + 1 < args.size()) views = std::atoi(args[++i].c_str());
    else throw_error("bench render: unknown argument '", args[i], "'");
  }
  if (!std::filesystem::exists(scene)) throw_error(scene, ": missing (set FILLGS_SHARED_DATA to the shared data folder)");
  const GaussianCloud cloud = read_scene(scene);
  const FrameGaussians g = evaluate(cloud, 0.0);
  const int all = tbb::info::default_concurrency();
  std::printf("scene %s: %zu Gaussians, SH degree %d; threads available: %d\n", scene.c_str(), cloud.size(), cloud.sh_degree, all);
  std::printf("%-10s %8s %12s %12s %14s %9s\n", "size", "threads", "ms/frame", "visible", "Gaussians/s", "speed-up");
  struct Size { int w, h; };
  const std::vector<Size> sizes = smoke ? std::vector<Size>{{160, 120}} : std::vector<Size>{{1352, 1014}, {640, 480}};
  if (smoke) views = 2;
  for (const Size& s : sizes) {
    const auto cams = orbit(cloud, views, s.w, s.h);
    size_t vis1 = 0, visn = 0;
    const double ms1 = time_views(g, cams, 1, &vis1);
    const double msn = time_views(g, cams, all, &visn);
    char label[32];
    std::snprintf(label, sizeof label, "%dx%d", s.w, s.h);
    std::printf("%-10s %8d %12.1f %12zu %14.3g %9s\n", label, 1, ms1, vis1, cloud.size() / (ms1 / 1000.0), "1.00");
    std::printf("%-10s %8d %12.1f %12zu %14.3g %9.2f\n", label, all, msn, visn, cloud.size() / (msn / 1000.0), ms1 / msn);
  }
  return 0;
}
