// Trained 4D models (E-D3DGS, 4DGaussians, 4DGS, Dynamic 3D Gaussians, per-frame PLYs)
// against what PyTorch evaluates from the same files. The files and the expected values are
// made by tests/make_model_fixtures.py (real PyTorch, each repository's architecture and
// save call); CTest runs it first and points FILLGS_MODEL_FIXTURES at its output.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <tbb/task_arena.h>

#include "cli_run.hpp"
#include "helpers.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/io/trained_models.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fs = std::filesystem;
using namespace fillgs;
using fillgs::test::run_cli;

namespace {

std::string fixtures() { return fillgs::test::model_fixtures(); }

struct Expect {
  std::map<std::string, std::vector<double>> arrays;
  std::map<std::string, std::vector<size_t>> shapes;
  const std::vector<double>& operator[](const std::string& k) const { return arrays.at(k); }
  bool has(const std::string& k) const { return arrays.count(k) != 0; }
};

Expect read_expect(const std::string& dir) {
  const std::string path = dir + "/expect.npz";
  const ZipArchive zip(path);
  Expect e;
  for (const std::string& n : zip.names()) {
    const NpyArray a = parse_npy(zip.read(n), path);
    const std::string key = n.substr(0, n.size() - 4);
    e.arrays[key] = a.to_doubles(path);
    e.shapes[key] = a.shape;
  }
  return e;
}

/// |a - b| <= 1e-5 (|b| + mean |b| of the quantity): relative, with the quantity's own scale
/// for values near zero.
void check_close(const std::vector<double>& got, const std::vector<double>& want, size_t from, const std::string& what) {
  double scale = 0;
  for (size_t i = 0; i < got.size(); ++i) scale += std::fabs(want[from + i]);
  scale /= double(std::max<size_t>(1, got.size()));
  double worst = 0;
  size_t at = 0;
  for (size_t i = 0; i < got.size(); ++i) {
    const double err = std::fabs(got[i] - want[from + i]) / (std::fabs(want[from + i]) + scale);
    if (err > worst) {
      worst = err;
      at = i;
    }
  }
  INFO(what << ": worst relative error " << worst << " at element " << at << " (got " << got[at] << ", PyTorch " << want[from + at] << ")");
  CHECK(worst <= 1e-5);
}

SceneReadOptions options_for(const std::string& name) {
  SceneReadOptions o;
  if (name == "4dgaussians") o.model_frames = 10;
  if (name.rfind("deformable3dgs", 0) == 0) o.model_frames = 9;
  if (name.rfind("4dgs", 0) == 0) {
    o.model_frames = 10;
    o.model_time_range = "0:2";
  }
  return o;
}

/// The activated values a renderer gets, in the fixture's layout.
struct Activated {
  std::vector<double> means, scales, rotations, cov, opacities, sh;
};

Activated activate(const ModelState& s) {
  Activated a;
  for (size_t i = 0; i < s.size(); ++i) {
    const Vec4f q = normalize_quat(s.rotations[i]);
    Vec3d sc;
    for (int k = 0; k < 3; ++k) {
      a.means.push_back(s.means[i][k]);
      sc[k] = std::exp(double(s.log_scales[i][k]));
      a.scales.push_back(sc[k]);
    }
    for (int k = 0; k < 4; ++k) a.rotations.push_back(q[k]);
    const Mat3d R = quat_to_matrix(Vec4d(q.cast<double>()));
    const Mat3d C = R * sc.cwiseAbs2().asDiagonal() * R.transpose();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a.cov.push_back(C(r, c));
    a.opacities.push_back(sigmoid(double(s.opacity_logits[i])) * (s.opacity_factor.empty() ? 1.0 : s.opacity_factor[i]));
  }
  a.sh.assign(s.sh.begin(), s.sh.end());
  return a;
}

void check_model(const std::string& name) {
  const std::string dir = fixtures() + "/" + name;
  const Expect e = read_expect(dir);
  const std::string f = detect_scene_format(dir);
  const auto model = open_trained_model(dir, f, options_for(name));
  const size_t T = e.shapes.at("times")[0], N = e.shapes.at("means")[1];
  REQUIRE(model->size() == N);
  for (size_t k = 0; k < T; ++k) {
    const double t = e["times"][k];
    const Activated a = activate(model->at(t));
    const std::string at = name + " at model time " + std::to_string(t);
    check_close(a.means, e["means"], k * N * 3, at + ": positions");
    if (e.has("cov")) {
      check_close(a.cov, e["cov"], k * N * 9, at + ": covariances");
    } else {
      check_close(a.scales, e["scales"], k * N * 3, at + ": scales");
      check_close(a.rotations, e["rotations"], k * N * 4, at + ": rotations");
    }
    check_close(a.opacities, e["opacities"], k * N, at + ": opacities");
    check_close(a.sh, e["sh"], k * a.sh.size(), at + ": SH");
  }
}

}  // namespace

