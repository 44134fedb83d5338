// Visibility: the speed/accuracy trade of mode × stride × static/dynamic threshold,
// measured against the `exact` mode in the same run.
//  (a) the synthetic scene (30 frames, 16 cameras, 320×240);
//  (b) guitar.ply (static, 90k Gaussians), orbit cameras at 1352×1014;
//  (c) guitar replicated and animated to about 1M Gaussians, 10% moving at speeds spread
//      over five decades, 20 orbit cameras at 1352×1014: BVH build and refit, full tables
//      in frustum mode, raytraced stride 4 per frame (incremental against from scratch),
//      and the static/dynamic threshold.
// Prints tables (markdown) and writes a Pareto plot (time against recall) into --out.
#include <iostream>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/instruction_set.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/visibility/gaussian_tracer.hpp"
#include "fillgs/visibility/observe_io.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/visibility/visibility.hpp"

using namespace fillgs;
using namespace fillgs::bench;

namespace {


struct Setting {
  std::string name;
  VisibilityOptions vis;
};

std::vector<Setting> settings(bool smoke) {
  std::vector<Setting> s;
  VisibilityOptions v;
  v.mode = VisibilityMode::Frustum;
  s.push_back({"frustum", v});
  for (int stride : smoke ? std::vector<int>{4} : std::vector<int>{1, 2, 4, 8}) {
    v.mode = VisibilityMode::Raytraced;
    v.stride = stride;
    v.dilate = true;
    s.push_back({"raytraced s" + std::to_string(stride), v});
  }
  v.stride = 4;
  v.dilate = false;
  s.push_back({"raytraced s4 plain 3D", v});
  return s;
}

struct SetAccuracy {
  double recall = 1, precision = 1, worst_recall = 1, worst_precision = 1;
};

/// Visible sets of `vis` against exact over (camera, time) pairs.
SetAccuracy set_accuracy(const GaussianCloud& cloud, const std::vector<Camera>& cams, const std::vector<double>& times,
                         const VisibilityOptions& vis, std::map<std::pair<size_t, size_t>, std::vector<uint32_t>>& exact_cache) {
  VisibilityEngine engine(cloud, vis);
  VisibilityOptions ex_opt = vis;
  ex_opt.mode = VisibilityMode::Exact;
  VisibilityEngine exact(cloud, ex_opt);
  double both = 0, got = 0, want = 0;
  SetAccuracy a;
  for (size_t f = 0; f < times.size(); ++f) {
    engine.set_time(times[f]);
    exact.set_time(times[f]);
    for (size_t c = 0; c < cams.size(); ++c) {
      auto key = std::make_pair(f, c);
      if (!exact_cache.count(key)) exact_cache[key] = exact.visible_set(cams[c]);
      const auto& e = exact_cache[key];
      const auto r = engine.visible_set(cams[c]);
      std::vector<uint32_t> common;
      std::set_intersection(r.begin(), r.end(), e.begin(), e.end(), std::back_inserter(common));
      both += double(common.size());
      got += double(r.size());
      want += double(e.size());
      if (!e.empty()) a.worst_recall = std::min(a.worst_recall, double(common.size()) / double(e.size()));
      if (!r.empty()) a.worst_precision = std::min(a.worst_precision, double(common.size()) / double(r.size()));
    }
  }
  a.recall = want > 0 ? both / want : 1.0;
  a.precision = got > 0 ? both / got : 1.0;
  return a;
}

/// Candidate scores (mean normalised-D map) of a fixed candidate set, for a table.
std::vector<double> candidate_scores(const GaussianCloud& cloud, const ObservationTables& t, const std::vector<Camera>& candidates,
                                     int frame, int stride) {
  VisibilityOptions v;
  v.mode = VisibilityMode::Raytraced;
  VisibilityEngine engine(cloud, v);
  engine.set_time(t.times[size_t(frame)]);
  std::vector<float> d = t.deficiency_row(frame);
  const float scale = t.deficiency_scale();
  for (float& x : d) x = std::min(1.0f, x / scale);
  std::vector<double> s;
  for (const Camera& c : candidates) s.push_back(engine.render_maps(c, d.data(), nullptr, stride).score());
  return s;
}

double mean_abs_count_difference(const ObservationTables& a, const ObservationTables& b) {
  double s = 0;
  for (size_t k = 0; k < a.counts.size(); ++k) s += std::abs(int(a.counts[k]) - int(b.counts[k]));
  return a.counts.empty() ? 0.0 : s / double(a.counts.size());
}

/// Adds the exact reference (recall 1 by definition) and hands the series to the plot.
void finish_series(ScatterSeries& series, double exact_seconds, std::vector<ScatterSeries>& pareto) {
  series.x.push_back(exact_seconds);
  series.y.push_back(1.0);
  series.point_labels.push_back("exact");
  series.joined = false;  // settings, not a sequence
  pareto.push_back(series);
}

void add_point(ScatterSeries& series, const std::string& name, double seconds, double recall) {
  series.x.push_back(seconds);
  series.y.push_back(recall);
  series.point_labels.push_back(name);
}

// ------------------------------------------------------------------ (a) synthetic

void synthetic_sweep(bool smoke, std::vector<ScatterSeries>& pareto) {
  SynthOptions so;
  if (smoke) {
    so.frames = 5;
    so.width = 96;
    so.height = 72;
    so.spacing = 0.04;
  }
  const SynthScene s = make_synthetic_scene(so);
  const auto times = FrameGrid(so.frames).times();
  const double dt = FrameGrid(so.frames).step();
  std::vector<Camera> candidates = s.interpolation;
  candidates.insert(candidates.end(), s.extrapolation.begin(), s.extrapolation.end());
  const int candidate_frame = so.frames / 2;
  std::vector<double> acc_times;
  for (int f : {0, so.frames / 3, so.frames / 2, 2 * so.frames / 3, so.frames - 1}) acc_times.push_back(times[size_t(f)]);
  acc_times.erase(std::unique(acc_times.begin(), acc_times.end()), acc_times.end());

  std::printf("\n(a) synthetic scene: %zu Gaussians (%zu moving), %zu cameras x %d frames at %dx%d; candidates: %zu views at frame %d\n",
              s.scene.size(), s.scene.dynamic_count(), s.train.size(), so.frames, so.width, so.height, candidates.size(), candidate_frame);
  ObservationOptions ref_opt;
  ref_opt.visibility.mode = VisibilityMode::Exact;
  auto t0 = Clock::now();
  const ObservationTables ref = observation_tables(s.scene, s.train, times, dt, ref_opt);
  const double ref_seconds = seconds_since(t0);
  const auto ref_scores = candidate_scores(s.scene, ref, candidates, candidate_frame, 4);
  std::printf("| setting | table time (s) | vs exact | rays/s | recall | precision | worst-view recall | worst-view precision | mean abs dC | candidate rank corr. |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| exact (reference) | %.2f | 1.00 | - | 1 | 1 | 1 | 1 | 0 | 1 |\n", ref_seconds);
  std::map<std::pair<size_t, size_t>, std::vector<uint32_t>> exact_cache;
  ScatterSeries series{"synthetic 320x240", {}, {}, {}};
  for (const Setting& st : settings(smoke)) {
    ObservationOptions o;
    o.visibility = st.vis;
    ObservationSummary sum;
    t0 = Clock::now();
    const ObservationTables t = observation_tables(s.scene, s.train, times, dt, o, &sum);
    const double seconds = seconds_since(t0);
    const SetAccuracy a = set_accuracy(s.scene, s.train, acc_times, st.vis, exact_cache);
    const double rho = spearman(ref_scores, candidate_scores(s.scene, t, candidates, candidate_frame, 4));
    const double rays_per_s = sum.counters.rays ? double(sum.counters.rays) / sum.seconds_frames : 0.0;
    std::printf("| %s | %.2f | %.3f | %s | %.4f | %.4f | %.4f | %.4f | %.4f | %.3f |\n", st.name.c_str(), seconds, seconds / ref_seconds,
                rays_per_s ? (std::to_string(int(rays_per_s / 1000)) + "k").c_str() : "-", a.recall, a.precision, a.worst_recall,
                a.worst_precision, mean_abs_count_difference(t, ref), rho);
    std::fflush(stdout);
    add_point(series, st.name, seconds, a.recall);
  }
  finish_series(series, ref_seconds, pareto);
}

// ------------------------------------------------------------------ (b) guitar

void guitar_sweep(bool smoke, std::vector<ScatterSeries>& pareto) {
  const std::string path = shared_data_dir() + "/scenes/guitar.ply";
  if (!std::filesystem::exists(path)) throw_error(path, ": missing (set FILLGS_SHARED_DATA to the shared data folder)");
  const GaussianCloud cloud = read_scene(path);
  const int w = smoke ? 338 : 1352, h = smoke ? 254 : 1014, n = smoke ? 2 : 8;
  const auto cams = orbit(cloud, n, w, h);
  std::printf("\n(b) guitar.ply: %zu Gaussians (static), %d orbit cameras at %dx%d, one frame\n", cloud.size(), n, w, h);
  std::printf("| setting | time (s) | vs exact | rays/s | recall | precision | worst-view recall | worst-view precision |\n|---|---|---|---|---|---|---|---|\n");
  std::map<std::pair<size_t, size_t>, std::vector<uint32_t>> exact_cache;
  VisibilityOptions ex;
  ex.mode = VisibilityMode::Exact;
  auto t0 = Clock::now();
  {
    VisibilityEngine e(cloud, ex);
    for (size_t c = 0; c < cams.size(); ++c) exact_cache[{0, c}] = e.visible_set(cams[c]);
  }
  const double ref_seconds = seconds_since(t0);
  std::printf("| exact (reference) | %.2f | 1.00 | - | 1 | 1 | 1 | 1 |\n", ref_seconds);
  ScatterSeries series{"guitar 1352x1014", {}, {}, {}};
  for (const Setting& st : settings(smoke)) {
    if (st.vis.mode == VisibilityMode::Raytraced && st.vis.stride == 1 && !smoke) continue;  // 1.4M rays per view: see README
    VisibilityEngine e(cloud, st.vis);
    t0 = Clock::now();
    for (const Camera& c : cams) e.visible_set(c);
    const double seconds = seconds_since(t0);  // includes the proxy build (first view)
    const SetAccuracy a = set_accuracy(cloud, cams, {0.0}, st.vis, exact_cache);
    const double rps = e.counters().rays ? double(e.counters().rays) / (seconds - e.build_seconds()) : 0.0;
    std::printf("| %s | %.2f | %.3f | %s | %.4f | %.4f | %.4f | %.4f |\n", st.name.c_str(), seconds, seconds / ref_seconds,
                rps ? (std::to_string(int(rps / 1000)) + "k").c_str() : "-", a.recall, a.precision, a.worst_recall, a.worst_precision);
    std::fflush(stdout);
    add_point(series, st.name, seconds, a.recall);
  }
  finish_series(series, ref_seconds, pareto);
}

// ------------------------------------------------------------------ (c) ~1M Gaussians

void million_scene(bool smoke) {
  const std::string path = shared_data_dir() + "/scenes/guitar.ply";
  const GaussianCloud base = read_scene(path);
  const int copies = smoke ? 2 : 11, cameras = smoke ? 4 : 20, frames = smoke ? 4 : 300, traced_frames = smoke ? 2 : 8;
  const int w = smoke ? 338 : 1352, h = smoke ? 254 : 1014;
  const GaussianCloud cloud = replicate(base, copies, 0.10, 7);
  const auto cams = orbit(cloud, cameras, w, h);
  const double extent = (bounding_box(base).second - bounding_box(base).first).norm();
  std::printf("\n(c) guitar x %d = %zu Gaussians, %zu moving (speeds 1e-5..1 x %.2f per unit time), %d cameras at %dx%d\n", copies,
              cloud.size(), cloud.dynamic_count(), extent, cameras, w, h);

  {  // BVH build and refit
    FrameSampler ev(cloud);
    const FrameGaussians& f0 = ev.at(0.0);
    GaussianTracer tracer(f0, cloud.dynamic_ids);
    double refit = 0;
    for (int k = 1; k <= 5; ++k) {
      tracer.refit_dynamic(ev.at(k / 5.0));
      refit += tracer.last_refit_seconds();
    }
    std::printf("BVH: build %.3f s (all %zu proxies, static + dynamic), refit %.1f ms per frame (%zu dynamic, mean of 5); proxy memory %.0f MB; "
                "%zu proxies larger than %.3g (half-diagonal) in the large tier\n",
                tracer.build_seconds(), cloud.size(), 1000 * refit / 5, cloud.dynamic_count(), tracer.memory_bytes() / 1048576.0,
                tracer.large_proxy_count(), double(tracer.large_proxy_threshold()));
  }
  const auto times = FrameGrid(frames).times();
  const double dt = FrameGrid(frames).step();
  // One folder per process: two benchmarks at once must not write into each other's tables.
  const std::string tmp =
      (std::filesystem::temp_directory_path() / ("fillgs_bench_visibility." + std::to_string(::getpid()))).string();
  {  // frustum: the full table, streamed to disk
    ObservationOptions o;
    o.visibility.mode = VisibilityMode::Frustum;
    ObserveOutputOptions oo;
    oo.plots = false;
    const auto t0 = Clock::now();
    const ObserveReport r = observe_to_directory(cloud, cams, times, dt, o, tmp, oo);
    std::printf("frustum, full table %zu x %d cameras x %d frames: %.1f s (static answers %.1f s, frames %.1f s, speeds %.1f s, write %.1f s); peak memory %.0f MB\n",
                cloud.size(), cameras, frames, seconds_since(t0), r.summary.seconds_static, r.summary.seconds_frames, r.summary.seconds_speed,
                r.summary.seconds_sink, r.peak_memory_bytes / 1048576.0);
  }
  double scratch_frame = 0;  // seconds of one raytraced s4 frame traced from scratch
  {  // raytraced stride 4: incremental against from scratch, on the first frames
    const std::vector<double> few(times.begin(), times.begin() + traced_frames);
    ObservationOptions inc, full;
    inc.visibility.mode = full.visibility.mode = VisibilityMode::Raytraced;
    inc.visibility.stride = full.visibility.stride = 4;
    full.incremental = false;
    // The ratio's two sides alternate, kRepeats times each, and the median ratio is taken:
    // this machine's speed drifts by up to 2x within minutes, more than the ratio moves.
    constexpr int kRepeats = 3;
    const int repeats = smoke ? 1 : kRepeats;
    const std::vector<double> fewer(times.begin(), times.begin() + 2);
    ObservationSummary si, sf;
    ObservationTables a, b;
    double inc_s = 0, full_s = 0;
    std::vector<double> inc_frames, full_frames, ratios;
    for (int rep = 0; rep < repeats; ++rep) {
      auto t0 = Clock::now();
      a = observation_tables(cloud, cams, few, dt, inc, &si);
      inc_s = seconds_since(t0);
      t0 = Clock::now();
      b = observation_tables(cloud, cams, fewer, dt, full, &sf);
      full_s = seconds_since(t0);
      inc_frames.push_back((si.seconds_frames - si.seconds_static) / traced_frames + si.seconds_refit / traced_frames);
      full_frames.push_back(sf.seconds_frames / 2.0 + sf.seconds_refit / 2.0);
      ratios.push_back(inc_frames.back() / full_frames.back());
    }
    const auto median = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    const auto list = [](const std::vector<double>& v) {
      std::string out;
      char number[32];
      for (double x : v) {
        std::snprintf(number, sizeof number, "%.3f", x);
        out += (out.empty() ? "" : ", ") + std::string(number);
      }
      return out;
    };
    bool same = std::equal(b.counts.begin(), b.counts.end(), a.counts.begin());
    const double per_frame_inc = median(inc_frames);
    const double per_frame_full = median(full_frames);
    scratch_frame = per_frame_full;
    // Earlier incremental paths in the same run: seconds per frame, counts checked.
    auto per_frame_of = [&](const ObservationOptions& o, ObservationSummary& su) {
      const ObservationTables t = observation_tables(cloud, cams, few, dt, o, &su);
      same = same && t.counts == a.counts;
      return (su.seconds_frames - su.seconds_static) / traced_frames + su.seconds_refit / traced_frames;
    };
    ObservationOptions every = inc;  // probing every ray (before footprints)
    every.footprints = false;
    ObservationSummary se;
    const double per_frame_every = per_frame_of(every, se);
    std::printf("raytraced s4, %d frames incremental probing every ray (the path before footprints): static answers %.1f s, then %.2f s per "
                "frame; footprints / every ray = %.3f per frame\n",
                traced_frames, se.seconds_static, per_frame_every, per_frame_inc / per_frame_every);
    ObservationOptions both_layers = inc;  // every re-traced ray through both layers (before kept static hits)
    both_layers.static_hit_cache_bytes = 0;
    ObservationSummary sb;
    const double per_frame_both = per_frame_of(both_layers, sb);
    std::printf("raytraced s4, %d frames incremental re-tracing both layers (the path before kept static hits): static answers %.1f s, "
                "then %.2f s per frame; kept static hits / both layers = %.3f per frame; kept: %llu rays (%llu of them at the static "
                "answers), %llu hits (%.0f MB)\n",
                traced_frames, sb.seconds_static, per_frame_both, per_frame_inc / per_frame_both, (unsigned long long)si.cached_static_rays,
                (unsigned long long)si.cached_at_static_answers, (unsigned long long)si.cached_static_hits,
                double(si.cached_static_hits) * sizeof(KeyedHit) / 1048576.0);
    ObservationOptions lazy = inc;  // kept hits only when first reached (before keeping at the static answers)
    lazy.keep_at_static_answers = false;
    ObservationSummary sl;
    const double per_frame_lazy = per_frame_of(lazy, sl);
    std::printf("raytraced s4, %d frames incremental keeping static hits only when a ray is first reached (the path before keeping them "
                "at the static answers): static answers %.1f s, then %.2f s per frame; keeping at the static answers / first reached = "
                "%.3f per frame, %.3f for static answers + %d frames\n",
                traced_frames, sl.seconds_static, per_frame_lazy, per_frame_inc / per_frame_lazy,
                (si.seconds_static + traced_frames * per_frame_inc) / (sl.seconds_static + traced_frames * per_frame_lazy), traced_frames);
    ObservationOptions first = inc;  // kept at the static answers: the first frame's footprints only (before sweeping)
    first.sweep_static_answers = false;
    ObservationSummary s1;
    const double per_frame_first = per_frame_of(first, s1);
    std::printf("raytraced s4, %d frames incremental keeping at the static answers the rays of the first frame's footprints only (the "
                "path before swept footprints): static answers %.1f s, then %.2f s per frame, kept %llu rays (%llu at the static "
                "answers, %.0f MB); swept / first frame's = %.3f per frame, %.3f for static answers + %d frames; swept: kept %llu rays "
                "(%llu at the static answers, %.0f MB)\n",
                traced_frames, s1.seconds_static, per_frame_first, (unsigned long long)s1.cached_static_rays,
                (unsigned long long)s1.cached_at_static_answers, double(s1.cached_static_hits) * sizeof(KeyedHit) / 1048576.0,
                per_frame_inc / per_frame_first,
                (si.seconds_static + traced_frames * per_frame_inc) / (s1.seconds_static + traced_frames * per_frame_first), traced_frames,
                (unsigned long long)si.cached_static_rays, (unsigned long long)si.cached_at_static_answers,
                double(si.cached_static_hits) * sizeof(KeyedHit) / 1048576.0);
    const double rays = double(std::max<uint64_t>(1, si.incremental_rays));
    std::printf("raytraced s4, %d frames incremental: %.1f s (build %.2f s, static answers %.1f s, then %.2f s per frame; of the views' rays "
                "%.1f%% in a dynamic footprint and probed, %.1f%% re-traced); from scratch: %.2f s per frame; incremental frame / scratch "
                "frame = %.3f (median of %d alternating runs of each side: per-run ratios %s; per frame the medians of %d runs); counts "
                "identical on the shared frames: %s\n",
                traced_frames, inc_s, si.seconds_build, si.seconds_static, per_frame_inc, 100.0 * double(si.footprint_rays) / rays,
                100.0 * double(si.retraced_rays) / rays, per_frame_full, median(ratios), repeats, list(ratios).c_str(), repeats,
                same ? "yes" : "NO");
    std::printf("raytraced s4, projected full table (%d frames): %.1f s = build + static answers + %d x per-frame (measured on %d frames); the 2-frame from-scratch run took %.1f s\n",
                frames, si.seconds_build + si.seconds_static + frames * per_frame_inc, frames, traced_frames, full_s);
    // Issue 17 asks whether choosing `exact` (the rasterizer's own rule) per (camera, frame)
    // by cost would win: its cost for one frame of every view, against the traced paths.
    ObservationOptions ex;
    ex.visibility.mode = VisibilityMode::Exact;
    ObservationSummary sx;
    const auto t0 = Clock::now();
    observation_tables(cloud, cams, {times[0]}, dt, ex, &sx);
    const double exact_frame = seconds_since(t0);
    std::printf("exact, one frame of %d views: %.2f s = %.2f x an incremental raytraced s4 frame, %.2f x a from-scratch one, %.2f x the "
                "raytraced static answers of %zu poses\n",
                cameras, exact_frame, exact_frame / per_frame_inc, exact_frame / per_frame_full, exact_frame / si.seconds_static,
                si.camera_poses);
    std::fflush(stdout);
  }
  // raytraced stride 4 end to end: the whole table streamed to disk, as `fillgs observe` writes
  // it; then the same without kept static hits (every re-traced ray through both layers). Over
  // the whole table the first-time cost of keeping a ray's static hits is amortised.
  for (bool keep : {true, false}) {
    ObservationOptions o;
    o.visibility.mode = VisibilityMode::Raytraced;
    o.visibility.stride = 4;
    if (!keep) o.static_hit_cache_bytes = 0;
    ObserveOutputOptions oo;
    oo.plots = false;
    const auto t0 = Clock::now();
    const ObserveReport r = observe_to_directory(cloud, cams, times, dt, o, tmp, oo);
    const ObservationSummary& su = r.summary;
    const double per_frame = (su.seconds_frames - su.seconds_static + su.seconds_refit) / frames;
    std::printf("raytraced s4, full table %zu x %d cameras x %d frames, end to end%s: %.1f s (build %.2f s, static answers %.1f s, frames %.1f s "
                "incl. refits %.1f s, speeds %.1f s, write %.1f s; %.1f%% of the incremental rays re-traced; static hits kept for %.1f%% of "
                "a frame's rays, %.0f MB); per frame %.3f s = %.3f of a from-scratch frame; process peak memory %.0f MB\n",
                cloud.size(), cameras, frames, keep ? "" : " re-tracing both layers (no kept static hits)", seconds_since(t0), su.seconds_build,
                su.seconds_static, su.seconds_frames + su.seconds_refit, su.seconds_refit, su.seconds_speed, su.seconds_sink,
                100.0 * double(su.retraced_rays) / double(std::max<uint64_t>(1, su.incremental_rays)),
                100.0 * double(su.cached_static_rays) * frames / double(std::max<uint64_t>(1, su.incremental_rays)),
                double(su.cached_static_hits) * sizeof(KeyedHit) / 1048576.0, per_frame, per_frame / scratch_frame,
                r.peak_memory_bytes / 1048576.0);
    std::fflush(stdout);
    if (smoke) break;
  }
  {  // static/dynamic threshold: Gaussians slower than it are frozen at their mean position
    const std::vector<double> few = {times[0], times[size_t(frames / 2)], times.back()};
    ObservationOptions ex;
    ex.visibility.mode = VisibilityMode::Exact;
    const std::vector<Camera> some(cams.begin(), cams.begin() + std::min<size_t>(4, cams.size()));
    const ObservationTables ref = observation_tables(cloud, some, few, dt, ex);
    std::printf("| static threshold (x scene size / unit time) | dynamic Gaussians | frustum table time (s) | raytraced s4 time (s) | mean abs dC vs exact (raytraced) | mean abs dD vs unfrozen |\n|---|---|---|---|---|---|\n");
    ObservationTables unfrozen;
    for (double th : {0.0, 1e-4, 1e-3, 1e-2}) {
      GaussianCloud c = cloud;
      PartitionOptions po;
      po.static_speed_threshold = float(th * extent);
      if (th > 0) partition_static_dynamic(c, po);
      ObservationOptions fr, rt;
      fr.visibility.mode = VisibilityMode::Frustum;
      rt.visibility.mode = VisibilityMode::Raytraced;
      rt.visibility.stride = 4;
      auto t0 = Clock::now();
      observation_tables(c, some, few, dt, fr);
      const double fs = seconds_since(t0);
      t0 = Clock::now();
      const ObservationTables t = observation_tables(c, some, few, dt, rt);
      const double rs = seconds_since(t0);
      if (th == 0.0) unfrozen = t;
      double dd = 0;
      for (int f = 0; f < int(few.size()); ++f) {
        const auto x = t.deficiency_row(f), y = unfrozen.deficiency_row(f);
        for (size_t g = 0; g < x.size(); ++g) dd += std::fabs(x[g] - y[g]);
      }
      dd /= double(few.size() * c.size());
      std::printf("| %g | %zu | %.2f | %.2f | %.4f | %.3g |\n", th, c.dynamic_count(), fs, rs, mean_abs_count_difference(t, ref), dd);
      std::fflush(stdout);
    }
  }
  std::filesystem::remove_all(tmp);
}

}  // namespace

