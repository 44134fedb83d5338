// Rendering throughput: a real scene from an orbit of cameras at the Neural 3D Video
// working resolution (1352x1014) and at 640x480, single thread against all threads.
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <iostream>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/options.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"
#include "bench_common.hpp"

using namespace fillgs;

using namespace fillgs::bench;

namespace {

struct Timing {
  double ms = 0;             ///< per frame
  size_t rendered = 0;       ///< Gaussians with radius > 0, per frame
  uint64_t box_pixels = 0;   ///< Gaussian-pixel pairs evaluated, per frame
};

/// Renders every camera inside an arena of `threads` threads (the library's loops run in
/// the caller's arena).
Timing time_views(const FrameGaussians& g, const std::vector<Camera>& cams, int threads, Kernel kernel) {
  RenderOptions o;
  o.kernel = kernel;
  Timing t;
  tbb::task_arena(threads).execute([&] {
    render(g, cams[0], o);  // warm-up (allocations, thread pool)
    const auto t0 = std::chrono::steady_clock::now();
    for (const Camera& c : cams) {
      const RenderOutput r = render(g, c, o);
      t.rendered += r.rendered / cams.size();
      t.box_pixels += r.box_pixels / cams.size();
    }
    t.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / double(cams.size());
  });
  return t;
}


}  // namespace

int bench_render(const std::vector<std::string>& args) {
  bool smoke = false;
  std::string scene = shared_data_dir() + "/scenes/guitar.ply";
  int views = 8;
  auto app = cli::make_parser("fillgs_bench render", "the tile kernel: ms per frame, vector against scalar, by size and threads");
  cli::add_flag(*app, "--smoke", smoke, "small sizes, few views");
  cli::add_text(*app, "--scene", scene, "the scene rendered", "PLY");
  cli::add_number(*app, "--frames", views, "views rendered per size", cli::at_least(1));
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  if (!std::filesystem::exists(scene)) throw_error(scene, ": missing (set FILLGS_SHARED_DATA to the shared data folder)");
  const GaussianCloud cloud = read_scene(scene);
  const FrameGaussians g = frame_at(cloud, 0.0);
  const int all = std::min(2, tbb::info::default_concurrency());
  std::printf("scene %s: %zu Gaussians, SH degree %d; vector kernel on %s\n\n", bench::shown_path(scene).c_str(), cloud.size(), cloud.sh_degree,
              simd_target());
  std::printf("| size | kernel | threads | ms/frame | speed-up vs scalar | visible | Gaussian-pixel evaluations/s per core |\n"
              "|---|---|---|---|---|---|---|\n");
  struct Size { int w, h; };
  const std::vector<Size> sizes = smoke ? std::vector<Size>{{160, 120}} : std::vector<Size>{{1352, 1014}, {640, 480}};
  if (smoke) views = 2;
  double best_rate = 0;
  for (const Size& s : sizes) {
    const auto cams = orbit(cloud, views, s.w, s.h);
    for (int threads : {1, all}) {
      const Timing ref = time_views(g, cams, threads, Kernel::Scalar);
      const Timing vec = time_views(g, cams, threads, Kernel::Simd);
      for (const auto& [name, t] : {std::pair<const char*, const Timing&>{"scalar", ref}, {"simd", vec}}) {
        const double rate = double(t.box_pixels) / (t.ms / 1000.0) / threads;
        if (std::string(name) == "simd") best_rate = std::max(best_rate, rate);
        std::printf("| %dx%d | %s | %d | %.1f | %.2f | %zu | %.3g |\n", s.w, s.h, name, threads, t.ms, ref.ms / t.ms, t.rendered, rate);
      }
      if (threads == all) break;
    }
  }
  // The bound: the arithmetic of one evaluation in the kernel's loop, counted from
  // tile_kernel_simd.cpp — offsets 2, the conic's quadratic and −½ 7, clamp 1, exp 14,
  // α = min(0.99, o·e) 2, the three tests 3, T·(1−α) 2, w = α·T 1, three channel FMAs 3:
  // 35 operations, at one per lane per cycle.
  constexpr int kOperations = 35;
  const double ghz = bench::clock_ghz();
  const int lanes = simd_lanes();
  if (ghz > 0) {
    const double peak = lanes * ghz * 1e9 / kOperations;
    std::printf("\nbound: %d lanes x %.2f GHz (measured) / %d operations = %.3g evaluations/s per core; the best measured (whole frame: "
                "projection, SH, binning and blend) is %.0f%% of it\n", lanes, ghz, kOperations, peak, 100.0 * best_rate / peak);
  }
  return 0;
}
