#pragma once
// Ray tracing through Gaussians: the narrow interface in front of the Embree proxies
// (implemented in accel/gaussian_tracer.cpp, the only place that sees Embree).
//
// Each Gaussian is an Embree user-geometry ellipsoid bounded at k = sqrt(2 ln(o / α_min))
// standard deviations (3DGRT's opacity-adaptive bound): beyond k sigmas its α is below
// α_min, so a Gaussian with o <= α_min has an empty bound and is never hit. A ray meets
// a Gaussian at the point of maximum response along the ray (t* = -o'·d' / d'·d' in the
// Gaussian's canonical frame, clamped to t >= 0), with α = min(0.99, o·exp(-½ m²)) where
// m is the Mahalanobis distance of that point. Hits are gathered in order of that
// distance (ties broken by id) with a kTraceBatch-entry k-buffer kept inside the intersect
// callback, blended front to back, and the ray stops before T would drop under T_min
// (the rasterizer's rule).
//
// Two levels: static Gaussians in a BVH built once, dynamic Gaussians in a DYNAMIC scene
// rebuilt per time step, both instanced into one top-level scene; and two such sets by size,
// so that a few large proxies do not widen every depth-ordered ray's pruning window.
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "fillgs/model/gaussians.hpp"
#include "fillgs/render/raster.hpp"

namespace fillgs {

/// Hits a ray gathers per traversal pass (its k-buffer); a ray with more blended hits
/// than this is traversed again from the last one.
constexpr int kTraceBatch = 128;

struct TracerOptions {
  float min_alpha = kMinAlpha;                  ///< α_min: a hit below it is not a hit
  float min_transmittance = kMinTransmittance;  ///< stop before T would fall under this
  /// World-space standard deviation added (in quadrature) to every proxy's bound, so that
  /// rays with a RasterMatch up to that size still find the dilated Gaussians.
  float dilation_padding = 0.0f;
  /// The cameras the rays will leave from, when known in advance: each proxy is then padded
  /// by the largest dilation those cameras give its mean (σ·z, z its view depth) instead of
  /// `dilation_padding` everywhere — tighter bounds for Gaussians nearer than the scene's
  /// farthest corner. Rays from other cameras may then miss dilated Gaussians.
  struct DilationView {
    float centre[3];
    float axis[3];           ///< unit optical axis
    float sigma_per_depth;   ///< sqrt(RasterMatch::variance_per_depth2)
  };
  std::vector<DilationView> dilation_views;
};

/// Makes a camera's rays draw what the rasterizer draws (for rays leaving the camera centre):
///  * the screen-space dilation (+0.3 px² on every 2D covariance): a Gaussian whose mean
///    lies at depth z along `axis` gets the variance `variance_per_depth2 · z²` added to
///    each of its axes (0.3 / (fx·fy) for focal lengths fx, fy in pixels);
///  * hits ordered by the view depth of the mean (the rasterizer's per-tile sort), not by
///    the distance of the maximum response;
///  * Gaussians whose mean is not beyond the near plane are not drawn.
/// Ordering by depth lets the BVH prune only to within the largest proxy's extent, so
/// huge Gaussians make such rays slower (never wrong).
struct RasterMatch {
  float axis[3] = {0, 0, 1};  ///< the camera's optical axis (unit, world space)
  float variance_per_depth2 = 0.0f;
  float near_depth = kNearPlane;
};

/// One blended hit: the Gaussian, where along the ray, its α and its weight α·T.
struct TracedHit {
  uint32_t id;
  float distance;
  float alpha;
  float weight;
};

/// What a traced ray ended with.
struct RayOutcome {
  float transmittance = 1.0f;  ///< T after the last blended hit
  /// Order key (distance, or view depth under a RasterMatch) of the hit that would have
  /// taken T under T_min: the ray ends there. +inf when the ray ran out of hits first.
  float end_key = std::numeric_limits<float>::infinity();
  uint32_t passes = 0;         ///< k-buffer passes
  /// Proxies the BVH traversal put into the k-buffer (hits given to trace_over not counted):
  /// 0 after trace_over means the dynamic layer changed nothing, the hits are the static ones.
  uint32_t traversal_entries = 0;
};

/// Which proxies a trace traverses: all, the static ones (built once), or the dynamic ones
/// (rebuilt per time; `trace_over` blends them with a static layer traced before).
enum class TraceLayers { All, StaticOnly, DynamicOnly };

/// A hit as the k-buffer orders it: by (key, id), the key a ray distance or, under a
/// RasterMatch, the view depth of the Gaussian's mean. What `trace` can return of one
/// layer so that another layer can later be traced over it (`trace_over`).
struct KeyedHit {
  float key;
  uint32_t id;
  float alpha;
  float ray_distance;
};

/// The world box a proxy's hits lie in (its k-sigma bound, dilation padding included):
/// centre = the Gaussian's mean at the current time. `half_extent[0] < 0`: an empty proxy
/// (α never reaches α_min), never hit.
struct ProxyBox {
  float centre[3];
  float half_extent[3];
};

class GaussianTracer {
 public:
  /// Builds proxies for `frame`: Gaussians listed in `dynamic_ids` (ascending) go to the
  /// per-time scene, all others to the static one.
  GaussianTracer(const FrameGaussians& frame, const std::vector<uint32_t>& dynamic_ids, const TracerOptions& options = {});
  ~GaussianTracer();
  GaussianTracer(const GaussianTracer&) = delete;
  GaussianTracer& operator=(const GaussianTracer&) = delete;

