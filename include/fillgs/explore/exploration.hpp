#pragma once
// The exploration space (the paper, Appendix A, after ExploreGS): a voxel grid over the scene box, stored as an
// OpenVDB grid (accel/exploration_grid.cpp), that candidate viewpoints are sampled from.
//
// Labels:
//  * occupied   — some Gaussian reaches α >= `occupancy_alpha` in the voxel: the voxel
//                 meets the ellipsoid {x : o·exp(-½ xᵀΣ⁻¹x) >= occupancy_alpha} (test: the
//                 voxel centre lies in that ellipsoid with every semi-axis grown by half
//                 the voxel diagonal, a conservative bound). Moving Gaussians occupy every
//                 voxel they sweep over the frames given (the union over time);
//  * unexplored — the voxel centre lies in no training camera's frustum (in front of the
//                 near plane, projecting inside the image);
//  * free       — everything else. Only free voxels take candidate viewpoints.
// Box: the training camera centres plus robust bounds of the Gaussian means (the
// `bounds_quantile` and 1 − `bounds_quantile` quantiles per axis, so floaters do not
// stretch it), grown by `margin` of its size. `divisions` cells along each axis (the
// paper's rule; voxels are boxes, not cubes, unless the scene box is a cube).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "fillgs/base/bounds.hpp"
#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/progress.hpp"

namespace fillgs {

enum class VoxelLabel : uint8_t { Free = 0, Occupied = 1, Unexplored = 2 };
FILLGS_ENUM_NAMES(VoxelLabel, "voxel label",
    {VoxelLabel::Free, "free"}, {VoxelLabel::Occupied, "occupied"}, {VoxelLabel::Unexplored, "unexplored"});

/// The most cells along an axis a grid may have (built or read).
constexpr int kMaxDivisions = 512;

struct ExplorationOptions {
  int divisions = 64;             ///< cells along each axis
  float occupancy_alpha = 0.1f;   ///< a Gaussian occupies where its α reaches this
  double bounds_quantile = 0.01;  ///< robust Gaussian bounds: this and 1 − this quantile per axis
  double margin = 0.05;           ///< box grown by this fraction of its size on every side
  /// Label voxels no training frustum contains "unexplored" (trajectories do not enter
  /// them); off: only occupied voxels are masked, as the paper does.
  bool label_unexplored = true;
};

struct ExplorationStats {
  size_t occupied = 0, unexplored = 0, free = 0;
  size_t occupied_by_static = 0;  ///< voxels the static Gaussians alone occupy
  size_t cleared_at_cameras = 0;  ///< occupied voxels freed because a training camera stands in them
  size_t occupying_gaussians = 0; ///< Gaussians with opacity >= occupancy_alpha
  int time_samples = 0;           ///< frames the moving Gaussians were swept over
  double seconds = 0;
};

/// The ranges of ExplorationOptions' values both faces take: divisions >= 1, the occupancy
/// alpha in (0, 1).
Bounds divisions_bounds();
Bounds occupancy_alpha_bounds();

/// Axis-aligned box.
struct Box3 {
  Vec3d lo = Vec3d::Zero(), hi = Vec3d::Zero();
  void extend(const Vec3d& p) { lo = lo.cwiseMin(p), hi = hi.cwiseMax(p); }
  bool contains(const Vec3d& p) const { return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all(); }
};

/// The labelled voxels of the exploration space, stored in OpenVDB (accel/): queries, and
/// the file. build_exploration_grid (below) decides the labels.
class ExplorationGrid {
 public:
  /// The grid of `dims` voxels over `box` with these labels (x fastest, then y, then z;
  /// VoxelLabel values); `occupancy_alpha` is recorded in the file. Counts the labels into
  /// stats->occupied, unexplored and free when given.
  static ExplorationGrid from_labels(const Box3& box, const Vec3i& dims, const std::vector<uint8_t>& labels, float occupancy_alpha,
                                     ExplorationStats* stats = nullptr);
  /// Reads a grid written by write(); throws naming the file when it is not one.
  static ExplorationGrid read(const std::string& path);
  /// Writes an OpenVDB file (atomically): BoolGrids "occupied" and "unexplored" (free = in
  /// neither) with the box and divisions as metadata. read() also takes the first layout, one
  /// Int32Grid "labels" (1 occupied, 2 unexplored, background 0 = free).
  void write(const std::string& path) const;

