#include "fillgs/io/scene_io.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/trained_models.hpp"
#include "fillgs/model/sh.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {

constexpr const char* kFillgsMagic = "fillgs_4d 1";
constexpr float kSaturatedLogit = 40.0f;

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

int sh_degree_of(const PlyElement& v, const std::string& rest_prefix) {
  const size_t n = v.indexed_properties(rest_prefix).size();
  if (n % 3 != 0) throw_error(v.source, ": ", n, " '", rest_prefix, "*' properties is not a multiple of 3");
  const int coeffs = int(n / 3) + 1;
  const int degree = int(std::lround(std::sqrt(double(coeffs)))) - 1;
  if ((degree + 1) * (degree + 1) != coeffs || degree > 3)
    throw_error(v.source, ": ", n, " '", rest_prefix, "*' properties do not make an SH degree 0..3");
  return degree;
}

void read_sh(const PlyElement& v, const std::string& dc_prefix, const std::string& rest_prefix, GaussianCloud& c,
             const std::vector<uint32_t>& target_ids) {
  const std::vector<std::string> rest = v.indexed_properties(rest_prefix);
  const int degree = sh_degree_of(v, rest_prefix);
  if (degree != c.sh_degree) throw_error(v.source, ": SH degree ", degree, " differs from the other file's ", c.sh_degree);
  const int K = c.sh_count();
  for (int ch = 0; ch < 3; ++ch) {
    const auto& dc = v.finite_column(dc_prefix + std::to_string(ch));
    for (size_t r = 0; r < v.count; ++r) c.sh[(size_t(target_ids[r]) * K) * 3 + ch] = dc[r];
  }
  // f_rest is channel-major: f_rest_{ch*(K-1) + (k-1)}.
  for (int ch = 0; ch < 3; ++ch)
    for (int k = 1; k < K; ++k) {
      const auto& col = v.finite_column(rest[size_t(ch * (K - 1) + (k - 1))]);
      for (size_t r = 0; r < v.count; ++r) c.sh[(size_t(target_ids[r]) * K + k) * 3 + ch] = col[r];
    }
}

/// Reads the geometric base properties (position, scale, rotation, opacity) into ids.
void read_base(const PlyElement& v, GaussianCloud& c, const std::vector<uint32_t>& ids, const std::string& prefix = "") {
  const char* axes[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (prefix.empty()) {
      const auto& col = v.finite_column(axes[a]);
      for (size_t r = 0; r < v.count; ++r) c.means[ids[r]][a] = col[r];
    }
    const auto& s = v.finite_column(prefix + "scale_" + std::to_string(a));
    for (size_t r = 0; r < v.count; ++r) c.log_scales[ids[r]][a] = s[r];
  }
  // An opacity of exactly 0 or 1 is stored by some exporters as a logit of -inf or +inf
  // (seen in real files). Those are saturated, not corrupt: keep them as ±40, which the
  // sigmoid maps to the same float 0 or 1. NaN stays an error.
  const auto& o = v.column(prefix + "opacity");
  size_t saturated = 0;
  for (size_t r = 0; r < v.count; ++r) {
    float x = o[r];
    if (std::isnan(x)) throw_error(v.source, ": ", v.name, " ", r, " property '", prefix, "opacity' is NaN");
    if (std::isinf(x)) {
      x = x > 0 ? kSaturatedLogit : -kSaturatedLogit;
      ++saturated;
    }
    c.opacity_logits[ids[r]] = x;
  }
  if (saturated)
    c.notes.push_back(std::to_string(saturated) + " opacity logits in " + v.source + " were infinite (opacity exactly 0 or 1); kept as ±40");
  if (prefix.empty())
    for (int a = 0; a < 4; ++a) {
      const auto& q = v.finite_column("rot_" + std::to_string(a));
      for (size_t r = 0; r < v.count; ++r) c.rotations[ids[r]][a] = q[r];
    }
}

std::vector<uint32_t> iota_ids(size_t n, uint32_t first = 0) {
  std::vector<uint32_t> ids(n);
  for (size_t i = 0; i < n; ++i) ids[i] = first + uint32_t(i);
  return ids;
}

/// A static cloud from a vertex element with the standard 3DGS properties.
GaussianCloud read_standard_vertex(const PlyElement& v) {
  GaussianCloud c;
  c.sh_degree = sh_degree_of(v, "f_rest_");
  c.resize(v.count);
  const auto ids = iota_ids(v.count);
  read_base(v, c, ids);
  read_sh(v, "f_dc_", "f_rest_", c, ids);
  return c;
}

