#include "fillgs/synth.hpp"
#include "fillgs/train.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "fillgs/error.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/image_io.hpp"
#include "fillgs/raster.hpp"
#include "fillgs/scene_io.hpp"
#include "fillgs/sh.hpp"

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

}  // namespace

std::vector<std::string> synthetic_variants() { return {"chair", "orbit", "lift"}; }

SynthScene make_synthetic_scene(const SynthOptions& o) {
  if (o.frames < 2) throw_error("synth: --frames must be at least 2 (got ", o.frames, ")");
  if (o.width < 8 || o.height < 8) throw_error("synth: image size must be at least 8x8");
  if (!(o.spacing > 0.002)) throw_error("synth: spacing must exceed 0.002 m");
  if (!(o.move_start >= 0 && o.move_start < o.move_end && o.move_end <= 1)) throw_error("synth: need 0 <= move start < move end <= 1");
  SynthScene out;
  out.options = o;
  Builder stat(o.seed), moving(o.seed + 1);
  room(stat, 4 * o.spacing);
  shelf(stat, o.spacing);
  chair(moving, o.spacing);

  GaussianCloud& c = out.scene;
  c.sh_degree = 0;
  const size_t ns = stat.size(), nm = moving.size();
  c.resize(ns + nm);
  auto put = [&](const Builder& b, size_t i, size_t g) {
    c.means[g] = b.pos[i];
    c.log_scales[g] = b.log_scale[i];
    c.rotations[g] = b.rot[i];
    c.opacity_logits[g] = logit(b.opacity[i]);
    for (int ch = 0; ch < 3; ++ch) c.sh[g * 3 + ch] = rgb_to_sh_dc(b.color[i][ch]);
  };
  for (size_t i = 0; i < ns; ++i) put(stat, i, i);
  for (size_t i = 0; i < nm; ++i) put(moving, i, ns + i);

  const int F = o.frames;
  // Chair pose (offset, yaw) at motion parameter s in [0, 1], per variant.
  using Pose = std::pair<Vec3d, double>;
  std::function<Pose(double)> path;
  if (o.variant == "chair") {  // behind the shelf's back panel (y < 0), sliding along x and turning
    path = [](double s) -> Pose { return {Vec3d(-0.55 + 1.05 * s, -0.65 + 0.05 * s, 0), s * kPi / 2}; };
  } else if (o.variant == "orbit") {  // around the shelf: front, side, behind
    path = [](double s) -> Pose {
      const double a = (30.0 + 240.0 * s) * kPi / 180.0;
      return {Vec3d(1.3 * std::cos(a), 1.3 * std::sin(a), 0), a};
    };
  } else if (o.variant == "lift") {  // rises behind the shelf, turning half a turn
    path = [](double s) -> Pose { return {Vec3d(0.0, -0.6, 0.9 * s), s * kPi}; };
  } else {
    throw_error("synth: unknown variant \"", o.variant, "\" (chair, orbit, lift)");
  }
  c.keyframed = per_frame_tracks(nm, F);
  KeyframedMotion& k = c.keyframed;
  for (int f = 0; f < F; ++f) {
    const double t = double(f) / (F - 1);
    const double s = smoothstep01((t - o.move_start) / (o.move_end - o.move_start));
    const auto [offset, yaw] = path(s);
    const Mat3d Rz = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
    const Vec4d qz(std::cos(yaw / 2), 0, 0, std::sin(yaw / 2));
    for (size_t i = 0; i < nm; ++i) {
      const Vec3d p = Rz * moving.pos[i].cast<double>() + offset;
      const Vec4d q = quat_mul(qz, moving.rot[i].cast<double>());
      for (int a = 0; a < 3; ++a) k.positions[(i * F + f) * 3 + a] = float(p[a]);
      for (int a = 0; a < 4; ++a) k.rotations[(i * F + f) * 4 + a] = float(q[a]);
    }
  }
  c.motion = MotionModel::Keyframed;
  for (size_t i = 0; i < nm; ++i) {
    c.dynamic_ids.push_back(uint32_t(ns + i));
    out.chair_ids.push_back(uint32_t(ns + i));
  }
  canonical_from_first_key(c);
  c.validate("synthetic scene");

  // Cameras.
  const Vec3d target(0, 0, 0.6), up(0, 0, 1);
  auto ring = [&](int n, double phase, double radius, double height, const char* prefix) {
    std::vector<Camera> cams;
    for (int i = 0; i < n; ++i) {
      const double a = phase + 2 * kPi * i / n;
      Camera cam;
      char name[32];
      std::snprintf(name, sizeof name, "%s%02d", prefix, i);
      cam.name = name;
      cam.set_fov_x(o.fov_x_degrees * kPi / 180.0, o.width, o.height);
      cam.look_at(Vec3d(radius * std::cos(a), radius * std::sin(a), height), target, up);
      cams.push_back(cam);
    }
    return cams;
  };
  out.train = ring(o.train_cameras, kPi / 2, o.camera_radius, o.camera_height, "cam");
  out.interpolation = ring(o.train_cameras, kPi / 2 + kPi / o.train_cameras, o.camera_radius, o.camera_height, "interp");
  out.extrapolation = ring(o.extrapolation_cameras, kPi / 2 + kPi / 8, 0.8 * o.camera_radius, o.camera_height + 1.0, "extrap");
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
      x.time = frames > 1 ? double(f) / (frames - 1) : 0.0;
      out.push_back(x);
    }
  return out;
}

