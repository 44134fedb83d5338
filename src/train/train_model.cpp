#include "fillgs/train/train_model.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "fillgs/base/error.hpp"
#include "fillgs/io/scene_io.hpp"
#include "model/motion_keys.hpp"

namespace fillgs {

template <typename Real>
ModelParams<Real> ModelParams<Real>::zeros_like() const {
  ModelParams z;
  z.set_zeros_like(*this);
  return z;
}

template <typename Real>
void ModelParams<Real>::set_zeros_like(const ModelParams& shape) {
  sh_degree = shape.sh_degree;
  dynamic_ids = shape.dynamic_ids;
  key_count = shape.key_count;
  first_key_time = shape.first_key_time;
  key_spacing = shape.key_spacing;
  keyed_opacity = shape.keyed_opacity;
  auto dst = arrays();
  auto src = shape.arrays();
  // Sized first, then zeroed in parallel blocks (a training step zeroes every key's gradient).
  for (size_t a = 0; a < dst.size(); ++a) dst[a]->resize(src[a]->size());
  for (std::vector<Real>* d : dst)
    tbb::parallel_for(tbb::blocked_range<size_t>(0, d->size(), size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
      std::fill(d->begin() + ptrdiff_t(r.begin()), d->begin() + ptrdiff_t(r.end()), Real(0));
    });
}

template <typename Real>
std::vector<std::vector<Real>*> ModelParams<Real>::arrays() {
  return {&means, &log_scales, &rotations, &opacity_logits, &sh, &key_positions, &key_rotations, &key_log_scales,
          &key_opacity_logits, &key_sh};
}

template <typename Real>
std::vector<const std::vector<Real>*> ModelParams<Real>::arrays() const {
  return {&means, &log_scales, &rotations, &opacity_logits, &sh, &key_positions, &key_rotations, &key_log_scales,
          &key_opacity_logits, &key_sh};
}

namespace {

using keys::KeySpot;
using keys::KeyWeights;
using keys::normalize4;
using keys::normalize4_backward;
using keys::Slerp;

}  // namespace

void shrink_key_deviations(ModelParams<float>& p, int keys, float tau_position, float tau_rotation, float tau_opacity,
                           const std::vector<uint8_t>* only, bool per_value) {
  const int K = p.key_count, n = std::min(keys, K);
  if (n < 2) return;
  FILLGS_CHECK(n <= 64);
  auto shrink = [n, per_value](float* x, int width, float tau) {
    if (per_value) {  // soft-threshold every value's steps between consecutive keys, keeping the mean
      for (int a = 0; a < width; ++a) {
        float mean = 0, y[64];
        y[0] = 0;
        for (int k = 0; k < n; ++k) mean += x[k * width + a] / float(n);
        for (int k = 1; k < n; ++k) {
          const float d = x[k * width + a] - x[(k - 1) * width + a];
          y[k] = y[k - 1] + (std::fabs(d) <= tau ? 0.0f : (d > 0 ? d - tau : d + tau));
        }
        float ym = 0;
        for (int k = 0; k < n; ++k) ym += y[k] / float(n);
        for (int k = 0; k < n; ++k) x[k * width + a] = mean + (y[k] - ym);
      }
      return;
    }
    float mean[4] = {0, 0, 0, 0};
    for (int k = 0; k < n; ++k)
      for (int a = 0; a < width; ++a) mean[a] += x[k * width + a] / float(n);
    double norm2 = 0;
    for (int k = 0; k < n; ++k)
      for (int a = 0; a < width; ++a) norm2 += double(x[k * width + a] - mean[a]) * double(x[k * width + a] - mean[a]);
    const double norm = std::sqrt(norm2);
    const float keep = norm <= double(tau) ? 0.0f : float(1.0 - double(tau) / norm);
    for (int k = 0; k < n; ++k)
      for (int a = 0; a < width; ++a) x[k * width + a] = mean[a] + keep * (x[k * width + a] - mean[a]);
  };
  tbb::parallel_for(tbb::blocked_range<size_t>(0, p.dynamic_count(), 2048), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) {
      if (only && !(*only)[p.dynamic_ids[j]]) continue;
      shrink(&p.key_positions[j * size_t(K) * 3], 3, tau_position);
      float* Q = &p.key_rotations[j * size_t(K) * 4];
      for (int k = 1; k < n; ++k) {
        float d = 0;
        for (int a = 0; a < 4; ++a) d += Q[a] * Q[4 * k + a];
        if (d < 0)
          for (int a = 0; a < 4; ++a) Q[4 * k + a] = -Q[4 * k + a];
      }
      shrink(Q, 4, tau_rotation);
      if (p.keyed_opacity) shrink(&p.key_opacity_logits[j * size_t(K)], 1, tau_opacity);
    }
  });
}

