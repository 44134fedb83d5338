// Viewpoint-time selection: priority on the synthetic chair/shelf scene, candidate
// geometry, observation updates, baselines, determinism, the command line.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <set>
#include <sstream>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/cli.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/visibility/visibility.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

constexpr int kFrames = 10;  // t = f / 9: frames 2..7 lie in [0.2, 0.8]

/// The chair/shelf scene at test size, its training views, images (8-bit like files) and grid.
struct Fixture {
  SynthScene synth = small_synth(kFrames, 80, 60, 0.04);
  std::vector<ObservedView> views;
  std::vector<std::vector<float>> images;
  ExplorationGrid grid;
  Fixture() {
    views = observed_views(cameras_over_time(synth.train, kFrames), kFrames);
    FrameSampler ev(synth.scene);
    for (const ObservedView& v : views) {
      std::vector<float> rgb = render(ev.at(v.camera.time), v.camera).rgb;
      for (float& x : rgb) x = std::round(std::clamp(x, 0.0f, 1.0f) * 255.0f) / 255.0f;
      images.push_back(std::move(rgb));
    }
    std::vector<Camera> cams;
    for (const ObservedView& v : views) cams.push_back(v.camera);
    grid = build_exploration_grid(synth.scene, cams, {});
  }
  SelectInput input() const {
    SelectInput in;
    in.scene = &synth.scene;
    in.views = views;
    in.frames = kFrames;
    in.image = [this](size_t i) { return images[i]; };
    in.grid = &grid;
    return in;
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

SelectOptions small_options(const std::string& s, int trajectories = 4) {
  SelectOptions o;
  o.strategy = s;
  o.trajectories = trajectories;
  o.render_scale = 1.0;
  o.stride = 2;
  return o;
}

/// Chair Gaussians a camera sees (occlusion-aware) at time t.
size_t chair_seen(const Camera& cam, double t) {
  const Fixture& fx = fixture();
  VisibilityOptions vo;
  vo.mode = VisibilityMode::Exact;
  VisibilityEngine e(fx.synth.scene, vo);
  e.set_time(t);
  const std::vector<uint32_t> vis = e.visible_set(cam);
  size_t n = 0;
  for (uint32_t g : fx.synth.moving_ids) n += std::binary_search(vis.begin(), vis.end(), g);
  return n;
}

bool chair_moving(double t) {
  const SynthOptions& o = fixture().synth.options;
  return t > o.move_start && t < o.move_end;
}

bool same_cameras(const std::vector<Trajectory>& a, const std::vector<Trajectory>& b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k) {
    if (a[k].frame != b[k].frame || a[k].poses.size() != b[k].poses.size() || a[k].scores != b[k].scores) return false;
    for (size_t j = 0; j < a[k].poses.size(); ++j)
      if (a[k].poses[j].R != b[k].poses[j].R || a[k].poses[j].t != b[k].poses[j].t) return false;
  }
  return true;
}

}  // namespace

TEST_CASE("priority: the highest viewpoints see the chair move, the lowest do not", "[select]") {
  const Fixture& fx = fixture();
  SelectOptions o = small_options("fillgs");
  const SelectInput in = fx.input();
  const PriorityScores p = exploration_priority(in, o);
  REQUIRE(p.views.size() == fx.views.size());
  std::vector<size_t> order(p.views.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return p.priority[a] > p.priority[b]; });
  int top_moving_chair = 0;
  for (size_t r = 0; r < 10; ++r) {
    const ObservedView& v = fx.views[p.views[order[r]]];
    const bool ok = v.camera.time >= 0.2 && v.camera.time <= 0.8 && chair_seen(v.camera, v.camera.time) > 0;
    INFO("rank " << r << ": " << v.camera.name << " t=" << v.camera.time << " E=" << p.priority[order[r]]);
    top_moving_chair += ok;
  }
  CHECK(top_moving_chair >= 8);
  for (size_t r = order.size() - 10; r < order.size(); ++r) {
    const ObservedView& v = fx.views[p.views[order[r]]];
    INFO(v.camera.name << " t=" << v.camera.time);
    CHECK_FALSE((chair_moving(v.camera.time) && chair_seen(v.camera, v.camera.time) > 0));
  }
  // Normalisation (the paper, Sec. 3.2): L averages 1, the groups 3/7, 3/7 and 1/7.
  auto mean = [](const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0) / double(x.size()); };
  CHECK(mean(p.error) == Approx(1.0).epsilon(1e-9));
  CHECK(mean(p.translation) == Approx(3.0 / 7.0).epsilon(1e-9));
  CHECK(mean(p.rotation) == Approx(3.0 / 7.0).epsilon(1e-9));
  CHECK(mean(p.time) == Approx(1.0 / 7.0).epsilon(1e-9));
}