TEST_CASE("a network's state is checked in parallel blocks, and the first Gaussian that is not finite is the one named", "[trained-models]") {
  // 100,003 rows of degree 1 (25 blocks of the check), finite but for the values planted
  // below; a serial scan is the reference.
  ModelState s;
  s.sh_degree = 1;
  const size_t n = 100003;
  s.means.assign(n, Vec3f(1, 2, 3));
  s.log_scales.assign(n, Vec3f(-1, -1, -1));
  s.rotations.assign(n, Vec4f(1, 0, 0, 0));
  s.opacity_logits.assign(n, 0.5f);
  s.sh.assign(n * 12, 0.25f);
  auto serial = [&] {
    for (size_t i = 0; i < n; ++i) {
      bool ok = s.means[i].allFinite() && s.log_scales[i].allFinite() && s.rotations[i].allFinite() && std::isfinite(s.opacity_logits[i]) &&
                (s.opacity_factor.empty() || std::isfinite(s.opacity_factor[i]));
      for (size_t q = 0; q < 12; ++q) ok = ok && std::isfinite(s.sh[i * 12 + q]);
      if (!ok) return i;
    }
    return n;
  };
  CHECK(first_not_finite(s) == n);
  s.sh[99000 * 12 + 11] = INFINITY;  // the last coefficient of a late row
  CHECK(first_not_finite(s) == 99000);
  s.rotations[70001][3] = NAN;
  CHECK(first_not_finite(s) == 70001);
  s.opacity_factor.assign(n, 1.0f);
  s.opacity_factor[4096] = -INFINITY;  // the first row of the second block
  CHECK(first_not_finite(s) == 4096);
  CHECK(serial() == 4096);
  s.means[4095][0] = NAN;  // the last row of the first block
  CHECK(first_not_finite(s) == 4095);
  CHECK(serial() == 4095);
  s.log_scales[0][2] = INFINITY;
  CHECK(first_not_finite(s) == 0);
}

TEST_CASE("E-D3DGS: positions, scales, rotations, opacities, SH equal PyTorch's at frames and between", "[trained-models]") {
  check_model("ed3dgs");        // coarse embedding at min_embeddings, fine at the full table, opacity deformed
  check_model("ed3dgs_early");  // mid coarse-to-fine (12 of 20 rows), annealing at half strength
  check_model("ed3dgs_still");  // a still background: half the first-layer units switched off
}

TEST_CASE("4DGaussians: HexPlane sampling and MLP heads equal PyTorch's", "[trained-models]") { check_model("4dgaussians"); }

TEST_CASE("4DGS: the 3D Gaussian at t (4D and 3D rotations), temporal marginal and time SH equal PyTorch's", "[trained-models]") {
  check_model("4dgs");
  check_model("4dgs_3drot");
}

TEST_CASE("Deformable 3D Gaussians: encoded MLP with skip, with and without its time network, equals PyTorch's", "[trained-models]") {
  check_model("deformable3dgs");
  check_model("deformable3dgs_blender");
}

TEST_CASE("Dynamic 3D Gaussians and per-frame PLYs: every frame as saved", "[trained-models]") {
  check_model("dynamic3dgs");
  check_model("ply_frames");
}

