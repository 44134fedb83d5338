// The reference-conditioned refiners (refine.hpp, ReferenceOptions): `reference` on
// synthetic scenes (ground truth where the reference camera saw it), `warp` on any data
// (the reference photograph warped through the render's depth).
#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/imgproc.hpp>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/random.hpp"
#include "fillgs/method/refine.hpp"
#include "fillgs/method/weights.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

double parallax_degrees(const Vec3d& p, const Vec3d& a, const Vec3d& b) {
  const Vec3d u = a - p, v = b - p;
  const double nu = u.norm(), nv = v.norm();
  if (!(nu > 0) || !(nv > 0)) return 0.0;
  return std::acos(std::clamp(u.dot(v) / (nu * nv), -1.0, 1.0)) * 180.0 / kPi;
}

const PatchImage& patch_reference(const Patch& patch, int frame) {
  const PatchImage* best = nullptr;
  for (const PatchImage& im : patch.images)
    if (im.observed && (!best || std::abs(im.frame - frame) < std::abs(best->frame - frame))) best = &im;
  if (!best) throw_error("patch ", patch.name, " has no observed image: a reference-conditioned refiner needs one");
  return *best;
}

std::vector<WarpedPixel> warp_pixels(const Camera& cam, const std::vector<float>& depth, const Camera& other,
                                     const std::vector<float>& other_depth, double tolerance) {
  const int W = cam.width, H = cam.height, OW = other.width, OH = other.height;
  if (depth.size() != size_t(W) * H || other_depth.size() != size_t(OW) * OH) throw_error("warp: depth maps do not match the cameras");
  std::vector<WarpedPixel> out(size_t(W) * H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float z = depth[size_t(y) * W + x];
      if (!(z > 0)) continue;
      WarpedPixel& w = out[size_t(y) * W + x];
      w.world = cam.unproject(x + 0.5, y + 0.5, z);
      const Vec3d q = other.project(w.world);  // corner convention: pixel i spans [i, i+1)
      if (!(q.z() > kNearPlane)) continue;
      // Inside the other image's pixels (centres at 0 .. OW − 1, each half a pixel wide).
      const double u = q.x() - 0.5, v = q.y() - 0.5;
      if (u < -0.5 || v < -0.5 || u > OW - 0.5 || v > OH - 0.5) continue;
      const int ni = std::clamp(int(std::lround(u)), 0, OW - 1), nj = std::clamp(int(std::lround(v)), 0, OH - 1);
      const float oz = other_depth[size_t(nj) * OW + ni];
      if (!(oz > 0) || std::abs(oz - q.z()) > tolerance * q.z()) continue;  // occluded in the other view
      w.valid = true, w.u = std::clamp(u, 0.0, double(OW - 1)), w.v = std::clamp(v, 0.0, double(OH - 1));
    }
  return out;
}

