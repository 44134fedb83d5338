#include "fillgs/io/array_input.hpp"

#include <cmath>
#include <algorithm>
#include <cstring>

#include "fillgs/base/error.hpp"
#include "fillgs/io/camera_io.hpp"

namespace fillgs {

namespace {

/// A pixel count: a whole number in [1, 65536].
int pixel_count(double x, const char* name, size_t index) {
  if (!(x >= 1 && x <= 65536) || x != std::floor(x)) throw_error(name, ": element ", index, " is not a pixel count (", x, ")");
  return int(x);
}

/// Every value of rows of `row` values finite; the message names the row (first_row + i / row).
void require_finite(const float* p, size_t n, size_t row, const std::string& name, size_t first_row = 0) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) throw_error(name, ": element ", first_row + i / row, " is not finite (", p[i], ")");
}

}  // namespace

Camera camera_from_arrays(const float* K, const float* M, double width, double height, double time, const std::string& name, size_t index) {
  const std::string element = "element " + std::to_string(index);
  require_finite(K, 9, 9, "K", index);
  require_finite(M, 16, 16, "world_to_camera", index);
  if (K[1] != 0.0f || K[3] != 0.0f || K[6] != 0.0f || K[7] != 0.0f || K[8] != 1.0f)
    throw_error("K: ", element, " is not a pinhole matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (skew ", K[1], ", last row ", K[6], " ", K[7], " ",
                K[8], ")");
  if (M[12] != 0.0f || M[13] != 0.0f || M[14] != 0.0f || M[15] != 1.0f)
    throw_error("world_to_camera: ", element, " has last row (", M[12], ", ", M[13], ", ", M[14], ", ", M[15], "), expected (0, 0, 0, 1)");
  if (!std::isnan(time) && !(time >= 0.0 && time <= 1.0)) throw_error("time: ", element, " is ", time, ", expected a time in [0, 1] or NaN");
  Camera c;
  c.fx = K[0], c.fy = K[4], c.cx = K[2], c.cy = K[5];
  for (int r = 0; r < 3; ++r) {
    for (int q = 0; q < 3; ++q) c.R(r, q) = M[r * 4 + q];
    c.t[r] = M[r * 4 + 3];
  }
  c.width = pixel_count(width, "width", index);
  c.height = pixel_count(height, "height", index);
  c.time = time;
  c.name = name;
  check_camera("cameras", element, c);  // the bounds every camera file's reader enforces
  return c;
}

Camera camera_from_3dgs(const double* R, const double* T, double fov_x, double fov_y, double width, double height, double time,
                        const std::string& name, size_t index) {
  const std::string element = "element " + std::to_string(index);
  for (const double fov : {fov_x, fov_y})
    if (!(fov > 0.0 && fov < M_PI)) throw_error("fov: ", element, " has a field of view of ", fov, " radians, expected (0, pi)");
  const int w = pixel_count(width, "width", index), h = pixel_count(height, "height", index);
  // The pinhole the codes' projection matrix makes: focal length W / (2 tan(FoVx / 2)),
  // principal point at the image centre.
  float K[9] = {float(w / (2.0 * std::tan(fov_x / 2.0))), 0.0f, float(w / 2.0), 0.0f, float(h / (2.0 * std::tan(fov_y / 2.0))), float(h / 2.0),
                0.0f, 0.0f, 1.0f};
  float M[16] = {0};
  for (int r = 0; r < 3; ++r) {
    for (int q = 0; q < 3; ++q) M[r * 4 + q] = float(R[q * 3 + r]);  // world-to-camera rotation: R transposed
    M[r * 4 + 3] = float(T[r]);
  }
  M[15] = 1.0f;
  return camera_from_arrays(K, M, w, h, time, name, index);
}

Camera3dgs camera_to_3dgs(const Camera& c, size_t index) {
  if (std::fabs(c.cx - c.width / 2.0) > 0.5 || std::fabs(c.cy - c.height / 2.0) > 0.5)
    throw_error("cameras: element ", index, " (", c.name, ") has its principal point at (", c.cx, ", ", c.cy, "), the 3DGS codes' at the image centre (",
                c.width / 2.0, ", ", c.height / 2.0, "): crop the image to centre it first");
  Camera3dgs o;
  for (int r = 0; r < 3; ++r) {
    for (int q = 0; q < 3; ++q) o.R[q * 3 + r] = c.R(r, q);  // R transposed, as camera_from_3dgs reads it
    o.T[r] = c.t[r];
  }
  o.fov_x = 2.0 * std::atan(c.width / (2.0 * c.fx));
  o.fov_y = 2.0 * std::atan(c.height / (2.0 * c.fy));
  return o;
}

