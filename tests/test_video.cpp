// Real captured video: the Dynamic 3D Gaussians (CMU Panoptic) reader against the real files
// in ../shared/data/video, frame ranges, downscaling, foreground masks and bad input.
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <Eigen/SVD>
#include <algorithm>
#include <cstring>
#include <set>
#include <filesystem>
#include <fstream>

#include "helpers.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/train/init.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/train/train.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Vec2d = Eigen::Vector2d;

std::string panoptic() { return shared_data() + "/video/panoptic_basketball"; }

/// The Panoptic training cameras named (all if none), the frames of `range`, downscaled by k.
Dataset load_panoptic(const std::vector<std::string>& cameras, const std::string& range, int k) {
  DatasetOptions o;
  o.cameras = cameras;
  o.frames = FrameRange::parse(range);
  o.downscale = k;
  return Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o);
}


}  // namespace

TEST_CASE("d3dgs reader: every Panoptic camera and frame, with the meta file's matrices and times f/149", "[video]") {
  const std::string meta = panoptic() + "/train_meta.json";
  CHECK(detect_camera_format(meta) == CameraFormat::D3dgs);
  const std::vector<Camera> cams = read_cameras(meta);
  std::ifstream in(meta);
  const json j = json::parse(in);
  REQUIRE(cams.size() == j["fn"].size() * j["fn"][0].size());
  REQUIRE(cams.size() == 150 * 27);
  for (size_t f : {size_t(0), size_t(75), size_t(149)})
    for (size_t i : {size_t(0), size_t(13), size_t(26)}) {
      const Camera& c = cams[f * 27 + i];
      INFO("frame " << f << " slot " << i);
      CHECK(c.name == std::to_string(j["cam_id"][f][i].get<int>()) + "/" + (f == 0 ? "000000" : f == 75 ? "000075" : "000149"));
      CHECK(c.image_path == j["fn"][f][i].get<std::string>());
      CHECK(c.time == Approx(double(f) / 149.0));
      CHECK(c.width == 640);
      CHECK(c.height == 360);
      CHECK(c.fx == j["k"][f][i][0][0].get<double>());
      CHECK(c.cy == j["k"][f][i][1][2].get<double>());
      // The centre −Rᵀt from the raw 4×4, element by element.
      const json& m = j["w2c"][f][i];
      for (int a = 0; a < 3; ++a) {
        double centre = 0;
        for (int b = 0; b < 3; ++b) centre -= m[size_t(b)][size_t(a)].get<double>() * m[size_t(b)][3].get<double>();
        CHECK(c.centre()[a] == Approx(centre).margin(1e-9));
      }
    }
}

