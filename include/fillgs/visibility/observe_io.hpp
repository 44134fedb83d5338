#pragma once
// `fillgs observe` as a library call: the observation tables streamed to .npy files frame
// by frame (never all held in memory), summary.json, and two pictures.
#include <functional>
#include <string>
#include <vector>

#include "fillgs/visibility/observe_tables.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

struct ObserveOutputOptions {
  /// Compact: what varies only (observe_tables.hpp); Dense: count.npy, speed.npy and
  /// deficiency.npy [T, N]; Dynamic: count.npy [T, N] with speed_dynamic.npy and
  /// deficiency_dynamic.npy [T, M] over dynamic_ids.npy.
  TableLayout tables = TableLayout::Compact;
  bool plots = true;
  int heatmap_columns = 256;  ///< bins of dynamic Gaussians across the heatmap
};

struct ObserveReport {
  ObservationSummary summary;
  std::vector<std::string> files;              ///< written, relative to the folder
  std::vector<double> visible_fraction;        ///< per camera: mean |visible| / N over its frames
  std::vector<double> deficiency_per_frame;    ///< Σ_g D[t][g]
  size_t peak_memory_bytes = 0;                ///< process peak resident set (VmHWM)
};

/// The most views any of `times` has (views_per_frame), and whether the count tables then fit
/// uint8 (at most 255), else uint16: the type `observe` writes and the Python module returns.
size_t max_views_per_frame(const std::vector<Camera>& cameras, const std::vector<double>& times, double frame_step);
inline bool counts_fit_uint8(size_t max_views) { return max_views <= 255; }

/// Computes the tables (see observe) and writes into `dir`:
///   the count, speed and deficiency tables in `output.tables`' layout (observe_tables.hpp;
///   counts uint8 when at most 255 views share a time, else uint16),
///   dynamic_ids.npy [M] uint32, times.npy [T] float64, summary.json,
///   with ObservationOptions::frames (a shard): only those rows, times.npy of those frames,
///   deficiency_heat.npy (the heatmap's rows) and "shard" in summary.json;
///   deficiency_heatmap.png (Σ D per frame and per bin of dynamic Gaussians ordered along
///   the scene's longest axis), visible_fraction.png (per camera).
/// Every file appears atomically; nothing is left under a final name if it fails.
ObserveReport observe_to_directory(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                   double frame_step, const ObservationOptions& options, const std::string& dir,
                                   const ObserveOutputOptions& output = {}, Progress& progress = null_progress());

using FrameSink = std::function<void(const FrameObservation&)>;
/// Hands every frame of a job to the sink in frame order and returns the summary: observe()
/// in this process, or the frames of several processes (observe_mpi.hpp).
using FrameSource = std::function<ObservationSummary(const FrameSink& sink, Progress& progress)>;

/// observe_to_directory with the frames from `source` (the files, pictures and summary.json
/// of the same job; `options` describes how the source computes them).
ObserveReport write_observation(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                double frame_step, const ObservationOptions& options, const FrameSource& source, const std::string& dir,
                                const ObserveOutputOptions& output = {}, Progress& progress = null_progress());

/// Shards of one job (folders of observe_to_directory with ObservationOptions::frames set:
/// `fillgs observe --shard i/n`) combined into `dir` as the single process writes it: the
/// .npy tables byte for byte (rows in frame order), summary.json (views, rays and seconds
/// summed over the shards, per-camera fractions over all frames) and, with `plots`, the
/// two pictures. The shards must agree on every setting and tile the frames exactly once;
/// otherwise one error names the shard and what differs.
ObserveReport merge_observations(const std::vector<std::string>& shard_dirs, const std::string& dir, bool plots = true);

/// Peak resident memory of this process so far (Linux VmHWM), 0 where unknown.
size_t peak_memory_bytes();

}  // namespace fillgs
