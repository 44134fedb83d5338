#include "fillgs/observe_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <memory>
#include <numeric>

#include "fillgs/error.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/npy.hpp"
#include "fillgs/plot.hpp"

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

ObserveReport observe_to_directory(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                   double frame_step, const ObservationOptions& options, const std::string& dir,
                                   const ObserveOutputOptions& output, Progress& progress) {
  using Clock = std::chrono::steady_clock;
  make_directories(dir);
  const size_t N = cloud.size(), M = cloud.dynamic_count(), T = times.size();
  const auto views = views_per_frame(cameras, times, frame_step);
  size_t max_views = 0;
  for (const auto& v : views) max_views = std::max(max_views, v.size());
  const bool narrow = max_views <= 255;

  ObserveReport report;
  const std::string motion_suffix = output.dense_motion_tables ? "" : "_dynamic";
  const size_t motion_width = output.dense_motion_tables ? N : M;
  auto count_file = std::make_unique<NpyStreamWriter>(join_path(dir, "count.npy"), narrow ? "|u1" : "<u2", narrow ? 1 : 2,
                                                      std::vector<size_t>{T, N});
  auto speed_file = std::make_unique<NpyStreamWriter>(join_path(dir, "speed" + motion_suffix + ".npy"), "<f4", 4,
                                                      std::vector<size_t>{T, motion_width});
  auto deficiency_file = std::make_unique<NpyStreamWriter>(join_path(dir, "deficiency" + motion_suffix + ".npy"), "<f4", 4,
                                                           std::vector<size_t>{T, motion_width});
  int columns = 1;
  const std::vector<uint32_t> bin = spatial_bins(cloud, output.heatmap_columns, &columns);
  std::vector<float> heat(T * size_t(columns), 0.0f);
  std::vector<double> visible_sum(cameras.size(), 0.0);
  std::vector<size_t> visible_frames(cameras.size(), 0);
  std::vector<uint8_t> narrow_row;
  std::vector<float> dense_row;
  double write_seconds = 0;

  const ObservationSummary summary = observe(
      cloud, cameras, times, frame_step, options,
      [&](const FrameObservation& fo) {
        const auto start = Clock::now();
        if (narrow) {
          narrow_row.assign(fo.counts, fo.counts + N);
          count_file->write(narrow_row.data(), N);
        } else {
          count_file->write(fo.counts, N * 2);
        }
        if (output.dense_motion_tables) {
          dense_row.assign(N, 0.0f);
          for (size_t j = 0; j < M; ++j) dense_row[cloud.dynamic_ids[j]] = fo.dynamic_speed[j];
          speed_file->write(dense_row.data(), N * 4);
          for (size_t j = 0; j < M; ++j) dense_row[cloud.dynamic_ids[j]] = fo.dynamic_deficiency[j];
          deficiency_file->write(dense_row.data(), N * 4);
        } else {
          speed_file->write(fo.dynamic_speed, M * 4);
          deficiency_file->write(fo.dynamic_deficiency, M * 4);
        }
        double total = 0;
        for (size_t j = 0; j < M; ++j) {
          heat[size_t(fo.frame) * size_t(columns) + bin[j]] += fo.dynamic_deficiency[j];
          total += fo.dynamic_deficiency[j];
        }
        report.deficiency_per_frame.push_back(total);
        for (size_t k = 0; k < fo.views.size(); ++k) {
          visible_sum[fo.views[k]] += N ? double(fo.visible_per_view[k]) / double(N) : 0.0;
          ++visible_frames[fo.views[k]];
        }
        write_seconds += std::chrono::duration<double>(Clock::now() - start).count();
      },
      progress);
  const auto start_files = Clock::now();
  count_file->finish();
  speed_file->finish();
  deficiency_file->finish();
  report.files = {"count.npy", "speed" + motion_suffix + ".npy", "deficiency" + motion_suffix + ".npy"};
  write_npy(join_path(dir, "dynamic_ids.npy"), cloud.dynamic_ids.data(), {M});
  write_npy(join_path(dir, "times.npy"), times.data(), {T});
  report.files.push_back("dynamic_ids.npy");
  report.files.push_back("times.npy");
  for (size_t c = 0; c < cameras.size(); ++c)
    report.visible_fraction.push_back(visible_frames[c] ? visible_sum[c] / double(visible_frames[c]) : 0.0);

  if (output.plots) {
    write_heatmap_png(join_path(dir, "deficiency_heatmap.png"), heat, int(T), columns,
                      {"deficiency D summed per frame (" + std::to_string(M) + " dynamic Gaussians in " + std::to_string(columns) + " bins)",
                       "dynamic Gaussians, ordered along the scene's longest axis", "frame"},
                      &report.deficiency_per_frame);
    // One bar per camera pose: a rig repeated per frame ("images/cam00/0000", ...) is
    // one camera; its bar is named after the folder that holds its frames.
    std::vector<std::string> names;
    std::vector<double> fractions;
    size_t pose_count = 0;
    const std::vector<uint32_t> pose = camera_pose_groups(cameras, &pose_count);
    names.resize(pose_count);
    fractions.assign(pose_count, 0.0);
    std::vector<size_t> frames_in_bar(pose_count, 0);
    for (size_t c = 0; c < cameras.size(); ++c) {
      if (names[pose[c]].empty()) {
        std::string n = cameras[c].name;
        const size_t last = n.find_last_of('/');
        if (last != std::string::npos && last > 0) {
          const size_t before = n.find_last_of('/', last - 1);
          const size_t from = before == std::string::npos ? 0 : before + 1;
          n = n.substr(from, last - from);
        }
        names[pose[c]] = n;
      }
      fractions[pose[c]] += visible_sum[c];
      frames_in_bar[pose[c]] += visible_frames[c];
    }
    for (size_t b = 0; b < fractions.size(); ++b) fractions[b] = frames_in_bar[b] ? fractions[b] / double(frames_in_bar[b]) : 0.0;
    write_bar_chart_png(join_path(dir, "visible_fraction.png"), names, fractions,
                        {std::string("visible fraction of the Gaussians per camera (") + to_string(options.visibility.mode) + ")",
                         "camera", "visible / N"});
    report.files.push_back("deficiency_heatmap.png");
    report.files.push_back("visible_fraction.png");
  }
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
  j["max_views_per_frame"] = summary.max_views_per_frame;
  j["count_dtype"] = narrow ? "uint8" : "uint16";
  j["rays_traced"] = summary.counters.rays;
  j["dynamic_probes"] = summary.counters.probes;
  j["hits"] = summary.counters.hits;
  j["rays_retraced"] = summary.retraced_rays;
  j["seconds"] = {{"build", summary.seconds_build},   {"refit", summary.seconds_refit},
                  {"static_answers", summary.seconds_static}, {"frames", summary.seconds_frames},
                  {"speeds", summary.seconds_speed},  {"write", write_seconds},
                  {"total", summary.seconds_total + std::chrono::duration<double>(Clock::now() - start_files).count()}};
  j["peak_memory_mb"] = double(report.peak_memory_bytes) / (1024.0 * 1024.0);
  j["deficiency_per_frame"] = report.deficiency_per_frame;
  nlohmann::json per_camera = nlohmann::json::array();
  for (size_t c = 0; c < cameras.size(); ++c)
    per_camera.push_back({{"camera", cameras[c].name}, {"visible_fraction", report.visible_fraction[c]}, {"frames", visible_frames[c]}});
  j["per_camera"] = per_camera;
  j["files"] = report.files;
  write_file_atomically(join_path(dir, "summary.json"), j.dump(2) + "\n");
  report.files.push_back("summary.json");
  return report;
}

}  // namespace fillgs