TEST_CASE("Panoptic: the 27 cameras' foreground masks carve one visual hull that projects back onto each mask", "[video]") {
  const Dataset d = load_panoptic({}, "0:1", 1);
  REQUIRE(d.views().size() == 27);
  REQUIRE(d.frames() == 1);
  REQUIRE(d.has_masks());
  std::vector<Camera> cams;
  std::vector<std::vector<uint8_t>> masks;
  for (size_t v = 0; v < d.views().size(); ++v) cams.push_back(d.views()[v].camera), masks.push_back(d.mask(v));
  // Space carving, computed here from the matrices alone: a voxel is foreground when it
  // projects into the foreground of every camera that sees it but at most one (and at
  // least 10 see it; the players leave the frame of many cameras). Consistent cameras and
  // masks carve the players; the carved voxels then cover most of each camera's mask.
  auto carve = [&](const std::vector<Camera>& cs, std::pair<int, double>* coverage) {
    // The point nearest to every optical axis (the dome's centre of interest), and a box
    // of half the mean camera distance around it.
    Mat3d A = Mat3d::Zero();
    Vec3d b = Vec3d::Zero();
    for (const Camera& c : cs) {
      const Vec3d dir = c.R.row(2).transpose(), o = c.centre();
      const Mat3d P = Mat3d::Identity() - dir * dir.transpose();
      A += P, b += P * o;
    }
    const Vec3d centre = A.ldlt().solve(b);
    double r = 0;
    for (const Camera& c : cs) r += (c.centre() - centre).norm() / double(cs.size());
    const int N = 96;
    std::vector<std::vector<uint8_t>> hit(cs.size());
    for (size_t v = 0; v < cs.size(); ++v) hit[v].assign(masks[v].size(), 0);
    size_t carved = 0;
    std::vector<Vec2d> px(cs.size());
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        for (int k = 0; k < N; ++k) {
          const Vec3d X = centre + r * (Vec3d(i, j, k) / (N - 1) * 2.0 - Vec3d::Ones());
          int misses = 0, seen = 0;
          std::vector<long> at(cs.size(), -1);
          for (size_t v = 0; v < cs.size() && misses <= 1; ++v) {
            const Vec3d p = cs[v].project(X);
            const int x = int(std::floor(p.x())), y = int(std::floor(p.y()));
            if (p.z() <= 0 || x < 0 || y < 0 || x >= cs[v].width || y >= cs[v].height) continue;  // out of view: no vote
            const long q = long(y) * cs[v].width + x;
            if (!masks[v][size_t(q)]) ++misses;
            else at[v] = q, ++seen;
          }
          if (misses > 1 || seen < 10) continue;
          ++carved;
          for (size_t v = 0; v < cs.size(); ++v)
            if (at[v] >= 0) hit[v][size_t(at[v])] = 1;
        }
    // Share of each mask's pixels hit by a carved voxel (a 96³ grid samples a mask sparsely:
    // count a mask pixel covered when a hit lies within 3 pixels).
    int worst = 100;
    double mean = 0;
    for (size_t v = 0; v < cs.size(); ++v) {
      const int W = cs[v].width, H = cs[v].height;
      size_t in_mask = 0, covered = 0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          if (!masks[v][size_t(y) * W + x]) continue;
          ++in_mask;
          bool near = false;
          for (int dy = -3; dy <= 3 && !near; ++dy)
            for (int dx = -3; dx <= 3 && !near; ++dx) {
              const int xx = x + dx, yy = y + dy;
              near = xx >= 0 && yy >= 0 && xx < W && yy < H && hit[v][size_t(yy) * W + xx];
            }
          covered += near;
        }
      const int percent = int(100 * covered / std::max<size_t>(1, in_mask));
      worst = std::min(worst, percent);
      mean += percent / double(cs.size());
    }
    coverage->first = worst, coverage->second = mean;
    return carved;
  };
  std::pair<int, double> coverage;
  const size_t carved = carve(cams, &coverage);
  INFO("carved voxels " << carved << ", mask coverage worst " << coverage.first << "%, mean " << coverage.second << "%");
  CHECK(carved > 500);
  CHECK(coverage.first >= 30);
  CHECK(coverage.second >= 60);
  // The check can fail: with the rotations transposed (a camera-to-world read as
  // world-to-camera) nothing consistent is carved.
  std::vector<Camera> wrong = cams;
  for (size_t v = 0; v < wrong.size(); ++v) {
    wrong[v].R.transposeInPlace();
    wrong[v].t = -wrong[v].R * cams[v].centre();  // same centres, rotations wrong
  }
  std::pair<int, double> coverage_wrong;
  const size_t carved_wrong = carve(wrong, &coverage_wrong);
  INFO("transposed: carved " << carved_wrong << ", mean coverage " << coverage_wrong.second << "%");
  CHECK(carved_wrong < 50);
  CHECK(coverage_wrong.second < 10);
}

