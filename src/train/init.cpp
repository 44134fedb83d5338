#include "fillgs/train/init.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "fillgs/base/error.hpp"
#include "fillgs/base/random.hpp"

namespace fillgs {

std::pair<Vec3d, double> centre_of_interest(const std::vector<Camera>& cameras) {
  Mat3d A = Mat3d::Zero();
  Vec3d b = Vec3d::Zero();
  for (const Camera& c : cameras) {
    const Vec3d dir = c.R.row(2).transpose(), o = c.centre();
    const Mat3d P = Mat3d::Identity() - dir * dir.transpose();  // distance to the axis through o along dir
    A += P, b += P * o;
  }
  if (cameras.size() < 2 || std::abs(A.determinant()) < 1e-12)
    throw_error("initialisation: the cameras' optical axes are parallel or too few; give initial points");
  const Vec3d centre = A.ldlt().solve(b);
  double r = 0;
  for (const Camera& c : cameras) r += (c.centre() - centre).norm() / double(cameras.size());
  return {centre, r};
}

namespace {

/// One first-frame view: camera, image (float RGB) and mask (may be empty).
struct FirstView {
  Camera camera;
  std::vector<float> rgb;
  std::vector<uint8_t> mask;
};

/// Where a point lands in a view: pixel index, or −1 (behind or outside).
long pixel_of(const Camera& c, const Vec3d& X) {
  const Vec3d p = c.project(X);
  if (!(p.z() > 1e-6)) return -1;
  const double x = std::floor(p.x()), y = std::floor(p.y());
  if (x < 0 || y < 0 || x >= c.width || y >= c.height) return -1;
  return long(y) * c.width + long(x);
}

}  // namespace

ViewInitResult points_from_views(const Dataset& data, const ViewInitOptions& o) {
  if (o.min_views < 1) throw_error("initialisation: min_views must be at least 1");
  // Each camera's first view: frame 0 of every camera of a multi-view capture; of a
  // monocular one (one camera per frame), each cycled camera at the first frame it holds.
  std::map<std::string, size_t> first;  // rig camera -> its view with the smallest frame
  for (size_t v = 0; v < data.views().size(); ++v) {
    const TrainView& tv = data.views()[v];
    const auto [it, inserted] = first.emplace(tv.rig, v);
    if (!inserted && tv.frame < data.views()[it->second].frame) it->second = v;
  }
  std::vector<size_t> order;  // in the dataset's order (frame 0 of a multi-view video: as it lists them)
  for (const auto& [rig, v] : first) order.push_back(v);
  std::sort(order.begin(), order.end());
  std::vector<FirstView> views;
  for (size_t v : order) views.push_back({data.views()[v].camera, data.image(v), data.mask(v)});
  std::vector<Camera> cams;
  for (const FirstView& v : views) cams.push_back(v.camera);
  const auto interest = centre_of_interest(cams);  // not a structured binding: lambdas below capture it (C++17)
  const Vec3d centre = interest.first;
  const double r = interest.second;
  const int need = std::min<int>(o.min_views, int(views.size()));
  ViewInitResult out;
  auto colour_of = [&](const Vec3d& X, bool foreground_only, Vec3f* colour) {
    Vec3d sum = Vec3d::Zero();
    int seen = 0;
    for (const FirstView& v : views) {
      const long q = pixel_of(v.camera, X);
      if (q < 0) continue;
      if (foreground_only && !v.mask[size_t(q)]) return false;  // carved away
      for (int c = 0; c < 3; ++c) sum[c] += v.rgb[size_t(q) * 3 + size_t(c)];
      ++seen;
    }
    if (seen < need) return false;
    *colour = (sum / seen).cast<float>();
    return true;
  };
  // Random points in the cube, seen by enough cameras (at most 50 draws per point kept).
  for (uint64_t i = 0; out.random < o.random_points && i < 50 * uint64_t(o.random_points); ++i) {
    const Vec3d X = centre + r * Vec3d(2 * uniform(o.seed, i, 0) - 1, 2 * uniform(o.seed, i, 1) - 1, 2 * uniform(o.seed, i, 2) - 1);
    Vec3f colour;
    if (!colour_of(X, false, &colour)) continue;
    out.points.positions.push_back(X.cast<float>());
    out.points.colours.push_back(colour);
    ++out.random;
  }
  // The visual hull of the foreground masks.
  if (o.method == ViewInit::RandomAndCarve && data.has_masks()) {
    const int N = std::max(2, o.carve_cells);
    std::vector<std::vector<std::pair<Vec3f, Vec3f>>> slabs(static_cast<size_t>(N));
    tbb::parallel_for(0, N, [&](int i) {
      for (int j = 0; j < N; ++j)
        for (int k = 0; k < N; ++k) {
          const Vec3d X = centre + r * (Vec3d(i + 0.5, j + 0.5, k + 0.5) / N * 2.0 - Vec3d::Ones());
          Vec3f colour;
          if (colour_of(X, true, &colour)) slabs[size_t(i)].push_back({X.cast<float>(), colour});
        }
    });
    for (const auto& slab : slabs)
      for (const auto& [X, colour] : slab) {
        out.points.positions.push_back(X);
        out.points.colours.push_back(colour);
        ++out.carved;
      }
  }
  if (out.points.positions.empty())
    throw_error("initialisation: no point is seen by ", need, " of the cameras' first views; give initial points");
  return out;
}

}  // namespace fillgs
