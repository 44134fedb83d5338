#include "fillgs/train/train.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/json_file.hpp"

#include <nlohmann/json.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <utility>
#include <chrono>
#include <cmath>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <sstream>
#include <unordered_map>

#include "fillgs/base/error.hpp"
#include "fillgs/train/flow.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/base/random.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/model/sh.hpp"
#include "fillgs/io/video.hpp"
#include "train/adam.hpp"

namespace fs = std::filesystem;

namespace fillgs {

void write_colour_correction(const std::string& path, const std::vector<ColourCorrection>& corrections) {
  nlohmann::json j = nlohmann::json::object();
  for (const ColourCorrection& c : corrections)
    j[c.rig] = {{"gain", {c.gain[0], c.gain[1], c.gain[2]}}, {"offset", {c.offset[0], c.offset[1], c.offset[2]}}};
  write_file_atomically(path, j.dump(1) + "\n");
}

void apply_colour_correction(const ColourCorrection& c, std::vector<float>& rgb) {
  for (size_t p = 0; p + 2 < rgb.size(); p += 3)
    for (int ch = 0; ch < 3; ++ch) rgb[p + size_t(ch)] = c.gain[ch] * rgb[p + size_t(ch)] + c.offset[ch];
}

ColourCorrection fold_mean_colour(GaussianCloud& model, std::vector<ColourCorrection>& corrections) {
  ColourCorrection mean{"mean", Vec3f::Zero(), Vec3f::Zero()};
  if (corrections.empty()) return {"mean", Vec3f::Ones(), Vec3f::Zero()};
  for (const ColourCorrection& c : corrections) mean.gain += c.gain, mean.offset += c.offset;
  mean.gain /= float(corrections.size());
  mean.offset /= float(corrections.size());
  if (!(mean.gain.minCoeff() > 0)) throw_error("colour correction: the cameras' mean gain is not positive");
  // colour = C0 · dc + 0.5 + Σ higher terms; ḡ ⊙ colour + ō needs dc' = ḡ dc + (ḡ/2 + ō − 1/2) / C0.
  const size_t K = size_t(model.sh_count());
  for (size_t g = 0; g < model.size(); ++g)
    for (size_t k = 0; k < K; ++k)
      for (int ch = 0; ch < 3; ++ch) {
        float& x = model.sh[(g * K + k) * 3 + size_t(ch)];
        x *= mean.gain[ch];
        if (k == 0) x += (0.5f * mean.gain[ch] + mean.offset[ch] - 0.5f) / kSHC0;
      }
  for (ColourCorrection& c : corrections) {
    c.gain = c.gain.cwiseQuotient(mean.gain);
    c.offset -= c.gain.cwiseProduct(mean.offset);
  }
  return mean;
}

std::vector<ColourCorrection> read_colour_correction(const std::string& path) {
  const nlohmann::json j = read_json_file(path);
  if (!j.is_object()) throw_error(path, ": colour corrections must be an object of cameras");
  std::vector<ColourCorrection> out;
  for (const auto& [rig, e] : j.items()) {
    ColourCorrection c;
    c.rig = rig;
    for (const char* key : {"gain", "offset"}) {
      if (!e.is_object() || !e.contains(key) || !e[key].is_array() || e[key].size() != 3)
        throw_error(path, ": camera '", rig, "' needs '", key, "' as three numbers");
      for (int k = 0; k < 3; ++k) {
        const nlohmann::json& x = e[key][size_t(k)];
        if (!x.is_number() || !std::isfinite(x.get<double>())) throw_error(path, ": camera '", rig, "' ", key, "[", k, "] is not a finite number");
        // A gain scales the camera's colours and is divided by when the model is folded to
        // the mean camera: a gain of 0 (or one far from 1) is no camera's exposure.
        if (std::string(key) == "gain" && !(x.get<double>() >= 1e-3 && x.get<double>() <= 1e3))
          throw_error(path, ": camera '", rig, "' gain[", k, "] is ", x.get<double>(), ", outside [0.001, 1000]");
        (std::string(key) == "gain" ? c.gain : c.offset)[k] = x.get<float>();
      }
    }
    out.push_back(c);
  }
  return out;
}

// ---------------------------------------------------------------------------------
// Points and initialisation

PointSet read_points(const std::string& path) {
  PointSet ps;
  const std::string ext = fs::path(path).extension().string();
  if (!fs::is_regular_file(path)) throw_error(path, ": point file not found");
  if (ext == ".ply") {
    const PlyData ply = read_ply(path);
    const PlyElement& v = ply.element("vertex");
    const auto &x = v.finite_column("x"), &y = v.finite_column("y"), &z = v.finite_column("z");
    const bool rgb = v.has("red") && v.has("green") && v.has("blue");
    float scale = 1.0f;
    if (rgb)
      for (const char* n : {"red", "green", "blue"})
        for (float c : v.column(n)) scale = std::max(scale, c);
    scale = scale > 1.0f ? 255.0f : 1.0f;
    for (size_t i = 0; i < v.count; ++i) {
      ps.positions.emplace_back(x[i], y[i], z[i]);
      ps.colours.push_back(rgb ? Vec3f(v.column("red")[i], v.column("green")[i], v.column("blue")[i]) / scale
                               : Vec3f(0.5f, 0.5f, 0.5f));
    }
  } else if (ext == ".bin") {
    // COLMAP points3D.bin: u64 count; per point u64 id, f64 x y z, u8 r g b, f64 error,
    // u64 track length, then that many (i32 image, i32 point2D). Every count is checked
    // against the bytes left before it is used.
    const std::string bytes = read_file(path);
    size_t at = 0;
    auto take = [&](void* out, size_t n, const char* what) {
      if (n > bytes.size() - at) throw_error(path, ": truncated in ", what, " at byte ", at);
      std::memcpy(out, bytes.data() + at, n);
      at += n;
    };
    uint64_t count = 0;
    take(&count, 8, "the point count");
    if (count > (bytes.size() - at) / 43) throw_error(path, ": claims ", count, " points, the file holds at most ", (bytes.size() - at) / 43);
    for (uint64_t i = 0; i < count; ++i) {
      uint64_t id = 0, track = 0;
      double xyz[3], error = 0;
      uint8_t rgb[3];
      take(&id, 8, "a point id");
      take(xyz, 24, "a position");
      take(rgb, 3, "a colour");
      take(&error, 8, "an error");
      take(&track, 8, "a track length");
      if (track > (bytes.size() - at) / 8) throw_error(path, ": point ", id, " claims a track of ", track, ", longer than the file");
      at += size_t(track) * 8;
      if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) throw_error(path, ": point ", id, " is not finite");
      ps.positions.emplace_back(float(xyz[0]), float(xyz[1]), float(xyz[2]));
      ps.colours.emplace_back(rgb[0] / 255.0f, rgb[1] / 255.0f, rgb[2] / 255.0f);
    }
    if (at != bytes.size()) throw_error(path, ": ", bytes.size() - at, " bytes after the last point");
  } else {
    // COLMAP points3D.txt: POINT3D_ID X Y Z R G B ERROR TRACK[]
    require_regular_file(path);
    std::ifstream in(path);
    std::string line;
    size_t line_no = 0;
    while (std::getline(in, line)) {
      ++line_no;
      if (line.empty() || line[0] == '#') continue;
      std::istringstream ls(line);
      long id;
      double X, Y, Z;
      int r, g, b;
      if (!(ls >> id >> X >> Y >> Z >> r >> g >> b)) throw_error(path, ": line ", line_no, ": expected 'ID X Y Z R G B ...'");
      if (!std::isfinite(X) || !std::isfinite(Y) || !std::isfinite(Z)) throw_error(path, ": point ", id, " is not finite");
      ps.positions.emplace_back(float(X), float(Y), float(Z));
      ps.colours.emplace_back(r / 255.0f, g / 255.0f, b / 255.0f);
    }
  }
  if (ps.positions.empty()) throw_error(path, ": the point cloud is empty");
  return ps;
}

