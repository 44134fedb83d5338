// Scene readers on the real files in ../shared/data (values checked against a reading
// made with Python's struct module), on every PLY encoding, and on hand-built Spacetime,
// Ex4DGS and fillgs files whose motion has a closed form.
#include <algorithm>
#include <cstring>
#include <fstream>

#include "fillgs/base/error.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/method/refiners.hpp"
#include "fillgs/method/strategies.hpp"
#include "fillgs/experiment/identity.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/train/train_model.hpp"
#include "fillgs/experiment/synth.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;

TEST_CASE("real 3DGS files: counts, SH degree, first and last Gaussian", "[io][data]") {
  const std::string dir = shared_data() + "/scenes/";
  SECTION("guitar.ply (x y z f_dc opacity rot scale order, +inf opacity logits)") {
    const GaussianCloud c = read_scene(dir + "guitar.ply");
    CHECK(c.size() == 90854);
    CHECK(c.sh_degree == 0);
    CHECK(c.static_count() == 90854);
    CHECK(c.means[0].x() == -0.4724908471107483f);
    CHECK(c.means[0].y() == -4.07820463180542f);
    CHECK(c.opacity_logits[0] == 0.7646061182022095f);
    CHECK(c.log_scales[0].x() == -8.7986421585083f);
    CHECK(c.rotations[0][0] == 0.7951075434684753f);
    CHECK(c.sh[0] == 0.1326712965965271f);
    CHECK(c.means[90853].z() == 0.7538047432899475f);
    CHECK(c.opacity_logits[90853] == -2.1756255626678467f);
    // 667 logits are +inf in the file (opacity exactly 1): kept saturated, finite.
    size_t saturated = 0;
    for (float o : c.opacity_logits) saturated += (o == 40.0f);
    CHECK(saturated == 667);
    CHECK(all_finite(c.opacity_logits));
  }
  SECTION("donut.ply (INRIA order, no normals)") {
    const GaussianCloud c = read_scene(dir + "donut.ply");
    CHECK(c.size() == 45624);
    CHECK(c.sh_degree == 0);
    CHECK(c.means[0].x() == 0.018263084813952446f);
    CHECK(c.opacity_logits[0] == 6.068385601043701f);
    CHECK(c.rotations[45623][0] == 1.0095418691635132f);  // unnormalised, as stored
    CHECK(c.sh[45623 * 3] == 0.9670575261116028f);
  }
  SECTION("playbot_3k.ply (SH degree 2 from 24 f_rest, channel-major)") {
    const GaussianCloud c = read_scene(dir + "playbot_3k.ply");
    CHECK(c.size() == 3000);
    CHECK(c.sh_degree == 2);
    const int K = 9;
    CHECK(c.sh[(0 * K + 1) * 3 + 0] == -0.10819711536169052f);   // f_rest_0: channel 0, k = 1
    CHECK(c.sh[(0 * K + 8) * 3 + 2] == 0.04050695151090622f);    // f_rest_23: channel 2, k = 8
    CHECK(c.sh[(2999 * K + 8) * 3 + 2] == -0.0016776674892753363f);
    CHECK(c.log_scales[2999].x() == -4.733701229095459f);
  }
}

