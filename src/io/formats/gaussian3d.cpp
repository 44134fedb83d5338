// The standard 3DGS PLY (any property order; binary LE/BE or ASCII; SH degree 0..3): a
// static scene. The canonical cloud of a deformation model is refused, not read as one.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/model/sh.hpp"
#include "io/ply_gaussians.hpp"

namespace fs = std::filesystem;

namespace fillgs::model_io {

namespace {

GaussianCloud read_3dgs(const std::string& path, const SceneReadOptions&) {
  refuse_canonical_ply(path, read_ply_header(path));
  // The vertex rows go into the cloud a block at a time: the file's columns are never held.
  GaussianCloud c;
  size_t saturated = 0;
  const PlyData ply = read_ply(path, {standard_vertex_sink(c, saturated)});
  (void)ply.element("vertex");  // no vertex element: one line naming the file
  note_saturated(c, saturated, path);
  return c;
}

}  // namespace

const ModelFormat& row_gaussian3d() {
  static const ModelFormat row{{"3dgs", {}, "3D Gaussian Splatting PLY (a static scene; any PLY of Gaussians the other formats do not claim)", 100, {}},
      [](const FormatProbe& p) { return !p.ply_header().empty(); }, nullptr, false, read_3dgs};
  return row;
}

}  // namespace fillgs::model_io
