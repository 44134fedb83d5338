// The command line end to end: outputs named after cameras, and bad input reported as
// one line naming the file and the element, with a non-zero exit and nothing written.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fillgs/cli.hpp"
#include "fillgs/image_io.hpp"
#include "fillgs/ply.hpp"
#include "fillgs/raster.hpp"
#include "fillgs/scene_io.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

namespace {

struct Result {
  int code;
  std::string out, err;
};

Result run_cli(std::vector<std::string> args) {
  std::ostringstream out, err;
  const int code = cli::run(args, out, err);
  return {code, out.str(), err.str()};
}

const char* kHeader =
    "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
    "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nproperty float opacity\n"
    "property float scale_0\nproperty float scale_1\nproperty float scale_2\n"
    "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n";

void expect_one_line_error(const Result& r, const std::vector<std::string>& words) {
  CHECK(r.code != 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  for (const std::string& w : words) {
    INFO("stderr: " << r.err << " should mention '" << w << "'");
    CHECK(r.err.find(w) != std::string::npos);
  }
}

std::string camera_file(const std::string& dir) {
  std::ofstream(dir + "/cams.json") << R"({"fl_x": 40, "w": 48, "h": 32, "frames": [
      {"file_path": "views/front", "time": 0.0, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]},
      {"file_path": "views/side.png", "time": 1.0, "transform_matrix": [[0,0,1,4],[0,1,0,0],[-1,0,0,0],[0,0,0,1]]}]})";
  return dir + "/cams.json";
}

}  // namespace

TEST_CASE("fillgs render writes one image per camera, named after it, plus summary.json", "[cli]") {
  const std::string dir = scratch("cli_render");
  std::ofstream(dir + "/s.ply") << kHeader << "0 0 0 1 0 0 2 -1 -1 -1 1 0 0 0\n0.3 0.2 0.1 0 1 0 1 -2 -2 -2 1 0 0 0\n";
  const std::string cams = camera_file(dir);
  const Result r = run_cli({"render", "--scene", dir + "/s.ply", "--cameras", cams, "--out", dir + "/out", "--quiet"});
  INFO(r.err);
  REQUIRE(r.code == 0);
  REQUIRE(fs::exists(dir + "/out/views/front.png"));
  REQUIRE(fs::exists(dir + "/out/views/side.png"));
  REQUIRE(fs::exists(dir + "/out/summary.json"));
  // The PNG holds the library's render, clamped and quantised to 8 bits.
  const Image img = read_image(dir + "/out/views/front.png");
  CHECK(img.width == 48);
  CHECK(img.height == 32);
  const GaussianCloud c = read_scene(dir + "/s.ply");
  const auto cam = read_cameras(cams);
  const RenderOutput ref = render(evaluate(c, 0), cam[0]);
  double max_err = 0;
  for (size_t i = 0; i < ref.rgb.size(); ++i)
    max_err = std::max(max_err, double(std::fabs(std::clamp(ref.rgb[i], 0.0f, 1.0f) - img.pixels[i])));
  CHECK(max_err <= 0.5 / 255 + 1e-6);
  // EXR keeps the float values; alpha channel is single-channel.
  REQUIRE(run_cli({"render", "--scene", dir + "/s.ply", "--cameras", cams, "--out", dir + "/exr", "--format", "exr",
                   "--channel", "alpha", "--quiet"})
              .code == 0);
  const Image a = read_image(dir + "/exr/views/front.exr");
  CHECK(a.channels == 1);
  CHECK(a.pixels == ref.alpha);
  std::ifstream js(dir + "/out/summary.json");
  const nlohmann::json s = nlohmann::json::parse(js);
  CHECK(s["cameras"] == 2);
}

TEST_CASE("fillgs info --json reports counts and motion", "[cli][data]") {
  const Result r = run_cli({"info", shared_data() + "/scenes/playbot_3k.ply", "--json"});
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  CHECK(j["gaussians"] == 3000);
  CHECK(j["sh_degree"] == 2);
  CHECK(j["motion_model"] == "static");
}

