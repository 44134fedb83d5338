#pragma once
// Camera rigs of the paper's datasets, for synthetic scenes shaped like them (the paper, Sec. 4.1).
//
// * Neural 3D Video: the 21 cameras of the real rig as its COLMAP model stores them
//   (../shared/data/video/n3v_flame_steak_frame0/sparse/0: one PINHOLE camera, 2690×2016,
//   fx 1460.64, fy 1455.03, cx 1345, cy 1008; world-to-camera quaternions and translations
//   per image, copied into src/experiment/rigs.cpp and checked against the file by a test). Two rows
//   on a wide arc: cam00–cam10 the upper row (cam00 in the middle, cam01–05 towards +x,
//   cam06–10 towards −x), cam11–cam20 the lower row (cam11 at +x … cam20 at −x).
// * Technicolor: a 4×4 planar grid (2048×1088 aspect), cameras cam00…cam15 row by row
//   from the top-left as seen from behind the rig.
//
// placed_rig maps a rig from its own world (COLMAP's: y down, z forward, arbitrary units)
// into a synthetic scene's (z up, metres): x' = s·A·(x − c) + p, with A = (x, z, −y), s
// metres per unit, c the point nearest to every optical axis (where the cameras look) and
// p where that point goes. Intrinsics are scaled to the requested image size.
#include <string>
#include <vector>

#include "fillgs/model/camera.hpp"

namespace fillgs {

/// One camera of a COLMAP model: world-to-camera quaternion (w, x, y, z) and translation.
struct ColmapPose {
  const char* name;
  double q[4];
  double t[3];
};

/// The Neural 3D Video rig's poses, as in the COLMAP model (21 entries, cam00..cam20).
const std::vector<ColmapPose>& n3v_rig_poses();
/// Its PINHOLE camera: width, height, fx, fy, cx, cy.
struct PinholeIntrinsics {
  int width, height;
  double fx, fy, cx, cy;
};
PinholeIntrinsics n3v_rig_intrinsics();

/// The N3V rig in its COLMAP world, intrinsics scaled to width × height.
std::vector<Camera> n3v_rig_colmap(int width, int height);

/// The point that minimises the summed squared distance to every camera's optical axis.
Vec3d convergence_point(const std::vector<Camera>& cameras);

/// `cameras` (COLMAP-like world: y down, z forward) moved into a z-up metric world:
/// x' = metres_per_unit · A · (x − convergence_point) + target, A = (x, z, −y).
std::vector<Camera> placed_rig(const std::vector<Camera>& cameras, double metres_per_unit, const Vec3d& target);

/// A 4×4 planar grid facing +y in a z-up world, `spacing` metres apart, centred on `centre`,
/// every camera looking straight ahead; horizontal field of view `fov_x` (radians).
std::vector<Camera> technicolor_rig(int width, int height, double spacing, const Vec3d& centre, double fov_x);

}  // namespace fillgs
