// The exploration grid on OpenVDB: labels live in an Int32 grid (background = free), so
// only occupied and unexplored voxels are stored; queries go through value accessors.
// On disk the labels are two BoolGrids, `occupied` and `unexplored` (free = in neither),
// the types every VDB tool reads (pyopenvdb and Blender read no Int32Grid); files of the
// first layout (one Int32Grid `labels`) are still read.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

#include "fillgs/frame_grid.hpp"
#include "fillgs/error.hpp"
#include "fillgs/exploration.hpp"
#include "fillgs/fs_util.hpp"
#include "fillgs/visibility.hpp"

namespace fillgs {

struct ExplorationGrid::Impl {
  openvdb::Int32Grid::Ptr grid;
};

ExplorationGrid::ExplorationGrid() : impl_(std::make_unique<Impl>()) {}
ExplorationGrid::~ExplorationGrid() = default;
ExplorationGrid::ExplorationGrid(ExplorationGrid&&) noexcept = default;
ExplorationGrid& ExplorationGrid::operator=(ExplorationGrid&&) noexcept = default;

namespace {

using Clock = std::chrono::steady_clock;

constexpr int kMaxDivisions = 512;

double quantile(std::vector<float>& v, double q) {
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

/// Times the moving Gaussians are swept over when the caller gives none.
std::vector<double> default_sweep_times(const GaussianCloud& scene) {
  if (scene.dynamic_ids.empty()) return {0.0};
  if (scene.motion == MotionModel::Keyframed && scene.keyframed.key_count > 1) return FrameGrid(scene.keyframed.key_count).times();
  return FrameGrid(33).times();
}

openvdb::math::Transform::Ptr index_to_world(const Box3& box, const Vec3i& dims) {
  const Vec3d vs = (box.hi - box.lo).cwiseQuotient(dims.cast<double>());
  const Vec3d origin = box.lo + 0.5 * vs;  // voxel (0,0,0)'s centre
  openvdb::math::MapBase::Ptr map(
      new openvdb::math::ScaleTranslateMap(openvdb::Vec3d(vs.x(), vs.y(), vs.z()), openvdb::Vec3d(origin.x(), origin.y(), origin.z())));
  return openvdb::math::Transform::Ptr(new openvdb::math::Transform(map));
}

}  // namespace

ExplorationGrid ExplorationGrid::build(const GaussianCloud& scene, const std::vector<Camera>& training, const std::vector<double>& times_in,
                                       const ExplorationOptions& o, ExplorationStats* stats_out, Progress& progress) {
  const auto t0 = Clock::now();
  if (o.divisions < 2 || o.divisions > kMaxDivisions)
    throw_error("exploration grid: divisions must lie in [2, ", kMaxDivisions, "] (got ", o.divisions, ")");
  if (!(o.occupancy_alpha > 0.0f && o.occupancy_alpha < 1.0f)) throw_error("exploration grid: occupancy alpha must lie in (0, 1)");
  if (training.empty()) throw_error("exploration grid: no training cameras");
  openvdb::initialize();
  ExplorationStats stats;
  const std::vector<double> times = times_in.empty() ? default_sweep_times(scene) : times_in;
  stats.time_samples = scene.dynamic_ids.empty() ? 0 : int(times.size());

  FrameEvaluator eval(scene);
  const FrameGaussians& f0 = eval.evaluate(times.front());
  std::vector<uint32_t> occupying;  // Gaussians that reach α >= occupancy_alpha anywhere
  for (uint32_t g = 0; g < f0.size(); ++g)
    if (f0.opacities[g] >= o.occupancy_alpha) occupying.push_back(g);
  // Temporal opacity (Ex4DGS) may lift a moving Gaussian above the threshold at other times.
  std::vector<char> is_dynamic(scene.size(), 0);
  for (uint32_t g : scene.dynamic_ids) is_dynamic[g] = 1;
  stats.occupying_gaussians = occupying.size();

  // ---- box: camera centres + robust bounds of the occupying means (all sweep times)
  ExplorationGrid grid;
  Box3 box{training.front().centre(), training.front().centre()};
  for (const Camera& c : training) box.extend(c.centre());
  {
    std::array<std::vector<float>, 3> coords;
    for (uint32_t g : occupying)
      if (!is_dynamic[g])
        for (int k = 0; k < 3; ++k) coords[size_t(k)].push_back(f0.means[g][k]);
    for (double t : times) {
      const FrameGaussians& f = eval.evaluate(t);
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
  const double longest = std::max(size.maxCoeff(), 1e-6);
  for (int k = 0; k < 3; ++k) {  // a flat box (cameras and scene in one plane) still gets a slab
    const double pad = std::max(o.margin * size[k], size[k] < 1e-3 * longest ? 0.05 * longest : 0.0);
    box.lo[k] -= pad;
    box.hi[k] += pad;
  }
  grid.box_ = box;
  grid.dims_ = Vec3i::Constant(o.divisions);
  const Vec3i dims = grid.dims_;
  const Vec3d vs = grid.voxel_size();
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
              const Vec3d d = grid.voxel_centre(Vec3i(ix, jy, kz)) - mean;
              const Vec3d l = R.transpose() * d;
              const double m = (l.array() / semi.array()).square().sum();
              if (m <= 1.0) labels[flat(ix, jy, kz)].store(1, std::memory_order_relaxed);
            }
      }
    });
  };
  progress.start("exploration grid", times.size() + 2);
  {
    const FrameGaussians& f = eval.evaluate(times.front());
    std::vector<uint32_t> statics;
    for (uint32_t g : occupying)
      if (!is_dynamic[g]) statics.push_back(g);
    occupy(f, statics);
    for (size_t v = 0; v < nvox; ++v) stats.occupied_by_static += labels[v].load(std::memory_order_relaxed);
    progress.advance();
  }
  if (!dyn.empty())
    for (double t : times) {
      occupy(eval.evaluate(t), dyn);
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
  tbb::parallel_for(tbb::blocked_range<int>(0, dims.z()), [&](const tbb::blocked_range<int>& r) {
    for (int kz = r.begin(); kz < r.end(); ++kz)
      for (int jy = 0; jy < dims.y(); ++jy)
        for (int ix = 0; ix < dims.x(); ++ix) {
          const size_t v = flat(ix, jy, kz);
          if (labels[v].load(std::memory_order_relaxed)) continue;
          const Vec3d c = grid.voxel_centre(Vec3i(ix, jy, kz));
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
    const Vec3i v = grid.voxel_of(cam->centre());
    if ((v.array() < 0).any() || (v.array() >= dims.array()).any()) continue;
    std::atomic<uint8_t>& l = labels[flat(v.x(), v.y(), v.z())];
    const uint8_t was = l.load(std::memory_order_relaxed);
    if (was) {
      stats.cleared_at_cameras += was == uint8_t(VoxelLabel::Occupied);
      l.store(0, std::memory_order_relaxed);
    }
  }

  // ---- into OpenVDB: only the non-free voxels are stored
  auto vdb = openvdb::Int32Grid::create(0);
  vdb->setName("labels");
  vdb->setTransform(index_to_world(box, dims));
  vdb->setGridClass(openvdb::GRID_UNKNOWN);
  {
    auto acc = vdb->getAccessor();
    for (int kz = 0; kz < dims.z(); ++kz)
      for (int jy = 0; jy < dims.y(); ++jy)
        for (int ix = 0; ix < dims.x(); ++ix) {
          const uint8_t l = labels[flat(ix, jy, kz)].load(std::memory_order_relaxed);
          if (l == 1) ++stats.occupied;
          if (l == 2) ++stats.unexplored;
          if (l) acc.setValue(openvdb::Coord(ix, jy, kz), int(l));
        }
  }
  stats.free = nvox - stats.occupied - stats.unexplored;
  vdb->insertMeta("fillgs_box_min", openvdb::Vec3DMetadata(openvdb::Vec3d(box.lo.x(), box.lo.y(), box.lo.z())));
  vdb->insertMeta("fillgs_box_max", openvdb::Vec3DMetadata(openvdb::Vec3d(box.hi.x(), box.hi.y(), box.hi.z())));
  vdb->insertMeta("fillgs_divisions", openvdb::Vec3IMetadata(openvdb::Vec3i(dims.x(), dims.y(), dims.z())));
  vdb->insertMeta("fillgs_labels", openvdb::StringMetadata("0 free (background), 1 occupied, 2 unexplored"));
  vdb->insertMeta("fillgs_occupancy_alpha", openvdb::FloatMetadata(o.occupancy_alpha));
  grid.impl_->grid = vdb;
  progress.advance();
  progress.finish();
  stats.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (stats_out) *stats_out = stats;
  return grid;
}

namespace {

/// The metadata fillgs reads back, copied onto every grid it writes.
void copy_fillgs_meta(const openvdb::GridBase& from, openvdb::GridBase& to) {
  for (auto it = from.beginMeta(); it != from.endMeta(); ++it)
    if (it->first.rfind("fillgs_", 0) == 0 && it->first != "fillgs_labels") to.insertMeta(it->first, *it->second);
}

/// One BoolGrid of the voxels whose label is `label`, active and true.
openvdb::BoolGrid::Ptr label_grid(const openvdb::Int32Grid& labels, VoxelLabel label) {
  auto g = openvdb::BoolGrid::create(false);
  g->setName(to_string(label));
  g->setTransform(labels.transform().copy());
  copy_fillgs_meta(labels, *g);
  auto acc = g->getAccessor();
  for (auto it = labels.cbeginValueOn(); it; ++it)
    if (*it == int(label)) acc.setValue(it.getCoord(), true);
  return g;
}

}  // namespace

void ExplorationGrid::write(const std::string& path) const {
  FILLGS_CHECK(impl_->grid);
  write_atomically(path, [&](const std::string& tmp) {
    try {
      openvdb::io::File file(tmp);
      file.write({label_grid(*impl_->grid, VoxelLabel::Occupied), label_grid(*impl_->grid, VoxelLabel::Unexplored)});
      file.close();
    } catch (const openvdb::Exception& e) {
      throw_error(path, ": cannot write the OpenVDB file (", e.what(), ")");
    }
  });
}

ExplorationGrid ExplorationGrid::read(const std::string& path) {
  openvdb::initialize();
  ExplorationGrid grid;
  try {
    openvdb::io::File file(path);
    file.open();
    openvdb::Int32Grid::Ptr labels;
    if (file.hasGrid("occupied") && file.hasGrid("unexplored")) {
      // This layout: two BoolGrids, merged into the in-memory labels.
      for (const VoxelLabel label : {VoxelLabel::Occupied, VoxelLabel::Unexplored}) {
        auto base = file.readGrid(to_string(label));
        auto g = openvdb::gridPtrCast<openvdb::BoolGrid>(base);
        if (!g) throw_error(path, ": grid '", to_string(label), "' is ", base->type(), ", expected bool");
        if (!labels) {
          labels = openvdb::Int32Grid::create(0);
          labels->setName("labels");
          labels->setTransform(g->transform().copy());
          copy_fillgs_meta(*g, *labels);
        }
        auto acc = labels->getAccessor();
        for (auto it = g->cbeginValueOn(); it; ++it)
          if (*it) acc.setValue(it.getCoord(), int(label));
      }
    } else if (file.hasGrid("labels")) {
      // The first layout: one Int32Grid of labels.
      auto base = file.readGrid("labels");
      labels = openvdb::gridPtrCast<openvdb::Int32Grid>(base);
      if (!labels) throw_error(path, ": grid 'labels' is ", base->type(), ", expected Int32");
    } else {
      throw_error(path, ": no grids named 'occupied' and 'unexplored' (not written by fillgs explore)");
    }
    file.close();
    for (const char* key : {"fillgs_box_min", "fillgs_box_max", "fillgs_divisions"})
      if (!(*labels)[key]) throw_error(path, ": metadata '", key, "' is missing");
    const auto lo = labels->metaValue<openvdb::Vec3d>("fillgs_box_min");
    const auto hi = labels->metaValue<openvdb::Vec3d>("fillgs_box_max");
    const auto d = labels->metaValue<openvdb::Vec3i>("fillgs_divisions");
    grid.box_.lo = Vec3d(lo.x(), lo.y(), lo.z());
    grid.box_.hi = Vec3d(hi.x(), hi.y(), hi.z());
    grid.dims_ = Vec3i(d.x(), d.y(), d.z());
    if ((grid.dims_.array() < 1).any() || (grid.dims_.array() > kMaxDivisions).any() || !((grid.box_.hi - grid.box_.lo).array() > 0).all() ||
        !grid.box_.lo.allFinite() || !grid.box_.hi.allFinite())
      throw_error(path, ": metadata fillgs_box_min/max or fillgs_divisions is invalid");
    grid.impl_->grid = labels;
  } catch (const openvdb::Exception& e) {
    throw_error(path, ": cannot read as an exploration grid (", e.what(), ")");
  }
  return grid;
}

Vec3i ExplorationGrid::voxel_of(const Vec3d& p) const {
  const Vec3d u = (p - box_.lo).cwiseQuotient(voxel_size());
  return Vec3i(int(std::floor(std::clamp(u.x(), -1e9, 1e9))), int(std::floor(std::clamp(u.y(), -1e9, 1e9))),
               int(std::floor(std::clamp(u.z(), -1e9, 1e9))));
}

Vec3d ExplorationGrid::voxel_centre(const Vec3i& ijk) const {
  return box_.lo + (ijk.cast<double>() + Vec3d::Constant(0.5)).cwiseProduct(voxel_size());
}

bool ExplorationGrid::inside(const Vec3i& ijk) const { return (ijk.array() >= 0).all() && (ijk.array() < dims_.array()).all(); }

VoxelLabel ExplorationGrid::label(const Vec3i& ijk) const {
  if (!inside(ijk) || !impl_->grid) return VoxelLabel::Unexplored;
  return VoxelLabel(impl_->grid->tree().getValue(openvdb::Coord(ijk.x(), ijk.y(), ijk.z())));
}

bool ExplorationGrid::segment_free(const Vec3d& a, const Vec3d& b) const {
  // Amanatides & Woo traversal in index space.
  const Vec3d vs = voxel_size();
  const Vec3d ua = (a - box_.lo).cwiseQuotient(vs), ub = (b - box_.lo).cwiseQuotient(vs);
  Vec3i v = voxel_of(a);
  const Vec3i end = voxel_of(b);
  auto acc = impl_->grid->getConstAccessor();
  auto free_at = [&](const Vec3i& ijk) { return inside(ijk) && acc.getValue(openvdb::Coord(ijk.x(), ijk.y(), ijk.z())) == 0; };
  if (!free_at(v)) return false;
  const Vec3d d = ub - ua;
  Vec3i step;
  Vec3d t_max, t_delta;
  for (int k = 0; k < 3; ++k) {
    if (d[k] > 0) {
      step[k] = 1;
      t_max[k] = (std::floor(ua[k]) + 1 - ua[k]) / d[k];
      t_delta[k] = 1 / d[k];
    } else if (d[k] < 0) {
      step[k] = -1;
      t_max[k] = (ua[k] - std::floor(ua[k])) / -d[k];
      t_delta[k] = -1 / d[k];
    } else {
      step[k] = 0;
      t_max[k] = t_delta[k] = std::numeric_limits<double>::infinity();
    }
  }
  const int max_steps = dims_.sum() + 3;
  for (int n = 0; n < max_steps && v != end; ++n) {
    int k = 0;
    if (t_max[1] < t_max[k]) k = 1;
    if (t_max[2] < t_max[k]) k = 2;
    if (t_max[k] > 1.0) break;  // b reached (rounding)
    v[k] += step[k];
    t_max[k] += t_delta[k];
    if (!free_at(v)) return false;
  }
  return free_at(end);
}

std::vector<Vec3i> ExplorationGrid::free_voxels_in(const Box3& box) const {
  std::vector<Vec3i> out;
  const Vec3d vs = voxel_size();
  Vec3i lo, hi;
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::max(0, int(std::ceil((box.lo[k] - box_.lo[k]) / vs[k] - 0.5)));
    hi[k] = std::min(dims_[k] - 1, int(std::floor((box.hi[k] - box_.lo[k]) / vs[k] - 0.5)));
  }
  auto acc = impl_->grid->getConstAccessor();
  for (int kz = lo.z(); kz <= hi.z(); ++kz)
    for (int jy = lo.y(); jy <= hi.y(); ++jy)
      for (int ix = lo.x(); ix <= hi.x(); ++ix)
        if (acc.getValue(openvdb::Coord(ix, jy, kz)) == 0) out.emplace_back(ix, jy, kz);
  return out;
}

std::vector<Vec3d> ExplorationGrid::sample_free(const Box3& box, int n, std::mt19937_64& rng) const {
  std::vector<Vec3i> voxels = free_voxels_in(box);
  std::vector<Vec3d> out;
  const Vec3d vs = voxel_size();
  // Distinct voxels (partial Fisher–Yates), a uniform point inside each.
  for (int s = 0; s < n && size_t(s) < voxels.size(); ++s) {
    const size_t j = size_t(s) + size_t(rng() % uint64_t(voxels.size() - size_t(s)));
    std::swap(voxels[size_t(s)], voxels[j]);
    Vec3d u;
    for (int k = 0; k < 3; ++k) u[k] = double(rng() >> 11) * (1.0 / 9007199254740992.0);
    out.push_back(box_.lo + (voxels[size_t(s)].cast<double>() + u).cwiseProduct(vs));
  }
  return out;
}

std::array<size_t, 3> ExplorationGrid::counts() const {
  std::array<size_t, 3> c{0, 0, 0};
  for (auto it = impl_->grid->cbeginValueOn(); it; ++it) {
    const int l = *it;
    if (l == 1 || l == 2) c[size_t(l)] += it.getVoxelCount();
  }
  c[0] = size_t(dims_.x()) * size_t(dims_.y()) * size_t(dims_.z()) - c[1] - c[2];
  return c;
}

}  // namespace fillgs
