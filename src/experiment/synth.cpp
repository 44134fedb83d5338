#include "fillgs/experiment/synth.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/train/train.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/names.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/experiment/rigs.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/model/sh.hpp"

namespace fillgs {

namespace {

using ColorFn = std::function<Vec3f(const Vec3d& p)>;

/// Collects surface Gaussians in world (or part-local) coordinates.
struct Builder {
  std::mt19937_64 rng;
  std::vector<Vec3f> pos, log_scale, color;
  std::vector<Vec4f> rot;
  std::vector<float> opacity;

  explicit Builder(uint64_t seed) : rng(seed) {}

  float jitter(float a) { return std::uniform_real_distribution<float>(-a, a)(rng); }

  /// A flat rectangle centred at c with half-extent vectors u, v (normal u×v).
  void rect(const Vec3d& c, const Vec3d& u, const Vec3d& v, double h, const ColorFn& col, float alpha = 0.97f) {
    const double lu = u.norm(), lv = v.norm();
    const int nu = std::max(1, int(std::ceil(2 * lu / h))), nv = std::max(1, int(std::ceil(2 * lv / h)));
    const Vec3d du = u / lu, dv = v / lv, n = du.cross(dv).normalized();
    Mat3d frame;
    frame.col(0) = du;
    frame.col(1) = dv;
    frame.col(2) = n;
    const Vec4f q = matrix_to_quat(frame).cast<float>();
    const double su = 2 * lu / nu, sv = 2 * lv / nv;
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j) {
        const double a = -lu + (i + 0.5) * su + jitter(float(0.2 * su));
        const double b = -lv + (j + 0.5) * sv + jitter(float(0.2 * sv));
        const Vec3d p = c + a * du + b * dv;
        pos.push_back(p.cast<float>());
        log_scale.push_back(Vec3f(std::log(float(0.55 * su)), std::log(float(0.55 * sv)), std::log(float(0.1 * std::min(su, sv)))));
        rot.push_back(q);
        const Vec3f cc = col(p) + Vec3f(jitter(0.02f), jitter(0.02f), jitter(0.02f));
        color.push_back(cc.cwiseMax(0.0f).cwiseMin(1.0f));
        opacity.push_back(alpha);
      }
  }

  /// An axis-aligned box (all six faces) centred at c with half sizes e.
  void box(const Vec3d& c, const Vec3d& e, double h, const ColorFn& col) {
    const Vec3d X(e.x(), 0, 0), Y(0, e.y(), 0), Z(0, 0, e.z());
    rect(c + Z, X, Y, h, col);
    rect(c - Z, Y, X, h, col);
    rect(c + X, Y, Z, h, col);
    rect(c - X, Z, Y, h, col);
    rect(c + Y, Z, X, h, col);
    rect(c - Y, X, Z, h, col);
  }

