#include "fillgs/method/refine.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/io/camera_json.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/base/process.hpp"
#include "fillgs/base/random.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {

/// Index of the observed view of `pose` at `frame`, or −1.
int find_observed(const std::vector<ObservedView>& views, uint32_t pose, int frame) {
  for (size_t i = 0; i < views.size(); ++i)
    if (views[i].pose == pose && views[i].frame == frame) return int(i);
  return -1;
}

/// Nearest observed view (camera centre) at `frame` to a point.
int nearest_observed(const std::vector<ObservedView>& views, int frame, const Vec3d& p) {
  int best = -1;
  double bd = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    if (views[i].frame != frame) continue;
    const double d = (views[i].camera.centre() - p).squaredNorm();
    if (best < 0 || d < bd) best = int(i), bd = d;
  }
  return best;
}

/// Soft disc mask: 1 inside radius r, falling to 0 at 1.3 r.
cv::Mat disc(int w, int h, double cx, double cy, double r) {
  cv::Mat m(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double d = std::hypot(x - cx, y - cy) / r;
      const double v = d <= 1 ? 1.0 : d >= 1.3 ? 0.0 : 1.0 - (d - 1.0) / 0.3;
      m.at<float>(y, x) = float(v);
    }
  return m;
}

void blend(cv::Mat& img, const cv::Mat& other, const cv::Mat& mask, float scale = 1.0f) {
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const float m = mask.at<float>(y, x) * scale;
      if (m <= 0) continue;
      cv::Vec3f& p = img.at<cv::Vec3f>(y, x);
      const cv::Vec3f& q = other.at<cv::Vec3f>(y, x);
      p = p * (1 - m) + q * m;
    }
}

class IdentityRefiner : public Refiner {
 public:
  std::string name() const override { return "identity"; }
  void refine(const std::string& in, const std::string& out, const Patch& patch) override {
    make_directories(out);
    for (const PatchImage& im : patch.images)
      if (!im.observed) write_image(join_path(out, im.file), read_image(join_path(in, im.file)));
  }
};

}  // namespace

void degrade_unsupported(Image& image, double strength, uint64_t seed, uint64_t key, double blur_sigma) {
  const int W = image.width, H = image.height;
  cv::Mat img(H, W, CV_32FC3, image.pixels.data());
  uint64_t draw = 1000;  // draws apart from inject_artifacts' for the same key
  auto u = [&] { return uniform(seed, key, draw++); };
  const double sigma = blur_sigma < 0 ? 2.0 + 3.0 * strength : blur_sigma;
  if (sigma > 0.05) cv::GaussianBlur(img, img, cv::Size(0, 0), sigma);
  cv::Vec3f gain;
  for (int c = 0; c < 3; ++c) gain[c] = float(1 + 0.2 * strength * (2 * u() - 1));
  img.forEach<cv::Vec3f>([&](cv::Vec3f& p, const int*) {
    for (int c = 0; c < 3; ++c) p[c] *= gain[c];
  });
  const double r = W * (0.05 + 0.05 * strength) * (0.6 + 0.4 * u());
  const cv::Mat m = disc(W, H, u() * W, u() * H, r);
  const cv::Mat colour(H, W, CV_32FC3, cv::Scalar(u(), u(), u()));
  blend(img, colour, m, 0.8f);
}

