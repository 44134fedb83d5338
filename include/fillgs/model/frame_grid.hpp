#pragma once
// The video's frame grid: F frames at normalised times t = f / (F − 1), so that the first
// frame is t = 0 and the last t = 1; a single frame is t = 0. Every conversion between a
// frame and a time goes through this type.
#include <algorithm>
#include <cmath>
#include <vector>

#include "fillgs/base/error.hpp"

namespace fillgs {

class FrameGrid {
 public:
  explicit FrameGrid(int frames) : frames_(frames) { FILLGS_CHECK(frames >= 1); }

  int frames() const { return frames_; }
  /// t of frame f: f / (F − 1); 0 for a single frame.
  double time(int f) const { return frames_ > 1 ? double(f) / double(frames_ - 1) : 0.0; }
  /// Every frame's time, in order.
  std::vector<double> times() const {
    std::vector<double> t(static_cast<size_t>(frames_));
    for (int f = 0; f < frames_; ++f) t[size_t(f)] = time(f);
    return t;
  }
  /// One frame's step in t, the Δt of speeds: 1 / (F − 1); 1 for a single frame (nothing
  /// moves within one time).
  double step() const { return frames_ > 1 ? 1.0 / double(frames_ - 1) : 1.0; }
  /// The frame nearest to t (t clamped to [0, 1]; NaN, a time-less camera: frame 0).
  int nearest(double t) const {
    if (frames_ <= 1 || std::isnan(t)) return 0;
    return int(std::lround(std::clamp(t, 0.0, 1.0) * (frames_ - 1)));
  }
  /// f clamped into the grid.
  int clamp(int f) const { return std::clamp(f, 0, frames_ - 1); }
  /// The frames within `radius` of f, clamped: [max(0, f − r), min(F − 1, f + r)].
  std::pair<int, int> window(int f, int radius) const { return {clamp(f - radius), clamp(f + radius)}; }
  /// `count` consecutive frames containing f, centred on it where the grid allows, shifted
  /// inward at the ends (every frame when there are fewer): a patch's frames, and (count 3)
  /// the window of the selection priority's time perturbation.
  std::vector<int> consecutive(int f, int count) const {
    FILLGS_CHECK(count >= 1);
    count = std::min(count, frames_);
    const int first = std::clamp(f - (count - 1) / 2, 0, frames_ - count);
    std::vector<int> out(static_cast<size_t>(count));
    for (int k = 0; k < count; ++k) out[size_t(k)] = first + k;
    return out;
  }

 private:
  int frames_;
};

}  // namespace fillgs
