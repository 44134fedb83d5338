// Visibility engine: analytic cases, agreement between modes, incremental = from scratch,
// speeds and deficiency, extremes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>

#include "fillgs/visibility/gaussian_tracer.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/visibility/visibility.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "helpers.hpp"
#include "render/frustum.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

const VisibilityMode kModes[] = {VisibilityMode::Frustum, VisibilityMode::Raytraced, VisibilityMode::Exact};

VisibilityOptions mode_options(VisibilityMode mode, int stride = 1) {
  VisibilityOptions o;
  o.mode = mode;
  o.stride = stride;
  return o;
}

bool contains(const std::vector<uint32_t>& ids, uint32_t g) { return std::binary_search(ids.begin(), ids.end(), g); }

size_t intersection_size(const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
  std::vector<uint32_t> both;
  std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both));
  return both.size();
}

/// The 3DGS preprocess culling rule written out from the CUDA source, independently of
/// project_gaussian: in_frustum (p_view.z <= 0.2), computeCov2D with the 1.3 tan clamp and
/// +0.3, det == 0, radius = ceil(3 sqrt(max(λ1, λ2))) with λ from max(0.1, mid² − det),
/// getRect over 16-pixel tiles, and (rect_max − rect_min) area == 0.
bool reference_3dgs_visible(const Vec3f& mean, const Vec3f& scale, const Vec4f& q, const Camera& cam) {
  const double x = mean.x(), y = mean.y(), z = mean.z();
  const Eigen::Vector3d pv = cam.R * Eigen::Vector3d(x, y, z) + cam.t;
  if (pv.z() <= 0.2) return false;
  const double r = q[0], qx = q[1], qy = q[2], qz = q[3];
  const double nq = std::sqrt(r * r + qx * qx + qy * qy + qz * qz);
  const double w = r / nq, a = qx / nq, b = qy / nq, c = qz / nq;
  Eigen::Matrix3d Rq;
  Rq << 1 - 2 * (b * b + c * c), 2 * (a * b - w * c), 2 * (a * c + w * b),  //
      2 * (a * b + w * c), 1 - 2 * (a * a + c * c), 2 * (b * c - w * a),    //
      2 * (a * c - w * b), 2 * (b * c + w * a), 1 - 2 * (a * a + b * b);
  Eigen::Matrix3d S = Eigen::Vector3d(scale.x(), scale.y(), scale.z()).asDiagonal();
  const Eigen::Matrix3d M = Rq * S;
  const Eigen::Matrix3d cov3 = M * M.transpose();
  const double tanx = 0.5 * cam.width / cam.fx, tany = 0.5 * cam.height / cam.fy;
  const double txtz = std::min(1.3 * tanx, std::max(-1.3 * tanx, pv.x() / pv.z()));
  const double tytz = std::min(1.3 * tany, std::max(-1.3 * tany, pv.y() / pv.z()));
  const double tx = txtz * pv.z(), ty = tytz * pv.z();
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  J(0, 0) = cam.fx / pv.z();
  J(0, 2) = -cam.fx * tx / (pv.z() * pv.z());
  J(1, 1) = cam.fy / pv.z();
  J(1, 2) = -cam.fy * ty / (pv.z() * pv.z());
  const Eigen::Matrix3d T = J * cam.R;
  const Eigen::Matrix3d cov = T * cov3 * T.transpose();
  const double c00 = cov(0, 0) + 0.3, c01 = cov(0, 1), c11 = cov(1, 1) + 0.3;
  const double det = c00 * c11 - c01 * c01;
  if (det == 0.0 || !(det > 0)) return false;
  const double mid = 0.5 * (c00 + c11);
  const double l1 = mid + std::sqrt(std::max(0.1, mid * mid - det)), l2 = mid - std::sqrt(std::max(0.1, mid * mid - det));
  const double radius = std::ceil(3.0 * std::sqrt(std::max(l1, l2)));
  const double px = cam.fx * pv.x() / pv.z() + cam.cx - 0.5, py = cam.fy * pv.y() / pv.z() + cam.cy - 0.5;
  const int gx = (cam.width + 15) / 16, gy = (cam.height + 15) / 16;
  auto clampi = [](int v, int hi) { return std::min(hi, std::max(0, v)); };
  const int minx = clampi(int((px - radius) / 16), gx), miny = clampi(int((py - radius) / 16), gy);
  const int maxx = clampi(int((px + radius + 15) / 16), gx), maxy = clampi(int((py + radius + 15) / 16), gy);
  return (maxx - minx) * (maxy - miny) != 0;
}

std::vector<Camera> orbit(const std::pair<Vec3f, Vec3f>& box, int count, int w, int h) {
  const Vec3d centre = ((box.first + box.second) * 0.5f).cast<double>();
  const double radius = 0.9 * (box.second - box.first).cast<double>().norm();
  RingPlacement r;
  r.count = count;
  r.centre = centre;
  r.radius = radius;
  r.elevation = -(0.3 * radius);
  r.up = Vec3d(0, -1, 0);
  r.prefix = "orbit";
  Camera lens;
  lens.set_fov_x(60.0 * kPi / 180.0, w, h);
  return camera_ring(r, lens);
}

}  // namespace

// ---------------------------------------------------------------------------------
// Analytic cases

TEST_CASE("one Gaussian in front of a camera is visible in every mode", "[visibility]") {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0.1f, -0.05f, 3.0f), 0.05f, 2.0f, Vec3f(1, 0, 0));
  const Camera cam = axis_camera(64, 48, 60);
  for (VisibilityMode mode : kModes) {
    VisibilityEngine engine(cloud, mode_options(mode));
    INFO(to_string(mode));
    CHECK(engine.visible_set(cam) == std::vector<uint32_t>{0});
  }
}

TEST_CASE("a Gaussian behind three opaque ones: visible to frustum only", "[visibility]") {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0, 0, 5.0f), 0.05f, 4.0f, Vec3f(1, 0, 0));  // the hidden one
  for (float z : {2.0f, 2.5f, 3.0f}) add_gaussian(cloud, Vec3f(0, 0, z), 1.0f, 10.0f, Vec3f(0, 1, 0));
  const Camera cam = axis_camera(64, 48, 60);
  // Three layers of α = 0.99 leave T = 1e-6 < 1e-4: the ray ends before the hidden one.
  VisibilityEngine frustum(cloud, mode_options(VisibilityMode::Frustum));
  CHECK(contains(frustum.visible_set(cam), 0));
  for (VisibilityMode mode : {VisibilityMode::Raytraced, VisibilityMode::Exact}) {
    INFO(to_string(mode));
    VisibilityEngine engine(cloud, mode_options(mode));
    const auto ids = engine.visible_set(cam);
    CHECK_FALSE(contains(ids, 0));
    CHECK(contains(ids, 1));
    CHECK(contains(ids, 2));
  }
}

TEST_CASE("Gaussians outside the frustum are invisible in every mode", "[visibility]") {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0, 0, -3.0f), 0.05f, 4.0f, Vec3f(1, 0, 0));  // behind the camera
  add_gaussian(cloud, Vec3f(20, 0, 3.0f), 0.05f, 4.0f, Vec3f(1, 0, 0));  // far to the right
  add_gaussian(cloud, Vec3f(0, -9, 2.0f), 0.05f, 4.0f, Vec3f(1, 0, 0));  // far above
  const Camera cam = axis_camera(64, 48, 60);
  for (VisibilityMode mode : kModes) {
    INFO(to_string(mode));
    VisibilityEngine engine(cloud, mode_options(mode));
    CHECK(engine.visible_set(cam).empty());
  }
}