template <typename Real>
ModelParams<Real> params_from_cloud(const GaussianCloud& cloud_in, int bake_frames) {
  const GaussianCloud* cloud = &cloud_in;
  GaussianCloud baked;
  const KeyframedMotion& km = cloud_in.keyframed;
  const bool trainable_as_is =
      cloud_in.motion == MotionModel::Static ||
      (cloud_in.motion == MotionModel::Keyframed && !km.ex4dgs_edges && km.position_interp == KeyInterp::CatmullRom &&
       km.temporal_opacity.empty() && !km.rotations.empty());
  if (cloud_in.motion == MotionModel::Evaluated) {  // a network's model: keys as dense as its motion needs
    baked = keyed_for_training(cloud_in);
    cloud = &baked;
  } else if (!trainable_as_is) {
    if (bake_frames < 2)
      throw_error("model with ", to_string(cloud_in.motion),
                  " motion cannot be trained as it is; give the number of frames to bake its tracks into keys");
    baked = bake_tracks(cloud_in, bake_frames);
    cloud = &baked;
  }
  const GaussianCloud& c = *cloud;
  ModelParams<Real> p;
  const size_t N = c.size(), K = c.motion == MotionModel::Keyframed ? size_t(c.keyframed.key_count) : 0;
  p.sh_degree = c.sh_degree;
  auto copy = [](const float* src, size_t n, std::vector<Real>& dst) { dst.assign(src, src + n); };
  copy(N ? c.means[0].data() : nullptr, 3 * N, p.means);
  copy(N ? c.log_scales[0].data() : nullptr, 3 * N, p.log_scales);
  copy(N ? c.rotations[0].data() : nullptr, 4 * N, p.rotations);
  copy(c.opacity_logits.data(), N, p.opacity_logits);
  copy(c.sh.data(), c.sh.size(), p.sh);
  p.dynamic_ids = c.dynamic_ids;
  if (K) {
    const KeyframedMotion& k = c.keyframed;
    p.key_count = int(K);
    p.first_key_time = k.first_key_time;
    p.key_spacing = k.key_spacing;
    copy(k.positions.data(), k.positions.size(), p.key_positions);
    copy(k.rotations.data(), k.rotations.size(), p.key_rotations);
    copy(k.log_scales.data(), k.log_scales.size(), p.key_log_scales);
    copy(k.opacity_logits.data(), k.opacity_logits.size(), p.key_opacity_logits);
    p.keyed_opacity = !k.opacity_logits.empty();
    if (!k.colours.empty()) {  // colour in time: every coefficient per key (the constant bands repeated)
      const size_t M = c.dynamic_ids.size(), C = size_t(c.sh_count()), W = (C - 1) * 3;
      p.key_sh.resize(M * K * C * 3);
      for (size_t j = 0; j < M; ++j)
        for (size_t k2 = 0; k2 < K; ++k2) {
          Real* dst = &p.key_sh[(j * K + k2) * C * 3];
          for (size_t a = 0; a < 3; ++a) dst[a] = k.colours[(j * K + k2) * 3 + a];
          const float* rest = k.sh_rest.empty() ? &c.sh[size_t(c.dynamic_ids[j]) * C * 3 + 3] : &k.sh_rest[(j * K + k2) * W];
          for (size_t a = 0; a < W; ++a) dst[3 + a] = rest[a];
        }
    }
  }
  return p;
}