Image reference_fill(const Image& render, const Image& reference, double strength, double blur_sigma, double hallucination, uint64_t seed,
                     uint64_t key) {
  Image fill = render;
  degrade_unsupported(fill, strength, seed, key, std::max(0.0, blur_sigma));
  if (!(hallucination > 0)) return fill;
  if (reference.width != render.width || reference.height != render.height || reference.channels != 3 || render.channels != 3)
    throw_error("reference fill: the reference and the render differ in size");
  const int W = render.width, H = render.height;
  const double phi = 2 * kPi * uniform(seed, key, 3000), r = (0.15 + 0.2 * uniform(seed, key, 3001)) * W;
  const cv::Mat T = (cv::Mat_<double>(2, 3) << 1, 0, r * std::cos(phi), 0, 1, r * std::sin(phi));
  cv::Mat ref(H, W, CV_32FC3, const_cast<float*>(reference.pixels.data())), moved;
  cv::warpAffine(ref, moved, T, ref.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const float h = float(std::min(1.0, hallucination));
  const float* m = moved.ptr<float>(0);
  for (size_t i = 0; i < fill.pixels.size(); ++i) fill.pixels[i] = (1 - h) * fill.pixels[i] + h * m[i];
  return fill;
}

namespace {

/// What one virtual view is composed from.
struct ViewInputs {
  std::vector<float> content;   ///< [H][W][3]: what the reference shows there (truth, or the warped photograph)
  std::vector<float> truth;     ///< [H][W][3]: the truth at the view, where the form rendered it already (else empty)
  std::vector<float> seen;      ///< [H][W] in {0, 1}
  std::vector<float> parallax;  ///< [H][W] degrees, < 0 where no surface
  std::vector<float> moving;    ///< [H][W] share of moving content
  double fallback_degrees = 0;  ///< θ where no pixel has a surface: the angle between the optical axes
};

double median_of(std::vector<float> v) {
  if (v.empty()) return 0.0;
  const size_t k = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

/// The refined image of one view (ReferenceOptions): content where the reference reaches,
/// blended by its confidence with the degraded render. Fills `record`'s support,
/// confidence and parallax.
Image compose(const ReferenceOptions& o, const ViewInputs& in, const Image& rendered, const Image& reference, uint64_t key, uint64_t frame_key,
              RefinedViewRecord* record) {
  const int W = rendered.width, H = rendered.height;
  const size_t P = size_t(W) * H;
  std::vector<float> surface;
  for (float t : in.parallax)
    if (t >= 0) surface.push_back(t);
  const double median = surface.empty() ? in.fallback_degrees : median_of(surface);
  const double theta0 = o.angle_scale_degrees;
  const double far = 1.0 - std::exp(-median / theta0);
  const uint64_t seed = o.artifacts.seed;
  uint64_t draw = 2000;  // apart from degrade_unsupported's and inject_artifacts' draws for the same key
  auto u = [&] { return uniform(seed, key, draw++); };
  // Misplaced texture: every pixel shifted along one direction by shift·θ (twice on moving
  // content, which drifts along a direction of its own frame).
  const double phi = 2 * kPi * u();
  const double phi_moving = 2 * kPi * uniform(seed, frame_key, 1);
  cv::Mat mx(H, W, CV_32F), my(H, W, CV_32F);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t p = size_t(y) * W + x;
      const double t = in.parallax[p] >= 0 ? in.parallax[p] : median;
      const double s = o.shift_per_degree * W * t, m = in.moving[p];
      const double dx = (1 - m) * s * std::cos(phi) + m * 2 * s * std::cos(phi_moving);
      const double dy = (1 - m) * s * std::sin(phi) + m * 2 * s * std::sin(phi_moving);
      mx.at<float>(y, x) = float(x - dx), my.at<float>(y, x) = float(y - dy);
    }
  cv::Mat content(H, W, CV_32FC3, const_cast<float*>(in.content.data())), moved;
  cv::remap(content, moved, mx, my, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  const double sigma = o.blur_per_degree * W * median;
  if (sigma > 0.05) cv::GaussianBlur(moved, moved, cv::Size(0, 0), sigma);
  const double gain = 1 + o.flicker * far * (2 * uniform(seed, frame_key, 0) - 1);
  const Image fill = reference_fill(rendered, reference, o.fill_strength, o.fill_blur * W, o.hallucination, seed, key);
  Image out(W, H, 3);
  double confidence = 0, seen = 0;
  for (size_t p = 0; p < P; ++p) {
    const double t = in.parallax[p] >= 0 ? in.parallax[p] : median;
    const double scale = in.moving[p] >= 0.5 ? 0.5 * theta0 : theta0;
    const double c = in.seen[p] * std::exp(-t / scale);
    confidence += c, seen += in.seen[p];
    const float* m = moved.ptr<float>(0) + p * 3;
    for (int ch = 0; ch < 3; ++ch) out.pixels[p * 3 + ch] = float(c * gain * m[ch] + (1 - c) * fill.pixels[p * 3 + ch]);
  }
  if (o.artifacts.strength > 0 && far > 0) {
    ArtifactOptions a = o.artifacts;
    a.strength *= far;
    inject_artifacts(out, a, key);
  }
  record->parallax_degrees = median;
  record->support = seen / double(P);
  record->confidence = confidence / double(P);
  return out;
}

/// The patch's observed image at `frame`, or at its nearest frame that has one.

double axis_degrees(const Camera& a, const Camera& b) {
  const double c = std::clamp(a.R.row(2).dot(b.R.row(2)), -1.0, 1.0);
  return std::acos(c) * 180.0 / kPi;
}

/// Parallax per pixel from an expected-depth map (< 0 where there is none).
std::vector<float> parallax_map(const Camera& cam, const std::vector<float>& depth, const Vec3d& reference_centre) {
  std::vector<float> out(depth.size(), -1.0f);
  const Vec3d c = cam.centre();
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const float z = depth[size_t(y) * cam.width + x];
      if (z > 0) out[size_t(y) * cam.width + x] = float(parallax_degrees(cam.unproject(x + 0.5, y + 0.5, z), c, reference_centre));
    }
  return out;
}

/// 1 for the moving Gaussians of `cloud`, 0 for the static ones (a feature channel).
std::vector<float> moving_flags(const GaussianCloud& cloud) {
  std::vector<float> m(cloud.size(), 0.0f);
  for (uint32_t g : cloud.dynamic_ids) m[g] = 1.0f;
  return m;
}

void check_options(const ReferenceOptions& o) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(o.angle_scale_degrees))
    throw_error("reference refiner: the angle scale must be a positive number of degrees (got ", o.angle_scale_degrees, ")");
  if (!positive(o.placement_tolerance))
    throw_error("reference refiner: the placement tolerance must be a positive number (got ", o.placement_tolerance, ")");
  for (double v : {o.shift_per_degree, o.blur_per_degree, o.flicker, o.fill_strength, o.fill_blur, o.hallucination, o.artifacts.strength,
                   o.depth_tolerance})
    if (!(std::isfinite(v) && v >= 0))
      throw_error("reference refiner: shift, blur, flicker, fill and artifact strengths and the depth tolerance must be finite and at least 0");
}

