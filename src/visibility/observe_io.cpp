#include "fillgs/visibility/observe_io.hpp"

#include <cfloat>
#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numeric>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/plot.hpp"

namespace fillgs {

size_t peak_memory_bytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return size_t(std::stoull(line.substr(6))) * 1024;
  return 0;
}

namespace {

/// Heatmap columns: dynamic Gaussians ordered along the longest axis of their canonical
/// means, cut into at most `bins` equal groups. Returns the bin of each dynamic index.
std::vector<uint32_t> spatial_bins(const GaussianCloud& cloud, int bins, int* used) {
  const size_t M = cloud.dynamic_count();
  std::vector<uint32_t> bin(M, 0);
  *used = int(std::max<size_t>(1, std::min<size_t>(size_t(bins), M)));
  if (M == 0) return bin;
  Vec3f lo = Vec3f::Constant(1e30f), hi = -lo;
  for (uint32_t g : cloud.dynamic_ids) {
    lo = lo.cwiseMin(cloud.means[g]);
    hi = hi.cwiseMax(cloud.means[g]);
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  std::vector<uint32_t> order(M);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return cloud.means[cloud.dynamic_ids[a]][axis] < cloud.means[cloud.dynamic_ids[b]][axis]; });
  for (size_t k = 0; k < M; ++k) bin[order[k]] = uint32_t(k * size_t(*used) / M);
  return bin;
}

}  // namespace

namespace {

/// What the pictures and summary.json need beyond the tables, per camera and per frame.
struct ObserveTallies {
  std::vector<std::string> camera_names;
  std::vector<uint32_t> pose_group;         ///< per camera (camera_pose_groups)
  std::vector<double> visible_sum;          ///< per camera: Σ over its frames of |visible| / N
  std::vector<size_t> visible_frames;       ///< per camera: frames it observed
  std::vector<double> deficiency_per_frame; ///< Σ_g D[t][g]
  std::vector<float> heat;                  ///< [T, columns]: Σ D per frame and spatial bin
  int columns = 1;
};

/// deficiency_heatmap.png and visible_fraction.png (one bar per camera pose: a rig repeated
/// per frame, "images/cam00/0000", ..., is one camera named after the folder of its frames).
std::vector<std::string> write_observe_plots(const std::string& dir, const ObserveTallies& t, size_t dynamic, const std::string& mode) {
  const int T = int(t.deficiency_per_frame.size());
  write_heatmap_png(join_path(dir, "deficiency_heatmap.png"), t.heat, T, t.columns,
                    {"deficiency D summed per frame (" + std::to_string(dynamic) + " dynamic Gaussians in " + std::to_string(t.columns) + " bins)",
                     "dynamic Gaussians, ordered along the scene's longest axis", "frame"},
                    &t.deficiency_per_frame);
  const size_t poses = t.pose_group.empty() ? 0 : size_t(*std::max_element(t.pose_group.begin(), t.pose_group.end())) + 1;
  std::vector<std::string> names(poses);
  std::vector<double> fractions(poses, 0.0);
  std::vector<size_t> frames_in_bar(poses, 0);
  for (size_t c = 0; c < t.camera_names.size(); ++c) {
    const uint32_t b = t.pose_group[c];
    if (names[b].empty()) {
      std::string n = t.camera_names[c];
      const size_t last = n.find_last_of('/');
      if (last != std::string::npos && last > 0) {
        const size_t before = n.find_last_of('/', last - 1);
        const size_t from = before == std::string::npos ? 0 : before + 1;
        n = n.substr(from, last - from);
      }
      names[b] = n;
    }
    fractions[b] += t.visible_sum[c];
    frames_in_bar[b] += t.visible_frames[c];
  }
  for (size_t b = 0; b < poses; ++b) fractions[b] = frames_in_bar[b] ? fractions[b] / double(frames_in_bar[b]) : 0.0;
  write_bar_chart_png(join_path(dir, "visible_fraction.png"), names, fractions,
                      {"visible fraction of the Gaussians per camera (" + mode + ")", "camera", "visible / N"});
  return {"deficiency_heatmap.png", "visible_fraction.png"};
}

/// The count, speed and deficiency tables of one folder in a layout, streamed frame by frame.
class TableStreams {
 public:
  TableStreams(const std::string& dir, TableLayout layout, bool narrow, size_t N, const std::vector<uint32_t>& dynamic_ids,
               const std::vector<uint32_t>& keys)
      : layout_(layout), narrow_(narrow), N_(N), ids_(dynamic_ids) {
    const size_t T = keys.size(), M = ids_.size();
    if (layout == TableLayout::Compact)
      counts_ = std::make_unique<CompactCountWriter>(dir, narrow, N, dynamic_ids, keys);
    else
      count_ = std::make_unique<NpyStreamWriter>(join_path(dir, "count.npy"), narrow ? "|u1" : "<u2", narrow ? 1 : 2, std::vector<size_t>{T, N});
    const bool dense = layout == TableLayout::Dense;
    const std::string suffix = dense ? "" : "_dynamic";
    motion_names_[0] = "speed" + suffix + ".npy";
    motion_names_[1] = "deficiency" + suffix + ".npy";
    for (int k = 0; k < 2; ++k)
      motion_[k] = std::make_unique<NpyStreamWriter>(join_path(dir, motion_names_[k]), "<f4", 4, std::vector<size_t>{T, dense ? N : M});
  }
  /// One frame: the counts of every Gaussian, the speeds and deficiencies of the moving ones.
  void write(const uint16_t* counts, const float* speed, const float* deficiency) {
    if (counts_) {
      counts_->write(counts);
    } else if (narrow_) {
      narrowed_.assign(counts, counts + N_);
      count_->write(narrowed_.data(), N_);
    } else {
      count_->write(counts, N_ * 2);
    }
    const float* motion[2] = {speed, deficiency};
    for (int k = 0; k < 2; ++k) {
      if (layout_ != TableLayout::Dense) {
        motion_[k]->write(motion[k], ids_.size() * 4);
        continue;
      }
      dense_.assign(N_, 0.0f);
      for (size_t j = 0; j < ids_.size(); ++j) dense_[ids_[j]] = motion[k][j];
      motion_[k]->write(dense_.data(), N_ * 4);
    }
  }
  /// Renames every table into place; returns their names.
  std::vector<std::string> finish() {
    std::vector<std::string> files;
    if (counts_) {
      counts_->finish();
      files = counts_->files();
    } else {
      count_->finish();
      files = {"count.npy"};
    }
    for (int k = 0; k < 2; ++k) {
      motion_[k]->finish();
      files.push_back(motion_names_[k]);
    }
    return files;
  }
  const CompactCountWriter* counts() const { return counts_.get(); }

