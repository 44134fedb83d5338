// The exploration space's labels (exploration.hpp, build_exploration_grid): which voxels
// the scene occupies, which no training camera sees, which are free. The grid that stores
// them, and everything that touches OpenVDB, is accel/exploration_grid.cpp.
#include "fillgs/explore/exploration.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>

#include "fillgs/base/error.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

namespace {

double quantile(std::vector<float>& v, double q) {
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

/// Times the moving Gaussians are swept over when the caller gives none.
std::vector<double> default_sweep_times(const GaussianCloud& scene) {
  if (scene.dynamic_ids.empty()) return {0.0};
  if (motion_frames(scene) > 1) return FrameGrid(motion_frames(scene)).times();
  return FrameGrid(33).times();
}

}  // namespace

ExplorationGrid build_exploration_grid(const GaussianCloud& scene, const std::vector<Camera>& training, const std::vector<double>& times_in,
                                       const ExplorationOptions& o, ExplorationStats* stats_out, Progress& progress) {
  const auto t0 = Clock::now();
  if (o.divisions < 2 || o.divisions > kMaxDivisions)
    throw_error("exploration grid: divisions must lie in [2, ", kMaxDivisions, "] (got ", o.divisions, ")");
  if (!occupancy_alpha_bounds().holds(o.occupancy_alpha)) throw_error("exploration grid: occupancy alpha must lie in (0, 1)");
  if (training.empty()) throw_error("exploration grid: no training cameras");
  ExplorationStats stats;
  const std::vector<double> times = times_in.empty() ? default_sweep_times(scene) : times_in;
  stats.time_samples = scene.dynamic_ids.empty() ? 0 : int(times.size());

  FrameSampler sampler(scene);
  const FrameGaussians& f0 = sampler.at(times.front());
  std::vector<uint32_t> occupying;  // Gaussians that reach α >= occupancy_alpha anywhere
  for (uint32_t g = 0; g < f0.size(); ++g)
    if (f0.opacities[g] >= o.occupancy_alpha) occupying.push_back(g);
  // Temporal opacity (Ex4DGS) may lift a moving Gaussian above the threshold at other times.
  std::vector<char> is_dynamic(scene.size(), 0);
  for (uint32_t g : scene.dynamic_ids) is_dynamic[g] = 1;
  stats.occupying_gaussians = occupying.size();

  // ---- box: camera centres + robust bounds of the occupying means (all sweep times)
  Box3 box{training.front().centre(), training.front().centre()};
  for (const Camera& c : training) box.extend(c.centre());
  {
    std::array<std::vector<float>, 3> coords;
    for (uint32_t g : occupying)
      if (!is_dynamic[g])
        for (int k = 0; k < 3; ++k) coords[size_t(k)].push_back(f0.means[g][k]);
    for (double t : times) {
      const FrameGaussians& f = sampler.at(t);
      for (uint32_t g : scene.dynamic_ids)
        if (f.opacities[g] >= o.occupancy_alpha)
          for (int k = 0; k < 3; ++k) coords[size_t(k)].push_back(f.means[g][k]);
    }
    if (!coords[0].empty()) {
      Vec3d lo, hi;
      for (int k = 0; k < 3; ++k) {
        lo[k] = quantile(coords[size_t(k)], o.bounds_quantile);
        hi[k] = quantile(coords[size_t(k)], 1.0 - o.bounds_quantile);
      }
      box.extend(lo);
      box.extend(hi);
    }
  }
  Vec3d size = box.hi - box.lo;
  // Nothing spans space: one camera and no Gaussian that occupies anything (an empty model, or
  // one whose every Gaussian is fainter than the occupancy alpha). A grid around a point would
  // have voxels of size 0, which OpenVDB refuses with its own words.
  if (!(size.maxCoeff() > 0.0))
    throw_error("exploration grid: nothing to span: ", scene.size() == 0 ? std::string("the model has no Gaussians")
                                                                         : "no Gaussian reaches the occupancy alpha " + std::to_string(o.occupancy_alpha),
                " and the ", training.size(), " training camera(s) stand at one point");
  const double longest = std::max(size.maxCoeff(), 1e-6);
  for (int k = 0; k < 3; ++k) {  // a flat box (cameras and scene in one plane) still gets a slab
    const double pad = std::max(o.margin * size[k], size[k] < 1e-3 * longest ? 0.05 * longest : 0.0);
    box.lo[k] -= pad;
    box.hi[k] += pad;
  }
  const Vec3i dims = Vec3i::Constant(o.divisions);
  const Vec3d vs = (box.hi - box.lo).cwiseQuotient(dims.cast<double>());
  auto voxel_centre = [&](const Vec3i& ijk) -> Vec3d { return box.lo + (ijk.cast<double>() + Vec3d::Constant(0.5)).cwiseProduct(vs); };
  const double half_diagonal = 0.5 * vs.norm();
  const size_t nvox = size_t(dims.x()) * size_t(dims.y()) * size_t(dims.z());
  auto flat = [&](int i, int j, int k) { return (size_t(k) * size_t(dims.y()) + size_t(j)) * size_t(dims.x()) + size_t(i); };

  // ---- occupancy: voxels whose centre lies in a Gaussian's α >= threshold ellipsoid grown by half a voxel diagonal
  std::unique_ptr<std::atomic<uint8_t>[]> labels(new std::atomic<uint8_t>[nvox]);
  for (size_t v = 0; v < nvox; ++v) labels[v].store(0, std::memory_order_relaxed);
  const std::vector<uint32_t>& dyn = scene.dynamic_ids;
  auto occupy = [&](const FrameGaussians& f, const std::vector<uint32_t>& ids) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ids.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t n = r.begin(); n < r.end(); ++n) {
        const uint32_t g = ids[n];
        const float op = f.opacities[g];
        if (!(op >= o.occupancy_alpha)) continue;
        const double k = std::sqrt(2.0 * std::log(double(op) / double(o.occupancy_alpha)));
        const Mat3d R = quat_to_matrix<float>(f.rotations[g]).cast<double>();
        Vec3d semi;
        for (int a = 0; a < 3; ++a) semi[a] = k * double(f.scales[g][a]) + half_diagonal;
        const Vec3d mean = f.means[g].cast<double>();
        Vec3i lo, hi;
        bool empty = false;
        for (int j = 0; j < 3; ++j) {
          double ext = 0;
          for (int a = 0; a < 3; ++a) ext += (R(j, a) * semi[a]) * (R(j, a) * semi[a]);
          ext = std::sqrt(ext);
          // voxel centres c_i = lo + (i + ½) vs within [mean − ext, mean + ext]
          lo[j] = std::max(0, int(std::ceil((mean[j] - ext - box.lo[j]) / vs[j] - 0.5)));
          hi[j] = std::min(dims[j] - 1, int(std::floor((mean[j] + ext - box.lo[j]) / vs[j] - 0.5)));
          if (lo[j] > hi[j]) empty = true;
        }
        if (empty) continue;
        for (int kz = lo.z(); kz <= hi.z(); ++kz)
          for (int jy = lo.y(); jy <= hi.y(); ++jy)
            for (int ix = lo.x(); ix <= hi.x(); ++ix) {
              const Vec3d d = voxel_centre(Vec3i(ix, jy, kz)) - mean;
              const Vec3d l = R.transpose() * d;
              const double m = (l.array() / semi.array()).square().sum();
              if (m <= 1.0) labels[flat(ix, jy, kz)].store(1, std::memory_order_relaxed);
            }
      }
    });
  };
  progress.start("exploration grid", times.size() + 2);
  {
    const FrameGaussians& f = sampler.at(times.front());
    std::vector<uint32_t> statics;
    for (uint32_t g : occupying)
      if (!is_dynamic[g]) statics.push_back(g);
    occupy(f, statics);
    for (size_t v = 0; v < nvox; ++v) stats.occupied_by_static += labels[v].load(std::memory_order_relaxed);
    progress.advance();
  }
  if (!dyn.empty())
    for (double t : times) {
      occupy(sampler.at(t), dyn);
      progress.advance();
    }
  else
    progress.advance(times.size());

  size_t distinct = 0;
  const std::vector<uint32_t> groups = camera_pose_groups(training, &distinct);
  std::vector<const Camera*> poses(distinct, nullptr);
  for (size_t c = 0; c < training.size(); ++c)
    if (!poses[groups[c]]) poses[groups[c]] = &training[c];
  // ---- unexplored: centres inside no training frustum (one test per distinct pose)
  if (o.label_unexplored)
  tbb::parallel_for(tbb::blocked_range<int>(0, dims.z()), [&](const tbb::blocked_range<int>& r) {
    for (int kz = r.begin(); kz < r.end(); ++kz)
      for (int jy = 0; jy < dims.y(); ++jy)
        for (int ix = 0; ix < dims.x(); ++ix) {
          const size_t v = flat(ix, jy, kz);
          if (labels[v].load(std::memory_order_relaxed)) continue;
          const Vec3d c = voxel_centre(Vec3i(ix, jy, kz));
          bool seen = false;
          for (const Camera* cam : poses) {
            const Vec3d p = cam->project(c);
            if (p.z() > 0 && p.x() >= 0 && p.y() >= 0 && p.x() < cam->width && p.y() < cam->height) {
              seen = true;
              break;
            }
          }
          if (!seen) labels[v].store(uint8_t(VoxelLabel::Unexplored), std::memory_order_relaxed);
        }
  });
  progress.advance();

  // ---- a training camera stood in free space: its voxel is free whatever a trained model
  // put there (a floater or an oversized Gaussian around a camera would otherwise wall in
  // every trajectory starting from it) and although no other camera may see it (a sparse
  // rig's own centres lie in no frustum)
  for (const Camera* cam : poses) {
    const Vec3d u = (cam->centre() - box.lo).cwiseQuotient(vs);
    const Vec3i v(int(std::floor(std::clamp(u.x(), -1e9, 1e9))), int(std::floor(std::clamp(u.y(), -1e9, 1e9))),
                  int(std::floor(std::clamp(u.z(), -1e9, 1e9))));
    if ((v.array() < 0).any() || (v.array() >= dims.array()).any()) continue;
    std::atomic<uint8_t>& l = labels[flat(v.x(), v.y(), v.z())];
    const uint8_t was = l.load(std::memory_order_relaxed);
    if (was) {
      stats.cleared_at_cameras += was == uint8_t(VoxelLabel::Occupied);
      l.store(0, std::memory_order_relaxed);
    }
  }

  // ---- into the grid (OpenVDB, accel/)
  std::vector<uint8_t> plain(nvox);
  for (size_t v = 0; v < nvox; ++v) plain[v] = labels[v].load(std::memory_order_relaxed);
  ExplorationGrid grid = ExplorationGrid::from_labels(box, dims, plain, o.occupancy_alpha, &stats);
  progress.advance();
  progress.finish();
  stats.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (stats_out) *stats_out = stats;
  return grid;
}