TEST_CASE("transmittance through two known Gaussians equals the closed form", "[visibility][tracer]") {
  FrameGaussians frame;
  const float o1 = 0.5f, o2 = 0.6f, s1 = 0.3f, s2 = 0.2f;
  frame.means = {Vec3f(0, 0, 2), Vec3f(0, 0, 4)};
  frame.scales = {Vec3f::Constant(s1), Vec3f::Constant(s2)};
  frame.rotations = {Vec4f(1, 0, 0, 0), Vec4f(1, 0, 0, 0)};
  frame.opacities = {o1, o2};
  GaussianTracer tracer(frame, {});
  for (float x0 : {0.0f, 0.1f, 0.25f}) {
    INFO("ray offset " << x0);
    std::vector<TracedHit> hits;
    const RayOutcome out = tracer.trace(Vec3f(x0, 0, 0), Vec3f(0, 0, 1), TraceLayers::All, hits);
    const double a1 = o1 * std::exp(-0.5 * x0 * x0 / (s1 * s1)), a2 = o2 * std::exp(-0.5 * x0 * x0 / (s2 * s2));
    REQUIRE(hits.size() == 2);
    CHECK(hits[0].id == 0);
    CHECK(hits[0].distance == Approx(2.0).epsilon(1e-5));
    CHECK(hits[0].weight == Approx(a1).epsilon(1e-5));
    CHECK(hits[1].id == 1);
    CHECK(hits[1].weight == Approx(a2 * (1 - a1)).epsilon(1e-5));
    CHECK(out.transmittance == Approx((1 - a1) * (1 - a2)).epsilon(1e-5));
    CHECK(std::isinf(out.end_key));
  }
}

TEST_CASE("a rotated anisotropic Gaussian is met at its maximum response along the ray", "[visibility][tracer]") {
  FrameGaussians frame;
  const Vec4f q = normalize_quat(Vec4f(0.9f, 0.3f, -0.2f, 0.25f));
  const Vec3f scale(0.4f, 0.1f, 0.2f), mean(0.2f, -0.1f, 3.0f);
  frame.means = {mean};
  frame.scales = {scale};
  frame.rotations = {q};
  frame.opacities = {0.8f};
  GaussianTracer tracer(frame, {});
  const Eigen::Matrix3d R = quat_to_matrix<double>(q.cast<double>());
  const Eigen::Matrix3d cov = R * scale.cast<double>().array().square().matrix().asDiagonal() * R.transpose();
  const Eigen::Matrix3d P = cov.inverse();
  const Eigen::Vector3d o(0.05, 0.02, 0.0);
  for (const Eigen::Vector3d& d : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.05, -0.03, 1), Eigen::Vector3d(0.1, 0.02, 1)}) {
    // m²(t) = (o + t d − μ)ᵀ P (o + t d − μ) is a parabola in t: minimum at t* = −dᵀP(o−μ) / dᵀPd.
    const Eigen::Vector3d rel = o - mean.cast<double>();
    const double t_star = -d.dot(P * rel) / d.dot(P * d);
    const Eigen::Vector3d at = rel + t_star * d;
    const double alpha = 0.8 * std::exp(-0.5 * at.dot(P * at));
    std::vector<TracedHit> hits;
    tracer.trace(o.cast<float>(), d.cast<float>(), TraceLayers::All, hits);
    if (alpha < kMinAlpha) {
      CHECK(hits.empty());
      continue;
    }
    REQUIRE(hits.size() == 1);
    CHECK(hits[0].distance == Approx(t_star).epsilon(1e-4));
    CHECK(hits[0].alpha == Approx(alpha).epsilon(1e-4));
  }
}

TEST_CASE("more hits on a ray than a pass gathers come out in depth order across k-buffer passes", "[visibility][tracer]") {
  FrameGaussians frame;
  // 2·kTraceBatch + 20 faint Gaussians on the axis, in shuffled id order, so three passes are needed.
  const int n = 2 * kTraceBatch + 20;
  const float opacity = 0.03f;  // T stays above T_min: 0.97^149 ≈ 0.011
  for (int i = 0; i < n; ++i) {
    const int slot = (i * 17) % n;
    frame.means.push_back(Vec3f(0, 0, 1.0f + 0.05f * slot));
    frame.scales.push_back(Vec3f::Constant(0.01f));
    frame.rotations.push_back(Vec4f(1, 0, 0, 0));
    frame.opacities.push_back(opacity);
  }
  // Two Gaussians at exactly the same depth: the tie is broken by id, each taken once.
  frame.means.push_back(Vec3f(0, 0, 1.0f + 0.05f * 16));
  frame.scales.push_back(Vec3f::Constant(0.01f));
  frame.rotations.push_back(Vec4f(1, 0, 0, 0));
  frame.opacities.push_back(opacity);
  GaussianTracer tracer(frame, {});
  std::vector<TracedHit> hits;
  const RayOutcome out = tracer.trace(Vec3f(0, 0, 0), Vec3f(0, 0, 1), TraceLayers::All, hits);
  REQUIRE(hits.size() == size_t(n + 1));
  CHECK(out.passes == 3);
  CHECK(std::isinf(out.end_key));
  std::vector<uint32_t> ids;
  double T = 1;
  for (size_t k = 0; k < hits.size(); ++k) {
    if (k > 0) CHECK((hits[k - 1].distance < hits[k].distance || (hits[k - 1].distance == hits[k].distance && hits[k - 1].id < hits[k].id)));
    CHECK(hits[k].weight == Approx(opacity * T).epsilon(1e-4));
    T *= 1 - opacity;
    ids.push_back(hits[k].id);
  }
  std::sort(ids.begin(), ids.end());
  CHECK(std::unique(ids.begin(), ids.end()) == ids.end());
  CHECK(out.transmittance == Approx(T).epsilon(1e-3));
}

TEST_CASE("a ray ends in its first pass at the hit that would take T under T_min", "[visibility][tracer]") {
  // 40 Gaussians of α = 0.5 on the axis (shuffled ids), 0.1 apart from z = 1: 0.5^13 ≥ 1e-4 >
  // 0.5^14, so 13 are blended and the 14th (z = 2.3) ends the ray, whatever lies behind.
  FrameGaussians frame;
  const int n = 40;
  for (int i = 0; i < n; ++i) {
    frame.means.push_back(Vec3f(0, 0, 1.0f + 0.1f * float((i * 17) % n)));
    frame.scales.push_back(Vec3f::Constant(0.01f));
    frame.rotations.push_back(Vec4f(1, 0, 0, 0));
    frame.opacities.push_back(0.5f);
  }
  GaussianTracer tracer(frame, {});
  std::vector<TracedHit> hits;
  const RayOutcome out = tracer.trace(Vec3f(0, 0, 0), Vec3f(0, 0, 1), TraceLayers::All, hits);
  REQUIRE(hits.size() == 13);
  CHECK(out.passes == 1);
  CHECK(out.end_key == Approx(2.3).epsilon(1e-5));
  CHECK(out.transmittance == Approx(std::pow(0.5, 13)).epsilon(1e-4));
  for (size_t k = 0; k < hits.size(); ++k) CHECK(hits[k].distance == Approx(1.0 + 0.1 * double(k)).epsilon(1e-5));
}