TEST_CASE("priority: the time-subsampling knob evaluates every k-th frame only", "[select]") {
  SelectOptions o = small_options("fillgs");
  o.time_stride = 3;
  const PriorityScores p = exploration_priority(fixture().input(), o);
  std::set<int> frames;
  for (uint32_t v : p.views) frames.insert(fixture().views[v].frame);
  CHECK(frames == std::set<int>{0, 3, 6, 9});
  CHECK(p.views.size() == 4 * fixture().synth.train.size());
}

TEST_CASE("patch frames and the time window stay inside the frame range at t = 0 and t = 1", "[select][extremes]") {
  CHECK(FrameGrid(30).consecutive(0, 3) == std::vector<int>{0, 1, 2});
  CHECK(FrameGrid(30).consecutive(29, 3) == std::vector<int>{27, 28, 29});
  CHECK(FrameGrid(30).consecutive(5, 3) == std::vector<int>{4, 5, 6});
  CHECK(FrameGrid(30).consecutive(5, 4) == std::vector<int>{4, 5, 6, 7});
  CHECK(FrameGrid(2).consecutive(1, 3) == std::vector<int>{0, 1});
  CHECK(FrameGrid(1).consecutive(0, 3) == std::vector<int>{0});
  // Trajectories chosen at the first and last frames (a rig: every frame a start).
  const Fixture& fx = fixture();
  for (const Trajectory& t : select_viewpoints(fx.input(), small_options("interpolation", 12)).trajectories) {
    CHECK(t.patch_frames == FrameGrid(kFrames).consecutive(t.frame, 3));
    for (size_t i = 0; i < t.patch_frames.size(); ++i) CHECK(t.patch_times[i] == double(t.patch_frames[i]) / (kFrames - 1));
  }
}

TEST_CASE("candidates: the 12 local poses are the paper's steps and angles (Appendix A)", "[select]") {
  const Fixture& fx = fixture();
  const Camera cur = fx.synth.train[3];
  const double step = 0.37;
  const std::vector<Camera> c = local_candidates(cur, fx.synth.train, step, 10.0);
  REQUIRE(c.size() == 12);
  const Vec3d o = cur.centre();
  for (int k = 0; k < 6; ++k) {  // ± right, up (camera y), forward
    const Vec3d axis = cur.R.row(k / 2).transpose();
    CHECK((c[size_t(k)].centre() - (o + (k % 2 ? -step : step) * axis)).norm() < 1e-12);
    CHECK((c[size_t(k)].R - cur.R).norm() < 1e-12);
  }
  for (int k = 6; k < 10; ++k) {  // ±10° about the camera's right, then up axis; centre kept
    CHECK((c[size_t(k)].centre() - o).norm() < 1e-9);
    const Mat3d rel = c[size_t(k)].R * cur.R.transpose();  // rotation in camera coordinates
    const Eigen::AngleAxisd aa(rel);
    CHECK(aa.angle() * 180.0 / kPi == Approx(10.0).epsilon(1e-9));
    const int axis = (k - 6) / 2;
    CHECK(std::fabs(aa.axis()[axis]) == Approx(1.0).epsilon(1e-9));
  }
  // Half-way to the two nearest training cameras: the ring neighbours 2 and 4 (22.5° apart).
  std::set<std::string> toward;
  for (int k = 10; k < 12; ++k) {
    bool found = false;
    for (int n : {2, 4}) {
      const Camera& t = fx.synth.train[size_t(n)];
      if ((c[size_t(k)].centre() - 0.5 * (o + t.centre())).norm() < 1e-9) {
        found = true;
        toward.insert(t.name);
        const double half = Eigen::AngleAxisd(cur.R * t.R.transpose()).angle() / 2;
        CHECK(Eigen::AngleAxisd(c[size_t(k)].R * cur.R.transpose()).angle() == Approx(half).epsilon(1e-9));
      }
    }
    CHECK(found);
  }
  CHECK(toward.size() == 2);
}

TEST_CASE("candidates: global candidates lie in free voxels of the grown box and look between the neighbours", "[select]") {
  const Fixture& fx = fixture();
  const Camera start = fx.synth.train[5];
  const double grow = 3 * fx.grid.step();
  std::mt19937_64 rng(11);
  const std::vector<Camera> g = global_candidates(start, fx.synth.train, fx.grid, 12, grow, rng);
  REQUIRE(g.size() == 12);
  Box3 box{start.centre(), start.centre()};
  box.extend(fx.synth.train[4].centre());
  box.extend(fx.synth.train[6].centre());
  const Vec3d pad = Vec3d::Constant(grow) + 0.5 * fx.grid.voxel_size();  // a voxel whose centre is inside
  for (const Camera& c : g) {
    CHECK(fx.grid.is_free(c.centre()));
    CHECK(((c.centre() - box.lo).array() >= -pad.array()).all());
    CHECK(((c.centre() - box.hi).array() <= pad.array()).all());
    // Its rotation lies on the geodesic between the neighbours' rotations.
    const Mat3d& ra = fx.synth.train[4].R;
    const Mat3d& rb = fx.synth.train[6].R;
    auto angle = [](const Mat3d& x, const Mat3d& y) { return Eigen::AngleAxisd(x * y.transpose()).angle(); };
    CHECK(angle(ra, c.R) + angle(c.R, rb) == Approx(angle(ra, rb)).margin(1e-9));
  }
}

