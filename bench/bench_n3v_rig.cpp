// fillgs_bench n3v-rig: a stand-in for a whole Neural 3D Video scene as distributed — one
// camNN.mp4 per camera of the real N3V rig and its poses_bounds.npy — at the size a user
// trains within this machine (21 cameras x 300 frames at 1352x1014, 26 GB of
// 8-bit frames). `../shared/data` holds frame 0 of flame_steak only, so frame f of camera c
// is that camera's real frame-0 photograph with a disc painted in at a place that moves with
// f: the real rig's geometry, image sizes and real image content, and frames that differ, so
// that nothing about memory depends on the content. bench/n3v_memory.sh trains on it.
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "cli/options.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/model/camera.hpp"

using namespace fillgs;

namespace {

/// One LLFF poses_bounds row (N3V's layout): the camera-to-world columns down, right, back
/// and the centre, each followed by one of (height, width, focal), then near and far.
std::vector<double> llff_row(const Camera& c, int width, int height, double focal, double near, double far) {
  const Mat3d c2w = c.R.transpose();
  const Vec3d cols[4] = {c2w.col(1), c2w.col(0), -c2w.col(2), c.centre()};
  const double hwf[3] = {double(height), double(width), focal};
  std::vector<double> row(17);
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 4; ++k) row[size_t(i * 5 + k)] = cols[k][i];
    row[size_t(i * 5 + 4)] = hwf[i];
  }
  row[15] = near;
  row[16] = far;
  return row;
}

}  // namespace

int bench_n3v_rig(const std::vector<std::string>& args) {
  bool smoke = false;
  std::string out;
  int frames = 300, width = 1352;
  auto app = cli::make_parser("fillgs_bench n3v-rig",
                              "writes a whole-scene Neural 3D Video stand-in (camNN.mp4 + poses_bounds.npy) from the real rig's frame 0");
  cli::add_flag(*app, "--smoke", smoke, "4 frames at 84 pixels wide");
  cli::add_text(*app, "--out", out, "the folder to write (must not exist)", "DIR")->required();
  cli::add_number(*app, "--frames", frames, "frames per camera", cli::within(2, 100000));
  cli::add_number(*app, "--width", width, "video width in pixels (the height keeps the photographs' aspect, rounded to even)", cli::within(16, 2690));
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  if (smoke) {
    frames = 4;
    width = 84;
  }
  if (std::filesystem::exists(out)) throw_error("n3v-rig: ", out, " exists; choose a new folder");
  const std::string src = shared_data_dir() + "/video/n3v_flame_steak_frame0";
  std::vector<Camera> cams = read_cameras(src + "/sparse/0");
  std::sort(cams.begin(), cams.end(), [](const Camera& a, const Camera& b) { return a.name < b.name; });
  const auto start = std::chrono::steady_clock::now();
  OutputFolder folder(out);
  std::vector<double> rows;
  uint64_t frame_bytes = 0;
  for (size_t c = 0; c < cams.size(); ++c) {
    const Camera& cam = cams[c];
    const std::string image = src + "/images/" + (cam.image_path.empty() ? cam.name + ".png" : cam.image_path);
    const cv::Mat photo = cv::imread(image, cv::IMREAD_COLOR);
    if (photo.empty()) throw_error(image, ": cannot read the photograph of ", cam.name);
    if (photo.cols != cam.width || photo.rows != cam.height)
      throw_error(image, ": ", photo.cols, "x", photo.rows, ", but the model's ", cam.name, " is ", cam.width, "x", cam.height);
    const double scale = double(width) / cam.width;
    const int height = 2 * int(std::lround(cam.height * scale / 2));  // MPEG-4 wants even sizes (1352 -> 1014)
    cv::Mat base;
    cv::resize(photo, base, cv::Size(width, height), 0, 0, cv::INTER_AREA);
    char name[32];
    std::snprintf(name, sizeof name, "cam%02zu.mp4", c);
    const std::string video = folder.path() + "/" + name;
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 30, cv::Size(width, height));
    if (!writer.isOpened()) throw_error(video, ": OpenCV cannot write MPEG-4 video here");
    const int radius = std::max(2, width / 16);
    for (int f = 0; f < frames; ++f) {
      cv::Mat m = base.clone();
      const double s = double(f) / double(frames - 1);
      cv::circle(m, cv::Point(int(width * (0.2 + 0.6 * s)), int(height * (0.5 + 0.2 * std::sin(6.283 * s)))), radius,
                 cv::Scalar(40, 60, 230), cv::FILLED, cv::LINE_AA);
      writer.write(m);
    }
    writer.release();
    // LLFF keeps one focal length and a centred principal point: N3V's own poses do.
    const std::vector<double> row = llff_row(cam, width, height, cam.fx * scale, 0.5, 100.0);
    rows.insert(rows.end(), row.begin(), row.end());
    frame_bytes += uint64_t(frames) * uint64_t(width) * uint64_t(height) * 3;
    std::printf("n3v-rig: %s (%s) %d frames at %dx%d\n", name, cam.name.c_str(), frames, width, height);
    std::fflush(stdout);
  }
  write_npy(folder.path() + "/poses_bounds.npy", rows.data(), {cams.size(), 17});
  folder.commit();
  std::printf("n3v-rig: %zu cameras x %d frames, %.1f GB of 8-bit frames, written to %s in %.0f s\n", cams.size(), frames,
              double(frame_bytes) / 1e9, out.c_str(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}
