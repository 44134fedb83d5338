#include "fillgs/model/gaussians.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/error.hpp"
#include "model/motion_keys.hpp"

namespace fillgs {

std::vector<uint32_t> GaussianCloud::static_ids() const {
  std::vector<uint32_t> ids;
  ids.reserve(static_count());
  size_t d = 0;
  for (uint32_t g = 0; g < size(); ++g) {
    if (d < dynamic_ids.size() && dynamic_ids[d] == g) {
      ++d;
      continue;
    }
    ids.push_back(g);
  }
  return ids;
}

void GaussianCloud::resize(size_t n) {
  means.resize(n, Vec3f::Zero());
  log_scales.resize(n, Vec3f::Zero());
  rotations.resize(n, Vec4f(1, 0, 0, 0));
  opacity_logits.resize(n, 0.0f);
  sh.resize(n * size_t(sh_count()) * 3, 0.0f);
}

namespace {

bool all_finite(const float* p, size_t n, size_t* bad) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) {
      *bad = i;
      return false;
    }
  return true;
}

void check_finite_array(const std::string& source, const char* what, const float* p, size_t n,
                        size_t stride) {
  size_t bad = 0;
  if (!all_finite(p, n, &bad))
    throw_error(source, ": Gaussian ", bad / stride, " has a non-finite ", what, " (", p[bad], ")");
}

}  // namespace

void GaussianCloud::validate(const std::string& source) const {
  const size_t n = size();
  if (log_scales.size() != n || rotations.size() != n || opacity_logits.size() != n ||
      sh.size() != n * size_t(sh_count()) * 3)
    throw_error(source, ": inconsistent per-Gaussian array sizes");
  if (sh_degree < 0 || sh_degree > 3) throw_error(source, ": SH degree ", sh_degree, " not in 0..3");
  check_finite_array(source, "mean", means.empty() ? nullptr : means[0].data(), 3 * n, 3);
  check_finite_array(source, "log-scale", log_scales.empty() ? nullptr : log_scales[0].data(), 3 * n, 3);
  check_finite_array(source, "rotation", rotations.empty() ? nullptr : rotations[0].data(), 4 * n, 4);
  check_finite_array(source, "opacity", opacity_logits.data(), n, 1);
  check_finite_array(source, "SH coefficient", sh.data(), sh.size(), size_t(sh_count()) * 3);
  for (size_t i = 1; i < dynamic_ids.size(); ++i)
    if (dynamic_ids[i] <= dynamic_ids[i - 1]) throw_error(source, ": dynamic ids not ascending");
  if (!dynamic_ids.empty() && dynamic_ids.back() >= n)
    throw_error(source, ": dynamic id ", dynamic_ids.back(), " out of range (", n, " Gaussians)");
  const size_t m = dynamic_ids.size();
  if (motion == MotionModel::Static && m != 0) throw_error(source, ": static model with dynamic Gaussians");
  if (motion == MotionModel::Evaluated && (!this->source || source_rows.size() != m))
    throw_error(source, ": evaluated motion without its model, or with ", source_rows.size(), " rows for ", m, " moving Gaussians");
  if (motion == MotionModel::Polynomial) {
    const auto& p = polynomial;
    if (p.coeffs.size() != 9 * m || p.omega.size() != 4 * m || p.trbf_center.size() != m ||
        p.trbf_log_scale.size() != m)
      throw_error(source, ": polynomial motion arrays do not match ", m, " dynamic Gaussians");
    check_finite_array(source, "motion coefficient", p.coeffs.data(), p.coeffs.size(), 9);
    check_finite_array(source, "omega", p.omega.data(), p.omega.size(), 4);
    check_finite_array(source, "trbf_center", p.trbf_center.data(), m, 1);
    check_finite_array(source, "trbf_scale", p.trbf_log_scale.data(), m, 1);
  }
  if (motion == MotionModel::Keyframed) {
    const auto& k = keyframed;
    const size_t K = size_t(k.key_count);
    if (K < 1) throw_error(source, ": keyframed motion with no keys");
    if (!(k.key_spacing > 0.0) || !std::isfinite(k.key_spacing) || !std::isfinite(k.first_key_time))
      throw_error(source, ": keyframed motion key spacing must be positive and finite");
    if (k.positions.size() != m * K * 3) throw_error(source, ": keyframe positions do not match");
    if (!k.rotations.empty() && k.rotations.size() != m * K * 4) throw_error(source, ": keyframe rotations do not match");
    if (!k.log_scales.empty() && k.log_scales.size() != m * K * 3) throw_error(source, ": keyframe scales do not match");
    if (!k.opacity_logits.empty() && k.opacity_logits.size() != m * K) throw_error(source, ": keyframe opacities do not match");
    if (!k.temporal_opacity.empty() && k.temporal_opacity.size() != m * 4) throw_error(source, ": temporal opacity does not match");
    if (!k.colours.empty() && k.colours.size() != m * K * 3) throw_error(source, ": keyframe colours do not match");
    check_finite_array(source, "keyframe colour", k.colours.data(), k.colours.size(), 3 * K);
    const size_t rest = size_t(sh_count() - 1) * 3;
    if (!k.sh_rest.empty() && (k.colours.empty() || k.sh_rest.size() != m * K * rest))
      throw_error(source, ": keyframe SH bands do not match");
    check_finite_array(source, "keyframe SH band", k.sh_rest.data(), k.sh_rest.size(), rest * K);
    check_finite_array(source, "keyframe position", k.positions.data(), k.positions.size(), 3 * K);
    check_finite_array(source, "keyframe rotation", k.rotations.data(), k.rotations.size(), 4 * K);
    check_finite_array(source, "keyframe scale", k.log_scales.data(), k.log_scales.size(), 3 * K);
    check_finite_array(source, "keyframe opacity", k.opacity_logits.data(), k.opacity_logits.size(), K);
    check_finite_array(source, "temporal opacity", k.temporal_opacity.data(), k.temporal_opacity.size(), 4);
  }
}