void write_points_ply(const std::string& path, const PointSet& pts) {
  PlyData ply;
  PlyElement v;
  v.name = "vertex";
  v.count = pts.positions.size();
  v.property_names = {"x", "y", "z", "red", "green", "blue"};
  v.columns.assign(6, std::vector<float>(v.count));
  for (size_t i = 0; i < v.count; ++i)
    for (int a = 0; a < 3; ++a) {
      v.columns[size_t(a)][i] = pts.positions[i][a];
      v.columns[size_t(3 + a)][i] = std::round(std::clamp(pts.colours[i][a], 0.0f, 1.0f) * 255.0f);
    }
  ply.elements.push_back(v);
  write_ply(path, ply);
}

ModelParams<float> init_from_points(const PointSet& pts) {
  const size_t n = pts.positions.size();
  if (n == 0) throw_error("initialisation: the point cloud is empty");
  // Mean squared distance to the 3 nearest neighbours through a uniform grid.
  Vec3f lo = pts.positions[0], hi = lo;
  for (const Vec3f& p : pts.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const float diag = std::max((hi - lo).norm(), 1e-6f);
  const float cell = std::max(diag / std::cbrt(float(n)), 1e-6f);
  auto key = [&](int x, int y, int z) { return (uint64_t(uint32_t(x)) << 42) ^ (uint64_t(uint32_t(y)) << 21) ^ uint64_t(uint32_t(z)); };
  auto cell_of = [&](const Vec3f& p, int* c) {
    for (int a = 0; a < 3; ++a) c[a] = int(std::floor((p[a] - lo[a]) / cell));
  };
  std::unordered_map<uint64_t, std::vector<uint32_t>> grid;
  for (uint32_t i = 0; i < n; ++i) {
    int c[3];
    cell_of(pts.positions[i], c);
    grid[key(c[0], c[1], c[2])].push_back(i);
  }
  std::vector<float> d2mean(n, 0.0f);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      int c[3];
      cell_of(pts.positions[i], c);
      float best[3] = {INFINITY, INFINITY, INFINITY};
      for (int ring = 1; ring <= 64; ++ring) {
        for (int dx = -ring; dx <= ring; ++dx)
          for (int dy = -ring; dy <= ring; ++dy)
            for (int dz = -ring; dz <= ring; ++dz) {
              if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring && ring > 1) continue;
              auto it = grid.find(key(c[0] + dx, c[1] + dy, c[2] + dz));
              if (it == grid.end()) continue;
              for (uint32_t j : it->second) {
                if (j == i) continue;
                const float d = (pts.positions[j] - pts.positions[i]).squaredNorm();
                if (d < best[2]) {
                  best[2] = d;
                  std::sort(best, best + 3);
                }
              }
            }
        // Every point within `ring` cells has been seen: stop when the third is closer.
        if (best[2] <= float(ring) * cell * float(ring) * cell) break;
      }
      float s = 0;
      int k = 0;
      for (float b : best)
        if (std::isfinite(b)) s += b, ++k;
      d2mean[i] = k ? s / float(k) : cell * cell;
    }
  });
  ModelParams<float> p;
  p.sh_degree = 0;
  p.means.resize(3 * n);
  p.log_scales.resize(3 * n);
  p.rotations.assign(4 * n, 0.0f);
  p.opacity_logits.assign(n, logit(0.1f));
  p.sh.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      p.means[3 * i + a] = pts.positions[i][a];
      p.log_scales[3 * i + a] = std::log(std::sqrt(std::max(d2mean[i], 1e-7f)));
      p.sh[3 * i + a] = rgb_to_sh_dc(pts.colours[i][a]);
    }
    p.rotations[4 * i] = 1.0f;
  }
  return p;
}

PointSet pseudo_sfm_points(const GaussianCloud& scene, double t, double fraction, double noise, uint64_t seed,
                           const std::vector<Camera>& observers, int min_views) {
  const FrameGaussians f = frame_at(scene, t);
  std::vector<int> seen(f.size(), 0);
  for (const Camera& cam : observers) {
    RenderOptions ro;
    ro.rgb = false;
    ro.max_weights = true;
    const RenderOutput r = render(f, cam, ro);
    for (size_t g = 0; g < f.size(); ++g) seen[g] += r.max_weight[g] >= kMinAlpha;
  }
  PointSet ps;
  const int K = scene.sh_count();
  for (size_t g = 0; g < f.size(); ++g) {
    if (uniform(seed, g, 0) >= fraction) continue;
    if (!observers.empty() && seen[g] < min_views) continue;
    Vec3f p = f.means[g];
    for (int a = 0; a < 3; ++a) p[a] += float(noise * normal(seed, g, 1 + a));
    ps.positions.push_back(p);
    Vec3f col;
    for (int c = 0; c < 3; ++c) col[c] = std::clamp(scene.sh[g * K * 3 + c] * kSHC0 + 0.5f, 0.0f, 1.0f);
    ps.colours.push_back(col);
  }
  return ps;
}

// ---------------------------------------------------------------------------------
// Options

TrainOptions TrainOptions::scaled(int iterations) {
  TrainOptions o;
  const double f = iterations / 30000.0;
  o.iterations = iterations;
  o.sh_increase_interval = std::max(1, int(std::lround(1000 * f)));
  o.densify_from = std::max(1, int(std::lround(500 * f)));
  o.densify_until = int(std::lround(15000 * f));
  o.densify_interval = std::max(100, int(std::lround(100 * f)));
  o.opacity_reset_interval = std::max(o.densify_interval * 5, int(std::lround(3000 * f)));
  return o;
}

// ---------------------------------------------------------------------------------
// Trainer

void check_trainable(const GaussianCloud& cloud, const std::string& source) {
  auto refuse = [&](size_t g, const char* what, double v, const char* bound) {
    throw_error(source, ": Gaussian ", g, " has ", what, " ", v, ", beyond what training keeps finite (", bound, ")");
  };
  for (size_t g = 0; g < cloud.size(); ++g) {
    for (int k = 0; k < 3; ++k) {
      const double m = cloud.means[g][k], s = cloud.log_scales[g][k];
      if (!(std::abs(m) <= kMaxTrainCoordinate)) refuse(g, "a position coordinate", m, "|x| <= 1e7");
      if (!(s >= kMinTrainLogScale && s <= kMaxTrainLogScale)) refuse(g, "a log-scale", s, "-30 to 20");
    }
    const int C = cloud.sh_count() * 3;
    for (int c = 0; c < C; ++c) {
      const double v = cloud.sh[g * size_t(C) + size_t(c)];
      if (!(std::abs(v) <= kMaxTrainSh)) refuse(g, "an SH coefficient", v, "|c| <= 1e4");
    }
  }
  const std::vector<float>& keys = cloud.keyframed.positions;
  for (size_t i = 0; i < keys.size(); ++i)
    if (!(std::abs(keys[i]) <= kMaxTrainCoordinate)) refuse(i / 3, "a key position coordinate", keys[i], "|x| <= 1e7");
}

