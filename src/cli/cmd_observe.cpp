// fillgs observe: the observation tables.
#include "fillgs/cli.hpp"
#include "fillgs/io/camera_io.hpp"
#include <nlohmann/json.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include "fillgs/base/error.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/train/init.hpp"
#include "fillgs/visibility/observe_io.hpp"
#include "fillgs/visibility/observe_mpi.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/experiment/synth.hpp"
#include "fillgs/train/train.hpp"
#include "fillgs/train/train_job.hpp"
#include "fillgs/visibility/visibility.hpp"
#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"

namespace fillgs::cli {

namespace {

// ------------------------------------------------------------------ observe

struct ObserveFlags {
  std::string scene, cameras, out, shard;
  std::vector<std::string> merge;
  TimeFlags time;
  ObservationOptions options;
  ObserveOutputOptions output;
  bool mpi = false;
  double hit_cache_mb = 0;
  SceneReadOptions read;
  CameraReadOptions camera_read;
};

/// What `fillgs observe` computes: the scene, the cameras, the times and how.
struct ObserveJob {
  ObservationOptions options;
  ObserveOutputOptions output;
  GaussianCloud cloud;
  std::vector<Camera> cameras;
  std::vector<double> times;
  double frame_step = 0;
};

ObserveJob observe_job(const ObserveFlags& f, const Invocation& in) {
  ObserveJob job;
  job.options = f.options;
  if (in.given("--hit-cache")) job.options.static_hit_cache_bytes = size_t(f.hit_cache_mb * 1048576.0);
  job.output = f.output;
  // The times asked for, where the flags say them before the model is read: a streamed
  // model's still rule then checks those times instead of sweeping frames the job never
  // evaluates (the full check of them follows, once the model is read).
  // Only as many as the sweep's frames matter (more: the sweep runs), so none are made for a
  // frame count that observe_times will refuse.
  SceneReadOptions read = f.read;
  const size_t sweep = size_t(std::max(0, read.still.sweep_frames));
  if (in.given("--times") && f.time.times.size() <= sweep) read.still.times = f.time.times;
  else if (!in.given("--times") && f.time.frames >= 2 && size_t(f.time.frames) <= sweep) read.still.times = FrameGrid(f.time.frames).times();
  std::sort(read.still.times.begin(), read.still.times.end());
  job.cloud = read_scene_shown(f.scene, read, in);
  job.cameras = read_cameras(f.cameras, f.camera_read);
  if (job.cameras.empty()) throw_error(f.cameras, ": no cameras");
  job.times = observe_times(in, f.time, job.cloud, job.cameras, &job.frame_step);
  {
    // The tables' size on disk, before any work, against the space free where they will be
    // written: counts (1 byte, 2 above 255 views) [T, N], or compact [T, M] with a static
    // row per camera set (at most T; the changes a moving Gaussian makes to static counts are
    // not foreseen); speed and deficiency 4 bytes each, [T, N] dense, else [T, M].
    const size_t T = job.times.size(), N = job.cloud.size(), M = job.cloud.dynamic_count();
    const TableLayout layout = job.output.tables;
    size_t rows = T;
    if (layout == TableLayout::Compact) {
      const std::vector<uint32_t> keys = count_row_keys(job.cameras, job.times, job.frame_step, {});
      rows = size_t(*std::max_element(keys.begin(), keys.end())) + 1;
    }
    const size_t count_bytes = layout == TableLayout::Compact ? checked_mul(rows, checked_mul(N, 2, "--frames", "the tables"), "--frames", "the tables") +
                                                                     checked_mul(T, M * 2, "--frames", "the tables")
                                                               : checked_mul(T, checked_mul(N, 2, "--frames", "the tables"), "--frames", "the tables");
    const size_t tables = count_bytes + checked_mul(T, checked_mul(layout == TableLayout::Dense ? N : M, 8, "--frames", "the tables"), "--frames", "the tables");
    namespace fs = std::filesystem;
    fs::path where = fs::absolute(f.out);
    std::error_code ec;
    while (!where.empty() && !fs::exists(where, ec)) where = where.parent_path();
    const fs::space_info space = fs::space(where, ec);
    if (!ec && tables > space.available)
      in.fail("the tables of ", N, " Gaussians at ", T, " frames need up to ", tables, " bytes, more than the ", space.available, " free under ",
              where.string());
  }
  if (in.given("--shard")) {
    // --shard i/n: the i-th of n contiguous blocks of frames (1-based), for observe --merge.
    const std::string& spec = f.shard;
    const size_t slash = spec.find('/');
    size_t index = 0, count = 0;
    if (slash != std::string::npos) {
      index = parse_count(spec.substr(0, slash), 1u << 20, "fillgs observe", "--shard index");
      count = parse_count(spec.substr(slash + 1), 1u << 20, "fillgs observe", "--shard count");
    }
    if (slash == std::string::npos || index < 1 || count < 1 || index > count) in.fail("--shard expects i/n with 1 <= i <= n (got '", spec, "')");
    if (count > job.times.size()) in.fail("--shard ", spec, ": more shards than the ", job.times.size(), " frames");
    job.options.frames = shard_frames(job.times.size(), index - 1, count);
  }
  return job;
}

void print_observed(std::ostream& out, const ObserveJob& job, const ObserveReport& r, double seconds, const std::string& out_dir) {
  const ObservationSummary& s = r.summary;
  out << "observed " << s.gaussians << " Gaussians (" << s.dynamic_count << " dynamic) over " << s.frames << " frames and " << s.views
      << " views (" << to_string(job.options.visibility.mode);
  if (job.options.visibility.mode == VisibilityMode::Raytraced) out << ", stride " << job.options.visibility.stride;
  out << ") in " << seconds << " s";
  if (s.counters.rays) out << ", " << s.counters.rays << " rays";
  out << ", peak memory " << (r.peak_memory_bytes >> 20) << " MB -> " << out_dir << "\n";
}

/// `fillgs observe --mpi` under mpirun: every rank reads the inputs; if any rank fails,
/// the lowest failing rank says why (one line) and every rank exits 1; then frames go
/// round the ranks and rank 0 writes the files.
int observe_over_mpi(const ObserveFlags& f, const Invocation& in) {
#ifdef FILLGS_WITH_MPI
  const auto t0 = Clock::now();
  mpi::Session session;
  ObserveJob job;
  std::optional<OutputFolder> folder;
  std::string failure;
  try {
    if (in.given("--shard")) in.fail("--mpi shares the whole job between the ranks; --shard splits it between separate runs");
    job = observe_job(f, in);
    if (session.rank() == 0) folder.emplace(f.out);
  } catch (const std::exception& e) {
    failure = e.what();
  }
  const int failed = session.first_failure(failure.empty());
  if (failed >= 0) {
    if (session.rank() != failed) return 1;
    throw_error(failed == 0 ? failure : "rank " + std::to_string(failed) + ": " + failure);
  }
  try {
    const FrameSource source = mpi::observe_source(job.cloud, job.cameras, job.times, job.frame_step, job.options);
    if (session.rank() != 0) {
      source([](const FrameObservation&) {}, null_progress());
      return 0;
    }
    TerminalProgress progress(in.err, in.progress());
    const ObserveReport r =
        write_observation(job.cloud, job.cameras, job.times, job.frame_step, job.options, source, folder->path(), job.output, progress);
    folder->commit();
    print_observed(in.out, job, r, seconds_since(t0), f.out);
    in.out << "(" << session.size() << " MPI ranks)\n";
    return 0;
  } catch (const std::exception& e) {
    // The ranks are exchanging frames: one that stops would leave the others waiting.
    in.err << "error: " << (session.rank() ? "rank " + std::to_string(session.rank()) + ": " : std::string()) << e.what() << "\n";
    in.err.flush();
    session.abort(1);
  }
#else
  (void)f;
  in.fail("--mpi needs fillgs built with MPI (scripts/install-deps.sh installs libopenmpi-dev; then rebuild)");
#endif
}

int observe(const ObserveFlags& f, const Invocation& in) {
  const auto t0 = Clock::now();
  if (in.given("--merge")) {
    for (const char* k : {"--scene", "--cameras", "--frames", "--times", "--mode", "--stride", "--tau", "--tables", "--motion-tables", "--shard", "--hit-cache"})
      if (in.given(k)) in.fail("--merge combines finished shards; ", k, " belongs to the shards' own runs");
    OutputFolder folder(f.out);
    const ObserveReport r = merge_observations(f.merge, folder.path(), f.output.plots);
    folder.commit();
    in.out << "merged " << f.merge.size() << " shards: " << r.summary.gaussians << " Gaussians over " << r.summary.frames << " frames and "
           << r.summary.views << " views -> " << f.out << "\n";
    return 0;
  }
  for (const char* k : {"--scene", "--cameras"})
    if (!in.given(k)) in.fail("missing ", k);
  if (f.mpi) return observe_over_mpi(f, in);
  const ObserveJob job = observe_job(f, in);
  TerminalProgress progress(in.err, in.progress());
  OutputFolder folder(f.out);  // a failed or killed run leaves the folder as it was
  const ObserveReport r = observe_to_directory(job.cloud, job.cameras, job.times, job.frame_step, job.options, folder.path(), job.output, progress);
  folder.commit();
  print_observed(in.out, job, r, seconds_since(t0), f.out);
  return 0;
}

}  // namespace

Action declare_observe(CLI::App& app) {
  auto f = std::make_shared<ObserveFlags>();
  VisibilityOptions& v = f->options.visibility;
  add_text(app, "--scene", f->scene, "the model (required unless --merge)", "PATH");
  add_text(app, "--cameras", f->cameras, "the training cameras (required unless --merge)", "PATH");
  add_text(app, "--out", f->out, "the folder for the tables, summary.json and plots", "DIR")->required();
  add_time_flags(app, f->time, true);
  add_choice(app, "--mode", v.mode, "how a camera observes a Gaussian: its centre in the frustum, or traced rays");
  add_number(app, "--stride", v.stride, "raytraced: one ray every s pixels", stride_bounds());
  add_number(app, "--tau", v.min_weight, "raytraced: the blending weight at which a hit counts", tau_bounds());
  add_switch_off(app, "--no-raster-match", v.dilate, "raytraced: footprints not widened to the rasterizer's");
  add_switch_off(app, "--from-scratch", f->options.incremental, "raytraced: every frame traced anew, not only what moved");
  add_number(app, "--hit-cache", f->hit_cache_mb, "raytraced: MB of static hits kept for re-traced rays (default 2048; 0: none)", hit_cache_mb_bounds())
      ->type_name("MB");
  add_choice(app, "--tables", f->output.tables,
             "the tables' layout: what varies only (static counts once per camera set), every Gaussian at every frame, or dense counts "
             "with the moving Gaussians' motion");
  add_choice(app, "--motion-tables", f->output.tables, "the older name of --tables")->group("");
  add_switch_off(app, "--no-plots", f->output.plots, "no heatmaps or charts");
  add_text(app, "--shard", f->shard, "the i-th of n blocks of frames, for --merge", "I/N");
  add_list(app, "--merge", f->merge, "finished shards' folders, combined into the single-process tables");
  add_flag(app, "--mpi", f->mpi, "under mpirun: frames shared by the ranks, rank 0 writes");
  add_scene_flags(app, f->read);
  add_camera_flags(app, f->camera_read);
  return bind(f, observe);
}

}  // namespace fillgs::cli
