#pragma once
// Synthetic dynamic scenes made of Gaussians, with ground truth for every camera and frame.
//
// Two kinds of scene, each with its rig and its sparse-view split (the paper, Sec. 4.1 and Appendix B.3):
//  * rig "ring" — the paper's analysis scene (the paper's Appendix B.3): a room (textured floor and
//    walls), a static shelf with thin boards and a back panel, some clutter, and a chair
//    that moves only for t in [move_start, move_end], passing behind the shelf so that some
//    cameras cannot see it while it moves. 16 training cameras on a circle 22.5° apart;
//    held-out cameras for interpolation (half-way angles on the same circle) and
//    extrapolation (higher and closer). Variants chair, orbit, lift move the chair.
//  * rigs "n3v" and "technicolor" — the paper's benchmark setting, forward-facing: a
//    kitchen (floor, tiled back wall with shelves and jars, ceiling, side walls), a counter
//    with objects, seen by every camera; in front of it a person-sized articulated figure
//    walks across (legs and arms swing, the right arm rises and waves), a box slides along
//    the counter, and a tall static pillar between the rig and the walker hides it from some
//    cameras part of the time. The "n3v" rig is the real Neural 3D Video rig (rigs.hpp,
//    0.25 m per COLMAP unit, looking at the walker's path); "technicolor" a 4×4 grid.
//    Variant "kitchen". data/README.md, "The synthetic scenes", says what each element is for.
// World axes: z up, metres.
#include <cstdint>
#include <string>
#include <vector>

#include "fillgs/model/camera.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/progress.hpp"

namespace fillgs {

struct SynthOptions {
  int frames = 30;
  int width = 320, height = 240;
  uint64_t seed = 1;
  /// "ring" (16 cameras around a room), "n3v" (the Neural 3D Video rig) or "technicolor"
  /// (a 4×4 grid).
  std::string rig = "ring";
  /// The moving content. Ring: "chair" (slides 1.05 m along x behind the shelf's back
  /// panel, turning 90°), "orbit" (travels 240° around the shelf at 1.3 m: long fast motion,
  /// occluded only at the end), "lift" (rises 0.9 m behind the shelf while turning 180°).
  /// n3v and technicolor: "kitchen". Empty: the rig's first.
  std::string variant;
  int train_cameras = 16;          ///< ring only
  int extrapolation_cameras = 8;   ///< ring only
  double camera_radius = 3.2, camera_height = 1.4;  ///< ring only
  double fov_x_degrees = 60.0;     ///< ring only
  double move_start = 0.2, move_end = 0.8;          ///< ring only
  /// Surface sample spacing (metres) for the objects; rooms use 4x coarser.
  double spacing = 0.02;

  /// The variant, or the rig's default when empty.
  std::string resolved_variant() const;
  /// A name for the scene: the variant for the ring, else the rig ("n3v", "technicolor").
  std::string scene_name() const;
};
/// The rigs make_synthetic_scene knows, and the variants of each: the one table of these
/// names (help, errors and the bench's scene list read it).
std::vector<std::string> synthetic_rigs();
std::vector<std::string> synthetic_variants(const std::string& rig = "ring");

/// The paper's sparse-view split of a rig (names of cameras): two training cameras,
/// interpolation cameras between them, extrapolation cameras beyond them.
struct CameraSplit {
  std::vector<std::string> train, interpolation, extrapolation;
};

struct SynthScene {
  GaussianCloud scene;             ///< ground truth, keyframed (one key per frame)
  std::vector<uint32_t> moving_ids; ///< the Gaussians that move (chair; walker and box)
  std::vector<Camera> train;       ///< the rig (no time): 16 ring cameras, 21 N3V, 16 grid
  /// Held-out rigs of the ring scene (empty for n3v and technicolor, whose test cameras are
  /// part of the rig).
  std::vector<Camera> interpolation, extrapolation;
  CameraSplit split;               ///< the paper's split for this rig
  SynthOptions options;
  /// A camera of any of the lists by name (nullptr if none).
  const Camera* camera(const std::string& name) const;
};

SynthScene make_synthetic_scene(const SynthOptions& options = {});

/// Copies of `rig` for every frame, named "<camera>/<frame:04d>", with t = f / (F-1)
/// and image_path "images/<camera>/<frame:04d>.png".
std::vector<Camera> cameras_over_time(const std::vector<Camera>& rig, int frames);

/// Writes scene.ply (fillgs 4D PLY), transforms_train.json (the rig at every frame, with
/// times), transforms_{interpolation,extrapolation}.json (the ring's held-out rigs, or the
/// split's test cameras of the other rigs), images/<camera>/<frame>.png once per camera and
/// frame, points.ply (pseudo SfM points, see pseudo_sfm_points), synth.json describing
/// the scene and its split, and split.png (write_split_picture).
/// Top view of the scene with its split: training cameras red, interpolation blue,
/// extrapolation purple, the others grey; static content grey, moving content orange;
/// `virtual_views` (a strategy's choice) green. An empty title describes the split.
void write_split_picture(const SynthScene& scene, const std::string& path, const std::vector<Camera>& virtual_views = {},
                         const std::string& title = "");

void write_synthetic_scene(const SynthScene& scene, const std::string& out_dir, Progress& progress);

}  // namespace fillgs