TEST_CASE("ASCII, big-endian and little-endian PLY read the same values", "[io]") {
  const std::string dir = scratch("encodings");
  const std::string ascii =
      "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 2\n"
      "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\n"
      "property float opacity\nproperty float x\nproperty float y\nproperty float z\n"
      "property float scale_0\nproperty float scale_1\nproperty float scale_2\n"
      "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "1 0 0 0 0.5 1.5 2.5 3.5 -1 -2 -3 0.1 0.2 0.3\n"
      "0.5 0.5 0.5 0.5 -0.5 -1.5 -2.5 -3.5 -4 -5 -6 0.4 0.5 0.6\n"
      "3 0 1 1\n";
  {
    std::ofstream(dir + "/a.ply") << ascii;
  }
  // Big-endian: the same records, bytes reversed per float (written here, not by fillgs).
  const float rows[2][14] = {{1, 0, 0, 0, 0.5f, 1.5f, 2.5f, 3.5f, -1, -2, -3, 0.1f, 0.2f, 0.3f},
                             {0.5f, 0.5f, 0.5f, 0.5f, -0.5f, -1.5f, -2.5f, -3.5f, -4, -5, -6, 0.4f, 0.5f, 0.6f}};
  const std::string header_tail = ascii.substr(0, ascii.find("end_header\n") + 11);
  for (const char* fmt : {"binary_big_endian", "binary_little_endian"}) {
    std::string h = header_tail;
    h.replace(h.find("ascii"), 5, fmt);
    std::string body;
    for (const auto& row : rows)
      for (float v : row) {
        unsigned char b[4];
        std::memcpy(b, &v, 4);
        if (std::string(fmt) == "binary_big_endian") std::swap(b[0], b[3]), std::swap(b[1], b[2]);
        body.append(reinterpret_cast<char*>(b), 4);
      }
    body += std::string("\x03", 1);
    for (int idx : {0, 1, 1}) {
      unsigned char b[4];
      std::memcpy(b, &idx, 4);
      if (std::string(fmt) == "binary_big_endian") std::swap(b[0], b[3]), std::swap(b[1], b[2]);
      body.append(reinterpret_cast<char*>(b), 4);
    }
    std::ofstream(dir + "/" + fmt + ".ply", std::ios::binary) << h << body;
  }
  for (const char* name : {"a.ply", "binary_big_endian.ply", "binary_little_endian.ply"}) {
    INFO(name);
    const GaussianCloud c = read_scene(dir + "/" + name);
    REQUIRE(c.size() == 2);
    CHECK(c.means[1] == Vec3f(-1.5f, -2.5f, -3.5f));
    CHECK(c.log_scales[0] == Vec3f(-1, -2, -3));
    CHECK(c.rotations[1] == Vec4f(0.5f, 0.5f, 0.5f, 0.5f));
    CHECK(c.opacity_logits[0] == 0.5f);
    CHECK(c.sh[1 * 3 + 2] == 0.6f);
  }
}

namespace {

PlyElement vertex_element(size_t n) {
  PlyElement v;
  v.name = "vertex";
  v.count = n;
  return v;
}

void add(PlyElement& e, const std::string& name, std::vector<float> values) {
  e.property_names.push_back(name);
  e.columns.push_back(std::move(values));
}

void add_standard(PlyElement& e, const std::vector<Vec3f>& xyz, const std::string& prefix = "", bool with_xyz = true) {
  const size_t n = xyz.size();
  if (with_xyz)
    for (int a = 0; a < 3; ++a) {
      std::vector<float> col(n);
      for (size_t i = 0; i < n; ++i) col[i] = xyz[i][a];
      add(e, std::string(1, char('x' + a)), col);
    }
  for (int ch = 0; ch < 3; ++ch) add(e, prefix + "f_dc_" + std::to_string(ch), std::vector<float>(n, 0.2f * ch));
  add(e, prefix + "opacity", std::vector<float>(n, 1.0f));
  for (int a = 0; a < 3; ++a) add(e, prefix + "scale_" + std::to_string(a), std::vector<float>(n, -3.0f));
  if (prefix.empty())
    for (int a = 0; a < 4; ++a) add(e, "rot_" + std::to_string(a), std::vector<float>(n, a == 0 ? 1.0f : 0.0f));
}

}  // namespace

