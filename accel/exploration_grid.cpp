// The exploration grid on OpenVDB: labels live in an Int32 grid (background = free), so
// only occupied and unexplored voxels are stored; queries go through value accessors.
// On disk the labels are two BoolGrids, `occupied` and `unexplored` (free = in neither),
// the types every VDB tool reads (pyopenvdb and Blender read no Int32Grid); files of the
// first layout (one Int32Grid `labels`) are still read.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "fillgs/base/error.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/base/fs_util.hpp"

namespace fillgs {

struct ExplorationGrid::Impl {
  openvdb::Int32Grid::Ptr grid;
};

ExplorationGrid::ExplorationGrid() : impl_(std::make_unique<Impl>()) {}
ExplorationGrid::~ExplorationGrid() = default;
ExplorationGrid::ExplorationGrid(ExplorationGrid&&) noexcept = default;
ExplorationGrid& ExplorationGrid::operator=(ExplorationGrid&&) noexcept = default;

namespace {

openvdb::math::Transform::Ptr index_to_world(const Box3& box, const Vec3i& dims) {
  const Vec3d vs = (box.hi - box.lo).cwiseQuotient(dims.cast<double>());
  const Vec3d origin = box.lo + 0.5 * vs;  // voxel (0,0,0)'s centre
  openvdb::math::MapBase::Ptr map(
      new openvdb::math::ScaleTranslateMap(openvdb::Vec3d(vs.x(), vs.y(), vs.z()), openvdb::Vec3d(origin.x(), origin.y(), origin.z())));
  return openvdb::math::Transform::Ptr(new openvdb::math::Transform(map));
}

}  // namespace

ExplorationGrid ExplorationGrid::from_labels(const Box3& box, const Vec3i& dims, const std::vector<uint8_t>& labels, float occupancy_alpha,
                                             ExplorationStats* stats) {
  const size_t nvox = size_t(dims.x()) * size_t(dims.y()) * size_t(dims.z());
  FILLGS_CHECK_EQ(labels.size(), nvox);
  openvdb::initialize();
  ExplorationGrid grid;
  grid.box_ = box;
  grid.dims_ = dims;
  grid.occupancy_alpha_ = occupancy_alpha;
  // Only the non-free voxels are stored.
  auto vdb = openvdb::Int32Grid::create(0);
  vdb->setName("labels");
  vdb->setTransform(index_to_world(box, dims));
  vdb->setGridClass(openvdb::GRID_UNKNOWN);
  size_t occupied = 0, unexplored = 0;
  {
    auto acc = vdb->getAccessor();
    size_t v = 0;
    for (int kz = 0; kz < dims.z(); ++kz)
      for (int jy = 0; jy < dims.y(); ++jy)
        for (int ix = 0; ix < dims.x(); ++ix, ++v) {
          const uint8_t l = labels[v];
          if (l == 1) ++occupied;
          if (l == 2) ++unexplored;
          if (l) acc.setValue(openvdb::Coord(ix, jy, kz), int(l));
        }
  }
  if (stats) {
    stats->occupied = occupied;
    stats->unexplored = unexplored;
    stats->free = nvox - occupied - unexplored;
  }
  vdb->insertMeta("fillgs_box_min", openvdb::Vec3DMetadata(openvdb::Vec3d(box.lo.x(), box.lo.y(), box.lo.z())));
  vdb->insertMeta("fillgs_box_max", openvdb::Vec3DMetadata(openvdb::Vec3d(box.hi.x(), box.hi.y(), box.hi.z())));
  vdb->insertMeta("fillgs_divisions", openvdb::Vec3IMetadata(openvdb::Vec3i(dims.x(), dims.y(), dims.z())));
  vdb->insertMeta("fillgs_labels", openvdb::StringMetadata("0 free (background), 1 occupied, 2 unexplored"));
  vdb->insertMeta("fillgs_occupancy_alpha", openvdb::FloatMetadata(occupancy_alpha));
  grid.impl_->grid = vdb;
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

namespace {

/// Walks the OpenVDB file's own layout — header, file metadata, grid descriptors and each
/// grid's metadata — checking every length and offset against the file's size before
/// OpenVDB trusts them: a damaged length there made OpenVDB allocate gigabytes or loop for
/// minutes. The voxel data itself is left to OpenVDB, which reports damage there itself.
void check_vdb_layout(const std::string& path) {
  const std::string b = read_file(path);
  size_t at = 0;
  auto need = [&](size_t n, const char* what) {
    if (n > b.size() - at) throw_error(path, ": damaged OpenVDB file (", what, " at byte ", at, " runs past the end of the file)");
  };
  auto i32 = [&](const char* what) {
    need(4, what);
    int32_t v;
    std::memcpy(&v, b.data() + at, 4);
    at += 4;
    if (v < 0) throw_error(path, ": damaged OpenVDB file (", what, " ", v, " at byte ", at - 4, ")");
    return size_t(v);
  };
  auto i64 = [&](const char* what) {
    need(8, what);
    int64_t v;
    std::memcpy(&v, b.data() + at, 8);
    at += 8;
    if (v < 0 || uint64_t(v) > b.size()) throw_error(path, ": damaged OpenVDB file (", what, " ", v, " at byte ", at - 8, ")");
    return size_t(v);
  };
  auto bytes = [&](size_t n, const char* what) {
    need(n, what);
    at += n;
  };
  auto text = [&](const char* what) { bytes(i32(what), what); };
  auto metadata = [&]() {
    const size_t n = i32("metadata count");
    for (size_t k = 0; k < n; ++k) {
      text("metadata name");
      text("metadata type");
      bytes(i32("metadata value size"), "metadata value");
    }
  };
  need(8 + 4 + 4 + 4 + 1 + 36, "the header");
  if (b.compare(0, 4, " BDV") != 0) throw_error(path, ": not an OpenVDB file");
  uint32_t version;
  std::memcpy(&version, b.data() + 8, 4);
  at = 8 + 4 + 4 + 4;
  const bool offsets = b[at] != 0;
  at += 1 + 36;  // the offsets flag, the UUID
  metadata();
  const size_t grids = i32("grid count");
  for (size_t g = 0; g < grids; ++g) {
    text("grid name");
    text("grid type");
    if (version >= 216) text("grid instance parent");
    if (!offsets) return;  // without offsets the grids follow inline: left to OpenVDB
    const size_t grid_at = i64("grid position"), block_at = i64("block position"), end_at = i64("end position");
    if (!(grid_at <= block_at && block_at <= end_at)) throw_error(path, ": damaged OpenVDB file (grid ", g, " offsets out of order)");
    const size_t next = end_at;
    at = grid_at;
    if (version >= 222) bytes(4, "compression flags");  // per-grid compression, from file version 222 on
    metadata();
    at = next;
  }
}

}  // namespace

ExplorationGrid ExplorationGrid::read(const std::string& path) {
  require_regular_file(path);
  check_vdb_layout(path);
  openvdb::initialize();
  // reading(): an allocation a damaged file provokes, or any library exception, becomes one
  // line naming the file.
  return reading(path, [&] {
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
      // Grids written before the alpha was recorded were built at the default.
      if ((*labels)["fillgs_occupancy_alpha"]) grid.occupancy_alpha_ = labels->metaValue<float>("fillgs_occupancy_alpha");
      if (!(grid.occupancy_alpha_ > 0.0f && grid.occupancy_alpha_ < 1.0f))
        throw_error(path, ": metadata fillgs_occupancy_alpha ", grid.occupancy_alpha_, " is not in (0, 1)");
      if ((grid.dims_.array() < 1).any() || (grid.dims_.array() > kMaxDivisions).any() || !((grid.box_.hi - grid.box_.lo).array() > 0).all() ||
          !grid.box_.lo.allFinite() || !grid.box_.hi.allFinite())
        throw_error(path, ": metadata fillgs_box_min/max or fillgs_divisions is invalid");
      grid.impl_->grid = labels;
    } catch (const openvdb::Exception& e) {
      throw_error(path, ": cannot read as an exploration grid (", e.what(), ")");
    }
    return grid;
  });
}

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