int vertical_axis(const std::vector<Camera>& cameras) {
  Vec3d up = Vec3d::Zero();
  for (const Camera& c : cameras) up -= c.R.row(1).transpose();  // OpenCV y points down
  int axis = 2;
  up.cwiseAbs().maxCoeff(&axis);
  return axis;
}

TopdownSlice topdown_slice(const ExplorationGrid& grid, const std::vector<Camera>& training) {
  TopdownSlice s;
  s.v = vertical_axis(training), s.a = (s.v + 1) % 3, s.b = (s.v + 2) % 3;
  s.lo = grid.box().lo, s.hi = grid.box().hi;
  const Vec3i dims = grid.dims();
  s.na = dims[s.a], s.nb = dims[s.b];
  // The horizontal slice at the training cameras' mean height (a floor would hide a projection).
  for (const Camera& c : training) s.height += c.centre()[s.v] / double(training.size());
  const int layer = std::clamp(grid.voxel_of(Vec3d::Constant(s.height))[s.v], 0, dims[s.v] - 1);
  s.labels.resize(size_t(s.na) * size_t(s.nb));
  for (int i = 0; i < s.na; ++i)
    for (int j = 0; j < s.nb; ++j) {
      Vec3i ijk;
      ijk[s.a] = i, ijk[s.b] = j, ijk[s.v] = layer;
      s.labels[size_t(i) * size_t(s.nb) + size_t(j)] = uint8_t(grid.label(ijk));
    }
  return s;
}

Bounds divisions_bounds() { return at_least(1); }
Bounds occupancy_alpha_bounds() { return within_open(0, 1); }

}  // namespace fillgs