Trainer::Trainer(const Dataset& data, ModelParams<float> initial, const TrainOptions& options)
    : data_(&data), options_(options), params_(std::move(initial)) {
  if (params_.size() == 0) throw_error("training: the initial model has no Gaussians");
  for (size_t i = 0; i < params_.means.size(); ++i)
    if (!(std::abs(params_.means[i]) <= kMaxTrainCoordinate))
      throw_error("training: initial Gaussian ", i / 3, " stands at coordinate ", params_.means[i], ", beyond what training keeps finite (|x| <= 1e7)");
  extent_ = data.camera_extent().second;
  if (params_.key_count == 0) set_key_layout(params_, data.frames(), options_.key_interval_frames);
  // Densification must reach the frames the time window adds last: content that appears
  // late (from behind an occluder, or moving in) needs Gaussians of its own.
  if (options_.allow_dynamic && options_.time_ramp > 0 && data.frames() > 1)
    options_.densify_until = std::max(options_.densify_until, int(std::lround((options_.time_ramp + options_.densify_after_ramp) * options_.iterations)));
  find_fixed_rigs();
  build_change_masks();
  if (!options_.initial_colour.empty() && !options_.colour_correction)
    throw_error("training: initial colour corrections given without colour correction");
  for (const std::string& rig : data.rigs()) {
    colour_.push_back({rig, Vec3f::Ones(), Vec3f::Zero()});
    for (const ColourCorrection& c : options_.initial_colour)
      if (c.rig == rig) colour_.back() = c;
  }
  colour_m_.assign(colour_.size(), {});
  colour_v_.assign(colour_.size(), {});
  colour_steps_.assign(colour_.size(), 0);
  for (const TrainView& v : data.views())
    view_rig_.push_back(int(std::find(data.rigs().begin(), data.rigs().end(), v.rig) - data.rigs().begin()));
  // Gaussians that move in the model given (fine-tuning) keep their right to move.
  on_change_.assign(params_.size(), change_masks_.empty() ? 1 : 0);
  for (uint32_t g : params_.dynamic_ids) on_change_[g] = 1;
  if (options_.allow_dynamic && data.frames() > 1) {
    if (options_.keyed_opacity) add_key_opacities(params_);
    if (options_.motion == MotionLearning::All) key_every_gaussian(params_);
  }
  // Views by frame, for the time curriculum.
  const int F = std::max(1, data.frames());
  views_by_frame_.resize(data.views().size());
  std::iota(views_by_frame_.begin(), views_by_frame_.end(), size_t(0));
  std::stable_sort(views_by_frame_.begin(), views_by_frame_.end(),
                   [&](size_t a, size_t b) { return data.views()[a].frame < data.views()[b].frame; });
  frame_begin_.assign(size_t(F) + 1, 0);
  for (const TrainView& v : data.views()) frame_begin_[size_t(FrameGrid(F).clamp(v.frame)) + 1] += 1;
  for (int f = 0; f < F; ++f) frame_begin_[size_t(f) + 1] += frame_begin_[size_t(f)];
  adam_m_ = params_.zeros_like();
  adam_v_ = params_.zeros_like();
  reset_stats();
}

void Trainer::find_fixed_rigs() {
  // Views of each rig camera by frame; a camera counts when it holds one pose and size in
  // every view it has.
  std::map<std::string, std::vector<long>> by_rig;
  const int F = std::max(1, data_->frames());
  for (size_t v = 0; v < data_->views().size(); ++v) {
    std::vector<long>& r = by_rig[data_->views()[v].rig];
    r.resize(size_t(F), -1);
    r[size_t(FrameGrid(F).clamp(data_->views()[v].frame))] = long(v);
  }
  fixed_rigs_.clear();
  for (const auto& [rig, frames] : by_rig) {
    const Camera* c0 = nullptr;
    bool fixed = true;
    for (long v : frames) {
      if (v < 0) continue;
      const Camera& c = data_->views()[size_t(v)].camera;
      if (!c0) c0 = &c;
      fixed = fixed && c.width == c0->width && c.height == c0->height && (c.R - c0->R).norm() < 1e-9 && (c.t - c0->t).norm() < 1e-9;
    }
    if (fixed && c0) fixed_rigs_.push_back(frames);
  }
}

void Trainer::build_change_masks() {
  view_mask_.assign(data_->views().size(), -1);
  change_masks_.clear();
  if (!options_.motion_where_images_change || data_->frames() < 3) return;
  // A fixed camera over 3 or more frames.
  for (const std::vector<long>& frames : fixed_rigs_) {
    std::vector<size_t> vs;
    for (long v : frames)
      if (v >= 0) vs.push_back(size_t(v));
    if (vs.size() < 3) continue;
    const Camera& c0 = data_->views()[vs[0]].camera;
    const size_t P = size_t(c0.width) * size_t(c0.height);
    std::vector<uint8_t> mask(P, 0);
    if (options_.change_from_masks && data_->has_masks()) {
      for (size_t v : vs) {
        const std::vector<uint8_t> fg = data_->mask(v);
        for (size_t p = 0; p < P; ++p) mask[p] |= fg[p];
      }
    } else {
      std::vector<float> lo(P * 3, 1e9f), hi(P * 3, -1e9f);
      for (size_t v : vs) {
        const std::vector<float> im = data_->image(v);
        for (size_t i = 0; i < P * 3; ++i) lo[i] = std::min(lo[i], im[i]), hi[i] = std::max(hi[i], im[i]);
      }
      for (size_t p = 0; p < P; ++p)
        for (int ch = 0; ch < 3; ++ch) mask[p] |= hi[p * 3 + ch] - lo[p * 3 + ch] > float(options_.change_threshold);
    }
    // Dilate (square, change_dilation pixels): a Gaussian's mean may sit just outside what it covers.
    const int r = std::max(0, options_.change_dilation), W = c0.width, H = c0.height;
    std::vector<uint8_t> grown(P, 0);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        if (!mask[size_t(y) * W + x]) continue;
        for (int dy = -r; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx >= 0 && yy >= 0 && xx < W && yy < H) grown[size_t(yy) * W + xx] = 1;
          }
      }
    change_masks_.push_back(std::move(grown));
    for (size_t v : vs) view_mask_[v] = int(change_masks_.size()) - 1;
  }
}

std::vector<double> Trainer::changing_share() const {
  std::vector<double> out(view_mask_.size(), -1.0);
  for (size_t v = 0; v < out.size(); ++v)
    if (view_mask_[v] >= 0) {
      const std::vector<uint8_t>& m = change_masks_[size_t(view_mask_[v])];
      out[v] = double(std::count(m.begin(), m.end(), 1)) / double(m.size());
    }
  return out;
}

void Trainer::carry(const std::vector<uint32_t>& sources) {
  std::vector<uint8_t> next(sources.size());
  for (size_t i = 0; i < sources.size(); ++i) next[i] = on_change_[sources[i]];
  on_change_ = std::move(next);
}

void Trainer::reset_stats() {
  const size_t n = params_.size();
  const int B = std::max(1, options_.time_bins);
  grad_accum_.assign(n, 0.0f);
  max_radii_.assign(n, 0.0f);
  denom_.assign(n, 0);
  bin_grad_.assign(n * B * 3, 0.0f);
  bin_count_.assign(n * B, 0);
}

int Trainer::window_last_frame(int iteration) const {
  const int F = data_->frames();
  const int ramp = int(std::lround(options_.time_ramp * options_.iterations));
  if (F <= 1 || ramp <= 0 || iteration >= ramp || !options_.allow_dynamic) return F - 1;
  // Each frame is the newest of the window for ramp / F iterations.
  return std::min(F - 1, int(double(F) * double(iteration) / double(ramp)));
}

int Trainer::key_interval_of_frame(int frame) const {
  const int K = params_.key_count, F = data_->frames();
  if (K < 2 || F < 2) return 0;
  const double t = FrameGrid(F).time(frame);
  return std::clamp(int(std::floor((t - params_.first_key_time) / params_.key_spacing + 1e-9)), 0, K - 2);
}

size_t Trainer::pick_view() const {
  const int last = window_last_frame(iteration_);
  if (last < data_->frames() - 1) {
    // Time curriculum: a frame of the window, one of its newest with probability frontier_share.
    const bool frontier = uniform(options_.seed ^ 0xc0ffee, uint64_t(iteration_), 0) < options_.frontier_share;
    const int first = frontier ? std::max(0, last - std::max(1, options_.frontier_frames) + 1) : 0;
    const size_t lo = frame_begin_[size_t(first)], hi = frame_begin_[size_t(last) + 1];
    if (hi > lo) {
      const size_t k = lo + std::min(hi - lo - 1, size_t(uniform(options_.seed ^ 0xc0ffee, uint64_t(iteration_), 1) * double(hi - lo)));
      return views_by_frame_[k];
    }
  }
  // A fresh permutation of the views every epoch, like 3DGS's shuffled camera stack.
  const size_t V = data_->views().size();
  const uint64_t epoch = uint64_t(iteration_) / V, pos = uint64_t(iteration_) % V;
  std::vector<size_t> perm(V);
  std::iota(perm.begin(), perm.end(), 0);
  for (size_t i = V; i-- > 1;) std::swap(perm[i], perm[size_t(uniform(options_.seed, epoch, i) * double(i + 1))]);
  return perm[pos];
}