ModelState gaussians_from_arrays(size_t n, const float* means, const float* log_scales, const float* quaternions, const float* opacity_logits,
                                 const float* sh, size_t sh_coefficients, const std::string& what) {
  require_finite(means, n * 3, 3, what + " means");
  require_finite(log_scales, n * 3, 3, what + " log_scales");
  require_finite(quaternions, n * 4, 4, what + " quaternions");
  require_finite(opacity_logits, n, 1, what + " opacity_logits");
  ModelState s;
  s.means.resize(n);
  s.log_scales.resize(n);
  s.rotations.resize(n);
  s.opacity_logits.assign(opacity_logits, opacity_logits + n);
  if (n) {
    std::memcpy(static_cast<void*>(s.means.data()), means, n * 12);
    std::memcpy(static_cast<void*>(s.log_scales.data()), log_scales, n * 12);
    std::memcpy(static_cast<void*>(s.rotations.data()), quaternions, n * 16);
  }
  for (size_t i = 0; i < n; ++i)
    if (s.rotations[i].squaredNorm() == 0.0f) throw_error(what, " quaternions: element ", i, " is zero");
  if (!sh) {
    s.sh.assign(n * 3, 0.0f);  // grey: SH DC 0 is colour 0.5
    return s;
  }
  const int degree = int(std::lround(std::sqrt(double(sh_coefficients)))) - 1;
  if (sh_coefficients < 1 || size_t((degree + 1) * (degree + 1)) != sh_coefficients || degree > 3)
    throw_error(what, " sh: ", sh_coefficients, " coefficients per Gaussian, expected 1, 4, 9 or 16");
  require_finite(sh, n * sh_coefficients * 3, sh_coefficients * 3, what + " sh");
  s.sh_degree = degree;
  s.sh.assign(sh, sh + n * sh_coefficients * 3);
  return s;
}

ObservationTables tables_from_arrays(size_t T, size_t N, const uint16_t* counts, const float* speed, const float* deficiency, const double* times,
                                     size_t M, const uint32_t* dynamic_ids, const GaussianCloud& model) {
  if (N != model.size()) throw_error("tables: ", N, " Gaussians, the model has ", model.size(), " (another model's tables?)");
  if (M != model.dynamic_ids.size() || !std::equal(dynamic_ids, dynamic_ids + M, model.dynamic_ids.begin()))
    throw_error("tables: dynamic_ids are not the model's ", model.dynamic_ids.size(), " moving Gaussians (another model's tables?)");
  if (T == 0) throw_error("tables: no times");
  for (size_t f = 0; f < T; ++f)
    if (!(times[f] >= 0.0 && times[f] <= 1.0) || (f && !(times[f] > times[f - 1])))
      throw_error("tables: times element ", f, " is ", times[f], ", expected ascending times in [0, 1]");
  ObservationTables t;
  t.times.assign(times, times + T);
  t.gaussians = N;
  t.dynamic_ids.assign(dynamic_ids, dynamic_ids + M);
  t.counts.assign(counts, counts + T * N);
  t.dynamic_speed.resize(T * M);
  t.dynamic_deficiency.resize(T * M);
  for (size_t f = 0; f < T; ++f)
    for (size_t j = 0; j < M; ++j) {
      const size_t g = f * N + dynamic_ids[j];
      if (!(speed[g] >= 0.0f && std::isfinite(speed[g]) && deficiency[g] >= 0.0f && std::isfinite(deficiency[g])))
        throw_error("tables: frame ", f, " Gaussian ", dynamic_ids[j], " has speed ", speed[g], " and deficiency ", deficiency[g],
                    ", expected finite values >= 0");
      t.dynamic_speed[f * M + j] = speed[g];
      t.dynamic_deficiency[f * M + j] = deficiency[g];
    }
  return t;
}

}  // namespace fillgs
