#pragma once
// Dense optical flow between frames of a fixed camera, and where a point of one frame goes
// in a later one by chaining it (forward–backward checked). The trainer uses it to place the
// keys of moving Gaussians where the images say their content goes (train.hpp, flow_keys).
#include <optional>
#include <vector>

namespace fillgs {

/// A flow field: for every pixel of the first image, its displacement into the second
/// ([H][W][2], pixels, x then y).
struct FlowField {
  int width = 0, height = 0;
  std::vector<float> uv;
  /// Bilinear at a point in the corner convention (pixel i covers [i, i + 1)); clamped at the border.
  void sample(double x, double y, double& u, double& v) const;
};

/// Dense flow from `from` to `to`, two RGB images ([H][W][3] in [0, 1]) of one size:
/// OpenCV's Farnebäck flow on their grey levels, over a pyramid down to ~12 px.
FlowField optical_flow(const std::vector<float>& from, const std::vector<float>& to, int width, int height);

/// Follows a point through consecutive flows: forward[k] maps frame k to k+1 and
/// backward[k] frame k+1 to k. Each step must be forward–backward consistent (the backward
/// flow at the new point returns within `tolerance` px + 5% of the step) and stay inside the
/// image; otherwise (an occlusion, a flow error) there is no answer. Returns the point
/// after `steps` steps.
std::optional<std::pair<double, double>> chain_flow(const std::vector<FlowField>& forward, const std::vector<FlowField>& backward, double x,
                                                    double y, size_t steps, double tolerance = 1.0);

}  // namespace fillgs
