#include "fillgs/visibility/visibility.hpp"

#include "render/frustum.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <set>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>

#include "fillgs/base/error.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/visibility/gaussian_tracer.hpp"

namespace fillgs {

double ViewMaps::score() const {
  if (deficiency.empty()) return 0.0;
  double s = 0;
  for (float v : deficiency) s += v;
  return s / double(deficiency.size());
}

std::vector<size_t> shard_frames(size_t total, size_t index, size_t count) {
  if (count < 1 || index >= count) throw_error("shard ", index + 1, " of ", count, " does not exist");
  std::vector<size_t> out;
  for (size_t f = total * index / count; f < total * (index + 1) / count; ++f) out.push_back(f);
  return out;
}

namespace {


RasterMatch camera_raster_match(const Camera& cam) {
  RasterMatch f;
  for (int i = 0; i < 3; ++i) f.axis[i] = float(cam.R(2, i));
  f.variance_per_depth2 = float(double(kDilation) / (cam.fx * cam.fy));
  return f;
}

/// Bound padding a camera needs so that its dilated matchs fit: the dilation's
/// standard deviation at the farthest corner of `box`.
float padding_for(const Camera& cam, const std::pair<Vec3f, Vec3f>& box) {
  const Vec3d c = cam.centre();
  double z = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3d corner((k & 1 ? box.second : box.first).x(), (k & 2 ? box.second : box.first).y(), (k & 4 ? box.second : box.first).z());
    z = std::max(z, (cam.R.row(2) * (corner - c))(0));
  }
  return float(std::sqrt(double(kDilation) / (cam.fx * cam.fy)) * z);
}

/// Bounds of every mean the scene takes (dynamic ones sampled over time).
std::pair<Vec3f, Vec3f> scene_extent(const GaussianCloud& cloud) {
  Vec3f lo = Vec3f::Constant(std::numeric_limits<float>::infinity()), hi = -lo;
  for (size_t g = 0; g < cloud.size(); ++g) {
    lo = lo.cwiseMin(cloud.means[g]);
    hi = hi.cwiseMax(cloud.means[g]);
  }
  std::vector<Vec3f> p;
  for (int k = 0; k <= 8 && cloud.dynamic_count() > 0; ++k) {
    dynamic_means_at(cloud, k / 8.0, p);
    for (const Vec3f& x : p) {
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
  }
  if (cloud.size() == 0) lo = hi = Vec3f::Zero();
  return {lo, hi};
}

/// Rays of one camera on a pixel grid of `stride`: ray (i, j) goes through the centre of
/// pixel (off + i·stride, off + j·stride), off = stride / 2; directions have unit view
/// depth, so distances along a ray are view-space z.
struct RayGrid {
  int width = 0, height = 0, stride = 1, offset = 0;
  Vec3f origin;
  Mat3d to_world;  // Rᵀ
  const Camera* camera = nullptr;
  RasterMatch match_storage;
  const RasterMatch* match = nullptr;  // null: Gaussians are not dilated

  RayGrid(const Camera& cam, int s, bool dilate) : stride(s), camera(&cam) {
    if (dilate) {
      match_storage = camera_raster_match(cam);
      match = &match_storage;
    }
    FILLGS_CHECK(s >= 1);
    offset = std::min(s / 2, std::max(0, std::min(cam.width, cam.height) - 1));
    width = cam.width > offset ? (cam.width - offset + s - 1) / s : 0;
    height = cam.height > offset ? (cam.height - offset + s - 1) / s : 0;
    origin = cam.centre().cast<float>();
    to_world = cam.R.transpose();
  }
  size_t count() const { return size_t(width) * size_t(height); }
  Vec3f direction(int i, int j) const {
    const double px = offset + i * stride + 0.5, py = offset + j * stride + 0.5;
    const Vec3d d((px - camera->cx) / camera->fx, (py - camera->cy) / camera->fy, 1.0);
    return (to_world * d).cast<float>();
  }
};

/// Marks the rays of `grid` that a dynamic proxy can reach before the ray's static answer
/// ended (`ray_end`: order keys, +inf for rays that never saturated): a ray meets a box only
/// through the box's screen footprint. The footprint is bounded through the box's
/// axis-aligned bounds in view space (centre c, half extents |R|·h): for z ∈ [z0, z1], z0 > 0,
/// and x ∈ [x0, x1], x/z lies in [x0 / (x0 ≥ 0 ? z1 : z0), x1 / (x1 ≥ 0 ? z0 : z1)] (y alike),
/// which contains the projection of every corner (half a pixel of margin against rounding) —
/// one rotation and four divisions a box instead of eight projected corners; z0 is the
/// corners' own nearest depth. Where that bound can be more than half a ray spacing wider
/// than the corners' (|a|·f·(1/z0 − 1/z1): large boxes, or near the camera), the 8 corners
/// are projected instead. A box reaching behind the camera plane has no bounded
/// footprint and marks every ray. A proxy's order key is its mean's view depth under a
/// RasterMatch (never drawn at or before the near plane) or the view depth of a point inside
/// its box otherwise, so rays that end before that depth are left out. Conservative: every
/// ray GaussianTracer::meets_dynamic can answer yes for is marked; the probe stays the test.
/// `swept`: each box holds its proxy's path over many times, so the mean may lie anywhere in
/// it and the key is bounded by the box's nearest corner under a RasterMatch too.
/// `marks` holds grid.count() flags; returns the number of marked rays.
size_t mark_dynamic_footprints(const std::vector<ProxyBox>& boxes, const RayGrid& grid, const float* ray_end, std::atomic<uint8_t>* marks,
                               bool swept = false) {
  const size_t n = grid.count();
  for (size_t r = 0; r < n; ++r) marks[r].store(0, std::memory_order_relaxed);
  const Camera& cam = *grid.camera;
  const Vec3d eye = cam.centre();
  const Mat3d abs_R = cam.R.cwiseAbs();
  const size_t width = size_t(grid.width);
  constexpr double kMargin = 0.5;  // pixels
  // Boxes whose view-space bounds are at most this many ray spacings wider than their
  // corners' footprint use them; the others (large, or near the camera) project 8 corners.
  constexpr double kLooser = 0.5;
  const auto mark_box = [&](const ProxyBox& box, bool key_from_corner) {
    const Vec3d centre = cam.R * (Vec3d(box.centre[0], box.centre[1], box.centre[2]) - eye);
    double min_key = -std::numeric_limits<double>::infinity();
    if (grid.match && !key_from_corner) {
      if (!(centre.z() > double(grid.match->near_depth))) return;
      min_key = centre.z();
    }
    const Vec3d half = abs_R * Vec3d(box.half_extent[0], box.half_extent[1], box.half_extent[2]);
    const double zmin = centre.z() - half.z();
    if (!grid.match || swept || key_from_corner) min_key = zmin;
    min_key -= 1e-5 * std::fabs(min_key) + 1e-6;  // the probe computes the key in its own rounding
    int i0 = 0, i1 = grid.width - 1, j0 = 0, j1 = grid.height - 1;
    if (zmin > 1e-9 * std::max(1.0, std::fabs(centre.z()))) {  // bounded footprint
      const double zmax = centre.z() + half.z();
      // Bounds of a / z over a ∈ [a0, a1], z ∈ [zmin, zmax], mapped to pixels.
      const auto screen_range = [&](double a0, double a1, double f, double c, double& lo, double& hi) {
        const double r0 = a0 / (a0 >= 0.0 ? zmax : zmin), r1 = a1 / (a1 >= 0.0 ? zmin : zmax);
        lo = std::min(f * r0, f * r1) + c;
        hi = std::max(f * r0, f * r1) + c;
      };
      double umin, umax, vmin, vmax;
      // How much wider (pixels) the view-space bounds can be than the corners' footprint:
      // a coordinate a is divided by z0 or z1 where a corner may have the other.
      const double ax = std::max(std::fabs(centre.x() - half.x()), std::fabs(centre.x() + half.x()));
      const double ay = std::max(std::fabs(centre.y() - half.y()), std::fabs(centre.y() + half.y()));
      const double looser = std::max(std::fabs(cam.fx) * ax, std::fabs(cam.fy) * ay) * (1.0 / zmin - 1.0 / zmax);
      if (looser <= kLooser * grid.stride) {
        screen_range(centre.x() - half.x(), centre.x() + half.x(), cam.fx, cam.cx, umin, umax);
        screen_range(centre.y() - half.y(), centre.y() + half.y(), cam.fy, cam.cy, vmin, vmax);
      } else {  // deep in view: the corners themselves (all in front of the camera here)
        umin = vmin = std::numeric_limits<double>::infinity();
        umax = vmax = -umin;
        for (int k = 0; k < 8; ++k) {
          const Vec3d corner(k & 1 ? box.half_extent[0] : -box.half_extent[0], k & 2 ? box.half_extent[1] : -box.half_extent[1],
                             k & 4 ? box.half_extent[2] : -box.half_extent[2]);
          const Vec3d x = centre + cam.R * corner;
          const double u = cam.fx * x.x() / x.z() + cam.cx, v = cam.fy * x.y() / x.z() + cam.cy;
          umin = std::min(umin, u);
          umax = std::max(umax, u);
          vmin = std::min(vmin, v);
          vmax = std::max(vmax, v);
        }
      }
      const double off = grid.offset + 0.5, s = grid.stride;
      // The first and last ray whose pixel centre (off + i·s) lies in [lo, hi], clamped to the grid.
      const auto first_ray = [&](double lo, int last) { return int(std::clamp(std::ceil((lo - kMargin - off) / s), 0.0, last + 1.0)); };
      const auto last_ray = [&](double hi, int last) { return int(std::clamp(std::floor((hi + kMargin - off) / s), -1.0, double(last))); };
      i0 = first_ray(umin, grid.width - 1);
      i1 = last_ray(umax, grid.width - 1);
      j0 = first_ray(vmin, grid.height - 1);
      j1 = last_ray(vmax, grid.height - 1);
    }
    const float key = float(min_key);  // ray ends are floats: compare in float, rounded down
    const float floor_key = double(key) > min_key ? std::nextafter(key, -std::numeric_limits<float>::infinity()) : key;
    for (int j = j0; j <= j1; ++j) {
      const size_t row = size_t(j) * width;
      for (int i = i0; i <= i1; ++i)
        if (ray_end[row + size_t(i)] >= floor_key) marks[row + size_t(i)].store(1, std::memory_order_relaxed);
    }
  };
  // Neighbours in `boxes` are neighbours in space (the tracer keeps its proxies in Z order),
  // so a run of boxes is marked once through its union when that union is compact (its
  // half-diagonal at most kCompact times its largest member's): a superset of the members'
  // footprints, keyed from its nearest corner, for one projection instead of one a box.
  // Runs of kRun boxes; a run that is not compact is split in four, down to single boxes.
  constexpr size_t kRun = 32;
  constexpr float kCompact = 2.0f;
  const auto mark_run = [&](const auto& self, size_t first, size_t last) -> void {
    double lo[3], hi[3], largest = 0.0;  // corners exactly as mark_box sees them (double)
    size_t members = 0;
    for (size_t b = first; b < last; ++b) {
      const ProxyBox& box = boxes[b];
      if (box.half_extent[0] < 0.0f) continue;
      double d2 = 0.0;
      for (int a = 0; a < 3; ++a) {
        const double l = double(box.centre[a]) - box.half_extent[a], h = double(box.centre[a]) + box.half_extent[a];
        lo[a] = members ? std::min(lo[a], l) : l;
        hi[a] = members ? std::max(hi[a], h) : h;
        d2 += double(box.half_extent[a]) * box.half_extent[a];
      }
      largest = std::max(largest, d2);
      ++members;
    }
    if (members == 0) return;
    if (members == 1 || last - first == 1) {
      for (size_t b = first; b < last; ++b)
        if (boxes[b].half_extent[0] >= 0.0f) mark_box(boxes[b], false);
      return;
    }
    ProxyBox hull;  // in float like every box: the half extent rounded up past the float centre
    double hull_d2 = 0.0;
    for (int a = 0; a < 3; ++a) {
      hull.centre[a] = float(0.5 * (lo[a] + hi[a]));
      const double reach = std::max(hi[a] - hull.centre[a], hull.centre[a] - lo[a]);
      hull.half_extent[a] = float(reach);
      if (double(hull.half_extent[a]) < reach) hull.half_extent[a] = std::nextafter(hull.half_extent[a], std::numeric_limits<float>::infinity());
      hull_d2 += double(hull.half_extent[a]) * hull.half_extent[a];
    }
    if (std::isfinite(hull_d2) && hull_d2 <= double(kCompact) * kCompact * largest) {
      mark_box(hull, true);
      return;
    }
    const size_t step = std::max<size_t>(1, (last - first + 3) / 4);
    for (size_t b = first; b < last; b += step) self(self, b, std::min(last, b + step));
  };
  const size_t runs = (boxes.size() + kRun - 1) / kRun;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, runs, 32), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t run = range.begin(); run < range.end(); ++run) mark_run(mark_run, run * kRun, std::min(boxes.size(), (run + 1) * kRun));
  });
  size_t marked = 0;
  for (size_t r = 0; r < n; ++r) marked += marks[r].load(std::memory_order_relaxed);
  return marked;
}

