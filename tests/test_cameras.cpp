// Camera readers: for every format a file written here by hand (or the real D-NeRF rig)
// and a world point whose pixel is known in closed form; writers round-trip.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "fillgs/model/camera.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/train/train.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

// The reference camera of the hand-made files: centre (0, 0, -5), looking along +z,
// OpenCV axes aligned with the world (right = +x, down = +y). World point (1, 0.5, 0)
// is at camera (1, 0.5, 5): pixel (cx + f/5, cy + f*0.5/5).
constexpr double kF = 500, kCx = 320, kCy = 240;
constexpr int kW = 640, kH = 480;

void check_reference_projection(const Camera& c, double cx = kCx, double cy = kCy) {
  const Vec3d p = c.project(Vec3d(1, 0.5, 0));
  CHECK(p.x() == Approx(cx + kF / 5).epsilon(1e-9));
  CHECK(p.y() == Approx(cy + kF * 0.5 / 5).epsilon(1e-9));
  CHECK(p.z() == Approx(5).epsilon(1e-9));
  CHECK(c.width == kW);
  CHECK(c.height == kH);
}

template <typename T>
void put(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}

}  // namespace

TEST_CASE("COLMAP text: PINHOLE and SIMPLE_PINHOLE, sorted by name", "[cameras]") {
  const std::string dir = scratch("colmap_txt");
  std::ofstream(dir + "/cameras.txt") << "# comment\n1 PINHOLE 640 480 500 500 320 240\n2 SIMPLE_PINHOLE 640 480 500 300 200\n";
  std::ofstream(dir + "/images.txt") << "# images\n2 1 0 0 0 0 0 5 2 b.png\n\n1 1 0 0 0 0 0 5 1 a.png\n10 20 -1\n";
  const auto cams = read_cameras(dir);
  REQUIRE(cams.size() == 2);
  CHECK(cams[0].name == "a");
  check_reference_projection(cams[0]);
  check_reference_projection(cams[1], 300, 200);
}

TEST_CASE("COLMAP text: a rotated camera projects like the pose says", "[cameras]") {
  const std::string dir = scratch("colmap_rot");
  // Rotation of 90° about y: q = (cos 45°, 0, sin 45°, 0). World point X ↦ R X + t.
  const double h = std::sqrt(0.5);
  std::ofstream(dir + "/cameras.txt") << "1 PINHOLE 640 480 500 500 320 240\n";
  std::ofstream(dir + "/images.txt") << "1 " << h << " 0 " << h << " 0 0 0 5 1 r.png\n\n";
  const auto cams = read_cameras(dir);
  // R_y(90°) maps world (0, 0.5, -1) to (-1, 0.5, 0); plus t = (0,0,5): camera (-1, 0.5, 5).
  const Vec3d p = cams[0].project(Vec3d(0, 0.5, -1));
  CHECK(p.x() == Approx(320 - 100).epsilon(1e-9));
  CHECK(p.y() == Approx(240 + 50).epsilon(1e-9));
}

TEST_CASE("COLMAP binary reads like text, and rejects distortion models", "[cameras]") {
  const std::string dir = scratch("colmap_bin");
  std::string cams, imgs;
  put<uint64_t>(cams, 1);
  put<int32_t>(cams, 7);
  put<int32_t>(cams, 1);  // PINHOLE
  put<uint64_t>(cams, 640);
  put<uint64_t>(cams, 480);
  for (double v : {500.0, 500.0, 320.0, 240.0}) put(cams, v);
  put<uint64_t>(imgs, 1);
  put<int32_t>(imgs, 3);
  for (double v : {1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 5.0}) put(imgs, v);
  put<int32_t>(imgs, 7);
  imgs += std::string("cam00.png") + '\0';
  put<uint64_t>(imgs, 1);
  put(imgs, 1.0);
  put(imgs, 2.0);
  put<int64_t>(imgs, -1);
  std::ofstream(dir + "/cameras.bin", std::ios::binary) << cams;
  std::ofstream(dir + "/images.bin", std::ios::binary) << imgs;
  const auto c = read_cameras(dir);
  REQUIRE(c.size() == 1);
  CHECK(c[0].name == "cam00");
  check_reference_projection(c[0]);

  const std::string d2 = scratch("colmap_opencv");
  std::ofstream(d2 + "/cameras.txt") << "1 OPENCV 640 480 500 500 320 240 0.1 0 0 0\n";
  std::ofstream(d2 + "/images.txt") << "1 1 0 0 0 0 0 5 1 a.png\n\n";
  try {
    read_cameras(d2);
    FAIL("expected an error");
  } catch (const Error& e) {
    const std::string m = e.what();
    CHECK(m.find("cameras.txt") != std::string::npos);
    CHECK(m.find("camera 1") != std::string::npos);
    CHECK(m.find("OPENCV") != std::string::npos);
  }
}

