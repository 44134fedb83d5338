// The command line end to end: outputs named after cameras, and bad input reported as
// one line naming the file and the element, with a non-zero exit and nothing written.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <chrono>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <nlohmann/json.hpp>

#include "fillgs/model/camera.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/cli.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/visibility/observe_tables.hpp"
#include "fillgs/visibility/visibility.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/scene_io.hpp"
#include "cli_run.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

namespace {

using Result = CliResult;

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
  const RenderOutput ref = render(frame_at(c, 0), cam[0]);
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

namespace {

/// A small synthetic scene for fillgs observe: DIR/scene.ply and DIR/train.json (the
/// training cameras at each of F frames).
SynthScene observe_inputs(const std::string& dir, int F) {
  SynthScene s = small_synth(F, 64, 48, 0.04);
  write_fillgs_ply(dir + "/scene.ply", s.scene);
  write_transforms_json(dir + "/train.json", cameras_over_time(s.train, F));
  return s;
}

}  // namespace

TEST_CASE("fillgs observe --tables dense writes [T, N] tables that numpy reads, summary.json and pictures", "[cli][observe]") {
  const std::string dir = scratch("cli_observe");
  const int F = 4;
  const SynthScene s = observe_inputs(dir, F);
  const Result r = run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/obs",
                            "--mode", "raytraced", "--stride", "4", "--tables", "dense", "--quiet"});
  INFO(r.err);
  REQUIRE(r.code == 0);
  const size_t N = s.scene.size(), M = s.scene.dynamic_count();
  const NpyArray count = read_npy(dir + "/obs/count.npy");
  CHECK(count.descr == "|u1");
  CHECK(count.shape == std::vector<size_t>{size_t(F), N});
  const NpyArray speed = read_npy(dir + "/obs/speed.npy"), deficiency = read_npy(dir + "/obs/deficiency.npy");
  CHECK(speed.descr == "<f4");
  CHECK(speed.shape == std::vector<size_t>{size_t(F), N});
  CHECK(deficiency.shape == std::vector<size_t>{size_t(F), N});
  CHECK(read_npy(dir + "/obs/dynamic_ids.npy").shape == std::vector<size_t>{M});
  CHECK(read_npy(dir + "/obs/times.npy").to_doubles("times") == std::vector<double>{0.0, 1.0 / 3, 2.0 / 3, 1.0});
  // The scene file round trip (fillgs 4D PLY) and the per-frame cameras give the same
  // tables as the library on the scene in memory.
  ObservationOptions o;
  o.visibility.mode = VisibilityMode::Raytraced;
  o.visibility.stride = 4;
  const ObservationTables t = observation_tables(s.scene, cameras_over_time(s.train, F), FrameGrid(F).times(), 1.0 / 3, o);
  const auto c = count.to_doubles("count"), d = deficiency.to_doubles("deficiency"), sp = speed.to_doubles("speed");
  size_t same = 0;
  for (size_t k = 0; k < c.size(); ++k) same += c[k] == t.counts[k];
  CHECK(same == c.size());
  for (int f = 0; f < F; ++f) {
    const auto row = t.deficiency_row(f);
    for (size_t j = 0; j < M; ++j) {
      const uint32_t g = s.scene.dynamic_ids[j];
      REQUIRE(d[size_t(f) * N + g] == Approx(row[g]).margin(1e-6));
      REQUIRE(sp[size_t(f) * N + g] == Approx(t.dynamic_speed[size_t(f) * M + j]).margin(1e-6));
      // D = s / (1 + C), read back from the three files
      REQUIRE(d[size_t(f) * N + g] == Approx(sp[size_t(f) * N + g] / (1.0 + c[size_t(f) * N + g])).margin(1e-6));
    }
  }
  const auto j = nlohmann::json::parse(std::ifstream(dir + "/obs/summary.json"));
  CHECK(j["mode"] == "raytraced");
  CHECK(j["views"] == 16 * F);
  CHECK(j["camera_poses"] == 16);
  CHECK(j["rays_traced"].get<uint64_t>() > 0);
  for (const char* png : {"deficiency_heatmap.png", "visible_fraction.png"}) {
    int w = 0, h = 0;
    CHECK(image_size(dir + "/obs/" + png, &w, &h));
    CHECK(w > 300);
  }

  SECTION("dynamic-only motion tables (--motion-tables, the flag's older name)") {
    REQUIRE(run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/dyn",
                     "--motion-tables", "dynamic", "--no-plots", "--quiet"}).code == 0);
    CHECK(read_npy(dir + "/dyn/speed_dynamic.npy").shape == std::vector<size_t>{size_t(F), M});
    CHECK(read_npy(dir + "/dyn/deficiency_dynamic.npy").shape == std::vector<size_t>{size_t(F), M});
    CHECK_FALSE(fs::exists(dir + "/dyn/speed.npy"));
    CHECK_FALSE(fs::exists(dir + "/dyn/deficiency_heatmap.png"));
  }
  SECTION("bad options: one line, nothing written") {
    expect_one_line_error(run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/bad",
                                   "--mode", "magic"}),
                          {"unknown visibility mode", "magic"});
    expect_one_line_error(run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/bad",
                                   "--times", "0.5,1.5"}),
                          {"--times", "1.5"});
    expect_one_line_error(run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/bad",
                                   "--mode", "raytraced", "--hit-cache", "-5"}),
                          {"--hit-cache", "-5"});
    CHECK_FALSE(fs::exists(dir + "/bad"));
  }
  SECTION("a static scene with untimed cameras has one time: tables [1, N], no flags needed") {
    std::ofstream(dir + "/static.ply") << kHeader << "0 0 0 1 0 0 2 -1 -1 -1 1 0 0 0\n0.3 0.2 0.1 0 1 0 1 -2 -2 -2 1 0 0 0\n";
    write_transforms_json(dir + "/rig.json", s.train);  // no times: a rig
    const Result st = run_cli({"observe", "--scene", dir + "/static.ply", "--cameras", dir + "/rig.json", "--out", dir + "/static", "--tables", "dense", "--quiet"});
    INFO(st.err);
    REQUIRE(st.code == 0);
    CHECK(read_npy(dir + "/static/times.npy").to_doubles("times") == std::vector<double>{0.0});
    const NpyArray sc = read_npy(dir + "/static/count.npy");
    CHECK(sc.shape == std::vector<size_t>{1, 2});
    // Frustum counts by hand: cameras in front of the centre whose image holds its projection.
    const GaussianCloud g = read_scene(dir + "/static.ply");
    const auto counts = sc.to_doubles("count");
    for (size_t k = 0; k < 2; ++k) {
      int seen = 0;
      for (const Camera& c : s.train) {
        const Vec3d x = c.R * g.means[k].cast<double>() + c.t;
        const double u = c.fx * x.x() / x.z() + c.cx, v = c.fy * x.y() / x.z() + c.cy;
        seen += x.z() > 0 && u >= 0 && u < c.width && v >= 0 && v < c.height;
      }
      CHECK(counts[k] == seen);
    }
    CHECK(counts[0] > 0);
  }
}

