#pragma once
// Figures for results people would rather look at than read. Charts (heatmaps, bar charts,
// scatter plots; src/io/chart.cpp) are drawn by gnuplot: each is NAME.png with NAME.csv (the
// numbers) and NAME.gp (the script: `gnuplot NAME.gp` re-plots) beside it, and a missing
// gnuplot leaves the CSV and script with one warning line. Pictures (scene top views, image
// grids; src/io/plot.cpp) are drawn with OpenCV. Files are written atomically.
#include <cstdint>
#include <string>
#include <vector>

#include "fillgs/model/camera.hpp"

namespace fillgs {

/// A horizontal slice of an exploration space seen from above: axis `a` to the right, `b`
/// up, `v` the vertical one, at height `height`; labels[i * nb + j] of cell (i, j) along a
/// and b: 0 free, 1 occupied, 2 unexplored; lo and hi the space's corners.
struct TopdownSlice {
  int a = 0, b = 1, v = 2;
  double height = 0;
  Vec3d lo = Vec3d::Zero(), hi = Vec3d::Ones();
  int na = 0, nb = 0;
  std::vector<uint8_t> labels;
};

/// Top-down picture: the slice's labels as colours, training cameras in red,
/// `virtual_cameras` in blue (a dot and a short line along the viewing direction), all
/// projected along the vertical axis. Written atomically.
void write_topdown_png(const std::string& path, const TopdownSlice& slice, const std::vector<Camera>& training,
                       const std::vector<Camera>& virtual_cameras, const std::string& title);

struct PlotLabels {
  std::string title, x, y;
  /// Heatmaps: a name per row, drawn beside it (empty: row numbers).
  std::vector<std::string> row_names = {};
};

/// A rows × cols heatmap (row 0 at the top), inferno colours from 0 to the maximum, with a
/// colour bar. `row_totals`, when given (size rows), is drawn as a bar profile on the right
/// (and is the CSV's last column).
void write_heatmap_png(const std::string& path, const std::vector<float>& values, int rows, int cols, const PlotLabels& labels,
                       const std::vector<double>* row_totals = nullptr);

/// One bar per value, names rotated underneath, values on the bars (up to 24 bars; beyond,
/// names thinned so they never touch).
void write_bar_chart_png(const std::string& path, const std::vector<std::string>& names, const std::vector<double>& values,
                         const PlotLabels& labels);

/// One series of intervals on an interval chart: per row its estimate and the interval around
/// it (NaN: no interval for that row; the row is left empty in this series).
struct IntervalSeries {
  std::string name;
  std::vector<double> estimate, low, high;
};

/// A forest plot: one row per name (top to bottom), each series' interval as a horizontal
/// bar with its estimate as a point, filled where the interval excludes 0 and open where it
/// does not; a dashed line at 0. Up to four series, side by side within a row.
void write_interval_chart_png(const std::string& path, const std::vector<std::string>& rows, const std::vector<IntervalSeries>& series,
                              const PlotLabels& labels);

struct ScatterSeries {
  std::string name;
  std::vector<double> x, y;
  std::vector<std::string> point_labels;  ///< optional, one per point
  bool joined = true;                     ///< false: points only (settings that are not a sequence)
};

/// Several series as points joined in order of x (one colour each, legend outside the plot on the
/// right); point labels placed where they cover no other label or point; log10 x when asked.
void write_scatter_png(const std::string& path, const std::vector<ScatterSeries>& series, const PlotLabels& labels, bool log_x);

/// Top view (z up) of a rig's split: static points grey, moving points orange, cameras
/// coloured by role (0 training red, 1 interpolation blue, 2 extrapolation purple, 3 other
/// grey) with their viewing direction and name; role 4: a virtual view (green, unnamed).
void write_split_png(const std::string& path, const std::vector<Vec3f>& static_points, const std::vector<Vec3f>& moving_points,
                     const std::vector<Camera>& cameras, const std::vector<int>& roles, const std::string& title);

/// RGB images ([H][W][3] in [0, 1], all width × height) in rows of `columns`, each with a
/// caption above it, scaled up by `zoom` (nearest neighbour).
void write_image_grid_png(const std::string& path, const std::vector<std::vector<float>>& images, int width, int height,
                          const std::vector<std::string>& captions, int columns, int zoom = 2);

/// RGB images ([H][W][3] in [0, 1], same height) side by side with a caption above each,
/// scaled up by `zoom` (nearest neighbour, so pixels stay visible).
void write_side_by_side_png(const std::string& path, const std::vector<std::vector<float>>& images, int width, int height,
                            const std::vector<std::string>& captions, int zoom = 2);

}  // namespace fillgs
