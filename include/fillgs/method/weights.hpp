#pragma once
// Per-pixel trust in a refined (generated) view (the paper, Sec. 3.5).
//
// FillGS: weight = consistency mask × co-visibility weight.
//  * Consistency: agreement of the refined image with each of its two adjacent observed
//    views (the two training cameras nearest to it at its frame), per-pixel maximum of the
//    two. The paper uses a learned matcher (RoMa v2); fillgs warps the observed image into
//    the virtual view through the model's rendered depth (occlusion-checked against the
//    observed view's own rendered depth) and scores local colour agreement,
//    c = exp(−mean_window ‖refined − warped‖² / σ²), 0 where the point is not seen.
//    Maps computed elsewhere (RoMa, ...) can be supplied instead (MaskMethod::External).
//  * Co-visibility: the rendered D̂ = min(1, D / D_99%) of the model at the view's frame,
//    from the observation tables of the training views: large where moving Gaussians are
//    rarely seen, 0 on static or well-observed content.
// Other weightings (the paper's ablation), as fillgs reads them:
//  * none: 1;
//  * 3dgs-enhancer: image weight exp(−d / d_ref) (d: distance to the nearest training camera,
//    d_ref: median distance between neighbouring training cameras) × rendered normalised
//    Gaussian size (large Gaussians = poorly constrained, the generated view should count);
//  * exploregs: (1 − IoU of the visible sets of the view and its nearest training camera)
//    × per-pixel SSIM of the refined image against the model's render (stand-in for the
//    LPIPS map);
//  * ua-4dgs: rendered per-Gaussian uncertainty 1 / (1 + Σ_training views at that frame of
//    the Gaussian's maximum blending weight).
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/model/gaussians.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/method/select.hpp"