namespace {

/// The dense [T, N] counts of a compact folder, rebuilt from its files as the layout's
/// numpy recipe does (observe_tables.hpp), without the library's reader.
std::vector<double> counts_from_compact_files(const std::string& d, size_t N) {
  const std::vector<double> stat = read_npy(d + "/count_static.npy").to_doubles("count_static");
  const std::vector<double> rows = read_npy(d + "/count_rows.npy").to_doubles("count_rows");
  const std::vector<double> ids = read_npy(d + "/dynamic_ids.npy").to_doubles("dynamic_ids");
  const std::vector<double> dyn = read_npy(d + "/count_dynamic.npy").to_doubles("count_dynamic");
  const std::vector<double> off = read_npy(d + "/count_change_offsets.npy").to_doubles("offsets");
  const std::vector<double> cid = read_npy(d + "/count_change_ids.npy").to_doubles("change ids");
  const std::vector<double> cval = read_npy(d + "/count_change_values.npy").to_doubles("change values");
  const size_t T = rows.size(), M = ids.size();
  std::vector<double> c(T * N);
  for (size_t t = 0; t < T; ++t) {
    for (size_t g = 0; g < N; ++g) c[t * N + g] = stat[size_t(rows[t]) * N + g];
    for (size_t j = 0; j < M; ++j) c[t * N + size_t(ids[j])] = dyn[t * M + j];
    for (size_t e = size_t(off[t]); e < size_t(off[t + 1]); ++e) c[t * N + size_t(cid[e])] = cval[e];
  }
  return c;
}

}  // namespace

