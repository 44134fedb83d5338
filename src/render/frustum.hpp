#pragma once
// The 3DGS frustum rule over many Gaussians at once (frustum_simd.cpp): the decision
// project_gaussian makes (radius > 0), on a lane of Gaussians per instruction.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "fillgs/model/camera.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "render/raster_internal.hpp"

namespace fillgs::internal {

/// A camera's numbers as the rule reads them, computed once per camera.
struct FrustumCamera {
  explicit FrustumCamera(const Camera& c);
  double W[3][3], t[3];
  double fx, fy, cx, cy, limx, limy, grid_x, grid_y;
  double near = double(kNearPlane), dilation = double(kDilation), tile = double(kTileSize), huge = kHugeCoordinate;
};

/// Appends to outs[c], in order, the ids among rows [begin, end) of `ids` (or the rows
/// themselves where `ids` is null) that project_gaussian keeps for camera cams[c], c < ncams;
/// each lane of rows is read once for all the cameras.
void frustum_keep(const FrustumCamera* cams, size_t ncams, const Vec3f* means, const Vec3f* scales, const Vec4f* rotations, const uint32_t* ids,
                  size_t begin, size_t end, std::vector<uint32_t>* outs);

/// project_splat<double> and splat_footprint for rows [begin, end) of float arrays ([N][3],
/// [N][3], [N][4]), a lane of rows per instruction with the scalar code's operations in its
/// order: for each row splat_footprint keeps, exact[g], projected[g] and radii[g] as the scalar
/// preprocess (preprocess.hpp) writes them, bit for bit; other rows are left as they were.
void project_rows(const FrustumCamera& cam, const float* means, const float* scales, const float* rotations, size_t begin, size_t end,
                  SplatProjection<double>* exact, ProjectedGaussian* projected, int* radii);

}  // namespace fillgs::internal