template <typename Real>
void set_key_layout(ModelParams<Real>& p, int frames, int interval) {
  FILLGS_CHECK(p.dynamic_count() == 0);  // existing keys would change meaning
  // An interval beyond the video is the video: keys at its first and last frame (and no
  // int arithmetic near INT_MAX).
  const int step = std::clamp(interval, 1, std::max(1, frames - 1));
  p.key_count = frames > 1 ? int((int64_t(frames) - 1 + step - 1) / step + 1) : 1;
  p.first_key_time = 0.0;
  p.key_spacing = frames > 1 ? double(step) / (frames - 1) : 1.0;
}

template <typename Real>
void add_key_opacities(ModelParams<Real>& p) {
  if (p.keyed_opacity) return;
  const size_t K = size_t(std::max(p.key_count, 1));
  p.key_opacity_logits.resize(p.dynamic_count() * K);
  for (size_t j = 0; j < p.dynamic_count(); ++j)
    std::fill_n(&p.key_opacity_logits[j * K], K, p.opacity_logits[p.dynamic_ids[j]]);
  p.keyed_opacity = true;
}

template <typename Real>
size_t key_every_gaussian(ModelParams<Real>& p) {
  FILLGS_CHECK(p.key_count > 0);
  const size_t N = p.size(), M = p.dynamic_count(), K = size_t(p.key_count);
  if (M == N) return 0;
  const bool keyed_scale = !p.key_log_scales.empty();
  ModelParams<Real> q = p;
  q.dynamic_ids.resize(N);
  for (uint32_t g = 0; g < N; ++g) q.dynamic_ids[g] = g;
  q.key_positions.assign(N * K * 3, Real(0));
  q.key_rotations.assign(N * K * 4, Real(0));
  if (keyed_scale) q.key_log_scales.assign(N * K * 3, Real(0));
  if (p.keyed_opacity) q.key_opacity_logits.assign(N * K, Real(0));
  const size_t S = size_t(p.sh_count()) * 3;
  if (!p.key_sh.empty()) q.key_sh.assign(N * K * S, Real(0));
  size_t j = 0;  // row of g among p's moving Gaussians
  for (uint32_t g = 0; g < N; ++g) {
    const bool moving = j < M && p.dynamic_ids[j] == g;
    for (size_t k = 0; k < K; ++k) {
      const size_t src = moving ? j * K + k : 0;
      for (int a = 0; a < 3; ++a) q.key_positions[(g * K + k) * 3 + a] = moving ? p.key_positions[src * 3 + a] : p.means[3 * g + a];
      for (int a = 0; a < 4; ++a) q.key_rotations[(g * K + k) * 4 + a] = moving ? p.key_rotations[src * 4 + a] : p.rotations[4 * g + a];
      if (keyed_scale)
        for (int a = 0; a < 3; ++a) q.key_log_scales[(g * K + k) * 3 + a] = moving ? p.key_log_scales[src * 3 + a] : p.log_scales[3 * g + a];
      if (p.keyed_opacity) q.key_opacity_logits[g * K + k] = moving ? p.key_opacity_logits[src] : p.opacity_logits[g];
      if (!p.key_sh.empty())
        std::copy_n(moving ? &p.key_sh[src * S] : &p.sh[g * S], S, &q.key_sh[(g * K + k) * S]);
    }
    if (moving) ++j;
  }
  p = std::move(q);
  return N - M;
}