TEST_CASE("Spacetime Gaussians: cubic position, linear rotation, temporal RBF, STG time", "[io][motion]") {
  const std::string dir = scratch("stg");
  PlyElement v = vertex_element(2);
  add_standard(v, {Vec3f(0, 0, 0), Vec3f(1, 1, 1)});
  add(v, "trbf_center", {0.5f, 0.5f});
  add(v, "trbf_scale", {std::log(0.25f), std::log(1000.0f)});
  // Gaussian 0: Δ coefficient (1,0,0), Δ² (0,2,0), Δ³ (0,0,3). Gaussian 1: no motion.
  const float m0[9] = {1, 0, 0, 0, 2, 0, 0, 0, 3};
  for (int k = 0; k < 9; ++k) add(v, "motion_" + std::to_string(k), {m0[k], 0.0f});
  add(v, "omega_0", {0.0f, 0.0f});
  add(v, "omega_1", {0.4f, 0.0f});
  add(v, "omega_2", {0.0f, 0.0f});
  add(v, "omega_3", {0.0f, 0.0f});
  for (int k = 3; k < 6; ++k) add(v, "f_dc_" + std::to_string(k), {0.0f, 0.0f});
  PlyData ply;
  ply.elements.push_back(v);
  write_ply(dir + "/stg.ply", ply);

  SceneReadOptions o;  // stg_duration: its declared default, 50
  const GaussianCloud c = read_scene(dir + "/stg.ply", o);
  CHECK(c.motion == MotionModel::Polynomial);
  CHECK(c.dynamic_count() == 1);  // Gaussian 1 neither moves nor fades (σ_t = 1000): static
  CHECK(c.static_ids() == std::vector<uint32_t>{1});
  REQUIRE_FALSE(c.notes.empty());
  for (double t : {0.0, 0.3, 1.0}) {
    const FrameGaussians f = frame_at(c, t);
    const double d = t * 49.0 / 50.0 - 0.5;  // STG time is frame / D
    CHECK(f.means[0].x() == Approx(d).margin(1e-6));
    CHECK(f.means[0].y() == Approx(2 * d * d).margin(1e-6));
    CHECK(f.means[0].z() == Approx(3 * d * d * d).margin(1e-6));
    const Vec4f q = Vec4f(1, 0.4f * float(d), 0, 0).normalized();
    CHECK((f.rotations[0] - q).norm() < 1e-6);
    CHECK(f.opacities[0] == Approx((1 / (1 + std::exp(-1.0))) * std::exp(-(d / 0.25) * (d / 0.25))).epsilon(1e-5));
    CHECK(f.means[1] == Vec3f(1, 1, 1));
  }
  // Colour: full model (6 f_dc) → sigmoid of f_dc_0..2 as the base colour.
  CHECK(c.sh[0 * 3 + 1] * kSHC0 + 0.5f == Approx(1 / (1 + std::exp(-0.2))).epsilon(1e-6));
}

TEST_CASE("A format's own parameter: declared in its row, given as a value, checked once", "[io][motion]") {
  const std::string dir = scratch("stg_parameter");
  PlyElement v = vertex_element(1);
  add_standard(v, {Vec3f(0, 0, 0)});
  add(v, "trbf_center", {0.5f});
  add(v, "trbf_scale", {std::log(1000.0f)});
  for (int k = 0; k < 9; ++k) add(v, "motion_" + std::to_string(k), {k == 0 ? 1.0f : 0.0f});  // x = t - 0.5 in STG time
  for (int k = 0; k < 4; ++k) add(v, "omega_" + std::to_string(k), {0.0f});
  PlyData ply;
  ply.elements.push_back(v);
  write_ply(dir + "/stg.ply", ply);

  const RowParameter* duration = model_format_table().parameter("stg_duration");
  REQUIRE(duration);
  CHECK(model_format("stg").parameters == std::vector<const RowParameter*>{duration, model_format_table().parameter("stg_color")});
  SceneReadOptions o;
  o.parameters.set(*duration, "10");
  // Frame f of D at STG time f / D: normalised time 1 is 9/10 with D = 10 (49/50 by default).
  CHECK(frame_at(read_scene(dir + "/stg.ply", o), 1.0).means[0].x() == Approx(0.9 - 0.5).margin(1e-6));
  CHECK(frame_at(read_scene(dir + "/stg.ply"), 1.0).means[0].x() == Approx(0.98 - 0.5).margin(1e-6));
  // The one check, in each face's spelling; a refused value is not kept.
  CHECK_THROWS_WITH(o.parameters.set(*duration, "0"), "--stg-duration must be in [1, 1e+06], got 0");
  CHECK_THROWS_WITH(o.parameters.set(*duration, "2.5", Spelling{false}), "stg_duration expects an integer, got '2.5'");
  CHECK(o.parameters.integer(*duration) == 10);
  const RowParameter* colour = model_format_table().parameter("stg_color");
  REQUIRE(colour);
  CHECK_THROWS_WITH(o.parameters.set(*colour, "tanh"), "--stg-color expects auto, sigmoid, clamp or none, got 'tanh'");
  CHECK(o.parameters.identity({duration, colour}) == nlohmann::json{{"stg_duration", 10}, {"stg_color", "auto"}});
  // A number's default reads back as the declared double, whatever its digits.
  const RowParameter fine = RowParameter::number("fine", 0.1234567891234, positive(), "a default of 13 digits");
  CHECK(RowParameterValues().number(fine) == 0.1234567891234);
}