void write_synthetic_scene(const SynthScene& s, const std::string& dir, Progress& progress, int threads) {
  make_directories(dir);
  const int F = s.options.frames;
  write_fillgs_ply(join_path(dir, "scene.ply"), s.scene);
  // Stand-in for SfM points: a quarter of the frame-0 means, 1 cm noise.
  write_points_ply(join_path(dir, "points.ply"), pseudo_sfm_points(s.scene, 0.0, 0.25, 0.01, s.options.seed));
  const std::pair<const char*, const std::vector<Camera>*> splits[] = {
      {"train", &s.train}, {"interpolation", &s.interpolation}, {"extrapolation", &s.extrapolation}};
  size_t total = 0;
  for (const auto& sp : splits) total += sp.second->size() * size_t(F);
  progress.start("rendering ground truth", total);
  FrameEvaluator ev(s.scene);
  RenderOptions ro;
  ro.threads = threads;
  nlohmann::json meta;
  for (const auto& sp : splits) {
    const std::vector<Camera> cams = cameras_over_time(*sp.second, F);
    write_transforms_json(join_path(dir, std::string("transforms_") + sp.first + ".json"), cams);
    for (int f = 0; f < F; ++f) {
      const FrameGaussians& g = ev.evaluate(double(f) / (F - 1));
      for (size_t c = 0; c < sp.second->size(); ++c) {
        const Camera& cam = cams[c * size_t(F) + size_t(f)];
        const RenderOutput r = render(g, cam, ro);
        Image img(cam.width, cam.height, 3);
        img.pixels = r.rgb;
        write_image(join_path(dir, cam.image_path), img);
        progress.advance();
      }
    }
    nlohmann::json names = nlohmann::json::array();
    for (const Camera& c : *sp.second) names.push_back(c.name);
    meta["cameras"][sp.first] = names;
  }
  progress.finish();
  meta["frames"] = F;
  meta["variant"] = s.options.variant;
  meta["width"] = s.options.width;
  meta["height"] = s.options.height;
  meta["seed"] = s.options.seed;
  meta["gaussians"] = s.scene.size();
  meta["moving_gaussians"] = s.chair_ids.size();
  meta["move_interval"] = {s.options.move_start, s.options.move_end};
  meta["points"] = "points.ply: 25% of the frame-0 Gaussian means with 1 cm noise, standing in for SfM points";
  meta["time_convention"] = "t = frame / (frames - 1)";
  write_file_atomically(join_path(dir, "synth.json"), meta.dump(2) + "\n");
}

}  // namespace fillgs