TEST_CASE("LLFF poses_bounds.npy: down-right-back columns and hwf", "[cameras]") {
  const std::string path = scratch("llff") + "/poses_bounds.npy";
  // Row: [c0 down | c1 right | c2 back | c3 centre | c4 hwf] row-major 3x5, then near, far.
  // right = +x, down = +y, back = -z (forward +z), centre (0,0,-5), H 960 W 1280 f 1000.
  const double row[17] = {0, 1, 0, 0, 960, 1, 0, 0, 0, 1280, 0, 0, -1, -5, 1000, 0.5, 50};
  write_npy(path, row, {1, 17});
  CameraReadOptions o;
  o.llff_downscale = 2;  // as Neural 3D Video is used
  const auto cams = read_cameras(path, o);
  REQUIRE(cams.size() == 1);
  CHECK(cams[0].name == "cam00");
  check_reference_projection(cams[0]);
}

TEST_CASE("transforms.json (OpenGL axes) and 3DGS cameras.json", "[cameras]") {
  const std::string dir = scratch("json");
  // OpenGL camera-to-world: columns right (+x), up (-y), back (-z), centre (0,0,-5).
  std::ofstream(dir + "/transforms.json") << R"({"fl_x": 500, "fl_y": 500, "cx": 320, "cy": 240, "w": 640, "h": 480,
    "frames": [{"file_path": "./images/c0", "time": 0.25,
      "transform_matrix": [[1,0,0,0],[0,-1,0,0],[0,0,-1,-5],[0,0,0,1]]}]})";
  const auto t = read_cameras(dir + "/transforms.json");
  REQUIRE(t.size() == 1);
  CHECK(t[0].name == "images/c0");
  CHECK(t[0].time == 0.25);
  check_reference_projection(t[0]);
  // cameras.json: rotation rows of camera-to-world with OpenCV axes as columns.
  std::ofstream(dir + "/cameras.json") << R"([{"id": 0, "img_name": "c0", "width": 640, "height": 480,
    "position": [0, 0, -5], "rotation": [[1,0,0],[0,1,0],[0,0,1]], "fx": 500, "fy": 500}])";
  const auto g = read_cameras(dir + "/cameras.json");
  REQUIRE(g.size() == 1);
  check_reference_projection(g[0]);
}

TEST_CASE("Technicolor cameras_parameters.txt", "[cameras]") {
  const std::string path = scratch("technicolor") + "/cameras_parameters.txt";
  std::ofstream(path) << "f cx cy ar skew qw qx qy qz tx ty tz\n500 300 200 1 0 1 0 0 0 0 0 5\n500 300 200 1 0 1 0 0 0 0 0 5\n";
  CameraReadOptions o;
  o.width = 640;
  o.height = 480;
  const auto cams = read_cameras(path, o);
  REQUIRE(cams.size() == 2);
  CHECK(cams[1].name == "cam01");
  check_reference_projection(cams[0], 300, 200);
}