TEST_CASE("fillgs observe's compact tables (the default) are the dense tables cell for cell", "[cli][observe]") {
  const std::string dir = scratch("cli_observe_compact");
  const int F = 5;
  const SynthScene s = observe_inputs(dir, F);
  // Timed cameras whose set changes: the even rig cameras at even frames, the odd ones at odd
  // frames, all of them at the last: three camera sets, the first two recurring.
  std::vector<Camera> alternating;
  const std::vector<Camera> timed = cameras_over_time(s.train, F);
  for (size_t k = 0; k < timed.size(); ++k) {
    const size_t cam = k / size_t(F), f = k % size_t(F);
    if (f == size_t(F) - 1 || cam % 2 == f % 2) alternating.push_back(timed[k]);
  }
  write_transforms_json(dir + "/alternating.json", alternating);
  const size_t N = s.scene.size(), M = s.scene.dynamic_count();
  struct Case {
    std::string cameras, mode;
    size_t rows;
  };
  for (const Case& c : {Case{"train.json", "raytraced", 1}, Case{"train.json", "frustum", 1}, Case{"train.json", "exact", 1},
                        Case{"alternating.json", "raytraced", 3}, Case{"alternating.json", "frustum", 3}}) {
    const std::string tag = c.cameras.substr(0, c.cameras.size() - 5) + "_" + c.mode;
    INFO(tag);
    for (const char* layout : {"compact", "dense"}) {
      const Result r = run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/" + c.cameras, "--mode", c.mode, "--stride", "2",
                                "--tables", layout, "--no-plots", "--out", dir + "/" + tag + "_" + layout, "--quiet"});
      INFO(r.err);
      REQUIRE(r.code == 0);
    }
    const std::string compact = dir + "/" + tag + "_compact", dense = dir + "/" + tag + "_dense";
    CHECK_FALSE(fs::exists(compact + "/count.npy"));
    const std::vector<double> want = read_npy(dense + "/count.npy").to_doubles("count");
    CHECK(counts_from_compact_files(compact, N) == want);
    // The library's reader (the merge's and the module's) gives the same rows.
    const ObservationFolder folder = read_observation(compact);
    std::vector<uint16_t> row(N);
    size_t same = 0;
    for (size_t f = 0; f < size_t(F); ++f) {
      folder.count_row(f, row.data());
      for (size_t g = 0; g < N; ++g) same += row[g] == want[f * N + g];
    }
    CHECK(same == want.size());
    CHECK(read_npy(compact + "/count_static.npy").shape == std::vector<size_t>{c.rows, N});
    CHECK(read_npy(compact + "/count_static.npy").descr == read_npy(dense + "/count.npy").descr);
    // Frustum: a static Gaussian's count depends on the cameras only, so nothing changes;
    // traced and exact: moving Gaussians hide and uncover static ones.
    const auto summary = nlohmann::json::parse(std::ifstream(compact + "/summary.json"));
    CHECK(summary["tables"] == "compact");
    CHECK(summary["count_static_rows"] == c.rows);
    const size_t changes = summary["count_changes"].get<size_t>();
    CHECK(read_npy(compact + "/count_change_ids.npy").shape == std::vector<size_t>{changes});
    if (c.mode == "frustum") CHECK(changes == 0);
    else CHECK(changes > 0);
    if (c.cameras == "alternating.json") CHECK(read_npy(compact + "/count_rows.npy").to_doubles("rows") == std::vector<double>{0, 1, 0, 1, 2});
    // The motion: the dense tables' moving columns, and 0 elsewhere.
    const std::vector<double> ids = read_npy(compact + "/dynamic_ids.npy").to_doubles("ids");
    REQUIRE(ids.size() == M);
    for (const char* table : {"speed", "deficiency"}) {
      const std::vector<double> d = read_npy(dense + "/" + table + ".npy").to_doubles(table);
      const std::vector<double> m = read_npy(compact + "/" + table + "_dynamic.npy").to_doubles(table);
      REQUIRE(m.size() == size_t(F) * M);
      size_t equal = 0;
      for (size_t f = 0; f < size_t(F); ++f)
        for (size_t j = 0; j < M; ++j) equal += m[f * M + j] == d[f * N + size_t(ids[j])];
      CHECK(equal == m.size());
    }
    CHECK(read_file(compact + "/times.npy") == read_file(dense + "/times.npy"));
  }
}