/// Every dynamic proxy's box swept over `times`: the hull of its mean's positions there,
/// grown by its box at the tracer's current frame (empty proxies stay empty). What the
/// static answers keep hits for (ObservationOptions::sweep_static_answers); a Gaussian whose
/// extent grows along its path may reach a ray outside it, which is then kept when reached.
std::vector<ProxyBox> swept_dynamic_boxes(const GaussianCloud& cloud, const GaussianTracer& tracer, const std::vector<double>& times) {
  std::vector<ProxyBox> boxes;
  std::vector<uint32_t> ids;
  tracer.dynamic_boxes(boxes, &ids);
  const size_t M = cloud.dynamic_count();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<Vec3f> lo(M, Vec3f::Constant(inf)), hi(M, Vec3f::Constant(-inf)), means;
  for (double t : times) {
    dynamic_means_at(cloud, t, means);
    for (size_t m = 0; m < M; ++m) {
      lo[m] = lo[m].cwiseMin(means[m]);
      hi[m] = hi[m].cwiseMax(means[m]);
    }
  }
  for (size_t b = 0; b < boxes.size(); ++b) {
    const size_t m = size_t(std::lower_bound(cloud.dynamic_ids.begin(), cloud.dynamic_ids.end(), ids[b]) - cloud.dynamic_ids.begin());
    ProxyBox& box = boxes[b];
    if (box.half_extent[0] < 0.0f || m >= M || times.empty()) continue;
    for (int a = 0; a < 3; ++a) {
      box.centre[a] = 0.5f * (lo[m][a] + hi[m][a]);
      box.half_extent[a] += 0.5f * (hi[m][a] - lo[m][a]);
    }
  }
  return boxes;
}

