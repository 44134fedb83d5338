#pragma once
// The deficiency strategy's class, shared by its row (fillgs.cpp) and negative.cpp's.
#include <algorithm>
#include <cmath>

#include "fillgs/base/error.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/train/train_model.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs::strategy_rows {

/// fillgs (the paper's): starts by the exploration priority E; a candidate scores the mean
/// of its rendered D̂ map (or, with SelectOptions::score_gain, the sum of D̂ over what it
/// sees), the counts and ablations as SelectOptions::score says.
class DeficiencyStrategy : public SelectionStrategy {
 public:
  explicit DeficiencyStrategy(SelectionContext& c) : c_(c) {}
  Starts starts() const override { return Starts::HighestPriority; }
  std::vector<double> score(const std::vector<Camera>& cands, int frame) override {
    std::vector<double> s(cands.size(), 0.0);
    const double t = c_.time_of(frame);
    const std::vector<float> values = c_.field.values(frame, c_.options.score);
    if (c_.options.score_gain) {
      c_.engine.set_time(t);
      for (size_t i = 0; i < cands.size(); ++i)
        for (uint32_t g : c_.engine.visible_set(cands[i])) s[i] += double(values[g]);
    } else {
      for (size_t i = 0; i < cands.size(); ++i) s[i] = map_mean(cands[i], t, values.data());
    }
    return s;
  }

 private:
  /// The mean of the rendered per-Gaussian `values` at time t.
  double map_mean(const Camera& cam, double t, const float* values) {
    if (c_.options.renderer == MapRenderer::Raytraced) {
      c_.engine.set_time(t);
      return c_.engine.render_maps(cam, values, nullptr, c_.options.stride).score();
    }
    return mean_value(render_value_map(c_.sampler.at(t), cam, values));
  }
  SelectionContext& c_;
};

}  // namespace fillgs::strategy_rows