TEST_CASE("Every row table (formats, refiners, strategies): defaults that pass their own check, keys and names unique", "[io]") {
  auto check_table = [](const auto& table) {
    std::vector<std::string> keys, names;
    for (const auto* row : table.rows()) {
      names.push_back(row->name);
      for (const RowParameter* p : row->parameters) {
        INFO(row->name << " " << p->key);
        CHECK(p->problem(p->default_text).empty());
        CHECK(p->key.find('-') == std::string::npos);  // the flag is its spelling (--a-b), the keyword the key (a_b)
        if (std::find(keys.begin(), keys.end(), p->key) == keys.end()) keys.push_back(p->key);
        else CHECK(table.parameter(p->key) == p);  // a key two rows read is one declaration
      }
    }
    std::sort(names.begin(), names.end());
    CHECK(std::adjacent_find(names.begin(), names.end()) == names.end());
  };
  check_table(model_format_table());
  check_table(refiner_table());
  check_table(strategy_table());
  // The strategies as the paper's tables list them, the method's first; a name no row has gets
  // the table's line.
  std::vector<std::string> strategies;
  for (const StrategyRow* r : strategy_table().rows()) strategies.push_back(r->name);
  CHECK(strategies == std::vector<std::string>{"fillgs", "random", "negative", "interpolation", "fisherrf", "coverage3d", "coverage4d"});
  CHECK(method_strategy().name == "fillgs");
  CHECK_THROWS_WITH(strategy_row("greedy"),
                    "unknown strategy 'greedy' (expected fillgs, random, negative, interpolation, fisherrf, coverage3d or coverage4d)");
  // A run's identity holds a strategy's own parameters only where its row declares some, so
  // the identities recorded before rows declared parameters still match.
  for (const StrategyRow* r : strategy_table().rows()) {
    SelectOptions o;
    o.strategy = r->name;
    CHECK(identity_json(o).contains("parameters") == !r->parameters.empty());
  }
  // The external refiner's command: required, so a run without it is refused before it starts.
  RefinerInputs in;
  CHECK_THROWS_WITH(make_refiner("external", in), "missing --refiner-command");
}

