// fillgs bench: the paper's comparison, resumable.
#include <optional>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"
#include "bench_setup.hpp"
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

// ------------------------------------------------------------------ bench

struct BenchFlags {
  std::string out = "fillgs_bench";
  std::vector<std::string> scenes = {"n3v"}, seeds, configs, merge;
  std::vector<ConfigGroup> only;
  double artifact_strength = 0.5;
  Weighting baseline_weighting = Weighting::ExploreGS;
  std::vector<std::string> refiners = {"reference"};
  ReferenceOptions reference = bench_reference_options(0.5, 1);  ///< the calibration's knobs set its fields
  SetupFlags setup;
};

int bench(const BenchFlags& f, const Invocation& in) {
  const bool smoke = f.setup.smoke;
  const std::string& root = f.out;
  if (in.given("--merge")) {
    // Tables over finished runs only: bench folders or results.csv files, nothing run.
    if (!in.given("--out")) in.fail("--merge needs --out DIR (the folder for the merged tables)");
    for (const char* k : {"--scenes", "--seeds", "--only", "--configs", "--iterations", "--select-every", "--backbone-iterations", "--width",
                          "--height", "--frames", "--artifact-strength", "--baseline-weighting", "--time-stride", "--refiner", "--reference-angle",
                          "--reference-hallucination", "--reference-fill-blur", "--reference-fill-strength", "--motion-rates",
                          "--position-lr", "--key-lr-scale", "--smoke"})
      if (in.given(k)) in.fail("--merge runs nothing, so ", k, " has no meaning with it");
    const std::vector<RunResult> all = merge_results(f.merge);
    make_directories(root);
    write_bench_report(root, all);
    in.out << "fillgs bench: " << all.size() << " runs from " << f.merge.size() << " inputs -> " << join_path(root, "results.md") << ", "
        << join_path(root, "results.csv") << "\n";
    return 0;
  }
  BenchSetup setup = bench_setup(f.setup, in);
  for (const std::string& sc : f.scenes) parse_scene(sc);  // unknown names fail before any work
  std::vector<uint64_t> seeds;
  for (const std::string& s : in.given("--seeds") ? f.seeds : std::vector<std::string>(smoke ? std::vector<std::string>{"1"} : std::vector<std::string>{"1", "2", "3"}))
    seeds.push_back(uint64_t(parse_count(s, size_t(1) << 62, "fillgs bench", "--seeds value")));
  for (size_t i = 0; i < f.refiners.size(); ++i) {
    try {
      bench_refiner(f.refiners[i]);
    } catch (const Error& e) {
      in.fail("--refiner: ", e.what());
    }
    for (size_t j = 0; j < i; ++j)
      if (f.refiners[i] == f.refiners[j]) in.fail("--refiner names ", f.refiners[i], " twice");
  }
  std::vector<RunConfig> configs = standard_configs(f.baseline_weighting, f.artifact_strength, f.refiners);
  for (RunConfig& c : configs) c.reference = f.reference;
  const std::vector<ConfigGroup>& only = f.only;
  const std::vector<std::string>& ids = f.configs;
  std::vector<RunConfig> chosen;
  for (const RunConfig& c : configs) {
    const bool by_group = only.empty() || std::count(only.begin(), only.end(), c.group);
    const bool by_id = ids.empty() || std::count(ids.begin(), ids.end(), c.id);
    const bool in_smoke = c.group == ConfigGroup::Control || c.group == ConfigGroup::Calibration || c.group == ConfigGroup::Strategy ||
                          c.group == ConfigGroup::Upper;
    if (by_group && by_id && (!smoke || in_smoke)) chosen.push_back(c);
  }
  if (chosen.empty()) in.fail("--only/--configs select no configuration");
  make_directories(root);
  remove_stale_temporaries(root);  // a chart's PNG or log a killed bench left
  TerminalProgress progress(in.err, in.progress());
  std::vector<RunResult> results;
  in.out << "fillgs bench: " << f.scenes.size() << " scene(s) x " << seeds.size() << " seed(s) x " << chosen.size() << " configurations -> " << root
      << " (resumable: finished runs are reused)\n";
  for (const std::string& sc : f.scenes)
    for (uint64_t seed : seeds) {
      ExperimentOptions eo = setup.scene;
      const SceneChoice choice = parse_scene(sc);
      eo.rig = choice.rig;
      eo.variant = choice.variant;
      eo.seed = seed;
      // The backbone is read or trained only where something still needs it: a seed whose
      // runs are all finished trains none.
      PreparedScene p = prepare_scene(root, eo, progress, in.out, false);
      const std::string bb_path = join_path(join_path(p.dir, "backbone"), "result.json");
      // A run still to make that fine-tunes the backbone (the dense model trains its own).
      const auto needs_backbone = [&](const RunConfig& c) { return c.kind != RunKind::Dense && !fs::exists(p.result_path(c.id)); };
      const bool all_finished = std::none_of(chosen.begin(), chosen.end(), needs_backbone);
      RunResult bb;
      if (fs::exists(bb_path)) {
        bb = load_result(bb_path, "backbone", seed, eo.scene_name());
      } else if (!all_finished) {
        ensure_backbone(p, progress, in.out);
        bb = evaluate_model(p, p.backbone, "backbone", "", progress);
        bb.group = ConfigGroup::Control;
        save_result(bb_path, bb);
      }
      if (fs::exists(bb_path))
        in.out << sc << " seed " << seed << " backbone: interpolation " << fixed(bb.interpolation.psnr) << " dB, extrapolation "
            << fixed(bb.extrapolation.psnr) << " dB, train " << fixed(bb.train.psnr) << " dB\n";
      else
        in.out << sc << " seed " << seed << ": every run is finished and the backbone's own row was not kept; it is not trained again for it\n";
      for (const RunConfig& c : chosen) {
        FinetuneOptions fo = setup.finetune;
        if (needs_backbone(c)) ensure_backbone(p, progress, in.out);
        results.push_back(run_config(p, c, fo, progress, in.out));
        // After every run, over everything the folder holds (earlier invocations included):
        // an interrupted bench still has its tables.
        write_bench_report(root, collect_results(root));
      }
    }
  write_bench_report(root, collect_results(root));
  in.out << "fillgs bench: " << results.size() << " runs here, tables over every run in the folder: " << join_path(root, "results.md") << ", "
      << join_path(root, "results.csv") << "\n";
  return 0;
}

}  // namespace

