#pragma once
// Cameras in one internal convention, and readers/writers for the formats users have.
//
// Convention: pinhole, world-to-camera x_cam = R x_world + t with OpenCV axes (x right,
// y down, z forward). Pixel (0,0) is the top-left corner of the image, so pixel centres
// sit at (i + 0.5, j + 0.5), and (cx, cy) is measured in the same frame (COLMAP's).
// Times are normalised to [0, 1] (see gaussians.hpp); a camera without one has NaN.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/base/math.hpp"

namespace fillgs {

struct Camera {
  std::string name;  ///< unique within a rig; may contain '/' (written as sub-folders)
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Mat3d R = Mat3d::Identity();  ///< world-to-camera rotation
  Vec3d t = Vec3d::Zero();      ///< world-to-camera translation
  double time = std::numeric_limits<double>::quiet_NaN();
  std::string image_path;       ///< image file as the rig names it (may be empty)

  Vec3d centre() const { return -R.transpose() * t; }
  bool has_time() const { return !std::isnan(time); }
  /// Camera-to-world 4x4 in OpenCV axes.
  Mat4d camera_to_world() const;
  /// Projects a world point to pixel coordinates (corner convention); z is the view depth.
  Vec3d project(const Vec3d& world) const;
  /// The world point at depth z (along the optical axis) behind pixel coordinates (u, v)
  /// (corner convention: the centre of pixel i is i + 0.5): project's inverse.
  Vec3d unproject(double u, double v, double z) const {
    return R.transpose() * (Vec3d((u - cx) / fx * z, (v - cy) / fy * z, z) - t);
  }
  /// Sets R, t from a camera centre, a point to look at and an up vector (world).
  void look_at(const Vec3d& eye, const Vec3d& target, const Vec3d& up);
  /// Sets intrinsics from a horizontal field of view (radians), centred principal point.
  void set_fov_x(double fov_x, int w, int h);
};

/// The camera with its intrinsics scaled by s: image size rounded (at least one pixel), focal
/// lengths and principal point by the rounded size's own ratio per axis.
Camera scaled_camera(const Camera& c, double s);

/// Where the cameras of a ring stand: `count` of them evenly spaced on a circle of
/// `radius` around `centre` + `elevation`·up, in the plane normal to `up` (from e1 = x, or y
/// when up is along x, towards e2 = up × e1, starting at angle `phase`), each looking at
/// `target` (NaN: the centre) with `up` as its up direction. Named prefix + index, the
/// index zero-padded to `digits`.
struct RingPlacement {
  int count = 8;
  Vec3d centre = Vec3d::Zero();
  double radius = 1.0, elevation = 0.0, phase = 0.0;
  Vec3d up = Vec3d::UnitZ();
  Vec3d target = Vec3d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::string prefix = "cam";
  int digits = 0;
};
/// The ring's cameras, with the intrinsics and size of `lens`.
std::vector<Camera> camera_ring(const RingPlacement& ring, const Camera& lens);

}  // namespace fillgs
