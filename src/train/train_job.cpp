// The training job `fillgs train` runs (train_job.hpp).
#include "fillgs/train/train_job.hpp"

#include <cstdio>
#include <filesystem>
#include <ostream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/train/train_model.hpp"

namespace fillgs {

TrainJobResult run_train_job(const TrainJob& job, std::ostream& log, Progress& progress,
                             const std::function<void(const Trainer&, const GaussianCloud&, double)>& report) {
  const auto t0 = Clock::now();
  const Dataset& data = *job.data;
  const TrainOptions& o = job.options;
  if (o.checkpoint_interval < 1) throw_error("training: the checkpoint interval must be at least 1");
  if (o.change_from_masks && !data.has_masks()) throw_error("training: motion from masks needs foreground masks (seg/ beside the meta file)");
  std::unique_ptr<Trainer> trainer;
  PointSet init_points;  // written beside the model when made from the views
  if (!job.resume.empty()) {
    trainer = std::make_unique<Trainer>(Trainer::resume(data, job.resume, o));
    // A checkpoint at exactly `iterations` is a run killed after its last checkpoint and
    // before its model was written: resuming it writes the model, training nothing more.
    if (trainer->iteration() > job.iterations)
      throw_error(job.iterations_name, " ", job.iterations, ": ", job.resume, " is already at iteration ", trainer->iteration(),
                  "; give at least that many iterations to continue it");
    if (trainer->iteration() == job.iterations) log << job.resume << " is at iteration " << job.iterations << ", the last: writing the model from it\n";
  } else if (job.init == InitSource::Points) {
    if (job.points.empty()) throw_error("training: initial points from a file, and none was given");
    const PointSet ps = read_points(job.points);
    for (size_t i = 0; i < ps.positions.size(); ++i)
      if (!(ps.positions[i].cwiseAbs().maxCoeff() <= kMaxTrainCoordinate))
        throw_error(job.points, ": point ", i, " lies beyond what training keeps finite (|x| <= 1e7)");
    trainer = std::make_unique<Trainer>(data, init_from_points(ps), o);
  } else {
    ViewInitOptions vo = job.view_init;
    vo.method = job.init == InitSource::Random ? ViewInit::Random : ViewInit::RandomAndCarve;
    vo.seed = o.seed;
    const ViewInitResult vi = points_from_views(data, vo);
    log << "initial points from the cameras' first views: " << vi.random << " random in the cameras' common volume"
        << (vo.method == ViewInit::RandomAndCarve
                ? ", " + std::to_string(vi.carved) + " carved from the foreground masks" + (data.has_masks() ? "" : " (no masks)")
                : "")
        << "\n";
    init_points = vi.points;
    trainer = std::make_unique<Trainer>(data, init_from_points(vi.points), o);
  }
  // The folder is unfinished until the model is written; a new run first removes the
  // results of a finished one it would replace, so a run killed half-way never leaves an
  // old model.ply and summary.json beside its own checkpoint.
  UnfinishedMarker unfinished(job.out, "train");
  if (job.resume.empty())
    for (const char* old : {"model.ply", "frame0_3dgs.ply", "summary.json", "colour_correction.json", "init_points.ply", "loss.png", "loss.csv",
                            "loss.gp"}) {
      std::error_code ec;
      std::filesystem::remove(join_path(job.out, old), ec);
    }
  make_directories(join_path(job.out, "checkpoints"));
  if (!init_points.positions.empty()) write_points_ply(join_path(job.out, "init_points.ply"), init_points);
  log << "training on " << data.views().size() << " views (" << data.rigs().size() << " cameras x " << data.frames() << " frames; "
      << (data.image_bytes() >> 20) << " MB of 8-bit images " << (data.images_spilled() ? "in the image cache file, read on demand" : "in memory")
      << "), " << trainer->params().size() << " initial Gaussians, " << job.iterations << " iterations\n";
  while (trainer->iteration() < job.iterations) {
    const int next = std::min(job.iterations, (trainer->iteration() / o.checkpoint_interval + 1) * o.checkpoint_interval);
    trainer->run(next, progress);
    const TrainStatus st = trainer->status();
    char line[200];
    std::snprintf(line, sizeof line, "iteration %d: loss %.4f, PSNR %.2f dB, %zu Gaussians (%zu moving), %.1f it/s\n", st.iteration, st.loss,
                  st.psnr, st.gaussians, st.dynamic, st.iterations_per_second);
    log << line << std::flush;
    trainer->save_checkpoint(join_path(job.out, "checkpoints/latest.ckpt"));
  }
  TrainJobResult r;
  r.seconds_train = seconds_since(t0);
  r.model = trainer->model();
  // Held-out cameras have no correction of their own: the model is written in the colours
  // of the rig's mean camera, the corrections relative to it (train.hpp, fold_mean_colour).
  if (o.colour_correction) {
    r.corrections = trainer->colour_correction();
    r.mean = fold_mean_colour(r.model, r.corrections);
  }
  write_fillgs_ply(join_path(job.out, "model.ply"), r.model, data.frames());
  write_3dgs_ply(join_path(job.out, "frame0_3dgs.ply"), r.model, 0.0);
  if (o.colour_correction) write_colour_correction(join_path(job.out, "colour_correction.json"), r.corrections);
  if (report) report(*trainer, r.model, r.seconds_train);
  unfinished.finish();
  return r;
}

}  // namespace fillgs