  size_t size() const { return pos.size(); }
};

float hash_noise(const Vec3d& p, double cell) {
  const long a = long(std::floor(p.x() / cell)), b = long(std::floor(p.y() / cell)), c = long(std::floor(p.z() / cell));
  uint64_t h = uint64_t(a) * 73856093ULL ^ uint64_t(b) * 19349663ULL ^ uint64_t(c) * 83492791ULL;
  h ^= h >> 13;
  h *= 0x5bd1e995ULL;
  h ^= h >> 15;
  return float(h % 1000) / 1000.0f;
}

Vec3f checker(const Vec3d& p, double cell, const Vec3f& a, const Vec3f& b) {
  const long k = long(std::floor(p.x() / cell)) + long(std::floor(p.y() / cell)) + long(std::floor(p.z() / cell));
  return (k & 1) ? a : b;
}

void chair(Builder& b, double h) {
  // Local frame: seat centre above the origin; legs thin (2.5 cm), back rest.
  const ColorFn fabric = [](const Vec3d& p) -> Vec3f {
    return Vec3f(0.75f, 0.12f, 0.1f) * (0.75f + 0.25f * float(checker(p, 0.05, Vec3f(1, 1, 1), Vec3f(0, 0, 0))[0])) +
           Vec3f(0.05f, 0.05f, 0.05f) * hash_noise(p, 0.02);
  };
  const ColorFn metal = [](const Vec3d&) -> Vec3f { return Vec3f(0.15f, 0.15f, 0.18f); };
  b.box(Vec3d(0, 0, 0.45), Vec3d(0.225, 0.225, 0.025), h, fabric);
  b.box(Vec3d(0, 0.21, 0.72), Vec3d(0.225, 0.015, 0.25), h, fabric);
  for (int sx : {-1, 1})
    for (int sy : {-1, 1}) b.box(Vec3d(sx * 0.19, sy * 0.19, 0.21), Vec3d(0.0125, 0.0125, 0.21), h * 0.6, metal);
}

void shelf(Builder& b, double h) {
  const ColorFn wood = [](const Vec3d& p) -> Vec3f {
    const float grain = 0.5f + 0.5f * float(std::sin(40.0 * p.x() + 7.0 * std::sin(9.0 * p.z())));
    return Vec3f(0.55f, 0.38f, 0.2f) * (0.8f + 0.2f * grain);
  };
  const ColorFn back = [](const Vec3d& p) -> Vec3f { return Vec3f(0.85f, 0.8f, 0.7f) * (0.85f + 0.15f * hash_noise(p, 0.1)); };
  const double W = 1.0, D = 0.175, H = 1.6;
  b.box(Vec3d(-W, 0, H / 2), Vec3d(0.02, D, H / 2), h, wood);
  b.box(Vec3d(W, 0, H / 2), Vec3d(0.02, D, H / 2), h, wood);
  for (int k = 0; k < 5; ++k) b.box(Vec3d(0, 0, 0.02 + k * (H - 0.04) / 4), Vec3d(W, D, 0.015), h, wood);
  b.box(Vec3d(0, -D, H / 2), Vec3d(W, 0.01, H / 2), h, back);  // back panel: hides what is behind
  // Objects on the shelves (books, a ball-ish box): texture and thin parts.
  const ColorFn book = [](const Vec3d& p) -> Vec3f {
    static const Vec3f pal[4] = {{0.1f, 0.3f, 0.7f}, {0.8f, 0.7f, 0.1f}, {0.1f, 0.6f, 0.3f}, {0.6f, 0.1f, 0.5f}};
    return pal[int(hash_noise(Vec3d(p.x(), 0, 0), 0.06) * 4) % 4];
  };
  for (int k = 0; k < 3; ++k) b.box(Vec3d(-0.3 + 0.25 * k, 0.02, 0.55 + k * 0.4), Vec3d(0.12, 0.1, 0.1), h, book);
}

void room(Builder& b, double h) {
  const ColorFn floor = [](const Vec3d& p) -> Vec3f {
    return checker(p, 0.5, Vec3f(0.55f, 0.55f, 0.5f), Vec3f(0.3f, 0.3f, 0.32f)) * (0.9f + 0.1f * hash_noise(p, 0.1));
  };
  const double R = 5.0, Hw = 3.0;
  b.rect(Vec3d(0, 0, 0), Vec3d(R, 0, 0), Vec3d(0, R, 0), h, floor, 0.99f);
  const Vec3f wall_col[4] = {{0.7f, 0.75f, 0.85f}, {0.85f, 0.75f, 0.65f}, {0.7f, 0.85f, 0.7f}, {0.85f, 0.7f, 0.8f}};
  for (int w = 0; w < 4; ++w) {
    const double a = w * kPi / 2;
    const Vec3d n(std::cos(a), std::sin(a), 0);
    const Vec3d tangent(-n.y(), n.x(), 0);
    const Vec3f base = wall_col[w];
    const ColorFn col = [base](const Vec3d& p) -> Vec3f {
      const float stripe = (long(std::floor(p.z() / 0.3)) & 1) ? 1.0f : 0.8f;
      return base * stripe * (0.9f + 0.1f * hash_noise(p, 0.2));
    };
    b.rect(n * R + Vec3d(0, 0, Hw / 2), Vec3d(0, 0, Hw / 2), tangent * R, h, col, 0.99f);
  }
  // Static clutter on the floor.
  const ColorFn crate = [](const Vec3d& p) -> Vec3f { return checker(p, 0.08, Vec3f(0.2f, 0.4f, 0.8f), Vec3f(0.9f, 0.9f, 0.9f)); };
  b.box(Vec3d(1.4, 1.0, 0.2), Vec3d(0.2, 0.2, 0.2), h / 3, crate);
  b.box(Vec3d(-1.5, 0.9, 0.15), Vec3d(0.3, 0.15, 0.15), h / 3, crate);
}

double smoothstep01(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3 - 2 * x);
}

// ---------------------------------------------------------------------------------
// The kitchen (rigs n3v and technicolor)

