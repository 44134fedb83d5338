#include "fillgs/method/weights.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/method/refine.hpp"
#include "fillgs/render/raster.hpp"

namespace fillgs {

namespace {

/// Gaussians whose maximum blending weight in a view reaches 1/255 (the rasterizer's own
/// notion of "contributes"), as a 0/1 vector, and the per-Gaussian maximum weights.
std::vector<float> max_weights(const FrameGaussians& frame, const Camera& camera) {
  RenderOptions ro;
  ro.rgb = false;
  ro.max_weights = true;
  return render(frame, camera, ro).max_weight;
}

/// Σ over RGB of (refined(x, y) − observed bilinear at (u, v))², (u, v) in pixel-index
/// coordinates inside the observed image.
double squared_difference(const Image& refined, int x, int y, const Image& observed, double u, double v) {
  double e = 0;
  for (int c = 0; c < 3; ++c) {
    const double d = refined.at(x, y, c) - observed.bilinear(u, v, c);
    e += d * d;
  }
  return e;
}

/// The model's expected depth in observed view `v` (cached in the context).
const std::vector<float>& observed_depth(const WeightContext& ctx, const FrameGaussians& frame, size_t v, double min_alpha) {
  auto it = ctx.observed_depths.find(v);
  if (it == ctx.observed_depths.end())
    it = ctx.observed_depths.emplace(v, expected_depth(frame, ctx.views[v].camera, min_alpha)).first;
  return it->second;
}

std::vector<float> ones(const Camera& c) { return std::vector<float>(size_t(c.width) * size_t(c.height), 1.0f); }

}  // namespace

void normalise_by_mean(std::vector<float>& w) {
  if (w.empty()) return;
  double sum = 0;
  for (float x : w) sum += double(x);
  if (!(sum > 0)) return;
  const float k = float(double(w.size()) / sum);
  for (float& x : w) x *= k;
}

std::vector<float> expected_depth(const FrameGaussians& frame, const Camera& camera, double min_alpha) {
  RenderOptions ro;
  ro.rgb = false;
  ro.depth = true;
  const RenderOutput r = render(frame, camera, ro);
  std::vector<float> d(r.depth.size(), 0.0f);
  for (size_t p = 0; p < d.size(); ++p)
    if (r.alpha[p] >= min_alpha) d[p] = r.depth[p] / r.alpha[p];
  return d;
}

std::vector<float> consistency_with(const Image& refined, const Camera& cam, const std::vector<float>& depth, const Image& observed,
                                    const Camera& ocam, const std::vector<float>& odepth, const MaskOptions& o) {
  const int W = cam.width, H = cam.height, OW = ocam.width, OH = ocam.height;
  if (refined.width != W || refined.height != H || refined.channels < 3) throw_error("consistency: refined image does not match its camera");
  if (observed.width != OW || observed.height != OH || observed.channels < 3) throw_error("consistency: observed image does not match its camera");
  if (depth.size() != size_t(W) * H || odepth.size() != size_t(OW) * OH) throw_error("consistency: depth maps do not match the cameras");
  cv::Mat diff(H, W, CV_32F, cv::Scalar(0)), valid(H, W, CV_32F, cv::Scalar(0));
  const std::vector<WarpedPixel> warp = warp_pixels(cam, depth, ocam, odepth, o.depth_tolerance);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const WarpedPixel& w = warp[size_t(y) * W + x];
      if (!w.valid) continue;
      // Colour difference to the warped observation, the best within ±search pixels (the
      // warp through a rendered depth is not exact at texture edges and silhouettes).
      double d2 = 1e30;
      for (int dv = -o.search; dv <= o.search; ++dv)
        for (int du = -o.search; du <= o.search; ++du) {
          const double su = std::clamp(w.u + du, 0.0, double(OW - 1)), sv = std::clamp(w.v + dv, 0.0, double(OH - 1));
          d2 = std::min(d2, squared_difference(refined, x, y, observed, su, sv));
        }
      diff.at<float>(y, x) = float(d2 / 3);
      valid.at<float>(y, x) = 1;
    }
  const int win = std::max(1, o.window | 1);
  cv::Mat sd, sv;
  cv::boxFilter(diff, sd, CV_32F, cv::Size(win, win), cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
  cv::boxFilter(valid, sv, CV_32F, cv::Size(win, win), cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
  std::vector<float> conf(size_t(W) * H, 0.0f);
  const double s2 = o.sigma * o.sigma;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      if (valid.at<float>(y, x) <= 0) continue;
      const double m = sd.at<float>(y, x) / std::max(1.0f, sv.at<float>(y, x));
      conf[size_t(y) * W + x] = float(std::exp(-m / s2));
    }
  return conf;
}

std::vector<float> sweep_consistency(const Image& refined, const Camera& cam, const Image& observed, const Camera& ocam, double near, double far,
                                     const MaskOptions& o) {
  const int W = cam.width, H = cam.height, OW = ocam.width, OH = ocam.height;
  if (refined.width != W || refined.height != H || observed.width != OW || observed.height != OH)
    throw_error("sweep consistency: images do not match their cameras");
  const int win = std::max(1, o.window | 1);
  const int K = std::max(2, o.sweep_planes);
  cv::Mat best(H, W, CV_32F, cv::Scalar(1e9f));
  cv::Mat cost(H, W, CV_32F), valid(H, W, CV_32F);
  for (int k = 0; k < K; ++k) {
    const double inv = 1.0 / near + (1.0 / far - 1.0 / near) * k / (K - 1);
    const double z = 1.0 / inv;
    cost.setTo(0);
    valid.setTo(0);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const Vec3d q = ocam.project(cam.unproject(x + 0.5, y + 0.5, z));
        if (!(q.z() > kNearPlane)) continue;
        const double u = q.x() - 0.5, v = q.y() - 0.5;
        if (u < 0 || v < 0 || u > OW - 1 || v > OH - 1) continue;
        cost.at<float>(y, x) = float(squared_difference(refined, x, y, observed, u, v) / 3);
        valid.at<float>(y, x) = 1;
      }
    cv::Mat sc, sv;
    cv::boxFilter(cost, sc, CV_32F, cv::Size(win, win), cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
    cv::boxFilter(valid, sv, CV_32F, cv::Size(win, win), cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        if (valid.at<float>(y, x) > 0) best.at<float>(y, x) = std::min(best.at<float>(y, x), sc.at<float>(y, x) / std::max(1.0f, sv.at<float>(y, x)));
  }
  std::vector<float> conf(size_t(W) * H, 0.0f);
  const double s2 = o.sigma * o.sigma;
  for (int p = 0; p < W * H; ++p) {
    const float m = best.at<float>(p);
    conf[size_t(p)] = m >= 1e8f ? 0.0f : float(std::exp(-m / s2));
  }
  return conf;
}

std::vector<float> ssim_map(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels < 3 || b.channels < 3) throw_error("ssim map: images differ in size");
  const int W = a.width, H = a.height;
  std::vector<float> out(size_t(W) * H, 0.0f);
  constexpr double C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;
  for (int c = 0; c < 3; ++c) {
    cv::Mat x(H, W, CV_32F), y(H, W, CV_32F);
    for (int p = 0; p < W * H; ++p) {
      x.at<float>(p) = std::clamp(a.pixels[size_t(p) * a.channels + c], 0.0f, 1.0f);
      y.at<float>(p) = std::clamp(b.pixels[size_t(p) * b.channels + c], 0.0f, 1.0f);
    }
    auto blur = [](const cv::Mat& m) {
      cv::Mat r;
      cv::GaussianBlur(m, r, cv::Size(11, 11), 1.5, 1.5, cv::BORDER_CONSTANT);
      return r;
    };
    const cv::Mat mx = blur(x), my = blur(y), sxx = blur(x.mul(x)), syy = blur(y.mul(y)), sxy = blur(x.mul(y));
    for (int p = 0; p < W * H; ++p) {
      const double ux = mx.at<float>(p), uy = my.at<float>(p);
      const double vx = sxx.at<float>(p) - ux * ux, vy = syy.at<float>(p) - uy * uy, cxy = sxy.at<float>(p) - ux * uy;
      out[size_t(p)] += float((2 * ux * uy + C1) * (2 * cxy + C2) / ((ux * ux + uy * uy + C1) * (vx + vy + C2)) / 3.0);
    }
  }
  return out;
}

std::vector<int> adjacent_observed(const std::vector<ObservedView>& views, const Camera& camera, int frame) {
  std::vector<std::pair<double, int>> d;
  for (size_t i = 0; i < views.size(); ++i)
    if (views[i].frame == frame) d.emplace_back((views[i].camera.centre() - camera.centre()).norm(), int(i));
  std::sort(d.begin(), d.end());
  std::vector<int> out;
  for (const auto& [dist, i] : d) {
    bool same_pose = false;
    for (int j : out) same_pose |= views[size_t(j)].pose == views[size_t(i)].pose;
    if (!same_pose) out.push_back(i);
    if (out.size() == 2) break;
  }
  return out;
}

namespace {

/// What a weighting reads for one refined view.
struct WeighInputs {
  const WeightContext& ctx;
  const Image& refined;
  const Camera& camera;
  const FrameGaussians& frame;  ///< the model at the view's time
  int f;                        ///< the view's frame
  const std::vector<int>& adjacent;
};

/// A weighting (weights.hpp, Weighting): which of the two fillgs maps it needs, and how it
/// turns them (or its own measure) into the view's weight map and image weight.
class WeightingRule {
 public:
  virtual ~WeightingRule() = default;
  virtual bool uses_consistency() const { return false; }
  virtual bool uses_covisibility() const { return false; }
  /// Sets w.weight (all ones on entry) and w.image_weight.
  virtual void weigh(const WeighInputs& in, ViewWeights& w) const = 0;
};

/// none: every refined pixel counts fully.
class Unweighted : public WeightingRule {
 public:
  void weigh(const WeighInputs&, ViewWeights&) const override {}
};

/// fillgs: consistency × co-visibility; no-consistency and no-covisibility keep one of them.
class FillgsWeights : public WeightingRule {
 public:
  FillgsWeights(bool consistency, bool covisibility) : consistency_(consistency), covisibility_(covisibility) {}
  bool uses_consistency() const override { return consistency_; }
  bool uses_covisibility() const override { return covisibility_; }
  void weigh(const WeighInputs&, ViewWeights& w) const override {
    for (size_t p = 0; p < w.weight.size(); ++p)
      w.weight[p] = (w.consistency.empty() ? 1.0f : w.consistency[p]) * (w.covisibility.empty() ? 1.0f : w.covisibility[p]);
  }

