#include "ply_gaussians.hpp"

#include <cmath>
#include <filesystem>

#include "fillgs/base/error.hpp"

namespace fillgs::model_io {

namespace {
constexpr float kSaturatedLogit = 40.0f;
}  // namespace

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

void note_saturated(GaussianCloud& c, size_t saturated, const std::string& source) {
  if (saturated)
    c.notes.push_back(std::to_string(saturated) + " opacity logits in " + source + " were infinite (opacity exactly 0 or 1); kept as ±40");
}

void read_base(const PlyElement& v, GaussianCloud& c, const std::vector<uint32_t>& ids, const std::string& prefix, size_t* saturated_out) {
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
    if (std::isnan(x)) throw_error(v.source, ": ", v.name, " ", v.first_row + r, " property '", prefix, "opacity' is NaN");
    if (std::isinf(x)) {
      x = x > 0 ? kSaturatedLogit : -kSaturatedLogit;
      ++saturated;
    }
    c.opacity_logits[ids[r]] = x;
  }
  if (saturated_out) *saturated_out += saturated;
  else note_saturated(c, saturated, v.source);
  if (prefix.empty())
    for (int a = 0; a < 4; ++a) {
      const auto& q = v.finite_column("rot_" + std::to_string(a));
      for (size_t r = 0; r < v.count; ++r) c.rotations[ids[r]][a] = q[r];
    }
}

void refuse_canonical_ply(const std::string& ply, const std::string& header) {
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::path(ply).parent_path();
  const bool embeddings = header.find(" embedding_0\n") != std::string::npos;
  const bool deformation = std::filesystem::exists(dir / "deformation.pth", ec);
  const bool deform_dir = std::filesystem::is_directory(dir.parent_path().parent_path() / "deform", ec) || std::filesystem::is_directory(dir / "deform", ec);
  if (!embeddings && !deformation && !deform_dir) return;
  const std::string what = embeddings ? "the canonical point cloud of an E-D3DGS model (it has embedding_* properties)"
                           : deformation ? "the canonical point cloud of a deformation model (deformation.pth lies beside it)"
                                         : "the canonical point cloud of a Deformable 3D Gaussians model (a deform/ folder lies beside it)";
  const std::string instead = deform_dir && !deformation && !embeddings
                                  ? "pass the training run's folder (the one holding deform/ and point_cloud/) instead"
                                  : "pass the folder " + (dir.empty() ? std::string(".") : dir.string()) + " (or the training run's folder) instead";
  throw_error(ply, ": ", what, ", which is no frame of the video: fillgs will not read it as a static scene; ", instead);
}

std::vector<uint32_t> iota_ids(size_t n, uint32_t first) {
  std::vector<uint32_t> ids(n);
  for (size_t i = 0; i < n; ++i) ids[i] = first + uint32_t(i);
  return ids;
}

GaussianCloud read_standard_vertex(const PlyElement& v) {
  GaussianCloud c;
  size_t saturated = 0;
  const PlyElementSink sink = standard_vertex_sink(c, saturated);
  sink.start(PlyData{}, v);
  sink.take(v);  // the whole element as one block
  note_saturated(c, saturated, v.source);
  return c;
}

PlyElementSink standard_vertex_sink(GaussianCloud& c, size_t& saturated) {
  PlyElementSink sink;
  sink.element = "vertex";
  sink.start = [&c](const PlyData&, const PlyElement& v) {
    c.sh_degree = sh_degree_of(v, "f_rest_");
    c.resize(v.count);
  };
  sink.take = [&c, &saturated](const PlyElement& block) {
    const auto ids = iota_ids(block.count, uint32_t(block.first_row));
    read_base(block, c, ids, "", &saturated);
    read_sh(block, "f_dc_", "f_rest_", c, ids);
  };
  return sink;
}

ModelState read_vertex_state(const PlyElement& v, std::vector<std::string>& notes) {
  GaussianCloud c = read_standard_vertex(v);
  notes.insert(notes.end(), c.notes.begin(), c.notes.end());
  ModelState s;
  s.sh_degree = c.sh_degree;
  s.means = std::move(c.means);
  s.log_scales = std::move(c.log_scales);
  s.rotations = std::move(c.rotations);
  s.opacity_logits = std::move(c.opacity_logits);
  s.sh = std::move(c.sh);
  return s;
}

}  // namespace fillgs::model_io
