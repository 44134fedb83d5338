#pragma once
// A camera as a JSON object (trajectories.json, patch.json): name, size, pinhole
// intrinsics, time and the OpenCV-convention camera-to-world matrix.
#include <string>

#include <nlohmann/json.hpp>

#include "fillgs/model/camera.hpp"

namespace fillgs {

nlohmann::json camera_json(const Camera& camera);
/// camera_json's inverse. Throws "<where>: ..." naming the missing or bad field (a size or
/// focal length that is not positive, a matrix that is not 4×4 of numbers with a rotation).
Camera camera_from_json(const nlohmann::json& j, const std::string& where);

}  // namespace fillgs