void kitchen_room(Builder& b, double h) {
  const double X = 5.0, Yback = 2.0, Yfront = -4.0, Hc = 3.0;
  const ColorFn planks = [](const Vec3d& p) -> Vec3f {  // floor: wooden planks along x
    const long plank = long(std::floor(p.y() / 0.18));
    const float shade = 0.8f + 0.2f * hash_noise(Vec3d(std::floor(p.x() / 1.1 + 0.37 * plank), double(plank), 0), 1.0);
    return Vec3f(0.62f, 0.45f, 0.3f) * shade * (0.92f + 0.08f * hash_noise(p, 0.04));
  };
  b.rect(Vec3d(0, 0.5 * (Yback + Yfront), 0), Vec3d(X, 0, 0), Vec3d(0, 0.5 * (Yback - Yfront), 0), h, planks, 0.99f);
  const ColorFn tiles = [](const Vec3d& p) -> Vec3f {  // back wall: 15 cm tiles with grout lines
    const double u = p.x() / 0.15 - std::floor(p.x() / 0.15), v = p.z() / 0.15 - std::floor(p.z() / 0.15);
    if (u < 0.08 || v < 0.08) return Vec3f(0.45f, 0.45f, 0.45f);
    return Vec3f(0.82f, 0.88f, 0.9f) * (0.9f + 0.1f * hash_noise(Vec3d(std::floor(p.x() / 0.15), 0, std::floor(p.z() / 0.15)), 1.0));
  };
  b.rect(Vec3d(0, Yback, Hc / 2), Vec3d(0, 0, Hc / 2), Vec3d(X, 0, 0), h / 2, tiles, 0.99f);
  const ColorFn ceiling = [](const Vec3d& p) -> Vec3f { return Vec3f(0.9f, 0.9f, 0.86f) * (0.93f + 0.07f * hash_noise(p, 0.3)); };
  b.rect(Vec3d(0, 0.5 * (Yback + Yfront), Hc), Vec3d(0, 0.5 * (Yback - Yfront), 0), Vec3d(X, 0, 0), h, ceiling, 0.99f);
  for (int side : {-1, 1}) {
    const Vec3f base = side < 0 ? Vec3f(0.75f, 0.8f, 0.65f) : Vec3f(0.85f, 0.75f, 0.6f);
    const ColorFn wall = [base](const Vec3d& p) -> Vec3f {
      return base * ((long(std::floor(p.y() / 0.5)) & 1) ? 1.0f : 0.88f) * (0.92f + 0.08f * hash_noise(p, 0.2));
    };
    b.rect(Vec3d(side * X, 0.5 * (Yback + Yfront), Hc / 2), Vec3d(0, 0.5 * (Yback - Yfront) * side, 0), Vec3d(0, 0, Hc / 2), h, wall, 0.99f);
  }
}

void kitchen_furniture(Builder& b, double h) {
  // Counter: 3.2 m long, 0.6 m deep, 0.9 m high, its front face 0.55 m behind the walker's path.
  const ColorFn doors = [](const Vec3d& p) -> Vec3f {  // cabinet doors 0.4 m wide, dark gaps, handles
    const double u = (p.x() + 1.6) / 0.4 - std::floor((p.x() + 1.6) / 0.4);
    if (u < 0.04 || p.z() < 0.08) return Vec3f(0.15f, 0.13f, 0.12f);
    if (u > 0.85 && u < 0.9 && p.z() > 0.55 && p.z() < 0.75) return Vec3f(0.75f, 0.75f, 0.78f);
    return Vec3f(0.35f, 0.5f, 0.62f) * (0.9f + 0.1f * hash_noise(p, 0.05));
  };
  const ColorFn marble = [](const Vec3d& p) -> Vec3f {
    const float vein = 0.5f + 0.5f * float(std::sin(11.0 * p.x() + 6.0 * std::sin(7.0 * p.y())));
    return Vec3f(0.92f, 0.9f, 0.86f) * (0.85f + 0.15f * vein) * (0.95f + 0.05f * hash_noise(p, 0.02));
  };
  b.box(Vec3d(0, 0.85, 0.44), Vec3d(1.6, 0.3, 0.44), h, doors);
  b.box(Vec3d(0, 0.85, 0.895), Vec3d(1.63, 0.32, 0.015), h, marble);
  // Objects on the counter, at its back half (the sliding box passes in front of them).
  const ColorFn steel = [](const Vec3d& p) -> Vec3f { return Vec3f(0.35f, 0.36f, 0.4f) * (0.8f + 0.2f * hash_noise(p, 0.03)); };
  b.box(Vec3d(-1.0, 0.95, 1.0), Vec3d(0.16, 0.16, 0.09), h, steel);  // pot
  const ColorFn glass_green = [](const Vec3d& p) -> Vec3f { return Vec3f(0.15f, 0.45f, 0.2f) * (0.85f + 0.3f * float(p.z() > 1.1)); };
  const ColorFn glass_brown = [](const Vec3d& p) -> Vec3f { return Vec3f(0.45f, 0.25f, 0.1f) * (0.85f + 0.3f * float(p.z() > 1.1)); };
  b.box(Vec3d(-0.55, 1.0, 1.06), Vec3d(0.035, 0.035, 0.15), h * 0.6, glass_green);  // bottles
  b.box(Vec3d(-0.42, 0.98, 1.06), Vec3d(0.035, 0.035, 0.15), h * 0.6, glass_brown);
  const ColorFn wood = [](const Vec3d& p) -> Vec3f {
    return Vec3f(0.7f, 0.52f, 0.3f) * (0.85f + 0.15f * float(std::sin(60.0 * p.x())));
  };
  b.box(Vec3d(0.3, 0.95, 0.92), Vec3d(0.22, 0.14, 0.01), h, wood);  // cutting board with vegetables
  const Vec3f veg[3] = {{0.8f, 0.1f, 0.1f}, {0.2f, 0.7f, 0.15f}, {0.95f, 0.55f, 0.1f}};
  for (int k = 0; k < 3; ++k) {
    const Vec3f c = veg[k];
    b.box(Vec3d(0.17 + 0.13 * k, 0.95, 0.965), Vec3d(0.045, 0.045, 0.035), h * 0.6,
          [c](const Vec3d& p) -> Vec3f { return c * (0.85f + 0.15f * hash_noise(p, 0.015)); });
  }
  const ColorFn bowl = [](const Vec3d& p) -> Vec3f { return checker(p, 0.03, Vec3f(0.9f, 0.9f, 0.95f), Vec3f(0.2f, 0.3f, 0.7f)); };
  b.box(Vec3d(0.9, 0.97, 0.96), Vec3d(0.12, 0.12, 0.05), h, bowl);
  // Shelves on the back wall with jars.
  for (int k = 0; k < 2; ++k) {
    const double z = 1.45 + 0.45 * k;
    b.box(Vec3d(0, 1.85, z), Vec3d(1.5, 0.15, 0.015), h, wood);
    for (int j = 0; j < 7; ++j) {
      const Vec3f lid = j % 2 ? Vec3f(0.8f, 0.15f, 0.1f) : Vec3f(0.15f, 0.3f, 0.75f);
      const ColorFn jar = [lid, z](const Vec3d& p) -> Vec3f {
        if (p.z() > z + 0.13) return lid;
        return Vec3f(0.85f, 0.8f, 0.6f) * (0.75f + 0.25f * hash_noise(p, 0.02));
      };
      b.box(Vec3d(-1.3 + 0.42 * j, 1.82, z + 0.09), Vec3d(0.05, 0.05, 0.075), h * 0.75, jar);
    }
  }
  // A tall pillar between the rig and the walker's path: hides the walker from some cameras.
  const ColorFn pillar = [](const Vec3d& p) -> Vec3f {
    return Vec3f(0.55f, 0.55f, 0.58f) * ((long(std::floor(p.z() / 0.25)) & 1) ? 1.0f : 0.85f) * (0.9f + 0.1f * hash_noise(p, 0.04));
  };
  b.box(Vec3d(-0.6, -1.0, 1.0), Vec3d(0.18, 0.18, 1.0), h, pillar);
}

