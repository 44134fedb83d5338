// Other programs are started without a shell (base/process.hpp): a command template is split
// as a shell would split words but never run by one, and a quote or a $(...) in an output path
// reaches no shell in any command that draws a chart or runs a refiner.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/process.hpp"
#include "fillgs/cli.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

using Words = std::vector<std::string>;

TEST_CASE("split_command: words as a shell splits them, placeholders replaced inside words after splitting", "[process]") {
  CHECK(split_command("a  'b c' \"d \\\"e\\\" \\\\ f\" g\\ h") == Words{"a", "b c", "d \"e\" \\ f", "g h"});
  CHECK(split_command("tool --in={in} {out}/x '{in}'", {{"{in}", "/p q/it's $(touch Z)"}, {"{out}", "O"}}) ==
        Words{"tool", "--in=/p q/it's $(touch Z)", "O/x", "/p q/it's $(touch Z)"});
  // A value that holds the other placeholder is not replaced again.
  CHECK(split_command("t {in} {out}", {{"{in}", "{out}"}, {"{out}", "B"}}) == Words{"t", "{out}", "B"});
  CHECK(split_command("sh -c 'exit \"$1\"' sh 3") == Words{"sh", "-c", "exit \"$1\"", "sh", "3"});
  CHECK(split_command("a#b c~") == Words{"a#b", "c~"});
  for (const char* bad : {"a | b", "a && b", "a; b", "a > f", "a < f", "(a)", "a $X", "a `b`", "#a", "~/x", "a \"$(b)\""})
    CHECK_THROWS_WITH(split_command(bad), Catch::Contains("is shell syntax"));
  CHECK_THROWS_WITH(split_command("a 'b"), Catch::Contains("never closed"));
  CHECK_THROWS_WITH(split_command("a \"b"), Catch::Contains("never closed"));
  CHECK_THROWS_WITH(split_command("a \\"), Catch::Contains("lone backslash"));
  CHECK_THROWS_WITH(split_command("   "), Catch::Contains("names no program"));
}

TEST_CASE("run_process: input on stdin, output to a file, exit status, signals, timeouts and programs that are missing", "[process]") {
  const std::string dir = scratch("process");
  ProcessOptions o;
  o.stdin_data = "line one\nit's $(not run)\n";
  o.stdout_path = join_path(dir, "out.txt");
  ProcessResult r = run_process({"cat"}, o);
  CHECK(r.started);
  CHECK(r.status == 0);
  CHECK(read_file(o.stdout_path) == o.stdin_data);

  // Arguments arrive as they are: no word splitting, no expansion.
  o.stdin_data.clear();
  r = run_process({"printf", "%s|", "a b", "$(touch PWNED)", "*"}, o);
  CHECK(r.status == 0);
  CHECK(read_file(o.stdout_path) == "a b|$(touch PWNED)|*|");
  CHECK_FALSE(fs::exists("PWNED"));

  CHECK(run_process({"sh", "-c", "exit 7"}).status == 7);
  CHECK(run_process({"sh", "-c", "kill -TERM $$"}).status == 128 + 15);

  // A program that stops reading a large input: no SIGPIPE here, its status comes back.
  ProcessOptions big;
  big.stdin_data.assign(size_t(8) << 20, 'x');
  r = run_process({"head", "-c", "1"}, big);
  CHECK(r.started);
  CHECK(r.status == 0);

  r = run_process({"/nonexistent/program"});
  CHECK_FALSE(r.started);
  CHECK(r.error.find("No such file") != std::string::npos);

  // The timeout kills the whole process group, the program's children included.
  const auto t0 = std::chrono::steady_clock::now();
  ProcessOptions slow;
  slow.timeout_seconds = 0.3;
  r = run_process({"sh", "-c", "sleep 30 & sleep 30"}, slow);
  CHECK(r.timed_out);
  CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 5.0);
}

