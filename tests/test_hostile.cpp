// The third hostile round (tests/README.md, "Robustness"): crafted .pth archives whose
// extents wrap around 2^64, storages that declare more than they hold, files that amplify into
// gigabytes, times that would become indices, outputs that are not files, refiners that fail
// silently, and choices that were made without a word. Every case is refused with one line
// naming the file and the element, or handled as the documents say.
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "helpers.hpp"
#include "torch_craft.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/base/process.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/io/trained_models.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

namespace {

std::string write_pth(const std::string& dir, const std::string& name, const std::string& bytes) {
  fs::create_directories(dir);
  const std::string path = dir + "/" + name;
  write_file_atomically(path, bytes);
  return path;
}

/// Reads every tensor of a state dict .pth (as the model readers do).
size_t read_all(const std::string& path) {
  const TorchFile tf(path);
  size_t values = 0;
  for (const auto& [key, ref] : tf.string_entries(tf.root(), "state dict")) values += tf.tensor(ref, "key '" + key + "'").numel();
  return values;
}

}  // namespace

TEST_CASE(".pth extents that wrap around 2^64 are refused, never read", "[robust][hostile]") {
  const std::string dir = scratch("hostile_wrap");
  const std::string storage = float_storage(9);
  // A control: a valid view (a transposed 3 x 3) reads the storage's values.
  const std::string ok = write_pth(dir, "ok.pth", craft_pth({{"w", "0", 9, 0, {3, 3}, {1, 3}}}, {{"0", storage}}));
  {
    const TorchFile tf(ok);
    const TorchTensor t = tf.tensor(tf.find(tf.root(), "w"), "w");
    REQUIRE(t.numel() == 9);
    CHECK(t.values[1] == 3.0f);  // element (0, 1) = storage[0 * 1 + 1 * 3]
    CHECK(t.values[3] == 1.0f);
  }
  const int64_t big = int64_t(1) << 62;
  struct Case {
    const char* name;
    CraftTensor t;
  };
  const std::vector<Case> cases = {
      // 2 x 2 x 2 x 2 with strides 2^62: the last element's index, 4 x 2^62, wraps to 0.
      {"sum", {"w", "0", 9, 0, {2, 2, 2, 2}, {big, big, big, big}}},
      // offset 3, stride 2^63 - 1 over 3 elements: 3 + 2 (2^63 - 1) wraps to 1; element 1 lies
      // 2^63 floats past the storage and used to crash.
      {"offset", {"w", "0", 9, 3, {3}, {INT64_MAX}}},
      // the product itself overflows: (2^62) x 8.
      {"product", {"w", "0", 9, 0, {9}, {big}}},
  };
  for (const Case& c : cases) {
    const std::string path = write_pth(dir, std::string(c.name) + ".pth", craft_pth({c.t}, {{"0", storage}}));
    INFO(c.name);
    CHECK_THROWS_WITH(read_all(path), Catch::Contains(path + ": key 'w' extent overflows"));
  }
}

TEST_CASE(".pth storages are what they declare: the message names the declared count", "[robust][hostile]") {
  const std::string dir = scratch("hostile_declared");
  const std::string path = write_pth(dir, "declared.pth", craft_pth({{"w", "0", int64_t(1) << 40, 0, {3}, {4}}}, {{"0", float_storage(9)}}));
  CHECK_THROWS_WITH(read_all(path), Catch::Contains(path + ": key 'w': its storage '0' declares 1099511627776 elements of float32, its entry holds 36 bytes"));
  const std::string missing = write_pth(dir, "missing.pth", craft_pth({{"w", "7", 9, 0, {3}, {1}}}, {{"0", float_storage(9)}}));
  CHECK_THROWS_WITH(read_all(missing), Catch::Contains(missing + ": key 'w': its storage '7' has no entry archive/data/7"));
}

