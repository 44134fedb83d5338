#include "fillgs/train/flow.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "fillgs/base/error.hpp"

namespace fillgs {

void FlowField::sample(double x, double y, double& u, double& v) const {
  // Pixel centres sit at i + 0.5.
  const double fx = std::clamp(x - 0.5, 0.0, double(width - 1)), fy = std::clamp(y - 0.5, 0.0, double(height - 1));
  const int x0 = std::min(int(fx), width - 1), y0 = std::min(int(fy), height - 1);
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const double ax = fx - x0, ay = fy - y0;
  auto at = [&](int xx, int yy, int c) { return double(uv[(size_t(yy) * size_t(width) + size_t(xx)) * 2 + size_t(c)]); };
  for (int c = 0; c < 2; ++c) {
    const double r = (1 - ay) * ((1 - ax) * at(x0, y0, c) + ax * at(x1, y0, c)) + ay * ((1 - ax) * at(x0, y1, c) + ax * at(x1, y1, c));
    (c == 0 ? u : v) = r;
  }
}

namespace {

cv::Mat grey8(const std::vector<float>& rgb, int W, int H) {
  cv::Mat g(H, W, CV_8UC1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float* p = &rgb[(size_t(y) * size_t(W) + size_t(x)) * 3];
      const float l = 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
      g.at<uint8_t>(y, x) = uint8_t(std::lround(std::clamp(l, 0.0f, 1.0f) * 255.0f));
    }
  return g;
}

}  // namespace

FlowField optical_flow(const std::vector<float>& from, const std::vector<float>& to, int width, int height) {
  const size_t P = size_t(width) * size_t(height);
  if (width < 2 || height < 2 || from.size() != P * 3 || to.size() != P * 3) throw_error("optical flow: images of ", width, "x", height, " expected");
  const cv::Mat a = grey8(from, width, height), b = grey8(to, width, height);
  cv::Mat flow;
  // Farnebäck's polynomial expansion over a pyramid whose coarsest level keeps ~12 px: on
  // small moving objects before a still background it keeps their full displacement, where
  // DIS (patch based, then smoothed) measured a 2 px/frame plane at 0.9 px (tests/test_motion).
  const int levels = std::clamp(int(std::floor(std::log2(std::min(width, height) / 12.0))), 1, 6);
  cv::calcOpticalFlowFarneback(a, b, flow, 0.5, levels, 9, 5, 5, 1.1, 0);
  FlowField f;
  f.width = width, f.height = height;
  f.uv.resize(P * 2);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const cv::Point2f d = flow.at<cv::Point2f>(y, x);
      f.uv[(size_t(y) * size_t(width) + size_t(x)) * 2] = d.x;
      f.uv[(size_t(y) * size_t(width) + size_t(x)) * 2 + 1] = d.y;
    }
  return f;
}

std::optional<std::pair<double, double>> chain_flow(const std::vector<FlowField>& forward, const std::vector<FlowField>& backward, double x,
                                                    double y, size_t steps, double tolerance) {
  if (steps > forward.size() || steps > backward.size()) throw_error("chain_flow: ", steps, " steps, ", forward.size(), " flows");
  for (size_t k = 0; k < steps; ++k) {
    const FlowField& f = forward[k];
    if (!(x >= 0 && y >= 0 && x < f.width && y < f.height)) return std::nullopt;
    double u, v, bu, bv;
    f.sample(x, y, u, v);
    const double nx = x + u, ny = y + v;
    if (!(nx >= 0 && ny >= 0 && nx < f.width && ny < f.height)) return std::nullopt;
    backward[k].sample(nx, ny, bu, bv);
    if (std::hypot(u + bu, v + bv) > tolerance + 0.05 * std::hypot(u, v)) return std::nullopt;
    x = nx, y = ny;
  }
  return std::make_pair(x, y);
}

}  // namespace fillgs
