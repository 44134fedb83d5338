// `fisherrf` (FisherRF): the expected information gain of a candidate's diagonal Fisher information.
#include <map>

#include "fillgs/render/raster_grad.hpp"
#include "fillgs/train/train_model.hpp"
#include "fillgs/method/strategies.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs::strategy_rows {

namespace {

/// fisherrf: a candidate scores Σ_params H_cand / (H_train + λ), H the diagonal Fisher
/// information Σ_pixels (∂Î/∂θ)² at the selection's render scale; accepted views join H_train.
class FisherStrategy : public SelectionStrategy {
 public:
  explicit FisherStrategy(SelectionContext& c) : c_(c), params_(params_from_cloud<float>(*c.in.scene)) {}
  std::vector<double> score(const std::vector<Camera>& cands, int frame) override {
    std::vector<double> s(cands.size(), 0.0);
    const std::vector<double>& train = train_information(frame);
    for (size_t i = 0; i < cands.size(); ++i) {
      const FisherDiagonal h = information(cands[i], frame);
      double total = 0;
      for (size_t k = 0; k < h.values.size(); ++k) total += h.values[k] / (train[k] + double(c_.options.fisher_lambda));
      s[i] = total;
    }
    return s;
  }
  void accept(const Camera& view, int frame) override {
    std::vector<double>& train = train_information(frame);
    const FisherDiagonal h = information(view, frame);
    for (size_t k = 0; k < h.values.size(); ++k) train[k] += h.values[k];
  }

 private:
  FisherDiagonal information(const Camera& cam, int frame) {
    if (frame != frame_index_) {
      params_at(params_, c_.time_of(frame), &frame_);
      frame_index_ = frame;
    }
    DiffRenderOptions ro;
    ro.background = c_.in.background;
    raster_.forward(frame_, scaled_camera(cam, c_.options.render_scale), ro);
    FisherDiagonal h;
    raster_.accumulate_fisher(&h);
    if (h.values.empty()) h.values.assign(c_.in.scene->size() * FisherDiagonal::kParams, 0.0);
    return h;
  }
  std::vector<double>& train_information(int frame) {
    auto it = train_.find(frame);
    if (it != train_.end()) return it->second;
    std::vector<double> sum(c_.in.scene->size() * FisherDiagonal::kParams, 0.0);
    for (const ObservedView& v : c_.in.views)
      if (v.frame == frame) {
        const FisherDiagonal h = information(v.camera, frame);
        for (size_t k = 0; k < sum.size(); ++k) sum[k] += h.values[k];
      }
    return train_.emplace(frame, std::move(sum)).first->second;
  }

  SelectionContext& c_;
  ModelParams<float> params_;
  DiffFrame<float> frame_;
  int frame_index_ = -1;
  DiffRasterizer<float> raster_;
  std::map<int, std::vector<double>> train_;  ///< H_train per frame
};

}  // namespace

const StrategyRow& row_fisherrf() {
  static const StrategyRow row = [] {
    StrategyRow r;
    r.name = "fisherrf";
    r.description = "a candidate scores its diagonal Fisher information over the training views' (FisherRF)";
    r.order = 50;
    r.make = [](SelectionContext& c) -> std::unique_ptr<SelectionStrategy> { return std::make_unique<FisherStrategy>(c); };
    return r;
  }();
  return row;
}

}  // namespace fillgs::strategy_rows