TEST_CASE("Ex4DGS pair: Catmull-Rom keyframes, slerp, temporal opacity, moving static set", "[io][motion]") {
  const std::string dir = scratch("ex4dgs");
  // cfg_args two folders up, as in point_cloud/iteration_N/.
  std::filesystem::create_directories(dir + "/point_cloud/iteration_7");
  std::ofstream(dir + "/cfg_args") << "Namespace(duration=21, time_interval=5, time_pad=2, interp_type='cube', var_pad=3)";
  const std::string pc = dir + "/point_cloud/iteration_7/";
  // Static file: two Gaussians, one still, one with a displacement.
  PlyElement sv = vertex_element(2);
  add_standard(sv, {Vec3f(0, 0, 0), Vec3f(5, 0, 0)});
  add(sv, "xyz_disp_0", {0.0f, 2.1f});
  add(sv, "xyz_disp_1", {0.0f, 0.0f});
  add(sv, "xyz_disp_2", {0.0f, 0.0f});
  PlyData sp;
  sp.elements.push_back(sv);
  write_ply(pc + "point_cloud.ply", sp);
  // Dynamic file: one Gaussian, K = 8 keys, key k at x = k², rotation about z by 10° per key.
  const int K = 8;
  PlyElement dv = vertex_element(1);
  for (int k = 0; k < K; ++k)
    for (int j = 0; j < 3; ++j) add(dv, "motion_xyz_" + std::to_string(k) + "_" + std::to_string(j), {j == 0 ? float(k * k) : 0.0f});
  add_standard(dv, {Vec3f(0, 0, 0)}, "motion_", false);
  add(dv, "motion_opacity_c_0", {3.0f});
  add(dv, "motion_opacity_c_1", {4.0f});
  add(dv, "motion_opacity_v_0", {0.0f});
  add(dv, "motion_opacity_v_1", {std::log(2.0f)});
  for (int k = 0; k < K; ++k) {
    const double h = 0.5 * (10.0 * k) * kPi / 180.0;
    const float q[4] = {float(std::cos(h)), 0, 0, float(std::sin(h))};
    for (int j = 0; j < 4; ++j) add(dv, "motion_rot_" + std::to_string(k) + "_" + std::to_string(j), {q[j]});
  }
  PlyData dp;
  dp.elements.push_back(dv);
  write_ply(pc + "dynamic_point_cloud.ply", dp);

  const GaussianCloud c = read_scene(pc + "point_cloud.ply");
  REQUIRE(c.size() == 3);
  CHECK(c.motion == MotionModel::Keyframed);
  CHECK(c.dynamic_ids == std::vector<uint32_t>{1, 2});
  // D = 21, I = 5, P = 2, cube: S = P + I = 7. Frame = t * 20; u = (frame + 7) / 5.
  for (double frame : {0.0, 3.0, 8.0, 10.5, 20.0}) {
    INFO("frame " << frame);
    const double t = frame / 20.0;
    const FrameGaussians f = frame_at(c, t);
    const double u = (frame + 7) / 5.0;
    const int i = std::clamp(int(std::floor(u)), 1, K - 3);
    const double s = u - i;
    auto P = [](int k) { return double(k * k); };
    const double m0 = (P(i + 1) - P(i - 1)) / 2, m1 = (P(i + 2) - P(i)) / 2;
    const double h00 = 2 * s * s * s - 3 * s * s + 1, h10 = s * s * s - 2 * s * s + s, h01 = -2 * s * s * s + 3 * s * s,
                 h11 = s * s * s - s * s;
    CHECK(f.means[2].x() == Approx(h00 * P(i) + h10 * m0 + h01 * P(i + 1) + h11 * m1).epsilon(1e-5));
    // Rotation: slerp between 10 i and 10 (i+1) degrees about z.
    const double angle = (10.0 * (i + s)) * kPi / 180.0;
    CHECK(f.rotations[2][0] == Approx(std::cos(angle / 2)).epsilon(1e-4));
    CHECK(f.rotations[2][3] == Approx(std::sin(angle / 2)).epsilon(1e-4));
    // Temporal opacity: tau = u; between centres 3 and 4 → 1; otherwise Gaussian falloff.
    double g = 1.0;
    if (!((3 - u) * (4 - u) < 0)) {
      const double m = u - 4.0;
      const double v = (u > 3 || u > 4) ? std::log(2.0) : 0.0;
      const double w = std::exp(v) + 3.0 / (2.36 * 5);
      g = std::exp(-m * m / (w * w));
    }
    CHECK(f.opacities[2] == Approx((1 / (1 + std::exp(-1.0))) * g).epsilon(1e-5));
    // Static set: mean = xyz + xyz_disp * frame / D.
    CHECK(f.means[1].x() == Approx(5 + 2.1 * frame / 21.0).epsilon(1e-5));
    CHECK(f.means[0] == Vec3f(0, 0, 0));
  }
}

TEST_CASE("fillgs 4D PLY round-trips the synthetic scene exactly", "[io][motion]") {
  const SynthScene s = small_synth(7, 64, 48, 0.05);
  const std::string path = scratch("fillgs4d") + "/scene.ply";
  write_fillgs_ply(path, s.scene);
  REQUIRE(detect_scene_format(path) == "fillgs");
  const GaussianCloud c = read_scene(path);
  REQUIRE(c.size() == s.scene.size());
  CHECK(c.dynamic_ids == s.scene.dynamic_ids);  // synth puts the chair last, as the format does
  CHECK(c.keyframed.key_count == 7);
  for (double t : {0.0, 0.1, 0.45, 0.8, 1.0}) {
    const FrameGaussians a = frame_at(s.scene, t), b = frame_at(c, t);
    CHECK(std::memcmp(a.means.data(), b.means.data(), a.means.size() * sizeof(Vec3f)) == 0);
    CHECK(std::memcmp(a.rotations.data(), b.rotations.data(), a.rotations.size() * sizeof(Vec4f)) == 0);
    CHECK(a.opacities == b.opacities);
  }
}