TEST_CASE("fillgs convert --to frames: one 3DGS PLY per frame, each the model at t = f/(F-1)", "[cli][convert][release-only]") {
  const std::string dir = scratch("cli_frames");
  REQUIRE(run_cli({"synth", "--out", dir + "/scene", "--frames", "4", "--width", "32", "--height", "24"}).code == 0);
  const std::string scene = dir + "/scene/scene.ply";
  const Result r = run_cli({"convert", "--scene", scene, "--to", "frames", "--frames", "3", "--out", dir + "/frames"});
  INFO(r.err);
  REQUIRE(r.code == 0);
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir + "/frames"))
    if (e.path().filename() != ".fillgs-outputs") names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  CHECK(names == std::vector<std::string>{"frame_0000.ply", "frame_0001.ply", "frame_0002.ply"});
  // The same bytes as converting at that one time.
  for (int f = 0; f < 3; ++f) {
    const std::string one = dir + "/t" + std::to_string(f) + ".ply";
    REQUIRE(run_cli({"convert", "--scene", scene, "--to", "3dgs", "--time", std::to_string(f / 2.0), "--out", one}).code == 0);
    CHECK(read_file(one) == read_file(dir + "/frames/" + names[size_t(f)]));
  }
  CHECK(read_file(dir + "/frames/frame_0000.ply") != read_file(dir + "/frames/frame_0002.ply"));  // the scene moves
  // A bad count: one line, nothing written.
  expect_one_line_error(run_cli({"convert", "--scene", scene, "--to", "frames", "--frames", "0", "--out", dir + "/none"}), {"--frames"});
  CHECK(!fs::exists(dir + "/none"));

  // PlayCanvas's splat-transform (npm), where installed, reads a frame with every Gaussian.
  const char* env = std::getenv("FILLGS_SPLAT_TRANSFORM");
  const std::string tool = env && *env ? env : "splat-transform";
  if (std::system((tool + " --version >/dev/null 2>&1").c_str()) != 0) {
    WARN("skipped the splat-transform check: no '" << tool << "' (npm install -g @playcanvas/splat-transform, or FILLGS_SPLAT_TRANSFORM=PATH)");
    return;
  }
  const std::string summary = dir + "/summary.md";
  REQUIRE(std::system((tool + " -q " + dir + "/frames/frame_0001.ply -m null > " + summary + " 2>&1").c_str()) == 0);
  const std::string text = read_file(summary);
  INFO(text);
  CHECK(text.find("**Row Count:** " + std::to_string(read_scene(scene).size())) != std::string::npos);
  CHECK(text.find("| x ") != std::string::npos);
}

