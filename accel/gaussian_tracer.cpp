// Embree Gaussian proxies: user-geometry ellipsoids, a k-buffer inside the intersect
// callback, a static BVH built once and a dynamic one rebuilt per time step, in two size tiers.
#include "fillgs/visibility/gaussian_tracer.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "embree_device.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/math.hpp"

namespace fillgs {

namespace {

// Scales are clamped into this range before inversion so that the canonical transform
// and the bound stay finite in float for degenerate (log-scale -inf) and huge Gaussians.
constexpr double kMinScale = 1e-30;
constexpr double kMaxExtent = 1e30;

/// One Gaussian as the callbacks need it.
struct Proxy {
  float axes[9];   ///< row j: the Gaussian's j-th axis in world space (column j of R)
  float scale[3];  ///< standard deviations along the axes, clamped to [1e-30, 1e30]
  float mean[3];
  float opacity;
  float k2;        ///< squared bound in sigmas; <= 0: α never reaches α_min
  float half_extent[3];  ///< world AABB half size at k sigmas (dilation padding included)
};

struct ProxySet {
  std::vector<Proxy> proxies;
  std::vector<uint32_t> ids;  ///< Gaussian id of each primitive
  float min_alpha = kMinAlpha;
  float padding = 0;          ///< bound padding (world sigma) for match dilation
  float slack = 0;            ///< largest proxy box half-diagonal (depth-order pruning)
};

Proxy make_proxy(const Vec3f& mean, const Vec3f& scale, const Vec4f& rotation, float opacity, float min_alpha, float padding) {
  Proxy p;
  const Mat3d R = quat_to_matrix<double>(rotation.cast<double>());
  Vec3d s;
  for (int j = 0; j < 3; ++j) s[j] = std::clamp(double(scale[j]), kMinScale, kMaxExtent);
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 3; ++i) p.axes[3 * j + i] = float(R(i, j));
    p.scale[j] = float(s[j]);
    p.mean[j] = mean[j];
  }
  p.opacity = std::min(opacity, kMaxAlpha);
  // α = min(0.99, o·exp(-m²/2)) >= α_min  <=>  m² <= 2 ln(o / α_min); the 0.99 clamp only
  // lowers α where o·exp(-m²/2) > 0.99, never at the boundary, so the bound uses o itself.
  p.k2 = opacity > min_alpha ? float(2.0 * std::log(double(opacity) / double(min_alpha))) : -1.0f;
  const double k = p.k2 > 0 ? std::sqrt(double(p.k2)) : 0.0;
  const double pad2 = double(padding) * double(padding);
  for (int i = 0; i < 3; ++i) {
    double e2 = pad2;  // rows of R are unit: Σ_j R_ij² (s_j² + pad²) = Σ_j R_ij² s_j² + pad²
    for (int j = 0; j < 3; ++j) e2 += (R(i, j) * s[j]) * (R(i, j) * s[j]);
    p.half_extent[i] = float(std::min(k * std::sqrt(e2), kMaxExtent));
  }
  return p;
}

/// The view depth of a proxy's mean under a RasterMatch: its order key (as float). The
/// callbacks compute it once and hand it to respond(), so that their window tests and the
/// key of the hit are the same number.
inline double mean_depth(const Proxy& p, const float org[3], const RasterMatch& fp) {
  const double rel[3] = {double(org[0]) - p.mean[0], double(org[1]) - p.mean[1], double(org[2]) - p.mean[2]};
  return -(rel[0] * fp.axis[0] + rel[1] * fp.axis[1] + rel[2] * fp.axis[2]);
}

