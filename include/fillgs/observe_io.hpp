#pragma once
// `fillgs observe` as a library call: the observation tables streamed to .npy files frame
// by frame (never all held in memory), summary.json, and two pictures.
#include <string>
#include <vector>

#include "fillgs/visibility.hpp"

namespace fillgs {

struct ObserveOutputOptions {
  /// true: speed.npy and deficiency.npy are [T, N] (zeros for static Gaussians);
  /// false: speed_dynamic.npy and deficiency_dynamic.npy are [T, M] over dynamic_ids.npy.
  bool dense_motion_tables = true;
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

/// Computes the tables (see observe) and writes into `dir`:
///   count.npy [T, N] (uint8 when at most 255 views share a time, else uint16),
///   speed.npy / deficiency.npy [T, N] float32 (or the _dynamic [T, M] variants),
///   dynamic_ids.npy [M] uint32, times.npy [T] float64, summary.json,
///   deficiency_heatmap.png (Σ D per frame and per bin of dynamic Gaussians ordered along
///   the scene's longest axis), visible_fraction.png (per camera).
/// Every file appears atomically; nothing is left under a final name if it fails.
ObserveReport observe_to_directory(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                   double frame_step, const ObservationOptions& options, const std::string& dir,
                                   const ObserveOutputOptions& output = {}, Progress& progress = null_progress());

/// Peak resident memory of this process so far (Linux VmHWM), 0 where unknown.
size_t peak_memory_bytes();

}  // namespace fillgs
