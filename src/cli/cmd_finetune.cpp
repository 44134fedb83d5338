// fillgs finetune: flags for the fine-tuning job (method/finetune_job.hpp), its reports, its lines.
#include <memory>

#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/method/finetune_job.hpp"
#include "fillgs/method/refiners.hpp"

namespace fillgs::cli {

namespace {

struct FinetuneFlags {
  std::string model, refiner = "identity", truth, confidence;
  bool paper_schedule = false;
  double refined_share = TrainOptions().refined_share;
  FinetuneJob job;  ///< the flags' values land here; the job checks them (finetune_job.hpp)
  MotionRateFlags rates;
  SceneReadOptions read;
};

int finetune_model(const FinetuneFlags& f, const Invocation& in) {
  TerminalProgress loading(in.err, in.progress());
  FinetuneJob job = f.job;
  const Dataset data = Dataset::load(job.images, job.cameras, job.data_options, loading);
  job.data = &data;
  job.model = read_scene_shown(f.model, f.read, in);
  job.model_path = f.model;
  const FinetuneOptions paper = FinetuneOptions::paper();  // --paper-schedule: the paper's counts; the flags given override them
  if (f.paper_schedule && !in.given("--iterations")) job.options.iterations = paper.iterations;
  if (f.paper_schedule && !in.given("--select-every")) job.options.select_every = paper.select_every;
  if (f.paper_schedule && !in.given("--trajectories")) job.options.trajectories = paper.trajectories;
  job.rates = motion_rates(in, f.rates);
  if (in.given("--refined-share")) job.refined_share = f.refined_share;
  if (in.given("--refiner")) job.refiner = f.refiner;
  job.trajectories_given = in.given("--trajectories");
  if (in.given("--confidence")) job.confidence_dir = f.confidence;
  if (in.given("--count-only") && in.given("--speed-only")) in.fail("--count-only and --speed-only exclude each other");
  std::unique_ptr<GaussianCloud> truth;
  if (in.given("--truth")) {
    truth = std::make_unique<GaussianCloud>(read_scene_shown(f.truth, f.read, in));
    job.refiner_inputs.truth = truth.get();
  }
  TerminalProgress progress(in.err, in.progress());
  run_finetune_job(std::move(job), Spelling{}, in.out, progress, [&](const FinetuneJobResult& r) {
    const FinetuneReport report = write_finetune_job_report(f.job.out, r, data);
    for (const FinetuneRound& rd : r.result.rounds)
      for (const auto& [patch, why] : rd.refine_failures) in.err << "warning: refinement failed for " << why << "\n";
    in.out << "fine-tuned in " << fixed(r.seconds, 1) << " s: " << r.result.virtual_views.size()
           << (r.options.pool_budget > 0 ? " pool photographs" : " refined views") << " added"
           << (report.dropped ? " (" + std::to_string(report.dropped) + " dropped by the refiner)" : "") << ", train PSNR "
           << fixed(report.train.psnr) << " dB -> " << f.job.out << "\n";
  });
  return 0;
}

}  // namespace

Action declare_finetune(CLI::App& app) {
  auto f = std::make_shared<FinetuneFlags>();
  FinetuneJob& job = f->job;
  FinetuneOptions& o = job.options;
  RefinerInputs& ri = job.refiner_inputs;
  add_text(app, "--model", f->model, "the trained model", "PATH")->required();
  add_text(app, "--images", job.images, "the training images", "DIR")->required();
  add_text(app, "--cameras", job.cameras, "the training cameras", "PATH")->required();
  add_text(app, "--out", job.out, "the folder for model.ply, virtual_views.json, work/ and summary.json (new or empty)", "DIR")->required();
  add_number(app, "--iterations", o.iterations, "fine-tuning iterations", at_least(1));
  add_number(app, "--select-every", o.select_every, "M: a selection round every M iterations", at_least(1));
  add_number(app, "--trajectories", o.trajectories, "K: trajectories per round (at most 100000)", within(0, 100000));
  add_flag(app, "--paper-schedule", f->paper_schedule, "the paper's counts: 30,000 iterations, 20 trajectories every 6,000");
  add_number(app, "--seed", job.seed, "random seed (training and selection)");
  add_number(app, "--refined-share", f->refined_share, "share of iterations that draw a refined view", within(0, 1));
  add_choice(app, "--weighting", o.weighting, "how refined pixels are trusted (fillgs: the paper's; the others: baselines and ablations)");
  add_number(app, "--mask-sigma", o.mask.sigma, "colour difference at which consistency is 1/e", positive());
  add_choice(app, "--mask", o.mask.method, "how consistency with the real views is measured");
  add_choice(app, "--covis", o.mask.covisibility, "how the co-visibility weight reads the observation tables");
  add_text(app, "--confidence", f->confidence, "consistency maps computed elsewhere (a folder)", "DIR");
  add_choice(app, "--covis-scale", o.mask.scale, "the co-visibility weight's D-hat scale: per frame over the visible moving Gaussians, or global");
  add_flag(app, "--normalise-weights", o.mask.normalise, "divide each refined view's weights by their mean");
  add_refiner_flags(app, f->refiner, f->truth, ri);
  add_flag(app, "--allow-failed-refinement", o.allow_failed_refinement,
           "go on when the refiner fails on every patch of a round (default: that ends the run with an error, nothing written)");
  add_list(app, "--pool-cameras", job.pool_cameras, "rig and --pool-budget: cameras neither trained on nor held out");
  add_number(app, "--pool-budget", o.pool_budget,
             "real camera-times: choose this many (camera, frame) photographs of the --pool-cameras by the strategy's own score, "
             "spread over the rounds, instead of refined virtual views (0: off)",
             within(0, 1000000));
  add_selection_flags(app, o.select);
  f->rates.preset = RatePreset::Converged;  // a user's model is kept; the benchmark asks for repair
  add_motion_rate_flags(app, f->rates);
  add_dataset_flags(app, job.data_options, "--train-cameras");
  add_scene_flags(app, f->read);
  return bind(f, finetune_model);
}

}  // namespace fillgs::cli