TEST_CASE("large proxies in a tier of their own: every ray's hits equal a brute-force blend", "[visibility][tracer]") {
  // 1,500 small faint Gaussians in a slab and 40 large ones scattered in a deeper volume (a
  // third of each moving): rays collect more hits than the k-buffer holds, so depth-ordered
  // rays prune by the small tier's size and the large tier is traversed apart.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  FrameGaussians frame;
  std::vector<uint32_t> dynamic;
  for (int g = 0; g < 1540; ++g) {
    const bool large = g >= 1500;
    frame.means.push_back(large ? Vec3f(5.0f * u(rng), 4.0f * u(rng), 9.0f + 5.0f * u(rng))
                                : Vec3f(2.0f * u(rng), 1.5f * u(rng), 6.0f + 1.0f * u(rng)));
    frame.scales.push_back(large ? Vec3f(0.8f, 0.5f, 0.9f) : Vec3f(0.12f + 0.05f * u(rng), 0.1f, 0.08f));
    frame.rotations.push_back(normalize_quat(Vec4f(1.0f, 0.3f * u(rng), 0.3f * u(rng), 0.3f * u(rng))));
    frame.opacities.push_back(large ? 0.3f : 0.12f + 0.08f * u(rng));
    if (g % 3 == 0) dynamic.push_back(uint32_t(g));
  }
  const Camera cam = axis_camera(40, 30, 30);
  RasterMatch match;
  match.variance_per_depth2 = float(double(kDilation) / (cam.fx * cam.fy));
  for (bool matched : {true, false}) {
    TracerOptions to;
    to.dilation_padding = matched ? float(std::sqrt(double(kDilation)) / 30.0 * 8.0) : 0.0f;
    GaussianTracer tracer(frame, dynamic, to);
    REQUIRE(std::isfinite(tracer.large_proxy_threshold()));
    CHECK(tracer.large_proxy_count() >= 40);
    CHECK(tracer.large_proxy_count() < 100);
    size_t compared = 0;
    for (int py = 0; py < cam.height; py += 2)
      for (int px = 0; px < cam.width; px += 2) {
        const Eigen::Vector3d d((px + 0.5 - cam.cx) / cam.fx, (py + 0.5 - cam.cy) / cam.fy, 1.0);
        // Reference: every Gaussian's maximum response along the ray, sorted by (key, id).
        struct Ref { double key; uint32_t id; double alpha; };
        std::vector<Ref> all;
        for (uint32_t g = 0; g < frame.size(); ++g) {
          const Eigen::Matrix3d R = quat_to_matrix<double>(frame.rotations[g].cast<double>());
          const Eigen::Vector3d mu = frame.means[g].cast<double>();
          Eigen::Matrix3d cov = R * frame.scales[g].cast<double>().array().square().matrix().asDiagonal() * R.transpose();
          const double z = mu.z();
          if (matched) {
            if (!(z > double(kNearPlane))) continue;
            cov += double(match.variance_per_depth2) * z * z * Eigen::Matrix3d::Identity();
          }
          const Eigen::Matrix3d P = cov.inverse();
          const double t = std::max(0.0, d.dot(P * mu) / d.dot(P * d));
          const Eigen::Vector3d at = t * d - mu;
          const double m2 = at.dot(P * at);
          const double k2 = 2.0 * std::log(double(frame.opacities[g]) / double(kMinAlpha));
          if (!(m2 <= k2)) continue;
          const double alpha = std::min(double(kMaxAlpha), double(frame.opacities[g]) * std::exp(-0.5 * m2));
          if (alpha < kMinAlpha) continue;
          all.push_back({matched ? z : t, g, alpha});
        }
        std::sort(all.begin(), all.end(), [](const Ref& a, const Ref& b) { return a.key < b.key || (a.key == b.key && a.id < b.id); });
        std::vector<TracedHit> hits;
        tracer.trace(Vec3f::Zero(), d.cast<float>(), TraceLayers::All, hits, matched ? &match : nullptr);
        double T = 1;
        size_t k = 0;
        for (; k < all.size(); ++k) {
          if (T * (1 - all[k].alpha) < kMinTransmittance) break;
          INFO("pixel " << px << "," << py << " hit " << k << (matched ? " matched" : " plain"));
          REQUIRE(k < hits.size());
          CHECK(hits[k].id == all[k].id);
          CHECK(hits[k].weight == Approx(all[k].alpha * T).epsilon(1e-3).margin(1e-6));
          T *= 1 - all[k].alpha;
        }
        CHECK(hits.size() == k);
        compared += k;
      }
    CHECK(compared > 1000);
  }
}

TEST_CASE("a large proxy met far behind its mean's depth is found through its own tier's slack", "[visibility][tracer]") {
  // A thin Gaussian 13 units long in depth (σ = 0.01, 0.01, 2) with its mean at depth 5, and
  // four small opaque ones on a slanted ray at depths 5.2–5.5. The ray (x = 0.04 z) reaches
  // the long Gaussian's box only beyond depth 6.7, where it crosses it (α ≈ 0.45 near depth
  // 7.5), but under a RasterMatch the hit's key is the mean's depth, 5: it is blended first,
  // then the first opaque one, and the second ends the ray at 5.3. A traversal that stops
  // beyond that end by the small proxies' slack (0.03) instead of the long one's would
  // never reach the long Gaussian's box.
  FrameGaussians frame;
  auto add = [&](const Vec3f& mean, const Vec3f& scale, float opacity) {
    frame.means.push_back(mean);
    frame.scales.push_back(scale);
    frame.rotations.push_back(Vec4f(1, 0, 0, 0));
    frame.opacities.push_back(opacity);
  };
  add(Vec3f(0.3f, 0.0f, 5.0f), Vec3f(0.01f, 0.01f, 2.0f), 0.99f);
  for (float z : {5.2f, 5.3f, 5.4f, 5.5f}) add(Vec3f(0.04f * z, 0.0f, z), Vec3f::Constant(0.01f), 0.99f);
  // 16 more long ones far off the ray, so that the large tier's BVH has inner boxes to cull by.
  for (int i = 0; i < 16; ++i) add(Vec3f(float(i % 2 ? 2 + i : -2 - i), float(i % 4) - 1.5f, 5.0f), Vec3f(0.01f, 0.01f, 2.0f), 0.99f);
  RasterMatch match;  // axis +z, no dilation
  GaussianTracer tracer(frame, {});
  REQUIRE(tracer.large_proxy_count() == 17);
  std::vector<TracedHit> hits;
  const RayOutcome out = tracer.trace(Vec3f::Zero(), Vec3f(0.04f, 0.0f, 1.0f), TraceLayers::All, hits, &match);
  REQUIRE(hits.size() == 2);
  CHECK(hits[0].id == 0);
  CHECK(hits[0].distance == Approx(7.5 * std::sqrt(1.0 + 0.04 * 0.04)).epsilon(0.05));
  CHECK(hits[1].id == 1);
  CHECK(out.end_key == Approx(5.3).epsilon(1e-5));
}