TEST_CASE("candidates: with two training cameras the start and the other one span the global box", "[select]") {
  // The paper's setting: two cameras. The start's only neighbour is the other camera; the
  // candidates lie in the grown box of the two and look between them.
  const Fixture& fx = fixture();
  const Camera& start = fx.synth.train[5];
  const Camera& other = fx.synth.train[6];
  const double grow = 3 * fx.grid.step();
  std::mt19937_64 rng(5);
  const std::vector<Camera> g = global_candidates(start, {start, other}, fx.grid, 12, grow, rng);
  REQUIRE(g.size() == 12);
  Box3 box{start.centre(), start.centre()};
  box.extend(other.centre());
  const Vec3d pad = Vec3d::Constant(grow) + 0.5 * fx.grid.voxel_size();
  auto angle = [](const Mat3d& x, const Mat3d& y) { return Eigen::AngleAxisd(x * y.transpose()).angle(); };
  for (const Camera& c : g) {
    CHECK(fx.grid.is_free(c.centre()));
    CHECK(((c.centre() - box.lo).array() >= -pad.array()).all());
    CHECK(((c.centre() - box.hi).array() <= pad.array()).all());
    CHECK(angle(start.R, c.R) + angle(c.R, other.R) == Approx(angle(start.R, other.R)).margin(1e-9));
  }
  CHECK(global_candidates(start, {start}, fx.grid, 12, grow, rng).empty());
}

TEST_CASE("selection: D falls where a trajectory looked and the next trajectory starts elsewhere", "[select]") {
  const Fixture& fx = fixture();
  SelectOptions o = small_options("fillgs", 2);
  const SelectResult r = select_viewpoints(fx.input(), o);
  REQUIRE(r.trajectories.size() == 2);
  const Trajectory& t0 = r.trajectories[0];
  CHECK(t0.poses.size() == 3);
  CHECK(t0.patch_frames.size() == 3);
  // Independent replay: D̂ of its views before and after counting them as observations.
  DeficiencyField field(r.initial_tables, o.deficiency_quantile);
  VisibilityEngine e(fx.synth.scene, o.visibility);
  FrameSampler ev(fx.synth.scene);
  auto mean_d = [&](const std::vector<Camera>& views) {
    double s = 0;
    for (const Camera& v : views) {
      const int f = int(std::lround(v.time * (kFrames - 1)));
      const std::vector<float> d = field.values(f, CandidateScore::Deficiency);
      s += mean_value(render_value_map(ev.at(v.time), v, d.data()));
    }
    return s / double(views.size());
  };
  const double before = mean_d(t0.views());
  for (const Camera& v : t0.views()) {
    e.set_time(v.time);
    field.add_view(int(std::lround(v.time * (kFrames - 1))), e.visible_set(v));
  }
  const double after = mean_d(t0.views());
  INFO("mean D̂ of trajectory 0's views: before " << before << ", after " << after);
  CHECK(before > 0.0);
  CHECK(after < 0.9 * before);
  const Trajectory& t1 = r.trajectories[1];
  CHECK((t1.frame != t0.frame || (t1.poses[0].centre() - t0.poses[0].centre()).norm() > 1e-6 ||
         (t1.poses[0].R - t0.poses[0].R).norm() > 1e-9));
  CHECK(t1.start_view != t0.start_view);
}

TEST_CASE("selection: fillgs looks at the moving chair, negative avoids it", "[select]") {
  const Fixture& fx = fixture();
  auto chair_views = [&](const std::string& s) {
    const SelectResult r = select_viewpoints(fx.input(), small_options(s, 4));
    REQUIRE(r.trajectories.size() == 4);
    size_t seeing = 0, total = 0;
    for (const Trajectory& t : r.trajectories)
      for (const Camera& c : t.poses) {
        seeing += chair_moving(c.time) && chair_seen(c, c.time) > 0;
        ++total;
      }
    return std::make_pair(seeing, total);
  };
  const auto fill = chair_views("fillgs");
  const auto neg = chair_views("negative");
  CHECK(fill.first == fill.second);
  CHECK(neg.first == 0);
}