void extrapolate_keys(ModelParams<float>& p, int from, float min_step) {
  const int K = p.key_count;
  FILLGS_CHECK(from >= 2);
  if (from >= K) return;
  const size_t M = p.dynamic_count(), S = size_t(p.sh_count()) * 3;
  auto hold_key_sh = [&](size_t j, int k) {  // colour keys hold the last one
    if (!p.key_sh.empty()) std::copy_n(&p.key_sh[(j * size_t(K) + size_t(k - 1)) * S], S, &p.key_sh[(j * size_t(K) + size_t(k)) * S]);
  };
  tbb::parallel_for(tbb::blocked_range<size_t>(0, M, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) {
      float* P = &p.key_positions[j * size_t(K) * 3];
      float* Q = &p.key_rotations[j * size_t(K) * 4];
      const uint32_t g = p.dynamic_ids[j];
      const float size = std::exp(std::max({p.log_scales[3 * g], p.log_scales[3 * g + 1], p.log_scales[3 * g + 2]}));
      const Vec3f last(P[3 * (from - 1)] - P[3 * (from - 2)], P[3 * (from - 1) + 1] - P[3 * (from - 2) + 1],
                       P[3 * (from - 1) + 2] - P[3 * (from - 2) + 2]);
      if (last.norm() < min_step * size) {  // no evidence of motion: hold the last key
        for (int k = from; k < K; ++k) {
          for (int a = 0; a < 3; ++a) P[3 * k + a] = P[3 * (k - 1) + a];
          for (int a = 0; a < 4; ++a) Q[4 * k + a] = Q[4 * (k - 1) + a];
          if (!p.key_log_scales.empty())
            for (int a = 0; a < 3; ++a) p.key_log_scales[(j * size_t(K) + size_t(k)) * 3 + a] = p.key_log_scales[(j * size_t(K) + size_t(k - 1)) * 3 + a];
          if (p.keyed_opacity) p.key_opacity_logits[j * size_t(K) + size_t(k)] = p.key_opacity_logits[j * size_t(K) + size_t(k - 1)];
          hold_key_sh(j, k);
        }
        continue;
      }
      for (int k = from; k < K; ++k) {
        for (int a = 0; a < 3; ++a) P[3 * k + a] = 2.0f * P[3 * (k - 1) + a] - P[3 * (k - 2) + a];
        Vec4d q0, q1;
        for (int a = 0; a < 4; ++a) q0[a] = Q[4 * (k - 2) + a], q1[a] = Q[4 * (k - 1) + a];
        q0 = q0.norm() > 1e-30 ? Vec4d(q0 / q0.norm()) : Vec4d(1, 0, 0, 0);
        q1 = q1.norm() > 1e-30 ? Vec4d(q1 / q1.norm()) : Vec4d(1, 0, 0, 0);
        if (q0.dot(q1) < 0) q0 = -q0;
        const Vec4d step = quat_mul(Vec4d(q0[0], -q0[1], -q0[2], -q0[3]), q1);
        Vec4d q2 = quat_mul(q1, step);
        q2 /= q2.norm();
        for (int a = 0; a < 4; ++a) Q[4 * k + a] = float(q2[a]);
        if (!p.key_log_scales.empty())
          for (int a = 0; a < 3; ++a) p.key_log_scales[(j * size_t(K) + size_t(k)) * 3 + a] = p.key_log_scales[(j * size_t(K) + size_t(k - 1)) * 3 + a];
        if (p.keyed_opacity) p.key_opacity_logits[j * size_t(K) + size_t(k)] = p.key_opacity_logits[j * size_t(K) + size_t(k - 1)];
        hold_key_sh(j, k);
      }
    }
  });
}