/// Appends the ids of hits whose weight reaches τ.
void observed_ids(const std::vector<TracedHit>& hits, float tau, std::vector<uint32_t>& out) {
  for (const TracedHit& h : hits)
    if (h.weight >= tau) out.push_back(h.id);
}

void sort_unique(std::vector<uint32_t>& v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
}

/// Per-thread scratch for ray work.
struct RayScratch {
  std::vector<TracedHit> hits;
  std::vector<uint32_t> ids;
  uint64_t rays = 0, probes = 0, hits_count = 0;
};

/// Gathers per-thread id lists into one ascending, duplicate-free list.
/// One ascending, duplicate-free list of several unsorted ones: each sorted on its own (in
/// parallel), then merged run by run (linear per run, one run per thread).
std::vector<uint32_t> merge_id_lists(const std::vector<std::vector<uint32_t>*>& lists) {
  tbb::parallel_for(size_t(0), lists.size(), [&](size_t i) { sort_unique(*lists[i]); });
  std::vector<uint32_t> all;
  for (std::vector<uint32_t>* list : lists) {
    const size_t mid = all.size();
    all.insert(all.end(), list->begin(), list->end());
    std::inplace_merge(all.begin(), all.begin() + std::ptrdiff_t(mid), all.end());
    list->clear();
  }
  all.erase(std::unique(all.begin(), all.end()), all.end());
  return all;
}

std::vector<uint32_t> merge_ids(tbb::enumerable_thread_specific<RayScratch>& scratch, TraceCounters* counters) {
  std::vector<std::vector<uint32_t>*> lists;
  for (RayScratch& s : scratch) {
    lists.push_back(&s.ids);
    if (counters) {
      counters->rays += s.rays;
      counters->probes += s.probes;
      counters->hits += s.hits_count;
    }
    s.rays = s.probes = s.hits_count = 0;
  }
  return merge_id_lists(lists);
}

/// Frustum rule for the listed Gaussians (all when ids is null), one list per view (an index
/// of `cameras`), ascending where `ids` is: blocks of rows in order, each read once and kept by the vector rule
/// (render/frustum.hpp) for every camera, joined in order.
std::vector<std::vector<uint32_t>> frustum_visible(const FrameGaussians& frame, const std::vector<Camera>& cameras,
                                                   const std::vector<uint32_t>& views, const std::vector<uint32_t>* ids) {
  const size_t n = ids ? ids->size() : frame.size();
  constexpr size_t kBlock = 8192;
  const size_t blocks = (n + kBlock - 1) / kBlock, C = views.size();
  std::vector<internal::FrustumCamera> fc;
  for (uint32_t c : views) fc.emplace_back(cameras[c]);
  std::vector<std::vector<uint32_t>> found(blocks * C);  // [block][camera]
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b < r.end(); ++b)
      internal::frustum_keep(fc.data(), C, frame.means.data(), frame.scales.data(), frame.rotations.data(), ids ? ids->data() : nullptr,
                             b * kBlock, std::min(n, (b + 1) * kBlock), &found[b * C]);
  });
  std::vector<std::vector<uint32_t>> all(C);
  tbb::parallel_for(size_t(0), C, [&](size_t c) {
    size_t total = 0;
    for (size_t b = 0; b < blocks; ++b) total += found[b * C + c].size();
    all[c].reserve(total);
    for (size_t b = 0; b < blocks; ++b) all[c].insert(all[c].end(), found[b * C + c].begin(), found[b * C + c].end());
  });
  return all;
}

std::vector<uint32_t> frustum_visible(const FrameGaussians& frame, const Camera& cam, const std::vector<uint32_t>* ids) {
  return std::move(frustum_visible(frame, std::vector<Camera>{cam}, {0}, ids)[0]);
}

std::vector<uint32_t> exact_visible(const FrameGaussians& frame, const Camera& cam, float tau) {
  RenderOptions ro;
  ro.rgb = false;
  ro.max_weights = true;
  const RenderOutput out = render(frame, cam, ro);
  std::vector<uint32_t> ids;
  for (size_t g = 0; g < out.max_weight.size(); ++g)
    if (out.max_weight[g] >= tau) ids.push_back(uint32_t(g));
  return ids;
}

/// Traces every ray of the grid through `layers` in parallel over rows and calls
/// visit(scratch, ray index, outcome) with the ray's hits in scratch.hits.
template <typename Visit>
void trace_grid(const GaussianTracer& tracer, const RayGrid& grid, TraceLayers layers,
                tbb::enumerable_thread_specific<RayScratch>& scratch, const Visit& visit) {
  tbb::parallel_for(tbb::blocked_range<int>(0, grid.height, 1), [&](const tbb::blocked_range<int>& r) {
    RayScratch& s = scratch.local();
    for (int j = r.begin(); j < r.end(); ++j)
      for (int i = 0; i < grid.width; ++i) {
        s.hits.clear();
        const RayOutcome o = tracer.trace(grid.origin, grid.direction(i, j), layers, s.hits, grid.match);
        ++s.rays;
        s.hits_count += s.hits.size();
        visit(s, size_t(j) * size_t(grid.width) + size_t(i), o);
      }
  });
}

/// Every ray of the grid through all layers; the union of observed ids.
std::vector<uint32_t> raytraced_visible(const GaussianTracer& tracer, const RayGrid& grid, float tau, TraceCounters* counters) {
  tbb::enumerable_thread_specific<RayScratch> scratch;
  trace_grid(tracer, grid, TraceLayers::All, scratch,
             [&](RayScratch& s, size_t, const RayOutcome&) { observed_ids(s.hits, tau, s.ids); });
  return merge_ids(scratch, counters);
}

}  // namespace

// ---------------------------------------------------------------------------------
// VisibilityEngine

struct VisibilityEngine::Impl {
  const GaussianCloud& cloud;
  VisibilityOptions options;
  FrameSampler sampler;
  const FrameGaussians* frame = nullptr;
  std::unique_ptr<GaussianTracer> tracer;
  TraceCounters counters;
  std::pair<Vec3f, Vec3f> extent;
  bool have_extent = false;

  Impl(const GaussianCloud& c, const VisibilityOptions& o)
      : cloud(c), options(o), sampler(c) {}

  /// The proxies, (re)built when a camera's dilated matchs need more bound padding
  /// than they have (with 25% headroom, so a rig of similar cameras builds once).
  GaussianTracer& proxies(const Camera* camera) {
    if (camera && options.dilate && !have_extent) {
      extent = scene_extent(cloud);  // only matched rays need it
      have_extent = true;
    }
    const float need = camera && options.dilate ? padding_for(*camera, extent) : 0.0f;
    if (!tracer || need > tracer->dilation_padding()) {
      TracerOptions to;
      to.min_transmittance = options.min_transmittance;
      to.dilation_padding = std::max(tracer ? tracer->dilation_padding() : 0.0f, 1.25f * need);
      tracer.reset();
      tracer = std::make_unique<GaussianTracer>(*frame, cloud.dynamic_ids, to);
    }
    return *tracer;
  }
};

VisibilityEngine::VisibilityEngine(const GaussianCloud& cloud, const VisibilityOptions& options)
    : impl_(std::make_unique<Impl>(cloud, options)) {
  FILLGS_CHECK(options.stride >= 1);
  FILLGS_CHECK(options.min_weight > 0.0f);
  impl_->frame = &impl_->sampler.at(0.0);
}

VisibilityEngine::~VisibilityEngine() = default;

void VisibilityEngine::set_time(double t) {
  Impl& m = *impl_;
  // The same time again (callers move between candidates of one frame): nothing to refit.
  if (std::clamp(t, 0.0, 1.0) == m.frame->time) return;
  m.frame = &m.sampler.at(t);
  if (m.tracer) m.tracer->refit_dynamic(*m.frame);
}

