#include "fillgs/visibility/observe_mpi.hpp"

#include <mpi.h>

#include <algorithm>
#include <climits>
#include <cstdlib>

#include "fillgs/base/error.hpp"

namespace fillgs::mpi {

namespace {

/// Rank 0's summary: the ranks' work added up, the slowest rank's seconds.
void reduce_summary(ObservationSummary* s, int rank) {
  uint64_t sums[7] = {uint64_t(s->views), s->counters.rays,     s->counters.probes, s->counters.hits,
                      s->incremental_rays,   s->footprint_rays, s->retraced_rays};
  double secs[7] = {s->seconds_build, s->seconds_refit, s->seconds_static, s->seconds_frames, s->seconds_speed, s->seconds_sink, s->seconds_total};
  uint64_t sum_out[7];
  double max_out[7];
  MPI_Reduce(sums, sum_out, 7, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
  MPI_Reduce(secs, max_out, 7, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  if (rank != 0) return;  // the reduced values exist on rank 0 only
  s->views = size_t(sum_out[0]);
  s->counters.rays = sum_out[1], s->counters.probes = sum_out[2], s->counters.hits = sum_out[3], s->retraced_rays = sum_out[4];
  s->seconds_build = max_out[0], s->seconds_refit = max_out[1], s->seconds_static = max_out[2], s->seconds_frames = max_out[3];
  s->seconds_speed = max_out[4], s->seconds_sink = max_out[5], s->seconds_total = max_out[6];
}

}  // namespace

Session::Session() {
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (!initialised) {
    // Serialized: MPI is called from whichever thread runs observe's sink, one at a time.
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided);
    owns_ = true;
  }
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Session::~Session() {
  if (owns_) MPI_Finalize();
}

int Session::first_failure(bool ok) const {
  int mine = ok ? size_ : rank_, lowest = size_;
  MPI_Allreduce(&mine, &lowest, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  return lowest == size_ ? -1 : lowest;
}

void Session::abort(int code) const {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::abort();  // MPI_Abort does not return; this only tells the compiler so
}

FrameSource observe_source(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times, double frame_step,
                           const ObservationOptions& options) {
  if (!options.frames.empty() || !options.cameras.empty()) throw_error("MPI observation: the ranks share the whole job (no shard of it)");
  return [&cloud, &cameras, &times, frame_step, options](const FrameSink& sink, Progress& progress) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const size_t N = cloud.size(), M = cloud.dynamic_count(), C = cameras.size();
    if (N > size_t(INT_MAX)) throw_error("MPI observation: ", N, " Gaussians do not fit one MPI message's count");
    // Camera poses round the ranks: each pose's static answer is traced once in the job.
    size_t poses = 0;
    const std::vector<uint32_t> pose = camera_pose_groups(cameras, &poses);
    ObservationOptions mine = options;
    mine.cameras.assign(C, 0);
    for (size_t c = 0; c < C; ++c) mine.cameras[c] = pose[c] % uint32_t(size) == uint32_t(rank);
    std::vector<uint16_t> counts(rank == 0 ? N : 0);
    std::vector<int64_t> per_camera(2 * C), per_camera_sum(rank == 0 ? 2 * C : 0);
    std::vector<float> deficiency(rank == 0 ? M : 0);
    // Every rank visits every frame in order; per frame the partial count rows and the
    // per-camera (observed, visible) pairs are added up on rank 0.
    ObservationSummary summary = observe(
        cloud, cameras, times, frame_step, mine,
        [&](const FrameObservation& fo) {
          std::fill(per_camera.begin(), per_camera.end(), 0);
          for (size_t k = 0; k < fo.views.size(); ++k) {
            per_camera[fo.views[k]] = 1;
            per_camera[C + fo.views[k]] = int64_t(fo.visible_per_view[k]);
          }
          MPI_Reduce(fo.counts, counts.data(), int(N), MPI_UINT16_T, MPI_SUM, 0, MPI_COMM_WORLD);
          MPI_Reduce(per_camera.data(), per_camera_sum.data(), int(2 * C), MPI_INT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
          if (rank != 0) return;
          FrameObservation whole;
          whole.frame = fo.frame;
          whole.time = fo.time;
          for (size_t c = 0; c < C; ++c)  // ascending camera index, as views_per_frame lists them
            if (per_camera_sum[c]) {
              whole.views.push_back(uint32_t(c));
              whole.visible_per_view.push_back(uint32_t(per_camera_sum[C + c]));
            }
          // The speeds do not depend on the counts; D = s / (1 + C) with the job's counts, as observe computes it.
          for (size_t j = 0; j < M; ++j) deficiency[j] = fo.dynamic_speed[j] / (1.0f + float(counts[cloud.dynamic_ids[j]]));
          whole.counts = counts.data();
          whole.dynamic_speed = fo.dynamic_speed;
          whole.dynamic_deficiency = deficiency.data();
          sink(whole);
        },
        rank == 0 ? progress : null_progress());
    reduce_summary(&summary, rank);
    return summary;
  };
}

}  // namespace fillgs::mpi