// ---------------------------------------------------------------------------------
// Motion evaluation

namespace {

struct DynamicState {
  Vec3f mean;
  Vec4f rotation;      // unit
  Vec3f log_scale;
  float opacity_logit;
  float opacity_factor;  // temporal factor multiplied after the sigmoid
  Vec3f dc = Vec3f::Zero();  // SH DC coefficients, where colour is keyed
};

struct KeyPosition {
  int i;    // interval start key
  float s;  // position within the interval (may leave [0,1] with Ex4DGS edges)
  double u; // continuous key coordinate
};

KeyPosition locate_key(const KeyframedMotion& k, double t) {
  const double u = (t - k.first_key_time) / k.key_spacing;
  const int K = k.key_count;
  if (K == 1) return {0, 0.0f, u};
  if (k.ex4dgs_edges && K >= 4) {
    const int i = int(std::floor(u > 1.0 ? std::min(u, double(K - 3)) : 1.0));  // clamped before it becomes an integer
    return {i, float(u - i), u};
  }
  const keys::KeySpot ks = keys::key_spot(k.first_key_time, k.key_spacing, K, t);
  return {ks.i, float(ks.s), u};
}

float pchip_tangent(float prev, float cur, float next) {
  const float a = next - cur, b = cur - prev;
  return (a * b > 0.0f) ? 2.0f * a * b / (next - prev) : 0.0f;
}

Vec3f interpolate_position(const KeyframedMotion& k, const float* P, const KeyPosition& kp) {
  const int K = k.key_count;
  if (K == 1) return Vec3f(P[0], P[1], P[2]);
  auto key = [&](int idx) {
    idx = std::clamp(idx, 0, K - 1);
    return Vec3f(P[3 * idx], P[3 * idx + 1], P[3 * idx + 2]);
  };
  const Vec3f p0 = key(kp.i), p1 = key(kp.i + 1);
  const float s = kp.s;
  if (k.position_interp == KeyInterp::Linear) return p0 + s * (p1 - p0);
  const Vec3f pm = key(kp.i - 1), p2 = key(kp.i + 2);
  if (k.position_interp == KeyInterp::CatmullRom) {  // the trainable path's weights (motion_keys.hpp)
    float w[4];
    keys::catmull_rom_weights(s, w);
    return w[0] * pm + w[1] * p0 + w[2] * p1 + w[3] * p2;
  }
  Vec3f m0, m1;
  for (int c = 0; c < 3; ++c) {
    m0[c] = pchip_tangent(pm[c], p0[c], p1[c]);
    m1[c] = pchip_tangent(p0[c], p1[c], p2[c]);
  }
  const float s2 = s * s, s3 = s2 * s;
  const float h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
  return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1;
}

// Ex4DGS quat_slerp_interp_uniiterval: no sign flip, clamped acos.
Vec4f slerp_ex4dgs(Vec4f q0, Vec4f q1, float s) {
  q0 = normalize_quat(q0);
  q1 = normalize_quat(q1);
  const float d = std::clamp(q0.dot(q1), -1.0f + 1e-4f, 1.0f - 1e-4f);
  const float w = std::max(std::acos(d), 1e-4f);
  const float sw = std::max(std::sin(w), 1e-4f);
  const Vec4f r = std::sin((1 - s) * w) / sw * q0 + std::sin(s * w) / sw * q1;
  if (r.cwiseAbs().sum() <= 1e-4f) return q0;
  return normalize_quat(r);
}

DynamicState keyframed_at(const GaussianCloud& c, size_t j, double t) {
  const KeyframedMotion& k = c.keyframed;
  const uint32_t g = c.dynamic_ids[j];
  const size_t K = size_t(k.key_count);
  const KeyPosition kp = locate_key(k, t);
  DynamicState st;
  st.mean = interpolate_position(k, &k.positions[j * K * 3], kp);
  const int i1 = std::min(kp.i + 1, int(K) - 1);
  if (!k.rotations.empty()) {
    const float* Q = &k.rotations[j * K * 4];
    const Vec4f q0(Q[4 * kp.i], Q[4 * kp.i + 1], Q[4 * kp.i + 2], Q[4 * kp.i + 3]);
    const Vec4f q1(Q[4 * i1], Q[4 * i1 + 1], Q[4 * i1 + 2], Q[4 * i1 + 3]);
    if (k.ex4dgs_edges) {
      st.rotation = slerp_ex4dgs(q0, q1, kp.s);
    } else {  // the trainable path's slerp (motion_keys.hpp)
      keys::Slerp<float> slerp;
      slerp.forward(q0.data(), q1.data(), kp.s, st.rotation.data());
    }
  } else {
    st.rotation = normalize_quat(c.rotations[g]);
  }
  if (!k.log_scales.empty()) {
    const float* S = &k.log_scales[j * K * 3];
    for (int a = 0; a < 3; ++a) st.log_scale[a] = S[3 * kp.i + a] + kp.s * (S[3 * i1 + a] - S[3 * kp.i + a]);
  } else {
    st.log_scale = c.log_scales[g];
  }
  if (!k.opacity_logits.empty()) {
    const float* O = &k.opacity_logits[j * K];
    st.opacity_logit = O[kp.i] + kp.s * (O[i1] - O[kp.i]);
  } else {
    st.opacity_logit = c.opacity_logits[g];
  }
  if (!k.colours.empty()) {
    const float* C = &k.colours[j * K * 3];
    for (int a = 0; a < 3; ++a) st.dc[a] = C[3 * kp.i + a] + kp.s * (C[3 * i1 + a] - C[3 * kp.i + a]);
  }
  st.opacity_factor = 1.0f;
  if (!k.temporal_opacity.empty()) {
    const float* T = &k.temporal_opacity[j * 4];
    const double c0 = T[0], c1 = T[1], v0 = T[2], v1 = T[3];
    const double tau = kp.u;
    if ((c0 - tau) * (c1 - tau) >= 0.0) {
      const double m = tau - std::max(c0, c1);
      const double v = (tau > c0 || tau > c1) ? v1 : v0;
      const double w = std::exp(v) + k.temporal_width_pad;
      st.opacity_factor = float(std::exp(-(m * m) / (w * w)));
    }
  }
  return st;
}

/// The higher SH bands of keyed Gaussian j at t (KeyframedMotion::sh_rest), linearly.
void keyed_rest_at(const GaussianCloud& c, size_t j, double t, float* out) {
  const KeyframedMotion& k = c.keyframed;
  const size_t K = size_t(k.key_count), W = size_t(c.sh_count() - 1) * 3;
  const KeyPosition kp = locate_key(k, t);
  const size_t i0 = size_t(kp.i), i1 = size_t(std::min(kp.i + 1, int(K) - 1));
  const float* R = &k.sh_rest[j * K * W];
  for (size_t a = 0; a < W; ++a) out[a] = R[i0 * W + a] + kp.s * (R[i1 * W + a] - R[i0 * W + a]);
}

DynamicState polynomial_at(const GaussianCloud& c, size_t j, double t) {
  const PolynomialMotion& p = c.polynomial;
  const uint32_t g = c.dynamic_ids[j];
  const float d = float(t * p.time_scale - double(p.trbf_center[j]));
  const float* m = &p.coeffs[9 * j];
  DynamicState st;
  const float d2 = d * d, d3 = d2 * d;
  for (int a = 0; a < 3; ++a) st.mean[a] = c.means[g][a] + m[a] * d + m[3 + a] * d2 + m[6 + a] * d3;
  const Vec4f w(p.omega[4 * j], p.omega[4 * j + 1], p.omega[4 * j + 2], p.omega[4 * j + 3]);
  st.rotation = normalize_quat(c.rotations[g] + d * w);
  st.log_scale = c.log_scales[g];
  st.opacity_logit = c.opacity_logits[g];
  const float r = d / std::exp(p.trbf_log_scale[j]);
  st.opacity_factor = std::exp(-r * r);
  return st;
}

/// The dynamic set of an evaluated cloud at time t (one call to its source).
std::shared_ptr<const ModelState> evaluated_at(const GaussianCloud& c, double t) {
  std::shared_ptr<const ModelState> s = c.source->evaluate(t, c.source_rows);
  if (!s || s->size() != c.dynamic_ids.size() || s->sh.size() != s->size() * size_t(c.sh_count()) * 3)
    throw_error("evaluated motion: the model returned ", s ? s->size() : 0, " Gaussians for ", c.dynamic_ids.size());
  return s;
}

DynamicState dynamic_at(const GaussianCloud& c, size_t j, double t) {
  return c.motion == MotionModel::Polynomial ? polynomial_at(c, j, t) : keyframed_at(c, j, t);
}

void write_static(const GaussianCloud& c, FrameGaussians& f, size_t g) {
  f.means[g] = c.means[g];
  f.scales[g] = c.log_scales[g].array().exp();
  f.rotations[g] = normalize_quat(c.rotations[g]);
  f.opacities[g] = sigmoid(c.opacity_logits[g]);
}

}  // namespace