double VisibilityEngine::time() const { return impl_->frame->time; }
const FrameGaussians& VisibilityEngine::frame() const { return *impl_->frame; }
const VisibilityOptions& VisibilityEngine::options() const { return impl_->options; }
const TraceCounters& VisibilityEngine::counters() const { return impl_->counters; }
double VisibilityEngine::build_seconds() const { return impl_->tracer ? impl_->tracer->build_seconds() : 0.0; }
double VisibilityEngine::last_refit_seconds() const { return impl_->tracer ? impl_->tracer->last_refit_seconds() : 0.0; }

std::vector<uint32_t> VisibilityEngine::visible_set(const Camera& camera) {
  Impl& m = *impl_;
  std::vector<uint32_t> ids;
  switch (m.options.mode) {
    case VisibilityMode::Frustum: ids = frustum_visible(*m.frame, camera, nullptr); break;
    case VisibilityMode::Exact: ids = exact_visible(*m.frame, camera, m.options.min_weight); break;
    case VisibilityMode::Raytraced:
      ids = raytraced_visible(m.proxies(&camera), RayGrid(camera, m.options.stride, m.options.dilate), m.options.min_weight, &m.counters);
      break;
  }
  return ids;
}

ViewMaps VisibilityEngine::render_maps(const Camera& camera, const float* deficiency, const float* count, int stride) {
  Impl& m = *impl_;
  ViewMaps maps;
  const GaussianTracer& tracer = m.proxies(&camera);
  const RayGrid grid(camera, stride, m.options.dilate);
  maps.width = grid.width;
  maps.height = grid.height;
  maps.stride = stride;
  const size_t n = grid.count();
  if (deficiency) maps.deficiency.assign(n, 0.0f);
  if (count) maps.count.assign(n, 0.0f);
  maps.depth.assign(n, 0.0f);
  maps.alpha.assign(n, 0.0f);
  tbb::enumerable_thread_specific<RayScratch> scratch;
  trace_grid(tracer, grid, TraceLayers::All, scratch, [&](RayScratch& s, size_t p, const RayOutcome& o) {
    double d = 0, c = 0, z = 0;
    for (const TracedHit& h : s.hits) {
      if (deficiency) d += double(h.weight) * deficiency[h.id];
      if (count) c += double(h.weight) * count[h.id];
      z += double(h.weight) * h.distance;
    }
    if (deficiency) maps.deficiency[p] = float(d);
    if (count) maps.count[p] = float(c);
    maps.depth[p] = float(z);
    maps.alpha[p] = 1.0f - o.transmittance;
  });
  merge_ids(scratch, &m.counters);
  return maps;
}

// ---------------------------------------------------------------------------------
// Views, speeds

int observation_frames(const GaussianCloud& cloud, const std::vector<Camera>& cameras) {
  if (cloud.motion == MotionModel::Keyframed && cloud.keyframed.first_key_time == 0.0 && cloud.keyframed.key_count >= 2 &&
      std::fabs(cloud.keyframed.key_spacing * (cloud.keyframed.key_count - 1) - 1.0) < 1e-6)
    return cloud.keyframed.key_count;  // one key per frame
  if (cloud.motion == MotionModel::Evaluated && motion_frames(cloud) > 0) return motion_frames(cloud);
  std::set<long long> distinct;
  for (const Camera& c : cameras)
    if (c.has_time()) distinct.insert(std::llround(c.time * 1e6));
  if (distinct.size() >= 2) return int(distinct.size());
  return cloud.dynamic_count() == 0 ? 1 : 0;  // a static scene has one time
}

ObserveTimes observe_times(const GaussianCloud& cloud, const std::vector<Camera>& cams, int frames, const std::vector<double>* times,
                           bool tables_in_memory, const Spelling& s) {
  if (cams.empty()) throw_error("no cameras");
  if (frames < 0) throw_error(s("frames"), " must be at least 0, got ", frames);
  ObserveTimes r;
  r.frames = frames ? frames : observation_frames(cloud, cams);
  if (!r.frames) throw_error("cannot tell the frame count from the scene or the cameras; give ", s("frames"), " F");
  // The work asked for, before any of it is done: a view per camera and time, and, where the
  // caller keeps them, the observation tables of every Gaussian at every time.
  {
    const std::string what = std::to_string(cams.size()) + " camera(s) at " + std::to_string(r.frames) + " frames";
    const std::string source = s("frames") + " " + std::to_string(r.frames);
    const size_t views = checked_mul(cams.size(), size_t(r.frames), s("frames"), what);
    size_t bytes = checked_mul(views, sizeof(Camera) + 64, s("frames"), what);
    if (tables_in_memory) bytes += checked_mul(checked_mul(cloud.size(), size_t(r.frames), s("frames"), what), 10, s("frames"), what);
    check_allocation(bytes, source, what + (tables_in_memory ? " with the tables of " + std::to_string(cloud.size()) + " Gaussians" : ""));
  }
  r.frame_step = FrameGrid(r.frames).step();
  if (!times) {
    r.times = FrameGrid(r.frames).times();
    return r;
  }
  if (r.frames < 2) throw_error("give ", s("frames"), " F with ", s("times"), " (the speed's step is one frame, 1/(F-1))");
  for (size_t i = 0; i < times->size(); ++i)
    if (!((*times)[i] >= 0.0 && (*times)[i] <= 1.0))
      throw_error(s("times"), ": element ", i, " is ", number_text((*times)[i]), ", not a time in [0, 1]");
  r.times = *times;
  std::sort(r.times.begin(), r.times.end());
  r.times.erase(std::unique(r.times.begin(), r.times.end()), r.times.end());
  if (r.times.empty()) throw_error(s("times"), " is empty");
  return r;
}

std::vector<std::vector<uint32_t>> views_per_frame(const std::vector<Camera>& cameras, const std::vector<double>& times,
                                                   double frame_step) {
  std::vector<std::vector<uint32_t>> views(times.size());
  for (size_t c = 0; c < cameras.size(); ++c) {
    if (!cameras[c].has_time()) {
      for (auto& v : views) v.push_back(uint32_t(c));
      continue;
    }
    const double t = cameras[c].time;
    const auto it = std::lower_bound(times.begin(), times.end(), t);
    size_t best = times.size();
    double best_gap = std::numeric_limits<double>::infinity();
    for (auto k : {it - times.begin() - 1, it - times.begin()}) {
      if (k < 0 || size_t(k) >= times.size()) continue;
      const double gap = std::fabs(times[size_t(k)] - t);
      if (gap < best_gap) best_gap = gap, best = size_t(k);
    }
    // Half a frame, with room for the rounding of times written as decimals.
    if (best < times.size() && best_gap <= 0.5 * frame_step * (1.0 + 1e-6) + 1e-9) views[best].push_back(uint32_t(c));
  }
  return views;
}

void dynamic_speeds(const GaussianCloud& cloud, double t, double frame_step, std::vector<float>& out) {
  out.assign(cloud.dynamic_count(), 0.0f);
  if (out.empty() || !(frame_step > 0.0)) return;
  const double t0 = std::max(0.0, t - frame_step), t1 = std::min(1.0, t + frame_step);
  if (!(t1 > t0)) return;
  std::vector<Vec3f> p0, p1;
  dynamic_means_at(cloud, t0, p0);
  dynamic_means_at(cloud, t1, p1);
  for (size_t j = 0; j < out.size(); ++j) out[j] = float((p1[j] - p0[j]).cast<double>().norm() / (t1 - t0));
}

