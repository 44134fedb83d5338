// fillgs bench: the paper's comparison, resumable.
#include <algorithm>

#include "bench_setup.hpp"
#include "commands.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/method/refiners.hpp"
#include "options.hpp"
#include "progress_bar.hpp"

namespace fillgs::cli {

namespace {

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
  const std::string& root = f.out;
  if (in.given("--merge")) {  // tables over finished runs only: bench folders or results.csv files, nothing run
    if (!in.given("--out")) in.fail("--merge needs --out DIR (the folder for the merged tables)");
    for (const char* k : {"--scenes", "--seeds", "--only", "--configs", "--iterations", "--select-every", "--backbone-iterations", "--width", "--height",
                          "--frames", "--artifact-strength", "--baseline-weighting", "--time-stride", "--refiner", "--reference-angle",
                          "--reference-hallucination", "--reference-fill-blur", "--reference-fill-strength", "--motion-rates", "--position-lr",
                          "--key-lr-scale", "--smoke"})
      if (in.given(k)) in.fail("--merge runs nothing, so ", k, " has no meaning with it");
    const std::vector<RunResult> all = merge_results(f.merge);
    make_directories(root);
    write_bench_report(root, all);
    in.out << "fillgs bench: " << all.size() << " runs from " << f.merge.size() << " inputs -> " << join_path(root, "results.md") << ", "
           << join_path(root, "results.csv") << "\n";
    return 0;
  }
  const BenchSetup setup = bench_setup(f.setup, in);
  BenchPlan plan{root, f.scenes, {}, {}, setup.scene, setup.finetune};
  for (const std::string& s : in.given("--seeds") ? f.seeds : std::vector<std::string>(f.setup.smoke ? 1 : 3, ""))
    plan.seeds.push_back(s.empty() ? plan.seeds.size() + 1 : uint64_t(parse_count(s, size_t(1) << 62, "fillgs bench", "--seeds value")));
  for (size_t i = 0; i < f.refiners.size(); ++i) {
    try {
      bench_refiner(f.refiners[i]);
    } catch (const Error& e) {
      in.fail("--refiner: ", e.what());
    }
    if (std::count(f.refiners.begin(), f.refiners.begin() + long(i), f.refiners[i])) in.fail("--refiner names ", f.refiners[i], " twice");
  }
  std::vector<RunConfig> configs = standard_configs(f.baseline_weighting, f.artifact_strength, f.refiners);
  for (RunConfig& c : configs) c.reference = f.reference;
  plan.configs = choose_configs(configs, f.only, f.configs, f.setup.smoke);
  TerminalProgress progress(in.err, in.progress());
  const std::vector<RunResult> results = run_bench_plan(plan, progress, in.out);
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