TEST_CASE(".pth amplification: storages inflated once, pickles and tensors charged to FILLGS_MAX_ALLOC", "[robust][hostile]") {
  const std::string dir = scratch("hostile_amplify");
  // 226 one-element views of one deflated 64 MB storage: 64 MB inflated once, not 226 times
  // (14 GB), so a 200 MB budget holds.
  const size_t n = size_t(16) << 20;
  std::vector<CraftTensor> views;
  for (int k = 0; k < 226; ++k) views.push_back({"w" + std::to_string(k), "0", int64_t(n), int64_t(k) * 1000, {1}, {1}});
  const std::string many = write_pth(dir, "views.pth", craft_pth(views, {{"0", std::string(n * 4, '\0')}}, true));
  CHECK(fs::file_size(many) < 200000);
  {
    EnvOverride cap("FILLGS_MAX_ALLOC", std::to_string(200 << 20));
    CHECK(read_all(many) == 226);
  }
  // Whole-storage views of the same storage: each is 64 MB of floats; the budget stops the
  // file at the view that crosses it, naming it.
  std::vector<CraftTensor> whole;
  for (int k = 0; k < 20; ++k) whole.push_back({"w" + std::to_string(k), "0", int64_t(n), 0, {int64_t(n)}, {1}});
  const std::string big = write_pth(dir, "whole.pth", craft_pth(whole, {{"0", std::string(n * 4, '\0')}}, true));
  {
    EnvOverride cap("FILLGS_MAX_ALLOC", std::to_string(300 << 20));
    CHECK_THROWS_WITH(read_all(big), Catch::Contains(big + ": key 'w") && Catch::Contains("would bring this file's memory to") &&
                                         Catch::Contains("FILLGS_MAX_ALLOC"));
  }
  // A pickle of a million values (2 MB of opcodes: EMPTY_LIST, then None + APPEND pairs):
  // about 150 MB of values, refused under a 50 MB budget as it grows.
  Pickle p;
  p.op(']');
  for (int k = 0; k < 1000000; ++k) p.op('N').op('a');
  p.op('.');
  {
    EnvOverride cap("FILLGS_MAX_ALLOC", std::to_string(50 << 20));
    PickleValues v;
    CHECK_THROWS_WITH(run_pickle(p.b, "list.pkl", v), Catch::Contains("list.pkl: pickle values") && Catch::Contains("would bring this file's memory to"));
  }
  PickleValues v;
  run_pickle(p.b, "list.pkl", v);  // under the machine's own budget it reads
  CHECK(v.items(v.root()).size() == 1000000);
}

TEST_CASE("zip archives with two entries of one name are refused, not read one way", "[robust][hostile]") {
  const std::string dir = scratch("hostile_zip");
  const std::string path = write_pth(dir, "params.npz", zip_of({{"means3D.npy", "a"}, {"rgb_colors.npy", "b"}, {"means3D.npy", "c"}}));
  CHECK_THROWS_WITH(ZipArchive(path), Catch::Contains(path + ": entry 'means3D.npy' appears twice"));
}

TEST_CASE("cfg_args with bytes that are not UTF-8 are refused at the byte, naming the file", "[robust][hostile]") {
  CHECK_THROWS_WITH(python_literal_to_json(std::string("Namespace(a='x\xff')"), "run/cfg_args"),
                    Catch::Contains("run/cfg_args: invalid UTF-8 byte 0xff at character 14"));
  CHECK_THROWS_WITH(python_literal_to_json(std::string("Namespace(a='\xc0\xaf')"), "cfg"), Catch::Contains("invalid UTF-8 byte 0xc0"));  // overlong '/'
  CHECK_THROWS_WITH(python_literal_to_json(std::string("Namespace(a='\xed\xa0\x80')"), "cfg"), Catch::Contains("invalid UTF-8 byte 0xed"));  // a surrogate
  CHECK(python_literal_to_json(std::string("Namespace(a='caf\xc3\xa9 \xf0\x9f\x8e\xa5')"), "cfg") == "{\"a\":\"caf\xc3\xa9 \xf0\x9f\x8e\xa5\"}");
  CHECK(first_invalid_utf8("plain") == std::string::npos);
  CHECK(first_invalid_utf8(std::string("ab\xe2\x82")) == 2);  // truncated at the end
}

