#pragma once
// Helpers shared by the benchmarks: where the shared data is, orbit cameras around a scene.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "fillgs/model/camera.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/timing.hpp"

namespace fillgs::bench {

/// The core's clock as the kernel reports it (first "cpu MHz" of /proc/cpuinfo), GHz; 0 if unknown.
inline double reported_clock_ghz() {
  std::FILE* f = std::fopen("/proc/cpuinfo", "r");
  if (!f) return 0;
  char line[256];
  double mhz = 0;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "cpu MHz : %lf", &mhz) == 1) break;
  std::fclose(f);
  return mhz / 1000.0;
}

/// The clock the core runs at now, GHz: a chain of dependent register adds (one a cycle on
/// x86 cores; a chain of 3-cycle multiplies gives the same clock on the AMD EPYC here) timed
/// in 20 short trials, the fastest counted (a trial the scheduler
/// interrupted is slower, never faster). The nominal clock /proc/cpuinfo reports can lie
/// below a boosting core's, which made shares of a bound read above 100 %. Elsewhere, or
/// where the chain cannot be timed: the reported clock.
inline double clock_ghz() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  constexpr uint64_t kIterations = 2000000;  // x 8 dependent adds: about 6 ms at 2.6 GHz
  double best = 0;
  for (int trial = 0; trial < 20; ++trial) {
    uint64_t x = 0;
    const uint64_t one = 1;  // a register operand: some cores fold chains of immediate adds
    const auto t0 = std::chrono::steady_clock::now();
    for (uint64_t i = 0; i < kIterations; ++i)
      asm volatile("add %1, %0\n\tadd %1, %0\n\tadd %1, %0\n\tadd %1, %0\n\tadd %1, %0\n\tadd %1, %0\n\tadd %1, %0\n\tadd %1, %0"
                   : "+r"(x)
                   : "r"(one));
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s > 0) best = std::max(best, double(x) / s / 1e9);
  }
  if (best > 0) return best;
#endif
  return reported_clock_ghz();
}

/// Ranks of x from 0, ties sharing their mean rank.
inline std::vector<double> ranks(const std::vector<double>& x) {
  std::vector<size_t> o(x.size());
  std::iota(o.begin(), o.end(), 0);
  std::sort(o.begin(), o.end(), [&](size_t a, size_t b) { return x[a] < x[b]; });
  std::vector<double> r(x.size());
  for (size_t i = 0; i < o.size();) {
    size_t j = i;
    while (j + 1 < o.size() && x[o[j + 1]] == x[o[i]]) ++j;
    for (size_t k = i; k <= j; ++k) r[o[k]] = 0.5 * double(i + j);
    i = j + 1;
  }
  return r;
}

/// Spearman's rank correlation of a and b (ties share their mean rank); 1 where either is constant.
inline double spearman(const std::vector<double>& a, const std::vector<double>& b) {
  const std::vector<double> ra = ranks(a), rb = ranks(b);
  const double ma = std::accumulate(ra.begin(), ra.end(), 0.0) / double(ra.size());
  const double mb = std::accumulate(rb.begin(), rb.end(), 0.0) / double(rb.size());
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < ra.size(); ++i) {
    sab += (ra[i] - ma) * (rb[i] - mb);
    saa += (ra[i] - ma) * (ra[i] - ma);
    sbb += (rb[i] - mb) * (rb[i] - mb);
  }
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 1.0;
}

/// A path as a results file names it: under the shared data as "shared/data/...", else by
/// its file name; never the absolute path of the machine that ran the benchmark.
inline std::string shown_path(const std::string& path) {
  const std::string shared = std::filesystem::weakly_canonical(shared_data_dir()).string();
  const std::string p = std::filesystem::weakly_canonical(path).string();
  if (p.size() > shared.size() && p.compare(0, shared.size(), shared) == 0 && p[shared.size()] == '/') return "shared/data" + p.substr(shared.size());
  return std::filesystem::path(path).filename().string();
}

using fillgs::Clock;
using fillgs::seconds_since;

inline std::vector<Camera> orbit(const GaussianCloud& c, int n, int w, int h) {
  // Robust centre and radius: median of the means, 90th percentile distance.
  std::vector<float> xs, ys, zs;
  for (const Vec3f& p : c.means) {
    xs.push_back(p.x());
    ys.push_back(p.y());
    zs.push_back(p.z());
  }
  auto median = [](std::vector<float> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const Vec3d centre(median(xs), median(ys), median(zs));
  std::vector<float> d;
  for (const Vec3f& p : c.means) d.push_back(float((p.cast<double>() - centre).norm()));
  std::nth_element(d.begin(), d.begin() + d.size() * 9 / 10, d.end());
  RingPlacement r;
  r.count = n;
  r.centre = centre;
  r.radius = 2.2 * d[d.size() * 9 / 10];
  r.elevation = -(r.radius * 0.3);
  r.up = Vec3d(0, -1, 0);
  r.prefix = "orbit";
  Camera lens;
  lens.set_fov_x(60.0 * kPi / 180.0, w, h);
  return camera_ring(r, lens);
}
/// `copies` of a cloud on a grid; every Gaussian of the first `moving` copies moves on a
/// straight line (polynomial motion) at a speed log-uniform over [1e-5, 1] × the copy's size.
inline GaussianCloud replicate(const GaussianCloud& base, int copies, double moving_fraction, uint64_t seed) {
  GaussianCloud c;
  c.sh_degree = base.sh_degree;
  const size_t n = base.size();
  c.resize(n * size_t(copies));
  const auto [lo, hi] = bounding_box(base);
  const Vec3f size = hi - lo;
  const int side = int(std::ceil(std::cbrt(double(copies))));
  for (int k = 0; k < copies; ++k) {
    const Vec3f offset(1.3f * size.x() * float(k % side), 1.3f * size.y() * float((k / side) % side), 1.3f * size.z() * float(k / (side * side)));
    for (size_t g = 0; g < n; ++g) {
      const size_t d = size_t(k) * n + g;
      c.means[d] = base.means[g] + offset;
      c.log_scales[d] = base.log_scales[g];
      c.rotations[d] = base.rotations[g];
      c.opacity_logits[d] = base.opacity_logits[g];
      std::copy_n(&base.sh[g * size_t(base.sh_count()) * 3], base.sh_count() * 3, &c.sh[d * size_t(c.sh_count()) * 3]);
    }
  }
  const size_t m = size_t(moving_fraction * double(c.size()));
  c.motion = MotionModel::Polynomial;
  c.dynamic_ids.resize(m);
  std::iota(c.dynamic_ids.begin(), c.dynamic_ids.end(), 0u);
  PolynomialMotion& p = c.polynomial;
  p.coeffs.assign(m * 9, 0.0f);
  p.omega.assign(m * 4, 0.0f);
  p.trbf_center.assign(m, 0.5f);
  p.trbf_log_scale.assign(m, std::log(1e4f));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  const double extent = size.norm();
  for (size_t j = 0; j < m; ++j) {
    const double speed = extent * std::pow(10.0, -5.0 + 5.0 * u(rng));
    Vec3d dir(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    dir.normalize();
    for (int a = 0; a < 3; ++a) p.coeffs[9 * j + size_t(a)] = float(speed * dir[a]);
  }
  return c;
}

}  // namespace fillgs::bench