/// Maximum response of a proxy along origin + t·direction, t >= 0. Returns false when the
/// ray misses the α_min ellipsoid; otherwise the distance of the maximum, α there and the
/// order key (that distance, or with a RasterMatch the mean's view depth).
/// With a RasterMatch every axis gets the variance c·z² (z: the mean's depth along the
/// camera axis), which is what the rasterizer's +0.3 px² does to a Gaussian at depth z,
/// and Gaussians with z <= the near plane are not drawn; `z` is mean_depth() under `fp`.
inline bool respond(const Proxy& p, const float org[3], const float dir[3], const RasterMatch* fp, double z, float min_alpha,
                    float* distance, float* alpha, float* key) {
  if (p.k2 <= 0.0f) return false;
  const double rel[3] = {double(org[0]) - p.mean[0], double(org[1]) - p.mean[1], double(org[2]) - p.mean[2]};
  double extra = 0.0;
  if (fp) {
    if (!(z > double(fp->near_depth))) return false;
    extra = double(fp->variance_per_depth2) * z * z;
  }
  double o[3], d[3];
  for (int j = 0; j < 3; ++j) {
    const float* a = p.axes + 3 * j;
    const double s = double(p.scale[j]);
    const double inv = extra > 0.0 ? 1.0 / std::sqrt(s * s + extra) : 1.0 / s;
    o[j] = inv * (a[0] * rel[0] + a[1] * rel[1] + a[2] * rel[2]);
    d[j] = inv * (a[0] * double(dir[0]) + a[1] * double(dir[1]) + a[2] * double(dir[2]));
  }
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  if (!(dd > 0.0) || !std::isfinite(dd)) return false;
  const double t = std::max(0.0, -(o[0] * d[0] + o[1] * d[1] + o[2] * d[2]) / dd);
  // Closest point, not |o|² - (o·d)²/|d|²: no cancellation for rays far from the Gaussian.
  const double c[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
  const double m2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
  if (!(m2 <= double(p.k2))) return false;
  const float a = std::min(kMaxAlpha, float(double(p.opacity) * std::exp(-0.5 * m2)));
  if (a < min_alpha) return false;
  *distance = float(t);
  *alpha = a;
  *key = fp ? float(z) : float(t);
  return true;
}

/// The first hits beyond the last accepted one, kept sorted by (key, id), up to the hit that
/// ends the ray: each entry knows the transmittance in front of it (from `start_T`, the
/// ray's T when the pass began, multiplied in the same order as the blend), and once some
/// entry would take T under `min_T` the entries behind it are dropped and its key becomes
/// the limit — so a ray's traversal stops where its blend will, not only once the buffer
/// is full. Keys are ray distances, or view depths under a RasterMatch.
struct KBuffer {
  static constexpr int kCapacity = kTraceBatch;
  struct Entry {
    float key;
    uint32_t id;
    float alpha;
    float ray_distance;
    float T;  ///< transmittance in front of this entry
  };
  Entry entries[kCapacity];
  int count = 0;
  bool ends = false;       ///< entries[count - 1] takes T under min_T: the ray ends there
  bool has_floor = false;  ///< false on the first pass
  float floor_key = 0;
  uint32_t floor_id = 0;
  float start_T = 1.0f, min_T = 0.0f;
  uint32_t traversal_entries = 0;  ///< offers from the BVH traversal that entered

  static bool before(float da, uint32_t ia, float db, uint32_t ib) { return da < db || (da == db && ia < ib); }

  /// Empties the buffer for a pass that starts with transmittance T.
  void begin_pass(float T) {
    count = 0;
    ends = false;
    start_T = T;
  }

  /// Whether a hit with this key and id could enter (what offer() tests first): proxies whose
  /// key is known before their response (depth keys) are skipped outside the window.
  bool admits(float key, uint32_t id) const {
    if (has_floor && !before(floor_key, floor_id, key, id)) return false;
    return !((ends || count == kCapacity) && !before(key, id, entries[count - 1].key, entries[count - 1].id));
  }

  /// Offers a hit; returns whether it entered (limit() then tells how far others still can).
  bool offer(float key, uint32_t id, float alpha, float ray_distance) {
    if (!admits(key, id)) return false;
    int i = count < kCapacity ? count++ : kCapacity - 1;
    while (i > 0 && before(key, id, entries[i - 1].key, entries[i - 1].id)) {
      entries[i] = entries[i - 1];
      --i;
    }
    entries[i] = {key, id, alpha, ray_distance, 0.0f};
    // Transmittances from the new entry on, exactly as the blend will multiply them.
    float T = i == 0 ? start_T : entries[i - 1].T * (1.0f - entries[i - 1].alpha);
    ends = false;
    for (int j = i; j < count; ++j) {
      entries[j].T = T;
      T *= 1.0f - entries[j].alpha;
      if (T < min_T) {
        count = j + 1;
        ends = true;
        break;
      }
    }
    return true;
  }
  /// The key beyond which nothing can enter any more (+inf while the buffer is neither full
  /// nor ended).
  float limit() const { return ends || count == kCapacity ? entries[count - 1].key : std::numeric_limits<float>::infinity(); }
};

/// Embree passes our context pointer through to the callbacks unchanged (also inside instances).
struct TraceContext {
  RTCIntersectContext base;
  KBuffer* buffer;
  const RasterMatch* match;
  // Depth keys: a proxy whose key is z has its box within z ± slack in depth, and ray
  // distance = depth / depth_per_distance; the BVH may skip what lies beyond.
  float slack = 0;
  float depth_per_distance = 1;
  float max_key = 0;  // occlusion queries: only hits with a key up to this count
};

void proxy_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* set = static_cast<const ProxySet*>(args->geometryUserPtr);
  const Proxy& p = set->proxies[args->primID];
  RTCBounds* b = args->bounds_o;
  if (p.k2 <= 0.0f) {
    // An empty (inverted) box: Embree leaves the primitive out of the BVH.
    b->lower_x = b->lower_y = b->lower_z = std::numeric_limits<float>::infinity();
    b->upper_x = b->upper_y = b->upper_z = -std::numeric_limits<float>::infinity();
    return;
  }
  b->lower_x = p.mean[0] - p.half_extent[0];
  b->lower_y = p.mean[1] - p.half_extent[1];
  b->lower_z = p.mean[2] - p.half_extent[2];
  b->upper_x = p.mean[0] + p.half_extent[0];
  b->upper_y = p.mean[1] + p.half_extent[1];
  b->upper_z = p.mean[2] + p.half_extent[2];
}

