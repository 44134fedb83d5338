// The fourth hostile round (tests/README.md, "Robustness"): help that a flag's value must not
// swallow, numbers that wrap, folders that hold two models, a deformation model's canonical
// cloud read as fillgs's own format, a seg/ that is a file, colour gains of zero, records
// that vouch for another run, an exploration of nothing and tensors of negative size. Every
// case is refused with one line naming the file, element or option, or handled as the
// documents say; each failed before the fix.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "helpers.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/io/trained_models.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/train/train.hpp"
#include "io/model_support.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

namespace round4 {  // named: the unity build puts this file beside others with names of their own

const char* kPly =
    "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float f_dc_0\n"
    "property float f_dc_1\nproperty float f_dc_2\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
    "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n"
    "0 0 0 0.1 0.2 0.3 1 -3 -3 -3 1 0 0 0\n";

}  // namespace round4

using round4::kPly;

TEST_CASE("help wins over a flag that takes a value (--out --help): nothing runs, no folder named --help", "[robust][hostile][cli]") {
  const std::string dir = scratch("help_wins");
  const fs::path before = fs::current_path();
  fs::current_path(dir);
  const std::vector<std::vector<std::string>> calls = {{"synth", "--out", "--help"},
                                                       {"bench", "--out", "--help"},
                                                       {"run", "--out", "--help"},
                                                       {"render", "s.ply", "c.json", "--out", "--help"},
                                                       {"observe", "--scene", "-h"}};
  for (const auto& args : calls) {
    const CliResult r = run_cli(args);
    INFO(args[0] << ": " << r.err);
    CHECK(r.code == 0);
    CHECK(r.out.find("--out") != std::string::npos);  // the command's help
    CHECK_FALSE(fs::exists(fs::path(dir) / "--help"));
    CHECK_FALSE(fs::exists(fs::path(dir) / "-h"));
  }
  fs::current_path(before);
}

TEST_CASE("a --camera-times frame beyond an int is refused, not wrapped to another frame", "[robust][hostile][cli]") {
  const std::string dir = scratch("camera_times_wrap");
  write(dir + "/chosen.json", R"({"chosen": [{"camera": "cam00", "frame": 4294967298}]})");
  expect_error(run_cli({"train", "--images", dir, "--cameras", dir + "/none.json", "--train-cameras", "cam00", "--camera-times",
                        dir + "/chosen.json", "--out", dir + "/o"}),
               {"chosen.json", "camera-time 0", "4294967298"});
  write(dir + "/negative.json", R"([{"camera": "cam00", "frame": -3}])");
  expect_error(run_cli({"train", "--images", dir, "--cameras", dir + "/none.json", "--train-cameras", "cam00", "--camera-times",
                        dir + "/negative.json", "--out", dir + "/o"}),
               {"negative.json", "frame -3"});
  CHECK_FALSE(fs::exists(dir + "/o"));
}

TEST_CASE("a folder holding two models is not read as whichever format detection asks first", "[robust][hostile][cli]") {
  const std::string dir = scratch("two_models");
  write(dir + "/params.npz", "");
  write(dir + "/chkpnt7000.pth", "");
  expect_error(run_cli({"info", dir}), {dir, "dynamic3dgs", "4dgs", "--scene-format"});
}

TEST_CASE("the fillgs format (--scene-format fillgs) refuses a deformation model's canonical point cloud, as every other path does", "[robust][hostile][cli]") {
  const std::string dir = scratch("canonical_as_fillgs");
  write(dir + "/point_cloud.ply", kPly);
  write(dir + "/deformation.pth", "");
  expect_error(run_cli({"info", dir + "/point_cloud.ply", "--scene-format", "fillgs"}), {"point_cloud.ply", "canonical point cloud"});
  expect_error(run_cli({"info", dir + "/point_cloud.ply", "--scene-format", "3dgs"}), {"point_cloud.ply", "canonical point cloud"});
  write(dir + "/alone/scene.ply", kPly);  // a plain PLY with nothing beside it still reads
  CHECK(run_cli({"info", dir + "/alone/scene.ply", "--scene-format", "fillgs"}).code == 0);
}

