// The fine-tuning job `fillgs finetune` and the Python module run (finetune_job.hpp).
#include "fillgs/method/finetune_job.hpp"

#include <cstdio>
#include <filesystem>
#include <ostream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/io/scene_io.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {

/// The refiner the job runs: the one asked for, else `identity` (none with a pool budget).
std::string refiner_of(const FinetuneJob& job) { return job.refiner.value_or("identity"); }

bool needs_pool(const FinetuneJob& job) { return job.options.pool_budget > 0 || refiner_kind(refiner_of(job)).needs_pool; }

std::string two_places(double x) {
  char b[64];
  std::snprintf(b, sizeof b, "%.2f", x);
  return b;
}

}  // namespace

void check_finetune_job(const FinetuneJob& job, const Spelling& s) {
  if (!job.data) throw_error("finetune: no training views");
  if (job.model.size() == 0) throw_error(job.model_path, ": has no Gaussians; fine-tuning needs a trained model");
  check_trainable(job.model, job.model_path);
  const FinetuneOptions& o = job.options;
  // The flags' own bounds (cmd_finetune.cpp), checked by the one check both faces use.
  check_within(s("iterations"), o.iterations, at_least(1));
  check_within(s("select_every"), o.select_every, at_least(1));
  check_within(s("trajectories"), o.trajectories, trajectory_bounds());
  check_within(s("pool_budget"), o.pool_budget, within(0, 1000000));
  if (job.refined_share) check_within(s("refined_share"), *job.refined_share, within(0, 1));
  check_within(s("position_lr"), job.rates.position_lr, positive());
  check_within(s("key_lr_scale"), job.rates.key_lr_scale, positive());
  check_select_options(o.select, s);
  if (!job.confidence_dir.empty() && !fs::is_directory(job.confidence_dir))
    throw_error(s("confidence"), " ", job.confidence_dir, " is not a folder");
  const RefinerKind& kind = refiner_kind(refiner_of(job));
  if (o.pool_budget > 0 && job.refiner) throw_error(s("pool_budget"), " adds the pool's own photographs: it takes no ", s("refiner"));
  if (o.pool_budget > 0 && job.trajectories_given)
    throw_error(s("pool_budget"), " chooses photographs, not trajectories: it takes no ", s("trajectories"));
  if (kind.needs_truth && !job.refiner_inputs.truth)
    throw_error(s("refiner"), " ", kind.name, " needs ", s("truth"), " (the ground-truth scene",
                kind.on_real_data.empty() ? ")" : "; on real data use " + s("refiner") + " " + kind.on_real_data + ")");
  job.refiner_inputs.parameters.require(kind.parameters, s);
  // The options several refiners share (the command line's --reference-angle,
  // --artifact-strength and --support-window).
  check_within(s("reference_angle"), job.refiner_inputs.reference.angle_scale_degrees, positive());
  check_within(s("artifact_strength"), job.refiner_inputs.oracle.artifacts.strength, at_least(0));
  check_within(s("support_window"), job.refiner_inputs.oracle.window, at_least(0));
  if (needs_pool(job)) {
    const std::string why = o.pool_budget > 0 ? s("pool_budget") : s("refiner") + " " + kind.name;
    if (job.pool_cameras.empty()) throw_error(why, " needs ", s("pool_cameras"), " (rig cameras neither trained on nor held out)");
    for (const std::string& c : job.pool_cameras)
      for (const std::string& t : job.data->rigs())
        if (c == t) throw_error(s("pool_cameras"), " names ", c, ", a training camera");
  }
  if (UnfinishedMarker::present(job.out))
    throw_error(job.out, ": holds an interrupted finetune (", UnfinishedMarker::path_in(job.out),
                "); fine-tuning does not resume, because its refined views and weights are not kept in checkpoints: remove the folder or use another ",
                s("out"));
  if (fs::exists(job.out) && !fs::is_empty(job.out)) throw_error("fillgs finetune: ", job.out, " exists and is not empty");
}