/// A rigid transform: x ↦ R x + T.
struct Pose {
  Mat3d R = Mat3d::Identity();
  Vec3d T = Vec3d::Zero();
  Pose then(const Pose& child) const { return {R * child.R, R * child.T + T}; }
};
Pose translate(const Vec3d& t) { return {Mat3d::Identity(), t}; }
Pose rotate(double angle, const Vec3d& axis) { return {Eigen::AngleAxisd(angle, axis).toRotationMatrix(), Vec3d::Zero()}; }

/// A rigid part of the moving content: Gaussians in its own frame, its pose relative to its
/// parent (−1: the world) at time t.
struct Part {
  Builder gaussians;
  int parent = -1;
  std::function<Pose(double)> local;
};

std::vector<Part> kitchen_movers(uint64_t seed, double h) {
  std::vector<Part> parts;
  auto add = [&](int parent, std::function<Pose(double)> local) {
    parts.push_back({Builder(seed + 7 * (parts.size() + 1)), parent, std::move(local)});
    return int(parts.size()) - 1;
  };
  // The walker: 1.75 m tall, facing +x, walks 2 m along x in front of the counter
  // (x −1.1 → 0.9 at y = 0, t 0.05 → 0.95, eased), legs and arms swinging with the stride
  // (1.2 m); the right arm (towards the rig) rises forward to 110° and waves, t 0.35–0.75.
  const double stride = 1.2;
  auto walked = [](double t) { return 2.0 * smoothstep01((t - 0.05) / 0.9); };
  auto phase = [=](double t) { return 2 * kPi * walked(t) / stride; };
  auto raise = [](double t) { return smoothstep01((t - 0.35) / 0.1) - smoothstep01((t - 0.65) / 0.1); };
  const Vec3d Y = Vec3d::UnitY();
  const int root = add(-1, [=](double t) { return translate(Vec3d(-1.1 + walked(t), 0.0, 0.02 * std::fabs(std::sin(phase(t))))); });
  const ColorFn shirt = [](const Vec3d& p) -> Vec3f {
    return ((long(std::floor(p.z() / 0.04)) & 1) ? Vec3f(0.15f, 0.3f, 0.7f) : Vec3f(0.9f, 0.9f, 0.92f)) * (0.92f + 0.08f * hash_noise(p, 0.01));
  };
  const ColorFn jeans = [](const Vec3d& p) -> Vec3f { return Vec3f(0.12f, 0.18f, 0.35f) * (0.8f + 0.2f * hash_noise(p, 0.015)); };
  const ColorFn skin = [](const Vec3d&) -> Vec3f { return Vec3f(0.85f, 0.64f, 0.5f); };
  const ColorFn head_col = [](const Vec3d& p) -> Vec3f {  // hair on top and at the back (−x)
    if (p.z() > 0.08 || p.x() < -0.06) return Vec3f(0.2f, 0.12f, 0.06f);
    return Vec3f(0.85f, 0.64f, 0.5f);
  };
  parts[size_t(root)].gaussians.box(Vec3d(0, 0, 1.2), Vec3d(0.11, 0.2, 0.275), h, shirt);  // torso
  const int head = add(root, [](double) { return translate(Vec3d(0, 0, 1.62)); });
  parts[size_t(head)].gaussians.box(Vec3d(0, 0, 0), Vec3d(0.1, 0.09, 0.12), h, head_col);
  for (int side : {1, -1}) {  // +1: left (+y, away from the rig), −1: right
    const int leg = add(root, [=](double t) { return translate(Vec3d(0, 0.1 * side, 0.93)).then(rotate(side * 0.44 * std::sin(phase(t)), Y)); });
    parts[size_t(leg)].gaussians.box(Vec3d(0, 0, -0.45), Vec3d(0.07, 0.065, 0.45), h, jeans);
    const int upper = add(root, [=](double t) {
      const double swing = -side * 0.35 * std::sin(phase(t));
      const double a = side > 0 ? swing : swing + raise(t) * (-1.92 - swing);
      return translate(Vec3d(0, 0.26 * side, 1.44)).then(rotate(a, Y));
    });
    parts[size_t(upper)].gaussians.box(Vec3d(0, 0, -0.15), Vec3d(0.05, 0.05, 0.15), h, shirt);
    const int fore = add(upper, [=](double t) {
      const double bend = -0.17, wave = -(0.8 + 0.45 * std::sin(2 * kPi * t / 0.1));
      const double e = side > 0 ? bend : bend + raise(t) * (wave - bend);
      return translate(Vec3d(0, 0, -0.3)).then(rotate(e, Y));
    });
    parts[size_t(fore)].gaussians.box(Vec3d(0, 0, -0.12), Vec3d(0.045, 0.045, 0.12), h, shirt);
    parts[size_t(fore)].gaussians.box(Vec3d(0, 0, -0.29), Vec3d(0.04, 0.05, 0.05), h * 0.6, skin);  // hand
  }
  // A box (toaster) sliding 1.4 m along the counter's front half while turning 90°, t 0.3–0.75.
  const int box = add(-1, [](double t) {
    const double s = smoothstep01((t - 0.3) / 0.45);
    return translate(Vec3d(1.1 - 1.4 * s, 0.68, 1.0)).then(rotate(s * kPi / 2, Vec3d::UnitZ()));
  });
  const ColorFn toaster = [](const Vec3d& p) -> Vec3f {
    if (p.z() > 0.095) return std::fabs(p.y()) < 0.02 ? Vec3f(0.1f, 0.1f, 0.1f) : Vec3f(0.8f, 0.8f, 0.82f);
    return ((long(std::floor((p.x() + p.z()) / 0.05)) & 1) ? Vec3f(0.85f, 0.12f, 0.12f) : Vec3f(0.95f, 0.9f, 0.85f));
  };
  parts[size_t(box)].gaussians.box(Vec3d(0, 0, 0), Vec3d(0.14, 0.09, 0.1), h, toaster);
  return parts;
}

