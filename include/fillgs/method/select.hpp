#pragma once
// Viewpoint-time selection (the paper, Sec. 3.2–3.3; the baselines of Sec. 4.3): the FillGS strategy and the baselines
// the paper compares against, behind one interface.
//
// Inputs: a 4D scene, its observed viewpoints (training cameras, each at a frame time),
// optionally their images (for the error term L), and the exploration grid. Output:
// trajectories, each a start viewpoint (an observed camera at a frame), `views` virtual
// poses found at that frame, and the consecutive frames a refiner patch spans
// (the paper, Sec. 3.4): every pose is a virtual view at every patch frame.
//
// FillGS, in order:
//  1. exploration priority E(v) = L(v) + V(v) over observed viewpoints (every
//     `time_stride`-th frame), highest first; each viewpoint starts at most one trajectory;
//  2. from the current viewpoint, 12 local candidates (± step along right/up/forward,
//     ±10° about right and up, half-way to each of the two nearest training cameras at
//     that time) and, at the first step, 12 global ones (free voxels of the box spanned by
//     the start and its two nearest observed viewpoints, grown by views × step; viewing
//     direction slerped between those two by distance). Candidates outside free space
//     (centre not free, or a blocked straight path from the current pose) are dropped;
//  3. score = mean of the rendered normalised deficiency D̂ = min(1, D / D_99%); the best
//     local candidate extends the trajectory, a winning global candidate ends the search:
//     the trajectory becomes the interpolation from the training camera nearest to it;
//  4. every virtual view then counts as an observation: C += 1 where it sees, D = s/(1+C)
//     recomputed, so the next trajectory goes to the next gap.
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "fillgs/base/bounds.hpp"
#include "fillgs/base/names.hpp"
#include "fillgs/base/row_table.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/explore/exploration.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/base/progress.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

/// What a candidate's rendered map holds per Gaussian (the paper's score and its ablations).
enum class CandidateScore { Deficiency, CountOnly, SpeedOnly };

/// How the co-visibility weight turns the observation tables into a per-Gaussian value
/// (rendered like colour). s: speed, C: observation count at the view's frame (the
/// training cameras and the virtual views chosen so far), D = s / (1 + C).
enum class Covisibility {
  Paper,        ///< D̂ = min(1, D / D_q), D_q the quantile of D over the scene (static: 0)
  StaticCount,  ///< Paper for moving Gaussians, 1 / (1 + C) for static ones (fillgs)
  /// min(1, (1 + s / s_q) / (1 + C)), s_q the quantile of the moving Gaussians' speeds:
  /// observation density discounted by motion (fillgs). Static content seen by n cameras
  /// weighs 1 / (1 + n); a Gaussian moving at s_q counts as half as observed; content no
  /// camera sees weighs 1.
  Density,
};
FILLGS_ENUM_NAMES(Covisibility, "co-visibility rule",
    {Covisibility::Paper, "paper"}, {Covisibility::StaticCount, "static-count"}, {Covisibility::Density, "density"});

/// Where the scale of D̂ in the co-visibility weight comes from (DeficiencyField).
enum class CovisibilityScale { Visible, Global };
FILLGS_ENUM_NAMES(CovisibilityScale, "co-visibility scale", {CovisibilityScale::Visible, "visible"}, {CovisibilityScale::Global, "global"});

/// How candidate maps are rendered: rays through the Embree proxies every `stride`
/// pixels, or the rasterizer at full resolution.
enum class MapRenderer { Raytraced, Raster };
FILLGS_ENUM_NAMES(MapRenderer, "map renderer", {MapRenderer::Raytraced, "raytraced"}, {MapRenderer::Raster, "raster"});

struct SelectOptions {
  /// A strategy's name (method/strategies.hpp: fillgs, the paper's, and the baselines).
  std::string strategy = "fillgs";
  /// The values given for the strategies' own parameters (each declared in its row; the
  /// strategy reads them through SelectionContext::options).
  RowParameterValues parameters;
  int trajectories = 20;         ///< budget
  int views = 3;                 ///< virtual poses per trajectory (the refiner patch takes 3)
  int patch_frames = 3;          ///< consecutive frames each pose is rendered at (centred on the start's)
  uint64_t seed = 1;

