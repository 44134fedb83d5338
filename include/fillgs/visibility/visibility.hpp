#pragma once
// Visibility: which Gaussians a camera observes at a time, the observation-count,
// speed and deficiency tables over all frames (the paper, Sec. 3.3, Eq. (motion-aware density)), and per-pixel maps of the
// deficiency for any viewpoint (co-visibility weights, candidate scores).
//
// Three modes, one interface, each a point on the speed/accuracy curve:
//  * frustum   — the original 3DGS `radii > 0` rule: view-space z > 0.2, a non-degenerate
//                2D covariance, a 3σ rectangle that touches an image tile. No opacity, no
//                occlusion.
//  * raytraced — rays on a pixel grid of `stride` through the Embree Gaussian proxies
//                (gaussian_tracer.hpp); a Gaussian is observed when its α·T >= τ on a ray.
//  * exact     — the rasterizer at full resolution: observed when its largest α·T over
//                the pixels is >= τ. The reference.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/bounds.hpp"

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/render/raster.hpp"

namespace fillgs {

enum class VisibilityMode { Frustum, Raytraced, Exact };
FILLGS_ENUM_NAMES(VisibilityMode, "visibility mode",
    {VisibilityMode::Frustum, "frustum"}, {VisibilityMode::Raytraced, "raytraced"}, {VisibilityMode::Exact, "exact"});

struct VisibilityOptions {
  VisibilityMode mode = VisibilityMode::Frustum;
  int stride = 4;                               ///< raytraced: one ray every `stride` pixels in x and y
  float min_weight = kMinAlpha;                 ///< τ: observed when α·T >= τ
  float min_transmittance = kMinTransmittance;  ///< rays stop before T falls under this
  /// Rays see Gaussians dilated as the rasterizer draws them (+0.3 px², see RayFootprint);
  /// off: the plain 3D Gaussians (3DGRT semantics).
  bool dilate = true;
};

/// The ranges of the options both faces take (the command line's flags declare them, the
/// module's keywords are checked against them): stride >= 1, τ in (0, 1), the static hit
/// cache in MB in [0, 1e9).
Bounds stride_bounds();
Bounds tau_bounds();
Bounds hit_cache_mb_bounds();

/// Counters of the ray work (raytraced mode; maps in any mode).
struct TraceCounters {
  uint64_t rays = 0;       ///< rays traced through all layers or the static layer
  uint64_t probes = 0;     ///< "does this ray meet a dynamic proxy" queries
  uint64_t hits = 0;       ///< blended hits
};

/// Per-pixel maps of one viewpoint, on the ray grid (width = ceil(W / stride), ...).
struct ViewMaps {
  int width = 0, height = 0, stride = 1;
  std::vector<float> deficiency;  ///< Σ α·T·D̂ (D̂: normalised deficiency): the co-visibility weight
  std::vector<float> count;       ///< Σ α·T·C: blended observation count
  std::vector<float> depth;       ///< Σ α·T·distance along the optical axis
  std::vector<float> alpha;       ///< 1 − T
  /// Candidate score: the mean of the deficiency map.
  double score() const;
};

/// Visibility of one 4D scene at a current time. Holds the evaluated frame and, when a
/// mode or a map needs it, the Embree proxies (static BVH built once, dynamic refit on
/// set_time). Not thread-safe; the work inside each call is threaded.
class VisibilityEngine {
 public:
  VisibilityEngine(const GaussianCloud& cloud, const VisibilityOptions& options);
  ~VisibilityEngine();
  VisibilityEngine(const VisibilityEngine&) = delete;
  VisibilityEngine& operator=(const VisibilityEngine&) = delete;

  /// Moves to normalised time t: re-evaluates the dynamic Gaussians and refits their proxies.
  void set_time(double t);
  double time() const;
  const FrameGaussians& frame() const;
  const VisibilityOptions& options() const;

  /// Ascending ids of the Gaussians `camera` observes at the current time.
  std::vector<uint32_t> visible_set(const Camera& camera);

  /// Maps of `camera` at the current time by ray traversal (one ray every `stride` pixels).
  /// `deficiency` and `count` are per-Gaussian values (size N) blended like colour;
  /// either may be null (its map is then left empty).
  ViewMaps render_maps(const Camera& camera, const float* deficiency, const float* count, int stride = 1);

