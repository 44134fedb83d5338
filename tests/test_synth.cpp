// The synthetic analysis scene keeps its promises: only the chair moves, only in
// [0.2, 0.8], and the shelf hides it from the cameras on the far side.
#include "fillgs/raster.hpp"
#include "fillgs/synth.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

float chair_max_weight(const RenderOutput& r, const SynthScene& s) {
  float m = 0;
  for (uint32_t g : s.chair_ids) m = std::max(m, r.max_weight[g]);
  return m;
}

}  // namespace

TEST_CASE("synthetic scene: only the chair moves, only between t = 0.2 and 0.8", "[synth]") {
  const SynthScene s = small_synth(11, 160, 120);
  CHECK(s.scene.dynamic_ids == s.chair_ids);
  CHECK(s.train.size() == 16);
  // Training cameras 22.5° apart on a circle.
  const Vec3d c0 = s.train[0].centre(), c1 = s.train[1].centre();
  CHECK(std::acos(c0.head<2>().normalized().dot(c1.head<2>().normalized())) * 180 / kPi == Approx(22.5));
  const FrameGaussians a = evaluate(s.scene, 0.0), b = evaluate(s.scene, 0.2), m = evaluate(s.scene, 0.5),
                       e = evaluate(s.scene, 0.8), z = evaluate(s.scene, 1.0);
  CHECK(a.means == b.means);
  CHECK(e.means == z.means);
  CHECK(a.means != m.means);
  double moved = 0;
  for (uint32_t g : s.chair_ids) moved = std::max(moved, double((e.means[g] - a.means[g]).norm()));
  CHECK(moved > 0.5);
}

TEST_CASE("synthetic scene: the shelf hides the moving chair from some cameras", "[synth]") {
  const SynthScene s = small_synth(11, 160, 120);
  RenderOptions o;
  o.max_weights = true;
  FrameEvaluator ev(s.scene);
  std::vector<std::string> hidden;
  int seen = 0;
  for (const Camera& cam : s.train) {
    bool ever = false;
    for (double t : {0.3, 0.5, 0.7}) {
      const RenderOutput r = render(ev.evaluate(t), cam, o);
      if (chair_max_weight(r, s) >= kMinAlpha) ever = true;
    }
    if (ever) ++seen;
    else hidden.push_back(cam.name);
    UNSCOPED_INFO(cam.name << (ever ? " sees" : " never sees") << " the moving chair");
  }
  // cam00 faces the shelf's front: the chair, behind the back panel, never shows.
  const RenderOutput front = render(ev.evaluate(0.5), s.train[0], o);
  CHECK(chair_max_weight(front, s) < kMinAlpha);
  const RenderOutput back = render(ev.evaluate(0.5), s.train[8], o);
  CHECK(chair_max_weight(back, s) > 0.5f);
  // The cameras that face the shelf's front (the README names them).
  CHECK(hidden == std::vector<std::string>{"cam00", "cam01", "cam14", "cam15"});
  CHECK(seen >= 8);
}
