#pragma once
// The projection's backward over the visible Gaussians of a render, a lane of them per
// instruction (splat_backward_simd.cpp): project_splat_backward<double>'s values bit for bit.
#include <cstddef>
#include <cstdint>

#include "render/splat_backward.hpp"

namespace fillgs::internal {

/// What the rows read: Gaussian visible[i]'s mean, scale and rotation (float arrays [N][3],
/// [N][3], [N][4]) and row i of `sums` ([V][stride]: dL/du, dL/dv, dL/dconic a, b, c first).
struct BackwardRowsInput {
  const uint32_t* visible = nullptr;
  const float* means = nullptr;
  const float* scales = nullptr;
  const float* rotations = nullptr;
  const float* sums = nullptr;
  int stride = 0;
};

/// For rows i in [begin, end): out[i·10 …] = dL/dmean (3), dL/dscale (3), dL/drotation (4), in
/// double, as project_splat_backward<double> adds them to zeros (0 where it adds nothing).
void project_backward_rows(const FrustumCamera& cam, const BackwardRowsInput& in, size_t begin, size_t end, double* out);

}  // namespace fillgs::internal