TEST_CASE("selection: spread starts take the best E(v) whose patch overlaps no earlier start of its camera", "[select]") {
  const Fixture& fx = fixture();
  const auto overlapping = [&](const SelectResult& r, int patch) {
    int pairs = 0;
    for (size_t a = 0; a < r.trajectories.size(); ++a)
      for (size_t b = 0; b < a; ++b) {
        const ObservedView& u = fx.views[size_t(r.trajectories[a].start_view)];
        const ObservedView& v = fx.views[size_t(r.trajectories[b].start_view)];
        pairs += u.pose == v.pose && std::abs(u.frame - v.frame) < patch;
      }
    return pairs;
  };
  SelectOptions o = small_options("fillgs", 4);
  o.no_global = true;  // a global winner moves Trajectory::start_view off the starting view
  const SelectResult plain = select_viewpoints(fx.input(), o);
  o.spread_starts = true;
  const SelectResult spread = select_viewpoints(fx.input(), o);
  REQUIRE(spread.trajectories.size() == 4);
  // On this scene the best E(v) cluster: without the option patches of one camera overlap.
  CHECK(overlapping(plain, o.patch_frames) > 0);
  CHECK(overlapping(spread, o.patch_frames) == 0);
  // The starts, independently: views by E descending, each taken unless it overlaps one taken.
  const PriorityScores& p = spread.priority;
  std::vector<size_t> order(p.views.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return p.priority[a] > p.priority[b]; });
  std::vector<uint32_t> expected;
  for (size_t k : order) {
    const ObservedView& v = fx.views[p.views[k]];
    bool clash = false;
    for (uint32_t e : expected) clash = clash || (fx.views[e].pose == v.pose && std::abs(fx.views[e].frame - v.frame) < o.patch_frames);
    if (!clash) expected.push_back(p.views[k]);
    if (expected.size() == 4) break;
  }
  REQUIRE(expected.size() == 4);
  for (size_t k = 0; k < 4; ++k) CHECK(spread.trajectories[k].start_view == int(expected[k]));
}

TEST_CASE("selection: the gain score of a pose is the sum of D-hat over what it sees", "[select]") {
  const Fixture& fx = fixture();
  SelectOptions o = small_options("fillgs", 2);
  o.score_gain = true;
  const SelectResult r = select_viewpoints(fx.input(), o);
  REQUIRE(r.trajectories.size() == 2);
  // The first trajectory is scored before any virtual view is observed: D-hat of the
  // training views' tables, summed here over each pose's visible set at the pose's time.
  const DeficiencyField field(r.initial_tables, o.deficiency_quantile);
  VisibilityEngine engine(fx.synth.scene, o.visibility);
  const Trajectory& t = r.trajectories[0];
  REQUIRE(t.poses.size() == t.scores.size());
  const std::vector<float> d = field.values(t.frame, CandidateScore::Deficiency);
  size_t seeing_motion = 0;
  for (size_t j = 0; j < t.poses.size(); ++j) {
    engine.set_time(t.poses[j].time);
    double expected = 0;
    for (uint32_t g : engine.visible_set(t.poses[j])) expected += double(d[g]);
    INFO("pose " << j);
    CHECK(t.scores[j] == Approx(expected).epsilon(1e-9));
    seeing_motion += expected > 0;
  }
  CHECK(seeing_motion == t.poses.size());
}

TEST_CASE("selection: every strategy returns free, deterministic trajectories whatever the thread count", "[select]") {
  const Fixture& fx = fixture();
  for (const std::string s : {"fillgs", "random", "negative", "interpolation", "fisherrf",
                     "coverage3d", "coverage4d"}) {
    INFO("strategy " << s);
    SelectOptions o = small_options(s, 2);
    o.time_stride = 3;  // priority on 4 of the 10 frames: the same code, a quarter of the renders
    const SelectResult a = with_threads(1, [&] { return select_viewpoints(fx.input(), o); });
    const SelectResult b = with_threads(2, [&] { return select_viewpoints(fx.input(), o); });
    CHECK(a.trajectories.size() == 2);
    CHECK(same_cameras(a.trajectories, b.trajectories));
    if (s == "random" || s == "interpolation") {  // the seeded ones: another seed, other views
      o.seed = 99;
      CHECK_FALSE(same_cameras(a.trajectories, select_viewpoints(fx.input(), o).trajectories));
    }
    for (const Trajectory& t : a.trajectories) {
      CHECK(t.start_view >= 0);
      for (const Camera& p : t.poses) CHECK(fx.grid.is_free(p.centre()));
      for (double sc : t.scores) CHECK(std::isfinite(sc));
    }
  }
}