ModelState ModelState::rows(const std::vector<uint32_t>& r) const {
  ModelState o;
  rows_into(r, o);
  return o;
}

void ModelState::rows_into(const std::vector<uint32_t>& r, ModelState& o) const {
  o.sh_degree = sh_degree;
  const size_t row = size_t(sh_degree + 1) * size_t(sh_degree + 1) * 3;
  o.means.resize(r.size());
  o.log_scales.resize(r.size());
  o.rotations.resize(r.size());
  o.opacity_logits.resize(r.size());
  o.opacity_factor.resize(opacity_factor.empty() ? 0 : r.size());
  o.sh.resize(r.size() * row);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, r.size(), 4096), [&](const tbb::blocked_range<size_t>& b) {
    for (size_t i = b.begin(); i < b.end(); ++i) {
      const size_t g = r[i];
      o.means[i] = means[g];
      o.log_scales[i] = log_scales[g];
      o.rotations[i] = rotations[g];
      o.opacity_logits[i] = opacity_logits[g];
      if (!opacity_factor.empty()) o.opacity_factor[i] = opacity_factor[g];
      std::copy_n(&sh[g * row], row, &o.sh[i * row]);
    }
  });
}

FrameSampler::FrameSampler(const GaussianCloud& cloud) : cloud_(cloud) {
  const size_t n = cloud.size();
  frame_.sh_degree = cloud.sh_degree;
  frame_.sh = cloud.sh.data();
  if ((cloud.motion == MotionModel::Keyframed && !cloud.keyframed.colours.empty()) || cloud.motion == MotionModel::Evaluated) {
    frame_.sh_storage = cloud.sh;
    frame_.sh = frame_.sh_storage.data();
  }
  frame_.means.resize(n);
  frame_.scales.resize(n);
  frame_.rotations.resize(n);
  frame_.opacities.resize(n);
  frame_.time = -1.0;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t g = r.begin(); g < r.end(); ++g) write_static(cloud, frame_, g);
  });
}