/// What both forms share: the loop over a patch's virtual views, the records.
class ReferenceConditioned : public Refiner {
 public:
  ReferenceConditioned(const ReferenceOptions& o, SupportStats* stats, const GaussianCloud* truth) : o_(o), stats_(stats), truth_(truth) {
    check_options(o_);
  }
  void begin_round(const GaussianCloud& current, const Vec3f&) override {
    model_ = &current;
    model_depths_.clear();
    model_moving_ = moving_flags(current);
  }
  void refine(const std::string& in, const std::string& out, const Patch& patch) override {
    make_directories(out);
    std::map<std::string, Image> references;  // each observed image of the patch, read once
    for (const PatchImage& im : patch.images) {
      if (im.observed) continue;
      const PatchImage& ref = patch_reference(patch, im.frame);
      auto photo = references.find(ref.file);
      if (photo == references.end())
        photo = references.emplace(ref.file, read_rgb_image(join_path(in, ref.file), ref.camera.width, ref.camera.height)).first;
      const Image rendered = read_rgb_image(join_path(in, im.file), im.camera.width, im.camera.height);
      ViewInputs vi = inputs(photo->second, ref, im);
      vi.fallback_degrees = axis_degrees(im.camera, ref.camera);
      RefinedViewRecord rec;
      const uint64_t key = string_key((patch.name + "/" + im.file).c_str());
      const uint64_t frame_key = string_key((patch.name + "/frame" + std::to_string(im.frame)).c_str());
      const Image refined = compose(o_, vi, rendered, photo->second, key, frame_key, &rec);
      write_image(join_path(out, im.file), refined);
      if (!stats_) continue;
      rec.file = patch.name + "/" + im.file;
      rec.frame = im.frame;
      rec.axis_degrees = vi.fallback_degrees;
      rec.baseline = (im.camera.centre() - ref.camera.centre()).norm();
      rec.psnr_refined = rec.psnr_render = rec.psnr_seen = std::nan("");
      if (truth_) {
        const std::vector<float> t = vi.truth.empty() ? render(frame_at(*truth_, im.camera.time), im.camera, truth_options()).rgb : vi.truth;
        rec.psnr_refined = psnr(refined.pixels.data(), t.data(), refined.width, refined.height, 3);
        rec.psnr_render = psnr(rendered.pixels.data(), t.data(), refined.width, refined.height, 3);
        std::vector<unsigned char> seen(vi.seen.size());
        for (size_t q = 0; q < seen.size(); ++q) seen[q] = vi.seen[q] >= 0.5f;
        rec.psnr_seen = psnr(refined.pixels.data(), t.data(), refined.width, refined.height, 3, seen.data());
      }
      stats_->support_sum += rec.support * double(refined.width) * refined.height;
      stats_->pixels += size_t(refined.width) * refined.height;
      stats_->views.push_back(rec);
    }
  }