FinetuneJobResult run_finetune_job(FinetuneJob job, const Spelling& s, std::ostream& log, Progress& progress,
                                   const std::function<void(const FinetuneJobResult&)>& report) {
  const auto t0 = Clock::now();
  const Dataset& data = *job.data;
  // A network's model trains as fillgs's keyed model: keys as dense as its motion needs.
  KeyChoice keys;
  job.model = keyed_for_training(job.model, &keys);
  if (keys.keys > 0)
    log << "keys: " << keys.keys << " for its " << keys.frames << " frames (one every " << two_places(keys.interval)
        << "), positions, rotations, scales, opacities and colours (" << (keys.keyed_bands ? "every SH band" : "the SH DC") << ") within "
        << two_places(keys.worst_share) << " of their tolerances of its network at every frame (" << keys.sample << " moving Gaussians measured"
        << (keys.limiting.empty() ? std::string() : "; " + keys.limiting + " decided the interval") << ")\n";
  check_finetune_job(job, s);
  FinetuneJobResult r;
  FinetuneOptions& o = r.options;
  o = job.options;
  o.train = fine_tune_schedule(o.iterations, job.rates);
  o.train.seed = job.seed;
  // The model's spherical-harmonics degree is kept (a degree-0 model stays one).
  o.train.max_sh_degree = job.model.sh_degree;
  // A model trained with colour correction keeps it: its corrections (beside it, as train
  // writes them) continue, so the model stays in the colours of the rig's mean camera.
  const std::string corrections = join_path(fs::path(job.model_path).parent_path().string(), "colour_correction.json");
  if (!job.model_path.empty() && fs::is_regular_file(corrections)) {
    o.train.colour_correction = true;
    o.train.initial_colour = read_colour_correction(corrections);
    log << "colour correction: continuing the " << o.train.initial_colour.size() << " cameras' corrections of " << corrections << "\n";
  }
  if (job.refined_share) o.train.refined_share = *job.refined_share;
  o.select.seed = job.seed;
  if (!job.confidence_dir.empty()) {
    o.mask.method = MaskMethod::External;
    o.mask.external_dir = job.confidence_dir;
  }
  o.work_dir = join_path(job.out, "work");
  // The refiner (method/refiners.hpp): what it is made from, then the row's own make.
  RefinerInputs ri = job.refiner_inputs;
  complete_refiner_inputs(ri, data, job.seed);
  // The pool: rig cameras neither trained on nor held out, every frame the training views have.
  RigPool pool;
  if (needs_pool(job)) {
    DatasetOptions po = job.data_options;
    po.cameras = job.pool_cameras;
    po.monocular_cycle.clear();
    r.pool = std::make_unique<Dataset>(Dataset::load(job.images, job.cameras, po));
    if (r.pool->frames() != data.frames())
      throw_error("the pool cameras have ", r.pool->frames(), " frames, the training cameras ", data.frames());
    for (const TrainView& v : r.pool->views()) pool.cameras.push_back(v.camera);
    pool.frame_count = r.pool->frames();
    pool.image = [d = r.pool.get()](size_t i) { return d->image(i); };
    ri.pool = &pool;
  }
  const std::unique_ptr<Refiner> refiner = make_refiner(refiner_of(job), ri);
  if (o.pool_budget > 0) o.pool = &pool;
  UnfinishedMarker unfinished(job.out, "finetune");
  const GaussianCloud& model = job.model;
  if (o.pool)
    log << "fine-tuning " << model.size() << " Gaussians on " << data.views().size() << " views for " << o.iterations << " iterations; "
        << o.pool_budget << " of the pool's " << pool.cameras.size() << " photographs (" << o.select.strategy << "), chosen over "
        << (o.iterations + o.select_every - 1) / o.select_every << " rounds, weights " << to_string(o.weighting) << "\n";
  else
    log << "fine-tuning " << model.size() << " Gaussians on " << data.views().size() << " views for " << o.iterations << " iterations; "
        << o.trajectories << " trajectories (" << o.select.strategy << ") every " << o.select_every << ", refiner " << refiner->name()
        << ", weights " << to_string(o.weighting) << "\n";
  r.result = finetune(data, model, *refiner, o, progress);
  r.result.keys = keys;
  r.refiner = o.pool ? "pool" : refiner->name();
  r.seconds = seconds_since(t0);
  if (report) report(r);
  unfinished.finish();
  o.pool = nullptr;  // the RigPool above does not outlive the job (r.pool keeps its views)
  return r;
}

}  // namespace fillgs
