#include "fillgs/io/video.hpp"

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <filesystem>

#include "fillgs/base/error.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {

/// FFmpeg's own log lines (e.g. "moov atom not found") would precede fillgs's one-line
/// error; OpenCV reads OPENCV_FFMPEG_LOGLEVEL when it first opens a video (−8: quiet).
/// A value the user set is kept.
cv::VideoCapture open_video(const std::string& path) {
  static const bool quiet = ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0) == 0;
  (void)quiet;
  cv::VideoCapture cap(path, cv::CAP_FFMPEG);
  if (!cap.isOpened()) throw_error(path, ": cannot open the video (not a video FFmpeg can read)");
  return cap;
}

}  // namespace

std::vector<std::string> videos_in(const std::string& folder) {
  std::vector<std::string> out;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return out;
  for (const auto& e : fs::directory_iterator(folder, ec))
    if (e.is_regular_file() && e.path().extension() == ".mp4") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

VideoInfo probe_video(const std::string& path) {
  cv::VideoCapture cap = open_video(path);
  VideoInfo v;
  v.frames = int(std::lround(cap.get(cv::CAP_PROP_FRAME_COUNT)));
  v.width = int(cap.get(cv::CAP_PROP_FRAME_WIDTH));
  v.height = int(cap.get(cv::CAP_PROP_FRAME_HEIGHT));
  if (v.frames < 1 || v.width < 1 || v.height < 1) throw_error(path, ": the video reports ", v.frames, " frames of ", v.width, "x", v.height);
  return v;
}

void decode_video_frames(const std::string& path, const std::vector<int>& frames, int k, int width, int height,
                         const std::function<void(size_t, std::vector<uint8_t>&&)>& sink) {
  if (frames.empty()) return;
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i] <= frames[i - 1]) throw_error(path, ": frames to decode must be distinct and in order");
  cv::VideoCapture cap = open_video(path);
  const int bgr_to_rgb[3] = {2, 1, 0};
  cv::Mat m;
  size_t next = 0;
  for (int f = 0; next < frames.size(); ++f) {
    if (!cap.read(m) || m.empty()) throw_error(path, ": frame ", frames[next], " could not be decoded (the video ended after ", f, " frames)");
    if (f != frames[next]) continue;
    if (m.cols != width || m.rows != height || m.type() != CV_8UC3)
      throw_error(path, ": frame ", f, " is ", m.cols, "x", m.rows, " (", m.channels(), " channels), but its camera is ", width, "x", height, " RGB");
    if (!m.isContinuous()) m = m.clone();
    sink(next, block_average_u8(m.ptr<uint8_t>(), m.cols, m.rows, 3, 3, bgr_to_rgb, k, 1.0f));
    ++next;
  }
}

}  // namespace fillgs
