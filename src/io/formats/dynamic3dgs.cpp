// Dynamic 3D Gaussians: params.npz (per-frame means, colours and rotations; per-Gaussian
// scales and opacities), sampled at its frames into keys.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/model/sh.hpp"
#include "io/model_support.hpp"
#include "io/ply_gaussians.hpp"

namespace fillgs::model_io {

namespace {

class Dynamic3dgs : public FrameSequence {
 public:
  Dynamic3dgs(const std::string& path, const SceneReadOptions&) {
    std::error_code ec;
    source = fs::is_directory(path, ec) ? join_path(path, "params.npz") : path;
    require_regular_file(source);
    const ZipArchive zip(source);
    auto array = [&](const std::string& key, size_t dims) {
      const std::string entry = key + ".npy";
      if (!zip.has(entry)) throw_error(source, ": key '", key, "' missing");
      NpyArray a = parse_npy(zip.read(entry), source + " (" + entry + ")");
      if (a.shape.size() != dims) throw_error(source, ": key '", key, "' has ", a.shape.size(), " dimensions, expected ", dims);
      if (a.fortran_order) throw_error(source, ": key '", key, "' is stored in Fortran order");
      return a;
    };
    auto shape_text = [](const std::vector<size_t>& s) {
      std::string t = "[";
      for (size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
      return t + "]";
    };
    const NpyArray means = array("means3D", 3), colours = array("rgb_colors", 3), rots = array("unnorm_rotations", 3);
    const NpyArray scales = array("log_scales", 2), opac = array("logit_opacities", 2);
    const size_t T = means.shape[0], N = means.shape[1];
    auto expect = [&](const char* key, const NpyArray& a, std::vector<size_t> shape) {
      if (a.shape != shape) throw_error(source, ": key '", key, "' has shape ", shape_text(a.shape), ", expected ", shape_text(shape));
    };
    expect("means3D", means, {T, N, 3});
    expect("rgb_colors", colours, {T, N, 3});
    expect("unnorm_rotations", rots, {T, N, 4});
    expect("log_scales", scales, {N, 3});
    expect("logit_opacities", opac, {N, 1});
    if (T < 1) throw_error(source, ": key 'means3D' holds no frames");
    const std::vector<double> M = means.to_doubles(source), C = colours.to_doubles(source), R = rots.to_doubles(source);
    const std::vector<double> S = scales.to_doubles(source), O = opac.to_doubles(source);
    for (const auto* v : {&M, &C, &R, &S, &O})
      for (size_t i = 0; i < v->size(); ++i)
        if (!std::isfinite((*v)[i])) throw_error(source, ": a value is not finite (element ", i, ")");
    frames_.resize(T);
    for (size_t f = 0; f < T; ++f) {
      ModelState& s = frames_[f];
      s.sh_degree = 0;
      s.means.resize(N);
      s.log_scales.resize(N);
      s.rotations.resize(N);
      s.opacity_logits.resize(N);
      s.sh.resize(N * 3);
      for (size_t i = 0; i < N; ++i) {
        for (int a = 0; a < 3; ++a) {
          s.means[i][a] = float(M[(f * N + i) * 3 + size_t(a)]);
          s.log_scales[i][a] = float(S[i * 3 + size_t(a)]);
          // Colours are given as RGB (its renderer takes them precomputed): the DC that gives them.
          s.sh[i * 3 + size_t(a)] = rgb_to_sh_dc(float(C[(f * N + i) * 3 + size_t(a)]));
        }
        for (int a = 0; a < 4; ++a) s.rotations[i][a] = float(R[(f * N + i) * 4 + size_t(a)]);
        s.opacity_logits[i] = float(O[i]);
      }
    }
    finish_times();
    if (zip.has("seg_colors.npy")) notes.push_back("Dynamic 3D Gaussians' seg_colors are not read (colour comes from rgb_colors)");
  }
};

}  // namespace

const ModelFormat& row_dynamic3dgs() {
  static const ModelFormat row{{"dynamic3dgs", {}, "Dynamic 3D Gaussians: params.npz, or the folder holding it", 20, {}},
      [](const FormatProbe& p) {
        const std::string n = p.filename();
        return p.directory() ? p.beside("params.npz") : n.size() > 4 && n.compare(n.size() - 4, 4, ".npz") == 0;
      },
      [](const std::string& path, const SceneReadOptions& o) -> std::unique_ptr<TrainedModel> { return std::make_unique<Dynamic3dgs>(path, o); },
      false, nullptr};
  return row;
}

}  // namespace fillgs::model_io