TEST_CASE("the dynamic layer traced over a ray's kept static hits blends exactly as both layers traced together",
          "[visibility][tracer]") {
  // 5,000 faint Gaussians in a thin slab (about 190 on a ray: two k-buffer passes), and on
  // its x > 0.3 side 150 opaque ones among them (rays there end in their first pass, on a
  // static or a moving hit); every third Gaussian moving.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  FrameGaussians frame;
  std::vector<uint32_t> dynamic;
  for (int g = 0; g < 5150; ++g) {
    const bool opaque = g >= 5000;
    frame.means.push_back(Vec3f(opaque ? 0.65f + 0.35f * u(rng) : u(rng), 0.75f * u(rng), 6.0f + 0.5f * u(rng)));
    frame.scales.push_back(opaque ? Vec3f(0.1f, 0.08f, 0.05f) : Vec3f(0.1f + 0.04f * u(rng), 0.09f, 0.06f));
    frame.rotations.push_back(normalize_quat(Vec4f(1.0f, 0.3f * u(rng), 0.3f * u(rng), 0.3f * u(rng))));
    frame.opacities.push_back(opaque ? 0.95f : 0.03f + 0.01f * u(rng));
    if (g % 3 == 0) dynamic.push_back(uint32_t(g));
  }
  const Camera cam = axis_camera(40, 30, 200);  // sees x, y within ±0.6, ±0.45 at z = 6
  RasterMatch match;
  match.variance_per_depth2 = float(double(kDilation) / (cam.fx * cam.fy));
  for (bool matched : {true, false}) {
    INFO((matched ? "matched" : "plain"));
    TracerOptions to;
    to.dilation_padding = matched ? float(std::sqrt(double(kDilation)) / 200.0 * 8.0) : 0.0f;
    GaussianTracer tracer(frame, dynamic, to);
    size_t multi_pass = 0, ended_static = 0, ended_dynamic = 0, compared = 0, entered = 0;
    std::vector<TracedHit> both, statics, over;
    std::vector<KeyedHit> keyed;
    std::vector<char> moving(frame.size(), 0);
    for (uint32_t g : dynamic) moving[g] = 1;
    for (int py = 0; py < cam.height; ++py)
      for (int px = 0; px < cam.width; ++px) {
        INFO("pixel " << px << "," << py);
        const Vec3f d(float((px + 0.5 - cam.cx) / cam.fx), float((py + 0.5 - cam.cy) / cam.fy), 1.0f);
        const RasterMatch* m = matched ? &match : nullptr;
        both.clear(), statics.clear(), over.clear(), keyed.clear();
        const RayOutcome a = tracer.trace(Vec3f::Zero(), d, TraceLayers::All, both, m);
        const RayOutcome s = tracer.trace(Vec3f::Zero(), d, TraceLayers::StaticOnly, statics, m, &keyed);
        // The kept hits: every blended static hit, then the one that ended the ray (if any).
        REQUIRE(keyed.size() == statics.size() + (std::isinf(s.end_key) ? 0 : 1));
        for (size_t k = 0; k < statics.size(); ++k) CHECK((keyed[k].id == statics[k].id && keyed[k].alpha == statics[k].alpha));
        if (!std::isinf(s.end_key)) CHECK(keyed.back().key == s.end_key);
        const RayOutcome o = tracer.trace_over(Vec3f::Zero(), d, keyed.data(), keyed.size(), over, m);
        REQUIRE(over.size() == both.size());
        for (size_t k = 0; k < both.size(); ++k) {
          CHECK(over[k].id == both[k].id);
          CHECK(over[k].distance == both[k].distance);
          CHECK(over[k].alpha == both[k].alpha);
          CHECK(over[k].weight == both[k].weight);
        }
        CHECK(o.transmittance == a.transmittance);
        CHECK((o.end_key == a.end_key || (std::isinf(o.end_key) && std::isinf(a.end_key))));
        // The trace over the static hits is its own probe: when no dynamic proxy entered its
        // k-buffer the answer is the static one; a dynamic hit in the answer, or a ray that
        // meets a dynamic proxy before its static end, has entries.
        bool dynamic_hit = false;
        for (const TracedHit& h : both) dynamic_hit = dynamic_hit || moving[h.id];
        if (dynamic_hit) CHECK(o.traversal_entries > 0);
        if (o.traversal_entries == 0) CHECK(both.size() == statics.size());
        const bool meets = tracer.meets_dynamic(Vec3f::Zero(), d, s.end_key, m);
        CHECK(meets == (o.traversal_entries > 0));
        CHECK(s.traversal_entries >= keyed.size());  // without seeds every hit entered through the traversal
        entered += o.traversal_entries > 0;
        compared += both.size();
        multi_pass += a.passes > 1;
        if (!std::isinf(a.end_key)) {
          // Which layer the hit that ended the ray came from (the last keyed hit of All).
          std::vector<KeyedHit> all_keyed;
          both.clear();
          tracer.trace(Vec3f::Zero(), d, TraceLayers::All, both, m, &all_keyed);
          REQUIRE(all_keyed.size() == both.size() + 1);
          CHECK(all_keyed.back().key == a.end_key);
          ended_dynamic += moving[all_keyed.back().id];
          ended_static += !moving[all_keyed.back().id];
        }
      }
    CHECK(compared > 100000);
    CHECK(multi_pass > 100);
    CHECK(ended_static > 20);
    CHECK(ended_dynamic > 20);
    CHECK(entered > 1000);

    // Only the slab's left part moving (faint Gaussians at x < -0.5, reaching about 0.2
    // beyond): rays on the right meet no moving proxy, so nothing enters the trace over
    // their static hits and its answer is the static one, hit for hit.
    std::vector<uint32_t> left;
    for (uint32_t g = 0; g < 5000; ++g)
      if (frame.means[g].x() < -0.5f) left.push_back(g);
    GaussianTracer partly(frame, left, to);
    size_t untouched = 0, reached = 0;
    for (int py = 0; py < cam.height; ++py)
      for (int px = 0; px < cam.width; ++px) {
        INFO("pixel " << px << "," << py << ", left part moving");
        const Vec3f d(float((px + 0.5 - cam.cx) / cam.fx), float((py + 0.5 - cam.cy) / cam.fy), 1.0f);
        const RasterMatch* m = matched ? &match : nullptr;
        statics.clear(), over.clear(), keyed.clear();
        const RayOutcome s = partly.trace(Vec3f::Zero(), d, TraceLayers::StaticOnly, statics, m, &keyed);
        const RayOutcome o = partly.trace_over(Vec3f::Zero(), d, keyed.data(), keyed.size(), over, m);
        CHECK(partly.meets_dynamic(Vec3f::Zero(), d, s.end_key, m) == (o.traversal_entries > 0));
        if (o.traversal_entries == 0) {
          REQUIRE(over.size() == statics.size());
          for (size_t k = 0; k < over.size(); ++k) CHECK((over[k].id == statics[k].id && over[k].weight == statics[k].weight));
          ++untouched;
        } else {
          ++reached;
        }
      }
    CHECK(untouched > 300);
    CHECK(reached > 100);
  }
}

// ---------------------------------------------------------------------------------
// Agreement between modes

TEST_CASE("raytraced at stride 1 agrees with exact on the synthetic scene", "[visibility][synth]") {
  const SynthScene s = small_synth(9, 160, 120);
  VisibilityEngine rt(s.scene, mode_options(VisibilityMode::Raytraced, 1));
  VisibilityEngine ex(s.scene, mode_options(VisibilityMode::Exact));
  double worst_precision = 1, worst_recall = 1;
  for (double t : {0.0, 0.5}) {
    rt.set_time(t);
    ex.set_time(t);
    for (const Camera& cam : s.train) {
      const auto r = rt.visible_set(cam), e = ex.visible_set(cam);
      REQUIRE(!e.empty());
      const double both = double(intersection_size(r, e));
      const double precision = both / double(r.size()), recall = both / double(e.size());
      INFO(cam.name << " t=" << t << " raytraced " << r.size() << " exact " << e.size() << " precision " << precision
                    << " recall " << recall);
      CHECK(precision >= 0.99);
      CHECK(recall >= 0.99);
      worst_precision = std::min(worst_precision, precision);
      worst_recall = std::min(worst_recall, recall);
    }
  }
  WARN("raytraced stride 1 vs exact, worst view: precision " << worst_precision << ", recall " << worst_recall);
}