const FrameGaussians& FrameSampler::at(double t) {
  t = std::clamp(t, 0.0, 1.0);
  if (t == frame_.time) return frame_;
  frame_.time = t;
  const GaussianCloud& c = cloud_;
  if (c.motion == MotionModel::Evaluated) {
    // Exactly at t, every SH coefficient included: the model's own evaluation, not keys.
    state_ = evaluated_at(c, t);
    const ModelState& st = *state_;
    const size_t row = size_t(c.sh_count()) * 3;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, c.dynamic_ids.size(), 2048), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t j = r.begin(); j < r.end(); ++j) {
        const uint32_t g = c.dynamic_ids[j];
        frame_.means[g] = st.means[j];
        frame_.scales[g] = st.log_scales[j].array().exp();
        frame_.rotations[g] = normalize_quat(st.rotations[j]);
        frame_.opacities[g] = sigmoid(st.opacity_logits[j]) * (st.opacity_factor.empty() ? 1.0f : st.opacity_factor[j]);
        std::copy_n(&st.sh[j * row], row, &frame_.sh_storage[size_t(g) * row]);
      }
    });
    return frame_;
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, c.dynamic_ids.size(), 2048),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t j = r.begin(); j < r.end(); ++j) {
                        const DynamicState st = dynamic_at(c, j, t);
                        const uint32_t g = c.dynamic_ids[j];
                        frame_.means[g] = st.mean;
                        frame_.scales[g] = st.log_scale.array().exp();
                        frame_.rotations[g] = st.rotation;
                        frame_.opacities[g] = sigmoid(st.opacity_logit) * st.opacity_factor;
                        if (!frame_.sh_storage.empty())
                          for (int a = 0; a < 3; ++a) frame_.sh_storage[size_t(g) * size_t(c.sh_count()) * 3 + size_t(a)] = st.dc[a];
                        if (!c.keyframed.sh_rest.empty()) keyed_rest_at(c, j, t, &frame_.sh_storage[size_t(g) * size_t(c.sh_count()) * 3 + 3]);
                      }
                    });
  return frame_;
}