namespace {

class OracleRefiner : public Refiner {
 public:
  OracleRefiner(const GaussianCloud& truth, const OracleOptions& o, SupportStats* stats) : truth_(truth), o_(o), stats_(stats) {
    if (o.support == OracleSupport::Observed) {
      if (o.observers.empty() || o.frames < 1) throw_error("oracle: support 'observed' needs the training cameras and the frame count");
      support_ = oracle_support_table(truth, o.observers, o.frames, o.window);
    }
  }
  std::string name() const override {
    return std::string(o_.artifacts.strength > 0 ? "oracle+artifacts" : "oracle") + (o_.support == OracleSupport::Observed ? " (observed support)" : "");
  }
  void refine(const std::string& in, const std::string& out, const Patch& patch) override {
    make_directories(out);
    const bool limited = o_.support == OracleSupport::Observed;
    if (o_.artifacts.strength > 0) make_directories(join_path(out, "masks"));
    if (limited) make_directories(join_path(out, "support"));
    const size_t N = truth_.size();
    std::vector<float> flags;
    for (const PatchImage& im : patch.images) {
      if (im.observed) continue;
      RenderOptions ro;
      ro.background = o_.background;
      if (limited) {
        const int f = FrameGrid(o_.frames).clamp(im.frame);
        flags.assign(support_.begin() + ptrdiff_t(size_t(f) * N), support_.begin() + ptrdiff_t(size_t(f + 1) * N));
        ro.features = flags.data();
        ro.feature_channels = 1;
      }
      const RenderOutput r = render(frame_at(truth_, im.camera.time), im.camera, ro);
      Image img(r.width, r.height, 3, r.rgb);
      const uint64_t key = string_key((patch.name + "/" + im.file).c_str());
      double sum = double(img.width) * img.height;
      if (limited) {
        Image fill = read_rgb_image(join_path(in, im.file), img.width, img.height);  // the rendered view
        degrade_unsupported(fill, o_.artifacts.strength > 0 ? o_.artifacts.strength : 0.5, o_.artifacts.seed, key);
        Image mask(img.width, img.height, 1);
        sum = 0;
        for (size_t p = 0; p < mask.pixels.size(); ++p) {
          const float a = r.alpha[p];
          // Supported where observed surfaces make up at least half of what the pixel shows.
          const float sp = a > 1e-4f && r.features[p] >= 0.5f * a ? 1.0f : 0.0f;
          mask.pixels[p] = sp;
          sum += sp;
          for (int c = 0; c < 3; ++c) img.pixels[p * 3 + c] = sp * img.pixels[p * 3 + c] + (1 - sp) * fill.pixels[p * 3 + c];
        }
        write_image(join_path(join_path(out, "support"), im.file), mask);
      }
      if (stats_) stats_->support_sum += sum, stats_->pixels += size_t(img.width) * img.height;
      if (o_.artifacts.strength > 0) {
        const std::vector<uint8_t> amask = inject_artifacts(img, o_.artifacts, key);
        Image m(img.width, img.height, 1);
        for (size_t p = 0; p < amask.size(); ++p) m.pixels[p] = amask[p] ? 1.0f : 0.0f;
        write_image(join_path(join_path(out, "masks"), im.file), m);
      }
      write_image(join_path(out, im.file), img);
    }
  }

 private:
  const GaussianCloud& truth_;
  OracleOptions o_;
  SupportStats* stats_;
  std::vector<uint8_t> support_;  // [F][N]
};

class ExternalRefiner : public Refiner {
 public:
  ExternalRefiner(std::string command, double timeout) : command_(std::move(command)), timeout_(timeout) {
    if (command_.find("{in}") == std::string::npos || command_.find("{out}") == std::string::npos)
      throw_error("refiner: the command template must contain {in} and {out} (got \"", command_, "\")");
    split_command(command_);  // shell syntax is refused before any work
  }
  std::string name() const override { return "external"; }
  void refine(const std::string& in, const std::string& out, const Patch&) override {
    make_directories(out);
    const std::string log = join_path(out, "refiner.log");
    ProcessOptions po;
    po.stdout_path = po.stderr_path = log;
    po.timeout_seconds = timeout_;
    po.end_descendants = true;  // a refiner's background children must not write on after it returned
    const ProcessResult r = run_process(split_command(command_, {{"{in}", in}, {"{out}", out}}), po);
    if (!r.started) throw_error("the refiner did not start: ", r.error);
    if (r.timed_out) throw_error("timed out after ", timeout_, " s (", log, ")");
    if (r.status != 0) throw_error("the refiner exited with status ", r.status, " (", log, ")");
  }