/// The frustum rule alone: the vector kernel (frustum_visible, what observe runs) against the
/// scalar preprocess it replaced (project_gaussian per Gaussian on the threads, ids sorted
/// after), on guitar replicated to about a million Gaussians and 20 orbit cameras, the
/// same run; the kept sets must be identical.
void frustum_rule(bool smoke) {
  const GaussianCloud base = read_scene(shared_data_dir() + "/scenes/guitar.ply");
  const int copies = smoke ? 2 : 11, cameras = 20, repeats = smoke ? 1 : 5;
  const GaussianCloud cloud = replicate(base, copies, 0.10, 7);
  const auto cams = orbit(cloud, cameras, 1352, 1014);
  VisibilityEngine engine(cloud, VisibilityOptions{});
  const FrameGaussians& f = engine.frame();
  auto scalar = [&](const Camera& cam) {
    tbb::enumerable_thread_specific<std::vector<uint32_t>> found;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, f.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
      auto& out = found.local();
      ProjectedGaussian p;
      for (size_t g = r.begin(); g < r.end(); ++g)
        if (project_gaussian(f.means[g], f.scales[g], f.rotations[g], cam, &p)) out.push_back(uint32_t(g));
    });
    std::vector<uint32_t> all;
    for (auto& v : found) all.insert(all.end(), v.begin(), v.end());
    std::sort(all.begin(), all.end());
    return all;
  };
  double s_scalar = 1e30, s_vector = 1e30;
  size_t kept = 0;
  bool same = true;
  for (int k = 0; k < repeats; ++k) {  // alternating, the fastest of each
    auto t0 = Clock::now();
    std::vector<std::vector<uint32_t>> a, b;
    for (const Camera& c : cams) a.push_back(scalar(c));
    s_scalar = std::min(s_scalar, seconds_since(t0));
    t0 = Clock::now();
    for (const Camera& c : cams) b.push_back(engine.visible_set(c));
    s_vector = std::min(s_vector, seconds_since(t0));
    same = same && a == b;
    kept = 0;
    for (const auto& v : b) kept += v.size();
  }
  const double tests = double(cloud.size()) * cameras;
  std::printf("\n(d) the frustum rule alone, guitar x %d = %zu Gaussians x %d cameras at 1352x1014 (%zu kept), fastest of %d alternating runs, "
              "vector kernel %s: scalar preprocess %.3f s (%.1f ns per Gaussian-camera), vector %.3f s (%.1f ns); vector / scalar %.3f; "
              "kept sets %s\n",
              copies, cloud.size(), cameras, kept, repeats, kernel_instruction_set().c_str(), s_scalar, 1e9 * s_scalar / tests, s_vector,
              1e9 * s_vector / tests, s_vector / s_scalar, same ? "identical" : "DIFFERENT");
  if (!same) throw_error("the vector frustum rule kept other Gaussians than the scalar one");
}

int bench_visibility(const std::vector<std::string>& args) {
  bool smoke = false;
  std::string out = "bench/results";
  std::string only;
  auto app = cli::make_parser("fillgs_bench visibility", "observation tables: modes against exact, incremental against from scratch, at scale");
  cli::add_flag(*app, "--smoke", smoke, "small scenes, few frames");
  cli::add_text(*app, "--out", out, "the folder for the Pareto plot", "DIR");
  cli::add_text(*app, "--only", only, "one part: synthetic, guitar, million or rule", "NAME");
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  std::vector<ScatterSeries> pareto;
  if (only.empty() || only == "synthetic") synthetic_sweep(smoke, pareto);
  if (only.empty() || only == "guitar") guitar_sweep(smoke, pareto);
  if (only.empty() || only == "million") million_scene(smoke);
  if (only.empty() || only == "rule") frustum_rule(smoke);
  if (!pareto.empty()) {
    const std::string png = out + "/visibility_pareto.png";
    write_scatter_png(png, pareto, {"visibility: time against visible-set recall (vs exact)", "time (s, log scale)", "recall"}, true);
    std::printf("\nPareto plot: %s\n", png.c_str());
  }
  return 0;
}