// ---------------------------------------------------------------------------------
// Tables over all frames

namespace {

/// A camera pose's static answer, computed once and reused by every frame it observes.
struct PoseCache {
  bool ready = false;
  size_t visible_count = 0;         ///< static ids observed
  std::vector<uint32_t> visible;    ///< raytraced: ascending static ids observed (frustum: the bitmap alone)
  std::vector<uint32_t> ray_refs;   ///< raytraced: rays observing visible[k]
  // raytraced: per ray (row-major over the grid) its static observed Gaussians, as slots k
  // of `visible`, and its end distance
  std::vector<uint64_t> ray_offsets;
  std::vector<uint32_t> ray_slots;
  std::vector<float> ray_end;
  std::vector<uint64_t> visible_bits;  ///< bit g set when static id g is observed
  // raytraced, static_hit_cache_bytes > 0: per ray its static hits once a moving Gaussian
  // reached it (null until then; they live in the run's HitArenas)
  struct KeptHits {
    const KeyedHit* hits = nullptr;
    uint32_t count = 0;
  };
  std::vector<KeptHits> kept;
  /// The observed static ids as the bitmap and the count (of a cloud of n Gaussians).
  void mark_visible(const std::vector<uint32_t>& ids, size_t n) {
    visible_count = ids.size();
    visible_bits.assign((n + 63) / 64, 0);
    for (uint32_t g : ids) visible_bits[g / 64] |= uint64_t(1) << (g % 64);
  }
  /// f(g) for each observed static id g, ascending.
  template <typename F>
  void for_each_visible(F&& f) const {
    for (size_t w = 0; w < visible_bits.size(); ++w)
      for (uint64_t bits = visible_bits[w]; bits; bits &= bits - 1) f(uint32_t(w * 64 + size_t(__builtin_ctzll(bits))));
  }
};

/// Storage that never moves what it holds: each ray's hits go contiguously into a block of
/// at least kBlock entries, appended to by one thread.
class HitArena {
 public:
  const KeyedHit* keep(const KeyedHit* hits, size_t n) {
    if (blocks_.empty() || used_ + n > capacity_) {
      capacity_ = std::max(kBlock, n);
      blocks_.emplace_back(new KeyedHit[capacity_]);
      used_ = 0;
    }
    KeyedHit* at = blocks_.back().get() + used_;
    std::copy(hits, hits + n, at);
    used_ += n;
    return at;
  }

 private:
  static constexpr size_t kBlock = size_t(1) << 16;
  std::vector<std::unique_ptr<KeyedHit[]>> blocks_;
  size_t capacity_ = 0, used_ = 0;
};

}  // namespace

std::vector<uint32_t> camera_pose_groups(const std::vector<Camera>& cameras, size_t* distinct) {
  std::map<std::vector<double>, uint32_t> seen;
  std::vector<uint32_t> index(cameras.size());
  for (size_t c = 0; c < cameras.size(); ++c) {
    const Camera& k = cameras[c];
    std::vector<double> key = {double(k.width), double(k.height), k.fx, k.fy, k.cx, k.cy};
    key.insert(key.end(), k.R.data(), k.R.data() + 9);
    key.insert(key.end(), k.t.data(), k.t.data() + 3);
    index[c] = seen.emplace(key, uint32_t(seen.size())).first->second;
  }
  *distinct = seen.size();
  return index;
}

namespace {

/// Change of one view's visible set at a time against its pose's static answer.
struct ViewDelta {
  std::vector<uint32_t> removed;  ///< static ids no longer observed (occluded by moving ones); any order
  std::vector<uint32_t> added;    ///< ids observed that the static answer lacks
};

class ObservationRun {
 public:
  ObservationRun(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const ObservationOptions& options)
      : cloud_(cloud), cameras_(cameras), vis_(options.visibility), footprints_(options.footprints),
        cache_budget_(options.static_hit_cache_bytes), keep_at_answers_(options.keep_at_static_answers) {
    pose_of_camera_ = camera_pose_groups(cameras, &pose_count_);
    poses_.resize(pose_count_);
    marks_.assign(cloud.size(), 0);
  }

  ObservationSummary summary;

  /// The static answers of the poses among `views` that no earlier frame viewed.
  /// Frustum: one reading of the static Gaussians for all of them, each answer kept as a
  /// bitmap (N / 8 bytes, not 4 bytes per observed id: 20 cameras of a 10-million-Gaussian
  /// scene would hold 800 MB of lists). Raytraced: static_answer, pose by pose.
  void static_answers(const FrameGaussians& frame, const GaussianTracer* tracer, const std::vector<ProxyBox>& boxes,
                      const std::vector<uint32_t>& views, bool swept) {
    if (vis_.mode != VisibilityMode::Frustum) {
      for (uint32_t c : views) static_answer(frame, tracer, boxes, c, swept);
      return;
    }
    std::vector<uint32_t> fresh;  // one camera per pose not answered yet
    for (uint32_t c : views)
      if (!pose(c).ready && std::none_of(fresh.begin(), fresh.end(), [&](uint32_t k) { return pose_index(k) == pose_index(c); }))
        fresh.push_back(c);
    if (fresh.empty()) return;
    const auto start = Clock::now();
    const std::vector<uint32_t> statics = cloud_.static_ids();
    const std::vector<std::vector<uint32_t>> visible = frustum_visible(frame, cameras_, fresh, &statics);
    for (size_t k = 0; k < fresh.size(); ++k) {
      pose(fresh[k]).mark_visible(visible[k], cloud_.size());
      pose(fresh[k]).ready = true;
    }
    summary.seconds_static += seconds_since(start);
  }

