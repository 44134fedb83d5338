#include "fillgs/plot.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "fillgs/error.hpp"
#include "fillgs/camera.hpp"
#include "fillgs/exploration.hpp"
#include "fillgs/fs_util.hpp"

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

void frame_and_titles(cv::Mat& img, const cv::Rect& area, const PlotLabels& labels) {
  cv::rectangle(img, area, kInk, 1);
  text(img, labels.title, cv::Point(area.x, 22), 0.55);
  int base = 0;
  const int w = cv::getTextSize(labels.x, kFont, 0.45, 1, &base).width;
  text(img, labels.x, cv::Point(area.x + area.width / 2 - w / 2, img.rows - 8));
  text_vertical(img, labels.y, cv::Point(12, area.y + area.height / 2));
}

}  // namespace

void write_heatmap_png(const std::string& path, const std::vector<float>& values, int rows, int cols, const PlotLabels& labels,
                       const std::vector<double>* row_totals) {
  FILLGS_CHECK(rows > 0 && cols > 0);
  FILLGS_CHECK_EQ(values.size(), size_t(rows) * size_t(cols));
  float vmax = 0;
  for (float v : values)
    if (std::isfinite(v)) vmax = std::max(vmax, v);
  const int cell_w = std::max(1, 720 / cols), cell_h = std::max(1, 360 / rows);
  const int W = cols * cell_w, H = rows * cell_h;
  const int left = 60, top = 48, profile = row_totals ? 110 : 0, bar = 70;
  cv::Mat img(top + H + 50, left + W + profile + bar + 20, CV_8UC3, kWhite);
  cv::Mat grey(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const float v = values[size_t(r) * size_t(cols) + size_t(c)];
      grey.at<uint8_t>(r, c) = uint8_t(vmax > 0 && std::isfinite(v) ? std::clamp(v / vmax, 0.0f, 1.0f) * 255.0f + 0.5f : 0);
    }
  cv::Mat colour, big;
  cv::applyColorMap(grey, colour, cv::COLORMAP_INFERNO);
  cv::resize(colour, big, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
  big.copyTo(img(cv::Rect(left, top, W, H)));
  frame_and_titles(img, cv::Rect(left, top, W, H), labels);
  text(img, "0", cv::Point(left - 14, top + 12));
  text(img, std::to_string(rows - 1), cv::Point(left - 30, top + H));
  if (row_totals) {
    FILLGS_CHECK_EQ(row_totals->size(), size_t(rows));
    double tmax = 0;
    for (double t : *row_totals) tmax = std::max(tmax, t);
    const int x0 = left + W + 10;
    for (int r = 0; r < rows; ++r) {
      const int len = tmax > 0 ? int(std::lround((*row_totals)[size_t(r)] / tmax * (profile - 20))) : 0;
      cv::rectangle(img, cv::Rect(x0, top + r * cell_h, std::max(len, 0), std::max(cell_h - (cell_h > 3), 1)), cv::Scalar(180, 120, 60), cv::FILLED);
    }
    text(img, "row sum", cv::Point(x0, top - 6), 0.4);
    text(img, short_number(tmax), cv::Point(x0 + profile - 50, top + H + 16), 0.4);
  }
  // colour bar
  const int bx = left + W + profile + 20;
  for (int y = 0; y < H; ++y) {
    cv::Mat one(1, 1, CV_8UC1, cv::Scalar(255.0 * (H - 1 - y) / std::max(1, H - 1)));
    cv::Mat c;
    cv::applyColorMap(one, c, cv::COLORMAP_INFERNO);
    cv::line(img, cv::Point(bx, top + y), cv::Point(bx + 14, top + y), cv::Scalar(c.at<cv::Vec3b>(0, 0)), 1);
  }
  text(img, short_number(vmax), cv::Point(bx + 16, top + 10), 0.4);
  text(img, "0", cv::Point(bx + 16, top + H), 0.4);
  save(path, img);
}

void write_bar_chart_png(const std::string& path, const std::vector<std::string>& names, const std::vector<double>& values,
                         const PlotLabels& labels) {
  FILLGS_CHECK_EQ(names.size(), values.size());
  const int n = int(values.size());
  const int left = 70, top = 36, W = std::max(300, std::min(1200, n * 40)), H = 300;
  cv::Mat img(top + H + 70, left + W + 20, CV_8UC3, kWhite);
  double vmax = 0;
  for (double v : values) vmax = std::max(vmax, v);
  if (vmax <= 0) vmax = 1;
  for (int k = 1; k <= 4; ++k) {
    const int y = top + H - H * k / 4;
    cv::line(img, cv::Point(left, y), cv::Point(left + W, y), kGrid, 1);
    text(img, short_number(vmax * k / 4), cv::Point(6 + 14, y + 4), 0.4);
  }
  const double slot = double(W) / std::max(1, n);
  const int every = std::max(1, int(std::ceil(40.0 / slot)));
  for (int i = 0; i < n; ++i) {
    const int x0 = left + int(i * slot + 0.15 * slot), x1 = left + int((i + 1) * slot - 0.15 * slot);
    const int h = int(std::lround(std::max(0.0, values[size_t(i)]) / vmax * H));
    cv::rectangle(img, cv::Point(x0, top + H - h), cv::Point(std::max(x0, x1), top + H), cv::Scalar(180, 120, 60), cv::FILLED);
    if (i % every == 0) text(img, names[size_t(i)], cv::Point(x0, top + H + 16 + 14 * ((i / every) % 2)), 0.35);
  }
  frame_and_titles(img, cv::Rect(left, top, W, H), labels);
  save(path, img);
}

void write_scatter_png(const std::string& path, const std::vector<ScatterSeries>& series, const PlotLabels& labels, bool log_x) {
  const int left = 70, top = 36, W = 720, H = 420;
  cv::Mat img(top + H + 50, left + W + 30, CV_8UC3, kWhite);
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  auto fx = [&](double x) { return log_x ? std::log10(std::max(x, 1e-12)) : x; };
  for (const auto& s : series)
    for (size_t i = 0; i < s.x.size(); ++i) {
      x0 = std::min(x0, fx(s.x[i]));
      x1 = std::max(x1, fx(s.x[i]));
      y0 = std::min(y0, s.y[i]);
      y1 = std::max(y1, s.y[i]);
    }
  if (!(x1 > x0)) x0 -= 0.5, x1 += 0.5;
  if (!(y1 > y0)) y0 -= 0.5, y1 += 0.5;
  const double px = 0.05 * (x1 - x0), py = 0.05 * (y1 - y0);
  x0 -= px, x1 += px, y0 -= py, y1 += py;
  auto to_px = [&](double x, double y) {
    return cv::Point(left + int((fx(x) - x0) / (x1 - x0) * W), top + H - int((y - y0) / (y1 - y0) * H));
  };
  for (int k = 0; k <= 4; ++k) {
    const double yv = y0 + (y1 - y0) * k / 4, xv = x0 + (x1 - x0) * k / 4;
    const int y = top + H - H * k / 4, x = left + W * k / 4;
    cv::line(img, cv::Point(left, y), cv::Point(left + W, y), kGrid, 1);
    cv::line(img, cv::Point(x, top), cv::Point(x, top + H), kGrid, 1);
    text(img, short_number(yv), cv::Point(18, y + 4), 0.4);
    text(img, short_number(log_x ? std::pow(10.0, xv) : xv), cv::Point(x - 14, top + H + 16), 0.4);
  }
  const cv::Scalar palette[] = {{180, 120, 60}, {60, 60, 220}, {60, 170, 60}, {200, 60, 180}, {40, 160, 220}, {120, 120, 120}};
  for (size_t k = 0; k < series.size(); ++k) {
    const cv::Scalar c = palette[k % 6];
    const auto& s = series[k];
    for (size_t i = 0; i < s.x.size(); ++i) {
      const cv::Point p = to_px(s.x[i], s.y[i]);
      cv::circle(img, p, 5, c, cv::FILLED, cv::LINE_AA);
      if (i < s.point_labels.size()) text(img, s.point_labels[i], p + cv::Point(6, -4), 0.33, c);
    }
    cv::circle(img, cv::Point(left + 12, top + 16 + 18 * int(k)), 5, c, cv::FILLED, cv::LINE_AA);
    text(img, s.name, cv::Point(left + 22, top + 20 + 18 * int(k)), 0.42);
  }
  frame_and_titles(img, cv::Rect(left, top, W, H), labels);
  save(path, img);
}


int vertical_axis(const std::vector<Camera>& cameras) {
  Vec3d up = Vec3d::Zero();
  for (const Camera& c : cameras) up -= c.R.row(1).transpose();  // OpenCV y points down
  int axis = 2;
  up.cwiseAbs().maxCoeff(&axis);
  return axis;
}

void write_topdown_png(const std::string& path, const ExplorationGrid& grid, const std::vector<Camera>& training,
                       const std::vector<Camera>& virtual_cameras, const std::string& title) {
  const int v = vertical_axis(training), a = (v + 1) % 3, b = (v + 2) % 3;
  const Vec3i dims = grid.dims();
  const Vec3d lo = grid.box().lo, hi = grid.box().hi;
  const double wa = hi[a] - lo[a], wb = hi[b] - lo[b];
  const double px = 640.0 / std::max(wa, wb);  // pixels per world unit
  const int margin = 40, top = 34;
  const int W = int(wa * px) + 2 * margin, H = int(wb * px) + margin + top + 24;
  cv::Mat img(H, W, CV_8UC3, kWhite);
  // world (a, b) → pixel: a to the right, b up
  auto to_px = [&](const Vec3d& p) { return cv::Point2d(margin + (p[a] - lo[a]) * px, top + (hi[b] - p[b]) * px); };
  const cv::Scalar occupied(70, 70, 70), free_col(250, 250, 250), unexplored(235, 215, 190);
  // The horizontal slice at the training cameras' mean height (a floor would hide a projection).
  double height = 0;
  for (const Camera& c : training) height += c.centre()[v] / double(training.size());
  const int layer = std::clamp(grid.voxel_of(Vec3d::Constant(height))[v], 0, dims[v] - 1);
  for (int i = 0; i < dims[a]; ++i)
    for (int j = 0; j < dims[b]; ++j) {
      Vec3i ijk;
      ijk[a] = i;
      ijk[b] = j;
      ijk[v] = layer;
      const VoxelLabel l = grid.label(ijk);
      const int best = l == VoxelLabel::Occupied ? 1 : l == VoxelLabel::Free ? 0 : 2;
      Vec3d c0 = lo, c1 = lo;
      c0[a] += i * wa / dims[a], c0[b] += (j + 1) * wb / dims[b];
      c1[a] += (i + 1) * wa / dims[a], c1[b] += j * wb / dims[b];
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