// No exception can be thrown below: plain arithmetic on preallocated arrays.
void proxy_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* set = static_cast<const ProxySet*>(args->geometryUserPtr);
  const TraceContext* context = reinterpret_cast<const TraceContext*>(args->context);
  KBuffer* buffer = context->buffer;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  for (unsigned i = 0; i < args->N; ++i) {
    if (!args->valid[i]) continue;
    const float org[3] = {RTCRayN_org_x(ray, args->N, i), RTCRayN_org_y(ray, args->N, i), RTCRayN_org_z(ray, args->N, i)};
    const float dir[3] = {RTCRayN_dir_x(ray, args->N, i), RTCRayN_dir_y(ray, args->N, i), RTCRayN_dir_z(ray, args->N, i)};
    const Proxy& p = set->proxies[args->primID];
    const uint32_t id = set->ids[args->primID];
    // Under depth keys the key is known before the response: a proxy outside the buffer's
    // window (the slack lets the BVH offer many) costs no response.
    const double z = context->match ? mean_depth(p, org, *context->match) : 0.0;
    if (context->match && !buffer->admits(float(z), id)) continue;
    float distance, alpha, key;
    if (!respond(p, org, dir, context->match, z, set->min_alpha, &distance, &alpha, &key)) continue;
    // Never commit the hit: Embree keeps looking; shrinking tfar once the buffer is full
    // lets the BVH skip everything that cannot come before its k-th key (which moves only
    // when a hit enters).
    if (!buffer->offer(key, id, alpha, distance)) continue;
    ++buffer->traversal_entries;
    const float limit = buffer->limit();
    if (limit < std::numeric_limits<float>::infinity())
      RTCRayN_tfar(ray, args->N, i) = context->match ? (limit + context->slack) / context->depth_per_distance : limit;
  }
}

void proxy_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* set = static_cast<const ProxySet*>(args->geometryUserPtr);
  const TraceContext* context = reinterpret_cast<const TraceContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (!args->valid[i]) continue;
    RTCRayN* ray = args->ray;
    const float org[3] = {RTCRayN_org_x(ray, args->N, i), RTCRayN_org_y(ray, args->N, i), RTCRayN_org_z(ray, args->N, i)};
    const float dir[3] = {RTCRayN_dir_x(ray, args->N, i), RTCRayN_dir_y(ray, args->N, i), RTCRayN_dir_z(ray, args->N, i)};
    const Proxy& p = set->proxies[args->primID];
    const double z = context->match ? mean_depth(p, org, *context->match) : 0.0;
    if (context->match && float(z) > context->max_key) continue;  // the key is known before the response
    float distance, alpha, key;
    if (!respond(p, org, dir, context->match, z, set->min_alpha, &distance, &alpha, &key)) continue;
    if (key > context->max_key) continue;
    RTCRayN_tfar(ray, args->N, i) = -std::numeric_limits<float>::infinity();
  }
}

