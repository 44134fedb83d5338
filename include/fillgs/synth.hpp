#pragma once
// The paper's synthetic analysis scene (METHOD.md §10), built from Gaussians:
// a room (textured floor and walls), a static shelf with thin boards and a back panel,
// some static clutter, and a chair that moves only for t in [move_start, move_end],
// passing behind the shelf so that some cameras cannot see it while it moves.
// 16 training cameras on a circle 22.5° apart; held-out cameras for interpolation
// (half-way angles on the same circle) and extrapolation (higher and closer).
// World axes: z up, metres.
#include <cstdint>
#include <string>
#include <vector>

#include "fillgs/camera.hpp"
#include "fillgs/gaussians.hpp"
#include "fillgs/progress.hpp"

namespace fillgs {

struct SynthOptions {
  int frames = 30;
  int width = 320, height = 240;
  uint64_t seed = 1;
  int train_cameras = 16;
  int extrapolation_cameras = 8;
  double camera_radius = 3.2, camera_height = 1.4;
  double fov_x_degrees = 60.0;
  double move_start = 0.2, move_end = 0.8;
  /// Surface sample spacing (metres) for the objects; the room uses 4x coarser.
  double spacing = 0.02;
  /// Motion and occlusion of the moving chair (the room, shelf and cameras are the same):
  ///  * "chair": slides 1.05 m along x behind the shelf's back panel, turning 90°;
  ///  * "orbit": travels 240° around the shelf at 1.3 m (front, side, then behind it),
  ///    facing along its path: long fast motion, occluded only at the end;
  ///  * "lift": rises 0.9 m behind the shelf while turning 180°: hidden at first, then
  ///    seen over the shelf's top from the front.
  std::string variant = "chair";
};
/// The variants make_synthetic_scene knows.
std::vector<std::string> synthetic_variants();

struct SynthScene {
  GaussianCloud scene;             ///< ground truth, keyframed (one key per frame)
  std::vector<uint32_t> chair_ids; ///< the Gaussians of the moving chair
  std::vector<Camera> train;       ///< rig: 16 cameras (no time)
  std::vector<Camera> interpolation, extrapolation;
  SynthOptions options;
};

SynthScene make_synthetic_scene(const SynthOptions& options = {});

/// Copies of `rig` for every frame, named "<camera>/<frame:04d>", with t = f / (F-1)
/// and image_path "images/<camera>/<frame:04d>.png".
std::vector<Camera> cameras_over_time(const std::vector<Camera>& rig, int frames);

/// Writes scene.ply (fillgs 4D PLY), transforms_{train,interpolation,extrapolation}.json
/// (every camera at every frame, with times), images/<camera>/<frame>.png for every
/// camera and frame of every split, and synth.json describing the scene.
void write_synthetic_scene(const SynthScene& scene, const std::string& out_dir, Progress& progress, int threads = 0);

}  // namespace fillgs