TEST_CASE("fillgs observe --shard i/n, then --merge: the single process's tables byte for byte", "[cli][observe][release-only]") {
  const std::string dir = scratch("cli_observe_shards");
  const int F = 7;
  const SynthScene s = observe_inputs(dir, F);
  auto observe = [&](const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> args = {"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/" + out, "--quiet"};
    args.insert(args.end(), extra.begin(), extra.end());
    const Result r = run_cli(args);
    INFO(r.err);
    REQUIRE(r.code == 0);
  };
  auto same_bytes = [&](const std::string& a, const std::string& b) {
    INFO(a << " vs " << b);
    CHECK(read_file(dir + "/" + a) == read_file(dir + "/" + b));
  };
  // Compact (the default; traced, so that static counts change), dense counts with the
  // moving Gaussians' motion, and dense.
  for (const std::vector<std::string>& mode : {std::vector<std::string>{"--mode", "raytraced", "--stride", "2"},
                                               std::vector<std::string>{"--mode", "frustum", "--tables", "dynamic"},
                                               std::vector<std::string>{"--mode", "exact", "--tables", "dense"}}) {
    const std::string tag = mode[1];
    observe(tag + "_whole", mode);
    if (tag == "raytraced") {  // no kept static hits: the same tables
      std::vector<std::string> extra = mode;
      extra.insert(extra.end(), {"--hit-cache", "0"});
      observe("raytraced_no_hit_cache", extra);
      same_bytes("raytraced_whole/count_static.npy", "raytraced_no_hit_cache/count_static.npy");
      same_bytes("raytraced_whole/count_change_ids.npy", "raytraced_no_hit_cache/count_change_ids.npy");
      same_bytes("raytraced_whole/deficiency_dynamic.npy", "raytraced_no_hit_cache/deficiency_dynamic.npy");
    }
    std::vector<std::string> parts;
    for (int i = 1; i <= 3; ++i) {
      std::vector<std::string> extra = mode;
      extra.insert(extra.end(), {"--shard", std::to_string(i) + "/3"});
      observe(tag + "_part" + std::to_string(i), extra);
      parts.push_back(dir + "/" + tag + "_part" + std::to_string(i));
    }
    // Blocks of 2, 2 and 3 frames (7 frames in 3 shards).
    CHECK(read_npy(parts[0] + (tag == "raytraced" ? "/count_dynamic.npy" : "/count.npy")).shape ==
          std::vector<size_t>{2, tag == "raytraced" ? s.scene.dynamic_count() : s.scene.size()});
    CHECK(read_npy(parts[2] + "/times.npy").to_doubles("times") == std::vector<double>{4.0 / 6, 5.0 / 6, 1.0});
    // Given out of order: the merge sorts the shards by their frames.
    const Result m = run_cli({"observe", "--merge", parts[2] + "," + parts[0] + "," + parts[1], "--out", dir + "/" + tag + "_merged", "--quiet"});
    INFO(m.err);
    REQUIRE(m.code == 0);
    size_t tables = 0;
    for (const auto& e : fs::directory_iterator(dir + "/" + tag + "_whole"))
      if (e.path().extension() == ".npy") {
        same_bytes(tag + "_whole/" + e.path().filename().string(), tag + "_merged/" + e.path().filename().string());
        ++tables;
      }
    CHECK(tables == (tag == "raytraced" ? 10u : 5u));  // compact: 6 count tables, 2 motion tables, ids, times
    const auto whole = nlohmann::json::parse(std::ifstream(dir + "/" + tag + "_whole/summary.json"));
    const auto merged = nlohmann::json::parse(std::ifstream(dir + "/" + tag + "_merged/summary.json"));
    CHECK(merged["views"] == whole["views"]);
    CHECK(merged["rays_traced"].get<uint64_t>() >= whole["rays_traced"].get<uint64_t>());  // each shard traces its cameras' static answers once
    CHECK(merged["frames"] == F);
    CHECK(merged["tables"] == whole["tables"]);
    if (tag == "raytraced") {
      CHECK(merged["count_changes"] == whole["count_changes"]);
      CHECK(merged["count_static_rows"] == whole["count_static_rows"]);
    }
    for (size_t k = 0; k < size_t(F); ++k)
      CHECK(merged["deficiency_per_frame"][k].get<double>() == Approx(whole["deficiency_per_frame"][k].get<double>()).epsilon(1e-12));
    for (size_t c = 0; c < whole["per_camera"].size(); ++c) {
      CHECK(merged["per_camera"][c]["frames"] == whole["per_camera"][c]["frames"]);
      CHECK(merged["per_camera"][c]["visible_fraction"].get<double>() ==
            Approx(whole["per_camera"][c]["visible_fraction"].get<double>()).epsilon(1e-12));
    }
    CHECK(fs::exists(dir + "/" + tag + "_merged/deficiency_heatmap.png"));
  }

  {  // shards that do not make one job: one line, nothing written
    const std::string p1 = dir + "/raytraced_part1", p2 = dir + "/raytraced_part2", p3 = dir + "/raytraced_part3";
    expect_one_line_error(run_cli({"observe", "--merge", p1 + "," + p3, "--out", dir + "/bad"}), {"raytraced_part3", "frame 4 where frame 2"});
    expect_one_line_error(run_cli({"observe", "--merge", p1 + "," + p2, "--out", dir + "/bad"}), {"a shard is missing"});
    expect_one_line_error(run_cli({"observe", "--merge", p1 + "," + p1 + "," + p2 + "," + p3, "--out", dir + "/bad"}),
                          {"raytraced_part1", "two shards hold it"});
    expect_one_line_error(run_cli({"observe", "--merge", p1 + "," + dir + "/frustum_part2," + p3, "--out", dir + "/bad"}),
                          {"frustum_part2", "'mode'", "shards of different jobs"});
    expect_one_line_error(run_cli({"observe", "--merge", dir + "/raytraced_whole", "--out", dir + "/bad"}), {"raytraced_whole", "not a shard"});
    expect_one_line_error(run_cli({"observe", "--merge", p1, "--out", dir + "/bad", "--mode", "exact"}), {"--mode", "belongs to the shards"});
    for (const char* spec : {"0/3", "4/3", "3", "a/3", "1/8"})
      expect_one_line_error(run_cli({"observe", "--scene", dir + "/scene.ply", "--cameras", dir + "/train.json", "--out", dir + "/bad", "--shard", spec}),
                            {"--shard"});
    CHECK_FALSE(fs::exists(dir + "/bad"));
  }
}