  // starting viewpoints (the paper, Sec. 3.2)
  int time_stride = 1;           ///< priority on every k-th frame only (long videos)
  double render_scale = 0.5;     ///< V and Fisher renders at this fraction of the resolution (L is always full)
  // candidates (the paper, Sec. 3.3)
  int global_candidates = 12;
  double rotation_step_degrees = 10.0;
  MapRenderer renderer = MapRenderer::Raster;  // measured faster than rays at equal accuracy (bench select)
  int stride = 4;                ///< ray stride of the candidate maps
  float deficiency_quantile = 0.99f;  ///< D̂ = min(1, D / this quantile of D > 0)
  VisibilityOptions visibility;  ///< counts C and their updates (frustum = the 3DGS rule, the paper's)

  // ablations (the paper's tables)
  bool no_start_selection = false;   ///< random starting viewpoints
  bool no_error_term = false;        ///< E = V
  bool no_sensitivity_term = false;  ///< E = L
  bool no_candidate_scoring = false; ///< a random candidate
  bool no_global = false;            ///< local candidates only
  CandidateScore score = CandidateScore::Deficiency;
  /// fillgs option beyond the paper (starting viewpoints by E): skip a start whose pose
  /// already began a trajectory of this call at a frame fewer than patch_frames away, so
  /// that no two patches of one camera overlap in time (the paper does not say how the top
  /// starts of one round may repeat; by default they may).
  bool spread_starts = false;
  /// fillgs option beyond the paper (candidate scoring): a candidate's score is the sum of
  /// D̂ over the Gaussians it sees at its time (the visibility rule of the counts C) — the
  /// information it gains, as the paper reads D — instead of the mean of the rendered D̂
  /// map, which grows as a view steps closer to a mover and fills its frame with it.
  bool score_gain = false;

  float fisher_lambda = 1e-6f;       ///< fisherrf: Σ H_cand / (H_train + λ)
};

/// One observed viewpoint: a training camera at a frame.
struct ObservedView {
  Camera camera;        ///< with time = frame time
  int frame = 0;
  uint32_t pose = 0;    ///< distinct pose (rig camera) it belongs to
};

/// The observed viewpoints of a camera list: timed cameras are assigned to their nearest
/// frame; cameras without a time are a rig seen at every frame (input order kept, a rig
/// camera's frames consecutively).
std::vector<ObservedView> observed_views(const std::vector<Camera>& cameras, int frames);

struct PriorityScores;

struct SelectInput {
  const GaussianCloud* scene = nullptr;
  std::vector<ObservedView> views;
  int frames = 1;
  /// Image of views[i] as float RGB [H][W][3] at the camera's resolution; empty function:
  /// no images (the error term L is then 0 and says so).
  std::function<std::vector<float>(size_t)> image;
  Vec3f background = Vec3f::Zero();
  const ExplorationGrid* grid = nullptr;
  /// Exploration priority computed before (it depends on the model and the views only, not
  /// on C or D): reused instead of recomputed, e.g. across ablation runs. Must come from
  /// exploration_priority on the same views with the same error/sensitivity flags.
  const PriorityScores* priority = nullptr;
  /// Virtual views added before (earlier fine-tuning rounds, with times): they count as
  /// observations (C, coverage, Fisher) before the first trajectory, but start nothing.
  std::vector<Camera> earlier_views;
};

/// Exploration priority of the evaluated observed viewpoints (the paper, Sec. 3.2).
struct PriorityScores {
  std::vector<uint32_t> views;        ///< indices into SelectInput::views that were evaluated
  std::vector<double> error;          ///< L (mean 1)
  std::vector<double> translation, rotation, time;  ///< normalised groups (means 3/7, 3/7, 1/7)
  std::vector<double> raw_error;      ///< mean squared error per pixel and channel
  std::vector<double> priority;       ///< E = L + V (ablations drop terms)
  double seconds = 0;
};