TEST_CASE("selection: interpolation poses lie between neighbouring training cameras", "[select]") {
  const Fixture& fx = fixture();
  const SelectResult r = select_viewpoints(fx.input(), small_options("interpolation", 6));
  for (const Trajectory& t : r.trajectories) {
    const Vec3d a = fx.views[size_t(t.start_view)].camera.centre();
    // The other end: the pose after the last is as far again as the spacing.
    const Vec3d d = t.poses[1].centre() - t.poses[0].centre();
    const Vec3d b = t.poses[2].centre() + d;
    CHECK((t.poses[0].centre() - (a + d)).norm() < 1e-9);
    // b is a training camera 22.5° along the ring (a neighbour).
    double nearest = 1e9;
    for (const Camera& c : fx.synth.train) nearest = std::min(nearest, (c.centre() - b).norm());
    CHECK(nearest < 1e-9);
    CHECK((b - a).norm() == Approx(2 * 3.2 * std::sin(22.5 / 2 * kPi / 180)).epsilon(1e-6));
  }
}

TEST_CASE("selection: interpolation on a monocular video (one camera per frame) still pairs neighbouring cameras", "[select]") {
  // Frame f keeps only training camera f mod 16, as --monocular-cycle makes it: no frame holds
  // a pair, and the pairs come from the cameras' first views.
  const Fixture& fx = fixture();
  SelectInput in = fx.input();
  std::vector<ObservedView> mono;
  std::vector<std::vector<float>> images;
  const uint32_t poses = uint32_t(fx.synth.train.size());
  for (size_t i = 0; i < fx.views.size(); ++i)
    if (fx.views[i].pose == uint32_t(fx.views[i].frame) % poses) {
      mono.push_back(fx.views[i]);
      images.push_back(fx.images[i]);
    }
  REQUIRE(mono.size() == size_t(kFrames));
  in.views = mono;
  in.image = [&images](size_t i) { return images[i]; };
  const SelectResult r = select_viewpoints(in, small_options("interpolation", 6));
  REQUIRE(r.trajectories.size() == 6);
  // The 10 frames film ring cameras 0..9 (22.5 degrees apart); each is paired with its two
  // nearest among them, so a pair is 22.5 or (at the ends: 0 with 2, 9 with 7) 45 degrees wide.
  const auto filmed = [&](const Vec3d& x) {
    double nearest = 1e9;
    for (const ObservedView& v : mono) nearest = std::min(nearest, (v.camera.centre() - x).norm());
    return nearest < 1e-9;
  };
  const double chord = 2 * 3.2 * std::sin(22.5 / 2 * kPi / 180), chord2 = 2 * 3.2 * std::sin(45.0 / 2 * kPi / 180);
  int wide = 0;
  for (const Trajectory& t : r.trajectories) {
    REQUIRE(t.poses.size() == 3);
    const Vec3d d = t.poses[1].centre() - t.poses[0].centre();
    const Vec3d a = t.poses[0].centre() - d, b = t.poses[2].centre() + d;
    CHECK(filmed(a));
    CHECK(filmed(b));
    const double ab = (b - a).norm();
    CHECK((std::fabs(ab - chord) < 1e-6 || std::fabs(ab - chord2) < 1e-6));
    wide += std::fabs(ab - chord2) < 1e-6;
    for (const Camera& p : t.poses) CHECK(p.time == Approx(t.frame / double(kFrames - 1)));
    // The start, when set, is the one view filmed at the trajectory's frame.
    if (t.start_view >= 0) CHECK(mono[size_t(t.start_view)].frame == t.frame);
  }
  CHECK(wide == 1);  // pairs in order (0,1), (0,2), (1,2), (2,3), …: the second is the wide one
}

TEST_CASE("selection: a scene with no motion selects without NaN and says D is zero", "[select]") {
  const Fixture& fx = fixture();
  GaussianCloud still = fx.synth.scene;
  // Freeze every track at its first key: nothing moves.
  const int K = still.keyframed.key_count;
  for (size_t m = 0; m < still.dynamic_ids.size(); ++m)
    for (int k = 1; k < K; ++k)
      for (int c = 0; c < 3; ++c) still.keyframed.positions[(m * K + k) * 3 + c] = still.keyframed.positions[m * K * 3 + c];
  if (!still.keyframed.rotations.empty())
    for (size_t m = 0; m < still.dynamic_ids.size(); ++m)
      for (int k = 1; k < K; ++k)
        for (int c = 0; c < 4; ++c) still.keyframed.rotations[(m * K + k) * 4 + c] = still.keyframed.rotations[m * K * 4 + c];
  partition_static_dynamic(still);
  REQUIRE(still.dynamic_count() == 0);
  SelectInput in = fx.input();
  in.scene = &still;
  SelectOptions o = small_options("fillgs", 2);
  o.time_stride = 3;
  const SelectResult r = select_viewpoints(in, o);
  CHECK(r.trajectories.size() == 2);
  CHECK(std::find(r.notes.begin(), r.notes.end(), "the scene has no moving Gaussians: D = 0 everywhere") != r.notes.end());
  for (const Trajectory& t : r.trajectories)
    for (double s : t.scores) CHECK(s == 0.0);
  for (double e : r.priority.priority) CHECK(std::isfinite(e));
}

