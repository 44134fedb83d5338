// fillgs run: the whole pipeline on the built-in scene, with a report (the main job).
#include <optional>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"
#include "bench_setup.hpp"
#include "fillgs/method/strategies.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/method/refiners.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"


namespace fs = std::filesystem;

namespace fillgs::cli {

namespace {

// ------------------------------------------------------------------ run

/// The refiner's artifact strength in `fillgs run` (the benchmark's default).
constexpr double kRunArtifactStrength = 0.5;

struct RunFlags {
  std::string out = "fillgs_run", scene = "n3v";
  std::string baseline = "coverage4d";
  std::string refiner = "reference";
  SetupFlags setup;
};

int run_pipeline(const RunFlags& f, const Invocation& in) {
  const std::string& dir = f.out;
  const std::string& baseline = f.baseline;
  const std::string& refiner = f.refiner;
  const std::string& method = method_strategy().name;
  if (strategy_row(baseline).method) in.fail("--baseline must be another strategy than ", method);
  const auto t0 = Clock::now();
  BenchSetup setup = bench_setup(f.setup, in);
  const SceneChoice choice = parse_scene(f.scene);
  setup.scene.rig = choice.rig;
  setup.scene.variant = choice.variant;
  TerminalProgress progress(in.err, in.progress());
  const ExperimentOptions eo = setup.scene.resolved();
  in.out << "fillgs run: the whole pipeline on the built-in scene (" << eo.scene_name() << ", " << eo.width << "x" << eo.height << ", "
      << eo.frames << " frames): train a backbone on 2 cameras, then fine-tune it without generated views, with FillGS's and with "
      << baseline << "'s viewpoints (" << refiner << " refiner, artifacts) -> " << dir << "\n";
  const PreparedScene p = prepare_scene(dir, setup.scene, progress, in.out);
  RunResult bb = evaluate_model(p, p.backbone, "backbone", "", progress);
  bb.group = ConfigGroup::Control;
  std::vector<RunResult> results;
  std::vector<std::string> run_ids;
  for (const RunConfig& c : standard_configs(Weighting::ExploreGS, kRunArtifactStrength, {refiner}))
    if (c.id == "no-refinement" || c.id == method || c.id == baseline) {
      results.push_back(run_config(p, c, setup.finetune, progress, in.out));
      run_ids.push_back(c.id);
    }
  std::vector<RunResult> all = {bb};
  all.insert(all.end(), results.begin(), results.end());
  write_bench_report(dir, all);

  RunReportInput report;
  report.scene = &p;
  report.results = all;
  report.run_ids = run_ids;
  report.finetune = setup.finetune;
  report.refiner = refiner;
  report.artifact_strength = kRunArtifactStrength;
  report.command = "fillgs";
  for (const std::string& s : in.args) report.command += " " + s;  // args[0] is "run"
  write_run_report(dir, report);
  in.out << "\nmethod           interp PSNR (moving)   extrap PSNR (moving)   train PSNR\n";
  for (const RunResult& r : all) {
    char line[200];
    std::snprintf(line, sizeof line, "%-16s %6s (%6s)        %6s (%6s)        %6s\n", r.id.c_str(), fixed(r.interpolation.psnr).c_str(),
                  fixed(r.interpolation.psnr_moving).c_str(), fixed(r.extrapolation.psnr).c_str(), fixed(r.extrapolation.psnr_moving).c_str(),
                  fixed(r.train.psnr).c_str());
    in.out << line;
  }
  in.out << "\nfillgs run: finished in " << fixed(seconds_since(t0), 0) << " s.\n"
      << "The report: " << join_path(dir, "report.html") << " (one self-contained page: open it in a browser, e.g. xdg-open "
      << join_path(dir, "report.html") << "), or " << join_path(dir, "report.md") << " as text.\n";
  return 0;
}

}  // namespace

Action declare_run(CLI::App& app) {
  auto f = std::make_shared<RunFlags>();
  add_text(app, "--out", f->out, "the folder for the report, pictures and runs", "DIR");
  add_text(app, "--scene", f->scene, "built-in scene: " + join_names(bench_scenes()), "NAME");
  add_table_choice(app, "--baseline", f->baseline, strategy_table(), "the strategy FillGS is compared with");
  add_row_choice(app, "--refiner", f->refiner, bench_refiners(), [](const std::string& v) { return bench_refiner(v); },
                 "the refiner: " + refiner_names(true) + " (" + bench_refiners().front() + " the default)");
  add_setup_flags(app, f->setup, false);
  return bind(f, run_pipeline);
}

}  // namespace fillgs::cli