 protected:
  /// The inputs of virtual view `view`, whose reference is `reference` with image `photo`.
  virtual ViewInputs inputs(const Image& photo, const PatchImage& reference, const PatchImage& view) = 0;
  RenderOptions truth_options() const {
    RenderOptions ro;
    ro.background = o_.background;
    return ro;
  }
  /// The round's model's expected depth at a reference camera (its time), 0 where it
  /// renders less than half an opacity; once per camera and time in a round.
  const std::vector<float>& reference_depth(const Camera& camera) {
    const std::string id = camera.name + "@" + std::to_string(camera.time);
    auto it = model_depths_.find(id);
    if (it == model_depths_.end()) it = model_depths_.emplace(id, expected_depth(frame_at(*model_, camera.time), camera, 0.5)).first;
    return it->second;
  }
  ReferenceOptions o_;
  SupportStats* stats_;
  const GaussianCloud* truth_;
  const GaussianCloud* model_ = nullptr;  ///< the round's model (begin_round)
  std::vector<float> model_moving_;       ///< its moving flags
  std::map<std::string, std::vector<float>> model_depths_;
};

class ReferenceRefiner : public ReferenceConditioned {
 public:
  ReferenceRefiner(const GaussianCloud& truth, const ReferenceOptions& o, SupportStats* stats)
      : ReferenceConditioned(o, stats, &truth), engine_(truth, exact()), moving_(moving_flags(truth)) {}
  std::string name() const override { return "reference"; }

 protected:
  ViewInputs inputs(const Image&, const PatchImage& ref, const PatchImage& im) override {
    // Which Gaussians the reference camera saw at its own time (cached per camera and time).
    const std::string id = ref.camera.name + "@" + std::to_string(ref.camera.time);
    auto it = seen_.find(id);
    if (it == seen_.end()) {
      engine_.set_time(ref.camera.time);
      std::vector<float> flags(truth_->size() * 2, 0.0f);
      for (uint32_t g : engine_.visible_set(ref.camera)) flags[size_t(g) * 2] = 1.0f;
      for (size_t g = 0; g < truth_->size(); ++g) flags[g * 2 + 1] = moving_[g];
      it = seen_.emplace(id, std::move(flags)).first;
    }
    RenderOptions ro = truth_options();
    ro.depth = true;
    ro.features = it->second.data();
    ro.feature_channels = 2;
    const RenderOutput r = render(frame_at(*truth_, im.camera.time), im.camera, ro);
    const size_t P = r.alpha.size();
    ViewInputs vi;
    vi.content = r.rgb;
    vi.truth = r.rgb;
    vi.seen.assign(P, 0.0f);
    vi.moving.assign(P, 0.0f);
    std::vector<float> depth(P, 0.0f);
    for (size_t p = 0; p < P; ++p) {
      const float a = r.alpha[p];
      // Seen where surfaces the reference saw make up at least half of what the pixel shows.
      vi.seen[p] = a > 1e-4f && r.features[p * 2] >= 0.5f * a ? 1.0f : 0.0f;
      vi.moving[p] = a > 1e-4f ? std::clamp(r.features[p * 2 + 1] / a, 0.0f, 1.0f) : 0.0f;
      if (a >= 0.5f) depth[p] = r.depth[p] / a;
    }
    vi.parallax = parallax_map(im.camera, depth, ref.camera.centre());
    // It restores what the render roughly places and cannot create geometry the render
    // lacks: "seen" only where the model's depth agrees with the truth's (within
    // placement_tolerance × depth, soft), nowhere the model renders nothing.
    if (model_) {
      const std::vector<float> placed = expected_depth(frame_at(*model_, im.camera.time), im.camera, 0.5);
      const double tol = o_.placement_tolerance;
      for (size_t p = 0; p < P; ++p) {
        if (vi.seen[p] <= 0) continue;
        const double zt = depth[p], zm = placed[p];
        const double e = zt > 0 && zm > 0 ? (zm - zt) / (tol * zt) : 1e9;
        vi.seen[p] = float(std::exp(-e * e));
      }
    }
    return vi;
  }

