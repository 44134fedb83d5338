#include "fillgs/io/scene_io.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/trained_models.hpp"
#include "io/ply_gaussians.hpp"
#include "fillgs/model/sh.hpp"

namespace fs = std::filesystem;

namespace fillgs {

using model_io::kFillgsMagic;

std::string detect_scene_format(const std::string& path) {
  const ModelFormat* f = find_model_format(path);
  if (f) return f->name;
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw_error(path, ": a folder that holds no model fillgs reads (", model_format_names(), "); give a file or --scene-format");
  throw_error(path, ": not a PLY file (missing 'ply' magic line) nor a model of another format fillgs reads (", model_format_names(), ")");
}

GaussianCloud read_scene(const std::string& path, const SceneReadOptions& options) {
  const ModelFormat& f = options.format == "auto" ? model_format(detect_scene_format(path)) : model_format(options.format);
  return reading(path, [&] {
    GaussianCloud c;
    Progress& progress = options.progress ? *options.progress : null_progress();
    const bool reference = options.network_kernel == NetworkKernel::Eigen;
    if (!f.open) {
      c = f.read(path, options);
    } else if (f.streams && options.model_evaluation == ModelEvaluation::Streamed) {
      // Networks and closed-form slices: streamed unless keys are asked for.
      c = stream_trained_model(std::shared_ptr<const TrainedModel>(open_trained_model(path, f, options)), options.still, reference, progress);
    } else {
      c = sample_trained_model(*open_trained_model(path, f, options), reference, progress);
    }
    c.validate(path);
    partition_static_dynamic(c, options.partition);
    return c;
  });
}

// ---- writers ----

namespace {

void add_column(PlyElement& e, const std::string& name, std::vector<float> values) {
  FILLGS_CHECK_EQ(values.size(), e.count);
  e.property_names.push_back(name);
  e.columns.push_back(std::move(values));
}

/// Standard 3DGS vertex element from per-Gaussian raw values in the given order.
PlyElement standard_vertex(const GaussianCloud& c, const std::vector<uint32_t>& order, const std::vector<Vec3f>& means,
                           const std::vector<Vec3f>& log_scales, const std::vector<Vec4f>& rots,
                           const std::vector<float>& opacity_logits, const float* sh) {
  PlyElement v;
  v.name = "vertex";
  v.count = order.size();
  auto gather = [&](auto f) {
    std::vector<float> col(order.size());
    for (size_t r = 0; r < order.size(); ++r) col[r] = f(order[r]);
    return col;
  };
  const char* xyz[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) add_column(v, xyz[a], gather([&](uint32_t g) { return means[g][a]; }));
  for (const char* n : {"nx", "ny", "nz"}) add_column(v, n, std::vector<float>(order.size(), 0.0f));
  const int K = c.sh_count();
  for (int ch = 0; ch < 3; ++ch)
    add_column(v, "f_dc_" + std::to_string(ch), gather([&](uint32_t g) { return sh[size_t(g) * K * 3 + ch]; }));
  for (int ch = 0; ch < 3; ++ch)
    for (int k = 1; k < K; ++k)
      add_column(v, "f_rest_" + std::to_string(ch * (K - 1) + k - 1),
                 gather([&](uint32_t g) { return sh[(size_t(g) * K + k) * 3 + ch]; }));
  add_column(v, "opacity", gather([&](uint32_t g) { return opacity_logits[g]; }));
  for (int a = 0; a < 3; ++a) add_column(v, "scale_" + std::to_string(a), gather([&](uint32_t g) { return log_scales[g][a]; }));
  for (int a = 0; a < 4; ++a) add_column(v, "rot_" + std::to_string(a), gather([&](uint32_t g) { return rots[g][a]; }));
  return v;
}

std::vector<uint32_t> static_first_order(const GaussianCloud& c) {
  std::vector<uint32_t> order = c.static_ids();
  order.insert(order.end(), c.dynamic_ids.begin(), c.dynamic_ids.end());
  return order;
}

}  // namespace

void write_3dgs_ply(const std::string& path, const GaussianCloud& cloud, double t) {
  FrameGaussians f = frame_at(cloud, t);
  std::vector<Vec3f> log_scales(cloud.size());
  std::vector<float> logits(cloud.size());
  for (size_t g = 0; g < cloud.size(); ++g) {
    log_scales[g] = f.scales[g].array().log();
    // Static Gaussians keep their stored logit exactly; moving ones get logit(opacity(t)).
    logits[g] = cloud.opacity_logits[g];
  }
  for (uint32_t g : cloud.dynamic_ids) logits[g] = logit(f.opacities[g]);
  std::vector<uint32_t> order(cloud.size());
  for (size_t g = 0; g < order.size(); ++g) order[g] = uint32_t(g);
  std::vector<Vec4f> rots = f.rotations;
  for (uint32_t g : cloud.static_ids()) rots[g] = cloud.rotations[g];  // raw, as stored
  // At a key's own time, a keyframed Gaussian is written with the key's raw values, so that
  // frames read from PLYs and written again are the same bytes.
  const KeyframedMotion& km = cloud.keyframed;
  const double u = cloud.motion == MotionModel::Keyframed ? (t - km.first_key_time) / km.key_spacing : -1.0;
  const long key = std::lround(u);
  if (cloud.motion == MotionModel::Keyframed && !km.ex4dgs_edges && km.temporal_opacity.empty() && key >= 0 && key < km.key_count &&
      std::fabs(u - double(key)) < 1e-9) {
    const size_t K = size_t(km.key_count), k = size_t(key);
    for (size_t j = 0; j < cloud.dynamic_ids.size(); ++j) {
      const uint32_t g = cloud.dynamic_ids[j];
      f.means[g] = Eigen::Map<const Vec3f>(&km.positions[(j * K + k) * 3]);
      if (!km.rotations.empty()) rots[g] = Eigen::Map<const Vec4f>(&km.rotations[(j * K + k) * 4]);
      if (!km.log_scales.empty()) log_scales[g] = Eigen::Map<const Vec3f>(&km.log_scales[(j * K + k) * 3]);
      if (!km.opacity_logits.empty()) logits[g] = km.opacity_logits[j * K + k];
    }
  }
  PlyData ply;
  ply.elements.push_back(standard_vertex(cloud, order, f.means, log_scales, rots, logits, f.sh));
  write_ply(path, ply);
}

GaussianCloud bake_tracks(const GaussianCloud& cloud, int frames, bool keyed_bands) {
  if (frames < 2) throw_error("baking tracks needs at least 2 frames (got ", frames, ")");
  GaussianCloud out = cloud;
  out.polynomial = PolynomialMotion{};
  out.keyframed = KeyframedMotion{};
  if (cloud.dynamic_ids.empty()) {
    out.motion = MotionModel::Static;
    out.source.reset();
    out.source_rows.clear();
    return out;
  }
  const size_t M = cloud.dynamic_ids.size(), K = size_t(frames);
  out.keyframed = per_frame_tracks(M, frames);
  KeyframedMotion& km = out.keyframed;
  km.opacity_logits.resize(M * K);
  const bool evaluated = cloud.motion == MotionModel::Evaluated;
  const bool keyed_scales = evaluated || (cloud.motion == MotionModel::Keyframed && !cloud.keyframed.log_scales.empty());
  if (keyed_scales) km.log_scales.resize(M * K * 3);
  const bool keyed_colours = evaluated || (cloud.motion == MotionModel::Keyframed && !cloud.keyframed.colours.empty());
  if (keyed_colours) km.colours.resize(M * K * 3);
  const size_t sh_row = size_t(cloud.sh_count()) * 3, W = sh_row - 3;
  const bool keyed_rest = W > 0 && keyed_colours &&
                          ((evaluated && keyed_bands) || (cloud.motion == MotionModel::Keyframed && !cloud.keyframed.sh_rest.empty()));
  if (keyed_rest) km.sh_rest.resize(M * K * W);
  FrameSampler ev(cloud);
  bool opacity_varies = false;
  for (size_t k = 0; k < K; ++k) {
    const FrameGaussians& f = ev.at(FrameGrid(frames).time(int(k)));
    for (size_t j = 0; j < M; ++j) {
      const uint32_t g = cloud.dynamic_ids[j];
      for (int a = 0; a < 3; ++a) km.positions[(j * K + k) * 3 + a] = f.means[g][a];
      for (int a = 0; a < 4; ++a) km.rotations[(j * K + k) * 4 + a] = f.rotations[g][a];
      if (keyed_scales)
        for (int a = 0; a < 3; ++a) km.log_scales[(j * K + k) * 3 + a] = std::log(f.scales[g][a]);
      if (keyed_colours)
        for (int a = 0; a < 3; ++a) km.colours[(j * K + k) * 3 + a] = f.sh[g * sh_row + a];
      if (keyed_rest) std::copy_n(&f.sh[g * sh_row + 3], W, &km.sh_rest[(j * K + k) * W]);
      km.opacity_logits[j * K + k] = logit(f.opacities[g]);
      if (std::fabs(f.opacities[g] - sigmoid(cloud.opacity_logits[g])) > 1e-6f) opacity_varies = true;
    }
  }
  if (!opacity_varies) km.opacity_logits.clear();
  out.motion = MotionModel::Keyframed;
  out.source.reset();
  out.source_rows.clear();
  canonical_from_first_key(out);
  return out;
}

namespace {

/// Shares of the key tolerances by which frame `b` misses frame `a` at Gaussian s, per property
/// (position, rotation, log-scale, opacity, colour), in the still rule's measures.
std::array<double, 5> key_misses(const FrameGaussians& a, const FrameGaussians& b, size_t s, const KeyTolerance& t) {
  auto share = [](double d, float tol) { return d <= 0.0 ? 0.0 : tol > 0.0f ? d / double(tol) : INFINITY; };
  const double c = std::min(1.0, std::fabs(double(a.rotations[s].dot(b.rotations[s]))));
  double scale = 0;
  for (int k = 0; k < 3; ++k) scale = std::max(scale, std::fabs(std::log(double(a.scales[s][k])) - std::log(double(b.scales[s][k]))));
  const int C = (a.sh_degree + 1) * (a.sh_degree + 1);
  double colour = 0;
  for (int ch = 0; ch < 3; ++ch)
    colour = std::max(colour, double(sh_colour_change(&a.sh[s * size_t(C) * 3], &b.sh[s * size_t(C) * 3], size_t(C), size_t(ch))));
  return {share((a.means[s] - b.means[s]).norm(), t.position), share(2.0 * std::acos(c) * 180.0 / M_PI, t.rotation_degrees),
          share(scale, t.log_scale), share(std::fabs(double(a.opacities[s]) - double(b.opacities[s])), t.opacity),
          share(colour, t.colour)};
}

}  // namespace

KeyChoice choose_keys(const GaussianCloud& cloud, const KeyTolerance& tolerance, size_t sample) {
  KeyChoice kc;
  kc.frames = motion_frames(cloud);
  if (cloud.motion != MotionModel::Evaluated || kc.frames < 2) return kc;
  // The sample: moving Gaussians evenly spread over the set, as a cloud of their own.
  const size_t M = cloud.dynamic_ids.size(), S = std::min(M, std::max<size_t>(sample, 1));
  GaussianCloud sub;
  sub.sh_degree = cloud.sh_degree;
  sub.resize(S);
  const size_t row = size_t(cloud.sh_count()) * 3;
  for (size_t s = 0; s < S; ++s) {
    const size_t j = s * M / S;
    const uint32_t g = cloud.dynamic_ids[j];
    sub.means[s] = cloud.means[g];
    sub.log_scales[s] = cloud.log_scales[g];
    sub.rotations[s] = cloud.rotations[g];
    sub.opacity_logits[s] = cloud.opacity_logits[g];
    std::copy_n(&cloud.sh[size_t(g) * row], row, &sub.sh[s * row]);
    sub.dynamic_ids.push_back(uint32_t(s));
    sub.source_rows.push_back(cloud.source_rows[j]);
  }
  sub.motion = MotionModel::Evaluated;
  sub.source = cloud.source;
  kc.sample = S;
  const int F = kc.frames;
  const FrameGrid grid(F);
  // The network at every frame, every SH coefficient kept (colour is a keyed property too). The
  // higher bands are keyed where they alone change by more than the colour tolerance from
  // frame 0's (E-D3DGS and 4DGaussians deform all 16 coefficients); else the DC alone.
  std::vector<FrameGaussians> truth;
  truth.reserve(size_t(F));
  {
    FrameSampler exact(sub);
    for (int f = 0; f < F; ++f) {
      const FrameGaussians& g = exact.at(grid.time(f));
      FrameGaussians kept;
      kept.sh_degree = g.sh_degree;
      kept.means = g.means, kept.scales = g.scales, kept.rotations = g.rotations, kept.opacities = g.opacities;
      kept.sh_storage.assign(g.sh, g.sh + S * row);
      kept.sh = kept.sh_storage.data();  // the vector's buffer moves with it
      const float* first = f == 0 ? kept.sh : truth[0].sh;
      for (size_t s = 0; s < S; ++s)
        for (size_t a = 0; a < 3; ++a) {
          kc.colour_change = std::max(kc.colour_change, double(sh_colour_change(&kept.sh[s * row], &first[s * row], row / 3, a)));
          kc.keyed_bands = kc.keyed_bands || sh_colour_change(&kept.sh[s * row], &first[s * row], row / 3, a, 1) > tolerance.colour;
        }
      truth.push_back(std::move(kept));
    }
  }
  // Interval 1 keys every frame: exact there, whatever the tolerance.
  kc.keys = F;
  kc.interval = 1.0;
  static const char* kProperty[5] = {"position", "rotation", "scale", "opacity", "colour"};
  for (int interval = 2; interval <= 32; interval *= 2) {
    const int K = (F - 1 + interval - 1) / interval + 1;
    if (K >= kc.keys || K < 2) continue;
    const GaussianCloud keyed = bake_tracks(sub, K, kc.keyed_bands);
    FrameSampler approx(keyed);
    std::array<double, 5> worst{};
    for (int f = 0; f < F; ++f) {
      const FrameGaussians& g = approx.at(grid.time(f));
      for (size_t s = 0; s < S; ++s) {
        const std::array<double, 5> miss = key_misses(truth[size_t(f)], g, s, tolerance);
        for (size_t p = 0; p < 5; ++p) worst[p] = std::max(worst[p], miss[p]);
      }
    }
    const size_t over = size_t(std::max_element(worst.begin(), worst.end()) - worst.begin());
    if (worst[over] > 1.0) {
      kc.limiting = kProperty[over];
      break;
    }
    kc.keys = K;
    kc.interval = double(F - 1) / double(K - 1);
    kc.worst_error = worst[0] * tolerance.position;
    kc.worst_share = worst[over];
  }
  return kc;
}

GaussianCloud keyed_for_training(const GaussianCloud& cloud, KeyChoice* choice, const KeyTolerance& tolerance) {
  KeyChoice kc = choose_keys(cloud, tolerance);
  if (choice) *choice = kc;
  if (cloud.motion != MotionModel::Evaluated) return cloud;
  GaussianCloud keyed = bake_tracks(cloud, std::max(2, kc.keys), kc.keyed_bands);
  std::ostringstream os;
  os << "keyed for training: " << kc.keys << " keys (one every " << kc.interval << " of its " << kc.frames
     << " frames); positions, rotations, scales, opacities and colours (" << (kc.keyed_bands ? "every SH band" : "the SH DC")
     << ") within " << kc.worst_share << " of their tolerances (" << tolerance.position << " world units, " << tolerance.rotation_degrees
     << " degrees, " << tolerance.log_scale << " in log-scale, " << tolerance.opacity << " in opacity, " << tolerance.colour
     << " in colour) of its network at every frame on " << kc.sample << " moving Gaussians";
  if (!kc.limiting.empty()) os << " (" << kc.limiting << " decided the interval)";
  keyed.notes.push_back(os.str());
  return keyed;
}

void write_fillgs_ply(const std::string& path, const GaussianCloud& cloud_in, int frames) {
  if (frames < 2 && cloud_in.motion == MotionModel::Evaluated) frames = motion_frames(cloud_in);  // a key at each of its frames
  const bool native = cloud_in.motion == MotionModel::Static ||
                      (cloud_in.motion == MotionModel::Keyframed && !cloud_in.keyframed.ex4dgs_edges &&
                       cloud_in.keyframed.temporal_opacity.empty() && !cloud_in.keyframed.rotations.empty());
  if (!native && frames < 2)
    throw_error(path, ": ", to_string(cloud_in.motion), " motion must be baked to frames before writing (give a frame count)");
  const GaussianCloud baked = native ? GaussianCloud() : bake_tracks(cloud_in, frames);
  const GaussianCloud& c = native ? cloud_in : baked;
  const std::vector<uint32_t> order = static_first_order(c);
  PlyData ply;
  ply.comments.push_back(kFillgsMagic);
  ply.elements.push_back(standard_vertex(c, order, c.means, c.log_scales, c.rotations, c.opacity_logits, c.sh.data()));
  const size_t M = c.dynamic_ids.size();
  if (M > 0) {
    const KeyframedMotion& km = c.keyframed;
    const int K = km.key_count;
    std::ostringstream kc;
    kc.precision(17);
    kc << "fillgs_keys count=" << K << " first=" << km.first_key_time << " spacing=" << km.key_spacing << " interp="
       << (km.position_interp == KeyInterp::Linear ? "linear" : km.position_interp == KeyInterp::Pchip ? "pchip" : "catmull_rom");
    ply.comments.push_back(kc.str());
    PlyElement tr;
    tr.name = "track";
    tr.count = M;
    auto col = [&](const std::vector<float>& src, int width, int k, int a) {
      std::vector<float> out(M);
      for (size_t j = 0; j < M; ++j) out[j] = src[(j * K + k) * width + a];
      return out;
    };
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 3; ++a) add_column(tr, "motion_xyz_" + std::to_string(k) + "_" + std::to_string(a), col(km.positions, 3, k, a));
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 4; ++a) add_column(tr, "motion_rot_" + std::to_string(k) + "_" + std::to_string(a), col(km.rotations, 4, k, a));
    if (!km.log_scales.empty())
      for (int k = 0; k < K; ++k)
        for (int a = 0; a < 3; ++a) add_column(tr, "motion_scale_" + std::to_string(k) + "_" + std::to_string(a), col(km.log_scales, 3, k, a));
    if (!km.opacity_logits.empty())
      for (int k = 0; k < K; ++k) add_column(tr, "motion_opacity_" + std::to_string(k), col(km.opacity_logits, 1, k, 0));
    if (!km.colours.empty())
      for (int k = 0; k < K; ++k)
        for (int a = 0; a < 3; ++a) add_column(tr, "motion_dc_" + std::to_string(k) + "_" + std::to_string(a), col(km.colours, 3, k, a));
    if (!km.sh_rest.empty()) {  // motion_rest_<k>_<i>: f_rest_<i>'s order (channel-major) at key k
      const int R = c.sh_count() - 1;
      for (int k = 0; k < K; ++k)
        for (int a = 0; a < 3; ++a)
          for (int i = 0; i < R; ++i) add_column(tr, "motion_rest_" + std::to_string(k) + "_" + std::to_string(a * R + i), col(km.sh_rest, 3 * R, k, 3 * i + a));
    }
    ply.elements.push_back(std::move(tr));
  }
  write_ply(path, ply);
}

}  // namespace fillgs