// ---------------------------------------------------------------------------------
// Every command's --help lists exactly what it accepts: each listed flag is fed to the
// command (with a value of the kind the help names) and accepted; every command takes
// --threads and --quiet; a bad number names the flag and the value.

namespace {

struct ListedFlag {
  std::vector<std::string> names;  ///< "--scenes", "--variants"
  std::string type;                ///< "" for a flag without a value; "N", "PATH", "a|b", ...
  std::string value;               ///< the default the help shows, if any
  bool required = false;
  bool positional = false;
};

/// The flags a command's help lists: lines "  --name[,--alias] [TYPE][=default] [(required)]  help".
std::vector<ListedFlag> listed_flags(const std::string& help) {
  std::vector<ListedFlag> flags;
  std::istringstream in(help);
  std::string line;
  bool positionals = false;
  while (std::getline(in, line)) {
    if (line.rfind("Positionals:", 0) == 0) positionals = true;
    else if (!line.empty() && line[0] != ' ') positionals = false;
    if (line.rfind("  ", 0) != 0 || line.size() < 3 || line[2] == ' ') continue;
    std::istringstream words(line.substr(2));
    std::string spec;
    words >> spec;
    ListedFlag f;
    f.positional = positionals;
    if (spec.rfind("-h,", 0) == 0) continue;  // --help
    std::stringstream names(spec);
    for (std::string n; std::getline(names, n, ',');) f.names.push_back(n);
    // The type follows the names after a single space; the help text after several.
    const size_t after = 2 + spec.size();
    if (after + 1 < line.size() && line[after] == ' ' && line[after + 1] != ' ') {
      words >> f.type;
      if (f.type.find('=') != std::string::npos) {
        f.value = f.type.substr(f.type.find('=') + 1);
        f.type = f.type.substr(0, f.type.find('='));
      }
    }
    f.required = line.find("(required)") != std::string::npos;
    if (f.positional || f.names[0].rfind("--", 0) == 0) flags.push_back(f);
  }
  return flags;
}

/// A good value for a flag: its default, else one of the kind its type names.
std::string value_for(const ListedFlag& f) {
  const std::string& type = f.type;
  if (type.empty()) return "";
  if (!f.value.empty()) return f.value;
  if (type == "N" || type == "MB" || type == "GB") return "1";
  if (type == "X") return "0.5";
  if (type == "R,G,B") return "0,0,0";
  if (type == "I/N") return "1/1";
  if (type == "A:B:S") return "0:";
  if (type == "T1,T2,..") return "0.5";
  if (type.find('|') != std::string::npos) return type.substr(0, type.find('|'));
  return "p";  // PATH, DIR, NAME, A,B,.., ...
}

}  // namespace