TEST_CASE("an output never replaces what is not a regular file", "[robust][hostile]") {
  const std::string dir = scratch("hostile_outputs");
  const std::string F = dir + "/tiny.ply";
  {
    GaussianCloud c;
    add_gaussian(c, Vec3f(0, 0, 0), 0.1f, 2.0f, Vec3f(0.5f, 0.4f, 0.3f));
    add_gaussian(c, Vec3f(0.2f, 0, 0.1f), 0.1f, 2.0f, Vec3f(0.2f, 0.4f, 0.3f));
    write_3dgs_ply(F, c, 0.0);
  }
  write_file_atomically(dir + "/cams.json", R"({"fl_x": 40, "w": 48, "h": 32, "frames": [
      {"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]})");
  const std::string fifo = dir + "/fifo";
  REQUIRE(::mkfifo(fifo.c_str(), 0644) == 0);
  fs::create_directories(dir + "/folder");
  for (const std::string& out : {fifo, dir + "/folder", std::string("/dev/null")}) {
    for (const std::vector<std::string>& args : {std::vector<std::string>{"cameras", "--cameras", dir + "/cams.json", "--to", "transforms", "--out", out},
                                                 std::vector<std::string>{"convert", "--scene", F, "--to", "3dgs", "--out", out}}) {
      const CliResult r = run_cli(args);
      INFO(args[0] << " --out " << out << ": " << r.err);
      CHECK(r.code == 1);
      CHECK(r.err.find(out) != std::string::npos);
      CHECK(r.err.find("fillgs replaces only regular files") != std::string::npos);
    }
  }
  struct stat st {};
  REQUIRE(::stat(fifo.c_str(), &st) == 0);
  CHECK(S_ISFIFO(st.st_mode));
  REQUIRE(::stat("/dev/null", &st) == 0);
  CHECK(S_ISCHR(st.st_mode));
  CHECK(fs::is_directory(dir + "/folder"));
  // A regular file, and a new name, are written.
  write_file_atomically(dir + "/old.json", "old");
  CHECK(run_cli({"cameras", "--cameras", dir + "/cams.json", "--to", "transforms", "--out", dir + "/old.json"}).code == 0);
  CHECK(read_file(dir + "/old.json") != "old");
}

TEST_CASE("a commit into an existing folder stopped half-way leaves a marker readers and the next run honour", "[robust][hostile]") {
  const std::string dir = scratch("hostile_commit");
  const std::string out = dir + "/out";
  fs::create_directories(out);
  write_file_atomically(out + "/count.npy", "old count");
  write_file_atomically(out + "/deficiency.npy", "old deficiency");
  write_file_atomically(out + "/mine.txt", "the user's");
  write_image(out + "/view.png", Image(2, 2, 3));
  // The real commit stopped half-way: a folder stands where the new run's blocker.npy goes,
  // so its rename fails (as a kill between two renames would stop it) and commit() throws
  // with the folder mixed, whichever files it had moved by then.
  fs::create_directories(out + "/blocker.npy/inside");
  {
    OutputFolder f(out);
    for (const char* name : {"count.npy", "deficiency.npy", "blocker.npy"}) write_file_atomically(join_path(f.path(), name), std::string("new ") + name);
    CHECK_THROWS_WITH(f.commit(), Catch::Contains("the commit stopped after"));
  }
  REQUIRE(fs::exists(out + "/.fillgs-commit-incomplete"));
  const std::string named = slurp(out + "/.fillgs-commit-incomplete");
  for (const char* name : {"count.npy", "deficiency.npy", "blocker.npy"}) CHECK(named.find(std::string("\n") + name + "\n") != std::string::npos);
  fs::remove_all(out + "/blocker.npy");
  // Readers refuse every file of the folder, naming the marker.
  CHECK_THROWS_WITH(read_file(out + "/deficiency.npy"), Catch::Contains("deficiency.npy: the fillgs command that wrote") &&
                                                            Catch::Contains(".fillgs-commit-incomplete is there"));
  CHECK_THROWS_WITH(read_file(out + "/mine.txt"), Catch::Contains("killed while moving its files into place"));
  CHECK_THROWS_WITH(read_image(out + "/view.png"), Catch::Contains("view.png: the fillgs command that wrote"));
  // The next commit on the folder writes its own files, removes what the interrupted one
  // named and it does not write again, and clears the marker; the user's file stays.
  {
    OutputFolder f(out);
    write_file_atomically(join_path(f.path(), "count.npy"), "third count");
    f.commit();
  }
  CHECK_FALSE(fs::exists(out + "/.fillgs-commit-incomplete"));
  CHECK(read_file(out + "/count.npy") == "third count");
  CHECK_FALSE(fs::exists(out + "/deficiency.npy"));
  CHECK(read_file(out + "/mine.txt") == "the user's");
}

TEST_CASE("a program run with end_descendants leaves no process behind: background, setsid, timed out", "[robust][hostile][process]") {
  const std::string dir = scratch("hostile_descendants");
  ProcessOptions o;
  o.end_descendants = true;
  o.timeout_seconds = 30;
  // A background child that would write after the program returned.
  ProcessResult r = run_process({"sh", "-c", "(sleep 1; echo late > \"$1/background.txt\") & exit 0", "sh", dir}, o);
  CHECK(r.status == 0);
  // One that left the process group (setsid) and would write later still.
  r = run_process({"sh", "-c", "setsid sh -c 'sleep 1; echo late > \"$0/setsid.txt\"' \"$1\" & exit 0", "sh", dir}, o);
  CHECK(r.status == 0);
  // One that left the group while the program ran past its timeout.
  o.timeout_seconds = 0.5;
  r = run_process({"sh", "-c", "setsid sh -c 'sleep 1; echo late > \"$0/timeout.txt\"' \"$1\" & sleep 30", "sh", dir}, o);
  CHECK(r.timed_out);
  // The control: without end_descendants the background child does write (the test would
  // otherwise pass for a shell that never ran it).
  o.end_descendants = false;
  o.timeout_seconds = 30;
  r = run_process({"sh", "-c", "(sleep 1; echo late > \"$1/control.txt\") & exit 0", "sh", dir}, o);
  CHECK(r.status == 0);
  for (int k = 0; k < 100 && !fs::exists(dir + "/control.txt"); ++k) ::usleep(50000);
  ::usleep(300000);  // past the others' 1 s as well
  CHECK(fs::exists(dir + "/control.txt"));
  CHECK_FALSE(fs::exists(dir + "/background.txt"));
  CHECK_FALSE(fs::exists(dir + "/setsid.txt"));
  CHECK_FALSE(fs::exists(dir + "/timeout.txt"));
}

TEST_CASE("PLY frames with two files of one frame are refused, not chosen between", "[robust][hostile]") {
  const std::string dir = scratch("hostile_duplicates");
  fs::create_directories(dir + "/frames");
  GaussianCloud c;
  add_gaussian(c, Vec3f(0, 0, 0), 0.1f, 2.0f, Vec3f(0.5f, 0.4f, 0.3f));
  write_3dgs_ply(dir + "/frames/frame_0000.ply", c, 0.0);
  write_3dgs_ply(dir + "/frames/frame_0001.ply", c, 0.0);
  CHECK(run_cli({"info", "--scene-format", "ply-frames", dir + "/frames"}).code == 0);
  write_3dgs_ply(dir + "/frames/frame_1.ply", c, 0.0);
  const CliResult r = run_cli({"info", "--scene-format", "ply-frames", dir + "/frames"});
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK(r.err.find("are both frame 1") != std::string::npos);
}

namespace {

/// A small synthetic scene (3 frames, 48 x 36) made by `fillgs synth` in `dir`/scene.
void synth_scene(const std::string& dir) {
  const CliResult r = run_cli({"synth", "--out", join_path(dir, "scene"), "--frames", "3", "--width", "48", "--height", "36", "--spacing", "0.06", "--quiet"});
  INFO(r.err);
  REQUIRE(r.code == 0);
}

/// `path` (a .npy) with the bytes of element `index` of its data replaced by `value`'s.
template <typename T>
void poke_npy(const std::string& path, size_t index, T value) {
  std::string bytes = read_file(path);
  const size_t data = bytes.size() - read_npy(path).bytes.size();
  std::memcpy(&bytes[data + index * sizeof(T)], &value, sizeof(T));
  write_file_atomically(path, bytes);
}

}  // namespace

TEST_CASE("observe --merge refuses shards whose tables hold what observe never writes, naming the file and element", "[robust][hostile][cli]") {
  const std::string dir = scratch("hostile_merge");
  synth_scene(dir);
  const std::string scene = dir + "/scene/scene.ply", cams = dir + "/scene/transforms_train.json";
  std::vector<std::string> parts;
  for (int i = 1; i <= 2; ++i) {
    parts.push_back(dir + "/part" + std::to_string(i));
    const CliResult r = run_cli({"observe", "--scene", scene, "--cameras", cams, "--shard", std::to_string(i) + "/2", "--tables", "dense", "--out", parts.back(),
                                 "--quiet"});
    INFO(r.err);
    REQUIRE(r.code == 0);
  }
  const std::string both = parts[0] + "," + parts[1];
  REQUIRE(run_cli({"observe", "--merge", both, "--out", dir + "/merged", "--quiet"}).code == 0);
  const nlohmann::json summary = nlohmann::json::parse(read_file(parts[0] + "/summary.json"));
  const size_t N = summary.at("gaussians").get<size_t>(), views = summary.at("max_views_per_frame").get<size_t>();
  REQUIRE(summary.at("dynamic").get<size_t>() > 0);
  // `file` of shard `folder` poked: the merge of `shards` refuses it in one line naming it, writes nothing.
  auto refused_in = [&](const std::string& folder, const std::string& shards, const std::string& file, const std::function<void()>& poke,
                        const std::vector<std::string>& says) {
    const std::string path = folder + "/" + file, keep = read_file(path);
    poke();
    const CliResult r = run_cli({"observe", "--merge", shards, "--out", dir + "/bad"});
    INFO(file << ": " << r.err);
    CHECK(r.code == 1);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find(path) != std::string::npos);
    for (const std::string& w : says) CHECK(r.err.find(w) != std::string::npos);
    CHECK_FALSE(fs::exists(dir + "/bad"));
    write_file_atomically(path, keep);
  };
  auto refused = [&](const std::string& file, const std::function<void()>& poke, const std::vector<std::string>& says) {
    refused_in(parts[0], both, file, poke, says);
  };
  refused("count.npy", [&] { poke_npy(parts[0] + "/count.npy", 1, uint8_t(views + 1)); },
          {"element [0, 1] is " + std::to_string(views + 1) + ", outside [0, " + std::to_string(views) + "]"});
  refused("deficiency.npy", [&] { poke_npy(parts[0] + "/deficiency.npy", 2, std::nanf("")); }, {"element [0, 2] is nan", "not a finite speed or deficiency"});
  refused("speed.npy", [&] { poke_npy(parts[0] + "/speed.npy", 0, -INFINITY); }, {"element [0, 0] is -inf"});
  refused("times.npy", [&] { poke_npy(parts[0] + "/times.npy", 0, std::nan("")); }, {"element 0 is nan, not a time in [0, 1]"});
  refused("dynamic_ids.npy", [&] { poke_npy(parts[0] + "/dynamic_ids.npy", 0, uint32_t(N + 5)); },
          {"element 0 is " + std::to_string(N + 5) + ", outside [0, " + std::to_string(N - 1) + "]"});
  // The compact layout's tables (traced, so that moving Gaussians change static counts).
  std::vector<std::string> compact;
  for (int i = 1; i <= 2; ++i) {
    compact.push_back(dir + "/compact" + std::to_string(i));
    const CliResult r = run_cli({"observe", "--scene", scene, "--cameras", cams, "--mode", "raytraced", "--stride", "2", "--shard", std::to_string(i) + "/2",
                                 "--out", compact.back(), "--quiet"});
    INFO(r.err);
    REQUIRE(r.code == 0);
  }
  {
    const std::string pair = compact[0] + "," + compact[1];
    const std::string& poked = compact[1];  // frames 1 and 2: the second holds changes
    REQUIRE(run_cli({"observe", "--merge", pair, "--out", dir + "/merged_compact", "--quiet"}).code == 0);
    const nlohmann::json js = nlohmann::json::parse(read_file(poked + "/summary.json"));
    REQUIRE(js.at("count_changes").get<size_t>() > 0);
    const std::vector<double> ids = read_npy(poked + "/dynamic_ids.npy").to_doubles("ids");
    REQUIRE(!ids.empty());
    const size_t moving = size_t(ids[0]), still = ids[0] > 0 ? 0 : size_t(ids[0]) + 1;
    REQUIRE((ids.size() < 2 || size_t(ids[1]) != still));
    auto refused_compact = [&](const std::string& file, const std::function<void()>& poke, const std::vector<std::string>& says) {
      refused_in(poked, pair, file, poke, says);
    };
    const std::string over = std::to_string(views + 1) + ", outside [0, " + std::to_string(views) + "]";
    refused_compact("count_static.npy", [&] { poke_npy(poked + "/count_static.npy", still, uint8_t(views + 1)); },
                    {"element [0, " + std::to_string(still) + "] is " + over});
    refused_compact("count_static.npy", [&] { poke_npy(poked + "/count_static.npy", moving, uint8_t(1)); }, {"for a moving Gaussian"});
    refused_compact("count_rows.npy", [&] { poke_npy(poked + "/count_rows.npy", 0, uint32_t(7)); }, {"element 0 is 7, outside [0, 0]"});
    refused_compact("count_dynamic.npy", [&] { poke_npy(poked + "/count_dynamic.npy", 0, uint8_t(views + 1)); }, {"element [0, 0] is " + over});
    refused_compact("count_change_values.npy", [&] { poke_npy(poked + "/count_change_values.npy", 0, uint8_t(views + 1)); },
                    {"element 0 is " + over});
    refused_compact("count_change_ids.npy", [&] { poke_npy(poked + "/count_change_ids.npy", 0, uint32_t(moving)); },
                    {"expected increasing ids of static Gaussians"});
    refused_compact("count_change_offsets.npy", [&] { poke_npy(poked + "/count_change_offsets.npy", 1, int64_t(1) << 40); }, {"element 1 is"});
    refused_compact("speed_dynamic.npy", [&] { poke_npy(poked + "/speed_dynamic.npy", 3, std::nanf("")); }, {"element [0, 3] is nan"});
    refused_compact("summary.json", [&] {
      nlohmann::json j = nlohmann::json::parse(read_file(poked + "/summary.json"));
      j["shard"].erase("count_static_keys");
      write_file_atomically(poked + "/summary.json", j.dump());
    }, {"malformed shard summary"});
  }
  // A wrong-typed field (in every shard, so that they agree): named with its file.
  for (const std::string& p : parts) {
    nlohmann::json j = nlohmann::json::parse(read_file(p + "/summary.json"));
    j["max_views_per_frame"] = "many";
    write_file_atomically(p + "/summary.json", j.dump());
  }
  const CliResult typed = run_cli({"observe", "--merge", both, "--out", dir + "/bad"});
  INFO(typed.err);
  CHECK(typed.code == 1);
  CHECK(typed.err.find(parts[0] + "/summary.json: malformed") != std::string::npos);
  for (const std::string& p : parts) {
    nlohmann::json j = nlohmann::json::parse(read_file(p + "/summary.json"));
    j["shard"]["frames_total"] = "three";
    write_file_atomically(p + "/summary.json", j.dump());
  }
  const CliResult total = run_cli({"observe", "--merge", both, "--out", dir + "/bad"});
  INFO(total.err);
  CHECK(total.code == 1);
  CHECK(total.err.find("/summary.json: malformed shard summary") != std::string::npos);
}