TEST_CASE("a seg that is a file, or a link to one, is refused, not read as no masks", "[robust][hostile]") {
  const std::string dir = scratch("seg_file");
  REQUIRE(run_cli({"synth", "--out", dir + "/scene", "--frames", "2", "--width", "32", "--height", "24", "--quiet"}).code == 0);
  const std::string scene = dir + "/scene", cams = scene + "/transforms_train.json";
  CHECK_NOTHROW(Dataset::load(scene, cams));
  write(scene + "/seg", "not a folder");
  CHECK(error_of([&] { Dataset::load(scene, cams); }).find("seg: not a folder") != std::string::npos);
  fs::remove(scene + "/seg");
  write(dir + "/elsewhere.txt", "x");
  fs::create_symlink(dir + "/elsewhere.txt", scene + "/seg");
  const std::string linked = error_of([&] { Dataset::load(scene, cams); });
  CHECK(linked.find("seg: not a folder") != std::string::npos);
  CHECK(linked.find("elsewhere.txt") != std::string::npos);
}

TEST_CASE("a colour correction whose gain is 0 is refused when read, naming the file and camera", "[robust][hostile]") {
  const std::string dir = scratch("zero_gain");
  write(dir + "/cc.json", R"({"cam00": {"gain": [1, 0, 1], "offset": [0, 0, 0]}})");
  const std::string e = error_of([&] { read_colour_correction(dir + "/cc.json"); });
  CHECK(e.find("cc.json") != std::string::npos);
  CHECK(e.find("camera 'cam00' gain[1] is 0") != std::string::npos);
  write(dir + "/good.json", R"({"cam00": {"gain": [1, 0.9, 1.1], "offset": [0, 0.01, 0]}})");
  CHECK(read_colour_correction(dir + "/good.json").size() == 1);
}

TEST_CASE("a kept result.json is checked against the run it is reused for, and a summary must be an object", "[robust][hostile]") {
  const std::string dir = scratch("records");
  RunResult control;
  control.id = "control";
  control.seed = 1;
  make_directories(dir + "/n3v_s1/runs/random.w-none");
  save_result(dir + "/n3v_s1/runs/random.w-none/result.json", control);  // another run's result, copied in
  const std::string e = error_of([&] { load_result(dir + "/n3v_s1/runs/random.w-none/result.json", "random.w-none", 1); });
  CHECK(e.find("holds run 'control', not 'random.w-none'") != std::string::npos);
  save_result(dir + "/n3v_s1/runs/control/result.json", control);
  CHECK(error_of([&] { load_result(dir + "/n3v_s1/runs/control/result.json", "control", 2); }).find("holds seed 1's result, not seed 2's") !=
        std::string::npos);
  CHECK(load_result(dir + "/n3v_s1/runs/control/result.json", "control", 1).id == "control");
  control.variant = "technicolor";  // the same run of another scene
  save_result(dir + "/n3v_s1/runs/control/result.json", control);
  CHECK(error_of([&] { load_result(dir + "/n3v_s1/runs/control/result.json", "control", 1, "n3v"); })
            .find("holds the result of scene 'technicolor', not of scene 'n3v'") != std::string::npos);
  write(dir + "/n3v_s1/options.json", "{}");  // the bench's tables refuse the copied record too
  CHECK(error_of([&] { collect_results(dir); }).find("random.w-none") != std::string::npos);
  write(dir + "/summary.json", "[1]");
  CHECK(error_of([&] { read_json_object(dir + "/summary.json"); }).find("summary.json: expected a JSON object, got an array") != std::string::npos);
}

TEST_CASE("explore of an empty scene from one camera says why, not OpenVDB's words", "[robust][hostile][cli]") {
  const std::string dir = scratch("explore_empty");
  write(dir + "/empty.ply", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nproperty float f_dc_0\n"
                            "property float f_dc_1\nproperty float f_dc_2\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
                            "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n");
  write(dir + "/one.json", R"({"fl_x": 40, "w": 48, "h": 32, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})");
  const CliResult r = run_cli({"explore", "--scene", dir + "/empty.ply", "--cameras", dir + "/one.json", "--out", dir + "/o"});
  expect_error(r, {"exploration grid", "no Gaussians"});
  CHECK(r.err.find("Non-zero scale") == std::string::npos);
}

TEST_CASE("a tensor of negative size is refused, naming it, before any count is made from it", "[robust][hostile]") {
  TorchTensor t;
  t.shape = {0, -2147483649LL, 3};
  const std::string e = error_of([&] { model_io::checked(t, "chkpnt.pth", "entry 3 (_features_rest)", {0, -1, 3}); });
  CHECK(e.find("chkpnt.pth: entry 3 (_features_rest)") != std::string::npos);
  CHECK(e.find("dimension 1 is negative") != std::string::npos);
}