TEST_CASE("a trained model read as a scene gives PyTorch's values at its frames and, streamed, exactly between them", "[trained-models]") {
  for (const std::string name : {"ed3dgs", "4dgaussians", "4dgs", "deformable3dgs", "dynamic3dgs", "ply_frames"}) {
    const std::string dir = fixtures() + "/" + name;
    const Expect e = read_expect(dir);
    SceneReadOptions o = options_for(name);
    // No tolerance: every Gaussian that changes at all moves (the still rule has its own test).
    o.still = {0, 0, 0, 0, 0, 1000, 0.5f, {}};
    const GaussianCloud c = read_scene(dir, o);
    const bool streamed = c.motion == MotionModel::Evaluated;
    CHECK(streamed == (name != "dynamic3dgs" && name != "ply_frames"));
    const auto model = open_trained_model(dir, detect_scene_format(dir), o);
    const FrameGrid grid(model->frames);
    FrameSampler sampler(c);
    const size_t N = c.size(), K = size_t(c.sh_count()) * 3;
    for (size_t k = 0; k < e.shapes.at("times")[0]; ++k) {
      // Which frame is this time? (the fixtures evaluate some frames and some times between)
      const double t = e["times"][k];
      int frame = -1;
      for (int f = 0; f < model->frames; ++f)
        if (std::fabs(model->frame_time(f) - t) < 1e-9) frame = f;
      // Streamed: any time within the frames' span, at the model's own time.
      const double u = (t - model->time_first) / (model->time_last - model->time_first);
      if (frame < 0 && !(streamed && u >= 0 && u <= 1)) continue;
      const FrameGaussians& g = sampler.at(frame >= 0 ? grid.time(frame) : u);
      std::vector<double> means, opac, dc, want_dc;
      for (size_t i = 0; i < N; ++i) {
        for (int a = 0; a < 3; ++a) {
          means.push_back(g.means[i][a]);
          dc.push_back(g.sh[i * K + size_t(a)]);
          want_dc.push_back(e["sh"][(k * N + i) * K + size_t(a)]);
        }
        opac.push_back(g.opacities[i]);
      }
      const std::string at = name + (frame >= 0 ? " frame " + std::to_string(frame) : " at t " + std::to_string(u));
      check_close(means, e["means"], k * N * 3, at + ": positions");
      check_close(dc, want_dc, 0, at + ": colour (SH DC)");
      // Opacity through a logit clamped at 1e-7: compared absolutely.
      for (size_t i = 0; i < N; ++i) REQUIRE(std::fabs(opac[i] - e["opacities"][k * N + i]) < 2e-6);
    }
  }
  // The fixtures' still Gaussians (a third of Dynamic 3D Gaussians', half of the PLY frames') are static.
  CHECK(read_scene(fixtures() + "/dynamic3dgs").static_count() == 250 / 3);
  CHECK(read_scene(fixtures() + "/ply_frames").static_count() == 100);
}

TEST_CASE("colour keys survive the fillgs 4D PLY and per-frame folders round-trip bit for bit", "[trained-models]") {
  const std::string tmp = test::scratch("trained_roundtrip");
  const GaussianCloud c = read_scene(fixtures() + "/dynamic3dgs");
  REQUIRE(!c.keyframed.colours.empty());
  write_fillgs_ply(tmp + "/model.ply", c);
  const GaussianCloud back = read_scene(tmp + "/model.ply");
  REQUIRE(back.keyframed.colours.size() == c.keyframed.colours.size());
  FrameSampler a(c), b(back);
  for (int f = 0; f < 8; ++f) {
    const double t = FrameGrid(8).time(f);
    const FrameGaussians &x = a.at(t), &y = b.at(t);
    // Static first in the file: compare by sorting both into (static, dynamic) order.
    std::vector<uint32_t> order = c.static_ids();
    order.insert(order.end(), c.dynamic_ids.begin(), c.dynamic_ids.end());
    for (size_t i = 0; i < order.size(); ++i) {
      REQUIRE(x.means[order[i]] == y.means[i]);
      for (int ch = 0; ch < 3; ++ch) REQUIRE(x.sh[order[i] * 3 + size_t(ch)] == y.sh[i * 3 + size_t(ch)]);
    }
  }
  // Per-frame folder -> fillgs convert --to frames -> read as a folder -> convert again: the same bytes.
  const std::string src = fixtures() + "/ply_frames";
  REQUIRE(run_cli({"convert", "--scene", src, "--to", "frames", "--out", tmp + "/once", "--quiet"}).code == 0);
  REQUIRE(run_cli({"convert", "--scene", tmp + "/once", "--to", "frames", "--out", tmp + "/twice", "--quiet"}).code == 0);
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(tmp + "/once")) {
    if (e.path().extension() != ".ply") continue;
    ++files;
    std::ifstream p(e.path(), std::ios::binary), q(tmp + "/twice/" + e.path().filename().string(), std::ios::binary);
    std::stringstream ps, qs;
    ps << p.rdbuf();
    qs << q.rdbuf();
    REQUIRE(ps.str() == qs.str());
  }
  CHECK(files == 6);
}