TEST_CASE("frustum agrees exactly with the 3DGS rule on the real scenes", "[visibility][shared]") {
  const std::string data = shared_data();
  for (const char* name : {"scenes/guitar.ply", "scenes/donut.ply", "scenes/playbot_3k.ply"}) {
    const GaussianCloud cloud = read_scene(data + "/" + name);
    const auto cams = orbit(bounding_box(cloud), 6, 400, 300);
    VisibilityEngine engine(cloud, mode_options(VisibilityMode::Frustum));
    const FrameGaussians& frame = engine.frame();
    for (const Camera& cam : cams) {
      std::vector<uint32_t> expected;
      for (size_t g = 0; g < cloud.size(); ++g)
        if (reference_3dgs_visible(frame.means[g], frame.scales[g], cloud.rotations[g], cam)) expected.push_back(uint32_t(g));
      const auto got = engine.visible_set(cam);
      INFO(name << " " << cam.name << ": engine " << got.size() << ", reference " << expected.size());
      CHECK(!expected.empty());
      CHECK(got == expected);
    }
  }
}

TEST_CASE("the vector frustum rule decides as the scalar 3DGS preprocess on every Gaussian, at each instruction set",
          "[visibility][extremes]") {
  std::vector<Camera> cams;
  const GaussianCloud c = preprocess_extremes(&cams);
  VisibilityEngine engine(c, mode_options(VisibilityMode::Frustum));
  const FrameGaussians& frame = engine.frame();
  std::vector<std::vector<uint32_t>> expected;
  for (const Camera& cam : cams) {
    std::vector<uint32_t> e;
    ProjectedGaussian p;
    for (size_t g = 0; g < c.size(); ++g)
      if (project_gaussian(frame.means[g], frame.scales[g], frame.rotations[g], cam, &p)) e.push_back(uint32_t(g));
    CHECK(e.size() > 1000);             // kept and
    CHECK(c.size() - e.size() > 1000);  // dropped, both many
    expected.push_back(e);
  }
  // Every camera over one reading of the rows (as observe's frames run the rule), over a
  // listed subset in two uneven blocks, gives each camera's own answer.
  std::vector<internal::FrustumCamera> fc;
  for (const Camera& cam : cams) fc.emplace_back(cam);
  std::vector<uint32_t> odd;
  for (uint32_t g = 1; g < c.size(); g += 2) odd.push_back(g);
  for_each_instruction_set([&](const char* set) {
    for (size_t k = 0; k < cams.size(); ++k) {
      INFO(set << " (" << kernel_instruction_set() << "), camera " << k);
      CHECK(engine.visible_set(cams[k]) == expected[k]);
    }
    std::vector<std::vector<uint32_t>> all(cams.size());
    const size_t split = odd.size() / 3 + 5;
    for (const auto& [b, e] : {std::pair<size_t, size_t>{0, split}, {split, odd.size()}})
      internal::frustum_keep(fc.data(), fc.size(), frame.means.data(), frame.scales.data(), frame.rotations.data(), odd.data(), b, e, all.data());
    for (size_t k = 0; k < cams.size(); ++k) {
      std::vector<uint32_t> want;
      for (uint32_t g : expected[k])
        if (g % 2 == 1) want.push_back(g);
      INFO(set << ", every camera at once, camera " << k);
      CHECK(!want.empty());
      CHECK(all[k] == want);
    }
  });
}

// ---------------------------------------------------------------------------------
// Tables over time

TEST_CASE("incremental time-stepping gives the counts of re-tracing every frame", "[visibility][synth]") {
  const SynthScene s = small_synth(7, 160, 120);
  const auto times = FrameGrid(7).times();
  for (VisibilityMode mode : {VisibilityMode::Frustum, VisibilityMode::Raytraced}) {
    INFO(to_string(mode));
    ObservationOptions inc, full, uncached, capped, lazy, first;
    inc.visibility = full.visibility = mode_options(mode, 4);
    full.incremental = false;
    uncached = capped = lazy = first = inc;
    uncached.static_hit_cache_bytes = 0;
    lazy.keep_at_static_answers = false;
    first.sweep_static_answers = false;
    ObservationSummary si, sf, su, sc, sl, s1;
    // The rig as per-frame cameras with times (as transforms_train.json has it).
    const auto cams = cameras_over_time(s.train, 7);
    const ObservationTables a = observation_tables(s.scene, cams, times, 1.0 / 6, inc, &si);
    const ObservationTables b = observation_tables(s.scene, cams, times, 1.0 / 6, full, &sf);
    const ObservationTables c = observation_tables(s.scene, cams, times, 1.0 / 6, uncached, &su);
    // A budget for about half the hits the unbounded run keeps: some rays kept, the rest
    // traced through both layers.
    capped.static_hit_cache_bytes = size_t(si.cached_static_hits) * sizeof(KeyedHit) / 2;
    const ObservationTables d = observation_tables(s.scene, cams, times, 1.0 / 6, capped, &sc);
    const ObservationTables e = observation_tables(s.scene, cams, times, 1.0 / 6, lazy, &sl);
    const ObservationTables g = observation_tables(s.scene, cams, times, 1.0 / 6, first, &s1);
    CHECK(g.counts == b.counts);
    CHECK(g.visible_per_view == b.visible_per_view);
    CHECK(e.counts == b.counts);
    CHECK(e.visible_per_view == b.visible_per_view);
    CHECK(a.counts == b.counts);
    CHECK(a.dynamic_deficiency == b.dynamic_deficiency);
    CHECK(a.visible_per_view == b.visible_per_view);
    CHECK(c.counts == b.counts);
    CHECK(c.visible_per_view == b.visible_per_view);
    CHECK(d.counts == b.counts);
    CHECK(d.visible_per_view == b.visible_per_view);
    CHECK(su.cached_static_rays == 0);
    CHECK(su.retraced_rays == si.retraced_rays);
    if (mode == VisibilityMode::Raytraced) {
      // Static hits are kept once per ray a moving Gaussian reaches, then reused: those in the
      // footprints of the dynamic proxies swept over the run as the static answers trace
      // them (with the first frame's footprints only: fewer), the rest when first reached.
      CHECK(si.cached_static_rays > 0);
      CHECK(s1.cached_at_static_answers > 0);
      CHECK(s1.cached_at_static_answers < s1.cached_static_rays);
      CHECK(si.cached_at_static_answers > s1.cached_at_static_answers);
      CHECK(si.cached_static_rays - si.cached_at_static_answers < s1.cached_static_rays - s1.cached_at_static_answers);
      CHECK(si.retraced_rays == s1.retraced_rays);
      CHECK(su.cached_at_static_answers == 0);
      CHECK(sl.cached_at_static_answers == 0);
      CHECK(sl.cached_static_rays > 0);
      CHECK(si.cached_static_rays < si.retraced_rays);
      CHECK(sc.cached_static_hits * sizeof(KeyedHit) <= capped.static_hit_cache_bytes);
      CHECK(sc.cached_static_rays > 0);
      CHECK(sc.cached_static_rays < si.cached_static_rays);
    }
    CHECK(si.camera_poses == 16);
    CHECK(si.views == 16 * 7);
    if (mode == VisibilityMode::Raytraced) {
      // Incremental: static rays once per pose, then only rays that meet the chair.
      CHECK(si.retraced_rays > 0);
      CHECK(si.counters.rays < sf.counters.rays / 3);
    }
    // The shelf hides the chair from cam00, cam01, cam14, cam15 at every frame (synth
    // test): occlusion-aware counts stay at most 12; the frustum rule counts all 16.
    uint16_t most = 0;
    for (int f = 0; f < 7; ++f)
      for (uint32_t g : s.moving_ids) most = std::max(most, a.counts[size_t(f) * a.gaussians + g]);
    if (mode == VisibilityMode::Raytraced) CHECK(most <= 12);
    else CHECK(most == 16);
  }
}

