#pragma once
// Dense layers (nn.Linear) on a block of Gaussians, for the deformation networks of trained
// models (io/trained_models.cpp, io/model_support.hpp). Activations are feature-major: row k of a block holds
// feature k of every Gaussian of the block, so one weight is broadcast against a vector of
// Gaussians and a layer of any width, 1 output or 256, runs at full vector width. The kernel
// is compiled for each instruction set by Google Highway and chosen at run time.
#include <cstddef>

namespace fillgs::dense {

/// Columns in a block: a multiple of every target's vector pair (2 x 16 floats).
constexpr size_t kBlock = 256;

/// Y[o][c] = act(bias[o] + sum_k W[o][k] X[k][c]) for o < out, c < kBlock, where W is row-major
/// with `in` columns at row stride `ldw`, X has `in` rows and Y `out` rows of kBlock floats;
/// act is max(0, .) when `relu`. Sums run over k in order, one FMA each.
void layer(const float* W, size_t ldw, const float* bias, int out, int in, const float* X, float* Y, bool relu);

/// The instruction set chosen ("AVX3_SPR", "AVX2", ...) and its float lanes.
const char* target_name();
int lane_count();

}  // namespace fillgs::dense