FrameGaussians frame_at(const GaussianCloud& cloud, double t) {
  FrameSampler ev(cloud);
  FrameGaussians f = ev.at(t);
  if (!f.sh_storage.empty()) f.sh = f.sh_storage.data();  // the copy's own SH, not the sampler's
  return f;
}

double model_time(const GaussianCloud& cloud, double t) {
  if (!(t >= 0.0 && t <= 1.0)) throw_error("t must be in [0, 1], got ", t);
  return cloud.model_time_first + t * (cloud.model_time_last - cloud.model_time_first);
}

double normalised_time(const GaussianCloud& cloud, double model_time) {
  const double a = cloud.model_time_first, b = cloud.model_time_last;
  if (!std::isfinite(model_time)) throw_error("model time ", model_time, " is not a number");
  if (a == b) {
    if (model_time != a) throw_error("model time ", model_time, ": the model covers only its time ", a);
    return 0.0;
  }
  const double t = (model_time - a) / (b - a), slack = 1e-9;
  if (!(t >= -slack && t <= 1.0 + slack))
    throw_error("model time ", model_time, " lies outside the times the model covers (", a, " … ", b, ")");
  return std::clamp(t, 0.0, 1.0);
}

void dynamic_means_at(const GaussianCloud& cloud, double t, std::vector<Vec3f>& out) {
  t = std::clamp(t, 0.0, 1.0);
  out.resize(cloud.dynamic_ids.size());
  if (cloud.motion == MotionModel::Evaluated) {
    out = evaluated_at(cloud, t)->means;
    return;
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, out.size(), 2048), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) out[j] = dynamic_at(cloud, j, t).mean;
  });
}