 private:
  std::string command_;
  double timeout_;
};

}  // namespace

Patch make_patch(const Trajectory& tr, const std::vector<ObservedView>& views, const std::string& name) {
  if (tr.poses.empty()) throw_error("patch: trajectory ", tr.index, " has no poses");
  if (tr.patch_frames.size() != tr.patch_times.size()) throw_error("patch: trajectory ", tr.index, " has frames without times");
  Patch p;
  p.trajectory = tr.index;
  p.name = name;
  // Random trajectories start nowhere in particular: their observed view is the nearest one.
  const int start = tr.start_view >= 0 ? tr.start_view : nearest_observed(views, tr.frame, tr.poses.front().centre());
  if (start < 0) throw_error("patch: no observed view at frame ", tr.frame, " for trajectory ", tr.index);
  p.observed_view = start;
  const uint32_t pose = views[size_t(start)].pose;
  const int V = int(tr.poses.size()) + 1;
  for (size_t fi = 0; fi < tr.patch_frames.size(); ++fi) {
    const int f = tr.patch_frames[fi];
    // A monocular video holds the start camera at its own frame only: at the patch's other
    // frames view 0 is the start camera's pose with no photograph, a virtual view like the
    // others (rendered, refined, weighted).
    const int obs = find_observed(views, pose, f);
    if (obs < 0 && f == tr.frame)
      throw_error("patch: trajectory ", tr.index, ": camera ", views[size_t(start)].camera.name, " has no image at frame ", f);
    for (int k = 0; k < V; ++k) {
      const int v = fi % 2 == 0 ? k : V - 1 - k;  // serpentine
      PatchImage im;
      char file[48];
      std::snprintf(file, sizeof file, "f%04d_v%d.png", f, v);
      im.file = file;
      im.frame = f;
      im.view = v;
      im.observed = v == 0 && obs >= 0;
      im.order = int(p.images.size());
      if (im.observed) {
        im.camera = views[size_t(obs)].camera;
      } else {
        im.camera = v == 0 ? views[size_t(start)].camera : tr.poses[size_t(v - 1)];
        im.camera.time = tr.patch_times[fi];
        std::snprintf(file, sizeof file, "%s_v%d_f%04d", name.c_str(), v, f);
        im.camera.name = file;
      }
      p.images.push_back(im);
    }
  }
  return p;
}

void write_patch(const std::string& dir, const Patch& patch, const std::vector<ObservedView>& views,
                 const std::function<std::vector<float>(size_t)>& observed_image,
                 const std::function<std::vector<float>(const Camera&)>& render_view) {
  make_directories(dir);
  nlohmann::json images = nlohmann::json::array();
  int frames = 0, last = -1;
  for (const PatchImage& im : patch.images) {
    std::vector<float> rgb;
    if (im.observed) {
      const int obs = find_observed(views, views[size_t(patch.observed_view)].pose, im.frame);
      rgb = observed_image(size_t(obs));
    } else {
      rgb = render_view(im.camera);
    }
    write_image(join_path(dir, im.file), Image(im.camera.width, im.camera.height, 3, std::move(rgb)));
    if (im.frame != last) ++frames, last = im.frame;
    images.push_back({{"file", im.file},
                      {"order", im.order},
                      {"frame", im.frame},
                      {"time", im.camera.time},
                      {"view", im.view},
                      {"observed", im.observed},
                      {"camera", camera_json(im.camera)}});
  }
  const nlohmann::json j = {{"trajectory", patch.trajectory},
                            {"name", patch.name},
                            {"frames", frames},
                            {"views", frames > 0 ? int(patch.images.size()) / frames : 0},
                            {"order", "serpentine: view k at even frame index, views-1-k at odd; frames increasing"},
                            {"images", images}};
  write_file_atomically(join_path(dir, "patch.json"), j.dump(1) + "\n");
}

