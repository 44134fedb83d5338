#pragma once
// Cameras and Gaussians from plain arrays (what the Python module hands over from NumPy),
// checked as the file readers check what they read: the module only converts the arrays'
// types and shapes, and everything else is decided here, where a fuzz harness reaches it
// too (tests/fuzz, "python_arrays"). Errors are fillgs::Error naming the argument and element.
#include <cstddef>
#include <string>

#include "fillgs/model/camera.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

/// Camera `index` from K (3x3, row-major) and world_to_camera (4x4, row-major, OpenCV axes),
/// a size and a time (NaN: a fixed rig's camera, at every frame). K must be a pinhole matrix
/// [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] and the pose's last row (0, 0, 0, 1): fillgs keeps
/// neither skew nor a projective row, so a value there is refused, not dropped. Then the
/// bounds every camera reader enforces (check_camera, "cameras: element i ...").
Camera camera_from_arrays(const float* K, const float* world_to_camera, double width, double height, double time, const std::string& name,
                          size_t index);

/// Camera `index` as the 3DGS family of codes holds one (3DGS, E-D3DGS, 4DGaussians,
/// Deformable 3D Gaussians: `scene/cameras.py`): R (3x3, row-major) the transpose of the
/// world-to-camera rotation (their getWorld2View2 takes R.T), T the world-to-camera
/// translation, FoVx and FoVy in radians, a centred principal point, and a size; `time` is
/// fillgs's normalised time (NaN: none; Model.normalised_time converts the codes' own).
Camera camera_from_3dgs(const double* R, const double* T, double fov_x, double fov_y, double width, double height, double time,
                        const std::string& name, size_t index);

/// camera_from_3dgs's inverse: a camera as the 3DGS family of codes holds one, R (row-major,
/// the world-to-camera rotation transposed), T, FoVx = 2 atan(W / 2fx), FoVy = 2 atan(H / 2fy).
/// Those codes have no principal point of their own (theirs is the image centre): a camera
/// whose principal point lies more than half a pixel off the centre is refused, one line
/// naming element `index` and both points, not handed over to project elsewhere.
struct Camera3dgs {
  double R[9], T[3], fov_x, fov_y;
};
Camera3dgs camera_to_3dgs(const Camera& c, size_t index);

/// n Gaussians of one frame: means [n,3], log_scales [n,3], quaternions [n,4] (w, x, y, z),
/// opacity_logits [n], sh [n, sh_coefficients, 3] (null: grey, degree 0). Every value finite,
/// no zero quaternion, sh_coefficients 1, 4, 9 or 16. `what` names the arrays in messages.
ModelState gaussians_from_arrays(size_t n, const float* means, const float* log_scales, const float* quaternions, const float* opacity_logits,
                                 const float* sh, size_t sh_coefficients, const std::string& what);

/// The observation tables `observe` returns, as arrays, for `model`: counts, speed and
/// deficiency [T, N] (counts widened to uint16), times [T] ascending in [0, 1], dynamic_ids [M]
/// (which must be the model's: tables of another model are refused). Speeds and deficiencies
/// finite and >= 0, zero for still Gaussians as observe writes them.
ObservationTables tables_from_arrays(size_t T, size_t N, const uint16_t* counts, const float* speed, const float* deficiency, const double* times,
                                     size_t M, const uint32_t* dynamic_ids, const GaussianCloud& model);

}  // namespace fillgs
