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
  // The track element's rows are scattered into the keys as they are read, a block at a
  // time: the keys are held once, not beside a copy of the file and of its columns.
  GaussianCloud c;
  bool have_vertex = false;
  size_t M = 0;
  int K = 0;
  // Per track property: the key array it fills, the values per key there, its key, its
  // offset within a key's values, its column in the element, its name.
  struct Target {
    std::vector<float>* values;
    size_t width;
    size_t key, offset, column;
    std::string name;
  };
  std::vector<Target> plan;
  PlyElementSink sink;
  sink.element = "track";
  size_t saturated = 0;
  PlyElementSink vertex = standard_vertex_sink(c, saturated);
  vertex.start = [&have_vertex, start = vertex.start](const PlyData& so_far, const PlyElement& v) {
    start(so_far, v);
    have_vertex = true;
  };
  sink.start = [&](const PlyData& so_far, const PlyElement& tr) {
    if (!have_vertex) throw_error(path, ": the track element comes before the vertex element (fillgs writes vertex first)");
    M = tr.count;
    if (M == 0) return;
    std::map<std::string, std::string> keys;
    for (const std::string& cm : so_far.comments)
      if (cm.rfind("fillgs_keys ", 0) == 0) keys = parse_key_values(cm.substr(12));
    auto key_number = [&](const char* k) {
      auto it = keys.find(k);
      if (it == keys.end()) throw_error(path, ": comment 'fillgs_keys' lacks '", k, "='");
      char* e = nullptr;
      const double x = std::strtod(it->second.c_str(), &e);
      if (e == it->second.c_str() || !std::isfinite(x)) throw_error(path, ": comment 'fillgs_keys' has a bad '", k, "' value");
      return x;
    };
    if (M > c.size()) throw_error(path, ": track element has ", M, " rows but vertex has only ", c.size());
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
    K = km.key_count;
    if (size_t(K) * 7 > tr.property_names.size())
      throw_error(path, ": comment 'fillgs_keys' count=", K, " needs ", size_t(K) * 7, " track properties, the track element has ",
                  tr.property_names.size());
    if (!(km.key_spacing > 0)) throw_error(path, ": comment 'fillgs_keys' spacing must be positive");
    const int R = c.sh_count() - 1;
    if (tr.has("motion_rest_0_0") && (!tr.has("motion_dc_0_0") || R < 1))
      throw_error(path, ": track properties motion_rest_* need motion_dc_* and SH bands above the DC (f_rest_*)");
    // values[(row·K + key)·width + offset] = the property `prefix`key_index (key_index absent for one value per key).
    auto add = [&](std::vector<float>& values, size_t width, const std::string& prefix, int per_key, bool indexed,
                   size_t (*offset)(int index, int R)) {
      values.resize(checked_mul(checked_mul(M, size_t(K), path, "track keys"), width, path, "track keys"));
      for (int k = 0; k < K; ++k)
        for (int i = 0; i < per_key; ++i) {
          const std::string name = prefix + std::to_string(k) + (indexed ? "_" + std::to_string(i) : "");
          const auto at = std::find(tr.property_names.begin(), tr.property_names.end(), name);
          if (at == tr.property_names.end())
            throw_error(path, ": property '", name, "' missing (track element has ", tr.property_names.size(), " properties)");
          plan.push_back({&values, width, size_t(k), offset(i, R), size_t(at - tr.property_names.begin()), name});
        }
    };
    auto same = [](int i, int) { return size_t(i); };
    add(km.positions, 3, "motion_xyz_", 3, true, same);
    add(km.rotations, 4, "motion_rot_", 4, true, same);
    if (tr.has("motion_scale_0_0")) add(km.log_scales, 3, "motion_scale_", 3, true, same);
    if (tr.has("motion_opacity_0")) add(km.opacity_logits, 1, "motion_opacity_", 1, false, same);
    if (tr.has("motion_dc_0_0")) add(km.colours, 3, "motion_dc_", 3, true, same);
    // motion_rest_k_(a·R + i): coefficient i of channel a, stored [i][a] within a key.
    if (tr.has("motion_rest_0_0")) add(km.sh_rest, size_t(R) * 3, "motion_rest_", 3 * R, true, [](int j, int R) { return size_t(j % R) * 3 + size_t(j / R); });
  };
  sink.take = [&](const PlyElement& block) {
    for (const Target& t : plan) {
      const std::vector<float>& col = block.columns[t.column];
      for (size_t r = 0; r < block.count; ++r)
        if (!std::isfinite(col[r]))
          throw_error(path, ": track ", block.first_row + r, " property '", t.name, "' is ", std::isnan(col[r]) ? "NaN" : "infinite");
    }
    for (size_t r = 0; r < block.count; ++r) {
      const size_t row = (block.first_row + r) * size_t(K);
      for (const Target& t : plan) (*t.values)[(row + t.key) * t.width + t.offset] = block.columns[t.column][r];
    }
  };
  const PlyData ply = read_ply(path, {vertex, sink});
  (void)ply.element("vertex");  // no vertex element: one line naming the file
  note_saturated(c, saturated, path);
  if (M == 0) return c;
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = iota_ids(M, uint32_t(c.size() - M));
  return c;
}

}  // namespace

const ModelFormat& row_fillgs4d() {
  static const ModelFormat row{{"fillgs", {}, "fillgs 4D PLY (a 3DGS vertex element and a track element of keys)", 70, {}},
      [](const FormatProbe& p) { return p.ply_header().find(kFillgsMagic) != std::string::npos; }, nullptr, false, read_fillgs};
  return row;
}

}  // namespace fillgs::model_io
