// Selection benchmark: time per phase of viewpoint-time selection and the trade of every
// knob that buys speed with accuracy, each against a reference measured in the same run.
//  (a) the synthetic chair/shelf scene (its ground truth as the model, 8-bit renders as
//      images): phases for 20 trajectories, every strategy (time, mean D̂ of the chosen
//      views, share of chosen views that see the chair move);
//  (b) the candidate-map renderer: ray-traced at strides 2/4/8 (1 too in --smoke) vs the rasterizer
//      (reference): ms per candidate, Spearman rank correlation of candidate scores,
//      same first pose chosen;
//  (c) time subsampling and (d) render scale of the priority: time vs the share of the
//      full-resolution every-frame top-20 priority captured;
//  (e) voxel resolution and (f) global candidate count: time vs mean D̂ of the chosen views;
//  (g) a large scene (guitar.ply replicated, 10 % moving): phases for 20 trajectories.
#include <iostream>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <numeric>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/method/strategies.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/visibility/visibility.hpp"

using namespace fillgs;
using namespace fillgs::bench;

namespace {


struct Setup {
  const GaussianCloud* scene = nullptr;
  std::vector<ObservedView> views;
  std::vector<std::vector<float>> images;
  int frames = 1;
  ExplorationGrid grid;
  SelectInput input() const {
    SelectInput in;
    in.scene = scene;
    in.views = views;
    in.frames = frames;
    if (!images.empty()) in.image = [this](size_t i) { return images[i]; };
    in.grid = &grid;
    return in;
  }
};

void build(Setup& s, const GaussianCloud& scene, const std::vector<Camera>& rig, int frames, bool images, int divisions = 64) {
  s.scene = &scene;
  s.frames = frames;
  s.views = observed_views(rig, frames);
  s.images.clear();
  if (images) {
    FrameSampler ev(scene);
    for (const ObservedView& v : s.views) {
      std::vector<float> rgb = render(ev.at(v.camera.time), v.camera).rgb;
      for (float& x : rgb) x = std::round(std::clamp(x, 0.0f, 1.0f) * 255.0f) / 255.0f;
      s.images.push_back(std::move(rgb));
    }
  }
  std::vector<Camera> cams;
  for (const ObservedView& v : s.views) cams.push_back(v.camera);
  ExplorationOptions eo;
  eo.divisions = divisions;
  s.grid = build_exploration_grid(scene, cams, {}, eo);
}

/// Mean D̂ (initial tables) over the chosen poses, rendered by the rasterizer at full resolution.
double mean_deficiency(const Setup& s, const SelectResult& r) {
  DeficiencyField field(r.initial_tables, 0.99f);
  FrameSampler ev(*s.scene);
  double sum = 0;
  size_t n = 0;
  for (const Trajectory& t : r.trajectories)
    for (const Camera& c : t.poses) {
      const std::vector<float> d = field.values(t.frame, CandidateScore::Deficiency);
      sum += mean_value(render_value_map(ev.at(c.time), c, d.data()));
      ++n;
    }
  return n ? sum / double(n) : 0.0;
}

/// Share of the reference's top-k priority (by the reference's own E) that a run's top-k captures.
double captured(const PriorityScores& ref, const PriorityScores& run, size_t k) {
  std::vector<double> e_ref(ref.views.size());
  std::vector<double> by_view(*std::max_element(ref.views.begin(), ref.views.end()) + 1, 0.0);
  for (size_t i = 0; i < ref.views.size(); ++i) by_view[ref.views[i]] = ref.priority[i];
  auto top = [&](const PriorityScores& p) {
    std::vector<size_t> o(p.views.size());
    std::iota(o.begin(), o.end(), 0);
    std::stable_sort(o.begin(), o.end(), [&](size_t a, size_t b) { return p.priority[a] > p.priority[b]; });
    double s = 0;
    for (size_t i = 0; i < std::min(k, o.size()); ++i) s += by_view[p.views[o[i]]];
    return s;
  };
  return top(run) / top(ref);
}

void print_phases(const char* label, const SelectResult& r, double grid_s) {
  const SelectTimings& t = r.timings;
  std::printf("| %s | %zu | %.2f | %.2f | %.2f | %.2f | %.2f | %.3f | %.2f |\n", label, r.trajectories.size(), grid_s, t.observe, t.priority,
              t.scoring, t.update, t.candidates, t.total);
}

const char* kPhaseHeader =
    "| scene | trajectories | setup s (images + grid) | observe (C, s, D) s | priority (L, V) s | candidate scoring s | C/D update s | candidate "
    "generation s | total s |\n|---|---|---|---|---|---|---|---|---|\n";

}  // namespace

