// The fillgs 4D PLY (baked keyframed tracks; data/README.md): the vertex element of a
// 3DGS PLY, then a `track` element for the dynamic Gaussians. Written by write_fillgs_ply.
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

GaussianCloud read_fillgs(const std::string& path, const SceneReadOptions&) {
  // A PLY without fillgs's comment (read so by --scene-format fillgs) is checked as every
  // reader of a plain PLY checks it: a deformation model's canonical cloud is no scene.
  const std::string header = read_ply_header(path);
  if (header.find(kFillgsMagic) == std::string::npos) refuse_canonical_ply(path, header);
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
  if (tr->has("motion_rest_0_0")) {
    const int R = c.sh_count() - 1;
    if (km.colours.empty() || R < 1) throw_error(path, ": track properties motion_rest_* need motion_dc_* and SH bands above the DC (f_rest_*)");
    km.sh_rest.resize(M * size_t(K) * size_t(R) * 3);
    for (int k = 0; k < K; ++k)
      for (int a = 0; a < 3; ++a)
        for (int i = 0; i < R; ++i) {
          const auto& col = tr->finite_column("motion_rest_" + std::to_string(k) + "_" + std::to_string(a * R + i));
          for (size_t r = 0; r < M; ++r) km.sh_rest[((r * size_t(K) + size_t(k)) * size_t(R) + size_t(i)) * 3 + size_t(a)] = col[r];
        }
  }
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = iota_ids(M, uint32_t(v.count - M));
  return c;
}

}  // namespace

const ModelFormat& row_fillgs4d() {
  static const ModelFormat row{{"fillgs", {}, "fillgs 4D PLY (a 3DGS vertex element and a track element of keys)", 70, {}},
      [](const FormatProbe& p) { return p.ply_header().find(kFillgsMagic) != std::string::npos; }, nullptr, false, read_fillgs};
  return row;
}

}  // namespace fillgs::model_io