void Trainer::step() {
  if (iteration_ > 0 && options_.sh_increase_interval > 0 && iteration_ % options_.sh_increase_interval == 0 &&
      params_.sh_degree < options_.max_sh_degree)
    raise_sh_degree();
  if (iteration_ > 0) {
    const int last = window_last_frame(iteration_), before = window_last_frame(iteration_ - 1);
    const bool entered = key_interval_of_frame(last) > key_interval_of_frame(before);
    if (entered) enter_key_interval();
    if (options_.flow_keys && last > before && (entered || before == 0)) place_keys_by_flow(before);
  }
  if (iteration_ > 0 && options_.motion == MotionLearning::All && options_.freeze_distance > 0 &&
      window_last_frame(iteration_) == data_->frames() - 1 && window_last_frame(iteration_ - 1) < data_->frames() - 1)
    frozen_ = freeze_still();
  // A refined view with probability refined_share (seeded by the iteration), else a real one.
  const RefinedView* refined = nullptr;
  if (!refined_.empty() && uniform(options_.seed ^ 0x5eed, uint64_t(iteration_), 0) < options_.refined_share)
    refined = &refined_[size_t(uniform(options_.seed ^ 0x5eed, uint64_t(iteration_), 1) * double(refined_.size())) % refined_.size()];
  const size_t v = refined ? 0 : pick_view();
  if (!refined) {
    if (view_draws_.size() != data_->views().size()) view_draws_.assign(data_->views().size(), 0);
    ++view_draws_[v];
  }
  TrainView refined_view;
  if (refined) refined_view.camera = refined->camera;
  const TrainView& view = refined ? refined_view : data_->views()[v];
  const std::vector<float> target = refined ? refined->rgb : data_->image(v);
  const float* loss_weights = refined ? refined->weight.data() : nullptr;
  DiffFrame<float> frame;
  params_at(params_, view.camera.time, &frame, /*keep_for_backward=*/true);
  DiffRenderOptions ro;
  ro.background = options_.background;
  DiffRasterizer<float> ras;
  ras.forward(frame, view.camera, ro);
  const int W = view.camera.width, H = view.camera.height;
  std::vector<float> dimg(size_t(W) * H * 3);
  // A real view of a corrected camera is compared as gain ⊙ render + offset.
  std::vector<float> corrected;
  int colour_rig = -1;
  if (!refined && options_.colour_correction) {
    corrected = ras.image();
    colour_rig = correct_colour(v, corrected);
  }
  const float* rendered = colour_rig >= 0 ? corrected.data() : ras.image().data();
  const LossValue lv = photometric_loss<float>(rendered, target.data(), W, H, loss_weights, options_.lambda_dssim, dimg.data());
  if (colour_rig >= 0) colour_backward(colour_rig, ras.image(), dimg.data());
  DiffFrameGrad<float> fg;
  ras.backward(dimg.data(), nullptr, nullptr, &fg);
  grad_.set_zeros_like(params_);
  params_at_backward(params_, view.camera.time, fg, &grad_, &frame);

  // Densification statistics (3DGS: norm of the NDC-space mean gradient, per view seen).
  const int B = std::max(1, options_.time_bins);
  // Time bins over the trained window (the whole video once the ramp is over).
  const int F = std::max(2, data_->frames());
  const double window_end = FrameGrid(F).time(std::max(1, window_last_frame(iteration_)));
  const int bin = std::clamp(int(view.camera.time / window_end * B), 0, B - 1);
  std::vector<uint8_t> moving(params_.size(), 0);
  for (uint32_t g : params_.dynamic_ids) moving[g] = 1;
  const std::vector<uint8_t>* change = !refined && view_mask_[v] >= 0 ? &change_masks_[size_t(view_mask_[v])] : nullptr;
  for (size_t g = 0; g < params_.size(); ++g) {
    if (ras.radii()[g] <= 0) continue;
    if (change && !on_change_[g]) {
      const Vec3d px = view.camera.project(Vec3d(frame.means[3 * g], frame.means[3 * g + 1], frame.means[3 * g + 2]));
      const int x = int(std::floor(px.x())), y = int(std::floor(px.y()));
      if (px.z() > 0 && x >= 0 && y >= 0 && x < W && y < H) on_change_[g] = (*change)[size_t(y) * size_t(W) + size_t(x)];
    }
    const float gx = fg.screen[2 * g] * 0.5f * float(W), gy = fg.screen[2 * g + 1] * 0.5f * float(H);
    grad_accum_[g] += std::sqrt(gx * gx + gy * gy);
    denom_[g] += 1;
    max_radii_[g] = std::max(max_radii_[g], float(ras.radii()[g]));
    if (!moving[g]) {
      for (int a = 0; a < 3; ++a) bin_grad_[(g * B + bin) * 3 + a] += fg.means[3 * g + a];
      bin_count_[g * B + bin] += 1;
    }
  }
  adam_step();
  ++iteration_;

  const int it = iteration_;
  if (it < options_.densify_until && it > options_.densify_from && it % options_.densify_interval == 0) {
    DensifyRecord rec;
    rec.iteration = it;
    if (options_.allow_dynamic && options_.motion == MotionLearning::All) rec.made_static = fold_unchanging();
    if (options_.allow_dynamic && (options_.motion == MotionLearning::Promote || window_last_frame(it) == data_->frames() - 1))
      rec.promoted = promote_static();
    densify_and_prune(opacity_was_reset_, &rec);
    rec.gaussians = params_.size();
    rec.dynamic = params_.dynamic_count();
    densify_log_.push_back(rec);
  }
  if (options_.opacity_reset_interval > 0 && it < options_.densify_until && it % options_.opacity_reset_interval == 0)
    reset_opacity();

  // Running status.
  const double p = std::min(99.0, psnr(rendered, target.data(), W, H, 3));
  const double a = status_.iteration == 0 ? 1.0 : 0.05;
  status_.loss = (1 - a) * status_.loss + a * lv.total;
  status_.psnr = (1 - a) * status_.psnr + a * p;
  status_.iteration = it;
  status_.gaussians = params_.size();
  status_.dynamic = params_.dynamic_count();
  status_.window_frames = window_last_frame(iteration_) + 1;
  loss_history_.push_back(float(lv.total));
}

void Trainer::enter_key_interval() {
  // The window has entered key interval i: keys i+1 on continue the motion of keys i−1, i.
  const int i = key_interval_of_frame(window_last_frame(iteration_));
  if (i < 1 || params_.dynamic_count() == 0) return;
  extrapolate_keys(params_, i + 1, float(options_.extrapolate_min_step));
  restart_key_moments(i + 1, false);
}

void Trainer::restart_key_moments(int from, bool positions_only) {
  const size_t K = size_t(params_.key_count), k0 = size_t(from);
  for (ModelParams<float>* m : {&adam_m_, &adam_v_})
    for (size_t j = 0; j < m->dynamic_count(); ++j) {
      std::fill(m->key_positions.begin() + (j * K + k0) * 3, m->key_positions.begin() + (j + 1) * K * 3, 0.0f);
      if (positions_only) continue;
      std::fill(m->key_rotations.begin() + (j * K + k0) * 4, m->key_rotations.begin() + (j + 1) * K * 4, 0.0f);
      if (m->keyed_opacity) std::fill(m->key_opacity_logits.begin() + j * K + k0, m->key_opacity_logits.begin() + (j + 1) * K, 0.0f);
      const size_t S = size_t(m->sh_count()) * 3;
      if (!m->key_sh.empty()) std::fill(m->key_sh.begin() + ptrdiff_t((j * K + k0) * S), m->key_sh.begin() + ptrdiff_t((j + 1) * K * S), 0.0f);
    }
}