 private:
  bool consistency_, covisibility_;
};

/// 3dgs-enhancer: an image weight from the distance to the nearest training camera against
/// the cameras' own spacing, times the rendered Gaussian size (over its 99th percentile).
class EnhancerWeights : public WeightingRule {
 public:
  void weigh(const WeighInputs& in, ViewWeights& w) const override {
    std::vector<Vec3d> centres;
    for (const ObservedView& v : in.ctx.views)
      if (v.frame == in.f) centres.push_back(v.camera.centre());
    double d = 1e30;
    for (const Vec3d& c : centres) d = std::min(d, (c - in.camera.centre()).norm());
    std::vector<double> spacing;
    for (size_t i = 0; i < centres.size(); ++i) {
      double s = 1e30;
      for (size_t j = 0; j < centres.size(); ++j)
        if (i != j && (centres[i] - centres[j]).norm() > 1e-9) s = std::min(s, (centres[i] - centres[j]).norm());
      if (s < 1e30) spacing.push_back(s);
    }
    std::sort(spacing.begin(), spacing.end());
    const double ref = spacing.empty() ? 1.0 : spacing[spacing.size() / 2];
    w.image_weight = centres.empty() ? 1.0 : std::exp(-d / ref);
    std::vector<float> size(in.frame.size());
    for (size_t g = 0; g < in.frame.size(); ++g) size[g] = in.frame.scales[g].maxCoeff();
    std::vector<float> sorted = size;
    const size_t q = std::min(sorted.size() - 1, size_t(0.99 * double(sorted.size())));
    std::nth_element(sorted.begin(), sorted.begin() + long(q), sorted.end());
    const float scale = std::max(sorted[q], 1e-12f);
    for (float& s : size) s = std::min(1.0f, s / scale);
    w.weight = render_value_map(in.frame, in.camera, size.data());
    for (float& x : w.weight) x = float(x * w.image_weight);
  }
};

/// exploregs: an image weight 1 − IoU of the Gaussians seen with the nearest observed view,
/// times the SSIM of the refined image against the model's render.
class ExploreGSWeights : public WeightingRule {
 public:
  void weigh(const WeighInputs& in, ViewWeights& w) const override {
    double iou = 0;
    if (!in.adjacent.empty()) {
      const std::vector<float> a = max_weights(in.frame, in.camera);
      const std::vector<float> b = max_weights(in.frame, in.ctx.views[size_t(in.adjacent[0])].camera);
      size_t inter = 0, uni = 0;
      for (size_t g = 0; g < a.size(); ++g) {
        const bool va = a[g] >= kMinAlpha, vb = b[g] >= kMinAlpha;
        inter += va && vb;
        uni += va || vb;
      }
      iou = uni ? double(inter) / double(uni) : 0.0;
    }
    w.image_weight = 1.0 - iou;
    RenderOptions ro;
    ro.background = in.ctx.background;
    const RenderOutput r = render(in.frame, in.camera, ro);
    const Image rendered(in.camera.width, in.camera.height, 3, r.rgb);
    const std::vector<float> s = ssim_map(in.refined, rendered);
    for (size_t p = 0; p < w.weight.size(); ++p) w.weight[p] = float(w.image_weight * std::clamp(s[p], 0.0f, 1.0f));
  }
};

/// ua-4dgs: the rendered 1 / (1 + Σ blending weights over the training views at the frame).
class UncertaintyWeights : public WeightingRule {
 public:
  void weigh(const WeighInputs& in, ViewWeights& w) const override {
    std::vector<float> seen(in.frame.size(), 0.0f);
    for (const ObservedView& v : in.ctx.views) {
      if (v.frame != in.f) continue;
      const std::vector<float> m = max_weights(in.frame, v.camera);
      for (size_t g = 0; g < seen.size(); ++g) seen[g] += m[g];
    }
    for (float& s : seen) s = 1.0f / (1.0f + s);
    w.weight = render_value_map(in.frame, in.camera, seen.data());
  }
};

/// The registry: each weighting's rule, by its value (whose name is in weights.hpp).
const WeightingRule& rule_of(Weighting weighting) {
  static const Unweighted none;
  static const FillgsWeights fillgs(true, true), no_consistency(false, true), no_covisibility(true, false);
  static const EnhancerWeights enhancer;
  static const ExploreGSWeights exploregs;
  static const UncertaintyWeights ua4dgs;
  static const std::pair<Weighting, const WeightingRule*> kRules[] = {
      {Weighting::FillGS, &fillgs},         {Weighting::None, &none},         {Weighting::NoConsistency, &no_consistency},
      {Weighting::NoCovisibility, &no_covisibility}, {Weighting::Enhancer3DGS, &enhancer}, {Weighting::ExploreGS, &exploregs},
      {Weighting::UA4DGS, &ua4dgs}};
  for (const auto& [id, rule] : kRules)
    if (id == weighting) return *rule;
  throw_error("weights: weighting '", to_string(weighting), "' has no rule in the registry");
}

}  // namespace

DeficiencyField weight_field(const GaussianCloud& model, const ObservationTables& tables, float quantile, const MaskOptions& options) {
  // D̂ scaled per frame by the moving Gaussians visible there (their opacity at each frame of
  // the tables), unless the global scale is asked for.
  std::vector<float> opacity;
  if (options.scale == CovisibilityScale::Visible) {
    const size_t M = tables.dynamic_ids.size();
    opacity.resize(tables.times.size() * M);
    for (size_t f = 0; f < tables.times.size(); ++f) {
      const FrameGaussians fg = frame_at(model, tables.times[f]);
      for (size_t j = 0; j < M; ++j) opacity[f * M + j] = fg.opacities[tables.dynamic_ids[j]];
    }
  }
  return DeficiencyField(tables, quantile, opacity.empty() ? nullptr : &opacity);
}

ViewWeights compute_weights(const WeightContext& ctx, const Image& refined, const Camera& camera, Weighting weighting,
                            const MaskOptions& o, const std::string& external_name) {
  if (!ctx.model) throw_error("weights: no model");
  const WeightingRule& rule = rule_of(weighting);
  ViewWeights w;
  const size_t P = size_t(camera.width) * size_t(camera.height);
  const int f = FrameGrid(std::max(1, ctx.frames)).nearest(camera.time);
  const FrameGaussians frame = frame_at(*ctx.model, camera.time);
  const std::vector<int> adj = adjacent_observed(ctx.views, camera, f);
  for (size_t k = 0; k < adj.size() && k < 2; ++k) w.adjacent[k] = adj[k];

  if (rule.uses_consistency()) {
    if (o.method == MaskMethod::External) {
      const std::string path = join_path(o.external_dir, external_name);
      const Image m = read_image(path);
      if (m.width != camera.width || m.height != camera.height)
        throw_error(path, ": confidence map is ", m.width, "x", m.height, ", expected ", camera.width, "x", camera.height);
      w.consistency.resize(P);
      for (size_t p = 0; p < P; ++p) w.consistency[p] = std::clamp(m.pixels[p * size_t(m.channels)], 0.0f, 1.0f);
    } else {
      if (!ctx.image) throw_error("weights: the consistency mask needs the observed images");
      const std::vector<float> depth = expected_depth(frame, camera, o.min_alpha);
      const float far = 2.0f * std::max(1.0f, *std::max_element(depth.begin(), depth.end()));
      w.consistency.assign(P, 0.0f);
      for (int a : adj) {
        const Camera& oc = ctx.views[size_t(a)].camera;
        const std::vector<float> c =
            o.method == MaskMethod::Sweep
                ? sweep_consistency(refined, camera, ctx.image(size_t(a)), oc, o.sweep_near, far, o)
                : consistency_with(refined, camera, depth, ctx.image(size_t(a)), oc, observed_depth(ctx, frame, size_t(a), o.min_alpha), o);
        for (size_t p = 0; p < P; ++p) w.consistency[p] = std::max(w.consistency[p], c[p]);
      }
    }
  }
  if (rule.uses_covisibility()) {
    if (!ctx.deficiency) throw_error("weights: the co-visibility weight needs the deficiency tables");
    const std::vector<float> v = ctx.deficiency->covisibility(f, o.covisibility);
    w.covisibility = render_value_map(frame, camera, v.data());
  }
  w.weight = ones(camera);
  rule.weigh({ctx, refined, camera, frame, f, adj}, w);
  for (float& x : w.weight)
    if (!std::isfinite(x)) x = 0;
  return w;
}

namespace {
cv::Mat grey8(const Image& im) {
  cv::Mat g(im.height, im.width, CV_8UC1);
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) {
      const double l = 0.299 * im.at(x, y, 0) + 0.587 * im.at(x, y, 1) + 0.114 * im.at(x, y, 2);
      g.at<uint8_t>(y, x) = uint8_t(std::lround(std::clamp(l, 0.0, 1.0) * 255.0));
    }
  return g;
}
cv::Mat dis_flow(const cv::Mat& from, const cv::Mat& to) {
  cv::Ptr<cv::DISOpticalFlow> dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  cv::Mat flow;
  dis->calc(from, to, flow);
  return flow;
}
}  // namespace

