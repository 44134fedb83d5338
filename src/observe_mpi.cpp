#include "fillgs/observe_mpi.hpp"

#include <mpi.h>

#include <climits>
#include <cstring>

#include "fillgs/error.hpp"

namespace fillgs::mpi {

namespace {

constexpr int kFrameTag = 17;

struct FrameHeader {
  int64_t frame;
  double time;
  uint64_t views;
};

/// One frame as bytes: header, views, visible counts per view, counts [N], speeds and
/// deficiencies [M].
void pack(const FrameObservation& fo, size_t N, size_t M, std::vector<char>& buf) {
  const FrameHeader h{fo.frame, fo.time, fo.views.size()};
  const size_t V = fo.views.size();
  buf.resize(sizeof h + 2 * V * sizeof(uint32_t) + N * sizeof(uint16_t) + 2 * M * sizeof(float));
  char* p = buf.data();
  auto put = [&](const void* src, size_t bytes) {
    if (bytes) std::memcpy(p, src, bytes);
    p += bytes;
  };
  put(&h, sizeof h);
  put(fo.views.data(), V * sizeof(uint32_t));
  put(fo.visible_per_view.data(), V * sizeof(uint32_t));
  put(fo.counts, N * sizeof(uint16_t));
  put(fo.dynamic_speed, M * sizeof(float));
  put(fo.dynamic_deficiency, M * sizeof(float));
}

/// A received frame: the arrays behind a FrameObservation.
struct Received {
  std::vector<uint16_t> counts;
  std::vector<float> speed, deficiency;
  FrameObservation fo;
};

void unpack(const std::vector<char>& buf, size_t N, size_t M, Received* r) {
  FrameHeader h;
  FILLGS_CHECK(buf.size() >= sizeof h);
  std::memcpy(&h, buf.data(), sizeof h);
  const size_t V = size_t(h.views);
  FILLGS_CHECK(buf.size() == sizeof h + 2 * V * sizeof(uint32_t) + N * sizeof(uint16_t) + 2 * M * sizeof(float));
  const char* p = buf.data() + sizeof h;
  auto get = [&](void* dst, size_t bytes) {
    if (bytes) std::memcpy(dst, p, bytes);
    p += bytes;
  };
  r->fo.frame = int(h.frame);
  r->fo.time = h.time;
  r->fo.views.resize(V);
  r->fo.visible_per_view.resize(V);
  r->counts.resize(N);
  r->speed.resize(M);
  r->deficiency.resize(M);
  get(r->fo.views.data(), V * sizeof(uint32_t));
  get(r->fo.visible_per_view.data(), V * sizeof(uint32_t));
  get(r->counts.data(), N * sizeof(uint16_t));
  get(r->speed.data(), M * sizeof(float));
  get(r->deficiency.data(), M * sizeof(float));
  r->fo.counts = r->counts.data();
  r->fo.dynamic_speed = r->speed.data();
  r->fo.dynamic_deficiency = r->deficiency.data();
}

/// Rank 0's summary: the ranks' work added up, the slowest rank's seconds.
void reduce_summary(ObservationSummary* s, int rank) {
  uint64_t sums[6] = {uint64_t(s->frames), uint64_t(s->views), s->counters.rays, s->counters.probes, s->counters.hits, s->retraced_rays};
  double secs[7] = {s->seconds_build, s->seconds_refit, s->seconds_static, s->seconds_frames, s->seconds_speed, s->seconds_sink, s->seconds_total};
  uint64_t sum_out[6];
  double max_out[7];
  MPI_Reduce(sums, sum_out, 6, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
  MPI_Reduce(secs, max_out, 7, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  if (rank != 0) return;  // the reduced values exist on rank 0 only
  s->frames = int(sum_out[0]);
  s->views = size_t(sum_out[1]);
  s->counters.rays = sum_out[2], s->counters.probes = sum_out[3], s->counters.hits = sum_out[4], s->retraced_rays = sum_out[5];
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
  if (!options.frames.empty()) throw_error("observe --mpi: the ranks share the whole job (no --shard with it)");
  return [&cloud, &cameras, &times, frame_step, options](const FrameSink& sink, Progress& progress) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const size_t T = times.size(), N = cloud.size(), M = cloud.dynamic_count();
    const size_t frame_bytes = sizeof(FrameHeader) + 2 * cameras.size() * sizeof(uint32_t) + N * sizeof(uint16_t) + 2 * M * sizeof(float);
    if (frame_bytes > size_t(INT_MAX)) throw_error("observe --mpi: one frame's rows take ", frame_bytes, " bytes, more than one MPI message holds");
    ObservationOptions mine = options;
    for (size_t f = size_t(rank); f < T; f += size_t(size)) mine.frames.push_back(f);
    ObservationSummary summary;
    auto run = [&](const FrameSink& local) {
      if (!mine.frames.empty()) summary = observe(cloud, cameras, times, frame_step, mine, local, progress);
    };
    std::vector<char> buf;
    if (rank != 0) {
      run([&](const FrameObservation& fo) {
        pack(fo, N, M, buf);
        MPI_Send(buf.data(), int(buf.size()), MPI_BYTE, 0, kFrameTag, MPI_COMM_WORLD);
      });
    } else {
      size_t next = 0;
      Received r;
      // The frames before `end` that other ranks computed, in order.
      auto receive_until = [&](size_t end) {
        for (; next < end; ++next) {
          const int from = int(next % size_t(size));
          FILLGS_CHECK(from != 0);
          MPI_Status status;
          MPI_Probe(from, kFrameTag, MPI_COMM_WORLD, &status);
          int bytes = 0;
          MPI_Get_count(&status, MPI_BYTE, &bytes);
          buf.resize(size_t(bytes));
          MPI_Recv(buf.data(), bytes, MPI_BYTE, from, kFrameTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
          unpack(buf, N, M, &r);
          FILLGS_CHECK(size_t(r.fo.frame) == next);
          sink(r.fo);
        }
      };
      run([&](const FrameObservation& fo) {
        receive_until(size_t(fo.frame));
        sink(fo);
        next = size_t(fo.frame) + 1;
      });
      receive_until(T);
    }
    reduce_summary(&summary, rank);
    if (rank == 0) {  // what every rank knows alike (set here too when rank 0 had no frame)
      summary.gaussians = N;
      summary.static_count = cloud.static_count();
      summary.dynamic_count = M;
      camera_pose_groups(cameras, &summary.camera_poses);
      size_t max_views = 0;
      for (const auto& v : views_per_frame(cameras, times, frame_step)) max_views = std::max(max_views, v.size());
      summary.max_views_per_frame = uint16_t(max_views);
    }
    return summary;
  };
}

}  // namespace fillgs::mpi
