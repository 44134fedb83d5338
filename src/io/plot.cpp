#include "fillgs/io/plot.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "fillgs/base/error.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/base/fs_util.hpp"

namespace fillgs {

namespace {

const cv::Scalar kInk(40, 40, 40), kGrid(225, 225, 225), kWhite(255, 255, 255);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.45, const cv::Scalar& colour = kInk) {
  cv::putText(img, s, at, kFont, scale, colour, 1, cv::LINE_AA);
}

void text_vertical(cv::Mat& img, const std::string& s, cv::Point centre, double scale = 0.45, const cv::Scalar& colour = kInk) {
  int base = 0;
  const cv::Size size = cv::getTextSize(s, kFont, scale, 1, &base);
  cv::Mat strip(size.height + base + 4, size.width + 4, CV_8UC3, kWhite);
  text(strip, s, cv::Point(2, size.height + 2), scale, colour);
  cv::Mat rotated;
  cv::rotate(strip, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int x = std::max(0, centre.x - rotated.cols / 2), y = std::max(0, centre.y - rotated.rows / 2);
  if (x + rotated.cols <= img.cols && y + rotated.rows <= img.rows) rotated.copyTo(img(cv::Rect(x, y, rotated.cols, rotated.rows)));
}

std::string short_number(double v) {
  char b[32];
  if (v != 0 && (std::fabs(v) >= 1e4 || std::fabs(v) < 1e-2)) std::snprintf(b, sizeof b, "%.2g", v);
  else std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

void save(const std::string& path, const cv::Mat& img) {
  write_atomically(path, [&](const std::string& tmp) {
    if (!cv::imwrite(tmp, img)) throw_error(path, ": cannot write the plot");
  });
}


}  // namespace

void write_topdown_png(const std::string& path, const TopdownSlice& slice, const std::vector<Camera>& training,
                       const std::vector<Camera>& virtual_cameras, const std::string& title) {
  const int v = slice.v, a = slice.a, b = slice.b;
  const Vec3d lo = slice.lo, hi = slice.hi;
  if (slice.labels.size() != size_t(slice.na) * size_t(slice.nb)) throw_error(path, ": the slice's labels do not match its ", slice.na, "x", slice.nb, " cells");
  const double wa = hi[a] - lo[a], wb = hi[b] - lo[b];
  const double px = 640.0 / std::max(wa, wb);  // pixels per world unit
  const int margin = 40, top = 34;
  const int W = int(wa * px) + 2 * margin, H = int(wb * px) + margin + top + 24;
  cv::Mat img(H, W, CV_8UC3, kWhite);
  // world (a, b) → pixel: a to the right, b up
  auto to_px = [&](const Vec3d& p) { return cv::Point2d(margin + (p[a] - lo[a]) * px, top + (hi[b] - p[b]) * px); };
  const cv::Scalar occupied(70, 70, 70), free_col(250, 250, 250), unexplored(235, 215, 190);
  const double height = slice.height;
  for (int i = 0; i < slice.na; ++i)
    for (int j = 0; j < slice.nb; ++j) {
      const int best = slice.labels[size_t(i) * size_t(slice.nb) + size_t(j)];
      Vec3d c0 = lo, c1 = lo;
      c0[a] += i * wa / slice.na, c0[b] += (j + 1) * wb / slice.nb;
      c1[a] += (i + 1) * wa / slice.na, c1[b] += j * wb / slice.nb;
      cv::rectangle(img, to_px(c0), to_px(c1), best == 1 ? occupied : best == 0 ? free_col : unexplored, cv::FILLED);
    }
  cv::rectangle(img, to_px(lo), to_px(hi), kInk, 1);
  const double arrow = 0.06 * std::max(wa, wb);
  auto draw = [&](const std::vector<Camera>& cams, const cv::Scalar& colour, int radius) {
    for (const Camera& c : cams) {
      const Vec3d o = c.centre(), f = c.R.row(2).transpose();
      cv::line(img, to_px(o), to_px(o + arrow * f), colour, 1, cv::LINE_AA);
      cv::circle(img, to_px(o), radius, colour, cv::FILLED, cv::LINE_AA);
    }
  };
  draw(virtual_cameras, cv::Scalar(220, 90, 20), 3);
  draw(training, cv::Scalar(30, 30, 220), 4);
  text(img, title, cv::Point(margin, 22), 0.55);
  const char* axes = "xyz";
  text(img,
       std::string("slice ") + axes[v] + " = " + short_number(height) + " (" + axes[a] + " right, " + axes[b] +
           " up): dark occupied, white free, beige unexplored; red training, blue virtual",
       cv::Point(8, H - 8), 0.38);
  save(path, img);
}

void write_split_png(const std::string& path, const std::vector<Vec3f>& static_points, const std::vector<Vec3f>& moving_points,
                     const std::vector<Camera>& cameras, const std::vector<int>& roles, const std::string& title) {
  FILLGS_CHECK_EQ(cameras.size(), roles.size());
  // Bounds: the cameras, the moving points and the central 90% of the static points (a room's
  // far walls would shrink everything else), 0.4 m around.
  std::vector<float> xs, ys;
  for (const Vec3f& p : static_points) xs.push_back(p.x()), ys.push_back(p.y());
  double x0 = 1e30, x1 = -1e30, y0 = 1e30, y1 = -1e30;
  auto grow = [&](double x, double y) { x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y); };
  if (!xs.empty()) {
    std::sort(xs.begin(), xs.end());
    std::sort(ys.begin(), ys.end());
    grow(xs[xs.size() / 20], ys[ys.size() / 20]);
    grow(xs[xs.size() * 19 / 20], ys[ys.size() * 19 / 20]);
  }
  for (const Camera& c : cameras) grow(c.centre().x(), c.centre().y());
  for (const Vec3f& p : moving_points) grow(p.x(), p.y());
  x0 -= 0.4, x1 += 0.4, y0 -= 0.4, y1 += 0.4;
  const double px = 720.0 / std::max(x1 - x0, y1 - y0);
  const int margin = 20, top = 36, legend = 40;
  const int W = int((x1 - x0) * px) + 2 * margin, H = int((y1 - y0) * px) + top + margin + legend + 40;
  cv::Mat img(H, W, CV_8UC3, kWhite);
  auto to_px = [&](double x, double y) { return cv::Point2d(margin + (x - x0) * px, top + 20 + (y1 - y) * px); };
  auto inside = [&](const Vec3f& p) { return p.x() >= x0 && p.x() <= x1 && p.y() >= y0 && p.y() <= y1; };
  for (const Vec3f& p : static_points)
    if (inside(p)) cv::circle(img, to_px(p.x(), p.y()), 1, cv::Scalar(190, 190, 190), cv::FILLED);
  for (const Vec3f& p : moving_points)
    if (inside(p)) cv::circle(img, to_px(p.x(), p.y()), 1, cv::Scalar(40, 140, 250), cv::FILLED);
  // Roles: 0 training (red), 1 interpolation (blue), 2 extrapolation (purple), 3 grey, 4 virtual (green).
  const cv::Scalar colours[] = {{30, 30, 220}, {220, 110, 30}, {160, 40, 120}, {150, 150, 150}, {60, 170, 40}};
  const double arrow = 0.05 * std::max(x1 - x0, y1 - y0);
  bool any_virtual = false;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const int role = std::clamp(roles[i], 0, 4);
    const cv::Scalar c = colours[role];
    const Vec3d o = cameras[i].centre(), f = cameras[i].R.row(2).transpose();
    cv::line(img, to_px(o.x(), o.y()), to_px(o.x() + arrow * f.x(), o.y() + arrow * f.y()), c, 1, cv::LINE_AA);
    cv::circle(img, to_px(o.x(), o.y()), role == 0 ? 5 : role == 4 ? 2 : 4, c, cv::FILLED, cv::LINE_AA);
    if (role == 4) {
      any_virtual = true;
      continue;
    }
    // Names vertical, beside the camera away from where it looks (below the rig for the
    // lower cameras of a two-row rig, above for the others), so that neighbours do not overlap.
    double zmax = -1e30;
    for (const Camera& k : cameras) zmax = std::max(zmax, k.centre().z());
    const bool lower = o.z() < zmax - 0.2;
    const cv::Point2d at = to_px(o.x(), o.y());
    text_vertical(img, cameras[i].name, cv::Point(int(at.x), int(at.y) + (lower ? 30 : -34)), 0.36, c);
  }
  text(img, title, cv::Point(margin, 22), 0.55);
  const char* names[] = {"training", "interpolation", "extrapolation", "other", "virtual views"};
  int x = margin;
  for (int r = 0; r < (any_virtual ? 5 : 4); ++r) {
    cv::circle(img, cv::Point(x + 5, H - legend / 2), 5, colours[r], cv::FILLED, cv::LINE_AA);
    text(img, names[r], cv::Point(x + 14, H - legend / 2 + 5), 0.42);
    int base = 0;
    x += 14 + cv::getTextSize(names[r], kFont, 0.42, 1, &base).width + 22;
  }
  cv::circle(img, cv::Point(x + 5, H - legend / 2), 3, cv::Scalar(40, 140, 250), cv::FILLED);
  text(img, "moving content, all frames", cv::Point(x + 14, H - legend / 2 + 5), 0.42);
  text(img, "top view, x right, y up (metres)", cv::Point(W - 230, H - 6), 0.36);
  save(path, img);
}

