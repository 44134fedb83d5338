// Spacetime Gaussians PLY: polynomial motion, linear rotation, temporal RBF opacity. Its
// 6/9-channel colour features have no SH meaning: the first three, activated, become the
// base colour; the colour MLP is not evaluated.
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


GaussianCloud read_spacetime(const std::string& path, const SceneReadOptions& opt) {
  const PlyData ply = read_ply(path);
  const PlyElement& v = ply.element("vertex");
  const size_t n = v.count;
  GaussianCloud c;
  c.sh_degree = 0;
  c.resize(n);
  const auto ids = iota_ids(n);
  read_base(v, c, ids);
  const size_t dc_count = v.indexed_properties("f_dc_").size();
  if (dc_count < 3) throw_error(path, ": Spacetime Gaussians file has ", dc_count, " 'f_dc_*' properties, need at least 3");
  std::string act = opt.stg_color_activation;
  if (act == "auto") act = dc_count >= 6 ? "sigmoid" : "none";
  if (act != "sigmoid" && act != "clamp" && act != "none")
    throw_error("unknown Spacetime colour activation '", act, "' (expected auto, sigmoid, clamp or none)");
  for (int ch = 0; ch < 3; ++ch) {
    const auto& f = v.finite_column("f_dc_" + std::to_string(ch));
    for (size_t r = 0; r < n; ++r) {
      float rgb = f[r];
      if (act == "sigmoid") rgb = sigmoid(rgb);
      else if (act == "clamp") rgb = std::clamp(rgb, 0.0f, 1.0f);
      c.sh[r * 3 + ch] = rgb_to_sh_dc(rgb);
    }
  }
  c.notes.push_back("Spacetime Gaussians colour: base colour " + act + "(f_dc_0..2); the " + std::to_string(dc_count) +
                    "-channel features and the colour MLP are not evaluated (view- and time-independent colour)");
  if (dc_count >= 6 && v.has("f_t_0")) c.notes.push_back("Spacetime Gaussians f_t_* time features ignored");
  c.motion = MotionModel::Polynomial;
  c.dynamic_ids = iota_ids(n);
  PolynomialMotion& p = c.polynomial;
  p.time_scale = opt.stg_duration > 0 ? double(opt.stg_duration - 1) / opt.stg_duration : 1.0;
  p.coeffs.resize(9 * n);
  for (int k = 0; k < 9; ++k) {
    const auto& m = v.finite_column("motion_" + std::to_string(k));
    for (size_t r = 0; r < n; ++r) p.coeffs[9 * r + k] = m[r];
  }
  p.omega.resize(4 * n);
  for (int k = 0; k < 4; ++k) {
    const auto& w = v.finite_column("omega_" + std::to_string(k));
    for (size_t r = 0; r < n; ++r) p.omega[4 * r + k] = w[r];
  }
  p.trbf_center = v.finite_column("trbf_center");
  p.trbf_log_scale = v.finite_column("trbf_scale");
  return c;
}

}  // namespace

const ModelFormat& row_spacetime() {
  static const ModelFormat row{"stg", {"spacetime"}, "Spacetime Gaussians PLY (trbf_center, motion_*, omega_*)", 71,
      [](const FormatProbe& p) { return p.ply_header().find(" trbf_center\n") != std::string::npos; }, nullptr, false, read_spacetime};
  return row;
}

}  // namespace fillgs::model_io
