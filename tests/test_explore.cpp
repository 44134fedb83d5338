// Exploration grid: labels on analytic scenes against a brute-force reference, sampling,
// free-segment queries, the OpenVDB file, bad input.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cstdlib>
#include <fstream>
#include <random>

#include "fillgs/base/error.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/base/fs_util.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

namespace {

/// 8 cameras on a circle of radius 4 in the z = 0 plane, looking at the origin, z up.
std::vector<Camera> ring(int n = 8, double radius = 4.0) {
  RingPlacement r;
  r.count = n;
  r.radius = radius;
  return camera_ring(r, axis_camera(64, 48, 40));
}

/// ring() plus a camera at (4, 0, 3) looking away from the scene: the box stretches upwards,
/// where no camera sees, so the grid has unexplored voxels as well as occupied ones.
std::vector<Camera> ring_and_high() {
  std::vector<Camera> cams = ring();
  Camera high = cams[0];
  high.look_at(Vec3d(4, 0, 3), Vec3d(8, 0, 3), Vec3d::UnitZ());
  cams.push_back(high);
  return cams;
}

/// Six cameras on the axes at distance d looking at the origin: a cubic box, cubic voxels.
std::vector<Camera> six_cameras(double d) {
  std::vector<Camera> six;
  for (int axis = 0; axis < 3; ++axis)
    for (double sign : {1.0, -1.0}) {
      Camera cam = axis_camera(32, 32, 20);
      cam.look_at(sign * d * Vec3d::Unit(axis), Vec3d::Zero(), axis == 2 ? Vec3d::UnitX() : Vec3d::UnitZ());
      six.push_back(cam);
    }
  return six;
}

/// Isotropic opaque Gaussians of scale s on a lattice filling [-half, half]^3.
GaussianCloud lattice_box(double half, int per_axis, float s, float opacity) {
  GaussianCloud c;
  for (int i = 0; i < per_axis; ++i)
    for (int j = 0; j < per_axis; ++j)
      for (int k = 0; k < per_axis; ++k) {
        const auto at = [&](int n) { return float(-half + 2 * half * n / (per_axis - 1)); };
        add_gaussian(c, Vec3f(at(i), at(j), at(k)), s, logit(opacity), Vec3f(0.5f, 0.5f, 0.5f));
      }
  return c;
}

}  // namespace

TEST_CASE("exploration grid: the occupied voxels of a box of Gaussians are exactly the brute-force ones", "[explore]") {
  const float s = 0.05f, opacity = 0.9f;
  const GaussianCloud box = lattice_box(0.5, 6, s, opacity);
  ExplorationOptions o;
  o.divisions = 64;  // voxels (0.066) finer than the Gaussians' reach (0.16): the boundary matters
  o.bounds_quantile = 0.0;
  ExplorationStats stats;
  const ExplorationGrid g = build_exploration_grid(box, six_cameras(2.0), {}, o, &stats);
  // Reference: every voxel centre within k·s + ½·diagonal of some mean, k = √(2 ln(o / α_occ)).
  const double k = std::sqrt(2.0 * std::log(double(opacity) / double(o.occupancy_alpha)));
  const double reach = k * s + 0.5 * g.voxel_size().norm();
  size_t expected = 0, mismatched = 0;
  for (int z = 0; z < g.dims().z(); ++z)
    for (int y = 0; y < g.dims().y(); ++y)
      for (int x = 0; x < g.dims().x(); ++x) {
        const Vec3d c = g.voxel_centre(Vec3i(x, y, z));
        bool occ = false;
        for (size_t n = 0; n < box.size() && !occ; ++n) occ = (c - box.means[n].cast<double>()).norm() <= reach;
        expected += occ;
        mismatched += occ != (g.label(Vec3i(x, y, z)) == VoxelLabel::Occupied);
      }
  CHECK(mismatched == 0);
  CHECK(stats.occupied == expected);
  CHECK(stats.occupied_by_static == expected);
  CHECK(g.counts()[1] == expected);
  CHECK(expected > 100);
  // The box's own inside is solid at this density (lattice spacing 0.2 < 2·reach).
  for (double x = -0.45; x <= 0.45; x += 0.15) CHECK(g.label_at(Vec3d(x, 0.1, -0.2)) == VoxelLabel::Occupied);
}