 private:
  static VisibilityOptions exact() {
    VisibilityOptions v;
    v.mode = VisibilityMode::Exact;
    return v;
  }
  VisibilityEngine engine_;
  std::vector<float> moving_;
  std::map<std::string, std::vector<float>> seen_;
};

class WarpRefiner : public ReferenceConditioned {
 public:
  WarpRefiner(const ReferenceOptions& o, SupportStats* stats, const GaussianCloud* truth) : ReferenceConditioned(o, stats, truth) {}
  std::string name() const override { return "warp"; }

 protected:
  ViewInputs inputs(const Image& photo, const PatchImage& ref, const PatchImage& im) override {
    if (!model_) throw_error("warp refiner: no model (begin_round was not called)");
    RenderOptions ro;
    ro.rgb = false;
    ro.depth = true;
    ro.features = model_moving_.data();
    ro.feature_channels = 1;
    const RenderOutput r = render(frame_at(*model_, im.camera.time), im.camera, ro);
    const size_t P = r.alpha.size();
    std::vector<float> depth(P, 0.0f);
    ViewInputs vi;
    vi.moving.assign(P, 0.0f);
    for (size_t p = 0; p < P; ++p) {
      if (r.alpha[p] >= 0.5f) depth[p] = r.depth[p] / r.alpha[p];
      if (r.alpha[p] > 1e-4f) vi.moving[p] = std::clamp(r.features[p] / r.alpha[p], 0.0f, 1.0f);
    }
    const std::vector<WarpedPixel> warp = warp_pixels(im.camera, depth, ref.camera, reference_depth(ref.camera), o_.depth_tolerance);
    vi.content.assign(P * 3, 0.0f);
    vi.seen.assign(P, 0.0f);
    vi.parallax = parallax_map(im.camera, depth, ref.camera.centre());
    for (size_t p = 0; p < P; ++p) {
      const WarpedPixel& w = warp[p];
      if (!w.valid) continue;
      vi.seen[p] = 1.0f;
      for (int c = 0; c < 3; ++c) vi.content[p * 3 + size_t(c)] = float(photo.bilinear(w.u, w.v, c));
    }
    return vi;
  }
};

}  // namespace

std::unique_ptr<Refiner> make_reference_refiner(const GaussianCloud& truth, const ReferenceOptions& options, SupportStats* stats) {
  return std::make_unique<ReferenceRefiner>(truth, options, stats);
}

std::unique_ptr<Refiner> make_warp_refiner(const ReferenceOptions& options, SupportStats* stats, const GaussianCloud* truth) {
  return std::make_unique<WarpRefiner>(options, stats, truth);
}

}  // namespace fillgs