TEST_CASE("a quote and $(...) in --out reach no shell: every command that draws a chart or runs a refiner", "[process][cli]") {
  const std::string dir = scratch("hostile_paths");
  const std::string marker = "PWNED_hostile";
  fs::remove(marker);
  std::ostringstream out, err;
  REQUIRE(cli::run({"synth", "--out", join_path(dir, "scene"), "--frames", "3", "--width", "48", "--height", "36", "--spacing", "0.06", "--quiet"},
                   out, err) == 0);
  const std::string images = join_path(dir, "scene"), cams = join_path(dir, "scene/transforms_train.json"),
                    scene = join_path(dir, "scene/scene.ply");
  // Each folder name closes a shell quote, runs a command substitution and backquotes (as
  // one shell would see it inside single quotes, and inside double ones).
  const std::string hostile = "x'$(touch " + marker + ")'y \"`touch " + marker + "`\"";
  const bool gnuplot = run_process({"gnuplot", "-e", "exit"}).status == 0;
  auto check_run = [&](const std::string& what, const std::vector<std::string>& args, const std::vector<std::string>& pictures) {
    std::ostringstream o, e;
    const int code = cli::run(args, o, e);
    INFO(what << ": " << o.str() << e.str());
    CHECK(code == 0);
    CHECK_FALSE(fs::exists(marker));
    CHECK_FALSE(fs::exists(join_path(dir, marker)));
    CHECK(e.str().find("not drawn") == std::string::npos);
    if (gnuplot)
      for (const std::string& p : pictures) CHECK(fs::exists(join_path(args.back(), p)));
  };
  check_run("train", {"train", "--images", images, "--cameras", cams, "--iterations", "20", "--quiet", "--out", join_path(dir, "train " + hostile)},
            {"loss.png"});
  check_run("train (a folder with one quote)",
            {"train", "--images", images, "--cameras", cams, "--iterations", "20", "--quiet", "--out", join_path(dir, "john's run")}, {"loss.png"});
  check_run("observe", {"observe", "--scene", scene, "--cameras", cams, "--quiet", "--out", join_path(dir, "observe " + hostile)},
            {"deficiency_heatmap.png", "visible_fraction.png"});
#if !FILLGS_SANITIZED  // select and finetune build an OpenVDB grid; bench takes minutes there
  check_run("select", {"select", "--scene", scene, "--cameras", cams, "--trajectories", "2", "--quiet", "--out", join_path(dir, "select " + hostile)},
            {"priority_heatmap.png"});
  const std::string script = std::string(FILLGS_SOURCE_DIR) + "/scripts/refiners/median_denoise.sh";
  const std::string ft = join_path(dir, "finetune " + hostile);
  check_run("finetune", {"finetune", "--model", scene, "--images", images, "--cameras", cams, "--train-cameras", "cam04,cam06", "--iterations", "20",
                         "--select-every", "10", "--trajectories", "1", "--refiner", "external", "--refiner-command", "bash " + script + " {in} {out}",
                         "--quiet", "--out", ft},
            {"loss.png"});
  // The refiner got the folders as they are: its log lies in the hostile folder.
  bool logged = false;
  for (const auto& e : fs::recursive_directory_iterator(ft)) logged |= e.path().filename() == "refiner.log";
  CHECK(logged);
  check_run("bench", {"bench", "--smoke", "--configs", "no-refinement", "--quiet", "--out", join_path(dir, "bench " + hostile)},
            {"psnr_interpolation.png", "time_per_phase.png"});
  // `run` draws its charts through the same code as bench (write_bench_report, then chart.cpp's draw).
#endif
  fs::remove(marker);
}

// ---------------------------------------------------------------------------------
// A failed write fails the command (the real executable: its streams and signals).

