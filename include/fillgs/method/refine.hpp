#pragma once
// Spatiotemporal patches for a generative refiner (the paper, Sec. 3.4 and Appendix A) and the refiners fillgs
// drives: `external` (any program, through a folder protocol), `oracle` (synthetic scenes:
// the ground truth at the virtual view where the training cameras support it, with optional
// injected generation artifacts), `rig` (real captures: the photograph of the nearest pool
// camera of the rig, at its real pose) and `identity` (the render itself).
//
// A patch is 3 consecutive frames × 4 views of one trajectory: the observed start image,
// then the trajectory's 3 virtual poses rendered by the current model. Order: serpentine
// over views per frame (view k for even frame index, 3 − k for odd), frames increasing, so
// neighbours in the sequence are neighbours in space or time.
//
// The folder protocol (what an external refiner sees):
//   <in>/patch.json   {"trajectory", "frames", "views", "images": [{"file", "order",
//                      "frame", "time", "view", "observed", "camera": {...}}]}
//   <in>/<file>       8-bit PNG per image (observed ones are the real photographs)
// The refiner writes <out>/<file> for every image with "observed": false, same size; it
// may also copy the observed ones (ignored). Extra files are ignored. fillgs checks that
// every expected image came back with the right size, applies a timeout, and reports which
// patch failed while keeping the others.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/method/select.hpp"

