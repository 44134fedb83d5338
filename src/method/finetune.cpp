#include "fillgs/method/finetune.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "fillgs/base/error.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/method/weights.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/train/train_model.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

namespace {


Image grey(const std::vector<float>& v, int w, int h) {
  Image im(w, h, 1);
  for (size_t p = 0; p < v.size(); ++p) im.pixels[p] = std::clamp(v[p], 0.0f, 1.0f);
  return im;
}

std::string stem(const std::string& file) { return file.substr(0, file.rfind('.')); }

}  // namespace

MotionRates motion_rates_of(RatePreset preset) {
  return preset == RatePreset::Gentle ? MotionRates::gentle() : preset == RatePreset::Converged ? MotionRates::converged_model() : MotionRates();
}

FinetuneOptions FinetuneOptions::paper() {
  FinetuneOptions o;
  o.iterations = 30000;
  o.select_every = 6000;
  o.trajectories = 20;
  o.train = fine_tune_schedule(o.iterations);
  return o;
}

TrainOptions fine_tune_schedule(int iterations, const MotionRates& rates) {
  if (!(rates.position_lr > 0 && std::isfinite(rates.position_lr)) || !(rates.key_lr_scale > 0 && std::isfinite(rates.key_lr_scale)))
    throw_error("finetune: the position learning rate and the key learning-rate scale must be positive numbers (got ", rates.position_lr, ", ",
                rates.key_lr_scale, ")");
  TrainOptions t = TrainOptions::scaled(iterations);
  t.position_lr_init = rates.position_lr;
  t.position_lr_final = rates.position_lr / 10;
  t.key_lr_scale = rates.key_lr_scale;
  t.opacity_reset_interval = 0;
  t.time_ramp = 0.0;  // the model already covers the whole video
  t.densify_from = std::max(1, iterations / 20);
  t.densify_until = iterations * 6 / 10;
  if (rates.converged) {  // a converged model: small steps, only where a view reaches, its own Gaussians and partition
    t.feature_lr *= kConvergedRate;
    t.opacity_lr *= kConvergedRate;
    t.scaling_lr *= kConvergedRate;
    t.rotation_lr *= kConvergedRate;
    t.sparse_adam = true;
    t.densify_until = 0;
    t.motion = MotionLearning::Promote;
  }
  return t;
}