namespace fillgs {

enum class Weighting { FillGS, None, NoConsistency, NoCovisibility, Enhancer3DGS, ExploreGS, UA4DGS };
FILLGS_ENUM_NAMES(Weighting, "weighting",
    {Weighting::FillGS, "fillgs"}, {Weighting::None, "none"}, {Weighting::NoConsistency, "no-consistency"},
    {Weighting::NoCovisibility, "no-covisibility"}, {Weighting::Enhancer3DGS, "3dgs-enhancer"}, {Weighting::ExploreGS, "exploregs"},
    {Weighting::UA4DGS, "ua-4dgs"});

/// depth-warp: through the model's rendered depth (occlusion-checked); sweep: the best
/// match along the epipolar line over `sweep_planes` depths (model-independent, like a
/// dense matcher); external: maps computed elsewhere.
enum class MaskMethod { DepthWarp, Sweep, External };
FILLGS_ENUM_NAMES(MaskMethod, "mask method", {MaskMethod::DepthWarp, "depth-warp"}, {MaskMethod::Sweep, "sweep"});
struct MaskOptions {
  MaskMethod method = MaskMethod::DepthWarp;
  double sigma = 0.05;            ///< colour difference (RMS, [0,1] units) at which confidence is 1/e
  int window = 3;                 ///< local agreement window (pixels, odd); 3 separated oracle artifacts best (AUC 0.913 vs 0.905 at 5, 0.890 at 9)
  int search = 0;                 ///< best match within ±search pixels of the warped position (±1 lowered the AUC to 0.901)
  double depth_tolerance = 0.05;  ///< occlusion test: |z − z_observed| ≤ this × z
  double min_alpha = 0.5;         ///< pixels with less rendered opacity have no depth
  int sweep_planes = 64;          ///< sweep: depths, uniform in inverse depth
  double sweep_near = 0.3;        ///< sweep: nearest depth; the farthest is 2 × the view's largest rendered depth
  /// External maps: `<external_dir>/<name>` (8/16-bit grey, same size) for a refined view
  /// named `name` (the refined image's path relative to the refined root).
  std::string external_dir;
  Covisibility covisibility = Covisibility::Paper;
  /// The scale of D̂ in the co-visibility weight (DeficiencyField): per frame over the moving
  /// Gaussians visible at it, opacity-weighted (the default), or over every moving Gaussian
  /// of every frame (the earlier rule).
  CovisibilityScale scale = CovisibilityScale::Visible;
  /// Divide each refined view's weights by their mean (a view with mean weight m then
  /// weighs as much in the loss as an unweighted one; the map only redistributes it).
  bool normalise = false;
};

/// Divides `weights` by their mean (left as they are when the mean is 0).
void normalise_by_mean(std::vector<float>& weights);

/// Expected depth Σ α·T·z / α of a render, 0 where α < min_alpha.
std::vector<float> expected_depth(const FrameGaussians& frame, const Camera& camera, double min_alpha);

/// Confidence ([H][W] in [0, 1]) that `refined` (seen from `camera` with depth `depth`)
/// agrees with `observed` (seen from `observed_camera`, depth `observed_depth`).
std::vector<float> consistency_with(const Image& refined, const Camera& camera, const std::vector<float>& depth, const Image& observed,
                                    const Camera& observed_camera, const std::vector<float>& observed_depth, const MaskOptions& options);

/// Sweep consistency: per pixel, the best local agreement of `refined` with `observed`
/// over depths uniform in inverse depth between `near` and `far` ([H][W] in [0, 1]).
std::vector<float> sweep_consistency(const Image& refined, const Camera& camera, const Image& observed, const Camera& observed_camera,
                                     double near, double far, const MaskOptions& options);

/// A check of a refined image against its reference that uses neither depth nor model:
/// dense optical flow alone (OpenCV's DIS, medium preset, on grey levels), both ways. A pixel
/// passes when its flow to the reference and the reference's flow back return within
/// `round_trip_pixels`, and its colour matches the reference's where the flow lands within
/// `colour_rms` (RMS over the channels, [0, 1] units). A warp through a wrong depth
/// stretches, folds and duplicates the reference's content; flow cannot map such pixels one
/// to one, so they fail the round trip.
struct FlowCheckOptions {
  double round_trip_pixels = 1.0;
  double colour_rms = 0.1;
};
/// [H][W], 1 where `image` passes against `reference` (same size, RGB).
std::vector<uint8_t> flow_consistency(const Image& image, const Image& reference, const FlowCheckOptions& options = {});

/// Per-pixel SSIM map (11×11 Gaussian window, σ 1.5) of two RGB images, mean over channels.
std::vector<float> ssim_map(const Image& a, const Image& b);

/// What the weights of one refined view are computed from: the model being fine-tuned,
/// the observed views with their images, and D̂ of the model.
struct WeightContext {
  const GaussianCloud* model = nullptr;
  std::vector<ObservedView> views;
  std::function<Image(size_t)> image;   ///< observed image of views[i]
  const DeficiencyField* deficiency = nullptr;
  int frames = 1;
  Vec3f background = Vec3f::Zero();
  /// Rendered depths of observed views, computed once per context (a context belongs to
  /// one model; every refined view of a round compares against the same few views).
  mutable std::map<size_t, std::vector<float>> observed_depths;
};

struct ViewWeights {
  std::vector<float> consistency;   ///< [H][W] (empty when the weighting does not use it)
  std::vector<float> covisibility;  ///< [H][W] (idem)
  std::vector<float> weight;        ///< [H][W], the loss weight
  double image_weight = 1.0;        ///< the per-view factor already folded into `weight`
  int adjacent[2] = {-1, -1};       ///< observed views compared against
};

/// The deficiency field the weights of a round read: D̂ of `tables` (the observation tables
/// of the round's training views), its scale the `quantile` of D per frame over the moving
/// Gaussians `model` shows there (each weighted by its opacity at that frame), or over every
/// moving Gaussian of every frame where options.scale is Global.
DeficiencyField weight_field(const GaussianCloud& model, const ObservationTables& tables, float quantile, const MaskOptions& options);

/// Weights of a refined view (`camera` at its time; frame = nearest frame).
/// `external_name` locates an external consistency map when options.method is External.
ViewWeights compute_weights(const WeightContext& context, const Image& refined, const Camera& camera, Weighting weighting,
                            const MaskOptions& options, const std::string& external_name = "");

/// How fine-tuning weighs a round's refined views, in one place for every face (`fillgs
/// finetune`, the module's `weights`): the round's model, the deficiency field of its tables,
/// the real views and their images as the context, the training background.
class RefinedViewWeigher {
 public:
  RefinedViewWeigher(const GaussianCloud& model, const ObservationTables& tables, float quantile, const MaskOptions& mask, Weighting weighting,
                     std::vector<ObservedView> views, std::function<Image(size_t)> image, int frames, const Vec3f& background);
  RefinedViewWeigher(const RefinedViewWeigher&) = delete;
  RefinedViewWeigher& operator=(const RefinedViewWeigher&) = delete;
  /// The weights of one refined image, before normalisation (MaskOptions::normalise is the
  /// trainer's: normalise_by_mean of `weight`).
  ViewWeights operator()(const Image& refined, const Camera& camera, const std::string& external_name = "") const;

 private:
  DeficiencyField field_;
  WeightContext context_;
  MaskOptions mask_;
  Weighting weighting_;
};

/// The two observed views nearest (camera centre) to `camera` at `frame`, distinct poses.
std::vector<int> adjacent_observed(const std::vector<ObservedView>& views, const Camera& camera, int frame);

/// Area under the ROC curve of `score` separating label 1 (positive) from label 0, ties
/// counted half (the Mann–Whitney statistic). NaN when a class is empty.
double roc_auc(const std::vector<float>& score, const std::vector<uint8_t>& label);

}  // namespace fillgs