TEST_CASE("train killed after its last checkpoint is finished by --resume, and a killed chart's leftovers go", "[robust][hostile][cli]") {
  const std::string dir = scratch("hostile_resume");
  synth_scene(dir);
  const std::string out = dir + "/train";
  const std::vector<std::string> base = {"train", "--images", dir + "/scene", "--cameras", dir + "/scene/transforms_train.json", "--iterations", "20",
                                         "--quiet", "--out", out};
  REQUIRE(run_cli(base).code == 0);
  // As a kill between the last checkpoint and the model leaves it: the marker, the
  // checkpoint at iteration 20, no model, and a chart's temporary PNG and gnuplot log.
  fs::remove(out + "/model.ply");
  fs::remove(out + "/summary.json");
  write_file_atomically(out + "/.fillgs-unfinished", "fillgs train (process 1) is writing this folder\n");
  write_file_atomically(out + "/.loss.fillgs-tmp-1-0000000000000000-0.png", "half a picture");
  write_file_atomically(out + "/.loss.gnuplot.fillgs-tmp-1-0000000000000000-1.log", "a log");
  std::vector<std::string> resume = base;
  resume.insert(resume.end(), {"--resume", out + "/checkpoints/latest.ckpt"});
  const CliResult r = run_cli(resume);
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK(fs::exists(out + "/model.ply"));
  CHECK(fs::exists(out + "/summary.json"));
  CHECK_FALSE(fs::exists(out + "/.fillgs-unfinished"));
  CHECK_FALSE(fs::exists(out + "/.loss.fillgs-tmp-1-0000000000000000-0.png"));
  CHECK_FALSE(fs::exists(out + "/.loss.gnuplot.fillgs-tmp-1-0000000000000000-1.log"));
  // Fewer iterations than the checkpoint has: refused.
  std::vector<std::string> fewer = resume;
  fewer[6] = "10";
  const CliResult f = run_cli(fewer);
  CHECK(f.code == 1);
  CHECK(f.err.find("is already at iteration 20") != std::string::npos);
}

