#pragma once
// Camera files: reading every rig format fillgs takes (COLMAP, LLFF poses_bounds.npy,
// transforms.json, 3DGS cameras.json, Technicolor, Dynamic 3D Gaussians' meta files) and
// writing transforms.json and COLMAP text. Definitions in src/io/camera_io.cpp.
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"

namespace fillgs {

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

/// What every reader checks before a camera is used, and what any other face (the Python
/// module's arrays) must check too: finite intrinsics with a focal length in [1e-3, 1e9]
/// pixels, a principal point and a camera position within 1e7 of the origin (what single
/// precision can represent), a rotation (orthonormal, determinant +1, to 1e-3), a size within
/// [1, 65536] whose render buffers fit this machine, and a time, when there is one, in [0, 1].
/// Throws fillgs::Error "<source>: <element> ..." naming what is wrong.
void check_camera(const std::string& source, const std::string& element, const Camera& c);

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