 private:
  TableLayout layout_;
  bool narrow_;
  size_t N_;
  std::vector<uint32_t> ids_;
  std::unique_ptr<CompactCountWriter> counts_;
  std::unique_ptr<NpyStreamWriter> count_, motion_[2];
  std::string motion_names_[2];
  std::vector<uint8_t> narrowed_;
  std::vector<float> dense_;
};

nlohmann::json per_camera_json(const ObserveTallies& t) {
  nlohmann::json per_camera = nlohmann::json::array();
  for (size_t c = 0; c < t.camera_names.size(); ++c)
    per_camera.push_back({{"camera", t.camera_names[c]},
                          {"visible_fraction", t.visible_frames[c] ? t.visible_sum[c] / double(t.visible_frames[c]) : 0.0},
                          {"frames", t.visible_frames[c]},
                          {"pose_group", t.pose_group[c]}});
  return per_camera;
}

}  // namespace

size_t max_views_per_frame(const std::vector<Camera>& cameras, const std::vector<double>& times, double frame_step) {
  size_t max_views = 0;
  for (const auto& v : views_per_frame(cameras, times, frame_step)) max_views = std::max(max_views, v.size());
  return max_views;
}

ObserveReport observe_to_directory(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                   double frame_step, const ObservationOptions& options, const std::string& dir,
                                   const ObserveOutputOptions& output, Progress& progress) {
  return write_observation(
      cloud, cameras, times, frame_step, options,
      [&](const FrameSink& sink, Progress& p) { return observe(cloud, cameras, times, frame_step, options, sink, p); }, dir, output, progress);
}

