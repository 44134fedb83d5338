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

/// Throws one line if `ply` is the canonical PLY of a deformation model (embedding_*
/// properties, or deformation.pth / deform/ beside it), saying what to pass instead.
void refuse_canonical_ply(const std::string& ply, const std::string& header) {
  std::error_code ec;
  const fs::path dir = fs::path(ply).parent_path();
  const bool embeddings = header.find(" embedding_0\n") != std::string::npos;
  const bool deformation = fs::exists(dir / "deformation.pth", ec);
  const bool deform_dir = fs::is_directory(dir.parent_path().parent_path() / "deform", ec) || fs::is_directory(dir / "deform", ec);
  if (!embeddings && !deformation && !deform_dir) return;
  const std::string what = embeddings ? "the canonical point cloud of an E-D3DGS model (it has embedding_* properties)"
                           : deformation ? "the canonical point cloud of a deformation model (deformation.pth lies beside it)"
                                         : "the canonical point cloud of a Deformable 3D Gaussians model (a deform/ folder lies beside it)";
  const std::string instead = deform_dir && !deformation && !embeddings
                                  ? "pass the training run's folder (the one holding deform/ and point_cloud/) instead"
                                  : "pass the folder " + (dir.empty() ? std::string(".") : dir.string()) + " (or the training run's folder) instead";
  throw_error(ply, ": ", what, ", which is no frame of the video: fillgs will not read it as a static scene; ", instead);
}


GaussianCloud read_3dgs(const std::string& path, const SceneReadOptions&) {
  refuse_canonical_ply(path, read_ply_header(path));
  return read_standard_vertex(read_ply(path).element("vertex"));
}

}  // namespace

const ModelFormat& row_gaussian3d() {
  static const ModelFormat row{"3dgs", {}, "3D Gaussian Splatting PLY (a static scene; any PLY of Gaussians the other formats do not claim)", 100,
      [](const FormatProbe& p) { return !p.ply_header().empty(); }, nullptr, false, read_3dgs};
  return row;
}

}  // namespace fillgs::model_io