GaussianCloud cloud_from_params(const ModelParams<float>& p) {
  GaussianCloud c;
  c.sh_degree = p.sh_degree;
  const size_t N = p.size();
  c.resize(N);
  for (size_t g = 0; g < N; ++g) {
    c.means[g] = Vec3f(p.means[3 * g], p.means[3 * g + 1], p.means[3 * g + 2]);
    c.log_scales[g] = Vec3f(p.log_scales[3 * g], p.log_scales[3 * g + 1], p.log_scales[3 * g + 2]);
    c.rotations[g] = Vec4f(p.rotations[4 * g], p.rotations[4 * g + 1], p.rotations[4 * g + 2], p.rotations[4 * g + 3]);
    c.opacity_logits[g] = p.opacity_logits[g];
  }
  c.sh = p.sh;
  if (!p.dynamic_ids.empty()) {
    c.motion = MotionModel::Keyframed;
    c.dynamic_ids = p.dynamic_ids;
    KeyframedMotion& k = c.keyframed;
    k.key_count = p.key_count;
    k.first_key_time = p.first_key_time;
    k.key_spacing = p.key_spacing;
    k.positions = p.key_positions;
    k.rotations = p.key_rotations;
    k.log_scales = p.key_log_scales;
    k.opacity_logits = p.keyed_opacity ? p.key_opacity_logits : std::vector<float>{};
    if (!p.key_sh.empty()) {  // colour keys: the DC per key, and the higher bands per key where there are any
      const size_t M = p.dynamic_count(), K = size_t(p.key_count), C = size_t(p.sh_count()), W = (C - 1) * 3;
      k.colours.resize(M * K * 3);
      k.sh_rest.resize(M * K * W);
      for (size_t r = 0; r < M * K; ++r) {
        std::copy_n(&p.key_sh[r * C * 3], 3, &k.colours[r * 3]);
        std::copy_n(&p.key_sh[r * C * 3 + 3], W, k.sh_rest.data() + r * W);
      }
      for (size_t j = 0; j < M; ++j)  // the Gaussian's own SH: its first key's
        std::copy_n(&p.key_sh[j * K * C * 3], C * 3, &c.sh[size_t(p.dynamic_ids[j]) * C * 3]);
    }
    canonical_from_first_key(c);
  }
  return c;
}

/// 1 for each moving (keyed) Gaussian, 0 for a static one.
template <typename Real>
std::vector<uint8_t> keyed_mask(const ModelParams<Real>& p) {
  std::vector<uint8_t> keyed(p.size(), 0);
  for (uint32_t g : p.dynamic_ids) keyed[g] = 1;
  return keyed;
}

/// Calls f(j, g, kw) in parallel for every keyed Gaussian: j its index among the moving
/// ones, g its index, kw the cubic position weights and the key interval at time t.
template <typename Real, typename F>
void for_each_keyed(const ModelParams<Real>& p, double t, F&& f) {
  if (p.dynamic_count() == 0) return;
  const KeyWeights<Real> kw(p.first_key_time, p.key_spacing, p.key_count, t);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, p.dynamic_count(), 2048), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) f(j, p.dynamic_ids[j], kw);
  });
}