TEST_CASE("fillgs explore and fillgs select write their outputs and bad input writes nothing", "[select][cli]") {
  const std::string dir = scratch("select_cli");
  const SynthScene s = small_synth(6, 48, 36, 0.05);
  write_synthetic_scene(s, join_path(dir, "scene"), null_progress());
  const std::string scene = join_path(dir, "scene/scene.ply"), cams = join_path(dir, "scene/transforms_train.json");
  std::ostringstream out, err;
  REQUIRE(cli::run({"explore", "--scene", scene, "--cameras", cams, "--out", join_path(dir, "ex"), "--divisions", "32"}, out, err) == 0);
  CHECK(std::filesystem::exists(join_path(dir, "ex/exploration.vdb")));
  CHECK(std::filesystem::exists(join_path(dir, "ex/exploration.png")));
  const int rc = cli::run({"select", "--scene", scene, "--cameras", cams, "--images", join_path(dir, "scene"), "--grid",
                           join_path(dir, "ex/exploration.vdb"), "--out", join_path(dir, "sel"), "--trajectories", "2", "--quiet"},
                          out, err);
  INFO(err.str());
  REQUIRE(rc == 0);
  std::ifstream tj(join_path(dir, "sel/trajectories.json"));
  const nlohmann::json j = nlohmann::json::parse(tj);
  CHECK(j["trajectories"].size() == 2);
  CHECK(j["cameras"].size() == 2 * 3 * 3);
  for (const auto& c : j["cameras"]) {
    CHECK(std::filesystem::exists(join_path(dir, "sel/renders/" + c["name"].get<std::string>() + ".png")));
    CHECK(std::filesystem::exists(join_path(dir, "sel/renders/" + c["name"].get<std::string>() + "_D.png")));
  }
  for (const char* f : {"transforms.json", "colmap/images.txt", "summary.json", "trajectories.png", "priority_E.npy",
                        "priority_heatmap.png", "priority_over_time.png"})
    CHECK(std::filesystem::exists(join_path(dir, std::string("sel/") + f)));
  const std::vector<Camera> back = read_cameras(join_path(dir, "sel/transforms.json"));
  CHECK(back.size() == 18);

  // Bad input: one line, exit 1, no output folder.
  std::ostringstream e2;
  CHECK(cli::run({"select", "--scene", scene, "--cameras", cams, "--out", join_path(dir, "bad"), "--strategy", "best"}, out, e2) == 1);
  const std::string msg = e2.str();
  CHECK(msg.find("unknown strategy 'best'") != std::string::npos);
  CHECK(std::count(msg.begin(), msg.end(), '\n') == 1);
  std::ostringstream e3;
  CHECK(cli::run({"select", "--scene", join_path(dir, "missing.ply"), "--cameras", cams, "--out", join_path(dir, "bad")}, out, e3) == 1);
  CHECK(e3.str().find("missing.ply") != std::string::npos);
  std::ostringstream e4;
  CHECK(cli::run({"select", "--scene", scene, "--cameras", cams, "--grid", cams, "--out", join_path(dir, "bad")}, out, e4) == 1);
  CHECK(e4.str().find("transforms_train.json") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(join_path(dir, "bad")));
}

TEST_CASE("co-visibility rules: paper D-hat, static count, motion-discounted density (hand-made tables)", "[select][weights]") {
  // One frame, four Gaussians: g0 static seen 2 times; g1 moving at s = 2 seen once; g2
  // moving at s = 1 seen 3 times; g3 moving at s = 1 never seen. D = s / (1 + C) =
  // {-, 1, 0.25, 1}: D_q (0.99 over D > 0) = 1; s_q (0.99 over s > 0) = 2.
  ObservationTables t;
  t.times = {0.0};
  t.gaussians = 4;
  t.dynamic_ids = {1, 2, 3};
  t.counts = {2, 1, 3, 0};
  t.dynamic_speed = {2.0f, 1.0f, 1.0f};
  t.dynamic_deficiency = {1.0f, 0.25f, 1.0f};
  DeficiencyField field(t, 0.99f);
  using V = std::vector<float>;
  auto near = [](const V& a, const V& b) {
    bool ok = a.size() == b.size();
    for (size_t i = 0; ok && i < a.size(); ++i) ok = std::abs(a[i] - b[i]) < 1e-6f;
    return ok;
  };
  CHECK(near(field.covisibility(0, Covisibility::Paper), V{0.0f, 1.0f, 0.25f, 1.0f}));
  CHECK(near(field.covisibility(0, Covisibility::StaticCount), V{1.0f / 3, 1.0f, 0.25f, 1.0f}));
  // (1 + s / s_q) / (1 + C), at most 1: g1 (1 + 1) / 2, g2 (1 + 0.5) / 4, g3 1.5 -> 1.
  CHECK(near(field.covisibility(0, Covisibility::Density), V{1.0f / 3, 1.0f, 0.375f, 1.0f}));
  // A virtual view that sees g0 and g2 counts as one more observation of both.
  field.add_view(0, {0, 2});
  CHECK(near(field.covisibility(0, Covisibility::Density), V{0.25f, 1.0f, 0.3f, 1.0f}));
  CHECK(near(field.covisibility(0, Covisibility::Paper), V{0.0f, 1.0f, 0.2f, 1.0f}));
  for (const char* name : {"paper", "static-count", "density"}) CHECK(to_string(parse_name<Covisibility>(name)) == std::string(name));
  CHECK_THROWS(parse_name<Covisibility>("zero"));
}