  /// Raytraced: the pose's static answer, at the first frame that views it. With kept hits:
  /// the static hits of the rays in the footprints of this frame's dynamic proxies (`boxes`)
  /// are kept as they are traced here, so the frames need not trace the static layer again
  /// for the rays a moving Gaussian reaches first (those it reaches later are kept then).
  void static_answer(const FrameGaussians& frame, const GaussianTracer* tracer, const std::vector<ProxyBox>& boxes, uint32_t camera,
                     bool swept) {
    PoseCache& pc = poses_[pose_of_camera_[camera]];
    if (pc.ready) return;
    const auto start = Clock::now();
    const Camera& cam = cameras_[camera];
    const RayGrid grid(cam, vis_.stride, vis_.dilate);
    const size_t n = grid.count();
    // Rays to keep hits of: first every ray in a footprint at any depth (known before the
    // trace), then those whose static ray reaches the proxy's depth (known after it).
    const bool keep = cache_budget_ > 0 && footprints_ && keep_at_answers_ && !boxes.empty();
    std::unique_ptr<std::atomic<uint8_t>[]> in_footprint;
    std::vector<std::vector<KeyedHit>> row_keyed;
    std::vector<std::vector<uint32_t>> row_keyed_ends;  // per row: end offset in row_keyed of each ray
    if (keep) {
      in_footprint.reset(new std::atomic<uint8_t>[n]);
      const std::vector<float> anywhere(n, std::numeric_limits<float>::infinity());
      mark_dynamic_footprints(boxes, grid, anywhere.data(), in_footprint.get(), swept);
      row_keyed.resize(size_t(grid.height));
      row_keyed_ends.resize(size_t(grid.height));
    }
    // Rows are traced in parallel into per-row lists, then packed.
    std::vector<std::vector<uint32_t>> row_ids(size_t(grid.height)), row_counts(size_t(grid.height));
    pc.ray_end.assign(n, 0.0f);
    tbb::enumerable_thread_specific<RayScratch> scratch;
    tbb::parallel_for(tbb::blocked_range<int>(0, grid.height, 1), [&](const tbb::blocked_range<int>& r) {
      RayScratch& s = scratch.local();
      std::vector<KeyedHit> keyed;
      for (int j = r.begin(); j < r.end(); ++j) {
        auto& ids = row_ids[size_t(j)];
        auto& counts = row_counts[size_t(j)];
        counts.resize(size_t(grid.width));
        if (keep) row_keyed_ends[size_t(j)].assign(size_t(grid.width), 0);
        for (int i = 0; i < grid.width; ++i) {
          const size_t ray = size_t(j) * size_t(grid.width) + size_t(i);
          const bool wanted = keep && in_footprint[ray].load(std::memory_order_relaxed);
          s.hits.clear();
          keyed.clear();
          const RayOutcome o =
              tracer->trace(grid.origin, grid.direction(i, j), TraceLayers::StaticOnly, s.hits, grid.match, wanted ? &keyed : nullptr);
          ++s.rays;
          s.hits_count += s.hits.size();
          const size_t before = ids.size();
          observed_ids(s.hits, vis_.min_weight, ids);
          counts[size_t(i)] = uint32_t(ids.size() - before);
          pc.ray_end[ray] = o.end_key;
          if (keep) {
            row_keyed[size_t(j)].insert(row_keyed[size_t(j)].end(), keyed.begin(), keyed.end());
            row_keyed_ends[size_t(j)][size_t(i)] = uint32_t(row_keyed[size_t(j)].size());
          }
        }
      }
    });
    merge_ids(scratch, &summary.counters);
    if (keep) {
      mark_dynamic_footprints(boxes, grid, pc.ray_end.data(), in_footprint.get(), swept);
      pc.kept.assign(n, {});
      for (int j = 0; j < grid.height; ++j) {
        const std::vector<KeyedHit>& hits = row_keyed[size_t(j)];
        for (int i = 0; i < grid.width; ++i) {
          const size_t ray = size_t(j) * size_t(grid.width) + size_t(i);
          const uint32_t first = i == 0 ? 0 : row_keyed_ends[size_t(j)][size_t(i - 1)], last = row_keyed_ends[size_t(j)][size_t(i)];
          // A ray with no static hit is kept too (empty): the frames then trace only the
          // dynamic layer on it, without probing it and tracing the static one first.
          if (!in_footprint[ray].load(std::memory_order_relaxed)) continue;
          if (!keep_hits(pc.kept[ray], hits.data() + first, last - first)) continue;
          ++summary.cached_static_rays;
          ++summary.cached_at_static_answers;
          summary.cached_static_hits += last - first;
        }
        std::vector<KeyedHit>().swap(row_keyed[size_t(j)]);
      }
    }
    pc.ray_offsets.assign(n + 1, 0);
    for (int j = 0; j < grid.height; ++j)
      for (int i = 0; i < grid.width; ++i) {
        const size_t ray = size_t(j) * size_t(grid.width) + size_t(i);
        pc.ray_offsets[ray + 1] = pc.ray_offsets[ray] + row_counts[size_t(j)][size_t(i)];
      }
    pc.ray_slots.reserve(pc.ray_offsets[n]);
    for (auto& v : row_ids) {
      pc.ray_slots.insert(pc.ray_slots.end(), v.begin(), v.end());
      std::vector<uint32_t>().swap(v);
    }
    // visible set with the number of rays that observe each Gaussian
    std::vector<uint32_t> sorted = pc.ray_slots;
    std::sort(sorted.begin(), sorted.end());
    for (size_t k = 0; k < sorted.size();) {
      size_t e = k;
      while (e < sorted.size() && sorted[e] == sorted[k]) ++e;
      pc.visible.push_back(sorted[k]);
      pc.ray_refs.push_back(uint32_t(e - k));
      k = e;
    }
    // Ids to slots of `visible` (marks_ lends itself as the map and is left zero), so the
    // frames find a Gaussian's ray count without a search; membership as a bitmap.
    for (size_t k = 0; k < pc.visible.size(); ++k) marks_[pc.visible[k]] = uint32_t(k);
    for (uint32_t& id : pc.ray_slots) id = marks_[id];
    for (uint32_t g : pc.visible) marks_[g] = 0;
    pc.mark_visible(pc.visible, cloud_.size());
    pc.ready = true;
    summary.seconds_static += seconds_since(start);
  }

  /// Keeps a ray's static hits in this thread's arena if the budget allows; false otherwise.
  bool keep_hits(PoseCache::KeptHits& slot, const KeyedHit* hits, size_t n) {
    const size_t bytes = n * sizeof(KeyedHit);
    if (cache_bytes_.fetch_add(bytes) + bytes > cache_budget_) {
      cache_bytes_.fetch_sub(bytes);
      return false;
    }
    slot = {arenas_.local().keep(hits, n), uint32_t(n)};
    return true;
  }

  const PoseCache& pose(uint32_t camera) const { return poses_[pose_of_camera_[camera]]; }
  PoseCache& pose(uint32_t camera) { return poses_[pose_of_camera_[camera]]; }
  uint32_t pose_index(uint32_t camera) const { return pose_of_camera_[camera]; }
  size_t pose_count() const { return pose_count_; }

  /// Frustum: the dynamic Gaussians in each view's frustum are the whole change (every view's
  /// rule over one reading of the moving Gaussians).
  std::vector<ViewDelta> frustum_deltas(const FrameGaussians& frame, const std::vector<uint32_t>& views) {
    std::vector<std::vector<uint32_t>> added = frustum_visible(frame, cameras_, views, &cloud_.dynamic_ids);
    std::vector<ViewDelta> d(views.size());
    for (size_t k = 0; k < views.size(); ++k) d[k].added = std::move(added[k]);
    return d;
  }

