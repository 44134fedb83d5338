#pragma once
// The projection's backward (project_splat_backward, raster_grad.cpp) written out operation
// by operation in the order its Eigen products evaluate them, over a number type V: double
// (the scalar form) or a lane of doubles (splat_backward_simd.cpp), so that the vector form
// gives the Eigen form's values bit for bit (tests/test_grad.cpp compares them).
//
// V needs +, -, * and / (each rounded on its own: the files that instantiate this are
// compiled without fused multiply-adds) and the overloads neg(a), less(a, b) (a mask),
// pick(mask, a, b) (a where the mask holds), both(m1, m2) and either(m1, m2); double's are
// below.
#include "render/frustum.hpp"

namespace fillgs::internal {

inline double neg(double a) { return -a; }
inline bool less(double a, double b) { return a < b; }
inline double pick(bool m, double a, double b) { return m ? a : b; }
inline bool both(bool a, bool b) { return a && b; }
inline bool either(bool a, bool b) { return a || b; }

// The math itself, shared with the per-instruction-set copies of splat_backward_simd.cpp
// (which include it inside Highway's target namespace): sum3_seq, sum3_row and
// splat_backward_math.
#include "render/splat_backward_math.inl"

}  // namespace fillgs::internal
