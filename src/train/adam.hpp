#pragma once
// The optimiser's element-wise Adam step on a parameter array, a lane of elements per
// instruction (src/train/adam_simd.cpp, dispatched at run time by Google Highway) with the
// scalar form's operations in its order: every value it stores is the scalar step's, bit
// for bit, on any instruction set (tests/test_train.cpp compares the two).
#include <cstddef>

namespace fillgs::train {

/// One step's constants: moments' decays b1, b2, the rate over the first moment's bias
/// correction (a = lr / (1 − b1^t)), 1 / √(1 − b2^t) (s2) and ε; sparse skips elements whose
/// gradient is exactly 0 (their value and moments unchanged).
struct AdamStep {
  float b1 = 0.9f, b2 = 0.999f, a = 0, s2 = 1, eps = 1e-15f;
  bool sparse = false;
};

/// For i in [0, n): m = b1·m + (1 − b1)·g; v = b2·v + (1 − b2)·g·g; x −= a·m / (√v·s2 + ε),
/// each product and sum rounded to float on its own (no fused multiply-add).
void adam_update(const AdamStep& step, float* x, const float* g, float* m, float* v, size_t n);

/// The scalar form, the reference of adam_update.
void adam_update_scalar(const AdamStep& step, float* x, const float* g, float* m, float* v, size_t n);

}  // namespace fillgs::train