template <typename Real>
void params_at(const ModelParams<Real>& p, double t, DiffFrame<Real>* f, bool keep_for_backward) {
  t = std::clamp(t, 0.0, 1.0);
  const size_t N = p.size();
  const int K = p.key_count;
  if (f->size() != N) f->resize(N);
  f->key_state.resize(keep_for_backward ? p.dynamic_count() * size_t(Slerp<Real>::kState) : 0);
  f->kept_for_backward = keep_for_backward;
  f->sh_degree = p.sh_degree;
  f->sh = p.sh.data();
  const size_t S = size_t(p.sh_count()) * 3;
  if (!p.key_sh.empty()) {  // moving Gaussians' SH at t, in the frame's own copy
    f->sh_storage = p.sh;
    f->sh = f->sh_storage.data();
  }
  // Every Gaussian's own values first, but the mean and rotation of a moving one: its keys
  // give those below (and its scales, opacity and colour where they are keyed).
  const std::vector<uint8_t> keyed = keyed_mask(p);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, N, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t g = r.begin(); g < r.end(); ++g) {
      for (int k = 0; k < 3; ++k) f->scales[3 * g + k] = std::exp(p.log_scales[3 * g + k]);
      if (!keyed[g]) {
        for (int k = 0; k < 3; ++k) f->means[3 * g + k] = p.means[3 * g + k];
        normalize4(&p.rotations[4 * g], &f->rotations[4 * g]);
      }
      f->opacities[g] = sigmoid(p.opacity_logits[g]);
    }
  });
  for_each_keyed(p, t, [&](size_t j, uint32_t g, const KeyWeights<Real>& kw) {
    const KeySpot& ks = kw.spot;
    const Real* w = kw.w;
    const int i1 = kw.next;
    const Real* P = &p.key_positions[j * K * 3];
    for (int a = 0; a < 3; ++a) {
      Real x = 0;
      if (K == 1) {
        x = P[a];
      } else {
        for (int n = 0; n < 4; ++n) x += w[n] * P[3 * std::clamp(ks.i - 1 + n, 0, K - 1) + a];
      }
      f->means[3 * g + a] = x;
    }
    const Real* Q = &p.key_rotations[j * K * 4];
    Slerp<Real> sl;
    sl.forward(Q + 4 * ks.i, Q + 4 * i1, Real(ks.s), &f->rotations[4 * g]);
    if (keep_for_backward) sl.save(&f->key_state[j * Slerp<Real>::kState]);
    if (!p.key_log_scales.empty()) {
      const Real* S = &p.key_log_scales[j * K * 3];
      for (int a = 0; a < 3; ++a)
        f->scales[3 * g + a] = std::exp(S[3 * ks.i + a] + Real(ks.s) * (S[3 * i1 + a] - S[3 * ks.i + a]));
    }
    if (p.keyed_opacity) {
      const Real* O = &p.key_opacity_logits[j * K];
      f->opacities[g] = sigmoid(O[ks.i] + Real(ks.s) * (O[i1] - O[ks.i]));
    }
    if (!p.key_sh.empty()) {
      const Real *A = &p.key_sh[(j * K + size_t(ks.i)) * S], *B = &p.key_sh[(j * K + size_t(i1)) * S];
      Real* out = &f->sh_storage[g * S];
      for (size_t a = 0; a < S; ++a) out[a] = A[a] + Real(ks.s) * (B[a] - A[a]);
    }
  });
}