  /// Rewrites the dynamic proxies from `frame` (same Gaussian count) and rebuilds their BVH
  /// (a rebuild, not a refit: a refit keeps the first frame's topology, whose boxes grow as
  /// the Gaussians move apart).
  void refit_dynamic(const FrameGaussians& frame);

  /// Traces one ray (direction need not be unit; distances are in units of it), appending
  /// every blended hit front to back to `hits`. Thread-safe.
  /// With a RasterMatch the hits are those the rasterizer would blend (see there).
  /// `keyed` (optional): also appends each blended hit with its key and, when the ray ends
  /// at a hit that would take T under T_min, that hit last — everything a later trace of
  /// another layer needs to blend in front of and between them.
  RayOutcome trace(const Vec3f& origin, const Vec3f& direction, TraceLayers layers, std::vector<TracedHit>& hits,
                   const RasterMatch* match = nullptr, std::vector<KeyedHit>* keyed = nullptr) const;

  /// The same ray traced through the dynamic layer only, blended with the static layer's
  /// hits given as `trace(…, StaticOnly, …, keyed)` returned them for this ray (ascending
  /// by (key, id)): hits and outcome equal `trace(…, All, …)` exactly, while the static
  /// BVH is not traversed again. The static hits are offered to each k-buffer pass first,
  /// so the dynamic traversal stops where the blended ray ends. Thread-safe.
  RayOutcome trace_over(const Vec3f& origin, const Vec3f& direction, const KeyedHit* static_hits, size_t static_count,
                        std::vector<TracedHit>& hits, const RasterMatch* match = nullptr) const;

  /// True if the ray meets a dynamic proxy (a point where α >= α_min) whose order key is at
  /// most `max_key` (pass a RayOutcome::end_key to ask "can moving Gaussians change this
  /// ray's answer"). Thread-safe.
  bool meets_dynamic(const Vec3f& origin, const Vec3f& direction, float max_key,
                     const RasterMatch* match = nullptr) const;

  /// The dynamic proxies' boxes at the last refit: where moving Gaussians can change a
  /// ray's answer (screen footprints, see visibility.cpp). Per size tier, in Z order of the
  /// means at construction, so that neighbours in the list are neighbours in space (not
  /// ascending ids). `ids` (optional): the Gaussian id of each box.
  void dynamic_boxes(std::vector<ProxyBox>& out, std::vector<uint32_t>* ids = nullptr) const;

  size_t static_count() const;
  size_t dynamic_count() const;
  float dilation_padding() const;
  /// Proxies whose box half-diagonal exceeds this threshold (+inf: none) are traversed in a
  /// tier of their own, so that depth-ordered rays prune the others by the smaller tier's
  /// largest proxy rather than the scene's (chosen at construction from the proxies' sizes).
  float large_proxy_threshold() const;
  size_t large_proxy_count() const;
  double build_seconds() const;       ///< proxies + static BVH + first dynamic build
  double last_refit_seconds() const;  ///< proxies + BVH rebuild of the last refit_dynamic
  size_t memory_bytes() const;        ///< proxy arrays (Embree's own BVH memory not included)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fillgs