  /// Raytraced: re-trace only the rays whose path (up to where the static ray ended) meets
  /// a dynamic proxy; static Gaussians those rays no longer observe may leave the set.
  /// `boxes`: the dynamic proxies at this time (GaussianTracer::dynamic_boxes); only rays in
  /// their screen footprints are probed.
  ViewDelta raytraced_delta(const GaussianTracer& tracer, const std::vector<ProxyBox>& boxes, uint32_t camera) {
    PoseCache& pc = pose(camera);
    const RayGrid grid(cameras_[camera], vis_.stride, vis_.dilate);
    summary.incremental_rays += grid.count();
    if (grid.count() > ray_marks_size_) {
      ray_marks_.reset(new std::atomic<uint8_t>[grid.count()]);
      ray_marks_size_ = grid.count();
    }
    if (footprints_) {
      summary.footprint_rays += mark_dynamic_footprints(boxes, grid, pc.ray_end.data(), ray_marks_.get());
    } else {
      for (size_t r = 0; r < grid.count(); ++r) ray_marks_[r].store(1, std::memory_order_relaxed);
      summary.footprint_rays += grid.count();
    }
    if (cache_budget_ > 0 && pc.kept.size() != grid.count()) pc.kept.assign(grid.count(), {});
    struct Local {
      RayScratch rs;
      std::vector<uint32_t> rays;  // re-traced ray indices
      std::vector<KeyedHit> keyed;
      uint64_t cached_rays = 0, cached_hits = 0;
    };
    tbb::enumerable_thread_specific<Local> local;
    tbb::parallel_for(tbb::blocked_range<int>(0, grid.height, 1), [&](const tbb::blocked_range<int>& r) {
      Local& l = local.local();
      for (int j = r.begin(); j < r.end(); ++j)
        for (int i = 0; i < grid.width; ++i) {
          const size_t ray = size_t(j) * size_t(grid.width) + size_t(i);
          if (!ray_marks_[ray].load(std::memory_order_relaxed)) continue;
          const Vec3f dir = grid.direction(i, j);
          ++l.rs.probes;
          l.rs.hits.clear();
          if (cache_budget_ > 0 && pc.kept[ray].hits) {
            // With the static hits at hand the trace over them is the probe: a ray that no
            // dynamic proxy entered has its static answer.
            const RayOutcome o = tracer.trace_over(grid.origin, dir, pc.kept[ray].hits, pc.kept[ray].count, l.rs.hits, grid.match);
            if (o.traversal_entries == 0) continue;
          } else {
            if (!tracer.meets_dynamic(grid.origin, dir, pc.ray_end[ray], grid.match)) continue;
            if (cache_budget_ == 0) {
              tracer.trace(grid.origin, dir, TraceLayers::All, l.rs.hits, grid.match);
            } else {
              // The static layer alone, kept while the budget lasts (each ray is handled by
              // one thread per frame: its slot needs no lock), then the dynamic layer over it.
              l.keyed.clear();
              tracer.trace(grid.origin, dir, TraceLayers::StaticOnly, l.rs.hits, grid.match, &l.keyed);
              l.rs.hits.clear();
              if (keep_hits(pc.kept[ray], l.keyed.data(), l.keyed.size())) {
                ++l.cached_rays;
                l.cached_hits += l.keyed.size();
              }
              tracer.trace_over(grid.origin, dir, l.keyed.data(), l.keyed.size(), l.rs.hits, grid.match);
            }
          }
          l.rays.push_back(uint32_t(ray));
          ++l.rs.rays;
          l.rs.hits_count += l.rs.hits.size();
          observed_ids(l.rs.hits, vis_.min_weight, l.rs.ids);
        }
    });
    std::vector<uint32_t> retraced;
    std::vector<std::vector<uint32_t>*> id_lists;
    for (Local& l : local) {
      retraced.insert(retraced.end(), l.rays.begin(), l.rays.end());
      summary.counters.probes += l.rs.probes;
      summary.counters.rays += l.rs.rays;
      summary.counters.hits += l.rs.hits_count;
      summary.cached_static_rays += l.cached_rays;
      summary.cached_static_hits += l.cached_hits;
      id_lists.push_back(&l.rs.ids);
    }
    summary.retraced_rays += retraced.size();

    ViewDelta d;
    // Observed by re-traced rays (each once; the order of `added` does not matter).
    std::vector<uint32_t> now;
    for (const std::vector<uint32_t>* ids : id_lists)
      for (uint32_t g : *ids)
        if (!(marks_[g] & kObservedAgain)) {
          marks_[g] |= kObservedAgain;
          now.push_back(g);
        }
    // Rays lost per static Gaussian; it leaves the set when it loses all its rays and no
    // re-traced ray observes it again.
    std::vector<uint32_t> touched;  // slots of pc.visible
    for (uint32_t ray : retraced)
      for (uint64_t r = pc.ray_offsets[ray]; r < pc.ray_offsets[ray + 1]; ++r) {
        const uint32_t k = pc.ray_slots[r];
        if ((marks_[pc.visible[k]]++ & ~kObservedAgain) == 0) touched.push_back(k);
      }
    for (uint32_t k : touched) {
      const uint32_t g = pc.visible[k];
      if (!(marks_[g] & kObservedAgain) && marks_[g] == pc.ray_refs[k]) d.removed.push_back(g);
    }
    for (uint32_t g : now)
      if (!(pc.visible_bits[g / 64] >> (g % 64) & 1)) d.added.push_back(g);
    for (uint32_t k : touched) marks_[pc.visible[k]] = 0;
    for (uint32_t g : now) marks_[g] = 0;
    return d;
  }

 private:
  static constexpr uint32_t kObservedAgain = 0x80000000u;

  const GaussianCloud& cloud_;
  const std::vector<Camera>& cameras_;
  VisibilityOptions vis_;
  bool footprints_ = true;
  size_t cache_budget_ = 0;                  // bytes of kept static hits allowed
  bool keep_at_answers_ = true;              // keep the first frame's footprint rays' hits at the static answers
  std::atomic<size_t> cache_bytes_{0};       // bytes kept so far
  tbb::enumerable_thread_specific<HitArena> arenas_;  // the cached static hits of every pose
  std::vector<uint32_t> pose_of_camera_;
  size_t pose_count_ = 0;
  std::vector<PoseCache> poses_;
  std::vector<uint32_t> marks_;  // per Gaussian: rays lost (low bits) | kObservedAgain
  std::unique_ptr<std::atomic<uint8_t>[]> ray_marks_;  // per ray of the view: in a dynamic footprint
  size_t ray_marks_size_ = 0;
};

}  // namespace