std::vector<uint8_t> flow_consistency(const Image& image, const Image& reference, const FlowCheckOptions& o) {
  if (image.width != reference.width || image.height != reference.height || image.channels != 3 || reference.channels != 3)
    throw_error("flow check: the image and its reference must be RGB images of one size");
  if (!(o.round_trip_pixels > 0) || !(o.colour_rms > 0)) throw_error("flow check: the tolerances must be positive");
  const int W = image.width, H = image.height;
  const cv::Mat a = grey8(image), b = grey8(reference);
  const cv::Mat forward = dis_flow(a, b), backward = dis_flow(b, a);
  Image back(W, H, 2);  // the backward flow, for Image::bilinear
  std::copy_n(backward.ptr<float>(), back.pixels.size(), back.pixels.begin());
  std::vector<uint8_t> pass(size_t(W) * H, 0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const cv::Vec2f f = forward.at<cv::Vec2f>(y, x);
      const double u = x + double(f[0]), v = y + double(f[1]);
      if (!(u >= 0 && v >= 0 && u <= W - 1 && v <= H - 1)) continue;
      const double g[2] = {back.bilinear(u, v, 0), back.bilinear(u, v, 1)};
      if (std::hypot(f[0] + g[0], f[1] + g[1]) > o.round_trip_pixels) continue;
      double e = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = image.at(x, y, c) - reference.bilinear(u, v, c);
        e += d * d;
      }
      if (std::sqrt(e / 3.0) <= o.colour_rms) pass[size_t(y) * W + x] = 1;
    }
  return pass;
}

