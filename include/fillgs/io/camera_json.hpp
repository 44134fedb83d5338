#pragma once
// A camera as a JSON object (trajectories.json, patch.json): name, size, pinhole
// intrinsics, time and the OpenCV-convention camera-to-world matrix.
#include <nlohmann/json.hpp>

#include "fillgs/model/camera.hpp"

namespace fillgs {

nlohmann::json camera_json(const Camera& camera);

}  // namespace fillgs