/// View depth gained per unit of ray distance (rays leave the camera centre forwards).
float depth_per_distance(const Vec3f& direction, const RasterMatch& match) {
  const float d = direction.x() * match.axis[0] + direction.y() * match.axis[1] + direction.z() * match.axis[2];
  FILLGS_DCHECK(d > 0.0f);
  return d;
}

/// RAII owners for scenes and geometries (Embree handles are reference counted).
struct SceneHandle {
  RTCScene scene = nullptr;
  ~SceneHandle() {
    if (scene) rtcReleaseScene(scene);
  }
};

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The half-diagonal above which proxies go to the large tier: with sizes d sorted
/// ascending, a traversal ordered by depth keys visits about (window) × (proxies per depth)
/// and its window is the tier's largest half-diagonal, so the split minimises
/// (i + 1)·d[i] + (n − 1 − i)·d[n − 1] over i (i = n − 1: one tier). +inf when one tier is best.
float large_tier_threshold(std::vector<float> d) {
  if (d.size() < 2) return std::numeric_limits<float>::infinity();
  std::sort(d.begin(), d.end());
  const size_t n = d.size();
  size_t best = n - 1;
  double best_cost = double(n) * double(d[n - 1]);
  for (size_t i = 0; i + 1 < n; ++i) {
    if (d[i] == d[i + 1]) continue;  // a threshold splits between distinct sizes only
    const double cost = double(i + 1) * double(d[i]) + double(n - 1 - i) * double(d[n - 1]);
    if (cost < best_cost) {
      best_cost = cost;
      best = i;
    }
  }
  return best == n - 1 ? std::numeric_limits<float>::infinity() : d[best];
}

float half_diagonal(const Proxy& p) {
  return std::sqrt(p.half_extent[0] * p.half_extent[0] + p.half_extent[1] * p.half_extent[1] + p.half_extent[2] * p.half_extent[2]);
}

/// A set's depth-order slack: its largest non-empty proxy's half-diagonal.
float largest_half_diagonal(const ProxySet& set) {
  float slack = 0;
  for (const Proxy& p : set.proxies)
    if (p.k2 > 0.0f) slack = std::max(slack, half_diagonal(p));
  return slack;
}

/// 10 bits of x spread to every third bit (the Morton code's interleave).
uint32_t spread_bits(uint32_t x) {
  x &= 0x3ffu;
  x = (x | (x << 16)) & 0x030000ffu;
  x = (x | (x << 8)) & 0x0300f00fu;
  x = (x | (x << 4)) & 0x030c30c3u;
  x = (x | (x << 2)) & 0x09249249u;
  return x;
}

/// Reorders a set's primitives along the Z-order curve of their means (1024 cells an axis
/// over the set's bounds), so that neighbours in the set — and in dynamic_boxes() — are
/// neighbours in space, wherever training left them in id order: the footprint pass marks
/// runs of neighbours together (mark_dynamic_footprints). The primitive order changes
/// nothing a trace returns (hits are kept by key and Gaussian id); a dynamic set keeps the
/// order of its first frame.
void spatial_order(ProxySet& set) {
  const size_t n = set.proxies.size();
  if (n < 2) return;
  float lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<float>::infinity();
    hi[a] = -std::numeric_limits<float>::infinity();
  }
  for (const Proxy& p : set.proxies)
    for (int a = 0; a < 3; ++a)
      if (std::isfinite(p.mean[a])) {
        lo[a] = std::min(lo[a], p.mean[a]);
        hi[a] = std::max(hi[a], p.mean[a]);
      }
  std::vector<std::pair<uint32_t, uint32_t>> keyed(n);  // (code, index)
  for (size_t i = 0; i < n; ++i) {
    uint32_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const double u = hi[a] > lo[a] ? (double(set.proxies[i].mean[a]) - lo[a]) / (double(hi[a]) - lo[a]) : 0.0;
      code |= spread_bits(uint32_t(std::clamp(std::isfinite(u) ? u : 0.0, 0.0, 1.0) * 1023.0)) << a;
    }
    keyed[i] = {code, uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<Proxy> proxies(n);
  std::vector<uint32_t> ids(n);
  for (size_t i = 0; i < n; ++i) {
    proxies[i] = set.proxies[keyed[i].second];
    ids[i] = set.ids[keyed[i].second];
  }
  set.proxies = std::move(proxies);
  set.ids = std::move(ids);
}

}  // namespace