namespace {

/// A static opaque wall at z = 6 (x, y in [-1, 1]) and three moving Gaussians on per-frame
/// keys: a small one crossing in front of the wall, one crossing behind it, and a large one
/// that passes through the plane of the camera at the origin.
GaussianCloud wall_and_movers(int frames) {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0, 0, 4), 0.1f, 3.0f, Vec3f(1, 0, 0));
  add_gaussian(cloud, Vec3f(0, 0, 8), 0.1f, 3.0f, Vec3f(0, 1, 0));
  add_gaussian(cloud, Vec3f(0, 0, 2), 0.6f, 3.0f, Vec3f(0, 0, 1));
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j) add_gaussian(cloud, Vec3f(0.25f * float(i), 0.25f * float(j), 6.0f), 0.2f, 5.0f, Vec3f(0.5f, 0.5f, 0.5f));
  cloud.motion = MotionModel::Keyframed;
  cloud.dynamic_ids = {0, 1, 2};
  cloud.keyframed = per_frame_tracks(3, frames);
  cloud.keyframed.position_interp = KeyInterp::Linear;
  const size_t K = size_t(frames);
  for (size_t f = 0; f < K; ++f) {
    const float t = float(f) / float(K - 1);
    const Vec3f at[3] = {{-3.0f + 6.0f * t, 0.1f, 4.0f}, {-2.5f + 5.0f * t, -0.2f, 8.0f}, {0.4f, 0.0f, 2.0f - 3.5f * t}};
    for (size_t j = 0; j < 3; ++j) {
      std::copy_n(at[j].data(), 3, &cloud.keyframed.positions[(j * K + f) * 3]);
      cloud.keyframed.rotations[(j * K + f) * 4] = 1.0f;
    }
  }
  return cloud;
}

/// The rays an incremental run must re-trace, counted independently: every ray of every
/// view and frame whose static answer (traced through the static layer alone) ends after a
/// point where a moving proxy reaches α_min, asked of a tracer with generous bound padding.
/// `rays` gets the number of rays of all views and frames.
uint64_t reached_rays(const GaussianCloud& cloud, const std::vector<Camera>& cams, const std::vector<double>& times, int stride,
                      bool dilate, uint64_t& rays) {
  FrameSampler ev(cloud);
  TracerOptions to;
  to.dilation_padding = dilate ? float(std::sqrt(double(kDilation)) / 60.0 * 20.0) : 0.0f;
  GaussianTracer tracer(ev.at(0.0), cloud.dynamic_ids, to);
  uint64_t expected = 0;
  rays = 0;
  std::vector<TracedHit> hits;
  for (double t : times) {
    tracer.refit_dynamic(ev.at(t));
    for (const Camera& cam : cams) {
      RasterMatch match;
      for (int k = 0; k < 3; ++k) match.axis[k] = float(cam.R(2, k));
      match.variance_per_depth2 = float(double(kDilation) / (cam.fx * cam.fy));
      const int offset = stride / 2;
      for (int py = offset; py < cam.height; py += stride)
        for (int px = offset; px < cam.width; px += stride) {
          const Vec3d d((px + 0.5 - cam.cx) / cam.fx, (py + 0.5 - cam.cy) / cam.fy, 1.0);
          const Vec3f dir = (cam.R.transpose() * d).cast<float>(), eye = cam.centre().cast<float>();
          hits.clear();
          const RayOutcome o = tracer.trace(eye, dir, TraceLayers::StaticOnly, hits, dilate ? &match : nullptr);
          expected += tracer.meets_dynamic(eye, dir, o.end_key, dilate ? &match : nullptr);
          ++rays;
        }
    }
  }
  return expected;
}

/// The wall of wall_and_movers and a swarm of 4×4×4 small moving Gaussians packed closer
/// than their size, crossing in front of it: neighbours whose union the footprint marking
/// projects once (mark_dynamic_footprints) instead of box by box.
GaussianCloud wall_and_swarm(int frames) {
  GaussianCloud cloud;
  const int side = 4, M = side * side * side;
  for (int k = 0; k < M; ++k)
    add_gaussian(cloud, Vec3f(0, 0, 4), 0.04f, 3.0f, Vec3f(float(k % side) / side, 0.5f, 0.2f));
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j) add_gaussian(cloud, Vec3f(0.25f * float(i), 0.25f * float(j), 6.0f), 0.2f, 5.0f, Vec3f(0.5f, 0.5f, 0.5f));
  cloud.motion = MotionModel::Keyframed;
  for (int k = 0; k < M; ++k) cloud.dynamic_ids.push_back(uint32_t(k));
  cloud.keyframed = per_frame_tracks(size_t(M), frames);
  cloud.keyframed.position_interp = KeyInterp::Linear;
  const size_t K = size_t(frames);
  for (size_t f = 0; f < K; ++f) {
    const float t = float(f) / float(K - 1);
    for (int k = 0; k < M; ++k) {
      const Vec3f at(-2.0f + 4.0f * t + 0.05f * float(k % side), -0.3f + 0.05f * float(k / side % side) + 0.2f * t,
                     4.0f + 0.05f * float(k / (side * side)));
      std::copy_n(at.data(), 3, &cloud.keyframed.positions[(size_t(k) * K + f) * 3]);
      cloud.keyframed.rotations[(size_t(k) * K + f) * 4] = 1.0f;
    }
  }
  return cloud;
}

/// Incremental against from-scratch tables of `cloud` over F frames, seen by a front and a
/// side camera, dilated or not, at each of `strides`: equal counts, only footprint rays
/// probed, and exactly the rays reached_rays counts re-traced. `more` checks a run's tables
/// and summary further.
template <typename More>
void check_retraced_rays(const GaussianCloud& cloud, int F, std::initializer_list<int> strides, More more) {
  const auto times = FrameGrid(F).times();
  Camera front = axis_camera(64, 48, 60), side = axis_camera(64, 48, 60);
  side.look_at(Vec3d(2.5, 0.3, -1.0), Vec3d(0, 0, 5), Vec3d(0, -1, 0));
  const std::vector<Camera> cams = {front, side};
  for (bool dilate : {true, false})
    for (int stride : strides) {
      INFO("dilate " << dilate << ", stride " << stride);
      ObservationOptions inc, full;
      inc.visibility = full.visibility = mode_options(VisibilityMode::Raytraced, stride);
      inc.visibility.dilate = full.visibility.dilate = dilate;
      full.incremental = false;
      ObservationSummary si;
      const ObservationTables a = observation_tables(cloud, cams, times, 1.0 / (F - 1), inc, &si);
      const ObservationTables b = observation_tables(cloud, cams, times, 1.0 / (F - 1), full);
      CHECK(a.counts == b.counts);
      CHECK(a.visible_per_view == b.visible_per_view);
      CHECK(si.counters.probes == si.footprint_rays);
      CHECK(si.retraced_rays <= si.footprint_rays);
      uint64_t rays = 0;
      const uint64_t expected = reached_rays(cloud, cams, times, stride, dilate, rays);
      CHECK(si.incremental_rays == rays);
      CHECK(si.retraced_rays == expected);
      CHECK(expected > 0);
      more(a, si);
    }
}

}  // namespace

TEST_CASE("incremental rays: only dynamic footprints are probed, and exactly the rays a moving Gaussian reaches are re-traced",
          "[visibility][motion]") {
  const int F = 9;
  check_retraced_rays(wall_and_movers(F), F, {1, 3}, [&](const ObservationTables& a, const ObservationSummary& si) {
    // The wall hides the far mover from the front camera in the middle frame, not at the ends.
    CHECK(a.counts[size_t(F / 2) * a.gaussians + 1] < a.counts[1]);
    CHECK(si.footprint_rays < si.incremental_rays);
  });
}