TEST_CASE("trained models: the bare canonical PLY and broken files are refused with one line, nothing written", "[trained-models]") {
  const std::string tmp = test::scratch("trained_refusals");
  const std::string F = fixtures();
  struct Case {
    std::string path, says;
  };
  const std::vector<Case> cases = {
      {F + "/ed3dgs/point_cloud/iteration_14000/point_cloud.ply", "canonical point cloud of an E-D3DGS model"},
      {F + "/4dgaussians/point_cloud/iteration_14000/point_cloud.ply", "canonical point cloud of a deformation model (deformation.pth lies beside it)"},
      {F + "/broken_shape", "key 'pos_deform_f.3.bias' has shape [3], expected [5]"},
      {F + "/broken_missing", "key 'scales_deform_c.1.bias' missing"},
      {F + "/broken_truncated", "truncated"},
      {F + "/broken_not_state_dict", "is a list, not a state dict"},
      {F + "/broken_offsets_huge", "key 'offsets' element 1 (3e+38) is no time offset within +-1e+06"},
      {F + "/broken_aabb", "key 'deformation_net.grid.aabb' has an empty or degenerate extent on axis 0"},
      {F + "/broken_4dgs_degree_nan", "entry 0 (active SH degree) nan is not a whole number in [0, 3]"},
      {F + "/broken_4dgs_degree_huge", "entry 0 (active SH degree) 1e+300 is not a whole number in [0, 3]"},
      {F + "/broken_4dgs_sh_huge", "entry 3 (_features_rest) has 2147483647 SH channels, more than the 47 of 4DGS's largest basis"},
      {F + "/4dgaussians", "give --model-frames"},
      {F + "/4dgs", "--model-time-range"},
      {F + "/deformable3dgs/point_cloud/iteration_40000/point_cloud.ply", "Deformable 3D Gaussians model (a deform/ folder lies beside it)"},
      {F + "/deformable3dgs", "give --model-frames"},
  };
  int k = 0;
  for (const Case& c : cases) {
    const std::string out = tmp + "/out" + std::to_string(k++) + ".ply";
    for (const std::vector<std::string>& args : {std::vector<std::string>{"info", c.path},
                                                 std::vector<std::string>{"convert", "--scene", c.path, "--to", "fillgs", "--frames", "4", "--out", out}}) {
      const auto r = run_cli(args);
      INFO(args[0] << " " << c.path << " -> " << r.err);
      CHECK(r.code == 1);
      CHECK(r.err.find(c.says) != std::string::npos);
      CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
      CHECK(!fs::exists(out));
    }
  }
  // Times from the command line: finite, within +-1e6, a span of at least 1e-6.
  for (const char* range : {"0:1e39", "0:inf", "nan:1", "0:1e-9", "1:0"}) {
    const auto r = run_cli({"info", "--model-time-range", range, F + "/ed3dgs"});
    INFO(range << " -> " << r.err);
    CHECK(r.code == 1);
    CHECK(r.err.find("--model-time-range") != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  }
  CHECK(run_cli({"info", "--model-time-range", "-2:3", F + "/ed3dgs"}).code == 0);
  // A 3DGS PLY of a static scene stays readable: the guard looks only at deformation models.
  CHECK(run_cli({"info", F + "/ply_frames/time_00000.ply"}).code == 0);
}

TEST_CASE("a network's working memory is charged to FILLGS_MAX_ALLOC before it is taken", "[trained-models]") {
  const std::string dir = fixtures() + "/ed3dgs";
  const size_t threads = size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
  // The fixture's widest E-D3DGS layer is its colour head's 48 outputs: 1024 rows x 4 blocks x 4 bytes each.
  const size_t network = threads * 1024 * 48 * 16;
  {
    const test::EnvOverride cap("FILLGS_MAX_ALLOC", std::to_string(network / 2));
    CHECK_THROWS_WITH(open_trained_model(dir, "e-d3dgs", {}),
                      Catch::Contains("E-D3DGS's network evaluation (" + std::to_string(threads) + " threads x 1024 rows x 4 blocks of its widest layer, 48 values)") &&
                          Catch::Contains("would bring this file's memory to"));
  }
  const test::EnvOverride cap("FILLGS_MAX_ALLOC", std::to_string(network * 4));
  CHECK(open_trained_model(dir, "e-d3dgs", {})->size() > 0);
}

TEST_CASE(".pth tensors of every dtype and strides read as PyTorch converts them to float", "[trained-models]") {
  const std::string dir = fixtures() + "/dtypes";
  const TorchFile tf(dir + "/tensors.pth");
  const Expect e = read_expect(dir);
  size_t seen = 0;
  for (const auto& [key, ref] : tf.string_entries(tf.root(), "tensors.pth")) {
    const TorchTensor t = tf.tensor(ref, key);
    const std::vector<double>& want = e[key];
    REQUIRE(t.values.size() == want.size());
    for (size_t i = 0; i < want.size(); ++i) {
      INFO(key << " element " << i);
      CHECK(double(t.values[i]) == want[i]);  // exact: both are the same float conversion
    }
    ++seen;
  }
  CHECK(seen == 9);
  CHECK(tf.tensor(tf.find(tf.root(), "t"), "t").shape_text() == "[3, 2]");
}

TEST_CASE("cfg_args: Python literals read as JSON, bad ones refused with a position", "[trained-models]") {
  CHECK(python_literal_to_json("Namespace(a=1, b='x', c=[1, 2.5], d={'k': True}, e=None, f=-3e-4, g=(1,))", "cfg") ==
        R"({"a":1,"b":"x","c":[1,2.5],"d":{"k":true},"e":null,"f":-0.0003,"g":[1]})");
  CHECK_THROWS_WITH(python_literal_to_json("Namespace(a=1", "cfg"), Catch::Contains("cfg: ") && Catch::Contains("at character"));
  CHECK_THROWS_WITH(python_literal_to_json("Namespace(a=os.system('x'))", "cfg"), Catch::Contains("is not a literal"));
}

TEST_CASE("the dense kernel's evaluation equals the reference products on every format, for any rows", "[trained-models]") {
  for (const std::string name : {"ed3dgs", "ed3dgs_early", "4dgaussians", "4dgs", "4dgs_3drot", "deformable3dgs", "deformable3dgs_blender",
                                 "dynamic3dgs", "ply_frames"}) {
    const std::string dir = fixtures() + "/" + name;
    const auto model = open_trained_model(dir, detect_scene_format(dir), options_for(name));
    // A subset in a scrambled order, more than one block of the kernel when the model has it.
    std::vector<uint32_t> rows;
    for (size_t i = 0; i < model->size(); i += 2) rows.push_back(uint32_t((i * 7919) % model->size()));
    for (const double f : {0.0, 0.5, 3.25, double(model->frames - 1)}) {
      const double t = model->frame_time(std::min(f, double(model->frames - 1)));
      const ModelState want = model->at(t).rows(rows);
      ModelState got;
      model->evaluate(t, rows, got);
      REQUIRE(got.size() == rows.size());
      REQUIRE(got.sh.size() == want.sh.size());
      double worst = 0;
      const auto cmp = [&](const float* a, const float* b, size_t n) {
        double w = 0;
        for (size_t i = 0; i < n; ++i) w = std::max(w, std::fabs(double(a[i]) - double(b[i])) / (1.0 + std::fabs(double(b[i]))));
        worst = std::max(worst, w);
      };
      cmp(got.means[0].data(), want.means[0].data(), 3 * rows.size());
      // Scales as the renderer takes them, exp(log-scale): a log-scale of a sum near zero
      // (Deformable 3D Gaussians' scale + delta) turns float rounding of the sum into large
      // relative differences of its logarithm.
      std::vector<float> sg, sw;
      for (size_t i = 0; i < rows.size(); ++i)
        for (int a = 0; a < 3; ++a) {
          sg.push_back(std::exp(got.log_scales[i][a]));
          sw.push_back(std::exp(want.log_scales[i][a]));
        }
      cmp(sg.data(), sw.data(), sg.size());
      cmp(got.rotations[0].data(), want.rotations[0].data(), 4 * rows.size());
      cmp(got.opacity_logits.data(), want.opacity_logits.data(), rows.size());
      cmp(got.sh.data(), want.sh.data(), want.sh.size());
      INFO(name << " at model time " << t << ": worst difference " << worst);
      CHECK(worst <= 1e-6);
    }
  }
}

TEST_CASE("the still rule: Gaussians whose network noise stays within the tolerance are static, the rest evaluated", "[trained-models]") {
  const std::string dir = fixtures() + "/ed3dgs_still";
  const Expect e = read_expect(dir);
  // PyTorch's values at every frame, by the rule in numpy: which are still, and how far the
  // still ones' noise moves them (more than nothing, less than the tolerance).
  REQUIRE(e["still_drift"][0] > 1e-6);
  REQUIRE(e["still_drift"][0] < 1e-3);
  SceneReadOptions o;
  o.still.sweep_frames = 1000;  // every frame, as the fixture's rule
  const GaussianCloud c = read_scene(dir, o);
  REQUIRE(c.motion == MotionModel::Evaluated);
  std::vector<char> moving(c.size(), 0);
  for (uint32_t g : c.dynamic_ids) moving[g] = 1;
  size_t agree = 0, still = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    agree += (e["still"][i] > 0.5) == !moving[i];
    still += e["still"][i] > 0.5;
  }
  CHECK(still == 180);
  CHECK(agree == c.size());
  CHECK(c.static_count() == 180);
  // A still Gaussian stays where frame 0 put it; a moving one follows the network at any time.
  const auto model = open_trained_model(dir, "e-d3dgs", o);
  FrameSampler s(c);
  for (const double t : {0.0, 0.37, 1.0}) {
    const ModelState want = model->at(model->frame_time(t * (model->frames - 1)));
    const FrameGaussians& g = s.at(t);
    for (size_t i = 0; i < c.size(); ++i) {
      const float d = (g.means[i] - want.means[i]).norm();
      if (moving[i]) REQUIRE(d <= 1e-5f * (1 + want.means[i].norm()));
      else REQUIRE(d <= e["still_drift"][0] * 1.01 + 1e-6);
    }
  }
  // Static Gaussians carry no motion: their deficiency is 0 by construction (the dynamic set
  // is what observe's deficiency covers); a sweep of two frames keeps the still set a
  // superset of the full sweep's.
  o.still.sweep_frames = 2;
  o.still.recheck = 1.0f;
  const GaussianCloud coarse = read_scene(dir, o);
  CHECK(coarse.static_count() >= c.static_count());
  // The recheck: a two-frame sweep whose every departing Gaussian is checked at every frame
  // finds the full sweep's still set, Gaussian for Gaussian.
  o.still.recheck = 0.0f;
  const GaussianCloud rechecked = read_scene(dir, o);
  CHECK(rechecked.dynamic_ids == c.dynamic_ids);
}