/// Proxies are split by size into tiers, each traversed on its own: a ray ordered by depth
/// keys may stop only a tier's largest proxy beyond its k-th key, so the few large proxies
/// (floaters, backgrounds) in a tier of their own keep that slack small for all the others.
/// A tier holds its static proxies (BVH built once) and dynamic ones (rebuilt per time),
/// both instanced into the tier's top-level scene.
struct GaussianTracer::Impl {
  struct Tier {
    ProxySet static_set, dynamic_set;
    SceneHandle static_scene, dynamic_scene, top;
    RTCGeometry dynamic_geometry = nullptr;  // owned by dynamic_scene
    RTCGeometry dynamic_instance = nullptr;  // owned by top

    bool empty(TraceLayers layers) const {
      if (layers == TraceLayers::DynamicOnly) return dynamic_set.proxies.empty();
      return static_set.proxies.empty() && (layers == TraceLayers::StaticOnly || dynamic_set.proxies.empty());
    }
    float slack(TraceLayers layers) const {
      if (layers == TraceLayers::DynamicOnly) return dynamic_set.slack;
      return layers == TraceLayers::All ? std::max(static_set.slack, dynamic_set.slack) : static_set.slack;
    }
    RTCScene scene(TraceLayers layers) const {
      if (layers == TraceLayers::DynamicOnly) return dynamic_scene.scene;
      return layers == TraceLayers::All ? top.scene : static_scene.scene;
    }
  };
  static constexpr int kTiers = 2;  ///< [0]: up to the threshold (and empty proxies), [1]: larger

  TracerOptions options;
  accel::EmbreeDevice device;
  Tier tiers[kTiers];
  float large_threshold = std::numeric_limits<float>::infinity();
  uint32_t max_dynamic_id = 0;  ///< what refit_dynamic checks each frame against, found once
  double build_seconds = 0, refit_seconds = 0;