TEST_CASE("incremental rays: a swarm of moving neighbours marked through their unions still gets exactly the rays it reaches re-traced",
          "[visibility][motion]") {
  check_retraced_rays(wall_and_swarm(5), 5, {1, 2}, [](const ObservationTables&, const ObservationSummary& si) {
    CHECK(si.footprint_rays < si.incremental_rays / 2);
  });
}

TEST_CASE("counts equal the sum of per-view visible sets", "[visibility][synth]") {
  const SynthScene s = small_synth(5, 160, 120);
  const auto times = FrameGrid(5).times();
  ObservationOptions o;
  o.visibility = mode_options(VisibilityMode::Raytraced, 6);
  const ObservationTables tables = observation_tables(s.scene, s.train, times, 0.25, o);
  VisibilityEngine engine(s.scene, o.visibility);
  for (int f : {0, 2}) {
    engine.set_time(times[size_t(f)]);
    std::vector<uint16_t> expected(s.scene.size(), 0);
    for (const Camera& cam : s.train)
      for (uint32_t g : engine.visible_set(cam)) ++expected[g];
    INFO("frame " << f);
    CHECK(std::equal(expected.begin(), expected.end(), tables.counts.begin() + std::ptrdiff_t(size_t(f) * s.scene.size())));
  }
}

namespace {

/// One Gaussian moving along x on per-frame keys with linear interpolation: x(t) = path(t).
GaussianCloud moving_gaussian(int frames, double (*path)(double)) {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0, 0, 4), 0.1f, 3.0f, Vec3f(1, 1, 1));
  cloud.motion = MotionModel::Keyframed;
  cloud.dynamic_ids = {0};
  cloud.keyframed = per_frame_tracks(1, frames);
  cloud.keyframed.position_interp = KeyInterp::Linear;
  for (int f = 0; f < frames; ++f) {
    const double t = double(f) / (frames - 1);
    cloud.keyframed.positions[size_t(f) * 3 + 0] = float(path(t));
    cloud.keyframed.positions[size_t(f) * 3 + 2] = 4.0f;
    cloud.keyframed.rotations[size_t(f) * 4] = 1.0f;
  }
  return cloud;
}

}  // namespace

TEST_CASE("speeds of known trajectories, including t = 0 and t = 1", "[visibility][motion]") {
  const int F = 11;
  const double dt = 1.0 / (F - 1);
  const auto times = FrameGrid(F).times();
  SECTION("linear: |v| everywhere") {
    const GaussianCloud cloud = moving_gaussian(F, [](double t) { return 0.5 * t; });
    std::vector<float> s;
    for (double t : times) {
      dynamic_speeds(cloud, t, dt, s);
      REQUIRE(s.size() == 1);
      CHECK(s[0] == Approx(0.5).epsilon(1e-5));
    }
  }
  SECTION("quadratic: central differences 2at inside, one-sided at the ends") {
    const GaussianCloud cloud = moving_gaussian(F, [](double t) { return 0.8 * t * t; });
    // D = s / (1 + C): one camera that sees it, one that looks away.
    Camera sees = axis_camera(64, 48, 60), away = axis_camera(64, 48, 60);
    away.look_at(Vec3d(0, 0, 0), Vec3d(0, 0, -1), Vec3d(0, -1, 0));
    ObservationOptions o;
    o.visibility = mode_options(VisibilityMode::Frustum);
    const ObservationTables tables = observation_tables(cloud, {sees, away}, times, dt, o);
    for (int f = 0; f < F; ++f) {
      const double t = times[size_t(f)];
      const double expected = f == 0 ? 0.8 * dt : f == F - 1 ? 0.8 * (2 - dt) : 1.6 * t;
      INFO("t = " << t);
      CHECK(tables.dynamic_speed[size_t(f)] == Approx(expected).epsilon(1e-4).margin(1e-6));
      CHECK(tables.counts[size_t(f)] == 1);
      CHECK(tables.dynamic_deficiency[size_t(f)] == Approx(expected / 2).epsilon(1e-4).margin(1e-6));
    }
  }
}

TEST_CASE("a scene with no motion has D = 0 everywhere and no NaN", "[visibility][motion]") {
  SynthScene s = small_synth(5, 64, 48, 0.04);
  // Freeze the chair: every key equal to the first.
  KeyframedMotion& k = s.scene.keyframed;
  const size_t K = size_t(k.key_count);
  for (size_t j = 0; j < s.scene.dynamic_count(); ++j)
    for (size_t key = 1; key < K; ++key) {
      std::copy_n(&k.positions[(j * K) * 3], 3, &k.positions[(j * K + key) * 3]);
      std::copy_n(&k.rotations[(j * K) * 4], 4, &k.rotations[(j * K + key) * 4]);
    }
  GaussianCloud frozen = s.scene;
  CHECK(partition_static_dynamic(frozen) == s.scene.dynamic_count());
  for (const GaussianCloud* cloud : {&s.scene, &frozen}) {
    ObservationOptions o;
    o.visibility = mode_options(VisibilityMode::Raytraced, 4);
    const ObservationTables t = observation_tables(*cloud, s.train, FrameGrid(5).times(), 0.25, o);
    CHECK(all_finite(t.dynamic_speed));
    CHECK(all_finite(t.dynamic_deficiency));
    for (int f = 0; f < 5; ++f) {
      const auto row = t.deficiency_row(f);
      CHECK(all_finite(row));
      CHECK(std::all_of(row.begin(), row.end(), [](float d) { return d == 0.0f; }));
    }
    CHECK(t.deficiency_scale() == 1.0f);
  }
}

TEST_CASE("a single moving camera (monocular) observes one view per frame", "[visibility][motion]") {
  const SynthScene s = small_synth(6, 64, 48, 0.04);
  // A camera that walks around the rig, one pose per frame, with times.
  std::vector<Camera> mono;
  for (int f = 0; f < 6; ++f) {
    Camera c = s.train[size_t(f * 3)];
    c.time = f / 5.0;
    mono.push_back(c);
  }
  for (VisibilityMode mode : kModes) {
    INFO(to_string(mode));
    ObservationOptions o;
    o.visibility = mode_options(mode, 2);
    const ObservationTables t = observation_tables(s.scene, mono, FrameGrid(6).times(), 0.2, o);
    VisibilityEngine engine(s.scene, o.visibility);
    for (int f = 0; f < 6; ++f) {
      REQUIRE(t.visible_per_view[size_t(f)].size() == 1);
      engine.set_time(f / 5.0);
      const auto ids = engine.visible_set(mono[size_t(f)]);
      CHECK(t.visible_per_view[size_t(f)][0] == ids.size());
      size_t seen = 0;
      for (size_t g = 0; g < s.scene.size(); ++g) {
        const uint16_t c = t.counts[size_t(f) * s.scene.size() + g];
        CHECK(c <= 1);
        seen += c;
      }
      CHECK(seen == ids.size());
    }
  }
}

TEST_CASE("views per frame: rig cameras see every frame, timed ones their nearest", "[visibility]") {
  std::vector<Camera> cams(4);
  cams[1].time = 0.0;
  cams[2].time = 0.49;   // nearest frame 0.5
  cams[3].time = 0.3;    // 0.2 from frame 0.5: within half a frame (0.25)
  const auto v = views_per_frame(cams, {0.0, 0.5, 1.0}, 0.5);
  CHECK(v[0] == std::vector<uint32_t>{0, 1});
  CHECK(v[1] == std::vector<uint32_t>{0, 2, 3});
  CHECK(v[2] == std::vector<uint32_t>{0});
  const auto w = views_per_frame(cams, {0.0, 0.5, 1.0}, 0.1);  // half a frame = 0.05: camera 3 fits nowhere
  CHECK(w[1] == std::vector<uint32_t>{0, 2});
}

