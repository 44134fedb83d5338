// Optimisation throughput and training quality.
//  * speed: one training iteration's rasterization (forward + L1/D-SSIM loss + backward)
//    versus Gaussian count and resolution on a real scene, as a ratio to the forward
//    renderer alone measured in the same run;
//  * quality: the synthetic scene trained with all 16 cameras and with a 2-camera sparse
//    split (cam04, cam06), evaluated on interpolation and extrapolation cameras; the
//    sparse numbers are the baseline the method must beat. Also: how many promoted
//    (moving) Gaussians sit on the chair's track.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/render/loss.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/render/raster_grad.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/train/train.hpp"

using namespace fillgs;
using namespace fillgs::bench;

namespace {

GaussianCloud subsample(const GaussianCloud& c, size_t n) {
  GaussianCloud s;
  s.sh_degree = c.sh_degree;
  const size_t step = std::max<size_t>(1, c.size() / n);
  for (size_t g = 0; g < c.size() && s.size() < n; g += step) {
    const size_t i = s.size();
    s.resize(i + 1);
    s.means[i] = c.means[g];
    s.log_scales[i] = c.log_scales[g];
    s.rotations[i] = c.rotations[g];
    s.opacity_logits[i] = c.opacity_logits[g];
    std::copy(c.sh.begin() + g * c.sh_count() * 3, c.sh.begin() + (g + 1) * c.sh_count() * 3, s.sh.begin() + i * c.sh_count() * 3);
  }
  return s;
}

/// One training iteration's rasterization, stage by stage, with one kernel.
struct IterationTimes {
  double forward = 0, loss = 0, backward = 0;
  double total() const { return forward + loss + backward; }
};

IterationTimes time_iterations(const DiffFrame<float>& df, const std::vector<Camera>& cams, Kernel kernel) {
  const int w = cams[0].width, h = cams[0].height;
  std::vector<float> target(size_t(w) * h * 3, 0.5f), dimg(target.size());
  set_default_kernel(kernel);  // the loss's blur follows the process default
  DiffRenderOptions dro;
  dro.kernel = kernel;
  IterationTimes t;
  for (size_t v = 0; v <= cams.size(); ++v) {  // view 0 twice: the first is a warm-up
    const Camera& cam = cams[v == 0 ? 0 : v - 1];
    DiffRasterizer<float> r;
    auto t0 = Clock::now();
    r.forward(df, cam, dro);
    const double f = seconds_since(t0);
    t0 = Clock::now();
    photometric_loss<float>(r.image().data(), target.data(), w, h, nullptr, 0.2, dimg.data());
    const double l = seconds_since(t0);
    DiffFrameGrad<float> g;
    t0 = Clock::now();
    r.backward(dimg.data(), nullptr, nullptr, &g);
    const double b = seconds_since(t0);
    if (v > 0) t.forward += f / cams.size(), t.loss += l / cams.size(), t.backward += b / cams.size();
  }
  set_default_kernel(Kernel::Simd);
  return t;
}

void speed(bool smoke, size_t only_count, int only_width, int only_height) {
  const GaussianCloud full = read_scene(shared_data_dir() + "/scenes/guitar.ply");
  std::printf("\n## Training iteration speed (guitar.ply subsets, 2 threads, vector kernel on %s): "
              "forward + L1/D-SSIM loss + backward, against the scalar kernel in the same run\n\n", simd_target());
  std::printf("| Gaussians | resolution | scalar ms (fwd / loss / bwd) | simd ms (fwd / loss / bwd) | speed-up | iterations/s scalar | iterations/s simd |\n"
              "|---|---|---|---|---|---|---|\n");
  std::vector<size_t> counts = smoke ? std::vector<size_t>{5000} : std::vector<size_t>{10000, 45000, full.size()};
  if (only_count) counts = {std::min(only_count, full.size())};
  std::vector<std::pair<int, int>> sizes =
      smoke ? std::vector<std::pair<int, int>>{{160, 120}} : std::vector<std::pair<int, int>>{{338, 253}, {676, 507}, {1352, 1014}};
  if (only_width) sizes = {{only_width, only_height}};
  const int reps = smoke ? 1 : 5;
  for (size_t n : counts) {
    const GaussianCloud c = subsample(full, n);
    const ModelParams<float> p = params_from_cloud<float>(c);
    DiffFrame<float> df;
    params_at(p, 0.0, &df);
    for (auto [w, h] : sizes) {
      const std::vector<Camera> cams = bench::orbit(c, reps, w, h);
      const IterationTimes ref = time_iterations(df, cams, Kernel::Scalar);
      const IterationTimes vec = time_iterations(df, cams, Kernel::Simd);
      std::printf("| %zu | %dx%d | %.1f (%.1f / %.1f / %.1f) | %.1f (%.1f / %.1f / %.1f) | %.2f | %.1f | %.1f |\n", c.size(), w, h,
                  ref.total() * 1e3, ref.forward * 1e3, ref.loss * 1e3, ref.backward * 1e3, vec.total() * 1e3, vec.forward * 1e3,
                  vec.loss * 1e3, vec.backward * 1e3, ref.total() / vec.total(), 1.0 / ref.total(), 1.0 / vec.total());
      std::fflush(stdout);
    }
  }
}

struct Quality {
  double interp = 0, arc = 0, extrap = 0, seconds = 0;
  size_t gaussians = 0, moving = 0, moving_on_chair = 0;
};

Quality train_and_eval(const std::string& dir, const SynthScene& s, const std::vector<std::string>& cams, int iterations,
                       const std::vector<std::string>& arc) {
  DatasetOptions d;
  d.cameras = cams;
  const Dataset data = Dataset::load(dir + "/images", dir + "/transforms_train.json", d);
  TrainOptions o = TrainOptions::scaled(iterations);
  Trainer t(data, init_from_points(read_points(dir + "/points.ply")), o);
  const auto t0 = Clock::now();
  t.run(iterations, null_progress());
  Quality q;
  q.seconds = seconds_since(t0);
  const GaussianCloud m = t.model();
  q.gaussians = m.size();
  q.moving = m.dynamic_count();
  q.interp = evaluate_split(m, Dataset::load(dir + "/images", dir + "/transforms_interpolation.json"), "views").psnr;
  q.extrap = evaluate_split(m, Dataset::load(dir + "/images", dir + "/transforms_extrapolation.json"), "views").psnr;
  DatasetOptions a;
  a.cameras = arc;
  q.arc = evaluate_split(m, Dataset::load(dir + "/images", dir + "/transforms_interpolation.json", a), "views").psnr;
  // A moving Gaussian is "on the chair" when some frame puts it within 5 cm of a chair Gaussian.
  const int F = s.options.frames;
  std::vector<std::vector<Vec3f>> chair(static_cast<size_t>(F));
  for (int f = 0; f < F; ++f) {
    const FrameGaussians g = frame_at(s.scene, FrameGrid(F).time(f));
    for (uint32_t id : s.moving_ids) chair[size_t(f)].push_back(g.means[id]);
  }
  for (size_t j = 0; j < m.dynamic_count(); ++j) {
    bool on = false;
    for (int f = 0; f < F && !on; f += 3) {
      const Vec3f x = frame_at(m, FrameGrid(F).time(f)).means[m.dynamic_ids[j]];
      for (const Vec3f& c : chair[size_t(f)])
        if ((c - x).squaredNorm() < 0.05f * 0.05f) {
          on = true;
          break;
        }
    }
    q.moving_on_chair += on;
  }
  return q;
}

void quality(bool smoke, const std::string& out) {
  SynthOptions so;
  int iterations = 3000;
  if (smoke) {
    so.width = 64, so.height = 48, so.frames = 4, so.spacing = 0.05;
    iterations = 30;
  }
  const std::string dir = out + "/synth";
  const SynthScene s = make_synthetic_scene(so);
  write_synthetic_scene(s, dir, null_progress());
  std::printf("\n## Training quality on the synthetic scene (%dx%d, %d frames, %d iterations, 2 threads)\n\n", so.width, so.height,
              so.frames, iterations);
  std::printf("| training cameras | PSNR interp (all 16) | PSNR interp04-05 (inside the pair's arc) | PSNR extrap | Gaussians | moving | moving on the chair | train s |\n"
              "|---|---|---|---|---|---|---|---|\n");
  const std::vector<std::string> arc = {"interp04", "interp05"};
  std::vector<std::string> all;
  for (const Camera& c : s.train) all.push_back(c.name);
  for (const auto& [label, cams] : std::vector<std::pair<std::string, std::vector<std::string>>>{{"all 16", all}, {"2 (cam04, cam06)", {"cam04", "cam06"}}}) {
    const Quality q = train_and_eval(dir, s, cams, iterations, arc);
    std::printf("| %s | %.2f | %.2f | %.2f | %zu | %zu | %zu | %.0f |\n", label.c_str(), q.interp, q.arc, q.extrap, q.gaussians, q.moving,
                q.moving_on_chair, q.seconds);
    std::fflush(stdout);
  }
}

}  // namespace