  void fill(ProxySet& set, const FrameGaussians& frame) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, set.ids.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const uint32_t g = set.ids[i];
        set.proxies[i] = make_proxy(frame.means[g], frame.scales[g], frame.rotations[g], frame.opacities[g], set.min_alpha,
                                    padding_at(frame.means[g], set.padding));
      }
    });
    set.slack = largest_half_diagonal(set);
  }

  /// Bound padding of a Gaussian with mean `x`: the largest dilation σ·z over the listed
  /// cameras (z: its view depth; none at or behind the camera plane), else `uniform`.
  float padding_at(const Vec3f& x, float uniform) const {
    if (options.dilation_views.empty()) return uniform;
    float pad = 0.0f;
    for (const TracerOptions::DilationView& v : options.dilation_views) {
      const float z = v.axis[0] * (x[0] - v.centre[0]) + v.axis[1] * (x[1] - v.centre[1]) + v.axis[2] * (x[2] - v.centre[2]);
      pad = std::max(pad, v.sigma_per_depth * z);
    }
    return pad * (1.0f + 1e-5f);  // the ray's depth is computed in its own rounding
  }

  /// Moves the proxies of `all` into the tiers' sets of the same kind by size, each set in
  /// Z order of its means (spatial_order).
  void split(ProxySet& all, ProxySet Tier::*kind) {
    for (Tier& t : tiers) {
      ProxySet& s = t.*kind;
      s.min_alpha = all.min_alpha;
      s.padding = all.padding;
    }
    for (size_t i = 0; i < all.proxies.size(); ++i) {
      const Proxy& p = all.proxies[i];
      ProxySet& s = tiers[p.k2 > 0.0f && half_diagonal(p) > large_threshold ? 1 : 0].*kind;
      s.proxies.push_back(p);
      s.ids.push_back(all.ids[i]);
    }
    for (Tier& t : tiers) {
      spatial_order(t.*kind);
      (t.*kind).slack = largest_half_diagonal(t.*kind);
    }
    all = ProxySet();
  }

  RTCGeometry add_user_geometry(RTCScene scene, ProxySet& set, RTCBuildQuality quality) {
    RTCGeometry g = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(g, unsigned(set.proxies.size()));
    rtcSetGeometryUserData(g, &set);
    rtcSetGeometryBoundsFunction(g, proxy_bounds, &set);
    rtcSetGeometryIntersectFunction(g, proxy_intersect);
    rtcSetGeometryOccludedFunction(g, proxy_occluded);
    rtcSetGeometryBuildQuality(g, quality);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);  // the scene holds it
    return g;
  }

  RTCGeometry add_instance(RTCScene parent, RTCScene child) {
    RTCGeometry inst = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(inst, child);
    const float identity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, identity);
    rtcCommitGeometry(inst);
    rtcAttachGeometry(parent, inst);
    rtcReleaseGeometry(inst);
    return inst;
  }

  void build_scenes(Tier& t) {
    RTCDevice dev = device.get();
    t.static_scene.scene = rtcNewScene(dev);
    rtcSetSceneBuildQuality(t.static_scene.scene, RTC_BUILD_QUALITY_MEDIUM);
    if (!t.static_set.proxies.empty()) add_user_geometry(t.static_scene.scene, t.static_set, RTC_BUILD_QUALITY_MEDIUM);
    rtcCommitScene(t.static_scene.scene);

    t.dynamic_scene.scene = rtcNewScene(dev);
    rtcSetSceneFlags(t.dynamic_scene.scene, RTC_SCENE_FLAG_DYNAMIC);
    rtcSetSceneBuildQuality(t.dynamic_scene.scene, RTC_BUILD_QUALITY_MEDIUM);
    if (!t.dynamic_set.proxies.empty()) t.dynamic_geometry = add_user_geometry(t.dynamic_scene.scene, t.dynamic_set, RTC_BUILD_QUALITY_MEDIUM);
    rtcCommitScene(t.dynamic_scene.scene);

    t.top.scene = rtcNewScene(dev);
    if (!t.static_set.proxies.empty()) add_instance(t.top.scene, t.static_scene.scene);
    if (!t.dynamic_set.proxies.empty()) t.dynamic_instance = add_instance(t.top.scene, t.dynamic_scene.scene);
    rtcCommitScene(t.top.scene);
  }

  /// One ray through `layers`, with `seeds` (hits of another layer, ascending by (key, id))
  /// offered to every k-buffer pass before the traversal, as that layer's traversal would
  /// have offered them: the buffer's content after a pass does not depend on the order of
  /// the offers, so the blend equals a trace through both layers.
  RayOutcome trace(const Vec3f& origin, const Vec3f& direction, TraceLayers layers, const KeyedHit* seeds, size_t seed_count,
                   std::vector<TracedHit>& hits, const RasterMatch* match, std::vector<KeyedHit>* keyed) const {
    KBuffer buffer;
    TraceContext context;
    rtcInitIntersectContext(&context.base);
    context.buffer = &buffer;
    context.match = match;
    if (match) context.depth_per_distance = depth_per_distance(direction, *match);
    buffer.min_T = options.min_transmittance;
    RayOutcome out;
    float T = 1.0f;
    size_t next_seed = 0;  // seeds before it lie at or in front of the floor
    for (;;) {
      buffer.begin_pass(T);
      for (size_t i = next_seed; i < seed_count; ++i) {
        const KeyedHit& h = seeds[i];
        buffer.offer(h.key, h.id, h.alpha, h.ray_distance);
        if (buffer.limit() <= h.key) break;  // the rest cannot enter
      }
      // Every tier offers its proxies to the one k-buffer; each traversal may stop its own
      // slack beyond the buffer's current k-th key (which only moves closer).
      for (const Tier& tier : tiers) {
        if (tier.empty(layers)) continue;
        context.slack = match ? tier.slack(layers) : 0.0f;
        const float limit = buffer.limit();
        RTCRayHit rh;
        rh.ray.org_x = origin.x();
        rh.ray.org_y = origin.y();
        rh.ray.org_z = origin.z();
        rh.ray.dir_x = direction.x();
        rh.ray.dir_y = direction.y();
        rh.ray.dir_z = direction.z();
        rh.ray.tnear = !buffer.has_floor ? 0.0f
                       : match ? std::max(0.0f, (buffer.floor_key - context.slack) / context.depth_per_distance)
                               : buffer.floor_key;
        rh.ray.tfar = limit == std::numeric_limits<float>::infinity() ? limit
                      : match ? (limit + context.slack) / context.depth_per_distance
                              : limit;
        rh.ray.time = 0.0f;
        rh.ray.mask = 0xFFFFFFFFu;
        rh.ray.id = 0;
        rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        if (rh.ray.tfar >= rh.ray.tnear) rtcIntersect1(tier.scene(layers), &context.base, &rh);
      }
      ++out.passes;
      for (int i = 0; i < buffer.count; ++i) {
        const KBuffer::Entry& e = buffer.entries[i];
        const float next_T = T * (1.0f - e.alpha);
        if (keyed) keyed->push_back({e.key, e.id, e.alpha, e.ray_distance});
        if (next_T < options.min_transmittance) {
          out.transmittance = T;
          out.end_key = e.key;
          out.traversal_entries = buffer.traversal_entries;
          return out;
        }
        hits.push_back({e.id, e.ray_distance, e.alpha, e.alpha * T});
        T = next_T;
      }
      if (buffer.count < KBuffer::kCapacity) break;
      buffer.has_floor = true;
      buffer.floor_key = buffer.entries[KBuffer::kCapacity - 1].key;
      buffer.floor_id = buffer.entries[KBuffer::kCapacity - 1].id;
      while (next_seed < seed_count && !KBuffer::before(buffer.floor_key, buffer.floor_id, seeds[next_seed].key, seeds[next_seed].id))
        ++next_seed;
    }
    out.transmittance = T;
    out.traversal_entries = buffer.traversal_entries;
    return out;
  }
};