void put_gaussian(GaussianCloud& c, const Builder& b, size_t i, size_t g) {
  c.means[g] = b.pos[i];
  c.log_scales[g] = b.log_scale[i];
  c.rotations[g] = b.rot[i];
  c.opacity_logits[g] = logit(b.opacity[i]);
  for (int ch = 0; ch < 3; ++ch) c.sh[g * 3 + ch] = rgb_to_sh_dc(b.color[i][ch]);
}

/// Static Gaussians, then the moving parts' (world pose per frame from the part tree).
void assemble(SynthScene& out, const Builder& stat, const std::vector<Part>& parts, int F) {
  GaussianCloud& c = out.scene;
  c.sh_degree = 0;
  size_t nm = 0;
  for (const Part& p : parts) nm += p.gaussians.size();
  const size_t ns = stat.size();
  c.resize(ns + nm);
  for (size_t i = 0; i < ns; ++i) put_gaussian(c, stat, i, i);
  c.keyframed = per_frame_tracks(nm, F);
  KeyframedMotion& k = c.keyframed;
  std::vector<Pose> world(parts.size());
  for (int f = 0; f < F; ++f) {
    const double t = FrameGrid(F).time(f);
    size_t j = 0;
    for (size_t pi = 0; pi < parts.size(); ++pi) {
      const Part& p = parts[pi];
      FILLGS_CHECK(p.parent < int(pi));  // parents first
      world[pi] = p.parent < 0 ? p.local(t) : world[size_t(p.parent)].then(p.local(t));
      const Vec4d q = matrix_to_quat(world[pi].R);
      for (size_t i = 0; i < p.gaussians.size(); ++i, ++j) {
        const Vec3d x = world[pi].R * p.gaussians.pos[i].cast<double>() + world[pi].T;
        const Vec4d r = quat_mul(q, p.gaussians.rot[i].cast<double>());
        for (int a = 0; a < 3; ++a) k.positions[(j * F + f) * 3 + a] = float(x[a]);
        for (int a = 0; a < 4; ++a) k.rotations[(j * F + f) * 4 + a] = float(r[a]);
      }
    }
  }
  size_t g = ns;
  for (const Part& p : parts)
    for (size_t i = 0; i < p.gaussians.size(); ++i, ++g) {
      put_gaussian(c, p.gaussians, i, g);
      c.dynamic_ids.push_back(uint32_t(g));
      out.moving_ids.push_back(uint32_t(g));
    }
  c.motion = MotionModel::Keyframed;
  canonical_from_first_key(c);
  c.validate("synthetic scene");
}