void Trainer::place_keys_by_flow(int f0) {
  const int F = data_->frames(), K = params_.key_count;
  const size_t D = params_.dynamic_count();
  if (K < 3 || D == 0 || F < 2) return;
  auto key_frame = [&](int k) { return (params_.first_key_time + k * params_.key_spacing) * (F - 1); };
  int k1 = 0;
  while (k1 < K && key_frame(k1) <= f0 + 1e-9) ++k1;
  if (k1 >= K) return;
  const int targets = k1 + 1 < K ? 2 : 1;
  // The frames each target key stands for, as far as the video goes.
  int frame_end[2] = {0, 0};
  double stretch[2] = {1, 1};
  for (int m = 0; m < targets; ++m) {
    const double fk = key_frame(k1 + m);
    frame_end[m] = std::min(F - 1, int(std::lround(fk)));
    if (frame_end[m] > f0) stretch[m] = (fk - f0) / double(frame_end[m] - f0);
  }
  const int last = frame_end[targets - 1];
  if (last <= f0) return;
  DiffFrame<float> frame;
  params_at(params_, FrameGrid(F).time(f0), &frame);
  const size_t N = frame.size();
  std::vector<Mat3d> A(D * 2, Mat3d::Zero());
  std::vector<Vec3d> b(D * 2, Vec3d::Zero());
  std::vector<float> depth(N);
  std::vector<double> nearest(D, 1e300);  // distance to the nearest camera that follows it
  for (const std::vector<long>& vs : fixed_rigs_) {  // the fixed cameras with a view at every frame from f0 to last
    bool complete = true;
    for (int f = f0; f <= last; ++f) complete = complete && vs[size_t(f)] >= 0;
    if (!complete) continue;
    const Camera& cam = data_->views()[size_t(vs[size_t(f0)])].camera;
    const int W = cam.width, H = cam.height;
    const int mask = options_.flow_changing_only ? view_mask_[size_t(vs[size_t(f0)])] : -1;
    const std::vector<uint8_t>* changing = mask >= 0 ? &change_masks_[size_t(mask)] : nullptr;
    // What the camera sees at f0: expected depth through the model.
    for (size_t g = 0; g < N; ++g)
      depth[g] = float((cam.R * Vec3d(frame.means[3 * g], frame.means[3 * g + 1], frame.means[3 * g + 2]) + cam.t).z());
    DiffRenderOptions ro;
    ro.features = depth.data();
    ro.feature_channels = 1;
    DiffRasterizer<float> ras;
    ras.forward(frame, cam, ro);
    std::vector<FlowField> forward, backward;
    for (int f = f0; f < last; ++f) {
      const std::vector<float> a = data_->image(size_t(vs[size_t(f)])), c = data_->image(size_t(vs[size_t(f + 1)]));
      forward.push_back(optical_flow(a, c, W, H));
      backward.push_back(optical_flow(c, a, W, H));
    }
    for (size_t j = 0; j < D; ++j) {
      const uint32_t g = params_.dynamic_ids[j];
      const Vec3d p(frame.means[3 * g], frame.means[3 * g + 1], frame.means[3 * g + 2]);
      const Vec3d q = cam.R * p + cam.t;
      if (q.z() <= 1e-6) continue;
      const double x = cam.fx * q.x() / q.z() + cam.cx, y = cam.fy * q.y() / q.z() + cam.cy;
      if (!(x >= 0 && y >= 0 && x < W && y < H)) continue;
      const size_t px = size_t(y) * size_t(W) + size_t(x);
      // Only where this camera's images change: still content keeps the keys it trained.
      if (changing && !(*changing)[px]) continue;
      const float alpha = ras.alpha()[px];
      if (alpha < 0.5f) continue;
      // Only the front surface: a Gaussian behind what the pixel shows does not move with its flow.
      const double size = std::max({frame.scales[3 * g], frame.scales[3 * g + 1], frame.scales[3 * g + 2]});
      if (q.z() > ras.features()[px] / alpha * 1.05 + 3.0 * size) continue;
      Eigen::Matrix<double, 2, 3> J;
      J << cam.fx / q.z(), 0, -cam.fx * q.x() / (q.z() * q.z()), 0, cam.fy / q.z(), -cam.fy * q.y() / (q.z() * q.z());
      J = J * cam.R;
      for (int m = 0; m < targets; ++m) {
        if (frame_end[m] <= f0) continue;
        const auto to = chain_flow(forward, backward, x, y, size_t(frame_end[m] - f0), options_.flow_tolerance);
        if (!to) continue;
        const Eigen::Vector2d d = Eigen::Vector2d(to->first - x, to->second - y) * stretch[m];
        nearest[j] = std::min(nearest[j], q.z());
        A[j * 2 + size_t(m)] += J.transpose() * J;
        b[j * 2 + size_t(m)] += J.transpose() * d;
      }
    }
  }
  // Least squares per Gaussian and key.
  const size_t Ks = size_t(K);
  bool any = false;
  for (size_t j = 0; j < D; ++j) {
    const uint32_t g = params_.dynamic_ids[j];
    const Vec3d p(frame.means[3 * g], frame.means[3 * g + 1], frame.means[3 * g + 2]);
    for (int m = 0; m < targets; ++m) {
      const Mat3d& a = A[j * 2 + size_t(m)];
      const double tr = a.trace();
      if (!(tr > 0)) continue;
      ++flow_tried_;
      // Ridge at 1% of the mean eigenvalue: directions the cameras barely constrain (depth from
      // nearby cameras, where flow noise of 0.2 px is metres) stay put.
      const Vec3d step = (a + 0.01 * tr / 3.0 * Mat3d::Identity()).ldlt().solve(b[j * 2 + size_t(m)]);
      // A step of half the viewing distance or more is a flow error, not motion.
      if (!step.allFinite() || step.norm() > 0.5 * nearest[j]) continue;
      float* key = &params_.key_positions[(j * Ks + size_t(k1 + m)) * 3];
      for (int c = 0; c < 3; ++c) key[c] = float(p[c] + step[c]);
      ++flow_placed_;
      any = true;
    }
  }
  if (!any) return;
  // Later keys continue the placed ones; the optimiser's moments restart for every key moved.
  if (k1 + targets < K) extrapolate_keys(params_, k1 + targets, float(options_.extrapolate_min_step));
  restart_key_moments(k1, true);
}

void Trainer::motion_sparsity_step(double key_lr) {
  // An L1 step per key value towards the mean of its Gaussian's keys, τ = sparsity × the
  // learning rate. Adam moves a value by about lr × |m̂|/√v̂ per step: a key that follows
  // motion (gradients of one sign whenever its frames are drawn) moves faster than τ and
  // keeps its motion; one that only wanders by noise (|m̂|/√v̂ ≪ 1) is pulled back exactly.
  if (!(options_.motion_sparsity > 0) || params_.dynamic_count() == 0 || params_.key_count < 2) return;
  const int trained = std::min(params_.key_count, key_interval_of_frame(window_last_frame(iteration_)) + 2);
  if (trained < 2) return;
  const double sp = options_.motion_sparsity;
  shrink_key_deviations(params_, trained, float(sp * key_lr), float(sp * options_.rotation_lr), float(sp * options_.opacity_lr), nullptr, true);
}

void Trainer::add_refined(std::vector<RefinedView> views) {
  for (RefinedView& v : views) {
    const size_t P = size_t(v.camera.width) * size_t(v.camera.height);
    if (!v.camera.has_time()) throw_error("refined view ", v.camera.name, ": no time");
    if (v.rgb.size() != P * 3 || v.weight.size() != P)
      throw_error("refined view ", v.camera.name, ": image or weights do not match its ", v.camera.width, "x", v.camera.height, " camera");
    refined_.push_back(std::move(v));
  }
}

int Trainer::correct_colour(size_t view, std::vector<float>& image) const {
  const int r = view_rig_.at(view);
  // The reference camera is the identity unless corrections were given (then its own, held).
  if (r < 0 || (r == 0 && options_.initial_colour.empty())) return -1;
  apply_colour_correction(colour_[size_t(r)], image);
  return r;
}