TEST_CASE("the still rule's recheck catches motion between the sweep's frames", "[trained-models]") {
  // 4DGaussians' fixture: time planes random, so motion between sparse frames is not what
  // the frames see. The full sweep is the reference.
  const std::string dir = fixtures() + "/4dgaussians";
  SceneReadOptions o = options_for("4dgaussians");
  o.still.position = 2e-4f;  // about half its Gaussians still over its 10 frames
  o.still.sweep_frames = 1000;
  const GaussianCloud full = read_scene(dir, o);
  o.still.sweep_frames = 2;
  o.still.recheck = 1.0f;
  const GaussianCloud sparse = read_scene(dir, o);
  o.still.recheck = 0.0f;
  const GaussianCloud rechecked = read_scene(dir, o);
  INFO("still: full sweep " << full.static_count() << ", two frames " << sparse.static_count() << ", rechecked " << rechecked.static_count());
  REQUIRE(full.static_count() > 0);
  REQUIRE(full.static_count() < full.size());
  CHECK(sparse.static_count() > full.static_count());  // the fixture does move between frame 0 and the last
  CHECK(rechecked.dynamic_ids == full.dynamic_ids);
}

TEST_CASE("4DGS: a Gaussian living between the sweep's frames, or changing a band above the DC, is not still, and its keys keep it", "[trained-models]") {
  // tests/make_model_fixtures.py, short_lived_4dgs: Gaussians 0, 4, 5 lit about a frame at
  // frames 75, 107, 139 of 300 (none of the sweep's 30), 2 changing colour only in SH
  // coefficient 5, 1 and 3 still. Before, the rule read 0, 4, 5 as still at frame 0's opacity
  // (about 0) and froze 2's colour; the keys then kept 0 dark at frame 75.
  const std::string dir = fixtures() + "/4dgs_short_lived";
  SceneReadOptions o;
  o.model_frames = 300;
  o.model_time_range = "0:10";
  const GaussianCloud streamed = read_scene(dir, o);
  CHECK(streamed.dynamic_ids == std::vector<uint32_t>{0, 2, 4, 5});
  o.model_evaluation = ModelEvaluation::Keys;
  const GaussianCloud keys = read_scene(dir, o);
  const double lit = 1.0 / (1.0 + std::exp(-1.96));  // 0.877
  for (const auto& [g, frame] : std::vector<std::pair<uint32_t, int>>{{0, 75}, {4, 107}, {5, 139}}) {
    const double t = frame / 299.0;
    INFO("Gaussian " << g << " at frame " << frame);
    CHECK(frame_at(streamed, t).opacities[g] == Approx(lit).margin(1e-5));
    CHECK(frame_at(keys, t).opacities[g] == Approx(lit).margin(1e-5));
    CHECK(frame_at(streamed, (frame + 5) / 299.0).opacities[g] < 1e-6);  // and dark a few frames on
  }
  // Gaussian 2's coefficient 5 follows the time band: base + 0.5 cos(2 pi (t_mean - t) / 10).
  const std::unique_ptr<TrainedModel> m = open_trained_model(dir, "4dgs", o);
  for (double t : {0.3, 0.7}) {
    const double model_time = t * 299.0 / 30.0;
    CHECK(frame_at(streamed, t).sh[2 * 48 + 15] == Approx(m->at(model_time).sh[2 * 48 + 15]).margin(1e-6));
  }
  CHECK(std::fabs(frame_at(streamed, 0.3).sh[2 * 48 + 15] - frame_at(streamed, 0.0).sh[2 * 48 + 15]) > 0.1);
  // Training keys (finetune's): the lit frames are kept within the opacity tolerance.
  KeyChoice kc;
  const GaussianCloud trained = keyed_for_training(streamed, &kc);
  INFO(kc.keys << " keys, " << kc.limiting << " decided");
  CHECK(kc.limiting == "opacity");
  for (const auto& [g, frame] : std::vector<std::pair<uint32_t, int>>{{0, 75}, {4, 107}, {5, 139}})
    CHECK(frame_at(trained, frame / 299.0).opacities[g] == Approx(lit).margin(1.0 / 255.0));
}