void write_image_grid_png(const std::string& path, const std::vector<std::vector<float>>& images, int width, int height,
                          const std::vector<std::string>& captions, int columns, int zoom) {
  if (images.empty() || images.size() != captions.size()) throw_error("image grid: ", images.size(), " images for ", captions.size(), " captions");
  const int cols = std::max(1, std::min(columns, int(images.size()))), rows = (int(images.size()) + cols - 1) / cols;
  const int cap = 22, gap = 6, W = width * zoom, H = height * zoom;
  cv::Mat img(rows * (H + cap + gap) - gap, cols * (W + gap) - gap, CV_8UC3, kWhite);
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i].size() != size_t(width) * height * 3) throw_error("image grid: image ", i, " is not ", width, "x", height);
    const int x0 = int(i) % cols * (W + gap), y0 = int(i) / cols * (H + cap + gap);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const float* p = &images[i][(size_t(y / zoom) * width + size_t(x / zoom)) * 3];
        cv::Vec3b& q = img.at<cv::Vec3b>(y0 + y + cap, x0 + x);
        for (int c = 0; c < 3; ++c) q[2 - c] = uint8_t(std::lround(std::clamp(p[c], 0.0f, 1.0f) * 255.0f));
      }
    text(img, captions[i], cv::Point(x0 + 4, y0 + 16));
  }
  save(path, img);
}

void write_side_by_side_png(const std::string& path, const std::vector<std::vector<float>>& images, int width, int height,
                            const std::vector<std::string>& captions, int zoom) {
  write_image_grid_png(path, images, width, height, captions, int(images.size()), zoom);
}

}  // namespace fillgs
