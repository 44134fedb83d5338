#pragma once
// Helpers shared by the benchmarks: where the shared data is, orbit cameras around a scene.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "fillgs/camera.hpp"
#include "fillgs/gaussians.hpp"

namespace fillgs::bench {

inline std::string shared_data() {
  if (const char* e = std::getenv("FILLGS_SHARED_DATA")) return e;
  return "../shared/data";
}

inline std::vector<Camera> orbit(const GaussianCloud& c, int n, int w, int h) {
  // Robust centre and radius: median of the means, 90th percentile distance.
  std::vector<float> xs, ys, zs;
  for (const Vec3f& p : c.means) {
    xs.push_back(p.x());
    ys.push_back(p.y());
    zs.push_back(p.z());
  }
  auto median = [](std::vector<float> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const Vec3d centre(median(xs), median(ys), median(zs));
  std::vector<float> d;
  for (const Vec3f& p : c.means) d.push_back(float((p.cast<double>() - centre).norm()));
  std::nth_element(d.begin(), d.begin() + d.size() * 9 / 10, d.end());
  const double radius = 2.2 * d[d.size() * 9 / 10];
  std::vector<Camera> cams;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * kPi * i / n;
    Camera cam;
    cam.name = "orbit" + std::to_string(i);
    cam.set_fov_x(60.0 * kPi / 180.0, w, h);
    cam.look_at(centre + radius * Vec3d(std::cos(a), 0.3, std::sin(a)), centre, Vec3d(0, -1, 0));
    cams.push_back(cam);
  }
  return cams;
}


}  // namespace fillgs::bench