int bench_train(const std::vector<std::string>& args) {
  const ThreadLimit two_threads(2);  // the tables say "2 threads"
  bool smoke = false;
  std::string out = "bench/results/train", only;
  size_t count = 0;  // --gaussians N: one subset only
  int width = 0, height = 0;  // --resolution WxH: one size only
  std::string resolution;
  auto app = cli::make_parser("fillgs_bench train", "training: iterations per second by model size and resolution, and quality");
  cli::add_flag(*app, "--smoke", smoke, "small sizes, few iterations");
  cli::add_text(*app, "--out", out, "the folder for the quality results", "DIR");
  cli::add_text(*app, "--only", only, "one part: speed or quality", "NAME");
  cli::add_number(*app, "--gaussians", count, "speed: one subset of this many Gaussians only (0: all sizes)");
  cli::add_text(*app, "--resolution", resolution, "speed: one image size only", "WxH");
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  if (!resolution.empty() && (std::sscanf(resolution.c_str(), "%dx%d", &width, &height) != 2 || width <= 0 || height <= 0))
    throw_error("fillgs_bench train: --resolution expects WxH, got '", resolution, "'");
  make_directories(out);
  if (only.empty() || only == "speed") speed(smoke, count, width, height);
  if (only.empty() || only == "quality") quality(smoke, out);
  return 0;
}