void ring_scene(SynthScene& out, const SynthOptions& o, const std::string& variant) {
  Builder stat(o.seed);
  room(stat, 4 * o.spacing);
  shelf(stat, o.spacing);
  std::vector<Part> parts(1, Part{Builder(o.seed + 1), -1, {}});
  chair(parts[0].gaussians, o.spacing);
  // Chair pose (offset, yaw) at motion parameter s in [0, 1], per variant.
  std::function<Pose(double)> path;
  if (variant == "chair") {  // behind the shelf's back panel (y < 0), sliding along x and turning
    path = [](double s) { return translate(Vec3d(-0.55 + 1.05 * s, -0.65 + 0.05 * s, 0)).then(rotate(s * kPi / 2, Vec3d::UnitZ())); };
  } else if (variant == "orbit") {  // around the shelf: front, side, behind
    path = [](double s) {
      const double a = (30.0 + 240.0 * s) * kPi / 180.0;
      return translate(Vec3d(1.3 * std::cos(a), 1.3 * std::sin(a), 0)).then(rotate(a, Vec3d::UnitZ()));
    };
  } else {  // lift: rises behind the shelf, turning half a turn
    path = [](double s) { return translate(Vec3d(0.0, -0.6, 0.9 * s)).then(rotate(s * kPi, Vec3d::UnitZ())); };
  }
  const double a = o.move_start, b = o.move_end;
  parts[0].local = [path, a, b](double t) { return path(smoothstep01((t - a) / (b - a))); };
  assemble(out, stat, parts, o.frames);

  Camera lens;
  lens.set_fov_x(o.fov_x_degrees * kPi / 180.0, o.width, o.height);
  auto ring = [&](int n, double phase, double radius, double height, const char* prefix) {
    RingPlacement r;
    r.count = n;
    r.radius = radius;
    r.elevation = height;
    r.phase = phase;
    r.target = Vec3d(0, 0, 0.6);
    r.prefix = prefix;
    r.digits = 2;
    return camera_ring(r, lens);
  };
  out.train = ring(o.train_cameras, kPi / 2, o.camera_radius, o.camera_height, "cam");
  out.interpolation = ring(o.train_cameras, kPi / 2 + kPi / o.train_cameras, o.camera_radius, o.camera_height, "interp");
  out.extrapolation = ring(o.extrapolation_cameras, kPi / 2 + kPi / 8, 0.8 * o.camera_radius, o.camera_height + 1.0, "extrap");
  // Two ring cameras 45° apart; between them on the same circle; outside their arc (the
  // neighbouring ring cameras and the raised, closer camera above the arc).
  out.split = {{"cam04", "cam06"}, {"interp04", "interp05"}, {"cam03", "cam07", "extrap02"}};
}