ObserveReport write_observation(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                double frame_step, const ObservationOptions& options, const FrameSource& source, const std::string& dir,
                                const ObserveOutputOptions& output, Progress& progress) {
  using Clock = std::chrono::steady_clock;
  make_directories(dir);
  const bool shard = !options.frames.empty();
  const size_t N = cloud.size(), M = cloud.dynamic_count(), T = shard ? options.frames.size() : times.size();
  // The count type follows every frame of the job, so that a shard writes what the whole would.
  const size_t max_views = max_views_per_frame(cameras, times, frame_step);
  const bool narrow = counts_fit_uint8(max_views);

  ObserveReport report;
  const TableLayout layout = output.tables;
  std::vector<uint32_t> keys;  // compact: the count row of every frame written
  {
    const std::vector<uint32_t> all = count_row_keys(cameras, times, frame_step, options.cameras);
    if (shard)
      for (size_t f : options.frames) keys.push_back(all[f]);
    else
      keys = all;
  }
  TableStreams streams(dir, layout, narrow, N, cloud.dynamic_ids, keys);
  ObserveTallies tally;
  const std::vector<uint32_t> bin = spatial_bins(cloud, output.heatmap_columns, &tally.columns);
  tally.heat.assign(T * size_t(tally.columns), 0.0f);
  tally.visible_sum.assign(cameras.size(), 0.0);
  tally.visible_frames.assign(cameras.size(), 0);
  for (const Camera& c : cameras) tally.camera_names.push_back(c.name);
  size_t pose_count = 0;
  tally.pose_group = camera_pose_groups(cameras, &pose_count);
  std::vector<double> evaluated_times;
  double write_seconds = 0;

  const ObservationSummary summary = source(
      [&](const FrameObservation& fo) {
        const auto start = Clock::now();
        streams.write(fo.counts, fo.dynamic_speed, fo.dynamic_deficiency);
        const size_t row = evaluated_times.size();
        evaluated_times.push_back(fo.time);
        double total = 0;
        for (size_t j = 0; j < M; ++j) {
          tally.heat[row * size_t(tally.columns) + bin[j]] += fo.dynamic_deficiency[j];
          total += fo.dynamic_deficiency[j];
        }
        tally.deficiency_per_frame.push_back(total);
        for (size_t k = 0; k < fo.views.size(); ++k) {
          tally.visible_sum[fo.views[k]] += N ? double(fo.visible_per_view[k]) / double(N) : 0.0;
          ++tally.visible_frames[fo.views[k]];
        }
        write_seconds += std::chrono::duration<double>(Clock::now() - start).count();
      },
      progress);
  const auto start_files = Clock::now();
  report.files = streams.finish();
  write_npy(join_path(dir, "dynamic_ids.npy"), cloud.dynamic_ids.data(), {M});
  write_npy(join_path(dir, "times.npy"), evaluated_times.data(), {T});
  report.files.push_back("dynamic_ids.npy");
  report.files.push_back("times.npy");
  if (shard) {  // what observe --merge needs to draw the whole job's heatmap
    write_npy(join_path(dir, "deficiency_heat.npy"), tally.heat.data(), {T, size_t(tally.columns)});
    report.files.push_back("deficiency_heat.npy");
  }
  for (size_t c = 0; c < cameras.size(); ++c)
    report.visible_fraction.push_back(tally.visible_frames[c] ? tally.visible_sum[c] / double(tally.visible_frames[c]) : 0.0);
  report.deficiency_per_frame = tally.deficiency_per_frame;
  if (output.plots)
    for (const std::string& f : write_observe_plots(dir, tally, M, to_string(options.visibility.mode))) report.files.push_back(f);
  write_seconds += std::chrono::duration<double>(Clock::now() - start_files).count();
  report.summary = summary;
  report.peak_memory_bytes = peak_memory_bytes();

  nlohmann::json j;
  j["command"] = "observe";
  j["mode"] = to_string(options.visibility.mode);
  j["stride"] = options.visibility.stride;
  j["min_weight"] = options.visibility.min_weight;
  j["rasterizer_matching"] = options.visibility.dilate;
  j["incremental"] = options.incremental;
  j["gaussians"] = N;
  j["static"] = summary.static_count;
  j["dynamic"] = summary.dynamic_count;
  j["frames"] = T;
  j["frame_step"] = frame_step;
  j["cameras"] = cameras.size();
  j["camera_poses"] = summary.camera_poses;
  j["views"] = summary.views;
  j["max_views_per_frame"] = max_views;
  j["count_dtype"] = narrow ? "uint8" : "uint16";
  j["tables"] = to_string(layout);
  if (layout == TableLayout::Compact) {
    j["count_static_rows"] = streams.counts()->row_keys().size();
    j["count_changes"] = streams.counts()->changes();
  }
  if (shard) {
    j["shard"] = {{"frames_total", times.size()}, {"frames", options.frames}};
    // The job's key of each static count row: the merge numbers the whole job's rows by them.
    if (layout == TableLayout::Compact) j["shard"]["count_static_keys"] = streams.counts()->row_keys();
  }
  j["rays_traced"] = summary.counters.rays;
  j["dynamic_probes"] = summary.counters.probes;
  j["hits"] = summary.counters.hits;
  j["rays_incremental"] = summary.incremental_rays;
  j["rays_in_dynamic_footprints"] = summary.footprint_rays;
  j["rays_retraced"] = summary.retraced_rays;
  j["seconds"] = {{"build", summary.seconds_build},   {"refit", summary.seconds_refit},
                  {"static_answers", summary.seconds_static}, {"frames", summary.seconds_frames},
                  {"speeds", summary.seconds_speed},  {"write", write_seconds},
                  {"total", summary.seconds_total + std::chrono::duration<double>(Clock::now() - start_files).count()}};
  j["peak_memory_mb"] = double(report.peak_memory_bytes) / (1024.0 * 1024.0);
  j["deficiency_per_frame"] = report.deficiency_per_frame;
  j["per_camera"] = per_camera_json(tally);
  j["files"] = report.files;
  write_file_atomically(join_path(dir, "summary.json"), j.dump(2) + "\n");
  report.files.push_back("summary.json");
  return report;
}