Patch read_patch(const std::string& dir) {
  const std::string path = join_path(dir, "patch.json");
  const nlohmann::json j = read_json_file(path);
  const auto images = j.find("images");
  if (!j.is_object() || images == j.end() || !images->is_array()) throw_error(path, ": no 'images' list");
  Patch p;
  p.name = j.contains("name") && j["name"].is_string() ? j["name"].get<std::string>() : std::filesystem::path(dir).filename().string();
  p.trajectory = j.contains("trajectory") && j["trajectory"].is_number_integer() ? j["trajectory"].get<int>() : 0;
  for (size_t i = 0; i < images->size(); ++i) {
    const nlohmann::json& e = (*images)[i];
    const std::string where = path + ": image " + std::to_string(i);
    if (!e.is_object()) throw_error(where, " is not an object");
    PatchImage im;
    auto integer = [&](const char* key) {
      const auto it = e.find(key);
      if (it == e.end() || !it->is_number_integer()) throw_error(where, ": '", key, "' is missing or not a whole number");
      return it->get<int>();
    };
    const auto file = e.find("file");
    if (file == e.end() || !file->is_string() || file->get<std::string>().empty() || file->get<std::string>().find('/') != std::string::npos ||
        file->get<std::string>().find("..") != std::string::npos)
      throw_error(where, ": 'file' must be a plain file name");
    im.file = file->get<std::string>();
    im.order = integer("order"), im.frame = integer("frame"), im.view = integer("view");
    const auto observed = e.find("observed");
    if (observed == e.end() || !observed->is_boolean()) throw_error(where, ": 'observed' is missing or not true/false");
    im.observed = observed->get<bool>();
    const auto camera = e.find("camera");
    if (camera == e.end()) throw_error(where, ": no 'camera'");
    im.camera = camera_from_json(*camera, where);
    p.images.push_back(std::move(im));
  }
  return p;
}

std::vector<uint8_t> inject_artifacts(Image& image, const ArtifactOptions& o, uint64_t key) {
  const int W = image.width, H = image.height;
  std::vector<uint8_t> mask(size_t(W) * H, 0);
  if (image.channels != 3) throw_error("artifacts: need an RGB image");
  if (!(o.strength > 0)) return mask;
  const double s = std::min(1.0, o.strength);
  cv::Mat img(H, W, CV_32FC3, image.pixels.data());
  const cv::Mat clean = img.clone();
  uint64_t draw = 0;
  auto u = [&] { return uniform(o.seed, key, draw++); };
  auto region = [&] {
    const double r = o.region_fraction * W * (0.7 + 0.6 * u());
    return disc(W, H, u() * W, u() * H, r);
  };
  // Each kind appears with probability 0.6; at least one does.
  bool kinds[4];
  for (bool& k : kinds) k = u() < 0.6;
  if (!(kinds[0] || kinds[1] || kinds[2] || kinds[3])) kinds[size_t(u() * 4) % 4] = true;
  if (kinds[0]) {  // blur
    cv::Mat blurred;
    const double sigma = 1.0 + 4.0 * s;
    cv::GaussianBlur(img, blurred, cv::Size(0, 0), sigma);
    blend(img, blurred, region());
  }
  if (kinds[1]) {  // colour drift
    cv::Mat drifted = img.clone();
    cv::Vec3f gain, offset;
    for (int c = 0; c < 3; ++c) gain[c] = float(1 + 0.3 * s * (2 * u() - 1)), offset[c] = float(0.1 * s * (2 * u() - 1));
    drifted.forEach<cv::Vec3f>([&](cv::Vec3f& p, const int*) {
      for (int c = 0; c < 3; ++c) p[c] = p[c] * gain[c] + offset[c];
    });
    blend(img, drifted, region());
  }
  if (kinds[2]) {  // hallucinated blobs
    const int n = 1 + int(u() * 3);
    for (int b = 0; b < n; ++b) {
      const double r = W * (0.04 + 0.08 * s) * (0.6 + 0.4 * u());
      const cv::Mat m = disc(W, H, u() * W, u() * H, r);
      const cv::Mat colour(H, W, CV_32FC3, cv::Scalar(u(), u(), u()));
      blend(img, colour, m, 0.9f);
    }
  }
  if (kinds[3]) {  // misalignment: a region shifted by a few pixels
    const double a = u() * 2 * 3.14159265358979, d = 1.0 + 5.0 * s;
    const cv::Mat T = (cv::Mat_<double>(2, 3) << 1, 0, d * std::cos(a), 0, 1, d * std::sin(a));
    cv::Mat shifted;
    cv::warpAffine(img, shifted, T, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
    blend(img, shifted, region());
  }
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const cv::Vec3f d = img.at<cv::Vec3f>(y, x) - clean.at<cv::Vec3f>(y, x);
      const float mx = std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});
      mask[size_t(y) * W + x] = mx > kArtifactVisible;
    }
  return mask;
}