template <typename Real>
void params_at_backward(const ModelParams<Real>& p, double t, const DiffFrameGrad<Real>& gf, ModelParams<Real>* d,
                        const DiffFrame<Real>* frame) {
  t = std::clamp(t, 0.0, 1.0);
  const size_t N = p.size();
  const int K = p.key_count;
  // The forward's values where it kept them (the same parameters and time): its scales and
  // opacities are exp and sigmoid of what the backward would evaluate, and its slerps' state.
  const DiffFrame<Real>* kept = frame && frame->kept_for_backward && frame->size() == N &&
                                        frame->key_state.size() == p.dynamic_count() * size_t(Slerp<Real>::kState)
                                    ? frame
                                    : nullptr;
  // Own values (static Gaussians; for moving ones only what keys do not replace).
  const std::vector<uint8_t> keyed = keyed_mask(p);
  const size_t S = size_t(p.sh_count()) * 3;
  if (p.key_sh.empty()) {
    for (size_t i = 0; i < gf.sh.size(); ++i) d->sh[i] += gf.sh[i];
  } else {
    for (size_t g = 0; g < N; ++g)
      if (!keyed[g])
        for (size_t a = 0; a < S; ++a) d->sh[g * S + a] += gf.sh[g * S + a];
  }
  const bool keyed_scale = !p.key_log_scales.empty(), keyed_opacity = p.keyed_opacity;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, N, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t g = r.begin(); g < r.end(); ++g) {
      if (!keyed[g]) {
        for (int k = 0; k < 3; ++k) d->means[3 * g + k] += gf.means[3 * g + k];
        normalize4_backward(&p.rotations[4 * g], &gf.rotations[4 * g], &d->rotations[4 * g]);
      }
      if (!keyed[g] || !keyed_scale)
        for (int k = 0; k < 3; ++k)
          d->log_scales[3 * g + k] += gf.scales[3 * g + k] * (kept ? kept->scales[3 * g + k] : std::exp(p.log_scales[3 * g + k]));
      if (!keyed[g] || !keyed_opacity) {
        const Real o = kept ? kept->opacities[g] : sigmoid(p.opacity_logits[g]);
        d->opacity_logits[g] += gf.opacities[g] * o * (Real(1) - o);
      }
    }
  });
  for_each_keyed(p, t, [&](size_t j, uint32_t g, const KeyWeights<Real>& kw) {
    const KeySpot& ks = kw.spot;
    const Real* w = kw.w;
    const int i1 = kw.next;
    Real* dP = &d->key_positions[j * K * 3];
    for (int a = 0; a < 3; ++a) {
      if (K == 1) {
        dP[a] += gf.means[3 * g + a];
      } else {
        for (int n = 0; n < 4; ++n) dP[3 * std::clamp(ks.i - 1 + n, 0, K - 1) + a] += w[n] * gf.means[3 * g + a];
      }
    }
    const Real* Q = &p.key_rotations[j * K * 4];
    Real* dQ = &d->key_rotations[j * K * 4];
    Slerp<Real> sl;
    if (kept) {
      sl.load(&kept->key_state[j * Slerp<Real>::kState]);
    } else {
      Real out[4];
      sl.forward(Q + 4 * ks.i, Q + 4 * i1, Real(ks.s), out);
    }
    Real g0[4] = {0, 0, 0, 0}, g1[4] = {0, 0, 0, 0};
    sl.backward(&gf.rotations[4 * g], g0, g1);
    for (int k = 0; k < 4; ++k) dQ[4 * ks.i + k] += g0[k], dQ[4 * i1 + k] += g1[k];
    const Real s = Real(ks.s);
    if (keyed_scale) {
      const Real* S = &p.key_log_scales[j * K * 3];
      Real* dS = &d->key_log_scales[j * K * 3];
      for (int a = 0; a < 3; ++a) {
        const Real x = S[3 * ks.i + a] + s * (S[3 * i1 + a] - S[3 * ks.i + a]);
        const Real gx = gf.scales[3 * g + a] * (kept ? kept->scales[3 * g + a] : std::exp(x));
        dS[3 * ks.i + a] += (Real(1) - s) * gx;
        dS[3 * i1 + a] += s * gx;
      }
    }
    if (keyed_opacity) {
      const Real* O = &p.key_opacity_logits[j * K];
      Real* dO = &d->key_opacity_logits[j * K];
      const Real o = kept ? kept->opacities[g] : sigmoid(O[ks.i] + s * (O[i1] - O[ks.i]));
      const Real gx = gf.opacities[g] * o * (Real(1) - o);
      dO[ks.i] += (Real(1) - s) * gx;
      dO[i1] += s * gx;
    }
    if (!p.key_sh.empty()) {
      Real *dA = &d->key_sh[(j * K + size_t(ks.i)) * S], *dB = &d->key_sh[(j * K + size_t(i1)) * S];
      const Real* gs = &gf.sh[g * S];
      for (size_t a = 0; a < S; ++a) dA[a] += (Real(1) - s) * gs[a], dB[a] += s * gs[a];
    }
  });
}

template struct ModelParams<float>;
template struct ModelParams<double>;
template ModelParams<float> params_from_cloud<float>(const GaussianCloud&, int);
template void set_key_layout<float>(ModelParams<float>&, int, int);
template void set_key_layout<double>(ModelParams<double>&, int, int);
template size_t key_every_gaussian<float>(ModelParams<float>&);
template size_t key_every_gaussian<double>(ModelParams<double>&);
template void add_key_opacities<float>(ModelParams<float>&);
template void add_key_opacities<double>(ModelParams<double>&);
template ModelParams<double> params_from_cloud<double>(const GaussianCloud&, int);
template void params_at<float>(const ModelParams<float>&, double, DiffFrame<float>*, bool);
template void params_at<double>(const ModelParams<double>&, double, DiffFrame<double>*, bool);
template void params_at_backward<float>(const ModelParams<float>&, double, const DiffFrameGrad<float>&, ModelParams<float>*,
                                        const DiffFrame<float>*);
template void params_at_backward<double>(const ModelParams<double>&, double, const DiffFrameGrad<double>&, ModelParams<double>*,
                                         const DiffFrame<double>*);

}  // namespace fillgs
