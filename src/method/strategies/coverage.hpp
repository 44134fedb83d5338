#pragma once
// The coverage strategies' class, shared by coverage3d.cpp and coverage4d.cpp.
#include <algorithm>
#include <cmath>

#include "fillgs/base/math.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/train/train_model.hpp"
#include "method/selection_strategy.hpp"

namespace fillgs::strategy_rows {

/// coverage3d / coverage4d: a candidate scores the (Gaussian × direction bin) cells it sees
/// that no view has covered, 8 azimuth × 4 elevation bins of 45°; 4D keeps one set of cells
/// per frame, 3D one for the whole video. The training views cover first.
class CoverageStrategy : public SelectionStrategy {
 public:
  CoverageStrategy(SelectionContext& c, bool per_frame) : c_(c), per_frame_(per_frame) {
    coverage_.assign((per_frame ? size_t(c.in.frames) : 1) * c.in.scene->size(), 0u);
    for (const ObservedView& v : c.in.views) cover(v.camera, v.frame);
  }
  std::vector<double> score(const std::vector<Camera>& cands, int frame) override {
    std::vector<double> s(cands.size(), 0.0);
    c_.engine.set_time(c_.time_of(frame));
    for (size_t i = 0; i < cands.size(); ++i) s[i] = double(new_cells(cands[i], frame));
    return s;
  }
  void accept(const Camera& view, int frame) override { cover(view, frame); }

 private:
  uint32_t direction_bit(const Vec3d& from_gaussian) const {
    const int a = (c_.vertical + 1) % 3, b = (c_.vertical + 2) % 3;
    const Vec3d d = from_gaussian.normalized();
    const double el = std::asin(std::clamp(d[c_.vertical], -1.0, 1.0)) * 180.0 / kPi;  // [-90, 90]
    const double az = std::atan2(d[b], d[a]) * 180.0 / kPi;                              // (-180, 180]
    const int e = std::clamp(int(std::floor((el + 90.0) / 45.0)), 0, 3);
    const int z = std::clamp(int(std::floor((az + 180.0) / 45.0)), 0, 7);
    return 1u << (e * 8 + z);
  }
  uint32_t* row(int frame) { return coverage_.data() + (per_frame_ ? size_t(frame) * c_.in.scene->size() : 0); }
  size_t new_cells(const Camera& cam, int frame) {
    const uint32_t* r = row(frame);
    const FrameGaussians& fg = c_.engine.frame();
    const Vec3d centre = cam.centre();
    size_t n = 0;
    for (uint32_t g : c_.engine.visible_set(cam))
      if (!(r[g] & direction_bit(centre - fg.means[g].cast<double>()))) ++n;
    return n;
  }
  void cover(const Camera& cam, int frame) {
    c_.engine.set_time(c_.time_of(frame));
    uint32_t* r = row(frame);
    const FrameGaussians& fg = c_.engine.frame();
    const Vec3d centre = cam.centre();
    for (uint32_t g : c_.engine.visible_set(cam)) r[g] |= direction_bit(centre - fg.means[g].cast<double>());
  }

  SelectionContext& c_;
  bool per_frame_;
  std::vector<uint32_t> coverage_;
};

}  // namespace fillgs::strategy_rows