TEST_CASE("exploration grid: a tiny Gaussian at a voxel centre occupies that voxel alone, transparent ones none", "[explore]") {
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 0), 1e-5f, logit(0.999f), Vec3f(1, 1, 1));
  add_gaussian(c, Vec3f(0.3f, 0.3f, 0.3f), 0.2f, logit(0.05f), Vec3f(1, 1, 1));  // under α_occ everywhere
  ExplorationOptions o;
  o.divisions = 21;  // the box [-1, 1]^3 is symmetric about 0 → the origin is a voxel centre
  o.bounds_quantile = 0.0;
  o.margin = 0.0;
  // Cubic voxels: half the diagonal is shorter than one voxel.
  const ExplorationGrid g = build_exploration_grid(c, six_cameras(1.0), {}, o);
  const Vec3i centre = g.voxel_of(Vec3d::Zero());
  CHECK((g.voxel_centre(centre) - Vec3d::Zero()).norm() < 1e-9);
  CHECK(g.counts()[1] == 1);
  CHECK(g.label(centre) == VoxelLabel::Occupied);
}

TEST_CASE("exploration grid: sampling never lands inside the box, and lands only in free voxels", "[explore]") {
  const GaussianCloud box = lattice_box(0.5, 6, 0.05f, 0.9f);
  const ExplorationGrid g = build_exploration_grid(box, ring(), {});
  std::mt19937_64 rng(7);
  Box3 all = g.box();
  const std::vector<Vec3d> pts = g.sample_free(all, 5000, rng);
  REQUIRE(pts.size() == 5000);
  size_t inside = 0, not_free = 0;
  for (const Vec3d& p : pts) {
    inside += (p.cwiseAbs().array() <= 0.5).all();
    not_free += !g.is_free(p);
  }
  CHECK(inside == 0);
  CHECK(not_free == 0);
  // A box around the Gaussians holds no free voxel: nothing to sample.
  CHECK(g.sample_free(Box3{Vec3d::Constant(-0.3), Vec3d::Constant(0.3)}, 5, rng).empty());
  // Same seed, same points.
  std::mt19937_64 a(3), b(3);
  CHECK(g.sample_free(all, 10, a) == g.sample_free(all, 10, b));
}

TEST_CASE("exploration grid: free-segment queries on both sides of a wall", "[explore]") {
  // A wall: the plane x = 0, |y|, |z| <= 1, of flat Gaussians.
  GaussianCloud wall;
  for (int j = -10; j <= 10; ++j)
    for (int k = -10; k <= 10; ++k) add_gaussian(wall, Vec3f(0, 0.1f * j, 0.1f * k), 0.06f, logit(0.95f), Vec3f(1, 1, 1));
  for (Vec3f& s : wall.log_scales) s.x() = std::log(0.005f);
  ExplorationOptions o;
  o.divisions = 48;
  const ExplorationGrid g = build_exploration_grid(wall, ring(), {}, o);
  const double v = g.voxel_size().maxCoeff();
  CHECK(g.segment_free(Vec3d(-1.5, 0.2, 0.1), Vec3d(-3 * v, -0.3, 0.2)));    // stays on the −x side
  CHECK(g.segment_free(Vec3d(3 * v, 0.2, 0.1), Vec3d(1.5, -0.5, 0.3)));      // stays on the +x side
  CHECK_FALSE(g.segment_free(Vec3d(-1.5, 0.2, 0.1), Vec3d(1.5, 0.2, 0.1)));  // crosses it
  CHECK_FALSE(g.segment_free(Vec3d(-0.5, 0.0, 0.0), Vec3d(0.5, 0.9, -0.9))); // crosses it obliquely
  CHECK(g.segment_free(Vec3d(-1.0, 1.5, 0.0), Vec3d(1.0, 1.5, 0.0)));        // passes beside it
  CHECK(g.segment_free(Vec3d(-1.0, 0.5, 0.0), Vec3d(-1.0, 0.5, 0.0)));       // a point in free space
  CHECK_FALSE(g.is_free(Vec3d(0, 0.5, 0.5)));
  CHECK_FALSE(g.segment_free(Vec3d(-1.0, 0.0, 0.0), g.box().hi + Vec3d::Constant(1.0)));  // leaves the grid
}