TEST_CASE("streamed observation tables equal those of keys at every frame, byte for byte", "[trained-models]") {
  RingPlacement ring;
  ring.count = 6;
  ring.radius = 4.0;
  ring.elevation = 0.5;
  ring.up = Vec3d(0, -1, 0);
  Camera lens;
  lens.set_fov_x(1.0, 64, 48);
  const std::vector<Camera> cams = camera_ring(ring, lens);
  // 4DGS is left out: its keys hold logit(sigmoid(o) x its temporal factor), not the
  // opacity itself, so its keyed opacities differ in the last bits.
  for (const std::string name : {"ed3dgs", "4dgaussians", "deformable3dgs"}) {
    const std::string dir = fixtures() + "/" + name;
    SceneReadOptions streamed = options_for(name);
    streamed.still = {0, 0, 0, 0, 0, 1000, 0.5f, {}};
    SceneReadOptions keys = streamed;
    keys.model_evaluation = ModelEvaluation::Keys;
    keys.partition.static_speed_threshold = 0;
    const GaussianCloud a = read_scene(dir, streamed), b = read_scene(dir, keys);
    REQUIRE(a.motion == MotionModel::Evaluated);
    REQUIRE(b.motion == MotionModel::Keyframed);
    REQUIRE(a.dynamic_ids == b.dynamic_ids);
    const FrameGrid grid(motion_frames(a));
    for (const VisibilityMode mode : {VisibilityMode::Frustum, VisibilityMode::Raytraced}) {
      ObservationOptions o;
      o.visibility.mode = mode;
      const ObservationTables ta = observation_tables(a, cams, grid.times(), grid.step(), o);
      const ObservationTables tb = observation_tables(b, cams, grid.times(), grid.step(), o);
      INFO(name << " " << to_string(mode));
      size_t seen = 0;
      for (uint16_t c : ta.counts) seen += c;
      CHECK(seen > 0);  // the cameras see the model
      CHECK(ta.counts == tb.counts);
      CHECK(ta.dynamic_speed == tb.dynamic_speed);
      CHECK(ta.dynamic_deficiency == tb.dynamic_deficiency);
    }
  }
}
