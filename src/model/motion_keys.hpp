#pragma once
// Keyframe motion shared by the frame sampler (frame_at(t), gaussians.cpp) and the
// trainable parameters (params_at, train_model.cpp), templated on the scalar:
// where t falls among the keys, the Catmull-Rom weights of the four keys around it (end
// keys repeated), and the shortest-arc slerp of normalised key quaternions with its
// backward. One definition, so that what trains is what renders.
#include <algorithm>
#include <cmath>

namespace fillgs::keys {

/// Where t falls among the keys: interval start i and position s in it (fillgs convention:
/// t clamped to the keys, i in [0, K − 2]).
struct KeySpot {
  int i = 0;
  double s = 0.0;
};

/// The norm normalize4 divides by.
template <typename Real>
Real norm4(const Real* x) {
  return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3]);
}

/// Whether normalize4 divides by n (else it returns the identity, and its backward is 0).
template <typename Real>
bool normalizable(Real n) {
  return n > Real(1e-30) && std::isfinite(n);
}

/// y = x / |x| (identity quaternion for a zero vector, as normalize_quat); returns |x|.
template <typename Real>
Real normalize4(const Real* x, Real* y) {
  const Real n = norm4(x);
  if (!normalizable(n)) {
    y[0] = Real(1), y[1] = y[2] = y[3] = Real(0);
    return n;
  }
  for (int k = 0; k < 4; ++k) y[k] = x[k] / n;
  return n;
}

/// dL/dx of y = x/|x| given dL/dy, added into gx, from the forward's n = |x| and y.
template <typename Real>
void normalize4_backward_from(Real n, const Real* y, const Real* gy, Real* gx) {
  if (!normalizable(n)) return;
  Real dot = 0;
  for (int k = 0; k < 4; ++k) dot += gy[k] * y[k];
  for (int k = 0; k < 4; ++k) gx[k] += (gy[k] - dot * y[k]) / n;
}

/// dL/dx of y = x/|x| given dL/dy, added into gx.
template <typename Real>
void normalize4_backward(const Real* x, const Real* gy, Real* gx) {
  const Real n = norm4(x);
  if (!normalizable(n)) return;
  Real y[4];
  for (int k = 0; k < 4; ++k) y[k] = x[k] / n;
  normalize4_backward_from(n, y, gy, gx);
}

/// The key interval of time t for K keys spaced `key_spacing` from `first_key_time`.
inline KeySpot key_spot(double first_key_time, double key_spacing, int K, double t) {
  if (K <= 1) return {};
  // Clamped before any integer is made: a NaN or huge time is key 0 or the last key, never
  // an out-of-range index (times are validated where they enter; this is the last guard).
  const double r = (t - first_key_time) / key_spacing;
  const double u = r > 0.0 ? std::min(r, double(K - 1)) : 0.0;
  const int i = std::min(int(std::floor(u)), K - 2);
  return {i, u - i};
}

/// Catmull-Rom weights of keys i−1, i, i+1, i+2 (end keys repeated) at position s.
template <typename Real>
void catmull_rom_weights(Real s, Real w[4]) {
  const Real s2 = s * s, s3 = s2 * s;
  const Real h00 = Real(2) * s3 - Real(3) * s2 + Real(1), h10 = s3 - Real(2) * s2 + s;
  const Real h01 = Real(-2) * s3 + Real(3) * s2, h11 = s3 - s2;
  w[0] = Real(-0.5) * h10;
  w[1] = h00 - Real(0.5) * h11;
  w[2] = h01 + Real(0.5) * h10;
  w[3] = Real(0.5) * h11;
}

/// The interval of time t and the Catmull-Rom weights of its four keys.
template <typename Real>
struct KeyWeights {
  KeySpot spot;
  Real w[4];
  int next;  // the interval's second key
  KeyWeights(double first_key_time, double key_spacing, int K, double t)
      : spot(key_spot(first_key_time, key_spacing, K, t)), next(std::min(spot.i + 1, K - 1)) {
    catmull_rom_weights(Real(spot.s), w);
  }
};