std::unique_ptr<Refiner> make_identity_refiner() { return std::make_unique<IdentityRefiner>(); }

int nearest_pool_view(const RigPool& pool, const Camera& view, const RigOptions& o) {
  const int frame = FrameGrid(std::max(1, pool.frame_count)).nearest(view.time);
  const Vec3d centre = view.centre();
  const Vec3d axis = view.R.row(2).transpose();
  const double cos_max = std::cos(o.max_angle_degrees * kPi / 180.0);
  int best = -1;
  double best_distance = 0, best_cos = 0;
  for (size_t i = 0; i < pool.cameras.size(); ++i) {
    const Camera& c = pool.cameras[i];
    if (FrameGrid(std::max(1, pool.frame_count)).nearest(c.time) != frame) continue;
    const double d = (c.centre() - centre).norm();
    const double cosine = axis.dot(c.R.row(2).transpose());
    if (d > o.max_distance || cosine < cos_max) continue;
    if (best < 0 || d < best_distance || (d == best_distance && cosine > best_cos)) best = int(i), best_distance = d, best_cos = cosine;
  }
  return best;
}

namespace {

class RigRefiner : public Refiner {
 public:
  RigRefiner(RigPool pool, const RigOptions& o) : pool_(std::move(pool)), o_(o) {
    if (pool_.cameras.empty()) throw_error("rig refiner: no pool camera (every camera of the rig is trained on or held out)");
    if (!pool_.image) throw_error("rig refiner: the pool's images are missing");
    if (!(o_.max_distance >= 0 && std::isfinite(o_.max_distance)))
      throw_error("rig refiner: max_distance must be a finite number at least 0 (got ", o_.max_distance, ")");
    if (!(o_.max_angle_degrees >= 0 && o_.max_angle_degrees <= 180))
      throw_error("rig refiner: max_angle_degrees must be in [0, 180] degrees (got ", o_.max_angle_degrees, ")");
  }
  std::string name() const override { return "rig"; }
  void refine(const std::string&, const std::string& out, const Patch& patch) override {
    make_directories(out);
    for (const PatchImage& im : patch.images) {
      if (im.observed) continue;
      const int k = nearest_pool_view(pool_, im.camera, o_);
      if (k < 0) continue;
      const Camera& c = pool_.cameras[size_t(k)];
      const Image photo(c.width, c.height, 3, pool_.image(size_t(k)));
      write_image(join_path(out, im.file), photo);
    }
  }
  RefinedPose pose(const PatchImage& image) const override {
    const int k = nearest_pool_view(pool_, image.camera, o_);
    RefinedPose p;
    if (k < 0) p.dropped = true;
    else p.camera = pool_.cameras[size_t(k)];
    return p;
  }

 private:
  RigPool pool_;
  RigOptions o_;
};

}  // namespace

std::unique_ptr<Refiner> make_rig_refiner(RigPool pool, const RigOptions& options) {
  return std::make_unique<RigRefiner>(std::move(pool), options);
}