namespace {

ProcessResult fillgs_process(const std::vector<std::string>& args, const std::string& out, const std::string& log, const std::string& shell_prefix = "") {
  // bash runs the prefix (ulimit, a pipe) and then fillgs with its arguments as they are.
  std::vector<std::string> argv = {"bash", "-c", shell_prefix.empty() ? "exec \"$0\" \"$@\"" : shell_prefix, FILLGS_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  ProcessOptions o;
  o.stdout_path = out;
  o.stderr_path = log;
  o.timeout_seconds = 300;
  return run_process(argv, o);
}

}  // namespace

TEST_CASE("a standard output that cannot be written fails the command, and a closed pipe does not kill it", "[process][robust]") {
  const std::string dir = scratch("stdout_fails");
  std::ostringstream o, e;
  REQUIRE(cli::run({"synth", "--out", join_path(dir, "scene"), "--frames", "3", "--width", "48", "--height", "36", "--spacing", "0.06", "--quiet"}, o, e) == 0);
  const std::string scene = join_path(dir, "scene/scene.ply"), log = join_path(dir, "log.txt");
  // info's output is its result: /dev/full takes none of it.
  ProcessResult r = fillgs_process({"info", "--json", scene}, "/dev/full", log);
  CHECK(r.status == 1);
  std::string err = read_file(log);
  CHECK(err.find("error: fillgs: cannot write to standard output (No space left on device); the files the command wrote are complete") != std::string::npos);
  CHECK(std::count(err.begin(), err.end(), '\n') == 1);
  r = fillgs_process({"info", "--json", scene}, join_path(dir, "info.json"), log);
  CHECK(r.status == 0);
  CHECK(read_file(join_path(dir, "info.json")).find("\"gaussians\"") != std::string::npos);
  // `train | head`: the pipe closes early; training goes on, writes its model, and says so.
  r = fillgs_process({"train", "--images", join_path(dir, "scene"), "--cameras", join_path(dir, "scene/transforms_train.json"), "--iterations",
                      "30", "--quiet", "--out", join_path(dir, "trained")},
                     "/dev/null", log, "\"$0\" \"$@\" | head -c 1 > /dev/null; exit ${PIPESTATUS[0]}");
  err = read_file(log);
  INFO(err);
  CHECK(r.status == 1);
  CHECK(err.find("cannot write to standard output (Broken pipe)") != std::string::npos);
  CHECK(fs::exists(join_path(dir, "trained/model.ply")));
}

TEST_CASE("a file-size limit fails the write that meets it: no truncated image is committed", "[process][robust]") {
  const std::string dir = scratch("fsize");
  std::ostringstream o, e;
  REQUIRE(cli::run({"synth", "--out", join_path(dir, "scene"), "--frames", "2", "--width", "320", "--height", "240", "--quiet"}, o, e) == 0);
  const std::string log = join_path(dir, "log.txt");
  // `ulimit -f 4`: 4 KiB, far under a 320x240 render of the scene.
  const ProcessResult r = fillgs_process({"render", "--scene", join_path(dir, "scene/scene.ply"), "--cameras",
                                          join_path(dir, "scene/transforms_train.json"), "--out", join_path(dir, "renders"), "--quiet"},
                                         "/dev/null", log, "ulimit -f 4; exec \"$0\" \"$@\"");
  const std::string err = read_file(log);
  INFO(err);
  CHECK(r.status == 1);
  CHECK(std::count(err.begin(), err.end(), '\n') == 1);
  CHECK((err.find("File too large") != std::string::npos || err.find("file-size limit") != std::string::npos));
  CHECK(err.find(join_path(dir, "renders")) != std::string::npos);  // the output named, not a hidden staging folder
  CHECK(err.find("staging") == std::string::npos);
  CHECK_FALSE(fs::exists(join_path(dir, "renders")));
}

TEST_CASE("a train or finetune killed half-way leaves its folder marked unfinished, never an old result beside new state", "[process][robust]") {
  const std::string dir = scratch("killed_runs");
  std::ostringstream o, e;
  REQUIRE(cli::run({"synth", "--out", join_path(dir, "scene"), "--frames", "3", "--width", "48", "--height", "36", "--spacing", "0.06", "--quiet"}, o, e) == 0);
  const std::string images = join_path(dir, "scene"), cams = join_path(dir, "scene/transforms_train.json"), log = join_path(dir, "log.txt");
  const std::string out = join_path(dir, "trained");
  REQUIRE(cli::run({"train", "--images", images, "--cameras", cams, "--iterations", "20", "--quiet", "--out", out}, o, e) == 0);
  REQUIRE(fs::exists(join_path(out, "model.ply")));
  CHECK_FALSE(fs::exists(join_path(out, ".fillgs-unfinished")));
  // A second, long training in the same folder, killed (SIGKILL to its process group) after 4 s;
  // where a loaded machine (a sanitizer build beside other jobs) had not yet reached the folder
  // by then, killed again after 8, 16, ... 64 s: a run killed before it marks the folder must
  // leave it as it was, the old model intact.
  auto killed_after = [&](const std::vector<std::string>& args, const std::string& folder) {
    std::vector<std::string> argv = {FILLGS_BINARY};
    argv.insert(argv.end(), args.begin(), args.end());
    ProcessResult last;
    for (double seconds = 4; seconds <= 64; seconds *= 2) {
      ProcessOptions po;
      po.stdout_path = po.stderr_path = log;
      po.timeout_seconds = seconds;
      last = run_process(argv, po);
      if (!last.timed_out || fs::exists(join_path(folder, ".fillgs-unfinished"))) break;
      INFO("killed after " << seconds << " s before it marked " << folder);
      CHECK((folder != out || fs::exists(join_path(out, "model.ply"))));
    }
    return last;
  };
  ProcessResult r = killed_after({"train", "--images", images, "--cameras", cams, "--iterations", "1000000", "--quiet", "--out", out}, out);
  REQUIRE(r.timed_out);
  CHECK(fs::exists(join_path(out, ".fillgs-unfinished")));
  CHECK_FALSE(fs::exists(join_path(out, "model.ply")));
  CHECK_FALSE(fs::exists(join_path(out, "summary.json")));
  // A new run finishes the folder.
  std::ostringstream o3, e3;
  REQUIRE(cli::run({"train", "--images", images, "--cameras", cams, "--iterations", "20", "--quiet", "--out", out}, o3, e3) == 0);
  CHECK_FALSE(fs::exists(join_path(out, ".fillgs-unfinished")));
  CHECK(fs::exists(join_path(out, "model.ply")));
  // A finetune killed half-way: the rerun says why it cannot resume.
  const std::string ft = join_path(dir, "finetuned");
  r = killed_after({"finetune", "--model", join_path(out, "model.ply"), "--images", images, "--cameras", cams, "--iterations", "1000000",
                    "--refiner", "identity", "--quiet", "--out", ft},
                   ft);
  REQUIRE(r.timed_out);
  CHECK(fs::exists(join_path(ft, ".fillgs-unfinished")));
  std::ostringstream o4, e4;
  CHECK(cli::run({"finetune", "--model", join_path(out, "model.ply"), "--images", images, "--cameras", cams, "--iterations", "20", "--refiner",
                  "identity", "--quiet", "--out", ft},
                 o4, e4) == 1);
  const std::string why = e4.str();
  INFO(why);
  CHECK(why.find("holds an interrupted finetune") != std::string::npos);
  CHECK(why.find("not kept in checkpoints") != std::string::npos);
  CHECK(std::count(why.begin(), why.end(), '\n') == 1);
}
