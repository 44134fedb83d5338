#pragma once
// Small geometric helpers shared by the library. Quaternions are (w, x, y, z).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <type_traits>

namespace fillgs {

using Vec2f = Eigen::Vector2f;
using Vec3f = Eigen::Vector3f;
using Vec4f = Eigen::Vector4f;
using Vec3d = Eigen::Vector3d;
using Vec3i = Eigen::Vector3i;
using Vec4d = Eigen::Vector4d;
using Mat3f = Eigen::Matrix3f;
using Mat3d = Eigen::Matrix3d;
using Mat4d = Eigen::Matrix4d;

/// Numerically stable logistic function; exact 0/1 only at the type's limits.
template <typename T, typename = std::enable_if_t<std::is_floating_point_v<T>>>
inline T sigmoid(T x) {
  if (x >= T(0)) return T(1) / (T(1) + std::exp(-x));
  const T e = std::exp(x);
  return e / (T(1) + e);
}

/// Inverse of sigmoid, clamped away from 0 and 1 so that it stays finite.
inline float logit(float p) {
  const float eps = 1e-7f;
  p = std::fmin(std::fmax(p, eps), 1.0f - eps);
  return std::log(p / (1.0f - p));
}

/// Rotation matrix of a unit quaternion (w, x, y, z), the formula the 3DGS code uses.
template <typename T>
Eigen::Matrix<T, 3, 3> quat_to_matrix(const Eigen::Matrix<T, 4, 1>& q) {
  const T w = q[0], x = q[1], y = q[2], z = q[3];
  Eigen::Matrix<T, 3, 3> R;
  R << T(1) - T(2) * (y * y + z * z), T(2) * (x * y - w * z), T(2) * (x * z + w * y),
      T(2) * (x * y + w * z), T(1) - T(2) * (x * x + z * z), T(2) * (y * z - w * x),
      T(2) * (x * z - w * y), T(2) * (y * z + w * x), T(1) - T(2) * (x * x + y * y);
  return R;
}

/// Unit quaternion (w, x, y, z) of a rotation matrix.
inline Vec4d matrix_to_quat(const Mat3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  return Vec4d(q.w(), q.x(), q.y(), q.z());
}

/// Normalises a quaternion; a zero quaternion becomes the identity.
inline Vec4f normalize_quat(const Vec4f& q) {
  const float n = q.norm();
  if (!(n > 1e-30f) || !std::isfinite(n)) return Vec4f(1, 0, 0, 0);
  return q / n;
}

/// Hamilton product a*b of quaternions (w, x, y, z).
inline Vec4d quat_mul(const Vec4d& a, const Vec4d& b) {
  return Vec4d(a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
               a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
               a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
               a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]);
}

/// Shortest-arc spherical interpolation between unit quaternions.
inline Vec4f slerp_shortest(Vec4f a, Vec4f b, float s) {
  float d = a.dot(b);
  if (d < 0.0f) {
    b = -b;
    d = -d;
  }
  if (d > 0.9995f) return normalize_quat(a + s * (b - a));
  const float w = std::acos(std::fmin(d, 1.0f));
  const float sw = std::sin(w);
  return normalize_quat(std::sin((1.0f - s) * w) / sw * a + std::sin(s * w) / sw * b);
}

constexpr double kPi = 3.14159265358979323846;

}  // namespace fillgs
