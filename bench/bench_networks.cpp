// fillgs_bench networks: the trained models' deformation networks evaluated by the dense
// kernel (model/dense.hpp) against the reference Eigen products (what fillgs ran before the
// kernel), on the same models in the same run: Gaussian-frames per second, the speed-up,
// the multiply-adds per Gaussian-frame and the share of the machine's FMA bound reached.
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/io/trained_models.hpp"
#include "fillgs/model/dense.hpp"

using namespace fillgs;

namespace {


double seconds_of(const std::chrono::steady_clock::time_point& t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int bench_networks(const std::vector<std::string>& args) {
  std::string models;
  int frames = 6, model_frames = 300, threads = 0;
  bool smoke = false;
  auto app = cli::make_parser("fillgs_bench networks", "trained models' networks: the dense kernel against the reference products, in one run");
  cli::add_text(*app, "--models", models, "a folder of models made by tests/make_model_fixtures.py --bench (e-d3dgs, 4dgaussians, deformable3dgs)", "DIR")
      ->required();
  cli::add_number(*app, "--frames", frames, "frames timed per model and path", cli::at_least(1));
  cli::add_number(*app, "--model-frames", model_frames, "the frames the 4DGaussians and Deformable 3D Gaussians models cover", cli::at_least(1));
  cli::add_number(*app, "--threads", threads, "threads (0: all)", cli::at_least(0));
  cli::add_flag(*app, "--smoke", smoke, "two frames");
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  if (smoke) frames = 2;
  const int T = threads ? threads : tbb::info::default_concurrency();
  const int lanes = dense::lane_count();
  const double ghz = bench::clock_ghz();
  // Two FMA units per core (Intel since Haswell, AMD since Zen), each `lanes` multiply-adds a cycle.
  const double bound = 2.0 * lanes * ghz * 1e9 * T;
  std::printf("dense kernel: %s, %d float lanes; %d threads; FMA bound: %d threads x 2 FMA units x %d lanes x %.2f GHz (the clock measured by a chain of adds) = %.3g multiply-adds/s\n\n",
              dense::target_name(), lanes, T, T, lanes, ghz, bound);
  std::printf("| format | Gaussians | multiply-adds per Gaussian-frame | reference Gaussian-frames/s | kernel Gaussian-frames/s | speed-up | kernel multiply-adds/s | share of the FMA bound | largest difference |\n"
              "|---|---|---|---|---|---|---|---|---|\n");
  int rows_printed = 0;
  tbb::task_arena(T).execute([&] {
    for (const char* name : {"e-d3dgs", "4dgaussians", "deformable3dgs"}) {
      const std::string dir = models + "/" + name;
      if (!std::filesystem::exists(dir)) continue;
      SceneReadOptions o;
      if (std::string(name) != "e-d3dgs") o.model_frames = model_frames;
      const auto model = open_trained_model(dir, "auto", o);
      const size_t N = model->size();
      std::vector<uint32_t> all(N);
      for (size_t i = 0; i < N; ++i) all[i] = uint32_t(i);
      std::vector<double> times;
      for (int k = 0; k < frames; ++k) times.push_back(model->frame_time(double(k) * (model->frames - 1) / std::max(1, frames - 1)));
      ModelState warm;
      model->evaluate(times[0], all, warm);  // first touch of the weights and pages
      double diff = 0;
      auto t0 = std::chrono::steady_clock::now();
      std::vector<ModelState> fast(times.size());
      for (size_t k = 0; k < times.size(); ++k) model->evaluate(times[k], all, fast[k]);
      const double s_fast = seconds_of(t0);
      t0 = std::chrono::steady_clock::now();
      for (size_t k = 0; k < times.size(); ++k) {
        const ModelState ref = model->at(times[k]);
        for (size_t i = 0; i < N; ++i) diff = std::max(diff, double((ref.means[i] - fast[k].means[i]).norm()));
      }
      const double s_ref = seconds_of(t0);
      const double gf = double(N) * double(times.size());
      const double macs = model->multiply_adds();
      std::printf("| %s | %zu | %.0f | %.3g | %.3g | %.2f | %.3g | %.0f %% | %.2g |\n", name, N, macs, gf / s_ref, gf / s_fast, s_ref / s_fast,
                  macs * gf / s_fast, 100.0 * macs * gf / s_fast / bound, diff);
      ++rows_printed;
    }
  });
  if (!rows_printed) throw_error(models, ": holds none of e-d3dgs, 4dgaussians, deformable3dgs");
  std::printf("\n(reference: Eigen products on row-major blocks of 1024 Gaussians, each layer's full inputs, the time columns included; "
              "its time includes comparing positions, under 1 %% of it. largest difference: of a position, world units)\n");
  return 0;
}