TEST_CASE("every command's help lists exactly the flags it accepts, each with its kind of value", "[cli][help]") {
  const Result overview = run_cli({"help"});
  REQUIRE(overview.code == 0);
  std::vector<std::string> commands;
  {
    std::istringstream in(overview.out.substr(overview.out.find("commands:")));
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line) && line.rfind("  ", 0) == 0) commands.push_back(line.substr(2, line.find(' ', 2) - 2));
  }
  CHECK(commands.size() == 13);
  // The overview points to the documents that explain the workflow and the formats, each
  // of which exists.
  CHECK(overview.out.find("README.md explains the workflow") != std::string::npos);
  CHECK(run_cli({"--help"}).out == overview.out);
  for (const char* doc : {"README.md", "data/README.md"}) CHECK(fs::exists(std::string(FILLGS_SOURCE_DIR) + "/" + doc));
  for (const std::string& command : commands) {
    INFO("fillgs " << command);
    const Result h = run_cli({command, "--help"});
    REQUIRE(h.code == 0);
    CHECK(h.out.find("Usage: fillgs " + command) != std::string::npos);
    CHECK(run_cli({"help", command}).out == h.out);
    const std::vector<ListedFlag> flags = listed_flags(h.out);
    auto listed = [&](const std::string& name) {
      return std::any_of(flags.begin(), flags.end(), [&](const ListedFlag& f) { return std::count(f.names.begin(), f.names.end(), name) > 0; });
    };
    CHECK(listed("--threads"));
    CHECK(listed("--quiet"));
    CHECK(listed("--kernel"));
    // The required flags, with stand-in values: the flag under test is then followed by an
    // unknown one, which must be what the command complains about (so the flag and its
    // value were taken, and nothing runs).
    std::vector<std::string> base = {command};
    for (const ListedFlag& f : flags)
      if (f.required) {
        if (!f.positional) base.push_back(f.names[0]);
        base.push_back(value_for(f));
      }
    size_t fed = 0;
    for (const ListedFlag& f : flags) {
      if (f.positional) continue;
      for (const std::string& name : f.names) {
        INFO(name << " " << value_for(f));
        std::vector<std::string> args = base;
        args.push_back(name);
        if (!f.type.empty()) args.push_back(value_for(f));
        args.push_back("--not-a-flag");
        const Result r = run_cli(args);
        CHECK(r.code == 1);
        CHECK(r.err == "error: fillgs " + command + ": unknown option --not-a-flag (see 'fillgs " + command + " --help')\n");
        ++fed;
        if (f.type == "N" || f.type == "X") {
          // A bad number: one line naming the flag and the value.
          std::vector<std::string> bad = base;
          bad.insert(bad.end(), {name, "1x"});
          const Result b = run_cli(bad);
          CHECK(b.code == 1);
          CHECK(std::count(b.err.begin(), b.err.end(), '\n') == 1);
          CHECK(b.err.find(name) != std::string::npos);
          CHECK(b.err.find("'1x'") != std::string::npos);
        }
      }
    }
    CHECK(fed >= 4);
    // And a flag the help does not list is refused.
    const Result u = run_cli({command, "--bogus-flag"});
    CHECK(u.err.find("unknown option --bogus-flag") != std::string::npos);
  }
}

TEST_CASE("enum names: every name parses to its value and back, aliases parse, an unknown name gets the list", "[cli]") {
  auto round_trip = [](auto tag) {
    using E = decltype(tag);
    const std::vector<std::string> names = names_of<E>();
    CHECK(names.size() >= 2);
    for (const std::string& n : names) CHECK(to_string(parse_name<E>(n)) == n);
    try {
      parse_name<E>("no-such-name");
      FAIL("parsed an unknown name");
    } catch (const Error& e) {
      const std::string m = e.what();
      CHECK(m.find("'no-such-name'") != std::string::npos);
      for (const std::string& n : names) CHECK(m.find(n) != std::string::npos);
    }
  };
  round_trip(VisibilityMode{});
  round_trip(CameraFormat{});
  round_trip(Kernel{});
  CHECK(parse_name<CameraFormat>("nerf") == CameraFormat::Transforms);  // aliases parse, never print
  // The model formats are a table of rows, not an enum: every name and alias finds its own
  // row, none is taken twice, and an unknown name's message lists every name.
  std::set<std::string> taken;
  for (const ModelFormat* f : model_formats()) {
    CHECK(&model_format(f->name) == f);
    CHECK(taken.insert(f->name).second);
    for (const std::string& a : f->aliases) {
      CHECK(&model_format(a) == f);
      CHECK(taken.insert(a).second);
    }
    CHECK((f->open != nullptr) != (f->read != nullptr));  // a row opens a model or reads a file, not both
  }
  CHECK(model_formats().size() == 10);
  CHECK(model_format("spacetime").name == "stg");
  try {
    model_format("no-such-name");
    FAIL("found an unknown format");
  } catch (const Error& e) {
    for (const ModelFormat* f : model_formats()) CHECK(std::string(e.what()).find(f->name) != std::string::npos);
  }
  CHECK(names_of<CameraFormat>().size() == 7);
}