GaussianTracer::GaussianTracer(const FrameGaussians& frame, const std::vector<uint32_t>& dynamic_ids, const TracerOptions& options)
    : impl_(std::make_unique<Impl>()) {
  const auto start = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  m.options = options;
  FILLGS_CHECK(options.min_alpha > 0.0f && options.min_alpha < 1.0f);
  FILLGS_CHECK(frame.size() < size_t(std::numeric_limits<uint32_t>::max()));
  FILLGS_CHECK(options.dilation_padding >= 0.0f && std::isfinite(options.dilation_padding));
  ProxySet statics, dynamics;
  statics.min_alpha = dynamics.min_alpha = options.min_alpha;
  statics.padding = dynamics.padding = options.dilation_padding;
  dynamics.ids = dynamic_ids;
  if (!dynamic_ids.empty()) m.max_dynamic_id = *std::max_element(dynamic_ids.begin(), dynamic_ids.end());
  std::vector<char> moving(frame.size(), 0);
  for (uint32_t g : dynamic_ids) {
    FILLGS_CHECK_LT(size_t(g), frame.size());
    moving[g] = 1;
  }
  statics.ids.reserve(frame.size() - dynamic_ids.size());
  for (size_t g = 0; g < frame.size(); ++g)
    if (!moving[g]) statics.ids.push_back(uint32_t(g));
  statics.proxies.resize(statics.ids.size());
  dynamics.proxies.resize(dynamics.ids.size());
  m.fill(statics, frame);
  m.fill(dynamics, frame);
  {
    std::vector<float> sizes;
    sizes.reserve(frame.size());
    for (const ProxySet* set : {&statics, &dynamics})
      for (const Proxy& p : set->proxies)
        if (p.k2 > 0.0f) sizes.push_back(half_diagonal(p));
    m.large_threshold = large_tier_threshold(std::move(sizes));
  }
  m.split(statics, &Impl::Tier::static_set);
  m.split(dynamics, &Impl::Tier::dynamic_set);
  for (Impl::Tier& t : m.tiers) m.build_scenes(t);
  m.device.check("building Gaussian proxies");
  m.build_seconds = seconds_since(start);
}

GaussianTracer::~GaussianTracer() = default;

void GaussianTracer::refit_dynamic(const FrameGaussians& frame) {
  const auto start = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  for (Impl::Tier& t : m.tiers) {
    if (t.dynamic_set.proxies.empty()) continue;
    FILLGS_CHECK_LT(size_t(m.max_dynamic_id), frame.size());
    m.fill(t.dynamic_set, frame);
    rtcCommitGeometry(t.dynamic_geometry);
    rtcCommitScene(t.dynamic_scene.scene);
    rtcCommitGeometry(t.dynamic_instance);
    rtcCommitScene(t.top.scene);
  }
  m.device.check("refitting dynamic Gaussian proxies");
  m.refit_seconds = seconds_since(start);
}

