// fillgs_bench city: a city-scale scene for end-to-end runs of the commands. guitar.ply
// replicated on a grid to N Gaussians, a share of them moving along straight lines at speeds
// spread over five decades (bench_common.hpp's replicate), baked to one key per frame and
// written as a fillgs 4D PLY, with 20 orbit cameras as a 3DGS cameras.json.
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/scene_io.hpp"

using namespace fillgs;

int bench_city(const std::vector<std::string>& args) {
  long long gaussians = 10000000;
  double moving = 0.01;
  int frames = 300, cameras = 20;
  std::string out;
  auto app = cli::make_parser("fillgs_bench city", "writes a city-scale fillgs 4D PLY (guitar.ply replicated) and orbit cameras");
  cli::add_number(*app, "--gaussians", gaussians, "Gaussians (a whole number of guitar copies, rounded up)", cli::at_least(1));
  cli::add_number(*app, "--moving", moving, "the share of them that moves", cli::within(0, 1));
  cli::add_number(*app, "--frames", frames, "frames (one key per frame)", cli::at_least(2));
  cli::add_number(*app, "--cameras", cameras, "orbit cameras, 1352x1014", cli::at_least(1));
  cli::add_text(*app, "--out", out, "the folder for city.ply and cameras.json", "DIR")->required();
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  const std::string scene = shared_data_dir() + "/scenes/guitar.ply";
  if (!std::filesystem::exists(scene)) throw_error(scene, ": missing (set FILLGS_SHARED_DATA to the shared data folder)");
  const GaussianCloud base = read_scene(scene);
  const int copies = int((size_t(gaussians) + base.size() - 1) / base.size());
  const GaussianCloud city = bench::replicate(base, copies, moving, 11);
  std::filesystem::create_directories(out);
  write_fillgs_ply(join_path(out, "city.ply"), city, frames);
  nlohmann::json cams = nlohmann::json::array();
  int id = 0;
  for (const Camera& c : bench::orbit(city, cameras, 1352, 1014)) {
    const Mat3d c2w = c.R.transpose();
    const Vec3d p = c.centre();
    cams.push_back({{"id", id}, {"img_name", "orbit" + std::to_string(id)}, {"width", c.width}, {"height", c.height},
                    {"position", {p.x(), p.y(), p.z()}},
                    {"rotation", {{c2w(0, 0), c2w(0, 1), c2w(0, 2)}, {c2w(1, 0), c2w(1, 1), c2w(1, 2)}, {c2w(2, 0), c2w(2, 1), c2w(2, 2)}}},
                    {"fx", c.fx}, {"fy", c.fy}});
    ++id;
  }
  write_file_atomically(join_path(out, "cameras.json"), cams.dump(1) + "\n");
  std::printf("%zu Gaussians (%d copies of guitar), %zu moving, %d frames, %d cameras -> %s\n", city.size(), copies, city.dynamic_count(), frames, cameras,
              out.c_str());
  return 0;
}