TEST_CASE("held-out cameras: --held-out finds a camera rounded to five decimals, with a tolerance in world units and degrees", "[robust][hostile][cli]") {
  const std::string dir = scratch("hostile_held_out");
  synth_scene(dir);
  const std::string cams = dir + "/scene/transforms_train.json";
  std::vector<Camera> held = {read_cameras(cams).front()};
  // Rounded: 1e-5 off in position, a rotation of 1e-5 rad.
  held[0].t += Vec3d(1e-5, -1e-5, 1e-5);
  held[0].R = held[0].R * Eigen::AngleAxisd(1e-5, Vec3d::UnitY()).toRotationMatrix();
  write_transforms_json(dir + "/held.json", held);
  const std::vector<std::string> base = {"train", "--images", dir + "/scene", "--cameras", cams, "--held-out", dir + "/held.json", "--iterations", "1",
                                         "--quiet"};
  std::vector<std::string> args = base;
  args.insert(args.end(), {"--out", dir + "/a"});
  const CliResult r = run_cli(args);
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK(r.err.find("stands where held-out camera") != std::string::npos);
  CHECK(r.err.find("within --held-out-distance 0.001 and --held-out-angle 0.1") != std::string::npos);
  // Tighter than the rounding: the camera is another one.
  args = base;
  args.insert(args.end(), {"--held-out-distance", "1e-7", "--out", dir + "/b"});
  const CliResult ok = run_cli(args);
  INFO(ok.err);
  CHECK(ok.code == 0);
}