TEST_CASE("exploration grid: moving Gaussians occupy what they sweep and unexplored is outside every frustum", "[explore]") {
  GaussianCloud c;
  add_gaussian(c, Vec3f(-1, 0, 0), 0.02f, logit(0.99f), Vec3f(1, 1, 1));
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = {0};
  c.keyframed = per_frame_tracks(1, 11);
  for (int f = 0; f < 11; ++f) {
    c.keyframed.positions[size_t(3 * f)] = -1.0f + 0.2f * f;
    if (!c.keyframed.rotations.empty()) c.keyframed.rotations[size_t(4 * f)] = 1.0f;
  }
  ExplorationOptions o;
  o.divisions = 64;
  ExplorationStats stats;
  std::vector<Camera> cams = ring();
  Camera high = cams[0];  // at (4, 0, 3) looking away from the scene: stretches the box upwards
  high.look_at(Vec3d(4, 0, 3), Vec3d(8, 0, 3), Vec3d::UnitZ());
  cams.push_back(high);
  const ExplorationGrid g = build_exploration_grid(c, cams, {}, o, &stats);
  CHECK(stats.occupied_by_static == 0);
  CHECK(stats.time_samples == 11);
  for (int f = 0; f < 11; ++f) CHECK(g.label_at(Vec3d(-1.0 + 0.2 * f, 0, 0)) == VoxelLabel::Occupied);
  CHECK(g.label_at(Vec3d(0, 1.0, 0)) == VoxelLabel::Free);
  // The ring looks horizontally with a ±31° vertical field and the high camera looks away:
  // far above the origin nothing is seen.
  CHECK(g.box().hi.z() > 3.0);
  CHECK(g.label_at(Vec3d(0, 0, g.box().hi.z() - 0.01)) == VoxelLabel::Unexplored);
  CHECK(stats.unexplored > 0);
}

TEST_CASE("exploration grid: the .vdb file opens in OpenVDB and reads back to the same labels", "[explore]") {
  const GaussianCloud box = lattice_box(0.5, 4, 0.08f, 0.9f);
  ExplorationOptions o;
  o.divisions = 24;
  const ExplorationGrid g = build_exploration_grid(box, ring_and_high(), {}, o);
  const std::string dir = scratch("explore_vdb"), path = join_path(dir, "exploration.vdb");
  g.write(path);
  // Plain OpenVDB, no fillgs: BoolGrids "occupied" and "unexplored", active where the label is.
  openvdb::initialize();
  openvdb::io::File file(path);
  file.open();
  auto occupied = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("occupied"));
  auto unexplored = openvdb::gridPtrCast<openvdb::BoolGrid>(file.readGrid("unexplored"));
  file.close();
  REQUIRE(occupied);
  REQUIRE(unexplored);
  CHECK(occupied->activeVoxelCount() == openvdb::Index64(g.counts()[1]));
  CHECK(unexplored->activeVoxelCount() == openvdb::Index64(g.counts()[2]));
  CHECK(occupied->activeVoxelCount() > 0);
  CHECK(unexplored->activeVoxelCount() > 0);
  size_t wrong = 0;
  for (auto it = occupied->cbeginValueOn(); it; ++it)
    wrong += g.label(Vec3i(it.getCoord().x(), it.getCoord().y(), it.getCoord().z())) != VoxelLabel::Occupied;
  CHECK(wrong == 0);
  const Vec3d world = g.voxel_centre(Vec3i(3, 5, 7));
  const openvdb::Vec3d idx = unexplored->transform().worldToIndex(openvdb::Vec3d(world.x(), world.y(), world.z()));
  CHECK(idx.x() == Approx(3).margin(1e-9));
  CHECK(idx.y() == Approx(5).margin(1e-9));
  CHECK(idx.z() == Approx(7).margin(1e-9));
  CHECK(unexplored->metaValue<openvdb::Vec3i>("fillgs_divisions") == openvdb::Vec3i(24, 24, 24));

  const ExplorationGrid r = ExplorationGrid::read(path);
  CHECK(r.dims() == g.dims());
  CHECK((r.box().lo - g.box().lo).norm() == 0.0);
  size_t differ = 0;
  for (int z = 0; z < g.dims().z(); ++z)
    for (int y = 0; y < g.dims().y(); ++y)
      for (int x = 0; x < g.dims().x(); ++x) differ += r.label(Vec3i(x, y, z)) != g.label(Vec3i(x, y, z));
  CHECK(differ == 0);

  // Not a VDB file: one clear error naming it.
  const std::string bad = join_path(dir, "bad.vdb");
  std::ofstream(bad) << "not a vdb";
  try {
    ExplorationGrid::read(bad);
    FAIL("read accepted a text file");
  } catch (const Error& e) {
    CHECK(std::string(e.what()).find(bad) != std::string::npos);
  }
}

