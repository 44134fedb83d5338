#pragma once
// Shared test helpers: locating ../shared/data, scratch folders outside the source tree,
// and small hand-made scenes.

// The sanitizer tree (tests/README.md): there, OpenVDB's accessor registry (a TBB
// concurrent_hash_map) trips UBSan's alignment check inside TBB's own header, so the parts
// of tests that build or read an OpenVDB grid, and the slow whole-pipeline runs, run in the
// release tree only.
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FILLGS_SANITIZED 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define FILLGS_SANITIZED 1
#endif
#ifndef FILLGS_SANITIZED
#define FILLGS_SANITIZED 0
#endif
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <tbb/task_arena.h>

#include "fillgs/base/error.hpp"
#include "fillgs/base/instruction_set.hpp"

#include "fillgs/model/camera.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/model/sh.hpp"
#include "fillgs/experiment/synth.hpp"

namespace fillgs::test {

/// shared_data_dir() (fs_util.hpp), which tests that need it require to exist.
inline std::string shared_data() {
  const std::string dir = shared_data_dir();
  INFO("shared data folder: " << dir << " (set FILLGS_SHARED_DATA)");
  REQUIRE(std::filesystem::is_directory(dir));
  return dir;
}

/// A file's bytes as they are (no checks: what a reader would see without fillgs's).
inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Sets an environment variable for the scope, and unsets it after.
struct EnvOverride {
  std::string name;
  EnvOverride(const char* n, const std::string& value) : name(n) { ::setenv(n, value.c_str(), 1); }
  ~EnvOverride() { ::unsetenv(name.c_str()); }
};

/// Writes `bytes` to `path`, making its folders (a hand-made input file).
inline void write(const std::string& path, const std::string& bytes) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

/// The message of the fillgs::Error `f` throws ("" if none).
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

/// The trained-model fixtures' folder: CTest runs tests/make_model_fixtures.py first and sets
/// FILLGS_MODEL_FIXTURES to its output.
inline std::string model_fixtures() {
  const char* d = std::getenv("FILLGS_MODEL_FIXTURES");
  REQUIRE(d != nullptr);
  REQUIRE(std::filesystem::is_directory(d));
  return d;
}

/// A fresh, empty scratch folder under the system temp directory.
inline std::string scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("fillgs_test_" + std::to_string(::getpid())) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

/// Camera at the origin looking down +z (OpenCV axes), W x H, focal f, centred principal point.
inline Camera axis_camera(int w, int h, double f) {
  Camera c;
  c.name = "axis";
  c.width = w;
  c.height = h;
  c.fx = c.fy = f;
  c.cx = w / 2.0;
  c.cy = h / 2.0;
  return c;
}

/// Adds one static, isotropic Gaussian with a flat colour (degree-0 SH).
inline void add_gaussian(GaussianCloud& c, const Vec3f& mean, float scale, float opacity_logit, const Vec3f& rgb) {
  const size_t g = c.size();
  c.resize(g + 1);
  c.means[g] = mean;
  c.log_scales[g] = Vec3f::Constant(std::log(scale));
  c.rotations[g] = Vec4f(1, 0, 0, 0);
  c.opacity_logits[g] = opacity_logit;
  const int K = c.sh_count();
  for (int ch = 0; ch < 3; ++ch) c.sh[size_t(g) * K * 3 + ch] = rgb_to_sh_dc(rgb[ch]);
}

/// The synthetic scene at a test-sized resolution (spacing in metres; coarser = fewer Gaussians).
/// 60,000 Gaussians placed to meet every branch of the 3DGS preprocess (its frustum rule and
/// footprint) and the cameras they are seen from: behind the camera, at the near plane, on
/// the image's edges and tile borders, far outside, needle-thin and huge (scales from 1e-9
/// to 1e7), with arbitrary rotations (unit and not), in front of cameras of odd sizes.
inline GaussianCloud preprocess_extremes(std::vector<Camera>* cams) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f), ls(-20.0f, 16.0f);
  Camera base;
  base.width = 37, base.height = 29, base.fx = 31.0, base.fy = 29.5, base.cx = 18.3, base.cy = 14.1;
  *cams = {base};
  Camera wide = base;
  wide.width = 1352, wide.height = 1014, wide.fx = 1100, wide.fy = 1100, wide.cx = 676, wide.cy = 507;
  cams->push_back(wide);
  Camera turned = base;
  turned.look_at(Vec3d(0.3, -0.2, -2.0), Vec3d(0.1, 0.05, 1.0), Vec3d(0, -1, 0));
  cams->push_back(turned);
  GaussianCloud c;
  for (int i = 0; i < 60000; ++i) {
    Vec3f m;
    switch (i % 6) {
      case 0: m = Vec3f(unit(rng) * 3, unit(rng) * 3, unit(rng) * 3); break;                            // anywhere, behind included
      case 1: m = Vec3f(unit(rng) * 0.2f, unit(rng) * 0.2f, 0.2f + unit(rng) * 1e-6f); break;           // at the near plane
      case 2: m = Vec3f(unit(rng) * 0.7f, unit(rng) * 0.6f, 1.0f); break;                               // near the image's edges at z = 1
      case 3: m = Vec3f(unit(rng) * 50, unit(rng) * 50, 1.0f + 20 * std::fabs(unit(rng))); break;      // far outside
      case 4: m = Vec3f(float(16 * int(unit(rng) * 3)) / 31.0f, unit(rng) * 0.5f, 1.0f); break;         // on tile borders
      default: m = Vec3f(unit(rng), unit(rng), 1e4f * std::fabs(unit(rng))); break;                     // very far
    }
    add_gaussian(c, m, 1.0f, 0.0f, Vec3f(0.5f, 0.5f, 0.5f));
    c.log_scales[size_t(i)] = Vec3f(ls(rng), ls(rng), ls(rng));
    const Vec4f q(unit(rng), unit(rng), unit(rng), unit(rng));
    c.rotations[size_t(i)] = i % 5 == 0 ? q : Vec4f(q.normalized());
  }
  return c;
}

/// f(set) once per instruction set the vector kernels can be held to (the native width, AVX2,
/// SSE4; one this CPU lacks is skipped with a warning), then back to the native width.
template <class F>
void for_each_instruction_set(F&& f) {
  for (const char* set : {"native", "avx2", "sse4"}) {
    try {
      limit_instruction_set(set, "test");
    } catch (const Error& e) {
      WARN("skipped " << set << ": " << e.what());
      continue;
    }
    f(set);
  }
  limit_instruction_set("native", "test");
}

/// A number's bits, to compare two computations bit for bit (-0 and +0, NaNs, apart).
inline uint64_t bits_of(double x) {
  uint64_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}
inline uint32_t bits_of(float x) {
  uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

inline SynthScene small_synth(int frames, int width, int height, double spacing = 0.02) {
  SynthOptions o;
  o.frames = frames;
  o.width = width;
  o.height = height;
  o.spacing = spacing;
  return make_synthetic_scene(o);
}

/// f() with `threads` threads: the library's loops run in the caller's task arena.
template <class F>
auto with_threads(int threads, F&& f) {
  return tbb::task_arena(threads).execute(std::forward<F>(f));
}

inline bool all_finite(const std::vector<float>& v) {
  for (float x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

}  // namespace fillgs::test