void Trainer::colour_backward(int rig, const std::vector<float>& render, float* dimg) {
  ColourCorrection& c = colour_[size_t(rig)];
  double g[6] = {0, 0, 0, 0, 0, 0};
  for (size_t p = 0; p < render.size(); p += 3)
    for (int ch = 0; ch < 3; ++ch) {
      const double d = dimg[p + size_t(ch)];
      g[ch] += d * render[p + size_t(ch)];
      g[3 + ch] += d;
      dimg[p + size_t(ch)] = float(d * c.gain[ch]);
    }
  if (rig == 0) return;  // the reference camera's correction is held: it fixes the gauge
  // Adam on the six values, its own step count per camera.
  constexpr double b1 = 0.9, b2 = 0.999, eps = 1e-15;
  const int t = ++colour_steps_[size_t(rig)];
  const double c1 = 1.0 - std::pow(b1, t), c2 = 1.0 - std::pow(b2, t);
  std::array<float, 6>&m = colour_m_[size_t(rig)], &v = colour_v_[size_t(rig)];
  for (int k = 0; k < 6; ++k) {
    m[size_t(k)] = float(b1 * m[size_t(k)] + (1 - b1) * g[k]);
    v[size_t(k)] = float(b2 * v[size_t(k)] + (1 - b2) * g[k] * g[k]);
    const double step = options_.colour_lr * (m[size_t(k)] / c1) / (std::sqrt(v[size_t(k)] / c2) + eps);
    if (k < 3) c.gain[k] = float(c.gain[k] - step);
    else c.offset[k - 3] = float(c.offset[k - 3] - step);
  }
}

void Trainer::adam_step() {
  constexpr double b1 = 0.9, b2 = 0.999, eps = 1e-15;
  const double t = double(iteration_ + 1);
  const double c1 = 1.0 - std::pow(b1, t), c2 = 1.0 - std::pow(b2, t);
  // Position learning rate: exponential decay (3DGS get_expon_lr_func, no delay). Keys hold
  // their initial rate while the time window grows, then decay over the remaining iterations.
  auto decayed = [&](double frac) {
    frac = std::clamp(frac, 0.0, 1.0);
    // A zero rate (frozen positions) has no logarithm: interpolate linearly then.
    if (!(options_.position_lr_init > 0 && options_.position_lr_final > 0))
      return (options_.position_lr_init * (1 - frac) + options_.position_lr_final * frac) * double(extent_);
    return std::exp(std::log(options_.position_lr_init) * (1 - frac) + std::log(options_.position_lr_final) * frac) * double(extent_);
  };
  const double pos_lr = decayed(double(iteration_) / std::max(1, options_.iterations));
  const int ramp_end = window_last_frame(0) < data_->frames() - 1 ? int(std::lround(options_.time_ramp * options_.iterations)) : 0;
  const double key_lr = options_.key_lr_scale * (iteration_ < ramp_end ? decayed(0.0)
                                                                        : decayed(double(iteration_ - ramp_end) / std::max(1, options_.iterations - ramp_end)));
  const int K = params_.sh_count();
  // Element-wise Adam in float, a lane of elements per instruction (train/adam.hpp: the
  // scalar step's values bit for bit); lr / c1 and 1 / √c2 fold the bias corrections.
  train::AdamStep step;
  step.b1 = float(b1), step.b2 = float(b2), step.s2 = float(1.0 / std::sqrt(c2)), step.eps = float(eps);
  step.sparse = options_.sparse_adam;
  auto update = [&](std::vector<float>& x, const std::vector<float>& g, std::vector<float>& m, std::vector<float>& v, double lr) {
    train::AdamStep s = step;
    s.a = float(lr / c1);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, x.size(), 16384), [&](const tbb::blocked_range<size_t>& r) {
      train::adam_update(s, x.data() + r.begin(), g.data() + r.begin(), m.data() + r.begin(), v.data() + r.begin(), r.size());
    });
  };
  update(params_.means, grad_.means, adam_m_.means, adam_v_.means, pos_lr);
  update(params_.key_positions, grad_.key_positions, adam_m_.key_positions, adam_v_.key_positions, key_lr);
  update(params_.log_scales, grad_.log_scales, adam_m_.log_scales, adam_v_.log_scales, options_.scaling_lr);
  update(params_.key_log_scales, grad_.key_log_scales, adam_m_.key_log_scales, adam_v_.key_log_scales, options_.scaling_lr);
  update(params_.rotations, grad_.rotations, adam_m_.rotations, adam_v_.rotations, options_.rotation_lr);
  update(params_.key_rotations, grad_.key_rotations, adam_m_.key_rotations, adam_v_.key_rotations, options_.rotation_lr);
  update(params_.opacity_logits, grad_.opacity_logits, adam_m_.opacity_logits, adam_v_.opacity_logits, options_.opacity_lr);
  update(params_.key_opacity_logits, grad_.key_opacity_logits, adam_m_.key_opacity_logits, adam_v_.key_opacity_logits, options_.opacity_lr);
  // SH, per block of one Gaussian's (or one colour key's) coefficients: the DC (its first 3
  // values) at feature_lr, the rest at 1/20 of it.
  const size_t block = size_t(K) * 3;
  train::AdamStep dc = step, rest = step;
  dc.a = float(options_.feature_lr / c1), rest.a = float(options_.feature_lr / 20.0 / c1);
  auto update_sh = [&](std::vector<float>& x, const std::vector<float>& g, std::vector<float>& m, std::vector<float>& v) {
    if (block == 3) return update(x, g, m, v, options_.feature_lr);  // degree 0: every value is a DC value
    tbb::parallel_for(tbb::blocked_range<size_t>(0, x.size() / block, 2048), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t row = r.begin(); row < r.end(); ++row) {
        const size_t o = row * block;
        train::adam_update(dc, &x[o], &g[o], &m[o], &v[o], 3);
        train::adam_update(rest, &x[o + 3], &g[o + 3], &m[o + 3], &v[o + 3], block - 3);
      }
    });
  };
  update_sh(params_.sh, grad_.sh, adam_m_.sh, adam_v_.sh);
  update_sh(params_.key_sh, grad_.key_sh, adam_m_.key_sh, adam_v_.key_sh);
  motion_sparsity_step(key_lr);
}