TEST_CASE("real D-NeRF rig: the optical axis and the right axis project as the matrix says", "[cameras][data]") {
  const std::string path = shared_data() + "/rigs/dnerf_monocular_train.json";
  CameraReadOptions o;
  o.width = o.height = 800;  // D-NeRF images are 800x800; the rig ships no images
  const auto cams = read_cameras(path, o);
  REQUIRE(cams.size() == 50);
  // Independent reading of the same JSON.
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in);
  const double f = 800 / (2 * std::tan(j["camera_angle_x"].get<double>() / 2));
  for (size_t i = 0; i < cams.size(); i += 7) {
    const auto& m = j["frames"][i]["transform_matrix"];
    const Vec3d C(m[0][3], m[1][3], m[2][3]);
    const Vec3d right(m[0][0], m[1][0], m[2][0]), back(m[0][2], m[1][2], m[2][2]);
    const Vec3d p = cams[i].project(C - 2.0 * back + 0.5 * right);
    // The stored matrices are float32-orthonormal: agreement to ~1e-6 relative.
    CHECK(p.x() == Approx(400 + f * 0.5 / 2).epsilon(1e-6));
    CHECK(p.y() == Approx(400).epsilon(1e-6));
    CHECK(p.z() == Approx(2).epsilon(1e-6));
    CHECK(cams[i].time == j["frames"][i]["time"].get<double>());
  }
  CHECK(cams.front().time == 0.0);
  CHECK(cams.back().time == Approx(1.0));
  CHECK(cams[0].name == "train_low/r_0");
}

TEST_CASE("transforms.json and COLMAP text writers round-trip", "[cameras]") {
  std::vector<Camera> cams(2);
  cams[0].look_at(Vec3d(1, 2, 3), Vec3d(0, 0, 0), Vec3d(0, 0, 1));
  cams[1].look_at(Vec3d(-2, 1, 0.5), Vec3d(0, 0.3, 0), Vec3d(0, 0, 1));
  for (int i = 0; i < 2; ++i) {
    cams[size_t(i)].name = "v" + std::to_string(i);
    cams[size_t(i)].width = 320 + i;
    cams[size_t(i)].height = 240;
    cams[size_t(i)].fx = 300;
    cams[size_t(i)].fy = 310;
    cams[size_t(i)].cx = 160.5;
    cams[size_t(i)].cy = 119;
    cams[size_t(i)].time = 0.1 * i;
  }
  const std::string dir = scratch("writers");
  write_transforms_json(dir + "/transforms.json", cams);
  write_colmap_text(dir + "/colmap", cams);
  const auto t = read_cameras(dir + "/transforms.json");
  const auto c = read_cameras(dir + "/colmap");
  for (size_t i = 0; i < 2; ++i) {
    for (const auto* r : {&t[i], &c[i]}) {
      CHECK((r->R - cams[i].R).cwiseAbs().maxCoeff() < 1e-9);
      CHECK((r->t - cams[i].t).cwiseAbs().maxCoeff() < 1e-9);
      CHECK(r->fx == cams[i].fx);
      CHECK(r->fy == cams[i].fy);
      CHECK(r->cx == cams[i].cx);
      CHECK(r->width == cams[i].width);
    }
    CHECK(t[i].time == cams[i].time);
  }
}

namespace {

/// Name, size and intrinsics equal; rotation and translation within `tolerance`.
void check_same_camera(const Camera& a, const Camera& b, double tolerance) {
  INFO(a.name);
  CHECK(a.name == b.name);
  CHECK((a.R - b.R).cwiseAbs().maxCoeff() < tolerance);
  CHECK((a.t - b.t).cwiseAbs().maxCoeff() < tolerance);
  CHECK(a.fx == b.fx);
  CHECK(a.fy == b.fy);
  CHECK(a.cx == b.cx);
  CHECK(a.cy == b.cy);
  CHECK(a.width == b.width);
  CHECK(a.height == b.height);
}

}  // namespace

