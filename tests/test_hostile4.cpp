// The fourth hostile round (tests/README.md, "Robustness"): help that a flag's value must not
// swallow, numbers that wrap, folders that hold two models, a deformation model's canonical
// cloud read as fillgs's own format, a seg/ that is a file, colour gains of zero, records
// that vouch for another run, an exploration of nothing and tensors of negative size. Every
// case is refused with one line naming the file, element or option, or handled as the
// documents say; each failed before the fix.
#include <nlohmann/json.hpp>

#include <algorithm>
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
#include "fillgs/train/train.hpp"
#include "io/model_support.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

namespace round4 {  // named: the unity build puts this file beside others with helpers of the same names

void write(const std::string& path, const std::string& bytes) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

/// One line, exit 1, naming every word.
void expect_error(const CliResult& r, const std::vector<std::string>& words) {
  INFO("stderr: " << r.err);
  CHECK(r.code == 1);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  for (const std::string& w : words) {
    INFO("should mention '" << w << "'");
    CHECK(r.err.find(w) != std::string::npos);
  }
}

/// The message of the Error `f` throws ("" where it throws none).
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

const char* kPly =
    "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float f_dc_0\n"
    "property float f_dc_1\nproperty float f_dc_2\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
    "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n"
    "0 0 0 0.1 0.2 0.3 1 -3 -3 -3 1 0 0 0\n";

}  // namespace round4

using round4::kPly;

TEST_CASE("--help wins over a flag that takes a value: nothing runs, no folder named --help", "[robust][hostile][cli]") {
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
  round4::write(dir + "/chosen.json", R"({"chosen": [{"camera": "cam00", "frame": 4294967298}]})");
  round4::expect_error(run_cli({"train", "--images", dir, "--cameras", dir + "/none.json", "--train-cameras", "cam00", "--camera-times",
                        dir + "/chosen.json", "--out", dir + "/o"}),
               {"chosen.json", "camera-time 0", "4294967298"});
  round4::write(dir + "/negative.json", R"([{"camera": "cam00", "frame": -3}])");
  round4::expect_error(run_cli({"train", "--images", dir, "--cameras", dir + "/none.json", "--train-cameras", "cam00", "--camera-times",
                        dir + "/negative.json", "--out", dir + "/o"}),
               {"negative.json", "frame -3"});
  CHECK_FALSE(fs::exists(dir + "/o"));
}

TEST_CASE("a folder holding two models is not read as whichever format detection asks first", "[robust][hostile][cli]") {
  const std::string dir = scratch("two_models");
  round4::write(dir + "/params.npz", "");
  round4::write(dir + "/chkpnt7000.pth", "");
  round4::expect_error(run_cli({"info", dir}), {dir, "dynamic3dgs", "4dgs", "--scene-format"});
}

TEST_CASE("--scene-format fillgs refuses a deformation model's canonical point cloud, as every other path does", "[robust][hostile][cli]") {
  const std::string dir = scratch("canonical_as_fillgs");
  round4::write(dir + "/point_cloud.ply", kPly);
  round4::write(dir + "/deformation.pth", "");
  round4::expect_error(run_cli({"info", dir + "/point_cloud.ply", "--scene-format", "fillgs"}), {"point_cloud.ply", "canonical point cloud"});
  round4::expect_error(run_cli({"info", dir + "/point_cloud.ply", "--scene-format", "3dgs"}), {"point_cloud.ply", "canonical point cloud"});
  round4::write(dir + "/alone/scene.ply", kPly);  // a plain PLY with nothing beside it still reads
  CHECK(run_cli({"info", dir + "/alone/scene.ply", "--scene-format", "fillgs"}).code == 0);
}