TEST_CASE("exploration grid: files of the first layout (one Int32Grid 'labels') still read", "[explore]") {
  const GaussianCloud box = lattice_box(0.5, 4, 0.08f, 0.9f);
  ExplorationOptions o;
  o.divisions = 12;
  const ExplorationGrid g = build_exploration_grid(box, ring_and_high(), {}, o);
  // The first layout, written here with plain OpenVDB: labels 1 occupied, 2 unexplored.
  openvdb::initialize();
  auto labels = openvdb::Int32Grid::create(0);
  labels->setName("labels");
  const Vec3d vs = g.voxel_size(), origin = g.box().lo + 0.5 * vs;
  labels->setTransform(openvdb::math::Transform::Ptr(new openvdb::math::Transform(openvdb::math::MapBase::Ptr(
      new openvdb::math::ScaleTranslateMap(openvdb::Vec3d(vs.x(), vs.y(), vs.z()), openvdb::Vec3d(origin.x(), origin.y(), origin.z()))))));
  labels->insertMeta("fillgs_box_min", openvdb::Vec3DMetadata(openvdb::Vec3d(g.box().lo.x(), g.box().lo.y(), g.box().lo.z())));
  labels->insertMeta("fillgs_box_max", openvdb::Vec3DMetadata(openvdb::Vec3d(g.box().hi.x(), g.box().hi.y(), g.box().hi.z())));
  labels->insertMeta("fillgs_divisions", openvdb::Vec3IMetadata(openvdb::Vec3i(12, 12, 12)));
  auto acc = labels->getAccessor();
  for (int z = 0; z < 12; ++z)
    for (int y = 0; y < 12; ++y)
      for (int x = 0; x < 12; ++x)
        if (const int l = int(g.label(Vec3i(x, y, z)))) acc.setValue(openvdb::Coord(x, y, z), l);
  const std::string dir = scratch("explore_vdb_v1"), path = join_path(dir, "old.vdb");
  {
    openvdb::io::File file(path);
    file.write({labels});
    file.close();
  }
  const ExplorationGrid r = ExplorationGrid::read(path);
  CHECK(r.dims() == g.dims());
  CHECK(r.counts() == g.counts());
  size_t differ = 0;
  for (int z = 0; z < 12; ++z)
    for (int y = 0; y < 12; ++y)
      for (int x = 0; x < 12; ++x) differ += r.label(Vec3i(x, y, z)) != g.label(Vec3i(x, y, z));
  CHECK(differ == 0);
}

TEST_CASE("exploration grid: the .vdb file opens in the OpenVDB Python binding (python3-openvdb)", "[explore]") {
  if (std::system("/usr/bin/python3 -c 'import pyopenvdb' >/dev/null 2>&1") != 0) {
    WARN("skipped: /usr/bin/python3 cannot import pyopenvdb (Debian python3-openvdb; scripts/install-deps.sh installs it)");
    return;
  }
  const GaussianCloud box = lattice_box(0.5, 4, 0.08f, 0.9f);
  ExplorationOptions o;
  o.divisions = 20;
  const ExplorationGrid g = build_exploration_grid(box, ring_and_high(), {}, o);
  const std::string dir = scratch("explore_pyvdb"), path = join_path(dir, "exploration.vdb"), out = join_path(dir, "py.txt");
  g.write(path);
  // What a user's script does: read every grid, count its voxels, map an index to the world.
  const std::string script = join_path(dir, "read.py");
  std::ofstream(script) << "import sys, pyopenvdb as vdb\n"
                           "grids = {g.name: g for g in vdb.readAll(sys.argv[1])[0]}\n"
                           "out = open(sys.argv[2], 'w')\n"
                           "for name in ('occupied', 'unexplored'):\n"
                           "    g = grids[name]\n"
                           "    out.write('%s %s %d\\n' % (name, g.valueTypeName, g.activeVoxelCount()))\n"
                           "    w = g.transform.indexToWorld((3, 5, 7))\n"
                           "    out.write('%.12g %.12g %.12g\\n' % tuple(w))\n"
                           "    out.write('%d %d %d\\n' % tuple(g['fillgs_divisions']))\n";
  REQUIRE(std::system(("/usr/bin/python3 " + script + " " + path + " " + out).c_str()) == 0);
  std::ifstream in(out);
  const Vec3d centre = g.voxel_centre(Vec3i(3, 5, 7));
  for (const VoxelLabel label : {VoxelLabel::Occupied, VoxelLabel::Unexplored}) {
    std::string name, type;
    long long count = -1;
    Vec3d w;
    int dx = 0, dy = 0, dz = 0;
    in >> name >> type >> count >> w.x() >> w.y() >> w.z() >> dx >> dy >> dz;
    REQUIRE(in);
    CHECK(name == to_string(label));
    CHECK(type == "bool");
    CHECK(count == (long long)g.counts()[size_t(label)]);
    CHECK((w - centre).norm() < 1e-9);
    CHECK((Vec3i(dx, dy, dz) == g.dims()));
  }
}