TEST_CASE("a fillgs 4D PLY read a block of rows at a time: the vertex and every key array exact, a NaN named with its row", "[io][motion]") {
  // 2,000 moving Gaussians of degree 1 with 40 keys of every kind (positions, rotations,
  // log-scales, opacities, DC and the band above): a track record of 3,680 bytes, so the
  // element is read in 8 blocks of 284 rows. Each value is distinct: a misplaced one shows.
  const size_t M = 2000, N = 25000, K = 40;
  GaussianCloud c;
  c.sh_degree = 1;
  c.resize(N);
  for (size_t g = 0; g < N; ++g) {
    c.means[g] = Vec3f(float(g) * 1e-3f, 0.5f, 5.0f);
    c.log_scales[g] = Vec3f(-3, -3, -3);
    c.rotations[g] = Vec4f(1, 0, 0, 0);
  }
  // Two opacity logits of +inf, in the vertex element's first and third blocks (10,082 rows
  // of 104 bytes each): kept as +40, with one note for both.
  c.opacity_logits[5] = c.opacity_logits[24000] = INFINITY;
  c.motion = MotionModel::Keyframed;
  for (size_t j = 0; j < M; ++j) c.dynamic_ids.push_back(uint32_t(N - M + j));
  KeyframedMotion& k = c.keyframed;
  k.key_count = int(K);
  k.key_spacing = 1.0 / double(K - 1);
  auto fill = [](std::vector<float>& v, size_t n, float salt) {
    v.resize(n);
    for (size_t i = 0; i < n; ++i) v[i] = salt + float(i % 100003) * 1e-4f;
  };
  fill(k.positions, M * K * 3, 1.0f);
  fill(k.rotations, M * K * 4, 2.0f);
  fill(k.log_scales, M * K * 3, -4.0f);
  fill(k.opacity_logits, M * K, 0.5f);
  fill(k.colours, M * K * 3, 0.25f);
  fill(k.sh_rest, M * K * 9, -0.5f);
  const std::string dir = scratch("fillgs4d_blocks"), path = dir + "/tracks.ply";
  write_fillgs_ply(path, c);
  const GaussianCloud r = read_scene(path);
  REQUIRE(r.keyframed.key_count == int(K));
  CHECK(r.dynamic_ids == c.dynamic_ids);
  CHECK(r.keyframed.positions == k.positions);
  CHECK(r.keyframed.rotations == k.rotations);
  CHECK(r.keyframed.log_scales == k.log_scales);
  CHECK(r.keyframed.opacity_logits == k.opacity_logits);
  CHECK(r.keyframed.colours == k.colours);
  CHECK(r.keyframed.sh_rest == k.sh_rest);
  CHECK(r.means == c.means);
  CHECK(r.sh == c.sh);
  CHECK(r.opacity_logits[5] == 40.0f);
  CHECK(r.opacity_logits[24000] == 40.0f);
  CHECK(std::count_if(r.notes.begin(), r.notes.end(), [](const std::string& n) { return n.find("2 opacity logits in") == 0; }) == 1);
  // A NaN in track row 1500 (the sixth block), key 7's z: named with its row in the element.
  const std::string header = read_ply_header(path), original = read_file(path);
  std::string bytes = original;
  auto count_of = [&](const std::string& element) {
    const size_t at = header.find("element " + element + " ");
    return size_t(std::stoul(header.substr(at + element.size() + 9)));
  };
  auto properties_of = [&](const std::string& element, const std::string& name, size_t* index) {
    size_t at = header.find("element " + element + " "), n = 0;
    const size_t stop = header.find("element ", at + 1);
    for (at = header.find("property ", at); at != std::string::npos && at < stop; at = header.find("property ", at + 1), ++n)
      if (header.compare(at, 16 + name.size(), "property float " + name + "\n") == 0) *index = n;
    return n;
  };
  size_t unused = 0, column = 0;
  const size_t vertex_record = properties_of("vertex", "", &unused) * 4, track_record = properties_of("track", "motion_xyz_7_2", &column) * 4;
  REQUIRE(count_of("vertex") == N);
  REQUIRE(track_record == K * 23 * 4);
  REQUIRE(column == 7 * 3 + 2);
  const float nan = std::nanf("");
  std::memcpy(&bytes[header.size() + N * vertex_record + 1500 * track_record + column * 4], &nan, 4);
  write_file_atomically(dir + "/nan.ply", bytes);
  CHECK_THROWS_WITH(read_scene(dir + "/nan.ply"), Catch::Contains("nan.ply: track 1500 property 'motion_xyz_7_2' is NaN"));
  // NaN in vertex row 21,000 (the third block): its x, then its opacity, named with the row.
  size_t x_column = 0, opacity_column = 0;
  (void)properties_of("vertex", "x", &x_column);
  (void)properties_of("vertex", "opacity", &opacity_column);
  for (const auto& [column, name] : {std::pair<size_t, std::string>{x_column, "x"}, {opacity_column, "opacity"}}) {
    std::string v = original;
    std::memcpy(&v[header.size() + 21000 * vertex_record + column * 4], &nan, 4);
    write_file_atomically(dir + "/vnan.ply", v);
    CHECK_THROWS_WITH(read_scene(dir + "/vnan.ply"), Catch::Contains("vnan.ply: vertex 21000 property '" + name + "' is NaN"));
  }
  // Cut short inside a block, and one byte too many: refused as the whole-file reader refused them.
  write_file_atomically(dir + "/short.ply", original.substr(0, original.size() - 100));
  CHECK_THROWS_WITH(read_scene(dir + "/short.ply"), Catch::Contains("short.ply: truncated"));
  write_file_atomically(dir + "/long.ply", original + "x");
  CHECK_THROWS_WITH(read_scene(dir + "/long.ply"), Catch::Contains("1 bytes follow the last element"));
}