// ---------------------------------------------------------------------------------
// Static / dynamic partition

namespace {

template <typename T>
void keep_rows(std::vector<T>& v, size_t row, const std::vector<char>& keep) {
  if (v.empty()) return;
  size_t w = 0;
  for (size_t j = 0; j < keep.size(); ++j) {
    if (!keep[j]) continue;
    if (w != j) std::copy(v.begin() + j * row, v.begin() + (j + 1) * row, v.begin() + w * row);
    ++w;
  }
  v.resize(w * row);
}

bool rows_constant(const std::vector<float>& v, size_t j, size_t K, size_t width) {
  if (v.empty()) return true;
  const float* r = &v[j * K * width];
  for (size_t k = 1; k < K; ++k)
    for (size_t a = 0; a < width; ++a)
      if (std::fabs(r[k * width + a] - r[a]) > 1e-6f * (1.0f + std::fabs(r[a]))) return false;
  return true;
}

}  // namespace

size_t partition_static_dynamic(GaussianCloud& c, const PartitionOptions& opt) {
  const size_t m = c.dynamic_ids.size();
  if (m == 0) {
    c.motion = MotionModel::Static;
    c.source.reset();
    return 0;
  }
  if (c.motion == MotionModel::Evaluated) return 0;  // its reader applied the static rule (io/trained_models.hpp)
  std::vector<char> keep(m, 1);
  std::vector<Vec3f> frozen(m);
  if (c.motion == MotionModel::Keyframed) {
    const KeyframedMotion& k = c.keyframed;
    const size_t K = size_t(k.key_count);
    for (size_t j = 0; j < m; ++j) {
      const float* P = &k.positions[j * K * 3];
      float max_speed = 0.0f;
      Vec3f sum = Vec3f::Zero();
      for (size_t i = 0; i < K; ++i) {
        sum += Vec3f(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
        if (i + 1 < K) {
          const Vec3f d(P[3 * i + 3] - P[3 * i], P[3 * i + 4] - P[3 * i + 1], P[3 * i + 5] - P[3 * i + 2]);
          max_speed = std::max(max_speed, float(d.norm() / k.key_spacing));
        }
      }
      const bool still = max_speed <= opt.static_speed_threshold && rows_constant(k.rotations, j, K, 4) &&
                         rows_constant(k.log_scales, j, K, 3) && rows_constant(k.opacity_logits, j, K, 1) &&
                         rows_constant(k.colours, j, K, 3) && rows_constant(k.sh_rest, j, K, size_t(c.sh_count() - 1) * 3) &&
                         k.temporal_opacity.empty();
      if (still) {
        keep[j] = 0;
        frozen[j] = max_speed == 0.0f ? Vec3f(P[0], P[1], P[2]) : Vec3f(sum / float(K));  // keys all equal: keep them exactly
      }
    }
  } else if (c.motion == MotionModel::Polynomial) {
    const PolynomialMotion& p = c.polynomial;
    for (size_t j = 0; j < m; ++j) {
      const float* w = &p.omega[4 * j];
      if (w[0] != 0.0f || w[1] != 0.0f || w[2] != 0.0f || w[3] != 0.0f) continue;
      // The temporal RBF must leave opacity unchanged (factor > 1 - 1e-6) over [0, 1].
      const double s = std::exp(double(p.trbf_log_scale[j]));
      const double dmax = std::max(std::fabs(0.0 - p.trbf_center[j]), std::fabs(p.time_scale - p.trbf_center[j]));
      if ((dmax / s) * (dmax / s) > 1e-6) continue;
      float max_speed = 0.0f;
      Vec3f sum = Vec3f::Zero();
      Vec3f prev = Vec3f::Zero();
      for (int i = 0; i <= opt.samples; ++i) {
        const double t = double(i) / opt.samples;
        const Vec3f x = polynomial_at(c, j, t).mean;
        sum += x;
        if (i > 0) max_speed = std::max(max_speed, float((x - prev).norm() * opt.samples));
        prev = x;
      }
      if (max_speed <= opt.static_speed_threshold) {
        keep[j] = 0;
        frozen[j] = sum / float(opt.samples + 1);
      }
    }
  }
  size_t moved = 0;
  std::vector<uint32_t> ids;
  for (size_t j = 0; j < m; ++j) {
    if (keep[j]) {
      ids.push_back(c.dynamic_ids[j]);
      continue;
    }
    const uint32_t g = c.dynamic_ids[j];
    c.means[g] = frozen[j];
    if (c.motion == MotionModel::Keyframed) {
      const size_t K = size_t(c.keyframed.key_count);
      if (!c.keyframed.rotations.empty()) c.rotations[g] = Eigen::Map<const Vec4f>(&c.keyframed.rotations[j * K * 4]);
      if (!c.keyframed.log_scales.empty()) c.log_scales[g] = Eigen::Map<const Vec3f>(&c.keyframed.log_scales[j * K * 3]);
      if (!c.keyframed.opacity_logits.empty()) c.opacity_logits[g] = c.keyframed.opacity_logits[j * K];
      if (!c.keyframed.colours.empty())
        for (int a = 0; a < 3; ++a) c.sh[size_t(g) * size_t(c.sh_count()) * 3 + size_t(a)] = c.keyframed.colours[j * K * 3 + size_t(a)];
      const size_t W = size_t(c.sh_count() - 1) * 3;
      if (!c.keyframed.sh_rest.empty())
        std::copy_n(&c.keyframed.sh_rest[j * K * W], W, &c.sh[size_t(g) * size_t(c.sh_count()) * 3 + 3]);
    }
    ++moved;
  }
  if (c.motion == MotionModel::Keyframed) {
    auto& k = c.keyframed;
    const size_t K = size_t(k.key_count);
    keep_rows(k.positions, K * 3, keep);
    keep_rows(k.rotations, K * 4, keep);
    keep_rows(k.log_scales, K * 3, keep);
    keep_rows(k.opacity_logits, K, keep);
    keep_rows(k.colours, K * 3, keep);
    keep_rows(k.sh_rest, K * size_t(c.sh_count() - 1) * 3, keep);
    keep_rows(k.temporal_opacity, 4, keep);
  } else {
    auto& p = c.polynomial;
    keep_rows(p.coeffs, 9, keep);
    keep_rows(p.omega, 4, keep);
    keep_rows(p.trbf_center, 1, keep);
    keep_rows(p.trbf_log_scale, 1, keep);
  }
  c.dynamic_ids = std::move(ids);
  if (c.dynamic_ids.empty()) c.motion = MotionModel::Static;
  return moved;
}

size_t fold_still_keys(GaussianCloud& c, const StillTolerance& tol) {
  if (c.motion != MotionModel::Keyframed || c.dynamic_ids.empty()) return 0;
  KeyframedMotion& k = c.keyframed;
  const size_t K = size_t(k.key_count), M = c.dynamic_ids.size();
  if (K < 2 || !k.temporal_opacity.empty()) return 0;
  const float cos_half = std::cos(float(tol.rotation_degrees * kPi / 360.0));
  std::vector<uint8_t> still(M, 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, M, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) {
      float* P = &k.positions[j * K * 3];
      Vec3f pm = Vec3f::Zero();
      for (size_t i = 0; i < K; ++i) pm += Eigen::Map<const Vec3f>(P + 3 * i) / float(K);
      bool ok = true;
      for (size_t i = 0; i < K && ok; ++i) ok = (Eigen::Map<const Vec3f>(P + 3 * i) - pm).norm() <= tol.position;
      Vec4f qm = Vec4f::Zero();
      if (ok && !k.rotations.empty()) {
        const float* Q = &k.rotations[j * K * 4];
        const Vec4f q0 = normalize_quat(Eigen::Map<const Vec4f>(Q));
        for (size_t i = 0; i < K; ++i) {
          const Vec4f q = normalize_quat(Eigen::Map<const Vec4f>(Q + 4 * i));
          qm += q.dot(q0) < 0 ? Vec4f(-q) : q;
        }
        qm = normalize_quat(qm);
        for (size_t i = 0; i < K && ok; ++i) ok = std::fabs(normalize_quat(Eigen::Map<const Vec4f>(Q + 4 * i)).dot(qm)) >= cos_half;
      }
      float om = 0;
      if (ok && !k.opacity_logits.empty()) {
        const float* O = &k.opacity_logits[j * K];
        for (size_t i = 0; i < K; ++i) om += O[i] / float(K);
        for (size_t i = 0; i < K && ok; ++i) ok = std::fabs(O[i] - om) <= tol.opacity_logit;
      }
      if (!ok || !k.log_scales.empty()) continue;
      still[j] = 1;
      for (size_t i = 0; i < K; ++i) {
        Eigen::Map<Vec3f>(P + 3 * i) = pm;
        if (!k.rotations.empty()) Eigen::Map<Vec4f>(&k.rotations[(j * K + i) * 4]) = qm;
        if (!k.opacity_logits.empty()) k.opacity_logits[j * K + i] = om;
      }
    }
  });
  return size_t(std::count(still.begin(), still.end(), 1));
}