// ---------------------------------------------------------------------------------
// Maps

TEST_CASE("traced deficiency maps agree with the rasterizer's feature maps", "[visibility][maps]") {
  const SynthScene s = small_synth(5, 160, 120);
  VisibilityEngine engine(s.scene, mode_options(VisibilityMode::Raytraced, 1));
  engine.set_time(0.5);
  // A per-Gaussian value: 1 on the chair, 0.25 elsewhere.
  std::vector<float> value(s.scene.size(), 0.25f);
  for (uint32_t g : s.moving_ids) value[g] = 1.0f;
  for (const Camera& cam : {s.train[4], s.train[8]}) {
    const ViewMaps maps = engine.render_maps(cam, value.data(), nullptr, 1);
    REQUIRE(maps.width == cam.width);
    REQUIRE(maps.height == cam.height);
    RenderOptions ro;
    ro.rgb = false;
    ro.features = value.data();
    ro.feature_channels = 1;
    const RenderOutput ref = render(engine.frame(), cam, ro);
    double traced = maps.score(), raster = 0, traced_alpha = 0, raster_alpha = 0;
    for (size_t p = 0; p < ref.features.size(); ++p) {
      raster += ref.features[p];
      traced_alpha += maps.alpha[p];
      raster_alpha += ref.alpha[p];
    }
    raster /= double(ref.features.size());
    INFO(cam.name << " traced score " << traced << " rasterized " << raster);
    CHECK(traced == Approx(raster).epsilon(0.02));
    CHECK(traced_alpha == Approx(raster_alpha).epsilon(0.01));
  }
}

TEST_CASE("one Gaussian's map: the deficiency map is D times the alpha map", "[visibility][maps]") {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0, 0, 3), 0.2f, 1.0f, Vec3f(1, 1, 1));
  VisibilityEngine engine(cloud, mode_options(VisibilityMode::Raytraced, 1));
  const std::vector<float> d = {0.7f}, c = {3.0f};
  const ViewMaps m = engine.render_maps(axis_camera(32, 24, 30), d.data(), c.data(), 2);
  CHECK(m.width == 16);
  CHECK(m.height == 12);
  double peak = 0;
  for (size_t p = 0; p < m.alpha.size(); ++p) {
    CHECK(m.deficiency[p] == Approx(0.7 * m.alpha[p]).margin(1e-6));
    CHECK(m.count[p] == Approx(3.0 * m.alpha[p]).margin(1e-6));
    if (m.alpha[p] > 0) CHECK(m.depth[p] / m.alpha[p] == Approx(3.0).epsilon(0.05));
    peak = std::max(peak, double(m.alpha[p]));
  }
  CHECK(peak > 0.5);
}

// ---------------------------------------------------------------------------------
// Extremes

TEST_CASE("degenerate, huge, opaque and transparent Gaussians: finite results in every mode", "[visibility][extremes]") {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0.1f, 0, 3), 1e-18f, 2.0f, Vec3f(1, 0, 0));   // 0: degenerate (log-scale ≈ -41)
  add_gaussian(cloud, Vec3f(0, 0, 50), 1e4f, 2.0f, Vec3f(0, 1, 0));       // 1: huge
  add_gaussian(cloud, Vec3f(-0.3f, 0, 3), 0.1f, 40.0f, Vec3f(0, 0, 1));   // 2: opacity 1
  add_gaussian(cloud, Vec3f(0.3f, 0, 3), 0.1f, -10.0f, Vec3f(1, 1, 0));   // 3: o = 4.5e-5 < α_min
  cloud.log_scales[1] = Vec3f(std::log(1e4f), std::log(1e-6f), std::log(1e4f));  // and flat
  const Camera cam = axis_camera(48, 36, 40);
  for (VisibilityMode mode : kModes) {
    INFO(to_string(mode));
    VisibilityEngine engine(cloud, mode_options(mode, 1));
    const auto ids = engine.visible_set(cam);
    CHECK(contains(ids, 2));
    if (mode != VisibilityMode::Frustum) CHECK_FALSE(contains(ids, 3));
    else CHECK(contains(ids, 3));
    const std::vector<float> d = {1, 1, 1, 1};
    const ViewMaps m = engine.render_maps(cam, d.data(), d.data(), 1);
    CHECK(all_finite(m.deficiency));
    CHECK(all_finite(m.depth));
    CHECK(all_finite(m.alpha));
  }
}

TEST_CASE("a camera inside a Gaussian", "[visibility][extremes]") {
  GaussianCloud cloud;
  add_gaussian(cloud, Vec3f(0, 0, 0.05f), 1.0f, 3.0f, Vec3f(1, 1, 1));  // the camera sits inside, mean at z 0.05
  add_gaussian(cloud, Vec3f(0, 0, 3), 0.2f, 3.0f, Vec3f(1, 0, 0));
  const Camera cam = axis_camera(32, 24, 30);
  // The rasterizer culls a mean at z <= 0.2; the raytraced mode follows it (RasterMatch).
  for (VisibilityMode mode : kModes) {
    INFO(to_string(mode));
    VisibilityEngine engine(cloud, mode_options(mode, 1));
    CHECK(engine.visible_set(cam) == std::vector<uint32_t>{1});
  }
  // Plain 3D Gaussians (no rasterizer matching): the ray starts inside the first one and
  // meets it at distance 0 with α = o·exp(-½ m²) of the camera's own position.
  VisibilityOptions plain = mode_options(VisibilityMode::Raytraced, 1);
  plain.dilate = false;
  VisibilityEngine engine(cloud, plain);
  CHECK(engine.visible_set(cam) == std::vector<uint32_t>{0, 1});
  const std::vector<float> d = {1, 1};
  const ViewMaps m = engine.render_maps(cam, d.data(), d.data(), 1);
  CHECK(all_finite(m.alpha));
  CHECK(all_finite(m.depth));
}

TEST_CASE("rays grazing the α_min ellipsoid", "[visibility][tracer][extremes]") {
  FrameGaussians frame;
  const float o = 0.9f;
  frame.means = {Vec3f(0, 0, 5)};
  frame.scales = {Vec3f(1.0f, 0.5f, 2.0f)};
  frame.rotations = {Vec4f(1, 0, 0, 0)};
  frame.opacities = {o};
  GaussianTracer tracer(frame, {});
  const double k = std::sqrt(2.0 * std::log(o / kMinAlpha));  // the bound, in sigmas
  for (double rel : {1e-3, -1e-3}) {
    const double x = k * (1.0 + rel);  // along the Gaussian's x axis (σ = 1)
    std::vector<TracedHit> hits;
    const RayOutcome out = tracer.trace(Vec3f(float(x), 0, 0), Vec3f(0, 0, 1), TraceLayers::All, hits);
    INFO("offset " << x << " against the bound " << k);
    CHECK(std::isfinite(out.transmittance));
    if (rel < 0) {
      REQUIRE(hits.size() == 1);
      CHECK(hits[0].alpha >= kMinAlpha);
      CHECK(hits[0].alpha == Approx(o * std::exp(-0.5 * x * x)).epsilon(1e-4));
    } else {
      CHECK(hits.empty());
    }
  }
  // Tangent to the bounding box corner, in a diagonal direction: no NaN, no hit.
  std::vector<TracedHit> hits;
  tracer.trace(Vec3f(float(k), float(0.5 * k), 0), Vec3f(0, 0, 1), TraceLayers::All, hits);
  CHECK(hits.empty());
  CHECK_FALSE(tracer.meets_dynamic(Vec3f(0, 0, 0), Vec3f(0, 0, 1), 100.0f));
}