GaussianCloud read_3dgs(const std::string& path) { return read_standard_vertex(read_ply(path).element("vertex")); }

// ---- Spacetime Gaussians ----

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

// ---- Ex4DGS ----

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

GaussianCloud read_ex4dgs(const std::string& static_path, const std::string& dynamic_path, const SceneReadOptions& opt) {
  Ex4dgsConfig cfg = read_ex4dgs_config(static_path);
  if (opt.ex4dgs_duration > 0) cfg.duration = opt.ex4dgs_duration;
  if (opt.ex4dgs_interval > 0) cfg.interval = opt.ex4dgs_interval;
  if (opt.ex4dgs_pad >= 0) cfg.pad = opt.ex4dgs_pad;
  if (cfg.duration < 2)
    throw_error(static_path, ": Ex4DGS duration unknown (", cfg.source, " has none): give the duration in frames");
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

std::map<std::string, std::string> parse_key_values(const std::string& s) {
  std::map<std::string, std::string> kv;
  std::istringstream is(s);
  std::string tok;
  while (is >> tok) {
    const size_t eq = tok.find('=');
    if (eq != std::string::npos) kv[tok.substr(0, eq)] = tok.substr(eq + 1);
  }
  return kv;
}

GaussianCloud read_fillgs(const std::string& path) {
  const PlyData ply = read_ply(path);
  const PlyElement& v = ply.element("vertex");
  GaussianCloud c = read_standard_vertex(v);
  const PlyElement* tr = ply.find("track");
  if (!tr || tr->count == 0) return c;
  std::map<std::string, std::string> keys;
  for (const std::string& cm : ply.comments)
    if (cm.rfind("fillgs_keys ", 0) == 0) keys = parse_key_values(cm.substr(12));
  auto key_number = [&](const char* k) {
    auto it = keys.find(k);
    if (it == keys.end()) throw_error(path, ": comment 'fillgs_keys' lacks '", k, "='");
    char* e = nullptr;
    const double x = std::strtod(it->second.c_str(), &e);
    if (e == it->second.c_str() || !std::isfinite(x)) throw_error(path, ": comment 'fillgs_keys' has a bad '", k, "' value");
    return x;
  };
  const size_t M = tr->count;
  if (M > v.count) throw_error(path, ": track element has ", M, " rows but vertex has only ", v.count);
  KeyframedMotion& km = c.keyframed;
  const double count = key_number("count");
  if (!(count >= 1 && count <= 1e6) || count != std::floor(count))
    throw_error(path, ": comment 'fillgs_keys' count=", count, " is not an integer in [1, 1000000]");
  km.key_count = int(count);
  km.first_key_time = key_number("first");
  km.key_spacing = key_number("spacing");
  const std::string interp = keys.count("interp") ? keys["interp"] : "catmull_rom";
  if (interp == "catmull_rom") km.position_interp = KeyInterp::CatmullRom;
  else if (interp == "linear") km.position_interp = KeyInterp::Linear;
  else if (interp == "pchip") km.position_interp = KeyInterp::Pchip;
  else throw_error(path, ": unknown interpolation '", interp, "' in comment 'fillgs_keys'");
  const int K = km.key_count;
  if (K < 1) throw_error(path, ": comment 'fillgs_keys' count must be at least 1");
  if (size_t(K) * 7 > tr->property_names.size())
    throw_error(path, ": comment 'fillgs_keys' count=", K, " needs ", size_t(K) * 7, " track properties, the track element has ",
                tr->property_names.size());
  if (!(km.key_spacing > 0)) throw_error(path, ": comment 'fillgs_keys' spacing must be positive");
  km.positions.resize(M * K * 3);
  km.rotations.resize(M * K * 4);
  for (int k = 0; k < K; ++k) {
    for (int a = 0; a < 3; ++a) {
      const auto& col = tr->finite_column("motion_xyz_" + std::to_string(k) + "_" + std::to_string(a));
      for (size_t r = 0; r < M; ++r) km.positions[(r * K + k) * 3 + a] = col[r];
    }
    for (int a = 0; a < 4; ++a) {
      const auto& col = tr->finite_column("motion_rot_" + std::to_string(k) + "_" + std::to_string(a));
      for (size_t r = 0; r < M; ++r) km.rotations[(r * K + k) * 4 + a] = col[r];
    }
  }
  if (tr->has("motion_scale_0_0")) {
    km.log_scales.resize(M * K * 3);
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 3; ++a) {
        const auto& col = tr->finite_column("motion_scale_" + std::to_string(k) + "_" + std::to_string(a));
        for (size_t r = 0; r < M; ++r) km.log_scales[(r * K + k) * 3 + a] = col[r];
      }
  }
  if (tr->has("motion_opacity_0")) {
    km.opacity_logits.resize(M * K);
    for (int k = 0; k < K; ++k) {
      const auto& col = tr->finite_column("motion_opacity_" + std::to_string(k));
      for (size_t r = 0; r < M; ++r) km.opacity_logits[r * K + k] = col[r];
    }
  }
  if (tr->has("motion_dc_0_0")) {
    km.colours.resize(M * K * 3);
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 3; ++a) {
        const auto& col = tr->finite_column("motion_dc_" + std::to_string(k) + "_" + std::to_string(a));
        for (size_t r = 0; r < M; ++r) km.colours[(r * K + k) * 3 + a] = col[r];
      }
  }
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = iota_ids(M, uint32_t(v.count - M));
  return c;
}

}  // namespace

