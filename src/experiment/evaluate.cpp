#include "fillgs/experiment/evaluate.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/dnn.hpp>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/base/timing.hpp"

namespace fillgs {

std::vector<unsigned char> moving_region(const GaussianCloud& truth, const Camera& camera) {
  std::vector<float> moving(truth.size(), 0.0f);
  for (uint32_t g : truth.dynamic_ids) moving[g] = 1.0f;
  RenderOptions ro;
  ro.rgb = false;
  ro.features = moving.data();
  ro.feature_channels = 1;
  const RenderOutput r = render(frame_at(truth, camera.time), camera, ro);
  std::vector<unsigned char> mask(r.alpha.size(), 0);
  for (size_t p = 0; p < mask.size(); ++p) mask[p] = r.alpha[p] > 0 && r.features[p] >= 0.5f * r.alpha[p];
  return mask;
}

struct LpipsNetwork::Impl {
  cv::dnn::Net net;
};

LpipsNetwork::LpipsNetwork(const std::string& path) : impl_(std::make_unique<Impl>()) {
  try {
    impl_->net = cv::dnn::readNetFromONNX(path);
  } catch (const cv::Exception& e) {
    throw_error(path, ": cannot load the LPIPS network (", e.what(), ")");
  }
}

LpipsNetwork::~LpipsNetwork() = default;
LpipsNetwork::LpipsNetwork(LpipsNetwork&&) noexcept = default;
LpipsNetwork& LpipsNetwork::operator=(LpipsNetwork&&) noexcept = default;

double LpipsNetwork::distance(const float* a, const float* b, int W, int H) {
  auto blob = [&](const float* img) {
    const int sz[4] = {1, 3, H, W};
    cv::Mat m(4, sz, CV_32F);
    float* d = m.ptr<float>();
    for (int c = 0; c < 3; ++c)
      for (int p = 0; p < W * H; ++p) d[size_t(c) * W * H + p] = 2.0f * std::clamp(img[size_t(p) * 3 + c], 0.0f, 1.0f) - 1.0f;
    return m;
  };
  cv::Mat ba = blob(a), bb = blob(b);
  // The graph's inputs must be named in0 and in1 (the lpips export's names).
  impl_->net.setInput(ba, "in0");
  impl_->net.setInput(bb, "in1");
  cv::Mat out = impl_->net.forward();
  if (out.total() == 0) throw_error("LPIPS network returned nothing");
  return double(out.ptr<float>()[0]);
}

std::vector<float> fit_colours(const std::vector<float>& render, const std::vector<float>& target, ColourFit fit) {
  if (render.size() != target.size() || render.size() % 3) throw_error("fit_colours: ", render.size(), " render values for ", target.size(), " image values");
  std::vector<float> out = render;
  const double P = double(render.size() / 3);
  if (P == 0) return out;
  for (int ch = 0; ch < 3; ++ch) {
    double r = 0, t = 0, rt = 0, rr = 0;
    for (size_t p = size_t(ch); p < out.size(); p += 3) r += render[p], t += target[p], rt += double(render[p]) * target[p], rr += double(render[p]) * render[p];
    double g = 1, b = 0;
    if (fit == ColourFit::Gain) {
      if (rr > 0) g = rt / rr;
    } else {
      // Centred sums: g = cov(r, t) / var(r), b = mean(t) − g·mean(r).
      const double var = rr - r * r / P, cov = rt - r * t / P;
      if (var > 1e-12 * std::max(1.0, rr)) g = cov / var;
      b = (t - g * r) / P;
    }
    for (size_t p = size_t(ch); p < out.size(); p += 3) out[p] = float(g * render[p] + b);
  }
  return out;
}

SplitMetrics evaluate_split(const GaussianCloud& model, const Dataset& split, const std::string& name, const EvalOptions& o,
                            Progress& progress) {
  const auto t0 = Clock::now();
  SplitMetrics m;
  m.split = name;
  std::unique_ptr<LpipsNetwork> lpips;
  if (!o.lpips_onnx.empty()) lpips = std::make_unique<LpipsNetwork>(o.lpips_onnx), m.lpips = 0;
  if (!o.save_dir.empty()) make_directories(o.save_dir);
  FrameSampler ev(model);
  RenderOptions ro;
  ro.background = o.background;
  double moving_se = 0;
  const size_t step = size_t(std::max(1, o.view_stride));
  progress.start("evaluate " + name, (split.views().size() + step - 1) / step);
  for (size_t v = 0; v < split.views().size(); v += step) {
    const TrainView& view = split.views()[v];
    const int W = view.camera.width, H = view.camera.height;
    RenderOutput out = render(ev.at(view.camera.time), view.camera, ro);
    const std::vector<float> target = split.image(v);
    for (const ColourCorrection& c : o.colour)
      if (c.rig == view.rig) apply_colour_correction(c, out.rgb);
    ViewMetrics vm;
    vm.camera = view.rig, vm.frame = view.frame;
    if (o.ls_gain) {
      vm.psnr_ls_gain = psnr(fit_colours(out.rgb, target, ColourFit::Gain).data(), target.data(), W, H, 3);
      m.psnr_ls_gain = (m.views ? m.psnr_ls_gain : 0.0) + vm.psnr_ls_gain;
    }
    if (o.affine_fit) {
      vm.psnr_affine = psnr(fit_colours(out.rgb, target, ColourFit::Affine).data(), target.data(), W, H, 3);
      m.psnr_affine = (m.views ? m.psnr_affine : 0.0) + vm.psnr_affine;
    }
    vm.psnr = psnr(out.rgb.data(), target.data(), W, H, 3);
    vm.ssim = ssim(out.rgb.data(), target.data(), W, H, 3);
    m.psnr += vm.psnr;
    m.ssim += vm.ssim;
    if (lpips) m.lpips += lpips->distance(out.rgb.data(), target.data(), W, H);
    if (o.moving && (o.truth || split.has_masks())) {
      // The moving region: the truth's moving Gaussians, else the dataset's foreground masks.
      const std::vector<unsigned char> mask = o.truth ? moving_region(*o.truth, view.camera) : split.mask(v);
      for (size_t p = 0; p < mask.size(); ++p) {
        if (!mask[p]) continue;
        ++vm.moving_pixels;
        for (int c = 0; c < 3; ++c) {
          const double d = std::clamp(out.rgb[p * 3 + c], 0.0f, 1.0f) - std::clamp(target[p * 3 + c], 0.0f, 1.0f);
          vm.moving_squared_error += d * d;
        }
      }
      m.moving_pixels += vm.moving_pixels;
      moving_se += vm.moving_squared_error;
    }
    m.per_view.push_back(std::move(vm));
    if (!o.save_dir.empty()) {
      const Image im(W, H, 3, out.rgb);
      std::string file = view.camera.name;
      for (char& c : file)
        if (c == '/') c = '_';
      write_image(join_path(o.save_dir, file + ".png"), im);
    }
    ++m.views;
    progress.advance();
  }
  progress.finish();
  if (m.views) {
    m.psnr /= double(m.views), m.ssim /= double(m.views);
    if (o.ls_gain) m.psnr_ls_gain /= double(m.views);
    if (o.affine_fit) m.psnr_affine /= double(m.views);
    if (lpips) m.lpips /= double(m.views);
  }
  if (m.moving_pixels > 0) {
    const double mse = moving_se / (3.0 * double(m.moving_pixels));
    m.psnr_moving = psnr_of_mse(mse);
  }
  m.seconds = seconds_since(t0);
  return m;
}

SplitMetrics evaluate_training_sample(const GaussianCloud& model, const Dataset& data, const Vec3f& background) {
  EvalOptions o;
  o.view_stride = std::max<int>(1, int(data.views().size() / 32));
  o.background = background;
  o.moving = false;
  return evaluate_split(model, data, "train", o);
}

}  // namespace fillgs