TEST_CASE("datasets: --frames keeps a slice of the video, --downscale averages k×k blocks", "[video]") {
  const Dataset d = load_panoptic({"1", "5"}, "0:150:50", 4);
  REQUIRE(d.views().size() == 6);
  CHECK(d.frames() == 3);
  const Camera full = read_cameras(panoptic() + "/train_meta.json")[50 * 27 + 4];  // camera 5 at frame 50
  for (size_t v = 0; v < d.views().size(); ++v) {
    const TrainView& tv = d.views()[v];
    CHECK(tv.camera.time == Approx(tv.frame / 2.0));
    CHECK(tv.camera.width == 160);
    CHECK(tv.camera.height == 90);
    if (tv.rig != "5" || tv.frame != 1) continue;
    CHECK(tv.camera.name == "5/000050");
    CHECK(tv.camera.fx == Approx(full.fx / 4));
    CHECK(tv.camera.cx == Approx(full.cx / 4));
    // Pixel (x, y) is the mean of the 4×4 block at (4x, 4y) of the file, within rounding.
    const Image im = read_image(panoptic() + "/ims/5/000050.jpg");
    const std::vector<float> px = d.image(v);
    for (auto [x, y] : {std::pair<int, int>{0, 0}, {80, 45}, {159, 89}})
      for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int dy = 0; dy < 4; ++dy)
          for (int dx = 0; dx < 4; ++dx) sum += im.pixels[(size_t(4 * y + dy) * 640 + size_t(4 * x + dx)) * size_t(im.channels) + size_t(c)];
        CHECK(px[(size_t(y) * 160 + size_t(x)) * 3 + size_t(c)] == Approx(sum / 16).margin(0.6 / 255));
      }
  }
  CHECK(FrameRange::parse("").all());
  CHECK(FrameRange::parse("10:").first == 10);
  CHECK(error_of([] { FrameRange::parse("5:2"); }).find("last must come after first") != std::string::npos);
  CHECK(error_of([] { FrameRange::parse("0:10:x"); }).find("'x' is not a frame number") != std::string::npos);
  DatasetOptions late;
  late.frames = FrameRange::parse("200:");
  CHECK(error_of([&] { Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", late); }).find("selects none of its 150 frames") !=
        std::string::npos);
}

TEST_CASE("datasets: single camera-times beside the cameras trained at every frame, their images and masks the files'", "[video]") {
  DatasetOptions o;
  o.cameras = {"1"};
  o.frames = FrameRange::parse("0:150:50");  // frames 0, 50, 100 become 0, 1, 2
  o.downscale = 8;
  o.camera_times = {{"5", 1}, {"7", 2}, {"1", 0}};  // camera 1 is trained at every frame anyway
  const Dataset d = Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o);
  REQUIRE(d.views().size() == 5);
  std::set<std::pair<std::string, int>> got;
  for (const TrainView& v : d.views()) got.insert({v.rig, v.frame});
  CHECK(got == std::set<std::pair<std::string, int>>{{"1", 0}, {"1", 1}, {"1", 2}, {"5", 1}, {"7", 2}});
  CHECK(d.rigs().size() == 3);
  REQUIRE(d.has_masks());
  for (size_t v = 0; v < d.views().size(); ++v) {
    const TrainView& tv = d.views()[v];
    if (tv.rig != "7") continue;
    CHECK(tv.camera.name == "7/000100");  // source frame 100
    CHECK(tv.camera.time == Approx(1.0));
    const Image im = read_image(panoptic() + "/ims/7/000100.jpg");
    double sum = 0;
    for (int dy = 0; dy < 8; ++dy)
      for (int dx = 0; dx < 8; ++dx) sum += im.pixels[(size_t(40 + dy) * 640 + size_t(320 + dx)) * size_t(im.channels)];
    CHECK(d.image(v)[(size_t(5) * 80 + 40) * 3] == Approx(sum / 64).margin(0.6 / 255));
    // Its mask is the file's, not another view's.
    const Image m = read_image(panoptic() + "/seg/7/000100.png");
    size_t fg = 0, mine = 0;
    for (int y = 0; y < 45; ++y)
      for (int x = 0; x < 80; ++x) {
        double s = 0;
        for (int dy = 0; dy < 8; ++dy)
          for (int dx = 0; dx < 8; ++dx) s += m.pixels[(size_t(8 * y + dy) * 640 + size_t(8 * x + dx)) * size_t(m.channels)];
        fg += std::lround(s / 64 * 255) > 127;  // the 8-bit block mean above one half
        mine += d.mask(v)[size_t(y) * 80 + size_t(x)];
      }
    CHECK(fg == mine);
  }
  DatasetOptions bad = o;
  bad.camera_times = {{"5", 3}};
  CHECK(error_of([&] { Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", bad); }).find("camera-time 5 at frame 3: the video has frames 0 to 2") !=
        std::string::npos);
  bad.camera_times = {{"nope", 0}};
  CHECK(error_of([&] { Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", bad); }).find("no camera named 'nope'") != std::string::npos);
  bad.cameras.clear();
  bad.camera_times = {{"5", 0}};
  CHECK(error_of([&] { Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", bad); }).find("none were named") != std::string::npos);
}

TEST_CASE("d3dgs reader: bad meta files and missing files are named in one line", "[video]") {
  const std::string dir = scratch("d3dgs_bad");
  // A two-frame, two-camera copy of the layout with the real first images and masks.
  std::ifstream in(panoptic() + "/train_meta.json");
  const json full = json::parse(in);
  json small = {{"w", 640}, {"h", 360}, {"k", json::array()}, {"w2c", json::array()}, {"fn", json::array()}, {"cam_id", json::array()}};
  for (size_t f = 0; f < 2; ++f)
    for (const char* key : {"k", "w2c", "fn", "cam_id"}) small[key].push_back({full[key][f][0], full[key][f][1]});
  for (const char* sub : {"ims", "seg"})
    for (size_t f = 0; f < 2; ++f)
      for (size_t i = 0; i < 2; ++i) {
        std::string rel = full["fn"][f][i].get<std::string>();
        if (std::string(sub) == "seg") rel = rel.substr(0, rel.size() - 4) + ".png";
        fs::create_directories((fs::path(dir) / sub / rel).parent_path());
        fs::copy_file(panoptic() + "/" + sub + "/" + rel, fs::path(dir) / sub / rel);
      }
  auto load = [&](const json& meta) {
    const std::string path = join_path(dir, "train_meta.json");
    write_file_atomically(path, meta.dump());
    return error_of([&] { Dataset::load(join_path(dir, "ims"), path); });
  };
  CHECK(load(small).empty());
  json j = small;
  j["fn"].erase(1);
  CHECK(load(j).find("train_meta.json: the lists disagree on the number of frames (k 2, w2c 2, fn 1, cam_id 2)") != std::string::npos);
  j = small;
  j["cam_id"][1][1] = 77;
  CHECK(load(j).find("train_meta.json: frame 1 has other cameras than frame 0") != std::string::npos);
  j = small;
  j["w2c"][1][0][0][0] = 2.0;
  CHECK(load(j).find("train_meta.json: frame 1 camera 1: w2c is not a rigid world-to-camera matrix") != std::string::npos);
  j = small;
  j["k"][0][1][2] = json::array({0, 0});
  CHECK(load(j).find("train_meta.json: frame 0 camera 2: k is not 3x3") != std::string::npos);
  j = small;
  j.erase("w2c");
  CHECK(load(j).find("train_meta.json: no 'w2c'") != std::string::npos);
  // A missing image, then a missing mask.
  fs::rename(join_path(dir, "ims/2/000001.jpg"), join_path(dir, "moved.jpg"));
  CHECK(load(small).find("camera '2/000001' has no image") != std::string::npos);
  fs::rename(join_path(dir, "moved.jpg"), join_path(dir, "ims/2/000001.jpg"));
  fs::remove(join_path(dir, "seg/1/000000.png"));
  CHECK(load(small).find("seg/1/000000.png: no foreground mask for") != std::string::npos);
  // A seg link that points nowhere is refused, not read as "no masks".
  fs::rename(join_path(dir, "seg"), join_path(dir, "seg.real"));
  fs::create_symlink("no/such/seg", join_path(dir, "seg"));
  CHECK(load(small).find("seg: a link to 'no/such/seg', which does not exist") != std::string::npos);
}

TEST_CASE("initialisation: the centre of interest of cameras looking at one point is that point", "[video][init]") {
  std::vector<Camera> cams;
  const Vec3d target(0.3, -1.2, 2.0);
  for (int i = 0; i < 5; ++i) {
    Camera c = axis_camera(64, 48, 50);
    const double a = 0.7 * i;
    c.look_at(target + 2.5 * Vec3d(std::cos(a), 0.3 * i - 0.6, std::sin(a)).normalized(), target, Vec3d(0, -1, 0));
    cams.push_back(c);
  }
  const auto [centre, r] = centre_of_interest(cams);
  CHECK((centre - target).norm() < 1e-9);
  CHECK(r == Approx(2.5));
  // Parallel axes have no such point: one clear error.
  std::vector<Camera> parallel(2, axis_camera(64, 48, 50));
  parallel[1].t = Vec3d(1, 0, 0);
  CHECK(error_of([&] { centre_of_interest(parallel); }).find("optical axes are parallel") != std::string::npos);
}

namespace {

/// Checks the initial points from the cameras alone: every point lands in front of each
/// view in `first` and inside its image; the carved ones (after `r.random`) on foreground
/// in each; every colour is the mean of the pixels it lands on. Returns the violations.
size_t init_points_violations(const Dataset& d, const std::vector<size_t>& first, const ViewInitResult& r) {
  size_t bad = 0;
  for (size_t i = 0; i < r.points.positions.size(); ++i) {
    Vec3d sum = Vec3d::Zero();
    bool in_all = true;
    for (size_t v : first) {
      const Camera& c = d.views()[v].camera;
      const Vec3d p = c.project(r.points.positions[i].cast<double>());
      const bool in = p.z() > 0 && p.x() >= 0 && p.y() >= 0 && p.x() < c.width && p.y() < c.height;
      if (!in) {
        in_all = false;
        break;
      }
      const size_t q = size_t(std::floor(p.y())) * size_t(c.width) + size_t(std::floor(p.x()));
      if (i >= r.random && !d.mask(v)[q]) in_all = false;
      const std::vector<float> im = d.image(v);
      for (int ch = 0; ch < 3; ++ch) sum[ch] += im[q * 3 + size_t(ch)] / double(first.size());
    }
    if (!in_all || (sum.cast<float>() - r.points.colours[i]).norm() > 1e-4f) ++bad;
  }
  return bad;
}

}  // namespace

TEST_CASE("initialisation from the views: random points both cameras see, and the masks' visual hull", "[video][init]") {
  const Dataset d = load_panoptic({"5", "6"}, "0:2", 4);
  ViewInitOptions vo;
  vo.random_points = 2000;
  vo.carve_cells = 64;
  const ViewInitResult r = points_from_views(d, vo);
  REQUIRE(r.random == 2000);
  REQUIRE(r.carved > 0);
  REQUIRE(r.points.positions.size() == r.random + r.carved);
  // Checked from the cameras alone against both first-frame views.
  std::vector<size_t> first;
  for (size_t v = 0; v < d.views().size(); ++v)
    if (d.views()[v].frame == 0) first.push_back(v);
  REQUIRE(first.size() == 2);
  CHECK(init_points_violations(d, first, r) == 0);
  // Same seed, same points; without carving only the random ones.
  CHECK(points_from_views(d, vo).points.positions == r.points.positions);
  vo.method = ViewInit::Random;
  CHECK(points_from_views(d, vo).carved == 0);
}

TEST_CASE("initialisation of a monocular video: each cycled camera's first view", "[video][init]") {
  // --monocular-cycle 5,6 over frames 0..3: frame f holds camera [f mod 2] only, so no frame
  // has two cameras; the points come from camera 5 at frame 0 and camera 6 at frame 1.
  DatasetOptions o;
  o.frames = FrameRange::parse("0:4");
  o.downscale = 4;
  o.monocular_cycle = {"5", "6"};
  const Dataset d = Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o);
  REQUIRE(d.views().size() == 4);
  std::vector<size_t> first;
  for (size_t v = 0; v < d.views().size(); ++v)
    if (d.views()[v].frame == (d.views()[v].rig == "5" ? 0 : 1)) first.push_back(v);
  REQUIRE(first.size() == 2);
  ViewInitOptions vo;
  vo.random_points = 1000;
  vo.carve_cells = 48;
  const ViewInitResult r = points_from_views(d, vo);
  CHECK(r.random == 1000);
  CHECK(init_points_violations(d, first, r) == 0);
  // Only one camera at frame 0: the frame-0 views alone cannot place a point.
  std::vector<size_t> frame0;
  for (size_t v = 0; v < d.views().size(); ++v)
    if (d.views()[v].frame == 0) frame0.push_back(v);
  CHECK(frame0.size() == 1);
}

namespace {

/// A Neural 3D Video-like folder: `names`.mp4 (written with OpenCV's VideoWriter, MPEG-4
/// part 2), `frames` frames of 64×48, frame f of video v a flat colour (30f, 60 + 40v,
/// 220 − 25f) with a white square at (4 + 4f, 8); poses_bounds.npy, one row per video.
std::string write_video_rig(const std::string& dir, const std::vector<std::string>& names, const std::vector<int>& frames) {
  std::vector<double> rows;
  for (size_t v = 0; v < names.size(); ++v) {
    cv::VideoWriter w(join_path(dir, names[v] + ".mp4"), cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 30, cv::Size(64, 48));
    REQUIRE(w.isOpened());
    for (int f = 0; f < frames[v]; ++f) {
      cv::Mat m(48, 64, CV_8UC3, cv::Scalar(220 - 25 * f, 60 + 40 * double(v), 30 * f));  // BGR
      cv::rectangle(m, cv::Rect(4 + 4 * f, 8, 8, 8), cv::Scalar(255, 255, 255), cv::FILLED);
      w.write(m);
    }
    // LLFF row: down, right, back, centre, hwf; cameras 0.5 apart along x, looking down +z.
    const double row[17] = {0, 1, 0, 0.5 * double(v), 48, 1, 0, 0, 0, 64, 0, 0, -1, -3, 60, 0.5, 20};
    rows.insert(rows.end(), row, row + 17);
  }
  write_npy(join_path(dir, "poses_bounds.npy"), rows.data(), {names.size(), 17});
  return join_path(dir, "poses_bounds.npy");
}

}  // namespace

TEST_CASE("Neural 3D Video as distributed: mp4 per camera + poses_bounds.npy, frames decoded on load", "[video]") {
  const std::string dir = scratch("n3v_mp4");
  // cam01 missing, as some N3V scenes lack a camera: the rows follow the videos there are.
  const std::string poses = write_video_rig(dir, {"cam00", "cam02", "cam03"}, {8, 8, 8});
  DatasetOptions o;
  o.frames = FrameRange::parse("1:8:3");  // frames 1, 4, 7
  o.downscale = 2;
  const Dataset d = Dataset::load(dir, poses, o);
  REQUIRE(d.frames() == 3);
  REQUIRE(d.views().size() == 9);
  CHECK(d.rigs() == std::vector<std::string>{"cam00", "cam02", "cam03"});
  for (size_t i = 0; i < d.views().size(); ++i) {
    const TrainView& v = d.views()[i];
    const int cam = int(i / 3), f = v.source_frame;
    INFO(v.camera.name);
    CHECK(f == 1 + 3 * v.frame);
    CHECK(v.camera.time == Approx(v.frame / 2.0));
    CHECK(v.camera.width == 32);
    CHECK(v.camera.fx == Approx(30));
    CHECK(v.camera.centre().x() == Approx(0.5 * cam));
    // A flat pixel away from the square, RGB, within the codec's error.
    const std::vector<float> px = d.image(i);
    const size_t p = (size_t(20) * 32 + 28) * 3;
    CHECK(px[p] * 255 == Approx(30 * f).margin(8));
    CHECK(px[p + 1] * 255 == Approx(60 + 40 * cam).margin(8));
    CHECK(px[p + 2] * 255 == Approx(220 - 25 * f).margin(8));
    // The white square moved with the frame: its 2×2-block centre is bright.
    const size_t q = (size_t(6) * 32 + size_t(2 + 2 * f + 2)) * 3;
    CHECK(px[q + 1] > 0.85f);
  }
}

TEST_CASE("image cache: a dataset past its image budget reads back the same images from its file, for JPEG frames and mp4 video", "[video]") {
  // The in-memory dataset is the reference; budget 0 spills every image.
  auto same = [](const Dataset& held, const Dataset& spilled) {
    CHECK_FALSE(held.images_spilled());
    CHECK(spilled.images_spilled());
    CHECK(held.image_bytes() == spilled.image_bytes());
    REQUIRE(held.views().size() == spilled.views().size());
    for (size_t i = 0; i < held.views().size(); ++i) {
      REQUIRE(held.views()[i].camera.name == spilled.views()[i].camera.name);
      REQUIRE(held.image(i) == spilled.image(i));
      REQUIRE(held.mask(i) == spilled.mask(i));
    }
  };
  DatasetOptions o;
  o.cameras = {"1", "5", "12"};
  o.frames = FrameRange::parse("0:150:30");
  o.downscale = 2;
  const Dataset held = Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o);
  CHECK(held.image_bytes() == 15 * size_t(320 * 180 * 3));
  o.image_memory = 0;
  const Dataset spilled = Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o);
  same(held, spilled);
  const Dataset copy = spilled;  // copies share the file
  CHECK(copy.image(7) == held.image(7));
  // A budget the images fit in keeps them in memory.
  o.image_memory = int64_t(held.image_bytes());
  CHECK_FALSE(Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o).images_spilled());

  const std::string dir = scratch("n3v_cache");
  const std::string poses = write_video_rig(dir, {"cam00", "cam01"}, {6, 6});
  DatasetOptions v;
  const Dataset vheld = Dataset::load(dir, poses, v);
  v.image_memory = 0;
  v.spill_dir = join_path(dir, "cache");
  make_directories(v.spill_dir);
  same(vheld, Dataset::load(dir, poses, v));
  CHECK(fs::is_empty(v.spill_dir));  // the cache file is unlinked as soon as it is made
  v.spill_dir = join_path(dir, "no/such/folder");
  CHECK(error_of([&] { Dataset::load(dir, poses, v); }).find("cannot make the image cache") != std::string::npos);
}

TEST_CASE("Neural 3D Video as distributed: bad videos are named in one line", "[video]") {
  const std::string dir = scratch("n3v_mp4_bad");
  const std::string poses = write_video_rig(dir, {"cam00", "cam01"}, {6, 5});
  CHECK(error_of([&] { Dataset::load(dir, poses); }).find("cam01.mp4: 5 frames, but other cameras have 6") != std::string::npos);
  write_video_rig(dir, {"cam00", "cam01"}, {6, 6});
  CHECK(error_of([&] { Dataset::load(dir, poses); }).empty());
  std::ofstream(join_path(dir, "cam01.mp4"), std::ios::binary | std::ios::trunc) << "not a video at all";
  CHECK(error_of([&] { Dataset::load(dir, poses); }).find("cam01.mp4: cannot open the video") != std::string::npos);
  std::ofstream(join_path(dir, "cam02.mp4"), std::ios::binary) << "x";
  CHECK(error_of([&] { Dataset::load(dir, poses); }).find("poses_bounds.npy: 2 rows, but") != std::string::npos);
}

TEST_CASE("Technicolor: cameras_parameters.txt and the frames as its preprocessing names them", "[video]") {
  const std::string dir = scratch("technicolor");
  // Two cameras (rows: f cx cy _ _ qw qx qy qz tx ty tz), frames 50..52 of scene "Birthday".
  std::ofstream(join_path(dir, "cameras_parameters.txt")) << "f cx cy ar skew qw qx qy qz tx ty tz\n"
                                                         << "1500 1024 544 1 0 1 0 0 0 0 0 0\n"
                                                         << "1500 1024 544 1 0 1 0 0 0 -0.1 0 0\n";
  for (int f = 50; f < 53; ++f)
    for (int c = 0; c < 2; ++c) {
      Image im(2048, 1088, 3, 0.0f);
      for (size_t p = 0; p < im.pixels.size(); p += 3) im.pixels[p] = float(f - 50) / 4, im.pixels[p + 1] = float(c) / 2;
      char name[64];
      std::snprintf(name, sizeof name, "Birthday_undist_%05d_%02d.png", f, c);
      write_image(join_path(dir, name), im);
    }
  std::ofstream(join_path(dir, "Birthday_undist_00050_00.png.bak")) << "not a frame";
  DatasetOptions o;
  o.downscale = 8;
  const Dataset d = Dataset::load(dir, join_path(dir, "cameras_parameters.txt"), o);
  REQUIRE(d.views().size() == 6);
  CHECK(d.frames() == 3);
  CHECK(d.rigs() == std::vector<std::string>{"cam00", "cam01"});
  for (size_t i = 0; i < d.views().size(); ++i) {
    const TrainView& v = d.views()[i];
    CHECK(v.camera.width == 256);
    const std::vector<float> px = d.image(i);
    CHECK(px[0] == Approx(v.frame / 4.0).margin(1.0 / 255));  // 8-bit PNG, then the 8-bit cache
    CHECK(px[1] == Approx(v.rig == "cam00" ? 0.0 : 0.5).margin(1.0 / 255));
  }
  // A camera without frames is named with the file pattern it looked for.
  std::ofstream(join_path(dir, "cameras_parameters.txt"), std::ios::app) << "1500 1024 544 1 0 1 0 0 0 -0.2 0 0\n";
  CHECK(error_of([&] { Dataset::load(dir, join_path(dir, "cameras_parameters.txt")); }).find("camera 'cam02' has no images") !=
        std::string::npos);
}

TEST_CASE("monocular video (--monocular-cycle): one view per frame, cycling through the cameras named", "[video]") {
  DatasetOptions o;
  o.frames = FrameRange::parse("0:14:2");  // 7 frames: source frames 0, 2, …, 12
  o.downscale = 8;
  o.monocular_cycle = {"3", "1", "8"};
  const Dataset d = Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o);
  REQUIRE(d.views().size() == 7);
  CHECK(d.frames() == 7);
  for (size_t i = 0; i < d.views().size(); ++i) {
    const TrainView& v = d.views()[i];
    CHECK(v.rig == o.monocular_cycle[size_t(v.frame) % 3]);
    CHECK(v.source_frame == 2 * v.frame);
  }
  std::vector<int> frames;
  for (const TrainView& v : d.views()) frames.push_back(v.frame);
  std::sort(frames.begin(), frames.end());
  CHECK(frames == std::vector<int>{0, 1, 2, 3, 4, 5, 6});
  o.monocular_cycle = {"3", "10"};  // camera 10 is not in the capture
  CHECK(error_of([&] { Dataset::load(panoptic() + "/ims", panoptic() + "/train_meta.json", o); })
            .find("the monocular cycle names camera '10', which the dataset does not have") != std::string::npos);
}

TEST_CASE("N3V frame 0: COLMAP points3D.bin and one image per camera", "[video]") {
  const std::string root = shared_data() + "/video/n3v_flame_steak_frame0";
  const PointSet ps = read_points(root + "/sparse/0/points3D.bin");
  REQUIRE(ps.positions.size() == 7298);
  // The first record, read with Python's struct ('<Q', then '<Qddd' and '<BBB').
  CHECK(ps.positions[0].x() == Approx(-4.694851556413252));
  CHECK(ps.positions[0].y() == Approx(6.23857386184535));
  CHECK(ps.positions[0].z() == Approx(11.362469012312957));
  CHECK(ps.colours[0].x() == Approx(51 / 255.0));
  CHECK(ps.colours[0].z() == Approx(21 / 255.0));
  // Truncated and inflated copies are refused with the file's name.
  const std::string dir = scratch("points_bin");
  const std::string bytes = read_file(root + "/sparse/0/points3D.bin");
  write_file_atomically(dir + "/cut.bin", bytes.substr(0, bytes.size() - 5));
  CHECK(error_of([&] { read_points(dir + "/cut.bin"); }).find("cut.bin: ") != std::string::npos);
  std::string inflated = bytes;
  const uint64_t huge = uint64_t(1) << 60;
  std::memcpy(&inflated[0], &huge, 8);
  write_file_atomically(dir + "/huge.bin", inflated);
  CHECK(error_of([&] { read_points(dir + "/huge.bin"); }).find("huge.bin: claims 1152921504606846976 points") != std::string::npos);
  // The frame-0 images, one per camera, with the rig's COLMAP model.
  DatasetOptions o;
  o.cameras = {"cam00", "cam14"};
  o.downscale = 8;
  const Dataset d = Dataset::load(root + "/images", root + "/sparse/0", o);
  REQUIRE(d.views().size() == 2);
  CHECK(d.frames() == 1);
  CHECK(d.views()[0].camera.width == 2690 / 8);
  CHECK(d.views()[0].camera.height == 2016 / 8);
}

TEST_CASE("Panoptic: --motion-from-masks makes a camera's changing pixels the union of its dilated foreground masks", "[video][motion]") {
  const Dataset d = load_panoptic({"1", "5"}, "0:150:50", 8);  // 2 cameras x 3 frames, 80x45
  REQUIRE(d.has_masks());
  REQUIRE(d.frames() == 3);
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 0), 0.1f, 0.0f, Vec3f(0.5f, 0.5f, 0.5f));
  TrainOptions o = TrainOptions::scaled(10);
  o.change_from_masks = true;
  const std::vector<double> share = Trainer(d, params_from_cloud<float>(c), o).changing_share();
  o.change_from_masks = false;
  const std::vector<double> colour = Trainer(d, params_from_cloud<float>(c), o).changing_share();
  REQUIRE(share.size() == d.views().size());
  for (size_t v = 0; v < d.views().size(); ++v) {
    const Camera& cam = d.views()[v].camera;
    const int W = cam.width, H = cam.height, r = o.change_dilation;
    // Union over this camera's frames, then a square dilation of r pixels, counted here.
    std::vector<uint8_t> any(size_t(W) * size_t(H), 0);
    for (size_t u = 0; u < d.views().size(); ++u)
      if (d.views()[u].camera.name.substr(0, d.views()[u].camera.name.find('/')) == cam.name.substr(0, cam.name.find('/'))) {
        const std::vector<uint8_t> m = d.mask(u);
        for (size_t p = 0; p < any.size(); ++p) any[p] |= m[p];
      }
    size_t grown = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        bool hit = false;
        for (int dy = -r; dy <= r && !hit; ++dy)
          for (int dx = -r; dx <= r && !hit; ++dx) {
            const int xx = x + dx, yy = y + dy;
            hit = xx >= 0 && yy >= 0 && xx < W && yy < H && any[size_t(yy) * size_t(W) + size_t(xx)];
          }
        grown += hit;
      }
    INFO("view " << cam.name);
    CHECK(share[v] == Approx(double(grown) / double(any.size())));
    CHECK(share[v] > 0.0);
    CHECK(share[v] != Approx(colour[v]));  // the colour rule marks other pixels
  }
}