SceneFormat detect_scene_format(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw_error(path, ": no such file or directory");
  if (!ex4dgs_pair(path).first.empty()) return SceneFormat::Ex4dgs;
  const SceneFormat trained = detect_trained_model(path);
  if (trained != SceneFormat::Auto) return trained;
  if (fs::is_directory(path, ec))
    throw_error(path, ": a folder that holds no model fillgs reads (Ex4DGS pair, E-D3DGS, 4DGaussians or Deformable 3D Gaussians run, 4DGS chkpnt*.pth, "
                      "params.npz, time_*.ply / frame_*.ply frames); give a file or --scene-format");
  const std::string header = read_ply_header(path);
  if (header.compare(0, 3, "ply") != 0) throw_error(path, ": not a PLY file (missing 'ply' magic line)");
  if (header.find(kFillgsMagic) != std::string::npos) return SceneFormat::Fillgs4D;
  if (header.find(" trbf_center\n") != std::string::npos) return SceneFormat::Spacetime;
  refuse_canonical_ply(path, header);
  return SceneFormat::Gaussian3D;
}

GaussianCloud read_scene(const std::string& path, const SceneReadOptions& options) {
  SceneFormat f = options.format == SceneFormat::Auto ? detect_scene_format(path) : options.format;
  return reading(path, [&] {
    GaussianCloud c;
    switch (f) {
      case SceneFormat::Gaussian3D:
        if (options.format != SceneFormat::Auto) refuse_canonical_ply(path, read_ply_header(path));  // detection did it otherwise
        c = read_3dgs(path);
        break;
      case SceneFormat::Ed3dgs:
      case SceneFormat::FourDGaussians:
      case SceneFormat::FourDGS:
      case SceneFormat::Deformable3DGS:
        // Networks and closed-form slices: streamed unless keys are asked for.
        if (options.model_evaluation == ModelEvaluation::Streamed) {
          c = stream_trained_model(std::shared_ptr<const TrainedModel>(open_trained_model(path, f, options)), options.still,
                                   options.network_kernel == NetworkKernel::Eigen, options.progress ? *options.progress : null_progress());
          break;
        }
        [[fallthrough]];
      case SceneFormat::Dynamic3DGS:
      case SceneFormat::PlyFrames:
        c = sample_trained_model(*open_trained_model(path, f, options), options.network_kernel == NetworkKernel::Eigen,
                                 options.progress ? *options.progress : null_progress());
        break;
      case SceneFormat::Spacetime: c = read_spacetime(path, options); break;
      case SceneFormat::Fillgs4D: c = read_fillgs(path); break;
      case SceneFormat::Ex4dgs: {
        auto [s, d] = ex4dgs_pair(path);
        if (s.empty()) throw_error(path, ": Ex4DGS needs point_cloud.ply and dynamic_point_cloud.ply side by side");
        c = read_ex4dgs(s, d, options);
        break;
      }
      case SceneFormat::Auto: break;
    }
    c.validate(path);
    partition_static_dynamic(c, options.partition);
    return c;
  });
}

// ---- writers ----