double roc_auc(const std::vector<float>& score, const std::vector<uint8_t>& label) {
  if (score.size() != label.size()) throw_error("roc_auc: ", score.size(), " scores for ", label.size(), " labels");
  std::vector<size_t> order(score.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return score[a] < score[b]; });
  double rank_sum = 0;
  size_t pos = 0;
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j < order.size() && score[order[j]] == score[order[i]]) ++j;
    const double mid = 0.5 * double(i + 1 + j);  // mean rank of the tie group (1-based)
    for (size_t k = i; k < j; ++k)
      if (label[order[k]]) rank_sum += mid, ++pos;
    i = j;
  }
  const size_t neg = score.size() - pos;
  if (pos == 0 || neg == 0) return std::nan("");
  return (rank_sum - double(pos) * double(pos + 1) / 2) / (double(pos) * double(neg));
}

}  // namespace fillgs

namespace fillgs {

RefinedViewWeigher::RefinedViewWeigher(const GaussianCloud& model, const ObservationTables& tables, float quantile, const MaskOptions& mask,
                                       Weighting weighting, std::vector<ObservedView> views, std::function<Image(size_t)> image, int frames,
                                       const Vec3f& background)
    : field_(weight_field(model, tables, quantile, mask)), mask_(mask), weighting_(weighting) {
  context_.model = &model;
  context_.views = std::move(views);
  context_.image = std::move(image);
  context_.deficiency = &field_;
  context_.frames = frames;
  context_.background = background;
}

ViewWeights RefinedViewWeigher::operator()(const Image& refined, const Camera& camera, const std::string& external_name) const {
  return compute_weights(context_, refined, camera, weighting_, mask_, external_name);
}

}  // namespace fillgs
