// Ex4DGS: a keyframed pair, point_cloud.ply (static Gaussians, some with a linear
// displacement) and dynamic_point_cloud.ply (keyframes of position and rotation, temporal
// opacity), with cfg_args (duration, time interval, padding, interpolation).
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

/// Where the Ex4DGS pair lives: (static ply, dynamic ply), or empty strings.
std::pair<std::string, std::string> ex4dgs_pair(const std::string& path) {
  fs::path p(path);
  std::error_code ec;
  if (fs::is_directory(p, ec)) {
    if (fs::exists(p / "dynamic_point_cloud.ply", ec)) return {(p / "point_cloud.ply").string(), (p / "dynamic_point_cloud.ply").string()};
    return {};
  }
  const fs::path dir = p.parent_path();
  if (p.filename() == "point_cloud.ply" && fs::exists(dir / "dynamic_point_cloud.ply", ec))
    return {p.string(), (dir / "dynamic_point_cloud.ply").string()};
  if (p.filename() == "dynamic_point_cloud.ply") return {(dir / "point_cloud.ply").string(), p.string()};
  return {};
}

struct Ex4dgsConfig {
  int duration = -1, interval = 5, pad = 3;
  double var_pad = 3.0;
  std::string interp = "cube";
  std::string source = "defaults";
};

Ex4dgsConfig read_ex4dgs_config(const std::string& static_ply) {
  Ex4dgsConfig cfg;
  fs::path dir = fs::path(static_ply).parent_path();
  for (int up = 0; up < 4 && !dir.empty(); ++up, dir = dir.parent_path()) {
    std::error_code ec;
    const fs::path f = dir / "cfg_args";
    if (!fs::exists(f, ec)) continue;
    const std::string text = read_file(f.string());
    const std::string source = f.string();
    // cfg_args is a Python Namespace repr: "Namespace(duration=300, ..., interp_type='cube')".
    // Scanned by hand (no regex on a file of any length); a value is what follows "key=" up
    // to the next ',' or ')'.
    auto value = [&](const char* key, std::string* out) {
      const std::string k = std::string(key) + "=";
      for (size_t at = text.find(k); at != std::string::npos; at = text.find(k, at + 1)) {
        const char before = at ? text[at - 1] : ' ';
        if (std::isalnum(static_cast<unsigned char>(before)) || before == '_') continue;
        const size_t from = at + k.size();
        size_t end = text.find_first_of(",)", from);
        if (end == std::string::npos) end = text.size();
        *out = text.substr(from, end - from);
        return true;
      }
      return false;
    };
    auto integer = [&](const char* key, int* out, int lo, int hi) {
      std::string v;
      if (!value(key, &v)) return;
      const double x = parse_number(v, source, std::string("cfg_args ") + key);
      if (x != std::floor(x) || x < lo || x > hi)
        throw_error(source, ": cfg_args ", key, " = ", x, " is not an integer in [", lo, ", ", hi, "]");
      *out = int(x);
    };
    integer("duration", &cfg.duration, 2, 1000000);
    integer("time_interval", &cfg.interval, 1, 1000000);
    integer("time_pad", &cfg.pad, 0, 1000000);
    std::string v;
    if (value("var_pad", &v)) cfg.var_pad = parse_number(v, source, "cfg_args var_pad");
    if (value("interp_type", &v)) {
      const size_t b = v.find_first_of("'\""), e = v.find_last_of("'\"");
      cfg.interp = (b != std::string::npos && e > b) ? v.substr(b + 1, e - b - 1) : v;
      // What fillgs evaluates; any other name would silently become cubic keys.
      if (cfg.interp != "cube" && cfg.interp != "linear" && cfg.interp != "pchip")
        throw_error(source, ": interp_type '", cfg.interp.substr(0, 40), "' is not one fillgs evaluates (cube, linear, pchip)");
    }
    cfg.source = f.string();
    break;
  }
  return cfg;
}

// Ex4DGS's own parameters: overrides of its cfg_args.
const RowParameter& ex4dgs_duration_parameter() {
  static const RowParameter p = [] {
    RowParameter q = RowParameter::integer("ex4dgs_duration", 0, within(0, 1000000), "Ex4DGS: frames the model covers (0: from cfg_args)");
    q.flag_aliases = {"--duration"};
    return q;
  }();
  return p;
}
const RowParameter& ex4dgs_interval_parameter() {
  static const RowParameter p = RowParameter::integer("ex4dgs_interval", 0, within(0, 1000000), "Ex4DGS: frames between its keys (0: cfg_args' time_interval)");
  return p;
}
const RowParameter& ex4dgs_pad_parameter() {
  static const RowParameter p = RowParameter::integer("ex4dgs_pad", -1, within(-1, 1000000), "Ex4DGS: keys padded at either end (-1: cfg_args' time_pad)");
  return p;
}