namespace {

void add_column(PlyElement& e, const std::string& name, std::vector<float> values) {
  FILLGS_CHECK_EQ(values.size(), e.count);
  e.property_names.push_back(name);
  e.columns.push_back(std::move(values));
}

/// Standard 3DGS vertex element from per-Gaussian raw values in the given order.
PlyElement standard_vertex(const GaussianCloud& c, const std::vector<uint32_t>& order, const std::vector<Vec3f>& means,
                           const std::vector<Vec3f>& log_scales, const std::vector<Vec4f>& rots,
                           const std::vector<float>& opacity_logits, const float* sh) {
  PlyElement v;
  v.name = "vertex";
  v.count = order.size();
  auto gather = [&](auto f) {
    std::vector<float> col(order.size());
    for (size_t r = 0; r < order.size(); ++r) col[r] = f(order[r]);
    return col;
  };
  const char* xyz[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) add_column(v, xyz[a], gather([&](uint32_t g) { return means[g][a]; }));
  for (const char* n : {"nx", "ny", "nz"}) add_column(v, n, std::vector<float>(order.size(), 0.0f));
  const int K = c.sh_count();
  for (int ch = 0; ch < 3; ++ch)
    add_column(v, "f_dc_" + std::to_string(ch), gather([&](uint32_t g) { return sh[size_t(g) * K * 3 + ch]; }));
  for (int ch = 0; ch < 3; ++ch)
    for (int k = 1; k < K; ++k)
      add_column(v, "f_rest_" + std::to_string(ch * (K - 1) + k - 1),
                 gather([&](uint32_t g) { return sh[(size_t(g) * K + k) * 3 + ch]; }));
  add_column(v, "opacity", gather([&](uint32_t g) { return opacity_logits[g]; }));
  for (int a = 0; a < 3; ++a) add_column(v, "scale_" + std::to_string(a), gather([&](uint32_t g) { return log_scales[g][a]; }));
  for (int a = 0; a < 4; ++a) add_column(v, "rot_" + std::to_string(a), gather([&](uint32_t g) { return rots[g][a]; }));
  return v;
}

std::vector<uint32_t> static_first_order(const GaussianCloud& c) {
  std::vector<uint32_t> order = c.static_ids();
  order.insert(order.end(), c.dynamic_ids.begin(), c.dynamic_ids.end());
  return order;
}

}  // namespace

void write_3dgs_ply(const std::string& path, const GaussianCloud& cloud, double t) {
  FrameGaussians f = frame_at(cloud, t);
  std::vector<Vec3f> log_scales(cloud.size());
  std::vector<float> logits(cloud.size());
  for (size_t g = 0; g < cloud.size(); ++g) {
    log_scales[g] = f.scales[g].array().log();
    // Static Gaussians keep their stored logit exactly; moving ones get logit(opacity(t)).
    logits[g] = cloud.opacity_logits[g];
  }
  for (uint32_t g : cloud.dynamic_ids) logits[g] = logit(f.opacities[g]);
  std::vector<uint32_t> order(cloud.size());
  for (size_t g = 0; g < order.size(); ++g) order[g] = uint32_t(g);
  std::vector<Vec4f> rots = f.rotations;
  for (uint32_t g : cloud.static_ids()) rots[g] = cloud.rotations[g];  // raw, as stored
  // At a key's own time, a keyframed Gaussian is written with the key's raw values, so that
  // frames read from PLYs and written again are the same bytes.
  const KeyframedMotion& km = cloud.keyframed;
  const double u = cloud.motion == MotionModel::Keyframed ? (t - km.first_key_time) / km.key_spacing : -1.0;
  const long key = std::lround(u);
  if (cloud.motion == MotionModel::Keyframed && !km.ex4dgs_edges && km.temporal_opacity.empty() && key >= 0 && key < km.key_count &&
      std::fabs(u - double(key)) < 1e-9) {
    const size_t K = size_t(km.key_count), k = size_t(key);
    for (size_t j = 0; j < cloud.dynamic_ids.size(); ++j) {
      const uint32_t g = cloud.dynamic_ids[j];
      f.means[g] = Eigen::Map<const Vec3f>(&km.positions[(j * K + k) * 3]);
      if (!km.rotations.empty()) rots[g] = Eigen::Map<const Vec4f>(&km.rotations[(j * K + k) * 4]);
      if (!km.log_scales.empty()) log_scales[g] = Eigen::Map<const Vec3f>(&km.log_scales[(j * K + k) * 3]);
      if (!km.opacity_logits.empty()) logits[g] = km.opacity_logits[j * K + k];
    }
  }
  PlyData ply;
  ply.elements.push_back(standard_vertex(cloud, order, f.means, log_scales, rots, logits, f.sh));
  write_ply(path, ply);
}

