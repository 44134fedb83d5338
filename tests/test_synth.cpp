// The synthetic analysis scene keeps its promises: only the chair moves, only in
// [0.2, 0.8], and the shelf hides it from the cameras on the far side.
#include <algorithm>

#include "fillgs/render/raster.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/experiment/rigs.hpp"
#include "fillgs/experiment/synth.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

/// The kitchen scene before a rig, at a test-sized resolution.
SynthOptions kitchen(const std::string& rig, int frames, int width, int height, double spacing) {
  SynthOptions o;
  o.rig = rig;
  o.frames = frames;
  o.width = width;
  o.height = height;
  o.spacing = spacing;
  return o;
}

float chair_max_weight(const RenderOutput& r, const SynthScene& s) {
  float m = 0;
  for (uint32_t g : s.moving_ids) m = std::max(m, r.max_weight[g]);
  return m;
}

}  // namespace

TEST_CASE("synthetic scene: only the chair moves, only between t = 0.2 and 0.8", "[synth]") {
  const SynthScene s = small_synth(11, 160, 120);
  CHECK(s.scene.dynamic_ids == s.moving_ids);
  CHECK(s.train.size() == 16);
  // Training cameras 22.5° apart on a circle.
  const Vec3d c0 = s.train[0].centre(), c1 = s.train[1].centre();
  CHECK(std::acos(c0.head<2>().normalized().dot(c1.head<2>().normalized())) * 180 / kPi == Approx(22.5));
  const FrameGaussians a = frame_at(s.scene, 0.0), b = frame_at(s.scene, 0.2), m = frame_at(s.scene, 0.5),
                       e = frame_at(s.scene, 0.8), z = frame_at(s.scene, 1.0);
  CHECK(a.means == b.means);
  CHECK(e.means == z.means);
  CHECK(a.means != m.means);
  double moved = 0;
  for (uint32_t g : s.moving_ids) moved = std::max(moved, double((e.means[g] - a.means[g]).norm()));
  CHECK(moved > 0.5);
}

TEST_CASE("synthetic scene: the shelf hides the moving chair from some cameras", "[synth]") {
  const SynthScene s = small_synth(11, 160, 120);
  RenderOptions o;
  o.max_weights = true;
  FrameSampler ev(s.scene);
  std::vector<std::string> hidden;
  int seen = 0;
  for (const Camera& cam : s.train) {
    bool ever = false;
    for (double t : {0.3, 0.5, 0.7}) {
      const RenderOutput r = render(ev.at(t), cam, o);
      if (chair_max_weight(r, s) >= kMinAlpha) ever = true;
    }
    if (ever) ++seen;
    else hidden.push_back(cam.name);
    UNSCOPED_INFO(cam.name << (ever ? " sees" : " never sees") << " the moving chair");
  }
  // cam00 faces the shelf's front: the chair, behind the back panel, never shows.
  const RenderOutput front = render(ev.at(0.5), s.train[0], o);
  CHECK(chair_max_weight(front, s) < kMinAlpha);
  const RenderOutput back = render(ev.at(0.5), s.train[8], o);
  CHECK(chair_max_weight(back, s) > 0.5f);
  // The cameras that face the shelf's front (data/README.md names them).
  CHECK(hidden == std::vector<std::string>{"cam00", "cam01", "cam14", "cam15"});
  CHECK(seen >= 8);
}

// ---------------------------------------------------------------------------------
// The paper-like rigs and the kitchen scene.

namespace {

/// World-to-camera rotation of a COLMAP quaternion, written out here rather than taken from
/// the library.
Mat3d rotation_of(double w, double x, double y, double z) {
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  w /= n, x /= n, y /= n, z /= n;
  Mat3d R;
  R << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y), 2 * (x * y + w * z), 1 - 2 * (x * x + z * z),
      2 * (y * z - w * x), 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return R;
}

}  // namespace