void kitchen_scene(SynthScene& out, const SynthOptions& o) {
  Builder stat(o.seed);
  kitchen_room(stat, 4 * o.spacing);
  kitchen_furniture(stat, o.spacing);
  assemble(out, stat, kitchen_movers(o.seed, o.spacing), o.frames);
  if (o.rig == "n3v") {
    // The real rig, 0.25 m per COLMAP unit, looking at the walker's path 1.1 m above the floor.
    out.train = placed_rig(n3v_rig_colmap(o.width, o.height), 0.25, Vec3d(0, 0, 1.1));
    // Train on two lower-row cameras with two lower-row cameras between them (cam15, cam16);
    // interpolation: every camera between them, both rows; extrapolation: the two outermost
    // cameras of each row at both ends of the rig.
    out.split = {{"cam14", "cam17"},
                 {"cam00", "cam05", "cam06", "cam15", "cam16"},
                 {"cam01", "cam02", "cam09", "cam10", "cam11", "cam12", "cam19", "cam20"}};
  } else {
    // A 4×4 grid 0.2 m apart, 3.6 m in front of the walker's path (far enough for its wide,
    // short 2048×1088 frame to hold the walker from head to feet), 65° across.
    out.train = technicolor_rig(o.width, o.height, 0.2, Vec3d(0, -3.6, 1.1), 65.0 * kPi / 180.0);
    // The bottom row's end cameras (two between them); interpolation: the two middle
    // columns of the two lower rows; extrapolation: the outer columns of the two upper rows.
    out.split = {{"cam12", "cam15"}, {"cam09", "cam10", "cam13", "cam14"}, {"cam00", "cam03", "cam04", "cam07"}};
  }
}

}  // namespace

std::vector<std::string> synthetic_rigs() { return {"ring", "n3v", "technicolor"}; }

std::vector<std::string> synthetic_variants(const std::string& rig) {
  if (rig == "ring") return {"chair", "orbit", "lift"};
  if (rig == "n3v" || rig == "technicolor") return {"kitchen"};
  return {};
}

std::string SynthOptions::resolved_variant() const {
  if (!variant.empty()) return variant;
  const std::vector<std::string> v = synthetic_variants(rig);
  return v.empty() ? "" : v.front();
}

std::string SynthOptions::scene_name() const { return rig == "ring" ? resolved_variant() : rig; }

const Camera* SynthScene::camera(const std::string& name) const {
  for (const auto* list : {&train, &interpolation, &extrapolation})
    for (const Camera& c : *list)
      if (c.name == name) return &c;
  return nullptr;
}

SynthScene make_synthetic_scene(const SynthOptions& o) {
  if (o.frames < 2) throw_error("synth: frames must be at least 2 (got ", o.frames, ")");
  if (o.width < 8 || o.height < 8) throw_error("synth: image size must be at least 8x8");
  if (!(o.spacing > 0.002)) throw_error("synth: spacing must exceed 0.002 m");
  if (!(o.move_start >= 0 && o.move_start < o.move_end && o.move_end <= 1)) throw_error("synth: need 0 <= move start < move end <= 1");
  const std::vector<std::string> rigs = synthetic_rigs();
  if (std::find(rigs.begin(), rigs.end(), o.rig) == rigs.end()) throw_error("synth: unknown rig \"", o.rig, "\" (", join_names(rigs), ")");
  const std::string variant = o.resolved_variant();
  const std::vector<std::string> variants = synthetic_variants(o.rig);
  if (std::find(variants.begin(), variants.end(), variant) == variants.end())
    throw_error("synth: unknown variant \"", variant, "\" for rig ", o.rig, " (", join_names(variants), ")");
  SynthScene out;
  out.options = o;
  out.options.variant = variant;
  if (o.rig == "ring") ring_scene(out, o, variant);
  else kitchen_scene(out, o);
  return out;
}

std::vector<Camera> cameras_over_time(const std::vector<Camera>& rig, int frames) {
  std::vector<Camera> out;
  for (const Camera& c : rig)
    for (int f = 0; f < frames; ++f) {
      Camera x = c;
      char fr[16];
      std::snprintf(fr, sizeof fr, "%04d", f);
      x.name = c.name + "/" + fr;
      x.image_path = "images/" + c.name + "/" + fr + ".png";
      x.time = FrameGrid(frames).time(f);
      out.push_back(x);
    }
  return out;
}