/// Shortest-arc slerp of normalised keys, exactly slerp_shortest's rule (normalised lerp
/// above a dot of 0.9995), with its backward. The forward keeps what the backward needs
/// (norms, normalised values, sines), so the backward evaluates no square root, no arcus and
/// only the cosines; save/load carry that state between a forward and a later backward.
template <typename Real>
struct Slerp {
  Real q0[4], q1[4];  // normalised keys; q1 sign-flipped onto q0's hemisphere
  bool flipped = false, linear = false;
  Real s = 0, w = 0;
  Real n0 = 0, n1 = 0, n_out = 0;  // |k0|, |k1|, |raw| (raw: the blend before its normalisation)
  Real out[4];                     // the normalised blend
  Real sw = 0, sa = 0, sb = 0;     // sin w, sin((1 − s)w), sin(sw)
  void forward(const Real* k0, const Real* k1, Real s_in, Real* result) {
    s = s_in;
    n0 = normalize4(k0, q0);
    n1 = normalize4(k1, q1);
    Real d = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3];
    if (d < Real(0)) {
      for (Real& c : q1) c = -c;
      d = -d;
      flipped = true;
    }
    Real raw[4];
    if (d > Real(0.9995)) {
      linear = true;
      for (int k = 0; k < 4; ++k) raw[k] = q0[k] + s * (q1[k] - q0[k]);
    } else {
      w = std::acos(std::min(d, Real(1)));
      sw = std::sin(w);
      sa = std::sin((Real(1) - s) * w), sb = std::sin(s * w);
      const Real a = sa / sw, b = sb / sw;
      for (int k = 0; k < 4; ++k) raw[k] = a * q0[k] + b * q1[k];
    }
    n_out = normalize4(raw, out);
    for (int k = 0; k < 4; ++k) result[k] = out[k];
  }
  /// Adds dL/dk0, dL/dk1 (the raw keys of the forward) for dL/dresult.
  void backward(const Real* g_result, Real* g_k0, Real* g_k1) const {
    Real g_raw[4] = {0, 0, 0, 0}, g0[4] = {0, 0, 0, 0}, g1[4] = {0, 0, 0, 0};
    normalize4_backward_from(n_out, out, g_result, g_raw);
    if (linear) {
      for (int k = 0; k < 4; ++k) g0[k] = (Real(1) - s) * g_raw[k], g1[k] = s * g_raw[k];
    } else {
      const Real cw = std::cos(w);
      const Real a = sa / sw, b = sb / sw;
      const Real da = ((Real(1) - s) * std::cos((Real(1) - s) * w) * sw - sa * cw) / (sw * sw);
      const Real db = (s * std::cos(s * w) * sw - sb * cw) / (sw * sw);
      Real gw = 0;
      for (int k = 0; k < 4; ++k) gw += g_raw[k] * (da * q0[k] + db * q1[k]);
      const Real gd = gw * (Real(-1) / sw);  // w = acos(d)
      for (int k = 0; k < 4; ++k) {
        g0[k] = a * g_raw[k] + gd * q1[k];
        g1[k] = b * g_raw[k] + gd * q0[k];
      }
    }
    if (flipped)
      for (Real& c : g1) c = -c;
    // k1 / |k1| is q1 before its flip.
    Real y1[4];
    for (int k = 0; k < 4; ++k) y1[k] = flipped ? -q1[k] : q1[k];
    normalize4_backward_from(n0, q0, g0, g_k0);
    normalize4_backward_from(n1, y1, g1, g_k1);
  }
  /// The state as kState values, and back.
  static constexpr int kState = 22;
  void save(Real* o) const {
    for (int k = 0; k < 4; ++k) o[k] = q0[k], o[4 + k] = q1[k], o[8 + k] = out[k];
    o[12] = s, o[13] = w, o[14] = n0, o[15] = n1, o[16] = n_out, o[17] = sw, o[18] = sa, o[19] = sb;
    o[20] = flipped ? Real(1) : Real(0), o[21] = linear ? Real(1) : Real(0);
  }
  void load(const Real* in) {
    for (int k = 0; k < 4; ++k) q0[k] = in[k], q1[k] = in[4 + k], out[k] = in[8 + k];
    s = in[12], w = in[13], n0 = in[14], n1 = in[15], n_out = in[16], sw = in[17], sa = in[18], sb = in[19];
    flipped = in[20] != Real(0), linear = in[21] != Real(0);
  }
};


}  // namespace fillgs::keys