GaussianCloud bake_tracks(const GaussianCloud& cloud, int frames) {
  if (frames < 2) throw_error("baking tracks needs at least 2 frames (got ", frames, ")");
  GaussianCloud out = cloud;
  out.polynomial = PolynomialMotion{};
  out.keyframed = KeyframedMotion{};
  if (cloud.dynamic_ids.empty()) {
    out.motion = MotionModel::Static;
    out.source.reset();
    out.source_rows.clear();
    return out;
  }
  const size_t M = cloud.dynamic_ids.size(), K = size_t(frames);
  out.keyframed = per_frame_tracks(M, frames);
  KeyframedMotion& km = out.keyframed;
  km.opacity_logits.resize(M * K);
  const bool evaluated = cloud.motion == MotionModel::Evaluated;
  const bool keyed_scales = evaluated || (cloud.motion == MotionModel::Keyframed && !cloud.keyframed.log_scales.empty());
  if (keyed_scales) km.log_scales.resize(M * K * 3);
  const bool keyed_colours = evaluated || (cloud.motion == MotionModel::Keyframed && !cloud.keyframed.colours.empty());
  if (keyed_colours) km.colours.resize(M * K * 3);
  const size_t sh_row = size_t(cloud.sh_count()) * 3;
  FrameSampler ev(cloud);
  bool opacity_varies = false;
  for (size_t k = 0; k < K; ++k) {
    const FrameGaussians& f = ev.at(FrameGrid(frames).time(int(k)));
    for (size_t j = 0; j < M; ++j) {
      const uint32_t g = cloud.dynamic_ids[j];
      for (int a = 0; a < 3; ++a) km.positions[(j * K + k) * 3 + a] = f.means[g][a];
      for (int a = 0; a < 4; ++a) km.rotations[(j * K + k) * 4 + a] = f.rotations[g][a];
      if (keyed_scales)
        for (int a = 0; a < 3; ++a) km.log_scales[(j * K + k) * 3 + a] = std::log(f.scales[g][a]);
      if (keyed_colours)
        for (int a = 0; a < 3; ++a) km.colours[(j * K + k) * 3 + a] = f.sh[g * sh_row + a];
      km.opacity_logits[j * K + k] = logit(f.opacities[g]);
      if (std::fabs(f.opacities[g] - sigmoid(cloud.opacity_logits[g])) > 1e-6f) opacity_varies = true;
    }
  }
  if (!opacity_varies) km.opacity_logits.clear();
  out.motion = MotionModel::Keyframed;
  out.source.reset();
  out.source_rows.clear();
  canonical_from_first_key(out);
  return out;
}

KeyChoice choose_keys(const GaussianCloud& cloud, float tolerance, size_t sample) {
  KeyChoice kc;
  kc.frames = motion_frames(cloud);
  if (cloud.motion != MotionModel::Evaluated || kc.frames < 2) return kc;
  // The sample: moving Gaussians evenly spread over the set, as a cloud of their own.
  const size_t M = cloud.dynamic_ids.size(), S = std::min(M, std::max<size_t>(sample, 1));
  GaussianCloud sub;
  sub.sh_degree = cloud.sh_degree;
  sub.resize(S);
  const size_t row = size_t(cloud.sh_count()) * 3;
  for (size_t s = 0; s < S; ++s) {
    const size_t j = s * M / S;
    const uint32_t g = cloud.dynamic_ids[j];
    sub.means[s] = cloud.means[g];
    sub.log_scales[s] = cloud.log_scales[g];
    sub.rotations[s] = cloud.rotations[g];
    sub.opacity_logits[s] = cloud.opacity_logits[g];
    std::copy_n(&cloud.sh[size_t(g) * row], row, &sub.sh[s * row]);
    sub.dynamic_ids.push_back(uint32_t(s));
    sub.source_rows.push_back(cloud.source_rows[j]);
  }
  sub.motion = MotionModel::Evaluated;
  sub.source = cloud.source;
  kc.sample = S;
  const int F = kc.frames;
  const FrameGrid grid(F);
  std::vector<Vec3f> truth(size_t(F) * S);
  {
    FrameSampler exact(sub);
    for (int f = 0; f < F; ++f) {
      const FrameGaussians& g = exact.at(grid.time(f));
      std::copy(g.means.begin(), g.means.end(), truth.begin() + ptrdiff_t(size_t(f) * S));
    }
  }
  kc.keys = F;
  kc.interval = 1.0;
  kc.worst_error = 0.0;
  for (int interval = 2; interval <= 32; interval *= 2) {
    const int K = (F - 1 + interval - 1) / interval + 1;
    if (K >= kc.keys || K < 2) continue;
    const GaussianCloud keyed = bake_tracks(sub, K);
    FrameSampler approx(keyed);
    double worst = 0;
    for (int f = 0; f < F; ++f) {
      const FrameGaussians& g = approx.at(grid.time(f));
      for (size_t s = 0; s < S; ++s) worst = std::max(worst, double((g.means[s] - truth[size_t(f) * S + s]).norm()));
    }
    if (worst > tolerance) break;
    kc.keys = K;
    kc.interval = double(F - 1) / double(K - 1);
    kc.worst_error = worst;
  }
  return kc;
}