void write_split_picture(const SynthScene& s, const std::string& path, const std::vector<Camera>& virtual_views, const std::string& title) {
  std::vector<Camera> cams;
  std::vector<int> roles;
  auto role_of = [&](const std::string& n) {
    const std::vector<std::string>* lists[] = {&s.split.train, &s.split.interpolation, &s.split.extrapolation};
    for (int r = 0; r < 3; ++r)
      if (std::count(lists[r]->begin(), lists[r]->end(), n)) return r;
    return 3;
  };
  for (const auto* list : {&s.train, &s.interpolation, &s.extrapolation})
    for (const Camera& c : *list) {
      const int r = role_of(c.name);
      if (r == 3 && list != &s.train) continue;  // held-out ring cameras outside the split
      cams.push_back(c);
      roles.push_back(r);
    }
  std::vector<Vec3f> still, moving;
  std::vector<uint8_t> is_moving(s.scene.size(), 0);
  for (uint32_t g : s.moving_ids) is_moving[g] = 1;
  for (size_t g = 0; g < s.scene.size(); g += 7)
    if (!is_moving[g] && s.scene.means[g].z() > 0.05f && s.scene.means[g].z() < 2.0f) still.push_back(s.scene.means[g]);
  const int F = s.options.frames;
  FrameSampler ev(s.scene);
  for (int f = 0; f < F; f += std::max(1, F / 10)) {
    const FrameGaussians& g = ev.at(FrameGrid(F).time(f));
    for (size_t k = 0; k < s.moving_ids.size(); k += 5) moving.push_back(g.means[s.moving_ids[k]]);
  }
  for (const Camera& v : virtual_views) cams.push_back(v), roles.push_back(4);
  write_split_png(path, still, moving, cams, roles,
                  !title.empty() ? title
                                 : "split of the " + s.options.scene_name() + " scene: train " + std::to_string(s.split.train.size()) +
                                       ", interpolation " + std::to_string(s.split.interpolation.size()) + ", extrapolation " +
                                       std::to_string(s.split.extrapolation.size()));
}

void write_synthetic_scene(const SynthScene& s, const std::string& dir, Progress& progress) {
  make_directories(dir);
  const int F = s.options.frames;
  write_fillgs_ply(join_path(dir, "scene.ply"), s.scene);
  // Stand-in for SfM points of frame 0 over the whole rig (what COLMAP gives N3V users): a
  // quarter of the frame-0 means that two or more rig cameras see, 1 cm noise.
  write_points_ply(join_path(dir, "points.ply"), pseudo_sfm_points(s.scene, 0.0, 0.25, 0.01, s.options.seed, s.train, 2));
  // Test cameras: the ring's held-out rigs, or the split's cameras of the rig.
  auto named = [&](const std::vector<std::string>& names) {
    std::vector<Camera> cams;
    for (const std::string& n : names) cams.push_back(*s.camera(n));
    return cams;
  };
  const std::vector<Camera> interp = s.interpolation.empty() ? named(s.split.interpolation) : s.interpolation;
  const std::vector<Camera> extrap = s.extrapolation.empty() ? named(s.split.extrapolation) : s.extrapolation;
  const std::pair<const char*, const std::vector<Camera>*> lists[] = {{"train", &s.train}, {"interpolation", &interp}, {"extrapolation", &extrap}};
  // Every camera is rendered once, whatever lists it is in.
  std::vector<Camera> unique;
  for (const auto& l : lists)
    for (const Camera& c : *l.second)
      if (std::none_of(unique.begin(), unique.end(), [&](const Camera& u) { return u.name == c.name; })) unique.push_back(c);
  progress.start("rendering ground truth", unique.size() * size_t(F));
  FrameSampler ev(s.scene);
  const std::vector<Camera> shots = cameras_over_time(unique, F);
  for (int f = 0; f < F; ++f) {
    const FrameGaussians& g = ev.at(FrameGrid(F).time(f));
    for (size_t c = 0; c < unique.size(); ++c) {
      const Camera& cam = shots[c * size_t(F) + size_t(f)];
      const Image img(cam.width, cam.height, 3, render(g, cam).rgb);
      write_image(join_path(dir, cam.image_path), img);
      progress.advance();
    }
  }
  progress.finish();
  nlohmann::json meta;
  for (const auto& l : lists) {
    write_transforms_json(join_path(dir, std::string("transforms_") + l.first + ".json"), cameras_over_time(*l.second, F));
    nlohmann::json names = nlohmann::json::array();
    for (const Camera& c : *l.second) names.push_back(c.name);
    meta["cameras"][l.first] = names;
  }
  meta["split"] = {{"train", s.split.train}, {"interpolation", s.split.interpolation}, {"extrapolation", s.split.extrapolation}};
  meta["frames"] = F;
  meta["rig"] = s.options.rig;
  meta["variant"] = s.options.variant;
  meta["width"] = s.options.width;
  meta["height"] = s.options.height;
  meta["seed"] = s.options.seed;
  meta["gaussians"] = s.scene.size();
  meta["moving_gaussians"] = s.moving_ids.size();
  if (s.options.rig == "ring") meta["move_interval"] = {s.options.move_start, s.options.move_end};
  meta["points"] = "points.ply: 25% of the frame-0 Gaussian means that at least 2 rig cameras see, with 1 cm noise, standing in for SfM points";
  meta["time_convention"] = "t = frame / (frames - 1)";
  write_file_atomically(join_path(dir, "synth.json"), meta.dump(2) + "\n");
  write_split_picture(s, join_path(dir, "split.png"));
}

}  // namespace fillgs
