#include "fillgs/model/camera.hpp"

#include <algorithm>
#include <cmath>

namespace fillgs {

Mat4d Camera::camera_to_world() const {
  Mat4d m = Mat4d::Identity();
  m.block<3, 3>(0, 0) = R.transpose();
  m.block<3, 1>(0, 3) = centre();
  return m;
}

Vec3d Camera::project(const Vec3d& world) const {
  const Vec3d v = R * world + t;
  return Vec3d(fx * v.x() / v.z() + cx, fy * v.y() / v.z() + cy, v.z());
}

void Camera::look_at(const Vec3d& eye, const Vec3d& target, const Vec3d& up) {
  const Vec3d z = (target - eye).normalized();          // forward
  Vec3d x = z.cross(up);                                  // right (y is down)
  if (x.norm() < 1e-12) x = z.cross(Vec3d::UnitX());
  x.normalize();
  const Vec3d y = z.cross(x);                             // down
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  t = -R * eye;
}

std::vector<Camera> camera_ring(const RingPlacement& ring, const Camera& lens) {
  const Vec3d e1 = std::fabs(ring.up.x()) < 0.9 * ring.up.norm() ? Vec3d::UnitX() : Vec3d::UnitY();
  const Vec3d e2 = ring.up.cross(e1);
  const Vec3d target = ring.target.allFinite() ? ring.target : ring.centre;
  std::vector<Camera> cams;
  for (int i = 0; i < ring.count; ++i) {
    const double a = ring.phase + 2 * kPi * i / ring.count;
    Camera c = lens;
    std::string index = std::to_string(i);
    if (int(index.size()) < ring.digits) index.insert(0, size_t(ring.digits) - index.size(), '0');
    c.name = ring.prefix + index;
    c.look_at(ring.centre + ring.radius * std::cos(a) * e1 + ring.radius * std::sin(a) * e2 + ring.elevation * ring.up, target, ring.up);
    cams.push_back(c);
  }
  return cams;
}

void Camera::set_fov_x(double fov_x, int w, int h) {
  width = w;
  height = h;
  fx = fy = w / (2.0 * std::tan(fov_x / 2.0));
  cx = w / 2.0;
  cy = h / 2.0;
}

Camera scaled_camera(const Camera& c, double s) {
  if (s == 1.0) return c;
  Camera out = c;
  out.width = std::max(1, int(std::lround(c.width * s)));
  out.height = std::max(1, int(std::lround(c.height * s)));
  const double sx = double(out.width) / c.width, sy = double(out.height) / c.height;
  out.fx *= sx, out.cx *= sx, out.fy *= sy, out.cy *= sy;
  return out;
}

}  // namespace fillgs