namespace {
/// Ring cameras 0 and 4 (90 degrees apart) as the training rig; the other 14 at every frame
/// as the pool.
struct PoolFixture {
  SelectInput in;
  std::vector<ObservedView> pool;
  explicit PoolFixture(const Fixture& fx) : in(fx.input()) {
    in.views.clear();
    for (const ObservedView& v : fx.views)
      if (v.pose == 0 || v.pose == 4) in.views.push_back(v);
      else pool.push_back(v);
    in.image = nullptr;
  }
};
}  // namespace

TEST_CASE("pool selection: the lazy search chooses exactly what rescoring every candidate after every choice chooses", "[select][pool]") {
  const Fixture& fx = fixture();
  PoolFixture p(fx);
  // Every other pool pose at frames 2..6 (35 candidates): the reference rescores them all after every choice.
  std::vector<ObservedView> few;
  for (const ObservedView& v : p.pool)
    if (v.pose % 2 == 1 && v.frame >= 2 && v.frame <= 6) few.push_back(v);
  p.pool = few;
  for (const std::string s : {"fillgs", "coverage3d", "coverage4d", "fisherrf", "negative"}) {
    INFO("strategy " << s);
    SelectOptions o = small_options(s, 0);
    const int count = s == "fisherrf" ? 3 : 8;
    const PoolSelectResult lazy = select_from_pool(p.in, p.pool, count, o);
    const PoolSelectResult full = select_from_pool(p.in, p.pool, count, o, true);
    REQUIRE(lazy.chosen.size() == size_t(count));
    REQUIRE(full.chosen.size() == size_t(count));
    for (int k = 0; k < count; ++k) {
      CHECK(lazy.chosen[size_t(k)].candidate == full.chosen[size_t(k)].candidate);
      CHECK(lazy.chosen[size_t(k)].score == full.chosen[size_t(k)].score);
    }
    if (s != "negative") CHECK(lazy.scored < full.scored);
    // No score grows as views are added: each choice scores at most the one before.
    for (int k = 1; k < count; ++k)
      if (s != "negative") CHECK(full.chosen[size_t(k)].score <= full.chosen[size_t(k - 1)].score);
    // Never the same candidate twice.
    std::set<size_t> seen;
    for (const PoolChoice& c : lazy.chosen) CHECK(seen.insert(c.candidate).second);
  }
}

TEST_CASE("pool selection: coverage4d keeps one map per frame and coverage3d one for the whole video", "[select][pool]") {
  // One pool pose at two frames. coverage4d: choosing it at one frame leaves its other
  // frame's score exactly as it was (a map per frame). coverage3d: after the first, only
  // Gaussians that moved can still add a (Gaussian x direction) cell from the same camera,
  // since a static Gaussian's direction to it is the same at every frame. Before any
  // choice, coverage3d's map holds the training views of every frame, so it scores at most
  // what coverage4d scores. Where every candidate and every chosen view share one frame and
  // no Gaussian changes direction bin over the clip, the two are therefore one strategy.
  const Fixture& fx = fixture();
  const PoolFixture p(fx);
  std::vector<ObservedView> two;
  for (const ObservedView& v : p.pool)
    if (v.pose == 2 && (v.frame == 1 || v.frame == 6)) two.push_back(v);
  REQUIRE(two.size() == 2);
  auto solo = [&](const std::string& s, const ObservedView& v) {
    const PoolSelectResult r = select_from_pool(p.in, {v}, 1, small_options(s, 0));
    REQUIRE(r.chosen.size() == 1);
    return r.chosen[0].score;
  };
  for (const ObservedView& v : two) CHECK(solo("coverage3d", v) <= solo("coverage4d", v));
  const PoolSelectResult c4 = select_from_pool(p.in, two, 2, small_options("coverage4d", 0), true);
  const PoolSelectResult c3 = select_from_pool(p.in, two, 2, small_options("coverage3d", 0), true);
  REQUIRE(c4.chosen.size() == 2);
  REQUIRE(c3.chosen.size() == 2);
  const double second4 = c4.chosen[1].score;
  CHECK(second4 == solo("coverage4d", two[c4.chosen[1].candidate]));
  CHECK(second4 > 0);
  // coverage3d's second choice: at most the moving Gaussians (each one cell), far fewer than
  // the Gaussians the camera sees.
  CHECK(c3.chosen[1].score <= double(fx.synth.moving_ids.size()));
  CHECK(c3.chosen[1].score < 0.5 * second4);
}