ObservationSummary observe(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                           double frame_step, const ObservationOptions& options,
                           const std::function<void(const FrameObservation&)>& sink, Progress& progress) {
  const auto start_total = Clock::now();
  const VisibilityOptions& vis = options.visibility;
  FILLGS_CHECK(vis.stride >= 1);
  FILLGS_CHECK(!times.empty());
  for (size_t f = 0; f < times.size(); ++f) {
    if (!(times[f] >= 0.0 && times[f] <= 1.0)) throw_error("observe: time ", times[f], " is outside [0, 1]");
    if (f > 0 && !(times[f] > times[f - 1])) throw_error("observe: times must be strictly ascending (", times[f - 1], ", ", times[f], ")");
  }
  const size_t N = cloud.size();
  std::vector<size_t> frames = options.frames;
  if (frames.empty()) {
    frames.resize(times.size());
    std::iota(frames.begin(), frames.end(), size_t(0));
  }
  for (size_t k = 0; k < frames.size(); ++k)
    if (frames[k] >= times.size() || (k > 0 && frames[k] <= frames[k - 1]))
      throw_error("observe: the frames to evaluate must be strictly ascending indices below ", times.size());
  auto views = views_per_frame(cameras, times, frame_step);
  size_t max_views = 0;
  for (const auto& v : views) max_views = std::max(max_views, v.size());
  if (max_views > 65535) throw_error("observe: ", max_views, " views at one time; counts are stored in 16 bits");
  if (!options.cameras.empty()) {
    FILLGS_CHECK(options.cameras.size() == cameras.size());
    for (auto& v : views) v.erase(std::remove_if(v.begin(), v.end(), [&](uint32_t c) { return !options.cameras[c]; }), v.end());
  }

  ObservationRun run(cloud, cameras, options);
  ObservationSummary& summary = run.summary;
  summary.gaussians = N;
  summary.static_count = cloud.static_count();
  summary.dynamic_count = cloud.dynamic_count();
  summary.frames = int(frames.size());
  summary.camera_poses = run.pose_count();
  summary.max_views_per_frame = uint16_t(max_views);

  FrameSampler sampler(cloud);
  const FrameGaussians* frame = &sampler.at(times[frames[0]]);
  std::unique_ptr<GaussianTracer> tracer;
  if (vis.mode == VisibilityMode::Raytraced) {
    TracerOptions to;
    to.min_transmittance = vis.min_transmittance;
    if (vis.dilate)  // every ray leaves one of these cameras: each proxy padded for its own depth
      for (const Camera& c : cameras) {
        const RasterMatch m = camera_raster_match(c);
        const Vec3d centre = c.centre();
        TracerOptions::DilationView v;
        for (int a = 0; a < 3; ++a) {
          v.centre[a] = float(centre[a]);
          v.axis[a] = m.axis[a];
        }
        v.sigma_per_depth = std::sqrt(m.variance_per_depth2);
        to.dilation_views.push_back(v);
      }
    tracer = std::make_unique<GaussianTracer>(*frame, cloud.dynamic_ids, to);
    summary.seconds_build = tracer->build_seconds();
  }
  const bool incremental = options.incremental && vis.mode != VisibilityMode::Exact;

  std::vector<uint16_t> counts(N, 0), base(N, 0);
  std::vector<uint32_t> base_poses;  // sorted pose indices the base was summed for
  bool have_base = false;
  std::vector<float> speed, deficiency;
  std::vector<ProxyBox> boxes;
  // The static answers keep the hits of the rays in the dynamic proxies' footprints: swept
  // over every frame of this run, or (off) those of the frame that answers.
  std::vector<ProxyBox> swept;
  // The sweep reads every frame ahead of the walk: not where the motion is to be read once.
  const bool sweep = incremental && tracer && options.keep_at_static_answers && options.sweep_static_answers && options.footprints &&
                     options.static_hit_cache_bytes > 0 && !(cloud.source && cloud.source->one_pass());
  progress.start("observe", frames.size());
  for (size_t f : frames) {
    if (f != frames[0]) {
      frame = &sampler.at(times[f]);
      if (tracer) {
        tracer->refit_dynamic(*frame);
        summary.seconds_refit += tracer->last_refit_seconds();
      }
    }
    const auto start_frame = Clock::now();
    FrameObservation fo;
    fo.frame = int(f);
    fo.time = times[f];
    fo.views = views[f];
    if (incremental) {
      if (tracer) tracer->dynamic_boxes(boxes);
      if (sweep && f == frames[0]) {  // part of the static answers (timed with them)
        const auto start_sweep = Clock::now();
        std::vector<double> run_times;
        for (size_t k : frames) run_times.push_back(times[k]);
        swept = swept_dynamic_boxes(cloud, *tracer, run_times);
        summary.seconds_static += seconds_since(start_sweep);
      }
      run.static_answers(*frame, tracer.get(), swept.empty() ? boxes : swept, views[f], !swept.empty());
      std::vector<uint32_t> poses;
      for (uint32_t c : views[f]) poses.push_back(run.pose_index(c));
      std::sort(poses.begin(), poses.end());
      const bool rebuilt = !have_base || poses != base_poses;
      if (rebuilt) {
        std::fill(base.begin(), base.end(), uint16_t(0));
        for (uint32_t c : views[f])
          run.pose(c).for_each_visible([&](uint32_t g) { ++base[g]; });
        base_poses = poses;
        have_base = true;
      }
      if (tracer || rebuilt) {
        counts = base;
      } else {  // frustum: the changes are the moving Gaussians' alone, so only their rows are reset
        for (uint32_t g : cloud.dynamic_ids) counts[g] = base[g];
      }
      std::vector<ViewDelta> frustum;
      if (!tracer) frustum = run.frustum_deltas(*frame, views[f]);
      for (size_t k = 0; k < views[f].size(); ++k) {
        const uint32_t c = views[f][k];
        const ViewDelta d = tracer ? run.raytraced_delta(*tracer, boxes, c) : std::move(frustum[k]);
        for (uint32_t g : d.removed) --counts[g];
        for (uint32_t g : d.added) ++counts[g];
        fo.visible_per_view.push_back(uint32_t(run.pose(c).visible_count - d.removed.size() + d.added.size()));
      }
    } else {
      std::fill(counts.begin(), counts.end(), uint16_t(0));
      std::vector<std::vector<uint32_t>> frustum;  // every view over one reading of the frame
      if (vis.mode == VisibilityMode::Frustum) frustum = frustum_visible(*frame, cameras, views[f], nullptr);
      for (size_t k = 0; k < views[f].size(); ++k) {
        const uint32_t c = views[f][k];
        std::vector<uint32_t> ids;
        switch (vis.mode) {
          case VisibilityMode::Frustum: ids = std::move(frustum[k]); break;
          case VisibilityMode::Exact: ids = exact_visible(*frame, cameras[c], vis.min_weight); break;
          case VisibilityMode::Raytraced:
            ids = raytraced_visible(*tracer, RayGrid(cameras[c], vis.stride, vis.dilate), vis.min_weight, &summary.counters);
            break;
        }
        for (uint32_t g : ids) ++counts[g];
        fo.visible_per_view.push_back(uint32_t(ids.size()));
      }
    }
    summary.views += views[f].size();
    summary.seconds_frames += seconds_since(start_frame);

    const auto start_speed = Clock::now();
    dynamic_speeds(cloud, times[f], frame_step, speed);
    deficiency.resize(speed.size());
    for (size_t j = 0; j < speed.size(); ++j) deficiency[j] = speed[j] / (1.0f + float(counts[cloud.dynamic_ids[j]]));
    summary.seconds_speed += seconds_since(start_speed);

    const auto start_sink = Clock::now();
    fo.counts = counts.data();
    fo.dynamic_speed = speed.data();
    fo.dynamic_deficiency = deficiency.data();
    sink(fo);
    summary.seconds_sink += seconds_since(start_sink);
    progress.advance();
  }
  progress.finish();
  summary.seconds_total = seconds_since(start_total);
  return summary;
}

ObservationTables observation_tables(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times,
                                     double frame_step, const ObservationOptions& options, ObservationSummary* summary,
                                     Progress& progress) {
  ObservationTables tables;
  tables.gaussians = cloud.size();
  tables.dynamic_ids = cloud.dynamic_ids;
  const size_t N = cloud.size(), M = cloud.dynamic_count();
  tables.counts.reserve(times.size() * N);
  tables.dynamic_speed.reserve(times.size() * M);
  tables.dynamic_deficiency.reserve(times.size() * M);
  const ObservationSummary s = observe(
      cloud, cameras, times, frame_step, options,
      [&](const FrameObservation& fo) {
        tables.times.push_back(fo.time);
        tables.counts.insert(tables.counts.end(), fo.counts, fo.counts + N);
        tables.dynamic_speed.insert(tables.dynamic_speed.end(), fo.dynamic_speed, fo.dynamic_speed + M);
        tables.dynamic_deficiency.insert(tables.dynamic_deficiency.end(), fo.dynamic_deficiency, fo.dynamic_deficiency + M);
        tables.visible_per_view.push_back(fo.visible_per_view);
      },
      progress);
  if (summary) *summary = s;
  return tables;
}

std::vector<float> ObservationTables::deficiency_row(int f) const {
  FILLGS_CHECK(f >= 0 && f < frames());
  std::vector<float> row(gaussians, 0.0f);
  const size_t M = dynamic_ids.size();
  for (size_t j = 0; j < M; ++j) row[dynamic_ids[j]] = dynamic_deficiency[size_t(f) * M + j];
  return row;
}

float ObservationTables::deficiency_scale(double quantile) const {
  std::vector<float> positive;
  for (float d : dynamic_deficiency)
    if (d > 0.0f) positive.push_back(d);
  if (positive.empty()) return 1.0f;
  const size_t k = std::min(positive.size() - 1, size_t(std::clamp(quantile, 0.0, 1.0) * double(positive.size() - 1) + 0.5));
  std::nth_element(positive.begin(), positive.begin() + std::ptrdiff_t(k), positive.end());
  return positive[k] > 0.0f ? positive[k] : 1.0f;
}

Bounds stride_bounds() { return at_least(1); }
Bounds tau_bounds() { return within_open(0, 1); }
Bounds hit_cache_mb_bounds() { return from_below(0, 1e9); }

}  // namespace fillgs