struct Trajectory {
  int index = 0;
  int start_view = -1;     ///< index into SelectInput::views
  int frame = 0;           ///< frame the poses were chosen at
  bool global = false;     ///< a global candidate won: interpolation from the nearest training camera
  std::vector<Camera> poses;     ///< virtual poses (time = the frame's)
  std::vector<double> scores;    ///< score of each pose when it was chosen (strategy's own score)
  std::vector<int> patch_frames; ///< consecutive frames, the trajectory's frame among them
  std::vector<double> patch_times;
  /// Every pose at every patch frame (pose-major), named "traj<k>_v<j>_f<frame>".
  std::vector<Camera> views() const;
};

struct SelectTimings {
  double observe = 0, priority = 0, candidates = 0, scoring = 0, update = 0, total = 0;
  size_t candidates_scored = 0, candidates_rejected = 0;
};

struct SelectResult {
  std::vector<Trajectory> trajectories;
  PriorityScores priority;       ///< filled by strategies that use it
  SelectTimings timings;
  float deficiency_scale = 1;    ///< D_99% of the initial tables
  ObservationTables initial_tables;  ///< C, s, D before any trajectory was added
  std::vector<std::string> notes;
};

/// The ranges of SelectOptions' counts: the command line's flags declare them, and
/// check_select_options checks them for every face.
Bounds trajectory_bounds();    ///< trajectories: [0, 100000]
Bounds views_bounds();         ///< views per trajectory: [1, 1000] (each is scored, rendered and refined)
Bounds patch_frame_bounds();   ///< patch_frames: [1, 1000]

/// The one check of a selection's options (counts in range, a priority left by the
/// ablations, a known strategy), each problem one line naming the option as `spell` writes it.
void check_select_options(const SelectOptions& o, const Spelling& spell = {});

/// Runs a strategy. Deterministic for a given seed, whatever the thread count.
SelectResult select_viewpoints(const SelectInput& input, const SelectOptions& options, Progress& progress = null_progress());

/// Selection among real candidates: the (camera, frame) pairs of a captured rig's pool,
/// neither trained on nor held out. Each strategy ranks them by its own score, `count` of
/// them greedily, one at a time, every chosen one counted as an observation before the next
/// (the counts C and D, and the strategy's own state: coverage cells, Fisher information):
///  * fillgs: the mean of the rendered D̂ at the candidate's camera and frame, highest
///    first (no start selection: a pool camera's priority E would need its photograph, and
///    a strategy that looks at the candidates' images before choosing them has an
///    advantage none of the others has); negative: lowest first;
///  * coverage3d / coverage4d: newly covered (Gaussian × direction) cells; fisherrf:
///    Σ H_cand / (H_train + λ); highest first;
///  * random: a seeded shuffle; interpolation: the pool cameras nearest (centre to segment)
///    to a chord between neighbouring training poses (each with its nearest other), closest
///    first, frames in a seeded order.
/// SelectInput::earlier_views count as observations first. Highest-first strategies search
/// lazily (a candidate is rescored only when it comes to the top: exact, since no score
/// grows as views are added — C only rises, coverage only fills, information only adds);
/// `exhaustive` rescores every candidate after every choice (the reference the lazy search
/// is tested against). Lowest-first rescores the chosen frame's candidates.
struct PoolChoice {
  size_t candidate = 0;  ///< index into the pool
  double score = 0;      ///< the strategy's score when it was chosen
};
struct PoolSelectResult {
  std::vector<PoolChoice> chosen;
  size_t scored = 0;             ///< candidate scores computed
  float deficiency_scale = 1;    ///< D_99% of the initial tables
  ObservationTables initial_tables;  ///< C, s, D of the observed views before any choice
  double seconds = 0;
  std::vector<std::string> notes;
};
PoolSelectResult select_from_pool(const SelectInput& input, const std::vector<ObservedView>& pool, int count, const SelectOptions& options,
                                  bool exhaustive = false, Progress& progress = null_progress());