TEST_CASE("pool selection: fillgs's first choice is the candidate with the largest mean rendered D-hat", "[select][pool]") {
  const Fixture& fx = fixture();
  const PoolFixture p(fx);
  const SelectOptions o = small_options("fillgs", 0);
  const PoolSelectResult r = select_from_pool(p.in, p.pool, 1, o);
  REQUIRE(r.chosen.size() == 1);
  // The same score from the tables directly: D = s / (1 + C) of the two training poses,
  // D-hat = min(1, D / its 99% quantile), rendered at every pool view.
  std::vector<Camera> cams;
  for (const ObservedView& v : p.in.views) cams.push_back(v.camera);
  ObservationOptions oo;
  oo.visibility = o.visibility;
  const ObservationTables t = observation_tables(fx.synth.scene, cams, FrameGrid(kFrames).times(), FrameGrid(kFrames).step(), oo);
  const DeficiencyField field(t, o.deficiency_quantile);
  double best = -1;
  size_t arg = 0;
  for (size_t i = 0; i < p.pool.size(); ++i) {
    Camera c = p.pool[i].camera;
    c.time = FrameGrid(kFrames).time(p.pool[i].frame);
    const std::vector<float> values = field.values(p.pool[i].frame, CandidateScore::Deficiency);
    const double m = mean_value(render_value_map(frame_at(fx.synth.scene, c.time), c, values.data()));
    if (m > best) best = m, arg = i;
  }
  CHECK(r.chosen[0].candidate == arg);
  CHECK(r.chosen[0].score == Approx(best).epsilon(1e-12));
  CHECK(best > 0);
}

TEST_CASE("pool selection: interpolation takes the pool cameras nearest the training chord first, and random is seeded", "[select][pool]") {
  const Fixture& fx = fixture();
  const PoolFixture p(fx);
  // Training poses 0 and 4 lie 90 degrees apart on the ring: the chord between them passes
  // 0.217 R from poses 1 and 3 (22.5 degrees from an end), 0.293 R from pose 2 (the middle),
  // and every other pose is farther (0.390 R from an end for poses 5 and 15).
  const PoolSelectResult r = select_from_pool(p.in, p.pool, 3 * kFrames, small_options("interpolation", 0));
  REQUIRE(r.chosen.size() == size_t(3 * kFrames));
  std::map<uint32_t, int> first, third;
  for (int k = 0; k < 2 * kFrames; ++k) ++first[p.pool[r.chosen[size_t(k)].candidate].pose];
  for (int k = 2 * kFrames; k < 3 * kFrames; ++k) ++third[p.pool[r.chosen[size_t(k)].candidate].pose];
  CHECK(first == std::map<uint32_t, int>{{1, kFrames}, {3, kFrames}});
  CHECK(third == std::map<uint32_t, int>{{2, kFrames}});
  const double R = (fx.synth.train[0].centre() - fx.synth.train[8].centre()).norm() / 2;
  CHECK(-r.chosen[0].score == Approx(R * (std::cos(kPi / 8) + std::sin(kPi / 8) - 1) / std::sqrt(2.0)).epsilon(1e-6));
  // random: the same seed, the same choices; another seed, others.
  SelectOptions o = small_options("random", 0);
  const PoolSelectResult a = select_from_pool(p.in, p.pool, 8, o), b = select_from_pool(p.in, p.pool, 8, o);
  o.seed = 2;
  const PoolSelectResult c = select_from_pool(p.in, p.pool, 8, o);
  auto ids = [](const PoolSelectResult& x) {
    std::vector<size_t> v;
    for (const PoolChoice& q : x.chosen) v.push_back(q.candidate);
    return v;
  };
  CHECK(ids(a) == ids(b));
  CHECK(ids(a) != ids(c));
  // A budget beyond the pool takes the whole pool; a pool view outside the video is refused.
  CHECK(select_from_pool(p.in, p.pool, int(p.pool.size()) + 5, o).chosen.size() == p.pool.size());
  std::vector<ObservedView> bad = p.pool;
  bad[0].frame = kFrames;
  CHECK_THROWS_WITH(select_from_pool(p.in, bad, 1, o), Catch::Contains("outside 0..9"));
}