Action declare_bench(CLI::App& app) {
  auto f = std::make_shared<BenchFlags>();
  add_text(app, "--out", f->out, "the benchmark's folder (resumable)", "DIR");
  add_list(app, "--scenes,--variants", f->scenes, "built-in scenes: " + join_names(bench_scenes()));
  add_list(app, "--seeds", f->seeds, "seeds (default 1,2,3; smoke 1)");
  add_choice_list(app, "--only", f->only, "only these groups of configurations");
  add_list(app, "--configs", f->configs, "only these configurations");
  add_number(app, "--artifact-strength", f->artifact_strength, "strength of the oracle's simulated refiner artifacts", at_least(0));
  add_choice(app, "--baseline-weighting", f->baseline_weighting, "the weights the baseline strategies fine-tune with");
  add_list(app, "--refiner", f->refiners, "refiners, a table each (the first's rows unsuffixed, the others' ending @NAME): " + refiner_names(true) + " (the first the default)");
  add_number(app, "--reference-angle", f->reference.angle_scale_degrees,
             "the reference refiner's confidence angle in degrees (the calibration's knob; default: the calibrated value)", positive());
  add_number(app, "--reference-hallucination", f->reference.hallucination,
             "the reference refiner's share of misplaced texture in its fill (the calibration's knob; default: the calibrated value)", within(0, 1));
  add_number(app, "--reference-fill-blur", f->reference.fill_blur,
             "the reference refiner's fill blur, a fraction of the width (the calibration's knob; default: the calibrated value)", at_least(0));
  add_number(app, "--reference-fill-strength", f->reference.fill_strength,
             "the reference refiner's fill degradation (colour drift, blob; the calibration's knob; default: the calibrated value)", at_least(0));
  add_list(app, "--merge", f->merge, "tables over finished runs: bench folders or results.csv files (needs --out)");
  add_setup_flags(app, f->setup, true);
  return bind(f, bench);
}

}  // namespace fillgs::cli