TEST_CASE("COLMAP 3.8 itself reads fillgs's export: model_converter to binary, read back by fillgs", "[cameras][colmap]") {
  if (std::system("colmap help >/dev/null 2>&1") != 0) {
    WARN("skipped: no 'colmap' program (Debian colmap; scripts/install-deps.sh installs it)");
    return;
  }
  std::vector<Camera> cams(3);
  cams[0].look_at(Vec3d(1, 2, 3), Vec3d(0, 0, 0), Vec3d(0, 0, 1));
  cams[1].look_at(Vec3d(-2, 1, 0.5), Vec3d(0, 0.3, 0), Vec3d(0, 0, 1));
  cams[2].look_at(Vec3d(0.3, -3, 1), Vec3d(0.1, 0, 0.2), Vec3d(0, 0, 1));
  for (int i = 0; i < 3; ++i) {
    Camera& c = cams[size_t(i)];
    c.name = "v" + std::to_string(i);
    c.width = 320 + 2 * i;
    c.height = 240;
    c.fx = 300 + i;
    c.fy = 310;
    c.cx = 160.5;
    c.cy = 119.25;
  }
  const std::string dir = scratch("colmap_program");
  write_colmap_text(dir + "/text", cams);
  std::filesystem::create_directories(dir + "/bin");
  const std::string cmd = "colmap model_converter --input_path " + dir + "/text --output_path " + dir + "/bin --output_type BIN > " + dir +
                          "/colmap.log 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  REQUIRE(std::filesystem::exists(dir + "/bin/images.bin"));
  const auto back = read_cameras(dir + "/bin");
  REQUIRE(back.size() == cams.size());
  // COLMAP stores the pose as a quaternion and translation in doubles: the same pose to
  // rounding, and the same intrinsics exactly.
  for (size_t i = 0; i < cams.size(); ++i) check_same_camera(back[i], cams[i], 1e-9);
}

TEST_CASE("COLMAP 3.8 converts the N3V model to text: fillgs reads both forms alike", "[cameras][colmap]") {
  if (std::system("colmap help >/dev/null 2>&1") != 0) {
    WARN("skipped: no 'colmap' program (Debian colmap; scripts/install-deps.sh installs it)");
    return;
  }
  const std::string model = shared_data() + "/video/n3v_flame_steak_frame0/sparse/0";
  const std::string dir = scratch("colmap_n3v_text");
  const std::string cmd = "colmap model_converter --input_path " + model + " --output_path " + dir + " --output_type TXT > " + dir + "/colmap.log 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  // Cameras: COLMAP's own text against fillgs's reading of the binary.
  const auto bin = read_cameras(model), txt = read_cameras(dir);
  REQUIRE(bin.size() == 21);
  REQUIRE(txt.size() == bin.size());
  for (size_t i = 0; i < bin.size(); ++i) check_same_camera(txt[i], bin[i], 1e-12);
  // Points: COLMAP writes the 7,298 points of points3D.bin as text; fillgs reads both.
  const PointSet pb = read_points(model + "/points3D.bin"), pt = read_points(dir + "/points3D.txt");
  REQUIRE(pb.positions.size() == 7298);
  REQUIRE(pt.positions.size() == pb.positions.size());
  // COLMAP writes them in its own order: compare sorted by position.
  auto sorted = [](const PointSet& p) {
    std::vector<std::array<float, 6>> rows;
    for (size_t i = 0; i < p.positions.size(); ++i)
      rows.push_back({p.positions[i].x(), p.positions[i].y(), p.positions[i].z(), p.colours[i].x(), p.colours[i].y(), p.colours[i].z()});
    std::sort(rows.begin(), rows.end());
    return rows;
  };
  const auto rb = sorted(pb), rt = sorted(pt);
  double worst = 0, worst_colour = 0;
  for (size_t i = 0; i < rb.size(); ++i)
    for (int k = 0; k < 6; ++k) (k < 3 ? worst : worst_colour) = std::max(k < 3 ? worst : worst_colour, double(std::fabs(rt[i][size_t(k)] - rb[i][size_t(k)])));
  CHECK(worst < 1e-5);  // COLMAP's text keeps 17 digits; fillgs stores floats
  CHECK(worst_colour == 0.0);
}