TEST_CASE("bake_tracks reproduces any motion at the key times", "[io][motion]") {
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 0), 0.1f, 0.0f, Vec3f(1, 0, 0));
  add_gaussian(c, Vec3f(1, 0, 0), 0.1f, 0.0f, Vec3f(0, 1, 0));
  c.motion = MotionModel::Polynomial;
  c.dynamic_ids = {1};
  c.polynomial.coeffs = {0.5f, 0, 0, 0, 1, 0, 0, 0, 0};
  c.polynomial.omega = {0, 0, 0, 0.3f};
  c.polynomial.trbf_center = {0.5f};
  c.polynomial.trbf_log_scale = {std::log(0.3f)};
  const GaussianCloud b = bake_tracks(c, 11);
  const std::string path = scratch("bake") + "/baked.ply";
  write_fillgs_ply(path, c, 11);
  const GaussianCloud r = read_scene(path);
  for (int f = 0; f <= 10; ++f) {
    const double t = f / 10.0;
    const FrameGaussians a = frame_at(c, t), x = frame_at(r, t);
    CHECK((a.means[1] - x.means[1]).norm() < 1e-6);
    CHECK((a.rotations[1] - x.rotations[1]).norm() < 1e-6);
    CHECK(a.opacities[1] == Approx(x.opacities[1]).epsilon(1e-5));
  }
  CHECK(b.keyframed.opacity_logits.size() == 11);
}

TEST_CASE("standard 3DGS PLY writer round-trips and keeps the 62-property layout", "[io]") {
  const GaussianCloud c = read_scene(shared_data() + "/scenes/playbot_3k.ply");
  const std::string path = scratch("w3dgs") + "/out.ply";
  write_3dgs_ply(path, c);
  const PlyData ply = read_ply(path);
  const PlyElement& v = ply.element("vertex");
  CHECK(v.property_names.size() == 3 + 3 + 3 + 24 + 1 + 3 + 4);
  CHECK(v.property_names[3] == "nx");
  CHECK(v.property_names[9] == "f_rest_0");
  const GaussianCloud r = read_scene(path);
  CHECK(r.sh == c.sh);
  CHECK(r.opacity_logits == c.opacity_logits);
  CHECK(r.rotations == c.rotations);
  for (size_t g = 0; g < c.size(); ++g) CHECK((r.log_scales[g] - c.log_scales[g]).cwiseAbs().maxCoeff() < 1e-6f);
}