GaussianCloud keyed_for_training(const GaussianCloud& cloud, KeyChoice* choice, float tolerance) {
  KeyChoice kc = choose_keys(cloud, tolerance);
  if (choice) *choice = kc;
  if (cloud.motion != MotionModel::Evaluated) return cloud;
  GaussianCloud keyed = bake_tracks(cloud, std::max(2, kc.keys));
  std::ostringstream os;
  os << "keyed for training: " << kc.keys << " keys (one every " << kc.interval << " of its " << kc.frames
     << " frames), Catmull-Rom positions within " << kc.worst_error << " world units of its network at every frame on " << kc.sample
     << " moving Gaussians (tolerance " << tolerance << ")";
  keyed.notes.push_back(os.str());
  return keyed;
}

void write_fillgs_ply(const std::string& path, const GaussianCloud& cloud_in, int frames) {
  if (frames < 2 && cloud_in.motion == MotionModel::Evaluated) frames = motion_frames(cloud_in);  // a key at each of its frames
  const bool native = cloud_in.motion == MotionModel::Static ||
                      (cloud_in.motion == MotionModel::Keyframed && !cloud_in.keyframed.ex4dgs_edges &&
                       cloud_in.keyframed.temporal_opacity.empty() && !cloud_in.keyframed.rotations.empty());
  if (!native && frames < 2)
    throw_error(path, ": ", to_string(cloud_in.motion), " motion must be baked to frames before writing (give a frame count)");
  const GaussianCloud baked = native ? GaussianCloud() : bake_tracks(cloud_in, frames);
  const GaussianCloud& c = native ? cloud_in : baked;
  const std::vector<uint32_t> order = static_first_order(c);
  PlyData ply;
  ply.comments.push_back(kFillgsMagic);
  ply.elements.push_back(standard_vertex(c, order, c.means, c.log_scales, c.rotations, c.opacity_logits, c.sh.data()));
  const size_t M = c.dynamic_ids.size();
  if (M > 0) {
    const KeyframedMotion& km = c.keyframed;
    const int K = km.key_count;
    std::ostringstream kc;
    kc.precision(17);
    kc << "fillgs_keys count=" << K << " first=" << km.first_key_time << " spacing=" << km.key_spacing << " interp="
       << (km.position_interp == KeyInterp::Linear ? "linear" : km.position_interp == KeyInterp::Pchip ? "pchip" : "catmull_rom");
    ply.comments.push_back(kc.str());
    PlyElement tr;
    tr.name = "track";
    tr.count = M;
    auto col = [&](const std::vector<float>& src, int width, int k, int a) {
      std::vector<float> out(M);
      for (size_t j = 0; j < M; ++j) out[j] = src[(j * K + k) * width + a];
      return out;
    };
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 3; ++a) add_column(tr, "motion_xyz_" + std::to_string(k) + "_" + std::to_string(a), col(km.positions, 3, k, a));
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 4; ++a) add_column(tr, "motion_rot_" + std::to_string(k) + "_" + std::to_string(a), col(km.rotations, 4, k, a));
    if (!km.log_scales.empty())
      for (int k = 0; k < K; ++k)
        for (int a = 0; a < 3; ++a) add_column(tr, "motion_scale_" + std::to_string(k) + "_" + std::to_string(a), col(km.log_scales, 3, k, a));
    if (!km.opacity_logits.empty())
      for (int k = 0; k < K; ++k) add_column(tr, "motion_opacity_" + std::to_string(k), col(km.opacity_logits, 1, k, 0));
    if (!km.colours.empty())
      for (int k = 0; k < K; ++k)
        for (int a = 0; a < 3; ++a) add_column(tr, "motion_dc_" + std::to_string(k) + "_" + std::to_string(a), col(km.colours, 3, k, a));
    ply.elements.push_back(std::move(tr));
  }
  write_ply(path, ply);
}

}  // namespace fillgs