int bench_select(const std::vector<std::string>& args) {
  const ThreadLimit two_threads(2);  // the tables say "2 threads"
  bool smoke = false;
  std::string only;
  auto app = cli::make_parser("fillgs_bench select", "selection: the strategies, the map renderer, the priority, the grid, a large scene");
  cli::add_flag(*app, "--smoke", smoke, "a small scene, 2 trajectories");
  cli::add_text(*app, "--only", only, "parts: strategies, renderer, priority, grid, large (comma-separated)", "A,B,..");
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  const int K = smoke ? 2 : 20;
  auto want = [&](const std::string& name) { return only.empty() || ("," + only + ",").find("," + name + ",") != std::string::npos; };

  SynthOptions so;
  if (smoke) so.frames = 6, so.width = 64, so.height = 48, so.spacing = 0.05;
  const SynthScene synth = make_synthetic_scene(so);
  auto t0 = Clock::now();
  Setup s;
  build(s, synth.scene, synth.train, so.frames, true);
  const double grid_s = seconds_since(t0);
  std::printf("## Selection on the synthetic scene (%zu Gaussians, %zu moving, %zu cameras x %d frames, %dx%d), 2 threads\n\n",
              synth.scene.size(), synth.scene.dynamic_count(), synth.train.size(), so.frames, so.width, so.height);
  std::fflush(stdout);

  SelectOptions base;
  base.trajectories = K;
  // (a) phases and strategies; the priority of the default run is reused below.
  const SelectResult ref_run = select_viewpoints(s.input(), base);
  const PriorityScores prio = ref_run.priority;
  std::printf("%s", kPhaseHeader);
  print_phases("synthetic", ref_run, grid_s);
  std::fflush(stdout);

  auto chair_moving_share = [&](const SelectResult& r) {
    VisibilityOptions vo;
    vo.mode = VisibilityMode::Exact;
    VisibilityEngine e(synth.scene, vo);
    size_t seeing = 0, total = 0;
    for (const Trajectory& t : r.trajectories)
      for (const Camera& c : t.poses) {
        ++total;
        if (!(c.time > so.move_start && c.time < so.move_end)) continue;
        e.set_time(c.time);
        const std::vector<uint32_t> vis = e.visible_set(c);
        size_t n = 0;
        for (uint32_t g : synth.moving_ids) n += std::binary_search(vis.begin(), vis.end(), g);
        seeing += n > 0;
      }
    return total ? double(seeing) / double(total) : 0.0;
  };
  if (want("strategies")) {
    std::printf("\n### Strategies (%d trajectories, seed 1; mean D̂ rendered at full resolution from the initial tables)\n\n", K);
    std::printf("| strategy | select s | mean D̂ of chosen views | chosen views seeing the chair move | global wins |\n|---|---|---|---|---|\n");
    for (const StrategyRow* row : strategy_table().rows()) {
      const std::string& st = row->name;
      SelectOptions o = base;
      o.strategy = st;
      SelectInput in = s.input();
      in.priority = &prio;
      const SelectResult r = row->method ? ref_run : select_viewpoints(in, o);
      size_t global = 0;
      for (const Trajectory& t : r.trajectories) global += t.global;
      std::printf("| %s | %.2f | %.4f | %.0f %% | %zu |\n", st.c_str(), r.timings.total - r.timings.priority, mean_deficiency(s, r),
                  100.0 * chair_moving_share(r), global);
      std::fflush(stdout);
    }
  }

  if (want("renderer")) {
    // (b) candidate pool: the 12 local + 12 global candidates of the 3 highest-priority starts.
    std::vector<size_t> order(prio.views.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return prio.priority[a] > prio.priority[b]; });
    std::mt19937_64 rng(5);
    std::vector<std::pair<Camera, int>> pool;
    for (size_t i = 0; i < std::min<size_t>(3, order.size()); ++i) {
      const ObservedView& v = s.views[prio.views[order[i]]];
      std::vector<Camera> train;
      for (const ObservedView& w : s.views)
        if (w.frame == v.frame) train.push_back(w.camera);
      for (const Camera& c : local_candidates(v.camera, train, s.grid.step(), 10.0))
        if (s.grid.is_free(c.centre())) pool.emplace_back(c, v.frame);
      for (const Camera& c : global_candidates(v.camera, train, s.grid, 12, 3 * s.grid.step(), rng)) pool.emplace_back(c, v.frame);
    }
    DeficiencyField field(ref_run.initial_tables, 0.99f);
    FrameSampler ev(synth.scene);
    VisibilityEngine engine(synth.scene, VisibilityOptions{});
    auto scores_with = [&](MapRenderer r, int stride, double* ms) {
      std::vector<double> out;
      const auto t = Clock::now();
      for (const auto& [cam, f] : pool) {
        const std::vector<float> d = field.values(f, CandidateScore::Deficiency);
        if (r == MapRenderer::Raytraced) {
          engine.set_time(cam.time);
          out.push_back(engine.render_maps(cam, d.data(), nullptr, stride).score());
        } else {
          out.push_back(mean_value(render_value_map(ev.at(cam.time), cam, d.data())));
        }
      }
      *ms = 1000.0 * seconds_since(t) / double(pool.size());
      return out;
    };
    const int Kr = smoke ? 2 : 5;
    auto first_poses = [&](MapRenderer r, int stride) {
      SelectOptions o = base;
      o.trajectories = Kr;
      o.renderer = r;
      o.stride = stride;
      SelectInput in = s.input();
      in.priority = &prio;
      return select_viewpoints(in, o);
    };
    double ref_ms = 0;
    const std::vector<double> ref_scores = scores_with(MapRenderer::Raster, 1, &ref_ms);
    const SelectResult ref_sel = first_poses(MapRenderer::Raster, 1);
    std::printf("\n### Candidate-map renderer (%zu candidates around the 3 highest-priority starts; selection of %d trajectories)\n\n",
                pool.size(), Kr);
    std::printf("| renderer | ms per candidate | vs rasterizer | Spearman vs rasterizer | same poses chosen | mean D̂ of chosen views |\n"
                "|---|---|---|---|---|---|\n");
    std::printf("| rasterizer (reference) | %.2f | 1.00x | 1.000 | %zu/%zu | %.4f |\n", ref_ms, ref_sel.trajectories.size(),
                ref_sel.trajectories.size(), mean_deficiency(s, ref_sel));
    for (int stride : smoke ? std::vector<int>{1, 2, 4, 8} : std::vector<int>{2, 4, 8}) {  // stride 1: ~3 s per candidate here
      double ms = 0;
      const std::vector<double> sc = scores_with(MapRenderer::Raytraced, stride, &ms);
      const SelectResult sel = first_poses(MapRenderer::Raytraced, stride);
      size_t same = 0;
      for (size_t k = 0; k < std::min(sel.trajectories.size(), ref_sel.trajectories.size()); ++k) {
        const Trajectory &a = sel.trajectories[k], &b = ref_sel.trajectories[k];
        bool eq = a.frame == b.frame && a.poses.size() == b.poses.size();
        for (size_t j = 0; eq && j < a.poses.size(); ++j) eq = (a.poses[j].centre() - b.poses[j].centre()).norm() < 1e-9 && a.poses[j].R == b.poses[j].R;
        same += eq;
      }
      std::printf("| ray-traced, stride %d | %.2f | %.2fx | %.3f | %zu/%zu | %.4f |\n", stride, ms, ms / ref_ms, spearman(sc, ref_scores), same,
                  ref_sel.trajectories.size(), mean_deficiency(s, sel));
      std::fflush(stdout);
    }
  }

  if (want("priority")) {
    // (c) time subsampling, (d) render scale of V.
    std::printf("\n### Priority knobs (reference: every frame, render scale 1; share of its top-20 E captured by each run's top-20)\n\n");
    std::printf("| time stride | render scale | views evaluated | priority s | vs reference | top-20 E captured |\n|---|---|---|---|---|---|\n");
    SelectOptions o = base;
    o.render_scale = 1.0;
    const PriorityScores full = exploration_priority(s.input(), o);
    std::printf("| 1 | 1 (reference) | %zu | %.2f | 1.00x | 1.000 |\n", full.views.size(), full.seconds);
    {  // the same priority with the scalar tile kernel: the vector kernel's ratio
      set_default_kernel(Kernel::Scalar);
      const PriorityScores scalar = exploration_priority(s.input(), o);
      set_default_kernel(Kernel::Simd);
      std::printf("| 1 | 1, scalar kernel | %zu | %.2f | %.2fx (vector kernel %.2fx faster; %.3f s per view scalar, %.3f simd) | %.3f |\n",
                  scalar.views.size(), scalar.seconds, scalar.seconds / full.seconds, scalar.seconds / full.seconds,
                  scalar.seconds / double(scalar.views.size()), full.seconds / double(full.views.size()), captured(full, scalar, 20));
    }
    for (const auto& [stride, scale] : std::vector<std::pair<int, double>>{{1, 0.5}, {1, 0.25}, {2, 0.5}, {3, 0.5}, {5, 0.5}}) {
      o.time_stride = stride;
      o.render_scale = scale;
      const PriorityScores p = exploration_priority(s.input(), o);
      std::printf("| %d | %g | %zu | %.2f | %.2fx | %.3f |\n", stride, scale, p.views.size(), p.seconds, p.seconds / full.seconds,
                  captured(full, p, 20));
      std::fflush(stdout);
    }
  }

  if (want("grid")) {
    // (e) voxel resolution, (f) global candidates.
    std::printf("\n### Voxel resolution and global candidates (%d trajectories; priority reused)\n\n", K);
    std::printf("| divisions | global candidates | grid s | free voxels | step m | select s | mean D̂ of chosen views | global wins |\n"
                "|---|---|---|---|---|---|---|---|\n");
    for (const auto& [div, globals] : std::vector<std::pair<int, int>>{{32, 12}, {64, 12}, {128, 12}, {64, 0}, {64, 6}, {64, 24}}) {
      Setup g;
      const auto tg = Clock::now();
      g.scene = s.scene;
      g.frames = s.frames;
      g.views = s.views;
      std::vector<Camera> cams;
      for (const ObservedView& v : s.views) cams.push_back(v.camera);
      ExplorationOptions eo;
      eo.divisions = div;
      g.grid = build_exploration_grid(*s.scene, cams, {}, eo);
      const double gs = seconds_since(tg);
      SelectOptions o = base;
      o.global_candidates = globals;
      o.no_global = globals == 0;
      SelectInput in = s.input();
      in.grid = &g.grid;
      in.priority = &prio;
      const SelectResult r = select_viewpoints(in, o);
      size_t global = 0;
      for (const Trajectory& t : r.trajectories) global += t.global;
      std::printf("| %d | %d | %.2f | %zu | %.3f | %.2f | %.4f | %zu |\n", div, globals, gs, g.grid.counts()[0], g.grid.step(),
                  r.timings.total - r.timings.priority, mean_deficiency(s, r), global);
      std::fflush(stdout);
    }
  }

  if (want("large")) {
    // (g) a large scene: guitar.ply replicated, 10 % moving.
    const GaussianCloud base_cloud = read_scene(shared_data_dir() + "/scenes/guitar.ply");
    const int copies = smoke ? 1 : 3, frames = smoke ? 3 : 10, ncam = smoke ? 3 : 8;
    const GaussianCloud big = replicate(base_cloud, copies, 0.10, 7);
    const std::vector<Camera> rig = orbit(big, ncam, smoke ? 169 : 676, smoke ? 127 : 507);
    Setup L;
    const auto tl = Clock::now();
    build(L, big, rig, frames, false);
    const double lg = seconds_since(tl);
    std::printf("\n### Large scene: guitar.ply x %d = %zu Gaussians (%zu moving), %d orbit cameras x %d frames at %dx%d, no images (L = 0)\n\n",
                copies, big.size(), big.dynamic_count(), ncam, frames, rig[0].width, rig[0].height);
    std::printf("%s", kPhaseHeader);
    SelectOptions o = base;
    const SelectResult r = select_viewpoints(L.input(), o);
    print_phases("guitar replicated", r, lg);
  }
  return 0;
}