TEST_CASE("the N3V rig table is the real COLMAP model, and placing it keeps every projection", "[synth][rigs]") {
  const std::string model = shared_data() + "/video/n3v_flame_steak_frame0/sparse/0";
  const std::vector<Camera> file = read_cameras(model);
  const std::vector<Camera> table = n3v_rig_colmap(2690, 2016);
  REQUIRE(file.size() == 21);
  REQUIRE(table.size() == 21);
  const std::vector<ColmapPose>& poses = n3v_rig_poses();
  for (size_t i = 0; i < table.size(); ++i) {
    INFO(table[i].name);
    // The reader's camera of the same image (names are the image file names).
    const Camera* f = nullptr;
    for (const Camera& c : file)
      if (c.name.rfind(table[i].name, 0) == 0) f = &c;
    REQUIRE(f != nullptr);
    CHECK((f->R - table[i].R).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((f->t - table[i].t).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(f->fx == Approx(table[i].fx));
    CHECK(f->cy == Approx(table[i].cy));
    // The centre from the quaternion and translation by hand: C = −Rᵀ t.
    const ColmapPose& p = poses[i];
    const Mat3d R = rotation_of(p.q[0], p.q[1], p.q[2], p.q[3]);
    const Vec3d C = -R.transpose() * Vec3d(p.t[0], p.t[1], p.t[2]);
    CHECK((table[i].centre() - C).norm() < 1e-9);
  }
  // Placed in metres: x' = 0.25·A·(x − c) + (0, 0, 1.1), A = (x, z, −y). A point 10 units in
  // front of each camera projects to the same pixel before and after, and the centres move
  // by the same map.
  const std::vector<Camera> placed = placed_rig(table, 0.25, Vec3d(0, 0, 1.1));
  const Vec3d c = convergence_point(table);
  auto place = [&](const Vec3d& x) -> Vec3d {
    const Vec3d d = 0.25 * (x - c);
    return Vec3d(d.x(), d.z(), -d.y()) + Vec3d(0, 0, 1.1);
  };
  for (size_t i = 0; i < table.size(); ++i) {
    INFO(table[i].name);
    CHECK((placed[i].centre() - place(table[i].centre())).norm() < 1e-9);
    const Mat3d R = table[i].R;
    const Vec3d X = table[i].centre() + 10.0 * R.row(2).transpose() + 1.5 * R.row(0).transpose() - 0.7 * R.row(1).transpose();
    const Vec3d v = R * X + table[i].t;
    const Eigen::Vector2d pixel(table[i].fx * v.x() / v.z() + table[i].cx, table[i].fy * v.y() / v.z() + table[i].cy);
    const Vec3d q = placed[i].project(place(X));
    CHECK((q.head<2>() - pixel).norm() < 1e-6);
    CHECK(q.z() == Approx(0.25 * v.z()));
    // z up: every camera's "down" axis points down in the placed world.
    CHECK(placed[i].R.row(1).z() < -0.9);
  }
  // Where the cameras look: within 0.5 m of the walker's path above the floor.
  CHECK((convergence_point(placed) - Vec3d(0, 0, 1.1)).norm() < 1e-6);
}

TEST_CASE("the N3V split follows the paper's rule", "[synth][rigs]") {
  const SynthOptions o = kitchen("n3v", 2, 32, 24, 0.08);
  const SynthScene s = make_synthetic_scene(o);
  REQUIRE(s.train.size() == 21);
  CHECK(s.options.variant == "kitchen");
  // Position along the rig: the camera centre's x (the rig spans x in the placed world).
  auto x_of = [&](const std::string& n) { return s.camera(n)->centre().x(); };
  auto lower = [&](const std::string& n) { return s.camera(n)->centre().z() < 1.1; };
  REQUIRE(s.split.train.size() == 2);
  const double a = std::min(x_of(s.split.train[0]), x_of(s.split.train[1])), b = std::max(x_of(s.split.train[0]), x_of(s.split.train[1]));
  CHECK(lower(s.split.train[0]));
  CHECK(lower(s.split.train[1]));
  // Exactly two lower-row cameras between the training pair.
  int between_lower = 0;
  for (const Camera& c : s.train)
    if (lower(c.name) && c.centre().x() > a && c.centre().x() < b) ++between_lower;
  CHECK(between_lower == 2);
  // Interpolation: every camera strictly between them, both rows.
  std::vector<std::string> between;
  for (const Camera& c : s.train)
    if (c.centre().x() > a && c.centre().x() < b) between.push_back(c.name);
  std::vector<std::string> interp = s.split.interpolation;
  std::sort(interp.begin(), interp.end());
  CHECK(between == interp);
  // Extrapolation: beyond the pair at both ends, in both rows.
  int left = 0, right = 0, upper = 0;
  for (const std::string& n : s.split.extrapolation) {
    CHECK((x_of(n) < a || x_of(n) > b));
    left += x_of(n) < a, right += x_of(n) > b, upper += !lower(n);
  }
  CHECK(left == 4);
  CHECK(right == 4);
  CHECK(upper == 4);
}

TEST_CASE("kitchen: the walker and the box move, the pillar hides the walker from some cameras part of the time", "[synth]") {
  const SynthOptions o = kitchen("n3v", 11, 80, 60, 0.04);
  const SynthScene s = make_synthetic_scene(o);
  CHECK(s.scene.dynamic_ids == s.moving_ids);
  const FrameGaussians a = frame_at(s.scene, 0.0), z = frame_at(s.scene, 1.0);
  double moved = 0;
  for (uint32_t g : s.moving_ids) moved = std::max(moved, double((z.means[g] - a.means[g]).norm()));
  CHECK(moved > 1.5);
  // Every camera sees the static counter; the walker is hidden from some camera at some
  // frame and seen by every camera at some frame.
  RenderOptions ro;
  ro.max_weights = true;
  FrameSampler ev(s.scene);
  int hidden_somewhere = 0;
  for (const Camera& cam : s.train) {
    int seen = 0;
    for (int f = 0; f < o.frames; ++f) {
      const RenderOutput r = render(ev.at(double(f) / (o.frames - 1)), cam, ro);
      seen += chair_max_weight(r, s) >= 0.5f;
    }
    INFO(cam.name << " sees the movers well at " << seen << " of " << o.frames << " frames");
    CHECK(seen > 0);
    hidden_somewhere += seen < o.frames;
  }
  CHECK(hidden_somewhere >= 3);
}

TEST_CASE("technicolor rig: a 4x4 grid facing the kitchen, with its split", "[synth][rigs]") {
  const SynthOptions o = kitchen("technicolor", 2, 48, 26, 0.08);
  const SynthScene s = make_synthetic_scene(o);
  REQUIRE(s.train.size() == 16);
  CHECK(s.train[5].centre().x() - s.train[4].centre().x() == Approx(0.2));
  CHECK(s.train[0].centre().z() - s.train[4].centre().z() == Approx(0.2));
  for (const std::string& n : s.split.interpolation) CHECK(s.camera(n) != nullptr);
  CHECK(s.split.train == std::vector<std::string>{"cam12", "cam15"});
  REQUIRE_THROWS_WITH(([] {
                        SynthOptions b;
                        b.rig = "technicolor";
                        b.variant = "chair";
                        make_synthetic_scene(b);
                      }()),
                      Catch::Contains("unknown variant \"chair\" for rig technicolor"));
}