namespace {

/// Builds a new parameter set from rows of the old one: row r copies Gaussian src[r]
/// (with its keys when it moves), then `edit` adjusts it. Dynamic ids stay ascending.
struct Row {
  uint32_t src;
  bool fresh;          // a new Gaussian: zero Adam moments
  bool make_dynamic;   // promote a static Gaussian (keys at its pose)
  Vec3f offset = Vec3f::Zero();
  float log_scale_shift = 0.0f;
  bool make_static = false;  // freeze a moving Gaussian at the mean of its keys
};

/// The mean of a moving Gaussian's keys: position, rotation (on the first key's hemisphere,
/// normalised) and opacity logit.
void key_means(const ModelParams<float>& p, size_t j, Vec3f* position, Vec4f* rotation, float* opacity) {
  const size_t K = size_t(p.key_count);
  Vec3f pm = Vec3f::Zero();
  Vec4f qm = Vec4f::Zero();
  float om = 0;
  const Vec4f q0 = normalize_quat(Eigen::Map<const Vec4f>(&p.key_rotations[j * K * 4]));
  for (size_t k = 0; k < K; ++k) {
    pm += Eigen::Map<const Vec3f>(&p.key_positions[(j * K + k) * 3]) / float(K);
    const Vec4f q = normalize_quat(Eigen::Map<const Vec4f>(&p.key_rotations[(j * K + k) * 4]));
    qm += q.dot(q0) < 0 ? Vec4f(-q) : q;
    if (p.keyed_opacity) om += p.key_opacity_logits[j * K + k] / float(K);
  }
  *position = pm;
  *rotation = normalize_quat(qm);
  *opacity = p.keyed_opacity ? om : p.opacity_logits[p.dynamic_ids[j]];
}

ModelParams<float> gather_rows(const ModelParams<float>& p, const std::vector<Row>& rows, bool moments) {
  ModelParams<float> q;
  q.sh_degree = p.sh_degree;
  q.key_count = p.key_count;
  q.first_key_time = p.first_key_time;
  q.key_spacing = p.key_spacing;
  q.keyed_opacity = p.keyed_opacity;
  const size_t K = size_t(std::max(p.key_count, 1)), S = size_t(p.sh_count()) * 3;
  std::vector<int64_t> dyn_index(p.size(), -1);
  for (size_t j = 0; j < p.dynamic_ids.size(); ++j) dyn_index[p.dynamic_ids[j]] = int64_t(j);
  const bool keyed_scale = !p.key_log_scales.empty(), keyed_opacity = p.keyed_opacity;
  auto put = [](std::vector<float>& dst, const float* src, size_t n, bool zero) {
    for (size_t i = 0; i < n; ++i) dst.push_back(zero ? 0.0f : src[i]);
  };
  for (const Row& r : rows) {
    const uint32_t s = r.src;
    const bool zero = moments && r.fresh;
    const uint32_t id = uint32_t(q.size());
    Vec3f mean(p.means[3 * s], p.means[3 * s + 1], p.means[3 * s + 2]);
    if (!moments) mean += r.offset;
    put(q.means, mean.data(), 3, zero);
    float ls[3];
    for (int a = 0; a < 3; ++a) ls[a] = p.log_scales[3 * s + a] + (moments ? 0.0f : r.log_scale_shift);
    put(q.log_scales, ls, 3, zero);
    put(q.rotations, &p.rotations[4 * s], 4, zero);
    put(q.opacity_logits, &p.opacity_logits[s], 1, zero);
    put(q.sh, &p.sh[s * S], S, zero);
    const int64_t j = dyn_index[s];
    if (j >= 0 && r.make_static) {
      // Frozen: its own values become the keys' mean (moments start at zero).
      Vec3f pm;
      Vec4f qm;
      float om;
      key_means(p, size_t(j), &pm, &qm, &om);
      for (int a = 0; a < 3; ++a) q.means[3 * id + a] = moments ? 0.0f : pm[a];
      for (int a = 0; a < 4; ++a) q.rotations[4 * id + a] = moments ? 0.0f : qm[a];
      q.opacity_logits[id] = moments ? 0.0f : om;
      if (!p.key_sh.empty())  // colour keys: their mean
        for (size_t a = 0; a < S; ++a) {
          double sum = 0;
          for (size_t k = 0; k < K; ++k) sum += p.key_sh[(size_t(j) * K + k) * S + a];
          q.sh[size_t(id) * S + a] = moments ? 0.0f : float(sum / double(K));
        }
      continue;
    }
    if (j >= 0 || r.make_dynamic) {
      q.dynamic_ids.push_back(id);
      for (size_t k = 0; k < K; ++k) {
        if (j >= 0) {
          float pos[3];
          for (int a = 0; a < 3; ++a) pos[a] = p.key_positions[(size_t(j) * K + k) * 3 + a] + (moments ? 0.0f : r.offset[a]);
          put(q.key_positions, pos, 3, zero);
          put(q.key_rotations, &p.key_rotations[(size_t(j) * K + k) * 4], 4, zero);
          if (keyed_scale) {
            float kls[3];
            for (int a = 0; a < 3; ++a) kls[a] = p.key_log_scales[(size_t(j) * K + k) * 3 + a] + (moments ? 0.0f : r.log_scale_shift);
            put(q.key_log_scales, kls, 3, zero);
          }
          if (keyed_opacity) put(q.key_opacity_logits, &p.key_opacity_logits[size_t(j) * K + k], 1, zero);
          if (!p.key_sh.empty()) put(q.key_sh, &p.key_sh[(size_t(j) * K + k) * S], S, zero);
        } else {
          // Promoted: keys at the current pose (moments start at zero).
          put(q.key_positions, mean.data(), 3, moments);
          put(q.key_rotations, &p.rotations[4 * s], 4, moments);
          if (keyed_scale) put(q.key_log_scales, ls, 3, moments);
          if (keyed_opacity) put(q.key_opacity_logits, &p.opacity_logits[s], 1, moments);
          if (!p.key_sh.empty()) put(q.key_sh, &p.sh[s * S], S, moments);
        }
      }
    }
  }
  return q;
}

/// Applies the rows to a model and to its two Adam moments; returns the source of every row
/// (for the per-Gaussian state the trainer carries).
std::vector<uint32_t> gather_all(const std::vector<Row>& rows, ModelParams<float>& params, ModelParams<float>& m, ModelParams<float>& v) {
  params = gather_rows(params, rows, false);
  m = gather_rows(m, rows, true);
  v = gather_rows(v, rows, true);
  std::vector<uint32_t> src;
  src.reserve(rows.size());
  for (const Row& r : rows) src.push_back(r.src);
  return src;
}

}  // namespace

size_t Trainer::fold_unchanging() {
  if (change_masks_.empty() || params_.dynamic_count() == 0) return 0;
  std::vector<uint8_t> fold(params_.size(), 0);
  for (uint32_t g : params_.dynamic_ids) fold[g] = !on_change_[g];
  return make_static(fold);
}

size_t Trainer::make_static(const std::vector<uint8_t>& flags) {
  std::vector<Row> rows;
  rows.reserve(params_.size());
  size_t made = 0;
  for (uint32_t g = 0; g < params_.size(); ++g) {
    Row r{g, false, false};
    r.make_static = flags[g] != 0;
    made += r.make_static;
    rows.push_back(r);
  }
  if (made == 0) return 0;
  carry(gather_all(rows, params_, adam_m_, adam_v_));
  return made;
}

size_t Trainer::freeze_still() {
  // Gaussians whose keys stayed within freeze_distance × their size (and 5° and 0.5 in
  // opacity logit) while the time window grew showed no motion: they become static again,
  // so that every view constrains their one position instead of each key drifting with
  // only its own frames' views. promote_static can key them again later.
  const size_t n = params_.size(), M = params_.dynamic_count(), K = size_t(params_.key_count);
  if (M == 0 || K < 2) return 0;
  std::vector<uint8_t> freeze(n, 0);
  const float cos_half = std::cos(float(5.0 * kPi / 360.0));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, M, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) {
      const uint32_t g = params_.dynamic_ids[j];
      Vec3f pm;
      Vec4f qm;
      float om;
      key_means(params_, j, &pm, &qm, &om);
      const float size = std::exp(std::max({params_.log_scales[3 * g], params_.log_scales[3 * g + 1], params_.log_scales[3 * g + 2]}));
      bool still = true;
      for (size_t k = 0; k < K && still; ++k) {
        still = (Eigen::Map<const Vec3f>(&params_.key_positions[(j * K + k) * 3]) - pm).norm() <= options_.freeze_distance * size &&
                std::fabs(normalize_quat(Eigen::Map<const Vec4f>(&params_.key_rotations[(j * K + k) * 4])).dot(qm)) >= cos_half &&
                (!params_.keyed_opacity || std::fabs(params_.key_opacity_logits[j * K + k] - om) <= 0.5f);
      }
      freeze[g] = still;
    }
  });
  return make_static(freeze);
}

size_t Trainer::promote_static() {
  const size_t n = params_.size();
  const int B = std::max(1, options_.time_bins);
  std::vector<uint8_t> moving(n, 0);
  for (uint32_t g : params_.dynamic_ids) moving[g] = 1;
  std::vector<Row> rows;
  rows.reserve(n);
  size_t promoted = 0;
  for (uint32_t g = 0; g < n; ++g) {
    Row r{g, false, false};
    if (!moving[g] && on_change_[g] && denom_[g] > 0 &&
        grad_accum_[g] / float(denom_[g]) >= options_.promote_grad_scale * options_.densify_grad_threshold) {
      Vec3f sum = Vec3f::Zero();
      float norms = 0;
      int bins = 0;
      for (int b = 0; b < B; ++b) {
        const uint32_t c = bin_count_[g * B + b];
        if (c < uint32_t(options_.promote_min_samples)) continue;  // too few views to tell noise from motion
        const Vec3f mean = Eigen::Map<const Vec3f>(&bin_grad_[(g * B + b) * 3]) / float(c);
        sum += mean;
        norms += mean.norm();
        ++bins;
      }
      if (bins >= 2 && norms > 0 && sum.norm() < options_.promote_agreement * norms) {
        r.make_dynamic = true;
        ++promoted;
      }
    }
    rows.push_back(r);
  }
  if (promoted == 0) return 0;
  // Same order, same count: the carried state and the statistics rows are unchanged.
  carry(gather_all(rows, params_, adam_m_, adam_v_));
  return promoted;
}