RayOutcome GaussianTracer::trace(const Vec3f& origin, const Vec3f& direction, TraceLayers layers,
                                 std::vector<TracedHit>& hits, const RasterMatch* match, std::vector<KeyedHit>* keyed) const {
  return impl_->trace(origin, direction, layers, nullptr, 0, hits, match, keyed);
}

RayOutcome GaussianTracer::trace_over(const Vec3f& origin, const Vec3f& direction, const KeyedHit* static_hits, size_t static_count,
                                      std::vector<TracedHit>& hits, const RasterMatch* match) const {
  FILLGS_DCHECK(std::is_sorted(static_hits, static_hits + static_count, [](const KeyedHit& a, const KeyedHit& b) {
    return KBuffer::before(a.key, a.id, b.key, b.id);
  }));
  return impl_->trace(origin, direction, TraceLayers::DynamicOnly, static_hits, static_count, hits, match, nullptr);
}

bool GaussianTracer::meets_dynamic(const Vec3f& origin, const Vec3f& direction, float max_key,
                                   const RasterMatch* match) const {
  const Impl& m = *impl_;
  if (!(max_key >= 0.0f)) return false;
  for (const Impl::Tier& tier : m.tiers) {
    if (tier.dynamic_set.proxies.empty()) continue;
    TraceContext context;
    rtcInitIntersectContext(&context.base);
    context.buffer = nullptr;
    context.match = match;
    context.max_key = max_key;
    float max_distance = max_key;
    if (match) {
      context.depth_per_distance = depth_per_distance(direction, *match);
      max_distance = (max_key + tier.dynamic_set.slack) / context.depth_per_distance;
    }
    RTCRay ray;
    ray.org_x = origin.x();
    ray.org_y = origin.y();
    ray.org_z = origin.z();
    ray.dir_x = direction.x();
    ray.dir_y = direction.y();
    ray.dir_z = direction.z();
    ray.tnear = 0.0f;
    ray.tfar = max_distance;
    ray.time = 0.0f;
    ray.mask = 0xFFFFFFFFu;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(tier.dynamic_scene.scene, &context.base, &ray);
    if (ray.tfar < 0.0f) return true;
  }
  return false;
}

void GaussianTracer::dynamic_boxes(std::vector<ProxyBox>& out, std::vector<uint32_t>* ids) const {
  out.clear();
  if (ids) ids->clear();
  for (const Impl::Tier& tier : impl_->tiers) {
    for (const Proxy& p : tier.dynamic_set.proxies) {
      ProxyBox b;
      for (int a = 0; a < 3; ++a) {
        b.centre[a] = p.mean[a];
        b.half_extent[a] = p.k2 > 0.0f ? p.half_extent[a] : -1.0f;
      }
      out.push_back(b);
    }
    if (ids) ids->insert(ids->end(), tier.dynamic_set.ids.begin(), tier.dynamic_set.ids.end());
  }
}

size_t GaussianTracer::static_count() const {
  size_t n = 0;
  for (const Impl::Tier& t : impl_->tiers) n += t.static_set.ids.size();
  return n;
}
size_t GaussianTracer::dynamic_count() const {
  size_t n = 0;
  for (const Impl::Tier& t : impl_->tiers) n += t.dynamic_set.ids.size();
  return n;
}
float GaussianTracer::dilation_padding() const { return impl_->options.dilation_padding; }
float GaussianTracer::large_proxy_threshold() const { return impl_->large_threshold; }
size_t GaussianTracer::large_proxy_count() const {
  return impl_->tiers[1].static_set.ids.size() + impl_->tiers[1].dynamic_set.ids.size();
}
double GaussianTracer::build_seconds() const { return impl_->build_seconds; }
double GaussianTracer::last_refit_seconds() const { return impl_->refit_seconds; }
size_t GaussianTracer::memory_bytes() const { return (static_count() + dynamic_count()) * (sizeof(Proxy) + sizeof(uint32_t)); }

}  // namespace fillgs
