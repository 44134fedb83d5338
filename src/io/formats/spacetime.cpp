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


// Spacetime Gaussians' own parameters.
const RowParameter& stg_duration_parameter() {
  static const RowParameter p = RowParameter::integer("stg_duration", 50, within(1, 1000000), "Spacetime Gaussians: frames one model covers (its configs use 50)");
  return p;
}
const RowParameter& stg_colour_parameter() {
  static const RowParameter p = RowParameter::choice("stg_color", "auto", {"auto", "sigmoid", "clamp", "none"},
                                                     "Spacetime Gaussians colour activation of f_dc_0..2 (auto: sigmoid for the full model, none for the lite one)");
  return p;
}

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
  std::string act = opt.parameters.text(stg_colour_parameter());  // one of its declared choices
  if (act == "auto") act = dc_count >= 6 ? "sigmoid" : "none";
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
  const double frames = double(opt.parameters.integer(stg_duration_parameter()));
  p.time_scale = (frames - 1) / frames;
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
  static const ModelFormat row{{"stg", {"spacetime"}, "Spacetime Gaussians PLY (trbf_center, motion_*, omega_*)", 71, {&stg_duration_parameter(), &stg_colour_parameter()}},
      [](const FormatProbe& p) { return p.ply_header().find(" trbf_center\n") != std::string::npos; }, nullptr, false, read_spacetime};
  return row;
}

}  // namespace fillgs::model_io