void Trainer::densify_and_prune(bool prune_big, DensifyRecord* record) {
  const size_t n = params_.size();
  std::vector<uint8_t> moving(n, 0);
  for (uint32_t g : params_.dynamic_ids) moving[g] = 1;
  const size_t K = size_t(std::max(params_.key_count, 1));
  std::vector<int64_t> dyn_index(n, -1);
  for (size_t j = 0; j < params_.dynamic_ids.size(); ++j) dyn_index[params_.dynamic_ids[j]] = int64_t(j);
  auto max_scale = [&](uint32_t g) {
    return std::exp(std::max({params_.log_scales[3 * g], params_.log_scales[3 * g + 1], params_.log_scales[3 * g + 2]}));
  };
  auto opacity = [&](uint32_t g) {
    float o = sigmoid(params_.opacity_logits[g]);
    if (dyn_index[g] >= 0 && params_.keyed_opacity)
      for (size_t k = 0; k < K; ++k) o = std::max(o, sigmoid(params_.key_opacity_logits[size_t(dyn_index[g]) * K + k]));
    return o;
  };
  // Candidates by gradient, strongest first, so the cap keeps the most needed.
  std::vector<uint32_t> hot;
  for (uint32_t g = 0; g < n; ++g)
    if (denom_[g] > 0 && grad_accum_[g] / float(denom_[g]) >= options_.densify_grad_threshold) hot.push_back(g);
  std::stable_sort(hot.begin(), hot.end(), [&](uint32_t a, uint32_t b) {
    return grad_accum_[a] / float(denom_[a]) > grad_accum_[b] / float(denom_[b]);
  });
  std::vector<uint8_t> clone(n, 0), split(n, 0), remove(n, 0);
  size_t budget = options_.max_gaussians > n ? options_.max_gaussians - n : 0;
  for (uint32_t g : hot) {
    if (budget == 0) break;
    if (max_scale(g) <= options_.percent_dense * extent_) {
      clone[g] = 1;
      --budget;
    } else {
      split[g] = 1;  // two replace one
      --budget;
    }
  }
  for (uint32_t g = 0; g < n; ++g) {
    if (split[g]) continue;
    bool prune = opacity(g) < options_.min_opacity;
    if (prune_big) prune = prune || max_radii_[g] > options_.max_screen_size || max_scale(g) > 0.1f * extent_;
    remove[g] = prune;
  }
  if (record) {
    record->cloned = size_t(std::count(clone.begin(), clone.end(), 1));
    record->split = size_t(std::count(split.begin(), split.end(), 1));
    record->pruned = size_t(std::count(remove.begin(), remove.end(), 1));
  }
  std::vector<Row> rows;
  rows.reserve(n + hot.size() * 2);
  for (uint32_t g = 0; g < n; ++g)
    if (!remove[g] && !split[g]) rows.push_back({g, false, false});
  for (uint32_t g = 0; g < n; ++g)
    if (clone[g]) rows.push_back({g, true, false});
  for (uint32_t g = 0; g < n; ++g) {
    if (!split[g]) continue;
    const Vec4f q = normalize_quat(Vec4f(params_.rotations[4 * g], params_.rotations[4 * g + 1], params_.rotations[4 * g + 2],
                                         params_.rotations[4 * g + 3]));
    const Mat3f R = quat_to_matrix<float>(q);
    for (int k = 0; k < 2; ++k) {
      Row r{g, true, false};
      Vec3f z;
      for (int a = 0; a < 3; ++a)
        z[a] = float(normal(options_.seed ^ 0x5b1177ull, uint64_t(iteration_) * 1000003ull + g, uint64_t(2 * k + a * 7))) *
               std::exp(params_.log_scales[3 * g + a]);
      r.offset = R * z;
      r.log_scale_shift = -std::log(0.8f * 2.0f);
      rows.push_back(r);
    }
  }
  // Dynamic ids must stay ascending: rows are in an order where every row's id is its index.
  carry(gather_all(rows, params_, adam_m_, adam_v_));
  reset_stats();
}

void Trainer::reset_opacity() {
  const float cap = logit(0.01f);
  for (float& l : params_.opacity_logits) l = std::min(l, cap);
  for (float& l : params_.key_opacity_logits) l = std::min(l, cap);
  std::fill(adam_m_.opacity_logits.begin(), adam_m_.opacity_logits.end(), 0.0f);
  std::fill(adam_v_.opacity_logits.begin(), adam_v_.opacity_logits.end(), 0.0f);
  std::fill(adam_m_.key_opacity_logits.begin(), adam_m_.key_opacity_logits.end(), 0.0f);
  std::fill(adam_v_.key_opacity_logits.begin(), adam_v_.key_opacity_logits.end(), 0.0f);
  opacity_was_reset_ = true;
}

void Trainer::raise_sh_degree() {
  const int from = params_.sh_count(), to = (params_.sh_degree + 2) * (params_.sh_degree + 2);
  auto widen = [&](ModelParams<float>& p) {
    std::vector<float> sh(p.size() * size_t(to) * 3, 0.0f);
    for (size_t g = 0; g < p.size(); ++g)
      std::copy(p.sh.begin() + g * from * 3, p.sh.begin() + (g + 1) * from * 3, sh.begin() + g * to * 3);
    p.sh = std::move(sh);
    if (!p.key_sh.empty()) {
      const size_t rows = p.key_sh.size() / (size_t(from) * 3);
      std::vector<float> ksh(rows * size_t(to) * 3, 0.0f);
      for (size_t r = 0; r < rows; ++r)
        std::copy(p.key_sh.begin() + r * from * 3, p.key_sh.begin() + (r + 1) * from * 3, ksh.begin() + r * to * 3);
      p.key_sh = std::move(ksh);
    }
    p.sh_degree += 1;
  };
  widen(params_);
  widen(adam_m_);
  widen(adam_v_);
}

void Trainer::run(int until, Progress& progress) {
  progress.start("training", size_t(std::max(0, until - iteration_)));
  auto t0 = std::chrono::steady_clock::now();
  const int first = iteration_;
  while (iteration_ < until) {
    step();
    if (!std::isfinite(status_.loss))
      throw_error("training: the loss became ", status_.loss, " at iteration ", iteration_,
                  "; the optimisation diverged (an extreme input or option?) and nothing was written");
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    status_.iterations_per_second = secs > 0 ? (iteration_ - first) / secs : 0;
    std::ostringstream s;
    s.precision(4);
    s << "loss " << status_.loss << "  PSNR " << std::fixed;
    s.precision(2);
    s << status_.psnr << "  " << status_.gaussians << " Gaussians (" << status_.dynamic << " moving)  " << status_.iterations_per_second
      << " it/s";
    progress.status(s.str());
    progress.advance();
  }
  progress.finish();
}

GaussianCloud Trainer::model() const {
  ModelParams<float> p = params_;
  if (!change_masks_.empty()) {  // keyed Gaussians never on a changing pixel: their keys' mean
    const size_t K = size_t(std::max(p.key_count, 1));
    for (size_t j = 0; j < p.dynamic_count(); ++j) {
      if (on_change_[p.dynamic_ids[j]]) continue;
      Vec3f pm;
      Vec4f qm;
      float om;
      key_means(p, j, &pm, &qm, &om);
      for (size_t k = 0; k < K; ++k) {
        Eigen::Map<Vec3f>(&p.key_positions[(j * K + k) * 3]) = pm;
        Eigen::Map<Vec4f>(&p.key_rotations[(j * K + k) * 4]) = qm;
        if (p.keyed_opacity) p.key_opacity_logits[j * K + k] = om;
      }
    }
  }
  GaussianCloud c = cloud_from_params(p);
  StillTolerance tol = options_.still;
  tol.position = float(options_.still_distance * extent_);
  fold_still_keys(c, tol);
  partition_static_dynamic(c);
  static_first(c);
  return c;
}

}  // namespace fillgs