// ------------------------------------------------------------------ the still rule and the keys

namespace round4 {

/// A model whose Gaussian g (1 to 6) moves in one property only, as a sine of `period` frames
/// (0: still): position, rotation, log-scale, opacity, the SH DC, one band-3 SH coefficient.
class OneProperty : public TrainedModel {
 public:
  OneProperty(int frame_count, double period) : period_(period) {
    frames = frame_count;
    time_first = 0.0, time_last = 1.0;
    format = "test", source = "one-property";
  }
  size_t size() const override { return 7; }
  ModelState at(double t) const override {
    const double w = std::sin(2.0 * M_PI * t * double(frames - 1) / period_);
    ModelState s;
    s.sh_degree = 3;
    for (size_t g = 0; g < 7; ++g) {
      s.means.push_back(Vec3f(0.1f * float(g), 0, 3));
      s.log_scales.push_back(Vec3f::Constant(-3));
      s.rotations.push_back(Vec4f(1, 0, 0, 0));
      s.opacity_logits.push_back(1.0f);
    }
    s.sh.assign(7 * 16 * 3, 0.1f);
    s.means[1].x() += float(0.05 * w);
    const double half = 0.5 * 10.0 * M_PI / 180.0 * w;  // 10 degrees about z
    s.rotations[2] = Vec4f(float(std::cos(half)), 0, 0, float(std::sin(half)));
    s.log_scales[3] += Vec3f::Constant(float(0.1 * w));
    s.opacity_logits[4] += float(1.0 * w);
    s.sh[5 * 48 + 0] += float(0.1 * w);       // DC, red
    s.sh[6 * 48 + 12 * 3] += float(0.1 * w);  // band 3 (coefficient 12), red: all E-D3DGS's colour head deforms
    return s;
  }

 private:
  double period_;
};

}  // namespace round4

TEST_CASE("the still rule measures every property a model lets vary, every SH band included", "[robust][hostile][trained-models]") {
  const auto model = std::make_shared<round4::OneProperty>(120, 240.0);
  const GaussianCloud c = stream_trained_model(model, StillRule{});
  CHECK(c.dynamic_ids == std::vector<uint32_t>{1, 2, 3, 4, 5, 6});  // 6 was frozen at frame 0 before
  // The band-3 coefficient follows the model at any time, not frame 0's value.
  for (double t : {0.25, 0.5, 0.8}) {
    const FrameGaussians f = frame_at(c, t);
    CHECK(f.sh[6 * 48 + 36] == Approx(model->at(t).sh[6 * 48 + 36]).margin(1e-6));
  }
}

TEST_CASE("training keys keep every keyed property within its tolerance, not positions alone", "[robust][hostile][trained-models]") {
  // Period 8 frames: Gaussian 1's positions need keys as dense as the others' rotation, scale
  // and opacity; with Gaussian 1 still (no position moves), the keys were one every 32 frames
  // before, whatever the rest did.
  const int F = 97;
  for (const bool with_position : {true, false}) {
    const auto model = std::make_shared<round4::OneProperty>(F, 8.0);
    GaussianCloud c = stream_trained_model(model, StillRule{});
    if (!with_position) {  // Gaussian 1 made still: no position moves
      c.dynamic_ids.erase(c.dynamic_ids.begin());
      c.source_rows.erase(c.source_rows.begin());
    }
    KeyChoice kc;
    const GaussianCloud keyed = keyed_for_training(c, &kc);
    INFO("with position motion " << with_position << ": " << kc.keys << " keys, limiting " << kc.limiting);
    CHECK(kc.worst_share <= 1.0);
    const KeyTolerance tol;
    for (int f = 0; f < F; ++f) {
      const double t = double(f) / double(F - 1);
      const FrameGaussians k = frame_at(keyed, t);
      const ModelState truth = model->at(t);
      for (uint32_t g : c.dynamic_ids) {
        CHECK(k.opacities[g] == Approx(sigmoid(truth.opacity_logits[g])).margin(tol.opacity));
        CHECK(std::log(k.scales[g].x()) == Approx(truth.log_scales[g].x()).margin(tol.log_scale));
        const double dot = std::min(1.0, std::fabs(double(k.rotations[g].dot(truth.rotations[g].normalized()))));
        CHECK(2.0 * std::acos(dot) * 180.0 / M_PI <= tol.rotation_degrees + 1e-4);
      }
    }
  }
}
