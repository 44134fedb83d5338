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

enum class CameraFormat { Auto, Colmap, Llff, Transforms, GaussianJson, Technicolor, D3dgs };
FILLGS_ENUM_NAMES(CameraFormat, "camera format",
    {CameraFormat::Auto, "auto"}, {CameraFormat::Colmap, "colmap"}, {CameraFormat::Llff, "llff"}, {CameraFormat::Transforms, "transforms"},
    {CameraFormat::GaussianJson, "3dgs"}, {CameraFormat::Technicolor, "technicolor"}, {CameraFormat::D3dgs, "d3dgs"},
    {CameraFormat::Transforms, "nerf"}, {CameraFormat::D3dgs, "panoptic"});

struct CameraReadOptions {
  CameraFormat format = CameraFormat::Auto;
  /// Image size for formats that do not store one (NeRF camera_angle_x without w/h when
  /// the image cannot be opened, Technicolor). 0: look at the image, then fail clearly.
  int width = 0, height = 0;
  /// LLFF: divide the stored H, W, f by this (Neural 3D Video is used at 2 → 1352×1014).
  double llff_downscale = 1.0;
};

/// Reads cameras, detecting the format from the path unless told:
/// a directory or cameras.txt/images.txt/*.bin → COLMAP; *.npy → LLFF;
/// *.json holding a list → 3DGS cameras.json, an object with frames → transforms;
/// *.txt other than COLMAP's → Technicolor cameras_parameters.txt; *_meta.json → Dynamic 3D
/// Gaussians (CMU Panoptic): a camera per frame and camera, "<cam_id>/<frame:06d>", timed.
std::vector<Camera> read_cameras(const std::string& path, const CameraReadOptions& options = {});
CameraFormat detect_camera_format(const std::string& path);

/// Writes NeRF-style transforms.json: per-frame fl_x fl_y cx cy w h, time (when known),
/// camera-to-world in OpenGL axes, file_path = image_path or the camera name.
void write_transforms_json(const std::string& path, const std::vector<Camera>& cams);

/// Writes COLMAP text (cameras.txt, images.txt, empty points3D.txt) into a directory;
/// one PINHOLE camera per view.
void write_colmap_text(const std::string& dir, const std::vector<Camera>& cams);
/// Throws naming the file when `dir` holds a binary COLMAP model (cameras.bin, images.bin),
/// which readers take before a text one: text cameras written there would be shadowed.
void check_colmap_text_target(const std::string& dir);

}  // namespace fillgs