GaussianCloud read_ex4dgs(const std::string& static_path, const std::string& dynamic_path, const SceneReadOptions& opt) {
  Ex4dgsConfig cfg = read_ex4dgs_config(static_path);
  // 0 / -1: cfg_args' value. A duration of 1 is refused below as an unknown one.
  if (const long long d = opt.parameters.integer(ex4dgs_duration_parameter()); d > 0) cfg.duration = int(d);
  if (const long long i = opt.parameters.integer(ex4dgs_interval_parameter()); i > 0) cfg.interval = int(i);
  if (const long long k = opt.parameters.integer(ex4dgs_pad_parameter()); k >= 0) cfg.pad = int(k);
  if (cfg.duration < 2)
    throw_error(static_path, ": Ex4DGS duration unknown (", cfg.source, " has none): give the duration in frames (--ex4dgs-duration)");
  if (cfg.interval < 1) throw_error(cfg.source, ": time_interval must be positive");
  const int D = cfg.duration, I = cfg.interval, P = cfg.pad;
  const int S = (cfg.interp == "linear") ? P : P + I;

  const PlyData sply = read_ply(static_path);
  const PlyData dply = read_ply(dynamic_path);
  const PlyElement& sv = sply.element("vertex");
  const PlyElement& dv = dply.element("vertex");
  const size_t ns = sv.count, nd = dv.count;
  // Every key k < K has three columns, so K is bounded by the property count: an index
  // beyond it names a column that cannot exist, whatever the file says.
  int K = 0;
  const std::string prefix = "motion_xyz_";
  for (const std::string& name : dv.property_names) {
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const size_t us = name.find('_', prefix.size());
    if (us == std::string::npos) continue;
    const std::string digits = name.substr(prefix.size(), us - prefix.size());
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const long k = digits.size() > 9 ? 1000000000L : std::strtol(digits.c_str(), nullptr, 10);
    if (size_t(k) >= dv.property_names.size() / 3)
      throw_error(dynamic_path, ": property '", name, "' names keyframe ", digits, ", but the vertex element has only ",
                  dv.property_names.size(), " properties (3 per keyframe)");
    K = std::max(K, int(k) + 1);
  }
  if (K < 2 && nd > 0) throw_error(dynamic_path, ": no 'motion_xyz_{k}_{j}' keyframe properties");
  GaussianCloud c;
  c.sh_degree = sh_degree_of(sv, "f_rest_");
  c.resize(ns + nd);
  const auto sids = iota_ids(ns), dids = iota_ids(nd, uint32_t(ns));
  read_base(sv, c, sids);
  read_sh(sv, "f_dc_", "f_rest_", c, sids);
  read_base(dv, c, dids, "motion_");
  read_sh(dv, "motion_f_dc_", "motion_f_rest_", c, dids);

  // Keyframe count from the file: the largest k in motion_xyz_{k}_{j} plus one.

  KeyframedMotion& km = c.keyframed;
  km.key_count = K;
  km.first_key_time = -double(S) / (D - 1);
  km.key_spacing = double(I) / (D - 1);
  km.position_interp = cfg.interp == "linear" ? KeyInterp::Linear : cfg.interp == "pchip" ? KeyInterp::Pchip : KeyInterp::CatmullRom;
  km.ex4dgs_edges = true;
  km.temporal_width_pad = cfg.var_pad / (2.36 * I);

  // Static Gaussians with a displacement move linearly: mean = xyz + xyz_disp * frame / D.
  std::vector<uint32_t> moving_static;
  std::vector<Vec3f> disp;
  if (sv.has("xyz_disp_0")) {
    const auto& d0 = sv.finite_column("xyz_disp_0");
    const auto& d1 = sv.finite_column("xyz_disp_1");
    const auto& d2 = sv.finite_column("xyz_disp_2");
    for (size_t r = 0; r < ns; ++r) {
      const Vec3f d(d0[r], d1[r], d2[r]);
      const float speed = d.norm() * float(D - 1) / float(D);  // per unit normalised time
      if (speed > opt.partition.static_speed_threshold) {
        moving_static.push_back(uint32_t(r));
        disp.push_back(d);
      } else {
        c.means[r] += d * (0.5f * float(D - 1) / float(D));  // frozen at mid-sequence
      }
    }
  }
  const size_t M = moving_static.size() + nd;
  km.positions.assign(M * K * 3, 0.0f);
  km.rotations.assign(M * K * 4, 0.0f);
  km.temporal_opacity.assign(M * 4, 0.0f);
  size_t j = 0;
  for (size_t i = 0; i < moving_static.size(); ++i, ++j) {
    const uint32_t g = moving_static[i];
    c.dynamic_ids.push_back(g);
    for (int k = 0; k < K; ++k) {
      const float frame = float(k * I - S);
      const Vec3f p = c.means[g] + disp[i] * frame / float(D);
      for (int a = 0; a < 3; ++a) km.positions[(j * K + k) * 3 + a] = p[a];
      for (int a = 0; a < 4; ++a) km.rotations[(j * K + k) * 4 + a] = c.rotations[g][a];
    }
    // Centres at -inf and +inf: every time lies strictly between them, so the factor is 1.
    km.temporal_opacity[4 * j + 0] = -1e30f;
    km.temporal_opacity[4 * j + 1] = 1e30f;
  }
  for (int k = 0; k < K; ++k)
    for (int a = 0; a < 3; ++a) {
      const auto& col = dv.finite_column("motion_xyz_" + std::to_string(k) + "_" + std::to_string(a));
      for (size_t r = 0; r < nd; ++r) km.positions[((j + r) * K + k) * 3 + a] = col[r];
    }
  for (int k = 0; k < K; ++k)
    for (int a = 0; a < 4; ++a) {
      const auto& col = dv.finite_column("motion_rot_" + std::to_string(k) + "_" + std::to_string(a));
      for (size_t r = 0; r < nd; ++r) km.rotations[((j + r) * K + k) * 4 + a] = col[r];
    }
  const char* tnames[4] = {"motion_opacity_c_0", "motion_opacity_c_1", "motion_opacity_v_0", "motion_opacity_v_1"};
  for (int a = 0; a < 4; ++a) {
    const auto& col = dv.finite_column(tnames[a]);
    for (size_t r = 0; r < nd; ++r) km.temporal_opacity[4 * (j + r) + a] = col[r];
  }
  for (size_t r = 0; r < nd; ++r) {
    c.dynamic_ids.push_back(uint32_t(ns + r));
    // Canonical mean and rotation of a dynamic Gaussian: its state at t = 0.
    c.means[ns + r] = Vec3f(km.positions[((j + r) * K) * 3], km.positions[((j + r) * K) * 3 + 1], km.positions[((j + r) * K) * 3 + 2]);
    for (int a = 0; a < 4; ++a) c.rotations[ns + r][a] = km.rotations[((j + r) * K) * 4 + a];
  }
  FILLGS_CHECK(std::is_sorted(c.dynamic_ids.begin(), c.dynamic_ids.end()));  // moving static ids precede ns
  c.motion = c.dynamic_ids.empty() ? MotionModel::Static : MotionModel::Keyframed;
  c.notes.push_back("Ex4DGS: duration " + std::to_string(D) + ", interval " + std::to_string(I) + ", pad " + std::to_string(P) +
                    ", interp " + cfg.interp + " (from " + cfg.source + "); rendered with the standard 3DGS rasterizer "
                    "(0.3 dilation), not Ex4DGS's 0.1 kernel with opacity compensation; static rotations normalised");
  return c;
}

// ---- fillgs 4D PLY ----

GaussianCloud read_ex4dgs_pair(const std::string& path, const SceneReadOptions& options) {
  auto [s, d] = ex4dgs_pair(path);
  if (s.empty()) throw_error(path, ": Ex4DGS needs point_cloud.ply and dynamic_point_cloud.ply side by side");
  return read_ex4dgs(s, d, options);
}

}  // namespace

const ModelFormat& row_ex4dgs() {
  static const ModelFormat row{{"ex4dgs", {}, "Ex4DGS: point_cloud.ply and dynamic_point_cloud.ply side by side (either file, or their folder), cfg_args", 10,
                                {&ex4dgs_duration_parameter(), &ex4dgs_interval_parameter(), &ex4dgs_pad_parameter()}},
      [](const FormatProbe& p) { return !ex4dgs_pair(p.path()).first.empty(); }, nullptr, false, read_ex4dgs_pair};
  return row;
}

}  // namespace fillgs::model_io