void static_first(GaussianCloud& c) {
  std::vector<uint32_t> order = c.static_ids();
  const size_t S = order.size();
  order.insert(order.end(), c.dynamic_ids.begin(), c.dynamic_ids.end());
  bool identity = true;
  for (size_t i = 0; i < order.size() && identity; ++i) identity = order[i] == i;
  if (identity) return;
  auto permute = [&](auto& v, size_t width) {
    auto out = v;
    for (size_t i = 0; i < order.size(); ++i)
      std::copy(v.begin() + ptrdiff_t(order[i] * width), v.begin() + ptrdiff_t((order[i] + 1) * width), out.begin() + ptrdiff_t(i * width));
    v = std::move(out);
  };
  permute(c.means, 1);
  permute(c.log_scales, 1);
  permute(c.rotations, 1);
  permute(c.opacity_logits, 1);
  permute(c.sh, size_t(c.sh_count()) * 3);
  for (size_t j = 0; j < c.dynamic_ids.size(); ++j) c.dynamic_ids[j] = uint32_t(S + j);
}

KeyframedMotion per_frame_tracks(size_t gaussians, int frames) {
  FILLGS_CHECK(frames >= 2);
  KeyframedMotion k;
  k.key_count = frames;
  k.first_key_time = 0.0;
  k.key_spacing = FrameGrid(frames).step();  // one key per frame
  k.positions.assign(gaussians * size_t(frames) * 3, 0.0f);
  k.rotations.assign(gaussians * size_t(frames) * 4, 0.0f);
  return k;
}

void canonical_from_first_key(GaussianCloud& c) {
  FILLGS_CHECK(c.motion == MotionModel::Keyframed);
  const KeyframedMotion& k = c.keyframed;
  const size_t K = size_t(k.key_count);
  for (size_t j = 0; j < c.dynamic_ids.size(); ++j) {
    const uint32_t g = c.dynamic_ids[j];
    c.means[g] = Eigen::Map<const Vec3f>(&k.positions[j * K * 3]);
    if (!k.rotations.empty()) c.rotations[g] = Eigen::Map<const Vec4f>(&k.rotations[j * K * 4]);
  }
}

int motion_frames(const GaussianCloud& c) {
  if (c.motion == MotionModel::Keyframed) return c.keyframed.key_count;
  if (c.motion == MotionModel::Evaluated && c.source) return c.source->frame_count();
  return 0;
}

std::pair<Vec3f, Vec3f> bounding_box(const GaussianCloud& cloud) {
  Vec3f lo = Vec3f::Constant(std::numeric_limits<float>::infinity());
  Vec3f hi = -lo;
  for (const Vec3f& p : cloud.means) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

}  // namespace fillgs