TEST_CASE("bad scene files: one line naming the file and the element, non-zero exit", "[cli][errors]") {
  const std::string dir = scratch("cli_bad");
  SECTION("NaN") {
    std::ofstream(dir + "/nan.ply") << kHeader << "0 0 0 1 0 0 2 -1 -1 -1 1 0 0 0\n0 0 0 1 0 0 2 nan -1 -1 1 0 0 0\n";
    expect_one_line_error(run_cli({"info", dir + "/nan.ply"}), {"nan.ply", "vertex 1", "scale_0", "NaN"});
  }
  SECTION("infinite position") {
    std::ofstream(dir + "/inf.ply") << kHeader << "0 0 inf 1 0 0 2 -1 -1 -1 1 0 0 0\n0 0 0 1 0 0 2 -1 -1 -1 1 0 0 0\n";
    expect_one_line_error(run_cli({"info", dir + "/inf.ply"}), {"inf.ply", "vertex 0", "'z'", "infinite"});
  }
  SECTION("missing property") {
    std::string h = kHeader;
    h.erase(h.find("property float scale_2\n"), 23);
    std::ofstream(dir + "/miss.ply") << h << "0 0 0 1 0 0 2 -1 -1 1 0 0 0\n0 0 0 1 0 0 2 -1 -1 1 0 0 0\n";
    expect_one_line_error(run_cli({"info", dir + "/miss.ply"}), {"miss.ply", "property 'scale_2' missing", "13 properties"});
  }
  SECTION("truncated binary file") {
    const GaussianCloud c = read_scene(shared_data() + "/scenes/playbot_3k.ply");
    write_3dgs_ply(dir + "/full.ply", c);
    std::string bytes;
    {
      std::ifstream in(dir + "/full.ply", std::ios::binary);
      std::stringstream ss;
      ss << in.rdbuf();
      bytes = ss.str();
    }
    std::ofstream(dir + "/cut.ply", std::ios::binary) << bytes.substr(0, bytes.size() - 1000);
    expect_one_line_error(run_cli({"info", dir + "/cut.ply"}), {"cut.ply", "truncated", "vertex"});
  }
  SECTION("not a PLY, and a missing file") {
    std::ofstream(dir + "/junk.ply") << "hello";
    expect_one_line_error(run_cli({"info", dir + "/junk.ply"}), {"junk.ply", "not a PLY"});
    expect_one_line_error(run_cli({"info", dir + "/nope.ply"}), {"nope.ply", "no such file"});
  }
}

TEST_CASE("bad cameras: unknown model and broken JSON fail before anything is written", "[cli][errors]") {
  const std::string dir = scratch("cli_badcam");
  std::ofstream(dir + "/s.ply") << kHeader << "0 0 0 1 0 0 2 -1 -1 -1 1 0 0 0\n0 0 0 1 0 0 2 -1 -1 -1 1 0 0 0\n";
  fs::create_directories(dir + "/colmap");
  std::ofstream(dir + "/colmap/cameras.txt") << "1 FULL_OPENCV 640 480 500 500 320 240 0 0 0 0 0 0 0 0\n";
  std::ofstream(dir + "/colmap/images.txt") << "1 1 0 0 0 0 0 5 1 a.png\n\n";
  Result r = run_cli({"render", "--scene", dir + "/s.ply", "--cameras", dir + "/colmap", "--out", dir + "/out"});
  expect_one_line_error(r, {"cameras.txt", "camera 1", "FULL_OPENCV"});
  CHECK_FALSE(fs::exists(dir + "/out"));
  std::ofstream(dir + "/broken.json") << R"({"frames": [ {"transform_matrix": )";
  r = run_cli({"render", "--scene", dir + "/s.ply", "--cameras", dir + "/broken.json", "--out", dir + "/out"});
  expect_one_line_error(r, {"broken.json", "invalid JSON"});
  std::ofstream(dir + "/nofocal.json") << R"({"w": 4, "h": 4, "frames": [{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}]})";
  r = run_cli({"render", "--scene", dir + "/s.ply", "--cameras", dir + "/nofocal.json", "--out", dir + "/out"});
  expect_one_line_error(r, {"nofocal.json", "frame 0", "focal"});
  CHECK_FALSE(fs::exists(dir + "/out"));
  r = run_cli({"render", "--scene", dir + "/s.ply", "--bogus", "1"});
  expect_one_line_error(r, {"unknown option --bogus"});
}

TEST_CASE("inputs are never modified and outputs are replaced atomically", "[cli]") {
  const std::string dir = scratch("cli_atomic");
  const std::string src = shared_data() + "/scenes/playbot_3k.ply";
  const auto before = fs::file_size(src);
  const auto mtime = fs::last_write_time(src);
  REQUIRE(run_cli({"convert", "--scene", src, "--out", dir + "/copy.ply"}).code == 0);
  CHECK(fs::file_size(src) == before);
  CHECK(fs::last_write_time(src) == mtime);
  // No temporary files are left beside the output.
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  CHECK(files == 1);
  CHECK(read_scene(dir + "/copy.ply").size() == 3000);
}
