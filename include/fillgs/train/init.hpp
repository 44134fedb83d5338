#pragma once
// Initial points for video without SfM points (real rigs such as CMU Panoptic): what the
// training cameras see in their first views — frame 0 of a multi-view capture; for a
// monocular one (one camera per frame, e.g. --monocular-cycle) each camera's first frame,
// so the views span the first n frames and the hull of a moving person is where the
// silhouettes of those frames overlap. Below, "first-frame camera" means a camera's first view.
//
//  * random: points drawn uniformly in the cube around the cameras' centre of interest (the
//    point nearest to every optical axis; half-size = the cameras' mean distance from it),
//    kept when at least `min_views` first-frame cameras see them in front and inside the
//    image, coloured with the mean of the pixels they land on (3DGS's random initialisation,
//    bounded by what the cameras look at);
//  * carve: with foreground masks, the visual hull on a grid over the same cube — cells
//    that land on foreground in every first-frame camera that sees them (at least
//    `min_views`), coloured alike — added to the random points, so the moving people start
//    with Gaussians where they stand.
#include <cstdint>
#include <string>
#include <utility>

#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/train/train.hpp"

namespace fillgs {

enum class ViewInit { Random, RandomAndCarve };
FILLGS_ENUM_NAMES(ViewInit, "initialisation", {ViewInit::Random, "random"}, {ViewInit::RandomAndCarve, "random+carve"});

struct ViewInitOptions {
  ViewInit method = ViewInit::RandomAndCarve;
  size_t random_points = 50000;
  int carve_cells = 96;  ///< grid cells per side of the cube
  int min_views = 2;
  uint64_t seed = 1;
};

/// The point nearest to every camera's optical axis (least squares) and the mean distance
/// of the camera centres from it. Needs two cameras that are not all parallel.
std::pair<Vec3d, double> centre_of_interest(const std::vector<Camera>& cameras);

struct ViewInitResult {
  PointSet points;
  size_t random = 0, carved = 0;
};

/// Points from the cameras' first views in `data` (see above). Carving needs masks (Dataset::has_masks).
ViewInitResult points_from_views(const Dataset& data, const ViewInitOptions& options);

}  // namespace fillgs