namespace fillgs {

struct PatchImage {
  std::string file;     ///< "f<frame:04d>_v<view>.png"
  Camera camera;        ///< with the frame's time
  int frame = 0;
  int view = 0;         ///< 0 = the start camera, 1..3 = the trajectory's poses
  bool observed = false;  ///< a photograph of the start camera (view 0 where the video holds one)
  int order = 0;        ///< position in the serpentine sequence
};

struct Patch {
  int trajectory = 0;
  std::string name;                ///< folder name, "patch_<trajectory:03d>" (prefix configurable)
  std::vector<PatchImage> images;  ///< in serpentine order
  int observed_view = -1;          ///< index into the observed views of the start (frame of the trajectory)
};

/// The patch of a trajectory: its patch frames × (the start's rig camera, then each pose).
/// The observed image at each patch frame is the start view's pose at that frame, looked up
/// in `views` (the ones selection ran on). Where the start camera has no image at a patch
/// frame (a monocular video: one camera per frame) view 0 of that frame is a virtual view
/// at the start camera's pose (not observed: rendered and refined). Throws when the start
/// view itself is missing at the trajectory's own frame.
Patch make_patch(const Trajectory& trajectory, const std::vector<ObservedView>& views, const std::string& name);

/// Writes `dir`/patch.json and every image: observed ones from `observed_image(view index)`,
/// virtual ones from `render(camera)` (float RGB [H][W][3]). Files are written atomically.
void write_patch(const std::string& dir, const Patch& patch, const std::vector<ObservedView>& views,
                 const std::function<std::vector<float>(size_t)>& observed_image,
                 const std::function<std::vector<float>(const Camera&)>& render);

/// Reads a patch folder's patch.json back (write_patch's inverse; observed_view is left −1,
/// the observed images are the ones marked so). Throws naming the file and the image.
Patch read_patch(const std::string& dir);

/// Oracle generation artifacts (synthetic scenes only), each drawn per image from the seed:
/// a blurred region, a colour drift over a region, hallucinated blobs and a shifted region.
/// `strength` 0 gives the clean ground truth; 1 is strong (blur σ up to 5 px, colour ±30%,
/// blobs up to 12% of the width, shifts up to 6 px).
struct ArtifactOptions {
  double strength = 0.0;
  uint64_t seed = 1;
  double region_fraction = 0.18;  ///< radius of an artifact region as a fraction of the width
};
/// A change counts as an artifact above this (≈ 8/255 in some channel): fainter changes (the
/// soft rims of the regions) are below what any check of agreement could see.
constexpr float kArtifactVisible = 0.03f;
/// The model's render where a refiner cannot know the content, degraded as diffusion models
/// fail there: blurred (σ 2 + 3a px, or `blur_sigma` px when it is ≥ 0), colours drifted
/// (±20a %), one hallucinated blob, a = `strength`, every draw from (seed, key).
void degrade_unsupported(Image& image, double strength, uint64_t seed, uint64_t key, double blur_sigma = -1);
/// The reference-conditioned refiners' fill where they cannot know the content: the render
/// degraded as above (`strength`, `blur_sigma`), blended by `hallucination` with plausible, wrong content —
/// the reference image translated by 15–35% of the width along a seeded direction
/// (reflected at the borders): the scene's own texture in the wrong place. Every draw from
/// (seed, key); the images must be the same size.
Image reference_fill(const Image& render, const Image& reference, double strength, double blur_sigma, double hallucination, uint64_t seed,
                     uint64_t key);
/// Applies artifacts to `image` in place; returns the artifact mask ([H][W], 1 where the
/// image changed by more than kArtifactVisible in some channel).
std::vector<uint8_t> inject_artifacts(Image& image, const ArtifactOptions& options, uint64_t key);

/// What a refiner made of one virtual view, where it is not "an image at the view's own pose".
struct RefinedPose {
  bool dropped = false;          ///< no image: the view is left out (and counted)
  std::optional<Camera> camera;  ///< the image shows this pose instead of the virtual one
};

class Refiner {
 public:
  virtual ~Refiner() = default;
  virtual std::string name() const = 0;
  /// Reads the patch in `in_dir`, writes refined images of the virtual views into `out_dir`
  /// (every one that pose() does not drop). Throws on failure.
  virtual void refine(const std::string& in_dir, const std::string& out_dir, const Patch& patch) = 0;
  /// The pose of the image refine() returns for a virtual view; the default: its own.
  virtual RefinedPose pose(const PatchImage& /*image*/) const { return {}; }
  /// Called before a round's patches are refined, with the model that rendered them (a
  /// refiner that reads the render's geometry keeps it until the next call).
  virtual void begin_round(const GaussianCloud& /*current*/, const Vec3f& /*background*/) {}
};

/// Copies the rendered images.
std::unique_ptr<Refiner> make_identity_refiner();
/// What the oracle may restore (the premise of the paper's Sec. 3.4: a generative model conditioned on the observed
/// views restores what they support and hallucinates the rest).
///  * Full: the ground truth everywhere (the earlier behaviour; rewards looking away from
///    the capture).
///  * Observed: the ground truth only where the surface is seen by some training camera —
///    a static Gaussian seen at any frame, a moving one seen within ±window frames of the
///    view's frame (exact visibility of the truth, α·T ≥ 1/255, through the visibility
///    engine; a pixel is supported when such surfaces make up at least half of its rendered
///    opacity); elsewhere the patch's own render (the
///    current model) degraded as diffusion models fail there: blurred (σ 2 + 3a px), its
///    colours drifted (±20a %) and a hallucinated blob, a = the artifact strength (0.5 when
///    it is 0), seeded per image. The artifacts of ArtifactOptions go on top everywhere.
enum class OracleSupport { Full, Observed };
FILLGS_ENUM_NAMES(OracleSupport, "oracle support", {OracleSupport::Full, "full"}, {OracleSupport::Observed, "observed"});

struct OracleOptions {
  ArtifactOptions artifacts;
  OracleSupport support = OracleSupport::Full;
  std::vector<Camera> observers;  ///< Observed: the training cameras (with times, or a rig without)
  int frames = 0;                 ///< Observed: the video's frame count
  int window = 2;                 ///< Observed: ± frames within which a moving surface counts as seen
  Vec3f background = Vec3f::Zero();
};

/// One virtual view a reference-conditioned refiner made, measured: what the calibration
/// plots (refined-vs-truth PSNR against the angle to the reference).
struct RefinedViewRecord {
  std::string file;               ///< <patch>/<file>
  int frame = 0;
  double parallax_degrees = 0;    ///< median over the view's surface pixels of the angle between the rays to the two camera centres
  double axis_degrees = 0;        ///< angle between the view's and the reference's optical axes
  double baseline = 0;            ///< distance between the camera centres (world units)
  double support = 0;             ///< share of the pixels whose surface the reference saw (warp: that the warp reached)
  double confidence = 0;          ///< mean blending confidence
  double psnr_refined = 0;        ///< refined image against the truth (NaN without one)
  double psnr_seen = 0;           ///< the same over the pixels whose surface the reference saw (NaN without one or without such pixels)
  double psnr_render = 0;         ///< the render it was given against the truth (NaN without one)
};

/// Mean support of the virtual views an oracle refined (1 for Full), and, for the
/// reference-conditioned refiners, every view's record.
struct SupportStats {
  double support_sum = 0;
  size_t pixels = 0;
  std::vector<RefinedViewRecord> views;
  double share() const { return pixels ? support_sum / double(pixels) : 0.0; }
};

/// A refiner conditioned on one observed view, as the published generative refiners are
/// (3DGS-Enhancer, ViewCrafter, Difix3D+, the video diffusion of ExploreGS and of the
/// paper): it sees the rendered patch and the patch's own reference observation at each
/// frame (the start camera's image; a frame without one takes the patch's nearest frame
/// that has one) and nothing else. Per pixel of a virtual view, with θ the parallax angle
/// between the rays from the two camera centres to the surface point:
///   refined = c · (reference content, misplaced by shift·θ px and blurred by blur·θ px)
///           + (1 − c) · (the render, degraded where the refiner cannot know: colours
///             drifted, a hallucinated blob, blurred by `fill_blur`, blended by
///             `hallucination` with the reference's texture in the wrong place: reference_fill),
///   c = seen · exp(−θ / θ0), θ0 halved on moving content, whose content also drifts twice
///   as far; a per-frame gain flickers by ±flicker·(1 − exp(−θ̄ / θ0)); the ArtifactOptions
///   go on top at strength·(1 − exp(−θ̄ / θ0)) (θ̄: the view's median parallax).
/// Every departure from the reference vanishes at θ = 0: a virtual view at the reference's
/// pose gets the reference back. Two forms:
///  * `reference` (synthetic scenes): the content is the ground truth rendered at the
///    virtual view; "seen" where the reference camera saw the surface at that frame (exact
///    visibility of the truth, α·T ≥ 1/255, at least half of the pixel's rendered opacity)
///    and where the render places that surface — it cannot create geometry the render
///    lacks: "seen" is multiplied by exp(−((z_render − z_truth) / (tolerance · z_truth))²),
///    0 where the render (the model of the round, begin_round) is empty; θ from the
///    truth's depth. No truth reaches a pixel the reference did not see.
///  * `warp` (any data, real video included): the reference photograph warped into the
///    virtual view through the *render's* depth (the model of the round, begin_round),
///    occlusion-checked against the render's depth at the reference; "seen" where the warp
///    lands inside the reference and passes the check; θ from the render's depth.
/// The defaults are the benchmark's calibration (bench_reference_options;
/// bench/results/README.md, "Calibrating the refiner"): θ0, the fill's blur and its
/// hallucination were set from the unweighted random views against the control, before
/// any other strategy ran with the refiner; shift, blur, flicker and placement were fixed
/// before any run.
struct ReferenceOptions {
  double angle_scale_degrees = 10.0;  ///< θ0: confidence exp(−θ/θ0)
  double shift_per_degree = 0.001;    ///< texture misplacement, fraction of the image width per degree of parallax
  double blur_per_degree = 0.0005;    ///< blur σ, fraction of the width per degree
  double flicker = 0.05;              ///< per-frame gain jitter at full distance
  ArtifactOptions artifacts;          ///< injected on top (scaled as above); artifacts.seed seeds every draw
  double fill_strength = 0.5;         ///< degradation of the render where c < 1 (the oracle's fill)
  double hallucination = 0.0;         ///< share of misplaced reference texture in the fill (reference_fill)
  double fill_blur = 0.0;             ///< the fill's blur σ, fraction of the width (the oracle's fill: 0.0219, 3.5 px at 160)
  Vec3f background = Vec3f::Zero();
  double depth_tolerance = 0.05;      ///< warp: occlusion test |z − z_reference| ≤ this × z
  double placement_tolerance = 0.1;   ///< reference: the render places a surface where its depth is within this × the truth's (soft)
};
/// The synthetic form: ground truth `truth` seen by the reference.
std::unique_ptr<Refiner> make_reference_refiner(const GaussianCloud& truth, const ReferenceOptions& options, SupportStats* stats = nullptr);
/// The real-data form: the reference photograph warped through the render's depth. With
/// `truth` (synthetic scenes) its records carry PSNRs against it.
std::unique_ptr<Refiner> make_warp_refiner(const ReferenceOptions& options, SupportStats* stats = nullptr, const GaussianCloud* truth = nullptr);
/// The observed image a reference-conditioned refiner conditions a virtual view at `frame`
/// on: the patch's observed image at that frame, or at the nearest frame that has one.
/// Throws when the patch has none.
const PatchImage& patch_reference(const Patch& patch, int frame);
/// The parallax angle (degrees) at world point `p` between the rays from the centres of `a` and `b`.
double parallax_degrees(const Vec3d& p, const Vec3d& centre_a, const Vec3d& centre_b);

/// Where each pixel of `camera` (expected depth `depth`, 0 = none) lands in `other`
/// (expected depth `other_depth`): pixel-index coordinates (u, v) and the world point, or
/// invalid where it has no depth, falls outside, or is occluded there
/// (|z − z_other| > tolerance · z, nearest pixel).
struct WarpedPixel {
  bool valid = false;
  double u = 0, v = 0;
  Vec3d world = Vec3d::Zero();
};
std::vector<WarpedPixel> warp_pixels(const Camera& camera, const std::vector<float>& depth, const Camera& other,
                                     const std::vector<float>& other_depth, double tolerance);

/// The support of every Gaussian of `truth` at every frame ([F][N], 1 = seen), as the
/// Observed oracle uses it: exact visibility from `observers`, static Gaussians at any frame,
/// moving ones within ±window frames.
std::vector<uint8_t> oracle_support_table(const GaussianCloud& truth, const std::vector<Camera>& observers, int frames, int window);

/// Renders `truth` at each virtual view (its time), limits it to the supported pixels (see
/// OracleSupport; the support mask goes to `out_dir`/support/<file>), applies artifacts
/// when strength > 0 and writes the artifact masks to `out_dir`/masks/<file>. `stats`, when
/// given, accumulates the support of every refined pixel.
std::unique_ptr<Refiner> make_oracle_refiner(const GaussianCloud& truth, const OracleOptions& options, SupportStats* stats = nullptr);
/// The full-support oracle (ground truth everywhere).
std::unique_ptr<Refiner> make_oracle_refiner(const GaussianCloud& truth, const ArtifactOptions& artifacts, const Vec3f& background);
/// The real-capture refiner (`--refiner rig`): the refined image of a virtual view is the
/// real photograph of the nearest *pool* camera — a camera of the rig neither trained on nor
/// held out — at the view's frame, and that camera's real pose replaces the virtual one.
/// Nearest: the smallest distance between camera centres among the pool cameras within
/// `max_distance` (world units) whose optical axis is within `max_angle_degrees` of the
/// view's (ties: the smaller angle, then the earlier camera). A virtual view with no pool
/// camera in tolerance at its frame is dropped (RefineReport::dropped). No generative model
/// is involved: the comparison on real data of which camera-times help most.
struct RigOptions {
  double max_distance = 1.0;
  double max_angle_degrees = 30.0;
};
struct RigPool {
  std::vector<Camera> cameras;  ///< every pool view, with its time (frame f at f / (frame_count − 1))
  std::function<std::vector<float>(size_t)> image;  ///< float RGB [H][W][3] of view i
  int frame_count = 1;
};
/// Index into `pool` of the photograph for `view` (its time picks the frame), or −1.
int nearest_pool_view(const RigPool& pool, const Camera& view, const RigOptions& options);
std::unique_ptr<Refiner> make_rig_refiner(RigPool pool, const RigOptions& options);

/// Runs the program `command` names, without a shell: the template is split into words
/// (split_command, base/process.hpp: quotes as in a shell, shell operators refused) and
/// {in} and {out} in any word are replaced by the folders, so a path is never read as
/// syntax. Killed with its process group after `timeout_seconds`; its output goes to
/// `out_dir`/refiner.log. A template without {in} and {out}, or with shell syntax, throws.
std::unique_ptr<Refiner> make_external_refiner(const std::string& command, double timeout_seconds);

/// One refined virtual view, read back.
struct RefinedImage {
  int patch = 0;
  PatchImage image;
  Image rgb;  ///< 3 channels
  std::string path;
};
struct RefineReport {
  std::vector<RefinedImage> images;                    ///< every virtual view of every patch that succeeded
  size_t dropped = 0;                                  ///< virtual views the refiner left out (Refiner::pose)
  std::vector<std::pair<int, std::string>> failures;   ///< (patch index, reason)
  double seconds = 0;
};
/// Refines every patch: `<in_root>/<patch.name>` in, `<out_root>/<patch.name>` out. A patch
/// whose refiner throws, times out, or misses an image (or returns a wrong size) is reported
/// and skipped; the others are kept.
RefineReport refine_patches(Refiner& refiner, const std::vector<Patch>& patches, const std::string& in_root, const std::string& out_root,
                            Progress& progress = null_progress());

}  // namespace fillgs