TEST_CASE("a seg that is a file, or a link to one, is refused, not read as no masks", "[robust][hostile]") {
  const std::string dir = scratch("seg_file");
  REQUIRE(run_cli({"synth", "--out", dir + "/scene", "--frames", "2", "--width", "32", "--height", "24", "--quiet"}).code == 0);
  const std::string scene = dir + "/scene", cams = scene + "/transforms_train.json";
  CHECK_NOTHROW(Dataset::load(scene, cams));
  round4::write(scene + "/seg", "not a folder");
  CHECK(round4::error_of([&] { Dataset::load(scene, cams); }).find("seg: not a folder") != std::string::npos);
  fs::remove(scene + "/seg");
  round4::write(dir + "/elsewhere.txt", "x");
  fs::create_symlink(dir + "/elsewhere.txt", scene + "/seg");
  const std::string linked = round4::error_of([&] { Dataset::load(scene, cams); });
  CHECK(linked.find("seg: not a folder") != std::string::npos);
  CHECK(linked.find("elsewhere.txt") != std::string::npos);
}

TEST_CASE("a colour correction whose gain is 0 is refused when read, naming the file and camera", "[robust][hostile]") {
  const std::string dir = scratch("zero_gain");
  round4::write(dir + "/cc.json", R"({"cam00": {"gain": [1, 0, 1], "offset": [0, 0, 0]}})");
  const std::string e = round4::error_of([&] { read_colour_correction(dir + "/cc.json"); });
  CHECK(e.find("cc.json") != std::string::npos);
  CHECK(e.find("camera 'cam00' gain[1] is 0") != std::string::npos);
  round4::write(dir + "/good.json", R"({"cam00": {"gain": [1, 0.9, 1.1], "offset": [0, 0.01, 0]}})");
  CHECK(read_colour_correction(dir + "/good.json").size() == 1);
}

TEST_CASE("a kept result.json is checked against the run it is reused for, and a summary must be an object", "[robust][hostile]") {
  const std::string dir = scratch("records");
  RunResult control;
  control.id = "control";
  control.seed = 1;
  make_directories(dir + "/n3v_s1/runs/random.w-none");
  save_result(dir + "/n3v_s1/runs/random.w-none/result.json", control);  // another run's result, copied in
  const std::string e = round4::error_of([&] { load_result(dir + "/n3v_s1/runs/random.w-none/result.json", "random.w-none", 1); });
  CHECK(e.find("holds run 'control', not 'random.w-none'") != std::string::npos);
  save_result(dir + "/n3v_s1/runs/control/result.json", control);
  CHECK(round4::error_of([&] { load_result(dir + "/n3v_s1/runs/control/result.json", "control", 2); }).find("holds seed 1's result, not seed 2's") !=
        std::string::npos);
  CHECK(load_result(dir + "/n3v_s1/runs/control/result.json", "control", 1).id == "control");
  round4::write(dir + "/n3v_s1/options.json", "{}");  // the bench's tables refuse the copied record too
  CHECK(round4::error_of([&] { collect_results(dir); }).find("random.w-none") != std::string::npos);
  round4::write(dir + "/summary.json", "[1]");
  CHECK(round4::error_of([&] { read_json_object(dir + "/summary.json"); }).find("summary.json: expected a JSON object, got an array") != std::string::npos);
}

TEST_CASE("explore of an empty scene from one camera says why, not OpenVDB's words", "[robust][hostile][cli]") {
  const std::string dir = scratch("explore_empty");
  round4::write(dir + "/empty.ply", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nproperty float f_dc_0\n"
                            "property float f_dc_1\nproperty float f_dc_2\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\n"
                            "property float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n");
  round4::write(dir + "/one.json", R"({"fl_x": 40, "w": 48, "h": 32, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})");
  const CliResult r = run_cli({"explore", "--scene", dir + "/empty.ply", "--cameras", dir + "/one.json", "--out", dir + "/o"});
  round4::expect_error(r, {"exploration grid", "no Gaussians"});
  CHECK(r.err.find("Non-zero scale") == std::string::npos);
}

TEST_CASE("a tensor of negative size is refused, naming it, before any count is made from it", "[robust][hostile]") {
  TorchTensor t;
  t.shape = {0, -2147483649LL, 3};
  const std::string e = round4::error_of([&] { model_io::checked(t, "chkpnt.pth", "entry 3 (_features_rest)", {0, -1, 3}); });
  CHECK(e.find("chkpnt.pth: entry 3 (_features_rest)") != std::string::npos);
  CHECK(e.find("dimension 1 is negative") != std::string::npos);
}