  ExplorationGrid();
  ~ExplorationGrid();
  ExplorationGrid(ExplorationGrid&&) noexcept;
  ExplorationGrid& operator=(ExplorationGrid&&) noexcept;

  const Box3& box() const { return box_; }
  const Vec3i& dims() const { return dims_; }
  /// The opacity at which a Gaussian occupied a voxel when the grid was built (its file's
  /// record; ExplorationOptions' default for a file written before it was recorded).
  float occupancy_alpha() const { return occupancy_alpha_; }
  Vec3d voxel_size() const { return (box_.hi - box_.lo).cwiseQuotient(dims_.cast<double>()); }
  /// Candidate step: twice the voxel's body diagonal (the paper, Appendix A, after ExploreGS).
  double step() const { return 2.0 * voxel_size().norm(); }

  /// Voxel index of a point (may lie outside [0, dims)).
  Vec3i voxel_of(const Vec3d& p) const {
    const Vec3d u = (p - box_.lo).cwiseQuotient(voxel_size());
    return Vec3i(int(std::floor(std::clamp(u.x(), -1e9, 1e9))), int(std::floor(std::clamp(u.y(), -1e9, 1e9))),
                 int(std::floor(std::clamp(u.z(), -1e9, 1e9))));
  }
  Vec3d voxel_centre(const Vec3i& ijk) const { return box_.lo + (ijk.cast<double>() + Vec3d::Constant(0.5)).cwiseProduct(voxel_size()); }
  bool inside(const Vec3i& ijk) const { return (ijk.array() >= 0).all() && (ijk.array() < dims_.array()).all(); }
  /// Label of a voxel; outside the grid counts as unexplored.
  VoxelLabel label(const Vec3i& ijk) const;
  VoxelLabel label_at(const Vec3d& p) const { return label(voxel_of(p)); }
  bool is_free(const Vec3d& p) const { return label_at(p) == VoxelLabel::Free; }
  /// True when every voxel the segment a→b passes through is free (exact voxel traversal).
  bool segment_free(const Vec3d& a, const Vec3d& b) const;
  /// Free voxels whose centres lie in `box`, in index order.
  std::vector<Vec3i> free_voxels_in(const Box3& box) const;
  /// `n` points drawn uniformly among the free voxels whose centres lie in `box` (a voxel
  /// drawn uniformly, then a point uniform inside it); fewer when the box holds none.
  std::vector<Vec3d> sample_free(const Box3& box, int n, std::mt19937_64& rng) const;
  /// Counts per label (free, occupied, unexplored).
  std::array<size_t, 3> counts() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Box3 box_;
  Vec3i dims_ = Vec3i::Zero();
  float occupancy_alpha_ = ExplorationOptions{}.occupancy_alpha;
};

/// The exploration space of a scene (the paper, Appendix A, after ExploreGS): a box around the training cameras and
/// the robust bounds of the Gaussians that reach `occupancy_alpha`; occupied where such a
/// Gaussian's ellipsoid (grown by half a voxel diagonal) holds a voxel's centre at any of
/// `times` (empty: every frame of a keyframed scene, else 33 samples), unexplored where no
/// training camera sees the centre, free elsewhere and where a training camera stands.
ExplorationGrid build_exploration_grid(const GaussianCloud& scene, const std::vector<Camera>& training, const std::vector<double>& times,
                                       const ExplorationOptions& options = {}, ExplorationStats* stats = nullptr,
                                       Progress& progress = null_progress());

/// World axis (0, 1, 2) closest to the training cameras' mean up direction.
int vertical_axis(const std::vector<Camera>& cameras);

/// The grid's horizontal slice at the training cameras' mean height, for the top-down
/// picture (io/plot.hpp, write_topdown_png).
TopdownSlice topdown_slice(const ExplorationGrid& grid, const std::vector<Camera>& training);

}  // namespace fillgs