std::vector<uint8_t> oracle_support_table(const GaussianCloud& truth, const std::vector<Camera>& observers, int frames, int window) {
  const size_t N = truth.size(), F = size_t(std::max(1, frames));
  ObservationOptions oo;
  oo.visibility.mode = VisibilityMode::Exact;
  const FrameGrid grid(static_cast<int>(F));
  const ObservationTables t = observation_tables(truth, observers, grid.times(), grid.step(), oo);
  std::vector<uint8_t> moving(N, 0);
  for (uint32_t g : truth.dynamic_ids) moving[g] = 1;
  std::vector<uint8_t> ever(N, 0), out(F * N, 0);
  for (size_t f = 0; f < F; ++f)
    for (size_t g = 0; g < N; ++g) ever[g] |= t.counts[f * N + g] > 0;
  for (size_t f = 0; f < F; ++f)
    for (size_t g = 0; g < N; ++g) {
      if (!moving[g]) {
        out[f * N + g] = ever[g];
        continue;
      }
      const auto [lo, hi] = grid.window(int(f), std::max(0, window));
      for (int k = lo; k <= hi && !out[f * N + g]; ++k) out[f * N + g] = t.counts[size_t(k) * N + g] > 0;
    }
  return out;
}

std::unique_ptr<Refiner> make_oracle_refiner(const GaussianCloud& truth, const OracleOptions& o, SupportStats* stats) {
  return std::make_unique<OracleRefiner>(truth, o, stats);
}

std::unique_ptr<Refiner> make_oracle_refiner(const GaussianCloud& truth, const ArtifactOptions& a, const Vec3f& bg) {
  OracleOptions o;
  o.artifacts = a;
  o.background = bg;
  return std::make_unique<OracleRefiner>(truth, o, nullptr);
}

std::unique_ptr<Refiner> make_external_refiner(const std::string& command, double timeout) {
  return std::make_unique<ExternalRefiner>(command, timeout);
}

RefineReport refine_patches(Refiner& refiner, const std::vector<Patch>& patches, const std::string& in_root, const std::string& out_root,
                            Progress& progress) {
  RefineReport rep;
  const auto t0 = Clock::now();
  progress.start("refine (" + refiner.name() + ")", patches.size());
  for (size_t i = 0; i < patches.size(); ++i) {
    const Patch& p = patches[i];
    const std::string in = join_path(in_root, p.name), out = join_path(out_root, p.name);
    std::vector<RefinedImage> got;
    try {
      std::error_code ec;
      fs::remove_all(out, ec);  // a stale result of an earlier run must not pass the check
      refiner.refine(in, out, p);
      size_t dropped = 0;
      for (const PatchImage& im : p.images) {
        if (im.observed) continue;
        const RefinedPose pose = refiner.pose(im);
        if (pose.dropped) {
          ++dropped;
          continue;
        }
        const Camera& cam = pose.camera ? *pose.camera : im.camera;
        const std::string path = join_path(out, im.file);
        int w = 0, h = 0;
        if (!fs::exists(fs::symlink_status(path))) throw_error("missing refined image ", im.file);
        if (!image_size(path, &w, &h)) {
          read_image(path);  // its complaint: a link to nothing, a folder, a pipe, not an image
          throw_error(path, ": the refined image's size cannot be read");
        }
        if (w != cam.width || h != cam.height) throw_error(im.file, " is ", w, "x", h, ", expected ", cam.width, "x", cam.height);
        RefinedImage r;
        r.patch = int(i);
        r.image = im;
        r.image.camera = cam;
        r.path = path;
        r.rgb = rgb_channels(read_image(path), im.file);  // alpha dropped
        got.push_back(std::move(r));
      }
      for (RefinedImage& r : got) rep.images.push_back(std::move(r));
      rep.dropped += dropped;
    } catch (const std::exception& e) {
      rep.failures.emplace_back(int(i), p.name + ": " + e.what());
    }
    progress.advance();
  }
  progress.finish();
  rep.seconds = seconds_since(t0);
  return rep;
}

}  // namespace fillgs