/// The exploration priority (the paper, Sec. 3.2) alone, for the given observed viewpoints (used by select_viewpoints and tests).
PriorityScores exploration_priority(const SelectInput& input, const SelectOptions& options, Progress& progress = null_progress());

/// The 12 local candidates (the paper, Sec. 3.3 and Appendix A) of a viewpoint, unfiltered, in the order: +right, −right, +up,
/// −up, +forward, −forward (translations by `step`), +pitch, −pitch (about right), +yaw,
/// −yaw (about up), then half-way to the nearest and second nearest of `training` (by
/// centre distance, ignoring cameras at the same centre).
std::vector<Camera> local_candidates(const Camera& current, const std::vector<Camera>& training, double step, double rotation_degrees);

/// The global candidates (the paper, Sec. 3.3): `count` points drawn among the free voxels of the box spanned by
/// `start` and its two nearest cameras in `training` (ignoring any at its centre), grown by
/// `grow` on every side; each looks in the direction slerped between those two cameras by
/// distance (all the way to a's when at a). With one other camera (two training cameras),
/// the two are `start` and that camera; with none, there are no global candidates.
/// Intrinsics of `start`.
std::vector<Camera> global_candidates(const Camera& start, const std::vector<Camera>& training, const ExplorationGrid& grid, int count,
                                      double grow, std::mt19937_64& rng);

/// Per-Gaussian `values` (one channel) rendered by the rasterizer into `camera`: [H][W].
std::vector<float> render_value_map(const FrameGaussians& frame, const Camera& camera, const float* values);
/// Mean of a map (0 for an empty one): the candidate score of a D̂ map.
double mean_value(const std::vector<float>& map);

/// Camera half-way (or at fraction s) between a and b: centre lerped, rotation slerped.
Camera interpolate_camera(const Camera& a, const Camera& b, double s);

/// The quantile of `values` weighted by `weights` (> 0): the smallest value whose
/// cumulative weight, in ascending order of value, reaches `quantile` × the total weight.
/// 1 when nothing has positive weight.
float weighted_quantile(const std::vector<float>& values, const std::vector<float>& weights, double quantile);

/// Per-Gaussian values whose rendering scores a candidate at frame f (D̂, 1/(1+C) or ŝ).
class DeficiencyField {
 public:
  /// D̂ = min(1, D / scale). Without `dynamic_opacity` the scale is the `quantile` of D > 0
  /// over every moving Gaussian of every frame (ObservationTables::deficiency_scale). With
  /// it ([T][Ndyn]: each moving Gaussian's opacity at each frame of the tables) the scale is
  /// per frame: the opacity-weighted `quantile` of D over the moving Gaussians visible at
  /// that frame (opacity ≥ 1/255, D > 0), so that faint Gaussians drifting through a frame
  /// do not set the scale of the ones it shows (the global one where a frame has none).
  DeficiencyField(ObservationTables tables, float quantile, const std::vector<float>* dynamic_opacity = nullptr);
  const ObservationTables& tables() const { return tables_; }
  float scale() const { return scale_; }
  /// The scale D̂ uses at frame f.
  float scale(int frame) const { return frame_scale_.empty() ? scale_ : frame_scale_[size_t(frame)]; }
  /// D̂ (or the ablation's value) for all N Gaussians at frame f.
  std::vector<float> values(int frame, CandidateScore score) const;
  /// The co-visibility weight's per-Gaussian value at frame f (weights.hpp, Covisibility).
  std::vector<float> covisibility(int frame, Covisibility rule) const;
  /// Counts one more observation of `visible` at frame f and updates D there.
  void add_view(int frame, const std::vector<uint32_t>& visible);

 private:
  ObservationTables tables_;
  std::vector<int32_t> dynamic_index_;
  float scale_ = 1, speed_scale_ = 1;
  std::vector<float> frame_scale_;  ///< per frame (visible-set scale), empty: scale_ everywhere
};

}  // namespace fillgs