FinetuneResult finetune(const Dataset& data, const GaussianCloud& model, Refiner& refiner, const FinetuneOptions& o, Progress& progress) {
  const auto t_start = Clock::now();
  if (o.iterations < 1) throw_error("finetune: iterations must be at least 1");
  if (o.select_every < 1) throw_error("finetune: select_every must be at least 1");
  if (o.trajectories < 0) throw_error("finetune: trajectories must be at least 0");
  if (o.pool_budget < 0) throw_error("finetune: the pool budget must be at least 0");
  if (o.work_dir.empty()) throw_error("finetune: no work folder");
  const int F = data.frames();
  std::vector<Camera> cameras;
  for (const TrainView& v : data.views()) cameras.push_back(v.camera);
  const std::vector<ObservedView> views = observed_views(cameras, F);
  auto image_of = [&](size_t i) { return data.image(i); };
  auto image_as = [&](size_t i) {
    return Image(data.views()[i].camera.width, data.views()[i].camera.height, 3, data.image(i));
  };

  TrainOptions to = o.train;
  to.iterations = o.iterations;
  Trainer trainer(data, params_from_cloud<float>(model, F), to);
  FinetuneResult result;
  if (!o.extra_views.empty()) trainer.add_refined(o.extra_views);
  double train_seconds = 0;
  // The images a round adds, weighted by o.weighting against the round's model; each
  // weight map written next to its image (`base`_mask.png, _covis.png, _weight.png).
  struct NewView {
    Camera camera;
    Image rgb;
    std::string base;  ///< path stem of its weight maps
    std::string name;  ///< external confidence map name
  };
  auto weigh_and_add = [&](const std::vector<NewView>& items, const GaussianCloud& current, const ObservationTables& tables,
                           float quantile, FinetuneRound& r) {
    const auto t0 = Clock::now();
    const RefinedViewWeigher weigh(current, tables, quantile, o.mask, o.weighting, views, image_as, F, to.background);
    std::vector<RefinedView> added;
    double weight_sum = 0;
    size_t weight_count = 0;
    progress.start("weights (" + std::string(to_string(o.weighting)) + ")", items.size());
    for (const NewView& v : items) {
      const Camera& cam = v.camera;
      ViewWeights w = weigh(v.rgb, cam, v.name);
      if (!w.consistency.empty()) write_image(v.base + "_mask.png", grey(w.consistency, cam.width, cam.height));
      if (!w.covisibility.empty()) write_image(v.base + "_covis.png", grey(w.covisibility, cam.width, cam.height));
      write_image(v.base + "_weight.png", grey(w.weight, cam.width, cam.height));
      for (float x : w.weight) weight_sum += x;
      weight_count += w.weight.size();
      if (o.mask.normalise) normalise_by_mean(w.weight);
      added.push_back({cam, v.rgb.pixels, w.weight});
      result.virtual_views.push_back(cam);
      progress.advance();
    }
    progress.finish();
    r.seconds_weights = seconds_since(t0);
    r.views_added = added.size();
    r.mean_weight = weight_count ? weight_sum / double(weight_count) : 0.0;
    trainer.add_refined(std::move(added));
  };
  // What a round's selection starts from: the round's model, the real views, and every view
  // added so far counted as observed.
  auto select_input = [&](const GaussianCloud& current) {
    SelectInput in;
    in.scene = &current;
    in.views = views;
    in.frames = F;
    in.image = image_of;
    in.background = to.background;
    in.earlier_views = result.virtual_views;
    return in;
  };
  // Real camera-times (FinetuneOptions::pool): the pool's views and which are still free.
  std::vector<ObservedView> pool_views;
  std::vector<size_t> pool_free;
  if (o.pool) {
    if (o.pool->frame_count != F)
      throw_error("finetune: the pool has ", o.pool->frame_count, " frames, the training views ", F);
    for (size_t i = 0; i < o.pool->cameras.size(); ++i) {
      const Camera& c = o.pool->cameras[i];
      if (!c.has_time()) throw_error("finetune: pool view ", c.name, " has no time");
      pool_views.push_back({c, FrameGrid(F).nearest(c.time), 0});
      pool_free.push_back(i);
    }
  }
  const int rounds = (o.iterations + o.select_every - 1) / o.select_every;
  for (int round = 0, it0 = 0; it0 < o.iterations; ++round, it0 += o.select_every) {
    FinetuneRound r;
    r.iteration = it0;
    // This round's share of the pool budget (spread evenly over the rounds).
    const int pool_count = o.pool ? o.pool_budget * (round + 1) / rounds - o.pool_budget * round / rounds : 0;
    if (o.pool && pool_count > 0) {
      const GaussianCloud current = round == 0 ? model : trainer.model();
      auto t0 = Clock::now();
      const SelectInput in = select_input(current);
      SelectOptions so = o.select;
      so.seed = o.select.seed + uint64_t(round) * 7919;
      std::vector<ObservedView> candidates;
      for (size_t i : pool_free) candidates.push_back(pool_views[i]);
      const PoolSelectResult sel = select_from_pool(in, candidates, pool_count, so, false, progress);
      r.seconds_select = seconds_since(t0);
      r.notes = sel.notes;
      r.trajectories = int(sel.chosen.size());
      std::vector<NewView> items;
      const std::string root = join_path(o.work_dir, "pool");
      make_directories(root);
      for (const PoolChoice& c : sel.chosen) {
        const size_t i = pool_free[c.candidate];
        Camera cam = o.pool->cameras[i];
        cam.time = FrameGrid(F).time(pool_views[i].frame);
        char name[32];
        std::snprintf(name, sizeof name, "r%d_v%03zu", round, items.size());
        std::vector<float> photo = o.pool->image(i);
        if (photo.size() != size_t(cam.width) * cam.height * 3)
          throw_error("finetune: pool view ", cam.name, ": its image does not have the camera's size ", cam.width, "x", cam.height);
        items.push_back({cam, Image(cam.width, cam.height, 3, std::move(photo)), join_path(root, name), std::string(name) + ".png"});
        result.pool_chosen.push_back({i, c.score, round});
      }
      std::vector<size_t> still_free;  // the candidates not chosen, in pool order
      std::vector<uint8_t> taken(candidates.size(), 0);
      for (const PoolChoice& c : sel.chosen) taken[c.candidate] = 1;
      for (size_t k = 0; k < candidates.size(); ++k)
        if (!taken[k]) still_free.push_back(pool_free[k]);
      pool_free = std::move(still_free);
      weigh_and_add(items, current, sel.initial_tables, so.deficiency_quantile, r);
    } else if (!o.pool && o.trajectories > 0) {
      const GaussianCloud current = round == 0 ? model : trainer.model();
      auto t0 = Clock::now();
      const ExplorationGrid grid = build_exploration_grid(current, cameras, FrameGrid(F).times(), o.grid, nullptr, progress);
      SelectInput in = select_input(current);
      in.grid = &grid;
      SelectOptions so = o.select;
      so.trajectories = o.trajectories;
      so.seed = o.select.seed + uint64_t(round) * 7919;
      const SelectResult sel = select_viewpoints(in, so, progress);
      r.seconds_select = seconds_since(t0);
      r.trajectories = int(sel.trajectories.size());
      r.notes = sel.notes;

      // Patches: observed start images and the current model's renders.
      t0 = Clock::now();
      std::vector<Patch> patches;
      const std::string patch_root = join_path(o.work_dir, "patches"), refined_root = join_path(o.work_dir, "refined");
      for (const Trajectory& tr : sel.trajectories) {
        char name[32];
        std::snprintf(name, sizeof name, "r%d_t%02d", round, tr.index);
        patches.push_back(make_patch(tr, views, name));
        RenderOptions ro;
        ro.background = to.background;
        write_patch(join_path(patch_root, name), patches.back(), views, image_of,
                    [&](const Camera& c) { return render(frame_at(current, c.time), c, ro).rgb; });
      }
      r.seconds_render = seconds_since(t0);
      t0 = Clock::now();
      refiner.begin_round(current, to.background);
      const RefineReport rep = refine_patches(refiner, patches, patch_root, refined_root, progress);
      r.seconds_refine = seconds_since(t0);
      r.refine_failures = rep.failures;
      r.views_dropped = rep.dropped;
      if (!patches.empty() && rep.failures.size() == patches.size() && !o.allow_failed_refinement)
        throw_error("round ", round, ": the refiner failed on every one of its ", patches.size(), " patches (first: ", rep.failures.front().second,
                    "); nothing was fine-tuned (--allow-failed-refinement goes on without them)");

      // Weights, written next to every refined image.
      std::vector<NewView> items;
      for (const RefinedImage& ri : rep.images) {
        const std::string& patch = patches[size_t(ri.patch)].name;
        items.push_back({ri.image.camera, ri.rgb, join_path(join_path(refined_root, patch), stem(ri.image.file)), patch + "/" + ri.image.file});
      }
      weigh_and_add(items, current, sel.initial_tables, so.deficiency_quantile, r);
    }
    const auto t0 = Clock::now();
    trainer.run(std::min(o.iterations, it0 + o.select_every), progress);
    train_seconds += seconds_since(t0);
    result.rounds.push_back(std::move(r));
  }
  result.model = trainer.model();
  if (to.colour_correction) {  // the model in the colours of the rig's mean camera again
    result.colour_correction = trainer.colour_correction();
    fold_mean_colour(result.model, result.colour_correction);
  }
  result.loss_history = trainer.loss_history();
  result.seconds_train = train_seconds;
  result.seconds_total = seconds_since(t_start);
  return result;
}

}  // namespace fillgs