namespace {

/// One shard folder of `fillgs observe --shard`: its summary and where its frames lie.
struct ShardInput {
  std::string dir;
  nlohmann::json summary;
  std::vector<size_t> frames;
};

/// A shard's heatmap rows (`row` bins wide), checked as observe writes them: finite and at
/// least 0. One line naming the file, the element and the value otherwise.
void check_heat_values(const std::string& path, const std::string& bytes, size_t row) {
  const size_t n = bytes.size() / sizeof(float);
  for (size_t i = 0; i < n; ++i) {
    float x;
    std::memcpy(&x, &bytes[i * sizeof(float)], sizeof(float));
    if (!(x >= 0.0f && x <= FLT_MAX))
      throw_error(path, ": element [", i / row, ", ", i % row, "] is ", x, ", outside [0, ", double(FLT_MAX), "] (not a finite speed or deficiency)");
  }
}

}  // namespace

ObserveReport merge_observations(const std::vector<std::string>& shard_dirs, const std::string& dir, bool plots) {
  if (shard_dirs.empty()) throw_error("merge: no shard folders");
  std::vector<ShardInput> shards;
  for (const std::string& d : shard_dirs) {
    ShardInput in;
    in.dir = d;
    const std::string path = join_path(d, "summary.json");
    if (!std::filesystem::exists(path)) throw_error(d, ": no summary.json (not a shard folder)");
    in.summary = read_json_file(path);
    try {
      if (!in.summary.contains("shard")) throw_error(path, ": not a shard (written as a whole job)");
      in.frames = in.summary.at("shard").at("frames").get<std::vector<size_t>>();
    } catch (const nlohmann::json::exception& e) {
      throw_error(path, ": malformed shard summary (", e.what(), ")");
    }
    if (in.frames.empty()) throw_error(path, ": a shard with no frames");
    shards.push_back(std::move(in));
  }
  std::sort(shards.begin(), shards.end(), [](const ShardInput& a, const ShardInput& b) { return a.frames.front() < b.frames.front(); });
  // One job: every setting that shapes the tables agrees; frames tile [0, total) in order.
  const nlohmann::json& first = shards.front().summary;
  const char* same_keys[] = {"mode", "stride", "min_weight", "rasterizer_matching", "incremental", "gaussians", "static", "dynamic", "frame_step",
                             "cameras", "camera_poses", "max_views_per_frame", "count_dtype", "tables", "motion_tables"};
  size_t next = 0, T = 0;
  for (const ShardInput& in : shards) try {
    for (const char* k : same_keys)
      if (in.summary.value(k, nlohmann::json()) != first.value(k, nlohmann::json()))
        throw_error(join_path(in.dir, "summary.json"), ": '", k, "' is ", in.summary.value(k, nlohmann::json()).dump(), " but ",
                    first.value(k, nlohmann::json()).dump(), " in ", join_path(shards.front().dir, "summary.json"), ": shards of different jobs");
    if (in.summary["shard"].value("frames_total", size_t(0)) != first["shard"].value("frames_total", size_t(0)))
      throw_error(join_path(in.dir, "summary.json"), ": shards of jobs with different frame counts");
    for (size_t f : in.frames) {
      if (f != next)
        throw_error(join_path(in.dir, "summary.json"), ": frame ", f, " where frame ", next,
                    f < next ? " was expected (two shards hold it)" : " was expected (no shard given holds it)");
      ++next;
    }
    T = first.at("shard").value("frames_total", size_t(0));
  } catch (const nlohmann::json::exception& e) {
    throw_error(join_path(in.dir, "summary.json"), ": malformed shard summary (", e.what(), ")");
  }
  if (next != T) throw_error("merge: the shards hold frames 0 to ", next - 1, " of ", T, " (a shard is missing)");

  const std::string first_path = join_path(shards.front().dir, "summary.json");
  // The tables: each shard read and checked (read_observation), one in memory at a time,
  // its frames streamed in order into the layout the shards share.
  std::vector<ObservationFolder> held;
  std::vector<uint32_t> keys;  // compact: the job's count-row key of every frame
  bool narrow = false;
  size_t N = 0;
  TableLayout layout = TableLayout::Compact;
  std::vector<uint32_t> ids;
  for (size_t s = 0; s < shards.size(); ++s) {
    ObservationFolder in = read_observation(shards[s].dir);
    const std::string where = join_path(shards[s].dir, "summary.json");
    if (in.frames() != shards[s].frames.size())
      throw_error(join_path(shards[s].dir, "times.npy"), ": ", in.frames(), " times for ", shards[s].frames.size(), " frames");
    if (s == 0) {
      narrow = in.narrow, N = in.gaussians, layout = in.layout, ids = in.dynamic_ids;
    } else if (in.dynamic_ids != ids) {
      throw_error(join_path(shards[s].dir, "dynamic_ids.npy"), ": other dynamic Gaussians than ", join_path(shards.front().dir, "dynamic_ids.npy"));
    }
    if (layout == TableLayout::Compact) {
      std::vector<uint32_t> row_keys;
      try {
        row_keys = shards[s].summary.at("shard").at("count_static_keys").get<std::vector<uint32_t>>();
      } catch (const nlohmann::json::exception& e) {
        throw_error(where, ": malformed shard summary (", e.what(), ")");
      }
      if (row_keys.size() != in.static_rows)
        throw_error(where, ": ", row_keys.size(), " count_static_keys for the ", in.static_rows, " rows of count_static.npy");
      for (uint32_t r : in.count_rows) keys.push_back(row_keys[r]);
    } else {
      keys.resize(keys.size() + in.frames(), 0);
    }
    // Only the first shard is kept while the others are checked; the rest are read again below.
    if (s == 0) held.push_back(std::move(in));
  }
  const size_t M = ids.size();
  make_directories(dir);
  ObserveReport report;
  std::vector<double> times;
  size_t static_rows = 0;
  uint64_t changes = 0;
  {
    TableStreams streams(dir, layout, narrow, N, ids, keys);
    std::vector<uint16_t> row(N);
    for (size_t s = 0; s < shards.size(); ++s) {
      const ObservationFolder in = s == 0 ? std::move(held.front()) : read_observation(shards[s].dir);
      if (s == 0) held.clear();
      for (size_t f = 0; f < in.frames(); ++f) {
        in.count_row(f, row.data());
        streams.write(row.data(), in.dynamic_speed.data() + f * M, in.dynamic_deficiency.data() + f * M);
      }
      times.insert(times.end(), in.times.begin(), in.times.end());
    }
    report.files = streams.finish();
    if (layout == TableLayout::Compact) {
      static_rows = streams.counts()->row_keys().size();
      changes = streams.counts()->changes();
    }
  }
  write_npy(join_path(dir, "dynamic_ids.npy"), ids.data(), {M});
  write_npy(join_path(dir, "times.npy"), times.data(), {T});
  report.files.push_back("dynamic_ids.npy");
  report.files.push_back("times.npy");

  // Tallies: per-camera sums, per-frame deficiency and heat rows, concatenated or added.
  ObserveTallies tally;
  nlohmann::json j = first;
  j.erase("shard");
  const char* summed[] = {"views", "rays_traced", "dynamic_probes", "hits", "rays_incremental", "rays_in_dynamic_footprints", "rays_retraced"};
  constexpr int kSummed = int(sizeof(summed) / sizeof(summed[0]));
  uint64_t sums[kSummed] = {};
  double seconds = 0, peak_mb = 0;
  for (const ShardInput& in : shards) {
    const std::string where = join_path(in.dir, "summary.json");
    try {
      for (int k = 0; k < kSummed; ++k) sums[k] += in.summary.at(summed[k]).get<uint64_t>();
      seconds += in.summary.at("seconds").at("total").get<double>();
      peak_mb = std::max(peak_mb, in.summary.at("peak_memory_mb").get<double>());
      const std::vector<double> d = in.summary.at("deficiency_per_frame").get<std::vector<double>>();
      if (d.size() != in.frames.size()) throw_error(where, ": deficiency_per_frame has ", d.size(), " values for ", in.frames.size(), " frames");
      for (size_t k = 0; k < d.size(); ++k)
        if (!(d[k] >= 0 && std::isfinite(d[k]))) throw_error(where, ": deficiency_per_frame element ", k, " is ", d[k], ", not a finite sum >= 0");
      tally.deficiency_per_frame.insert(tally.deficiency_per_frame.end(), d.begin(), d.end());
      const nlohmann::json& cams = in.summary.at("per_camera");
      if (tally.camera_names.empty()) {
        for (const auto& c : cams) {
          tally.camera_names.push_back(c.at("camera").get<std::string>());
          tally.pose_group.push_back(c.at("pose_group").get<uint32_t>());
        }
        tally.visible_sum.assign(cams.size(), 0.0);
        tally.visible_frames.assign(cams.size(), 0);
      }
      if (cams.size() != tally.camera_names.size()) throw_error(where, ": ", cams.size(), " cameras, the first shard ", tally.camera_names.size());
      for (size_t c = 0; c < cams.size(); ++c) {
        if (cams[c].at("camera").get<std::string>() != tally.camera_names[c]) throw_error(where, ": camera ", c, " is not the first shard's");
        const size_t frames = cams[c].at("frames").get<size_t>();
        tally.visible_sum[c] += cams[c].at("visible_fraction").get<double>() * double(frames);
        tally.visible_frames[c] += frames;
      }
    } catch (const nlohmann::json::exception& e) {
      throw_error(where, ": malformed (", e.what(), ")");
    }
    const NpyArray heat = read_npy(join_path(in.dir, "deficiency_heat.npy"));
    if (heat.descr != "<f4" || heat.shape.size() != 2 || heat.shape[0] != in.frames.size())
      throw_error(join_path(in.dir, "deficiency_heat.npy"), ": not [frames, bins] float32");
    if (tally.heat.empty()) tally.columns = int(heat.shape[1]);
    if (heat.shape[1] != size_t(tally.columns)) throw_error(join_path(in.dir, "deficiency_heat.npy"), ": other heatmap bins than the first shard");
    check_heat_values(join_path(in.dir, "deficiency_heat.npy"), heat.bytes, heat.shape[1]);
    const float* h = reinterpret_cast<const float*>(heat.bytes.data());
    tally.heat.insert(tally.heat.end(), h, h + heat.size());
  }
  for (int k = 0; k < kSummed; ++k) j[summed[k]] = sums[k];
  j["frames"] = T;
  if (layout == TableLayout::Compact) {
    j["count_static_rows"] = static_rows;
    j["count_changes"] = changes;
  }
  j["seconds"] = {{"total_over_shards", seconds}};
  j["peak_memory_mb"] = peak_mb;
  j["deficiency_per_frame"] = tally.deficiency_per_frame;
  j["per_camera"] = per_camera_json(tally);
  j["merged_from"] = shard_dirs;
  report.deficiency_per_frame = tally.deficiency_per_frame;
  for (size_t c = 0; c < tally.camera_names.size(); ++c)
    report.visible_fraction.push_back(tally.visible_frames[c] ? tally.visible_sum[c] / double(tally.visible_frames[c]) : 0.0);
  if (plots)
    for (const std::string& f : write_observe_plots(dir, tally, M, first.at("mode").get<std::string>())) report.files.push_back(f);
  j["files"] = report.files;
  write_file_atomically(join_path(dir, "summary.json"), j.dump(2) + "\n");
  report.files.push_back("summary.json");
  report.summary.gaussians = N;
  report.summary.dynamic_count = M;
  report.summary.frames = int(T);
  report.summary.views = size_t(sums[0]);
  return report;
}

}  // namespace fillgs