#if !FILLGS_SANITIZED  // fine-tuning builds an OpenVDB grid: minutes under the sanitizers
TEST_CASE("a fine-tuning whose refiner fails on every patch ends with an error, unless asked to go on", "[robust][hostile][cli]") {
  const std::string dir = scratch("hostile_refiner");
  synth_scene(dir);
  auto finetune = [&](const std::string& command, const std::string& out, bool allow) {
    std::vector<std::string> args = {"finetune", "--model", dir + "/scene/scene.ply", "--images", dir + "/scene", "--cameras",
                                     dir + "/scene/transforms_train.json", "--train-cameras", "cam04,cam06", "--iterations", "20",
                                     "--select-every", "10", "--trajectories", "1", "--refiner", "external", "--refiner-command", command,
                                     "--quiet", "--out", out};
    if (allow) args.push_back("--allow-failed-refinement");
    return run_cli(args);
  };
  // Exits 0 and writes nothing; a program that does not exist.
  for (const std::string& command : {std::string("true {in} {out}"), std::string("/nonexistent/refiner {in} {out}")}) {
    const std::string out = dir + "/ft" + std::to_string(command.size());
    const CliResult r = finetune(command, out, false);
    INFO(command << ": " << r.err);
    CHECK(r.code == 1);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find("the refiner failed on every one of its") != std::string::npos);
    CHECK_FALSE(fs::exists(out + "/model.ply"));
  }
  const CliResult allowed = finetune("true {in} {out}", dir + "/allowed", true);
  INFO(allowed.err);
  CHECK(allowed.code == 0);
  CHECK(fs::exists(dir + "/allowed/model.ply"));
  CHECK(allowed.err.find("warning: refinement failed") != std::string::npos);
}
#endif