TEST_CASE("ThreadLimit, what --threads n sets: one thread runs the library's loops while it lives, none after, and 0 sets no limit", "[cli][threads]") {
  using tbb::global_control;
  const size_t before = global_control::active_value(global_control::max_allowed_parallelism);
  // The threads a parallel loop of short sleeping tasks runs on.
  auto threads_used = [] {
    std::mutex m;
    std::set<std::thread::id> ids;
    tbb::parallel_for(0, 64, [&](int) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      const std::lock_guard<std::mutex> lock(m);
      ids.insert(std::this_thread::get_id());
    });
    return ids.size();
  };
  {
    const ThreadLimit one(1);
    CHECK(global_control::active_value(global_control::max_allowed_parallelism) == 1);
    CHECK(threads_used() == 1);
  }
  CHECK(global_control::active_value(global_control::max_allowed_parallelism) == before);
  {
    const ThreadLimit none(0);
    CHECK(global_control::active_value(global_control::max_allowed_parallelism) == before);
  }
}

TEST_CASE("a rerun into a used folder leaves its own outputs only, and the user's files alone", "[cli][convert][robust]") {
  const std::string dir = scratch("cli_rerun");
  REQUIRE(run_cli({"synth", "--out", dir + "/scene", "--frames", "4", "--width", "32", "--height", "24", "--quiet"}).code == 0);
  const std::string scene = dir + "/scene/scene.ply", cams = dir + "/scene/transforms_train.json";
  auto listing = [](const std::string& folder) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(folder)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  };
  // 6 frames, then 3: three files on one time grid, not six on two; a file of the user's stays.
  REQUIRE(run_cli({"convert", "--scene", scene, "--to", "frames", "--frames", "6", "--out", dir + "/frames"}).code == 0);
  std::ofstream(dir + "/frames/notes.txt") << "mine";
  const Result again = run_cli({"convert", "--scene", scene, "--to", "frames", "--frames", "3", "--out", dir + "/frames"});
  INFO(again.err);
  REQUIRE(again.code == 0);
  CHECK(listing(dir + "/frames") == std::vector<std::string>{".fillgs-outputs", "frame_0000.ply", "frame_0001.ply", "frame_0002.ply", "notes.txt"});
  // observe with dense tables, then compact: no count.npy or speed.npy of the first run is left.
  REQUIRE(run_cli({"observe", "--scene", scene, "--cameras", cams, "--tables", "dense", "--out", dir + "/obs", "--quiet"}).code == 0);
  CHECK(fs::exists(dir + "/obs/speed.npy"));
  REQUIRE(run_cli({"observe", "--scene", scene, "--cameras", cams, "--out", dir + "/obs", "--quiet"}).code == 0);
  CHECK_FALSE(fs::exists(dir + "/obs/speed.npy"));
  CHECK_FALSE(fs::exists(dir + "/obs/count.npy"));
  CHECK(fs::exists(dir + "/obs/speed_dynamic.npy"));
  CHECK(fs::exists(dir + "/obs/count_static.npy"));
  // COLMAP text into a folder that holds a binary model would be shadowed by it: refused.
  fs::create_directories(dir + "/colmap");
  std::ofstream(dir + "/colmap/cameras.bin") << "binary";
  const Result shadowed = run_cli({"cameras", "--cameras", cams, "--to", "colmap", "--out", dir + "/colmap"});
  expect_one_line_error(shadowed, {"cameras.bin", "binary COLMAP model"});
  CHECK_FALSE(fs::exists(dir + "/colmap/cameras.txt"));
}