TEST_CASE("a scene with no motion has an empty dynamic set", "[io][motion]") {
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 1), 0.1f, 0.0f, Vec3f(1, 1, 1));
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = {0};
  c.keyframed.key_count = 4;
  c.keyframed.key_spacing = 1.0 / 3;
  c.keyframed.positions.assign(12, 0.0f);
  for (int k = 0; k < 4; ++k) c.keyframed.positions[3 * k + 2] = 1.0f;
  c.keyframed.rotations = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  CHECK(partition_static_dynamic(c) == 1);
  CHECK(c.motion == MotionModel::Static);
  CHECK(c.dynamic_count() == 0);
  CHECK(frame_at(c, 1.0).means[0] == Vec3f(0, 0, 1));
}

TEST_CASE("colour keys: every SH band linear between keys, the same in the cloud, the trainer and the 4D PLY", "[io][motion]") {
  // Two Gaussians of degree 1, both keyed (3 keys over t = 0, 0.5, 1); Gaussian 1's colour keys
  // are all equal (still colour), Gaussian 0's change in the DC and in the band above it.
  GaussianCloud c;
  c.sh_degree = 1;
  c.resize(2);
  for (size_t g = 0; g < 2; ++g) {
    c.means[g] = Vec3f(float(g), 0, 5);
    c.log_scales[g] = Vec3f(-2, -2, -2);
    c.rotations[g] = Vec4f(1, 0, 0, 0);
  }
  c.motion = MotionModel::Keyframed;
  c.dynamic_ids = {0, 1};
  KeyframedMotion& k = c.keyframed;
  k.key_count = 3;
  k.key_spacing = 0.5;
  k.positions.assign(2 * 3 * 3, 0.0f);
  k.rotations.assign(2 * 3 * 4, 0.0f);
  for (size_t j = 0; j < 2; ++j)
    for (size_t key = 0; key < 3; ++key) {
      for (int a = 0; a < 3; ++a) k.positions[(j * 3 + key) * 3 + a] = c.means[j][a];
      k.rotations[(j * 3 + key) * 4] = 1.0f;
    }
  k.colours.resize(2 * 3 * 3);
  k.sh_rest.resize(2 * 3 * 9);
  for (size_t key = 0; key < 3; ++key) {
    for (size_t a = 0; a < 3; ++a) k.colours[key * 3 + a] = 0.1f * float(key) + 0.01f * float(a), k.colours[(3 + key) * 3 + a] = 0.2f;
    for (size_t a = 0; a < 9; ++a) k.sh_rest[key * 9 + a] = key == 1 ? 0.4f : -0.2f * float(a % 3), k.sh_rest[(3 + key) * 9 + a] = 0.3f;
  }
  c.validate("test");
  // At t = 0.25 (between keys 0 and 1, halfway): the DC and each band halfway.
  const FrameGaussians f = frame_at(c, 0.25);
  for (size_t a = 0; a < 3; ++a) CHECK(f.sh[a] == Approx(0.05 + 0.01 * double(a)));
  for (size_t a = 0; a < 9; ++a) CHECK(f.sh[3 + a] == Approx(0.5 * (-0.2 * double(a % 3) + 0.4)));
  // The trainer's parameters give the same SH at t (params_at interpolates key_sh).
  const ModelParams<float> p = params_from_cloud<float>(c);
  DiffFrame<float> d;
  params_at(p, 0.25, &d);
  for (size_t a = 0; a < 12; ++a) CHECK(d.sh[a] == Approx(f.sh[a]));
  // Back to a cloud and through the 4D PLY (which the reader partitions): every band at every
  // key of the Gaussian whose colour moves; the one whose colour keys never change (nor
  // anything else) is static, with its keys' colour.
  const GaussianCloud back = cloud_from_params(p);
  REQUIRE(back.keyframed.sh_rest == k.sh_rest);
  const std::string path = fillgs::test::scratch("colour_keys") + "/keys.ply";
  write_fillgs_ply(path, back);
  const GaussianCloud read = read_scene(path);
  REQUIRE(read.dynamic_count() == 1);
  const uint32_t moving = read.dynamic_ids[0], still = 1 - moving;
  CHECK(read.means[moving].x() == 0.0f);  // Gaussian 0
  REQUIRE(read.keyframed.sh_rest.size() == 27);
  for (size_t i = 0; i < 27; ++i) CHECK(read.keyframed.sh_rest[i] == k.sh_rest[i]);
  for (size_t a = 0; a < 9; ++a) CHECK(read.sh[size_t(still) * 12 + 3 + a] == 0.3f);
}