  const TraceCounters& counters() const;
  /// Seconds spent building proxies (0 until a mode or map needed them) and in the last refit.
  double build_seconds() const;
  double last_refit_seconds() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The frame count a job over `cloud` and `cameras` has when none is given: the cloud's key
/// count (a key per frame from 0 to 1) or its model's frames, else the cameras' distinct
/// times (two or more), else 1 for a static scene; 0 when none of these tells.
int observation_frames(const GaussianCloud& cloud, const std::vector<Camera>& cameras);

/// The times an observation job is asked for, checked once for every face.
struct ObserveTimes {
  std::vector<double> times;  ///< ascending, in [0, 1]
  double frame_step = 0;      ///< the speeds' Δt: one frame, 1/(F − 1)
  int frames = 0;             ///< F
};
/// F frames (`frames` 0: observation_frames of the cloud and cameras), or `times` (any order,
/// repeats dropped, each in [0, 1]; needs F ≥ 2 for the speeds' step). Refuses, before any
/// work, a request whose views (a camera per time) and, with `tables_in_memory`, [T, N]
/// tables would need more memory than the process may use. Messages name the options
/// ("frames", "times") in `spelling`'s words.
ObserveTimes observe_times(const GaussianCloud& cloud, const std::vector<Camera>& cameras, int frames, const std::vector<double>* times,
                           bool tables_in_memory, const Spelling& spelling);

/// Which training views see each frame: a camera with a time observes the frame nearest to
/// it (within half a frame; farther ones are dropped); a camera without a time is part of
/// a fixed rig and observes every frame. Returns, per time in `times`, camera indices.
std::vector<std::vector<uint32_t>> views_per_frame(const std::vector<Camera>& cameras, const std::vector<double>& times,
                                                   double frame_step);

/// Groups cameras with identical pose and intrinsics (a fixed rig written once per frame):
/// the group index of every camera, groups numbered in order of first appearance.
std::vector<uint32_t> camera_pose_groups(const std::vector<Camera>& cameras, size_t* distinct);

/// Speeds of the dynamic Gaussians at time t (dynamic_ids order), world units per unit
/// normalised time: |p(t+Δt) − p(t−Δt)| / 2Δt, one-sided where t ± Δt leaves [0, 1].
void dynamic_speeds(const GaussianCloud& cloud, double t, double frame_step, std::vector<float>& out);

struct ObservationOptions {
  VisibilityOptions visibility;
  /// Reuse each camera's static answer across frames and re-trace (raytraced) or
  /// re-project (frustum) only what dynamic Gaussians can change. Same counts either way.
  bool incremental = true;
  /// Incremental raytraced: probe only the rays inside the dynamic proxies' screen
  /// footprints; off: probe every ray (the earlier path, kept for the benchmark's ratio).
  /// Same counts either way.
  bool footprints = true;
  /// Incremental raytraced: keep the static hits of each ray the first time a moving
  /// Gaussian reaches it, and from then on trace only the dynamic layer over them
  /// (GaussianTracer::trace_over) instead of both layers again, up to this many bytes of
  /// kept hits (16 a hit); rays reached once the budget is spent are traced through both
  /// layers every time. 0: keep none. Same counts either way.
  size_t static_hit_cache_bytes = size_t(2) << 30;
  /// With kept hits and footprints: keep those of the rays in the dynamic footprints of the
  /// first frame that views a pose as its static answer traces them, instead of tracing the
  /// static layer again when a moving Gaussian first reaches them; off: the earlier path,
  /// kept for the benchmark's ratio. Same counts either way.
  bool keep_at_static_answers = true;
  /// With keep_at_static_answers: the footprints are those of every dynamic proxy swept over
  /// all the run's frames (the hull of its mean's path, grown by its first-frame box), so
  /// the static answers keep the hits of (nearly) every ray a moving Gaussian will reach and
  /// no frame traces the static layer again; off: the first frame's footprints only (the
  /// earlier path, kept for the benchmark's ratio). Same counts either way.
  bool sweep_static_answers = true;
  /// Indices into `times` to evaluate, strictly ascending; empty: every time. Views are
  /// assigned to frames over all of `times`, so the rows of a subset equal the same rows of
  /// the whole (a shard of a job split over processes or machines).
  std::vector<size_t> frames;
  /// One flag per camera: count only the views of flagged cameras; empty: every camera.
  /// The others still shape the job (which frame a view belongs to, the rasterizer-matching
  /// padding), so the counts of cameras split between processes add up to the whole's.
  std::vector<uint8_t> cameras;
};

/// The frames of shard `index` (0-based) of `count`: a contiguous block of [0, total),
/// sizes differing by at most one, earlier shards first.
std::vector<size_t> shard_frames(size_t total, size_t index, size_t count);

/// One frame of the tables, handed to the sink in frame order. Spans are valid during the call.
struct FrameObservation {
  int frame = 0;  ///< index into the `times` given to observe (also for a subset)
  double time = 0;
  const uint16_t* counts = nullptr;           ///< C[t][g] for all N Gaussians
  const float* dynamic_speed = nullptr;       ///< s[t][g] for the dynamic set (0 elsewhere)
  const float* dynamic_deficiency = nullptr;  ///< D[t][g] = s / (1 + C) for the dynamic set
  std::vector<uint32_t> views;                ///< camera indices observing this frame
  std::vector<uint32_t> visible_per_view;     ///< |visible set| per view, same order
};

struct ObservationSummary {
  size_t gaussians = 0, static_count = 0, dynamic_count = 0;
  int frames = 0;              ///< frames evaluated
  size_t views = 0;            ///< (camera, frame) pairs evaluated
  size_t camera_poses = 0;     ///< distinct poses (static answers cached per pose)
  uint16_t max_views_per_frame = 0;
  TraceCounters counters;
  uint64_t incremental_rays = 0;  ///< incremental raytraced: grid rays of the views evaluated against their static answer
  uint64_t footprint_rays = 0;    ///< of those, rays inside a dynamic proxy's screen footprint (probed)
  uint64_t retraced_rays = 0;     ///< of those, rays whose path met a dynamic proxy (re-traced)
  uint64_t cached_static_rays = 0;  ///< rays whose static hits are kept (static_hit_cache_bytes)
  uint64_t cached_static_hits = 0;  ///< static hits kept for them (sizeof(KeyedHit) = 16 bytes each)
  uint64_t cached_at_static_answers = 0;  ///< of cached_static_rays, those kept while the static answers traced them
  double seconds_build = 0, seconds_refit = 0, seconds_static = 0, seconds_frames = 0, seconds_speed = 0,
         seconds_sink = 0, seconds_total = 0;
};

/// Computes C, s and D for every time in `times` (ascending, in [0, 1]) and hands each
/// frame to `sink`. `frame_step` is Δt of the speeds (one frame of the video).
ObservationSummary observe(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                           double frame_step, const ObservationOptions& options,
                           const std::function<void(const FrameObservation&)>& sink, Progress& progress = null_progress());

/// The tables in memory: counts for every Gaussian, speeds and deficiency only for the
/// dynamic set (static Gaussians have s = D = 0).
struct ObservationTables {
  std::vector<double> times;  ///< the times evaluated (a subset when ObservationOptions::frames names one)
  size_t gaussians = 0;
  std::vector<uint32_t> dynamic_ids;
  std::vector<uint16_t> counts;              ///< [T][N]
  std::vector<float> dynamic_speed;          ///< [T][Ndyn]
  std::vector<float> dynamic_deficiency;     ///< [T][Ndyn]
  std::vector<std::vector<uint32_t>> visible_per_view;  ///< [T][views at t]
  int frames() const { return int(times.size()); }
  /// D[t][g] for all N Gaussians of frame f.
  std::vector<float> deficiency_row(int f) const;
  /// The normaliser of D for maps: the `quantile` of D over all frames and dynamic
  /// Gaussians with D > 0 (1 if there are none). D̂ = min(1, D / normaliser).
  float deficiency_scale(double quantile = 0.99) const;
};

ObservationTables observation_tables(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                     double frame_step, const ObservationOptions& options, ObservationSummary* summary = nullptr,
                                     Progress& progress = null_progress());


}  // namespace fillgs
